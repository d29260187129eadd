//! The whole IMU through a real daemon: a CSV replay's accelerometer columns (in g) ride beside
//! the rates through a lagged denoiser and the bias filter, and every published sample carries
//! its own row's reading in m/s², bit for bit; a bad accelerometer cell past the rows checked
//! at validation keeps its row's rate, the accelerometer held and flagged, never dropped; a
//! gyro-only log publishes no accelerometer at all (absent, never zero). The magnetometer's
//! columns (in uT) arrive likewise, in tesla with `SENSOR_MAG`, an empty cell held and flagged.

mod common;

use std::time::Duration;

use common::{finish, start, wait_ready, Dir, Prefix};
use driftless::allan::STANDARD_GRAVITY;
use driftless::drift::bias::AccelTerms;
use driftless::transport::Transport;
use driftless::wire::{
    GyroSample, FLAG_INPUT_INVALID, SENSOR_ACCEL, SENSOR_ACCEL_INVALID, SENSOR_MAG,
    SENSOR_MAG_INVALID,
};

const N: usize = 2000;
/// The row whose accelerometer cell is not a number (past the 1000 rows validation checks).
const BAD_ROW: usize = 1500;
/// The row whose magnetometer cell is empty.
const BAD_MAG_ROW: usize = 1700;

/// The accelerometer of row `i`, g: gravity on z and a tilt that differs from row to row.
fn accel_g(i: usize) -> [f64; 3] {
    [
        0.001 * (i % 101) as f64,
        -0.002 * (i % 53) as f64,
        -1.0 + 1e-4 * (i % 7) as f64,
    ]
}

/// The magnetometer of row `i`, uT: a field of about 45 uT that turns a little.
fn mag_ut(i: usize) -> [f64; 3] {
    [
        20.0 + 0.01 * (i % 97) as f64,
        -3.5 + 0.02 * (i % 13) as f64,
        -40.25,
    ]
}

/// What a log carries beside the rates.
#[derive(Clone, Copy, PartialEq)]
enum Beside {
    Nothing,
    Accel,
    AccelAndMag,
}

