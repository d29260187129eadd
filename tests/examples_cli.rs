//! The examples' command lines are clap's, as `driftless`'s: `--help` exits 0, a usage error 2,
//! and they still do their job (raw_driver publishes what nav_subscriber receives).

mod common;

use common::Prefix;
use std::path::PathBuf;
use std::process::{Command, Output};

const EXAMPLES: [&str; 3] = ["nav_subscriber", "raw_driver", "external_stage"];

/// The example, built up to date: `cargo test` builds the examples beside the test binaries,
/// but a run of this test alone (`cargo test --test examples_cli`) does not, and could find a
/// stale one; so cargo is asked for it (same target directory and profile; a no-op when fresh).
fn example(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test binary path");
    let profile_dir = exe
        .parent()
        .and_then(|d| d.parent())
        .expect("target/PROFILE");
    let path = profile_dir.join("examples").join(name);
    // Once per example and test process.
    static BUILT: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
    let mut built = BUILT.lock().unwrap_or_else(|e| e.into_inner());
    if built.iter().any(|b| b == name) {
        return path;
    }
    let target = profile_dir.parent().expect("target dir");
    let mut build = Command::new(env!("CARGO"));
    build
        .args(["build", "--quiet", "--example", name, "--target-dir"])
        .arg(target)
        .current_dir(env!("CARGO_MANIFEST_DIR"));
    if profile_dir.file_name().is_some_and(|p| p == "release") {
        build.arg("--release");
    }
    let status = build.status().expect("cargo runs");
    assert!(status.success(), "cargo build --example {name}");
    built.push(name.to_string());
    path
}

fn run(name: &str, args: &[&str]) -> Output {
    run_built(&example(name), args)
}

/// Run an example already built: no wait on [`example`]'s lock, which the other test can hold
/// for a whole build.
fn run_built(exe: &std::path::Path, args: &[&str]) -> Output {
    Command::new(exe)
        .args(args)
        .env_remove("DRIFTLESS_IOX2_PREFIX")
        .output()
        .expect("the example runs")
}

#[test]
fn help_exits_0_and_usage_errors_exit_2() {
    for name in EXAMPLES {
        let o = run(name, &["--help"]);
        let out = String::from_utf8_lossy(&o.stdout);
        assert_eq!(o.status.code(), Some(0), "{name} --help: {out}");
        assert!(out.contains(&format!("Usage: {name}")), "{name}: {out}");
        for option in ["--prefix", "--help"] {
            assert!(out.contains(option), "{name}: {option} in {out}");
        }
        let o = run(name, &["--bogus"]);
        assert_eq!(o.status.code(), Some(2), "{name} --bogus");
        assert!(String::from_utf8_lossy(&o.stderr).contains("'--bogus'"));
        let o = run(name, &["--prefix", "a/b"]);
        assert_eq!(
            o.status.code(),
            Some(2),
            "{name}: a bad prefix is bad usage"
        );
    }
    for option in ["--service", "--duration", "--report"] {
        let out = String::from_utf8_lossy(&run("nav_subscriber", &["--help"]).stdout).to_string();
        assert!(out.contains(option), "nav_subscriber {option}: {out}");
    }
    for option in ["--service", "--rate", "--duration"] {
        let out = String::from_utf8_lossy(&run("raw_driver", &["--help"]).stdout).to_string();
        assert!(out.contains(option), "raw_driver {option}: {out}");
    }
    for option in ["--input", "--output", "--scale", "--offset", "--count"] {
        let out = String::from_utf8_lossy(&run("external_stage", &["--help"]).stdout).to_string();
        assert!(out.contains(option), "external_stage {option}: {out}");
    }
    for bad in [
        &["--rate", "0"][..],
        &["--rate", "-5"],
        &["--duration", "soon"],
    ] {
        let o = run("raw_driver", bad);
        assert_eq!(o.status.code(), Some(2), "raw_driver {bad:?}");
    }
    let o = run("nav_subscriber", &["--duration", "0s"]);
    assert_eq!(o.status.code(), Some(2));
}

