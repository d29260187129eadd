//! Everything Zenoh (feature `zenoh`): the session's configuration, a publisher and a subscriber
//! of our wire types as their documented little-endian bytes ([`crate::wire::WireBytes`]), and the
//! bridge that carries our services over them (`bridge.rs`, [`run_bridge`]; `driftless bridge`
//! is its command).
//!
//! Only the blocking API (`zenoh::Wait`): zenoh runs its own tokio runtime on its own threads,
//! so nothing here is async and no zenoh call runs on the daemon's hot thread (the bridge is a
//! separate process).

mod bridge;

pub use bridge::{run_bridge, BridgeError, BridgeSettings, Event, Route, Stream, StreamCounts};

use std::path::PathBuf;
use std::time::Duration;

use zenoh::bytes::Encoding;
use zenoh::config::{Config, EndPoint};
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::sample::Sample;
use zenoh::Wait;

/// A Zenoh key expression (zenoh's own type).
pub use zenoh::key_expr::KeyExpr;
/// A Zenoh session (zenoh's own type; cheap to clone, shared between threads).
pub use zenoh::Session;

use crate::wire::WireBytes;

/// How to configure the session: a standard Zenoh JSON5 file, then these settings over it.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// A Zenoh configuration file (JSON5), loaded with zenoh's own `Config::from_file`.
    pub config_file: Option<PathBuf>,
    /// Session mode, `peer` or `client` (default: the file's, else zenoh's default, peer).
    pub mode: Option<&'static str>,
    /// Endpoints to connect to (`tcp/192.168.1.5:7447`).
    pub connect: Vec<String>,
    /// Endpoints to listen on.
    pub listen: Vec<String>,
    /// Turn multicast scouting off (then peers find each other through the endpoints only).
    pub no_multicast_scouting: bool,
}

/// A configuration problem: bad input (exit 2), or a session that could not open (exit 1).
#[derive(Debug, thiserror::Error)]
pub enum ZenohError {
    /// A file, endpoint, key expression or setting that zenoh refuses.
    #[error("{0}")]
    Config(String),
    /// Opening the session or declaring on it failed at run time.
    #[error("{0}")]
    Runtime(String),
}

/// zenoh's errors span lines (a JSON5 parser's context) and end with the zenoh source file
/// they came from; ours are one line, about the user's input.
fn one_line(e: impl std::fmt::Display) -> String {
    let text = e
        .to_string()
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ");
    strip_source_locations(&text)
}

/// `... at /root/.cargo/registry/src/.../endpoint.rs:615.` -> `...`.
fn strip_source_locations(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(i) = rest.find(" at /") {
        let tail = &rest[i + 4..];
        let end = tail.find(".rs:").map(|j| {
            let digits = tail[j + 4..]
                .find(|c: char| !c.is_ascii_digit())
                .unwrap_or(tail.len() - j - 4);
            j + 4 + digits
        });
        match end {
            Some(end) => {
                out.push_str(&rest[..i]);
                rest = tail[end..].strip_prefix('.').unwrap_or(&tail[end..]);
            }
            None => break,
        }
    }
    out.push_str(rest);
    out.trim_end().to_string()
}

/// Line and column of a configuration file error, as json5 (`--> 4:1`) or serde
/// (`line: 1, column: 3`) give them.
fn file_position(message: &str) -> Option<(u32, u32)> {
    let number = |s: &str| -> Option<u32> {
        let end = s.find(|c: char| !c.is_ascii_digit()).unwrap_or(s.len());
        s[..end].parse().ok()
    };
    if let Some(i) = message.find("--> ") {
        let rest = &message[i + 4..];
        let line = number(rest)?;
        let col = number(&rest[rest.find(':')? + 1..])?;
        return Some((line, col));
    }
    let i = message.find("line: ")?;
    let line = number(&message[i + 6..])?;
    let j = message.find("column: ")?;
    Some((line, number(&message[j + 8..])?))
}

/// The session configuration from `opts` (the file first, then the flags over it).
pub fn config(opts: &Options) -> Result<Config, ZenohError> {
    let mut cfg = match &opts.config_file {
        Some(path) => Config::from_file(path).map_err(|e| {
            let mut message = one_line(e);
            let at = file_position(&message)
                .map(|(l, c)| format!(":{l}:{c}"))
                .unwrap_or_default();
            // json5's `--> 4:1 | 4 | } | ^--- | = expected ...`: the position is given already.
            if let Some(i) = message.rfind("| = ") {
                message = message[i + 4..].to_string();
            }
            ZenohError::Config(format!(
                "{}{at}: not a valid Zenoh configuration: {message}",
                path.display(),
            ))
        })?,
        None => Config::default(),
    };
    let mut set = |key: &str, value: String| {
        cfg.insert_json5(key, &value).map_err(|e| {
            ZenohError::Config(format!("zenoh setting {key} = {value}: {}", one_line(e)))
        })
    };
    if let Some(mode) = opts.mode {
        set("mode", format!("{mode:?}"))?;
    }
    for (what, key, list) in [
        ("--connect", "connect/endpoints", &opts.connect),
        ("--listen", "listen/endpoints", &opts.listen),
    ] {
        if list.is_empty() {
            continue;
        }
        for e in list {
            e.parse::<EndPoint>().map_err(|err| {
                ZenohError::Config(format!(
                    "{what} {e:?}: not a Zenoh endpoint ({}); expected PROTOCOL/ADDRESS, e.g. tcp/127.0.0.1:7447",
                    one_line(err)
                ))
            })?;
        }
        set(key, serde_json::to_string(list).expect("strings serialise"))?;
    }
    if opts.no_multicast_scouting {
        set("scouting/multicast/enabled", "false".into())?;
    }
    Ok(cfg)
}

