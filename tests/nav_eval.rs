//! `driftless nav-eval`, run as a user runs it: the built-in chain and a pipeline file go through
//! the daemon's stage code, the figures are the library's, and bad input is one line, exit 2.

mod common;

use common::Dir;
use serde_json::Value;
use std::process::{Command, Output};

fn nav_eval(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_driftless"))
        .arg("nav-eval")
        .args(args)
        .output()
        .expect("driftless runs")
}

fn json(out: &Output) -> Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON document")
}

fn method<'a>(section: &'a Value, name: &str) -> &'a Value {
    section["methods"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["method"].as_str().unwrap().starts_with(name))
        .unwrap_or_else(|| panic!("no method {name} in {section}"))
}

fn med(m: &Value, key: &str) -> f64 {
    m[key]["median"].as_f64().unwrap()
}

const PASS_THROUGH: &str = r#"
name = "pass"
rate_hz = 100.0
axes = 3
input_units = "rad/s"

[[stage]]
name = "sensor"
kind = "ingest.iceoryx2"
input = "sensor/raw"
output = "pass/raw"

[[stage]]
name = "denoise"
kind = "denoise.none"
input = "pass/raw"
output = "pass/denoised"

[[stage]]
name = "predict"
kind = "predict.none"
input = "pass/denoised"
output = "pass/predicted"

[[stage]]
name = "publish"
kind = "publish"
input = "pass/predicted"
output = "pass/corrected"
"#;

#[test]
fn on_the_simulator_the_stages_are_judged_with_the_baselines() {
    let dir = Dir::new();
    let pass = dir.write("pass.toml", PASS_THROUGH);
    let out = nav_eval(&[
        "--sim",
        "adis16405",
        "--windows",
        "2",
        "--window",
        "5min",
        "--motion",
        "stop-and-go",
        "--json",
        "--pipeline",
        pass.to_str().unwrap(),
    ]);
    let v = json(&out);
    let s = &v["sections"][0];
    assert_eq!(s["profile"], "stop-and-go");
    assert_eq!(v["axes"], 3);
    assert_eq!(v["windows_per_axis"], 2);
    let raw = method(s, "raw");
    let zaru = method(s, "ZARU oracle");
    let chain = method(s, "denoise.wavelet -> predict.bias");
    let pass = method(s, "pass.toml (denoise.none -> predict.none -> publish)");
    assert_eq!(med(zaru, "rms_ratio_to_zaru_oracle"), 1.0);
    // A pass-through pipeline, fed in rad/s, publishes the raw rate: the same figures exactly
    // but for rounding through the unit conversion.
    for key in ["rms_heading_deg", "final_heading_deg", "rms_rate_degps"] {
        let (a, b) = (med(pass, key), med(raw, key));
        assert!((a - b).abs() <= 1e-9 * b, "{key}: {a} vs raw {b}");
    }
    // The product's chain removes the bias: far from raw, near the oracle ZARU.
    assert!(med(raw, "rms_ratio_to_zaru_oracle") > 20.0);
    let r = med(chain, "rms_ratio_to_zaru_oracle");
    assert!(r < 1.5, "the stages against oracle ZARU: {r}");
    // x-io Fusion's deployed algorithm is judged too: it removes most of the bias.
    let fusion = med(method(s, "x-io Fusion bias"), "rms_ratio_to_zaru_oracle");
    assert!(
        fusion.is_finite() && fusion < med(raw, "rms_ratio_to_zaru_oracle") / 5.0,
        "Fusion against oracle ZARU: {fusion}"
    );
    // The simulator knows its noise model: the floor is reported.
    method(s, "floor");
}

