//! Orientation through a real daemon: a CSV replay of a body tilted 15 deg about x, standing,
//! turning a quarter turn about the vertical, standing again, through `predict.bias` and
//! `attitude.6d`. Every published sample carries an orientation; its roll is the tilt, its
//! heading the quarter turn, its heading's standard deviation grows from the start; a row whose
//! accelerometer cell is not a number is published, coasting and flagged, never dropped.

mod common;

use std::time::Duration;

use common::{finish, start, wait_ready, Dir, Prefix};
use driftless::allan::STANDARD_GRAVITY;
use driftless::attitude::roll_pitch_yaw;
use driftless::transport::Transport;
use driftless::wire::{
    GyroSample, SENSOR_ACCEL, SENSOR_ACCEL_INVALID, SENSOR_ORIENTATION, SENSOR_ORIENTATION_COASTING,
};

const RATE_HZ: f64 = 100.0;
/// Still 0-6 s, a 30 deg/s turn about the vertical 6-9 s, still 9-14 s.
const N: usize = 1400;
const TURN: (usize, usize) = (600, 900);
const TILT_DEG: f64 = 15.0;
/// The gyro's constant bias on every axis, deg/s: the bias filter learns it at the first rest.
const BIAS: f64 = 0.1;
/// The row whose accelerometer cell is not a number (past the 1000 rows validation checks).
const BAD_ROW: usize = 1200;

const PIPELINE: &str = r#"
name = "att"
rate_hz = 100.0
input_units = "deg/s"
accel_units = "m/s^2"

