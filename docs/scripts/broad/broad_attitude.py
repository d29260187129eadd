"""Orientation from gyro + accelerometer on BROAD's real motion: the peers a navigator would pick
(VQF 6D, Madgwick, Mahony, x-io Fusion), judged with the authors' error metrics (issue 50;
docs/navigation.md, "Real motion: BROAD").

BROAD (Laidig, Caruso, Cereatti, Seel 2021, CC BY 4.0) is fetched, never stored here:

    git clone https://github.com/dlaidig/broad /path/to/broad     # data_hdf5/, data_mat/
    python3 -m venv target/broad && target/broad/bin/pip install -r docs/scripts/broad/requirements-attitude.txt
    DRIFTLESS_BROAD=/path/to/broad target/broad/bin/python docs/scripts/broad/broad_attitude.py --json target/broad-attitude.json

What it does, per trial that the copy holds (`data_hdf5/NN_*.hdf5`, else `data_mat/NN_*.mat`, the
same data; all of 01-39 by default, `--trials 1-18` for the undisturbed development set):

1. Each method runs on the IMU's real gyro (rad/s) and accelerometer (m/s²) at the trial's rate,
   from the first sample, with its package defaults:
   - `vqf`: VQF 6D, `VQF(Ts).updateBatch(gyr, acc)["quat6D"]` (rest detection and motion bias
     estimation on, as they are by default).
   - `vqf9`: VQF 9D, `VQF(Ts).updateBatch(gyr, acc, mag)["quat9D"]` at its defaults (magnetic
     disturbance rejection on), the trial's magnetometer; judged absolute (no alignment).
   - `madgwick`: `ahrs.filters.Madgwick` with gain 0.1, imu_tools' imu_filter_madgwick default
     (`gain: 0.1`; ahrs' own default is 0.033). Starts from the first accelerometer sample, as
     imu_filter_madgwick does.
   - `mahony`: `ahrs.filters.Mahony` at ahrs' defaults, k_P = 1.0 and k_I = 0.3 (imu_tools has
     no Mahony filter, so ahrs' defaults stand in).
   - `fusion`: x-io Fusion's `imufusion.Ahrs` with `AhrsSettings(sample_rate=rate)` and every
     other setting at its default (gain 0.5, no rejection, 3 s start-up), gyro in deg/s and
     accelerometer in g as its API wants, `update_no_magnetometer`. Its NWU earth frame is turned
     to ENU (a 90 deg turn about up). `fusion_bias`: the same behind Fusion's gyro `Bias` at its
     defaults (stationary under 3 deg/s for 3 s, then a 0.02 Hz high-pass), as x-io's own
     examples chain them: Fusion's AHRS alone corrects no gyro bias.
   - `gyro_raw`: the raw gyro integrated, a sanity baseline, and `gyro_zaru`: the gyro less the
     bias of ZARU with the true rests (each rest's running mean, 1 s minimum, held while moving;
     `driftless::nav::Zaru::oracle`). Both start from the optical truth at its first valid sample
     (q <- q (x) exp(w dt / 2)).
   - With `--example PATH` (repeatable), ours: see `ours()`. With `--mag` too, our chain again
     with `use_mag = true` and the trial's magnetometer (tesla) in every sample (`ours9_imu`,
     `ours9_stop`), judged absolute, and a 9D table at the end: per trial our 9D heading /
     inclination against our 6D's (aligned at the start) and VQF 9D's, the 9D heading's 2-sd
     coverage, the medians and issue 61's goals (docs/attitude.md, "The magnetometer (9D)").
   Every quaternion is scalar first, IMU body to an earth frame with z up.
2. A 6D estimate's heading is relative, so it is aligned to the truth at the first sample with a
   valid truth, as a navigator would initialise it: the estimate is turned about the earth's
   vertical by the heading part of q_est (x) q_ref^-1 there. (The integrations start from the
   truth, so this changes nothing for them.) The authors' own example (their `process_data.py`)
   judges 9D filters with no alignment and `broad_utils.py` has no alignment helper; removing
   the mean heading offset over the motion instead is printed beside, for comparison.
3. The authors' metrics (`example_code/broad_utils.py`, loaded from the clone): total, heading and
   inclination error of q_est (x) q_ref^-1 in the earth frame, RMS over the movement samples (a
   sample whose truth is lost is left out).

Prints one table per trial (method x total / heading / inclination RMS, deg; "dev" marks the
undisturbed trials 01-18) and the medians over the dev trials and over all trials; `--json FILE`
writes the same numbers. The stored copy holds 30 trials (22 in data_hdf5, 8 more only in
data_mat); `--hdf5-only` keeps the 22, the set of the medians in the team's notes (VQF 6D: total
2.84, heading 2.81, inclination 0.55 deg). Every peer's median inclination stays under 5 deg,
the check that its frame convention is read right. About 3.5 min for the 30 trials on 2 cores
(ahrs' Madgwick and Mahony are per-sample Python loops; VQF and Fusion take seconds).
"""

