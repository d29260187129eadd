//! `driftless bridge SERVICE...`: our iceoryx2 services on Zenoh key expressions
//! (`driftless/<service>`), for subscribers on other machines; and `--from-zenoh KEY --to
//! SERVICE`, raw samples from Zenoh into a service `ingest.iceoryx2` reads. The bridge is
//! `transport::zenoh::run_bridge` (docs/bridge.md); this file reads the arguments and prints
//! what it reports.
//!
//! Needs the cargo feature `zenoh`; without it the command says how to build it (exit 2).

use std::path::PathBuf;
use std::time::Duration;

use crate::cli::CliError;

/// Zenoh session mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// Talk to other peers directly (and to routers).
    Peer,
    /// Talk only through the router (or peer) given with --connect.
    Client,
}

/// Arguments of `driftless bridge`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Services to put on Zenoh, e.g. demo/corrected (any service of driftless::GyroSample or
    /// driftless::RawSample). Each goes to the key KEY_PREFIX/SERVICE.
    #[arg(
        value_name = "SERVICE",
        required_unless_present = "from_zenoh",
        conflicts_with = "from_zenoh"
    )]
    pub services: Vec<String>,
    /// Key expression prefix of the bridged services.
    #[arg(long, default_value = "driftless")]
    pub key_prefix: String,
    /// Reverse direction: take driftless::RawSample payloads (48 bytes) from this key
    /// expression ...
    #[arg(long, value_name = "KEY", requires = "to")]
    pub from_zenoh: Option<String>,
    /// ... and publish them (and notify) on this iceoryx2 service, for an `ingest.iceoryx2`
    /// stage.
    #[arg(long, value_name = "SERVICE", requires = "from_zenoh")]
    pub to: Option<String>,
    /// Subscriber buffer of the service --to creates (the pipeline's buffer_size).
    #[arg(long, default_value_t = 256)]
    pub buffer_size: usize,
    /// Where the pipeline's iceoryx2 files are.
    #[command(flatten)]
    pub iceoryx2: crate::cli::iceoryx2::Iceoryx2Args,
    /// Zenoh session mode (default: the --zenoh-config file's, else peer).
    #[arg(long, value_enum)]
    pub mode: Option<Mode>,
    /// Zenoh endpoint to connect to, e.g. tcp/192.168.1.5:7447 (repeatable).
    #[arg(long, value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// Zenoh endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable).
    #[arg(long, value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Turn Zenoh's multicast scouting off (peers then meet only through the endpoints).
    #[arg(long)]
    pub no_multicast_scouting: bool,
    /// A standard Zenoh configuration file (JSON5); the options above override it.
    #[arg(long, value_name = "FILE")]
    pub zenoh_config: Option<PathBuf>,
    /// Exit after this long ("10s", "500ms", "90min", or seconds); default until SIGINT/SIGTERM.
    #[arg(
        long,
        value_parser = crate::cli::duration::parse_duration,
        allow_hyphen_values = true
    )]
    pub duration: Option<Duration>,
}

/// Run the bridge until SIGINT/SIGTERM or `--duration`.
#[cfg(not(feature = "zenoh"))]
pub fn run(_args: Args) -> Result<(), CliError> {
    Err(CliError::input(
        "this driftless was built without the `zenoh` feature: build it with \
         `cargo build --release --features zenoh` (see docs/bridge.md)",
    ))
}

/// Run the bridge until SIGINT/SIGTERM or `--duration`.
#[cfg(feature = "zenoh")]
pub fn run(args: Args) -> Result<(), CliError> {
    imp::run(args)
}

#[cfg(feature = "zenoh")]
mod imp {
    use std::time::Instant;

    use super::{Args, Mode};
    use crate::cli::CliError;
    use crate::transport;
    use crate::transport::zenoh::{
        run_bridge, BridgeError, BridgeSettings, Event, Options, Route, StreamCounts,
    };

    impl From<BridgeError> for CliError {
        fn from(e: BridgeError) -> Self {
            match e {
                BridgeError::Input(m) => CliError::input(m),
                BridgeError::Runtime(m) => CliError::internal(m),
                BridgeError::Transport(e) => e.into(),
            }
        }
    }

    pub(super) fn run(args: Args) -> Result<(), CliError> {
        transport::quiet_logging();
        let prefix = args.iceoryx2.resolve(None)?;
        let route = match (&args.from_zenoh, &args.to) {
            (Some(key), Some(service)) => Route::In {
                key: key.clone(),
                service: service.clone(),
                buffer_size: args.buffer_size,
            },
            _ => Route::Out {
                services: args.services.clone(),
                key_prefix: args.key_prefix.clone(),
            },
        };
        let settings = BridgeSettings {
            session: Options {
                config_file: args.zenoh_config.clone(),
                mode: args.mode.map(|m| match m {
                    Mode::Peer => "peer",
                    Mode::Client => "client",
                }),
                connect: args.connect.clone(),
                listen: args.listen.clone(),
                no_multicast_scouting: args.no_multicast_scouting,
            },
            route,
        };
        let stop = crate::cli::signals::stop_flag();
        let end = args.duration.map(|d| Instant::now() + d);
        let mut previous: Vec<StreamCounts> = Vec::new();
        let result = run_bridge(&settings, &prefix, &stop, end, |event| match event {
            Event::Ready(streams) => {
                let list: Vec<String> = streams
                    .iter()
                    .map(|s| format!("{} ({}) -> {}", s.from, s.type_name, s.to))
                    .collect();
                eprintln!("bridge: ready: {}", list.join(", "));
            }
            Event::Counts(streams, counts, dt) => {
                previous.resize(counts.len(), StreamCounts::default());
                for ((s, c), prev) in streams.iter().zip(counts).zip(previous.iter_mut()) {
                    eprintln!(
                        "bridge: {} -> {}: {:.1} Hz, {}",
                        s.from,
                        s.to,
                        (c.forwarded - prev.forwarded) as f64 / dt.as_secs_f64().max(1e-9),
                        s.totals(c)
                    );
                    *prev = *c;
                }
            }
            Event::Done(s, c) => {
                eprintln!("bridge: done: {} -> {}: {}", s.from, s.to, s.totals(&c))
            }
        });
        // The last process of a prefix removes its management file.
        transport::remove_prefix_leftovers(&prefix);
        result?;
        Ok(())
    }
}
