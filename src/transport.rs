//! Everything iceoryx2: the wire types, the quality of service, node set-up, ports.
//!
//! This is the only module that imports `iceoryx2` (and its submodule `zenoh` the only one that
//! imports `zenoh`, feature `zenoh`); the rest of the crate sees plain Rust types
//! ([`RawSample`], [`GyroSample`], [`StatsSnapshot`]) and the small port wrappers below.
//!
//! # Wire types
//! All are `#[repr(C)]`, contain only `u64`/`u32`/`f64`/`u8` fields with no implicit padding,
//! and carry a stable iceoryx2 type name so that C, C++ or Python subscribers can open the
//! services with iceoryx2's own bindings. The byte layouts are documented on each type and in
//! the README.
//!
//! # Quality of service
//! One definition ([`Qos`]) is used for every service the daemon creates: history 0, safe
//! overflow off, a publisher never blocks (backpressure strategy `DiscardData`): a subscriber
//! whose buffer is full loses the new sample (it keeps the older ones it has not read) and the
//! publisher counts the loss ([`Output::lost`]: subscribers registered minus served). Readers of our services open them without requirements, so they never
//! conflict with the creator's settings.

use std::fmt::Debug;
use std::os::fd::AsRawFd as _;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use iceoryx2::node::NodeView;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections as _;
use iceoryx2::prelude::*;

/// iceoryx2's marker of a type that can live in shared memory (our wire types derive it); for
/// code generic over them.
pub use iceoryx2::prelude::ZeroCopySend;

#[cfg(feature = "zenoh")]
pub mod zenoh;

/// The iceoryx2 service flavour used everywhere: inter-process, even inside one process
/// (`local` lost wake-ups at high rates on our machines).
type Svc = ipc::Service;

type PubSubFactory<T> = iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, T, ()>;

/// Default iceoryx2 prefix of the daemon's files in `/dev/shm` and `/tmp/iceoryx2`.
pub const DEFAULT_PREFIX: &str = "driftless_";

/// Environment variable that overrides the iceoryx2 prefix (tests give each run its own).
pub const PREFIX_ENV: &str = "DRIFTLESS_IOX2_PREFIX";

/// iceoryx2's own root directory (its node and service files) on Linux, used unless
/// [`set_root`] says otherwise. The shared memory itself is in `/dev/shm` either way.
pub const DEFAULT_ROOT: &str = "/tmp/iceoryx2";

/// Environment variable that sets iceoryx2's root directory (overrides the pipeline's
/// `[iceoryx2] root_path`; `--root-path` overrides it).
pub const ROOT_ENV: &str = "DRIFTLESS_IOX2_ROOT";

/// The root directory every node of this process uses (`None`: [`DEFAULT_ROOT`]).
static ROOT: std::sync::RwLock<Option<std::path::PathBuf>> = std::sync::RwLock::new(None);

/// Raw-sample flag: the sensor driver marks the sample as invalid.
pub const RAW_INVALID: u32 = 1;

/// Output flag: a stage is still filling (denoiser window, predictor warm-up).
pub const FLAG_WARMING_UP: u32 = 1;
/// Output flag: the input was NaN/Inf or marked invalid; the last valid value was held.
pub const FLAG_INPUT_INVALID: u32 = 1 << 1;
/// Output flag: one or more sequence numbers are missing before this sample.
pub const FLAG_GAP_BEFORE: u32 = 1 << 2;
/// Output flag: the sensor timestamp went backwards at this sample.
pub const FLAG_TIME_BACKWARDS: u32 = 1 << 3;
/// Output flag: emitted while draining at shutdown (a lagged stage's held samples).
pub const FLAG_FLUSHED: u32 = 1 << 4;
/// Output flag: a non-finite value was produced by a stage and replaced by 0 before publishing.
pub const FLAG_OUTPUT_REPAIRED: u32 = 1 << 5;
/// Output flag (`predict.rbf`): every axis judged still; the drift model was re-anchored on the
/// measured drift.
pub const FLAG_STILL: u32 = 1 << 6;
/// Output flag (`predict.rbf`): an axis judged moving; its drift model runs on its own
/// predictions, so the rotation is not subtracted.
pub const FLAG_MOVING: u32 = 1 << 7;

/// The output flags by name, in bit order (`tap`, `record` and reports decode them with it).
pub const FLAG_NAMES: [(u32, &str); 8] = [
    (FLAG_WARMING_UP, "warming_up"),
    (FLAG_INPUT_INVALID, "input_invalid"),
    (FLAG_GAP_BEFORE, "gap_before"),
    (FLAG_TIME_BACKWARDS, "time_backwards"),
    (FLAG_FLUSHED, "flushed"),
    (FLAG_OUTPUT_REPAIRED, "output_repaired"),
    (FLAG_STILL, "still"),
    (FLAG_MOVING, "moving"),
];

/// Names of the flags set in `flags` ([`FLAG_NAMES`]); a bit without a name reads as its hex
/// value, so nothing is hidden.
pub fn flag_names(flags: u32) -> Vec<String> {
    let mut names = Vec::new();
    let mut rest = flags;
    for (bit, name) in FLAG_NAMES {
        if flags & bit != 0 {
            names.push(name.to_string());
            rest &= !bit;
        }
    }
    for i in 0..32 {
        if rest & (1 << i) != 0 {
            names.push(format!("{:#x}", 1u32 << i));
        }
    }
    names
}

/// Type name of [`RawSample`] on the wire.
pub const RAW_TYPE_NAME: &str = "driftless::RawSample";
/// Type name of [`GyroSample`] on the wire.
pub const GYRO_TYPE_NAME: &str = "driftless::GyroSample";
/// Type name of [`StatsSnapshot`] on the wire.
pub const STATS_TYPE_NAME: &str = "driftless::StatsSnapshot";

/// A raw gyro sample as a sensor driver publishes it (48 bytes, 8-byte aligned).
///
/// | offset | type | field |
/// |---:|---|---|
/// | 0 | u64 | `t_ns` sensor timestamp, ns |
/// | 8 | u64 | `seq` sequence number |
/// | 16 | `[f64; 3]` | `rate` x, y, z in the pipeline's `input_units` |
/// | 40 | u32 | `flags` (bit 0: [`RAW_INVALID`]) |
/// | 44 | u32 | `epoch` the publisher's run id (see [`GyroSample::epoch`]); a driver may leave it 0 |
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
#[type_name("driftless::RawSample")]
pub struct RawSample {
    /// Sensor timestamp in nanoseconds (any epoch, monotonic per sensor).
    pub t_ns: u64,
    /// Sequence number, +1 per sample; a jump is a gap.
    pub seq: u64,
    /// Angular rate per axis, in the pipeline's input units.
    pub rate: [f64; 3],
    /// Validity flags (bit 0: invalid).
    pub flags: u32,
    /// The publisher's run id: when it changes, `seq` starts again (see [`GyroSample::epoch`]).
    /// A driver that sets it (any non-zero value per driver start) lets the daemon tell a
    /// driver restart from lost samples; 0 means "not given".
    pub epoch: u32,
}

/// A processed gyro sample: every hop after the ingest carries one (104 bytes, 8-byte aligned).
///
/// | offset | type | field |
/// |---:|---|---|
/// | 0 | u64 | `t_ns` sensor timestamp of this sample, ns |
/// | 8 | u64 | `seq` sequence number, unchanged from the raw sample |
/// | 16 | u64 | `ingest_ns` CLOCK_MONOTONIC ns when the sample completing this output was ingested |
/// | 24 | `[f64; 3]` | `rate` corrected rate, rad/s (= denoised - drift) |
/// | 48 | `[f64; 3]` | `drift` drift estimate, rad/s |
/// | 72 | `[f64; 3]` | `denoised` denoised rate, rad/s |
/// | 96 | u32 | `flags` ([`FLAG_WARMING_UP`], [`FLAG_INPUT_INVALID`], ...) |
/// | 100 | u32 | `epoch` the stream's run id: `seq` counts within one epoch |
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
#[type_name("driftless::GyroSample")]
pub struct GyroSample {
    /// Sensor timestamp of this sample in nanoseconds.
    pub t_ns: u64,
    /// Sequence number, passed through every stage unchanged.
    pub seq: u64,
    /// CLOCK_MONOTONIC nanoseconds at the ingest of the sample that completed this output
    /// (see [`monotonic_ns`]); a subscriber on the same host measures its latency from it.
    pub ingest_ns: u64,
    /// Corrected angular rate, rad/s.
    pub rate: [f64; 3],
    /// Drift estimate removed from `denoised`, rad/s.
    pub drift: [f64; 3],
    /// Denoised angular rate, rad/s.
    pub denoised: [f64; 3],
    /// Flags, see the `FLAG_*` constants.
    pub flags: u32,
    /// The stream's run id, never 0 from the daemon: random at each daemon start, +1 whenever
    /// the source restarts (a driver's own `epoch` changes, or its `seq` returns to 0). `seq`
    /// counts within one epoch: a subscriber that sees the epoch change starts counting again,
    /// instead of taking the new run's samples for duplicates or reordered ones.
    pub epoch: u32,
}

