//! `predict.bias` learning the bias while the vehicle drives, from the yaw rate of its
//! odometry, between real processes: this test is the sensor driver and the vehicle. It
//! publishes raw rates at 200 Hz (a known bias on every axis, the vehicle turning about the
//! gyro's -z) and `StopSignal`s at 50 Hz saying "moves", with the true turn rate as the yaw
//! rate. The vehicle never stops, so the stops teach nothing: the bias of the up axis is learnt
//! from the yaw rate alone, with the sign of `vehicle_up` applied; without `vehicle_up` the yaw
//! rate is refused with a message naming the fix, and without a yaw rate nothing is learnt.

mod common;

use std::time::{Duration, Instant};

use common::{collect, finish, qos, raw, report, signal, start, wait_ready, Dir, Prefix};
use driftless::transport::{monotonic_ns, Transport};
use driftless::wire::{GyroSample, OdometryStats, RawSample, StatsSnapshot, StopSignal, RAW_ACCEL};
use libc::SIGTERM;

const BIAS_DEG_S: f64 = 0.5;
const RATE_HZ: u64 = 200;
/// Samples per odometry message (50 Hz).
const PER_MESSAGE: usize = 4;
const N: usize = 3000;

/// The vehicle's true turn rate, deg/s: 2 s segments, straight and turning both ways.
fn turn(i: usize) -> f64 {
    [0.0, 15.0, 0.0, -10.0, 5.0][(i / 400) % 5]
}

struct Run {
    got: Vec<GyroSample>,
    stderr: String,
    learnt: Vec<String>,
    /// The stats service's odometry, from a snapshot taken after the last sample.
    odometry: OdometryStats,
}

/// The daemon with `keys` in its predict.bias table, fed by this test; `yaw`: whether the
/// signals carry the yaw rate.
fn run(test: &str, keys: &str, yaw: bool) -> Run {
    run_with(test, keys, yaw, 0)
}

/// [`run`], the vehicle standing for its first `stand` samples (and saying so) with an
/// accelerometer level and upside down (the gyro's -z is up: it reads -g on z), then driving.
fn run_with(test: &str, keys: &str, yaw: bool, stand: usize) -> Run {
    let prefix = Prefix::new(test);
    let dir = Dir::new();
    let text = format!(
        r#"
name = "o"
rate_hz = {RATE_HZ}.0
axes = 3
input_units = "deg/s"
report_interval_s = 0.5

[iceoryx2]
buffer_size = 4096

[[stage]]
name = "sensor"
kind = "ingest.iceoryx2"
input = "o/sensor"
output = "o/raw"

[[stage]]
name = "denoise"
kind = "denoise.none"
input = "o/raw"
output = "o/denoised"

[[stage]]
name = "predict"
kind = "predict.bias"
input = "o/denoised"
output = "o/predicted"
profile = "adis16405"
stop_input = "o/stop"
stop_max_age_s = 2.0
{keys}

[[stage]]
name = "publish"
kind = "publish"
input = "o/predicted"
output = "o/corrected"
"#
    );
    let file = dir.write("p.toml", &text);
    let me = Transport::new(&prefix.0, "vehicle", qos(4096)).expect("node");
    let corrected = me.input::<GyroSample>("o/corrected").expect("subscriber");
    let sensor = me.output::<RawSample>("o/sensor", true).expect("sensor");
    let stop = me
        .output::<StopSignal>("o/stop", false)
        .expect("stop signal");
    let mut child = start(
        &file,
        &prefix,
        &["--report", dir.path("report.json").to_str().unwrap()],
    );
    wait_ready(&prefix, "o/stats", &mut child);
    let stats = me.input::<StatsSnapshot>("o/stats").expect("stats");

    let noise = |i: usize| 0.3 * (((i * 7919) % 101) as f64 / 101.0 - 0.5);
    let period = Duration::from_nanos(1_000_000_000 / RATE_HZ);
    let started = Instant::now();
    let mut got = Vec::with_capacity(N);
    for i in 0..N {
        let stands = i < stand;
        let w = if stands { 0.0 } else { turn(i - stand) };
        // The vehicle's up is the gyro's -z: a turn to the left reads negative there.
        let x = BIAS_DEG_S + noise(i);
        let z = BIAS_DEG_S - w + noise(i + 17);
        let mut sample = raw(i as u64, i as u64 * 1_000_000_000 / RATE_HZ, [x, x, z]);
        if stand > 0 {
            sample.flags |= RAW_ACCEL;
            sample.accel = [0.05, -0.03, -9.80665];
        }
        assert_eq!(sensor.send(&sample).unwrap(), 1);
        if (i + 1) % PER_MESSAGE == 0 {
            // The mean yaw rate over the message's period, which ends now.
            let mut s = if stands {
                StopSignal::new(monotonic_ns(), 0.0, 1)
            } else {
                StopSignal::new(monotonic_ns(), 3.0, 0)
            };
            if yaw {
                s.yaw_rate_rad_s = w.to_radians();
                s.yaw_rate_std_rad_s = 0.1f64.to_radians();
                s.period_ns = PER_MESSAGE as u64 * 1_000_000_000 / RATE_HZ;
            }
            stop.send(&s).expect("send stop signal");
        }
        if i % 200 == 199 {
            got.extend(collect(
                &corrected,
                i + 1 - got.len(),
                Duration::from_secs(10),
            ));
        }
        let due = started + period * (i as u32 + 1);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
    }
    got.extend(collect(&corrected, N - got.len(), Duration::from_secs(10)));
    // A snapshot from after the last sample (one every 0.5 s).
    let mut snapshot = None;
    let until = Instant::now() + Duration::from_secs(5);
    while Instant::now() < until {
        while let Some(s) = stats.receive().expect("stats") {
            snapshot = Some(s);
        }
        if snapshot.is_some_and(|s| s.samples_out >= N as u64) {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let odometry = snapshot.expect("a stats snapshot").odometry;
    signal(&child, SIGTERM);
    let (code, stderr) = finish(child, Duration::from_secs(10));
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(got.len(), N, "every sample once");
    let r = report(&dir);
    let learnt = r["learnt"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l.as_str().unwrap().to_string())
        .collect();
    Run {
        got,
        stderr,
        learnt,
        odometry,
    }
}

/// The one line of `stderr` that says `what`; fails unless there is exactly one.
fn said_once<'a>(stderr: &'a str, what: &str) -> &'a str {
    let said: Vec<&str> = stderr.lines().filter(|l| l.contains(what)).collect();
    assert_eq!(
        said.len(),
        1,
        "{what:?} said {} times: {stderr}",
        said.len()
    );
    said[0]
}

