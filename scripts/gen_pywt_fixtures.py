#!/usr/bin/env python3
"""Write tests/fixtures/pywt/*.json: PyWavelets' dwt/idwt and wavedec/waverec on reproducible signals.

Rerun (from the repository root; `cargo test` itself never needs Python):

    pip install PyWavelets==1.9.0 numpy
    python3 scripts/gen_pywt_fixtures.py

Pinned peer: PyWavelets==1.9.0 (checked through the distribution metadata: `pywt.__version__`
wrongly reads "1.8.0" inside the 1.9.0 wheel). The output is deterministic.

Inputs are not stored: both sides generate them bit-identically from an integer generator,
splitmix64 seeded with the signal length n, sample = (u >> 11) * 2**-53 - 0.5
(`tests/pywavelets.rs` has the Rust twin).

Every output array ("band") is stored as
    [len, max_abs, dot, idx, val]
- len, max_abs: its length and largest |value| (15 significant digits);
- dot: sum_i w_i * c_i (math.fsum, 15 significant digits) with weights w_i from splitmix64 seeded
  0xC0FFEE (same sample formula): a checksum over *every* coefficient, so a wrong value anywhere
  shows (a per-value error e moves it by |w_i| e; the test allows 1e-12 * max_abs * sum |w_i|);
- idx, val: exact stored values. idx is null when the band is stored whole (short bands: up to 12
  values in dwt.json, whole decompositions of up to 64 coefficients in wavedec.json, so idwt and
  waverec can run on PyWavelets' own coefficients); otherwise the first and last values (edges,
  where the modes differ) and one in the middle. Checksums keep the files small (~0.5 MB) while
  still covering every value.

Files:
- dwt.json: single-level pywt.dwt (cA, cD) and pywt.idwt of those reference coefficients, for
  every n in 1..=40 and every mode, for long filters (where PyWavelets repeats the extension) and
  short ones. PyWavelets refuses reflect for n = 1, so that case is absent.
- wavedec.json: pywt.wavedec at the maximum level (all bands), the approximation pywt.wavedec
  returns at each lower level, and pywt.waverec of the maximum-level reference coefficients, for
  16 wavelets x 7 modes x lengths from 2 (F - 1) (the shortest allowing level 1) to 20000,
  odd and even.
"""
import importlib.metadata
import json
import math
import pathlib

import numpy as np
import pywt

from splitmix import splitmix64  # scripts/splitmix.py

# pywt.__version__ reads "1.8.0" inside the 1.9.0 wheel; the distribution metadata is right.
assert importlib.metadata.version("PyWavelets") == "1.9.0"

MODES = ["zero", "constant", "symmetric", "reflect", "periodic", "smooth", "periodization"]
WAVELETS = ["haar", "db1", "db2", "db4", "db6", "db10", "db20", "sym2", "sym5", "sym8", "sym10",
            "sym20", "coif1", "coif3", "coif5", "coif17"]
WEIGHT_SEED = 0xC0FFEE


def splitmix(seed, n):
    """n samples in [-0.5, 0.5), bit-identical to the Rust twin."""
    return np.fromiter(splitmix64(seed), dtype=float, count=n) - 0.5


_signals = {}


def signal(n):
    if n not in _signals:
        _signals[n] = splitmix(n, n)
    return _signals[n]


WEIGHTS = splitmix(WEIGHT_SEED, 40000)


