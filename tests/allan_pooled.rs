//! `driftless allan` over several logs, through the real binary: the logs pool per tau, never
//! joined. The goal test cuts the real ADIS16405 6-axis log (../shared/data, never copied into the
//! repository) into five pieces, each shifted by its own constant bias (as five power-ups would
//! be): pooled, they give the uncut log's N, B and K within their intervals; joined end to end,
//! they do not (the steps read as a huge bias instability or rate random walk).

mod common;

use common::{driftless, simulated_log};
use driftless::io::read_table;
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Output;

const VAR: &str = "DRIFTLESS_ADIS16405_6AXIS";
const DEFAULT: &str = "/work/shared/data/adis16405-imu1-static-100hz-6axis.csv.gz";
const GYRO: [&str; 3] = ["gyro_x_degps", "gyro_y_degps", "gyro_z_degps"];
/// Each piece's bias shift (deg/s): steps of several deg/s, three orders of magnitude above the
/// unit's bias instability (about 0.01 deg/s).
const OFFSETS: [f64; 5] = [0.0, 3.0, -2.5, 5.0, -4.0];
/// The terms compared.
const TERMS: [&str; 3] = ["N", "B", "K"];

fn log_path() -> Option<PathBuf> {
    let path = std::env::var_os(VAR).map_or_else(|| PathBuf::from(DEFAULT), PathBuf::from);
    if path.exists() {
        Some(path)
    } else {
        println!(
            "skipped: {} is absent; set {VAR} to the ADIS16405 6-axis log, e.g. {VAR}=../shared/data/adis16405-imu1-static-100hz-6axis.csv.gz",
            path.display()
        );
        None
    }
}

fn stdout(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// `driftless allan` on `inputs`, the three gyro axes at 100 Hz, with `extra`.
fn allan(inputs: &[&Path], extra: &[&str]) -> String {
    let mut args: Vec<String> = vec!["allan".into()];
    args.extend(inputs.iter().map(|p| p.display().to_string()));
    args.extend(["--rate", "100"].map(String::from));
    for c in GYRO {
        args.extend(["--column".to_string(), c.to_string()]);
    }
    args.extend(extra.iter().map(|s| s.to_string()));
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    stdout(&driftless(&refs))
}

/// A fitted term: value and interval (datasheet units), or None where not identifiable.
type Term = Option<(f64, f64, f64)>;

/// Per axis, the fitted N, B, K of `--json`.
fn terms(inputs: &[&Path]) -> (Value, Vec<[Term; 3]>) {
    let v: Value = serde_json::from_str(&allan(inputs, &["--json"])).unwrap();
    let per_axis = v["columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            TERMS.map(|t| {
                let e = &c["terms"][t];
                e.as_object()
                    .map(|_| (num(&e["value"]), num(&e["lo"]), num(&e["hi"])))
            })
        })
        .collect();
    (v, per_axis)
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// `--stage`'s `arw` and `bias_instability` (datasheet units).
fn stage(inputs: &[&Path]) -> (String, f64, f64) {
    let text = allan(inputs, &["--stage"]);
    let key = |k: &str| -> f64 {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("{k} = ")))
            .unwrap_or_else(|| panic!("no {k} in:\n{text}"));
        line[k.len() + 3..].parse().unwrap()
    };
    let (n, b) = (key("arw"), key("bias_instability"));
    (text, n, b)
}

/// Whether two fits of one term agree: both identified with overlapping intervals, or neither.
fn agree(a: Term, b: Term) -> bool {
    match (a, b) {
        (Some((_, alo, ahi)), Some((_, blo, bhi))) => alo <= bhi && blo <= ahi,
        (None, None) => true,
        _ => false,
    }
}

fn shown(t: Term) -> String {
    match t {
        Some((v, lo, hi)) => format!("{v:.4} [{lo:.4}, {hi:.4}]"),
        None => "not identified".into(),
    }
}

/// Whether every axis's N, B and K of `other` agree with `uncut`'s, printing the comparison.
fn all_agree(what: &str, uncut: &[[Term; 3]], other: &[[Term; 3]]) -> bool {
    let mut ok = true;
    for (axis, (u, o)) in GYRO.iter().zip(uncut.iter().zip(other)) {
        for (k, t) in TERMS.iter().enumerate() {
            let same = agree(u[k], o[k]);
            ok &= same;
            println!(
                "{axis} {t}: uncut {} | {what} {} {}",
                shown(u[k]),
                shown(o[k]),
                if same { "agree" } else { "DIFFER" }
            );
        }
    }
    ok
}