fn pipeline(beside: Beside) -> String {
    let accel = match beside {
        Beside::Nothing => "",
        Beside::Accel => "accel_columns = [\"ax\", \"ay\", \"az\"]\n",
        Beside::AccelAndMag => {
            "accel_columns = [\"ax\", \"ay\", \"az\"]\n\
             mag_columns = [\"mx\", \"my\", \"mz\"]\nmag_units = \"uT\"\n"
        }
    };
    format!(
        r#"
name = "imu"
rate_hz = 100.0
input_units = "deg/s"
accel_units = "g"

[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "imu/raw"
file = "log.csv"
time_column = "t"
{accel}pace = "asap"
start_delay_s = 1.0

[[stage]]
name = "denoise"
kind = "denoise.wavelet"
input = "imu/raw"
output = "imu/denoised"
lag = 16

[[stage]]
name = "predict"
kind = "predict.bias"
input = "imu/denoised"
output = "imu/predicted"
profile = "adis16405"

[[stage]]
name = "publish"
kind = "publish"
input = "imu/predicted"
output = "imu/corrected"

[iceoryx2]
buffer_size = 4096
"#
    )
}

/// Replays the log through a daemon; every published sample, in order.
fn run(beside: Beside, name: &str) -> (Vec<GyroSample>, String) {
    let mut csv = String::from("t,x,y,z,ax,ay,az,mx,my,mz\n");
    for i in 0..N {
        let [ax, ay, az] = accel_g(i);
        let az = if i == BAD_ROW {
            "nan".to_string()
        } else {
            az.to_string()
        };
        let [mx, my, mz] = mag_ut(i);
        let my = if i == BAD_MAG_ROW {
            String::new()
        } else {
            my.to_string()
        };
        csv.push_str(&format!(
            "{},{},{},{},{ax},{ay},{az},{mx},{my},{mz}\n",
            i as f64 / 100.0,
            0.3,
            -0.1,
            0.05 * (i as f64 * 0.01).sin()
        ));
    }
    let dir = Dir::new();
    dir.write("log.csv", &csv);
    let file = dir.write("p.toml", &pipeline(beside));
    let prefix = Prefix::new(name);
    // The probe's node before the daemon: the replay starts `start_delay_s` after the
    // daemon is ready, and the subscriber must be open by then.
    let node = Transport::new(&prefix.0, "imu-probe", Default::default()).unwrap();
    let mut daemon = start(&file, &prefix, &[]);
    wait_ready(&prefix, "imu/stats", &mut daemon);
    let input = node.open_input::<GyroSample>("imu/corrected").unwrap();
    let got = common::collect(&input, N, Duration::from_secs(30));
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    (got, err)
}

#[test]
fn the_accelerometer_rides_beside_the_corrected_rate_sample_for_sample() {
    let (got, err) = run(Beside::Accel, "imuaccel");
    // The cell's position and the count, on stderr (line: the header, then row BAD_ROW).
    for want in [
        format!(":{}:", BAD_ROW + 2),
        "column 'az': NaN is not a finite sample".to_string(),
        "1 row(s) with an unreadable accelerometer, magnetometer, stop or odometry cell"
            .to_string(),
    ] {
        assert!(err.contains(&want), "{want} in {err}");
    }
    let white_std = AccelTerms::ADIS16405.white_std(100.0);
    assert!((white_std - 0.2 / 60.0 * 10.0).abs() < 1e-15, "{white_std}");
    assert_eq!(got.len(), N, "every sample published once");
    for (i, s) in got.iter().enumerate() {
        assert_eq!(s.seq, i as u64, "in order");
        let want = accel_g(i).map(|g| g * STANDARD_GRAVITY);
        if i == BAD_ROW {
            // A bad accelerometer cell: the row is replayed, not dropped, and its rate kept;
            // the accelerometer is held from the row before and flagged.
            let held = accel_g(i - 1).map(|g| g * STANDARD_GRAVITY);
            assert_eq!(s.sensors, SENSOR_ACCEL | SENSOR_ACCEL_INVALID, "row {i}");
            assert_eq!(s.accel, held, "row {i}");
            assert_eq!(s.accel_reading(), None);
            assert_eq!(s.flags & FLAG_INPUT_INVALID, 0, "the rate is good");
        } else {
            assert_eq!(s.sensors, SENSOR_ACCEL, "row {i}");
            // The bias filter's accelerometer terms (the ADIS16405 data sheet's VRW) give each
            // reading its white noise.
            assert_eq!(s.accel_std, [white_std; 3], "row {i}");
            // Each sample's own row, through a denoiser 16 samples late: time-aligned, exact.
            assert_eq!(s.accel.map(f64::to_bits), want.map(f64::to_bits), "row {i}");
        }
    }
}

#[test]
fn a_gyro_only_log_publishes_no_accelerometer() {
    let (got, _) = run(Beside::Nothing, "imugyro");
    assert_eq!(got.len(), N);
    assert!(got.iter().all(|s| s.sensors == 0
        && s.accel_reading().is_none()
        && s.accel == [0.0; 3]
        && s.mag_reading().is_none()
        && s.mag == [0.0; 3]));
}

#[test]
fn the_magnetometer_arrives_in_tesla_and_a_bad_cell_is_held_and_flagged() {
    let (got, err) = run(Beside::AccelAndMag, "imumag");
    for want in [
        format!(":{}:", BAD_MAG_ROW + 2),
        "column 'my': '' is not a number".to_string(),
        "2 row(s) with an unreadable accelerometer, magnetometer, stop or odometry cell"
            .to_string(),
    ] {
        assert!(err.contains(&want), "{want} in {err}");
    }
    assert_eq!(got.len(), N, "every sample published once");
    let tesla = |i: usize| mag_ut(i).map(|ut| ut * 1e-6);
    for (i, s) in got.iter().enumerate() {
        assert_eq!(s.seq, i as u64, "in order");
        assert_eq!(s.flags & FLAG_INPUT_INVALID, 0, "row {i}: the rate is good");
        let accel = if i == BAD_ROW {
            SENSOR_ACCEL | SENSOR_ACCEL_INVALID
        } else {
            SENSOR_ACCEL
        };
        if i == BAD_MAG_ROW {
            // An empty magnetometer cell: the row replayed, not dropped, its rate and its
            // accelerometer kept; the field held from the row before and flagged.
            assert_eq!(
                s.sensors,
                accel | SENSOR_MAG | SENSOR_MAG_INVALID,
                "row {i}"
            );
            assert_eq!(s.mag, tesla(i - 1), "row {i}");
            assert_eq!(s.mag_reading(), None);
            assert!(s.accel_reading().is_some());
        } else {
            assert_eq!(s.sensors, accel | SENSOR_MAG, "row {i}");
            // Each sample's own row, in tesla, through a denoiser 16 samples late: exact.
            assert_eq!(
                s.mag.map(f64::to_bits),
                tesla(i).map(f64::to_bits),
                "row {i}"
            );
        }
    }
}

#[test]
fn the_simulator_and_accel_units_take_the_same_standard_gravity() {
    // Two layers-apart copies of one constant (the simulator sits beside `allan`).
    assert_eq!(
        driftless::sim::force::STANDARD_GRAVITY.to_bits(),
        STANDARD_GRAVITY.to_bits()
    );
}
