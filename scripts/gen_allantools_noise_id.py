#!/usr/bin/env python3
"""Write tests/fixtures/allantools/noise_id.json: allantools 2024.6's own noise identification
(`ci.autocorr_noise_id`, lag-1 autocorrelation, on the phase decimated by the averaging factor),
Greenhall EDF and 68.3% interval at every octave tau of two records, for
tests/allan_vs_allantools.rs (issue 14: what allantools does at the longest taus).

allantools refuses to identify the noise (NotImplementedError) where the decimated series has
fewer than 30 points, i.e. at the taus with fewer than about 30 tau-spans; those points are
written with "alpha": null and the reason, and driftless must flag them as not identified.

The data sets are splitmix64 white noise and its running sum, generated bit for bit in the Rust
test as in scripts/gen_allantools_fixtures.py (whose generators this imports).

Pinned peer: allantools==2024.6   (pip install allantools==2024.6 numpy scipy;
                                   python3 scripts/gen_allantools_noise_id.py)
"""
import contextlib
import importlib.metadata
import io
import json
import sys
import pathlib

import numpy as np
import allantools
from allantools import ci as at_ci

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from gen_allantools_fixtures import OUT, random_walk, white  # noqa: E402

assert importlib.metadata.version("allantools") == "2024.6", importlib.metadata.version("allantools")

DATASETS = {
    "white_32768": (white(11, 32768), 1.0),
    "random_walk_32768": (random_walk(12, 32768), 1.0),
}


def curve(y, rate):
    y = np.array(y)
    phase = allantools.frequency2phase(y, rate)
    taus, devs, _err, ns = allantools.oadev(y, rate=rate, data_type="freq", taus="octave")
    rows = []
    for tau, dev, n in zip(taus, devs, ns):
        af = int(round(tau * rate))
        row = {"tau": float(tau), "m": af, "dev": float(dev), "n": int(n)}
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                alpha = at_ci.autocorr_noise_id(phase, af, data_type="phase", dmin=0, dmax=2)[0]
        except NotImplementedError:
            row.update({"alpha": None, "refused": "autocorr_noise_id: fewer than 30 decimated points"})
            rows.append(row)
            continue
        edf = at_ci.edf_greenhall(alpha=int(alpha), d=2, m=af, N=len(phase), overlapping=True,
                                  modified=False)
        lo, hi = at_ci.confidence_interval(dev=dev, edf=edf, ci=at_ci.ONE_SIGMA_CI)
        row.update({"alpha": int(alpha), "edf": float(edf), "lo": float(lo), "hi": float(hi)})
        rows.append(row)
    return {"phase_len": len(phase), "points": rows}


def main():
    meta = {"allantools": importlib.metadata.version("allantools"),
            "numpy": importlib.metadata.version("numpy"),
            "scipy": importlib.metadata.version("scipy")}
    cases = [{"data": name, "rate": rate, **curve(y, rate)} for name, (y, rate) in DATASETS.items()]
    (OUT / "noise_id.json").write_text(json.dumps({"generator": meta, "cases": cases},
                                                  separators=(",", ":")) + "\n")
    for c in cases:
        print(c["data"], [(p["m"], p["alpha"]) for p in c["points"]])


if __name__ == "__main__":
    main()
