#!/usr/bin/env python3
"""A navigation subscriber in Python, like examples/nav_subscriber.rs: reads a pipeline's corrected
rates (driftless::GyroSample), checks exactly-once in-order delivery, integrates heading from the
z axis and measures the latency from the daemon's ingest to receipt here.

    driftless run pipelines/external-sensor.toml &
    python3 examples/python/subscriber.py --service external/corrected --count 5000 &
    python3 examples/python/driver.py --count 5000        # then stop the daemon (Ctrl-C)

Waking: it sleeps on the event service of the same name (Listener.timed_wait, 100 ms at most)
and drains the subscriber at each wake-up, one wake-up per sample as nav_subscriber.rs; no
polling, so an idle subscriber costs nothing, and the timeout only bounds how late it notices
SIGINT/SIGTERM or its --timeout. A plain Listener does it: a WaitSet adds nothing for one source.

Opening, as driftless::transport's Transport::open_input: the service is the daemon's, opened
with open() and no QoS requirements (asking for more than its creator gave fails, e.g.
DoesNotSupportRequestedMinBufferSize),
retried every 50 ms for --wait-service seconds (services live with the daemon); the
subscriber's buffer is the service's subscriber_max_buffer_size (the pipeline's buffer_size,
256 by default; iceoryx2's own default would be 2). Each sample is copied out and released at
once (the service lends a subscriber only 2 samples at a time).

Checks, within each epoch (seq restarts when the epoch changes): seq rises by exactly one (a jump
is a loss, a repeat or step back an error), t_ns rises, no sample is flagged invalid, gap, time
backwards or repaired, drift_std is -1 ("not provided") or a finite 1-sigma > 0 on each axis;
a sample with an orientation (an attitude.6d stage ran) carries a unit quaternion and, about
each earth axis, a finite 1-sigma >= 0 or -1 (with --expect-orientation every sample must have
one); the newest roll, pitch and yaw are printed;
with --expect-pattern also the values driver.py sends (t_ns, rates within a tolerance after the
denoiser, rate = denoised - drift, heading). With --count N it stops after
N samples and exits 0 only if N came, each once and in order, and every check held; 1 otherwise
(one line per kind of problem), 2 bad usage. Prefix and root as the daemon's: --prefix, else
DRIFTLESS_IOX2_PREFIX, else driftless_; --root-path, else DRIFTLESS_IOX2_ROOT, else /tmp/iceoryx2.
"""

import argparse
import ctypes
import json
import math
import os
import sys
import time

import iceoryx2 as iox2

import driftless_iox2 as dl

# --expect-pattern tolerances. The denoiser (external-sensor.toml: db6, level 5, lag 64) takes
# out most of the +-0.05 deg/s dither: measured within 0.004 deg/s of the base rate once warm,
# 0.033 while warming up, 0.038 for the samples flushed at shutdown; heading within 4e-5 deg
# of the driver's over 5000 samples. An axis swapped, a unit wrong or a field misplaced is off
# by far more.
RATE_TOL_DEG_S = 0.06
HEADING_TOL_DEG = 0.001


