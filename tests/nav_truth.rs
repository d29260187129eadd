//! `driftless nav-eval --truth FILE.csv`, run as a user runs it: a truth file that writes out a
//! built-in profile's motion gives that profile's figures, its still columns are the oracle's
//! stops, and a bad file is one line with its place, exit 2.

mod common;

use common::{driftless, text, Dir};
use driftless::nav::{generate, Profile};
use serde_json::Value;
use std::path::Path;

const RATE: f64 = 100.0;
/// Two minutes: one window per axis of the simulator's noise, quick to run.
const SECONDS: f64 = 120.0;

fn nav_eval_json(args: &[&str]) -> Value {
    let mut all = vec!["nav-eval"];
    all.extend_from_slice(args);
    let out = driftless(&all);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{all:?}: {stderr}");
    serde_json::from_str(&stdout).expect("one JSON document")
}

/// The figures of every method of a section, in order: (label, rms, final, max, rate).
fn figures(section: &Value) -> Vec<(String, [f64; 4])> {
    section["methods"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            let f = |k: &str| m[k]["median"].as_f64().unwrap();
            (
                m["method"].as_str().unwrap().to_string(),
                [
                    f("rms_heading_deg"),
                    f("final_heading_deg"),
                    f("max_heading_deg"),
                    f("rms_rate_degps"),
                ],
            )
        })
        .collect()
}

fn method<'a>(section: &'a Value, name: &str) -> &'a Value {
    section["methods"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["method"] == name)
        .unwrap_or_else(|| panic!("no method {name}"))
}

/// The stop-and-go profile's motion of the first window of each of the simulator's three axes
/// (seeds 0, 1, 2 as nav-eval draws them), as a truth file: time, x, y, z and, when asked, one
/// still column per axis. Rust prints the shortest text that reads back to the same f64.
fn profile_as_truth(dir: &Dir, name: &str, still_columns: bool) -> std::path::PathBuf {
    let m: Vec<_> = (0..3)
        .map(|a| generate(Profile::StopAndGo, RATE, SECONDS, a).unwrap())
        .collect();
    let mut s = String::from("t,x,y,z");
    if still_columns {
        s.push_str(",still_x,still_y,still_z");
    }
    s.push('\n');
    for k in 0..m[0].truth.len() {
        s.push_str(&format!("{:.2}", k as f64 / RATE));
        for axis in &m {
            s.push_str(&format!(",{}", axis.truth[k]));
        }
        if still_columns {
            for axis in &m {
                s.push_str(if axis.still[k] { ",1" } else { ",0" });
            }
        }
        s.push('\n');
    }
    dir.write(name, &s)
}

fn sim_with(extra: &[&str]) -> Value {
    let mut args = vec!["--sim", "adis16405", "--windows", "1", "--json"];
    args.extend_from_slice(extra);
    nav_eval_json(&args)
}

#[test]
fn a_truth_file_of_a_profiles_motion_gives_the_profiles_figures() {
    let dir = Dir::new();
    let with_still = profile_as_truth(&dir, "still.csv", true);
    let without = profile_as_truth(&dir, "zero.csv", false);
    let profile = sim_with(&["--motion", "stop-and-go", "--window", "2min"]);
    // The gyro+accel chain differs by design: a truth file's motion turns in place, so its
    // accelerometer reads no vehicle force, and the profile's does.
    let gyro_only = |f: Vec<(String, [f64; 4])>| -> Vec<(String, [f64; 4])> {
        let n = f.len();
        let kept: Vec<_> = f
            .into_iter()
            .filter(|(m, _)| !m.contains("gyro+accel"))
            .collect();
        assert_eq!(kept.len() + 1, n, "one gyro+accel chain");
        kept
    };
    let want = gyro_only(figures(&profile["sections"][0]));
    assert!(want.len() >= 8, "{want:?}");
    for truth in [&with_still, &without] {
        // No --window: the file's 12,000 rows are the window.
        let v = sim_with(&["--truth", truth.to_str().unwrap()]);
        let name = truth.file_name().unwrap().to_string_lossy();
        assert_eq!(v["sections"][0]["profile"], format!("truth {name}"));
        assert_eq!(v["window_s"], profile["window_s"]);
        assert_eq!(gyro_only(figures(&v["sections"][0])), want, "{name}");
    }
    // One rate column for every axis is another motion on two of the three axes: other figures.
    let x_only = dir.write(
        "x.csv",
        &std::fs::read_to_string(&without)
            .unwrap()
            .lines()
            .map(|l| l.split(',').take(2).collect::<Vec<_>>().join(","))
            .collect::<Vec<_>>()
            .join("\n"),
    );
    let v = sim_with(&["--truth", x_only.to_str().unwrap()]);
    assert_ne!(figures(&v["sections"][0]), want);
}

