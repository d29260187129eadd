//! What recording costs the daemon, and how fast the recorder keeps up, in one run:
//!
//! 1. `pipelines/demo.toml` at 1 kHz (as shipped, SCHED_FIFO 50 where permitted), alternately
//!    without and with `driftless record demo/raw demo/corrected demo/stats` in another process:
//!    the daemon's end-to-end p50 / p99.9 / max, deadline misses and losses, and what the
//!    recorder wrote (samples, sequence gaps);
//! 2. flat out, 10^6 samples through `pipelines/delivery.toml`'s stages, from its simulator
//!    and from a CSV replay (`ingest.csv`, pace "asap", of a log `driftless simulate` wrote),
//!    each without and with a recorder of the corrected service (the heaviest message): the
//!    daemon's throughput, the recorder's rate (samples between its first and last receipt),
//!    its sequence gaps, and whether it holds every sample from its first to the daemon's last.
//!
//! ```text
//! cargo bench --bench record                        # 4 x 30 s at 1 kHz, then flat out
//! DRIFTLESS_BENCH_SECONDS=10 cargo bench --bench record
//! ```

#[path = "support/mod.rs"]
mod support;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use driftless::io::recording::{Recording, METADATA_NAME};
use driftless::transport::Transport;
use serde_json::Value;
use support::{bench_seconds, clean, loadavg, prefix, read_report, start_daemon, wait_exit_within};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Wait until the service `name` exists (the daemon set its chain up).
fn wait_service(p: &str, name: &str) {
    let t = Transport::new(p, "bench-probe", Default::default()).expect("probe");
    let end = Instant::now() + Duration::from_secs(10);
    while !t.payload_type_name(name).is_ok_and(|n| n.is_some()) {
        assert!(Instant::now() < end, "{name} did not appear");
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// `driftless record ARGS` started and subscribed.
fn recorder(
    p: &str,
    out: &Path,
    services: &[&str],
) -> (Child, BufReader<std::process::ChildStderr>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .arg("record")
        .args(services)
        .arg("-o")
        .arg(out)
        .args(["--prefix", p])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn recorder");
    let mut err = BufReader::new(child.stderr.take().expect("stderr"));
    let mut line = String::new();
    err.read_line(&mut line).expect("recorder's first line");
    assert!(line.starts_with("driftless: recording"), "{line}");
    (child, err)
}

/// Stop the recorder (SIGINT) and wait for its file; returns the CPU seconds it used.
fn stop(mut child: Child, mut err: BufReader<std::process::ChildStderr>) -> f64 {
    let cpu = support::cpu_seconds(child.id());
    // SAFETY: kill(2) on our own child.
    unsafe {
        libc::kill(child.id() as i32, libc::SIGINT);
    }
    let mut rest = String::new();
    let _ = std::io::Read::read_to_string(&mut err, &mut rest);
    wait_exit_within(&mut child, Duration::from_secs(30));
    assert!(rest.contains("wrote "), "recorder failed: {rest}");
    cpu
}

/// What a recording holds of one service.
struct Topic {
    samples: u64,
    /// Missing by `seq` (the metadata's count).
    missing: u64,
    /// Samples per second between its first and last receipt.
    rate: f64,
    /// First and last `seq` (the metadata's).
    seqs: Option<(u64, u64)>,
}

/// Per recorded topic, in channel order.
fn recorded(out: &Path) -> Vec<Topic> {
    let rec = Recording::open(out).expect("a complete recording");
    let meta = rec.metadata(METADATA_NAME).expect("metadata").remove(0);
    let bytes = std::fs::read(out).expect("read");
    let mut span: std::collections::BTreeMap<String, (u64, u64)> = Default::default();
    for m in mcap::MessageStream::new(&bytes).expect("mcap") {
        let m = m.expect("message");
        let e = span
            .entry(m.channel.topic.clone())
            .or_insert((m.log_time, m.log_time));
        e.0 = e.0.min(m.log_time);
        e.1 = e.1.max(m.log_time);
    }
    rec.channels()
        .into_iter()
        .map(|c| {
            let service = c.topic.trim_start_matches('/').to_string();
            let missing = meta
                .get(&format!("{service}.missing"))
                .and_then(|v| v.parse().ok())
                .unwrap_or(0);
            let (t0, t1) = span.get(&c.topic).copied().unwrap_or((0, 0));
            let rate = (c.messages.saturating_sub(1)) as f64 / ((t1 - t0) as f64 * 1e-9);
            let seq = |k: &str| {
                meta.get(&format!("{service}.{k}"))
                    .and_then(|v| v.rsplit(' ').next()?.parse::<u64>().ok())
            };
            Topic {
                samples: c.messages,
                missing,
                rate,
                seqs: seq("first").zip(seq("last")),
            }
        })
        .collect()
}

fn us(v: &Value) -> String {
    format!("{:.1}", v.as_f64().unwrap_or(f64::NAN) / 1e3)
}

fn main() {
    let secs = bench_seconds(30.0);
    let dir = tempfile::tempdir().expect("tempdir");
    println!("load average at start: {}", loadavg());

    // 1. 1 kHz, alternately without and with a recorder.
    println!();
    println!("| demo, 1 kHz | samples | p50 us | p99 us | p99.9 us | max us | 1 ms misses | daemon lost | recorded (raw / corrected / stats) | recorder gaps |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let demo = root().join("pipelines/demo.toml");
    for (i, with) in [false, true, false, true].into_iter().enumerate() {
        let p = prefix(&format!("rec1k{i}"));
        clean(&p);
        let report = dir.path().join(format!("1k{i}.json"));
        let mut daemon = start_daemon(&demo, &p, &report, &["--duration", &format!("{secs}s")]);
        wait_service(&p, "demo/stats");
        let out = dir.path().join(format!("1k{i}.mcap"));
        let rec = with.then(|| recorder(&p, &out, &["demo/raw", "demo/corrected", "demo/stats"]));
        wait_exit_within(&mut daemon, Duration::from_secs_f64(secs + 30.0));
        let (counts, gaps) = match rec {
            Some((child, err)) => {
                let cpu = stop(child, err);
                let r = recorded(&out);
                let total: u64 = r.iter().map(|t| t.samples).sum();
                eprintln!(
                    "recorder: {:.2} CPU s for {total} samples ({:.1}% of a core)",
                    cpu,
                    cpu / secs * 100.0
                );
                let counts: Vec<String> = r.iter().map(|t| t.samples.to_string()).collect();
                let gaps: u64 = r.iter().map(|t| t.missing).sum();
                (counts.join(" / "), gaps.to_string())
            }
            None => ("-".into(), "-".into()),
        };
        clean(&p);
        let r = read_report(&report);
        let e = &r["end_to_end_ns"];
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {counts} | {gaps} |",
            if with { "with recorder" } else { "without" },
            r["samples_out"],
            us(&e["p50"]),
            us(&e["p99"]),
            us(&e["p999"]),
            us(&e["max"]),
            r["deadline_misses"],
            r["lost"],
        );
    }

    // 2. Flat out, without and with a recorder of the corrected service: the simulator, and a
    //    replay of a 10^6-row CSV log through the same stages.
    println!();
    println!("| flat out | daemon samples/s | daemon lost | recorded | recorder gaps | every sample from the recorder's first | recorder samples/s | recorder CPU per sample (samples per CPU second) |");
    println!("|---|---:|---:|---:|---:|---|---:|---:|");
    let csv = dir.path().join("replay.csv");
    let status = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .args(["simulate", "--profile", "adis16405", "--rate", "1000"])
        .args(["--duration", "1000s", "--motion", "stop-and-go", "-o"])
        .arg(&csv)
        .stderr(Stdio::null())
        .status()
        .expect("simulate");
    assert!(status.success(), "simulate failed");
    let replay = dir.path().join("replay.toml");
    std::fs::write(&replay, replay_pipeline(&csv)).expect("write pipeline");
    let runs = [
        (
            "delivery.toml (simulator)",
            root().join("pipelines/delivery.toml"),
            "delivery",
        ),
        ("CSV replay (ingest.csv)", replay, "replay"),
    ];
    for (name, pipeline, service) in &runs {
        for (i, with) in [false, true].into_iter().enumerate() {
            let p = prefix(&format!("recfast{service}{i}"));
            clean(&p);
            let report = dir.path().join(format!("fast{service}{i}.json"));
            let mut daemon = start_daemon(pipeline, &p, &report, &[]);
            let out = dir.path().join(format!("fast{service}{i}.mcap"));
            let corrected = format!("{service}/corrected");
            let rec = with.then(|| {
                wait_service(&p, &corrected);
                recorder(&p, &out, &[&corrected])
            });
            wait_exit_within(&mut daemon, Duration::from_secs(120));
            let r = read_report(&report);
            let cols = match rec {
                Some((child, err)) => {
                    let cpu = stop(child, err);
                    let t = &recorded(&out)[0];
                    let whole = t.missing == 0
                        && t.seqs.is_some_and(|(first, last)| {
                            last + 1 == r["samples_out"].as_u64().unwrap_or(0)
                                && last + 1 - first == t.samples
                        });
                    format!(
                        "{} | {} | {whole} | {:.0} | {:.2} us ({:.0}/s)",
                        t.samples,
                        t.missing,
                        t.rate,
                        cpu / t.samples as f64 * 1e6,
                        t.samples as f64 / cpu
                    )
                }
                None => "- | - | - | - | -".into(),
            };
            clean(&p);
            let tp =
                r["samples_out"].as_f64().unwrap_or(0.0) / r["duration_s"].as_f64().unwrap_or(1.0);
            println!(
                "| {name}, {} | {tp:.0} | {} | {cols} |",
                if with { "with recorder" } else { "without" },
                r["lost"]
            );
        }
    }
    println!();
    println!("load average at end: {}", loadavg());
}

/// `pipelines/delivery.toml`'s stages behind a flat-out replay of `csv` (`driftless simulate`'s
/// columns).
fn replay_pipeline(csv: &Path) -> String {
    format!(
        r#"name = "replay"
rate_hz = 1000.0
axes = 3
input_units = "deg/s"
report_interval_s = 2.0

[iceoryx2]
buffer_size = 65536
max_subscribers = 3

[[stage]]
name = "sensor"
kind = "ingest.csv"
file = "{}"
time_column = "t_s"
columns = ["gyro_x_degps", "gyro_y_degps", "gyro_z_degps"]
pace = "asap"
output = "replay/raw"

[[stage]]
name = "denoise"
kind = "denoise.wavelet"
input = "replay/raw"
output = "replay/denoised"
wavelet = "db6"
level = 5
lag = 64
window = 256

[[stage]]
name = "predict"
kind = "predict.bias"
input = "replay/denoised"
output = "replay/predicted"
profile = "adis16405"

[[stage]]
name = "publish"
kind = "publish"
input = "replay/predicted"
output = "replay/corrected"
"#,
        csv.display()
    )
}
