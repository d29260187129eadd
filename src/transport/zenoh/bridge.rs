//! The Zenoh bridge (`driftless bridge`): our iceoryx2 services on Zenoh key expressions
//! (`driftless/<service>`), for subscribers on other machines; or raw samples from Zenoh into
//! a service an `ingest.iceoryx2` stage reads. It runs in a process of its own
//! (docs/bridge.md): to the daemon it is one more iceoryx2 subscriber (or driver), so the
//! network can never block the hot thread, and a crash of the bridge cannot touch the daemon.
//!
//! The shape of the daemon's ROS 2 side ([`crate::transport::ros2::run_bridge`]): settings in,
//! [`run_bridge`] until a stop flag, what it carried out. Its caller prints: it hears when the
//! streams are ready, their counts about once a second and each one's end ([`Event`]); news
//! of one stream (a Zenoh subscriber matches, a put failed, a payload refused) goes to stderr
//! from here, as the ROS 2 side says its own.

use std::fmt::Debug;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use super::{
    close, config, key_expr, open, KeyExpr, Options, Receiver, Sender, Session, ZenohError,
};
use crate::transport::{
    check_service_name, AnyInput, Carried, Input, Qos, Transport, TransportError, Waker, WireType,
    ZeroCopySend,
};
use crate::wire::{GyroSample, RawSample, WireBytes};

/// Which way the bridge carries samples.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Route {
    /// Our services out, each on the key expression `<key_prefix>/<service>`.
    Out {
        /// The services (of `GyroSample` or `RawSample`).
        services: Vec<String>,
        /// The key expressions' prefix (`driftless`).
        key_prefix: String,
    },
    /// `RawSample` payloads from a key expression into a service, created with the pipeline's
    /// QoS if it does not exist, so that the daemon's `ingest.iceoryx2` accepts it.
    In {
        /// The key expression.
        key: String,
        /// The service.
        service: String,
        /// The subscriber buffer of the service it creates (the pipeline's `buffer_size`).
        buffer_size: usize,
    },
}

/// What the bridge carries, and how its Zenoh session is configured.
#[derive(Debug, Clone)]
pub struct BridgeSettings {
    /// The Zenoh session.
    pub session: Options,
    /// Which way, between what.
    pub route: Route,
}

/// One stream of the bridge.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Stream {
    /// Where its samples come from: a service, or a key expression.
    pub from: String,
    /// Where they go.
    pub to: String,
    /// Their wire type's name.
    pub type_name: &'static str,
    /// From Zenoh into iceoryx2.
    pub inbound: bool,
}

/// What one stream carried.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StreamCounts {
    /// Samples forwarded.
    pub forwarded: u64,
    /// Sequence numbers missing within an epoch, before the bridge.
    pub missing: u64,
    /// Out: samples Zenoh refused to put.
    pub put_errors: u64,
    /// In: payloads that were not a `RawSample`.
    pub rejected: u64,
    /// In: samples lost by full iceoryx2 subscriber buffers.
    pub lost: u64,
}

impl Stream {
    /// What `c` says of this stream: `12 forwarded, 0 missing (sequence gaps), 0 put errors`.
    pub fn totals(&self, c: &StreamCounts) -> String {
        if self.inbound {
            format!(
                "{} forwarded, {} missing (sequence gaps), {} rejected, {} lost by full \
                 iceoryx2 buffers",
                c.forwarded, c.missing, c.rejected, c.lost
            )
        } else {
            format!(
                "{} forwarded, {} missing (sequence gaps), {} put errors",
                c.forwarded, c.missing, c.put_errors
            )
        }
    }
}