/// A sample type that crosses a network as its documented little-endian bytes: the same layout
/// as in shared memory (`repr(C)`, no padding), written field by field so that it holds on any
/// host. What `driftless bridge` puts on Zenoh and takes back (docs/bridge.md).
pub trait WireBytes: Sized {
    /// Size of the encoded sample in bytes (its `size_of`).
    const SIZE: usize;
    /// The type name, as on iceoryx2 ([`RAW_TYPE_NAME`], [`GYRO_TYPE_NAME`]).
    const TYPE_NAME: &'static str;
    /// Append the sample's bytes to `out` (cleared first).
    fn encode(&self, out: &mut Vec<u8>);
    /// The sample from exactly [`WireBytes::SIZE`] bytes; `None` for any other length.
    fn decode(bytes: &[u8]) -> Option<Self>;
}

/// Little-endian reader over a byte slice of known length.
struct Le<'a>(&'a [u8]);

impl Le<'_> {
    fn u64(&mut self) -> u64 {
        let (head, rest) = self.0.split_at(8);
        self.0 = rest;
        u64::from_le_bytes(head.try_into().expect("8 bytes"))
    }
    fn u32(&mut self) -> u32 {
        let (head, rest) = self.0.split_at(4);
        self.0 = rest;
        u32::from_le_bytes(head.try_into().expect("4 bytes"))
    }
    fn f64x3(&mut self) -> [f64; 3] {
        [(); 3].map(|_| f64::from_bits(self.u64()))
    }
}

fn put_f64x3(out: &mut Vec<u8>, v: &[f64; 3]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

impl WireBytes for RawSample {
    const SIZE: usize = 48;
    const TYPE_NAME: &'static str = RAW_TYPE_NAME;

    fn encode(&self, out: &mut Vec<u8>) {
        out.clear();
        out.extend_from_slice(&self.t_ns.to_le_bytes());
        out.extend_from_slice(&self.seq.to_le_bytes());
        put_f64x3(out, &self.rate);
        out.extend_from_slice(&self.flags.to_le_bytes());
        out.extend_from_slice(&self.epoch.to_le_bytes());
    }

    fn decode(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != Self::SIZE {
            return None;
        }
        let mut r = Le(bytes);
        Some(RawSample {
            t_ns: r.u64(),
            seq: r.u64(),
            rate: r.f64x3(),
            flags: r.u32(),
            epoch: r.u32(),
        })
    }
}

impl WireBytes for GyroSample {
    const SIZE: usize = 104;
    const TYPE_NAME: &'static str = GYRO_TYPE_NAME;

    fn encode(&self, out: &mut Vec<u8>) {
        out.clear();
        out.extend_from_slice(&self.t_ns.to_le_bytes());
        out.extend_from_slice(&self.seq.to_le_bytes());
        out.extend_from_slice(&self.ingest_ns.to_le_bytes());
        put_f64x3(out, &self.rate);
        put_f64x3(out, &self.drift);
        put_f64x3(out, &self.denoised);
        out.extend_from_slice(&self.flags.to_le_bytes());
        out.extend_from_slice(&self.epoch.to_le_bytes());
    }

    fn decode(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != Self::SIZE {
            return None;
        }
        let mut r = Le(bytes);
        Some(GyroSample {
            t_ns: r.u64(),
            seq: r.u64(),
            ingest_ns: r.u64(),
            rate: r.f64x3(),
            drift: r.f64x3(),
            denoised: r.f64x3(),
            flags: r.u32(),
            epoch: r.u32(),
        })
    }
}

/// Latency percentiles of one histogram, in nanoseconds.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
#[type_name("driftless::Percentiles")]
pub struct Percentiles {
    /// Number of recorded values.
    pub count: u64,
    /// Median.
    pub p50: u64,
    /// 99th percentile.
    pub p99: u64,
    /// 99.9th percentile.
    pub p999: u64,
    /// Maximum.
    pub max: u64,
}

/// Most stages a [`StatsSnapshot`] describes.
pub const MAX_STATS_STAGES: usize = 8;

/// One stage in a [`StatsSnapshot`].
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
#[type_name("driftless::StageStats")]
pub struct StageStats {
    /// Stage name, UTF-8, NUL-padded (truncated to 32 bytes).
    pub name: [u8; 32],
    /// Samples that entered the stage.
    pub samples_in: u64,
    /// Samples the stage emitted.
    pub samples_out: u64,
    /// Samples a subscriber of the stage's output could not take (its buffer was full).
    pub lost: u64,
    /// Compute time per sample.
    pub compute: Percentiles,
}

/// The daemon's statistics, published on the pipeline's stats service every report interval.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
#[type_name("driftless::StatsSnapshot")]
pub struct StatsSnapshot {
    /// Nanoseconds since the pipeline started.
    pub uptime_ns: u64,
    /// Samples ingested.
    pub samples_in: u64,
    /// Samples published by the final stage.
    pub samples_out: u64,
    /// Ingest rate over the last interval, Hz.
    pub rate_hz: f64,
    /// Outputs whose end-to-end latency exceeded the deadline.
    pub deadline_misses: u64,
    /// Samples lost by subscribers of any of our services (full buffers).
    pub lost: u64,
    /// Samples flagged (invalid input, gap, time backwards).
    pub flagged: u64,
    /// Sequence numbers missing in the input.
    pub gap_samples: u64,
    /// Per-sample metric records the reporting thread could not take (histograms incomplete).
    pub metric_drops: u64,
    /// The deadline, ns.
    pub deadline_ns: u64,
    /// Algorithmic delay of the chain (sum of the stages' lags / rate), ns.
    pub algorithmic_delay_ns: u64,
    /// End-to-end latency: ingest of the completing sample to publish of the output.
    pub end_to_end: Percentiles,
    /// Number of valid entries in `stages`.
    pub stage_count: u64,
    /// Per-stage statistics.
    pub stages: [StageStats; MAX_STATS_STAGES],
}

/// CLOCK_MONOTONIC in nanoseconds: comparable between processes on one host.
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC is always available on Linux.
    unsafe {
        libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts);
    }
    (ts.tv_sec as u64)
        .wrapping_mul(1_000_000_000)
        .wrapping_add(ts.tv_nsec as u64)
}

/// A transport failure, with what was being done.
#[derive(Debug, thiserror::Error)]
pub enum TransportError {
    /// A service, port or node name is not acceptable to iceoryx2.
    #[error("invalid name {name:?}: {reason}")]
    Name {
        /// The name.
        name: String,
        /// Why.
        reason: String,
    },
    /// Setting up a node, service or port failed.
    #[error("{what} {name:?}: {reason}")]
    Setup {
        /// What was being set up.
        what: &'static str,
        /// Its name.
        name: String,
        /// iceoryx2's error.
        reason: String,
    },
    /// An existing input service, created by another process, would lose samples silently.
    #[error(
        "service {name:?} was created by another process with a subscriber buffer of {buffer} \
         and safe overflow {overflow}: it would lose samples silently. driftless needs a buffer \
         of at least {need} (the pipeline's buffer_size) and safe overflow off: start the daemon \
         first (it creates the service), or create it with subscriber_max_buffer_size >= {need} \
         and enable_safe_overflow(false)",
        overflow = if *safe_overflow { "on" } else { "off" }
    )]
    Qos {
        /// The service.
        name: String,
        /// Its creator's subscriber buffer limit.
        buffer: usize,
        /// Whether its creator enabled safe overflow (new samples overwrite unread ones).
        safe_overflow: bool,
        /// The buffer the pipeline asks for.
        need: usize,
    },
    /// iceoryx2's files belong to another user: what, whose, and how to fix it.
    #[error("{what} {name:?}: {problem}")]
    Permission {
        /// What was being set up.
        what: &'static str,
        /// Its name.
        name: String,
        /// Which file or directory, its owner and mode, and the ways out.
        problem: String,
    },
    /// Sending or receiving failed at run time.
    #[error("{what}: {reason}")]
    Io {
        /// What failed.
        what: &'static str,
        /// iceoryx2's error.
        reason: String,
    },
}

