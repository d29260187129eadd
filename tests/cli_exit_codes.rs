//! One rule for exit codes, every kind of command (docs/commands.md, "Exit codes"): 0 done
//! (and --help), 1 a run-time failure (nothing to read, already running), 2 bad usage or bad
//! input. Failures are one `driftless: error:` line on stderr, never a panic.

mod common;

use common::{driftless, subcommands, Dir, Prefix};
use std::process::Output;

/// Exit `code`, nothing on stdout, one `driftless: error:` line containing `needle`.
fn assert_fails(o: &Output, code: i32, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(code), "stderr: {err}");
    assert!(
        o.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(err.starts_with("driftless: error: "), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains(needle), "'{needle}' not in: {err}");
}

#[test]
fn help_and_version_exit_0_on_stdout() {
    let commands = subcommands();
    assert!(commands.len() >= 14, "{commands:?}");
    // Listed with and without the `zenoh` feature: without it, it says how to build it.
    assert!(commands.iter().any(|c| c == "bridge"), "{commands:?}");
    for cmd in &commands {
        let o = driftless(&[cmd, "--help"]);
        assert_eq!(o.status.code(), Some(0), "{cmd} --help");
        assert!(
            String::from_utf8_lossy(&o.stdout).contains("Usage: driftless"),
            "{cmd}"
        );
        assert!(o.stderr.is_empty(), "{cmd}");
    }
    let o = driftless(&["--version"]);
    assert_eq!(o.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&o.stdout).starts_with("driftless "));
}

#[test]
fn usage_errors_exit_2_in_one_line_for_every_command() {
    for cmd in &subcommands() {
        let o = driftless(&[cmd, "--no-such-option"]);
        assert_fails(&o, 2, "'--no-such-option'");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(&format!("driftless {cmd} --help")), "{err}");
    }
    assert_fails(&driftless(&["frobnicate"]), 2, "'frobnicate'");
    assert_fails(
        &driftless(&["simulate", "--N", "1"]),
        2,
        "--output <OUT.csv>",
    );
    assert_fails(
        &driftless(&["tap", "x/y", "--count", "many"]),
        2,
        "'many' for '--count <COUNT>'",
    );
}

#[test]
fn bad_input_exits_2_for_offline_commands() {
    let dir = Dir::new();
    let missing = dir.path("missing.csv");
    let missing = missing.to_str().unwrap();
    let model = dir.path("missing-model.json");
    let model = model.to_str().unwrap();
    for args in [
        vec!["denoise", missing],
        vec!["allan", missing, "--rate", "100"],
        vec!["train", missing, "--rate", "100", "-o", model],
        vec!["eval", missing, "--model", model],
        vec!["nav-eval", missing, "--rate", "100"],
        vec!["validate", missing],
    ] {
        assert_fails(&driftless(&args), 2, "missing");
    }
    let nowhere = dir.path("no/such/dir/out.csv");
    assert_fails(
        &driftless(&[
            "simulate",
            "--N",
            "1",
            "--duration",
            "1s",
            "-o",
            nowhere.to_str().unwrap(),
        ]),
        2,
        "no/such/dir",
    );
}

#[test]
fn bad_input_exits_2_for_daemon_commands() {
    let dir = Dir::new();
    let bad = dir.write("bad.toml", "name = \"b\"\nbogus = 1\n");
    let bad = bad.to_str().unwrap();
    assert_fails(&driftless(&["run", bad]), 2, "bad.toml:");
    assert_fails(&driftless(&["stats", bad]), 2, "bad.toml:");
    assert_fails(&driftless(&["tap", ""]), 2, "invalid service name");
    assert_fails(
        &driftless(&["tap", "x/y", "--prefix", "a/b"]),
        2,
        "invalid iceoryx2 prefix",
    );
    assert_fails(
        &driftless(&["list", "--prefix", "a/b"]),
        2,
        "invalid iceoryx2 prefix",
    );
    assert_fails(
        &driftless(&["list", "--stats-wait", "0s"]),
        2,
        "not a positive duration",
    );
    assert_fails(
        &driftless(&["relay", "--input", "", "--output", "o/p"]),
        2,
        "--input",
    );
}

/// Built without the `zenoh` feature, `bridge` says how to get it (the feature's own tests are
/// tests/bridge.rs).
#[cfg(not(feature = "zenoh"))]
#[test]
fn bridge_without_the_zenoh_feature_says_how_to_build_it() {
    assert_fails(
        &driftless(&["bridge", "demo/corrected"]),
        2,
        "cargo build --release --features zenoh",
    );
}

#[test]
fn nothing_to_read_exits_1_for_tap_and_stats_alike() {
    let prefix = Prefix::new("exit1");
    let dir = Dir::new();
    let pipeline = dir.write(
        "p.toml",
        r#"
name = "e"
rate_hz = 100.0

[[stage]]
name = "sim"
kind = "ingest.sim"
output = "e/raw"

[[stage]]
name = "publish"
kind = "publish"
input = "e/raw"
output = "e/corrected"
"#,
    );
    let o = driftless(&["validate", pipeline.to_str().unwrap()]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let o = driftless(&[
        "stats",
        pipeline.to_str().unwrap(),
        "--prefix",
        &prefix.0,
        "--once",
    ]);
    assert_fails(&o, 1, "is it running?");
    let o = driftless(&["tap", "e/corrected", "--prefix", &prefix.0, "--count", "1"]);
    assert_fails(&o, 1, "is the pipeline running?");
    assert!(prefix.leftovers().is_empty(), "{:?}", prefix.leftovers());
}
