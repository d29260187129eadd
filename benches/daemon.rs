//! The daemon's latency and throughput targets, measured in one run beside the bare iceoryx2
//! chain of the same hops (no computation), so the overhead shows as a ratio.
//!
//! ```text
//! cargo bench --bench daemon                       # 10^5 samples at 1 kHz (100 s) + the rest
//! DRIFTLESS_BENCH_SECONDS=20 cargo bench --bench daemon   # shorter
//! DRIFTLESS_BENCH_ONLY=scale cargo bench --bench daemon    # runs 5 and 6 alone
//! DRIFTLESS_BENCH_ONLY=drivers cargo bench --bench daemon  # run 6 alone
//! DRIFTLESS_BENCH_ONLY=single cargo bench --bench daemon   # runs 1-4 and 7 (one pipeline)
//! DRIFTLESS_BENCH_ONLY=fed cargo bench --bench daemon      # run 7 alone
//! ```
//!
//! Runs, in order (each alone on the machine):
//! 1. bare chain, 1 kHz, one thread, 4 ipc hops, no computation (it sends and receives on each
//!    hop; the daemon only sends, to hops someone reads, the next stage taking the value
//!    directly); a bare thread sleeping to each 1 ms; a bare 1 kHz publisher in another process
//!    (this binary again) with this process as its subscriber;
//! 2. `pipelines/demo.toml` at 1 kHz (simulator, db6/5 levels, predictor, publish, 3 axes) with
//!    this process as a separate-process subscriber (its latency: ingest to receipt), and the
//!    daemon's CPU use from /proc;
//! 3. `pipelines/adxrs450.toml` at 50 Hz against its 20 ms deadline;
//! 4. CSV replay as fast as possible through all stages, nobody reading its services (a hop
//!    nobody reads costs no send), then again with this process reading its corrected service,
//!    and the bare chain as fast as possible;
//! 5. scale: N 1 kHz 3-axis pipelines of the demo at once (`DRIFTLESS_BENCH_PIPELINES`, default
//!    "8,32"), for the same time as run 2, laid out three ways: N separate daemons, one daemon
//!    running all N on its hot thread, and two daemons of N/2 (a hot thread per core);
//! 6. drivers: the same N pipelines reading sensor drivers (`ingest.iceoryx2`) instead of the
//!    simulator, this process publishing every IMU's sample each 1 ms and reading every
//!    corrected service; N daemons against one daemon;
//! 7. fed by a sensor driver, as deployed: this process publishes a raw sample each 1 ms on
//!    "sensor/raw" and reads the corrected service; the consumer is the bare chain of the same
//!    hops in its own process (this binary again), `pipelines/navigator.toml`, the same with
//!    the vehicle's odometry (this process also publishes a `StopSignal` with a yaw rate each
//!    20 ms, which the bias filter takes while moving), `pipelines/navigator-attitude.toml`
//!    (one hop more), `pipelines/external-sensor.toml`, then
//!    the bare chain again. Their CPU and p50 are judged against the mean of the two bare runs,
//!    and the attitude stage's compute time against its budget.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[path = "support/mod.rs"]
mod support;

use support::{
    bench_seconds, clean, cpu_seconds, loadavg, prefix, read_report, realtime, sigterm_and_wait,
    start_daemon, start_group, wait_exit,
};

use driftless::transport::{monotonic_ns, Qos, Transport, WakeSet};
use driftless::wire::{GyroSample, RawSample, StatsSnapshot, StopSignal, FLAG_FLUSHED, RAW_ACCEL};
use hdrhistogram::Histogram;
use serde_json::Value;

