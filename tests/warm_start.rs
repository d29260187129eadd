//! `predict.bias`'s warm start (`state_file`) between real daemon processes: killed with
//! SIGKILL mid-run, the next start's first output is corrected, within the saved uncertainty;
//! a state of another pipeline, or a corrupt one, is refused with its file and exit 2.

mod common;

use std::time::{Duration, Instant};

use common::{finish, signal, start, wait_ready, Dir, Prefix};
use driftless::transport::{GyroSample, Transport};

/// The gyro's bias on each axis, deg/s: what a warm start must remove from the first sample.
const BIAS: [f64; 3] = [0.5, -0.3, 0.2];

/// A still gyro at 100 Hz: the bias plus deterministic noise of about 0.05 deg/s.
fn still_csv(rows: usize) -> String {
    let mut s = String::from("t,x,y,z\n");
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut noise = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.17
    };
    for i in 0..rows {
        s.push_str(&format!(
            "{},{},{},{}\n",
            i as f64 / 100.0,
            BIAS[0] + noise(),
            BIAS[1] + noise(),
            BIAS[2] + noise()
        ));
    }
    s
}

fn pipeline(name: &str, state: &str) -> String {
    format!(
        r#"
name = "{name}"
rate_hz = 100.0
input_units = "deg/s"
report_interval_s = 60.0

[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "{name}/raw"
file = "still.csv"
time_column = "t"
loop = true
# Time for the test to subscribe before the first sample.
start_delay_s = 1.0

[[stage]]
name = "denoise"
kind = "denoise.none"
input = "{name}/raw"
output = "{name}/denoised"

[[stage]]
name = "predict"
kind = "predict.bias"
input = "{name}/denoised"
output = "{name}/predicted"
profile = "adis16405"
state_file = "{state}"
state_every_s = 0.5

[[stage]]
name = "publish"
kind = "publish"
input = "{name}/predicted"
output = "{name}/corrected"
"#
    )
}

/// The first sample the daemon publishes on `service`.
fn first_output(prefix: &Prefix, service: &str) -> GyroSample {
    let node = Transport::new(&prefix.0, "warm-probe", Default::default()).unwrap();
    let input = node.open_input::<GyroSample>(service).unwrap();
    let got = common::collect(&input, 1, Duration::from_secs(10));
    got.first().copied().expect("a first sample")
}

/// The state file's bias and sd per axis, deg/s, if there is one (always whole: it is
/// replaced atomically).
fn read_state(path: &std::path::Path) -> Option<Vec<(f64, f64)>> {
    let text = std::fs::read_to_string(path).ok()?;
    let v: toml::Value = toml::from_str(&text).expect("a whole state file, never half");
    Some(
        v["axis"]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| {
                (
                    a["bias_deg_s"].as_float().unwrap(),
                    a["sd_deg_s"].as_float().unwrap(),
                )
            })
            .collect(),
    )
}

/// Wait until the state file holds an estimate within 0.02 deg/s of the truth: the daemon's
/// own progress, not a time.
fn wait_for_learnt_state(path: &std::path::Path, daemon: &mut std::process::Child) {
    let end = Instant::now() + Duration::from_secs(60);
    loop {
        if let Some(axes) = read_state(path) {
            if axes
                .iter()
                .zip(BIAS)
                .all(|((b, _), t)| (b - t).abs() < 0.02)
            {
                return;
            }
        }
        assert!(daemon.try_wait().unwrap().is_none(), "the daemon ended");
        assert!(Instant::now() < end, "no learnt state after 60 s");
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn after_sigkill_the_next_start_is_corrected_from_the_first_sample() {
    let dir = Dir::new();
    dir.write("still.csv", &still_csv(3000));
    let file = dir.write("p.toml", &pipeline("w", "w.state"));
    let state = dir.path("w.state");

    // Cold: the first output is uncorrected (no drift removed) while the filter learns.
    let prefix = Prefix::new("warm1");
    let mut daemon = start(&file, &prefix, &[]);
    wait_ready(&prefix, "w/stats", &mut daemon);
    let cold = first_output(&prefix, "w/corrected");
    assert_eq!(cold.drift, [0.0; 3], "a cold start removes nothing yet");
    wait_for_learnt_state(&state, &mut daemon);
    signal(&daemon, libc::SIGKILL);
    let _ = daemon.wait();
    let saved = read_state(&state).unwrap();

    // Warm: corrected from the first sample, within the saved uncertainty (grown a little).
    let prefix = Prefix::new("warm2");
    let mut daemon = start(&file, &prefix, &[]);
    wait_ready(&prefix, "w/stats", &mut daemon);
    let warm = first_output(&prefix, "w/corrected");
    for (k, ((bias, sd), truth)) in saved.iter().zip(BIAS).enumerate() {
        let drift = warm.drift[k].to_degrees();
        let std = warm.drift_std[k].to_degrees();
        assert!(
            (drift - bias).abs() <= 3.0 * sd + 1e-9,
            "axis {k}: first drift {drift} against the saved {bias} +- {sd}"
        );
        assert!(
            std >= *sd && std < 0.1,
            "axis {k}: sd {std} grown from {sd}"
        );
        assert!(
            (drift - truth).abs() < 0.03,
            "axis {k}: {drift} against {truth}"
        );
    }
    signal(&daemon, libc::SIGTERM);
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("warm start from state_file"), "{err}");
    assert!(state.exists(), "saved again at shutdown");
}

#[test]
fn a_state_of_another_pipeline_or_a_corrupt_one_is_refused_with_its_file_and_exit_2() {
    let dir = Dir::new();
    dir.write("still.csv", &still_csv(300));
    let first = dir.write("a.toml", &pipeline("a", "shared.state"));
    let prefix = Prefix::new("warmref");
    // A run that ends with its file leaves a state behind.
    let short = std::fs::read_to_string(&first)
        .unwrap()
        .replace("loop = true", "loop = false");
    let first = dir.write("a.toml", &short);
    let (code, err) = finish(start(&first, &prefix, &[]), Duration::from_secs(30));
    assert_eq!(code, Some(0), "{err}");
    assert!(dir.path("shared.state").exists(), "{err}");

    let other = dir.write("b.toml", &pipeline("b", "shared.state"));
    let out = common::driftless(&["validate", other.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{text}");
    assert!(
        text.contains("it is pipeline \"a\" stage \"predict\"'s, not \"b\" \"predict\"'s"),
        "{text}"
    );
    assert!(text.contains("b.toml:"), "the pipeline file's line: {text}");

    let state = dir.path("shared.state");
    let whole = std::fs::read_to_string(&state).unwrap();
    std::fs::write(&state, &whole[..whole.len() / 3]).unwrap();
    let out = common::driftless(&["run", first.to_str().unwrap(), "--prefix", &prefix.0]);
    let text = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{text}");
    assert!(
        text.contains("shared.state:") && text.contains("not a bias state driftless wrote"),
        "{text}"
    );
}
