//! The command line: one file per command; this file only dispatches and maps errors to exit codes.
//!
//! Exit codes, the same for every command (docs/commands.md, "Exit codes"):
//! - 0: done, including a daemon, `tap`, `stats`, `record`, `relay` or `bridge` stopped by
//!   SIGINT/SIGTERM, `--duration` or `--count`, and `list` with nothing running; `--help` and
//!   `--version`.
//! - 1: a run-time failure: the command line and the files are fine, but the command could not
//!   do its work: no daemon or service to read (`tap`, `stats`), the pipeline already running
//!   (`run`), iceoryx2 or the operating system failing during a run.
//! - 2: bad usage or bad input: an unknown option or a bad value (clap's own code for usage
//!   errors), an input file missing, unreadable or malformed, a pipeline file that does not
//!   validate, a model that does not fit the data, an output path that cannot be written, an
//!   iceoryx2 root directory or `/dev/shm` name another user controls
//!   (`transport::TransportError::Untrusted`).

use clap::{Parser, Subcommand};
use std::io::Write as _;
use std::process::ExitCode;

pub mod allan;
pub mod bridge;
pub mod completions;
pub mod denoise;
pub mod duration;
pub mod eval;
pub mod iceoryx2;
pub mod list;
pub mod log_input;
pub mod mag_cal;
pub mod man;
pub mod nav_eval;
pub mod num;
pub mod record;
pub mod reference;
pub mod relay;
pub mod run;
pub mod signals;
pub mod simulate;
pub mod stats;
pub mod table;
pub mod tap;
pub mod train;
pub mod validate;

/// driftless: real-time MEMS gyro rate cleaning, and the offline tools to characterise a gyro.
#[derive(Debug, Parser)]
#[command(name = "driftless", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
#[allow(clippy::large_enum_variant)]
enum Command {
    /// Wavelet-threshold denoise a CSV log (or a built-in synthetic benchmark).
    Denoise(denoise::Args),
    /// Train the RBF drift model on a static log; prints the baselines and the model's skill.
    Train(train::Args),
    /// Evaluate a drift model on a log: the paper's Table 3 (Allan terms before and after).
    Eval(eval::Args),
    /// The heading benchmark: known motion added to a static log (or the simulator), every
    /// method (baselines, estimators, pipelines' stages) judged by the integrated heading error.
    NavEval(nav_eval::Args),
    /// Run a pipeline (the daemon) until SIGINT/SIGTERM or --duration.
    Run(run::Args),
    /// Check a pipeline file as `run` would, without starting anything.
    Validate(validate::Args),
    /// Print the samples of a service, with its rate (like `ros2 topic echo` / `hz`).
    Tap(tap::Args),
    /// Show the live statistics of a running pipeline.
    Stats(stats::Args),
    /// Record services into an MCAP file (Foxglove opens and plots it; ingest.mcap replays it).
    Record(record::Args),
    /// What runs under a prefix: pipelines and their rate, nodes, services with their types,
    /// publishers and subscribers (like `ros2 topic list`); --clean removes dead nodes.
    List(list::Args),
    /// Run a reference `external` stage in this process: read a GyroSample service, scale and
    /// offset the rates, publish (and notify) another.
    Relay(relay::Args),
    /// Put services on Zenoh key expressions for other machines (driftless/<service>), or raw
    /// samples from Zenoh into a service (needs the `zenoh` feature).
    Bridge(bridge::Args),
    /// Allan deviation of a rate log (several still logs: pooled per tau, never joined) with
    /// intervals, and its IEEE Std 952 noise terms.
    Allan(allan::Args),
    /// Simulate a gyro log with known IEEE Std 952 noise terms.
    Simulate(simulate::Args),
    /// The magnetometer's hard and soft iron from a recorded rotation (an ellipsoid fit), with
    /// their uncertainty and the rotation's coverage, as a ready attitude.6d table.
    MagCal(mag_cal::Args),
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell).
    Completions(completions::Args),
    /// Print the manual page (roff), or write one page per command into a folder, or print the
    /// command reference as Markdown (--markdown).
    Man(man::Args),
}

/// The whole command line as clap sees it: what parses `driftless ...`, prints `--help` and
/// renders the manual pages and `docs/reference/cli.md`. Parsing with it
/// (`try_get_matches_from`) checks a command line without running anything.
pub fn command() -> clap::Command {
    use clap::CommandFactory as _;
    Cli::command()
}

/// A command's failure: the message for stderr and the process exit code (module docs).
#[derive(Debug)]
pub struct CliError {
    /// 2 for bad usage, input or configuration; 1 for a run-time failure.
    pub code: u8,
    /// One line for the user.
    pub message: String,
}

impl CliError {
    /// Bad input from the user (exit code 2).
    pub fn input(message: impl Into<String>) -> Self {
        CliError {
            code: 2,
            message: message.into(),
        }
    }

    /// A run-time failure, not the input's fault (exit code 1): nothing to read, the pipeline
    /// already running, iceoryx2 or the operating system failing.
    pub fn internal(message: impl Into<String>) -> Self {
        CliError {
            code: 1,
            message: message.into(),
        }
    }
}

impl From<crate::io::InputError> for CliError {
    fn from(e: crate::io::InputError) -> Self {
        CliError::input(e.to_string())
    }
}