/// The span of the uncut axes' intervals of term `k`: the stage's one value must fall in it.
fn span(uncut: &[[Term; 3]], k: usize) -> (f64, f64) {
    uncut
        .iter()
        .filter_map(|a| a[k])
        .fold((f64::INFINITY, 0.0), |(lo, hi), (_, l, h)| {
            (lo.min(l), f64::max(hi, h))
        })
}

/// Five pieces of the gyro columns, each shifted by its offset, as CSV texts.
fn pieces(path: &Path) -> Vec<String> {
    let names: Vec<String> = GYRO.iter().map(|c| c.to_string()).collect();
    let table = read_table(path, &names).unwrap_or_else(|e| panic!("{VAR}: {e}"));
    let rows = table.columns[0].len();
    assert_eq!(rows, 1_000_000);
    OFFSETS
        .iter()
        .enumerate()
        .map(|(k, off)| {
            let mut text = GYRO.join(",") + "\n";
            for r in k * rows / OFFSETS.len()..(k + 1) * rows / OFFSETS.len() {
                let row: Vec<String> = table
                    .columns
                    .iter()
                    .map(|c| format!("{}", c[r] + off))
                    .collect();
                writeln!(text, "{}", row.join(",")).unwrap();
            }
            text
        })
        .collect()
}

#[test]
fn five_shifted_pieces_pool_to_the_uncut_terms_and_joined_do_not() {
    let Some(path) = log_path() else { return };
    let dir = tempfile::tempdir().unwrap();
    let texts = pieces(&path);
    let mut files = Vec::new();
    let mut joined = GYRO.join(",") + "\n";
    for (k, t) in texts.iter().enumerate() {
        let f = dir.path().join(format!("power-up-{}.csv", k + 1));
        std::fs::write(&f, t).unwrap();
        files.push(f);
        joined.extend(t.lines().skip(1).map(|l| format!("{l}\n")));
    }
    let joined_file = dir.path().join("joined.csv");
    std::fs::write(&joined_file, &joined).unwrap();
    let piece_refs: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();

    let (_, uncut) = terms(&[&path]);
    let (json, pooled) = terms(&piece_refs);
    let (_, joined) = terms(&[&joined_file]);

    // The output says what was pooled.
    assert_eq!(json["pooled"], 5);
    let logs = json["logs"].as_array().unwrap();
    assert_eq!(logs.len(), 5);
    for (l, f) in logs.iter().zip(&files) {
        assert_eq!(l["name"], f.display().to_string());
        assert_eq!(l["samples"], 200_000);
        // 200,000 samples reach m = 65,536 (tau 655.36 s), not 131,072.
        assert_eq!(l["largest_tau"], 655.36);
    }
    for p in json["columns"][0]["points"].as_array().unwrap() {
        assert_eq!(p["logs"], 5, "{p}");
    }

    let pooled_ok = all_agree("pooled", &uncut, &pooled);
    let joined_ok = all_agree("joined", &uncut, &joined);
    assert!(pooled_ok, "the pooled terms differ from the uncut log's");
    assert!(!joined_ok, "joined end to end, the pieces should not pass");

    // --stage on the pooled curve: its one N and B lie within the uncut axes' intervals;
    // joined, B blows up.
    let (_, n_uncut, b_uncut) = stage(&[&path]);
    let (text, n_pooled, b_pooled) = stage(&piece_refs);
    let (_, n_joined, b_joined) = stage(&[&joined_file]);
    println!("stage arw: uncut {n_uncut:.4} pooled {n_pooled:.4} joined {n_joined:.4} deg/sqrt(h)");
    println!(
        "stage bias_instability: uncut {b_uncut:.3} pooled {b_pooled:.3} joined {b_joined:.3} deg/h"
    );
    assert!(text.contains("1000000 samples in 5 logs"), "{text}");
    let ((nlo, nhi), (blo, bhi)) = (span(&uncut, 0), span(&uncut, 1));
    assert!(
        (nlo..=nhi).contains(&n_pooled),
        "N {n_pooled} outside {nlo}..{nhi}"
    );
    assert!(
        (blo..=bhi).contains(&b_pooled),
        "B {b_pooled} outside {blo}..{bhi}"
    );
    assert!(b_joined > 5.0 * bhi, "joined B {b_joined} against {bhi}");
}

