//! `driftless allan --accel-column` through the real binary, on a simulated 6-axis log whose
//! accelerometer terms are known: the terms' names and units in text, JSON, plots and the
//! `--stage` table (which a pipeline takes), the unit check by gravity, and the errors.

mod common;

use common::driftless;

use serde_json::Value;
use std::path::Path;
use std::process::Output;

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The accelerometer's simulated terms: N 0.3 m/s/sqrt(h), B 0.4 mg.
const VRW: f64 = 0.3;
const B_MG: f64 = 0.4;
const G: f64 = 9.80665;

/// A 20-min, 100 Hz log `t_s, gyro_{x,y,z}_degps, accel_{x,y,z}_g`: the gyro with N 1.5
/// deg/sqrt(h) and B 20 deg/h, the accelerometer in g with the terms above (the simulator is
/// unit-blind: its N and B given in g-based numbers) and gravity on z (-1 g).
fn six_axis(dir: &Path) -> String {
    let sim = |name: &str, n: f64, b: f64, seed: &str| {
        let out = dir.join(name);
        let o = driftless(&[
            "simulate",
            "--N",
            &n.to_string(),
            "--B",
            &b.to_string(),
            "--axes",
            "3",
            "--rate",
            "100",
            "--duration",
            "20min",
            "--seed",
            seed,
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read_to_string(out).unwrap()
    };
    let gyro = sim("gyro.csv", 1.5, 20.0, "3");
    // N m/s/sqrt(h) / g: g/sqrt(h); B mg / 1000 g, as deg/h: x 3600 for the simulator's hours.
    let accel = sim("accel.csv", VRW / G, B_MG / 1000.0 * 3600.0, "4");
    let mut out =
        String::from("t_s,gyro_x_degps,gyro_y_degps,gyro_z_degps,accel_x_g,accel_y_g,accel_z_g\n");
    for (g, a) in gyro.lines().zip(accel.lines()).skip(1) {
        let a: Vec<f64> = a.split(',').skip(1).map(|v| v.parse().unwrap()).collect();
        out.push_str(&format!("{g},{},{},{}\n", a[0], a[1], a[2] - 1.0));
    }
    let path = dir.join("six.csv");
    std::fs::write(&path, out).unwrap();
    path.to_str().unwrap().to_string()
}

fn accel_args<'a>(log: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "allan",
        log,
        "--rate",
        "100",
        "--accel-column",
        "accel_x_g",
        "--accel-column",
        "accel_y_g",
        "--accel-column",
        "accel_z_g",
    ];
    args.extend_from_slice(extra);
    args
}

fn close(value: f64, truth: f64, within: f64) -> bool {
    (value / truth - 1.0).abs() < within
}