fn drift_deg(s: &GyroSample, axis: usize) -> f64 {
    s.drift[axis].to_degrees()
}

#[test]
fn the_yaw_rate_teaches_the_up_axis_bias_while_driving() {
    let r = run("odo-up", "vehicle_up = \"-z\"", true);
    let last = &r.got[N - 1];
    // The up axis (-z) learnt its bias in motion, with the sign of vehicle_up; the others
    // were never told anything (no stop).
    assert!(
        (drift_deg(last, 2) - BIAS_DEG_S).abs() < 0.1,
        "z drift {} deg/s, not {BIAS_DEG_S}; {:?}",
        drift_deg(last, 2),
        r.learnt
    );
    // Its uncertainty shrank from the prior (1 deg/s) with it.
    assert!(last.drift_std[2].to_degrees() < 0.1, "{:?}", last.drift_std);
    for axis in [0, 1] {
        assert!(drift_deg(last, axis).abs() < 0.05, "{:?}", last.drift);
    }
    // Converged within the first half and stays there.
    assert!(r.got[N / 2..]
        .iter()
        .all(|s| (drift_deg(s, 2) - BIAS_DEG_S).abs() < 0.15));
    let line = r
        .learnt
        .iter()
        .find(|l| l.contains("odometry (vehicle_up = -z, confirmed by the turns (slope"))
        .unwrap_or_else(|| panic!("no odometry line in {:?}", r.learnt));
    assert!(line.contains("spans accepted"), "{line}");
    eprintln!(
        "{line}; z drift {} deg/s, sd {} deg/s",
        drift_deg(last, 2),
        last.drift_std[2].to_degrees()
    );
    assert!(!r.stderr.contains("refused"), "{}", r.stderr);
    // The stats service (and so ROS 2's /diagnostics) says the same.
    let o = r.odometry;
    assert_eq!(
        (o.up_name(), o.mounting_name()),
        ("-z", "confirmed"),
        "{o:?}"
    );
    assert!(o.learnt > 10 && o.spans_accepted >= o.learnt, "{o:?}");
    assert!(
        (o.bias_learnt_rad_s.to_degrees() - BIAS_DEG_S).abs() < 0.1,
        "{o:?}"
    );
}

