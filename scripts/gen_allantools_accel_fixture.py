#!/usr/bin/env python3
"""Write tests/fixtures/allantools/accel_6axis.json: allantools 2024.6 on the three accelerometer
columns of the real ADIS16405 6-axis static log (in g, as recorded), for
tests/allan_accel_real_log.rs (issue 49: `driftless allan --accel-column`).

Per axis and octave tau: `oadev` (data_type="freq", rate=100), its n, and allantools' own noise
identification (`ci.autocorr_noise_id` on the phase decimated by the averaging factor), Greenhall
EDF and 68.3% interval where it identifies one (it refuses with fewer than 30 decimated points).
Also each column's mean, so the test knows it read the same numbers.

The log is never copied into the repository: its path comes from DRIFTLESS_ADIS16405_6AXIS (or
the first argument), e.g. ../shared/data/adis16405-imu1-static-100hz-6axis.csv.gz.

Pinned peer: allantools==2024.6   (pip install allantools==2024.6 numpy scipy;
                                   python3 scripts/gen_allantools_accel_fixture.py [LOG])
"""
import contextlib
import importlib.metadata
import io
import json
import os
import pathlib
import sys

import numpy as np
import allantools
from allantools import ci as at_ci

assert importlib.metadata.version("allantools") == "2024.6", importlib.metadata.version("allantools")

OUT = pathlib.Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "allantools"
COLUMNS = ["accel_x_g", "accel_y_g", "accel_z_g"]
RATE = 100.0


def curve(y):
    phase = allantools.frequency2phase(y, RATE)
    taus, devs, _err, ns = allantools.oadev(y, rate=RATE, data_type="freq", taus="octave")
    rows = []
    for tau, dev, n in zip(taus, devs, ns):
        af = int(round(tau * RATE))
        row = {"tau": float(tau), "m": af, "dev": float(dev), "n": int(n)}
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                alpha = at_ci.autocorr_noise_id(phase, af, data_type="phase", dmin=0, dmax=2)[0]
        except NotImplementedError:
            row["alpha"] = None
            rows.append(row)
            continue
        edf = at_ci.edf_greenhall(alpha=int(alpha), d=2, m=af, N=len(phase), overlapping=True,
                                  modified=False)
        lo, hi = at_ci.confidence_interval(dev=dev, edf=edf, ci=at_ci.ONE_SIGMA_CI)
        row.update({"alpha": int(alpha), "edf": float(edf), "lo": float(lo), "hi": float(hi)})
        rows.append(row)
    return rows


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("DRIFTLESS_ADIS16405_6AXIS")
    if not path:
        sys.exit("give the 6-axis log: DRIFTLESS_ADIS16405_6AXIS=... or its path as argument")
    with open(path, "rb") as f:
        header = __import__("gzip").open(f).readline().decode().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, usecols=[header.index(c) for c in COLUMNS])
    meta = {"allantools": importlib.metadata.version("allantools"),
            "numpy": importlib.metadata.version("numpy"),
            "scipy": importlib.metadata.version("scipy"),
            "log": pathlib.Path(path).name, "rate": RATE, "unit": "g"}
    axes = []
    for k, name in enumerate(COLUMNS):
        y = np.ascontiguousarray(data[:, k])
        axes.append({"column": name, "samples": len(y), "mean": float(np.mean(y)),
                     "points": curve(y)})
        print(name, len(y), [(p["m"], p["alpha"]) for p in axes[-1]["points"]])
    (OUT / "accel_6axis.json").write_text(json.dumps({"generator": meta, "axes": axes},
                                                     separators=(",", ":")) + "\n")


if __name__ == "__main__":
    main()