fn hist() -> Histogram<u64> {
    Histogram::new_with_bounds(1, 60_000_000_000, 3).expect("bounds")
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

struct Row {
    name: String,
    samples: u64,
    p50: u64,
    p99: u64,
    p999: u64,
    max: u64,
    misses: String,
    lost: String,
    cpu: String,
    throughput: String,
}

fn row_from(name: &str, h: &Histogram<u64>) -> Row {
    Row {
        name: name.into(),
        samples: h.len(),
        p50: h.value_at_quantile(0.5),
        p99: h.value_at_quantile(0.99),
        p999: h.value_at_quantile(0.999),
        max: h.max(),
        misses: "-".into(),
        lost: "-".into(),
        cpu: "-".into(),
        throughput: "-".into(),
    }
}

fn row_from_report(name: &str, r: &Value) -> Row {
    let e = &r["end_to_end_ns"];
    let u = |v: &Value| v.as_u64().unwrap_or(0);
    Row {
        name: name.into(),
        samples: u(&r["samples_out"]),
        p50: u(&e["p50"]),
        p99: u(&e["p99"]),
        p999: u(&e["p999"]),
        max: u(&e["max"]),
        misses: format!(
            "{} ({} the kernel's)",
            u(&r["deadline_misses"]),
            u(&r["deadline_misses_explained"])
        ),
        lost: u(&r["lost"]).to_string(),
        cpu: "-".into(),
        throughput: "-".into(),
    }
}

/// The bare chain's four ipc hops, `{stem}/raw` to `{stem}/corrected`, in one thread: each
/// sample is sent and received on every hop (the last is only sent, and notified).
struct BareHops {
    raw_out: driftless::transport::Output<RawSample>,
    raw_in: driftless::transport::Input<RawSample>,
    outs: Vec<driftless::transport::Output<GyroSample>>,
    ins: Vec<driftless::transport::Input<GyroSample>>,
}

impl BareHops {
    fn new(t: &Transport, stem: &str) -> Self {
        let names = ["denoised", "predicted", "corrected"].map(|h| format!("{stem}/{h}"));
        Self {
            raw_out: t.output(&format!("{stem}/raw"), false).expect("pub"),
            raw_in: t.input(&format!("{stem}/raw")).expect("sub"),
            outs: names
                .iter()
                .enumerate()
                .map(|(i, n)| t.output(n, i == 2).expect("pub"))
                .collect(),
            ins: names[..2]
                .iter()
                .map(|n| t.input(n).expect("sub"))
                .collect(),
        }
    }

    /// Pass `raw`, taken at `ingest_ns`, over the four hops; notify the last one's listeners.
    fn pass(&self, raw: &RawSample, ingest_ns: u64) {
        self.raw_out.send(raw).expect("send");
        let r = self.raw_in.receive().expect("recv").expect("sample");
        let mut g = GyroSample {
            seq: r.seq,
            t_ns: r.t_ns,
            ingest_ns,
            rate: r.rate,
            ..GyroSample::default()
        };
        for (i, out) in self.outs.iter().enumerate() {
            out.send(&g).expect("send");
            if let Some(input) = self.ins.get(i) {
                g = input.receive().expect("recv").expect("sample");
            }
        }
        self.outs[2].notify();
    }
}

/// The bare chain: the same four ipc hops in one thread, no computation.
fn bare_chain(prefix: &str, rate_hz: Option<f64>, n: u64) -> (Histogram<u64>, f64, f64) {
    let t = Transport::new(prefix, "bare", Qos::default()).expect("node");
    let hops = BareHops::new(&t, "b");
    let mut h = hist();
    let cpu0 = thread_cpu_seconds();
    let start = Instant::now();
    for k in 0..n {
        if let Some(rate) = rate_hz {
            let due = start + Duration::from_secs_f64(k as f64 / rate);
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
        let t0 = monotonic_ns();
        let raw = RawSample {
            seq: k,
            ..RawSample::default()
        };
        hops.pass(&raw, t0);
        h.saturating_record((monotonic_ns() - t0).max(1));
    }
    let elapsed = start.elapsed().as_secs_f64();
    let cpu = (thread_cpu_seconds() - cpu0) / elapsed;
    (h, n as f64 / elapsed, cpu)
}

/// CPU time of the calling thread (user and system), seconds.
fn thread_cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid timespec to write; CLOCK_THREAD_CPUTIME_ID has no other preconditions.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// Sleep to each 1 ms due time for `secs`, doing nothing else: how late each wake-up came, and
/// the CPU share any 1 kHz paced loop pays here just to wake up (timer, context switches; on a
/// VM, the exits).
fn sleeper(secs: f64) -> (Histogram<u64>, f64) {
    let mut late = hist();
    let cpu0 = thread_cpu_seconds();
    let start = Instant::now();
    for k in 1..(secs * 1000.0) as u64 {
        let due = start + Duration::from_millis(k);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        late.saturating_record((Instant::now() - due).as_nanos().max(1) as u64);
    }
    let cpu = (thread_cpu_seconds() - cpu0) / start.elapsed().as_secs_f64();
    (late, cpu)
}

/// Run a paced pipeline for `secs` with this process subscribed to `service`.
fn paced(
    pipeline: &Path,
    tag: &str,
    service: &str,
    secs: f64,
    dir: &Path,
) -> (Value, Histogram<u64>, f64, u64) {
    let p = prefix(tag);
    clean(&p);
    let report = dir.join(format!("{tag}.json"));
    let mut child = start_daemon(pipeline, &p, &report, &[]);
    let cpu0 = cpu_seconds(child.id());
    let t0 = Instant::now();
    let (h, lost) = subscribe(&p, service, secs);
    let cpu = (cpu_seconds(child.id()) - cpu0) / t0.elapsed().as_secs_f64();
    sigterm_and_wait(&mut child);
    clean(&p);
    (read_report(&report), h, cpu, lost)
}

/// Subscribe to `service` under `prefix` once it exists and read it for `secs`, sleeping on its
/// event service as a navigator does: each sample's `ingest_ns` to its receipt, and the
/// samples missing by `seq`.
fn subscribe(prefix: &str, service: &str, secs: f64) -> (Histogram<u64>, u64) {
    let me = Transport::new(prefix, "bench-sub", Qos::default()).expect("node");
    let ready = Instant::now();
    let input = loop {
        if let Ok(i) = me.open_input::<GyroSample>(service) {
            break i;
        }
        assert!(
            ready.elapsed() < Duration::from_secs(10),
            "publisher not ready"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    let waker = me.waker(service).expect("waker");
    let mut h = hist();
    let (mut last_seq, mut lost) = (None::<u64>, 0u64);
    let end = Instant::now() + Duration::from_secs_f64(secs);
    while Instant::now() < end {
        let _ = waker.wait(Duration::from_millis(100));
        while let Ok(Some(s)) = input.receive() {
            let now = monotonic_ns();
            if s.flags & FLAG_FLUSHED == 0 {
                h.saturating_record(now.saturating_sub(s.ingest_ns).max(1));
            }
            if let Some(prev) = last_seq {
                lost += s.seq.saturating_sub(prev + 1);
            }
            last_seq = Some(s.seq);
        }
    }
    (h, lost)
}

/// The environment variable that makes this bench binary the bare publisher of
/// [`bare_subscriber`]: "PREFIX SECONDS".
const BARE_PUBLISHER: &str = "DRIFTLESS_BENCH_BARE_PUBLISHER";

/// A bare iceoryx2 publisher at 1 kHz (SCHED_FIFO 50, as the daemon's hot thread): sleep to each
/// 1 ms, stamp, publish, notify. No computation: the floor of a subscriber's latency here.
fn bare_publisher(arg: &str) {
    let (prefix, secs) = arg.split_once(' ').expect("PREFIX SECONDS");
    let secs: f64 = secs.parse().expect("seconds");
    realtime(50);
    let t = Transport::new(prefix, "bare-pub", Qos::default()).expect("node");
    let out = t
        .output::<GyroSample>("bare/corrected", true)
        .expect("publisher");
    let start = Instant::now();
    for k in 0..(secs * 1000.0) as u64 {
        let due = start + Duration::from_millis(k + 1);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        let s = GyroSample {
            seq: k,
            ingest_ns: monotonic_ns(),
            ..GyroSample::default()
        };
        out.send(&s).expect("send");
        out.notify();
    }
}

/// A subscriber in this process to a bare 1 kHz publisher in another (this binary again):
/// publish to receipt, the floor for the demo's separate-process subscriber.
fn bare_subscriber(secs: f64) -> (Histogram<u64>, u64) {
    let p = prefix("baresub");
    clean(&p);
    let mut child = std::process::Command::new(std::env::current_exe().expect("this bench"))
        .env(BARE_PUBLISHER, format!("{p} {}", secs + 1.0))
        .spawn()
        .expect("spawn the bare publisher");
    let measured = subscribe(&p, "bare/corrected", secs);
    wait_exit(&mut child);
    clean(&p);
    measured
}

fn us(ns: u64) -> String {
    format!("{:.1}", ns as f64 / 1e3)
}

fn main() {
    if let Ok(arg) = std::env::var(BARE_PUBLISHER) {
        bare_publisher(&arg);
        return;
    }
    if let Ok(prefix) = std::env::var(BARE_DRIVEN) {
        bare_driven(&prefix);
        return;
    }
    let secs = bench_seconds(100.0);
    let dir = tempfile::tempdir().expect("tempdir");
    let only = std::env::var("DRIFTLESS_BENCH_ONLY").unwrap_or_default();
    if only == "fed" {
        println!("load average at the start: {}", loadavg());
        realtime(50);
        driver_fed_rows(secs.min(30.0), dir.path());
        return;
    }
    if only == "scale" || only == "drivers" {
        println!("load average at the start: {}", loadavg());
        if only == "scale" {
            scale(secs, dir.path());
        }
        drivers(secs, dir.path());
        return;
    }
    let mut rows = Vec::new();
    // Like the demo's hot thread, so the comparison with the bare chain is fair.
    let rt = realtime(50);
    println!("load average at the start: {}", loadavg());
    println!("bench thread (bare chain, subscriber): {rt}");

    // 1. Bare chain at 1 kHz.
    let bare_secs = secs.min(30.0);
    let p = prefix("bare1k");
    clean(&p);
    let (bare_1k, _, bare_cpu) = bare_chain(&p, Some(1000.0), (bare_secs * 1000.0) as u64);
    clean(&p);
    let mut r = row_from("bare iceoryx2 chain, 4 hops, 1 kHz", &bare_1k);
    r.cpu = format!("{:.1}%", bare_cpu * 100.0);
    rows.push(r);
    let (idle_late, idle_cpu) = sleeper(bare_secs / 3.0);
    let (bare_sub, bare_sub_lost) = bare_subscriber(bare_secs);
    let mut r = row_from(
        "bare iceoryx2 publisher, 1 kHz, separate-process subscriber",
        &bare_sub,
    );
    r.lost = bare_sub_lost.to_string();
    rows.push(r);

    // 2. Demo at 1 kHz with a separate-process subscriber (as shipped: its stages prewarmed
    // 150 us before each sample is due); then the same without prewarming.
    let (demo, sub, cpu) = demo_rows(
        &root().join("pipelines/demo.toml"),
        "demo",
        "demo",
        secs,
        dir.path(),
        &mut rows,
    );
    let cold_file = dir.path().join("demo-cold.toml");
    let text = std::fs::read_to_string(root().join("pipelines/demo.toml"))
        .expect("demo.toml")
        .replace("prewarm_us = 150.0", "prewarm_us = 0.0");
    std::fs::write(&cold_file, text).expect("write");
    let (cold, _, cold_cpu) = demo_rows(
        &cold_file,
        "democold",
        "demo, prewarm_us = 0 (off)",
        secs,
        dir.path(),
        &mut rows,
    );

    // 3. The paper's rate.
    let (paper, _, cpu50, _) = paced(
        &root().join("pipelines/adxrs450.toml"),
        "adxrs",
        "adxrs450/corrected",
        (secs / 5.0).max(2.0),
        dir.path(),
    );
    let mut r = row_from_report("adxrs450 pipeline, 50 Hz, 20 ms deadline", &paper);
    r.cpu = format!("{:.1}%", cpu50 * 100.0);
    rows.push(r);

    // 4. As fast as possible: CSV replay through all stages (nobody reading, then a reader on
    // its corrected service), then the bare chain.
    let asap_secs = (secs / 20.0).clamp(1.0, 5.0);
    let (asap, ours_tp, _) = asap_run(dir.path(), asap_secs, false);
    let mut r = row_from_report("replay as fast as possible, all stages", &asap);
    r.throughput = format!("{:.0}/s", ours_tp);
    rows.push(r);
    let (asap_read, read_tp, reader_lost) = asap_run(dir.path(), asap_secs, true);
    let mut r = row_from_report(
        "replay as fast as possible, a reader on its corrected service",
        &asap_read,
    );
    r.throughput = format!("{:.0}/s", read_tp);
    r.lost = format!(
        "{} (reader saw {reader_lost} missing)",
        asap_read["lost"].as_u64().unwrap_or(0)
    );
    rows.push(r);
    let p = prefix("bareasap");
    clean(&p);
    let (bare_asap, bare_tp, _) = bare_chain(
        &p,
        None,
        1_000_000.min((bare_secs * 100_000.0) as u64).max(100_000),
    );
    clean(&p);
    let mut r = row_from("bare iceoryx2 chain as fast as possible", &bare_asap);
    r.throughput = format!("{:.0}/s", bare_tp);
    rows.push(r);

    println!();
    println!("| run | samples | p50 us | p99 us | p99.9 us | max us | misses | lost | CPU | throughput |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in &rows {
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.name,
            r.samples,
            us(r.p50),
            us(r.p99),
            us(r.p999),
            us(r.max),
            r.misses,
            r.lost,
            r.cpu,
            r.throughput
        );
    }
    let demo_p50 = demo["end_to_end_ns"]["p50"].as_f64().unwrap_or(0.0);
    println!();
    println!(
        "overhead vs the bare chain: 1 kHz p50 x{:.2}; as-fast-as-possible throughput x{:.2} ({:.0} vs {:.0} samples/s), x{:.2} with a reader on corrected ({:.0}/s)",
        demo_p50 / bare_1k.value_at_quantile(0.5).max(1) as f64,
        ours_tp / bare_tp.max(1.0),
        ours_tp,
        bare_tp,
        read_tp / bare_tp.max(1.0),
        read_tp
    );
    let bare_p50 = bare_1k.value_at_quantile(0.5).max(1) as f64;
    for (name, r) in [("demo", &demo), ("demo, prewarm_us = 0 (off)", &cold)] {
        let late = &r["woken_late_ns"];
        println!(
            "{name}: p50 x{:.2} the bare chain's; samples woken late (after their due time, before ingest): p50 {} us, p99 {} us, max {} us",
            r["end_to_end_ns"]["p50"].as_f64().unwrap_or(0.0) / bare_p50,
            us(late["p50"].as_u64().unwrap_or(0)),
            us(late["p99"].as_u64().unwrap_or(0)),
            us(late["max"].as_u64().unwrap_or(0))
        );
    }
    println!(
        "CPU at 1 kHz, share of one core: the demo daemon {:.1}% (x{:.2} the bare sleeper's, x{:.2} the bare chain's), the bare chain's thread {:.1}%, a thread that only sleeps to each 1 ms {:.1}%",
        cpu * 100.0,
        cpu / idle_cpu.max(1e-9),
        cpu / bare_cpu.max(1e-9),
        bare_cpu * 100.0,
        idle_cpu * 100.0
    );
    let sub_floor = bare_sub.value_at_quantile(0.99);
    println!(
        "subscriber in another process, p99: the demo's {} us, a bare publisher's {} us ({:+.1} us)",
        us(sub.value_at_quantile(0.99)),
        us(sub_floor),
        (sub.value_at_quantile(0.99) as f64 - sub_floor as f64) / 1e3
    );
    let p999 = |r: &Value| r["end_to_end_ns"]["p999"].as_u64().unwrap_or(u64::MAX);
    println!(
        "prewarm_us = 150 (shipped): p99.9 {} us against {} us without; CPU {:.1}% against {:.1}% ({:+.1} points)",
        us(p999(&demo)),
        us(p999(&cold)),
        cpu * 100.0,
        cold_cpu * 100.0,
        (cpu - cold_cpu) * 100.0
    );
    println!(
        "the VM's own stalls: a bare sleeper woken over 1 ms late {} times in {} s",
        idle_late.count_between(1_000_000, u64::MAX),
        bare_secs / 3.0
    );
    // Issue 41's goals, each against this machine's floor measured above in the same run. The
    // demo's CPU is reported, not judged: its simulator is not what a user deploys (run 7
    // judges the driver-fed pipelines' CPU).
    let goals = [
        (
            "1 kHz demo p50 <= 2x the bare chain's",
            demo_p50 <= 2.0 * bare_p50,
        ),
        (
            "1 kHz demo p99.9 <= the bare chain's p99.9 + 20 us",
            p999(&demo) <= bare_1k.value_at_quantile(0.999) + 20_000,
        ),
        (
            "1 kHz demo: no unexplained 1 ms miss from ingest",
            demo["deadline_misses"] == demo["deadline_misses_explained"],
        ),
        (
            "separate-process subscriber p99 <= a bare publisher's subscriber p99 + 20 us",
            sub.value_at_quantile(0.99) <= sub_floor + 20_000,
        ),
        (
            "50 Hz: no unexplained miss of 20 ms",
            paper["deadline_misses"] == paper["deadline_misses_explained"],
        ),
        (
            "flat-out replay >= 0.8x the bare chain's throughput, nothing lost",
            ours_tp >= 0.8 * bare_tp && asap["lost"] == 0,
        ),
    ];
    for (goal, ok) in goals {
        println!("  goal {goal}: {ok}");
    }
    println!(
        "algorithmic delay of the demo's denoiser (lag / rate): {} us, reported beside the end-to-end latency",
        us(demo["algorithmic_delay_ns"].as_u64().unwrap_or(0))
    );
    // 7. Fed by a sensor driver, as deployed.
    driver_fed_rows(bare_secs, dir.path());
    if only != "single" {
        scale(secs, dir.path());
        drivers(secs, dir.path());
    }
    println!("load average at the end: {}", loadavg());
}

/// CSV replay of `pipelines/replay.toml` as fast as possible, looping, for `secs`; with `reader`,
/// a subscriber in this process on its corrected service, sleeping on its event service as a
/// navigator does. Returns the report, the throughput and the samples the reader found missing.
fn asap_run(dir: &Path, secs: f64, reader: bool) -> (Value, f64, u64) {
    let csv = root().join("pipelines/data/replay.csv");
    let text = std::fs::read_to_string(root().join("pipelines/replay.toml"))
        .expect("replay.toml")
        .replace(
            "file = \"data/replay.csv\"",
            &format!("file = {:?}", csv.display().to_string()),
        )
        .replace("pace = \"asap\"", "pace = \"asap\"\nloop = true");
    let asap_file = dir.join("asap.toml");
    std::fs::write(&asap_file, text).expect("write");
    let p = prefix(if reader { "asapread" } else { "asap" });
    clean(&p);
    let report = dir.join("asap.json");
    let mut child = start_daemon(
        &asap_file,
        &p,
        &report,
        &["--duration", &format!("{secs}s")],
    );
    let reader_lost = reader.then(|| {
        let p = p.clone();
        std::thread::spawn(move || subscribe(&p, "replay/corrected", secs + 1.0).1)
    });
    wait_exit(&mut child);
    let reader_lost = reader_lost.map_or(0, |t| t.join().expect("reader"));
    clean(&p);
    let r = read_report(&report);
    let tp = r["samples_out"].as_f64().unwrap_or(0.0) / r["duration_s"].as_f64().unwrap_or(1.0);
    (r, tp, reader_lost)
}

/// Run the demo pipeline `file` paced for `secs` with a subscriber in this process; push its
/// end-to-end row and its subscriber's row labelled `label`; returns the report, the
/// subscriber's histogram and the daemon's CPU share.
fn demo_rows(
    file: &Path,
    tag: &str,
    label: &str,
    secs: f64,
    dir: &Path,
    rows: &mut Vec<Row>,
) -> (Value, Histogram<u64>, f64) {
    let (report, sub, cpu, sub_lost) = paced(file, tag, "demo/corrected", secs, dir);
    let mut r = row_from_report(&format!("{label}, 1 kHz, end to end (daemon)"), &report);
    r.cpu = format!("{:.1}%", cpu * 100.0);
    rows.push(r);
    let mut r = row_from(
        &format!("{label}, separate-process subscriber (ingest to receipt)"),
        &sub,
    );
    r.lost = sub_lost.to_string();
    rows.push(r);
    (report, sub, cpu)
}

/// How run 5 lays out its pipelines over processes.
#[derive(Clone, Copy)]
enum Layout {
    /// A daemon of `pipelines/demo.toml` per pipeline, each under its own prefix.
    Separate,
    /// This many daemons, the pipelines dealt out among them, each daemon running its share on
    /// one hot thread.
    Daemons(usize),
}

/// Run 5: `n` 1 kHz 3-axis pipelines at once, as a vehicle with several IMUs would, in each
/// [`Layout`]; every pipeline reports its own misses and latency. Goal: 32 of them with no miss
/// of 1 ms in 10^5 samples each. A pipeline sharing a hot thread may be taken late (it waits
/// for those before it in the round), which its end-to-end latency from ingest does not show:
/// the due-to-publish columns do, and count too.
fn scale(secs: f64, dir: &Path) {
    let demo = std::fs::read_to_string(root().join("pipelines/demo.toml")).expect("demo.toml");
    println!();
    println!("| 1 kHz 3-axis pipelines at once | samples each (min) | misses (all) | worst e2e p99 us | worst e2e p99.9 us | worst e2e max us | due to publish: worst p99.9 / max us, over 1 ms | lost | CPU (all) | a 1 kHz sleeper beside them, woken late: p99.9 / max us, over 1 ms |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for n in pipeline_counts() {
        let imus = per_imu(&demo, "imu", n, dir);
        let demo_path = root().join("pipelines/demo.toml");
        for layout in [Layout::Separate, Layout::Daemons(1), Layout::Daemons(2)] {
            let (label, groups): (String, Vec<Vec<&Path>>) = match layout {
                Layout::Separate => (
                    format!("{n} daemons of the demo"),
                    (0..n).map(|_| vec![demo_path.as_path()]).collect(),
                ),
                Layout::Daemons(k) => (
                    match k {
                        1 => format!("{n} in one daemon"),
                        k => format!("{n} in {k} daemons of {}", n.div_ceil(k)),
                    },
                    imus.chunks(n.div_ceil(k))
                        .map(|c| c.iter().map(PathBuf::as_path).collect())
                        .collect(),
                ),
            };
            scale_row(&label, &groups, secs, dir, n == 32);
        }
    }
}

/// How many pipelines runs 5 and 6 lay out (`DRIFTLESS_BENCH_PIPELINES`, default "8,32").
fn pipeline_counts() -> Vec<usize> {
    std::env::var("DRIFTLESS_BENCH_PIPELINES")
        .unwrap_or_else(|_| "8,32".into())
        .split(',')
        .filter_map(|v| v.trim().parse().ok())
        .collect()
}

/// `n` copies of the pipeline `text` (named and publishing as "demo"), renamed `{stem}{i}`
/// so that each publishes its own services; their files in `dir`.
fn per_imu(text: &str, stem: &str, n: usize, dir: &Path) -> Vec<PathBuf> {
    (0..n)
        .map(|i| {
            let file = dir.join(format!("{stem}{i}.toml"));
            std::fs::write(&file, text.replace("demo", &format!("{stem}{i}"))).expect("write");
            file
        })
        .collect()
}

/// Wait for `child` to exit (killed after `timeout`); the CPU seconds it used, all threads.
fn wait_cpu_seconds(child: std::process::Child, timeout: Duration) -> f64 {
    let pid = child.id() as libc::pid_t;
    let end = Instant::now() + timeout;
    loop {
        let mut status = 0;
        // SAFETY: a zeroed rusage is valid; wait4 on our own child, which std has not reaped.
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        let rc = unsafe { libc::wait4(pid, &mut status, libc::WNOHANG, &mut usage) };
        if rc == pid {
            let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
            return secs(usage.ru_utime) + secs(usage.ru_stime);
        }
        if rc < 0 {
            return f64::NAN;
        }
        if Instant::now() > end {
            // SAFETY: kill(2) on our own child; the next round reaps it.
            unsafe { libc::kill(pid, libc::SIGKILL) };
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A thread of this process on SCHED_FIFO 50 (as the daemons' hot threads) that only sleeps
/// to each 1 ms due time for `secs`: how late it wakes is the machine's floor beside the
/// daemons, which no daemon can do better than.
fn sleeper_beside(secs: f64) -> std::thread::JoinHandle<Histogram<u64>> {
    std::thread::spawn(move || {
        realtime(50);
        sleeper(secs).0
    })
}

/// Start one daemon per group of pipeline files, wait for them, and print their row.
fn scale_row(label: &str, groups: &[Vec<&Path>], secs: f64, dir: &Path, goal: bool) {
    let duration = format!("{secs}s");
    let sleeper = sleeper_beside(secs);
    let runs: Vec<(String, PathBuf, std::process::Child)> = groups
        .iter()
        .enumerate()
        .map(|(j, files)| {
            let p = prefix(&format!("scale{j}"));
            clean(&p);
            let report = dir.join(format!("scale{j}.json"));
            let child = start_group(files, &p, &report, &["--duration", &duration]);
            (p, report, child)
        })
        .collect();
    let (mut samples, mut misses, mut lost, mut due_over) = (u64::MAX, 0u64, 0u64, 0u64);
    let mut explained = 0u64;
    let (mut p99, mut p999, mut max, mut due_p999, mut due_max) = (0u64, 0u64, 0u64, 0u64, 0u64);
    let mut cpu = 0.0;
    for (p, report, child) in runs {
        cpu += wait_cpu_seconds(child, Duration::from_secs_f64(secs + 60.0));
        clean(&p);
        let r = read_report(&report);
        let reports = r.as_array().cloned().unwrap_or_else(|| vec![r]);
        let u = |v: &Value| v.as_u64().unwrap_or(0);
        for r in &reports {
            print_unexplained(r);
            let e = &r["end_to_end_ns"];
            let d = &r["due_to_published_ns"];
            samples = samples.min(u(&r["samples_out"]));
            misses += u(&r["deadline_misses"]);
            explained += u(&r["deadline_misses_explained"]);
            lost += u(&r["lost"]);
            due_over += u(&r["due_to_published_over_deadline"]);
            p99 = p99.max(u(&e["p99"]));
            p999 = p999.max(u(&e["p999"]));
            max = max.max(u(&e["max"]));
            due_p999 = due_p999.max(u(&d["p999"]));
            due_max = due_max.max(u(&d["max"]));
        }
    }
    let floor = sleeper.join().expect("sleeper thread");
    let floor_over = floor.count_between(1_000_001, u64::MAX);
    println!(
        "| {label} | {samples} | {misses} ({explained} the kernel's) | {} | {} | {} | {} / {}, {due_over} | {lost} | {:.0}% | {} / {}, {floor_over} |",
        us(p99),
        us(p999),
        us(max),
        us(due_p999),
        us(due_max),
        cpu / secs * 100.0,
        us(floor.value_at_quantile(0.999)),
        us(floor.max()),
    );
    if goal {
        println!(
            "  goal 32 concurrent 1 kHz 3-axis pipelines with no unexplained 1 ms miss ({label}): \
             {} (from ingest: {misses}, {explained} of them the kernel's; from when due: \
             {due_over})",
            misses == explained && lost == 0
        );
    }
}

/// Each miss of report `r` the kernel does not explain, with where its time went (the
/// daemon's verdict says the same; the bench's reports are gone after the run).
fn print_unexplained(r: &Value) {
    let deadline = r["deadline_ns"].as_u64().unwrap_or(u64::MAX);
    for m in r["misses"].as_array().into_iter().flatten() {
        let e2e = m["e2e_ns"].as_u64().unwrap_or(0);
        let off = m["off_cpu_ns"].as_u64();
        if !driftless::metrics::miss_explained(e2e, off, deadline) {
            println!(
                "  UNEXPLAINED miss of {}: at {:.1} s, {} us end to end, off a CPU {}, stages (ns) {}",
                r["pipeline"].as_str().unwrap_or("?"),
                m["at_s"].as_f64().unwrap_or(0.0),
                us(e2e),
                off.map_or("not measured".into(), |o| format!("{} us", us(o))),
                m["stage_ns"]
            );
        }
    }
}

/// `lag` of the demo's denoiser, in samples.
const DEMO_LAG: u64 = 64;

/// Run 6: `n` IMUs whose samples come from sensor drivers (`ingest.iceoryx2`, the demo's
/// processing): one thread of this process (SCHED_FIFO 50) publishes every IMU's raw sample
/// each 1 ms and notifies, as drivers woken by one clock would; another reads every corrected
/// service, sleeping on all their wakers at once (`transport::WakeSet`, as a navigation process
/// with several IMUs would), and times each sample from its send to its receipt (the driver
/// notes when it sent each sample). A daemon per IMU against one daemon for all: the
/// daemon's end-to-end figures start when it takes the sample, so a pipeline waiting for others
/// in its round shows only in send to receipt.
fn drivers(secs: f64, dir: &Path) {
    let demo = std::fs::read_to_string(root().join("pipelines/demo.toml")).expect("demo.toml");
    let sim = "kind = \"ingest.sim\"\noutput = \"demo/raw\"\nprofile = \"adis16405\"\nmotion = \"stop-and-go\"\nseed = 1\n";
    assert!(
        demo.contains(sim) && demo.contains(&format!("\nlag = {DEMO_LAG}\n")),
        "demo.toml's ingest and lag as this run expects"
    );
    let driven = demo.replace(
        sim,
        "kind = \"ingest.iceoryx2\"\ninput = \"demo/sensor\"\noutput = \"demo/raw\"\n",
    );
    println!();
    println!("| 1 kHz 3-axis IMUs from sensor drivers | samples received (all) | send to receipt p50 / p99 / p99.9 / max us, over 1 ms | misses from ingest (all) | lost | CPU, all daemons |");
    println!("|---|---:|---:|---:|---:|---:|");
    for n in pipeline_counts() {
        let imus = per_imu(&driven, "drv", n, dir);
        let one: Vec<&Path> = imus.iter().map(PathBuf::as_path).collect();
        let separate: Vec<Vec<&Path>> = one.iter().map(|f| vec![*f]).collect();
        for (label, groups) in [
            (format!("{n} daemons"), separate),
            (format!("{n} in one daemon"), vec![one]),
        ] {
            drivers_row(&label, n, &groups, secs, dir);
        }
    }
}

/// Start one daemon per group, drive and read all `n` IMUs for `secs`, print the row.
fn drivers_row(label: &str, n: usize, groups: &[Vec<&Path>], secs: f64, dir: &Path) {
    let p = prefix("drivers");
    clean(&p);
    let duration = format!("{}s", secs + 3.0);
    let runs: Vec<(PathBuf, std::process::Child)> = groups
        .iter()
        .enumerate()
        .map(|(j, files)| {
            let report = dir.join(format!("drivers{j}.json"));
            let child = start_group(files, &p, &report, &["--duration", &duration]);
            (report, child)
        })
        .collect();
    let probe = Transport::new(&p, "probe", Qos::default()).expect("probe node");
    let end = Instant::now() + Duration::from_secs(30);
    while (0..n).any(|i| {
        !probe
            .service_exists::<StatsSnapshot>(&format!("drv{i}/stats"))
            .unwrap_or(false)
    }) && Instant::now() < end
    {
        std::thread::sleep(Duration::from_millis(20));
    }
    let ticks = (secs * 1000.0) as u64;
    // When the driver sent each IMU's sample k, at [i * ticks + k].
    let sent: Arc<Vec<AtomicU64>> =
        Arc::new((0..n as u64 * ticks).map(|_| AtomicU64::new(0)).collect());
    let stop = Arc::new(AtomicBool::new(false));
    let reader = {
        let (p, stop, sent) = (p.clone(), stop.clone(), sent.clone());
        std::thread::spawn(move || {
            realtime(50);
            let t = Transport::new(&p, "reader", Qos::default()).expect("node");
            let names: Vec<String> = (0..n).map(|i| format!("drv{i}/corrected")).collect();
            let inputs: Vec<_> = names
                .iter()
                .map(|s| t.input::<GyroSample>(s).expect("subscriber"))
                .collect();
            let wakers: Vec<_> = names.iter().map(|s| t.waker(s).expect("waker")).collect();
            let mut set = WakeSet::new().expect("wake set");
            for (i, w) in wakers.iter().enumerate() {
                set.add(w, i).expect("watch");
            }
            let mut h = hist();
            while !stop.load(Ordering::Relaxed) {
                let _ = set.wait(None, Duration::from_millis(10), |i| {
                    let _ = wakers[i].drain();
                });
                let now = monotonic_ns();
                for (i, input) in inputs.iter().enumerate() {
                    while let Ok(Some(s)) = input.receive() {
                        // The output of sample q leaves with sample q + lag (the denoiser's
                        // delay): time it from that one's send.
                        let k = s.seq + DEMO_LAG;
                        if s.flags & FLAG_FLUSHED == 0 && k < ticks {
                            let at = sent[i * ticks as usize + k as usize].load(Ordering::Relaxed);
                            h.record(now.saturating_sub(at).max(1)).expect("record");
                        }
                    }
                }
            }
            h
        })
    };
    // The driver: every IMU's sample at each 1 ms, on one clock.
    realtime(50);
    let outs: Vec<_> = (0..n)
        .map(|i| {
            probe
                .output::<RawSample>(&format!("drv{i}/sensor"), true)
                .expect("driver")
        })
        .collect();
    let start = Instant::now();
    for k in 0..ticks {
        let due = start + Duration::from_micros(k * 1000);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        let t = (k as f64) * 1e-3;
        for (i, out) in outs.iter().enumerate() {
            let rate = [(t + i as f64).sin(), (2.0 * t).cos(), 0.1 * (t * 7.0).sin()];
            let t_ns = monotonic_ns();
            sent[i * ticks as usize + k as usize].store(t_ns, Ordering::Relaxed);
            // Six axes: the accelerometer rides beside the rates, as a real IMU's does.
            let sample = RawSample {
                t_ns,
                seq: k,
                rate,
                flags: RAW_ACCEL,
                accel: [0.01 * rate[0], 0.02 * rate[1], -9.81],
                ..RawSample::default()
            };
            let _ = out.send(&sample);
            out.notify();
        }
    }
    std::thread::sleep(Duration::from_millis(200));
    stop.store(true, Ordering::Relaxed);
    let h = reader.join().expect("reader thread");
    let mut cpu = 0.0;
    let (mut misses, mut explained, mut lost) = (0u64, 0u64, 0u64);
    for (_, child) in &runs {
        // SAFETY: kill(2) on our own child: stop it now rather than at its --duration.
        unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    }
    for (report, child) in runs {
        cpu += wait_cpu_seconds(child, Duration::from_secs(60));
        let r = read_report(&report);
        for r in r.as_array().cloned().unwrap_or_else(|| vec![r]) {
            print_unexplained(&r);
            misses += r["deadline_misses"].as_u64().unwrap_or(0);
            explained += r["deadline_misses_explained"].as_u64().unwrap_or(0);
            lost += r["lost"].as_u64().unwrap_or(0);
        }
    }
    drop((outs, probe));
    clean(&p);
    println!(
        "| {label} | {} of {} | {} / {} / {} / {}, {} | {misses} ({explained} the kernel's) | {lost} | {:.0}% |",
        h.len(),
        n as u64 * ticks,
        us(h.value_at_quantile(0.5)),
        us(h.value_at_quantile(0.99)),
        us(h.value_at_quantile(0.999)),
        us(h.max()),
        h.count_between(1_000_001, u64::MAX),
        cpu / secs * 100.0,
    );
}

/// The environment variable that makes this bench binary [`bare_driven`]: the prefix.
const BARE_DRIVEN: &str = "DRIFTLESS_BENCH_BARE_DRIVEN";

/// The floor of a driver-fed pipeline, in its own process as a daemon is (SCHED_FIFO 50): sleep
/// on the driver's event service "sensor/raw" (1 ms timeout, as `ingest.iceoryx2`'s
/// `poll_timeout_us = 1000`), take each raw sample and pass it over the bare chain's four hops
/// to "bare/corrected", notifying. No computation. Until SIGTERM.
fn bare_driven(prefix: &str) {
    realtime(50);
    let stop = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGTERM, stop.clone()).expect("SIGTERM");
    let t = Transport::new(prefix, "bare-driven", Qos::default()).expect("node");
    let sensor = t
        .input::<RawSample>("sensor/raw")
        .expect("driver's service");
    let waker = t.waker("sensor/raw").expect("driver's event service");
    let hops = BareHops::new(&t, "bare");
    while !stop.load(Ordering::Relaxed) {
        let _ = waker.wait(Duration::from_millis(1));
        while let Ok(Some(raw)) = sensor.receive() {
            hops.pass(&raw, monotonic_ns());
        }
    }
}

/// What run 7 feeds from a driver.
#[derive(Clone, Copy)]
enum Fed<'a> {
    /// [`bare_driven`].
    Bare,
    /// A daemon of this pipeline file; its corrected service and its denoiser's lag (samples).
    Daemon(&'a Path, &'a str, u64),
    /// [`Fed::Daemon`], and the vehicle's odometry at 50 Hz on "vehicle/stop" (moving, with
    /// the yaw rate the gyro's z reads).
    WithOdometry(&'a Path, &'a str),
}

/// What run 7 measured of one consumer.
struct FedRun {
    /// The consumer's CPU, share of one core, over the driven window.
    cpu: f64,
    /// Driver's send to the subscriber's receipt.
    sub: Histogram<u64>,
    /// Samples the subscriber found missing (by `seq`).
    lost: u64,
    /// The daemon's report (none for the bare chain).
    report: Option<Value>,
}

/// Run 7: a sensor driver (this process's thread, SCHED_FIFO 50) publishes a `RawSample` on
/// "sensor/raw" each 1 ms for `secs` and notifies, as `examples/raw_driver.rs` does; `fed`
/// consumes it in its own process; a thread of this process subscribes to its corrected
/// service as a navigator would. The consumer's CPU is its process's (every thread) over the
/// driven window, from /proc.
fn driver_fed(fed: Fed<'_>, tag: &str, secs: f64, dir: &Path) -> FedRun {
    let p = prefix(tag);
    clean(&p);
    let report = dir.join(format!("{tag}.json"));
    let (mut child, service, lag) = match fed {
        Fed::Bare => (
            std::process::Command::new(std::env::current_exe().expect("this bench"))
                .env(BARE_DRIVEN, &p)
                .spawn()
                .expect("spawn the bare chain"),
            "bare/corrected",
            0,
        ),
        Fed::Daemon(file, service, lag) => (start_daemon(file, &p, &report, &[]), service, lag),
        Fed::WithOdometry(file, service) => (start_daemon(file, &p, &report, &[]), service, 0),
    };
    let driver = Transport::new(&p, "driver", Qos::default()).expect("driver node");
    let out = driver
        .output::<RawSample>("sensor/raw", true)
        .expect("driver's service");
    let odometry = matches!(fed, Fed::WithOdometry(..)).then(|| {
        driver
            .output::<StopSignal>("vehicle/stop", false)
            .expect("the odometry's service")
    });
    let ticks = (secs * 1000.0) as u64;
    let sent: Arc<Vec<AtomicU64>> = Arc::new((0..ticks).map(|_| AtomicU64::new(0)).collect());
    let (stop, ready) = (
        Arc::new(AtomicBool::new(false)),
        Arc::new(AtomicBool::new(false)),
    );
    let reader = {
        let (p, stop, ready, sent) = (p.clone(), stop.clone(), ready.clone(), sent.clone());
        let service = service.to_string();
        std::thread::spawn(move || {
            realtime(50);
            let t = Transport::new(&p, "navigator", Qos::default()).expect("node");
            let end = Instant::now() + Duration::from_secs(30);
            let input = loop {
                if let Ok(i) = t.open_input::<GyroSample>(&service) {
                    break i;
                }
                assert!(Instant::now() < end, "{service} not offered");
                std::thread::sleep(Duration::from_millis(20));
            };
            let waker = t.waker(&service).expect("waker");
            ready.store(true, Ordering::Release);
            let (mut h, mut last, mut lost) = (hist(), None::<u64>, 0u64);
            while !stop.load(Ordering::Relaxed) {
                let _ = waker.wait(Duration::from_millis(10));
                let now = monotonic_ns();
                while let Ok(Some(s)) = input.receive() {
                    // The output of sample q leaves with sample q + lag (the denoiser's delay).
                    let k = (s.seq + lag) as usize;
                    if s.flags & FLAG_FLUSHED == 0 && k < sent.len() {
                        let at = sent[k].load(Ordering::Relaxed);
                        h.saturating_record(now.saturating_sub(at).max(1));
                    }
                    lost += last.map_or(0, |l| s.seq.saturating_sub(l + 1));
                    last = Some(s.seq);
                }
            }
            (h, lost)
        })
    };
    while !ready.load(Ordering::Acquire) {
        assert!(!reader.is_finished(), "the subscriber gave up");
        std::thread::sleep(Duration::from_millis(10));
    }
    // Let the consumer's hot thread settle before the window opens.
    std::thread::sleep(Duration::from_millis(300));
    let cpu0 = cpu_seconds(child.id());
    let start = Instant::now();
    for (k, at) in sent.iter().enumerate() {
        let due = start + Duration::from_micros(k as u64 * 1000);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        let t = k as f64 * 1e-3;
        let t_ns = monotonic_ns();
        at.store(t_ns, Ordering::Relaxed);
        let _ = out.send(&RawSample {
            t_ns,
            seq: k as u64,
            rate: [t.sin(), (2.0 * t).cos(), 0.1 * (7.0 * t).sin()],
            flags: RAW_ACCEL,
            accel: [0.01 * t.sin(), 0.02 * t.cos(), -9.81],
            ..RawSample::default()
        });
        out.notify();
        if let Some(o) = odometry.as_ref().filter(|_| k % 20 == 19) {
            let mut s = StopSignal::new(t_ns, 2.0, 0);
            s.yaw_rate_rad_s = (0.1 * (7.0 * t).sin()).to_radians();
            s.period_ns = 20_000_000;
            let _ = o.send(&s);
        }
    }
    let cpu = (cpu_seconds(child.id()) - cpu0) / start.elapsed().as_secs_f64();
    std::thread::sleep(Duration::from_millis(200));
    stop.store(true, Ordering::Relaxed);
    let (sub, lost) = reader.join().expect("subscriber thread");
    sigterm_and_wait(&mut child);
    drop((odometry, out, driver));
    clean(&p);
    FedRun {
        cpu,
        sub,
        lost,
        report: (!matches!(fed, Fed::Bare)).then(|| read_report(&report)),
    }
}

/// Run 7's rows and goals: the bare chain, `navigator.toml`, `navigator-attitude.toml`,
/// `external-sensor.toml` and the bare chain again, each fed by the same driver for `secs`. The
/// baseline is the mean of the two bare runs: the machine's drift over the run shows in their
/// difference rather than in one pipeline's ratio.
fn driver_fed_rows(secs: f64, dir: &Path) {
    let nav = root().join("pipelines/navigator.toml");
    let att = root().join("pipelines/navigator-attitude.toml");
    let ext = root().join("pipelines/external-sensor.toml");
    // navigator.toml whose bias filter takes the vehicle's odometry, its yaw rate included.
    let odo = dir.join("navigator-odometry.toml");
    let text = std::fs::read_to_string(&nav).expect("navigator.toml");
    let with = text.replacen(
        "profile = \"adis16405\"\n",
        "profile = \"adis16405\"\nstop_input = \"vehicle/stop\"\nstop_speed = 0.05\nvehicle_up = \"+z\"\n",
        1,
    );
    assert_ne!(with, text, "navigator.toml's predict.bias table");
    std::fs::write(&odo, with).expect("write the odometry's pipeline");
    let runs = [
        ("bare iceoryx2 chain, 4 hops", Fed::Bare, "fedbare"),
        (
            "navigator.toml (bias filter, no denoiser)",
            Fed::Daemon(&nav, "nav/corrected", 0),
            "fednav",
        ),
        (
            "navigator.toml + the odometry's yaw rate at 50 Hz (stop_input, vehicle_up)",
            Fed::WithOdometry(&odo, "nav/corrected"),
            "fedodo",
        ),
        (
            "navigator-attitude.toml (bias filter, attitude.6d; 5 hops)",
            Fed::Daemon(&att, "nav/corrected", 0),
            "fedatt",
        ),
        (
            "external-sensor.toml (denoiser, lag 64)",
            Fed::Daemon(&ext, "external/corrected", DEMO_LAG),
            "fedext",
        ),
        ("bare iceoryx2 chain, again", Fed::Bare, "fedbare2"),
    ]
    .map(|(label, fed, tag)| (label, driver_fed(fed, tag, secs, dir)));
    println!();
    println!("| 1 kHz, fed by a sensor driver | CPU | x the bare chain's (mean of both runs) | send to receipt p50 / p99 / p99.9 / max us | misses (the kernel's) | lost |");
    println!("|---|---:|---:|---:|---:|---:|");
    let bare_cpu = ((runs[0].1.cpu + runs[5].1.cpu) / 2.0).max(1e-9);
    for (label, r) in &runs {
        let misses = r.report.as_ref().map_or("-".into(), |v| {
            format!(
                "{} ({})",
                v["deadline_misses"].as_u64().unwrap_or(0),
                v["deadline_misses_explained"].as_u64().unwrap_or(0)
            )
        });
        let reported_lost = r
            .report
            .as_ref()
            .map_or(0, |v| v["lost"].as_u64().unwrap_or(0));
        println!(
            "| {label} | {:.1}% | {:.2} | {} / {} / {} / {} | {misses} | {} |",
            r.cpu * 100.0,
            r.cpu / bare_cpu,
            us(r.sub.value_at_quantile(0.5)),
            us(r.sub.value_at_quantile(0.99)),
            us(r.sub.value_at_quantile(0.999)),
            us(r.sub.max()),
            r.lost + reported_lost,
        );
    }
    let unexplained = |r: &FedRun| {
        r.report.as_ref().map_or(0, |v| {
            v["deadline_misses"].as_u64().unwrap_or(0)
                - v["deadline_misses_explained"].as_u64().unwrap_or(0)
        })
    };
    for (goal, r, ratio) in [
        (
            "driver-fed navigator.toml CPU <= 1.5x the bare chain's",
            &runs[1].1,
            1.5,
        ),
        (
            "driver-fed navigator.toml with the odometry CPU <= 1.5x the bare chain's",
            &runs[2].1,
            1.5,
        ),
        (
            "driver-fed navigator-attitude.toml CPU <= 1.5x the bare chain's",
            &runs[3].1,
            1.5,
        ),
        (
            "driver-fed external-sensor.toml CPU <= 2.5x the bare chain's",
            &runs[4].1,
            2.5,
        ),
    ] {
        println!(
            "  goal {goal}: {} (x{:.2}; {} unexplained misses, {} lost)",
            r.cpu <= ratio * bare_cpu,
            r.cpu / bare_cpu,
            unexplained(r),
            r.lost
        );
    }
    // The attitude stage's own cost, and what it adds to the sample's way to a navigator.
    let (nav_run, odo_run, att_run) = (&runs[1].1, &runs[2].1, &runs[3].1);
    let p50 = |r: &FedRun| r.sub.value_at_quantile(0.5).max(1) as f64;
    let bare_p50 = (p50(&runs[0].1) + p50(&runs[5].1)) / 2.0;
    println!(
        "  goal driver-fed navigator-attitude.toml p50 <= 2x the bare chain's: {} (x{:.2}; \
         navigator.toml x{:.2})",
        p50(att_run) <= 2.0 * bare_p50,
        p50(att_run) / bare_p50,
        p50(nav_run) / bare_p50
    );
    println!(
        "  goal driver-fed navigator.toml with the odometry p50 <= 2x the bare chain's: {} \
         (x{:.2}; CPU {:+.1} points over navigator.toml's)",
        p50(odo_run) <= 2.0 * bare_p50,
        p50(odo_run) / bare_p50,
        (odo_run.cpu - nav_run.cpu) * 100.0
    );
    // Every stage's time (its compute and the publish of its output), for scale.
    if let Some(stages) = att_run
        .report
        .as_ref()
        .and_then(|v| v["stages"].as_array().cloned())
    {
        for s in &stages {
            let c = &s["compute_ns"];
            println!(
                "  {} ({}): p50 {} / p99 {} / p99.9 {} / max {} us",
                s["name"].as_str().unwrap_or("?"),
                s["kind"].as_str().unwrap_or("?"),
                us(c["p50"].as_u64().unwrap_or(0)),
                us(c["p99"].as_u64().unwrap_or(0)),
                us(c["p999"].as_u64().unwrap_or(0)),
                us(c["max"].as_u64().unwrap_or(0)),
            );
        }
    }
    let stage = att_run.report.as_ref().and_then(|v| {
        v["stages"]
            .as_array()?
            .iter()
            .find(|s| s["kind"] == "attitude.6d")
            .map(|s| s["compute_ns"].clone())
    });
    match stage {
        Some(c) => println!(
            "  goal attitude.6d p99.9 <= 5 us: {} (p50 {} / p99 {} / p99.9 {} / max {} us)",
            c["p999"].as_u64().is_some_and(|ns| ns <= 5_000),
            us(c["p50"].as_u64().unwrap_or(0)),
            us(c["p99"].as_u64().unwrap_or(0)),
            us(c["p999"].as_u64().unwrap_or(0)),
            us(c["max"].as_u64().unwrap_or(0)),
        ),
        None => println!("  goal attitude.6d p99.9 <= 5 us: no attitude.6d stage in the report"),
    }
}
