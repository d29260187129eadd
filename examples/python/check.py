#!/usr/bin/env python3
"""End-to-end check of the Python driver and subscriber through a real daemon.

    python3 -m venv target/pyenv && target/pyenv/bin/pip install -r examples/python/requirements.txt
    cargo build --release
    target/pyenv/bin/python examples/python/check.py          # --help for the options
    target/pyenv/bin/python examples/python/check.py --attitude   # with attitude.6d before publish

1. `driftless run <pipeline> --quiet` (default pipelines/external-sensor.toml: ingest.iceoryx2 on
   sensor/raw, wavelet denoiser with lag 64, corrected rates on external/corrected), under a
   prefix of its own (DRIFTLESS_IOX2_PREFIX, unique per run) and a root directory in a fresh
   temporary directory (DRIFTLESS_IOX2_ROOT), so parallel runs never meet;
2. subscriber.py on the corrected service, --expect-pattern, --count N;
3. driver.py sends N samples (default 5000 at 1 kHz) on the raw service;
4. the denoiser holds its last `lag` samples until the input ends, and a driver that stops does
   not end the daemon's input (it waits for more): so the check waits until the subscriber has
   exactly N - lag samples, sends SIGTERM, and the daemon drains the held samples (flagged
   0x10) before it exits 0 (docs/operations.md, "Restarts and crashes");
5. asserts: driver, daemon and subscriber exit 0; the subscriber got seq 0..N-1 exactly once, in
   order, in one epoch (the daemon's), with the driver's values, `lag` of them flushed at
   shutdown, each with drift_std "not provided" (-1: no bias filter in the pipeline); with
   --attitude (an attitude.6d stage inserted before publish) each with a unit quaternion and
   its standard deviations (the heading's -1: no bias filter says how far to trust it); the
   daemon's report says N in, N out, nothing lost, no source restart.

Creates nothing outside its temporary directory but iceoryx2's shared memory, /dev/shm/<prefix>*,
removed at the end. Exit 0 when every assertion held, 1 otherwise (saying which, with the logs).
"""

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import tomllib

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))


class CheckFailed(Exception):
    pass


def pipeline_facts(path: str) -> dict:
    """The services, rate, buffer and total denoiser lag of a pipeline reading a driver."""
    with open(path, "rb") as f:
        p = tomllib.load(f)
    stages = p.get("stage", [])
    ingest = [s for s in stages if s.get("kind") == "ingest.iceoryx2"]
    publish = [s for s in stages if s.get("kind") == "publish"]
    if len(ingest) != 1 or len(publish) != 1:
        raise CheckFailed(f"{path}: needs one ingest.iceoryx2 stage and one publish stage")
    if any(s.get("kind") not in ("ingest.iceoryx2", "denoise.wavelet", "denoise.none",
                                 "predict.none", "attitude.6d", "publish") for s in stages):
        raise CheckFailed(f"{path}: only ingest.iceoryx2, denoise.*, predict.none, attitude.6d "
                          "and publish stages keep the driver's values checkable")
    # denoise.wavelet's lag: 64 by default (at most the full lag; external-sensor.toml sets it).
    lag = sum(s.get("lag", 64) for s in stages if s.get("kind") == "denoise.wavelet")
    return {
        "raw": ingest[0]["input"],
        "corrected": publish[0]["output"],
        "rate_hz": float(p["rate_hz"]),
        "buffer_size": p.get("iceoryx2", {}).get("buffer_size", 256),
        "max_subscribers": p.get("iceoryx2", {}).get("max_subscribers", 8),
        "lag": lag,
        "before_publish": publish[0]["input"],
        "attitude": any(s.get("kind") == "attitude.6d" for s in stages),
    }


def with_attitude(path: str, facts: dict, out: str) -> None:
    """Write to `out` the pipeline at `path` with an attitude.6d stage before its publish."""
    with open(path) as f:
        text = f.read()
    before = facts["before_publish"]
    publish = f'[[stage]]\nname = "publish"\nkind = "publish"\ninput = "{before}"\n'
    if text.count(publish) != 1:
        raise CheckFailed(f"{path}: --attitude needs the publish stage written as\n{publish}")
    service = before.rsplit("/", 1)[0] + "/attitude"
    attitude = (f'[[stage]]\nname = "attitude"\nkind = "attitude.6d"\ninput = "{before}"\n'
                f'output = "{service}"\n\n')
    with open(out, "w") as f:
        f.write(text.replace(publish, attitude + publish.replace(before, service)))


def wait_for(what: str, cond, timeout: float, procs: dict) -> None:
    """Wait until cond() holds; fail at the timeout or when one of procs has exited."""
    end = time.monotonic() + timeout
    while not cond():
        for name, p in procs.items():
            if p.poll() is not None:
                raise CheckFailed(f"{name} exited (code {p.returncode}) while waiting for {what}")
        if time.monotonic() >= end:
            raise CheckFailed(f"timed out after {timeout:.0f} s waiting for {what}")
        time.sleep(0.02)