#[test]
fn on_the_real_log_the_product_beats_the_navigators_own_baselines() {
    let Some(log) = std::env::var_os("DRIFTLESS_ADIS16405") else {
        println!("SKIP: DRIFTLESS_ADIS16405 is not set");
        return;
    };
    let dir = Dir::new();
    let svg = dir.path("h.svg");
    let out = nav_eval(&[
        log.to_str().unwrap(),
        "--rate",
        "100",
        "--lsb",
        "0.05",
        "--motion",
        "stop-and-go,pedestrian",
        "--json",
        "--plot",
        svg.to_str().unwrap(),
    ]);
    let v = json(&out);
    let sections = v["sections"].as_array().unwrap();
    assert_eq!(sections.len(), 3, "two profiles and all");
    let all = &sections[2];
    assert_eq!(all["profile"], "all profiles");
    let chain = med(
        method(all, "denoise.wavelet -> predict.bias"),
        "rms_heading_deg",
    );
    for baseline in ["power-on", "ZARU detected", "x-io Fusion bias"] {
        let b = med(method(all, baseline), "rms_heading_deg");
        assert!(chain < b, "stages {chain} deg against {baseline} {b} deg");
    }
    let text = std::fs::read_to_string(&svg).expect("the plot");
    assert!(text.starts_with("<svg") && text.contains("ZARU oracle"));
}

/// `--model` adds the paper's chain twice: with the network, and with the model's AR(p) in its
/// place; the AR method is exactly the `predict.rbf` stage with `predictor = "ar"` that a
/// pipeline file would run.
#[test]
fn with_a_model_the_rbf_and_its_ar_are_judged_side_by_side() {
    let dir = Dir::new();
    let log = dir.path("static.csv");
    let model = dir.path("m.json");
    for args in [
        vec![
            "simulate",
            "--profile",
            "adis16405",
            "--axes",
            "1",
            "--seed",
            "7",
            "--duration",
            "200s",
            "-o",
            log.to_str().unwrap(),
        ],
        vec![
            "train",
            log.to_str().unwrap(),
            "--rate",
            "100",
            "--train",
            "15000",
            "--test",
            "2000",
            "-o",
            model.to_str().unwrap(),
        ],
    ] {
        let out = common::driftless(&args);
        assert!(out.status.success(), "{args:?}: {}", common::text(&out).1);
    }
    let ar_file = dir.write(
        "ar.toml",
        &PASS_THROUGH
            .replace("\"denoise.none\"", "\"denoise.wavelet\"")
            .replace("\"rad/s\"", "\"deg/s\"")
            .replace(
                "kind = \"predict.none\"",
                "kind = \"predict.rbf\"\nmodel = \"m.json\"\npredictor = \"ar\"",
            ),
    );
    let v = json(&nav_eval(&[
        "--sim",
        "adis16405",
        "--windows",
        "1",
        "--window",
        "3min",
        "--motion",
        "stop-and-go",
        "--json",
        "--model",
        model.to_str().unwrap(),
        "--pipeline",
        ar_file.to_str().unwrap(),
    ]));
    let s = &v["sections"][0];
    let rbf = method(s, "denoise.wavelet -> predict.rbf (stages)");
    let ar = method(s, "denoise.wavelet -> predict.rbf, predictor ar (stages)");
    let file = method(s, "ar.toml (denoise.wavelet -> predict.rbf -> publish)");
    for key in ["rms_heading_deg", "final_heading_deg", "rms_rate_degps"] {
        assert_eq!(med(ar, key), med(file, key), "{key}");
        assert!(med(ar, key).is_finite() && med(rbf, key).is_finite());
    }
    assert_ne!(
        med(ar, "rms_heading_deg"),
        med(rbf, "rms_heading_deg"),
        "the AR method ran the network"
    );
}

