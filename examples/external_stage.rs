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
//! Options: `--prefix P` (default driftless_ or DRIFTLESS_IOX2_PREFIX), `--input NAME`,
//! `--output NAME` (defaults: the services of pipelines/external-stage.toml), `--scale S`
//! (default 2), `--offset O` (rad/s, default 0), `--count N` (exit after N samples; default:
//! until Ctrl-C). The same loop is `driftless relay` (the library's `stages::external::relay`).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use driftless::transport::{self, GyroSample, Transport};

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("external_stage: {e}");
            std::process::ExitCode::from(1)
        }
    }
}

fn run() -> Result<(), String> {
    let mut prefix =
        std::env::var(transport::PREFIX_ENV).unwrap_or_else(|_| transport::DEFAULT_PREFIX.into());
    let mut input = "ext/denoised".to_string();
    let mut output = "ext/filtered".to_string();
    let mut scale = 2.0f64;
    let mut offset = 0.0f64;
    let mut count: Option<u64> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--prefix" => prefix = value()?,
            "--input" => input = value()?,
            "--output" => output = value()?,
            "--scale" => scale = value()?.parse().map_err(|_| "--scale needs a number")?,
            "--offset" => offset = value()?.parse().map_err(|_| "--offset needs a number")?,
            "--count" => count = Some(value()?.parse().map_err(|_| "--count needs a count")?),
            other => return Err(format!("unknown argument {other:?}")),
        }
    }
    transport::quiet_logging();
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&stop)).map_err(|e| e.to_string())?;
    }
    let result = relay(&prefix, &input, &output, scale, offset, count, &stop);
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