/// The wrong sign: the gyro's up is -z, the file says +z. The first turns show it, the daemon
/// says so once with the fix, and the yaw rate teaches nothing after (the summary says it was
/// refused).
/// The scale learnt in the turns is saved with the bias (`state_file`), on the up axis only,
/// and the next start resumes that axis (the others, never told anything, start cold).
#[test]
fn the_learnt_odometry_scale_is_kept_in_the_state_file() {
    let dir = Dir::new();
    let state = dir.path("bias.toml");
    let keys = format!("vehicle_up = \"-z\"\nstate_file = \"{}\"", state.display());
    run("odo-state", &keys, true);
    let text = std::fs::read_to_string(&state).expect("the state saved");
    let file: toml::Table = text.parse().expect("TOML");
    let axes = file["axis"].as_array().expect("axes");
    let z = axes[2].as_table().unwrap();
    let sd = z["odometry_scale_sd"]
        .as_float()
        .expect("z keeps its scale");
    let scale = z["odometry_scale"].as_float().unwrap();
    // Learnt from the 1 % prior: the odometry here is exact.
    assert!(
        sd < 0.005 && scale.abs() < 2.0 * sd + 1e-3,
        "{scale} +- {sd}"
    );
    assert!(!axes[0].as_table().unwrap().contains_key("odometry_scale"));
    // x and y never learnt (no stop): they start cold, z resumes.
    let r = run("odo-state2", &keys, true);
    let line = said_once(&r.stderr, "warm start from state_file");
    assert!(
        line.contains("(x, y cold: no better than the prior by now)"),
        "{line}"
    );
}

#[test]
fn a_yaw_rate_of_the_wrong_sign_is_found_and_refused_with_the_fix() {
    let r = run("odo-sign", "vehicle_up = \"+z\"", true);
    let said = said_once(&r.stderr, "the yaw rate turns against the gyro's +z axis");
    assert!(said.contains("set vehicle_up = \"-z\""), "{said}");
    // Before the turns told, the straights taught it (a sign does not matter there); the
    // turns, of the wrong sign, never pulled it off: the truth, or nothing learnt.
    let z = drift_deg(&r.got[N - 1], 2);
    assert!(
        (z - BIAS_DEG_S).abs() < 0.15 || z.abs() < 0.05,
        "the wrong sign pulled z to {z} deg/s"
    );
    assert!(
        r.learnt
            .iter()
            .any(|l| l.contains("refused: it did not turn with the gyro")),
        "{:?}",
        r.learnt
    );
    assert_eq!(r.odometry.mounting_name(), "refused: wrong sign");
}

#[test]
fn without_the_yaw_rate_nothing_is_learnt_while_driving() {
    let r = run("odo-none", "vehicle_up = \"-z\"", false);
    let last = &r.got[N - 1];
    assert!(drift_deg(last, 2).abs() < 0.05, "{:?}", last.drift);
    assert!(last.drift_std[2].to_degrees() > 0.5, "{:?}", last.drift_std);
}

#[test]
fn a_yaw_rate_without_vehicle_up_is_refused_with_the_fix() {
    let r = run("odo-refused", "", true);
    assert_eq!(r.odometry.up, 0, "no odometry in the stats");
    let last = &r.got[N - 1];
    assert!(drift_deg(last, 2).abs() < 0.05, "{:?}", last.drift);
    assert!(
        r.stderr.contains("the yaw rate is refused") && r.stderr.contains("vehicle_up = \"+z\""),
        "{}",
        r.stderr
    );
    assert_eq!(
        r.stderr.matches("the yaw rate is refused").count(),
        1,
        "said once: {}",
        r.stderr
    );
    assert!(r.learnt.iter().all(|l| !l.contains("odometry")));
}

/// `vehicle_up = "gravity"`: the first rest's specific force names -z as up, and the turns
/// after it teach that axis's bias, as a configured "-z" would.
#[test]
fn gravity_names_the_up_axis_at_the_first_rest() {
    let r = run_with("odo-gravity", "vehicle_up = \"gravity\"", true, 600);
    assert!(
        r.stderr
            .contains("vehicle_up from gravity: the gyro's -z points up"),
        "{}",
        r.stderr
    );
    let last = &r.got[N - 1];
    assert!(
        (drift_deg(last, 2) - BIAS_DEG_S).abs() < 0.1,
        "z drift {}: {:?}",
        drift_deg(last, 2),
        r.learnt
    );
    assert_eq!(r.odometry.up_name(), "-z", "{:?}", r.odometry);
    assert!(r.odometry.learnt > 5, "{:?}", r.odometry);
    assert!(
        r.learnt
            .iter()
            .any(|l| l.contains("vehicle_up = -z from gravity")),
        "{:?}",
        r.learnt
    );
}