/// A transport failure: bad configuration (another user's iceoryx2 root) is exit code 2, the
/// rest a run-time failure (1).
impl From<crate::transport::TransportError> for CliError {
    fn from(e: crate::transport::TransportError) -> Self {
        if e.is_configuration() {
            CliError::input(e.to_string())
        } else {
            CliError::internal(e.to_string())
        }
    }
}

impl From<crate::wavelet::WaveletError> for CliError {
    fn from(e: crate::wavelet::WaveletError) -> Self {
        CliError::input(e.to_string())
    }
}

/// Let a closed stdout (`driftless ... | head`) end the process quietly, as it does `cat`, instead
/// of failing a `println!`. Rust ignores SIGPIPE by default; this restores the Unix default.
fn restore_default_sigpipe() {
    // SAFETY: setting a signal's disposition to SIG_DFL at start-up, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Where the user finds the usage of the command they typed: `driftless CMD --help`.
fn help_hint() -> String {
    use clap::CommandFactory as _;
    let cli = Cli::command();
    match std::env::args().nth(1) {
        Some(sub) if cli.find_subcommand(&sub).is_some() => format!("driftless {sub} --help"),
        _ => "driftless --help".into(),
    }
}

/// A clap usage error as one line: its first paragraph (the error, with the arguments it lists),
/// without clap's tip, usage and "For more information" paragraphs, and where the usage is.
fn usage_error_line(rendered: &str, help: &str) -> String {
    let first = rendered.split("\n\n").next().unwrap_or(rendered);
    let joined = first
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ");
    let message = joined.strip_prefix("error: ").unwrap_or(&joined);
    format!("{message} (see '{help}')")
}

/// Parse the command line, run the command, and turn its outcome into an exit code.
pub fn main() -> ExitCode {
    signals::install();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            let code = ExitCode::from(e.exit_code().clamp(0, 255) as u8);
            // --help and --version go to stdout as clap writes them, and so does the help that
            // a bare `driftless` prints; a usage error is one line, like every other error.
            if !e.use_stderr() || e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                let _ = e.print();
            } else {
                let line = usage_error_line(&e.render().to_string(), &help_hint());
                let _ = writeln!(std::io::stderr(), "driftless: error: {line}");
            }
            return code;
        }
    };
    // Offline filters end quietly on a closed stdout; the daemon, tap, stats, record and list hold iceoryx2
    // ports, so they keep SIGPIPE ignored and handle a closed stream themselves (clean-up runs).
    if !matches!(
        cli.command,
        Command::Run(_)
            | Command::Tap(_)
            | Command::Stats(_)
            | Command::Record(_)
            | Command::List(_)
            | Command::Bridge(_)
    ) {
        restore_default_sigpipe();
    }
    let result = match cli.command {
        Command::Denoise(args) => denoise::run(args),
        Command::Train(args) => train::run(args),
        Command::Eval(args) => eval::run(args),
        Command::NavEval(args) => nav_eval::run(args),
        Command::Run(args) => run::run(args),
        Command::Validate(args) => validate::run(args),
        Command::Tap(args) => tap::run(args),
        Command::Stats(args) => stats::run(args),
        Command::Record(args) => record::run(args),
        Command::List(args) => list::run(args),
        Command::Relay(args) => relay::run(args),
        Command::Bridge(args) => bridge::run(args),
        Command::Allan(args) => allan::run(args),
        Command::Simulate(args) => simulate::run(args),
        Command::MagCal(args) => mag_cal::run(args),
        Command::Completions(args) => completions::run(args),
        Command::Man(args) => man::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // A closed stderr must not turn a clean error exit into a panic.
            let _ = writeln!(std::io::stderr(), "driftless: error: {}", e.message);
            ExitCode::from(e.code)
        }
    }
}

/// The warnings a pipeline file gave when read (they do not stop it), one line each on
/// stderr (a closed stderr loses them, nothing else).
pub fn print_warnings(p: &crate::pipeline::config::Pipeline) {
    for w in &p.warnings {
        let _ = writeln!(
            std::io::stderr(),
            "driftless: warning: {}: {w}",
            p.path.display()
        );
    }
}

/// The parser of a unit argument (`--units deg/s`): clap lists and checks `names` (a unit
/// type's names, in the order and with the help the command shows), the unit's own parser
/// (`FromStr`, in [`crate::units`]) makes the unit of the name.
pub fn unit_arg<U>(
    names: impl IntoIterator<Item = impl Into<clap::builder::PossibleValue>>,
) -> impl clap::builder::TypedValueParser<Value = U>
where
    U: std::str::FromStr<Err = String> + Clone + Send + Sync + 'static,
{
    use clap::builder::TypedValueParser as _;
    clap::builder::PossibleValuesParser::new(names).try_map(|name| name.parse::<U>())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn usage_errors_are_one_line() {
        let rendered = "error: the following required arguments were not provided:\n  --output <OUT.csv>\n\nUsage: driftless simulate --output <OUT.csv> --N <N>\n\nFor more information, try '--help'.\n";
        assert_eq!(
            usage_error_line(rendered, "driftless simulate --help"),
            "the following required arguments were not provided: --output <OUT.csv> (see 'driftless simulate --help')"
        );
        let rendered = "error: unexpected argument '--bogus' found\n\n  tip: to pass '--bogus' as a value, use '-- --bogus'\n\nUsage: driftless run [OPTIONS] <PIPELINE>\n";
        assert_eq!(
            usage_error_line(rendered, "driftless run --help"),
            "unexpected argument '--bogus' found (see 'driftless run --help')"
        );
    }
}
