//! With a simulated ingest the daemon knows the truth: its report gives the heading error of
//! the raw, denoised and corrected rates, which must be what integrating the simulator's own
//! samples against its truth gives.

mod common;

use std::time::Duration;

use common::{finish, report, start, Dir, Prefix};
use driftless::sim::{Motion, SimConfig, Simulator};

const N: u64 = 4000;

/// A pipeline `name`: the ADIS16405 simulated at 1 kHz in stop-and-go (seed 5, and `sensor`'s
/// further keys), no denoiser, published.
fn sim_pipeline(name: &str, sensor: &str) -> String {
    format!(
        r#"
name = "{name}"
rate_hz = 1000.0
axes = 3
report_interval_s = 60.0

[[stage]]
name = "sensor"
kind = "ingest.sim"
output = "{name}/raw"
profile = "adis16405"
motion = "stop-and-go"
seed = 5
{sensor}

[[stage]]
name = "denoise"
kind = "denoise.none"
input = "{name}/raw"
output = "{name}/denoised"

[[stage]]
name = "publish"
kind = "publish"
input = "{name}/denoised"
output = "{name}/corrected"
"#
    )
}

#[test]
fn the_report_gives_the_heading_error_against_the_simulators_truth() {
    let prefix = Prefix::new("heading");
    let dir = Dir::new();
    let text = sim_pipeline("h", &format!("samples = {N}"));
    let file = dir.write("p.toml", &text);
    let child = start(
        &file,
        &prefix,
        &["--report", dir.path("report.json").to_str().unwrap()],
    );
    let (code, err) = finish(child, Duration::from_secs(30));
    assert_eq!(code, Some(0), "{err}");
    let r = report(&dir);
    assert_eq!(r["samples_out"], N);

    // The same simulator, integrated here.
    let mut cfg = SimConfig::profile("adis16405").unwrap();
    cfg.rate_hz = 1000.0;
    cfg.axes = 3;
    cfg.seed = 5;
    cfg.motion = Motion::StopAndGo;
    let mut sim = Simulator::new(&cfg).unwrap();
    let mut heading = [0.0f64; 3];
    let mut sum_sq = [0.0f64; 3];
    for _ in 0..N {
        let s = sim.next_sample();
        for a in 0..3 {
            heading[a] += (s.measured[a] - s.truth[a]) * 1e-3;
            sum_sq[a] += heading[a] * heading[a];
        }
    }
    let h = &r["heading"];
    for part in ["raw", "denoised", "corrected"] {
        for a in 0..3 {
            let e = &h[part][a];
            let got = e["final_deg"].as_f64().expect("final_deg");
            assert!(
                (got - heading[a]).abs() < 1e-9 * (1.0 + heading[a].abs()),
                "{part} axis {a}: {got} vs {}",
                heading[a]
            );
            let rms = (sum_sq[a] / N as f64).sqrt();
            let got = e["rms_deg"].as_f64().expect("rms_deg");
            assert!((got - rms).abs() < 1e-9 * (1.0 + rms), "{part} {a} rms");
        }
    }
    // The bias alone makes a visible error in 4 s (ADIS16405 turn-on bias).
    assert!(heading.iter().any(|h| h.abs() > 1e-3), "{heading:?}");
    // And the stderr table shows it.
    assert!(
        err.contains("heading error vs the simulator's truth"),
        "{err}"
    );
}