fn setup(what: &'static str, name: &str, e: impl Debug) -> TransportError {
    let reason = format!("{e:?}");
    // iceoryx2 says only `InsufficientPermissions`, or even `InternalError`: say whose files.
    let culprit = foreign_directory();
    if culprit.is_some() || reason.contains("Permission") {
        return TransportError::Permission {
            what,
            name: name.to_string(),
            problem: access_problem(culprit, &reason),
        };
    }
    TransportError::Setup {
        what,
        name: name.to_string(),
        reason,
    }
}

/// A user's name and id, as `name (uid N)`, or `uid N` when it has no name.
fn who(uid: u32) -> String {
    match user_name(uid) {
        Some(n) => format!("{n} (uid {uid})"),
        None => format!("uid {uid}"),
    }
}

/// `belongs to NAME (uid N), mode 0750`.
fn owner_and_mode(m: &std::fs::Metadata) -> String {
    use std::os::unix::fs::MetadataExt;
    format!(
        "belongs to {}, mode {:04o}",
        who(m.uid()),
        m.mode() & 0o7777
    )
}

/// The first of iceoryx2's directories (root, nodes, services) that belongs to another user
/// without granting this process access, or that it cannot create: with owner and mode.
fn foreign_directory() -> Option<String> {
    use std::os::unix::fs::MetadataExt;
    // SAFETY: geteuid cannot fail.
    let me = unsafe { libc::geteuid() };
    if me == 0 {
        return None;
    }
    let root = root();
    for dir in [root.clone(), root.join("nodes"), root.join("services")] {
        match std::fs::metadata(&dir) {
            Ok(m) if m.uid() != me && m.mode() & 0o002 == 0 => {
                return Some(format!(
                    "iceoryx2's directory {} {}",
                    dir.display(),
                    owner_and_mode(&m)
                ));
            }
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                let parent = dir.parent().unwrap_or(&dir);
                let m = std::fs::metadata(parent).ok()?;
                return (m.uid() != me && m.mode() & 0o002 == 0).then(|| {
                    format!(
                        "iceoryx2 cannot create {}: {} {}",
                        dir.display(),
                        parent.display(),
                        owner_and_mode(&m)
                    )
                });
            }
            Err(e) => return Some(format!("{}: {e}", dir.display())),
        }
    }
    None
}

/// The refusal in full: whose files (or iceoryx2's own words), who we are, the ways out.
fn access_problem(culprit: Option<String>, reason: &str) -> String {
    // SAFETY: geteuid cannot fail.
    let me = unsafe { libc::geteuid() };
    let root = root();
    let culprit =
        culprit.unwrap_or_else(|| format!("iceoryx2 says {reason} (under {})", root.display()));
    format!(
        "{culprit}; this process runs as {}. iceoryx2's files are for one user: run the daemon \
         and every process that talks to it as the same user (README, \"Users and \
         permissions\"), or give your own pipelines their own directory: `root_path = \"...\"` \
         under [iceoryx2] in the pipeline file, or {ROOT_ENV}=..., or --root-path, the same for \
         the daemon and its subscribers",
        who(me)
    )
}

/// Quality of service of every service the daemon creates (one definition, see module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    /// Samples a subscriber can hold before it loses new ones.
    pub buffer_size: usize,
    /// Subscribers per service (the daemon's own hop takes one).
    pub max_subscribers: usize,
}

impl Default for Qos {
    fn default() -> Self {
        Qos {
            buffer_size: 256,
            max_subscribers: 8,
        }
    }
}

/// Check that `name` is a valid iceoryx2 service name.
pub fn check_service_name(name: &str) -> Result<(), String> {
    ServiceName::new(name)
        .map(|_| ())
        .map_err(|e| format!("{e:?}"))
}

/// Check that `prefix` is a valid iceoryx2 prefix (a file name).
pub fn check_prefix(prefix: &str) -> Result<(), String> {
    FileName::new(prefix.as_bytes())
        .map(|_| ())
        .map_err(|e| format!("{e:?}"))
}

fn service_name(name: &str) -> Result<ServiceName, TransportError> {
    ServiceName::new(name).map_err(|e| TransportError::Name {
        name: name.to_string(),
        reason: format!("{e:?}"),
    })
}

/// Check that `root` can be iceoryx2's root directory: an absolute path iceoryx2 accepts.
pub fn check_root(root: &std::path::Path) -> Result<(), String> {
    iox_root(root).map(|_| ())
}

fn iox_root(root: &std::path::Path) -> Result<Path, String> {
    use std::os::unix::ffi::OsStrExt;
    if !root.is_absolute() {
        return Err("must be an absolute path".into());
    }
    // iceoryx2 joins its directory names to the root as to a string.
    let mut bytes = root.as_os_str().as_bytes().to_vec();
    if !bytes.ends_with(b"/") {
        bytes.push(b'/');
    }
    Path::new(&bytes).map_err(|e| format!("not a path iceoryx2 accepts: {e:?}"))
}

/// Set iceoryx2's root directory for every node this process creates from now on (`None`:
/// [`DEFAULT_ROOT`]). Process-wide, as iceoryx2's own global configuration: a daemon and every
/// process that talks to it must use the same root directory and prefix.
pub fn set_root(root: Option<std::path::PathBuf>) -> Result<(), String> {
    if let Some(r) = &root {
        check_root(r)?;
    }
    *ROOT.write().unwrap_or_else(|e| e.into_inner()) = root;
    Ok(())
}

/// iceoryx2's root directory in force in this process.
pub fn root() -> std::path::PathBuf {
    ROOT.read()
        .unwrap_or_else(|e| e.into_inner())
        .clone()
        .unwrap_or_else(|| DEFAULT_ROOT.into())
}

/// The explicit iceoryx2 configuration (never the silently discovered `config/iceoryx2.toml`).
fn config(prefix: &str) -> Result<Config, TransportError> {
    let mut cfg = Config::default();
    cfg.global.prefix = FileName::new(prefix.as_bytes()).map_err(|e| TransportError::Name {
        name: prefix.to_string(),
        reason: format!("{e:?}"),
    })?;
    if let Some(r) = ROOT.read().unwrap_or_else(|e| e.into_inner()).as_deref() {
        let path = iox_root(r).map_err(|reason| TransportError::Name {
            name: r.display().to_string(),
            reason,
        })?;
        cfg.global.set_root_path(&path);
    }
    Ok(cfg)
}

/// Quiet iceoryx2's own logging unless `IOX2_LOG_LEVEL` asks for it.
pub fn quiet_logging() {
    set_log_level_from_env_or(LogLevel::Fatal);
}

/// One iceoryx2 node and the ports it creates. Not `Send`: create it in the thread that uses it.
pub struct Transport {
    node: Node<Svc>,
    qos: Qos,
    prefix: String,
}

impl Transport {
    /// Create a node named `node_name` under `prefix`. Creating a node also removes the
    /// resources of dead nodes (a daemon killed with SIGKILL) of the same prefix.
    pub fn new(prefix: &str, node_name: &str, qos: Qos) -> Result<Self, TransportError> {
        let cfg = config(prefix)?;
        remove_unsized_segments(prefix);
        let name = NodeName::new(node_name).map_err(|e| TransportError::Name {
            name: node_name.to_string(),
            reason: format!("{e:?}"),
        })?;
        let node = NodeBuilder::new()
            .name(&name)
            .config(&cfg)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Svc>()
            .map_err(|e| setup("node", node_name, e))?;
        node.try_cleanup_dead_nodes();
        restrict_global_segment(prefix);
        Ok(Transport {
            node,
            qos,
            prefix: prefix.to_string(),
        })
    }

    /// The prefix this node lives under.
    pub fn prefix(&self) -> &str {
        &self.prefix
    }

    /// Remove the resources of dead nodes of this prefix; returns how many were cleaned.
    pub fn cleanup_dead_nodes(&self) -> u64 {
        self.node.try_cleanup_dead_nodes().cleanups
    }

    /// Number of live nodes named `node_name` under `prefix`, other than the caller's.
    pub fn live_nodes_named(prefix: &str, node_name: &str) -> Result<usize, TransportError> {
        Ok(Self::holders_of(prefix, node_name)?.len())
    }

    /// The live nodes named `node_name` under `prefix` (other than the caller's), described as
    /// far as iceoryx2's node list and `/proc` tell: who holds a pipeline.
    pub fn holders_of(prefix: &str, node_name: &str) -> Result<Vec<NodeHolder>, TransportError> {
        let cfg = config(prefix)?;
        let mut holders = Vec::new();
        Node::<Svc>::list(&cfg, |state| {
            if let NodeState::Alive(view) = &state {
                if view.details().as_ref().map(|d| d.name().as_str()) == Some(node_name) {
                    holders.extend(holder(view, true));
                }
            }
            CallbackProgression::Continue
        })
        .map_err(|e| setup("node list", prefix, e))?;
        Ok(holders)
    }