class Checker:
    """Delivery and value checks over the samples in arrival order."""

    def __init__(self, expect_pattern: bool, rate_hz: float):
        self.expect_pattern = expect_pattern
        self.rate_hz = rate_hz
        self.received = self.missing = self.disorder = self.flagged = 0
        self.flushed = self.warming_up = self.pattern_errors = 0
        # Samples whose drift_std is "not provided" (-1) on every axis, and samples with a
        # value that is neither that nor a finite positive 1-sigma (NaN, 0, another negative).
        self.drift_std_not_provided = self.drift_std_bad = 0
        self.drift_std_last = None  # the newest sample's, rad/s
        # Samples carrying an orientation, those whose quaternion or sd is not one, the newest
        # roll/pitch/yaw (deg) and sd (rad).
        self.orientation = self.orientation_bad = 0
        self.rpy_last = self.orientation_std_last = None
        # Samples whose heading is absolute (the magnetometer fixed it), and those whose
        # magnetometer reading the attitude stage rejected as disturbed.
        self.heading_absolute = self.mag_rejected = 0
        self.epochs = 0
        self.first_seq = self.last_seq = None
        self.heading_deg = self.expected_heading_deg = 0.0
        self.latency_ns = []
        self.problems = []  # the first few, for the verdict
        self.last = None  # (epoch, seq, t_ns)

    def problem(self, text: str) -> None:
        if len(self.problems) < 10:
            self.problems.append(text)

    def add(self, s: dl.GyroSample, now_ns: int) -> None:
        self.received += 1
        if self.first_seq is None:
            self.first_seq = s.seq
        self.last_seq = s.seq
        if s.flags & dl.FLAG_FLUSHED:
            self.flushed += 1
        else:
            self.latency_ns.append(now_ns - s.ingest_ns)
        if s.flags & dl.FLAG_WARMING_UP:
            self.warming_up += 1
        if s.flags & dl.FLAGS_BAD:
            self.flagged += 1
            self.problem(f"seq {s.seq}: flags {s.flags:#x}")
        sd = list(s.drift_std)
        self.drift_std_last = sd
        if all(v == dl.DRIFT_STD_NOT_PROVIDED for v in sd):
            self.drift_std_not_provided += 1
        elif not all(v == dl.DRIFT_STD_NOT_PROVIDED or (math.isfinite(v) and v > 0) for v in sd):
            self.drift_std_bad += 1
            self.problem(f"seq {s.seq}: drift_std {sd} (neither -1 nor a finite 1-sigma > 0)")
        if s.sensors & dl.SENSOR_ORIENTATION:
            self.check_orientation(s)
        last = self.last
        if last is not None and last[0] == s.epoch:
            _, seq, t_ns = last
            if s.seq > seq + 1:
                self.missing += s.seq - seq - 1
                self.problem(f"epoch {s.epoch}: seq {seq} then {s.seq} ({s.seq - seq - 1} missing)")
            elif s.seq <= seq:
                self.disorder += 1
                self.problem(f"epoch {s.epoch}: seq {seq} then {s.seq} (repeat or step back)")
            elif s.t_ns <= t_ns:
                self.disorder += 1
                self.problem(f"epoch {s.epoch}: seq {s.seq}: t_ns {s.t_ns} after {t_ns}")
            dt = max(s.t_ns - t_ns, 0) * 1e-9
            self.heading_deg += s.rate[2] * dl.RAD_TO_DEG * dt
            if self.expect_pattern:
                self.expected_heading_deg += dl.pattern(s.seq)[2] * dt
        else:
            self.epochs += 1
        self.last = (s.epoch, s.seq, s.t_ns)
        if self.expect_pattern:
            self.check_pattern(s)

    def check_orientation(self, s: dl.GyroSample) -> None:
        self.orientation += 1
        q, sd = list(s.orientation), list(s.orientation_std)
        self.rpy_last = [math.degrees(a) for a in dl.roll_pitch_yaw(q)]
        self.orientation_std_last = sd
        self.heading_absolute += bool(s.sensors & dl.SENSOR_HEADING_ABSOLUTE)
        self.mag_rejected += bool(s.sensors & dl.SENSOR_MAG_REJECTED)
        norm = math.sqrt(sum(v * v for v in q))
        sd_ok = all(v == dl.DRIFT_STD_NOT_PROVIDED or (math.isfinite(v) and v >= 0) for v in sd)
        if not (abs(norm - 1.0) < 1e-9 and sd_ok):
            self.orientation_bad += 1
            self.problem(f"seq {s.seq}: orientation {q} (norm {norm}), sd {sd}")

    def check_pattern(self, s: dl.GyroSample) -> None:
        bad = []
        if s.t_ns != dl.t_ns_of(s.seq, self.rate_hz):
            bad.append(f"t_ns {s.t_ns} != {dl.t_ns_of(s.seq, self.rate_hz)}")
        for i, base in enumerate(dl.PATTERN_BASE_DEG_S):
            d = s.denoised[i] * dl.RAD_TO_DEG
            if not abs(d - base) <= RATE_TOL_DEG_S:
                bad.append(f"axis {i}: denoised {d:+.4f} deg/s, expected {base:+.4f} +- {RATE_TOL_DEG_S}")
            if s.rate[i] != s.denoised[i] - s.drift[i]:
                bad.append(f"axis {i}: rate != denoised - drift")
        # The accelerometer rides beside the rate, time-aligned and untouched (m/s^2 in, m/s^2
        # out: bit for bit).
        if s.sensors & (dl.SENSOR_ACCEL | dl.SENSOR_ACCEL_INVALID) != dl.SENSOR_ACCEL:
            bad.append(f"sensors {s.sensors:#x}: no valid accelerometer reading")
        elif tuple(s.accel) != dl.accel_pattern(s.seq):
            bad.append(f"accel {tuple(s.accel)} != {dl.accel_pattern(s.seq)} sent with it")
        if bad:
            self.pattern_errors += 1
            self.problem(f"seq {s.seq}: " + "; ".join(bad))

    def verdict(self, count: int, expect_orientation: bool = False) -> list:
        """Why the run failed; empty when it passed."""
        why = []
        if self.orientation_bad:
            why.append(f"{self.orientation_bad} samples with an orientation that is not a unit "
                       "quaternion or a standard deviation that is neither >= 0 nor -1")
        if expect_orientation and self.orientation < self.received:
            why.append(f"{self.received - self.orientation} samples without an orientation")
        if count and self.received < count:
            why.append(f"only {self.received} of {count} samples arrived")
        if self.missing:
            why.append(f"{self.missing} samples missing (seq gaps)")
        if self.disorder:
            why.append(f"{self.disorder} samples repeated or out of order")
        if self.flagged:
            why.append(f"{self.flagged} samples flagged invalid/gap/time backwards/repaired")
        if self.pattern_errors:
            why.append(f"{self.pattern_errors} samples differ from driver.py's pattern")
        if self.drift_std_bad:
            why.append(f"{self.drift_std_bad} samples with a drift_std that is not a 1-sigma or -1")
        if self.expect_pattern and self.received > 1:
            err = self.heading_deg - self.expected_heading_deg
            if not abs(err) <= HEADING_TOL_DEG:
                why.append(f"heading {self.heading_deg:+.4f} deg, expected "
                           f"{self.expected_heading_deg:+.4f} +- {HEADING_TOL_DEG}")
        return why

    def summary(self) -> dict:
        lat = sorted(self.latency_ns)

        def q(p: float) -> int:
            return lat[min(len(lat) - 1, int(p * len(lat)))] if lat else 0

        return {
            "received": self.received, "missing": self.missing, "disorder": self.disorder,
            "flagged": self.flagged, "pattern_errors": self.pattern_errors,
            "epochs": self.epochs, "epoch": self.last[0] if self.last else None,
            "first_seq": self.first_seq, "last_seq": self.last_seq,
            "flushed": self.flushed, "warming_up": self.warming_up,
            "drift_std_not_provided": self.drift_std_not_provided,
            "drift_std_bad": self.drift_std_bad, "drift_std_last": self.drift_std_last,
            "orientation": self.orientation, "orientation_bad": self.orientation_bad,
            "rpy_last_deg": self.rpy_last, "orientation_std_last": self.orientation_std_last,
            "heading_absolute": self.heading_absolute, "mag_rejected": self.mag_rejected,
            "heading_deg": self.heading_deg, "expected_heading_deg": self.expected_heading_deg,
            "latency_ns": {"count": len(lat), "p50": q(0.5), "p99": q(0.99), "max": lat[-1] if lat else 0},
        }


