//! A stop column in a CSV replay drives `predict.bias` by sample time: replayed as fast as
//! possible through a real daemon, every output's flags follow the column, sample for sample.

mod common;

use std::time::Duration;

use common::{finish, start, wait_ready, Dir, Prefix};
use driftless::transport::{
    GyroSample, Transport, FLAG_MOVING, FLAG_STILL, FLAG_VEHICLE_MOVING, FLAG_VEHICLE_STOPPED,
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