def read_int(path: str):
    try:
        with open(path) as f:
            return int(f.read().strip() or "0")
    except (OSError, ValueError):
        return None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--binary", default=os.path.join(REPO, "target/release/driftless"))
    ap.add_argument("--pipeline", default=os.path.join(REPO, "pipelines/external-sensor.toml"))
    ap.add_argument("--count", type=int, default=5000, help="samples the driver sends")
    ap.add_argument("--python", default=sys.executable,
                    help="interpreter with iceoryx2==0.10.0 for driver.py and subscriber.py")
    ap.add_argument("--attitude", action="store_true",
                    help="insert an attitude.6d stage before the pipeline's publish stage")
    ap.add_argument("--driver-arg", action="append", default=[],
                    help="extra argument for driver.py (e.g. --driver-arg=--skip=2500 must fail)")
    args = ap.parse_args()
    facts = pipeline_facts(args.pipeline)
    if args.count <= facts["lag"]:
        ap.error(f"--count must exceed the pipeline's denoiser lag ({facts['lag']})")

    tmp = tempfile.mkdtemp(prefix="driftless-pycheck-")
    args.pipeline_used = args.pipeline
    prefix = f"dlpy{os.getpid()}-{os.urandom(3).hex()}_"
    env = dict(os.environ, DRIFTLESS_IOX2_PREFIX=prefix,
               DRIFTLESS_IOX2_ROOT=os.path.join(tmp, "iceoryx2"),
               PYTHONDONTWRITEBYTECODE="1", PYTHONUNBUFFERED="1")
    env.pop("IOX2_LOG_LEVEL", None)
    procs = {}
    logs = {}

    def start(name: str, argv: list) -> subprocess.Popen:
        logs[name] = os.path.join(tmp, f"{name}.log")
        with open(logs[name], "w") as log:
            procs[name] = subprocess.Popen(argv, cwd=tmp, env=env, stdin=subprocess.DEVNULL,
                                           stdout=log, stderr=subprocess.STDOUT)
        return procs[name]

    ok = False
    try:
        if args.attitude:
            args.pipeline_used = os.path.join(tmp, "pipeline.toml")
            with_attitude(args.pipeline, facts, args.pipeline_used)
            facts = pipeline_facts(args.pipeline_used)
        ok = run(args, facts, tmp, start, procs)
    except CheckFailed as e:
        print(f"check: FAILED: {e}", file=sys.stderr)
    finally:
        for name, p in procs.items():  # only the processes this check started, by pid
            if p.poll() is None:
                print(f"check: stopping {name} (pid {p.pid})", file=sys.stderr)
                p.terminate()  # SIGTERM: each removes its iceoryx2 files
                try:
                    p.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
        if not ok:
            for name, path in logs.items():
                with open(path) as f:
                    text = f.read().strip()
                print(f"---- {name} ({path}) ----\n{text}", file=sys.stderr)
        leftovers = [n for n in os.listdir("/dev/shm") if n.startswith(prefix)]
        if leftovers:
            print(f"check: note: {len(leftovers)} files of prefix {prefix} left in /dev/shm "
                  f"(removed): {', '.join(leftovers)}", file=sys.stderr)
        for n in leftovers:
            try:
                os.remove(os.path.join("/dev/shm", n))
            except OSError:
                pass
        shutil.rmtree(tmp, ignore_errors=True)
    print("check: OK" if ok else "check: FAILED", file=sys.stderr)
    return 0 if ok else 1


