//! `driftless man [--dir DIR]`: the manual page (clap_mangen), on stdout or one page per
//! command into a folder; `driftless man --markdown`: the command reference as Markdown
//! (`docs/reference/cli.md`, see `reference.rs`).

use std::path::PathBuf;

use clap::CommandFactory as _;

use super::{Cli, CliError};

/// Arguments of `driftless man`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Write driftless.1 and one page per command (driftless-run.1, ...) into this folder
    /// instead of printing driftless.1.
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// Print the command reference as Markdown instead (the file docs/reference/cli.md): every
    /// command with its usage, arguments and options.
    #[arg(long, conflicts_with = "dir")]
    pub markdown: bool,
}

/// Print or write the manual pages.
pub fn run(args: Args) -> Result<(), CliError> {
    let cmd = Cli::command();
    if args.markdown {
        print!("{}", super::reference::markdown(cmd));
        return Ok(());
    }
    match args.dir {
        None => clap_mangen::Man::new(cmd)
            .render(&mut std::io::stdout())
            .map_err(|e| CliError::internal(format!("man page: {e}"))),
        Some(dir) => {
            if !dir.is_dir() {
                return Err(CliError::input(format!(
                    "--dir {}: no such directory",
                    dir.display()
                )));
            }
            clap_mangen::generate_to(cmd, &dir)
                .map_err(|e| CliError::input(format!("--dir {}: {e}", dir.display())))
        }
    }
}
