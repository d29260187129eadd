//! ROS 2 bags in (issue 30, item 2): the offline commands read a bag's sensor_msgs/msg/Imu
//! topic as they read the same doubles from CSV, take the rate from the stamps, report
//! irregular stamps, and refuse bad bags with one line naming the file and the message (exit
//! 2); `ingest.mcap` replays a bag through a real daemon, every message once, a message that
//! does not decode and a stamp going backwards flagged, and the daemon keeps serving.

mod common;

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::Duration;

use common::{collect, driftless, finish, qos, start, text, Dir, Prefix};
use driftless::sim::{SimConfig, Simulator};
use driftless::transport::ros2::bag::ImuBagWriter;
use driftless::transport::ros2::{Imu, MagneticField, Time, IMU_TYPE, MAG_TYPE};
use driftless::transport::Transport;
use driftless::wire::{
    GyroSample, FLAG_INPUT_INVALID, FLAG_STAMP_FAULT, FLAG_TIME_BACKWARDS, SENSOR_MAG,
    SENSOR_MAG_INVALID,
};
use serde_json::Value;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/ros2")
        .join(name)
}

fn imu(stamp_ns: i64, w: [f64; 3]) -> Imu {
    Imu {
        stamp: Time::from_ns(stamp_ns).unwrap(),
        frame_id: "imu_link".into(),
        angular_velocity: w,
        ..Imu::default()
    }
}

/// A bag of one Imu topic `/imu` written by our writer.
fn write_bag(path: &Path, messages: &[Imu]) {
    let mut w = ImuBagWriter::create(path, "/imu").unwrap();
    for m in messages {
        w.write(m).unwrap();
    }
    w.finish().unwrap();
}

/// A bag written directly: `/imu` messages, `None` a message that does not decode.
fn bag_with_bad(path: &Path, messages: &[Option<Imu>]) {
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(BufWriter::new(File::create(path).unwrap()))
        .unwrap();
    let schema = w.add_schema(IMU_TYPE, "ros2msg", b"").unwrap();
    let channel = w
        .add_channel(schema, "/imu", "cdr", &BTreeMap::new())
        .unwrap();
    for (i, m) in messages.iter().enumerate() {
        let data = match m {
            Some(m) => m.to_cdr().unwrap(),
            None => vec![0, 1, 0, 0, 7],
        };
        let t = 1_000_000_000 + i as u64 * 10_000_000;
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: channel,
                sequence: 0,
                log_time: t,
                publish_time: t,
            },
            &data,
        )
        .unwrap();
    }
    w.finish().unwrap();
}

/// `n` samples of the simulated ADIS16405 at 100 Hz, static, rad/s, stamped from 1.7e9 s.
fn simulated(n: usize) -> Vec<Imu> {
    let mut cfg = SimConfig::profile("adis16405").unwrap();
    cfg.rate_hz = 100.0;
    cfg.axes = 3;
    let mut sim = Simulator::new(&cfg).unwrap();
    (0..n)
        .map(|k| {
            let s = sim.next_sample();
            imu(
                1_700_000_000_000_000_000 + k as i64 * 10_000_000,
                s.measured.map(f64::to_radians),
            )
        })
        .collect()
}

/// The same samples as CSV (shortest round-trip decimals: the same doubles), `f` applied.
fn write_csv(path: &Path, messages: &[Imu], f: fn(f64) -> f64) {
    let mut s = String::from("x,y,z\n");
    for m in messages {
        let [x, y, z] = m.angular_velocity.map(f);
        s.push_str(&format!("{x},{y},{z}\n"));
    }
    std::fs::write(path, s).unwrap();
}

fn run_ok(args: &[&str]) -> String {
    let o = driftless(args);
    let (out, err) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{args:?}: {err}");
    out
}

/// Exit 2 with one line on stderr; the line.
fn run_bad(args: &[&str]) -> String {
    let o = driftless(args);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    let line = err.trim_end();
    assert!(!line.contains('\n'), "not one line: {err}");
    line.to_string()
}

