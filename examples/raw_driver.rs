//! A stand-in sensor driver in its own process: publishes simulated raw gyro samples
//! (`driftless::RawSample`, deg/s) on an iceoryx2 service at a fixed rate and notifies the event
//! service of the same name after each one, as `ingest.iceoryx2` expects.
//!
//! ```text
//! cargo run --release --example raw_driver -- --service sensor/raw --rate 1000 &
//! driftless run pipelines/external-sensor.toml
//! ```
//!
//! Options: `--service NAME` (default sensor/raw), `--rate HZ` (default 1000), `--prefix P`
//! (default driftless_ or DRIFTLESS_IOX2_PREFIX), `--duration D` (default: until Ctrl-C).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use driftless::sim::{Motion, SimConfig, Simulator};
use driftless::transport::{self, RawSample, Transport};

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("raw_driver: {e}");
            std::process::ExitCode::from(1)
        }
    }
}

fn run() -> Result<(), String> {
    let mut service = "sensor/raw".to_string();
    let mut rate = 1000.0f64;
    let mut prefix =
        std::env::var(transport::PREFIX_ENV).unwrap_or_else(|_| transport::DEFAULT_PREFIX.into());
    let mut duration = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--service" => service = value()?,
            "--rate" => {
                rate = value()?
                    .parse()
                    .map_err(|_| "--rate needs a number".to_string())?;
                if !(rate > 0.0 && rate <= 100_000.0) {
                    return Err("--rate must be in (0, 100000]".into());
                }
            }
            "--prefix" => prefix = value()?,
            "--duration" => duration = Some(driftless::cli::duration::parse_duration(&value()?)?),
            other => return Err(format!("unknown argument {other:?}")),
        }
    }
    transport::quiet_logging();
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&stop)).map_err(|e| e.to_string())?;
    }
    let result = publish(&prefix, &service, rate, duration, &stop);
    // The last process of a prefix removes its management file.
    transport::remove_prefix_leftovers(&prefix);
    result
}

fn publish(
    prefix: &str,
    service: &str,
    rate: f64,
    duration: Option<Duration>,
    stop: &AtomicBool,
) -> Result<(), String> {
    let node = Transport::new(
        prefix,
        &format!("raw-driver-{}", std::process::id()),
        Default::default(),
    )
    .map_err(|e| e.to_string())?;
    let out = node
        .output::<RawSample>(service, true)
        .map_err(|e| e.to_string())?;
    let mut cfg = SimConfig::profile("adis16405").map_err(|e| e.to_string())?;
    cfg.rate_hz = rate;
    cfg.axes = 3;
    cfg.motion = Motion::Sines;
    let mut sim = Simulator::new(&cfg).map_err(|e| e.to_string())?;
    let start = Instant::now();
    let mut k = 0u64;
    while !stop.load(Ordering::Relaxed) && duration.is_none_or(|d| start.elapsed() < d) {
        let due = start + Duration::from_secs_f64(k as f64 / rate);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        let s = sim.next_sample();
        let raw = RawSample {
            t_ns: (k as f64 * 1e9 / rate).round() as u64,
            seq: k,
            rate: s.measured,
            flags: 0,
            reserved: 0,
        };
        out.send(&raw).map_err(|e| e.to_string())?;
        out.notify();
        k += 1;
    }
    eprintln!("raw_driver: published {k} samples on {service}");
    Ok(())
}
