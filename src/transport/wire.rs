//! The wire types: what crosses shared memory, byte for byte, and the flags that qualify it.
//!
//! All are `#[repr(C)]`, contain only `u64`/`u32`/`f64`/`u8` fields with no implicit padding,
//! and carry a stable iceoryx2 type name so that C, C++ or Python subscribers can open the
//! services with iceoryx2's own bindings (docs/wire-types.md). [`monotonic_ns`] is the clock
//! their `ingest_ns` stamps are read on.

use iceoryx2::prelude::*;

/// Raw-sample flag: the sensor driver marks the sample as invalid.
pub const RAW_INVALID: u32 = 1;
/// Raw-sample flag: the vehicle stands at this sample, by a signal logged with it (a replay's
/// stop column): a stop signal judged by sample time, not by wall-clock age.
pub const RAW_VEHICLE_STOPPED: u32 = 1 << 1;
/// Raw-sample flag: the vehicle moves at this sample (as [`RAW_VEHICLE_STOPPED`]). Neither:
/// unknown.
pub const RAW_VEHICLE_MOVING: u32 = 1 << 2;
/// Raw-sample flag: the source does not believe this sample's stamp (a ROS 2 stamp of 0, "not
/// set"; or a stamp its bridge judged as the guard would, [`crate::clock::StampCheck`]). The
/// guard flags it [`FLAG_STAMP_FAULT`] and counts it, never as a loss.
pub const RAW_STAMP_FAULT: u32 = 1 << 3;

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
/// Output flag (`predict.bias` with a stop signal): the vehicle said it stands while the gyro
/// clearly turned; the signal was not trusted for this sample (it counts as moving).
pub const FLAG_STOP_CONTRADICTED: u32 = 1 << 8;

/// Output flag: the raw sample said the vehicle stood ([`RAW_VEHICLE_STOPPED`], carried on
/// with the sample through every stage; `predict.bias` takes it as its stop signal).
pub const FLAG_VEHICLE_STOPPED: u32 = 1 << 9;
/// Output flag: the raw sample said the vehicle moved ([`RAW_VEHICLE_MOVING`]).
pub const FLAG_VEHICLE_MOVING: u32 = 1 << 10;
/// Output flag: the sensor's stamp was not believed (it went back, leapt more than 10 s ahead,
/// or was unset: [`crate::clock::StampCheck`]); `t_ns` is the source's as it came. A stamp that
/// went back also sets [`FLAG_TIME_BACKWARDS`].
pub const FLAG_STAMP_FAULT: u32 = 1 << 11;

/// The output flags by name, in bit order (`tap`, `record` and reports decode them with it).
pub const FLAG_NAMES: [(u32, &str); 12] = [
    (FLAG_WARMING_UP, "warming_up"),
    (FLAG_INPUT_INVALID, "input_invalid"),
    (FLAG_GAP_BEFORE, "gap_before"),
    (FLAG_TIME_BACKWARDS, "time_backwards"),
    (FLAG_FLUSHED, "flushed"),
    (FLAG_OUTPUT_REPAIRED, "output_repaired"),
    (FLAG_STILL, "still"),
    (FLAG_MOVING, "moving"),
    (FLAG_STOP_CONTRADICTED, "stop_contradicted"),
    (FLAG_VEHICLE_STOPPED, "vehicle_stopped"),
    (FLAG_VEHICLE_MOVING, "vehicle_moving"),
    (FLAG_STAMP_FAULT, "stamp_fault"),
];

/// The raw-sample flags by name, in bit order.
pub const RAW_FLAG_NAMES: [(u32, &str); 4] = [
    (RAW_INVALID, "invalid"),
    (RAW_VEHICLE_STOPPED, "vehicle_stopped"),
    (RAW_VEHICLE_MOVING, "vehicle_moving"),
    (RAW_STAMP_FAULT, "stamp_fault"),
];

/// Names of the output flags set in `flags` ([`FLAG_NAMES`]); a bit without a name reads as
/// its hex value, so nothing is hidden.
pub fn flag_names(flags: u32) -> Vec<String> {
    names_of(flags, &FLAG_NAMES)
}