    /// Number of nodes (alive or dead) under `prefix`.
    pub fn node_count(prefix: &str) -> Result<usize, TransportError> {
        let cfg = config(prefix)?;
        let mut count = 0;
        Node::<Svc>::list(&cfg, |_| {
            count += 1;
            CallbackProgression::Continue
        })
        .map_err(|e| setup("node list", prefix, e))?;
        Ok(count)
    }

    fn pubsub<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
    ) -> Result<
        iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, T, ()>,
        TransportError,
    > {
        self.node
            .service_builder(&service_name(name)?)
            .publish_subscribe::<T>()
            .history_size(0)
            .enable_safe_overflow(false)
            .subscriber_max_buffer_size(self.qos.buffer_size)
            .max_subscribers(self.qos.max_subscribers)
            .max_publishers(1)
            .open_or_create()
            .map_err(|e| setup("service", name, e))
    }

    /// The publishing side of service `name`, with an event service of the same name that is
    /// notified after every send when `notify` is set (so readers can sleep until data comes).
    /// Fails if another process already publishes on it (one publisher per service).
    pub fn output<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
        notify: bool,
    ) -> Result<Output<T>, TransportError> {
        let service = self.pubsub::<T>(name)?;
        self.output_on(service, name, notify)
    }

    /// Like [`Transport::output`] for a service another process may have created first (the
    /// input of an `external` stage, or an external stage's own output): opened without
    /// requirements if it exists, created with our QoS otherwise.
    pub fn external_output<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
        notify: bool,
    ) -> Result<Output<T>, TransportError> {
        if !self.service_exists::<T>(name)? {
            return self.output(name, notify);
        }
        let service = self
            .node
            .service_builder(&service_name(name)?)
            .publish_subscribe::<T>()
            .open()
            .map_err(|e| setup("service", name, e))?;
        self.output_on(service, name, notify)
    }

    fn output_on<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        service: PubSubFactory<T>,
        name: &str,
        notify: bool,
    ) -> Result<Output<T>, TransportError> {
        let lost = Arc::new(AtomicU64::new(0));
        let publisher = service
            .publisher_builder()
            .backpressure_strategy(BackpressureStrategy::DiscardData)
            .create()
            .map_err(|e| setup("publisher (is another daemon running?)", name, e))?;
        let notifier = if notify {
            let event = self
                .node
                .service_builder(&service_name(name)?)
                .event()
                .open_or_create()
                .map_err(|e| setup("event service", name, e))?;
            Some(
                event
                    .notifier_builder()
                    .create()
                    .map_err(|e| setup("notifier", name, e))?,
            )
        } else {
            None
        };
        Ok(Output {
            service,
            publisher,
            notifier,
            lost,
        })
    }

    /// A subscriber to service `name`, created with our QoS if it does not exist yet.
    pub fn input<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
    ) -> Result<Input<T>, TransportError> {
        let service = self.pubsub::<T>(name)?;
        let subscriber = service
            .subscriber_builder()
            .buffer_size(self.qos.buffer_size)
            .create()
            .map_err(|e| setup("subscriber", name, e))?;
        Ok(Input { subscriber })
    }

    /// A subscriber to a service another process publishes (a sensor driver, an external
    /// stage): created with our QoS if it does not exist yet; if it does, its creator's settings
    /// are checked, because a small buffer or safe overflow (iceoryx2's defaults: 2 samples,
    /// overwrite the oldest) loses samples under ordinary jitter without the publisher
    /// knowing. Refused ([`TransportError::Qos`]) unless it holds our buffer with safe overflow
    /// off.
    pub fn external_input<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
    ) -> Result<Input<T>, TransportError> {
        if !self.service_exists::<T>(name)? {
            return self.input(name);
        }
        let service = self
            .node
            .service_builder(&service_name(name)?)
            .publish_subscribe::<T>()
            .open()
            .map_err(|e| setup("service", name, e))?;
        let cfg = service.static_config();
        let (buffer, safe_overflow) = (cfg.subscriber_max_buffer_size(), cfg.has_safe_overflow());
        if buffer < self.qos.buffer_size || safe_overflow {
            return Err(TransportError::Qos {
                name: name.to_string(),
                buffer,
                safe_overflow,
                need: self.qos.buffer_size,
            });
        }
        let subscriber = service
            .subscriber_builder()
            .buffer_size(self.qos.buffer_size)
            .create()
            .map_err(|e| setup("subscriber", name, e))?;
        Ok(Input { subscriber })
    }

    /// A subscriber to an existing service `name` whatever its creator's QoS (for `tap`,
    /// `stats` and external consumers), with the largest buffer the service allows.
    pub fn open_input<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
    ) -> Result<Input<T>, TransportError> {
        let service = self
            .node
            .service_builder(&service_name(name)?)
            .publish_subscribe::<T>()
            .open()
            .map_err(|e| setup("service", name, e))?;
        let max = service.static_config().subscriber_max_buffer_size();
        let subscriber = service
            .subscriber_builder()
            .buffer_size(max)
            .create()
            .map_err(|e| setup("subscriber", name, e))?;
        Ok(Input { subscriber })
    }

    /// A listener on the event service `name` (opened or created), to sleep until a publisher
    /// announces new data.
    pub fn waker(&self, name: &str) -> Result<Waker, TransportError> {
        let event = self
            .node
            .service_builder(&service_name(name)?)
            .event()
            .open_or_create()
            .map_err(|e| setup("event service", name, e))?;
        let listener = event
            .listener_builder()
            .create()
            .map_err(|e| setup("listener", name, e))?;
        Ok(Waker { listener })
    }

    /// A listener on the event service `name` if its publisher created one (the services a
    /// daemon notifies, e.g. the corrected one); `None` otherwise, creating nothing.
    pub fn existing_waker(&self, name: &str) -> Result<Option<Waker>, TransportError> {
        let sn = service_name(name)?;
        let exists = ipc::Service::does_exist(&sn, self.node.config(), MessagingPattern::Event)
            .map_err(|e| setup("service lookup", name, e))?;
        if exists {
            self.waker(name).map(Some)
        } else {
            Ok(None)
        }
    }

    /// The payload type name of the publish-subscribe service `name` (e.g.
    /// `driftless::GyroSample`), or `None` when no such service exists under this prefix.
    pub fn payload_type_name(&self, name: &str) -> Result<Option<String>, TransportError> {
        let sn = service_name(name)?;
        let details =
            ipc::Service::details(&sn, self.node.config(), MessagingPattern::PublishSubscribe)
                .map_err(|e| setup("service lookup", name, e))?;
        Ok(details.map(|d| {
            d.static_details
                .publish_subscribe()
                .message_type_details()
                .payload
                .type_name()
                .to_string()
        }))
    }

    /// Whether a publish-subscribe service `name` of type `T` exists under this prefix.
    pub fn service_exists<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
    ) -> Result<bool, TransportError> {
        let sn = service_name(name)?;
        ipc::Service::does_exist(&sn, self.node.config(), MessagingPattern::PublishSubscribe)
            .map_err(|e| setup("service lookup", name, e))
    }
}

/// A live iceoryx2 node as the node list describes it: which process, whose, since when.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeHolder {
    /// Process id of the node's owner.
    pub pid: i32,
    /// File name of its executable, when iceoryx2 recorded one.
    pub executable: Option<String>,
    /// The process owner's user name (or `uid N` without one), while the process is visible.
    pub user: Option<String>,
    /// When the node was created (wall clock) and how long ago.
    pub since: Option<(std::time::SystemTime, Duration)>,
}

impl std::fmt::Display for NodeHolder {
    /// `pid 4242 (driftless, user alice, since 2025-06-01T10:00:00Z, 5m 3s ago)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "pid {}", self.pid)?;
        let mut parts: Vec<String> = Vec::new();
        parts.extend(self.executable.clone());
        parts.extend(self.user.as_ref().map(|u| format!("user {u}")));
        if let Some((since, age)) = self.since {
            parts.push(format!(
                "since {}, {} ago",
                humantime::format_rfc3339_seconds(since),
                humantime::format_duration(Duration::from_secs(age.as_secs()))
            ));
        }
        if !parts.is_empty() {
            write!(f, " ({})", parts.join(", "))?;
        }
        Ok(())
    }
}

