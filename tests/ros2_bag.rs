//! ROS 2 bags (`driftless::transport::ros2::bag`) against the independent peer `rosbags` (pinned in
//! scripts/gen_ros2_fixture.py): our reader decodes the bag rosbags wrote (tests/fixtures/ros2/
//! imu.mcap) to exactly the values rosbags put in (imu.csv and the script's formulas), every
//! message once and in order; every bad input is one line naming the file, the topic and the
//! message; what our writer writes reads back bit for bit, and the committed written.mcap,
//! which rosbags read and checked message by message (written.json), is what the writer still
//! writes (`DRIFTLESS_BLESS=1` rewrites it after a deliberate change; then rerun the script's
//! `check`); and recorded.mcap, what `driftless record --format ros2` recorded of a daemon
//! replaying imu.mcap (tests/record.rs), reads here as rosbags read it (recorded.json: every
//! message's stamp, angular velocity and covariance, by digest).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use driftless::io::BagErrorKind;
use driftless::synthetic::SplitMix64;
use driftless::transport::ros2::bag::{
    Bag, ImuBagWriter, ImuRecord, IMU_TYPE_HASH, OFFERED_QOS_PROFILES,
};
use driftless::transport::ros2::{Imu, Time, IMU_DEFINITION, IMU_TYPE};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/ros2")
        .join(name)
}

fn read_all(bag: &Bag, topic: &str) -> Vec<ImuRecord> {
    bag.imu_messages(topic)
        .unwrap()
        .collect::<Result<Vec<_>, _>>()
        .unwrap()
}

/// The value of a doubles array in the fixture script's `diag`.
fn diag(a: f64, b: f64, c: f64) -> [f64; 9] {
    [a, 0.0, 0.0, 0.0, b, 0.0, 0.0, 0.0, c]
}

fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// rosbags' nav_msgs/msg/Odometry (scripts/gen_ros2_fixture.py odom): every message's stamp
/// and speed as the script computed them, bit for bit; the Imu topic is refused as motion.
#[test]
fn the_rosbags_odometry_reads_its_stamps_and_speeds_bit_for_bit() {
    let bag = Bag::open(&fixture("odom.mcap")).unwrap();
    let got: Vec<_> = bag
        .motion_messages("/odom")
        .unwrap()
        .collect::<Result<Vec<_>, _>>()
        .unwrap();
    let csv = std::fs::read_to_string(fixture("odom.csv")).unwrap();
    let rows: Vec<(i64, f64)> = csv
        .lines()
        .skip(1)
        .map(|l| {
            let (t, v) = l.split_once(',').unwrap();
            (t.parse().unwrap(), v.parse().unwrap())
        })
        .collect();
    assert_eq!(got.len(), 200);
    assert_eq!(rows.len(), got.len());
    for (r, (stamp, speed)) in got.iter().zip(&rows) {
        assert_eq!(r.msg.stamp.ns(), *stamp, "message {}", r.number);
        assert_eq!(
            r.msg.speed().to_bits(),
            speed.to_bits(),
            "message {}",
            r.number
        );
    }
    let e = bag.motion_messages("/imu/data").err().unwrap();
    assert_eq!(e.kind, BagErrorKind::NotImu);
    assert!(e.to_string().contains("not a vehicle's motion"), "{e}");
}

