//! `driftless denoise` (placeholder).

use super::CliError;

/// Arguments of `driftless denoise`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `driftless denoise`.
pub fn run(_args: Args) -> Result<(), CliError> {
    Err(CliError::internal("not yet"))
}
