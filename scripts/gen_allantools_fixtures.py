#!/usr/bin/env python3
"""Write tests/fixtures/allantools/*.json: allantools 2024.6 results that tests/allan_vs_allantools.rs
must reproduce to 1e-9 relative.

No input data is stored: every data set is generated here and in the Rust test bit for bit
(the NBS14 sets of Riley's handbook; splitmix64 with value = (u >> 11) * 2**-53 for the others,
combined with plain Python float arithmetic in a fixed order).

Pinned peer: allantools==2024.6   (pip install allantools==2024.6 numpy scipy;
                                   python3 scripts/gen_allantools_fixtures.py)
"""
import importlib.metadata
import json
import pathlib

import numpy as np
import allantools
from allantools import ci as at_ci

from splitmix import splitmix64  # scripts/splitmix.py

assert importlib.metadata.version("allantools") == "2024.6", importlib.metadata.version("allantools")

OUT = pathlib.Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "allantools"


def take(gen, n):
    return [next(gen) for _ in range(n)]


def nbs14_1000():
    """Riley's 1000-point test set: n(i) = 16807 n(i-1) mod (2^31 - 1), n(0) = 1234567890."""
    n = [1234567890]
    for _ in range(999):
        n.append((16807 * n[-1]) % 2147483647)
    assert n[1] == 395529916 and n[2] == 1209410747 and n[3] == 633705974
    return [v / 2147483647.0 for v in n]


NBS14 = [892.0, 809.0, 823.0, 798.0, 671.0, 644.0, 883.0, 903.0, 677.0]


def white(seed, n):
    return [u - 0.5 for u in take(splitmix64(seed), n)]


def random_walk(seed, n):
    s, out = 0.0, []
    for u in take(splitmix64(seed), n):
        s += u - 0.5
        out.append(s)
    return out


def gyro_like(seed, n):
    """white + 0.01 * random walk + 1e-4 * k + 3 (a bias)"""
    g = splitmix64(seed)
    rw, out = 0.0, []
    for k in range(n):
        a = next(g)
        b = next(g)
        rw += b - 0.5
        out.append(((a - 0.5) * 2.0 + rw * 0.01) + (1e-4 * k + 3.0))
    return out


DATASETS = {
    "nbs14": (NBS14, 1.0),
    "nbs14_1000": (nbs14_1000(), 1.0),
    "white_4096": (white(1, 4096), 1.0),
    "random_walk_3000": (random_walk(2, 3000), 10.0),
    "gyro_like_20000": (gyro_like(3, 20000), 100.0),
}
FUNCS = {"oadev": allantools.oadev, "adev": allantools.adev, "mdev": allantools.mdev,
         "hdev": allantools.ohdev}
GRIDS = {"octave": "octave", "decade": "decade", "list": [0.5, 1.0, 3.0, 7.0, 20.0, 55.0, 100.0]}


def deviations():
    cases = []
    for name, (data, rate) in DATASETS.items():
        grids = dict(GRIDS)
        if len(data) <= 1000:
            grids["all"] = "all"
        for kind, func in FUNCS.items():
            for gname, taus in grids.items():
                if gname == "all" and kind != "oadev" and len(data) > 10:
                    continue
                t = taus if isinstance(taus, str) else [x / rate * 10 for x in taus]
                try:
                    tau, dev, _err, ns = func(np.array(data), rate=rate, data_type="freq", taus=t)
                except UserWarning:
                    continue
                cases.append({
                    "data": name, "rate": rate, "kind": kind, "grid": gname,
                    "taus_in": None if isinstance(t, str) else t,
                    "tau": [float(v) for v in tau], "dev": [float(v) for v in dev],
                    "n": [int(v) for v in ns],
                })
    return cases


def edfs():
    rows = []
    combos = [("oadev", 2, True, False), ("adev", 2, False, False), ("mdev", 2, True, True),
              ("hdev", 3, True, False)]
    for kind, d, ov, mod in combos:
        alphas = [2, 1, 0, -1, -2] + ([-3, -4] if d == 3 else [])
        for alpha in alphas:
            for n in [10, 1001, 100001, 1000001]:
                for m in [1, 2, 3, 7, 16, 33, 50, 100, 512, 3000, 40000]:
                    if m * 4 > n:
                        continue
                    try:
                        e = at_ci.edf_greenhall(alpha=alpha, d=d, m=m, N=n, overlapping=ov,
                                                modified=mod)
                    except (NotImplementedError, AssertionError):
                        continue
                    rows.append({"kind": kind, "alpha": alpha, "d": d, "m": m, "n": n,
                                 "overlapping": ov, "modified": mod, "edf": float(e)})
    return rows


def intervals():
    rows = []
    for edf in [0.7, 1.0, 2.5, 10.0, 123.4, 1e4, 1e6]:
        for ci in [at_ci.ONE_SIGMA_CI, 0.9, 0.95, 0.99]:
            lo, hi = at_ci.confidence_interval(dev=2.0, edf=edf, ci=ci)
            rows.append({"edf": edf, "ci": float(ci), "dev": 2.0, "lo": float(lo), "hi": float(hi)})
    return rows


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    meta = {"allantools": importlib.metadata.version("allantools"),
            "numpy": importlib.metadata.version("numpy"),
            "scipy": importlib.metadata.version("scipy")}
    for fname, rows in [("deviations.json", deviations()), ("edf.json", edfs()),
                        ("intervals.json", intervals())]:
        (OUT / fname).write_text(json.dumps({"generator": meta, "cases": rows}, separators=(",", ":")) + "\n")
        print(fname, len(rows))


if __name__ == "__main__":
    main()
