//! `attitude.6d`'s `state_file` between real daemon processes: a magnet fixed to a turning
//! sensor is learnt online as hard iron, saved while running, kept at SIGTERM, and the next
//! start begins from it; a file that cannot be used costs the warm start, never the start.

mod common;

use std::time::{Duration, Instant};

use common::{finish, signal, start, wait_ready, Dir, Prefix};

const RATE_HZ: f64 = 100.0;
/// The earth's field, uT: 20 north, 40 down.
const FIELD: [f64; 3] = [0.0, 20.0, -40.0];
/// The magnet fixed to the sensor, uT: attached `MAGNET_FROM` s into the log.
const MAGNET: [f64; 3] = [9.0, -6.0, 5.0];
const MAGNET_FROM: f64 = 20.0;
const GRAVITY: f64 = 9.80665;

fn mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// An earth vector in the body at the body-to-earth attitude `q`: `q^-1 v q`.
fn to_body(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let c = [q[0], -q[1], -q[2], -q[3]];
    let r = mul(mul(c, [0.0, v[0], v[1], v[2]]), q);
    [r[1], r[2], r[3]]
}

/// A body turning about every axis for `secs` s: gyro (deg/s), accelerometer (m/s^2) and
/// magnetometer (uT, with the magnet from `magnet_from` s on), as CSV.
fn turning_csv(secs: f64, magnet_from: f64) -> String {
    let mut s = String::from("t,x,y,z,ax,ay,az,mx,my,mz\n");
    let dt = 1.0 / RATE_HZ;
    let mut q = [1.0, 0.0, 0.0, 0.0];
    for k in 0..(secs * RATE_HZ) as usize {
        let t = k as f64 * dt;
        let w = [
            0.8 * (0.5 * t).sin(),
            0.6 * (0.3 * t + 1.0).cos(),
            1.5 * (0.2 * t).sin(),
        ];
        let a = to_body(q, [0.0, 0.0, GRAVITY]);
        let mut m = to_body(q, FIELD);
        if t >= magnet_from {
            for i in 0..3 {
                m[i] += MAGNET[i];
            }
        }
        let [gx, gy, gz] = w.map(f64::to_degrees);
        s.push_str(&format!(
            "{t},{gx},{gy},{gz},{},{},{},{},{},{}\n",
            a[0], a[1], a[2], m[0], m[1], m[2]
        ));
        let angle = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt() * dt;
        if angle > 0.0 {
            let f = (angle / 2.0).sin() / (angle / dt);
            q = mul(q, [(angle / 2.0).cos(), w[0] * f, w[1] * f, w[2] * f]);
            let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            q = q.map(|v| v / n);
        }
    }
    s
}

fn pipeline(log: &str, pace: &str) -> String {
    format!(
        r#"
name = "mag"
rate_hz = 100.0
input_units = "deg/s"
accel_units = "m/s^2"

[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "mag/raw"
file = "{log}"
time_column = "t"
accel_columns = ["ax", "ay", "az"]
mag_columns = ["mx", "my", "mz"]
mag_units = "uT"
pace = {pace}
start_delay_s = 0.5

[[stage]]
name = "denoise"
kind = "denoise.none"
input = "mag/raw"
output = "mag/denoised"

[[stage]]
name = "predict"
kind = "predict.bias"
input = "mag/denoised"
output = "mag/predicted"
profile = "adis16405"

[[stage]]
name = "attitude"
kind = "attitude.6d"
input = "mag/predicted"
output = "mag/attitude"
use_mag = true
state_file = "mag.state"
state_every_s = 0.5

[[stage]]
name = "publish"
kind = "publish"
input = "mag/attitude"
output = "mag/corrected"
"#
    )
}

/// The state file's hard iron, uT, if there is one (always whole: it is replaced atomically).
fn saved_hard_iron(path: &std::path::Path) -> Option<[f64; 3]> {
    let text = std::fs::read_to_string(path).ok()?;
    let v: toml::Value = toml::from_str(&text).expect("a whole state file, never half");
    let h = v["hard_iron_ut"].as_array().unwrap();
    Some([0, 1, 2].map(|i| h[i].as_float().unwrap()))
}

fn near_magnet(h: &[f64; 3], tol: f64) -> bool {
    h.iter().zip(MAGNET).all(|(a, b)| (a - b).abs() < tol)
}

#[test]
fn the_learnt_hard_iron_is_kept_across_a_restart() {
    let dir = Dir::new();
    dir.write("turning.csv", &turning_csv(100.0, MAGNET_FROM));
    let file = dir.write("p.toml", &pipeline("turning.csv", "10.0"));
    let state = dir.path("mag.state");

    // Cold: the magnet comes at 20 s and the rotation teaches it; saved while running.
    let prefix = Prefix::new("magst1");
    let mut daemon = start(&file, &prefix, &[]);
    wait_ready(&prefix, "mag/stats", &mut daemon);
    let end = Instant::now() + Duration::from_secs(60);
    loop {
        if saved_hard_iron(&state).is_some_and(|h| near_magnet(&h, 1.0)) {
            break;
        }
        assert!(daemon.try_wait().unwrap().is_none(), "the daemon ended");
        assert!(Instant::now() < end, "no learnt hard iron saved after 60 s");
        std::thread::sleep(Duration::from_millis(50));
    }
    signal(&daemon, libc::SIGTERM);
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    let saved = saved_hard_iron(&state).expect("saved at shutdown");
    assert!(near_magnet(&saved, 1.0), "{saved:?}");

    // Warm: the magnet is there from the first sample; the filter starts from what it learnt.
    dir.write("again.csv", &turning_csv(5.0, 0.0));
    let again = dir.write("p2.toml", &pipeline("again.csv", "\"asap\""));
    let prefix = Prefix::new("magst2");
    let mut daemon = start(&again, &prefix, &[]);
    wait_ready(&prefix, "mag/stats", &mut daemon);
    let (code, err) = finish(daemon, Duration::from_secs(30));
    assert_eq!(code, Some(0), "{err}");
    let line = err
        .lines()
        .find(|l| l.contains("warm start from state_file"))
        .unwrap_or_else(|| panic!("a warm start: {err}"));
    let shown = format!(
        "hard iron ({:.2}, {:.2}, {:.2})",
        saved[0], saved[1], saved[2]
    );
    assert!(line.contains(&shown), "{line} does not start from {shown}");
    let after = saved_hard_iron(&state).unwrap();
    assert!(near_magnet(&after, 1.0), "kept: {after:?}");

    // Garbage: a cold start that says why and keeps the file aside; the run goes on.
    std::fs::write(&state, "hard_iron_ut = [1, 2").unwrap();
    let prefix = Prefix::new("magst3");
    let mut daemon = start(&again, &prefix, &[]);
    wait_ready(&prefix, "mag/stats", &mut daemon);
    let (code, err) = finish(daemon, Duration::from_secs(30));
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("not a magnetometer state driftless wrote")
            && err.contains("starts cold; the file is kept as"),
        "{err}"
    );
    let aside: Vec<_> = std::fs::read_dir(state.parent().unwrap())
        .unwrap()
        .flatten()
        .filter(|e| {
            e.file_name()
                .to_string_lossy()
                .starts_with("mag.state.unusable-")
        })
        .collect();
    assert_eq!(aside.len(), 1, "kept aside once");
    assert!(saved_hard_iron(&state).is_some(), "saved anew");
}
