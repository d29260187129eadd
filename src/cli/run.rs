//! `driftless run PIPELINE [--duration D] [--report FILE]`: the daemon.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use crate::cli::duration::parse_duration;
use crate::cli::CliError;
use crate::pipeline::config::{self, Pipeline};
use crate::pipeline::runtime::{self, RunError, RunOptions};
use crate::transport;

/// Arguments of `driftless run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Pipeline file (TOML).
    pub pipeline: PathBuf,
    /// Stop by itself after this long: "10s", "500ms", "1.5s", "90min", or seconds.
    #[arg(long, value_parser = parse_duration, allow_hyphen_values = true)]
    pub duration: Option<Duration>,
    /// Write the final report as JSON to this file.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Where the pipeline's iceoryx2 files are.
    #[command(flatten)]
    pub iceoryx2: crate::cli::iceoryx2::Iceoryx2Args,
    /// No start line and no periodic summary line on stderr (the final table is still printed).
    #[arg(long, short)]
    pub quiet: bool,
}

/// How to run a second daemon of a pipeline whose prefix `prefix` is taken: the three ways to
/// set another (the tools that read it then take the same), with a free-to-use example name.
fn another_prefix_hint(prefix: &str, pipeline: &Path) -> String {
    // SAFETY: getuid cannot fail.
    let me = transport::user_name(unsafe { libc::getuid() });
    let example = me
        .map(|u| format!("{prefix}{u}_"))
        .filter(|p| p != prefix && transport::check_prefix(p).is_ok())
        .unwrap_or_else(|| format!("{prefix}2_"));
    format!(
        "--prefix {example}, or DRIFTLESS_IOX2_PREFIX={example}, or `prefix = \"{example}\"` \
         under [iceoryx2] in {} (tap, stats and subscribers then take the same prefix)",
        pipeline.display()
    )
}

fn write_report(path: &Path, report: &crate::metrics::Report) -> Result<(), CliError> {
    let json = serde_json::to_string_pretty(report)
        .map_err(|e| CliError::internal(format!("report: {e}")))?;
    crate::io::atomic::write_atomically(path, json.as_bytes())
        .map_err(|e| CliError::input(format!("{}: {e}", path.display())))?;
    Ok(())
}

/// Run a pipeline until SIGINT/SIGTERM, `--duration`, or the end of a finite source.
pub fn run(args: Args) -> Result<(), CliError> {
    let pipeline: Pipeline = config::load(&args.pipeline)?;
    let prefix = args.iceoryx2.resolve(Some(&pipeline.iceoryx2))?;
    if let Some(r) = &args.report {
        if r.is_dir() {
            return Err(CliError::input(format!(
                "--report {}: is a directory",
                r.display()
            )));
        }
        let parent = r.parent().filter(|d| !d.as_os_str().is_empty());
        if parent.is_some_and(|d| !d.is_dir()) {
            return Err(CliError::input(format!(
                "--report {}: no such directory",
                r.display()
            )));
        }
    }
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&stop))
            .map_err(|e| CliError::internal(format!("cannot install signal handler: {e}")))?;
    }
    let opts = RunOptions {
        prefix,
        duration: args.duration,
        stop,
        print_summary: !args.quiet,
    };
    let report = runtime::run(&pipeline, &opts).map_err(|e| match e {
        RunError::AlreadyRunning { ref prefix, .. } => CliError::internal(format!(
            "{e}; stop it first, or run a second one under another prefix: {}",
            another_prefix_hint(prefix, &args.pipeline)
        )),
        other => CliError::internal(other.to_string()),
    })?;
    // Best effort: the report file below must be written even if stderr is gone.
    let _ = write!(std::io::stderr(), "{}", report.table());
    if let Some(path) = &args.report {
        write_report(path, &report)?;
    }
    Ok(())
}