#[test]
fn the_still_column_is_the_oracles_stops() {
    // 60 s: still 20 s, a 10 deg/s turn for 20 s, still 20 s. A still column that calls the
    // turn's middle still hands oracle ZARU the turn as bias; without it, still is rate == 0.
    let dir = Dir::new();
    let write = |name: &str, lie: bool| {
        let mut s = String::from("rate,still\n");
        for k in 0..6000 {
            let rate = if (2000..4000).contains(&k) { 10.0 } else { 0.0 };
            let still = rate == 0.0 || (lie && (2500..3500).contains(&k));
            s.push_str(&format!("{rate},{}\n", u8::from(still)));
        }
        dir.write(name, &s)
    };
    let honest = write("honest.csv", false);
    let lying = write("lying.csv", true);
    let zaru = |truth: &Path| -> f64 {
        let v = sim_with(&["--truth", truth.to_str().unwrap()]);
        method(&v["sections"][0], "ZARU oracle")["rms_heading_deg"]["median"]
            .as_f64()
            .unwrap()
    };
    let (good, bad) = (zaru(&honest), zaru(&lying));
    // Honest stops: a fraction of a degree. A 10 deg/s "bias" held for the last 15 s: ~100 deg.
    assert!(good < 1.0, "oracle ZARU on the true stops: {good} deg");
    assert!(bad > 50.0, "oracle ZARU told the turn is still: {bad} deg");
}

#[test]
fn a_bad_truth_file_is_one_line_with_its_place_and_exit_2() {
    let dir = Dir::new();
    let rows = |n: usize, line: &dyn Fn(usize) -> String| -> String {
        let mut s = String::from("t,rate,still\n");
        for k in 0..n {
            s.push_str(&line(k));
            s.push('\n');
        }
        s
    };
    let ok = |k: usize| format!("{:.2},0,1", k as f64 / RATE);
    let short = dir.write("short.csv", &rows(11_999, &ok));
    let word = dir.write(
        "word.csv",
        &rows(500, &|k| {
            if k == 41 {
                format!("{:.2},fast,0", k as f64 / RATE)
            } else {
                ok(k)
            }
        }),
    );
    let missing = dir.write(
        "missing.csv",
        &rows(500, &|k| {
            if k == 7 {
                format!("{:.2},0", k as f64 / RATE)
            } else {
                ok(k)
            }
        }),
    );
    let half = dir.write(
        "half.csv",
        &rows(500, &|k| format!("{:.2},0,{}", k as f64 / RATE, k % 3)),
    );
    let slow = dir.write(
        "slow.csv",
        &rows(500, &|k| format!("{:.2},0,1", k as f64 / 50.0)),
    );
    let two = dir.write("two.csv", "x,y\n0,0\n0,0\n0,0\n");
    let no_rate = dir.write("none.csv", "t,still\n0,1\n0.01,1\n");
    let p = |f: &Path| f.to_str().unwrap().to_string();
    let cases: Vec<(Vec<String>, String)> = vec![
        (
            vec!["--truth".into(), p(&short), "--window".into(), "2min".into()],
            format!(
                "{}: 11999 rows, but a window of 120 s at 100 Hz is 12000 samples",
                short.display()
            ),
        ),
        (
            vec!["--truth".into(), p(&word)],
            format!("{}:43:6: column 'rate': 'fast' is not a number", word.display()),
        ),
        (
            vec!["--truth".into(), p(&missing)],
            format!(
                "{}:9:1: this row has 2 fields, the first row has 3",
                missing.display()
            ),
        ),
        (
            vec!["--truth".into(), p(&half)],
            format!(
                "{}:4:8: column 'still': 2 is neither 0 (moving) nor 1 (still)",
                half.display()
            ),
        ),
        (
            vec!["--truth".into(), p(&slow)],
            format!(
                "{}:3:1: column 't': time 0.02 s, but row 2 of a file at the log's 100 Hz is at 0.01 s",
                slow.display()
            ),
        ),
        (
            vec!["--truth".into(), p(&two)],
            format!(
                "{}: 2 rate columns (x, y) for 3 axes",
                two.display()
            ),
        ),
        (
            vec!["--truth".into(), p(&no_rate)],
            format!("{}: no rate column", no_rate.display()),
        ),
        (
            vec!["--truth".into(), p(&dir.path("absent.csv"))],
            format!("{}: No such file", dir.path("absent.csv").display()),
        ),
        (
            vec!["--truth".into(), p(&two), "--motion".into(), "vehicle".into()],
            "cannot be used with".into(),
        ),
    ];
    for (args, want) in cases {
        let mut all = vec!["nav-eval", "--sim", "adis16405", "--windows", "1"];
        all.extend(args.iter().map(String::as_str));
        let out = driftless(&all);
        let (stdout, stderr) = text(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains(&want),
            "{args:?}: want {want:?}, got {stderr}"
        );
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
        assert!(stdout.is_empty(), "{args:?}");
    }
}

#[test]
fn a_truth_longer_than_the_log_is_refused() {
    // A log of 90 s holds no window of the truth's 120 s after 10 s of characterisation.
    let dir = Dir::new();
    let mut log = String::from("gyro\n");
    for k in 0..9000 {
        log.push_str(&format!(
            "{}\n",
            0.1 + 0.05 * ((k * 7919 % 13) as f64 - 6.0)
        ));
    }
    let log = dir.write("log.csv", &log);
    let truth = profile_as_truth(&dir, "t.csv", false);
    let out = driftless(&[
        "nav-eval",
        log.to_str().unwrap(),
        "--rate",
        "100",
        "--terms",
        "adis16405",
        "--characterise",
        "10s",
        "--truth",
        truth.to_str().unwrap(),
    ]);
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(
            "9000 rows, but the characterisation (1000) and one window (12000) need 13000"
        ),
        "{stderr}"
    );
}