#[test]
fn the_rosbags_bag_reads_bit_for_bit_every_message_once_in_order() {
    let bag = Bag::open(&fixture("imu.mcap")).unwrap();
    let topic = bag.imu_topic(None).unwrap();
    assert_eq!(topic, "/imu/data");
    let got = read_all(&bag, &topic);
    let csv = std::fs::read_to_string(fixture("imu.csv")).unwrap();
    let mut rows = csv.lines();
    assert_eq!(rows.next(), Some("stamp_ns,wx,wy,wz"));
    let rows: Vec<Vec<&str>> = rows.map(|l| l.split(',').collect()).collect();
    assert_eq!(got.len(), 1800);
    assert_eq!(rows.len(), got.len());
    for (k, (r, row)) in got.iter().zip(&rows).enumerate() {
        let stamp: i64 = row[0].parse().unwrap();
        let w: Vec<f64> = row[1..].iter().map(|v| v.parse().unwrap()).collect();
        assert_eq!(r.number, k as u64 + 1);
        assert_eq!(r.msg.stamp.ns(), stamp, "message {k}");
        assert!(same_bits(&r.msg.angular_velocity, &w), "message {k}");
        // The log time is the script's receive time, not the stamp.
        assert_eq!(
            r.log_time_ns,
            stamp as u64 + 1_000_000 + (k as u64 % 7) * 100_000
        );
        let imu = &r.msg;
        assert_eq!(imu.frame_id, "imu_link");
        assert!(same_bits(&imu.orientation, &[0.48, 0.6, 0.0, 0.64]));
        assert!(same_bits(
            &imu.orientation_covariance,
            &diag(0.01, 0.02, 0.03)
        ));
        assert!(same_bits(
            &imu.angular_velocity_covariance,
            &diag(1e-6, 2e-6, 3e-6)
        ));
        assert!(same_bits(
            &imu.linear_acceleration,
            &[0.125, -0.25, 9.80665]
        ));
        assert!(same_bits(
            &imu.linear_acceleration_covariance,
            &diag(1e-4, 1e-4, 1e-4)
        ));
    }
    // Stamps strictly rising, 10 ms apart.
    assert!(got
        .windows(2)
        .all(|w| w[1].msg.stamp.ns() - w[0].msg.stamp.ns() == 10_000_000));
}

#[test]
fn topics_are_listed_with_their_types() {
    let bag = Bag::open(&fixture("imu.mcap")).unwrap();
    let shown: Vec<_> = bag
        .topics()
        .iter()
        .map(|t| {
            (
                t.topic.clone(),
                t.msg_type.clone(),
                t.schema_encoding.clone(),
                t.message_encoding.clone(),
                t.messages,
                t.is_imu(),
            )
        })
        .collect();
    let s = |x: &str| x.to_string();
    assert_eq!(
        shown,
        [
            (
                s("/chatter"),
                s("std_msgs/msg/String"),
                s("ros2msg"),
                s("cdr"),
                180,
                false
            ),
            (
                s("/imu/data"),
                s(IMU_TYPE),
                s("ros2msg"),
                s("cdr"),
                1800,
                true
            ),
        ]
    );
    assert_eq!(bag.imu_topics().len(), 1);
    assert_eq!(bag.imu_topic(Some("/imu/data")).unwrap(), "/imu/data");
}

#[test]
fn a_bag_directory_reads_its_metadata_yaml_or_its_mcap_files() {
    let dir = tempfile::tempdir().unwrap();
    // rosbags' metadata.yaml lists imu.mcap.
    std::fs::copy(fixture("imu.mcap"), dir.path().join("imu.mcap")).unwrap();
    std::fs::copy(fixture("metadata.yaml"), dir.path().join("metadata.yaml")).unwrap();
    let bag = Bag::open(dir.path()).unwrap();
    assert_eq!(bag.files(), [dir.path().join("imu.mcap")]);
    assert_eq!(read_all(&bag, "/imu/data").len(), 1800);
    // Without a metadata.yaml: every *.mcap in name order; the numbers run on across files.
    std::fs::remove_file(dir.path().join("metadata.yaml")).unwrap();
    std::fs::copy(fixture("imu.mcap"), dir.path().join("imu_1.mcap")).unwrap();
    let bag = Bag::open(dir.path()).unwrap();
    assert_eq!(bag.files().len(), 2);
    assert_eq!(bag.topics()[1].messages, 3600);
    let all = read_all(&bag, "/imu/data");
    assert_eq!(all.len(), 3600);
    assert_eq!(all[3599].number, 3600);
    assert_eq!(all[1800].msg, all[0].msg);
    // A bag in sqlite3 storage is refused, saying what to do.
    std::fs::write(
        dir.path().join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  relative_file_paths:\n    - b_0.db3\n",
    )
    .unwrap();
    let e = Bag::open(dir.path()).err().unwrap();
    assert_eq!(e.kind, BagErrorKind::NotMcap);
    assert!(e.message.contains("b_0.db3") && e.message.contains("ros2 bag convert"));
}