/// Every column's points without its name: what must not depend on the container.
fn points(json: &str) -> Vec<Value> {
    let v: Value = serde_json::from_str(json).unwrap();
    v["columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            let mut c = c.clone();
            c.as_object_mut().unwrap().remove("name");
            c
        })
        .collect()
}

#[test]
fn allan_on_a_bag_is_allan_on_the_same_doubles_in_csv_with_the_rate_from_the_stamps() {
    let bag = fixture("imu.mcap");
    let csv = fixture("imu.csv");
    let from_bag = run_ok(&["allan", bag.to_str().unwrap(), "--json"]);
    let from_csv = run_ok(&[
        "allan",
        csv.to_str().unwrap(),
        "--rate",
        "100",
        "--units",
        "rad/s",
        "--column",
        "wx",
        "--column",
        "wy",
        "--column",
        "wz",
        "--json",
    ]);
    let (b, c) = (points(&from_bag), points(&from_csv));
    assert_eq!(b.len(), 3);
    assert_eq!(b, c, "the same deviations, bit for bit");
    // A --rate that the stamps agree with is taken; one they do not is refused.
    run_ok(&["allan", bag.to_str().unwrap(), "--rate", "100.2", "--json"]);
    let line = run_bad(&["allan", bag.to_str().unwrap(), "--rate", "200"]);
    assert!(
        line.contains("topic /imu/data: --rate 200 Hz, but the stamps say 100.000000 Hz"),
        "{line}"
    );
    let line = run_bad(&["allan", bag.to_str().unwrap(), "--units", "deg/s"]);
    assert!(line.contains("rad/s (REP 103)"), "{line}");
    let line = run_bad(&["allan", bag.to_str().unwrap(), "--topic", "/nope"]);
    assert!(
        line.contains(
            "no topic /nope; its topics: /chatter (std_msgs/msg/String, 180 messages), /imu/data \
             (sensor_msgs/msg/Imu, 1800 messages)"
        ),
        "{line}"
    );
    let line = run_bad(&["allan", csv.to_str().unwrap()]);
    assert!(line.contains("--rate is needed for a CSV log"), "{line}");
}

#[test]
fn bad_bags_are_one_line_naming_the_file_topic_message_and_log_time() {
    let dir = Dir::new();
    let good: Vec<Imu> = (0..50)
        .map(|k| imu(2_000_000_000 + k * 10_000_000, [0.01, 0.02, 0.03]))
        .collect();

    let mut back = good.clone();
    back[20].stamp = Time::from_ns(2_000_000_000 + 15 * 10_000_000).unwrap();
    let back_path = dir.path("back.mcap");
    write_bag(&back_path, &back);
    let line = run_bad(&["allan", back_path.to_str().unwrap()]);
    assert_eq!(
        line,
        format!(
            "driftless: error: {}: topic /imu, message 21 (log time 2150000000 ns): stamp \
             2150000000 ns is not after the previous message's 2190000000 ns: stamps must rise",
            back_path.display()
        )
    );

    let mut messages: Vec<Option<Imu>> = good.iter().cloned().map(Some).collect();
    messages[7] = None;
    let cdr_path = dir.path("cdr.mcap");
    bag_with_bad(&cdr_path, &messages);
    let model = dir.path("model.json");
    let model = model.to_str().unwrap();
    for (cmd, extra) in [
        ("allan", &[][..]),
        ("denoise", &[]),
        ("nav-eval", &[]),
        ("train", &["-o", model]),
    ] {
        let mut args = vec![cmd, cdr_path.to_str().unwrap()];
        args.extend_from_slice(extra);
        let line = run_bad(&args);
        assert!(
            line.contains(&format!(
                "{}: topic /imu, message 8 (log time 1070000000 ns): not a CDR {IMU_TYPE}",
                cdr_path.display()
            )),
            "{cmd}: {line}"
        );
    }

    let mut nan = good.clone();
    nan[3].angular_velocity[1] = f64::NAN;
    let nan_path = dir.path("nan.mcap");
    write_bag(&nan_path, &nan);
    let line = run_bad(&["allan", nan_path.to_str().unwrap()]);
    assert!(
        line.ends_with("topic /imu, message 4 (log time 2030000000 ns): angular_velocity.y is NaN"),
        "{line}"
    );

    let line = run_bad(&[
        "allan",
        fixture("written.json").to_str().unwrap(),
        "--topic",
        "/imu",
    ]);
    assert!(line.contains("not a ROS 2 bag"), "{line}");
}