/// A simulated 300 s log at 100 Hz, `seed` its noise.
fn simulate(dir: &Path, name: &str, seed: &str) -> PathBuf {
    let out = dir.join(name);
    simulated_log(&out, seed, &[]);
    out
}

/// Exit code 2 and one `driftless: error:` line naming `file` and saying `needle`.
fn assert_refused(o: &Output, file: &Path, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.starts_with("driftless: error: "), "{err}");
    assert!(err.contains(&file.display().to_string()), "{err}");
    assert!(err.contains(needle), "'{needle}' not in {err}");
}

#[test]
fn logs_that_cannot_pool_are_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let a = simulate(dir.path(), "a.csv", "1");
    let b = simulate(dir.path(), "b.csv", "2");
    let (a_s, b_s) = (a.to_str().unwrap(), b.to_str().unwrap());
    // Other columns.
    let other = dir.path().join("other.csv");
    let text = std::fs::read_to_string(&b).unwrap();
    let renamed = text.replacen("gyro_x_degps", "gyro_q_degps", 1);
    std::fs::write(&other, renamed).unwrap();
    let o = driftless(&["allan", a_s, other.to_str().unwrap(), "--rate", "100"]);
    assert_refused(&o, &other, "must share rate, units and columns");
    // Too short for any tau, among good logs.
    let short = dir.path().join("short.csv");
    std::fs::write(&short, "gyro_x_degps\n0.1\n0.2\n").unwrap();
    let o = driftless(&["allan", a_s, short.to_str().unwrap(), b_s, "--rate", "100"]);
    assert_refused(&o, &short, "too short");
    // Not a log at all.
    let junk = dir.path().join("junk.csv");
    std::fs::write(&junk, [0u8, 159, 146, 150]).unwrap();
    let o = driftless(&["allan", a_s, junk.to_str().unwrap(), "--rate", "100"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("junk.csv"));
}

#[test]
fn two_logs_pool_in_every_output_and_their_order_does_not_matter() {
    let dir = tempfile::tempdir().unwrap();
    let a = simulate(dir.path(), "a.csv", "1");
    let b = simulate(dir.path(), "b.csv", "2");
    let (a_s, b_s) = (a.to_str().unwrap(), b.to_str().unwrap());
    let out = dir.path().join("tau.csv");
    let plot = dir.path().join("adev.svg");
    let o = driftless(&[
        "allan",
        a_s,
        b_s,
        "--rate",
        "100",
        "-o",
        out.to_str().unwrap(),
        "--plot",
        plot.to_str().unwrap(),
    ]);
    let text = stdout(&o);
    assert!(
        text.starts_with("2 logs pooled per tau, never joined"),
        "{text}"
    );
    assert!(
        text.contains(&format!("log 2: {b_s}: 30000 samples")),
        "{text}"
    );
    assert!(text.contains("60000 samples in 2 logs"), "{text}");
    let csv = std::fs::read_to_string(&out).unwrap();
    assert!(csv.starts_with("tau_s,logs,gyro_x_degps_dev,"), "{csv}");
    let listed = std::fs::read_to_string(dir.path().join("tau-logs.csv")).unwrap();
    assert_eq!(listed.lines().count(), 3, "{listed}");
    assert!(listed.contains(&format!("2,{b_s},30000,")), "{listed}");
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.contains("2 logs pooled per tau"));
    assert!(svg.contains(a_s));
    // The order of the logs changes their list, not the curve or the terms.
    let json = |x: &str, y: &str| -> Value {
        let o = driftless(&["allan", x, y, "--rate", "100", "--json"]);
        serde_json::from_str(&stdout(&o)).unwrap()
    };
    let (ab, ba) = (json(a_s, b_s), json(b_s, a_s));
    assert_eq!(ab["pooled"], 2);
    let (p, q) = (&ab["columns"][0], &ba["columns"][0]);
    assert_eq!(p["samples"], 60_000);
    for (x, y) in p["points"]
        .as_array()
        .unwrap()
        .iter()
        .zip(q["points"].as_array().unwrap())
    {
        assert_eq!(x["logs"], 2);
        let (u, v) = (num(&x["dev"]), num(&y["dev"]));
        assert!((u - v).abs() <= 1e-12 * u, "{x} vs {y}");
    }
    let (n1, n2) = (
        num(&p["terms"]["N"]["value"]),
        num(&q["terms"]["N"]["value"]),
    );
    assert!((n1 - n2).abs() <= 1e-9 * n1);
}
