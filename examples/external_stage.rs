//! A pipeline stage in its own process: the `external` stage of `pipelines/external-stage.toml`.
//! It subscribes to a `driftless::GyroSample` service the daemon publishes, applies a fixed
//! scale and offset to `rate` and `denoised` (every other field, `seq`, `t_ns`, `ingest_ns` and
//! the flags pass unchanged), publishes the result on the output service and notifies the event
//! service of the same name, so the daemon's next segment wakes at once.
//!
//! ```text
//! cargo run --release --example external_stage -- --input ext/denoised --output ext/filtered &
//! driftless run pipelines/external-stage.toml
//! ```
//!
//! Options (`--help`): `--prefix P` (default driftless_ or DRIFTLESS_IOX2_PREFIX), `--input
//! NAME`, `--output NAME` (defaults: the services of pipelines/external-stage.toml), `--scale S`
//! (default 2), `--offset O` (rad/s, default 0), `--count N` (exit after N samples; default:
//! until Ctrl-C). The same loop is `driftless relay` (the library's `stages::external::relay`).
//! Exit codes as `driftless`'s: 0 done, 1 a run-time failure, 2 bad usage.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use clap::Parser;
use driftless::transport::{self, Transport};
use driftless::wire::GyroSample;

/// An `external` pipeline stage in its own process: scales and offsets `rate` and `denoised` of
/// a GyroSample service and publishes (and notifies) another.
#[derive(Debug, Parser)]
#[command(name = "external_stage", version)]
struct Options {
    /// iceoryx2 prefix (default: DRIFTLESS_IOX2_PREFIX, else driftless_).
    #[arg(long, value_parser = prefix)]
    prefix: Option<String>,
    /// Service to read (the external stage's `input`).
    #[arg(long, default_value = "ext/denoised")]
    input: String,
    /// Service to publish (the external stage's `output`); notified after each sample.
    #[arg(long, default_value = "ext/filtered")]
    output: String,
    /// Multiply `rate` and `denoised` by this.
    #[arg(long, default_value_t = 2.0, allow_hyphen_values = true)]
    scale: f64,
    /// Then add this (rad/s).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    offset: f64,
    /// Exit after this many samples (default: until Ctrl-C).
    #[arg(long)]
    count: Option<u64>,
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
            eprintln!("external_stage: {e}");
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
    let result = relay(
        &prefix, &o.input, &o.output, o.scale, o.offset, o.count, &stop,
    );
    // The last process of a prefix removes its management file.
    transport::remove_prefix_leftovers(&prefix);
    result
}

fn relay(
    prefix: &str,
    input: &str,
    output: &str,
    scale: f64,
    offset: f64,
    count: Option<u64>,
    stop: &AtomicBool,
) -> Result<(), String> {
    let node = Transport::new(
        prefix,
        &format!("external-stage-{}", std::process::id()),
        Default::default(),
    )
    .map_err(|e| e.to_string())?;
    // Opened as they are if the daemon created them first; created otherwise.
    let rx = node
        .external_input::<GyroSample>(input)
        .map_err(|e| e.to_string())?;
    let wake = node.waker(input).map_err(|e| e.to_string())?;
    let tx = node
        .external_output::<GyroSample>(output, true)
        .map_err(|e| e.to_string())?;
    eprintln!("external_stage: {input} -> x * {scale} + {offset} -> {output}");
    let mut n = 0u64;
    while !stop.load(Ordering::Relaxed) && count.is_none_or(|c| n < c) {
        match rx.receive().map_err(|e| e.to_string())? {
            Some(mut s) => {
                for v in s.rate.iter_mut().chain(s.denoised.iter_mut()) {
                    *v = *v * scale + offset;
                }
                tx.send(&s).map_err(|e| e.to_string())?;
                tx.notify();
                n += 1;
            }
            // Sleep until the daemon notifies; the timeout is a safety net. An error is a
            // signal interrupting the wait: the loop condition decides.
            None => {
                let _ = wake.wait(Duration::from_millis(10));
            }
        }
    }
    eprintln!("external_stage: relayed {n} samples");
    Ok(())
}