/// A log with the accelerometer beside the gyro (3 axes of the simulated ADIS16405 in deg/s,
/// its accelerometer in g, at rest): its columns are split off the rates and every case
/// carries them plus its motion's own force. The product's chain is judged twice, gyro only
/// and gyro+accel; the gyro-only figures do not change for the accelerometer's presence.
#[test]
fn an_accelerometer_log_is_judged_gyro_only_and_with_the_accelerometer() {
    use driftless::sim::force::{specific_force, Accelerometer, Attitude, ADIS16405_ACCEL};
    use driftless::sim::{SimConfig, Simulator};
    use std::fmt::Write as _;
    let dir = Dir::new();
    let cfg = SimConfig {
        seed: 11,
        ..SimConfig::profile("adis16405").unwrap()
    };
    let mut gyro = Simulator::new(&cfg).unwrap();
    let mut acc = Accelerometer::new(&ADIS16405_ACCEL, 100.0, 11).unwrap();
    let rest = specific_force(&Attitude::LEVEL, [0.0; 3]);
    let mut text = String::from("t,gyro_x,gyro_y,gyro_z,accel_x_g,accel_y_g,accel_z_g\n");
    for k in 0..30_000 {
        let g = gyro.next_sample().measured;
        let a = acc.measure(rest).map(|v| v / 9.80665);
        writeln!(
            text,
            "{},{},{},{},{},{},{}",
            k as f64 / 100.0,
            g[0],
            g[1],
            g[2],
            a[0],
            a[1],
            a[2]
        )
        .unwrap();
    }
    let log = dir.write("six.csv", &text);
    let common_args = [
        log.to_str().unwrap(),
        "--rate",
        "100",
        "--terms",
        "adis16405",
        "--characterise",
        "1min",
        "--window",
        "2min",
        "--motion",
        "stop-and-go",
        "--json",
    ];
    let accel = [
        "--accel-column",
        "accel_x_g",
        "--accel-column",
        "accel_y_g",
        "--accel-column",
        "accel_z_g",
        "--accel-units",
        "g",
    ];
    let columns = [
        "--column", "gyro_x", "--column", "gyro_y", "--column", "gyro_z",
    ];
    let with_accel = json(&nav_eval(&[&common_args[..], &accel[..]].concat()));
    let named = json(&nav_eval(
        &[&common_args[..], &columns[..], &accel[..]].concat(),
    ));
    let gyro_only = json(&nav_eval(&[&common_args[..], &columns[..]].concat()));
    assert_eq!(with_accel["axes"], 3, "the accelerometer is no gyro axis");
    assert_eq!(with_accel["sections"], named["sections"]);
    let s = &with_accel["sections"][0];
    let g = &gyro_only["sections"][0];
    let imu = method(s, "denoise.wavelet -> predict.bias (stages, gyro+accel)");
    for key in ["rms_heading_deg", "final_heading_deg", "rms_rate_degps"] {
        assert_eq!(
            med(method(s, "denoise.wavelet -> predict.bias (stages)"), key),
            med(method(g, "denoise.wavelet -> predict.bias (stages)"), key),
            "{key}"
        );
        assert!(med(imu, key).is_finite(), "{key}");
    }
    let labels = |v: &Value| -> Vec<String> {
        v["sections"][0]["methods"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m["method"].as_str().unwrap().to_string())
            .collect()
    };
    assert!(!labels(&gyro_only).iter().any(|l| l.contains("gyro+accel")));
    let l = labels(&with_accel);
    let at = l.iter().position(|x| x.ends_with("(stages)")).unwrap();
    assert!(
        l[at + 1].ends_with("(stages, gyro+accel)"),
        "side by side: {l:?}"
    );
}

