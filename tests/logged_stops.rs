//! A stop column in a CSV replay, and a ROS 2 bag's odometry, drive `predict.bias` by sample
//! time: replayed as fast as possible through a real daemon, every output's flags follow the
//! logged stops, sample for sample.

mod common;

use std::path::Path;
use std::time::Duration;

use common::{driftless, finish, start, text, wait_ready, Dir, Prefix};
use driftless::transport::Transport;
use driftless::wire::{
    GyroSample, FLAG_INPUT_INVALID, FLAG_MOVING, FLAG_OUTPUT_REPAIRED, FLAG_STILL,
    FLAG_VEHICLE_MOVING, FLAG_VEHICLE_STOPPED,
};

const N: usize = 3000;

#[test]
fn a_stop_column_drives_the_bias_filter_by_sample_time_at_any_replay_speed() {
    // A gyro at rest with a bias; the log says the vehicle moves for the first third, stands
    // for the second, and says nothing for the last.
    let mut csv = String::from("t,x,y,z,stopped\n");
    for i in 0..N {
        let stop = match i * 3 / N {
            0 => "0",
            1 => "1",
            _ => "nan",
        };
        let wobble = 0.02 * ((i * 7919 % 17) as f64 / 17.0 - 0.5);
        csv.push_str(&format!(
            "{},{},{},{},{stop}\n",
            i as f64 / 100.0,
            0.4 + wobble,
            -0.2 - wobble,
            0.1 + wobble
        ));
    }
    let dir = Dir::new();
    dir.write("log.csv", &csv);
    let file = dir.write(
        "p.toml",
        r#"
name = "s"
rate_hz = 100.0
input_units = "deg/s"

[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "s/raw"
file = "log.csv"
time_column = "t"
stop_column = "stopped"
pace = "asap"
start_delay_s = 1.0

[[stage]]
name = "predict"
kind = "predict.bias"
input = "s/raw"
output = "s/predicted"
profile = "adis16405"

[[stage]]
name = "publish"
kind = "publish"
input = "s/predicted"
output = "s/corrected"

[iceoryx2]
buffer_size = 4096
"#,
    );
    let prefix = Prefix::new("logstops");
    let mut daemon = start(&file, &prefix, &[]);
    wait_ready(&prefix, "s/stats", &mut daemon);
    let node = Transport::new(&prefix.0, "stops-probe", Default::default()).unwrap();
    let input = node.open_input::<GyroSample>("s/corrected").unwrap();
    let got = common::collect(&input, N, Duration::from_secs(30));
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(got.len(), N, "{err}");
    for (i, s) in got.iter().enumerate() {
        let has = |f: u32| s.flags & f != 0;
        match i * 3 / N {
            0 => assert!(
                has(FLAG_VEHICLE_MOVING) && has(FLAG_MOVING) && !has(FLAG_STILL),
                "{i}: {:#x}",
                s.flags
            ),
            1 => assert!(
                has(FLAG_VEHICLE_STOPPED) && has(FLAG_STILL),
                "{i}: {:#x}",
                s.flags
            ),
            _ => assert!(
                !has(FLAG_VEHICLE_STOPPED) && !has(FLAG_VEHICLE_MOVING),
                "{i}: {:#x}",
                s.flags
            ),
        }
    }
    // Moving, nothing was learnt: no drift removed. Standing, the bias was.
    assert_eq!(got[N / 3 - 1].drift, [0.0; 3]);
    let learnt = got[2 * N / 3 - 1].drift.map(f64::to_degrees);
    for (d, b) in learnt.iter().zip([0.4, -0.2, 0.1]) {
        assert!((d - b).abs() < 0.01, "{learnt:?}");
    }
}

/// Rows of the nan test: more than the 1000 validation checks, so the replay reads some itself.
const M: usize = 1600;
/// The one stop cell that is no number, past the rows validation checks.
const WORD_ROW: usize = 1400;

/// Row `i`'s stop cell: unknown in every spelling of NaN (the first data row among them, and
/// rows before and after the 1000 validation checks), else 1, 0, and one word.
fn stop_cell(i: usize) -> &'static str {
    match i {
        WORD_ROW => "abc",
        _ if i % 5 == 0 => ["nan", "NaN", "-nan", " NAN"][i / 5 % 4],
        _ if i % 5 < 3 => "1",
        _ => "0",
    }
}