/// `run`'s report says per axis what walk a `predict.bias` stage uses against the configured
/// one: learnt from its stops with `learn_walk = "always"`; nothing from a stage with the
/// default, which learns only from a stop signal, and this chain has none.
#[test]
fn the_report_says_what_the_bias_filter_learnt() {
    let prefix = Prefix::new("learnt");
    let dir = Dir::new();
    let stage = |name: &str, input: &str, output: &str, extra: &str| {
        format!(
            "\n[[stage]]\nname = \"{name}\"\nkind = \"predict.bias\"\ninput = \"{input}\"\n\
             output = \"{output}\"\nprofile = \"adis16405\"\n{extra}\n"
        )
    };
    let text = format!(
        r#"
name = "l"
rate_hz = 100.0
axes = 3
report_interval_s = 600.0

[[stage]]
name = "sensor"
kind = "ingest.sim"
output = "l/raw"
profile = "adis16405"
motion = "stop-and-go"
seed = 3
samples = 60000
pace = "asap"
{}{}
[[stage]]
name = "publish"
kind = "publish"
input = "l/fixed"
output = "l/corrected"
"#,
        stage("learns", "l/raw", "l/learnt", "learn_walk = \"always\""),
        stage("keeps", "l/learnt", "l/fixed", "")
    );
    let file = dir.write("p.toml", &text);
    let child = start(
        &file,
        &prefix,
        &["--report", dir.path("report.json").to_str().unwrap()],
    );
    let (code, err) = finish(child, Duration::from_secs(60));
    assert_eq!(code, Some(0), "{err}");
    let r = report(&dir);
    let lines: Vec<&str> = r["learnt"]
        .as_array()
        .expect("learnt lines")
        .iter()
        .map(|l| l.as_str().unwrap())
        .collect();
    assert_eq!(lines.len(), 3, "{lines:?}");
    // "NAME: AXIS: walk W deg/h/sqrt(h) from S stops (configured C, bounds LO..HI; learn_walk = L)"
    let parse = |l: &str| -> (f64, u64, f64, f64, f64) {
        let num = |after: &str, until: char| -> f64 {
            let rest = &l[l.find(after).unwrap() + after.len()..];
            rest[..rest.find(until).unwrap()].parse().unwrap()
        };
        let bounds = &l[l.find("bounds ").unwrap() + 7..l.find(';').unwrap()];
        let (lo, hi) = bounds.split_once("..").unwrap();
        (
            num("walk ", ' '),
            num("from ", ' ') as u64,
            num("configured ", ','),
            lo.parse().unwrap(),
            hi.parse().unwrap(),
        )
    };
    for (i, axis) in ["x", "y", "z"].iter().enumerate() {
        let learns = lines[i];
        assert!(
            learns.starts_with(&format!("learns: {axis}: walk ")),
            "{learns}"
        );
        assert!(learns.ends_with("learn_walk = always)"), "{learns}");
        let (walk, stops, configured, lo, hi) = parse(learns);
        assert!(stops >= 5, "{learns}");
        assert!(walk != configured && walk >= lo && walk <= hi, "{learns}");
    }
}

/// `--duration` on a paced source ends at the sample due that long after the clock started,
/// however late the daemon runs: the same samples, so the same heading figures, on a busy
/// machine (issue 59: README's demo moved with the load). The daemon is stopped (SIGSTOP) for
/// 2.5 s across the end of its 2 s and then resumed: it must catch up and publish every sample
/// due by then, not end at the first one it takes after the wall clock passed the end.
#[test]
fn a_late_daemon_runs_its_duration_to_the_same_samples() {
    let prefix = Prefix::new("late");
    let dir = Dir::new();
    let text = sim_pipeline("late", "");
    let file = dir.write("p.toml", &text);
    let child = start(
        &file,
        &prefix,
        &[
            "--duration",
            "2s",
            "--report",
            dir.path("report.json").to_str().unwrap(),
        ],
    );
    let signal = |name: &str| {
        let ok = std::process::Command::new("kill")
            .args([name, &child.id().to_string()])
            .status()
            .expect("kill")
            .success();
        assert!(ok, "kill {name}");
    };
    // The run's 2 s end lies between 1.5 s and 4 s after the spawn, whatever its start-up.
    std::thread::sleep(Duration::from_millis(1500));
    signal("-STOP");
    std::thread::sleep(Duration::from_millis(2500));
    signal("-CONT");
    let (code, err) = finish(child, Duration::from_secs(30));
    assert_eq!(code, Some(0), "{err}");
    // Samples 0 to 2000: the last one due at 2 s.
    assert_eq!(report(&dir)["samples_out"], 2001, "{err}");
}