/// An MCAP file written directly (not by our writer): topics of given types, raw messages.
fn raw_bag(path: &Path, topics: &[(&str, &str)], messages: &[(usize, u64, Vec<u8>)]) {
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(BufWriter::new(File::create(path).unwrap()))
        .unwrap();
    let mut channels = Vec::new();
    for (topic, ty) in topics {
        let schema = w.add_schema(ty, "ros2msg", b"").unwrap();
        channels.push(
            w.add_channel(schema, topic, "cdr", &BTreeMap::new())
                .unwrap(),
        );
    }
    for (c, t, data) in messages {
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: channels[*c],
                sequence: 0,
                log_time: *t,
                publish_time: *t,
            },
            data,
        )
        .unwrap();
    }
    w.finish().unwrap();
}

fn one_line(message: &str) {
    assert!(!message.contains('\n'), "not one line: {message}");
}

#[test]
fn topic_choice_errors_list_what_there_is() {
    let dir = tempfile::tempdir().unwrap();
    let imu = fixture("imu.mcap");
    let shown = imu.display().to_string();
    let bag = Bag::open(&imu).unwrap();
    let e = bag.imu_topic(Some("/chatter")).unwrap_err();
    assert_eq!(e.kind, BagErrorKind::NotImu);
    assert_eq!(
        e.message,
        format!(
            "{shown}: topic /chatter (std_msgs/msg/String, 180 messages): not {IMU_TYPE} in cdr"
        )
    );
    assert_eq!(
        bag.imu_messages("/chatter").err().unwrap().kind,
        BagErrorKind::NotImu
    );
    let e = bag.imu_topic(Some("/imu")).unwrap_err();
    assert_eq!(e.kind, BagErrorKind::NoSuchTopic);
    assert_eq!(
        e.message,
        format!(
            "{shown}: no topic /imu; its topics: /chatter (std_msgs/msg/String, 180 messages), \
             /imu/data (sensor_msgs/msg/Imu, 1800 messages)"
        )
    );

    let none = dir.path().join("none.mcap");
    raw_bag(
        &none,
        &[
            ("/chatter", "std_msgs/msg/String"),
            ("/tf", "tf2_msgs/msg/TFMessage"),
        ],
        &[(0, 1, vec![0, 1, 0, 0, 1, 0, 0, 0, 0])],
    );
    let e = Bag::open(&none).unwrap().imu_topic(None).unwrap_err();
    assert_eq!(e.kind, BagErrorKind::NoImuTopic);
    assert_eq!(
        e.message,
        format!(
            "{}: no {IMU_TYPE} topic; its topics: /chatter (std_msgs/msg/String, 1 messages), \
             /tf (tf2_msgs/msg/TFMessage, 0 messages)",
            none.display()
        )
    );

    let two = dir.path().join("two.mcap");
    let m = Imu::default().to_cdr().unwrap();
    raw_bag(
        &two,
        &[("/imu/b", IMU_TYPE), ("/imu/a", IMU_TYPE)],
        &[(0, 1, m.clone()), (1, 2, m)],
    );
    let bag = Bag::open(&two).unwrap();
    let e = bag.imu_topic(None).unwrap_err();
    assert_eq!(e.kind, BagErrorKind::SeveralImuTopics);
    assert_eq!(
        e.message,
        format!(
            "{}: 2 {IMU_TYPE} topics, choose one: /imu/a (sensor_msgs/msg/Imu, 1 messages), \
             /imu/b (sensor_msgs/msg/Imu, 1 messages)",
            two.display()
        )
    );
    assert_eq!(read_all(&bag, "/imu/b").len(), 1);
}

