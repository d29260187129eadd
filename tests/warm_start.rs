//! `predict.bias`'s warm start (`state_file`) between real daemon processes: killed with
//! SIGKILL mid-run, the next start's first output is corrected, within the saved uncertainty.
//! A state that cannot be used (garbage, saved with other terms, another pipeline's) costs the
//! warm start, never the start: the daemon starts cold, says why in one line, keeps the file
//! aside byte for byte at `<name>.unusable-<UTC time>` and saves anew at `<name>`; with
//! `state_required = true` it is refused with exit 2 and left as it was.

mod common;

use std::time::{Duration, Instant};

use common::{finish, signal, start, wait_ready, Dir, Prefix};
use driftless::transport::Transport;
use driftless::wire::{GyroSample, FLAG_WARMING_UP};

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

    // Cold: the first output carries only what the filter has seen since the start (the body
    // stands at power-up), flagged warming up.
    let prefix = Prefix::new("warm1");
    let mut daemon = start(&file, &prefix, &[]);
    wait_ready(&prefix, "w/stats", &mut daemon);
    let cold = first_output(&prefix, "w/corrected");
    assert_ne!(cold.flags & FLAG_WARMING_UP, 0, "a cold start warms up");
    wait_for_learnt_state(&state, &mut daemon);
    signal(&daemon, libc::SIGKILL);
    let _ = daemon.wait();
    let saved = read_state(&state).unwrap();
    for (k, (_, sd)) in saved.iter().enumerate() {
        assert!(
            cold.drift_std[k].to_degrees() > *sd,
            "axis {k}: cold {} against the saved {sd}",
            cold.drift_std[k].to_degrees()
        );
    }

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
        // Grown over the gap, and shrunk a little by the start-up rest's first samples.
        assert!(
            std >= 0.5 * sd && std < 0.1,
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

/// The files beside `state` named `<its name>.unusable-*`.
fn kept_aside(state: &std::path::Path) -> Vec<std::path::PathBuf> {
    let name = state.file_name().unwrap().to_string_lossy().into_owned();
    let mut out: Vec<_> = std::fs::read_dir(state.parent().unwrap())
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with(&format!("{name}.unusable-"))
        })
        .collect();
    out.sort();
    out
}

/// The one line of `err` that mentions `state` and says the filter starts cold.
fn cold_line<'a>(err: &'a str, state: &std::path::Path) -> &'a str {
    let shown = state.display().to_string();
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.contains(&shown) && l.contains("starts cold"))
        .collect();
    assert_eq!(lines.len(), 1, "one line says why: {err}");
    lines[0]
}

/// The pipeline of this file replaying the still log once, as fast as possible.
fn once(name: &str, state: &str) -> String {
    pipeline(name, state)
        .replace("loop = true", "loop = false\npace = \"asap\"")
        .replace("start_delay_s = 1.0", "")
}

