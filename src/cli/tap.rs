//! `driftless tap SERVICE`: print the samples of any of our services, with a rate display
//! (like `ros2 topic echo` and `ros2 topic hz`).

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::cli::run::effective_prefix;
use crate::cli::CliError;
use crate::transport::{self, GyroSample, Input, RawSample, StatsSnapshot, Transport};

/// Arguments of `driftless tap`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Service name, e.g. demo/corrected (any hop of a pipeline, or a raw sensor service).
    pub service: String,
    /// iceoryx2 prefix (default: DRIFTLESS_IOX2_PREFIX or driftless_).
    #[arg(long)]
    pub prefix: Option<String>,
    /// Only the rate line, once a second, on stdout; no samples.
    #[arg(long)]
    pub hz: bool,
    /// Exit after this many samples.
    #[arg(long)]
    pub count: Option<u64>,
    /// Exit after this long ("10s", "500ms", "1.5s", "90min", or seconds).
    #[arg(
        long,
        value_parser = crate::cli::duration::parse_duration,
        allow_hyphen_values = true
    )]
    pub duration: Option<Duration>,
}

enum Tapped {
    Gyro(Input<GyroSample>),
    Raw(Input<RawSample>),
    Stats(Input<StatsSnapshot>),
}

fn line_gyro(s: &GyroSample) -> String {
    format!(
        "seq {} t {:.6} s rate [{:+.6} {:+.6} {:+.6}] rad/s drift [{:+.6} {:+.6} {:+.6}] denoised [{:+.6} {:+.6} {:+.6}] flags {:#x}",
        s.seq,
        s.t_ns as f64 * 1e-9,
        s.rate[0],
        s.rate[1],
        s.rate[2],
        s.drift[0],
        s.drift[1],
        s.drift[2],
        s.denoised[0],
        s.denoised[1],
        s.denoised[2],
        s.flags
    )
}

fn line_raw(s: &RawSample) -> String {
    format!(
        "seq {} t {:.6} s rate [{:+.6} {:+.6} {:+.6}] flags {:#x}",
        s.seq,
        s.t_ns as f64 * 1e-9,
        s.rate[0],
        s.rate[1],
        s.rate[2],
        s.flags
    )
}

/// Subscribe to SERVICE (whichever of our wire types it carries) and print what comes.
pub fn run(args: Args) -> Result<(), CliError> {
    transport::quiet_logging();
    transport::check_service_name(&args.service)
        .map_err(|e| CliError::input(format!("invalid service name {:?}: {e}", args.service)))?;
    let prefix = effective_prefix(args.prefix.as_deref(), transport::DEFAULT_PREFIX)?;
    let result = tap(&args, &prefix);
    // The last process of a prefix removes its management file.
    transport::remove_prefix_leftovers(&prefix);
    result
}

fn tap(args: &Args, prefix: &str) -> Result<(), CliError> {
    let node = Transport::new(
        prefix,
        &format!("driftless-tap-{}", std::process::id()),
        Default::default(),
    )
    .map_err(|e| CliError::internal(e.to_string()))?;
    let tapped = if let Ok(i) = node.open_input::<GyroSample>(&args.service) {
        Tapped::Gyro(i)
    } else if let Ok(i) = node.open_input::<RawSample>(&args.service) {
        Tapped::Raw(i)
    } else if let Ok(i) = node.open_input::<StatsSnapshot>(&args.service) {
        Tapped::Stats(i)
    } else {
        // Nothing to read is a run-time failure (exit 1), as for `stats`: the name may be right.
        return Err(CliError::internal(format!(
            "no service {:?} of a driftless type under prefix {prefix:?} (is the pipeline running?)",
            args.service
        )));
    };
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&stop))
            .map_err(|e| CliError::internal(format!("cannot install signal handler: {e}")))?;
    }
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let end = args.duration.map(|d| Instant::now() + d);
    let (mut total, mut window, mut gaps) = (0u64, 0u64, 0u64);
    let mut last_seq: Option<(u32, u64)> = None; // (epoch, seq)
    let mut tick = Instant::now();
    while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| Instant::now() < e) {
        let got = match &tapped {
            Tapped::Gyro(i) => i
                .receive()
                .ok()
                .flatten()
                .map(|s| (Some((s.epoch, s.seq)), line_gyro(&s))),
            Tapped::Raw(i) => i
                .receive()
                .ok()
                .flatten()
                .map(|s| (Some((s.epoch, s.seq)), line_raw(&s))),
            Tapped::Stats(i) => i
                .receive()
                .ok()
                .flatten()
                .map(|s| (None, crate::metrics::format_snapshot(&args.service, &s))),
        };
        match got {
            Some((seq, line)) => {
                total += 1;
                window += 1;
                // Sequence numbers count within one epoch (a daemon or source restart).
                if let (Some((epoch, seq)), Some((prev_epoch, prev))) = (seq, last_seq) {
                    if epoch == prev_epoch && seq > prev + 1 {
                        gaps += seq - prev - 1;
                    }
                }
                if seq.is_some() {
                    last_seq = seq;
                }
                if !args.hz && writeln!(out, "{line}").is_err() {
                    return Ok(()); // the reader went away (e.g. `| head`)
                }
                if args.count.is_some_and(|c| total >= c) {
                    break;
                }
            }
            None => std::thread::sleep(Duration::from_micros(500)),
        }
        let dt = tick.elapsed();
        if dt >= Duration::from_secs(1) {
            let rate = format!(
                "{}: {:.1} Hz, {} samples, {} missing (sequence gaps)",
                args.service,
                window as f64 / dt.as_secs_f64(),
                total,
                gaps
            );
            // With --hz the rate is the data asked for (stdout); beside samples, a message.
            if args.hz {
                if writeln!(out, "{rate}").and_then(|()| out.flush()).is_err() {
                    return Ok(());
                }
            } else {
                eprintln!("{rate}");
            }
            window = 0;
            tick = Instant::now();
        }
    }
    let _ = out.flush();
    Ok(())
}