/// The external-sensor chain with nothing in the middle: raw_driver -> daemon -> nav_subscriber.
const CHAIN: &str = r#"
name = "ex"
rate_hz = 200.0
axes = 3
input_units = "deg/s"
report_interval_s = 60.0

[[stage]]
name = "sensor"
kind = "ingest.iceoryx2"
input = "ex/sensor"
output = "ex/raw"
poll_timeout_us = 1000

[[stage]]
name = "publish"
kind = "publish"
input = "ex/raw"
output = "ex/corrected"
"#;

#[test]
fn raw_driver_feeds_the_daemon_and_nav_subscriber_reads_it() {
    let prefix = Prefix::new("examples");
    let dir = common::Dir::new();
    let pipeline = dir.write("p.toml", CHAIN);
    let report = dir.path("nav.json");
    // Both built before the subscriber's 3 s start: the driver must not wait for a build.
    let (nav_bin, driver_bin) = (example("nav_subscriber"), example("raw_driver"));
    let mut daemon = common::start(&pipeline, &prefix, &[]);
    common::wait_ready(&prefix, "ex/stats", &mut daemon);
    let nav = Command::new(nav_bin)
        .args(["--prefix", &prefix.0, "--service", "ex/corrected"])
        .args(["--duration", "3s", "--report"])
        .arg(&report)
        .output_later();
    // What is published before it subscribes is not seen (and not counted as lost): wait for
    // its node (a loaded machine can take seconds to start it), then for its port.
    let node = format!("nav-subscriber-{}", nav.id());
    let until = std::time::Instant::now() + std::time::Duration::from_secs(30);
    while driftless::transport::Transport::live_nodes_named(&prefix.0, &node).unwrap_or(0) == 0 {
        assert!(
            std::time::Instant::now() < until,
            "nav_subscriber never started"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    std::thread::sleep(std::time::Duration::from_millis(300));
    let driver = run_built(
        &driver_bin,
        &[
            "--prefix",
            &prefix.0,
            "--service",
            "ex/sensor",
            "--rate",
            "200",
            "--duration",
            "1.5s",
        ],
    );
    let err = String::from_utf8_lossy(&driver.stderr);
    assert_eq!(driver.status.code(), Some(0), "{err}");
    let published: u64 = err
        .split_whitespace()
        .nth(2)
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("count in {err}"));
    assert!((250..=301).contains(&published), "{err}");
    let nav = nav.wait_with_output().expect("nav_subscriber");
    let nav_err = String::from_utf8_lossy(&nav.stderr);
    assert_eq!(nav.status.code(), Some(0), "{nav_err}");
    let summary = String::from_utf8_lossy(&nav.stdout);
    assert!(summary.starts_with("nav_subscriber: "), "{summary}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let received = v["received"].as_u64().unwrap();
    assert!(
        received <= published && received >= published / 2,
        "{received} of {published}: {v}"
    );
    assert_eq!(v["lost"], 0, "{v}");
    assert_eq!(v["epochs"], 1, "one daemon run, one driver run: {v}");
    // The driver's accelerometer rides beside every rate: gravity's magnitude, give or take
    // the simulated motion and noise.
    assert_eq!(v["with_accel"], v["received"], "{v}");
    let g = v["accel_mean_norm_m_s2"].as_f64().unwrap();
    assert!((9.0..10.6).contains(&g), "mean |a| {g}: {v}");
    // No predict stage: the bias uncertainty is "not provided" (-1), so no heading sigma.
    assert_eq!(v["heading_sd_deg"], serde_json::Value::Null, "{v}");
    assert!(summary.contains("+- ? (not provided)"), "{summary}");
    common::signal(&daemon, 2);
    let (code, err) = common::finish(daemon, std::time::Duration::from_secs(10));
    assert_eq!(code, Some(0), "{err}");
    assert!(prefix.leftovers().is_empty(), "{:?}", prefix.leftovers());
}

/// Spawn with captured output, to be collected after the process ends.
trait OutputLater {
    fn output_later(&mut self) -> std::process::Child;
}

impl OutputLater for Command {
    fn output_later(&mut self) -> std::process::Child {
        self.stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("spawn")
    }
}