#[test]
fn accelerometer_columns_give_their_terms_with_names_and_units() {
    let dir = tempfile::tempdir().unwrap();
    let log = six_axis(dir.path());
    let svg = dir.path().join("allan.svg");
    let o = driftless(&accel_args(
        &log,
        &[
            "--accel-units",
            "g",
            "--json",
            "--plot",
            svg.to_str().unwrap(),
        ],
    ));
    assert!(o.status.success(), "{}", stderr(&o));
    // The gravity of the columns agrees with --accel-units g: no warning about the unit.
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    let cols = v["columns"].as_array().unwrap();
    // Without --column the gyro's are the other numeric columns but time.
    let names: Vec<&str> = cols.iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "gyro_x_degps",
            "gyro_y_degps",
            "gyro_z_degps",
            "accel_x_g",
            "accel_y_g",
            "accel_z_g"
        ]
    );
    for c in &cols[..3] {
        assert_eq!(
            (c["sensor"].as_str(), c["unit"].as_str()),
            (Some("gyro"), Some("deg/s"))
        );
        assert_eq!(c["term_names"]["N"], "angle random walk");
        assert_eq!(c["terms"]["N"]["unit"], "deg/sqrt(h)");
    }
    for c in &cols[3..] {
        let name = c["name"].as_str().unwrap();
        assert_eq!(
            (c["sensor"].as_str(), c["unit"].as_str()),
            (Some("accel"), Some("g"))
        );
        assert_eq!(c["term_names"]["N"], "velocity random walk");
        assert_eq!(c["term_names"]["B"], "bias instability");
        assert_eq!(c["term_names"]["K"], "acceleration random walk");
        let n = &c["terms"]["N"];
        assert_eq!(n["unit"], "m/s/sqrt(h)");
        let value = n["value"].as_f64().unwrap();
        assert!(close(value, VRW, 0.05), "{name}: N {value}");
        let b = &c["terms"]["B"];
        if !b.is_null() {
            assert_eq!(b["unit"], "mg");
            let value = b["value"].as_f64().unwrap();
            assert!(close(value, B_MG, 0.5), "{name}: B {value} mg");
        }
        // The points stay in the log's unit, g.
        let p0 = c["points"][0]["dev"].as_f64().unwrap();
        assert!(p0 < 0.1, "{name}: {p0} g at 10 ms");
    }
    let gyro_plot = std::fs::read_to_string(&svg).unwrap();
    let accel_plot = std::fs::read_to_string(dir.path().join("allan-accel.svg")).unwrap();
    assert!(gyro_plot.contains("deg/sqrt(h)") && !gyro_plot.contains("m/s/sqrt(h)"));
    assert!(
        accel_plot.contains("m/s/sqrt(h)")
            && accel_plot.contains("velocity random walk")
            && accel_plot.contains("oadev (g)"),
        "the accelerometer's plot"
    );

    // Text: its own header, names and units.
    let o = driftless(&accel_args(
        &log,
        &["--accel-units", "g", "--column", "gyro_x_degps"],
    ));
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(
        text.contains("accel_y_g (accelerometer, 120000 samples at 100 Hz): oadev in g"),
        "{text}"
    );
    assert!(text.contains("N velocity random walk"), "{text}");
    assert!(text.contains("N angle random walk"), "{text}");
    let n_line = text
        .lines()
        .skip_while(|l| !l.starts_with("accel_x_g"))
        .find(|l| l.trim_start().starts_with("N  "))
        .unwrap();
    assert!(
        n_line.contains(" m/s/sqrt(h)  [") && n_line.contains("m/s/sqrt(s)"),
        "{n_line}"
    );
    let o = driftless(&accel_args(
        &log,
        &["--accel-units", "g", "--term-units", "seconds"],
    ));
    let text = String::from_utf8(o.stdout).unwrap();
    let b_line = text
        .lines()
        .skip_while(|l| !l.starts_with("accel_x_g"))
        .find(|l| l.trim_start().starts_with("B  "))
        .unwrap();
    assert!(b_line.contains(" m/s^2"), "{b_line}");
}

/// A unit given wrong is caught by the gravity the three axes read, and the terms differ by g.
#[test]
fn a_unit_the_gravity_contradicts_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let log = six_axis(dir.path());
    let n = |o: &Output| -> f64 {
        let v: Value = serde_json::from_slice(&o.stdout).unwrap();
        v["columns"][1]["terms"]["N"]["value"].as_f64().unwrap()
    };
    let wrong = driftless(&accel_args(&log, &["--column", "gyro_x_degps", "--json"]));
    assert!(wrong.status.success());
    let err = stderr(&wrong);
    assert!(
        err.contains("read a gravity of ")
            && err.contains("as a still unit does in g")
            && err.contains("--accel-units g"),
        "{err}"
    );
    let right = driftless(&accel_args(
        &log,
        &["--column", "gyro_x_degps", "--accel-units", "g", "--json"],
    ));
    assert!((n(&right) / n(&wrong) - G).abs() < 1e-9);
}