def run(args, facts: dict, tmp: str, start, procs: dict) -> bool:
    n, lag, rate = args.count, facts["lag"], facts["rate_hz"]
    if not os.access(args.binary, os.X_OK):
        raise CheckFailed(f"{args.binary}: not built (cargo build --release)")
    t0 = time.monotonic()
    daemon_report = os.path.join(tmp, "daemon.json")
    daemon = start("daemon", [args.binary, "run", args.pipeline_used, "--quiet",
                              "--report", daemon_report])

    ready = os.path.join(tmp, "subscriber.ready")
    progress = os.path.join(tmp, "subscriber.progress")
    sub_report = os.path.join(tmp, "subscriber.json")
    sub = start("subscriber", [args.python, os.path.join(HERE, "subscriber.py"),
                               "--service", facts["corrected"], "--count", str(n),
                               "--expect-pattern", "--rate", str(rate),
                               *(["--expect-orientation"] if facts["attitude"] else []),
                               "--timeout", str(n / rate * 3 + 60),
                               "--ready-file", ready, "--progress-file", progress,
                               "--report", sub_report])
    wait_for("the subscriber to subscribe", lambda: os.path.exists(ready), 30, procs)

    t_send = time.monotonic()
    driver = start("driver", [args.python, os.path.join(HERE, "driver.py"),
                              "--service", facts["raw"], "--rate", str(rate), "--count", str(n),
                              "--buffer-size", str(facts["buffer_size"]),
                              "--max-subscribers", str(facts["max_subscribers"]),
                              *args.driver_arg])
    try:
        driver.wait(timeout=n / rate * 3 + 60)
    except subprocess.TimeoutExpired:
        raise CheckFailed("the driver did not finish in time") from None
    t_sent = time.monotonic()
    if driver.returncode != 0:
        raise CheckFailed(f"driver.py exited {driver.returncode}")

    # The denoiser holds the last `lag` samples until the input ends: wait for the rest (until
    # the count stops growing, for a broken run), and make sure no more come before the shutdown.
    failures = []
    held_back = n - lag
    got = lambda: read_int(progress) or 0  # noqa: E731
    last, since = -1, time.monotonic()
    give_up = time.monotonic() + 30
    while got() < held_back and time.monotonic() - since < 2 and time.monotonic() < give_up:
        if got() != last:
            last, since = got(), time.monotonic()
        if daemon.poll() is not None or sub.poll() is not None:
            break
        time.sleep(0.02)
    time.sleep(0.3)
    if got() != held_back:
        failures.append(f"the subscriber had {got()} samples before the shutdown, expected "
                        f"{held_back} (N - the {lag} the denoiser holds)")

    t_term = time.monotonic()
    daemon.send_signal(signal.SIGTERM)
    try:
        daemon.wait(timeout=30)
    except subprocess.TimeoutExpired:
        raise CheckFailed("the daemon did not exit within 30 s of SIGTERM") from None
    t_exit = time.monotonic()
    if daemon.returncode != 0:
        failures.append(f"the daemon exited {daemon.returncode} after SIGTERM, expected 0")
    # The subscriber stops by itself at --count; one still waiting after 5 s never will:
    # SIGTERM makes it report what it has.
    try:
        sub.wait(timeout=5)
    except subprocess.TimeoutExpired:
        failures.append(f"the subscriber was still waiting 5 s after the daemon's exit "
                        f"({got()} of {n} samples)")
        sub.send_signal(signal.SIGTERM)
        try:
            sub.wait(timeout=10)
        except subprocess.TimeoutExpired:
            raise CheckFailed("; ".join(failures + ["the subscriber ignored SIGTERM"])) from None
    if sub.returncode != 0:
        failures.append(f"subscriber.py exited {sub.returncode}")
    if failures:
        raise CheckFailed("; ".join(failures))

    with open(sub_report) as f:
        s = json.load(f)
    # The pipeline has no bias filter (predict.none at most): every sample's drift_std is
    # "not provided", -1 on each axis, read at offset 104 of GyroSample v4.
    expect = {"received": n, "first_seq": 0, "last_seq": n - 1, "epochs": 1, "missing": 0,
              "disorder": 0, "flagged": 0, "pattern_errors": 0, "flushed": lag,
              "drift_std_not_provided": n, "drift_std_bad": 0,
              "drift_std_last": [-1.0, -1.0, -1.0], "ok": True,
              "orientation": n if facts["attitude"] else 0, "orientation_bad": 0}
    wrong = {k: (s.get(k), v) for k, v in expect.items() if s.get(k) != v}
    if wrong:
        raise CheckFailed("subscriber report: " + ", ".join(
            f"{k} = {got_} (expected {want})" for k, (got_, want) in wrong.items()))
    with open(daemon_report) as f:
        d = json.load(f)
    counts = {k: d.get(k) for k in ("samples_in", "samples_out", "lost", "source_restarts", "epoch")}
    want = {"samples_in": n, "samples_out": n, "lost": 0, "source_restarts": 0, "epoch": s["epoch"]}
    if counts != want:
        raise CheckFailed(f"daemon report: {counts}, expected {want}")

    lat = s["latency_ns"]
    print(f"check: driver sent {n} samples at {rate:g} Hz in {t_sent - t_send:.2f} s; "
          f"subscriber got {s['received']} (seq 0..{n - 1}, one epoch, each once, in order; "
          f"{n - lag} live + {s['flushed']} flushed at SIGTERM), heading {s['heading_deg']:+.3f} deg "
          f"(expected {s['expected_heading_deg']:+.3f}); "
          + (f"an orientation on each, the last roll/pitch/yaw "
             + "/".join(f"{a:+.1f}" for a in s["rpy_last_deg"]) + " deg; "
             if facts["attitude"] else "")
          + f"latency ingest->python p50 "
          f"{lat['p50'] / 1e3:.0f} us, p99 {lat['p99'] / 1e3:.0f} us, max {lat['max'] / 1e3:.0f} us; "
          f"daemon: {counts['samples_in']} in, {counts['samples_out']} out, {counts['lost']} lost, "
          f"exit 0 {t_exit - t_term:.2f} s after SIGTERM; total {time.monotonic() - t0:.1f} s",
          file=sys.stderr)
    return True


if __name__ == "__main__":
    sys.exit(main())
