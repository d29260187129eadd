//! `driftless record` and `ingest.mcap`, with real daemons, recorders and iceoryx2 services in
//! separate processes: every sample recorded exactly once, a recording replayed through the
//! same stages gives the recorded corrected samples bit for bit, the file is complete after
//! SIGINT and SIGTERM and never looks complete after a write error, bad input is one line with
//! the documented exit code; and our reader decodes the committed recording exactly as the
//! independent Python `mcap` package did (tests/fixtures/mcap/).

mod common;

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::{
    bin, collect, finish, qos, raw, signal, start, test_rates, text, wait_ready, Dir, Prefix,
};
use driftless::io::recording::{
    GyroMessage, RawMessage, Recording, StatsMessage, METADATA_NAME, RAW_SCHEMA,
};
use driftless::transport::Transport;
use driftless::wire::{GyroSample, Percentiles, RawSample};
use serde_json::Value;

const BUFFER: usize = 4096;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/mcap")
        .join(name)
}

/// The daemon's chain behind an external raw service (this process is the sensor driver), so
/// that a recorder can subscribe before the first sample.
fn driven_pipeline(ingest: &str) -> String {
    format!(
        r#"name = "rec"
rate_hz = 1000.0
axes = 3
input_units = "deg/s"
report_interval_s = 0.2

[iceoryx2]
buffer_size = {BUFFER}

[[stage]]
name = "sensor"
{ingest}
output = "rec/raw"

[[stage]]
name = "denoise"
kind = "denoise.wavelet"
input = "rec/raw"
output = "rec/denoised"
window = 256

[[stage]]
name = "predict"
kind = "predict.bias"
input = "rec/denoised"
output = "rec/predicted"
profile = "adis16405"
delay_s = 0.2

[[stage]]
name = "publish"
kind = "publish"
input = "rec/predicted"
output = "rec/corrected"
"#
    )
}

/// The demo (the simulator at 1 kHz in real time, without its real-time priority) running
/// under `prefix`, its chain set up.
fn demo_daemon(prefix: &Prefix, dir: &Dir) -> Child {
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/demo.toml"))
            .expect("pipelines/demo.toml")
            .replace("realtime_priority = 50", "")
            .replace("report_interval_s = 2.0", "report_interval_s = 0.2");
    let mut daemon = start(&dir.write("demo.toml", &text), prefix, &[]);
    wait_ready(prefix, "demo/stats", &mut daemon);
    daemon
}

/// Start `driftless record ARGS --prefix P` and wait until it says it is recording (it has
/// subscribed); its stderr's later lines are returned by [`finish_recorder`].
fn start_recorder(prefix: &Prefix, args: &[&str]) -> (Child, BufReader<std::process::ChildStderr>) {
    start_recorder_with(prefix, args, |_| {})
}

fn start_recorder_with(
    prefix: &Prefix,
    args: &[&str],
    tweak: impl FnOnce(&mut Command),
) -> (Child, BufReader<std::process::ChildStderr>) {
    let mut cmd = Command::new(bin());
    cmd.arg("record")
        .args(args)
        .args(["--prefix", &prefix.0])
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    tweak(&mut cmd);
    let mut child = cmd.spawn().expect("spawn recorder");
    let mut err = BufReader::new(child.stderr.take().expect("stderr"));
    let mut line = String::new();
    err.read_line(&mut line).expect("recorder's first line");
    assert!(
        line.starts_with("driftless: recording "),
        "recorder did not start: {line:?} (exit {:?})",
        child.try_wait()
    );
    (child, err)
}

/// Wait for the recorder's exit; (code, the rest of its stderr).
fn finish_recorder(
    mut child: Child,
    mut err: BufReader<std::process::ChildStderr>,
) -> (Option<i32>, String) {
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut err, &mut rest).expect("stderr");
    let end = Instant::now() + Duration::from_secs(20);
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            return (status.code(), rest);
        }
        assert!(Instant::now() < end, "recorder did not exit");
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The messages of `topic`, read with the mcap crate's own stream (not our wrapper).
fn mcap_messages<T: serde::de::DeserializeOwned>(file: &Path, topic: &str) -> Vec<T> {
    let bytes = std::fs::read(file).expect("recording");
    mcap::MessageStream::new(&bytes)
        .expect("an MCAP file")
        .map(|m| m.expect("a readable message"))
        .filter(|m| m.channel.topic == topic)
        .map(|m| serde_json::from_slice(&m.data).expect("our JSON"))
        .collect()
}