/// Names of the raw-sample flags set in `flags` ([`RAW_FLAG_NAMES`]), as [`flag_names`].
pub fn raw_flag_names(flags: u32) -> Vec<String> {
    names_of(flags, &RAW_FLAG_NAMES)
}

fn names_of(flags: u32, table: &[(u32, &str)]) -> Vec<String> {
    let mut names = Vec::new();
    let mut rest = flags;
    for &(bit, name) in table {
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
/// Type name of [`GyroSample`] on the wire. The `.v2` names the layout: a layout change takes
/// a new name, so that a subscriber built for another one is refused by iceoryx2
/// (`IncompatibleTypes`) and by the Zenoh receivers, never handed bytes it misreads
/// ([`wire_version_mismatch`] words the refusal).
pub const GYRO_TYPE_NAME: &str = "driftless::GyroSample.v2";
/// The layout version of [`GyroSample`] (the `.vN` of [`GYRO_TYPE_NAME`]).
pub const GYRO_VERSION: u32 = 2;
/// The type name of [`GyroSample`] version 1 (104 bytes, before `drift_std`), as a driftless
/// before it publishes it.
pub const GYRO_V1_TYPE_NAME: &str = "driftless::GyroSample";
/// Size of [`GyroSample`] version 1, bytes.
pub const GYRO_V1_SIZE: usize = 104;
/// Type name of [`StatsSnapshot`] on the wire; `.v3` names the layout, as for
/// [`GYRO_TYPE_NAME`].
pub const STATS_TYPE_NAME: &str = "driftless::StatsSnapshot.v3";
/// The layout version of [`StatsSnapshot`] (the `.vN` of [`STATS_TYPE_NAME`]).
pub const STATS_VERSION: u32 = 3;
/// The type name of [`StatsSnapshot`] version 1 (904 bytes, before the misses' explanation).
pub const STATS_V1_TYPE_NAME: &str = "driftless::StatsSnapshot";
/// Size of [`StatsSnapshot`] version 1, bytes.
pub const STATS_V1_SIZE: usize = 904;
/// [`StatsSnapshot::last_miss_off_cpu_ns`] when it was not measured (an output after an
/// `external` stage, whose sample crossed threads): the miss cannot be explained.
pub const OFF_CPU_NOT_MEASURED: u64 = u64::MAX;
/// Type name of [`StopSignal`] on the wire.
pub const STOP_TYPE_NAME: &str = "driftless::StopSignal";

/// Whether the vehicle stands, as its own sensors say (wheel odometry, a speed over ground,
/// the drive's state): what a vehicle's process publishes for `predict.bias`'s `stop_input`
/// (24 bytes, 8-byte aligned). Publish it whenever it is known, at any rate; the stage reads the
/// newest at each gyro sample and treats one older than its `stop_max_age_s` as unknown.
///
/// | offset | type | field |
/// |---:|---|---|
/// | 0 | u64 | `t_ns` CLOCK_MONOTONIC ns when the state was measured ([`monotonic_ns`]) |
/// | 8 | f64 | `speed_m_s` speed, m/s (NaN: not measured) |
/// | 16 | u32 | `stopped` 1: stands, 0: moves, anything else: unknown |
/// | 20 | u32 | `reserved` 0 |
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
#[type_name("driftless::StopSignal")]
pub struct StopSignal {
    /// CLOCK_MONOTONIC nanoseconds when the state was measured (the clock of `ingest_ns`).
    pub t_ns: u64,
    /// Speed, m/s; NaN when not measured.
    pub speed_m_s: f64,
    /// 1: the vehicle stands; 0: it moves; anything else: unknown.
    pub stopped: u32,
    /// Reserved, 0.
    pub reserved: u32,
}

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

/// `drift_std` on an axis where no stage estimated the drift's uncertainty (`predict.none`,
/// `predict.rbf`, a chain without a predict stage): "not provided", as ROS marks an unknown
/// covariance. Never NaN: a subscriber tests `< 0.0`.
pub const DRIFT_STD_NOT_PROVIDED: f64 = -1.0;

/// A processed gyro sample: every hop after the ingest carries one (128 bytes, 8-byte aligned;
/// type name [`GYRO_TYPE_NAME`], layout version [`GYRO_VERSION`]).
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
/// | 104 | `[f64; 3]` | `drift_std` 1-sigma of `drift`, rad/s; -1: not provided |
///
/// `drift_std` comes last so that every field of version 1 keeps its offset (and the struct
/// needs no padding); the layout change is told by the type name, not by the offsets.
/// [`Default`] gives zeros with `drift_std` not provided.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("driftless::GyroSample.v2")]
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
    /// Standard deviation (1 sigma) of the drift estimate removed on each axis, rad/s: the
    /// bias filter's own (`predict.bias`). [`DRIFT_STD_NOT_PROVIDED`] (-1) where no stage
    /// estimates it (`predict.none`, `predict.rbf`, no predict stage); never NaN. Stages that
    /// do not estimate drift pass it through; one that resets `drift` to 0 resets it too.
    pub drift_std: [f64; 3],
}

impl Default for GyroSample {
    /// Zeros, with `drift_std` not provided (a zero would claim a drift known exactly).
    fn default() -> Self {
        GyroSample {
            t_ns: 0,
            seq: 0,
            ingest_ns: 0,
            rate: [0.0; 3],
            drift: [0.0; 3],
            denoised: [0.0; 3],
            flags: 0,
            epoch: 0,
            drift_std: [DRIFT_STD_NOT_PROVIDED; 3],
        }
    }
}

/// One of our wire types whose layout has changed.
struct Versioned {
    /// The type's name without the crate, as `driftless list` shows it.
    short: &'static str,
    /// Version 1's type name and size; version N > 1 is named `{v1}.vN`.
    v1: &'static str,
    v1_size: usize,
    /// The current version: its name, number and size, and what it added.
    name: &'static str,
    version: u32,
    size: usize,
    added: &'static str,
}

/// Every type whose layout has changed (docs/wire-types.md#versions).
const VERSIONED: [Versioned; 2] = [
    Versioned {
        short: "GyroSample",
        v1: GYRO_V1_TYPE_NAME,
        v1_size: GYRO_V1_SIZE,
        name: GYRO_TYPE_NAME,
        version: GYRO_VERSION,
        size: std::mem::size_of::<GyroSample>(),
        added: "drift_std",
    },
    Versioned {
        short: "StatsSnapshot",
        v1: STATS_V1_TYPE_NAME,
        v1_size: STATS_V1_SIZE,
        name: STATS_TYPE_NAME,
        version: STATS_VERSION,
        size: std::mem::size_of::<StatsSnapshot>(),
        added: "the stamp faults and the warm start",
    },
];

/// Which of our versioned types `type_name` is a layout version of, and which version; `None`
/// when it is not one of ours.
fn layout_version(type_name: &str) -> Option<(&'static Versioned, u32)> {
    VERSIONED.iter().find_map(|v| {
        let version = if type_name == v.v1 {
            1
        } else {
            type_name
                .strip_prefix(v.v1)?
                .strip_prefix(".v")?
                .parse::<u32>()
                .ok()?
        };
        Some((v, version))
    })
}

/// The short name (`GyroSample`) of the type whose other layout version `type_name` is; `None`
/// when it is ours in this release's layout, or not ours at all.
pub fn other_layout_of(type_name: &str) -> Option<&'static str> {
    layout_version(type_name)
        .filter(|(v, version)| *version != v.version)
        .map(|(v, _)| v.short)
}

