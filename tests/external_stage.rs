//! A stage outside the daemon (`kind = "external"`): the real daemon, the real `driftless relay`
//! process as the external stage, and this test process as sensor driver and final subscriber.
//! Each test has its own iceoryx2 prefix and cleans up after itself.

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Child, ChildStderr, Command, Stdio};
use std::time::{Duration, Instant};

use common::{
    collect, finish, qos, raw, report, signal, start, test_rates, wait_ready, Dir, Prefix,
};
use driftless::stages::external::transform;
use driftless::transport::Transport;
use driftless::wavelet::stream::{Sigma, StreamConfig, StreamingDenoiser};
use driftless::wavelet::threshold::ThresholdFn;
use driftless::wire::{GyroSample, RawSample};

const SIGTERM: i32 = 15;
const SCALE: f64 = 2.0;
const OFFSET: f64 = 0.5;

/// sensor (from `head`) -> denoise -> external "filter" (t/denoised -> t/filtered) -> predict
/// -> publish.
fn pipeline(head: &str, denoise: &str, buffer: usize) -> String {
    format!(
        r#"
name = "t"
rate_hz = 1000.0
axes = 3
input_units = "rad/s"
report_interval_s = 60.0

[iceoryx2]
buffer_size = {buffer}

[[stage]]
name = "sensor"
{head}
output = "t/raw"

[[stage]]
name = "denoise"
{denoise}
input = "t/raw"
output = "t/denoised"

[[stage]]
name = "filter"
kind = "external"
input = "t/denoised"
output = "t/filtered"

[[stage]]
name = "predict"
kind = "predict.none"
input = "t/filtered"
output = "t/predicted"

[[stage]]
name = "publish"
kind = "publish"
input = "t/predicted"
output = "t/corrected"
"#
    )
}

const FROM_TEST: &str = "kind = \"ingest.iceoryx2\"\ninput = \"t/sensor\"";
const FROM_CSV: &str =
    "kind = \"ingest.csv\"\nfile = \"data.csv\"\ntime_column = \"t\"\npace = \"realtime\"\nloop = true";

/// Start `driftless relay` as the external stage and wait until it is subscribed.
fn start_relay(
    prefix: &Prefix,
    buffer: usize,
    count: Option<usize>,
    delay_us: u64,
) -> (Child, BufReader<ChildStderr>) {
    let mut cmd = Command::new(common::bin());
    cmd.args(["relay", "--input", "t/denoised", "--output", "t/filtered"])
        .args([
            "--scale",
            &SCALE.to_string(),
            "--offset",
            &OFFSET.to_string(),
        ])
        .args(["--prefix", &prefix.0, "--buffer-size", &buffer.to_string()])
        .args(["--delay-us", &delay_us.to_string()]);
    if let Some(n) = count {
        cmd.args(["--count", &n.to_string()]);
    }
    let mut child = cmd
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn relay");
    let mut err = BufReader::new(child.stderr.take().expect("stderr"));
    let mut line = String::new();
    err.read_line(&mut line).expect("relay stderr");
    assert_eq!(line.trim(), "relay: ready", "relay did not start");
    (child, err)
}