import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from broad_heading import PIPELINE, REPO, first_rest, integrate, load_broad_utils, load_trial, parse_trials, stage_keys  # noqa: E402  (the same loading, terms and integration)

# broad_heading.py's chain with the attitude stage after the bias filter: what we publish.
ATTITUDE_PIPELINE = PIPELINE.replace('''input = "broad/predicted"
output = "broad/corrected"''', '''input = "broad/attitude"
output = "broad/corrected"''').replace('''[[stage]]
name = "publish"''', '''[[stage]]
name = "attitude"
kind = "attitude.6d"
input = "broad/predicted"
output = "broad/attitude"

[[stage]]
name = "publish"''')
assert "attitude.6d" in ATTITUDE_PIPELINE and 'input = "broad/attitude"' in ATTITUDE_PIPELINE

METRICS = ("total", "heading", "inclination")
PEERS = [
    ("vqf", "VQF 6D, defaults"),
    ("vqf9", "VQF 9D, defaults (absolute)"),
    ("madgwick", "Madgwick, gain 0.1 (imu_tools)"),
    ("mahony", "Mahony, Kp 1.0 Ki 0.3 (ahrs)"),
    ("fusion", "Fusion AHRS, defaults"),
    ("fusion_bias", "Fusion AHRS + Bias, defaults"),
    ("gyro_zaru", "gyro only, ZARU true rests"),
    ("gyro_raw", "gyro only, raw"),
]
ABSOLUTE = {"vqf9"}  # judged without alignment (with ours9_*)
DEV = range(1, 19)  # the undisturbed trials, the development set (the authors' split)
GRAVITY = 9.81  # Fusion's accelerometer is in g


def load_mag(broad, number):
    """The trial's magnetometer (uT, N x 3) from its HDF5 or MAT file."""
    for path in sorted(glob.glob(os.path.join(broad, "data_hdf5", f"{number:02d}_*.hdf5"))):
        import h5py

        with h5py.File(path, "r") as f:
            return np.asarray(f["imu_mag"][()], float)
    for path in sorted(glob.glob(os.path.join(broad, "data_mat", f"{number:02d}_*.mat"))):
        import scipy.io as spio

        return np.asarray(spio.loadmat(path, squeeze_me=True)["imu_mag"], float)
    return None


def source(broad, number):
    """Which copy load_trial read: "hdf5", or "mat" where the HDF5 blob is absent."""
    return "hdf5" if glob.glob(os.path.join(broad, "data_hdf5", f"{number:02d}_*.hdf5")) else "mat"


def cut_rest(d, seconds):
    """The trial cut to the last `seconds` of its first rest and its motion, every later rest
    dropped (the truth is still through a rest, so the motion on both sides of one joins)."""
    moving = np.asarray(d["movement"], bool)
    k = int(np.argmax(moving))
    keep = moving.copy()
    keep[max(0, k - int(round(seconds * d["rate"]))):k] = True
    return {**{key: np.asarray(d[key])[keep] for key in ("imu_gyr", "imu_acc", "opt_quat", "movement", "imu_mag")
               if d.get(key) is not None},
            "rate": d["rate"]}