/// The recorder's metadata record.
fn metadata(file: &Path) -> BTreeMap<String, String> {
    let rec = Recording::open(file).expect("a complete recording");
    let mut records = rec.metadata(METADATA_NAME).expect("metadata");
    assert_eq!(records.len(), 1, "one metadata record");
    records.remove(0)
}

/// Every sequence number once, in order, within one epoch.
fn assert_exactly_once(seqs: &[(u32, u64)], what: &str) {
    assert!(!seqs.is_empty(), "{what}: nothing recorded");
    for w in seqs.windows(2) {
        assert_eq!(w[1].0, w[0].0, "{what}: one epoch");
        assert_eq!(w[1].1, w[0].1 + 1, "{what}: {:?} then {:?}", w[0], w[1]);
    }
}

#[test]
fn a_recording_of_the_raw_service_replays_to_the_recorded_corrected_samples_bit_for_bit() {
    const N: usize = 3000;
    let dir = Dir::new();
    let out = dir.path("run.mcap");

    // The recorded run: daemon, recorder subscribed, then the driver (this process) starts.
    let live = Prefix::new("recdrv");
    let file = dir.write(
        "live.toml",
        &driven_pipeline("kind = \"ingest.iceoryx2\"\ninput = \"rec/sensor\""),
    );
    let mut daemon = start(&file, &live, &[]);
    wait_ready(&live, "rec/stats", &mut daemon);
    let (recorder, err) = start_recorder(
        &live,
        &[
            "rec/raw",
            "rec/corrected",
            "rec/stats",
            "-o",
            out.to_str().unwrap(),
            "--raw-units",
            "deg/s",
            "--raw-accel-units",
            "m/s^2",
        ],
    );
    let me = Transport::new(&live.0, "driver", qos(BUFFER)).expect("node");
    let sensor = me.output::<RawSample>("rec/sensor", true).expect("driver");
    for (i, rate) in test_rates(N).into_iter().enumerate() {
        sensor
            .send(&raw(i as u64, i as u64 * 1_000_000, rate))
            .expect("send");
        sensor.notify();
        if i % 100 == 99 {
            std::thread::sleep(Duration::from_millis(10));
        }
    }
    std::thread::sleep(Duration::from_millis(500));
    signal(&daemon, libc::SIGINT);
    let (code, daemon_err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{daemon_err}");
    std::thread::sleep(Duration::from_millis(200));
    signal(&recorder, libc::SIGINT);
    let (code, rec_err) = finish_recorder(recorder, err);
    assert_eq!(code, Some(0), "{rec_err}");
    assert!(
        rec_err.contains(&format!(
            "rec/raw: {N} samples, 0 missing (sequence gaps), 1 epoch(s)"
        )),
        "{rec_err}"
    );
    drop(sensor);
    drop(me);

    // Exactly once, read with the mcap crate: every seq of both services, in order.
    let raw_msgs: Vec<RawMessage> = mcap_messages(&out, "/rec/raw");
    let corrected: Vec<GyroMessage> = mcap_messages(&out, "/rec/corrected");
    let stats: Vec<StatsMessage> = mcap_messages(&out, "/rec/stats");
    assert_eq!(raw_msgs.len(), N);
    assert_eq!(corrected.len(), N, "the drained lag included");
    assert!(!stats.is_empty(), "stats snapshots recorded");
    assert_exactly_once(
        &raw_msgs
            .iter()
            .map(|m| (m.epoch, m.seq))
            .collect::<Vec<_>>(),
        "raw",
    );
    assert_exactly_once(
        &corrected
            .iter()
            .map(|m| (m.epoch, m.seq))
            .collect::<Vec<_>>(),
        "corrected",
    );
    assert_eq!((raw_msgs[0].seq, corrected[0].seq), (0, 0));
    for (m, rate) in raw_msgs.iter().zip(test_rates(N)) {
        let sent: [f64; 3] = m.rate.into();
        assert_eq!(
            sent.map(f64::to_bits),
            rate.map(f64::to_bits),
            "raw values kept"
        );
    }
    // The raw channel names the units it was recorded in; a pipeline of other units is refused.
    let raw_channel = Recording::open(&out)
        .expect("a complete recording")
        .channels()
        .into_iter()
        .find(|c| c.topic == "/rec/raw")
        .expect("the raw channel");
    assert_eq!(raw_channel.metadata["rate_units"], "deg/s");
    assert_eq!(raw_channel.metadata["accel_units"], "m/s^2");
    for (units, says) in [
        (
            "input_units = \"rad/s\"",
            "was recorded in deg/s, but the pipeline's input_units is rad/s",
        ),
        (
            "accel_units = \"g\"",
            "was recorded in m/s^2, but the pipeline's accel_units is g",
        ),
    ] {
        let p = mcap_pipeline(&dir, &out, Some("rec/raw"));
        let toml = std::fs::read_to_string(&p).unwrap();
        std::fs::write(
            &p,
            toml.replace("rate_hz = 1000.0", &format!("rate_hz = 1000.0\n{units}")),
        )
        .unwrap();
        let o = common::driftless(&["validate", p.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{units}");
        assert!(text(&o).1.contains(says), "{}", text(&o).1);
    }
    let meta = metadata(&out);
    assert_eq!(meta["rec/raw.samples"], N.to_string());
    assert_eq!(meta["rec/raw.missing"], "0");
    assert_eq!(meta["rec/corrected.samples"], N.to_string());
    assert_eq!(meta["rec/corrected.missing"], "0");
    assert_eq!(meta["stopped_by"], "SIGINT");

    // The replay: the same stages behind ingest.mcap, this process subscribed before it starts.
    let again = Prefix::new("recrep");
    let file = dir.write(
        "replay.toml",
        &driven_pipeline(&format!(
            "kind = \"ingest.mcap\"\nfile = {:?}\ntopic = \"rec/raw\"\npace = \"asap\"",
            out.to_str().unwrap()
        )),
    );
    let me = Transport::new(&again.0, "reader", qos(BUFFER)).expect("node");
    let sub = me.input::<GyroSample>("rec/corrected").expect("subscriber");
    let daemon = start(&file, &again, &[]);
    let replayed = collect(&sub, N, Duration::from_secs(60));
    let (code, daemon_err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{daemon_err}");
    assert_eq!(replayed.len(), N);
    // Identical but for what a run stamps: the epoch (random per daemon start) and ingest_ns
    // (the replay's own clock).
    let epoch = replayed[0].epoch;
    let mut warm = 0;
    for (r, c) in replayed.iter().zip(&corrected) {
        let c = GyroSample::from(c);
        assert_eq!(
            (r.seq, r.t_ns, r.flags, r.epoch),
            (c.seq, c.t_ns, c.flags, epoch)
        );
        for (a, b) in [
            (r.rate, c.rate),
            (r.drift, c.drift),
            (r.denoised, c.denoised),
        ] {
            assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "seq {}", r.seq);
        }
        warm += usize::from(c.drift != [0.0; 3]);
    }
    assert!(warm > N / 2, "the drift estimate ran ({warm} samples)");
}

#[test]
fn sigint_and_sigterm_leave_a_complete_recording_with_its_summary() {
    let prefix = Prefix::new("recsig");
    let dir = Dir::new();
    let daemon = demo_daemon(&prefix, &dir);
    for (sig, name) in [(libc::SIGINT, "SIGINT"), (libc::SIGTERM, "SIGTERM")] {
        let out = dir.path(&format!("{name}.mcap"));
        let (recorder, err) = start_recorder(
            &prefix,
            &["demo/raw", "demo/corrected", "-o", out.to_str().unwrap()],
        );
        let part = dir.path(&format!("{name}.mcap.part"));
        std::thread::sleep(Duration::from_millis(1500));
        assert!(part.exists() && !out.exists(), "OUT.part until it stops");
        signal(&recorder, sig);
        let (code, rest) = finish_recorder(recorder, err);
        assert_eq!(code, Some(0), "{name}: {rest}");
        assert!(
            out.exists() && !part.exists(),
            "{name}: renamed when complete"
        );
        assert!(rest.contains(&format!("stopped by {name}")), "{rest}");
        let meta = metadata(&out);
        assert_eq!(meta["stopped_by"], name);
        for service in ["demo/raw", "demo/corrected"] {
            let msgs: Vec<RawOrGyro> = mcap_messages(&out, &format!("/{service}"));
            let seqs: Vec<(u32, u64)> = msgs.iter().map(|m| (m.epoch, m.seq)).collect();
            assert!(seqs.len() > 1000, "{service}: {} samples", seqs.len());
            assert_exactly_once(&seqs, service);
            assert_eq!(meta[&format!("{service}.samples")], seqs.len().to_string());
            assert_eq!(meta[&format!("{service}.missing")], "0");
            assert_eq!(
                meta[&format!("{service}.last")],
                format!(
                    "epoch {} seq {}",
                    seqs[seqs.len() - 1].0,
                    seqs[seqs.len() - 1].1
                )
            );
        }
    }
    signal(&daemon, libc::SIGINT);
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
}

/// What raw and processed messages share.
#[derive(serde::Deserialize)]
struct RawOrGyro {
    seq: u64,
    epoch: u32,
}

#[test]
fn a_write_error_stops_with_exit_1_and_leaves_nothing_that_looks_complete() {
    let prefix = Prefix::new("recfull");
    let dir = Dir::new();
    let daemon = demo_daemon(&prefix, &dir);
    let out = dir.path("full.mcap");
    // A file-size limit plays the full disk: writes past 16 KiB fail (EFBIG) as they would
    // with ENOSPC.
    let (recorder, err) = start_recorder_with(
        &prefix,
        &["demo/raw", "demo/corrected", "-o", out.to_str().unwrap()],
        |cmd| {
            use std::os::unix::process::CommandExt as _;
            // SAFETY: only async-signal-safe calls between fork and exec.
            unsafe {
                cmd.pre_exec(|| {
                    let lim = libc::rlimit {
                        rlim_cur: 16 * 1024,
                        rlim_max: 16 * 1024,
                    };
                    libc::setrlimit(libc::RLIMIT_FSIZE, &lim);
                    libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
                    Ok(())
                });
            }
        },
    );
    let (code, rest) = finish_recorder(recorder, err);
    signal(&daemon, libc::SIGINT);
    let _ = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(1), "{rest}");
    assert_eq!(rest.lines().count(), 1, "one line: {rest}");
    assert!(rest.starts_with("driftless: error: "), "{rest}");
    assert!(rest.contains("File too large"), "{rest}");
    assert!(rest.contains("has no summary"), "{rest}");
    assert!(!out.exists(), "no file under the final name");
    let part = dir.path("full.mcap.part");
    assert!(part.exists(), "what was written is kept as OUT.part");
    let e = Recording::open(&part)
        .err()
        .expect("not a complete recording");
    assert!(e.contains("incomplete MCAP file"), "{e}");
}

#[test]
fn bad_input_is_one_line_with_the_documented_exit_code_and_no_file() {
    let prefix = Prefix::new("recbad");
    let dir = Dir::new();
    let out = dir.path("x.mcap");
    let out_s = out.to_str().unwrap().to_string();
    let node = Transport::new(&prefix.0, "foreign", qos(16)).expect("node");
    let _foreign = node
        .output::<Percentiles>("rec/foreign", false)
        .expect("a service of another type");
    let dir_s = dir.dir.path().to_str().unwrap().to_string();
    let part = dir.path("busy.mcap.part");
    std::fs::write(&part, b"someone's").unwrap();
    let busy = dir.path("busy.mcap").to_str().unwrap().to_string();
    let cases: [(&[&str], i32, &str); 6] = [
        // Nothing to read is a run-time failure, as for `tap` (docs/commands.md, "Exit codes").
        (
            &["rec/nothing", "-o", &out_s],
            1,
            "no service \"rec/nothing\"",
        ),
        (
            &["rec/foreign", "-o", &out_s],
            2,
            "carries driftless::Percentiles, not a driftless type",
        ),
        (
            &["rec/foreign", "-o", "/nonexistent/x.mcap"],
            2,
            "cannot write /nonexistent/x.mcap.part",
        ),
        (&["rec/foreign", "-o", &dir_s], 2, "is a directory"),
        (&["rec/foreign", "-o", &busy], 2, "busy.mcap.part exists"),
        (&["", "-o", &out_s], 2, "invalid service name"),
    ];
    for (args, want, says) in cases {
        let mut all = vec!["record"];
        all.extend_from_slice(args);
        all.extend_from_slice(&["--prefix", &prefix.0]);
        let o = common::driftless(&all);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(want), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(
            !out.exists() && !dir.path("x.mcap.part").exists(),
            "{args:?}"
        );
    }
    assert_eq!(std::fs::read(&part).unwrap(), b"someone's", "left alone");
}

/// A pipeline replaying `file` (and `topic`, if given), for `validate`.
fn mcap_pipeline(dir: &Dir, file: &Path, topic: Option<&str>) -> PathBuf {
    let topic = topic.map_or(String::new(), |t| format!("topic = {t:?}\n"));
    dir.write(
        "m.toml",
        &format!(
            r#"name = "m"
rate_hz = 1000.0

[[stage]]
name = "sensor"
kind = "ingest.mcap"
output = "m/raw"
file = {:?}
{topic}
[[stage]]
name = "publish"
kind = "publish"
input = "m/raw"
output = "m/corrected"
"#,
            file.to_str().unwrap()
        ),
    )
}

#[test]
fn ingest_mcap_refuses_truncated_foreign_and_wrong_topic_files_with_one_line() {
    let dir = Dir::new();
    let small = fixture("small.mcap");
    let ok = mcap_pipeline(&dir, &small, None);
    let o = common::driftless(&["validate", ok.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o).1);
    let python: Value =
        serde_json::from_str(&std::fs::read_to_string(fixture("small.json")).unwrap()).unwrap();
    let count = &python["topics"]["/demo/raw"]["count"];
    assert!(
        text(&o)
            .0
            .contains(&format!("replays {count} messages of /demo/raw")),
        "{}",
        text(&o).0
    );

    let bytes = std::fs::read(&small).unwrap();
    let truncated = dir.path("cut.mcap");
    std::fs::write(&truncated, &bytes[..bytes.len() - 100]).unwrap();
    let foreign = dir.write("log.mcap", "t,x,y,z\n0,1,2,3\n");
    let cases: [(&Path, Option<&str>, &str); 5] = [
        (&truncated, None, "an incomplete MCAP file"),
        (&foreign, None, "not an MCAP file"),
        (
            &small,
            Some("demo/corrected"),
            "holds \"driftless.GyroSample\", not driftless.RawSample",
        ),
        (&small, Some("demo/elsewhere"), "no topic /demo/elsewhere"),
        (Path::new("/nonexistent.mcap"), None, "no such file"),
    ];
    for (file, topic, says) in cases {
        let p = mcap_pipeline(&dir, file, topic);
        let o = common::driftless(&["validate", p.to_str().unwrap()]);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{file:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        let at = format!("{}:", p.display());
        assert!(err.starts_with(&format!("driftless: error: {at}")), "{err}");
        assert!(err.contains(says), "{err}");
    }
    // The pipeline's units must be the recording's.
    let p = mcap_pipeline(&dir, &small, None);
    let text_rad = std::fs::read_to_string(&p).unwrap().replace(
        "rate_hz = 1000.0",
        "rate_hz = 1000.0\ninput_units = \"rad/s\"",
    );
    std::fs::write(&p, text_rad).unwrap();
    let o = common::driftless(&["validate", p.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o).1.contains("was recorded in deg/s"),
        "{}",
        text(&o).1
    );
}

/// Sum every number of `v` into `sums` by path, as read_mcap.py does (file order; floats as
/// IEEE doubles, integers exactly).
fn add_sums(sums: &mut BTreeMap<String, (u128, f64, bool)>, prefix: &str, v: &Value) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                let path = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                add_sums(sums, &path, x);
            }
        }
        Value::Number(n) => {
            let e = sums.entry(prefix.to_string()).or_insert((0, 0.0, false));
            match n.as_u64() {
                Some(i) if !n.is_f64() => e.0 += u128::from(i),
                _ => {
                    e.1 += n.as_f64().expect("a number");
                    e.2 = true;
                }
            }
        }
        _ => {}
    }
}