/// What iceoryx2 can tell of a node from its view: which process, whose (only while it is
/// alive: a dead node's pid may belong to another process by now), since when.
fn holder(view: &impl NodeView, alive: bool) -> Option<NodeHolder> {
    let details = view.details().as_ref()?;
    let pid = details.process_id().value();
    let age = view
        .id()
        .creation_time::<Svc>()
        .ok()
        .and_then(|t| t.elapsed().ok());
    Some(NodeHolder {
        pid,
        executable: Some(details.executable().to_string())
            .filter(|e| !e.is_empty() && e != "undefined"),
        user: if alive { process_owner(pid) } else { None },
        since: age.and_then(|a| {
            std::time::SystemTime::now()
                .checked_sub(a)
                .map(|since| (since, a))
        }),
    })
}

/// The state of a node as iceoryx2's node list gives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeLife {
    /// Its process is alive.
    Alive,
    /// Its process died without removing its resources (e.g. SIGKILL); another process may
    /// remove them ([`Transport::remove_dead_nodes`]).
    Dead,
    /// This user may not tell whether it is alive (another user's node).
    Inaccessible,
    /// Its files are incomplete or inconsistent.
    Undefined,
}

impl NodeLife {
    /// `alive`, `dead`, `inaccessible` or `undefined`.
    pub fn as_str(self) -> &'static str {
        match self {
            NodeLife::Alive => "alive",
            NodeLife::Dead => "dead",
            NodeLife::Inaccessible => "inaccessible",
            NodeLife::Undefined => "undefined",
        }
    }
}

/// One node under a prefix.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ListedNode {
    /// iceoryx2's unique node id (what services name their ports' nodes by).
    pub id: u128,
    /// The node's name; empty when its details are unreadable.
    pub name: String,
    /// Alive, dead, ...
    pub life: NodeLife,
    /// Process, user and age, as far as they are known.
    pub holder: Option<NodeHolder>,
}

/// Which of our wire types a publish-subscribe service carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireType {
    /// [`RawSample`].
    Raw,
    /// [`GyroSample`].
    Gyro,
    /// [`StatsSnapshot`].
    Stats,
}

impl WireType {
    /// The type's name without the crate: `RawSample`, `GyroSample`, `StatsSnapshot`.
    pub fn short_name(self) -> &'static str {
        match self {
            WireType::Raw => "RawSample",
            WireType::Gyro => "GyroSample",
            WireType::Stats => "StatsSnapshot",
        }
    }

    /// Ours if both the type name and the size are those of one of our types.
    fn of(type_name: &str, size: usize) -> Option<WireType> {
        [
            (
                WireType::Raw,
                RAW_TYPE_NAME,
                std::mem::size_of::<RawSample>(),
            ),
            (
                WireType::Gyro,
                GYRO_TYPE_NAME,
                std::mem::size_of::<GyroSample>(),
            ),
            (
                WireType::Stats,
                STATS_TYPE_NAME,
                std::mem::size_of::<StatsSnapshot>(),
            ),
        ]
        .into_iter()
        .find(|&(_, name, bytes)| name == type_name && bytes == size)
        .map(|(w, _, _)| w)
    }
}

/// The messaging pattern of a listed service.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ServiceKind {
    /// Publish-subscribe: the payload's type name, and which of ours it is (None: foreign).
    PubSub {
        /// The payload's iceoryx2 type name.
        type_name: String,
        /// Our wire type, when it is one.
        wire: Option<WireType>,
    },
    /// An event service (notifiers wake listeners).
    Event,
    /// Request-response or blackboard: listed, not opened.
    Other(&'static str),
}

/// One service under a prefix, with the nodes of its ports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ListedService {
    /// Service name.
    pub name: String,
    /// Pattern and payload type.
    pub kind: ServiceKind,
    /// Node id of each publisher (notifier, for an event service); None when the service could
    /// not be opened (a foreign payload type, another user's service).
    pub senders: Option<Vec<u128>>,
    /// Node id of each subscriber (listener, for an event service); None as for `senders`.
    pub receivers: Option<Vec<u128>>,
    /// Node ids of every node attached to the service (whatever its type: for a foreign
    /// service, who uses it).
    pub nodes: Vec<u128>,
}

/// What runs under a prefix: its nodes and services, as iceoryx2 lists them.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Listing {
    /// Every node, alive or not.
    pub nodes: Vec<ListedNode>,
    /// Every service, sorted by name.
    pub services: Vec<ListedService>,
}

fn view_name(view: &impl NodeView) -> String {
    view.details()
        .as_ref()
        .map(|d| d.name().as_str().to_string())
        .unwrap_or_default()
}

/// A node's name, or its id where its details are gone.
pub fn display_name(node: &ListedNode) -> String {
    if node.name.is_empty() {
        format!("node {:x}", node.id)
    } else {
        node.name.clone()
    }
}

fn listed_node(state: &NodeState<Svc>) -> ListedNode {
    match state {
        NodeState::Alive(v) => ListedNode {
            id: v.id().value(),
            name: view_name(v),
            life: NodeLife::Alive,
            holder: holder(v, true),
        },
        NodeState::Dead(v) => ListedNode {
            id: v.id().value(),
            name: view_name(v),
            life: NodeLife::Dead,
            holder: holder(v, false),
        },
        NodeState::Inaccessible(id) => ListedNode {
            id: id.value(),
            name: String::new(),
            life: NodeLife::Inaccessible,
            holder: None,
        },
        NodeState::Undefined(id) => ListedNode {
            id: id.value(),
            name: String::new(),
            life: NodeLife::Undefined,
            holder: None,
        },
    }
}

/// A node that only looks: creating, dropping it or opening a service with it removes no dead
/// node's resources (iceoryx2 does that by default), so `list` shows the dead as dead.
fn observer(prefix: &str) -> Result<Node<Svc>, TransportError> {
    let mut cfg = config(prefix)?;
    remove_unsized_segments(prefix);
    cfg.global.node.cleanup_dead_nodes_on_creation = false;
    cfg.global.node.cleanup_dead_nodes_on_destruction = false;
    cfg.global.service.cleanup_dead_nodes_on_open = false;
    let node_name = format!("driftless-list-{}", std::process::id());
    let name = NodeName::new(&node_name).map_err(|e| TransportError::Name {
        name: node_name.clone(),
        reason: format!("{e:?}"),
    })?;
    NodeBuilder::new()
        .name(&name)
        .config(&cfg)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<Svc>()
        .map_err(|e| setup("node", &node_name, e))
}

/// The publishers' and subscribers' node ids of a publish-subscribe service of our type `T`.
fn pubsub_ports<T: Debug + ZeroCopySend + Copy + 'static>(
    node: &Node<Svc>,
    name: &ServiceName,
) -> Option<(Vec<u128>, Vec<u128>)> {
    let service = node
        .service_builder(name)
        .publish_subscribe::<T>()
        .open()
        .ok()?;
    let dynamic = service.dynamic_config();
    let (mut senders, mut receivers) = (Vec::new(), Vec::new());
    dynamic.list_publishers(|p| {
        senders.push(p.node_id.value());
        CallbackProgression::Continue
    });
    dynamic.list_subscribers(|s| {
        receivers.push(s.node_id.value());
        CallbackProgression::Continue
    });
    Some((senders, receivers))
}

/// The notifiers' and listeners' node ids of an event service.
fn event_ports(node: &Node<Svc>, name: &ServiceName) -> Option<(Vec<u128>, Vec<u128>)> {
    let service = node.service_builder(name).event().open().ok()?;
    let dynamic = service.dynamic_config();
    let (mut senders, mut receivers) = (Vec::new(), Vec::new());
    dynamic.list_notifiers(|p| {
        senders.push(p.node_id.value());
        CallbackProgression::Continue
    });
    dynamic.list_listeners(|s| {
        receivers.push(s.node_id.value());
        CallbackProgression::Continue
    });
    Some((senders, receivers))
}