/// A log whose stop column says `nan` in its first data row and in many later ones.
fn nan_stops_log() -> String {
    let mut csv = String::from("t,x,y,z,stopped\n");
    for i in 0..M {
        csv.push_str(&format!(
            "{},{},{},{},{}\n",
            i as f64 / 100.0,
            0.25 + i as f64 * 1e-4,
            -0.5,
            (i % 7) as f64 * 0.125,
            stop_cell(i)
        ));
    }
    csv
}

/// The rates row `i` of [`nan_stops_log`] holds, read back from its text as the replay reads
/// them.
fn logged_rate(log: &str, i: usize) -> [f64; 3] {
    let line = log.lines().nth(i + 1).unwrap();
    let cells: Vec<f64> = line
        .split(',')
        .skip(1)
        .take(3)
        .map(|c| c.parse().unwrap())
        .collect();
    [cells[0], cells[1], cells[2]]
}

/// A NaN stop cell means "unknown": validation takes it, in the first data row too, without a
/// word; the replay publishes every such row valid, its rates untouched, neither stopped nor
/// moving. A stop cell that is no number is still refused at validation with its position,
/// and past the checked rows it is reported at file:line:col, its rates kept.
#[test]
fn a_nan_stop_cell_is_unknown_neither_a_refusal_nor_a_warning_nor_an_invalid_rate() {
    let dir = Dir::new();
    let log = nan_stops_log();
    dir.write("log.csv", &log);
    let pipeline = |file: &str| {
        format!(
            r#"
name = "n"
rate_hz = 100.0
input_units = "rad/s"

[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "n/raw"
file = "{file}"
time_column = "t"
stop_column = "stopped"
pace = "asap"
start_delay_s = 1.0

[[stage]]
name = "publish"
kind = "publish"
input = "n/raw"
output = "n/corrected"

[iceoryx2]
buffer_size = 4096
"#
        )
    };
    let file = dir.write("p.toml", &pipeline("log.csv"));
    let (out, err) = text(&driftless(&["validate", file.to_str().unwrap()]));
    assert!(err.is_empty() && !out.contains("warning"), "{out}{err}");

    // The word within the checked rows: refused, at its line and column.
    let mut early = log.lines().take(4).collect::<Vec<_>>().join("\n");
    early = early.replacen(",1\n", ",abc\n", 1) + "\n";
    assert!(early.contains("abc"), "{early}");
    dir.write("early.csv", &early);
    let bad = dir.write("bad.toml", &pipeline("early.csv"));
    let o = driftless(&["validate", bad.to_str().unwrap()]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("early.csv:3:") && err.contains("column 'stopped': 'abc' is not a number"),
        "{err}"
    );

    let prefix = Prefix::new("nanstops");
    let mut daemon = start(&file, &prefix, &[]);
    wait_ready(&prefix, "n/stats", &mut daemon);
    let node = Transport::new(&prefix.0, "nan-stops-probe", Default::default()).unwrap();
    let input = node.open_input::<GyroSample>("n/corrected").unwrap();
    let got = common::collect(&input, M, Duration::from_secs(30));
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(got.len(), M, "{err}");
    // Only the word is reported: at its line (the header is line 1) and the stop's column.
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("warning")).collect();
    let at = format!("log.csv:{}:", WORD_ROW + 2);
    assert_eq!(warnings.len(), 2, "{err}");
    assert!(
        warnings[0].contains(&at)
            && warnings[0].contains("column 'stopped': 'abc' is not a number"),
        "{err}"
    );
    assert!(
        warnings[1].contains(
            "1 row(s) with an unreadable accelerometer, magnetometer, stop or odometry cell"
        ),
        "{err}"
    );
    for (i, s) in got.iter().enumerate() {
        assert_eq!(s.seq, i as u64);
        let has = |f: u32| s.flags & f != 0;
        assert!(
            !has(FLAG_INPUT_INVALID) && !has(FLAG_OUTPUT_REPAIRED),
            "{i}: {:#x}",
            s.flags
        );
        let want = logged_rate(&log, i);
        assert_eq!(s.rate.map(f64::to_bits), want.map(f64::to_bits), "row {i}");
        let (stopped, moving) = (has(FLAG_VEHICLE_STOPPED), has(FLAG_VEHICLE_MOVING));
        match stop_cell(i) {
            "1" => assert!(stopped && !moving, "{i}: {:#x}", s.flags),
            "0" => assert!(moving && !stopped, "{i}: {:#x}", s.flags),
            _ => assert!(
                !stopped && !moving,
                "{i} ({:?}): {:#x}",
                stop_cell(i),
                s.flags
            ),
        }
    }
}

