//! `driftless allan` and `driftless simulate` through the real binary: output shapes, errors,
//! exit codes, and no partial output files.

mod common;

use common::{driftless, simulated_log};

use serde_json::Value;
use std::path::Path;
use std::process::Output;

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Exit code 2 and a single `driftless: error:` line containing `needle`.
fn assert_input_error(o: &Output, needle: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(err.starts_with("driftless: error: "), "{err}");
    assert!(err.contains(needle), "'{needle}' not in: {err}");
}

fn simulate(dir: &Path, extra: &[&str]) -> String {
    simulate_to(&dir.join("sim.csv"), extra)
}

/// The 300 s simulated log of [`simulate`] (seed 7), written to `out`.
fn simulate_to(out: &Path, extra: &[&str]) -> String {
    simulated_log(out, "7", extra)
}

#[test]
fn simulate_writes_a_deterministic_headed_log() {
    let dir = tempfile::tempdir().unwrap();
    let path = simulate(dir.path(), &[]);
    let first = std::fs::read_to_string(&path).unwrap();
    let mut lines = first.lines();
    assert_eq!(lines.next(), Some("t_s,gyro_x_degps"));
    assert_eq!(lines.count(), 30_000);
    simulate(dir.path(), &[]);
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        first,
        "same seed, same file"
    );

    let path = simulate(dir.path(), &["--axes", "3", "--motion", "turn"]);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with(
        "t_s,gyro_x_degps,gyro_y_degps,gyro_z_degps,truth_x_degps,truth_y_degps,truth_z_degps\n"
    ));

    let out = dir.path().join("p.csv");
    let o = driftless(&[
        "simulate",
        "--profile",
        "adis16405",
        "--duration",
        "2s",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(text.lines().count(), 201);
    assert!(text.starts_with("t_s,gyro_x_degps,gyro_y_degps,gyro_z_degps\n"));
}

#[test]
fn allan_json_has_the_documented_shape() {
    let dir = tempfile::tempdir().unwrap();
    let path = simulate(dir.path(), &[]);
    let o = driftless(&[
        "allan",
        &path,
        "--rate",
        "100",
        "--column",
        "gyro_x_degps",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    let cols = v["columns"].as_array().unwrap();
    assert_eq!(cols.len(), 1);
    let c = &cols[0];
    assert_eq!(c["name"], "gyro_x_degps");
    let points = c["points"].as_array().unwrap();
    assert_eq!(points.len(), 14); // octave m = 1 .. 8192 of 30000 samples
    for p in points {
        for key in ["tau", "dev", "lo", "hi"] {
            assert!(p[key].as_f64().unwrap() > 0.0, "{key}");
        }
        assert!(p["n"].as_u64().unwrap() > 1);
        assert!(p["lo"].as_f64() < p["dev"].as_f64() && p["dev"].as_f64() < p["hi"].as_f64());
        assert!(p["alpha"].is_i64());
        match p["noise_id"].as_str() {
            Some("slope") => assert!(p["alpha_plausible"].is_null()),
            Some("widest") => {
                let range = p["alpha_plausible"].as_array().expect("[lo, hi]");
                let (lo, hi) = (range[0].as_i64().unwrap(), range[1].as_i64().unwrap());
                assert!(lo <= p["alpha"].as_i64().unwrap() && p["alpha"].as_i64().unwrap() <= hi);
            }
            other => panic!("noise_id {other:?}"),
        }
    }
    // 300 s: the far neighbour has 30 tau-spans up to tau 5 s; the octaves from 5.12 s are
    // flagged, and they come last.
    let ids: Vec<&str> = points
        .iter()
        .map(|p| p["noise_id"].as_str().unwrap())
        .collect();
    assert_eq!(ids.iter().filter(|&&i| i == "widest").count(), 5, "{ids:?}");
    assert!(ids
        .windows(2)
        .all(|w| !(w[0] == "widest" && w[1] == "slope")));
    assert_eq!(c["trust"]["use"], "terms");
    assert!(c["trust"]["why"]
        .as_str()
        .unwrap()
        .starts_with("trust the fitted terms"));
    assert!(c["trust"]["read_offs_outside_fit_interval"].is_array());
    let terms = c["terms"].as_object().unwrap();
    assert_eq!(terms.keys().collect::<Vec<_>>(), ["B", "K", "N", "Q", "R"]);
    for (name, t) in terms {
        if t.is_null() {
            assert!(c["not_identified"][name].is_string(), "{name} has a reason");
            continue;
        }
        for key in ["value", "lo", "hi"] {
            assert!(t[key].is_f64(), "{name}.{key}");
        }
        assert!(t["unit"].is_string());
    }
    // The simulated N (1.5 deg/sqrt(h)) is found with its unit.
    let n = &terms["N"];
    assert_eq!(n["unit"], "deg/sqrt(h)");
    let value = n["value"].as_f64().unwrap();
    assert!((value - 1.5).abs() < 0.1, "N = {value}");
}

#[test]
fn allan_writes_table_and_plot_and_prints_tables() {
    let dir = tempfile::tempdir().unwrap();
    let path = simulate(dir.path(), &["--axes", "2"]);
    let csv = dir.path().join("out.csv");
    let svg = dir.path().join("allan.svg");
    let o = driftless(&[
        "allan",
        &path,
        "--rate",
        "100",
        "--column",
        "gyro_x_degps",
        "--column",
        "gyro_y_degps",
        "--taus",
        "log:5",
        "--kind",
        "mdev",
        "-o",
        csv.to_str().unwrap(),
        "--plot",
        svg.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("mdev in deg/s"), "{stdout}");
    assert!(stdout.contains("IEEE 952 terms"), "{stdout}");
    assert!(stdout.contains("-2*"), "a flagged long-tau point: {stdout}");
    assert!(stdout.contains("* noise type not identified"), "{stdout}");
    assert!(stdout.contains("Which to trust: "), "{stdout}");
    let table = std::fs::read_to_string(&csv).unwrap();
    assert!(table.starts_with("tau_s,gyro_x_degps_dev,gyro_x_degps_lo,gyro_x_degps_hi,gyro_x_degps_n,gyro_x_degps_edf,gyro_x_degps_alpha,gyro_x_degps_identified,gyro_y_degps_dev,"));
    let plot = std::fs::read_to_string(&svg).unwrap();
    assert!(
        plot.starts_with("<svg") && plot.contains("N = "),
        "plot with the terms"
    );
}

#[test]
fn bad_input_is_one_line_exit_2_and_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("out.csv");
    let out_s = out.to_str().unwrap();
    let write = |name: &str, text: &str| {
        let p = d.join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_string()
    };
    let missing = d.join("missing.csv");
    assert_input_error(
        &driftless(&[
            "allan",
            missing.to_str().unwrap(),
            "--rate",
            "10",
            "-o",
            out_s,
        ]),
        "missing.csv",
    );
    let empty = write("empty.csv", "");
    assert_input_error(
        &driftless(&["allan", &empty, "--rate", "10", "-o", out_s]),
        "the file is empty",
    );
    let bad = write("bad.csv", "x,y\n1,2\n3,oops\n5,6\n");
    assert_input_error(
        &driftless(&["allan", &bad, "--rate", "10", "-o", out_s]),
        "bad.csv:3:3: column 'y'",
    );
    let nan = write("nan.csv", "x\n1\nNaN\n3\n");
    assert_input_error(
        &driftless(&["allan", &nan, "--rate", "10", "-o", out_s]),
        "nan.csv:3:1",
    );
    let inf = write("inf.csv", "x\n1\n2\n-inf\n");
    assert_input_error(
        &driftless(&["allan", &inf, "--rate", "10", "-o", out_s]),
        "inf.csv:4:1",
    );
    let ok = write("ok.csv", "x\n1\n2\n3\n4\n5\n");
    assert_input_error(
        &driftless(&["allan", &ok, "--rate", "0", "-o", out_s]),
        "--rate",
    );
    assert_input_error(
        &driftless(&["allan", &ok, "--rate", "-5", "-o", out_s]),
        "--rate",
    );
    assert_input_error(
        &driftless(&["allan", &ok, "--rate", "fast", "-o", out_s]),
        "--rate 'fast' is not a number",
    );
    assert_input_error(
        &driftless(&["allan", &ok, "--rate", "10", "--taus", "log:x", "-o", out_s]),
        "--taus",
    );
    assert_input_error(
        &driftless(&["allan", &ok, "--rate", "10", "--kind", "tdev", "-o", out_s]),
        "--kind",
    );
    assert_input_error(
        &driftless(&["allan", &ok, "--rate", "10", "--units", "rpm", "-o", out_s]),
        "--units",
    );
    assert_input_error(
        &driftless(&["allan", &ok, "--rate", "10", "--column", "z", "-o", out_s]),
        "no column named 'z'",
    );
    let short = write("short.csv", "x\n1\n2\n");
    assert_input_error(
        &driftless(&["allan", &short, "--rate", "10", "-o", out_s]),
        "too short",
    );
    // A tau list none of whose taus fits the record.
    assert_input_error(
        &driftless(&[
            "allan", &ok, "--rate", "10", "--taus", "100,200", "-o", out_s,
        ]),
        "too short",
    );
    assert!(!out.exists(), "no partial output file");

    let sim_out = d.join("sim.csv");
    let so = sim_out.to_str().unwrap();
    assert_input_error(
        &driftless(&["simulate", "--profile", "nope", "-o", so]),
        "unknown profile",
    );
    assert_input_error(
        &driftless(&["simulate", "--duration", "1s", "-o", so]),
        "--profile",
    );
    assert_input_error(
        &driftless(&["simulate", "--N", "1", "--axes", "4", "-o", so]),
        "axes",
    );
    assert_input_error(
        &driftless(&["simulate", "--N", "1", "--rate", "0", "-o", so]),
        "rate",
    );
    assert_input_error(
        &driftless(&["simulate", "--N", "-1", "-o", so]),
        "--N must be a finite number >= 0, not -1",
    );
    assert_input_error(
        &driftless(&["simulate", "--B", "lots", "-o", so]),
        "--B 'lots' is not a number",
    );
    assert_input_error(
        &driftless(&["simulate", "--N", "1", "--duration", "soon", "-o", so]),
        "--duration",
    );
    assert_input_error(
        &driftless(&["simulate", "--N", "1", "--motion", "spin", "-o", so]),
        "unknown motion",
    );
    let nodir = d.join("no/such/dir/sim.csv");
    assert_input_error(
        &driftless(&[
            "simulate",
            "--N",
            "1",
            "--duration",
            "1s",
            "-o",
            nodir.to_str().unwrap(),
        ]),
        "no/such/dir",
    );
    assert!(!sim_out.exists(), "no partial output file");
}

#[test]
fn simulate_writes_gzip_for_a_gz_name_and_allan_reads_it() {
    let dir = tempfile::tempdir().unwrap();
    let plain = simulate(dir.path(), &[]);
    let gz = dir.path().join("sim.csv.gz");
    let gz_s = simulate_to(&gz, &[]);
    let bytes = std::fs::read(&gz).unwrap();
    assert_eq!(&bytes[..2], &[0x1f, 0x8b], "gzip magic");
    let mut text = String::new();
    std::io::Read::read_to_string(&mut flate2::read::GzDecoder::new(&bytes[..]), &mut text)
        .unwrap();
    assert_eq!(text, std::fs::read_to_string(&plain).unwrap(), "same log");
    let from_gz = driftless(&["allan", &gz_s, "--rate", "100", "--json"]);
    assert!(from_gz.status.success(), "{}", stderr(&from_gz));
    let from_plain = driftless(&["allan", &plain, "--rate", "100", "--json"]);
    assert_eq!(from_gz.stdout, from_plain.stdout);
}

#[test]
fn rad_per_s_input_gives_the_same_terms_in_degree_units() {
    let dir = tempfile::tempdir().unwrap();
    let path = simulate(dir.path(), &[]);
    let text = std::fs::read_to_string(&path).unwrap();
    let mut rad = String::from("gyro_x_rads\n");
    for line in text.lines().skip(1) {
        let v: f64 = line.split(',').nth(1).unwrap().parse().unwrap();
        rad.push_str(&format!("{}\n", v.to_radians()));
    }
    let rad_path = dir.path().join("rad.csv");
    std::fs::write(&rad_path, rad).unwrap();
    let run = |p: &str, units: &str| -> Value {
        let o = driftless(&["allan", p, "--rate", "100", "--units", units, "--json"]);
        assert!(o.status.success(), "{}", stderr(&o));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let deg = run(&path, "deg/s");
    let rad = run(rad_path.to_str().unwrap(), "rad/s");
    let (dc, rc) = (&deg["columns"][0], &rad["columns"][0]);
    assert_eq!(rc["unit"], "rad/s");
    let dev_ratio =
        dc["points"][0]["dev"].as_f64().unwrap() / rc["points"][0]["dev"].as_f64().unwrap();
    assert!(
        (dev_ratio - 180.0 / std::f64::consts::PI).abs() < 1e-9,
        "deviations stay in the input unit"
    );
    assert!(dc["terms"]["N"].is_object(), "N identified");
    for t in ["Q", "N", "B", "K", "R"] {
        let (a, b) = (&dc["terms"][t], &rc["terms"][t]);
        assert_eq!(a.is_null(), b.is_null(), "{t}");
        if let (Some(a), Some(b)) = (a["value"].as_f64(), b["value"].as_f64()) {
            assert!(
                ((a - b) / a).abs() < 1e-6,
                "{t}: {a} deg-based vs {b} from rad/s"
            );
            assert_eq!(dc["terms"][t]["unit"], rc["terms"][t]["unit"]);
        }
    }
}

/// The value and unit printed first on a term's line of `allan`'s text output.
fn term(out: &str, name: &str) -> (f64, String) {
    let line = out
        .lines()
        .find(|l| l.trim_start().starts_with(&format!("{name}  ")))
        .unwrap_or_else(|| panic!("no {name} line in {out}"));
    let mut words = line.split_whitespace().skip(1);
    let value = words.next().unwrap().parse().expect("a plain number");
    (value, words.next().unwrap().to_string())
}

#[test]
fn terms_print_in_datasheet_units_or_per_second_on_request_as_plain_decimals() {
    let dir = tempfile::tempdir().unwrap();
    let path = simulate(dir.path(), &[]);
    let run = |extra: &[&str]| {
        let mut args = vec!["allan", &path, "--rate", "100"];
        args.extend_from_slice(extra);
        let o = driftless(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let datasheet = run(&[]);
    let seconds = run(&["--term-units", "seconds"]);
    let (n_h, unit_h) = term(&datasheet, "N");
    let (n_s, unit_s) = term(&seconds, "N");
    assert_eq!(
        (unit_h.as_str(), unit_s.as_str()),
        ("deg/sqrt(h)", "deg/sqrt(s)")
    );
    // Simulated with N = 1.5 deg/sqrt(h).
    assert!((n_h - 1.5).abs() < 0.1, "{datasheet}");
    assert!((n_h / n_s - 60.0).abs() < 0.01, "{n_h} vs {n_s}");
    // B: too short a record for the fit; its slope read-off (after the `|`) converts alike.
    let read_off = |out: &str| -> (f64, String) {
        let line = out
            .lines()
            .find(|l| l.trim_start().starts_with("B  "))
            .unwrap();
        let mut words = line.split(" | ").nth(1).unwrap().split_whitespace();
        (
            words.next().unwrap().parse().unwrap(),
            words.next().unwrap().into(),
        )
    };
    let ((b_h, unit_h), (b_s, unit_s)) = (read_off(&datasheet), read_off(&seconds));
    assert_eq!((unit_h.as_str(), unit_s.as_str()), ("deg/h", "deg/s"));
    assert!((b_h / b_s - 3600.0).abs() < 1.0, "{b_h} vs {b_s}");
    // No `e0`-style exponents in the readable range.
    assert!(
        !datasheet.contains("e0 ") && !datasheet.contains("e-1 "),
        "{datasheet}"
    );
    let o = driftless(&["allan", &path, "--rate", "100", "--term-units", "hours"]);
    assert_eq!(o.status.code(), Some(2));
}

/// The pipeline around a `predict.bias` table: a driver's samples in, the table, publish.
fn pipeline_around(table: &str) -> String {
    format!(
        r#"name = "own"
rate_hz = 100.0
axes = 1
input_units = "deg/s"

[[stage]]
name = "sensor"
kind = "ingest.iceoryx2"
input = "sensor/raw"
output = "nav/raw"

[[stage]]
name = "denoise"
kind = "denoise.none"
input = "nav/raw"
output = "nav/denoised"

{table}
[[stage]]
name = "publish"
kind = "publish"
input = "nav/predicted"
output = "nav/corrected"
"#
    )
}

/// `allan --stage` prints a table a pipeline takes as it is: every key given, the fit's terms,
/// what was done with the terms the record cannot identify; and a table that gives some terms
/// but not all, without naming a sensor, is refused rather than filled in with one's.
#[test]
fn allan_stage_prints_a_table_the_pipeline_takes_with_every_term() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(dir.path(), &[]);
    let o = driftless(&["allan", &log, "--rate", "100", "--stage", "--lsb", "0.01"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8(o.stdout).unwrap();
    for key in [
        "arw = ",
        "bias_instability = ",
        "rrw = ",
        "quantization = ",
        "lsb = 1e-2",
    ] {
        assert!(table.contains(key), "{key} missing in:\n{table}");
    }
    // 300 s cannot identify K: the comments say so and what is taken (never the fit's
    // best value of a term it cannot identify).
    assert!(
        table.contains("not identifiable") && table.contains("; 0 is taken"),
        "{table}"
    );
    assert!(table.contains("rrw = 0e0"), "{table}");
    assert!(!table.contains("best value"), "{table}");
    let arw: f64 = table
        .lines()
        .find_map(|l| l.strip_prefix("arw = "))
        .unwrap()
        .parse()
        .unwrap();
    // The simulated N is 1.5 deg/sqrt(h).
    assert!((arw - 1.5).abs() < 0.1, "arw {arw}");
    let file = dir.path().join("own.toml");
    std::fs::write(&file, pipeline_around(&table)).unwrap();
    let v = driftless(&["validate", file.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&v.stdout);
    assert!(v.status.success(), "{}\n{}", out, stderr(&v));
    assert!(out.contains(&format!("N {arw:.3} deg/sqrt(h)")), "{out}");
    assert!(out.contains("lsb 0.01 deg/s"), "{out}");

    // Some terms without a profile: refused, the missing ones named.
    let partial = "[[stage]]\nname = \"predict\"\nkind = \"predict.bias\"\ninput = \"nav/denoised\"\noutput = \"nav/predicted\"\narw = 1.5\n";
    std::fs::write(&file, pipeline_around(partial)).unwrap();
    assert_input_error(
        &driftless(&["validate", file.to_str().unwrap()]),
        "bias_instability and rrw not given",
    );
    // With the sensor named, its terms fill in the rest, as documented.
    std::fs::write(
        &file,
        pipeline_around(&format!("{partial}profile = \"adis16405\"\n")),
    )
    .unwrap();
    let v = driftless(&["validate", file.to_str().unwrap()]);
    assert!(v.status.success(), "{}", stderr(&v));
    assert!(String::from_utf8_lossy(&v.stdout).contains("N 1.500 deg/sqrt(h), B 33.77 deg/h"));
}

#[test]
fn allan_stage_refuses_a_record_too_short_for_n_with_the_length_needed() {
    let dir = tempfile::tempdir().unwrap();
    let sim = |duration: &str| {
        let out = dir.path().join(format!("still-{duration}.csv"));
        let out_s = out.to_str().unwrap().to_string();
        let o = driftless(&[
            "simulate",
            "--N",
            "1.5",
            "--B",
            "20",
            "--Q",
            "0.01",
            "--rate",
            "100",
            "--duration",
            duration,
            "--seed",
            "7",
            "-o",
            &out_s,
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        out_s
    };
    let short = sim("6s");
    let o = driftless(&["allan", &short, "--rate", "100", "--stage"]);
    assert_input_error(&o, "6s of data cannot identify the angle random walk N");
    let err = stderr(&o);
    let needed = err
        .split("record about ")
        .nth(1)
        .and_then(|r| r.split("s of still data").next())
        .unwrap_or_else(|| panic!("the length needed: {err}"));
    let secs: u64 = needed.parse().unwrap_or_else(|_| panic!("{err}"));
    assert!(secs > 6, "{err}");
    // A record that long gives N.
    let long = sim(&format!("{secs}s"));
    let o = driftless(&["allan", &long, "--rate", "100", "--stage"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("arw = "));
}