/// What the bridge tells its caller while it runs.
#[derive(Debug)]
pub enum Event<'a> {
    /// Every stream is set up.
    Ready(&'a [Stream]),
    /// About once a second: each stream's counts so far, and the time since the last.
    Counts(&'a [Stream], &'a [StreamCounts], Duration),
    /// A stream stopped: what it carried.
    Done(&'a Stream, StreamCounts),
}

/// Why the bridge did not start, or stopped.
#[derive(Debug, thiserror::Error)]
pub enum BridgeError {
    /// The user's input: a setting, a name or a service the bridge refuses.
    #[error("{0}")]
    Input(String),
    /// A failure at run time: nothing to read, a session that did not open, a stream that
    /// failed.
    #[error("{0}")]
    Runtime(String),
    /// iceoryx2 refused.
    #[error(transparent)]
    Transport(#[from] TransportError),
}

impl From<ZenohError> for BridgeError {
    fn from(e: ZenohError) -> Self {
        match e {
            ZenohError::Config(m) => BridgeError::Input(m),
            ZenohError::Runtime(m) => BridgeError::Runtime(m),
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

/// One outbound stream's counters, shared with the reporting loop.
#[derive(Default)]
struct Counters {
    forwarded: AtomicU64,
    missing: AtomicU64,
    errors: AtomicU64,
}

fn add(c: &AtomicU64, n: u64) {
    c.fetch_add(n, Ordering::Relaxed);
}

fn get(c: &AtomicU64) -> u64 {
    c.load(Ordering::Relaxed)
}

impl Counters {
    fn now(&self) -> StreamCounts {
        StreamCounts {
            forwarded: get(&self.forwarded),
            missing: get(&self.missing),
            put_errors: get(&self.errors),
            ..StreamCounts::default()
        }
    }
}

/// Run the bridge under iceoryx2 `prefix` until `stop` is set or `end` passes, telling `on`
/// what happens; returns what each stream carried. Everything the user gave (names, key
/// expressions, the session's settings) is checked before anything opens.
pub fn run_bridge(
    settings: &BridgeSettings,
    prefix: &str,
    stop: &AtomicBool,
    end: Option<Instant>,
    mut on: impl FnMut(Event<'_>),
) -> Result<Vec<StreamCounts>, BridgeError> {
    let cfg = config(&settings.session)?;
    match &settings.route {
        Route::In {
            key,
            service,
            buffer_size,
        } => {
            check_service_name(service)
                .map_err(|e| BridgeError::Input(format!("--to {service:?}: {e}")))?;
            if !(1..=65_536).contains(buffer_size) {
                return Err(BridgeError::Input(
                    "--buffer-size must be in 1..=65536".into(),
                ));
            }
            let key = key_expr(key)?;
            let session = open(cfg)?;
            let inbound = Inbound {
                prefix,
                key,
                service,
                buffer_size: *buffer_size,
            };
            let r = inbound.run(&session, stop, end, &mut on);
            close(&session);
            r
        }
        Route::Out {
            services,
            key_prefix,
        } => {
            let mut keys = Vec::new();
            for s in services {
                check_service_name(s)
                    .map_err(|e| BridgeError::Input(format!("invalid service name {s:?}: {e}")))?;
                let key = format!("{}/{}", key_prefix.trim_end_matches('/'), s);
                keys.push((s.clone(), key_expr(&key)?));
            }
            let session = open(cfg)?;
            let r = forward(prefix, &session, keys, stop, end, &mut on);
            close(&session);
            r
        }
    }
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

/// The outcome of one stream's set-up: its type's name, or why not.
type SetUp = Result<&'static str, BridgeError>;

/// iceoryx2 -> Zenoh: one thread per service (iceoryx2 ports are not Send), each its own node
/// and its own Zenoh publisher on the shared session.
fn forward(
    prefix: &str,
    session: &Session,
    keys: Vec<(String, KeyExpr<'static>)>,
    stop: &AtomicBool,
    end: Option<Instant>,
    on: &mut impl FnMut(Event<'_>),
) -> Result<Vec<StreamCounts>, BridgeError> {
    let counters: Vec<Counters> = keys.iter().map(|_| Counters::default()).collect();
    std::thread::scope(|scope| {
        let mut streams = Vec::new();
        let mut handles = Vec::new();
        let mut setup_error = None;
        for ((service, key), c) in keys.into_iter().zip(&counters) {
            let (tx, rx) = mpsc::channel::<SetUp>();
            let (shown, s, sess) = (key.to_string(), service.clone(), session.clone());
            let spawned = std::thread::Builder::new()
                .name(format!("bridge {service}"))
                .spawn_scoped(scope, move || {
                    forward_one(prefix, &s, key, &sess, c, stop, tx)
                });
            let handle = match spawned {
                Ok(h) => h,
                Err(e) => {
                    setup_error = Some(BridgeError::Runtime(format!("cannot start a thread: {e}")));
                    break;
                }
            };
            match rx.recv() {
                Ok(Ok(type_name)) => {
                    streams.push(Stream {
                        from: service,
                        to: shown,
                        type_name,
                        inbound: false,
                    });
                    handles.push(handle);
                }
                Ok(Err(e)) => {
                    let _ = handle.join();
                    setup_error = Some(e);
                    break;
                }
                Err(_) => {
                    let r = handle.join();
                    setup_error = Some(BridgeError::Runtime(format!(
                        "{service}: the bridge thread ended during set-up: {r:?}"
                    )));
                    break;
                }
            }
        }
        if let Some(e) = setup_error {
            stop.store(true, Ordering::Relaxed);
            for h in handles {
                let _ = h.join();
            }
            return Err(e);
        }
        on(Event::Ready(&streams));
        let mut tick = Instant::now();
        while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| Instant::now() < e) {
            nap(Duration::from_secs(1), stop, end);
            if handles.iter().any(|h| h.is_finished()) {
                break;
            }
            let counts: Vec<StreamCounts> = counters.iter().map(Counters::now).collect();
            on(Event::Counts(&streams, &counts, tick.elapsed()));
            tick = Instant::now();
        }
        stop.store(true, Ordering::Relaxed);
        let mut failure = None;
        let mut carried = Vec::new();
        for ((s, h), c) in streams.iter().zip(handles).zip(&counters) {
            let r = h.join();
            carried.push(c.now());
            on(Event::Done(s, c.now()));
            match r {
                Ok(Ok(())) => {}
                Ok(Err(e)) => failure = Some(BridgeError::Runtime(format!("{}: {e}", s.from))),
                Err(_) => {
                    failure = Some(BridgeError::Runtime(format!("{}: thread panicked", s.from)))
                }
            }
        }
        failure.map_or(Ok(carried), Err)
    })
}

/// Set up one service (reporting the outcome on `ready`), then pump it until `stop`.
fn forward_one(
    prefix: &str,
    service: &str,
    key: KeyExpr<'static>,
    session: &Session,
    counters: &Counters,
    stop: &AtomicBool,
    ready: mpsc::Sender<SetUp>,
) -> Result<(), String> {
    let node = match Transport::new(prefix, "driftless-bridge", Qos::default()) {
        Ok(n) => n,
        Err(e) => {
            let _ = ready.send(Err(e.into()));
            return Ok(());
        }
    };
    let waker = node.existing_waker(service).ok().flatten();
    let refused = match node.carried(service) {
        Ok(Carried::Ours(w @ (WireType::Gyro | WireType::Raw | WireType::Stats))) => {
            match node.open_any(service, w) {
                Ok(AnyInput::Gyro(input)) => {
                    return pump(&input, waker.as_ref(), session, key, counters, stop, ready)
                }
                Ok(AnyInput::Raw(input)) => {
                    return pump(&input, waker.as_ref(), session, key, counters, stop, ready)
                }
                Ok(AnyInput::Stats(_)) => Some(BridgeError::Input(format!(
                    "{service} carries statistics snapshots, which the bridge does not carry \
                     (bridge the samples; `driftless stats` reads the snapshots)"
                ))),
                _ => None,
            }
        }
        Ok(Carried::OtherVersion(m)) => Some(BridgeError::Input(m)),
        _ => None,
    };
    // Nothing to read is a run-time failure (exit 1), as for `tap`.
    let _ = ready.send(Err(refused.unwrap_or_else(|| {
        BridgeError::Runtime(format!(
            "no service {service:?} of a driftless sample type under prefix {prefix:?} (is the \
             pipeline running?)"
        ))
    })));
    Ok(())
}

/// Put every sample of `input` on `key` until `stop`.
fn pump<T: WireBytes + Stamped + Debug + ZeroCopySend + Copy + 'static>(
    input: &Input<T>,
    waker: Option<&Waker>,
    session: &Session,
    key: KeyExpr<'static>,
    c: &Counters,
    stop: &AtomicBool,
    ready: mpsc::Sender<SetUp>,
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
                add(&c.missing, gaps.missing(s.stamp()));
                match sender.put(&s) {
                    Ok(()) => add(&c.forwarded, 1),
                    Err(e) => {
                        add(&c.errors, 1);
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
                    eprintln!(
                        "bridge: {shown}: no Zenoh subscriber any more (samples are put and \
                         dropped)"
                    );
                }
            }
        }
    }
    Ok(())
}

/// Zenoh -> iceoryx2: `RawSample` payloads from `key` onto `service`.
struct Inbound<'a> {
    prefix: &'a str,
    key: KeyExpr<'static>,
    service: &'a str,
    buffer_size: usize,
}

impl Inbound<'_> {
    fn run(
        &self,
        session: &Session,
        stop: &AtomicBool,
        end: Option<Instant>,
        on: &mut impl FnMut(Event<'_>),
    ) -> Result<Vec<StreamCounts>, BridgeError> {
        let (key, service) = (&self.key, self.service);
        let qos = Qos {
            buffer_size: self.buffer_size,
            ..Qos::default()
        };
        let node = Transport::new(self.prefix, "driftless-bridge", qos)?;
        let output = node
            .external_output::<RawSample>(service, true)
            .map_err(|e| BridgeError::Runtime(e.to_string()))?;
        let receiver = Receiver::new(session, key.clone(), self.buffer_size)?;
        let stream = [Stream {
            from: key.to_string(),
            to: service.to_string(),
            type_name: RawSample::TYPE_NAME,
            inbound: true,
        }];
        on(Event::Ready(&stream));
        let mut c = StreamCounts::default();
        let mut gaps = Gaps::default();
        let mut tick = Instant::now();
        while !stop.load(Ordering::Relaxed) && end.is_none_or(|e| Instant::now() < e) {
            match receiver.recv::<RawSample>(Duration::from_millis(20)) {
                Some(Ok(s)) => {
                    c.missing += gaps.missing(s.stamp());
                    output
                        .send(&s)
                        .map_err(|e| BridgeError::Runtime(format!("{service}: {e}")))?;
                    output.notify();
                    c.forwarded += 1;
                }
                Some(Err(why)) => {
                    if c.rejected == 0 {
                        eprintln!(
                            "bridge: {key}: not a {} ({why}; {} bytes expected): not published",
                            RawSample::TYPE_NAME,
                            RawSample::SIZE
                        );
                    }
                    c.rejected += 1;
                }
                None => {}
            }
            if tick.elapsed() >= Duration::from_secs(1) {
                c.lost = output.lost();
                on(Event::Counts(&stream, &[c], tick.elapsed()));
                tick = Instant::now();
            }
        }
        c.lost = output.lost();
        on(Event::Done(&stream[0], c));
        Ok(vec![c])
    }
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

    #[test]
    fn each_direction_says_its_own_counts() {
        let c = StreamCounts {
            forwarded: 5,
            missing: 1,
            put_errors: 2,
            rejected: 3,
            lost: 4,
        };
        let mut s = Stream {
            from: "t/corrected".into(),
            to: "driftless/t/corrected".into(),
            type_name: "driftless::GyroSample.v2",
            inbound: false,
        };
        assert_eq!(
            s.totals(&c),
            "5 forwarded, 1 missing (sequence gaps), 2 put errors"
        );
        s.inbound = true;
        assert_eq!(
            s.totals(&c),
            "5 forwarded, 1 missing (sequence gaps), 3 rejected, 4 lost by full iceoryx2 buffers"
        );
    }
}
