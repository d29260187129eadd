//! `driftless validate PIPELINE`: every check `run` makes, nothing started.

use std::path::PathBuf;

use crate::cli::CliError;
use crate::pipeline::config;

/// Arguments of `driftless validate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Pipeline file (TOML).
    pub pipeline: PathBuf,
}

/// Validate the pipeline and describe it on stdout.
pub fn run(args: Args) -> Result<(), CliError> {
    let p = config::load(&args.pipeline)?;
    println!(
        "{}: pipeline {:?} is valid: {} Hz, deadline {} us, {} axis/axes, prefix {:?}",
        args.pipeline.display(),
        p.name,
        p.rate_hz,
        p.deadline.as_micros(),
        p.axes,
        p.iceoryx2.prefix
    );
    for s in &p.stages {
        println!(
            "  {:<12} {:<16} {} -> {}",
            s.name,
            s.kind.name(),
            s.input.as_deref().unwrap_or("-"),
            s.output
        );
        if let config::StageKind::External { .. } = &s.kind {
            println!(
                "    runs in another process: it reads {} and must publish {} (and notify it)",
                s.input.as_deref().unwrap_or("-"),
                s.output
            );
        }
        if let config::StageKind::PredictRbf(r) = &s.kind {
            for (axis, (path, m)) in r.paths.iter().zip(&r.models).enumerate() {
                println!(
                    "    axis {axis}: model {} ({} Hz, {}, {} lags, {} centres, trained on {} [{}])",
                    path.display(),
                    m.rate_hz,
                    m.units,
                    m.network.lags,
                    m.network.centre_count(),
                    m.provenance.file,
                    m.provenance.column
                );
            }
        }
    }
    println!("  stats on {}", p.iceoryx2.stats_service);
    Ok(())
}
