#!/usr/bin/env python3
"""A stand-in sensor driver in Python, like examples/raw_driver.rs: publishes driftless::RawSample.v2
(rates in deg/s, the accelerometer in m/s^2) on an iceoryx2 service at a fixed rate and notifies the event service of the same name
after each sample, as `ingest.iceoryx2` expects.

    driftless run pipelines/external-sensor.toml &
    python3 examples/python/driver.py --service sensor/raw --rate 1000 --count 5000

The samples are deterministic (driftless_iox2.pattern): seq 0, 1, 2, ...; t_ns = seq / rate;
rate = (1.5, -2.0, 10.0) deg/s plus a zero-mean dither of +-0.05 deg/s with period 17; the
accelerometer driftless_iox2.accel_pattern (gravity on z, a tilt that changes with seq); flags
RAW_ACCEL;
epoch random non-zero per start (or --epoch). subscriber.py --expect-pattern checks them.

The service is opened with the daemon's QoS (history 0, safe overflow off, subscriber buffer
--buffer-size, default 256, --max-subscribers, default 8, one publisher), so a driver started
before the daemon creates a service the daemon accepts; the publisher never blocks
(backpressure DiscardData), as the daemon's. Prefix and root as the daemon's: --prefix, else
DRIFTLESS_IOX2_PREFIX, else driftless_; --root-path, else DRIFTLESS_IOX2_ROOT, else
/tmp/iceoryx2. Exit 0 done (--count sent, or SIGINT/SIGTERM), 1 a failure, 2 bad usage.
"""

import argparse
import ctypes
import os
import sys
import time

import iceoryx2 as iox2

import driftless_iox2 as dl


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--service", default="sensor/raw", help="service to publish on")
    ap.add_argument("--rate", type=float, default=1000.0, help="sample rate, Hz, (0, 100000]")
    ap.add_argument("--count", type=int, default=0, help="samples to send (0: until Ctrl-C)")
    ap.add_argument("--prefix", help="iceoryx2 prefix (default: $DRIFTLESS_IOX2_PREFIX or driftless_)")
    ap.add_argument("--root-path", help="iceoryx2 root (default: $DRIFTLESS_IOX2_ROOT or /tmp/iceoryx2)")
    ap.add_argument("--epoch", type=int, help="this run's epoch (default: random non-zero)")
    ap.add_argument("--buffer-size", type=int, default=dl.BUFFER_SIZE,
                    help="subscriber buffer if this driver creates the service (the pipeline's buffer_size)")
    ap.add_argument("--max-subscribers", type=int, default=dl.MAX_SUBSCRIBERS,
                    help="subscribers if this driver creates the service (the pipeline's max_subscribers)")
    ap.add_argument("--skip", type=int, action="append", default=[], metavar="SEQ",
                    help="fault injection: leave out this sequence number (repeatable)")
    args = ap.parse_args()
    if not 0 < args.rate <= 100_000:
        ap.error("--rate must be in (0, 100000] Hz")
    if args.count < 0:
        ap.error("--count must be >= 0")
    if args.epoch is not None and not 0 < args.epoch < 2**32:
        ap.error("--epoch must be in [1, 2^32)")
    epoch = args.epoch or int.from_bytes(os.urandom(4), "little") or 1

    prefix, root = dl.resolve_prefix(args.prefix), dl.resolve_root(args.root_path)
    stop = dl.stop_flag()
    try:
        sent = publish(args, prefix, root, epoch, stop)
    except Exception as e:  # noqa: BLE001 (iceoryx2's errors are exceptions of many types)
        print(f"driver: {args.service}: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    finally:
        dl.remove_prefix_leftovers(prefix, root)
    print(f"driver: published {sent} samples on {args.service} (epoch {epoch})", file=sys.stderr)
    return 0


def publish(args, prefix: str, root: str, epoch: int, stop: list) -> int:
    node = dl.create_node(prefix, root, f"py-driver-{os.getpid()}")
    name = iox2.ServiceName.new(args.service)
    # The daemon's QoS (driftless::transport, Transport::pubsub): opening an existing service with these
    # requirements fails unless it holds at least as much, and creating one gives the daemon what
    # it checks for (buffer >= its buffer_size, safe overflow off).
    service = (
        node.service_builder(name)
        .publish_subscribe(dl.RawSample)
        .history_size(0)
        .enable_safe_overflow(False)
        .subscriber_max_buffer_size(args.buffer_size)
        .max_subscribers(args.max_subscribers)
        .max_publishers(1)
        .open_or_create()
    )
    publisher = (
        service.publisher_builder()
        .backpressure_strategy(iox2.BackpressureStrategy.DiscardData)
        .create()
    )
    event = node.service_builder(name).event().open_or_create()
    notifier = event.notifier_builder().create()
    skip = set(args.skip)
    sent = 0
    try:
        start = time.monotonic()
        k = 0
        while not stop[0] and (args.count == 0 or k < args.count):
            due = start + k / args.rate
            now = time.monotonic()
            if due > now:
                time.sleep(due - now)
            if k not in skip:
                x, y, z = dl.pattern(k)
                raw = dl.RawSample(
                    t_ns=dl.t_ns_of(k, args.rate),
                    seq=k,
                    rate=(ctypes.c_double * 3)(x, y, z),
                    flags=dl.RAW_ACCEL,
                    epoch=epoch,
                    accel=(ctypes.c_double * 3)(*dl.accel_pattern(k)),
                )
                publisher.loan_uninit().write_payload(raw).send()
                notifier.notify()
                sent += 1
            k += 1
    finally:
        # Ports, then the node: iceoryx2 removes their files only when they are dropped, and a
        # Python object still referenced at interpreter exit may never be.
        notifier.delete()
        publisher.delete()
        del event, service, node
    return sent


if __name__ == "__main__":
    sys.exit(main())