/// A key expression from text, or why not.
pub fn key_expr(text: &str) -> Result<KeyExpr<'static>, ZenohError> {
    KeyExpr::try_from(text.to_string()).map_err(|e| {
        ZenohError::Config(format!(
            "{text:?} is not a Zenoh key expression: {}",
            one_line(e)
        ))
    })
}

/// Open a session (blocking).
pub fn open(cfg: Config) -> Result<Session, ZenohError> {
    zenoh::open(cfg)
        .wait()
        .map_err(|e| ZenohError::Runtime(format!("cannot open the Zenoh session: {}", one_line(e))))
}

/// Close `session`, waiting for it (its error is of no use to a process that ends).
pub fn close(session: &Session) {
    let _ = session.close().wait();
}

/// The encoding of a wire type on Zenoh: `application/octet-stream;driftless::GyroSample`.
pub fn encoding<T: WireBytes>() -> Encoding {
    Encoding::APPLICATION_OCTET_STREAM.with_schema(T::TYPE_NAME)
}

/// Puts samples of one wire type on one key expression. Congestion control `Drop`: a stalled
/// network loses samples instead of stalling the caller. Not `express`: zenoh sends small
/// messages one by one anyway and batches them only when the link pushes back; express samples
/// each take one of the link queue's two batches and are dropped after 1 ms of a busy CPU.
pub struct Sender {
    publisher: Publisher<'static>,
    buf: Vec<u8>,
}

impl Sender {
    /// Declare a publisher of `T` on `key`.
    pub fn new<T: WireBytes>(session: &Session, key: KeyExpr<'static>) -> Result<Self, ZenohError> {
        let publisher = session
            .declare_publisher(key.clone())
            .encoding(encoding::<T>())
            .congestion_control(CongestionControl::Drop)
            .wait()
            .map_err(|e| {
                ZenohError::Runtime(format!(
                    "cannot declare a publisher on {key}: {}",
                    one_line(e)
                ))
            })?;
        Ok(Sender {
            publisher,
            buf: Vec::with_capacity(T::SIZE),
        })
    }

    /// Put one sample (its wire bytes).
    pub fn put<T: WireBytes>(&mut self, sample: &T) -> Result<(), String> {
        sample.encode(&mut self.buf);
        self.publisher
            .put(self.buf.as_slice())
            .wait()
            .map_err(one_line)
    }

    /// Whether a subscriber anywhere on the Zenoh network matches this publisher's key.
    pub fn has_subscribers(&self) -> bool {
        self.publisher
            .matching_status()
            .wait()
            .map(|s| s.matching())
            .unwrap_or(false)
    }
}

/// Why a received Zenoh sample was not taken.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Rejected {
    /// The payload is not `T::SIZE` bytes.
    Size(usize),
    /// The sample's encoding names another type.
    Encoding(String),
    /// The sample's encoding names another layout version of the type (a bridge of another
    /// driftless release): the sentence of [`crate::wire::wire_version_mismatch`].
    Version(String),
}

impl std::fmt::Display for Rejected {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            // Without an encoding schema, the size is all there is to go on.
            Rejected::Size(n) => match [
                crate::wire::GYRO_V1_SIZE,
                crate::wire::GYRO_V2_SIZE,
                crate::wire::GYRO_V3_SIZE,
            ]
            .iter()
            .position(|size| size == n)
            {
                Some(i) => write!(
                    f,
                    "payload of {n} bytes, the size of {} layout v{} (from an older \
                     driftless); this driftless reads {} ({} bytes)",
                    crate::wire::GYRO_V1_TYPE_NAME,
                    i + 1,
                    crate::wire::GYRO_TYPE_NAME,
                    <crate::wire::GyroSample as WireBytes>::SIZE
                ),
                None => write!(f, "payload of {n} bytes"),
            },
            Rejected::Encoding(e) => write!(f, "encoding {e}"),
            Rejected::Version(m) => f.write_str(m),
        }
    }
}

