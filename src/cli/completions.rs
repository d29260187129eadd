//! `driftless completions SHELL`: a shell completion script on stdout (clap_complete).

use clap::CommandFactory as _;

use super::{Cli, CliError};

/// Arguments of `driftless completions`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The shell: bash, zsh, fish, elvish or powershell.
    pub shell: clap_complete::Shell,
}

/// Print the completion script for `args.shell`.
pub fn run(args: Args) -> Result<(), CliError> {
    clap_complete::generate(
        args.shell,
        &mut Cli::command(),
        "driftless",
        &mut std::io::stdout(),
    );
    Ok(())
}