/// A configured axis that gravity contradicts: refused at the first rest, before any turn,
/// with the fix; the turns teach nothing after.
#[test]
fn gravity_refuses_a_vehicle_up_it_contradicts_with_the_fix() {
    let r = run_with("odo-gravity-no", "vehicle_up = \"+z\"", true, 600);
    let said = said_once(&r.stderr, "gravity says the gyro's -z points up");
    assert!(said.contains("Set vehicle_up = \"-z\""), "{said}");
    assert_eq!(r.odometry.mounting_name(), "refused: wrong sign");
    assert_eq!(r.odometry.learnt, 0, "{:?}", r.odometry);
}

/// A CSV log of the same drive (its stop column: never stands), replayed as fast as possible:
/// `yaw_rate_column` holds the odometry's message on every fourth row (empty between), `motion_output` publishes it, and
/// `predict.bias` learns the up axis's bias from it as from a live odometry. Without the
/// column nothing is learnt in motion.
#[test]
fn a_csv_logs_yaw_rate_teaches_the_bias_while_driving() {
    let dir = Dir::new();
    let noise = |i: usize| 0.3 * (((i * 7919) % 101) as f64 / 101.0 - 0.5);
    let mut csv = String::from("t,x,y,z,stopped,wz,wz_sd\n");
    for i in 0..N {
        let (x, z) = (BIAS_DEG_S + noise(i), BIAS_DEG_S - turn(i) + noise(i + 17));
        // The message stamped at the end of its period, on its last row.
        let (wz, sd) = if (i + 1) % PER_MESSAGE == 0 {
            let mean = (i + 1 - PER_MESSAGE..=i).map(turn).sum::<f64>() / PER_MESSAGE as f64;
            (mean.to_string(), "0.1".to_string())
        } else {
            (String::new(), String::new())
        };
        let t = i as f64 / RATE_HZ as f64;
        csv += &format!("{t},{x},{x},{z},0,{wz},{sd}\n");
    }
    dir.write("drive.csv", &csv);
    let run = |tag: &str, yaw: bool| {
        let prefix = Prefix::new(tag);
        let odometry = if yaw {
            format!(
                "yaw_rate_column = \"wz\"\nyaw_rate_std_column = \"wz_sd\"\n\
                 motion_output = \"{tag}/stop\""
            )
        } else {
            String::new()
        };
        let text = format!(
            r#"
name = "{tag}"
rate_hz = {RATE_HZ}.0
axes = 3
input_units = "deg/s"

[iceoryx2]
buffer_size = 4096

[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "{tag}/raw"
file = "drive.csv"
time_column = "t"
stop_column = "stopped"
pace = "asap"
{odometry}

[[stage]]
name = "predict"
kind = "predict.bias"
input = "{tag}/raw"
output = "{tag}/predicted"
profile = "adis16405"
stop_input = "{tag}/stop"
vehicle_up = "-z"

[[stage]]
name = "publish"
kind = "publish"
input = "{tag}/predicted"
output = "{tag}/corrected"
"#
        );
        let file = dir.write(&format!("{tag}.toml"), &text);
        let me = Transport::new(&prefix.0, "reader", qos(4096)).expect("node");
        let sub = me
            .input::<GyroSample>(&format!("{tag}/corrected"))
            .expect("subscriber");
        let child = start(
            &file,
            &prefix,
            &["--report", dir.path("report.json").to_str().unwrap()],
        );
        let got = collect(&sub, N, Duration::from_secs(60));
        let (code, stderr) = finish(child, Duration::from_secs(20));
        assert_eq!(code, Some(0), "{stderr}");
        assert_eq!(got.len(), N, "every sample once: {stderr}");
        let learnt: Vec<String> = report(&dir)["learnt"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l.as_str().unwrap().to_string())
            .collect();
        (got, learnt)
    };
    let (got, learnt) = run("csvodo", true);
    let last = &got[N - 1];
    assert!(
        (drift_deg(last, 2) - BIAS_DEG_S).abs() < 0.1,
        "z drift {}: {learnt:?}",
        drift_deg(last, 2)
    );
    assert!(drift_deg(last, 0).abs() < 0.05, "x was never told");
    assert!(
        learnt
            .iter()
            .any(|l| l.contains("odometry (vehicle_up = -z, confirmed by the turns")),
        "{learnt:?}"
    );
    let (got, _) = run("csvnoodo", false);
    assert!(
        drift_deg(&got[N - 1], 2).abs() < 0.05,
        "nothing learnt in motion without the yaw rate"
    );
}
