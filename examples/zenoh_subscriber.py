#!/usr/bin/env python3
"""A subscriber of driftless's corrected rates over Zenoh, in another language than the daemon.

    pip install eclipse-zenoh==1.10.2      # the version of the Rust zenoh crate driftless uses
    driftless run pipelines/demo.toml &
    driftless bridge demo/corrected --listen tcp/127.0.0.1:7447 --no-multicast-scouting &
    python3 examples/zenoh_subscriber.py --connect tcp/127.0.0.1:7447 --count 2000

The payload is driftless::GyroSample.v4's 264 little-endian bytes (docs/wire-types.md, "Layouts"):
    0 u64 t_ns | 8 u64 seq | 16 u64 ingest_ns | 24 f64[3] rate | 48 f64[3] drift
    72 f64[3] denoised | 96 u32 flags | 100 u32 epoch | 104 f64[3] drift_std (-1: not provided)
    128 f64[3] accel (m/s^2) | 152 f64[3] accel_std | 176 f64[3] mag (T) | 200 u32 sensors
    204 u32 reserved | 208 f64[4] orientation (x, y, z, w) | 240 f64[3] orientation_std (rad)
with encoding application/octet-stream;driftless::GyroSample.v4. A payload of an older layout
(driftless::GyroSample.v3, 208 bytes, driftless::GyroSample.v2, 128 bytes, or
driftless::GyroSample, 104 bytes, from a bridge of an older driftless) is refused by name.
Checks that seq rises by one within each epoch (a jump is a loss, a repeat or a step back is an
error) and prints the rate and the bias's 1-sigma once a second. Exit 0 when --count samples
came in order, 1 otherwise.
"""

import argparse
import math
import queue
import struct
import sys
import time

import zenoh

GYRO = struct.Struct("<QQQ9dII12dII7d")  # 264 bytes
assert GYRO.size == 264
GYRO_TYPE = "driftless::GyroSample.v4"
# Older layouts: version 1 before drift_std, version 2 before the accelerometer, version 3
# before the orientation.
GYRO_OLD = {"driftless::GyroSample": (1, 104), "driftless::GyroSample.v2": (2, 128),
            "driftless::GyroSample.v3": (3, 208)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--key", default="driftless/demo/corrected")
    ap.add_argument("--connect", action="append", default=[], help="endpoint, e.g. tcp/127.0.0.1:7447")
    ap.add_argument("--listen", action="append", default=[])
    ap.add_argument("--count", type=int, default=0, help="exit after this many samples (0: never)")
    ap.add_argument("--timeout", type=float, default=30.0, help="give up after this many seconds")
    args = ap.parse_args()

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    if args.connect:
        conf.insert_json5("connect/endpoints", str(args.connect).replace("'", '"'))
    if args.listen:
        conf.insert_json5("listen/endpoints", str(args.listen).replace("'", '"'))

    samples: "queue.Queue[tuple[bytes, str]]" = queue.Queue()
    received = missing = disorder = 0
    last = None  # (epoch, seq)
    deg = 180.0 / math.pi
    with zenoh.open(conf) as session:
        sub = session.declare_subscriber(
            args.key, lambda s: samples.put((s.payload.to_bytes(), str(s.encoding)))
        )
        start = tick = time.monotonic()
        window = 0
        while time.monotonic() - start < args.timeout:
            try:
                payload, encoding = samples.get(timeout=0.1)
            except queue.Empty:
                continue
            schema = encoding.split(";", 1)[1] if ";" in encoding else None
            old = schema if schema in GYRO_OLD else next(
                (n for n, (_, size) in GYRO_OLD.items() if schema is None and len(payload) == size),
                None)
            if old is not None:
                version, size = GYRO_OLD[old]
                print(f"{args.key} carries {old} (layout v{version}, {size} bytes, from an "
                      f"older driftless); this subscriber reads {GYRO_TYPE} ({GYRO.size} bytes): "
                      "run the bridge and this subscriber from one release", file=sys.stderr)
                return 1
            if len(payload) != GYRO.size or schema not in (None, GYRO_TYPE):
                print(f"not a {GYRO_TYPE}: {len(payload)} bytes, {encoding}", file=sys.stderr)
                return 1
            t_ns, seq, ingest_ns, *f = GYRO.unpack(payload)
            rate, flags, epoch, sd = f[0:3], f[9], f[10], f[11:14]
            if last is not None and last[0] == epoch:
                if seq > last[1] + 1:
                    missing += seq - last[1] - 1
                elif seq <= last[1]:
                    disorder += 1
            last = (epoch, seq)
            received += 1
            window += 1
            if time.monotonic() - tick >= 1.0:
                print(
                    f"{args.key}: {window / (time.monotonic() - tick):.1f} Hz, seq {seq}, "
                    f"rate [{rate[0] * deg:+.4f} {rate[1] * deg:+.4f} {rate[2] * deg:+.4f}] deg/s, "
                    # -1: no bias filter in the pipeline gives one ("not provided").
                    f"bias 1-sigma [{' '.join(f'{v * deg:.4f}' if v >= 0 else '-' for v in sd)}] deg/s, "
                    f"flags {flags:#x}, {received} received, {missing} missing",
                    file=sys.stderr,
                )
                tick, window = time.monotonic(), 0
            if args.count and received >= args.count:
                break
        sub.undeclare()
    print(f"{received} received, {missing} missing (sequence gaps), {disorder} out of order")
    ok = disorder == 0 and missing == 0 and (not args.count or received >= args.count)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