#[test]
fn irregular_stamps_are_reported_not_hidden() {
    let dir = Dir::new();
    let mut stamps: Vec<i64> = (0..400).map(|k| k * 10_000_000).collect();
    // Samples 100..=104 missing (a gap of 6 periods), and one stamp 8 ms early (2 ms after
    // the one before it, 18 ms before the next: a gap too).
    stamps.drain(100..105);
    stamps[300] -= 8_000_000;
    let messages: Vec<Imu> = stamps
        .iter()
        .map(|&t| imu(5_000_000_000 + t, [0.001, 0.0, -0.001]))
        .collect();
    let p = dir.path("gaps.mcap");
    write_bag(&p, &messages);
    let o = driftless(&["allan", p.to_str().unwrap(), "--json"]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(
        err.contains("topic /imu: irregular stamps: 2 gaps (intervals over 1.5x the median 0.010000 s; the longest 0.060000 s, 6.0 periods)"),
        "{err}"
    );
    assert!(
        err.contains("1 intervals under half the median (the shortest 0.002000 s)"),
        "{err}"
    );
}

#[test]
fn denoise_writes_the_stamps_as_t_s() {
    let dir = Dir::new();
    let out = dir.path("out.csv");
    run_ok(&[
        "denoise",
        fixture("imu.mcap").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t_s,x,y,z"));
    assert!(lines.next().unwrap().starts_with("1700000000.123456789,"));
    assert_eq!(text.lines().count(), 1801);
}

#[test]
fn train_eval_and_nav_eval_read_a_bag_as_its_csv() {
    let dir = Dir::new();
    // 25 minutes at 100 Hz.
    let messages = simulated(150_000);
    let bag = dir.path("static.mcap");
    write_bag(&bag, &messages);
    let rad = dir.path("static-rad.csv");
    write_csv(&rad, &messages, |v| v);
    let deg = dir.path("static-deg.csv");
    write_csv(&deg, &messages, f64::to_degrees);

    let train = |input: &Path, model: &Path, extra: &[&str]| {
        let mut args = vec![
            "train",
            input.to_str().unwrap(),
            "--train",
            "60000",
            "--test",
            "30000",
            "-o",
            model.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        run_ok(&args)
    };
    let m_bag = dir.path("bag.json");
    let m_csv = dir.path("csv.json");
    let from_bag = train(&bag, &m_bag, &[]);
    let from_csv = train(&rad, &m_csv, &["--rate", "100", "--units", "rad/s"]);
    let body = |out: &str| out.split_once('\n').unwrap().1.to_string();
    assert!(from_bag.starts_with(&format!("{}: column x, 100 Hz", bag.display())));
    assert_eq!(
        body(&from_bag),
        body(&from_csv),
        "the same scores from the same doubles"
    );
    let model: Value = serde_json::from_str(&std::fs::read_to_string(&m_bag).unwrap()).unwrap();
    assert_eq!(model["units"], "rad/s");
    assert_eq!(model["rate_hz"], 100.0);
    run_ok(&[
        "eval",
        bag.to_str().unwrap(),
        "--model",
        m_bag.to_str().unwrap(),
    ]);

    let nav = |input: &Path, extra: &[&str]| {
        let mut args = vec![
            "nav-eval",
            input.to_str().unwrap(),
            "--characterise",
            "10min",
            "--window",
            "10min",
            "--terms",
            "adis16405",
            "--motion",
            "stop-and-go",
            "--json",
        ];
        args.extend_from_slice(extra);
        let mut v: Value = serde_json::from_str(&run_ok(&args)).unwrap();
        v.as_object_mut().unwrap().remove("source");
        v
    };
    let on_bag = nav(&bag, &[]);
    let on_csv = nav(&deg, &["--rate", "100"]);
    assert!(
        on_bag["cases"].as_array().is_some_and(|c| !c.is_empty()),
        "{on_bag}"
    );
    assert_eq!(on_bag, on_csv, "a bag's rad/s are the CSV's deg/s");
}

/// A pipeline replaying `file` at 100 Hz in rad/s, as fast as possible, straight to publish.
fn bag_pipeline(dir: &Dir, prefix: &str, file: &Path) -> PathBuf {
    dir.write(
        "bag.toml",
        &format!(
            r#"name = "{prefix}"
rate_hz = 100.0
input_units = "rad/s"

[iceoryx2]
buffer_size = 4096

[[stage]]
name = "sensor"
kind = "ingest.mcap"
output = "{prefix}/raw"
file = {file:?}
pace = "asap"

[[stage]]
name = "publish"
kind = "publish"
input = "{prefix}/raw"
output = "{prefix}/corrected"
"#,
            file = file.to_str().unwrap()
        ),
    )
}

#[test]
fn ingest_mcap_replays_a_bag_once_in_order_flagging_what_it_cannot_use() {
    const N: usize = 2000;
    let dir = Dir::new();
    let mut messages: Vec<Option<Imu>> = simulated(N).into_iter().map(Some).collect();
    messages[499] = None;
    let back = messages[798].as_ref().unwrap().stamp;
    messages[799].as_mut().unwrap().stamp = Time::from_ns(back.ns() - 5_000_000).unwrap();
    let file = dir.path("replay.mcap");
    bag_with_bad(&file, &messages);

    let prefix = Prefix::new("bagin");
    let pipeline = bag_pipeline(&dir, "bagin", &file);
    let o = driftless(&["validate", pipeline.to_str().unwrap()]);
    assert!(
        text(&o)
            .0
            .contains(&format!("replays {N} messages of /imu")),
        "{}",
        text(&o).0
    );
    let me = Transport::new(&prefix.0, "reader", qos(4096)).expect("node");
    let sub = me
        .input::<GyroSample>("bagin/corrected")
        .expect("subscriber");
    let daemon = start(&pipeline, &prefix, &[]);
    let got = collect(&sub, N, Duration::from_secs(60));
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(got.len(), N, "every message once");
    assert!(
        err.contains("topic /imu, message 500 (log time 5990000000 ns): not a CDR")
            && err.contains("(replayed as an invalid sample: flagged)"),
        "{err}"
    );
    for (i, (s, m)) in got.iter().zip(&messages).enumerate() {
        assert_eq!(s.seq, i as u64, "in order");
        match (i, m) {
            (499, None) => assert_ne!(s.flags & FLAG_INPUT_INVALID, 0, "seq 499 flagged"),
            (_, Some(m)) => {
                assert_eq!(
                    s.t_ns,
                    m.stamp.ns() as u64,
                    "seq {i}: the stamp is the time"
                );
                assert_eq!(
                    s.rate.map(f64::to_bits),
                    m.angular_velocity.map(f64::to_bits),
                    "seq {i}: rad/s bit for bit"
                );
                let flags = if i == 799 {
                    FLAG_TIME_BACKWARDS | FLAG_STAMP_FAULT
                } else {
                    0
                };
                assert_eq!(s.flags, flags, "seq {i}");
            }
            _ => unreachable!(),
        }
    }
}

#[test]
fn ingest_mcap_refuses_a_bag_at_another_rate_or_units_with_file_line_col() {
    let dir = Dir::new();
    let bag = fixture("imu.mcap");
    let good = std::fs::read_to_string(bag_pipeline(&dir, "badbag", &bag)).unwrap();
    for (from, to, want) in [
        (
            "rate_hz = 100.0",
            "rate_hz = 200.0",
            "its stamps step 10000000 ns at the median (100.000000 Hz), but the pipeline's \
             rate is 200 Hz",
        ),
        (
            "input_units = \"rad/s\"",
            "input_units = \"deg/s\"",
            "is a sensor_msgs/msg/Imu: its angular velocity is in rad/s (REP 103), but the \
             pipeline's input_units is deg/s",
        ),
    ] {
        let p = dir.write("bad.toml", &good.replace(from, to));
        let o = driftless(&["validate", p.to_str().unwrap()]);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{to}: {err}");
        // At the `file` key (line 12, column 8).
        let at = format!(
            "driftless: error: {}:12:8: topic /imu/data of ",
            p.display()
        );
        assert!(err.starts_with(&at), "{err}");
        assert!(err.contains(want), "{to}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    }
}

#[test]
fn a_looped_bag_whose_first_message_does_not_decode_keeps_its_time_base() {
    let dir = Dir::new();
    let file = dir.path("loop.mcap");
    // bag_with_bad's log times are 1 s + 10 ms per message; the stamps here say the same.
    let good = |k: i64| Some(imu(1_000_000_000 + k * 10_000_000, [0.01, 0.0, 0.0]));
    bag_with_bad(&file, &[None, good(1), good(2)]);
    let text_ = std::fs::read_to_string(bag_pipeline(&dir, "bagloop", &file))
        .unwrap()
        .replace("pace = \"asap\"", "loop = true");
    let pipeline = dir.write("loop.toml", &text_);
    let prefix = Prefix::new("bagloop");
    let me = Transport::new(&prefix.0, "reader", qos(4096)).expect("node");
    let sub = me
        .input::<GyroSample>("bagloop/corrected")
        .expect("subscriber");
    let daemon = start(&pipeline, &prefix, &["--duration", "2s"]);
    let got = collect(&sub, 6, Duration::from_secs(20));
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    let t: Vec<(u64, u64)> = got.iter().map(|s| (s.seq, s.t_ns)).collect();
    // The second pass starts one period after the first pass's last real stamp, whatever
    // the undecodable first message held.
    assert_eq!(
        t[3..],
        [(3, 1_020_000_000), (4, 1_030_000_000), (5, 1_040_000_000)],
        "{t:?}"
    );
}

/// The field of magnetometer reading `k`, tesla: 20 uT north-ish, 40 uT down, its own doubles.
fn mag_field(k: i64) -> [f64; 3] {
    [
        20e-6 + k as f64 * 1e-9,
        -5e-6 + (k * 7919 % 101) as f64 * 1e-10,
        -40e-6,
    ]
}

/// A bag of `/imu` (`imu`, log time = stamp) and `/imu/mag` (`mags`, in the order given) with
/// their types, written directly.
fn bag_with_mag(path: &Path, imu: &[Imu], mags: &[MagneticField]) {
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(BufWriter::new(File::create(path).unwrap()))
        .unwrap();
    let mut channel = |topic: &str, ty: &str| {
        let schema = w.add_schema(ty, "ros2msg", b"").unwrap();
        w.add_channel(schema, topic, "cdr", &BTreeMap::new())
            .unwrap()
    };
    let (imu_channel, mag_channel) = (channel("/imu", IMU_TYPE), channel("/imu/mag", MAG_TYPE));
    let mut all: Vec<(u16, u64, Vec<u8>)> = imu
        .iter()
        .map(|m| (imu_channel, m.stamp.ns() as u64, m.to_cdr().unwrap()))
        .collect();
    // The mags' receive times: 1 ms after the stamps in order, given in the mags' order (so a
    // mag given out of stamp order was received out of order).
    let mut received: Vec<u64> = mags
        .iter()
        .map(|m| m.stamp.ns() as u64 + 1_000_000)
        .collect();
    received.sort_unstable();
    for (m, t) in mags.iter().zip(received) {
        all.push((mag_channel, t, m.to_cdr().unwrap()));
    }
    // By log time, as a recorder writes.
    all.sort_by_key(|&(c, t, _)| (t, c));
    for (c, t, data) in all {
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: c,
                sequence: 0,
                log_time: t,
                publish_time: t,
            },
            &data,
        )
        .unwrap();
    }
    w.finish().unwrap();
}

/// A bag's magnetometer through `ingest.mcap`'s `mag_topic` and a real daemon: Imu at 100 Hz,
/// MagneticField at 50 Hz stamped 2 ms after every second Imu message (in the file out of
/// order here and there, one without a stamp, one NaN), stopping at 3.98 s. Each sample
/// carries, in tesla bit for bit, the newest reading up to half a period after its stamp
/// while it is at most 0.1 s old; after that none; the NaN reading flagged invalid by the
/// guard; every Imu sample served with its own rates.
#[test]
fn ingest_mcap_joins_a_bags_magnetometer_to_the_samples_by_stamp() {
    const N: usize = 600;
    const MS: i64 = 1_000_000;
    let dir = Dir::new();
    let imu = simulated(N);
    let t0 = imu[0].stamp.ns();
    let mut mags: Vec<MagneticField> = (0..400i64)
        .step_by(2)
        .map(|k| MagneticField {
            stamp: Time::from_ns(t0 + k * 10 * MS + 2 * MS).unwrap(),
            frame_id: "imu_link".into(),
            magnetic_field: if k == 100 {
                [f64::NAN; 3]
            } else {
                mag_field(k)
            },
            magnetic_field_covariance: [1e-12, 0.0, 0.0, 0.0, 1e-12, 0.0, 0.0, 0.0, 1e-12],
        })
        .collect();
    // Stamps out of order in the file (a recorder's receive order), and one not set.
    mags.swap(60, 61);
    mags.swap(150, 152);
    mags.push(MagneticField {
        stamp: Time::default(),
        ..mags[0].clone()
    });
    let file = dir.path("mag.mcap");
    bag_with_mag(&file, &imu, &mags);

    let prefix = Prefix::new("bagmag");
    let text_ = std::fs::read_to_string(bag_pipeline(&dir, "bagmag", &file))
        .unwrap()
        .replace(
            "pace = \"asap\"",
            "pace = \"asap\"\nmag_topic = \"/imu/mag\"",
        );
    let pipeline = dir.write("mag.toml", &text_);
    let o = driftless(&["validate", pipeline.to_str().unwrap()]);
    let (out, err) = text(&o);
    assert!(
        out.contains("magnetometer from /imu/mag, joined by stamp"),
        "{out}{err}"
    );
    let me = Transport::new(&prefix.0, "reader", qos(4096)).expect("node");
    let sub = me
        .input::<GyroSample>("bagmag/corrected")
        .expect("subscriber");
    let daemon = start(&pipeline, &prefix, &[]);
    let got = collect(&sub, N, Duration::from_secs(60));
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(got.len(), N, "every Imu sample once: {err}");
    assert!(err.contains("1 without a stamp left out"), "{err}");
    let bits = |v: [f64; 3]| v.map(f64::to_bits);
    for (k, (s, m)) in got.iter().zip(&imu).enumerate() {
        let k = k as i64;
        assert_eq!(s.seq, k as u64, "in order");
        assert_eq!(s.t_ns, m.stamp.ns() as u64, "{k}");
        assert_eq!(
            bits(s.rate),
            bits(m.angular_velocity),
            "{k}: the rates untouched"
        );
        assert_eq!(s.flags & FLAG_INPUT_INVALID, 0, "{k}");
        // The reading of this stamp: the even message at or just before it (2 ms after an
        // even one is within half a period), held while at most 0.1 s old.
        let j = (k - k % 2).min(398);
        let fresh = k * 10 * MS <= j * 10 * MS + 2 * MS + 100 * MS;
        let sensors = s.sensors & (SENSOR_MAG | SENSOR_MAG_INVALID);
        match (fresh, j) {
            (false, _) => assert_eq!(sensors, 0, "{k}: aged out"),
            // The NaN reading: flagged, the last good field (reading 98) held.
            (true, 100) => {
                assert_eq!(sensors, SENSOR_MAG | SENSOR_MAG_INVALID, "{k}");
                assert_eq!(bits(s.mag), bits(mag_field(98)), "{k}: held");
            }
            (true, _) => {
                assert_eq!(sensors, SENSOR_MAG, "{k}");
                assert_eq!(bits(s.mag), bits(mag_field(j)), "{k}: reading {j}, tesla");
            }
        }
    }
    // The last fresh sample is 408 (3.98 s + 0.1 s); every one after carries none.
    assert!(got[408].sensors & SENSOR_MAG != 0);
    assert!(got[409..].iter().all(|s| s.sensors & SENSOR_MAG == 0));

    // Its keys checked: a topic of another type, an age without a topic.
    for (from, to, want) in [
        (
            "mag_topic = \"/imu/mag\"",
            "mag_topic = \"/imu\"",
            "not sensor_msgs/msg/MagneticField",
        ),
        (
            "mag_topic = \"/imu/mag\"",
            "mag_max_age_s = 0.2",
            "mag_max_age_s needs a mag_topic",
        ),
        (
            "mag_topic = \"/imu/mag\"",
            "mag_topic = \"/nope\"",
            "no topic /nope",
        ),
    ] {
        let bad = dir.write("bad.toml", &text_.replace(from, to));
        let o = driftless(&["validate", bad.to_str().unwrap()]);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{to}: {err}");
        assert!(err.contains(want), "{to}: {err}");
    }
}

/// `nav_msgs/msg/Odometry` in little-endian CDR, written field by field (the layout rosbags
/// writes: `tests/ros2_bag.rs` reads its odometry): a speed along x, a yaw rate and its variance.
fn odometry_cdr(stamp: Time, speed: f64, yaw_rate: f64, yaw_var: f64) -> Vec<u8> {
    let mut b = vec![0, 1, 0, 0];
    let string = |b: &mut Vec<u8>, s: &str| {
        while (b.len() - 4) % 4 != 0 {
            b.push(0);
        }
        b.extend_from_slice(&((s.len() + 1) as u32).to_le_bytes());
        b.extend_from_slice(s.as_bytes());
        b.push(0);
    };
    let doubles = |b: &mut Vec<u8>, v: &[f64]| {
        while (b.len() - 4) % 8 != 0 {
            b.push(0);
        }
        for x in v {
            b.extend_from_slice(&x.to_le_bytes());
        }
    };
    b.extend_from_slice(&stamp.sec.to_le_bytes());
    b.extend_from_slice(&stamp.nanosec.to_le_bytes());
    string(&mut b, "odom");
    string(&mut b, "base_link");
    doubles(&mut b, &[0.0; 7 + 36]);
    doubles(&mut b, &[speed, 0.0, 0.0, 0.0, 0.0, yaw_rate]);
    let mut cov = [0.0; 36];
    cov[35] = yaw_var;
    doubles(&mut b, &cov);
    b
}

/// A bag of a vehicle that never stops: its Imu at 100 Hz (rad/s, the gyro's z up, a bias of
/// 0.5 deg/s on every axis) and its wheel odometry at 50 Hz (the true yaw rate, logged 30 ms
/// after its stamp), replayed as fast as possible. With `motion_output` the odometry reaches
/// `predict.bias` on the samples' clock and teaches the z bias while driving; without it, only
/// the stops would, and there are none.
#[test]
fn ingest_mcap_publishes_a_bags_odometry_and_the_bias_learns_it_while_driving() {
    const N: usize = 3000;
    const BIAS_DEG_S: f64 = 0.5;
    let turn = |k: usize| [0.0, 15.0, 0.0, -10.0, 5.0][(k / 200) % 5];
    let t0 = 1_700_000_000_000_000_000i64;
    let stamp = |k: usize| Time::from_ns(t0 + k as i64 * 10_000_000).unwrap();
    let noise = |k: usize| 0.2 * (((k * 7919) % 101) as f64 / 101.0 - 0.5);
    let imu: Vec<Imu> = (0..N)
        .map(|k| {
            let w = [
                BIAS_DEG_S + noise(k),
                BIAS_DEG_S + noise(k + 3),
                BIAS_DEG_S + turn(k) + noise(k + 7),
            ];
            imu(stamp(k).ns(), w.map(f64::to_radians))
        })
        .collect();
    let dir = Dir::new();
    let file = dir.path("drive.mcap");
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(BufWriter::new(File::create(&file).unwrap()))
        .unwrap();
    let mut channel = |topic: &str, ty: &str| {
        let schema = w.add_schema(ty, "ros2msg", b"").unwrap();
        w.add_channel(schema, topic, "cdr", &BTreeMap::new())
            .unwrap()
    };
    let (imu_ch, odo_ch) = (
        channel("/imu", IMU_TYPE),
        channel("/odom", "nav_msgs/msg/Odometry"),
    );
    let mut all: Vec<(u16, u64, Vec<u8>)> = imu
        .iter()
        .map(|m| (imu_ch, m.stamp.ns() as u64, m.to_cdr().unwrap()))
        .collect();
    for k in (1..N).step_by(2) {
        // The mean over its 20 ms: samples k - 1 and k.
        let yaw = ((turn(k - 1) + turn(k)) / 2.0).to_radians();
        let cdr = odometry_cdr(stamp(k), 2.0, yaw, 0.1f64.to_radians().powi(2));
        all.push((odo_ch, stamp(k).ns() as u64 + 30_000_000, cdr));
    }
    all.sort_by_key(|&(c, t, _)| (t, c));
    for (c, t, data) in all {
        let header = mcap::records::MessageHeader {
            channel_id: c,
            sequence: 0,
            log_time: t,
            publish_time: t,
        };
        w.write_to_known_channel(&header, &data).unwrap();
    }
    w.finish().unwrap();

    let run = |tag: &str, motion: bool| {
        let prefix = Prefix::new(tag);
        let stages = format!(
            "pace = \"asap\"\nstop_topic = \"/odom\"\nstop_speed = 0.05\n{}\n\
             [[stage]]\nname = \"predict\"\nkind = \"predict.bias\"\ninput = \"{tag}/raw\"\n\
             output = \"{tag}/predicted\"\nprofile = \"adis16405\"\n\
             stop_input = \"{tag}/stop\"\nvehicle_up = \"+z\"\n",
            if motion {
                format!("motion_output = \"{tag}/stop\"")
            } else {
                String::new()
            }
        );
        let text_ = std::fs::read_to_string(bag_pipeline(&dir, tag, &file))
            .unwrap()
            .replace("pace = \"asap\"\n", &stages)
            .replace(
                &format!("input = \"{tag}/raw\"\noutput = \"{tag}/corrected\""),
                &format!("input = \"{tag}/predicted\"\noutput = \"{tag}/corrected\""),
            );
        let pipeline = dir.write(&format!("{tag}.toml"), &text_);
        let o = driftless(&["validate", pipeline.to_str().unwrap()]);
        let (out, err) = text(&o);
        assert_eq!(o.status.code(), Some(0), "{out}{err}");
        assert_eq!(
            out.contains(&format!("motion out: {tag}/stop")),
            motion,
            "{out}"
        );
        let me = Transport::new(&prefix.0, "reader", qos(4096)).expect("node");
        let sub = me
            .input::<GyroSample>(&format!("{tag}/corrected"))
            .expect("subscriber");
        let daemon = start(&pipeline, &prefix, &[]);
        let got = collect(&sub, N, Duration::from_secs(60));
        let (code, err) = finish(daemon, Duration::from_secs(20));
        assert_eq!(code, Some(0), "{err}");
        assert_eq!(got.len(), N, "every sample once: {err}");
        (got, err)
    };
    let (got, err) = run("bagodo", true);
    let drift = |s: &GyroSample, a: usize| s.drift[a].to_degrees();
    let last = &got[N - 1];
    assert!(
        (drift(last, 2) - BIAS_DEG_S).abs() < 0.1,
        "z drift {}: {err}",
        drift(last, 2)
    );
    assert!(drift(last, 0).abs() < 0.05, "x was never told: {err}");
    assert!(
        err.contains("odometry (vehicle_up = +z, confirmed by the turns"),
        "{err}"
    );
    let (got, err) = run("bagnoodo", false);
    assert!(
        drift(&got[N - 1], 2).abs() < 0.05,
        "nothing learnt without it: {err}"
    );
}