#[test]
fn a_garbage_state_file_costs_the_warm_start_not_the_start() {
    let dir = Dir::new();
    dir.write("still.csv", &still_csv(3000));
    // Stats each second, so that `stats --once` below needs no long wait.
    let text =
        pipeline("g", "g.state").replace("report_interval_s = 60.0", "report_interval_s = 1.0");
    let file = dir.write("p.toml", &text);
    let state = dir.path("g.state");
    let bytes = common::garbage();
    std::fs::write(&state, &bytes).unwrap();

    let prefix = Prefix::new("warmjunk");
    let report = dir.path("report.json");
    let mut daemon = start(&file, &prefix, &["--report", report.to_str().unwrap()]);
    wait_ready(&prefix, "g/stats", &mut daemon);
    // The old file goes aside at the start; a new state appears where it was (every 0.5 s).
    let end = Instant::now() + Duration::from_secs(60);
    while read_state(&state).is_none() {
        assert!(daemon.try_wait().unwrap().is_none(), "the daemon ended");
        assert!(Instant::now() < end, "no new state after 60 s");
        std::thread::sleep(Duration::from_millis(50));
    }
    // The stats service says it too, while the daemon serves.
    let file_arg = file.to_str().unwrap();
    let out = common::driftless(&["stats", file_arg, "--prefix", &prefix.0, "--once", "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        json["warm_start"], "cold, the saved state unusable (moved aside)",
        "{json}"
    );
    signal(&daemon, libc::SIGTERM);
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("; started COLD: the saved state was unusable (moved aside)"),
        "the verdict says it: {err}"
    );

    let aside = kept_aside(&state);
    assert_eq!(aside.len(), 1, "{aside:?}");
    let line = cold_line(&err, &state);
    assert!(
        line.starts_with("driftless: warning: state_file ")
            && line.contains("not a bias state driftless wrote: it holds binary data")
            && line.ends_with(&format!("the file is kept as {}", aside[0].display())),
        "{line}"
    );
    assert_eq!(
        std::fs::read(&aside[0]).unwrap(),
        bytes,
        "kept byte for byte"
    );
    let stamp = aside[0]
        .to_string_lossy()
        .rsplit('-')
        .next()
        .unwrap()
        .to_string();
    assert!(
        stamp.len() == 16 && stamp.ends_with('Z'),
        "UTC YYYYMMDDTHHMMSSZ: {stamp}"
    );
    // Saved anew at its name at exit, and the report says how the start went.
    let text = std::fs::read_to_string(&state).unwrap();
    assert!(text.contains("pipeline = \"g\""), "{text}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let lines = report["warm_start"].as_array().unwrap();
    assert_eq!(lines.len(), 1, "{report}");
    let l = lines[0].as_str().unwrap();
    assert!(
        l.starts_with("predict: cold: state_file ") && l.contains(".unusable-"),
        "{l}"
    );
}

#[test]
fn a_state_saved_with_other_terms_starts_cold_and_is_kept_aside() {
    let dir = Dir::new();
    // 20 s of a still gyro: a state worth more than the prior.
    dir.write("still.csv", &still_csv(2000));
    let first = dir.write("a.toml", &once("a", "a.state"));
    let state = dir.path("a.state");
    let prefix = Prefix::new("warmterms");
    let (code, err) = finish(start(&first, &prefix, &[]), Duration::from_secs(60));
    assert_eq!(code, Some(0), "{err}");
    let old = std::fs::read(&state).expect("a state saved at the end");

    // The user re-ran `allan --stage` and wrote the unit's own terms in.
    let own = once("a", "a.state").replace(
        "profile = \"adis16405\"",
        "arw = 2.0\nbias_instability = 30.0\nrrw = 0.5",
    );
    let second = dir.write("a.toml", &own);
    // validate says what run will do, and moves nothing.
    let out = common::driftless(&["validate", second.to_str().unwrap()]);
    let said = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{said}");
    assert!(
        said.contains("other noise terms") && said.contains("`run` starts cold and moves it aside"),
        "{said}"
    );
    assert_eq!(
        std::fs::read(&state).unwrap(),
        old,
        "validate moves nothing"
    );
    assert!(kept_aside(&state).is_empty());

    let (code, err) = finish(start(&second, &prefix, &[]), Duration::from_secs(60));
    assert_eq!(code, Some(0), "{err}");
    let aside = kept_aside(&state);
    assert_eq!(aside.len(), 1, "{aside:?}");
    let line = cold_line(&err, &state);
    assert!(
        line.contains("it was saved with other noise terms")
            && line.ends_with(&format!("the file is kept as {}", aside[0].display())),
        "{line}"
    );
    assert_eq!(std::fs::read(&aside[0]).unwrap(), old, "kept byte for byte");
    // The new state is the new terms': the next start takes it.
    let (code, err) = finish(start(&second, &prefix, &[]), Duration::from_secs(60));
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("warm start from state_file"), "{err}");
    assert_eq!(kept_aside(&state).len(), 1, "nothing more moved");
}

