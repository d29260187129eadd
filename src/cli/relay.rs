//! `driftless relay --input A --output B [--scale S] [--offset O]`: a reference `external` stage
//! in its own process ([`crate::stages::external::relay`]).

use std::time::Duration;

use crate::cli::CliError;
use crate::stages::external::{relay, RelayOptions};
use crate::transport::{self, Qos};

/// Arguments of `driftless relay`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Service to read (the external stage's `input`).
    #[arg(long)]
    pub input: String,
    /// Service to publish (the external stage's `output`); notified after each sample.
    #[arg(long)]
    pub output: String,
    /// Multiply `rate` and `denoised` by this.
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Then add this (rad/s).
    #[arg(long, default_value_t = 0.0)]
    pub offset: f64,
    /// Exit after this many samples (default: until SIGINT/SIGTERM).
    #[arg(long)]
    pub count: Option<u64>,
    /// Where the pipeline's iceoryx2 files are.
    #[command(flatten)]
    pub iceoryx2: crate::cli::iceoryx2::Iceoryx2Args,
    /// Sleep this many microseconds before relaying each sample (plays a slow stage).
    #[arg(long, default_value_t = 0)]
    pub delay_us: u64,
    /// Subscriber buffer of services this process creates (use the pipeline's buffer_size).
    #[arg(long, default_value_t = 256)]
    pub buffer_size: usize,
}

/// Relay until stopped or `--count` samples; prints "ready" on stderr once subscribed.
pub fn run(args: Args) -> Result<(), CliError> {
    let prefix = args.iceoryx2.resolve(None)?;
    for (what, name) in [("--input", &args.input), ("--output", &args.output)] {
        transport::check_service_name(name)
            .map_err(|e| CliError::input(format!("{what} {name:?}: {e}")))?;
    }
    if !(args.scale.is_finite() && args.offset.is_finite()) {
        return Err(CliError::input("--scale and --offset must be finite"));
    }
    if !(1..=65_536).contains(&args.buffer_size) {
        return Err(CliError::input("--buffer-size must be in 1..=65536"));
    }
    let stop = crate::cli::signals::stop_flag();
    let opts = RelayOptions {
        prefix,
        input: args.input,
        output: args.output,
        scale: args.scale,
        offset: args.offset,
        count: args.count,
        qos: Qos {
            buffer_size: args.buffer_size,
            ..Qos::default()
        },
        poll_timeout: Duration::from_millis(10),
        delay: Duration::from_micros(args.delay_us),
    };
    let n = relay(&opts, &stop, || eprintln!("relay: ready"))?;
    eprintln!("relay: {n} samples relayed");
    Ok(())
}