/// The refusal of a payload type that is another layout version of one of ours (a
/// [`GyroSample`] or [`StatsSnapshot`] of an older or newer driftless), met as `what` (e.g.
/// `service "demo/corrected"`, or a Zenoh sample with its encoding); `None` when `type_name` is
/// ours or not a version of ours at all. The one place that knows the versions: `tap`,
/// `record`, `stats`, `bridge`, the transport's errors and the Zenoh receiver word their
/// refusal with it.
pub fn wire_version_mismatch(what: &str, type_name: &str) -> Option<String> {
    let (v, version) = layout_version(type_name)?;
    if version == v.version {
        return None;
    }
    let whose = if version < v.version {
        "an older"
    } else {
        "a newer"
    };
    let size = if version == 1 {
        format!(", {} bytes", v.v1_size)
    } else {
        String::new()
    };
    Some(format!(
        "{what} carries {type_name} (layout v{version}{size}, from {whose} driftless); this \
         driftless reads {} (layout v{}, {} bytes, with {}): run the daemon and its \
         subscribers from one release (docs/wire-types.md#versions)",
        v.name, v.version, v.size, v.added
    ))
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
    const SIZE: usize = 128;
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
        put_f64x3(out, &self.drift_std);
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
            drift_std: r.f64x3(),
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
    /// Time per sample: compute and the publish of the output.
    pub compute: Percentiles,
}

