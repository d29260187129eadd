//! A navigation consumer in its own process: subscribes to a pipeline's corrected rates,
//! integrates heading from the z axis, and keeps its own histogram of the latency it sees
//! (from the daemon's ingest of the sample to receipt here, both CLOCK_MONOTONIC).
//!
//! ```text
//! driftless run pipelines/demo.toml &
//! cargo run --release --example nav_subscriber -- --service demo/corrected --duration 10s
//! ```
//!
//! Options: `--service NAME` (default demo/corrected), `--prefix P` (default driftless_ or
//! DRIFTLESS_IOX2_PREFIX), `--duration D` (default: until Ctrl-C), `--report FILE` (JSON).
//! It sleeps on the event service the publish stage notifies, so it costs one wake-up per sample.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use driftless::transport::{self, monotonic_ns, GyroSample, Transport, FLAG_FLUSHED};
use hdrhistogram::Histogram;

struct Options {
    service: String,
    prefix: String,
    duration: Option<Duration>,
    report: Option<String>,
}

fn options() -> Result<Options, String> {
    let mut o = Options {
        service: "demo/corrected".into(),
        prefix: std::env::var(transport::PREFIX_ENV)
            .unwrap_or_else(|_| transport::DEFAULT_PREFIX.into()),
        duration: None,
        report: None,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--service" => o.service = value()?,
            "--prefix" => o.prefix = value()?,
            "--duration" => {
                o.duration = Some(driftless::cli::duration::parse_duration(&value()?)?);
            }
            "--report" => o.report = Some(value()?),
            other => return Err(format!("unknown argument {other:?}")),
        }
    }
    Ok(o)
}

fn main() -> std::process::ExitCode {
    let o = match options() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("nav_subscriber: {e}");
            return std::process::ExitCode::from(2);
        }
    };
    let result = run(&o);
    // The last process of a prefix removes its management file.
    transport::remove_prefix_leftovers(&o.prefix);
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("nav_subscriber: {e}");
            std::process::ExitCode::from(1)
        }
    }
}

fn run(o: &Options) -> Result<(), String> {
    transport::quiet_logging();
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&stop)).map_err(|e| e.to_string())?;
    }
    let node = Transport::new(
        &o.prefix,
        &format!("nav-subscriber-{}", std::process::id()),
        Default::default(),
    )
    .map_err(|e| e.to_string())?;
    // Wait for the daemon to create the service.
    let started = Instant::now();
    let input = loop {
        match node.open_input::<GyroSample>(&o.service) {
            Ok(i) => break i,
            Err(_) if started.elapsed() < Duration::from_secs(10) => {
                std::thread::sleep(Duration::from_millis(50))
            }
            Err(e) => return Err(format!("{e} (is the pipeline running?)")),
        }
    };
    let waker = node.waker(&o.service).map_err(|e| e.to_string())?;
    let mut latency =
        Histogram::<u64>::new_with_bounds(1, 60_000_000_000, 3).map_err(|e| e.to_string())?;
    let (mut received, mut lost) = (0u64, 0u64);
    let mut heading_deg = 0.0f64;
    let mut last: Option<(u64, u64)> = None; // (seq, t_ns)
    let end = o.duration.map(|d| Instant::now() + d);
    let mut tick = Instant::now();
    while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| Instant::now() < e) {
        let _ = waker.wait(Duration::from_millis(100));
        while let Ok(Some(s)) = input.receive() {
            let now = monotonic_ns();
            received += 1;
            if s.flags & FLAG_FLUSHED == 0 {
                latency.saturating_record(now.saturating_sub(s.ingest_ns).max(1));
            }
            if let Some((seq, t_ns)) = last {
                if s.seq > seq + 1 {
                    lost += s.seq - seq - 1;
                }
                let dt = s.t_ns.saturating_sub(t_ns) as f64 * 1e-9;
                heading_deg += s.rate[2].to_degrees() * dt;
            }
            last = Some((s.seq, s.t_ns));
        }
        if tick.elapsed() >= Duration::from_secs(1) {
            eprintln!(
                "nav: {received} received, {lost} lost, heading {heading_deg:+.2} deg, latency p50 {:.1} us p99 {:.1} us max {:.1} us",
                latency.value_at_quantile(0.5) as f64 / 1e3,
                latency.value_at_quantile(0.99) as f64 / 1e3,
                latency.max() as f64 / 1e3
            );
            tick = Instant::now();
        }
    }
    let q = |p: f64| latency.value_at_quantile(p);
    println!(
        "nav_subscriber: {received} received, {lost} lost; heading {heading_deg:+.3} deg; latency (ingest to receipt) p50 {} ns, p99 {} ns, p99.9 {} ns, max {} ns",
        q(0.5),
        q(0.99),
        q(0.999),
        latency.max()
    );
    if let Some(path) = &o.report {
        let json = format!(
            "{{\"received\":{received},\"lost\":{lost},\"heading_deg\":{heading_deg},\"latency_ns\":{{\"count\":{},\"p50\":{},\"p99\":{},\"p999\":{},\"max\":{}}}}}\n",
            latency.len(),
            q(0.5),
            q(0.99),
            q(0.999),
            latency.max()
        );
        std::fs::write(path, json).map_err(|e| format!("{path}: {e}"))?;
    }
    Ok(())
}
