//! A navigation consumer in its own process: subscribes to a pipeline's corrected rates,
//! integrates heading from the z axis with the uncertainty the removed bias leaves in it
//! (`drift_std`, where the pipeline's predict stage provides it), and keeps its own histogram of
//! the latency it sees (from the daemon's ingest of the sample to receipt here, both
//! CLOCK_MONOTONIC).
//!
//! ```text
//! driftless run pipelines/demo.toml &
//! cargo run --release --example nav_subscriber -- --service demo/corrected --duration 10s
//! ```
//!
//! Options (`--help`): `--service NAME` (default demo/corrected), `--prefix P` (default
//! driftless_ or DRIFTLESS_IOX2_PREFIX), `--duration D` (default: until Ctrl-C), `--report FILE`
//! (JSON). It sleeps on the event service the publish stage notifies, so it costs one wake-up
//! per sample. Exit codes as `driftless`'s: 0 done, 1 no service to read (after 10 s) or a
//! run-time failure, 2 bad usage.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::Parser;
use driftless::cli::duration::parse_duration;
use driftless::transport::{self, monotonic_ns, Transport, TransportError};
use driftless::wire::{GyroSample, FLAG_FLUSHED};
use hdrhistogram::Histogram;

/// A navigation consumer in its own process: integrates heading from a pipeline's corrected
/// rates and keeps its own latency histogram (ingest to receipt).
#[derive(Debug, Parser)]
#[command(name = "nav_subscriber", version)]
struct Options {
    /// Service of corrected rates to subscribe to.
    #[arg(long, default_value = "demo/corrected")]
    service: String,
    /// iceoryx2 prefix (default: DRIFTLESS_IOX2_PREFIX, else driftless_).
    #[arg(long, value_parser = prefix)]
    prefix: Option<String>,
    /// Stop after this long ("10s", "90min", or seconds; default: until Ctrl-C).
    #[arg(long, value_parser = parse_duration, allow_hyphen_values = true)]
    duration: Option<Duration>,
    /// Write the summary as JSON to this file.
    #[arg(long, value_name = "FILE")]
    report: Option<String>,
}

/// A valid iceoryx2 prefix, or a usage error.
fn prefix(s: &str) -> Result<String, String> {
    transport::check_prefix(s).map(|()| s.to_string())
}

fn main() -> std::process::ExitCode {
    // Usage errors exit 2, --help 0 (clap).
    let o = Options::parse();
    let prefix = o.prefix.clone().unwrap_or_else(|| {
        std::env::var(transport::PREFIX_ENV).unwrap_or_else(|_| transport::DEFAULT_PREFIX.into())
    });
    let result = run(&o, &prefix);
    // The last process of a prefix removes its management file.
    transport::remove_prefix_leftovers(&prefix);
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("nav_subscriber: {e}");
            std::process::ExitCode::from(1)
        }
    }
}

