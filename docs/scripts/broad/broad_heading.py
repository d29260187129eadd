"""Heading and total error on BROAD's real motion: our pipeline's corrected gyro, integrated,
against ZARU with the true rests (docs/navigation.md, "Real motion: BROAD").

BROAD (Laidig, Caruso, Cereatti, Seel 2021, CC BY 4.0) is fetched, never stored here:

    git clone https://github.com/dlaidig/broad /path/to/broad     # data_hdf5/, data_mat/
    python3 -m venv target/broad && target/broad/bin/pip install -r docs/scripts/broad/requirements.txt
    cargo build --release --example broad_rates
    DRIFTLESS_BROAD=/path/to/broad target/broad/bin/python docs/scripts/broad/broad_heading.py

What it does, per undisturbed trial 01-18 that the copy holds (`data_hdf5/NN_*.hdf5`, else
`data_mat/NN_*.mat`, the same data):

1. The unit's noise terms, once for every trial: `driftless allan --stage` on the trials' first
   rests (before the first `movement` sample), concatenated: the gyro's and, with
   `--accel-column`, the accelerometer's. That is a still record of the unit, as a user would
   take one; no motion is used.
2. `target/release/examples/broad_rates` runs the pipeline's stages offline (`denoise.wavelet
   -> predict.bias`, the terms above) on the IMU's real gyro. It runs them twice: gyro only (no
   accelerometer in the samples), and gyro+accel (the IMU's real accelerometer in every sample).
   It also writes ZARU with the true rests: the bias is each true rest's mean (the dataset's
   `movement` flags; `driftless::nav::Zaru::oracle`, 1 s minimum), held while moving.
3. Each method's corrected rate is integrated from the first sample with a valid truth. The
   orientation starts there from the optical truth (q <- q (x) exp(w dt / 2), body rates). Our
   outputs are taken from the first sample: the start is judged too.
4. The authors' own metrics (their `example_code/broad_utils.py`, loaded from the clone):
   heading and total error of q_est (x) q_ref^-1, RMS over the movement samples.

Prints one table (per trial: each method's heading and total RMSE, our ratios to ZARU) and the
median and worst ratios; `--json FILE` writes the same numbers.
"""

import argparse
import glob
import importlib.util
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", ".."))
METHODS = [("zaru", "ZARU, true rests"), ("gyro", "ours, gyro only"), ("imu", "ours, gyro+accel")]


def load_trial(broad, number):
    """(name, dict of arrays) of trial `number`, from its HDF5 file or else its MAT file."""
    for path in sorted(glob.glob(os.path.join(broad, "data_hdf5", f"{number:02d}_*.hdf5"))):
        import h5py

        with h5py.File(path, "r") as f:
            d = {k: f[k][()] for k in ("imu_gyr", "imu_acc", "opt_quat", "movement")}
            d["rate"] = float(f.attrs["sampling_rate"])
        return os.path.basename(path)[:-5], d
    for path in sorted(glob.glob(os.path.join(broad, "data_mat", f"{number:02d}_*.mat"))):
        import scipy.io as spio

        m = spio.loadmat(path, squeeze_me=True)
        d = {k: np.asarray(m[k]) for k in ("imu_gyr", "imu_acc", "opt_quat", "movement")}
        d["rate"] = float(m["sampling_rate"])
        return os.path.basename(path)[:-4], d
    return None, None


def parse_trials(text):
    """'1-18,24,30-36' -> [1, ..., 18, 24, 30, ..., 36]."""
    numbers = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        numbers.extend(range(int(lo), int(hi or lo) + 1))
    return numbers