#[test]
fn our_reader_decodes_the_committed_recording_as_the_python_mcap_package_did() {
    let rec = Recording::open(&fixture("small.mcap")).expect("the fixture");
    let python: Value =
        serde_json::from_str(&std::fs::read_to_string(fixture("small.json")).unwrap()).unwrap();
    assert_eq!(python["reader"], "mcap 1.6.0 (Python)");
    let topics = python["topics"].as_object().expect("topics");
    let channels = rec.channels();
    assert_eq!(channels.len(), topics.len());
    assert!(channels.iter().any(|c| c.schema == RAW_SCHEMA));
    for c in &channels {
        let want = &topics[&c.topic];
        assert_eq!(want["schema"], c.schema.as_str());
        assert_eq!(want["schema_encoding"], "jsonschema");
        assert_eq!(want["message_encoding"], c.encoding.as_str());
        assert_eq!(
            want["channel_metadata"],
            serde_json::to_value(&c.metadata).unwrap()
        );
        let decoded: Vec<Value> = match c.schema.as_str() {
            "driftless.RawSample" => values::<RawMessage>(&rec, &c.topic),
            "driftless.GyroSample" => values::<GyroMessage>(&rec, &c.topic),
            // Recording format 1: statistics in s, ms and us, which no part of driftless
            // reads back (format 2 writes `StatsMessage`, the form of `stats --json`).
            "driftless.StatsSnapshot" => values::<Value>(&rec, &c.topic),
            other => panic!("unexpected schema {other}"),
        };
        assert_eq!(want["count"], decoded.len() as u64, "{}", c.topic);
        assert_eq!(c.messages, decoded.len() as u64);
        assert_eq!(want["first"], decoded[0], "{}", c.topic);
        assert_eq!(want["last"], decoded[decoded.len() - 1], "{}", c.topic);
        let mut sums = BTreeMap::new();
        for v in &decoded {
            add_sums(&mut sums, "", v);
        }
        let want_sums = want["sums"].as_object().expect("sums");
        assert_eq!(want_sums.len(), sums.len(), "{}", c.topic);
        for (path, (int, float, is_float)) in sums {
            let w = &want_sums[&path];
            if is_float {
                assert_eq!(
                    w.as_f64().map(f64::to_bits),
                    Some(float.to_bits()),
                    "{path}"
                );
            } else {
                assert_eq!(w.as_u64().map(u128::from), Some(int), "{path}");
            }
        }
    }
    let meta = rec.metadata(METADATA_NAME).unwrap();
    let want_meta = python["metadata"].as_array().unwrap();
    assert_eq!(want_meta.len(), meta.len());
    assert_eq!(want_meta[0]["name"], METADATA_NAME);
    assert_eq!(
        want_meta[0]["metadata"],
        serde_json::to_value(&meta[0]).unwrap()
    );
}