#[test]
fn bad_input_is_one_line_and_exit_2() {
    let dir = Dir::new();
    let fast = dir.write("fast.toml", &PASS_THROUGH.replace("100.0", "1000.0"));
    let short = dir.write("short.csv", "t,x\n0,0.1\n0.01,0.2\n");
    let cases: Vec<(Vec<&str>, String)> = vec![
        (
            vec!["--sim", "adis16405", "--pipeline", fast.to_str().unwrap()],
            format!(
                "{}:3:11: rate_hz is 1000 Hz but the log is 100 Hz",
                fast.display()
            ),
        ),
        (
            vec!["--sim", "adis16405", "--motion", "walk"],
            "--motion: unknown motion profile 'walk'".into(),
        ),
        (
            vec!["--sim", "gyro9"],
            "--sim: unknown profile 'gyro9'".into(),
        ),
        (
            vec![short.to_str().unwrap(), "--rate", "100"],
            "2 rows, but the characterisation".into(),
        ),
        (
            vec![short.to_str().unwrap()],
            "--rate is needed for a CSV log".into(),
        ),
        (
            vec![
                "--sim",
                "adis16405",
                "--model",
                "a.json",
                "--model",
                "b.json",
            ],
            "--model: 2 models for 3 axes".into(),
        ),
        (
            vec![
                "--sim",
                "adis16405",
                "--window",
                "10s",
                "--judge-from",
                "10s",
            ],
            "--judge-from 10s leaves nothing of a 1000-sample window to judge".into(),
        ),
        (
            vec!["--sim", "adis16405", "--terms", "nope"],
            "--terms: no default bias terms for 'nope'".into(),
        ),
        (
            vec!["--sim", "adis16405", "--accel-column", "ax"],
            "--accel-column: give the accelerometer's 3 columns (x, y, z), not 1".into(),
        ),
        (
            vec![
                short.to_str().unwrap(),
                "--rate",
                "100",
                "--accel-column",
                "x",
                "--accel-column",
                "nope",
                "--accel-column",
                "x",
            ],
            "no column \"nope\" (--accel-column)".into(),
        ),
        (
            vec![
                short.to_str().unwrap(),
                "--rate",
                "100",
                "--accel-column",
                "x",
                "--accel-column",
                "x",
                "--accel-column",
                "x",
                "--accel-units",
                "mg",
            ],
            "--accel-units mg: m/s^2 or g".into(),
        ),
    ];
    for (args, want) in cases {
        let out = nav_eval(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(&want), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(out.stdout.is_empty(), "{args:?}");
    }
}

#[test]
fn judge_from_starts_the_integration_later_and_runs_every_method_from_the_first_sample() {
    let run = |from: Option<&str>| {
        let mut args = vec![
            "--sim",
            "adis16405",
            "--windows",
            "1",
            "--window",
            "60s",
            "--json",
        ];
        if let Some(f) = from {
            args.extend(["--judge-from", f]);
        }
        json(&nav_eval(&args))
    };
    let (all, later) = (run(None), run(Some("3s")));
    assert_eq!(all["judge_from_s"].as_f64(), Some(0.0));
    assert_eq!(later["judge_from_s"].as_f64(), Some(3.0));
    let raw = |v: &Value| med(method(&v["sections"][0], "raw"), "rms_heading_deg");
    // The raw rate's error grows from where the integration starts: judged later, a different
    // heading.
    assert!(raw(&all).is_finite() && raw(&later).is_finite());
    assert_ne!(raw(&all), raw(&later));
}

/// The wheel odometry's row (`--odometry`) against the true stops alone: on the vehicle
/// profile the median RMS heading is at most half of the stops alone's (measured 0.31x on
/// the simulator's 6 windows, 0.36x on the real log: the margin is 0.45 here, 0.40 on the
/// real log), the robustness variants are not worse than the stops alone at the median, and
/// without the slip test the odometry is far worse (the test is what makes it safe).
#[test]
fn the_odometry_halves_the_heading_error_of_the_true_stops_alone() {
    let check = |v: &Value, bound: f64| {
        let section = &v["sections"].as_array().unwrap()[0];
        assert_eq!(section["profile"], "vehicle");
        let stops = med(method(section, "KF oracle"), "rms_heading_deg");
        let odo = med(
            method(section, "KF true stops + odometry"),
            "rms_heading_deg",
        );
        assert!(
            odo <= bound * stops,
            "odometry {odo} deg against the true stops alone {stops} deg"
        );
        let rows = v["odometry"].as_array().unwrap();
        assert_eq!(rows.len(), 7, "{rows:?}");
        let ratio = |name: &str| {
            rows.iter()
                .find(|r| r["method"] == name)
                .unwrap_or_else(|| panic!("no {name}"))["ratio_to_stops"]["median"]
                .as_f64()
                .unwrap()
        };
        for variant in [
            "",
            ", scale 3%",
            ", 10 slips",
            ", latency 100 ms",
            ", stops at mid-window",
        ] {
            let r = ratio(&format!("KF true stops + odometry{variant}"));
            assert!(r <= 1.02, "{variant}: {r}x the stops alone at the median");
        }
        let blind = ratio("KF true stops + odometry, no slip test");
        assert!(blind > 1.5, "without the slip test: {blind}x");
    };
    let out = nav_eval(&[
        "--sim",
        "adis16405",
        "--windows",
        "6",
        "--motion",
        "vehicle",
        "--odometry",
        "--json",
    ]);
    check(&json(&out), 0.45);
    let Some(log) = std::env::var_os("DRIFTLESS_ADIS16405") else {
        println!("SKIP (real log): DRIFTLESS_ADIS16405 is not set");
        return;
    };
    let out = nav_eval(&[
        log.to_str().unwrap(),
        "--rate",
        "100",
        "--lsb",
        "0.05",
        "--motion",
        "vehicle",
        "--odometry",
        "--json",
    ]);
    check(&json(&out), 0.40);
}