[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "att/raw"
file = "log.csv"
time_column = "t"
accel_columns = ["ax", "ay", "az"]
pace = "asap"
start_delay_s = 1.0

[[stage]]
name = "denoise"
kind = "denoise.none"
input = "att/raw"
output = "att/denoised"

[[stage]]
name = "predict"
kind = "predict.bias"
input = "att/denoised"
output = "att/predicted"
profile = "adis16405"

[[stage]]
name = "attitude"
kind = "attitude.6d"
input = "att/predicted"
output = "att/attitude"

[[stage]]
name = "publish"
kind = "publish"
input = "att/attitude"
output = "att/corrected"

[iceoryx2]
buffer_size = 4096
"#;

/// The log: the body's up is (0, sin 15, cos 15), so a turn about the vertical at w reads
/// w times that on the gyro, and gravity's reaction reads g times it on the accelerometer.
fn log() -> String {
    let t = TILT_DEG.to_radians();
    let up = [0.0, t.sin(), t.cos()];
    let mut csv = String::from("t,x,y,z,ax,ay,az\n");
    for i in 0..N {
        let w = if (TURN.0..TURN.1).contains(&i) {
            30.0
        } else {
            0.0
        };
        let [gx, gy, gz] = up.map(|u| u * w + BIAS);
        let [ax, ay, az] = up.map(|u| u * STANDARD_GRAVITY);
        let az = if i == BAD_ROW {
            "nan".to_string()
        } else {
            az.to_string()
        };
        csv.push_str(&format!(
            "{},{gx},{gy},{gz},{ax},{ay},{az}\n",
            i as f64 / RATE_HZ
        ));
    }
    csv
}

/// Run the pipeline `file` in a daemon under a prefix of `tag`: up to `n` published samples, and
/// its stderr once it ended with exit 0.
fn run(file: &std::path::Path, tag: &str, n: usize) -> (Vec<GyroSample>, String) {
    let prefix = Prefix::new(tag);
    // The probe's node before the daemon: the replay starts `start_delay_s` after the
    // daemon is ready, and the subscriber must be open by then.
    let node = Transport::new(&prefix.0, "att-probe", Default::default()).unwrap();
    let mut daemon = start(file, &prefix, &[]);
    wait_ready(&prefix, "att/stats", &mut daemon);
    let input = node.open_input::<GyroSample>("att/corrected").unwrap();
    let got = common::collect(&input, n, Duration::from_secs(30));
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{tag}: {err}");
    (got, err)
}

#[test]
fn the_orientation_rides_with_every_sample_and_follows_the_body() {
    let dir = Dir::new();
    dir.write("log.csv", &log());
    let (got, err) = run(&dir.write("p.toml", PIPELINE), "attitude", N);
    assert!(
        err.contains("attitude: 1400 samples, 1 coasting on the gyro"),
        "{err}"
    );
    assert_eq!(got.len(), N, "every sample published once");

    let deg =
        |s: &GyroSample| roll_pitch_yaw(s.orientation_estimate().unwrap()).map(f64::to_degrees);
    let mut last_heading_sd = 0.0;
    for (i, s) in got.iter().enumerate() {
        assert_eq!(s.seq, i as u64, "in order");
        let q = s
            .orientation_estimate()
            .unwrap_or_else(|| panic!("row {i}: {s:?}"));
        let norm: f64 = q.iter().map(|v| v * v).sum();
        assert!((norm - 1.0).abs() < 1e-9, "row {i}: {q:?}");
        assert!(
            s.orientation_std.iter().all(|v| v.is_finite() && *v > 0.0),
            "row {i}: {s:?}"
        );
        // The heading's uncertainty only grows: it is relative to the start.
        assert!(s.orientation_std[2] >= last_heading_sd, "row {i}: {s:?}");
        last_heading_sd = s.orientation_std[2];
        if i == BAD_ROW {
            assert_eq!(
                s.sensors,
                SENSOR_ACCEL
                    | SENSOR_ACCEL_INVALID
                    | SENSOR_ORIENTATION
                    | SENSOR_ORIENTATION_COASTING,
                "row {i}"
            );
        } else {
            assert_eq!(s.sensors, SENSOR_ACCEL | SENSOR_ORIENTATION, "row {i}");
        }
    }
    // Settled at the first rest: the tilt is the roll, the heading still 0.
    let [roll, pitch, yaw] = deg(&got[TURN.0 - 1]);
    assert!((roll - TILT_DEG).abs() < 0.5, "{roll} {pitch} {yaw}");
    assert!(pitch.abs() < 0.5 && yaw.abs() < 1.0, "{roll} {pitch} {yaw}");
    // After the quarter turn: the heading is +90 deg (counter-clockwise about up), the
    // inclination unchanged.
    let [roll, pitch, yaw] = deg(&got[N - 1]);
    assert!((yaw - 90.0).abs() < 2.0, "{roll} {pitch} {yaw}");
    assert!(
        (roll - TILT_DEG).abs() < 0.5 && pitch.abs() < 0.5,
        "{roll} {pitch} {yaw}"
    );
    // The uncertainty says the heading is known to a few degrees, not exactly nor not at all.
    let sd = got[N - 1].orientation_std[2].to_degrees();
    assert!(sd > 0.01 && sd < 10.0, "{sd}");
}

/// Prewarming (`prewarm_us`: before each paced sample the attitude stage runs VQF once on a
/// spare copy, to bring its code back into the cache) changes no output: two real-time runs of
/// the log's first 3 s, with and without it, publish the same samples bit for bit.
#[test]
fn prewarming_changes_no_orientation() {
    const ROWS: usize = 300;
    let dir = Dir::new();
    let head: String = log()
        .lines()
        .take(ROWS + 1)
        .map(|l| l.to_owned() + "\n")
        .collect();
    dir.write("log.csv", &head);
    let paced = PIPELINE.replace("pace = \"asap\"", "pace = \"realtime\"");
    let warmed = paced.replace("input_units", "prewarm_us = 2000.0\ninput_units");
    assert_ne!(paced, warmed);
    let [plain, prewarmed] = [("plain", paced), ("prewarmed", warmed)].map(|(name, text)| {
        let file = dir.write(&format!("{name}.toml"), &text);
        let (got, _) = run(&file, &format!("attwarm{name}"), ROWS);
        assert_eq!(got.len(), ROWS, "{name}: every sample");
        // What the clock stamps differs from run to run; nothing else may.
        got.into_iter()
            .map(|s| GyroSample {
                ingest_ns: 0,
                epoch: 0,
                ..s
            })
            .collect::<Vec<_>>()
    });
    assert!(plain.iter().all(|s| s.sensors & SENSOR_ORIENTATION != 0));
    for (i, (p, w)) in plain.iter().zip(&prewarmed).enumerate() {
        assert_eq!(p, w, "sample {i}");
    }
}