#[test]
fn a_message_that_does_not_decode_names_file_topic_number_and_log_time() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.mcap");
    let good = Imu::default().to_cdr().unwrap();
    raw_bag(
        &p,
        &[("/chatter", "std_msgs/msg/String"), ("/imu/data", IMU_TYPE)],
        &[
            (1, 100, good.clone()),
            (0, 150, vec![0, 1, 0, 0, 1, 0, 0, 0, 0]),
            (1, 200, good[..good.len() - 8].to_vec()),
            (1, 300, good),
        ],
    );
    let bag = Bag::open(&p).unwrap();
    let mut it = bag.imu_messages("/imu/data").unwrap();
    assert_eq!(it.next().unwrap().unwrap().log_time_ns, 100);
    let e = it.next().unwrap().unwrap_err();
    assert_eq!(e.kind, BagErrorKind::Cdr);
    assert_eq!(
        e.message,
        format!(
            "{}: topic /imu/data, message 2 (log time 200 ns): not a CDR {IMU_TYPE}: ends \
             inside linear_acceleration_covariance[8]: 8 bytes needed at byte 308, the message \
             has 308",
            p.display()
        )
    );
    one_line(&e.message);
    let next = it.next().unwrap().unwrap();
    assert_eq!(
        (next.number, next.log_time_ns),
        (3, 300),
        "the message after the bad one comes next"
    );
    assert!(it.next().is_none());
}

/// The first chunk record of an MCAP file: (where its compressed records start, their size).
fn first_chunk(bytes: &[u8]) -> (usize, usize) {
    let u64_at = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
    let mut at = 8; // the magic
    loop {
        let (op, len) = (bytes[at], u64_at(at + 1));
        if op == 0x06 {
            // start, end, uncompressed size, crc, compression (u32 length + text), size.
            let c = at + 9 + 8 + 8 + 8 + 4;
            let name = u32::from_le_bytes(bytes[c..c + 4].try_into().unwrap()) as usize;
            let records = c + 4 + name + 8;
            return (records, u64_at(c + 4 + name));
        }
        at += 9 + len;
    }
}

#[test]
fn a_truncated_file_or_a_corrupt_chunk_is_one_line_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(fixture("imu.mcap")).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = Bag::open(&cut).err().unwrap();
    assert_eq!(e.kind, BagErrorKind::Incomplete);
    assert!(e
        .message
        .starts_with(&format!("{}: an incomplete MCAP file", cut.display())));
    one_line(&e.message);
    let e = Bag::open(&dir.path().join("missing.mcap")).err().unwrap();
    assert_eq!(e.kind, BagErrorKind::Io);
    std::fs::write(dir.path().join("text.mcap"), "stamp_ns,wx\n").unwrap();
    let e = Bag::open(&dir.path().join("text.mcap")).err().unwrap();
    assert_eq!(e.kind, BagErrorKind::NotMcap);

    // The second half of the first chunk's compressed records zeroed, its summary intact: the
    // messages before the damage come (the chunk is decompressed as a stream), then one error.
    let (start, size) = first_chunk(&bytes);
    let mut bad = bytes.clone();
    bad[start + size / 2..start + size].fill(0);
    let p = dir.path().join("chunk.mcap");
    std::fs::write(&p, &bad).unwrap();
    let good = read_all(&Bag::open(&fixture("imu.mcap")).unwrap(), "/imu/data");
    let bag = Bag::open(&p).unwrap();
    let mut results: Vec<_> = bag.imu_messages("/imu/data").unwrap().collect();
    let e = results.pop().unwrap().unwrap_err();
    let before: Vec<ImuRecord> = results.into_iter().map(Result::unwrap).collect();
    assert!(
        before.len() < good.len() / 2,
        "{} messages before",
        before.len()
    );
    assert_eq!(before[..], good[..before.len()]);
    assert_eq!(e.kind, BagErrorKind::Corrupt);
    let last = before.last().unwrap();
    assert!(
        e.message.starts_with(&format!(
            "{}: topic /imu/data, after message {} (log time {} ns): a corrupt or truncated \
             chunk: ",
            p.display(),
            last.number,
            last.log_time_ns
        )),
        "{}",
        e.message
    );
    one_line(&e.message);
}