fn run(o: &Options, prefix: &str) -> Result<(), String> {
    transport::quiet_logging();
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&stop)).map_err(|e| e.to_string())?;
    }
    let node = Transport::new(
        prefix,
        &format!("nav-subscriber-{}", std::process::id()),
        Default::default(),
    )
    .map_err(|e| e.to_string())?;
    // Wait for the daemon to create the service.
    let started = Instant::now();
    let input = loop {
        match node.open_input::<GyroSample>(&o.service) {
            Ok(i) => break i,
            // A daemon of another release: waiting will not help.
            Err(e @ TransportError::Version(_)) => return Err(e.to_string()),
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
    // Samples that carried an accelerometer reading, and the sum of its magnitudes (m/s²): at
    // rest or cruising, about gravity's.
    let (mut with_accel, mut accel_norm_sum) = (0u64, 0.0f64);
    let mut heading_deg = 0.0f64;
    // The heading error the removed bias can leave: its 1-sigma integrated over time (a bias
    // error is nearly constant between stops, so errors add up rather than average out: an
    // upper bound). None once a sample did not provide it.
    let mut heading_sd_deg = Some(0.0f64);
    let mut bias_sd_z: Option<f64> = None; // newest z drift_std, deg/s; None: not provided
    let mut last: Option<(u32, u64, u64)> = None; // (epoch, seq, t_ns)
    let mut epochs = 0u64;
    let end = o.duration.map(|d| Instant::now() + d);
    let mut tick = Instant::now();
    while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| Instant::now() < e) {
        let _ = waker.wait(Duration::from_millis(100));
        while let Ok(Some(s)) = input.receive() {
            let now = monotonic_ns();
            received += 1;
            if let Some(a) = s.accel_reading() {
                with_accel += 1;
                accel_norm_sum += a.iter().map(|v| v * v).sum::<f64>().sqrt();
            }
            if s.flags & FLAG_FLUSHED == 0 {
                latency.saturating_record(now.saturating_sub(s.ingest_ns).max(1));
            }
            match last {
                // `seq` and time count within one epoch (one daemon run, one source run).
                Some((epoch, seq, t_ns)) if epoch == s.epoch => {
                    if s.seq > seq + 1 {
                        lost += s.seq - seq - 1;
                    }
                    let dt = s.t_ns.saturating_sub(t_ns) as f64 * 1e-9;
                    heading_deg += s.rate[2].to_degrees() * dt;
                    heading_sd_deg = match (heading_sd_deg, bias_sd_z) {
                        (Some(h), Some(b)) => Some(h + b * dt),
                        _ => None,
                    };
                }
                _ => epochs += 1,
            }
            last = Some((s.epoch, s.seq, s.t_ns));
            // Negative: not provided (predict.none, predict.rbf); never NaN on the wire.
            bias_sd_z = (s.drift_std[2] >= 0.0).then(|| s.drift_std[2].to_degrees());
        }
        if tick.elapsed() >= Duration::from_secs(1) {
            eprintln!(
                "nav: {received} received, {lost} lost, heading {heading_deg:+.2} deg {}, bias z {}, latency p50 {:.1} us p99 {:.1} us max {:.1} us",
                sd_text(heading_sd_deg, "deg"),
                sd_text(bias_sd_z, "deg/s"),
                latency.value_at_quantile(0.5) as f64 / 1e3,
                latency.value_at_quantile(0.99) as f64 / 1e3,
                latency.max() as f64 / 1e3
            );
            tick = Instant::now();
        }
    }
    let q = |p: f64| latency.value_at_quantile(p);
    let accel_mean_norm = (with_accel > 0).then(|| accel_norm_sum / with_accel as f64);
    println!(
        "nav_subscriber: {received} received, {lost} lost, {epochs} epochs; heading {heading_deg:+.3} deg {} (from the removed bias); {with_accel} with an accelerometer (mean |a| {}); latency (ingest to receipt) p50 {} ns, p99 {} ns, p99.9 {} ns, max {} ns",
        sd_text(heading_sd_deg, "deg"),
        accel_mean_norm.map_or("-".to_string(), |v| format!("{v:.3} m/s²")),
        q(0.5),
        q(0.99),
        q(0.999),
        latency.max()
    );
    if let Some(path) = &o.report {
        let json = format!(
            "{{\"received\":{received},\"lost\":{lost},\"epochs\":{epochs},\"heading_deg\":{heading_deg},\"heading_sd_deg\":{},\"with_accel\":{with_accel},\"accel_mean_norm_m_s2\":{},\"latency_ns\":{{\"count\":{},\"p50\":{},\"p99\":{},\"p999\":{},\"max\":{}}}}}\n",
            heading_sd_deg.map_or("null".to_string(), |v| v.to_string()),
            accel_mean_norm.map_or("null".to_string(), |v| v.to_string()),
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

/// `+- 0.123 UNIT`, or `+- ? (not provided)` when the pipeline gives no bias uncertainty.
fn sd_text(sd: Option<f64>, unit: &str) -> String {
    match sd {
        Some(v) => format!("+- {v:.3} {unit}"),
        None => "+- ? (not provided)".to_string(),
    }
}
