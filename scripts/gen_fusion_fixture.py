#!/usr/bin/env python3
"""Write tests/fixtures/fusion/*.csv: x-io Fusion's gyroscope bias algorithm (imufusion.Bias,
default settings) on reproducible three-axis rates, for tests/fusion_vs_imufusion.rs.

Rerun (from the repository root; `cargo test` itself never needs Python):

    pip install imufusion==1.3.3 numpy
    python3 scripts/gen_fusion_fixture.py

Pinned peer: imufusion==1.3.3 (checked below through the distribution metadata). The output is
deterministic.

Inputs are not stored: both sides make them bit-identically (splitmix64, the library's
`synthetic::SplitMix64`; the motion by + and * only). Each case (one file per sample rate)
stores imufusion's corrected rates and offset at every 50th sample and at the last, and the
in-order sum of every corrected rate per axis, so a wrong value anywhere shows. The signal: a
constant bias per axis and uniform noise, then motion that exercises every branch of the
algorithm: still periods longer and shorter than the stationary period, turns on one axis
above the 3 deg/s threshold (which stop the learning of every axis), and a slow triangular sway
below it (which the algorithm takes for bias).
"""

import csv
import importlib.metadata
import os

import imufusion
import numpy as np

from splitmix import splitmix64  # scripts/splitmix.py

VERSION = "1.3.3"
assert importlib.metadata.version("imufusion") == VERSION, "pin imufusion==" + VERSION

HERE = os.path.join(os.path.dirname(__file__), "..", "tests", "fixtures", "fusion")


def signal(rate, seconds, seed):
    """Sample k, axis a: bias[a] + 0.6 (u - 0.5) + motion; u drawn k-major, then by axis."""
    u = splitmix64(seed)
    bias = [0.4, -0.3, 0.2]
    rows = []
    for k in range(int(rate * seconds)):
        t = k / rate
        row = [bias[a] + 0.6 * (next(u) - 0.5) for a in range(3)]
        # 0-20 s still; 20-25 s a 20 deg/s turn on z; 25-27 s still (shorter than the period);
        # 27-30 s a 10 deg/s turn on x; 30-60 s still; 60-75 s a triangular sway of 1 deg/s
        # on y (below the threshold); 75-90 s still.
        if 20.0 <= t < 25.0:
            row[2] += 20.0
        if 27.0 <= t < 30.0:
            row[0] += 10.0
        if 60.0 <= t < 75.0:
            phase = (t - 60.0) * 0.2
            phase -= int(phase)
            row[1] += 4.0 * abs(phase - 0.5) - 1.0
        rows.append(row)
    return rows


def write(rate, seconds, seed):
    bias = imufusion.Bias()
    settings = imufusion.BiasSettings()
    settings.sample_rate = float(rate)
    bias.set_settings(settings)
    rows = signal(rate, seconds, seed)
    sums = [0.0, 0.0, 0.0]
    path = os.path.join(HERE, f"bias_{rate}hz.csv")
    with open(path, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["k", "out_x", "out_y", "out_z", "offset_x", "offset_y", "offset_z"])
        for k, row in enumerate(rows):
            out = [float(v) for v in bias.update(np.array(row, dtype=float))]
            for a in range(3):
                sums[a] += out[a]
            if k % 50 == 0 or k == len(rows) - 1:
                off = [float(v) for v in bias.get_offset()]
                w.writerow([k] + [repr(v) for v in out + off])
        w.writerow(["sum"] + [repr(v) for v in sums] + ["", "", ""])
    print("wrote", path, len(rows), "samples, sums", sums)


if __name__ == "__main__":
    os.makedirs(HERE, exist_ok=True)
    assert imufusion.BiasSettings().stationary_threshold == 3.0
    assert imufusion.BiasSettings().stationary_period == 3.0
    write(100, 90, 100)
    write(1000, 90, 1000)