/// `--stage` with the accelerometer: its keys beside the gyro's, what was taken and why, the
/// per-sample white noise; and the table is one a pipeline takes.
#[test]
fn allan_stage_writes_the_accelerometer_keys_a_pipeline_takes() {
    let dir = tempfile::tempdir().unwrap();
    let log = six_axis(dir.path());
    let o = driftless(&accel_args(&log, &["--accel-units", "g", "--stage"]));
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8(o.stdout).unwrap();
    let key = |k: &str| -> f64 {
        table
            .lines()
            .find_map(|l| l.strip_prefix(&format!("{k} = ")))
            .unwrap_or_else(|| panic!("{k} in:\n{table}"))
            .parse()
            .unwrap()
    };
    let vrw = key("accel_vrw");
    assert!(close(vrw, VRW, 0.05), "accel_vrw {vrw}");
    let b = key("accel_bias_instability");
    assert!(close(b, B_MG, 0.5), "accel_bias_instability {b}");
    assert!(close(key("arw"), 1.5, 0.1));
    assert!(
        table.contains("#   N, the accelerometer's velocity random walk (accel_vrw) = "),
        "{table}"
    );
    assert!(table.contains("#     accel_z_g: "), "{table}");
    // The white noise per sample the stage takes from accel_vrw: N / 60 x sqrt(100 Hz).
    let white: f64 = table
        .lines()
        .find_map(|l| l.split("sqrt(rate_hz), ").nth(1))
        .and_then(|l| l.strip_suffix(" m/s^2 at 100 Hz"))
        .unwrap_or_else(|| panic!("the white noise per sample in:\n{table}"))
        .parse()
        .unwrap();
    assert!(close(white, vrw / 60.0 * 10.0, 1e-3), "{white}");
    let file = dir.path().join("own.toml");
    let pipeline = format!(
        "name = \"own\"\nrate_hz = 100.0\naxes = 3\ninput_units = \"deg/s\"\n\n\
         [[stage]]\nname = \"sensor\"\nkind = \"ingest.iceoryx2\"\ninput = \"sensor/raw\"\noutput = \"nav/raw\"\n\n\
         [[stage]]\nname = \"denoise\"\nkind = \"denoise.none\"\ninput = \"nav/raw\"\noutput = \"nav/denoised\"\n\n\
         {table}\n\
         [[stage]]\nname = \"publish\"\nkind = \"publish\"\ninput = \"nav/predicted\"\noutput = \"nav/corrected\"\n"
    );
    std::fs::write(&file, &pipeline).unwrap();
    let v = driftless(&["validate", file.to_str().unwrap()]);
    assert!(v.status.success(), "{}", stderr(&v));
    // The stage checks the keys' ranges.
    let bad = pipeline.replace(
        &format!(
            "accel_vrw = {}",
            table
                .lines()
                .find_map(|l| l.strip_prefix("accel_vrw = "))
                .unwrap()
        ),
        "accel_vrw = 0.0",
    );
    std::fs::write(&file, bad).unwrap();
    let v = driftless(&["validate", file.to_str().unwrap()]);
    assert_eq!(v.status.code(), Some(2));
    assert!(
        stderr(&v).contains("accel_vrw must be > 0"),
        "{}",
        stderr(&v)
    );

    // Without accelerometer columns the table says the stage takes the data sheet's.
    let o = driftless(&[
        "allan",
        &log,
        "--rate",
        "100",
        "--column",
        "gyro_x_degps",
        "--stage",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8(o.stdout).unwrap();
    assert!(!table.contains("accel_vrw = "), "{table}");
    assert!(
        table.contains("accel_vrw and accel_bias_instability are not given"),
        "{table}"
    );
    // Only accelerometer columns: no gyro terms to give.
    let only = dir.path().join("accel.csv");
    let text = std::fs::read_to_string(&log).unwrap();
    let cut: String = text
        .lines()
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            format!("{},{}\n", f[0], f[4])
        })
        .collect();
    std::fs::write(&only, cut).unwrap();
    let o = driftless(&[
        "allan",
        only.to_str().unwrap(),
        "--rate",
        "100",
        "--accel-column",
        "accel_x_g",
        "--accel-units",
        "g",
        "--stage",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("no gyro column to give predict.bias its terms"));
}

#[test]
fn bad_accelerometer_options_are_one_line_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let log = six_axis(dir.path());
    let error = |args: &[&str], needle: &str| {
        let o = driftless(args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "'{needle}' not in: {err}");
    };
    error(
        &accel_args(&log, &["--column", "accel_x_g"]),
        "column 'accel_x_g' is named by both --column and --accel-column",
    );
    error(
        &["allan", &log, "--rate", "100", "--accel-column", "accel_q"],
        "no column named 'accel_q'",
    );
    error(
        &accel_args(&log, &["--accel-units", "mg"]),
        "unknown accelerometer unit 'mg' (m/s^2 or g)",
    );
    error(
        &["allan", &log, "--rate", "100", "--accel-units", "g"],
        "--accel-column",
    );
}

