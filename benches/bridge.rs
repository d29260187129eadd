//! The Zenoh bridge (feature `zenoh`): its latency on loopback beside the iceoryx2 hop, measured
//! on the same samples, and the daemon's own 1 kHz latency with and without a bridge running,
//! in one run.
//!
//! ```text
//! cargo bench --features zenoh --bench bridge                 # 10^5 samples at 1 kHz per run
//! DRIFTLESS_BENCH_SECONDS=20 cargo bench --features zenoh --bench bridge
//! ```
//!
//! Runs `pipelines/demo.toml` twice for the same time:
//! 1. without a bridge: this process as an iceoryx2 subscriber of `demo/corrected`;
//! 2. with `driftless bridge demo/corrected` (loopback, 127.0.0.1, scouting off) and this
//!    process subscribed both ways: over iceoryx2 and over Zenoh through the bridge. Latency is
//!    CLOCK_MONOTONIC at receipt minus the sample's `ingest_ns`; every sample must arrive over
//!    Zenoh exactly once, in order, the same ones as over iceoryx2.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use driftless::transport::{monotonic_ns, Qos, Transport};
use driftless::wire::{GyroSample, WireBytes, FLAG_FLUSHED};
use hdrhistogram::Histogram;
use serde_json::Value;
use zenoh::Wait;

mod support;

use support::{bench_seconds, clean, loadavg, prefix, read_report, sigterm_and_wait, start_daemon};

fn hist() -> Histogram<u64> {
    Histogram::new_with_bounds(1, 60_000_000_000, 3).expect("bounds")
}

/// Samples received over one path: (epoch, seq) in arrival order and the latency histogram
/// (flushed samples, published at shutdown, not timed).
#[derive(Default)]
struct Path1 {
    seqs: Vec<(u32, u64)>,
    lat: Option<Histogram<u64>>,
}

impl Path1 {
    fn add(&mut self, s: &GyroSample, now: u64) {
        self.seqs.push((s.epoch, s.seq));
        if s.flags & FLAG_FLUSHED == 0 {
            self.lat
                .get_or_insert_with(hist)
                .saturating_record(now.saturating_sub(s.ingest_ns).max(1));
        }
    }
}

struct Run {
    report: Value,
    iox: Path1,
    zenoh: Option<(Path1, String)>,
}

