//! One duration parser on every command (`src/cli/duration.rs`): the forms one command takes,
//! the others take too, and a bad value is one line naming it and the accepted forms, exit 2.

mod common;

use common::{driftless, text, Dir, Prefix};
use std::process::Output;

/// Exit 2, one `driftless: error:` line holding the value, the option and the forms.
fn assert_refused(o: &Output, value: &str, option: &str) {
    let (_, err) = text(o);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(err.starts_with("driftless: error: "), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        err.contains(&format!("\"{value}\"")),
        "value {value}: {err}"
    );
    assert!(err.contains(option), "option {option}: {err}");
    assert!(
        err.contains("90min") && err.contains("plain number of seconds"),
        "the accepted forms: {err}"
    );
}

/// A pipeline replaying `data.csv` (500 rows) as fast as it can, once: it ends by itself.
const REPLAY: &str = r#"
name = "d"
rate_hz = 1000.0
input_units = "deg/s"
report_interval_s = 60.0

[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "d/raw"
file = "data.csv"
time_column = "t"
pace = "asap"

[[stage]]
name = "publish"
kind = "publish"
input = "d/raw"
output = "d/corrected"
"#;

#[test]
fn run_takes_the_forms_simulate_took() {
    let prefix = Prefix::new("dur");
    let dir = Dir::with_csv(500);
    let file = dir.write("p.toml", REPLAY);
    let file = file.to_str().unwrap();
    // `90min` was refused by `run` before; the replay ends long before.
    for d in ["90min", "1h 30min", "0.5h", "600"] {
        let o = driftless(&[
            "run",
            file,
            "--prefix",
            &prefix.0,
            "--quiet",
            "--duration",
            d,
        ]);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(0), "--duration {d}: {err}");
    }
    for bad in ["0s", "-1s", "soon", "3 weeks ago"] {
        let o = driftless(&["run", file, "--prefix", &prefix.0, "--duration", bad]);
        assert_refused(&o, bad, "--duration");
    }
    assert!(prefix.leftovers().is_empty(), "{:?}", prefix.leftovers());
}

#[test]
fn simulate_takes_the_forms_run_took() {
    let dir = Dir::new();
    let out = dir.path("s.csv");
    let out = out.to_str().unwrap();
    // `500ms` was refused by `simulate` before.
    for (d, rows) in [("500ms", 50), ("1.5s", 150), ("2", 200), ("0.01min", 60)] {
        let o = driftless(&[
            "simulate",
            "--N",
            "1",
            "--rate",
            "100",
            "--duration",
            d,
            "-o",
            out,
        ]);
        assert!(o.status.success(), "--duration {d}: {}", text(&o).1);
        let written = std::fs::read_to_string(out).unwrap();
        assert_eq!(written.lines().count(), rows + 1, "--duration {d}");
    }
    for bad in ["0h", "-5s", "3 weeks ago", "inf"] {
        let o = driftless(&["simulate", "--N", "1", "--duration", bad, "-o", out]);
        assert_refused(&o, bad, "--duration");
    }
}

#[test]
fn tap_nav_eval_and_train_use_the_same_parser() {
    assert_refused(
        &driftless(&["tap", "x/y", "--duration", "0ms"]),
        "0ms",
        "--duration",
    );
    assert_refused(
        &driftless(&[
            "nav-eval",
            "--sim",
            "adis16405",
            "--window",
            "10 minutes ago",
        ]),
        "10 minutes ago",
        "--window",
    );
    let dir = Dir::new();
    let log = dir.write("log.csv", "x\n0.1\n0.2\n");
    assert_refused(
        &driftless(&[
            "nav-eval",
            log.to_str().unwrap(),
            "--rate",
            "100",
            "--characterise",
            "0",
        ]),
        "0",
        "--characterise",
    );
    let model = dir.path("m.json");
    for (option, bad) in [("--horizon", "-1"), ("--still-window", "1/2s")] {
        let o = driftless(&[
            "train",
            log.to_str().unwrap(),
            "--rate",
            "50",
            option,
            bad,
            "-o",
            model.to_str().unwrap(),
        ]);
        assert_refused(&o, bad, option);
    }
    // A unit the old train options did not take: accepted, so the failure is the short log's.
    let o = driftless(&[
        "train",
        log.to_str().unwrap(),
        "--rate",
        "50",
        "--still-window",
        "500ms",
        "--horizon",
        "2s",
        "-o",
        model.to_str().unwrap(),
    ]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(!err.contains("duration"), "{err}");
}