#[test]
fn every_sample_crosses_the_external_stage_once_in_order_with_the_offline_values() {
    const N: usize = 1200;
    const LAG: usize = 32;
    let prefix = Prefix::new("extorder");
    let dir = Dir::new();
    let denoise = "kind = \"denoise.wavelet\"\nwavelet = \"db4\"\nlevel = 4\nthreshold = \"soft\"\nwindow = 256\nlag = 32";
    let file = dir.write("p.toml", &pipeline(FROM_TEST, denoise, 4096));
    let report_path = dir.path("report.json");

    let (relay, mut relay_err) = start_relay(&prefix, 4096, Some(N), 0);
    let me = Transport::new(&prefix.0, "test", qos(4096)).expect("node");
    let corrected = me.input::<GyroSample>("t/corrected").expect("subscriber");
    let sensor = me
        .output::<RawSample>("t/sensor", true)
        .expect("sensor publisher");
    let mut child = start(&file, &prefix, &["--report", report_path.to_str().unwrap()]);
    wait_ready(&prefix, "t/stats", &mut child);

    let input = test_rates(N);
    for (i, r) in input.iter().enumerate() {
        let sample = raw(i as u64, i as u64 * 1_000_000, *r);
        assert_eq!(sensor.send(&sample).expect("send"), 1);
        sensor.notify();
        if i % 64 == 63 {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    let mut got = collect(&corrected, N - LAG, Duration::from_secs(10));
    assert_eq!(got.len(), N - LAG, "all but the lag arrive while running");
    signal(&child, SIGTERM);
    // The drained samples cross the external process too.
    got.extend(collect(&corrected, LAG, Duration::from_secs(5)));
    let (code, err) = finish(child, Duration::from_secs(10));
    assert_eq!(code, Some(0), "stderr: {err}");
    // Nothing more once the daemon is gone (no sample twice).
    while let Some(s) = corrected.receive().expect("receive") {
        got.push(s);
    }
    assert_eq!(finish(relay, Duration::from_secs(5)).0, Some(0));
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut relay_err, &mut rest).unwrap();
    assert!(
        rest.contains(&format!("relay: {N} samples relayed")),
        "{rest}"
    );

    assert_eq!(got.len(), N, "all samples arrive, none twice");
    let cfg = StreamConfig {
        wavelet: "db4".into(),
        level: 4,
        threshold: ThresholdFn::Soft,
        window: 256,
        lag: LAG,
        sigma: Sigma::Mad,
    };
    let mut denoised = vec![[0.0; 3]; N];
    for axis in 0..3 {
        let mut d = StreamingDenoiser::new(&cfg).unwrap();
        let mut out = Vec::new();
        for r in &input {
            out.extend(d.push(r[axis]));
        }
        while let Some(v) = d.flush() {
            out.push(v);
        }
        assert_eq!(out.len(), N);
        for (e, v) in denoised.iter_mut().zip(out) {
            e[axis] = v;
        }
    }
    for (i, s) in got.iter().enumerate() {
        assert_eq!(s.seq, i as u64, "in order, exactly once");
        assert_eq!(s.t_ns, i as u64 * 1_000_000);
        let offline = transform(
            &GyroSample {
                rate: denoised[i],
                denoised: denoised[i],
                ..GyroSample::default()
            },
            SCALE,
            OFFSET,
        );
        assert_ne!(
            offline.denoised, denoised[i],
            "the external transform is visible"
        );
        assert_eq!(
            s.denoised, offline.denoised,
            "sample {i}: denoiser then the external stage"
        );
        assert_eq!(s.rate, offline.denoised, "predict.none: rate = denoised");
        assert_eq!(s.drift, [0.0; 3]);
        assert!(
            s.ingest_ns > 0,
            "ingest time carried through the external process"
        );
    }
    let r = report(&dir);
    assert_eq!(r["samples_in"], N as u64);
    assert_eq!(r["samples_out"], N as u64);
    assert_eq!(r["lost"], 0);
    let stages = r["stages"].as_array().unwrap();
    let names: Vec<&str> = stages.iter().map(|s| s["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["sensor", "denoise", "filter", "predict", "publish"]);
    assert_eq!(stages[2]["kind"], "external");
    for s in stages {
        assert_eq!(s["samples_in"], N as u64, "{s}");
        assert_eq!(s["samples_out"], N as u64, "{s}");
        assert_eq!(s["lost"], 0, "{s}");
    }
    assert_eq!(
        stages[2]["compute_ns"]["count"], 0,
        "no compute time of ours"
    );
    assert_eq!(stages[1]["compute_ns"]["count"], N as u64);
    // The segment after the external stage times every sample it runs.
    assert_eq!(stages[3]["compute_ns"]["count"], N as u64);
    assert_eq!(stages[4]["compute_ns"]["count"], N as u64);
    // End to end from the ingest, across the external process (flushed outputs excluded).
    assert_eq!(r["end_to_end_ns"]["count"], (N - LAG) as u64);
    assert!(r["end_to_end_ns"]["p50"].as_u64().unwrap() > 0);
    drop(corrected);
    drop(sensor);
    drop(me);
    driftless::transport::remove_prefix_leftovers(&prefix.0);
    assert!(prefix.leftovers().is_empty(), "{:?}", prefix.leftovers());
}

#[test]
fn sigterm_drains_through_the_external_stage_exits_zero_and_leaves_nothing() {
    let prefix = Prefix::new("extterm");
    let dir = Dir::with_csv(500);
    let file = dir.write(
        "p.toml",
        &pipeline(
            FROM_CSV,
            "kind = \"denoise.wavelet\"\nwavelet = \"db2\"\nlevel = 2\nlag = 9",
            256,
        ),
    );
    let report_path = dir.path("report.json");
    // A slow external stage (0.5 ms per sample at 1 kHz): the samples flushed at shutdown
    // reach the last segment milliseconds after the hot thread has finished.
    let (relay, _relay_err) = start_relay(&prefix, 256, None, 500);
    let mut child = start(&file, &prefix, &["--report", report_path.to_str().unwrap()]);
    wait_ready(&prefix, "t/stats", &mut child);
    std::thread::sleep(Duration::from_millis(400));
    let t = Instant::now();
    signal(&child, SIGTERM);
    let (code, err) = finish(child, Duration::from_secs(10));
    assert_eq!(code, Some(0), "stderr: {err}");
    assert!(
        t.elapsed() < Duration::from_secs(3),
        "stops promptly: {:?}",
        t.elapsed()
    );
    assert!(err.contains("end-to-end"), "final table printed: {err}");
    let r = report(&dir);
    let n = r["samples_in"].as_u64().unwrap();
    assert!(n > 100, "ran at ~1 kHz for 400 ms: {n}");
    assert_eq!(
        r["samples_out"], n,
        "drained through the external stage: {r}"
    );
    let ext = &r["stages"][2];
    assert_eq!(ext["samples_in"], n);
    assert_eq!(ext["samples_out"], n);
    assert_eq!(r["lost"], 0);
    signal(&relay, SIGTERM);
    assert_eq!(finish(relay, Duration::from_secs(5)).0, Some(0));
    let left = prefix.leftovers();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn without_its_external_process_the_daemon_still_stops_and_counts_what_never_came_back() {
    let prefix = Prefix::new("extnone");
    let dir = Dir::with_csv(500);
    let file = dir.write(
        "p.toml",
        &pipeline(FROM_CSV, "kind = \"denoise.none\"", 256),
    );
    let report_path = dir.path("report.json");
    let mut child = start(&file, &prefix, &["--report", report_path.to_str().unwrap()]);
    wait_ready(&prefix, "t/stats", &mut child);
    std::thread::sleep(Duration::from_millis(200));
    signal(&child, SIGTERM);
    let (code, err) = finish(child, Duration::from_secs(10));
    assert_eq!(code, Some(0), "stderr: {err}");
    let r = report(&dir);
    let n = r["samples_in"].as_u64().unwrap();
    assert!(n > 50, "{n}");
    assert_eq!(
        r["stages"][2]["samples_in"], n,
        "offered to the external stage"
    );
    assert_eq!(r["stages"][2]["samples_out"], 0, "nothing came back");
    assert_eq!(r["samples_out"], 0);
    let left = prefix.leftovers();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn external_stage_config_errors_name_file_line_column_and_exit_2() {
    let prefix = Prefix::new("extcfg");
    let dir = Dir::new();
    let good = pipeline(FROM_TEST, "kind = \"denoise.none\"", 16);
    let first = good
        .replace(
            "input = \"t/raw\"\noutput = \"t/denoised\"",
            "input = \"t/filtered\"\noutput = \"t/denoised\"",
        )
        .replace(
            "input = \"t/denoised\"\noutput = \"t/filtered\"",
            "input = \"t/raw\"\noutput = \"t/filtered\"",
        )
        .replace(
            "input = \"t/filtered\"\noutput = \"t/predicted\"",
            "input = \"t/denoised\"\noutput = \"t/predicted\"",
        );
    let cases: Vec<(&str, String, &str, u32)> = vec![
        ("first", first, "cannot be the first stage after the ingest", 26),
        (
            "last",
            format!("{good}\n[[stage]]\nname = \"tail\"\nkind = \"external\"\ninput = \"t/corrected\"\noutput = \"t/tail\"\n"),
            "cannot be the last stage",
            45,
        ),
        (
            "dangling",
            good.replace("input = \"t/filtered\"", "input = \"t/filterd\""),
            "dangling input \"t/filterd\"",
            32,
        ),
        (
            "unknown-key",
            good.replace("input = \"t/filtered\"\noutput = \"t/predicted\"", "input = \"t/filtered\"\noutput = \"t/predicted\"\nkind2 = 1"),
            "unknown field `kind2`",
            34,
        ),
        (
            "in-a-row",
            good.replace("kind = \"predict.none\"", "kind = \"external\""),
            "follows external stage",
            32,
        ),
        (
            "timeout",
            good.replace("output = \"t/filtered\"", "output = \"t/filtered\"\npoll_timeout_us = 5"),
            "poll_timeout_us must be in",
            28,
        ),
    ];
    for (name, text, message, line) in cases {
        let file = dir.write(&format!("{name}.toml"), &text);
        for cmd in ["validate", "run"] {
            let mut c = Command::new(common::bin());
            c.arg(cmd).arg(&file);
            if cmd == "run" {
                c.args(["--prefix", prefix.0.as_str()]);
            }
            let out = c.output().expect("run driftless");
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{name} {cmd}: {err}");
            let shown = format!("{}:{line}:", file.display());
            assert!(
                err.contains(&shown),
                "{name}: names file and line {line}: {err}"
            );
            let col = err[err.find(&shown).unwrap() + shown.len()..]
                .split(':')
                .next()
                .unwrap()
                .parse::<u32>();
            assert!(col.is_ok_and(|c| c >= 1), "{name}: column in {err}");
            assert!(err.contains(message), "{name}: {err}");
        }
        assert!(prefix.leftovers().is_empty(), "{name}: nothing started");
    }
    // The valid file lists the external stage.
    let file = dir.write("good.toml", &good);
    let out = Command::new(common::bin())
        .arg("validate")
        .arg(&file)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("filter       external         t/denoised -> t/filtered"),
        "{text}"
    );
    assert!(text.contains("runs in another process"), "{text}");
}