def open_ports(node, service: str, wait_s: float, stop: list):
    """The daemon's service and its event service, retried while the daemon starts."""
    name = iox2.ServiceName.new(service)
    give_up = time.monotonic() + wait_s
    while True:
        try:
            ps = node.service_builder(name).publish_subscribe(dl.GyroSample).open()
            event = node.service_builder(name).event().open()
            break
        except Exception as e:  # noqa: BLE001 (DoesNotExist while the daemon starts, ...)
            if "IncompatibleTypes" in str(e):
                # Waiting will not help: the service holds another type, or another layout
                # version of ours (a driftless of another release).
                raise RuntimeError(
                    f"cannot open {service!r}: IncompatibleTypes: it does not carry "
                    f"{dl.GyroSample.type_name()} ({ctypes.sizeof(dl.GyroSample)} bytes), which "
                    "this subscriber reads; an older driftless publishes "
                    "driftless::GyroSample.v2 (128 bytes) or driftless::GyroSample (104 bytes): "
                    "run the daemon and this subscriber from one release "
                    "(docs/wire-types.md#versions)") from e
            if stop[0] or time.monotonic() >= give_up:
                raise RuntimeError(f"cannot open {service!r}: {type(e).__name__}: {e} "
                                   "(is the pipeline running, with this prefix and root?)") from e
            time.sleep(0.05)
    buffer = ps.static_config.subscriber_max_buffer_size
    subscriber = ps.subscriber_builder().buffer_size(buffer).create()
    listener = event.listener_builder().create()
    return ps, event, subscriber, listener


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--service", default="external/corrected", help="corrected service to read")
    ap.add_argument("--count", type=int, default=0, help="stop after this many samples and judge (0: until Ctrl-C)")
    ap.add_argument("--timeout", type=float, default=0.0,
                    help="give up after this many seconds of reading (0: never); with --count, a failure")
    ap.add_argument("--wait-service", type=float, default=10.0, help="seconds to wait for the service")
    ap.add_argument("--prefix", help="iceoryx2 prefix (default: $DRIFTLESS_IOX2_PREFIX or driftless_)")
    ap.add_argument("--root-path", help="iceoryx2 root (default: $DRIFTLESS_IOX2_ROOT or /tmp/iceoryx2)")
    ap.add_argument("--expect-pattern", action="store_true", help="check the values driver.py sends")
    ap.add_argument("--rate", type=float, default=1000.0, help="driver.py's --rate (for --expect-pattern)")
    ap.add_argument("--expect-orientation", action="store_true",
                    help="every sample must carry an orientation (an attitude.6d stage)")
    ap.add_argument("--ready-file", help="create this file once subscribed")
    ap.add_argument("--report", help="write the summary as JSON to this file")
    ap.add_argument("--progress-file", help="keep the number of samples received so far in this file "
                    "(rewritten at most every 20 ms, and when the stream pauses)")
    args = ap.parse_args()
    if args.count < 0 or args.timeout < 0 or not args.rate > 0:
        ap.error("--count and --timeout must be >= 0, --rate > 0")

    prefix, root = dl.resolve_prefix(args.prefix), dl.resolve_root(args.root_path)
    stop = dl.stop_flag()
    check = Checker(args.expect_pattern, args.rate)
    try:
        elapsed = receive(args, prefix, root, check, stop)
    except Exception as e:  # noqa: BLE001 (iceoryx2's errors are exceptions of many types)
        print(f"subscriber: {e}", file=sys.stderr)
        return 1
    finally:
        dl.remove_prefix_leftovers(prefix, root)

    s = check.summary()
    s["elapsed_s"] = elapsed
    why = check.verdict(args.count, args.expect_orientation)
    s["ok"] = not why
    lat = s["latency_ns"]
    print(f"subscriber: {s['received']} received (seq {s['first_seq']}..{s['last_seq']}, "
          f"{s['epochs']} epochs, {s['flushed']} flushed at shutdown, {s['warming_up']} warming up), "
          f"{s['missing']} missing, {s['disorder']} out of order, {s['flagged']} flagged; "
          f"heading {s['heading_deg']:+.4f} deg; "
          + (f"{s['orientation']} with an orientation, the last roll/pitch/yaw "
             + "/".join(f"{a:+.2f}" for a in s["rpy_last_deg"]) + " deg ("
             + f"{s['heading_absolute']} with an absolute heading, {s['mag_rejected']} with the "
             + "magnetometer rejected); "
             if s["rpy_last_deg"] else "")
          + f"latency (ingest to receipt) p50 {lat['p50']} ns, "
          f"p99 {lat['p99']} ns, max {lat['max']} ns; {elapsed:.2f} s")
    if args.report:
        with open(args.report, "w") as f:
            json.dump(s, f)
            f.write("\n")
    if why:
        for w in why:
            print(f"subscriber: FAILED: {w}", file=sys.stderr)
        for p in check.problems:
            print(f"subscriber:   {p}", file=sys.stderr)
        return 1
    return 0