impl Transport {
    /// Every node and service under `prefix` (iceoryx2's `Node::list` and `Service::list`), with
    /// the nodes of each service's ports. Removes nothing: a dead node is listed as dead. The
    /// ports are read through a node of this process that exists only during the call (and is
    /// not in the listing); nothing is created when the prefix holds no service.
    pub fn list(prefix: &str) -> Result<Listing, TransportError> {
        use iceoryx2::service::static_config::messaging_pattern::MessagingPattern as Static;
        let cfg = config(prefix)?;
        let mut listing = Listing::default();
        let mut found = Vec::new();
        Svc::list(&cfg, |details| {
            found.push(details);
            CallbackProgression::Continue
        })
        .map_err(|e| setup("service list", prefix, e))?;
        let observer = if found.is_empty() {
            None
        } else {
            Some(observer(prefix)?)
        };
        for details in found {
            let st = &details.static_details;
            let name = *st.name();
            let kind = match st.messaging_pattern() {
                Static::PublishSubscribe(ps) => {
                    let payload = &ps.message_type_details().payload;
                    let type_name = payload.type_name().to_string();
                    ServiceKind::PubSub {
                        wire: WireType::of(&type_name, payload.size()),
                        type_name,
                    }
                }
                Static::Event(_) => ServiceKind::Event,
                Static::RequestResponse(_) => ServiceKind::Other("request-response"),
                Static::Blackboard(_) => ServiceKind::Other("blackboard"),
                _ => ServiceKind::Other("other"),
            };
            let ports = observer.as_ref().and_then(|node| match &kind {
                ServiceKind::PubSub {
                    wire: Some(WireType::Raw),
                    ..
                } => pubsub_ports::<RawSample>(node, &name),
                ServiceKind::PubSub {
                    wire: Some(WireType::Gyro),
                    ..
                } => pubsub_ports::<GyroSample>(node, &name),
                ServiceKind::PubSub {
                    wire: Some(WireType::Stats),
                    ..
                } => pubsub_ports::<StatsSnapshot>(node, &name),
                ServiceKind::Event => event_ports(node, &name),
                _ => None,
            });
            // Listed before the observer opened anything; kept clean of it all the same.
            let observer_id = observer.as_ref().map(|n| n.id().value());
            let mut nodes: Vec<u128> = details
                .dynamic_details
                .map(|d| d.nodes.iter().map(|n| n.node_id().value()).collect())
                .unwrap_or_default();
            let (senders, receivers) = ports.unzip();
            // A port read after the service list may belong to a node that attached in between:
            // the node of every listed port is among the service's nodes.
            for id in senders.iter().chain(receivers.iter()).flatten() {
                if !nodes.contains(id) {
                    nodes.push(*id);
                }
            }
            nodes.retain(|id| Some(*id) != observer_id);
            listing.services.push(ListedService {
                name: name.as_str().to_string(),
                kind,
                senders,
                receivers,
                nodes,
            });
        }
        listing
            .services
            .sort_by(|a, b| (&a.name, kind_rank(&a.kind)).cmp(&(&b.name, kind_rank(&b.kind))));
        // Nodes last, so every node a port above belongs to is listed (unless it ended since);
        // the observer is gone by then, so it is not listed.
        drop(observer);
        Node::<Svc>::list(&cfg, |state| {
            listing.nodes.push(listed_node(&state));
            CallbackProgression::Continue
        })
        .map_err(|e| setup("node list", prefix, e))?;
        Ok(listing)
    }

    /// Remove the resources of every dead node under `prefix` (its ports, and its services
    /// when no live node uses them); returns the nodes removed. A process killed while it was
    /// creating a port leaves a port tag that iceoryx2 0.10's own clean-up stops at (it then
    /// keeps listing the node as dead, and reports it cleaned up): what is left of such a dead
    /// node (its directory, its monitor files) is removed here.
    pub fn remove_dead_nodes(prefix: &str) -> Result<Vec<ListedNode>, TransportError> {
        let cfg = config(prefix)?;
        remove_unsized_segments(prefix);
        let dead_nodes = |cfg: &Config| -> Result<Vec<ListedNode>, TransportError> {
            let mut dead = Vec::new();
            Node::<Svc>::list(cfg, |state| {
                if matches!(state, NodeState::Dead(_)) {
                    dead.push(listed_node(&state));
                }
                CallbackProgression::Continue
            })
            .map_err(|e| setup("node list", prefix, e))?;
            Ok(dead)
        };
        let before = dead_nodes(&cfg)?;
        let mut failures = std::collections::HashMap::new();
        Node::<Svc>::list(&cfg, |state| {
            if let NodeState::Dead(view) = state {
                let id = view.id().value();
                if let Err(e) = view.try_remove_stale_resources() {
                    failures.insert(id, format!("{e:?}"));
                }
            }
            CallbackProgression::Continue
        })
        .map_err(|e| setup("node list", prefix, e))?;
        let node_dir = std::path::PathBuf::from(cfg.global.node_dir().to_string());
        for node in dead_nodes(&cfg)? {
            // This prefix's files in the directory iceoryx2 names by the node id, then the
            // node's monitor files (`PREFIXID.node_monitor...`), as iceoryx2 orders them.
            let id = node.id.to_string();
            let dir = node_dir.join(&id);
            remove_files_with_prefix(&dir, prefix);
            let _ = std::fs::remove_dir(&dir);
            remove_files_with_prefix(&node_dir, &format!("{prefix}{id}."));
        }
        let left = dead_nodes(&cfg)?;
        if !left.is_empty() {
            let names: Vec<String> = left
                .iter()
                .map(|n| {
                    let why = failures.get(&n.id).map_or("", String::as_str);
                    format!("{} ({why})", display_name(n))
                })
                .collect();
            return Err(TransportError::Io {
                what: "removing dead nodes",
                reason: names.join(", "),
            });
        }
        Ok(before)
    }

    /// One snapshot from each of the StatsSnapshot services `names` under `prefix`: the next one
    /// each publishes within `timeout` (the daemon keeps no history), None where none came.
    pub fn read_stats(
        prefix: &str,
        names: &[String],
        timeout: Duration,
    ) -> Result<Vec<Option<StatsSnapshot>>, TransportError> {
        let mut got = vec![None; names.len()];
        if names.is_empty() {
            return Ok(got);
        }
        let node = observer(prefix)?;
        let mut subscribers = Vec::new();
        for name in names {
            let sub = node
                .service_builder(&service_name(name)?)
                .publish_subscribe::<StatsSnapshot>()
                .open()
                .ok()
                .and_then(|s| s.subscriber_builder().create().ok());
            subscribers.push(sub);
        }
        let end = std::time::Instant::now() + timeout;
        loop {
            for (slot, sub) in got.iter_mut().zip(&subscribers) {
                if let (None, Some(sub)) = (&slot, sub) {
                    if let Ok(Some(sample)) = sub.receive() {
                        *slot = Some(*sample.payload());
                    }
                }
            }
            let waiting = got
                .iter()
                .zip(&subscribers)
                .any(|(g, s)| g.is_none() && s.is_some());
            if !waiting || std::time::Instant::now() >= end {
                return Ok(got);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

fn kind_rank(kind: &ServiceKind) -> u8 {
    match kind {
        ServiceKind::PubSub { .. } => 0,
        ServiceKind::Event => 1,
        ServiceKind::Other(_) => 2,
    }
}

/// The user owning process `pid` (the owner of `/proc/PID`), by name where it has one.
fn process_owner(pid: i32) -> Option<String> {
    use std::os::unix::fs::MetadataExt as _;
    let uid = std::fs::metadata(format!("/proc/{pid}")).ok()?.uid();
    Some(user_name(uid).unwrap_or_else(|| format!("uid {uid}")))
}

/// The name of user `uid` from the password database.
pub fn user_name(uid: u32) -> Option<String> {
    // SAFETY: a zeroed passwd is a valid out-parameter for getpwuid_r.
    let mut pwd: libc::passwd = unsafe { std::mem::zeroed() };
    let mut buf: Vec<libc::c_char> = vec![0; 16 * 1024];
    let mut found: *mut libc::passwd = std::ptr::null_mut();
    // SAFETY: every pointer is valid for the call; the strings it sets point into `buf`.
    let rc = unsafe { libc::getpwuid_r(uid, &mut pwd, buf.as_mut_ptr(), buf.len(), &mut found) };
    if rc != 0 || found.is_null() || pwd.pw_name.is_null() {
        return None;
    }
    // SAFETY: pw_name is a NUL-terminated string inside `buf`, alive here.
    let name = unsafe { std::ffi::CStr::from_ptr(pwd.pw_name) };
    Some(name.to_string_lossy().into_owned())
}

/// Remove this prefix's shared memory segments of size 0 older than a second: what a process
/// killed between creating a segment and sizing it leaves (creator and size are microseconds
/// apart). iceoryx2 0.10 waits for such a segment to be sized without a timeout
/// (`MappingSizeIsZero` in its `open_impl`), so the next node's clean-up of dead nodes, or a
/// listing, would hang forever (found by the `list --clean` test killing daemons mid-start).
fn remove_unsized_segments(prefix: &str) {
    const SETTLE: Duration = Duration::from_secs(1);
    let unsized_segments = || -> Vec<(std::path::PathBuf, Duration)> {
        own_segments(prefix)
            .into_iter()
            .filter(|(_, m)| m.is_file() && m.len() == 0)
            .filter_map(|(path, m)| Some((path, m.modified().ok()?.elapsed().unwrap_or_default())))
            .collect()
    };
    let found = unsized_segments();
    // A segment younger than a second may be one a live process is sizing right now: wait
    // until it is a second old (rare: only after a kill at that instant), then look again.
    if let Some(youngest) = found.iter().map(|(_, age)| *age).min() {
        if youngest < SETTLE {
            std::thread::sleep(SETTLE - youngest);
        }
        for (path, age) in unsized_segments() {
            if age >= SETTLE {
                let _ = std::fs::remove_file(path);
            }
        }
    }
}

/// iceoryx2 0.10 makes each prefix's global management segment (a node counter in `/dev/shm`)
/// readable and writable by every user, the one resource it opens to all: make ours the
/// owner's alone, as everything else it creates is (a process of another user is then refused,
/// as by the rest).
fn restrict_global_segment(prefix: &str) {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    for (path, m) in own_segments(prefix) {
        let global = path.to_string_lossy().ends_with(".global_mgmt");
        if global && m.mode() & 0o077 != 0 {
            let _ = std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600));
        }
    }
}

/// This prefix's shared memory segments in `/dev/shm` that belong to this process's user, with
/// their metadata.
fn own_segments(prefix: &str) -> Vec<(std::path::PathBuf, std::fs::Metadata)> {
    use std::os::unix::fs::MetadataExt;
    // SAFETY: geteuid cannot fail.
    let me = unsafe { libc::geteuid() };
    let Ok(entries) = std::fs::read_dir("/dev/shm") else {
        return Vec::new();
    };
    entries
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with(prefix))
        .filter_map(|e| Some((e.path(), e.metadata().ok()?)))
        .filter(|(_, m)| m.uid() == me)
        .collect()
}

/// Remove the files iceoryx2 leaves for `prefix` once no node of it is left (the per-prefix
/// management file in `/dev/shm`). Does nothing while a node of the prefix is alive.
pub fn remove_prefix_leftovers(prefix: &str) {
    if Transport::node_count(prefix).map_or(true, |n| n > 0) {
        return;
    }
    for dir in [std::path::PathBuf::from("/dev/shm"), root()] {
        remove_files_with_prefix(&dir, prefix);
    }
}

fn remove_files_with_prefix(dir: &std::path::Path, prefix: &str) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name();
        if !name.to_string_lossy().starts_with(prefix) {
            if path.is_dir() {
                remove_files_with_prefix(&path, prefix);
            }
            continue;
        }
        if path.is_dir() {
            let _ = std::fs::remove_dir_all(&path);
        } else {
            let _ = std::fs::remove_file(&path);
        }
    }
}