def run_vqf(gyr, acc, rate):
    import vqf

    # updateBatch wants C-contiguous float64.
    out = vqf.VQF(1.0 / rate).updateBatch(np.ascontiguousarray(gyr, float), np.ascontiguousarray(acc, float))
    return out["quat6D"]


def run_vqf9(gyr, acc, mag, rate):
    """VQF 9D at its defaults (magnetic disturbance rejection on), the magnetometer as BROAD
    gives it (uT: VQF learns its own norm reference, so the unit does not matter)."""
    import vqf

    c = lambda a: np.ascontiguousarray(a, float)
    return vqf.VQF(1.0 / rate).updateBatch(c(gyr), c(acc), c(mag))["quat9D"]


def run_madgwick(gyr, acc, rate):
    from ahrs.filters import Madgwick

    return Madgwick(gyr=gyr, acc=acc, frequency=rate, gain=0.1).Q


def run_mahony(gyr, acc, rate):
    from ahrs.filters import Mahony

    return Mahony(gyr=gyr, acc=acc, frequency=rate).Q


def run_fusion(gyr, acc, rate, quatmult, with_bias=False):
    import imufusion

    ahrs = imufusion.Ahrs()
    # Only the sample rate is set: it is the data's, not a tuning choice (the default is 100 Hz).
    ahrs.set_settings(imufusion.AhrsSettings(sample_rate=rate))
    bias = imufusion.Bias()
    bias.set_settings(imufusion.BiasSettings(sample_rate=rate))
    gyr_deg = np.ascontiguousarray(np.degrees(gyr))
    acc_g = np.ascontiguousarray(acc / GRAVITY)
    q = np.empty((len(gyr), 4))
    for k in range(len(gyr)):
        # Fusion's AHRS corrects no gyro bias; its `Bias` (x-io's own examples put it in front)
        # does, while the gyro stays under 3 deg/s for 3 s.
        g = bias.update(gyr_deg[k]) if with_bias else gyr_deg[k]
        ahrs.update_no_magnetometer(g, acc_g[k])
        q[k] = ahrs.get_quaternion()
    # NWU -> ENU: east = -west, north = north, a +90 deg turn about up on the earth side.
    return quatmult(np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)]), q)


def zaru_bias(gyr, still, min_samples):
    """ZARU with the true rests, as `driftless::nav::Zaru::oracle`: in a rest, once it is
    `min_samples` long, the rest's running mean; after it, that rest's mean, held; 0 before the
    first."""
    bias = np.zeros_like(gyr)
    held = np.zeros(3)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], still.astype(np.int8), [0]))))
    pos = 0
    for a, b in zip(edges[::2], edges[1::2]):
        bias[pos:a] = held
        if b - a >= min_samples:
            mean = np.cumsum(gyr[a:b], axis=0) / np.arange(1, b - a + 1)[:, None]
            bias[a:a + min_samples - 1] = held
            bias[a + min_samples - 1:b] = mean[min_samples - 1:]
            held = mean[-1]
        else:
            bias[a:b] = held
        pos = b
    bias[pos:] = held
    return bias