/// Every message of `topic` decoded as `T` by our reader, as JSON values.
fn values<T: serde::de::DeserializeOwned + serde::Serialize>(
    rec: &Recording,
    topic: &str,
) -> Vec<Value> {
    rec.messages::<T>(topic)
        .map(|m| serde_json::to_value(m.expect("decodes")).unwrap())
        .collect()
}

/// The pipeline of the ROS 2 round trip: the rosbags-written fixture bag replayed through the
/// product's chain, held 3 s so that the recorder subscribes before the first sample.
fn ros2_pipeline(bag: &Path) -> String {
    format!(
        r#"name = "rt"
rate_hz = 100.0
axes = 3
input_units = "rad/s"

[iceoryx2]
buffer_size = {BUFFER}

[[stage]]
name = "sensor"
kind = "ingest.mcap"
output = "rt/raw"
file = {bag:?}
topic = "/imu/data"
pace = "asap"
start_delay_s = 3.0

[[stage]]
name = "denoise"
kind = "denoise.wavelet"
input = "rt/raw"
output = "rt/denoised"
window = 256

[[stage]]
name = "predict"
kind = "predict.bias"
input = "rt/denoised"
output = "rt/predicted"
profile = "adis16405"

[[stage]]
name = "publish"
kind = "publish"
input = "rt/predicted"
output = "rt/corrected"
"#,
        bag = bag.to_str().unwrap()
    )
}

