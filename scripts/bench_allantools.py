#!/usr/bin/env python3
"""OADEV of 10^7 samples at ~90 log-spaced taus: allantools' `oadev` and driftless (criterion,
benches/allan.rs) on the same data, measured in one run on this machine.

Data: splitmix64 from seed 42, value = (u >> 11) * 2**-53 - 0.5 (white noise), rate 1 Hz;
taus: m = round(10^(j/15)), j = 0..96, duplicates removed (as benches/allan.rs).

Pinned peer: allantools==2024.6.   Run from the repository root:
    python3 scripts/bench_allantools.py            (allantools, then `cargo bench --bench allan`)
    python3 scripts/bench_allantools.py --python-only
"""
import importlib.metadata
import re
import subprocess
import sys
import time

import numpy as np
import allantools

assert importlib.metadata.version("allantools") == "2024.6", importlib.metadata.version("allantools")

N = 10_000_000


def splitmix64(seed, n):
    with np.errstate(over="ignore"):
        state = (np.uint64(seed) + np.arange(1, n + 1, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15))
        z = state
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) * 2.0 ** -53


def main():
    y = splitmix64(42, N) - 0.5
    ms = []
    for j in range(97):
        m = float(round(10 ** (j / 15)))
        if not ms or ms[-1] != m:
            ms.append(m)
    taus = np.array(ms)
    t0 = time.perf_counter()
    tau, dev, _, _ = allantools.oadev(y, rate=1.0, data_type="freq", taus=taus)
    t_py = time.perf_counter() - t0
    print(f"allantools 2024.6 oadev: {N} samples, {len(tau)} taus: {t_py:.3f} s")
    if "--python-only" in sys.argv:
        return
    out = subprocess.run(["cargo", "bench", "--bench", "allan"], capture_output=True, text=True)
    text = out.stdout + out.stderr
    m = re.search(r"time:\s+\[\S+ \S+ (\S+) (\S+) \S+ \S+\]", text)
    if not m:
        print(text)
        sys.exit("could not read criterion's time")
    value, unit = float(m.group(1)), m.group(2)
    t_rs = value * {"s": 1.0, "ms": 1e-3, "µs": 1e-6, "us": 1e-6, "ns": 1e-9}[unit]
    print(f"driftless (criterion median estimate): {t_rs:.3f} s")
    print(f"ratio allantools / driftless: {t_py / t_rs:.1f}x")


if __name__ == "__main__":
    main()
