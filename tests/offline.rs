//! The offline runner (`pipeline::offline`, what `driftless nav-eval` judges) publishes, for the
//! same raw samples and the same pipeline file, exactly what the live daemon publishes: every
//! field of every sample but the ingest clock.

mod common;

use std::time::Duration;

use common::{collect, finish, qos, start, Dir, Prefix};
use driftless::pipeline::config;
use driftless::pipeline::offline::Offline;
use driftless::sim::{Motion, SimConfig, Simulator};
use driftless::transport::Transport;
use driftless::wire::{GyroSample, RawSample};

const N: usize = 25_000;

fn pipeline(predict: &str) -> String {
    format!(
        r#"
name = "off"
rate_hz = 1000.0
axes = 3
input_units = "deg/s"
report_interval_s = 60.0

[iceoryx2]
buffer_size = {N}

[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "off/raw"
file = "log.csv"
pace = "asap"

[[stage]]
name = "denoise"
kind = "denoise.wavelet"
input = "off/raw"
output = "off/denoised"
lag = 33

[[stage]]
name = "predict"
input = "off/denoised"
output = "off/predicted"
{predict}

[[stage]]
name = "publish"
kind = "publish"
input = "off/predicted"
output = "off/corrected"
"#
    )
}

/// A simulated ADIS16405 at 1 kHz, 3 axes (still 20 s, then a turn starting on the last
/// axis): the CSV text (columns x,y,z, and a time column t first when `time_column`) and the
/// raw samples it holds, read back through the CSV's own decimal text.
fn sim_log(seed: u64, n: usize, time_column: bool) -> (String, Vec<RawSample>) {
    let mut cfg = SimConfig::profile("adis16405").unwrap();
    cfg.rate_hz = 1000.0;
    cfg.axes = 3;
    cfg.seed = seed;
    cfg.motion = Motion::Turn;
    let mut sim = Simulator::new(&cfg).unwrap();
    let mut text = String::from(if time_column { "t,x,y,z\n" } else { "x,y,z\n" });
    let mut raws = Vec::with_capacity(n);
    for i in 0..n {
        let m = sim.next_sample().measured;
        let line = format!("{},{},{}", m[0], m[1], m[2]);
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        raws.push(RawSample {
            t_ns: i as u64 * 1_000_000,
            seq: i as u64,
            rate: [v[0], v[1], v[2]],
            ..RawSample::default()
        });
        if time_column {
            text.push_str(&format!("{:.3},", i as f64 * 1e-3));
        }
        text.push_str(&line);
        text.push('\n');
    }
    (text, raws)
}

#[test]
fn offline_output_is_the_live_daemons_sample_for_sample() {
    let dir = Dir::new();
    let (text, raws) = sim_log(11, N, false);
    dir.write("log.csv", &text);
    let model = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/pipelines/models/demo-drift-1khz.json"
    );
    for (name, predict) in [
        ("rbf", format!("kind = \"predict.rbf\"\nmodel = {model:?}")),
        ("none", "kind = \"predict.none\"".to_string()),
        ("bias", "kind = \"predict.bias\"".to_string()),
    ] {
        let file = dir.write(&format!("{name}.toml"), &pipeline(&predict));
        let want = live_equals_offline(&file, name, &raws);
        if name != "none" {
            let anchored = want.iter().filter(|s| s.drift != [0.0; 3]).count();
            assert!(
                anchored > N / 2,
                "{name}: the drift model ran: {anchored} samples"
            );
        }
    }
}

/// Run `file` offline on `raws` and live (the daemon replaying the same log), assert the two
/// publish the same samples, every field but the ingest clock and the epoch; returns them.
fn live_equals_offline(file: &std::path::Path, name: &str, raws: &[RawSample]) -> Vec<GyroSample> {
    let n = raws.len();
    let p = config::load(file).expect("valid pipeline");
    let mut offline = Offline::new(&p).expect("offline");
    let mut want: Vec<GyroSample> = Vec::with_capacity(n);
    for r in raws {
        offline.push(r, &mut |s| want.push(s));
    }
    offline.finish(&mut |s| want.push(s));
    assert_eq!(want.len(), n, "{name}: every sample offline");

    let prefix = Prefix::new(&format!("off{name}"));
    // The pipeline file's buffer_size (N), whatever the log's length.
    let me = Transport::new(&prefix.0, "nav", qos(N)).expect("node");
    let corrected = me.input::<GyroSample>("off/corrected").expect("subscriber");
    let child = start(file, &prefix, &[]);
    let got = collect(&corrected, n, Duration::from_secs(30));
    let (code, err) = finish(child, Duration::from_secs(10));
    assert_eq!(code, Some(0), "{name}: {err}");
    assert_eq!(got.len(), n, "{name}: every sample live");
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        let mut g = *g;
        g.ingest_ns = w.ingest_ns;
        assert_ne!(g.epoch, 0, "{name}: a live epoch");
        g.epoch = w.epoch;
        assert_eq!(g, *w, "{name}: sample {i} differs");
    }
    want
}

#[test]
fn prewarming_the_stages_before_each_paced_sample_changes_no_output() {
    let dir = Dir::new();
    let (text, raws) = sim_log(12, 1500, true);
    dir.write("log.csv", &text);
    // In real time (prewarming needs a paced source), 200 us before each sample is due.
    let text = pipeline("kind = \"predict.bias\"")
        .replace(
            "pace = \"asap\"",
            "pace = \"realtime\"\ntime_column = \"t\"",
        )
        .replace(
            "report_interval_s = 60.0",
            "report_interval_s = 60.0\nprewarm_us = 200.0",
        );
    let file = dir.write("prewarm.toml", &text);
    live_equals_offline(&file, "prewarm", &raws);
}