/// The bag of scripts/gen_ros2_fixture.py odom: a gyro at rest with a bias, 1,500 Imu
/// messages at 100 Hz; odometry at 20 Hz, 3 ms after an Imu stamp, moving for 5 s, standing
/// for 5 s, then silent. Each sample takes the last odometry at or before its stamp, up to
/// 0.5 s old.
#[test]
fn a_bags_odometry_drives_the_bias_filter_by_stamp() {
    const M: usize = 1500;
    let bag = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/ros2/odom.mcap");
    let dir = Dir::new();
    let pipeline = |stop_topic: &str| {
        format!(
            r#"
name = "o"
rate_hz = 100.0
input_units = "rad/s"

[[stage]]
name = "sensor"
kind = "ingest.mcap"
output = "o/raw"
file = "{}"
stop_topic = "{stop_topic}"
pace = "asap"
start_delay_s = 1.0

[[stage]]
name = "predict"
kind = "predict.bias"
input = "o/raw"
output = "o/predicted"
profile = "adis16405"

[[stage]]
name = "publish"
kind = "publish"
input = "o/predicted"
output = "o/corrected"

[iceoryx2]
buffer_size = 4096
"#,
            bag.display()
        )
    };
    // The Imu topic is no vehicle's motion: refused at validation, with its position.
    let wrong = dir.write("wrong.toml", &pipeline("/imu/data"));
    let out = std::process::Command::new(common::bin())
        .args(["validate", wrong.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("wrong.toml:") && err.contains("not a vehicle's motion"),
        "{err}"
    );

    let file = dir.write("p.toml", &pipeline("/odom"));
    let prefix = Prefix::new("bagstops");
    let mut daemon = start(&file, &prefix, &[]);
    wait_ready(&prefix, "o/stats", &mut daemon);
    let node = Transport::new(&prefix.0, "bag-stops-probe", Default::default()).unwrap();
    let input = node.open_input::<GyroSample>("o/corrected").unwrap();
    let got = common::collect(&input, M, Duration::from_secs(30));
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(got.len(), M, "{err}");
    for (k, s) in got.iter().enumerate() {
        let has = |f: u32| s.flags & f != 0;
        let (stopped, moving) = (has(FLAG_VEHICLE_STOPPED), has(FLAG_VEHICLE_MOVING));
        match k {
            // Before the first odometry (3 ms after the first stamp): unknown.
            0 => assert!(!stopped && !moving, "{k}: {:#x}", s.flags),
            // Odometry says 1.5 m/s up to its message at 4.953 s.
            1..=500 => assert!(
                moving && !stopped && has(FLAG_MOVING),
                "{k}: {:#x}",
                s.flags
            ),
            // Standing from 5.003 s; the last message (9.953 s) holds for 0.5 s.
            501..=1045 => assert!(stopped && !moving && has(FLAG_STILL), "{k}: {:#x}", s.flags),
            _ => assert!(!stopped && !moving, "{k}: {:#x}", s.flags),
        }
    }
    assert_eq!(got[500].drift, [0.0; 3], "nothing learnt while moving");
    let learnt = got[1045].drift.map(f64::to_degrees);
    for (d, b) in learnt.iter().zip([0.4, -0.2, 0.1]) {
        assert!((d - b).abs() < 0.01, "{learnt:?}");
    }
}