#[test]
fn written_bags_read_back_bit_for_bit_and_look_like_ros2_bag_record() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("out.mcap");
    let mut u = SplitMix64(99);
    let mut next = || (u.next().unwrap() - 0.5) * 1e3;
    let mut written = Vec::new();
    let mut w = ImuBagWriter::create(&p, "/imu/data").unwrap();
    assert!(!p.exists(), "visible before finish");
    for k in 0..1000i64 {
        let imu = Imu {
            stamp: Time::from_ns(1_700_000_000_000_000_000 + k * 1_000_000).unwrap(),
            frame_id: format!("frame{}", k % 11),
            orientation: std::array::from_fn(|_| next()),
            orientation_covariance: std::array::from_fn(|_| next()),
            angular_velocity: [next(), -0.0, if k == 7 { f64::NAN } else { next() }],
            angular_velocity_covariance: std::array::from_fn(|_| next()),
            linear_acceleration: [f64::INFINITY, next(), f64::MIN_POSITIVE / 4.0],
            linear_acceleration_covariance: std::array::from_fn(|_| next()),
        };
        w.write(&imu).unwrap();
        written.push(imu);
    }
    assert_eq!(w.finish().unwrap(), 1000);
    let bag = Bag::open(&p).unwrap();
    let back = read_all(&bag, &bag.imu_topic(None).unwrap());
    assert_eq!(back.len(), written.len());
    for (r, imu) in back.iter().zip(&written) {
        assert_eq!(r.msg.to_cdr().unwrap(), imu.to_cdr().unwrap());
        assert_eq!(r.log_time_ns, imu.stamp.ns_u64().unwrap());
    }
    // The records ros2 bag play and Foxglove read.
    let bytes = std::fs::read(&p).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let channel = summary.channels.values().next().unwrap();
    assert_eq!(channel.topic, "/imu/data");
    assert_eq!(channel.message_encoding, "cdr");
    assert_eq!(
        channel.metadata,
        BTreeMap::from([
            (
                "offered_qos_profiles".to_string(),
                OFFERED_QOS_PROFILES.to_string()
            ),
            ("topic_type_hash".to_string(), IMU_TYPE_HASH.to_string()),
        ])
    );
    let schema = channel.schema.as_ref().unwrap();
    assert_eq!(
        (schema.name.as_str(), schema.encoding.as_str()),
        (IMU_TYPE, "ros2msg")
    );
    assert_eq!(&*schema.data, IMU_DEFINITION.as_bytes());
    assert_eq!(header_profile(&bytes), "ros2");
    assert!(summary
        .chunk_indexes
        .iter()
        .all(|c| c.compression == "zstd"));

    // A stamp before 1970 is refused; the unfinished file never appears.
    let q = dir.path().join("early.mcap");
    let mut w = ImuBagWriter::create(&q, "/imu").unwrap();
    let e = w
        .write(&Imu {
            stamp: Time {
                sec: -1,
                nanosec: 0,
            },
            ..Imu::default()
        })
        .unwrap_err();
    assert_eq!(e.kind, BagErrorKind::Write);
    drop(w);
    assert!(!q.exists());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    assert!(ImuBagWriter::create(&q, "imu").is_err(), "not a ROS 2 name");
}

/// The profile of an MCAP file's header record.
fn header_profile(bytes: &[u8]) -> String {
    assert_eq!(bytes[8], 0x01, "the header record");
    let n = u32::from_le_bytes(bytes[17..21].try_into().unwrap()) as usize;
    String::from_utf8(bytes[21..21 + n].to_vec()).unwrap()
}

#[test]
fn stamps_going_backwards_are_seen_by_the_caller() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("back.mcap");
    let mut w = ImuBagWriter::create(&p, "/imu").unwrap();
    for ns in [
        3_000_000_000i64,
        4_000_000_000,
        3_500_000_000,
        5_000_000_000,
    ] {
        w.write(&Imu {
            stamp: Time::from_ns(ns).unwrap(),
            ..Imu::default()
        })
        .unwrap();
    }
    w.finish().unwrap();
    let bag = Bag::open(&p).unwrap();
    let stamps: Vec<i64> = read_all(&bag, "/imu")
        .iter()
        .map(|r| r.msg.stamp.ns())
        .collect();
    let back: Vec<usize> = (1..stamps.len())
        .filter(|&i| stamps[i] < stamps[i - 1])
        .map(|i| i + 1)
        .collect();
    assert_eq!(back, [3], "message 3 steps back");
}