def ours(name, d, pipeline, examples, work, mag=None, prefix="ours"):
    """Our orientations for one trial: {method name: quaternions (N x 4)}.

    Each `--example PATH` (`target/release/examples/broad_attitude`) runs as `PATH PIPELINE
    in.csv out.csv`. PIPELINE is our chain (`denoise.wavelet -> predict.bias -> attitude.6d`,
    reading a stop signal) with the unit's terms from the trials' first rests, as
    broad_heading.py takes them (ATTITUDE_PIPELINE).
    in.csv has a header and the columns gx,gy,gz (the IMU's gyro, deg/s), ax,ay,az (its
    accelerometer, m/s²) and still (1 where the dataset's `movement` is false: the rest flags,
    for the vehicle's stop signal). out.csv has a header and, per method M that the example
    writes, the columns M_qw,M_qx,M_qy,M_qz, one row per input sample: scalar first, IMU body to
    an earth frame with z up (the heading may be relative; it is aligned like the peers'), and
    optionally M_incl_sd and M_head_sd, the standard deviations it publishes for its
    inclination and its heading (rad). Per
    rate R it writes, the columns R_wx,R_wy,R_wz (rad/s): a corrected gyro, integrated here from
    the truth at its first valid sample (`ours_R_integrated`), what a navigator without an
    attitude stage gets from us.
    """
    moving = np.asarray(d["movement"], bool)
    src, dst = os.path.join(work, "in.csv"), os.path.join(work, "out.csv")
    table = np.column_stack([np.degrees(d["imu_gyr"]), d["imu_acc"], (~moving).astype(float)])
    header = "gx,gy,gz,ax,ay,az,still"
    if mag is not None:
        # The magnetometer, uT in BROAD, in tesla as the wire carries it.
        table = np.column_stack([table, np.asarray(mag, float) * 1e-6])
        header += ",mx,my,mz"
    np.savetxt(src, table, delimiter=",", header=header, comments="", fmt="%.17g")
    out, sds = {}, {}
    for path in examples:
        if os.path.exists(dst):
            os.remove(dst)
        run = subprocess.run([path, pipeline, src, dst], capture_output=True, text=True)
        if run.returncode != 0:
            sys.exit(f"{path} on {name}: exit {run.returncode}: {run.stderr.strip()}")
        cols = np.genfromtxt(dst, delimiter=",", names=True)
        for m in [c[:-3] for c in cols.dtype.names if c.endswith("_qw")]:
            q = np.column_stack([cols[f"{m}_{c}"] for c in ("qw", "qx", "qy", "qz")])
            if q.shape != (len(moving), 4):
                sys.exit(f"{path} on {name}: {q.shape[0]} rows out for {len(moving)} samples in")
            out[f"{prefix}_{m}"] = q
            if f"{m}_incl_sd" in cols.dtype.names:
                head = f"{m}_head_sd"
                sds[f"{prefix}_{m}"] = (np.asarray(cols[f"{m}_incl_sd"], float),
                                    np.asarray(cols[head], float) if head in cols.dtype.names else None)
        for m in [c[:-3] for c in cols.dtype.names if c.endswith("_wx")]:
            w = np.column_stack([cols[f"{m}_{c}"] for c in ("wx", "wy", "wz")])
            out[f"{prefix}_{m}_integrated"] = integrate(w, np.asarray(d["opt_quat"], float), 1.0 / d["rate"])
    return out, sds


def heading_part(q_err):
    """The rotation about the earth's vertical in an earth-frame error quaternion: (w, 0, 0, z),
    normalised. q_err = t (x) s with t this and s free of any z part, so t^-1 (x) q_err has no
    heading error (the authors' heading error is 2 atan(|z| / |w|))."""
    t = np.array([q_err[0], 0.0, 0.0, q_err[3]])
    return t / np.linalg.norm(t)


def align_first(q, q_ref, k0, bu):
    """The estimate turned about the earth's vertical so its heading matches the truth at k0."""
    t = heading_part(bu.calculateErrorQuatEarth(q[k0:k0 + 1], q_ref[k0:k0 + 1])[0])
    return bu.quatmult(bu.invquat(t), q)


def align_mean(q, q_ref, moving, bu):
    """The estimate turned about the earth's vertical by its mean heading offset over the motion
    (a circular mean), for comparison with the first-sample alignment."""
    e = bu.calculateErrorQuatEarth(q, q_ref)
    e *= np.where(e[:, :1] < 0, -1.0, 1.0)  # q and -q are one rotation
    psi = 2 * np.arctan2(e[:, 3], e[:, 0])
    psi = psi[moving & np.isfinite(psi)]
    mean = np.arctan2(np.mean(np.sin(psi)), np.mean(np.cos(psi)))
    t = np.array([np.cos(mean / 2), 0.0, 0.0, np.sin(mean / 2)])
    return bu.quatmult(bu.invquat(t), q)