def write_progress(path: str, received: int) -> None:
    """Replace `path` by one holding `received` (a reader never sees it half written)."""
    with open(path + ".tmp", "w") as f:
        f.write(f"{received}\n")
    os.replace(path + ".tmp", path)


def receive(args, prefix: str, root: str, check: Checker, stop: list) -> float:
    node = dl.create_node(prefix, root, f"py-subscriber-{os.getpid()}")
    ps, event, subscriber, listener = open_ports(node, args.service, args.wait_service, stop)
    try:
        if args.ready_file:
            open(args.ready_file, "w").close()
        start = tick = time.monotonic()
        wake = iox2.Duration.from_millis(100)
        payload = dl.GyroSample()
        size = ctypes.sizeof(payload)
        written, written_at = None, 0.0  # --progress-file
        shown = 0  # the once-a-second progress line
        while not stop[0]:
            if args.timeout and time.monotonic() - start >= args.timeout:
                break
            try:
                listener.timed_wait(wake)
            except Exception:  # noqa: BLE001 (interrupted by a signal: look at the flag)
                pass
            drained = 0
            while True:
                sample = subscriber.receive()
                if sample is None:
                    break
                drained += 1
                now = time.monotonic_ns()  # CLOCK_MONOTONIC, as the daemon's ingest_ns
                ctypes.memmove(ctypes.addressof(payload), sample.payload_ptr, size)
                sample.delete()  # give the slot back before anything else
                check.add(payload, now)
                if args.count and check.received >= args.count:
                    return time.monotonic() - start
            if args.progress_file and check.received != written and (
                    drained == 0 or time.monotonic() - written_at >= 0.02):
                write_progress(args.progress_file, check.received)
                written, written_at = check.received, time.monotonic()
            if time.monotonic() - tick >= 1.0 and check.received != shown:
                tick, shown = time.monotonic(), check.received
                print(f"subscriber: {check.received} received, {check.missing} missing, "
                      f"heading {check.heading_deg:+.2f} deg", file=sys.stderr)
        return time.monotonic() - start
    finally:
        listener.delete()
        subscriber.delete()
        del event, ps, node


if __name__ == "__main__":
    sys.exit(main())