fn run(pipeline: &Path, tag: &str, secs: f64, bridge: bool, dir: &Path) -> Run {
    let prefix = prefix(tag);
    clean(&prefix);
    let report = dir.join(format!("{tag}.json"));
    let mut daemon = start_daemon(pipeline, &prefix, &report, &[]);
    let me = Transport::new(&prefix, "bench-sub", Qos::default()).expect("node");
    let t = Instant::now();
    let input = loop {
        if let Ok(i) = me.open_input::<GyroSample>("demo/corrected") {
            break i;
        }
        assert!(t.elapsed() < Duration::from_secs(10), "daemon not ready");
        std::thread::sleep(Duration::from_millis(20));
    };
    let waker = me.waker("demo/corrected").expect("waker");

    // The Zenoh side: this process listens, the bridge connects.
    let mut far = None;
    if bridge {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let mut cfg = zenoh::Config::default();
        cfg.insert_json5("listen/endpoints", &format!("[\"tcp/127.0.0.1:{port}\"]"))
            .unwrap();
        cfg.insert_json5("scouting/multicast/enabled", "false")
            .unwrap();
        let session = zenoh::open(cfg).wait().expect("zenoh");
        let got = Arc::new(Mutex::new(Path1::default()));
        let sink = Arc::clone(&got);
        let sub = session
            .declare_subscriber("driftless/demo/corrected")
            .callback(move |sample| {
                let now = monotonic_ns();
                let s = GyroSample::decode(&sample.payload().to_bytes())
                    .expect("a GyroSample v2 payload, 128 bytes");
                sink.lock().unwrap().add(&s, now);
            })
            .wait()
            .expect("subscriber");
        let mut child = Command::new(env!("CARGO_BIN_EXE_driftless"))
            .args(["bridge", "demo/corrected", "--prefix", &prefix])
            .args([
                "--connect",
                &format!("tcp/127.0.0.1:{port}"),
                "--no-multicast-scouting",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawn bridge");
        let mut err = BufReader::new(child.stderr.take().unwrap());
        let mut line = String::new();
        while !line.contains("a Zenoh subscriber matches") {
            line.clear();
            assert!(err.read_line(&mut line).unwrap() > 0, "bridge ended");
        }
        // Keep reading its lines (the last one is the summary).
        let lines = std::thread::spawn(move || {
            let mut all = String::new();
            let _ = std::io::Read::read_to_string(&mut err, &mut all);
            all
        });
        far = Some((session, sub, got, child, lines));
    }

    let mut iox = Path1::default();
    let end = Instant::now() + Duration::from_secs_f64(secs);
    while Instant::now() < end {
        let _ = waker.wait(Duration::from_millis(100));
        while let Ok(Some(s)) = input.receive() {
            iox.add(&s, monotonic_ns());
        }
    }
    sigterm_and_wait(&mut daemon);
    // The flushed samples, then nothing more.
    let quiet = Instant::now() + Duration::from_millis(500);
    while Instant::now() < quiet {
        while let Ok(Some(s)) = input.receive() {
            iox.add(&s, monotonic_ns());
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let zenoh = far.map(|(session, sub, got, mut child, lines)| {
        std::thread::sleep(Duration::from_millis(500));
        sigterm_and_wait(&mut child);
        let summary = lines.join().unwrap_or_default();
        drop(sub);
        let _ = session.close().wait();
        let got = std::mem::take(&mut *got.lock().unwrap());
        let last = summary
            .lines()
            .filter(|l| l.starts_with("bridge: done:"))
            .collect::<Vec<_>>()
            .join("; ");
        (got, last)
    });
    drop((input, waker, me));
    clean(&prefix);
    Run {
        report: read_report(&report),
        iox,
        zenoh,
    }
}

fn us(ns: u64) -> String {
    format!("{:.1}", ns as f64 / 1e3)
}

fn row(name: &str, samples: usize, h: &Histogram<u64>, extra: &str) {
    println!(
        "| {name} | {samples} | {} | {} | {} | {} | {extra} |",
        us(h.value_at_quantile(0.5)),
        us(h.value_at_quantile(0.99)),
        us(h.value_at_quantile(0.999)),
        us(h.max())
    );
}

fn daemon_row(name: &str, r: &Value) {
    let e = &r["end_to_end_ns"];
    let u = |v: &Value| v.as_u64().unwrap_or(0);
    println!(
        "| {name} | {} | {} | {} | {} | {} | misses {}, lost {} |",
        u(&r["samples_out"]),
        us(u(&e["p50"])),
        us(u(&e["p99"])),
        us(u(&e["p999"])),
        us(u(&e["max"])),
        u(&r["deadline_misses"]),
        u(&r["lost"])
    );
}

fn main() {
    let secs = bench_seconds(100.0);
    let dir = tempfile::tempdir().expect("tempdir");
    let pipeline: PathBuf = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("pipelines/demo.toml");
    println!("load before: {}", loadavg());
    let without = run(&pipeline, "nobr", secs, false, dir.path());
    let with = run(&pipeline, "br", secs, true, dir.path());
    println!("load after: {}", loadavg());
    let (far, summary) = with.zenoh.as_ref().expect("bridged run");

    // Exactly once: every sample the iceoryx2 subscriber saw from the bridge's first one on,
    // over Zenoh too, in the same order, and nothing else.
    let first = far.seqs.first().copied().expect("samples over Zenoh");
    let from = with
        .iox
        .seqs
        .iter()
        .position(|s| *s == first)
        .expect("same stream");
    let same = with.iox.seqs[from..] == far.seqs[..];
    let in_order = far
        .seqs
        .windows(2)
        .all(|w| w[1].0 == w[0].0 && w[1].1 == w[0].1 + 1);

    println!();
    println!("| run ({secs} s each, demo.toml at 1 kHz) | samples | p50 us | p99 us | p99.9 us | max us | |");
    println!("|---|---:|---:|---:|---:|---:|---|");
    daemon_row("daemon end to end, no bridge", &without.report);
    daemon_row("daemon end to end, bridge running", &with.report);
    let h = |p: &Path1| p.lat.clone().unwrap_or_else(hist);
    row(
        "iceoryx2 subscriber, no bridge (ingest to receipt)",
        without.iox.seqs.len(),
        &h(&without.iox),
        "",
    );
    row(
        "iceoryx2 subscriber, bridge running",
        with.iox.seqs.len(),
        &h(&with.iox),
        "",
    );
    row(
        "Zenoh subscriber through the bridge, loopback",
        far.seqs.len(),
        &h(far),
        &format!("exactly once and in order: {}", same && in_order),
    );
    println!();
    println!("{summary}");
    let p = |r: &Value, q: &str| r["end_to_end_ns"][q].as_f64().unwrap_or(f64::NAN);
    println!(
        "daemon p50 with / without the bridge: x{:.2}; p99.9: x{:.2}; bridge hop p50 over the iceoryx2 hop: x{:.2}",
        p(&with.report, "p50") / p(&without.report, "p50"),
        p(&with.report, "p999") / p(&without.report, "p999"),
        h(far).value_at_quantile(0.5) as f64 / h(&with.iox).value_at_quantile(0.5).max(1) as f64
    );
    assert!(
        same && in_order,
        "samples lost, repeated or reordered over Zenoh"
    );
}
