//! `driftless stats PIPELINE`: show the live statistics a running daemon publishes.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use crate::cli::CliError;
use crate::pipeline::config;
use crate::transport::{self, Transport};
use crate::wire::StatsSnapshot;

/// Arguments of `driftless stats`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Pipeline file of the running daemon (for its stats service and prefix).
    pub pipeline: PathBuf,
    /// Where the pipeline's iceoryx2 files are.
    #[command(flatten)]
    pub iceoryx2: crate::cli::iceoryx2::Iceoryx2Args,
    /// Print one snapshot and exit.
    #[arg(long)]
    pub once: bool,
    /// One JSON object per snapshot, one per line (times in ns).
    #[arg(long)]
    pub json: bool,
}

/// Print every snapshot the daemon publishes until interrupted.
pub fn run(args: Args) -> Result<(), CliError> {
    transport::quiet_logging();
    let p = config::load(&args.pipeline)?;
    let prefix = args.iceoryx2.resolve(Some(&p.iceoryx2))?;
    let result = watch(&args, &p, &prefix);
    // The last process of a prefix removes its management file.
    transport::remove_prefix_leftovers(&prefix);
    result
}

fn watch(args: &Args, p: &config::Pipeline, prefix: &str) -> Result<(), CliError> {
    let node = Transport::new(
        prefix,
        &format!("driftless-stats-{}", std::process::id()),
        Default::default(),
    )?;
    let not_running = || {
        CliError::internal(format!(
            "no statistics from pipeline {:?} on {:?} (prefix {prefix:?}): is it running?",
            p.name, p.iceoryx2.stats_service
        ))
    };
    let input = node
        .open_input::<StatsSnapshot>(&p.iceoryx2.stats_service)
        .map_err(|e| match e {
            // A daemon of another release: say so, not "is it running?".
            transport::TransportError::Version(m) => CliError::input(m),
            _ => not_running(),
        })?;
    let stop = crate::cli::signals::stop_flag();
    // On a terminal the snapshot is redrawn in place (as `top`); piped, snapshots follow each
    // other.
    let redraw = !args.once && !args.json && std::io::stdout().is_terminal();
    let patience = p.report_interval * 2 + Duration::from_secs(1);
    let mut last = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        match input.receive() {
            Ok(Some(s)) => {
                let text = if args.json {
                    let mut v = crate::io::recording::StatsMessage::json(&s);
                    v["pipeline"] = p.name.clone().into();
                    format!("{v}\n")
                } else if redraw {
                    // Home, clear the screen, the snapshot.
                    format!(
                        "\x1b[H\x1b[2J{}",
                        crate::metrics::format_snapshot(&p.name, &s)
                    )
                } else {
                    crate::metrics::format_snapshot(&p.name, &s)
                };
                // A closed stdout (`| head`) ends the command cleanly, ports dropped.
                if std::io::Write::write_all(&mut std::io::stdout(), text.as_bytes()).is_err() {
                    return Ok(());
                }
                if args.once {
                    return Ok(());
                }
                last = Instant::now();
            }
            Ok(None) => {
                if last.elapsed() > patience {
                    return Err(not_running());
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(e) => return Err(CliError::internal(e.to_string())),
        }
    }
    Ok(())
}