/// Receives samples of one wire type from a key expression (a FIFO of zenoh's own).
pub struct Receiver {
    subscriber: Subscriber<FifoChannelHandler<Sample>>,
}

impl Receiver {
    /// Declare a subscriber on `key`, holding up to `capacity` samples not yet taken.
    pub fn new(
        session: &Session,
        key: KeyExpr<'static>,
        capacity: usize,
    ) -> Result<Self, ZenohError> {
        let subscriber = session
            .declare_subscriber(key.clone())
            .with(zenoh::handlers::FifoChannel::new(capacity))
            .wait()
            .map_err(|e| {
                ZenohError::Runtime(format!(
                    "cannot declare a subscriber on {key}: {}",
                    one_line(e)
                ))
            })?;
        Ok(Receiver { subscriber })
    }

    /// The next sample within `timeout`: `None` when none came, `Some(Err)` for a sample that is
    /// not a `T` (wrong size, or an encoding schema naming another type; no schema is accepted).
    pub fn recv<T: WireBytes>(&self, timeout: Duration) -> Option<Result<T, Rejected>> {
        let sample = self.subscriber.recv_timeout(timeout).ok().flatten()?;
        Some(decode_sample(&sample))
    }
}

fn decode_sample<T: WireBytes>(sample: &Sample) -> Result<T, Rejected> {
    decode_payload(&sample.encoding().to_string(), &sample.payload().to_bytes())
}

/// A `T` from a sample's encoding as text and its payload.
fn decode_payload<T: WireBytes>(enc: &str, bytes: &[u8]) -> Result<T, Rejected> {
    // Shown as `application/octet-stream;driftless::RawSample`: the schema follows the `;`.
    if let Some((_, schema)) = enc.split_once(';') {
        if schema != T::TYPE_NAME {
            return Err(
                match crate::wire::wire_version_mismatch(&format!("the sample ({enc})"), schema) {
                    Some(m) => Rejected::Version(m),
                    None => Rejected::Encoding(enc.to_string()),
                },
            );
        }
    }
    T::decode(bytes).ok_or(Rejected::Size(bytes.len()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_old_gyro_payload_is_refused_by_its_version() {
        use crate::wire::{GyroSample, GYRO_TYPE_NAME, GYRO_V1_TYPE_NAME};
        let enc = |schema: &str| {
            Encoding::APPLICATION_OCTET_STREAM
                .with_schema(schema.to_string())
                .to_string()
        };
        let why = decode_payload::<GyroSample>(&enc(GYRO_V1_TYPE_NAME), &[0; 104]).unwrap_err();
        assert!(matches!(why, Rejected::Version(_)), "{why:?}");
        assert!(
            why.to_string().starts_with(
                "the sample (application/octet-stream;driftless::GyroSample) carries \
                 driftless::GyroSample (layout v1, 104 bytes, from an older driftless)"
            ),
            "{why}"
        );
        assert!(decode_payload::<GyroSample>(&enc(GYRO_TYPE_NAME), &[0; 264]).is_ok());
        // The older layouts, by their schema and, without one, by their size.
        for (version, size) in [(3, 208), (2, 128)] {
            let name = format!("driftless::GyroSample.v{version}");
            let why = decode_payload::<GyroSample>(&enc(&name), &vec![0; size]).unwrap_err();
            assert!(
                why.to_string().contains(&format!(
                    "(layout v{version}, {size} bytes, from an older driftless)"
                )),
                "{why}"
            );
            let why = decode_payload::<GyroSample>("application/octet-stream", &vec![0; size])
                .unwrap_err();
            assert!(
                why.to_string().contains(&format!("layout v{version}")),
                "{why}"
            );
        }
        // No schema, the old size: the size says it.
        let why = decode_payload::<GyroSample>("application/octet-stream", &[0; 104]).unwrap_err();
        assert_eq!(why, Rejected::Size(104));
        assert!(why.to_string().contains("layout v1"), "{why}");
    }

    #[test]
    fn zenoh_messages_lose_their_source_file_and_keep_the_users_position() {
        assert_eq!(
            strip_source_locations(
                "Invalid Key Expr `a//b`: empty chunks at /root/.cargo/registry/src/x/borrowed.rs:777."
            ),
            "Invalid Key Expr `a//b`: empty chunks"
        );
        assert_eq!(
            strip_source_locations("form <p>/<a>: tcp at /r/endpoint.rs:615.); expected X"),
            "form <p>/<a>: tcp); expected X"
        );
        assert_eq!(
            strip_source_locations("nothing to strip at all"),
            "nothing to strip at all"
        );
        assert_eq!(
            file_position("--> 4:1 | 4 | } | ^--- | = expected array"),
            Some((4, 1))
        );
        assert_eq!(
            file_position("unknown field `moode`, location: Some(Location { line: 1, column: 3 })"),
            Some((1, 3))
        );
        assert_eq!(
            file_position("No such file or directory (os error 2)"),
            None
        );
    }
}