impl StageStats {
    /// Its name as text (up to the first NUL).
    pub fn name_text(&self) -> String {
        let end = self
            .name
            .iter()
            .position(|&b| b == 0)
            .unwrap_or(self.name.len());
        String::from_utf8_lossy(&self.name[..end]).into_owned()
    }
}

/// The daemon's statistics, published on the pipeline's stats service every report interval.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
#[type_name("driftless::StatsSnapshot.v3")]
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
    /// Flags raised on input and output: invalid input, gaps, stamp faults, repaired outputs.
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
    /// Of `deadline_misses`, those the kernel explains: the time it kept the hot thread off a
    /// CPU between the sample's ingest and its output covers the overshoot (version 2).
    pub deadline_misses_explained: u64,
    /// The latest miss: when, ns since the pipeline started (0: none yet).
    pub last_miss_uptime_ns: u64,
    /// The latest miss's end-to-end latency, ns.
    pub last_miss_e2e_ns: u64,
    /// The hot thread's time off a CPU during the latest miss, ns; [`OFF_CPU_NOT_MEASURED`]
    /// when not measured.
    pub last_miss_off_cpu_ns: u64,
    /// Of `flagged`, samples whose stamp was not believed ([`FLAG_STAMP_FAULT`]); never counted
    /// in `lost` (version 3).
    pub stamp_faults: u64,
    /// How the pipeline's state-keeping stage started: one of the `WARM_START_*` codes.
    pub warm_start: u64,
}

/// [`StatsSnapshot::warm_start`]: no stage of the pipeline keeps state across runs.
pub const WARM_START_NONE: u64 = 0;
/// [`StatsSnapshot::warm_start`]: resumed from the saved state.
pub const WARM_START_WARM: u64 = 1;
/// [`StatsSnapshot::warm_start`]: started cold: no saved state yet, or one too old to use.
pub const WARM_START_COLD: u64 = 2;
/// [`StatsSnapshot::warm_start`]: started cold because the saved state could not be used (it
/// was damaged or another sensor's); the file was moved aside.
pub const WARM_START_UNUSABLE: u64 = 3;

/// The words of a [`StatsSnapshot::warm_start`] code.
pub fn warm_start_name(code: u64) -> &'static str {
    match code {
        WARM_START_NONE => "none",
        WARM_START_WARM => "warm",
        WARM_START_COLD => "cold",
        WARM_START_UNUSABLE => "cold, the saved state unusable (moved aside)",
        _ => "unknown",
    }
}

impl StatsSnapshot {
    /// Whether the latest miss was the kernel's ([`crate::clock::miss_explained`]); `None`
    /// when there has been none.
    pub fn last_miss_explained(&self) -> Option<bool> {
        (self.last_miss_uptime_ns > 0).then(|| {
            crate::clock::miss_explained(
                self.last_miss_e2e_ns,
                self.last_miss_off_cpu(),
                self.deadline_ns,
            )
        })
    }

    /// The latest miss's time off a CPU, ns; `None` when not measured.
    pub fn last_miss_off_cpu(&self) -> Option<u64> {
        (self.last_miss_off_cpu_ns != OFF_CPU_NOT_MEASURED).then_some(self.last_miss_off_cpu_ns)
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
        assert_eq!(std::mem::size_of::<GyroSample>(), 128);
        assert_eq!(std::mem::align_of::<GyroSample>(), 8);
        assert_eq!(std::mem::offset_of!(GyroSample, ingest_ns), 16);
        assert_eq!(std::mem::offset_of!(GyroSample, rate), 24);
        assert_eq!(std::mem::offset_of!(GyroSample, drift), 48);
        assert_eq!(std::mem::offset_of!(GyroSample, denoised), 72);
        assert_eq!(std::mem::offset_of!(GyroSample, flags), 96);
        assert_eq!(std::mem::offset_of!(GyroSample, epoch), 100);
        assert_eq!(std::mem::offset_of!(GyroSample, drift_std), 104);
        // Version 1 was this layout up to `epoch`.
        assert_eq!(std::mem::offset_of!(GyroSample, drift_std), GYRO_V1_SIZE);
        assert_eq!(GyroSample::default().drift_std, [DRIFT_STD_NOT_PROVIDED; 3]);
    }