/// The sending side of one service. Sending never blocks: a subscriber with a full buffer
/// loses the sample, counted in [`Output::lost`].
pub struct Output<T: Debug + ZeroCopySend + Copy + 'static> {
    service: PubSubFactory<T>,
    publisher: Publisher<Svc, T, ()>,
    notifier: Option<Notifier<Svc>>,
    lost: Arc<AtomicU64>,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Output<T> {
    /// Connect to the subscribers that exist now, so that the first [`send`](Self::send) does
    /// not pay for it (mapping their shared memory) on the hot path.
    pub fn connect(&self) -> Result<(), TransportError> {
        self.publisher
            .update_connections()
            .map_err(|e| TransportError::Io {
                what: "connect",
                reason: format!("{e:?}"),
            })
    }

    /// Publish a copy of `value` (zero-copy into shared memory); returns the number of
    /// subscribers that received it. Does not notify: call [`Output::notify`] after it.
    /// Allocation-free on our side (iceoryx2 0.10 allocates one small `Arc` per loan).
    pub fn send(&self, value: &T) -> Result<usize, TransportError> {
        let sample = self
            .publisher
            .loan_uninit()
            .map_err(|e| TransportError::Io {
                what: "loan",
                reason: format!("{e:?}"),
            })?;
        let n = sample
            .write_payload(*value)
            .send()
            .map_err(|e| TransportError::Io {
                what: "send",
                reason: format!("{e:?}"),
            })?;
        // Subscribers registered on the service but not served: their buffers were full.
        let subscribers = self.service.dynamic_config().number_of_subscribers();
        if n < subscribers {
            self.lost
                .fetch_add((subscribers - n) as u64, Ordering::Relaxed);
        }
        Ok(n)
    }

    /// Wake the readers sleeping on the event service of the same name (if this output was
    /// created with `notify`). A separate call so the caller can timestamp the publish first.
    pub fn notify(&self) {
        if let Some(notifier) = &self.notifier {
            // A failed wake-up only delays a reader until its own timeout.
            let _ = notifier.notify();
        }
    }

    /// Samples that subscribers could not take so far (their buffers were full).
    pub fn lost(&self) -> u64 {
        self.lost.load(Ordering::Relaxed)
    }

    /// A handle on the loss counter, readable from another thread.
    pub fn lost_counter(&self) -> Arc<AtomicU64> {
        Arc::clone(&self.lost)
    }
}

/// The receiving side of one service.
pub struct Input<T: Debug + ZeroCopySend + Copy + 'static> {
    subscriber: Subscriber<Svc, T, ()>,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Input<T> {
    /// Samples this subscriber holds unread before it loses new ones.
    pub fn buffer_size(&self) -> usize {
        self.subscriber.buffer_size()
    }

    /// The oldest sample not yet taken, copied out of shared memory. Allocation-free.
    pub fn receive(&self) -> Result<Option<T>, TransportError> {
        match self.subscriber.receive() {
            Ok(Some(sample)) => Ok(Some(*sample.payload())),
            Ok(None) => Ok(None),
            Err(e) => Err(TransportError::Io {
                what: "receive",
                reason: format!("{e:?}"),
            }),
        }
    }
}

/// Sleeps until a publisher notifies (or a timeout passes).
pub struct Waker {
    listener: Listener<Svc>,
}

impl Waker {
    /// Wait up to `timeout` for a notification; consumes all pending ones.
    pub fn wait(&self, timeout: Duration) -> Result<(), TransportError> {
        self.listener
            .timed_wait(|_| {}, timeout)
            .map(|_| ())
            .map_err(|e| TransportError::Io {
                what: "wait",
                reason: format!("{e:?}"),
            })
    }

    /// Consume the pending notifications without waiting (after a [`WakeSet`] reported this
    /// waker: until then its descriptor stays readable).
    pub fn drain(&self) -> Result<(), TransportError> {
        self.listener
            .try_wait(|_| {})
            .map(|_| ())
            .map_err(|e| TransportError::Io {
                what: "wait",
                reason: format!("{e:?}"),
            })
    }

    fn fd(&self) -> std::os::fd::RawFd {
        // SAFETY: only read to register the descriptor with epoll; the listener owns it.
        unsafe { self.listener.file_descriptor().native_handle() }
    }
}

/// One thread sleeping until any of several [`Waker`]s is notified or a due time comes,
/// whichever is first: the hot thread of a daemon whose pipelines read several sensor drivers,
/// or sensor drivers and paced sources.
///
/// Written on epoll and a timerfd rather than iceoryx2 0.10's `WaitSet`, which rounds its
/// timeouts up to whole milliseconds (a 1 kHz source would be served up to a period late) and
/// allocates at every wake-up. A waker's descriptor stays registered until the waker is
/// dropped (closing it removes it from the set).
pub struct WakeSet {
    epoll: std::os::fd::OwnedFd,
    timer: std::os::fd::OwnedFd,
    timer_armed: bool,
}

/// The epoll tag of the timer (wakers are tagged with the caller's index).
const TIMER_TAG: u64 = u64::MAX;

