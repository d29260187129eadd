//! Where a command finds iceoryx2's files: the prefix and the root directory, shared by every
//! command that talks to a pipeline (run, stats, tap, record, list, relay), resolved the same
//! way everywhere: the option, else the environment, else the pipeline file, else the default.

use std::path::PathBuf;

use clap::Args;

use crate::cli::CliError;
use crate::pipeline::config::Iceoryx2Settings;
use crate::transport;

/// The `--prefix` and `--root-path` options.
#[derive(Debug, Clone, Default, Args)]
pub struct Iceoryx2Args {
    /// iceoryx2 prefix of the pipeline's files (default: DRIFTLESS_IOX2_PREFIX, else the
    /// pipeline's `[iceoryx2] prefix`, else driftless_).
    #[arg(long)]
    pub prefix: Option<String>,
    /// iceoryx2's root directory of node and service files (default: DRIFTLESS_IOX2_ROOT, else
    /// the pipeline's `[iceoryx2] root_path`, else /tmp/iceoryx2).
    #[arg(long, value_name = "DIR")]
    pub root_path: Option<PathBuf>,
}

impl Iceoryx2Args {
    /// Set iceoryx2's root directory for this process and return the prefix in force, from
    /// these options, the environment and `pipeline` (when the command reads a pipeline file).
    pub fn resolve(&self, pipeline: Option<&Iceoryx2Settings>) -> Result<String, CliError> {
        let prefix = match &self.prefix {
            Some(p) => p.clone(),
            None => std::env::var(transport::PREFIX_ENV).unwrap_or_else(|_| {
                pipeline.map_or(transport::DEFAULT_PREFIX.into(), |p| p.prefix.clone())
            }),
        };
        transport::check_prefix(&prefix)
            .map_err(|e| CliError::input(format!("invalid iceoryx2 prefix {prefix:?}: {e}")))?;
        let root = match &self.root_path {
            Some(r) => Some(r.clone()),
            None => match std::env::var_os(transport::ROOT_ENV) {
                Some(r) if !r.is_empty() => Some(PathBuf::from(r)),
                _ => pipeline.and_then(|p| p.root_path.clone()),
            },
        };
        let shown = root.as_ref().map(|r| r.display().to_string());
        transport::set_root(root).map_err(|e| {
            CliError::input(format!(
                "invalid iceoryx2 root path {}: {e}",
                shown.unwrap_or_default()
            ))
        })?;
        Ok(prefix)
    }
}