#[test]
fn state_required_refuses_an_unusable_state_with_exit_2_and_leaves_it() {
    let dir = Dir::new();
    dir.write("still.csv", &still_csv(300));
    let prefix = Prefix::new("warmreq");
    let a = dir.write("a.toml", &once("a", "shared.state"));
    let (code, err) = finish(start(&a, &prefix, &[]), Duration::from_secs(60));
    assert_eq!(code, Some(0), "{err}");
    let state = dir.path("shared.state");
    let required = |name: &str| {
        once(name, "shared.state").replace(
            "state_every_s = 0.5",
            "state_every_s = 0.5\nstate_required = true",
        )
    };

    // Another pipeline's state, then garbage: refused by validate and run, untouched.
    let b = dir.write("b.toml", &required("b"));
    let whose = "it is pipeline \"a\" stage \"predict\"'s, not \"b\" \"predict\"'s";
    let cases = [
        (std::fs::read(&state).unwrap(), whose),
        (
            common::garbage(),
            "not a bias state driftless wrote: it holds binary data",
        ),
    ];
    for (bytes, why) in cases {
        std::fs::write(&state, &bytes).unwrap();
        for cmd in [
            vec!["validate", b.to_str().unwrap()],
            vec!["run", b.to_str().unwrap(), "--prefix", &prefix.0],
        ] {
            let out = common::driftless(&cmd);
            let text = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{cmd:?}: {text}");
            assert_eq!(text.trim_end().lines().count(), 1, "one line: {text}");
            assert!(
                text.contains(why)
                    && text.contains("state_required = true")
                    && text.contains("b.toml:"),
                "{text}"
            );
            assert_eq!(std::fs::read(&state).unwrap(), bytes, "untouched");
            assert!(kept_aside(&state).is_empty(), "nothing moved");
        }
    }
}

#[test]
fn a_directory_at_the_state_path_is_a_cold_start_and_stays() {
    let dir = Dir::new();
    dir.write("still.csv", &still_csv(300));
    let file = dir.write("d.toml", &once("d", "d.state"));
    let state = dir.path("d.state");
    std::fs::create_dir(&state).unwrap();
    std::fs::write(state.join("mine"), "a user's file").unwrap();
    let prefix = Prefix::new("warmdir");
    let (code, err) = finish(start(&file, &prefix, &[]), Duration::from_secs(60));
    assert_eq!(code, Some(0), "{err}");
    let line = cold_line(&err, &state);
    assert!(
        line.contains("a directory") && line.ends_with("point state_file at a file"),
        "{line}"
    );
    assert_eq!(
        std::fs::read_to_string(state.join("mine")).unwrap(),
        "a user's file"
    );
    assert!(kept_aside(&state).is_empty(), "a directory is never moved");
}

#[test]
fn an_offline_run_moves_an_unusable_state_once_and_resumes_from_its_own_save() {
    // nav-eval builds the stages once per case, each saving at its end: the state is read
    // again at each build, so the second finds the first's save, not the garbage.
    let dir = Dir::new();
    dir.write("still.csv", &still_csv(10));
    let file = dir.write("o.toml", &once("o", "o.state"));
    let state = dir.path("o.state");
    std::fs::write(&state, common::garbage()).unwrap();
    let p = driftless::pipeline::config::load(&file).unwrap();
    let axes: Vec<Vec<f64>> = BIAS.iter().map(|b| vec![*b; 2000]).collect();
    let inputs: Vec<&[f64]> = axes.iter().map(Vec::as_slice).collect();
    for _ in 0..2 {
        driftless::pipeline::offline::Offline::run_series(&p, &inputs, None).unwrap();
        assert_eq!(kept_aside(&state).len(), 1, "moved once");
        assert!(read_state(&state).is_some(), "saved at the end of the run");
    }
    assert_eq!(
        std::fs::read(&kept_aside(&state)[0]).unwrap(),
        common::garbage()
    );
}