#[test]
fn a_rosbags_bag_round_trips_through_the_daemon_into_a_ros2_recording() {
    use driftless::pipeline::{config, offline::Offline};
    use driftless::transport::ros2::bag::Bag;
    use driftless::transport::ros2::Imu;
    // Its accelerometer varies per message; messages 300-309 mark it not provided.
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/ros2/accel.mcap");
    let dir = Dir::new();
    let pipeline = dir.write("rt.toml", &ros2_pipeline(&input));

    // What the stages give offline on the bag's samples, as our reader reads them.
    let bag = Bag::open(&input).expect("the fixture bag");
    let sent: Vec<Imu> = bag
        .imu_messages("/imu/data")
        .expect("its Imu topic")
        .map(|m| m.expect("a message").msg)
        .collect();
    let raws: Vec<RawSample> = sent
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let mut r = raw(i as u64, m.stamp.ns() as u64, m.angular_velocity);
            if m.accel_reading().is_some() {
                r.accel = m.linear_acceleration;
                r.flags |= driftless::wire::RAW_ACCEL;
            }
            r
        })
        .collect();
    assert_eq!(
        sent.iter().filter(|m| m.accel_reading().is_none()).count(),
        10,
        "the fixture's stretch without an accelerometer"
    );
    let mut offline = Offline::new(&config::load(&pipeline).expect("valid")).expect("offline");
    let mut want = Vec::with_capacity(raws.len());
    for r in &raws {
        offline.push(r, &mut |s| want.push(s));
    }
    offline.finish(&mut |s| want.push(s));
    assert_eq!(want.len(), sent.len());

    let prefix = Prefix::new("rosrt");
    let mut daemon = start(&pipeline, &prefix, &[]);
    wait_ready(&prefix, "rt/stats", &mut daemon);
    let out = dir.path("rt.mcap");
    let (recorder, err) = start_recorder(
        &prefix,
        &[
            "rt/raw",
            "rt/corrected",
            "--format",
            "ros2",
            "--raw-units",
            "rad/s",
            "--rate-noise",
            "0.3",
            "--accel-noise",
            "0.02",
            "--raw-accel-units",
            "m/s^2",
            "--frame-id",
            "gyro",
            "-o",
            out.to_str().unwrap(),
        ],
    );
    let (code, daemon_err) = finish(daemon, Duration::from_secs(60));
    assert_eq!(code, Some(0), "{daemon_err}");
    // The recorder drains every 20 ms at most.
    std::thread::sleep(Duration::from_millis(300));
    signal(&recorder, libc::SIGINT);
    let (code, rest) = finish_recorder(recorder, err);
    assert_eq!(code, Some(0), "{rest}");
    assert!(
        rest.contains("rt/corrected: 600 samples, 0 missing"),
        "{rest}"
    );
    assert!(
        !rest.contains("accelerometer reading(s)"),
        "every covariance known: {rest}"
    );

    let got = Bag::open(&out).expect("a complete bag");
    let topics: Vec<(String, u64)> = got
        .imu_topics()
        .into_iter()
        .map(|t| (t.topic, t.messages))
        .collect();
    assert_eq!(
        topics,
        [
            ("/rt/corrected".to_string(), 600),
            ("/rt/raw".to_string(), 600)
        ]
    );
    let noise = 0.3f64.to_radians().powi(2);
    let read = |topic: &str| -> Vec<Imu> {
        got.imu_messages(topic)
            .expect("topic")
            .map(|m| m.expect("a message").msg)
            .collect()
    };
    for (m, s) in read("/rt/raw").iter().zip(&sent) {
        assert_eq!(m.stamp, s.stamp, "the stamp through the daemon");
        assert_eq!(
            m.angular_velocity.map(f64::to_bits),
            s.angular_velocity.map(f64::to_bits)
        );
        assert_eq!(m.frame_id, "gyro");
        assert_eq!(m.orientation_covariance[0], -1.0, "not provided");
        // A raw sample carries no accel_std: --accel-noise's.
        same_accel(m, s, 0.02, "raw");
        for (i, c) in m.angular_velocity_covariance.iter().enumerate() {
            assert_eq!(
                *c,
                if i % 4 == 0 { noise } else { 0.0 },
                "raw covariance {i}"
            );
        }
    }
    let corrected = read("/rt/corrected");
    assert_eq!(corrected.len(), want.len(), "every sample once");
    // Time-aligned: each output carries the accelerometer of the input of its own stamp.
    let by_stamp: std::collections::HashMap<i64, &Imu> =
        sent.iter().map(|m| (m.stamp.ns(), m)).collect();
    for (i, (m, w)) in corrected.iter().zip(&want).enumerate() {
        assert_eq!(m.stamp.ns() as u64, w.t_ns, "sample {i}: stamp");
        // predict.bias gives each reading its white noise (accel_std, from the profile's VRW).
        let std = w.accel_std[0];
        if w.accel_reading().is_some() {
            assert!(
                std > 0.0 && w.accel_std == [std; 3],
                "sample {i}: {:?}",
                w.accel_std
            );
        }
        same_accel(m, by_stamp[&m.stamp.ns()], std, &format!("corrected {i}"));
        assert_eq!(
            m.linear_acceleration.map(f64::to_bits),
            w.accel_reading().unwrap_or([0.0; 3]).map(f64::to_bits),
            "sample {i}: the acceleration offline"
        );
        assert_eq!(
            m.angular_velocity.map(f64::to_bits),
            w.rate.map(f64::to_bits),
            "sample {i}: the corrected rate, bit for bit as offline"
        );
        for a in 0..3 {
            let v = m.angular_velocity_covariance[4 * a];
            assert!(
                w.drift_std[a] > 0.0,
                "sample {i}: predict.bias gives its std"
            );
            assert_eq!(
                v,
                noise + w.drift_std[a].powi(2),
                "sample {i}: the rate noise and the drift's uncertainty"
            );
        }
    }
    // The committed fixture that rosbags reads (tests/ros2_bag.rs, recorded.json: it checks
    // every message's acceleration against accel.mcap's with rosbags' own reader).
    if std::env::var_os("DRIFTLESS_BLESS").is_some_and(|v| v == "1") {
        let fixture =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/ros2/recorded.mcap");
        std::fs::copy(&out, fixture).expect("bless recorded.mcap");
    }
}

/// `got`'s linear acceleration is `sent`'s bit for bit with the covariance a white noise of
/// `std` m/s^2 gives, or "not provided" where `sent` did not provide it.
fn same_accel(
    got: &driftless::transport::ros2::Imu,
    sent: &driftless::transport::ros2::Imu,
    std: f64,
    what: &str,
) {
    let c = got.linear_acceleration_covariance;
    if sent.accel_reading().is_some() {
        assert_eq!(
            got.linear_acceleration.map(f64::to_bits),
            sent.linear_acceleration.map(f64::to_bits),
            "{what}: linear_acceleration bit for bit"
        );
        let var = std * std;
        assert_eq!(c, [var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, var], "{what}");
    } else {
        assert_eq!(c[0], -1.0, "{what}: not provided");
    }
}