    #[test]
    fn another_layout_version_is_named_and_ours_is_not() {
        let old = wire_version_mismatch("service \"d/corrected\"", GYRO_V1_TYPE_NAME).unwrap();
        assert_eq!(
            old,
            "service \"d/corrected\" carries driftless::GyroSample (layout v1, 104 bytes, from \
             an older driftless); this driftless reads driftless::GyroSample.v2 (layout v2, 128 \
             bytes, with drift_std): run the daemon and its subscribers from one release \
             (docs/wire-types.md#versions)"
        );
        let stats = wire_version_mismatch("service \"d/stats\"", STATS_V1_TYPE_NAME).unwrap();
        assert_eq!(
            stats,
            "service \"d/stats\" carries driftless::StatsSnapshot (layout v1, 904 bytes, from \
             an older driftless); this driftless reads driftless::StatsSnapshot.v3 (layout v3, \
             952 bytes, with the stamp faults and the warm start): run the daemon and its \
             subscribers from one release (docs/wire-types.md#versions)"
        );
        assert_eq!(other_layout_of(STATS_V1_TYPE_NAME), Some("StatsSnapshot"));
        assert_eq!(other_layout_of(GYRO_V1_TYPE_NAME), Some("GyroSample"));
        assert_eq!(other_layout_of(GYRO_TYPE_NAME), None);
        let newer = wire_version_mismatch("key k", "driftless::GyroSample.v3").unwrap();
        assert!(
            newer.contains("(layout v3, from a newer driftless)"),
            "{newer}"
        );
        for not_a_version in [
            GYRO_TYPE_NAME,
            RAW_TYPE_NAME,
            STATS_TYPE_NAME,
            "driftless::GyroSample.vx",
            "driftless::GyroSampleX",
            "driftless::StatsSnapshotX",
            "other::GyroSample",
        ] {
            assert_eq!(
                wire_version_mismatch("s", not_a_version),
                None,
                "{not_a_version}"
            );
        }
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
            drift_std: [1e-5, DRIFT_STD_NOT_PROVIDED, 3.5e-7],
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
        assert_eq!(&out[104..112], &1e-5f64.to_le_bytes());
        assert_eq!(GyroSample::decode(&out), Some(g));
        assert_eq!(GyroSample::decode(&out[..127]), None);
        // A version 1 payload is refused, not read as a short version 2.
        assert_eq!(GyroSample::decode(&out[..GYRO_V1_SIZE]), None);
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
        assert_eq!(
            std::mem::offset_of!(StatsSnapshot, deadline_misses_explained),
            STATS_V1_SIZE
        );
        assert_eq!(
            std::mem::offset_of!(StatsSnapshot, last_miss_off_cpu_ns),
            928
        );
        // Version 3 appended two counts to version 2's 936 bytes.
        assert_eq!(std::mem::offset_of!(StatsSnapshot, stamp_faults), 936);
        assert_eq!(std::mem::size_of::<StatsSnapshot>(), 952);
    }

    #[test]
    fn type_names_are_stable() {
        // SAFETY: type_name only returns the static string of the derive attribute.
        unsafe {
            assert_eq!(RawSample::type_name(), RAW_TYPE_NAME);
            assert_eq!(GyroSample::type_name(), GYRO_TYPE_NAME);
            assert_eq!(StatsSnapshot::type_name(), STATS_TYPE_NAME);
            assert_eq!(StopSignal::type_name(), STOP_TYPE_NAME);
        }
        assert_eq!(std::mem::size_of::<StopSignal>(), 24);
        assert_eq!(std::mem::offset_of!(StopSignal, stopped), 16);
    }
}
