//! `driftless bridge SERVICE...`: our iceoryx2 services on Zenoh key expressions
//! (`driftless/<service>`), for subscribers on other machines; and `--from-zenoh KEY --to
//! SERVICE`, raw samples from Zenoh into a service `ingest.iceoryx2` reads. A separate process
//! (docs/bridge.md): to the daemon it is one more iceoryx2 subscriber, so the network can never
//! block the hot thread, and a crash of the bridge cannot touch the daemon.
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
    use std::fmt::Debug;
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::sync::{mpsc, Arc};
    use std::time::{Duration, Instant};

    use super::{Args, Mode};
    use crate::cli::CliError;
    use crate::transport::zenoh::{self as z, KeyExpr, Receiver, Sender, Session, ZenohError};
    use crate::transport::{
        self, GyroSample, Input, Qos, RawSample, StatsSnapshot, Transport, Waker, WireBytes,
        ZeroCopySend,
    };

    impl From<ZenohError> for CliError {
        fn from(e: ZenohError) -> Self {
            match e {
                ZenohError::Config(m) => CliError::input(m),
                ZenohError::Runtime(m) => CliError::internal(m),
            }
        }
    }

    /// A sample with a place in its stream: (epoch, seq).
    trait Stamped {
        fn stamp(&self) -> (u32, u64);
    }

    impl Stamped for GyroSample {
        fn stamp(&self) -> (u32, u64) {
            (self.epoch, self.seq)
        }
    }

    impl Stamped for RawSample {
        fn stamp(&self) -> (u32, u64) {
            (self.epoch, self.seq)
        }
    }

    /// Sequence numbers missing within an epoch (a new epoch starts counting again).
    #[derive(Default)]
    struct Gaps {
        last: Option<(u32, u64)>,
    }

    impl Gaps {
        fn missing(&mut self, (epoch, seq): (u32, u64)) -> u64 {
            let n = match self.last {
                Some((e, s)) if e == epoch && seq > s + 1 => seq - s - 1,
                _ => 0,
            };
            self.last = Some((epoch, seq));
            n
        }
    }

    /// One bridged stream's counters, shared with the reporting loop.
    #[derive(Default)]
    struct Counters {
        forwarded: AtomicU64,
        missing: AtomicU64,
        errors: AtomicU64,
        /// Zenoh -> iceoryx2 only: payloads that were not a RawSample.
        rejected: AtomicU64,
    }

    impl Counters {
        fn add(c: &AtomicU64, n: u64) {
            c.fetch_add(n, Ordering::Relaxed);
        }
        fn get(c: &AtomicU64) -> u64 {
            c.load(Ordering::Relaxed)
        }
    }

    pub(super) fn run(args: Args) -> Result<(), CliError> {
        transport::quiet_logging();
        let prefix = args.iceoryx2.resolve(None)?;
        let opts = z::Options {
            config_file: args.zenoh_config.clone(),
            mode: args.mode.map(|m| match m {
                Mode::Peer => "peer",
                Mode::Client => "client",
            }),
            connect: args.connect.clone(),
            listen: args.listen.clone(),
            no_multicast_scouting: args.no_multicast_scouting,
        };
        // Everything the user typed is checked before anything opens.
        let cfg = z::config(&opts)?;
        let stop = crate::cli::signals::stop_flag();
        let result = match (&args.from_zenoh, &args.to) {
            (Some(key), Some(service)) => {
                transport::check_service_name(service)
                    .map_err(|e| CliError::input(format!("--to {service:?}: {e}")))?;
                if !(1..=65_536).contains(&args.buffer_size) {
                    return Err(CliError::input("--buffer-size must be in 1..=65536"));
                }
                let key = z::key_expr(key)?;
                let session = z::open(cfg)?;
                let r = reverse(&args, &prefix, &session, key, service, &stop);
                z::close(&session);
                r
            }
            _ => {
                let mut keys = Vec::new();
                for s in &args.services {
                    transport::check_service_name(s)
                        .map_err(|e| CliError::input(format!("invalid service name {s:?}: {e}")))?;
                    let key = format!("{}/{}", args.key_prefix.trim_end_matches('/'), s);
                    keys.push((s.clone(), z::key_expr(&key)?));
                }
                let session = z::open(cfg)?;
                let r = forward(&args, &prefix, &session, keys, &stop);
                z::close(&session);
                r
            }
        };
        // The last process of a prefix removes its management file.
        transport::remove_prefix_leftovers(&prefix);
        result
    }

    /// Sleep `period` in small steps, or less if `stop` is set.
    fn nap(period: Duration, stop: &AtomicBool, end: Option<Instant>) {
        let until = Instant::now() + period;
        while Instant::now() < until
            && !stop.load(Ordering::Relaxed)
            && end.is_none_or(|e| Instant::now() < e)
        {
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    struct Stream {
        service: String,
        key: String,
        type_name: &'static str,
        counters: Arc<Counters>,
        handle: std::thread::JoinHandle<Result<(), String>>,
    }

    /// iceoryx2 -> Zenoh: one thread per service (iceoryx2 ports are not Send), each its own
    /// node and its own Zenoh publisher on the shared session.
    fn forward(
        args: &Args,
        prefix: &str,
        session: &Session,
        keys: Vec<(String, KeyExpr<'static>)>,
        stop: &Arc<AtomicBool>,
    ) -> Result<(), CliError> {
        let mut streams = Vec::new();
        let mut setup_error = None;
        for (service, key) in keys {
            let counters = Arc::new(Counters::default());
            let (tx, rx) = mpsc::channel::<Result<&'static str, CliError>>();
            let (p, s, k, c, st, sess) = (
                prefix.to_string(),
                service.clone(),
                key.clone(),
                Arc::clone(&counters),
                Arc::clone(stop),
                session.clone(),
            );
            let handle = std::thread::Builder::new()
                .name(format!("bridge {service}"))
                .spawn(move || forward_one(&p, &s, k, &sess, &c, &st, tx))
                .map_err(|e| CliError::internal(format!("cannot start a thread: {e}")))?;
            match rx.recv() {
                Ok(Ok(type_name)) => streams.push(Stream {
                    service,
                    key: key.to_string(),
                    type_name,
                    counters,
                    handle,
                }),
                Ok(Err(e)) => {
                    let _ = handle.join();
                    setup_error = Some(e);
                    break;
                }
                Err(_) => {
                    let r = handle.join();
                    setup_error = Some(CliError::internal(format!(
                        "{service}: the bridge thread ended during set-up: {r:?}"
                    )));
                    break;
                }
            }
        }
        if let Some(e) = setup_error {
            stop.store(true, Ordering::Relaxed);
            for s in streams {
                let _ = s.handle.join();
            }
            return Err(e);
        }
        let list: Vec<String> = streams
            .iter()
            .map(|s| format!("{} ({}) -> {}", s.service, s.type_name, s.key))
            .collect();
        eprintln!("bridge: ready: {}", list.join(", "));
        let end = args.duration.map(|d| Instant::now() + d);
        let mut previous: Vec<u64> = vec![0; streams.len()];
        let mut tick = Instant::now();
        while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| Instant::now() < e) {
            nap(Duration::from_secs(1), stop, end);
            if streams.iter().any(|s| s.handle.is_finished()) {
                break;
            }
            let dt = tick.elapsed().as_secs_f64();
            tick = Instant::now();
            for (s, prev) in streams.iter().zip(previous.iter_mut()) {
                let n = Counters::get(&s.counters.forwarded);
                eprintln!(
                    "bridge: {} -> {}: {:.1} Hz, {}",
                    s.service,
                    s.key,
                    (n - *prev) as f64 / dt.max(1e-9),
                    totals(&s.counters)
                );
                *prev = n;
            }
        }
        stop.store(true, Ordering::Relaxed);
        let mut failure = None;
        for s in streams {
            let r = s.handle.join();
            eprintln!(
                "bridge: done: {} -> {}: {}",
                s.service,
                s.key,
                totals(&s.counters)
            );
            match r {
                Ok(Ok(())) => {}
                Ok(Err(e)) => failure = Some(CliError::internal(format!("{}: {e}", s.service))),
                Err(_) => {
                    failure = Some(CliError::internal(format!(
                        "{}: thread panicked",
                        s.service
                    )))
                }
            }
        }
        failure.map_or(Ok(()), Err)
    }

    fn totals(c: &Counters) -> String {
        format!(
            "{} forwarded, {} missing (sequence gaps), {} put errors",
            Counters::get(&c.forwarded),
            Counters::get(&c.missing),
            Counters::get(&c.errors)
        )
    }

    /// Set up one service (reporting the outcome on `ready`), then pump it until `stop`.
    fn forward_one(
        prefix: &str,
        service: &str,
        key: KeyExpr<'static>,
        session: &Session,
        counters: &Counters,
        stop: &AtomicBool,
        ready: mpsc::Sender<Result<&'static str, CliError>>,
    ) -> Result<(), String> {
        let node = match Transport::new(prefix, "driftless-bridge", Qos::default()) {
            Ok(n) => n,
            Err(e) => {
                let _ = ready.send(Err(CliError::from(e)));
                return Ok(());
            }
        };
        let waker = node.existing_waker(service).ok().flatten();
        if let Ok(input) = node.open_input::<GyroSample>(service) {
            pump(&input, waker.as_ref(), session, key, counters, stop, ready)
        } else if let Ok(input) = node.open_input::<RawSample>(service) {
            pump(&input, waker.as_ref(), session, key, counters, stop, ready)
        } else if node.open_input::<StatsSnapshot>(service).is_ok() {
            let _ = ready.send(Err(CliError::input(format!(
                "{service} carries statistics snapshots, which the bridge does not carry \
                 (bridge the samples; `driftless stats` reads the snapshots)"
            ))));
            Ok(())
        } else if let Some(m) = node.version_mismatch(service) {
            let _ = ready.send(Err(CliError::input(m)));
            Ok(())
        } else {
            // Nothing to read is a run-time failure (exit 1), as for `tap`.
            let _ = ready.send(Err(CliError::internal(format!(
                "no service {service:?} of a driftless sample type under prefix {prefix:?} \
                 (is the pipeline running?)"
            ))));
            Ok(())
        }
    }

    fn pump<T: WireBytes + Stamped + Debug + ZeroCopySend + Copy + 'static>(
        input: &Input<T>,
        waker: Option<&Waker>,
        session: &Session,
        key: KeyExpr<'static>,
        c: &Counters,
        stop: &AtomicBool,
        ready: mpsc::Sender<Result<&'static str, CliError>>,
    ) -> Result<(), String> {
        let shown = key.to_string();
        let mut sender = match Sender::new::<T>(session, key) {
            Ok(s) => s,
            Err(e) => {
                let _ = ready.send(Err(e.into()));
                return Ok(());
            }
        };
        let _ = ready.send(Ok(T::TYPE_NAME));
        let mut gaps = Gaps::default();
        let mut matched = false;
        let mut checked = Instant::now() - Duration::from_secs(1);
        let mut last_error: Option<String> = None;
        while !stop.load(Ordering::Relaxed) {
            match input.receive() {
                Ok(Some(s)) => {
                    Counters::add(&c.missing, gaps.missing(s.stamp()));
                    match sender.put(&s) {
                        Ok(()) => Counters::add(&c.forwarded, 1),
                        Err(e) => {
                            Counters::add(&c.errors, 1);
                            if last_error.as_ref() != Some(&e) {
                                eprintln!("bridge: {shown}: put failed: {e}");
                                last_error = Some(e);
                            }
                        }
                    }
                }
                // The daemon notifies the services it publishes for other processes (e.g. the
                // corrected one); the others are polled.
                Ok(None) => match waker {
                    Some(w) => {
                        let _ = w.wait(Duration::from_millis(10));
                    }
                    None => std::thread::sleep(Duration::from_micros(500)),
                },
                Err(e) => return Err(e.to_string()),
            }
            // Whether anyone listens is news for whoever runs the bridge.
            if checked.elapsed() >= Duration::from_millis(100) {
                checked = Instant::now();
                let now = sender.has_subscribers();
                if now != matched {
                    matched = now;
                    if now {
                        eprintln!("bridge: {shown}: a Zenoh subscriber matches");
                    } else {
                        eprintln!("bridge: {shown}: no Zenoh subscriber any more (samples are put and dropped)");
                    }
                }
            }
        }
        Ok(())
    }

    /// Zenoh -> iceoryx2: RawSample payloads from `key` onto `service` (created with the
    /// pipeline's QoS if it does not exist, so the daemon's `ingest.iceoryx2` accepts it).
    fn reverse(
        args: &Args,
        prefix: &str,
        session: &Session,
        key: KeyExpr<'static>,
        service: &str,
        stop: &AtomicBool,
    ) -> Result<(), CliError> {
        let qos = Qos {
            buffer_size: args.buffer_size,
            ..Qos::default()
        };
        let node = Transport::new(prefix, "driftless-bridge", qos)?;
        let output = node
            .external_output::<RawSample>(service, true)
            .map_err(|e| CliError::internal(e.to_string()))?;
        let receiver = Receiver::new(session, key.clone(), args.buffer_size)?;
        eprintln!(
            "bridge: ready: {key} ({}) -> {service}",
            RawSample::TYPE_NAME
        );
        let c = Counters::default();
        let mut gaps = Gaps::default();
        let end = args.duration.map(|d| Instant::now() + d);
        let (mut tick, mut prev) = (Instant::now(), 0u64);
        let line = |c: &Counters, lost: u64| {
            format!(
                "{} forwarded, {} missing (sequence gaps), {} rejected, {} lost by full iceoryx2 buffers",
                Counters::get(&c.forwarded),
                Counters::get(&c.missing),
                Counters::get(&c.rejected),
                lost
            )
        };
        while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| Instant::now() < e) {
            match receiver.recv::<RawSample>(Duration::from_millis(20)) {
                Some(Ok(s)) => {
                    Counters::add(&c.missing, gaps.missing(s.stamp()));
                    output
                        .send(&s)
                        .map_err(|e| CliError::internal(format!("{service}: {e}")))?;
                    output.notify();
                    Counters::add(&c.forwarded, 1);
                }
                Some(Err(why)) => {
                    if Counters::get(&c.rejected) == 0 {
                        eprintln!(
                            "bridge: {key}: not a {} ({why}; {} bytes expected): not published",
                            RawSample::TYPE_NAME,
                            RawSample::SIZE
                        );
                    }
                    Counters::add(&c.rejected, 1);
                }
                None => {}
            }
            if tick.elapsed() >= Duration::from_secs(1) {
                let n = Counters::get(&c.forwarded);
                eprintln!(
                    "bridge: {key} -> {service}: {:.1} Hz, {}",
                    (n - prev) as f64 / tick.elapsed().as_secs_f64(),
                    line(&c, output.lost())
                );
                (tick, prev) = (Instant::now(), n);
            }
        }
        eprintln!(
            "bridge: done: {key} -> {service}: {}",
            line(&c, output.lost())
        );
        Ok(())
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        #[test]
        fn gaps_count_within_an_epoch_and_restart_with_a_new_one() {
            let mut g = Gaps::default();
            assert_eq!(g.missing((1, 5)), 0, "the first sample starts the count");
            assert_eq!(g.missing((1, 6)), 0);
            assert_eq!(g.missing((1, 9)), 2);
            assert_eq!(g.missing((2, 0)), 0, "a new epoch starts again");
            assert_eq!(g.missing((2, 3)), 2);
        }
    }
}