/// A ROS 2 bag's `linear_acceleration` is `ax`, `ay`, `az` (m/s^2): the same doubles as from
/// CSV give the same curve and terms; a topic that marks it not provided, or another unit, is
/// refused in one line.
#[test]
fn a_bags_linear_acceleration_is_read_as_ax_ay_az() {
    use driftless::transport::ros2::bag::ImuBagWriter;
    use driftless::transport::ros2::{Imu, Time};
    let dir = tempfile::tempdir().unwrap();
    let log = six_axis(dir.path());
    let text = std::fs::read_to_string(&log).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .take(6000)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let messages: Vec<Imu> = rows
        .iter()
        .enumerate()
        .map(|(k, r)| Imu {
            stamp: Time::from_ns(1_700_000_000_000_000_000 + k as i64 * 10_000_000).unwrap(),
            frame_id: "imu_link".into(),
            angular_velocity: [r[1], r[2], r[3]].map(f64::to_radians),
            linear_acceleration: [r[4], r[5], r[6]].map(|a| a * G),
            ..Imu::default()
        })
        .collect();
    let write = |path: &Path, messages: &[Imu]| {
        let mut w = ImuBagWriter::create(path, "/imu").unwrap();
        for m in messages {
            w.write(m).unwrap();
        }
        w.finish().unwrap();
    };
    let bag = dir.path().join("six.mcap");
    write(&bag, &messages);
    let csv = dir.path().join("accel.csv");
    let mut s = String::from("ax,ay,az\n");
    for m in &messages {
        let [x, y, z] = m.linear_acceleration;
        s.push_str(&format!("{x},{y},{z}\n"));
    }
    std::fs::write(&csv, s).unwrap();
    let json = |file: &Path, extra: &[&str]| -> Value {
        let mut args = vec![
            "allan",
            file.to_str().unwrap(),
            "--accel-column",
            "ax",
            "--accel-column",
            "ay",
            "--accel-column",
            "az",
            "--json",
        ];
        args.extend_from_slice(extra);
        let o = driftless(&args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let from_bag = json(&bag, &[]);
    let from_csv = json(&csv, &["--rate", "100"]);
    let cols = from_bag["columns"].as_array().unwrap();
    // Without --column a bag's gyro columns are x, y, z.
    let names: Vec<&str> = cols.iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["x", "y", "z", "ax", "ay", "az"]);
    assert_eq!(cols[0]["unit"], "rad/s");
    for (b, c) in cols[3..]
        .iter()
        .zip(from_csv["columns"].as_array().unwrap())
    {
        assert_eq!(
            (b["sensor"].as_str(), b["unit"].as_str()),
            (Some("accel"), Some("m/s^2"))
        );
        assert_eq!(b["points"], c["points"], "{}: the same doubles", b["name"]);
        assert_eq!(b["terms"], c["terms"]);
    }
    let refused = |file: &Path, extra: &[&str], needle: &str| {
        let mut args = vec!["allan", file.to_str().unwrap(), "--accel-column", "ax"];
        args.extend_from_slice(extra);
        let o = driftless(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(needle), "'{needle}' not in: {err}");
    };
    refused(
        &bag,
        &["--accel-units", "g"],
        "a sensor_msgs/msg/Imu linear acceleration is in m/s^2 (REP 103), not g",
    );
    refused(
        &bag,
        &["--column", "w"],
        "ax, ay, az (its linear_acceleration, m/s^2)",
    );
    let mut none = messages[..200].to_vec();
    none[7].linear_acceleration_covariance[0] = -1.0;
    let gyro_only = dir.path().join("gyro-only.mcap");
    write(&gyro_only, &none);
    refused(&gyro_only, &[], "message 8 (log time");
    refused(
        &gyro_only,
        &[],
        "linear_acceleration is marked not provided (covariance[0] = -1)",
    );
}