def load_broad_utils(broad):
    """The authors' `example_code/broad_utils.py` from the clone, as a module."""
    spec = importlib.util.spec_from_file_location("broad_utils", os.path.join(broad, "example_code", "broad_utils.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def first_rest(d):
    """The trial's rest before its first movement sample: gyro (deg/s) and accelerometer (m/s²)."""
    moving = np.asarray(d["movement"], bool)
    k = int(np.argmax(moving))
    return np.column_stack([np.degrees(d["imu_gyr"][:k]), d["imu_acc"][:k]])


KEYS = ("arw", "bias_instability", "rrw", "quantization", "lsb", "accel_vrw", "accel_bias_instability")


def stage_keys(driftless, rests, rate, work, shift=False):
    """`driftless allan --stage` on the concatenated rests: its predict.bias keys, the gyro's
    and the accelerometer's. With `shift`, each rest is moved to the rests' common mean first,
    so the steps between power-ups do not read as in-run drift (docs/navigation.md, "The terms
    from rests of several power-ups")."""
    if shift:
        common = np.mean([r.mean(axis=0) for r in rests], axis=0)
        rests = [r - r.mean(axis=0) + common for r in rests]
    path = os.path.join(work, "rests.csv")
    np.savetxt(path, np.concatenate(rests), delimiter=",", header="x,y,z,ax,ay,az", comments="", fmt="%.10g")
    accel = [a for c in ("ax", "ay", "az") for a in ("--accel-column", c)]
    run = subprocess.run(
        [driftless, "allan", path, "--rate", repr(rate), "--units", "deg/s", *accel, "--stage"],
        capture_output=True, text=True,
    )
    if run.returncode != 0:
        sys.exit(f"the unit's terms from {len(rests)} first rests: {run.stderr.strip()}")
    out = run.stdout
    keys = [l for l in out.splitlines() if l.split(" = ")[0] in KEYS]
    comments = [l for l in out.splitlines() if l.startswith("#")]
    return "\n".join(keys), comments


PIPELINE = """name = "broad"
rate_hz = {rate!r}
axes = 3
input_units = "deg/s"

[[stage]]
name = "sensor"
kind = "ingest.sim"
output = "broad/raw"

[[stage]]
name = "denoise"
kind = "denoise.wavelet"
input = "broad/raw"
output = "broad/denoised"

[[stage]]
name = "predict"
kind = "predict.bias"
input = "broad/denoised"
output = "broad/predicted"
{keys}

[[stage]]
name = "publish"
kind = "publish"
input = "broad/predicted"
output = "broad/corrected"
"""


def quat_mult(a, b):
    return np.array([
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ])


def integrate(rate_rad, q_ref, dt):
    """Orientation from the body rates, starting at the first valid truth sample (NaN before)."""
    n = len(rate_rad)
    valid = np.all(np.isfinite(q_ref), axis=1)
    k0 = int(np.argmax(valid))
    q = np.full((n, 4), np.nan)
    cur = q_ref[k0] / np.linalg.norm(q_ref[k0])
    for k in range(k0, n):
        q[k] = cur
        w = rate_rad[k]
        angle = np.linalg.norm(w) * dt
        if angle > 0:
            axis = w / np.linalg.norm(w)
            cur = quat_mult(cur, np.concatenate(([np.cos(angle / 2)], np.sin(angle / 2) * axis)))
            cur /= np.linalg.norm(cur)
    return q


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("broad", nargs="?", default=os.environ.get("DRIFTLESS_BROAD"),
                    help="a clone of github.com/dlaidig/broad (default: $DRIFTLESS_BROAD)")
    ap.add_argument("--trials", default="1-18", help="trial numbers, e.g. 1-18 or 2,3,5")
    ap.add_argument("--target", default=os.path.join(REPO, "target", "release"),
                    help="where driftless and examples/broad_rates are built")
    ap.add_argument("--json", help="write the numbers to this file")
    ap.add_argument("--shift-rests", action="store_true",
                    help="move each first rest to the rests' common mean before taking the terms")
    args = ap.parse_args()
    if not args.broad:
        sys.exit("give the BROAD clone's path, or set DRIFTLESS_BROAD")
    numbers = parse_trials(args.trials)
    broad_utils = load_broad_utils(args.broad)

    driftless = os.path.join(args.target, "driftless")
    example = os.path.join(args.target, "examples", "broad_rates")
    for exe in (driftless, example):
        if not os.path.exists(exe):
            sys.exit(f"{exe} is missing: cargo build --release --example broad_rates")

    trials = []
    for n in numbers:
        name, d = load_trial(args.broad, n)
        if name is None:
            print(f"trial {n:02d}: not in this copy, skipped", file=sys.stderr)
            continue
        trials.append((name, d))
    rates = {d["rate"] for _, d in trials}
    assert len(rates) == 1, rates
    rate = rates.pop()

    results = []
    with tempfile.TemporaryDirectory(prefix="broad-") as work:
        keys, comments = stage_keys(driftless, [first_rest(d) for _, d in trials], rate, work, args.shift_rests)
        pipeline = os.path.join(work, "broad.toml")
        with open(pipeline, "w") as f:
            f.write(PIPELINE.format(rate=rate, keys=keys))
        for name, d in trials:
            moving = np.asarray(d["movement"], bool)
            table = np.column_stack([np.degrees(d["imu_gyr"]), d["imu_acc"], (~moving).astype(float)])
            src, dst = os.path.join(work, "in.csv"), os.path.join(work, "out.csv")
            np.savetxt(src, table, delimiter=",", header="gx,gy,gz,ax,ay,az,still", comments="", fmt="%.17g")
            subprocess.run([example, pipeline, src, dst], check=True)
            out = np.genfromtxt(dst, delimiter=",", names=True)
            row = {"trial": name}
            for key, _ in METHODS:
                w = np.radians(np.column_stack([out[f"{key}_{a}"] for a in "xyz"]))
                q = integrate(w, d["opt_quat"], 1.0 / rate)
                # The authors' metrics (NaN before the first valid truth: left out, as lost markers are).
                e = broad_utils.calculateRMSE(q, d["opt_quat"], moving)
                row[key] = {"heading": float(e["heading_rmse_deg"]), "total": float(e["total_rmse_deg"])}
            results.append(row)

    print(f"BROAD undisturbed trials, {len(results)} present; terms from the first rests:")
    for c in comments:
        if c.startswith("#   ") and not c.startswith("#     "):
            print("  " + c)
    print()
    head = "| trial | " + " | ".join(f"{label} heading / total (deg)" for _, label in METHODS)
    print(head + " | gyro-only / ZARU heading | gyro+accel / ZARU heading | gyro-only / ZARU total | gyro+accel / ZARU total |")
    print("|---" * (2 + len(METHODS) + 3) + "|")
    ratios = {k: {"heading": [], "total": []} for k in ("gyro", "imu")}
    for r in results:
        cells = [f"{r[k]['heading']:.2f} / {r[k]['total']:.2f}" for k, _ in METHODS]
        rs = []
        for metric in ("heading", "total"):
            for k in ("gyro", "imu"):
                x = r[k][metric] / r["zaru"][metric]
                ratios[k][metric].append(x)
                rs.append(f"{x:.3f}")
        print(f"| {r['trial']} | " + " | ".join(cells) + " | " + " | ".join(rs) + " |")
    print()
    summary = {}
    for k, label in METHODS[1:]:
        for metric in ("heading", "total"):
            x = np.array(ratios[k][metric])
            summary[f"{k}_{metric}"] = {"median": float(np.median(x)), "worst": float(np.max(x))}
            print(f"{label}, {metric}: median {np.median(x):.3f}x, worst {np.max(x):.3f}x ZARU with the true rests")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"rate_hz": rate, "terms": comments, "trials": results, "summary": summary}, f, indent=1)


if __name__ == "__main__":
    main()