def band(c, full, edge, interior):
    """A band stored whole if len(c) <= full, else `edge` values at each end plus `interior`."""
    c = np.asarray(c, dtype=float)
    n = len(c)
    dot = math.fsum(float(v) for v in WEIGHTS[:n] * c)
    mx = float(np.max(np.abs(c))) if n else 0.0
    if n <= full:
        idx = None
        vals = c
    else:
        e = edge
        inner = [e + (2 * k + 1) * (n - 2 * e) // (2 * interior) for k in range(interior)]
        idx = sorted(set(list(range(e)) + inner + list(range(n - e, n))))
        vals = c[idx]
    # Summaries to 15 significant digits (far below the 1e-12 tolerance), values exact.
    return [n, float(f"{mx:.15g}"), float(f"{dot:.15g}"), idx, [float(v) for v in vals]]


def reconstructs(rec, x, coeffs, name):
    """PyWavelets' own perfect-reconstruction error, relative to the data's scale (max of |x| and
    |coefficients|). Its sym filters are orthonormal only to ~1e-11 (sym20), so its sym
    reconstructions are only that good; the others hold 1e-12 easily."""
    scale = max(float(np.max(np.abs(x))), max(float(np.max(np.abs(c))) for c in coeffs))
    err = float(np.max(np.abs(rec[:len(x)] - x))) / scale
    return err <= (1e-10 if name.startswith("sym") else 1e-12)


# Single-level cases: every n in 1..=40 in every mode with one wavelet in rotation, plus db20 and
# coif5 (F = 40, 30: the whole range is shorter than the filter) on a spread of n.
ROTATION = ["db20", "coif5", "coif17", "sym8", "haar", "db2", "sym5", "coif1", "db6", "sym20", "db10"]
SPREAD = [1, 2, 3, 4, 5, 6, 7, 8, 11, 16, 19, 20, 21, 29, 30, 31, 39, 40]


def dwt_cases():
    cases = []
    for n in range(1, 41):
        for mi, mode in enumerate(MODES):
            if mode == "reflect" and n == 1:
                continue  # PyWavelets: "Input data length must be greater than 1 for reflect"
            names = [ROTATION[(n + 3 * mi) % len(ROTATION)]]
            if n in SPREAD:
                names += [w for w in ("db20", "coif5") if w not in names]
            for name in names:
                w = pywt.Wavelet(name)
                x = signal(n)
                ca, cd = pywt.dwt(x, w, mode)
                rec = pywt.idwt(ca, cd, w, mode)
                assert reconstructs(rec, x, [ca, cd], name), (name, mode, n)
                cases.append([name, mode, n, [band(ca, 12, 1, 1), band(cd, 12, 1, 1)],
                              band(rec, 0, 0, 0)])
    return cases


MEDIUM = [100, 127, 255, 333, 512, 999, 1001, 1536, 2047, 3001, 64, 777]
LARGE = [4095, 4096, 6001, 8191, 10000, 12345, 16383, 18000, 19999, 20000, 15001]


def wavedec_cases():
    cases = []
    for wi, name in enumerate(WAVELETS):
        w = pywt.Wavelet(name)
        f = w.dec_len
        for mi, mode in enumerate(MODES):
            r = wi * 7 + mi
            # Level 1 only, level 2, a medium length, and (every third combination, to keep the
            # fixture small) a long one.
            lengths = [2 * (f - 1) + r % 3, 4 * (f - 1) + 1 + r % 4,
                       max(MEDIUM[r % len(MEDIUM)], 3 * f + r % 2)]
            if r % 3 == 0:
                lengths.append(LARGE[(r // 3) % len(LARGE)])
            if name == "db6" and mode == "symmetric":
                lengths.append(18000)  # the worked example
            for n in sorted(set(lengths)):  # level 1, level 2, deeper
                x = signal(n)
                top = pywt.dwt_max_level(n, f)
                assert top >= 1, (name, n)
                coeffs = pywt.wavedec(x, w, mode, level=top)
                approx = []
                for lev in range(1, top):
                    cl = pywt.wavedec(x, w, mode, level=lev)
                    # The detail bands of a shallower decomposition are the deepest one's tail.
                    for a, b in zip(cl[1:], coeffs[len(coeffs) - lev:]):
                        assert np.array_equal(a, b)
                    approx.append(band(cl[0], 0, 0, 0))
                rec = pywt.waverec(coeffs, w, mode)
                assert reconstructs(rec, x, coeffs, name), (name, mode, n)
                # Small decompositions whole (so waverec can run on PyWavelets' own coefficients).
                full = 4 if sum(len(c) for c in coeffs) > 64 else 64
                cases.append([name, mode, n, [band(c, full, 1, 1) for c in coeffs], approx,
                              band(rec, 4, 1, 1)])
    return cases


def main():
    root = pathlib.Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "pywt"
    root.mkdir(parents=True, exist_ok=True)
    meta = {"generator": "scripts/gen_pywt_fixtures.py", "pywavelets": "1.9.0",
            "band": "[len, max_abs, dot, idx (null = all), val]",
            "dwt_case": "[wavelet, mode, n, [cA, cD], idwt(cA, cD)]",
            "wavedec_case": "[wavelet, mode, n, bands at max level, [cA_1 .. cA_(max-1)], waverec]"}
    for fname, cases in [("dwt.json", dwt_cases()), ("wavedec.json", wavedec_cases())]:
        doc = dict(meta, cases=cases)
        path = root / fname
        path.write_text(json.dumps(doc, separators=(",", ":")) + "\n")
        print(f"wrote {path}: {len(cases)} cases, {path.stat().st_size / 1024:.0f} KB")


if __name__ == "__main__":
    main()
