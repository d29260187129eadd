#!/usr/bin/env python3
"""Time PyWavelets' wavedec + threshold + waverec (db6, 5 levels, universal threshold, MAD sigma)
on the same signals as benches/denoise.rs, for a same-run speed comparison.

Pinned peer: PyWavelets==1.9.0.  Run: python3 scripts/bench_pywt.py
"""
import importlib.metadata
import time

import numpy as np
import pywt

assert importlib.metadata.version("PyWavelets") == "1.9.0"


def signal(n):
    i = np.arange(n)
    return np.sin(i * 0.001) + ((i * 7919) % 1000) / 1000.0 - 0.5


def denoise(x, mode):
    coeffs = pywt.wavedec(x, "db6", mode="symmetric", level=5)
    d1 = coeffs[-1]
    sigma = np.median(np.abs(d1[d1 != 0])) / 0.6744897501960817
    lam = sigma * np.sqrt(2 * np.log(len(x)))
    coeffs[1:] = [pywt.threshold(c, lam, mode) for c in coeffs[1:]]
    return pywt.waverec(coeffs, "db6", mode="symmetric")[: len(x)]


def transform(x, _):
    return pywt.waverec(pywt.wavedec(x, "db6", mode="symmetric", level=5), "db6", mode="symmetric")


def best_of(work, x, arg):
    reps = max(3, int(2e6 // len(x)))
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(reps):
            work(x, arg)
        best = min(best, (time.perf_counter() - t0) / reps)
    return best


for n in (18_000, 1_000_000):
    x = signal(n)
    for name, work, arg in (("hard", denoise, "hard"), ("soft", denoise, "soft"), ("wavedec+waverec", transform, None)):
        best = best_of(work, x, arg)
        print(f"pywt {name:4} n={n:>9}: {best * 1e3:9.3f} ms  ({best / n * 1e9:6.1f} ns/sample)")