def errors(q, q_ref, moving, bu):
    e = bu.calculateRMSE(q, q_ref, moving)
    return {m: float(e[f"{m}_rmse_deg"]) for m in METRICS}


def medians(results, methods, key, numbers):
    rows = [r for r in results if r["number"] in numbers]
    return {
        m: {metric: float(np.median([r[key][m][metric] for r in rows])) for metric in METRICS}
        for m in methods
    } if rows else {}


def nine_d_table(results):
    """Per trial: our 9D (absolute) against our 6D (aligned at the start) and VQF 9D: heading
    and inclination RMS, the 9D heading's 2-sd coverage; then the medians and the goals of
    issue 61. Returns the same numbers."""
    ours9, ours6 = "ours9_imu", "ours_imu"
    has_vqf9 = all("vqf9" in r["first"] for r in results)
    print("\n9D: heading / inclination RMS (deg), our 9D absolute, our 6D aligned at the start"
          + (", VQF 9D absolute" if has_vqf9 else "") + "; 9D - 6D heading; our 9D heading within 2 sd")
    print("| trial | ours 9D | ours 6D | 9D - 6D | " + ("VQF 9D | " if has_vqf9 else "") + "2-sd coverage |")
    print("|---|---|---|---|" + ("---|" if has_vqf9 else "") + "---|")
    rows = []
    for r in results:
        a, b = r["first"][ours9], r["first"][ours6]
        inside, total = r["coverage"].get(ours9 + " heading", [0, 0])
        v = r["first"].get("vqf9")
        row = {"number": r["number"], "ours9": a, "ours6": b, "vqf9": v,
               "diff": a["heading"] - b["heading"], "coverage": inside / max(total, 1), "nan": r["nan"][ours9]}
        rows.append(row)
        cells = [f"{a['heading']:.2f} / {a['inclination']:.2f}", f"{b['heading']:.2f} / {b['inclination']:.2f}",
                 f"{row['diff']:+.2f}"]
        if has_vqf9:
            cells.append(f"{v['heading']:.2f} / {v['inclination']:.2f}")
        cells.append(f"{row['coverage']:.3f}")
        print(f"| {r['number']:02d}{' (dev)' if r['dev'] else ''} | " + " | ".join(cells) + " |")
    med = lambda key, metric: float(np.median([x[key][metric] for x in rows]))
    cells = [f"{med('ours9', 'heading'):.2f} / {med('ours9', 'inclination'):.2f}",
             f"{med('ours6', 'heading'):.2f} / {med('ours6', 'inclination'):.2f}",
             f"{np.median([x['diff'] for x in rows]):+.2f}"]
    if has_vqf9:
        cells.append(f"{med('vqf9', 'heading'):.2f} / {med('vqf9', 'inclination'):.2f}")
    inside = sum(r["coverage"].get(ours9 + " heading", [0, 0])[0] for r in results)
    total = sum(r["coverage"].get(ours9 + " heading", [0, 0])[1] for r in results)
    cells.append(f"{inside / max(total, 1):.3f} (pooled)")
    print(f"| median ({len(rows)}) | " + " | ".join(cells) + " |")
    worst = max(rows, key=lambda x: x["diff"])
    goals = {
        "heading median <= VQF 9D's": has_vqf9 and med("ours9", "heading") <= med("vqf9", "heading"),
        "no trial's 9D heading > 6D's + 0.5 deg": worst["diff"] <= 0.5,
        "inclination median <= 6D's": med("ours9", "inclination") <= med("ours6", "inclination") + 1e-9,
        "heading 2-sd coverage 0.90-0.99 (pooled)": 0.90 <= inside / max(total, 1) <= 0.99,
        "no NaN": all(x["nan"] == 0 for x in rows),
    }
    print(f"worst 9D - 6D: trial {worst['number']:02d}, {worst['diff']:+.2f} deg")
    for goal, met in goals.items():
        print(f"  {'met   ' if met else 'MISSED'} {goal}")
    return {"trials": rows, "goals": goals}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("broad", nargs="?", default=os.environ.get("DRIFTLESS_BROAD"),
                    help="a clone of github.com/dlaidig/broad (default: $DRIFTLESS_BROAD)")
    ap.add_argument("--trials", default="1-39", help="trial numbers, e.g. 1-39, 1-18 or 2,3,5 (those absent are skipped)")
    ap.add_argument("--hdf5-only", action="store_true",
                    help="only the trials whose data_hdf5 file the copy holds (22 in the stored copy, "
                         "the set the medians in the notes were measured on)")
    ap.add_argument("--example", action="append", default=[], metavar="PATH",
                    help="our attitude example to run beside the peers (see ours()); repeatable")
    ap.add_argument("--target", default=os.path.join(REPO, "target", "release"),
                    help="where driftless is built (the unit's terms for --example)")
    ap.add_argument("--json", help="write the numbers to this file")
    ap.add_argument("--shift-rests", action="store_true",
                    help="move each first rest to the rests' common mean before taking the terms (broad_heading.py)")
    ap.add_argument("--cut-rest", type=float, metavar="S",
                    help="cut each trial to the last S seconds of its first rest and its motion, every "
                         "later rest dropped: a short start-up rest, then motion with no rest (issue 59)")
    ap.add_argument("--shipped", action="store_true",
                    help="judge pipelines/navigator-attitude.toml's chain (no denoiser, the ADIS16405's "
                         "terms, no stop signal) at each trial's rate, instead of the chain with BROAD's "
                         "own terms")
    ap.add_argument("--peers", default=",".join(m for m, _ in PEERS),
                    help="the peers to run, comma-separated (default: all; vqf,gyro_raw is quick)")
    ap.add_argument("--attitude-key", action="append", default=[], metavar="KEY=VALUE",
                    help="a key of the attitude.6d stage (TOML), e.g. vqf_bias='\"rest\"'; repeatable")
    ap.add_argument("--mag", action="store_true",
                    help="also run our chain with the magnetometer (use_mag = true, the trial's field in "
                         "every sample: ours9_imu, ours9_stop), judged absolute, and print the 9D table: "
                         "ours 9D, ours 6D aligned at the start, VQF 9D (add vqf9 to --peers)")
    args = ap.parse_args()
    if not args.broad:
        sys.exit("give the BROAD clone's path, or set DRIFTLESS_BROAD")
    for path in args.example:
        if not os.access(path, os.X_OK):
            sys.exit(f"{path} is not an executable")

    bu = load_broad_utils(args.broad)

    runners = {
        "vqf": run_vqf,
        "madgwick": run_madgwick,
        "mahony": run_mahony,
        "fusion": lambda g, a, r: run_fusion(g, a, r, bu.quatmult),
        "fusion_bias": lambda g, a, r: run_fusion(g, a, r, bu.quatmult, with_bias=True),
        "vqf9": None,  # needs the magnetometer: run in the loop
    }
    labels = dict(PEERS)
    methods = [m for m, _ in PEERS if m in args.peers.split(",")]
    runners = {m: run for m, run in runners.items() if m in methods}
    seconds = {m: 0.0 for m in methods}
    results = []
    start = time.time()
    with tempfile.TemporaryDirectory(prefix="broad-attitude-") as work:
        trials = []
        for n in parse_trials(args.trials):
            name, d = load_trial(args.broad, n)
            if name is not None and args.hdf5_only and source(args.broad, n) != "hdf5":
                print(f"trial {n:02d}: no HDF5 file, skipped (--hdf5-only)", file=sys.stderr)
                continue
            if name is None:
                print(f"trial {n:02d}: not in this copy, skipped", file=sys.stderr)
                continue
            d = {**d, "imu_mag": load_mag(args.broad, n)}
            trials.append((n, name, cut_rest(d, args.cut_rest) if args.cut_rest is not None else d))
        pipeline = None
        if args.example and trials and args.shipped:
            pipeline = os.path.join(work, "navigator-attitude.toml")
            with open(os.path.join(REPO, "pipelines", "navigator-attitude.toml")) as f:
                text = f.read()
            assert "rate_hz = 1000.0\n" in text
            with open(pipeline, "w") as f:
                f.write(text.replace("rate_hz = 1000.0\n", f"rate_hz = {trials[0][2]['rate']!r}\n"))
        elif args.example and trials:
            # One parameter set for every trial: the unit's terms from the first rests of the
            # undisturbed trials (as broad_heading.py takes them), whichever trials are judged.
            rests = [first_rest(d) for d in (load_trial(args.broad, n)[1] for n in DEV) if d is not None]
            driftless = os.path.join(args.target, "driftless")
            keys, _ = stage_keys(driftless, rests, trials[0][2]["rate"], work, args.shift_rests)
            pipeline = os.path.join(work, "broad.toml")
            with open(pipeline, "w") as f:
                text = ATTITUDE_PIPELINE.format(rate=trials[0][2]["rate"], keys=keys + '\nstop_input = "broad/stop"')
                own = 'kind = "attitude.6d"\n'
                f.write(text.replace(own, own + "".join(k + "\n" for k in args.attitude_key)))
        pipeline9 = None
        if args.mag and pipeline:
            # The same chain, the attitude stage with the magnetometer.
            pipeline9 = os.path.join(work, "broad9.toml")
            with open(pipeline) as f:
                text = f.read()
            own = 'kind = "attitude.6d"\n'
            assert own in text
            with open(pipeline9, "w") as f:
                f.write(text.replace(own, own + "use_mag = true\n"))
        for n, name, d in trials:
            rate = d["rate"]
            gyr = np.asarray(d["imu_gyr"], float)
            acc = np.asarray(d["imu_acc"], float)
            q_ref = np.asarray(d["opt_quat"], float)
            moving = np.asarray(d["movement"], bool)
            k0 = int(np.argmax(np.all(np.isfinite(q_ref), axis=1)))

            est = {}
            for m, run in runners.items():
                t = time.time()
                if m == "vqf9":
                    if d.get("imu_mag") is None:
                        sys.exit(f"{name}: no magnetometer for vqf9")
                    est[m] = run_vqf9(gyr, acc, d["imu_mag"], rate)
                else:
                    est[m] = run(gyr, acc, rate)
                seconds[m] += time.time() - t
            t = time.time()
            if "gyro_raw" in methods:
                est["gyro_raw"] = integrate(gyr, q_ref, 1.0 / rate)
            if "gyro_zaru" in methods:
                est["gyro_zaru"] = integrate(gyr - zaru_bias(gyr, ~moving, int(round(rate))), q_ref, 1.0 / rate)
            if "gyro_raw" in seconds:
                seconds["gyro_raw"] += time.time() - t  # both integrations
            if args.example:
                found, sds = ours(name, d, pipeline, args.example, work)
                if pipeline9:
                    found9, sds9 = ours(name, d, pipeline9, args.example, work, mag=d["imu_mag"], prefix="ours9")
                    found.update({m: q for m, q in found9.items() if not m.endswith("_integrated")})
                    sds.update(sds9)
                for m, q in found.items():
                    est[m] = q
                    if m not in methods:
                        methods.append(m)
                        labels[m] = f"ours: {m}"

            row = {"trial": name, "number": n, "dev": n in DEV, "source": source(args.broad, n),
                   "first_valid_truth": k0, "first": {}, "mean_heading": {}, "nan": {}, "coverage": {}}
            for m in methods:
                q = est[m]
                nan = int(np.sum(~np.all(np.isfinite(q[k0:]), axis=1)))
                row["nan"][m] = nan
                # A 9D heading is judged absolute, as BROAD's authors judge it; a 6D one aligned.
                absolute = m in ABSOLUTE or m.startswith("ours9_")
                row["first"][m] = errors(q if absolute else align_first(q, q_ref, k0, bu), q_ref, moving, bu)
                row["mean_heading"][m] = errors(align_mean(q, q_ref, moving, bu), q_ref, moving, bu)
            for m, (sd, head_sd) in (sds.items() if args.example else ()):
                # The published sd's honesty: how many motion samples' inclination error (and
                # heading error, aligned at the first valid truth) lies within 2 sd.
                e = bu.calculateErrorQuatEarth(est[m], q_ref)
                e *= np.where(e[:, :1] < 0, -1.0, 1.0)
                incl = 2 * np.arccos(np.clip(np.sqrt(e[:, 0] ** 2 + e[:, 3] ** 2), -1.0, 1.0))
                ok = moving & np.isfinite(incl)
                row["coverage"][m] = [int(np.sum(incl[ok] <= 2 * sd[ok])), int(np.sum(ok))]
                if head_sd is not None:
                    q = est[m] if m.startswith("ours9_") else align_first(est[m], q_ref, k0, bu)
                    e = bu.calculateErrorQuatEarth(q, q_ref)
                    e *= np.where(e[:, :1] < 0, -1.0, 1.0)
                    head = np.abs(2 * np.arctan2(e[:, 3], e[:, 0]))
                    ok = moving & np.isfinite(head) & (head_sd >= 0)
                    row["coverage"][m + " heading"] = [int(np.sum(head[ok] <= 2 * head_sd[ok])), int(np.sum(ok))]
            results.append(row)

            print(f"\n{name}{' (dev)' if row['dev'] else ''}, heading aligned at sample {k0}")
            print("| method | total | heading | inclination |")
            print("|---|---|---|---|")
            for m in methods:
                e = row["first"][m]
                flag = f" ({row['nan'][m]} NaN samples)" if row["nan"][m] else ""
                print(f"| {labels[m]}{flag} | " + " | ".join(f"{e[x]:.2f}" for x in METRICS) + " |")
            sys.stdout.flush()
    elapsed = time.time() - start
    if not results:
        sys.exit("no trial of --trials is in this copy")

    dev = [r["number"] for r in results if r["dev"]]
    every = [r["number"] for r in results]
    summary = {}
    for key, what in (("first", "heading aligned at the first valid truth"),
                      ("mean_heading", "mean heading offset over the motion removed (for comparison)")):
        summary[key] = {"dev": medians(results, methods, key, dev), "all": medians(results, methods, key, every)}
        print(f"\nMedian RMS error (deg), {what}:")
        print(f"| method | dev 01-18 ({len(dev)} trial(s)): total | heading | inclination "
              f"| all ({len(every)} trial(s)): total | heading | inclination |")
        print("|---|---|---|---|---|---|---|")
        for m in methods:
            cells = [f"{summary[key][s][m][x]:.2f}" if summary[key][s] else "-" for s in ("dev", "all") for x in METRICS]
            print(f"| {labels[m]} | " + " | ".join(cells) + " |")
    for m in sorted({m for r in results for m in r["coverage"]}):
        cells = []
        for label, numbers in (("dev 01-18", dev), ("all", every)):
            inside = sum(r["coverage"][m][0] for r in results if r["number"] in numbers and m in r["coverage"])
            total = sum(r["coverage"][m][1] for r in results if r["number"] in numbers and m in r["coverage"])
            cells.append(f"{label} {inside / max(total, 1):.3f}")
            summary.setdefault("coverage", {}).setdefault(m, {})[label] = inside / max(total, 1)
        what, who = ("heading", m[:-len(" heading")]) if m.endswith(" heading") else ("inclination", m)
        print(f"\n{labels[who]}: {what} error within the published 2 sd in " + ", ".join(cells) + " of the motion samples")
    if args.mag and args.example:
        summary["9d"] = nine_d_table(results)
    print(f"\n{len(results)} trial(s) in {elapsed:.0f} s (" + ", ".join(f"{m} {s:.0f} s" for m, s in seconds.items() if s) + "; gyro_raw: both integrations)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"rate_hz": float(rate), "methods": labels, "trials": results,
                       "medians": summary, "seconds": {"total": elapsed, **seconds}}, f, indent=1)


if __name__ == "__main__":
    main()