/// The messages of written.mcap, the fixture script's `written_message`.
fn written_messages() -> Vec<Imu> {
    let mut u = SplitMix64(7);
    (0..200i64)
        .map(|k| {
            let stamp = 1_700_000_000_000_000_000 + k * 5_000_000;
            let gyro: [f64; 3] = std::array::from_fn(|_| 0.5 * (u.next().unwrap() - 0.5));
            let var: [f64; 3] = std::array::from_fn(|a| (1.0 + a as f64) * 1e-6);
            let not_provided = [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
            Imu {
                stamp: Time::from_ns(stamp).unwrap(),
                frame_id: "imu_link".into(),
                orientation: [0.0, 0.0, 0.0, 1.0],
                orientation_covariance: not_provided,
                angular_velocity: gyro,
                angular_velocity_covariance: diag(var[0], var[1], var[2]),
                linear_acceleration: [0.0; 3],
                linear_acceleration_covariance: not_provided,
            }
        })
        .collect()
}

/// Every record of an MCAP file that says what it holds (header, schemas, channels, messages
/// with their data, in order), without the chunking, compression and index bytes.
fn records(path: &Path) -> Vec<String> {
    let bytes = std::fs::read(path).unwrap();
    mcap::read::ChunkFlattener::new(&bytes)
        .unwrap()
        .map(|r| r.unwrap())
        .filter_map(|r| match r {
            mcap::records::Record::Header(h) => Some(format!("{h:?}")),
            mcap::records::Record::Schema { header, data } => {
                Some(format!("{header:?} {}", String::from_utf8_lossy(&data)))
            }
            mcap::records::Record::Channel(c) => Some(format!("{c:?}")),
            mcap::records::Record::Message { header, data } => Some(format!("{header:?} {data:?}")),
            _ => None,
        })
        .collect()
}

#[test]
fn the_committed_written_bag_is_what_the_writer_writes_and_what_rosbags_read() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("written.mcap");
    let mut w = ImuBagWriter::create(&p, "/imu/data").unwrap();
    for m in written_messages() {
        w.write(&m).unwrap();
    }
    w.finish().unwrap();
    let committed = fixture("written.mcap");
    if std::env::var_os("DRIFTLESS_BLESS").is_some_and(|v| v == "1") {
        std::fs::copy(&p, &committed).unwrap();
    }
    let (now, then) = (records(&p), records(&committed));
    assert_eq!(now.len(), then.len());
    for (a, b) in now.iter().zip(&then) {
        // The library names our version; everything else must match.
        if a.starts_with("Header") {
            assert!(a.contains("profile: \"ros2\"") && b.contains("profile: \"ros2\""));
            continue;
        }
        assert_eq!(a, b, "written.mcap differs from what the writer writes now");
    }

    // What rosbags read from it (scripts/gen_ros2_fixture.py check), against our reading.
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixture("written.json")).unwrap()).unwrap();
    assert_eq!(json["reader"], "rosbags 0.11.9");
    assert_eq!(json["every_message_as_written"], true);
    assert_eq!(json["rihs01"], IMU_TYPE_HASH);
    let t = &json["topics"]["/imu/data"];
    assert_eq!(t["type"], IMU_TYPE);
    assert_eq!(t["message_encoding"], "cdr");
    assert_eq!(t["definition_format"], "MSG");
    assert_eq!(t["definition"], IMU_DEFINITION);
    assert_eq!(t["messages"], 200);
    let q = &t["offered_qos_profiles"][0];
    assert_eq!(q["history"], "keep_last");
    assert_eq!(q["depth"], 10);
    assert_eq!(q["reliability"], "reliable");
    assert_eq!(q["durability"], "volatile");
    let bag = Bag::open(&committed).unwrap();
    let ours = read_all(&bag, "/imu/data");
    assert_eq!(json["count"], ours.len());
    let mut sums = [0.0f64; 3];
    for r in &ours {
        for (s, w) in sums.iter_mut().zip(r.msg.angular_velocity) {
            *s += w;
        }
    }
    let theirs: Vec<f64> = json["angular_velocity_sums"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().parse().unwrap())
        .collect();
    assert!(same_bits(&sums, &theirs));
    let last = &json["last"];
    let imu = &ours[199].msg;
    assert_eq!(last["sec"], imu.stamp.sec);
    assert_eq!(last["nanosec"], imu.stamp.nanosec);
    assert_eq!(last["frame_id"], "imu_link");
    let w: Vec<f64> = last["angular_velocity"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(same_bits(&imu.angular_velocity, &w));
}

