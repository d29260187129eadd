//! A stand-in sensor driver in its own process: publishes simulated raw IMU samples
//! (`driftless::RawSample`: the gyro in deg/s, and beside it the accelerometer in m/s², flag
//! `RAW_ACCEL`, the pipelines' default `accel_units`) on an iceoryx2 service at a fixed rate and
//! notifies the event service of the same name after each one, as `ingest.iceoryx2` expects. A
//! gyro-only driver leaves the accelerometer out (flag clear): absent, never zero. With `--mag`
//! it sends the magnetometer too (flag `RAW_MAG`, tesla): the earth's field as the body reads
//! it, for `use_mag` (pipelines/navigator-9d.toml).
//!
//! ```text
//! cargo run --release --example raw_driver -- --service sensor/raw --rate 1000 &
//! driftless run pipelines/external-sensor.toml
//! ```
//!
//! Options (`--help`): `--service NAME` (default sensor/raw), `--rate HZ` (default 1000),
//! `--prefix P` (default driftless_ or DRIFTLESS_IOX2_PREFIX), `--duration D` (default: until
//! Ctrl-C), `--mag`. Exit codes as `driftless`'s: 0 done, 1 a run-time failure, 2 bad usage.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::Parser;
use driftless::cli::duration::parse_duration;
use driftless::sim::force::SimAccel;
use driftless::sim::{Motion, SimConfig, Simulator};
use driftless::transport::{self, Transport};
use driftless::wire::{RawSample, RAW_ACCEL, RAW_MAG};

/// A stand-in sensor driver: publishes simulated raw gyro samples (deg/s) at a fixed rate and
/// notifies after each one, for `ingest.iceoryx2` (pipelines/external-sensor.toml).
#[derive(Debug, Parser)]
#[command(name = "raw_driver", version)]
struct Options {
    /// Service to publish `driftless::RawSample`s on.
    #[arg(long, default_value = "sensor/raw")]
    service: String,
    /// Sample rate, Hz, in (0, 100000].
    #[arg(long, default_value = "1000", value_parser = rate, allow_hyphen_values = true)]
    rate: f64,
    /// iceoryx2 prefix (default: DRIFTLESS_IOX2_PREFIX, else driftless_).
    #[arg(long, value_parser = prefix)]
    prefix: Option<String>,
    /// Stop after this long ("10s", "90min", or seconds; default: until Ctrl-C).
    #[arg(long, value_parser = parse_duration, allow_hyphen_values = true)]
    duration: Option<Duration>,
    /// Send the magnetometer too (flag RAW_MAG, tesla): a field of 49 uT, dip 66 deg.
    #[arg(long)]
    mag: bool,
}

/// A sample rate in (0, 100000] Hz, or a usage error.
fn rate(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(r) if r > 0.0 && r <= 100_000.0 => Ok(r),
        _ => Err(format!(
            "{s:?}: the rate must be a number of Hz in (0, 100000]"
        )),
    }
}

/// A valid iceoryx2 prefix, or a usage error.
fn prefix(s: &str) -> Result<String, String> {
    transport::check_prefix(s).map(|()| s.to_string())
}

fn main() -> std::process::ExitCode {
    // Usage errors exit 2, --help 0 (clap).
    let o = Options::parse();
    match run(&o) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("raw_driver: {e}");
            std::process::ExitCode::from(1)
        }
    }
}

fn run(o: &Options) -> Result<(), String> {
    let prefix = o.prefix.clone().unwrap_or_else(|| {
        std::env::var(transport::PREFIX_ENV).unwrap_or_else(|_| transport::DEFAULT_PREFIX.into())
    });
    transport::quiet_logging();
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&stop)).map_err(|e| e.to_string())?;
    }
    let result = publish(&prefix, o, &stop);
    // The last process of a prefix removes its management file.
    transport::remove_prefix_leftovers(&prefix);
    result
}

/// The earth's field in the simulator's north-east-down frame, tesla: 20 uT north, 45 uT down.
const EARTH_FIELD: [f64; 3] = [20e-6, 0.0, 45e-6];

fn publish(prefix: &str, o: &Options, stop: &AtomicBool) -> Result<(), String> {
    let (service, rate, duration) = (o.service.as_str(), o.rate, o.duration);
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
    // The same unit's accelerometer: the specific force of the same motion, with its noise.
    let mut accel = SimAccel::new("adis16405", &cfg)
        .map_err(|e| e.to_string())?
        .ok_or("the adis16405 profile has no accelerometer")?;
    // This run's id: a daemon that outlives the driver tells a restart from lost samples.
    let epoch = rand::random::<u32>().max(1);
    let start = Instant::now();
    let mut k = 0u64;
    while !stop.load(Ordering::Relaxed) && duration.is_none_or(|d| start.elapsed() < d) {
        let due = start + Duration::from_secs_f64(k as f64 / rate);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        let s = sim.next_sample();
        // The field at this sample's attitude, read before the accelerometer moves it on.
        let mag = accel.body_field(EARTH_FIELD);
        let raw = RawSample {
            t_ns: (k as f64 * 1e9 / rate).round() as u64,
            seq: k,
            rate: s.measured,
            accel: accel.next_reading(),
            flags: if o.mag {
                RAW_ACCEL | RAW_MAG
            } else {
                RAW_ACCEL
            },
            mag: if o.mag { mag } else { [0.0; 3] },
            epoch,
        };
        out.send(&raw).map_err(|e| e.to_string())?;
        out.notify();
        k += 1;
    }
    eprintln!("raw_driver: published {k} samples on {service}");
    Ok(())
}