impl WakeSet {
    /// An empty set.
    pub fn new() -> Result<Self, TransportError> {
        use std::os::fd::FromRawFd;
        let os = |what: &'static str| TransportError::Io {
            what,
            reason: std::io::Error::last_os_error().to_string(),
        };
        // SAFETY: plain system calls; each descriptor is owned as soon as it exists.
        let epoll = unsafe { libc::epoll_create1(libc::EPOLL_CLOEXEC) };
        if epoll < 0 {
            return Err(os("epoll_create1"));
        }
        let epoll = unsafe { std::os::fd::OwnedFd::from_raw_fd(epoll) };
        let timer = unsafe {
            libc::timerfd_create(
                libc::CLOCK_MONOTONIC,
                libc::TFD_CLOEXEC | libc::TFD_NONBLOCK,
            )
        };
        if timer < 0 {
            return Err(os("timerfd_create"));
        }
        let mut set = WakeSet {
            epoll,
            timer: unsafe { std::os::fd::OwnedFd::from_raw_fd(timer) },
            timer_armed: false,
        };
        set.register(set.timer.as_raw_fd(), TIMER_TAG)?;
        Ok(set)
    }

    /// Watch `waker`; [`wait`](Self::wait) reports it by `tag`.
    pub fn add(&mut self, waker: &Waker, tag: usize) -> Result<(), TransportError> {
        self.register(waker.fd(), tag as u64)
    }

    fn register(&mut self, fd: std::os::fd::RawFd, tag: u64) -> Result<(), TransportError> {
        let mut event = libc::epoll_event {
            events: libc::EPOLLIN as u32,
            u64: tag,
        };
        // SAFETY: `event` outlives the call; the kernel copies it.
        let rc =
            unsafe { libc::epoll_ctl(self.epoll.as_raw_fd(), libc::EPOLL_CTL_ADD, fd, &mut event) };
        if rc < 0 {
            return Err(TransportError::Io {
                what: "epoll_ctl",
                reason: std::io::Error::last_os_error().to_string(),
            });
        }
        Ok(())
    }

    /// Sleep until a watched waker has a notification, `due` comes (to the timer's precision,
    /// not epoll's millisecond) or `timeout` passes (rounded up to a millisecond); call
    /// `notified` with the tag of each waker that has one (then [`Waker::drain`] it). A
    /// signal ends the wait early, reporting nothing. Allocation-free.
    pub fn wait(
        &mut self,
        due: Option<std::time::Instant>,
        timeout: Duration,
        mut notified: impl FnMut(usize),
    ) -> Result<(), TransportError> {
        if let Some(due) = due {
            let until = due.saturating_duration_since(std::time::Instant::now());
            if until.is_zero() {
                return Ok(());
            }
            self.arm(until)?;
        } else if self.timer_armed {
            self.arm(Duration::ZERO)?;
        }
        let ms = timeout.as_nanos().div_ceil(1_000_000).min(i32::MAX as u128) as i32;
        let mut events = [libc::epoll_event { events: 0, u64: 0 }; 32];
        // SAFETY: the buffer holds `events.len()` entries.
        let n = unsafe {
            libc::epoll_wait(
                self.epoll.as_raw_fd(),
                events.as_mut_ptr(),
                events.len() as i32,
                ms,
            )
        };
        if n < 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() == std::io::ErrorKind::Interrupted {
                return Ok(());
            }
            return Err(TransportError::Io {
                what: "epoll_wait",
                reason: e.to_string(),
            });
        }
        for e in &events[..n as usize] {
            let tag = e.u64;
            if tag != TIMER_TAG {
                notified(tag as usize);
            }
        }
        Ok(())
    }

    /// Arm the timer to fire once after `after` (zero disarms it). Setting it also clears an
    /// expiry not yet read, so the timer is readable only when this wait's due time passed.
    fn arm(&mut self, after: Duration) -> Result<(), TransportError> {
        let spec = libc::itimerspec {
            it_interval: libc::timespec {
                tv_sec: 0,
                tv_nsec: 0,
            },
            it_value: libc::timespec {
                tv_sec: after.as_secs() as libc::time_t,
                tv_nsec: after.subsec_nanos() as libc::c_long,
            },
        };
        // SAFETY: `spec` outlives the call; the old value is not asked for.
        let rc = unsafe {
            libc::timerfd_settime(self.timer.as_raw_fd(), 0, &spec, std::ptr::null_mut())
        };
        if rc < 0 {
            return Err(TransportError::Io {
                what: "timerfd_settime",
                reason: std::io::Error::last_os_error().to_string(),
            });
        }
        self.timer_armed = !after.is_zero();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_layouts_are_the_documented_ones() {
        assert_eq!(std::mem::size_of::<RawSample>(), 48);
        assert_eq!(std::mem::align_of::<RawSample>(), 8);
        assert_eq!(std::mem::offset_of!(RawSample, rate), 16);
        assert_eq!(std::mem::offset_of!(RawSample, flags), 40);
        assert_eq!(std::mem::size_of::<GyroSample>(), 104);
        assert_eq!(std::mem::offset_of!(GyroSample, ingest_ns), 16);
        assert_eq!(std::mem::offset_of!(GyroSample, rate), 24);
        assert_eq!(std::mem::offset_of!(GyroSample, drift), 48);
        assert_eq!(std::mem::offset_of!(GyroSample, denoised), 72);
        assert_eq!(std::mem::offset_of!(GyroSample, flags), 96);
    }

    /// The bytes a bridge sends are the bytes in shared memory (on this little-endian host),
    /// and they decode back to the identical sample.
    #[test]
    fn wire_bytes_are_the_memory_layout_and_round_trip() {
        fn memory<T>(v: &T) -> Vec<u8> {
            // SAFETY: the wire types are repr(C) with no padding: every byte is initialised.
            unsafe {
                std::slice::from_raw_parts(v as *const T as *const u8, std::mem::size_of::<T>())
            }
            .to_vec()
        }
        let g = GyroSample {
            t_ns: 1,
            seq: u64::MAX - 3,
            ingest_ns: 0x0102_0304_0506_0708,
            rate: [1.5, -0.0, f64::MIN_POSITIVE],
            drift: [f64::MAX, 2e-300, -7.25],
            denoised: [0.1, 0.2, 0.3],
            flags: FLAG_STILL | FLAG_GAP_BEFORE,
            epoch: 0xdead_beef,
        };
        let r = RawSample {
            t_ns: 9,
            seq: 10,
            rate: [-1.0, 1e-9, 3.0],
            flags: RAW_INVALID,
            epoch: 77,
        };
        let mut out = Vec::new();
        g.encode(&mut out);
        assert_eq!(out.len(), GyroSample::SIZE);
        if cfg!(target_endian = "little") {
            assert_eq!(out, memory(&g));
        }
        assert_eq!(&out[8..16], &g.seq.to_le_bytes());
        assert_eq!(&out[96..100], &g.flags.to_le_bytes());
        assert_eq!(GyroSample::decode(&out), Some(g));
        assert_eq!(GyroSample::decode(&out[..103]), None);
        r.encode(&mut out);
        assert_eq!(out.len(), RawSample::SIZE);
        if cfg!(target_endian = "little") {
            assert_eq!(out, memory(&r));
        }
        assert_eq!(&out[44..48], &77u32.to_le_bytes());
        assert_eq!(RawSample::decode(&out), Some(r));
        assert_eq!(RawSample::decode(&[0; 104]), None);
    }

    #[test]
    fn stats_layout_is_the_documented_one() {
        assert_eq!(std::mem::size_of::<Percentiles>(), 40);
        assert_eq!(std::mem::size_of::<StageStats>(), 96);
        assert_eq!(std::mem::offset_of!(StageStats, compute), 56);
        assert_eq!(std::mem::offset_of!(StatsSnapshot, rate_hz), 24);
        assert_eq!(std::mem::offset_of!(StatsSnapshot, end_to_end), 88);
        assert_eq!(std::mem::offset_of!(StatsSnapshot, stage_count), 128);
        assert_eq!(std::mem::offset_of!(StatsSnapshot, stages), 136);
        assert_eq!(std::mem::size_of::<StatsSnapshot>(), 904);
    }

    #[test]
    fn type_names_are_stable() {
        // SAFETY: type_name only returns the static string of the derive attribute.
        unsafe {
            assert_eq!(RawSample::type_name(), RAW_TYPE_NAME);
            assert_eq!(GyroSample::type_name(), GYRO_TYPE_NAME);
            assert_eq!(StatsSnapshot::type_name(), STATS_TYPE_NAME);
        }
    }

    #[test]
    fn a_holder_reads_as_pid_executable_user_and_age() {
        let since = std::time::UNIX_EPOCH + Duration::from_secs(1_750_000_000);
        let h = NodeHolder {
            pid: 4242,
            executable: Some("driftless".into()),
            user: Some("alice".into()),
            since: Some((since, Duration::from_millis(303_900))),
        };
        assert_eq!(
            h.to_string(),
            "pid 4242 (driftless, user alice, since 2025-06-15T15:06:40Z, 5m 3s ago)"
        );
        let bare = NodeHolder {
            pid: 7,
            executable: None,
            user: None,
            since: None,
        };
        assert_eq!(bare.to_string(), "pid 7");
    }

    #[test]
    fn user_names_come_from_the_password_database() {
        assert_eq!(user_name(0).as_deref(), Some("root"));
    }
}