/// Per topic of a bag: (count, frame ids, first and last stamps, SHA-256 over every message's
/// stamp, angular velocity, linear acceleration and covariance bytes), as
/// scripts/gen_ros2_fixture.py `recorded` computes it from rosbags' reading.
fn recorded_digest(bag: &Bag, topic: &str) -> (u64, Vec<String>, [i64; 2], [i64; 2], String) {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    let (mut n, mut frames, mut first, mut last) = (0u64, Vec::<String>::new(), None, [0i64; 2]);
    for r in read_all(bag, topic) {
        let m = r.msg;
        if !frames.contains(&m.frame_id) {
            frames.push(m.frame_id.clone());
        }
        let stamp = [i64::from(m.stamp.sec), i64::from(m.stamp.nanosec)];
        first.get_or_insert(stamp);
        last = stamp;
        n += 1;
        h.update(m.stamp.sec.to_le_bytes());
        h.update(m.stamp.nanosec.to_le_bytes());
        for v in m
            .angular_velocity
            .iter()
            .chain(&m.angular_velocity_covariance)
            .chain(&m.linear_acceleration)
            .chain(&m.linear_acceleration_covariance)
        {
            h.update(v.to_le_bytes());
        }
    }
    let hex: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    (n, frames, first.unwrap_or_default(), last, hex)
}

#[test]
fn the_committed_ros2_recording_reads_as_rosbags_read_it() {
    // recorded.mcap: `driftless record --format ros2` of a daemon replaying accel.mcap
    // (tests/record.rs writes it under DRIFTLESS_BLESS=1); recorded.json: rosbags' reading,
    // which checked every message's acceleration against accel.mcap's of the same stamp.
    let bag = Bag::open(&fixture("recorded.mcap")).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixture("recorded.json")).unwrap()).unwrap();
    assert_eq!(json["reader"], "rosbags 0.11.9");
    assert_eq!(json["every_message_checked"], true);
    assert_eq!(json["input"], "accel.mcap");
    let topics = json["topics"].as_object().unwrap();
    let ours: Vec<String> = bag.imu_topics().into_iter().map(|t| t.topic).collect();
    assert_eq!(ours, topics.keys().cloned().collect::<Vec<_>>());
    assert_eq!(ours, ["/rt/corrected", "/rt/raw"]);
    for (topic, t) in topics {
        assert_eq!(t["type"], IMU_TYPE);
        assert_eq!(t["message_encoding"], "cdr");
        assert_eq!(t["definition_format"], "MSG");
        let (n, frames, first, last, sha) = recorded_digest(&bag, topic);
        assert_eq!(t["count"], n, "{topic}");
        assert_eq!(t["messages"], n, "{topic}: the summary's count");
        assert_eq!(t["frame_ids"], serde_json::json!(frames), "{topic}");
        assert_eq!(t["first"], serde_json::json!(first), "{topic}");
        assert_eq!(t["last"], serde_json::json!(last), "{topic}");
        assert_eq!(
            t["sha256"], sha,
            "{topic}: every message as rosbags read it"
        );
        // accel.mcap's messages 300-309 mark their accelerometer not provided.
        assert_eq!(t["accel_not_provided"], 10, "{topic}");
        assert_eq!(t["accel_provided"], n - 10, "{topic}");
    }
}
