//! `driftless run PIPELINE... [--duration D] [--report FILE]`: the daemon, running one pipeline
//! or several on one hot thread.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::cli::duration::parse_duration;
use crate::cli::CliError;
use crate::pipeline::config::{self, Pipeline};
use crate::pipeline::runtime::{self, RunError, RunOptions};
use crate::transport;

/// Arguments of `driftless run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Pipeline file (TOML). Several: one daemon runs them all on one hot thread (a vehicle's
    /// IMUs), those due together in the order given.
    #[arg(value_name = "PIPELINE", required = true)]
    pub pipelines: Vec<PathBuf>,
    /// Stop by itself after this long: "10s", "500ms", "1.5s", "90min", or seconds. A paced
    /// source (a simulator, a replay) ends at its sample due that long after it started, so a
    /// run is the same samples however late a busy machine runs it.
    #[arg(long, value_parser = parse_duration, allow_hyphen_values = true)]
    pub duration: Option<Duration>,
    /// Write the final report as JSON to this file (several pipelines: an array of their
    /// reports, in the order given).
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
    let stem = prefix.trim_end_matches('_');
    let example = me
        .map(|u| format!("{stem}-{u}_"))
        .filter(|p| p != prefix && transport::check_prefix(p).is_ok())
        .unwrap_or_else(|| format!("{stem}-2_"));
    format!(
        "--prefix {example}, or DRIFTLESS_IOX2_PREFIX={example}, or `prefix = \"{example}\"` \
         under [iceoryx2] in {} (tap, stats and subscribers then take the same prefix)",
        pipeline.display()
    )
}

/// One pipeline: its report; several: an array in the order given, `null` where one failed.
fn write_report(path: &Path, reports: &[Option<crate::metrics::Report>]) -> Result<(), CliError> {
    let json = match reports {
        [Some(one)] => serde_json::to_string_pretty(one),
        all => serde_json::to_string_pretty(all),
    }
    .map_err(|e| CliError::internal(format!("report: {e}")))?;
    crate::io::atomic::write_atomically(path, json.as_bytes())
        .map_err(|e| CliError::input(format!("{}: {e}", path.display())))?;
    Ok(())
}

/// Load every pipeline file and the prefix each runs under; one daemon has one iceoryx2 root.
fn load_all(args: &Args) -> Result<Vec<(Pipeline, String)>, CliError> {
    let mut out: Vec<(Pipeline, String)> = Vec::new();
    // The first file's root, which every other must share.
    let mut first_root: Option<PathBuf> = None;
    for path in &args.pipelines {
        let pipeline: Pipeline = config::load(path)?;
        crate::cli::print_warnings(&pipeline);
        let prefix = args.iceoryx2.resolve(Some(&pipeline.iceoryx2))?;
        let here = transport::root();
        let first = first_root.get_or_insert_with(|| here.clone());
        if *first != here {
            return Err(CliError::input(format!(
                "{} uses iceoryx2 root {} and {} uses {}: one daemon has one root; give the \
                 same `root_path`, or --root-path",
                args.pipelines[0].display(),
                first.display(),
                path.display(),
                here.display()
            )));
        }
        out.push((pipeline, prefix));
    }
    Ok(out)
}

/// Run pipelines until SIGINT/SIGTERM, `--duration`, or the end of their finite sources.
pub fn run(args: Args) -> Result<(), CliError> {
    let loaded = load_all(&args)?;
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
    // What a side needs of its environment is configuration: refused before anything starts.
    for (p, _) in &loaded {
        for spec in &p.sides {
            spec.side.check_environment().map_err(CliError::input)?;
        }
    }
    let stop = crate::cli::signals::stop_flag();
    if stop.load(std::sync::atomic::Ordering::SeqCst) {
        let by = crate::cli::signals::stopped_by().unwrap_or("a signal");
        let _ = writeln!(
            std::io::stderr(),
            "driftless: stopped by {by} before any pipeline started"
        );
        return Ok(());
    }
    let opts = RunOptions {
        duration: args.duration,
        stop,
        print_summary: !args.quiet,
    };
    let members: Vec<(&Pipeline, String)> = loaded
        .iter()
        .map(|(p, prefix)| (p, prefix.clone()))
        .collect();
    let results = runtime::run_group(&members, &opts).map_err(|e| match e {
        RunError::AlreadyRunning {
            ref prefix,
            ref pipeline,
            ..
        } => {
            let file = loaded
                .iter()
                .find(|(p, _)| p.name == *pipeline)
                .map_or_else(|| PathBuf::from(pipeline), |(p, _)| p.path.clone());
            CliError::internal(format!(
                "{e}; stop it first, or run a second one under another prefix: {}",
                another_prefix_hint(prefix, &file)
            ))
        }
        RunError::Group(_)
        | RunError::Transport(transport::TransportError::SharedMemoryFull { .. }) => {
            CliError::input(e.to_string())
        }
        RunError::Transport(e) => e.into(),
        other => CliError::internal(other.to_string()),
    })?;
    let several = results.len() > 1;
    let mut reports = Vec::new();
    let mut failures = Vec::new();
    for ((p, _), result) in loaded.iter().zip(results) {
        match result {
            // Best effort: the report file below must be written even if stderr is gone.
            Ok(report) => {
                let _ = write!(std::io::stderr(), "{}", report.table());
                reports.push(Some(report));
            }
            Err(e) => {
                reports.push(None);
                failures.push(if several {
                    format!("pipeline {} failed: {e}", p.name)
                } else {
                    e.to_string()
                });
            }
        }
    }
    if let Some(path) = args
        .report
        .as_ref()
        .filter(|_| reports.iter().any(Option::is_some))
    {
        write_report(path, &reports)?;
    }
    if failures.is_empty() {
        Ok(())
    } else {
        Err(CliError::internal(failures.join("; ")))
    }
}
