#!/usr/bin/env python3
"""End to end, as a user runs it: `np.loadtxt` + `allantools.oadev` against `driftless allan`
on the same 10^7-row CSV, timed in one run on this machine (issue 10's goal: driftless >= 10x).

The CSV is what `driftless simulate` writes (a time column and one rate column, shortest
round-trip floats; 10^7 rows at 50 Hz, ~280 MB); it is made once under /tmp unless given.
Both sides compute the overlapping Allan deviation at octave taus (m = 1, 2, 4, ...) of the
rate column; the script checks that they agree.

Pinned peers (benches/python/requirements.txt): numpy==2.4.6, allantools==2024.6.
    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install -r benches/python/requirements.txt
    cargo build --release
    /tmp/venv/bin/python benches/python/csv_allan_vs_numpy.py [--csv FILE] [--repeat 3]
"""
import argparse
import importlib.metadata
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np
import allantools

for name, want in (("numpy", "2.4.6"), ("allantools", "2024.6")):
    got = importlib.metadata.version(name)
    if got != want:
        sys.exit(f"{name} {got} installed, this benchmark pins {want} (requirements.txt)")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RATE = 50.0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--csv", default="/tmp/driftless-bench-1e7.csv")
    ap.add_argument("--bin", default=os.path.join(ROOT, "target/release/driftless"))
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    if not os.path.exists(a.csv):
        subprocess.run([a.bin, "simulate", "--profile", "adxrs450", "--rate", str(RATE),
                        "--duration", "200000s", "-o", a.csv], check=True)
    size = os.path.getsize(a.csv)
    print(f"{a.csv}: {size / 1e6:.1f} MB; load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")

    # Warm the page cache, so that both sides read from memory.
    with open(a.csv, "rb") as f:
        while f.read(1 << 24):
            pass

    # CPU seconds too: on a shared 2-core machine the wall clock also counts other work.
    def cpu(who):
        r = resource.getrusage(who)
        return r.ru_utime + r.ru_stime

    best_load = best_dev = python_cpu = float("inf")
    for _ in range(a.repeat):
        c0, t0 = cpu(resource.RUSAGE_SELF), time.perf_counter()
        y = np.loadtxt(a.csv, delimiter=",", skiprows=1, usecols=1)
        t1 = time.perf_counter()
        taus, dev, _, _ = allantools.oadev(y, rate=RATE, data_type="freq", taus="octave")
        t2, c2 = time.perf_counter(), cpu(resource.RUSAGE_SELF)
        best_load, best_dev = min(best_load, t1 - t0), min(best_dev, t2 - t1)
        python_cpu = min(python_cpu, c2 - c0)
    python = best_load + best_dev

    ours = ours_cpu = float("inf")
    for _ in range(a.repeat):
        c0, t0 = cpu(resource.RUSAGE_CHILDREN), time.perf_counter()
        out = subprocess.run([a.bin, "allan", a.csv, "--rate", str(RATE), "--json"],
                             check=True, capture_output=True)
        ours = min(ours, time.perf_counter() - t0)
        ours_cpu = min(ours_cpu, cpu(resource.RUSAGE_CHILDREN) - c0)
    points = json.loads(out.stdout)["columns"][0]["points"]
    mine = {round(p["tau"], 9): p["dev"] for p in points}
    common = [(t, d) for t, d in zip(taus, dev) if round(t, 9) in mine]
    worst = max(abs(mine[round(t, 9)] - d) / d for t, d in common)
    print(f"same deviations: {len(common)} common taus, worst relative difference {worst:.1e}")
    assert common and worst < 1e-9, "driftless and allantools disagree"

    print(f"np.loadtxt {best_load:.2f} s + allantools.oadev {best_dev:.2f} s = {python:.2f} s "
          f"({size / 1e6 / best_load:.0f} MB/s of CSV)")
    print(f"driftless allan (end to end, process start to exit): {ours:.2f} s")
    print(f"CPU seconds: Python {python_cpu:.2f}, driftless {ours_cpu:.2f} (both threads)")
    print(f"ratio (wall clock): {python / ours:.1f}x; goal >= 10x: {python / ours >= 10}; "
          f"load average now {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
