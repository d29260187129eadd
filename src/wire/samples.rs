//! The samples: what a driver gives ([`RawSample`]), what every later hop carries
//! ([`GyroSample`]) and the vehicle's motion ([`StopSignal`]).

use super::flags::{
    RAW_ACCEL, RAW_MAG, SENSOR_ACCEL, SENSOR_ACCEL_INVALID, SENSOR_MAG, SENSOR_MAG_INVALID,
    SENSOR_ORIENTATION,
};

/// Type name of [`RawSample`] on the wire; `.v2` names the layout, as for [`GYRO_TYPE_NAME`].
pub const RAW_TYPE_NAME: &str = "driftless::RawSample.v2";
/// The layout version of [`RawSample`] (the `.vN` of [`RAW_TYPE_NAME`]).
pub const RAW_VERSION: u32 = 2;
/// The type name of [`RawSample`] version 1 (48 bytes, the gyro alone).
pub const RAW_V1_TYPE_NAME: &str = "driftless::RawSample";
/// Size of [`RawSample`] version 1, bytes.
pub const RAW_V1_SIZE: usize = 48;
/// Type name of [`GyroSample`] on the wire. The `.v4` names the layout: a layout change takes
/// a new name, so that a subscriber built for another one is refused by iceoryx2
/// (`IncompatibleTypes`) and by the Zenoh receivers, never handed bytes it misreads
/// ([`super::wire_version_mismatch`] words the refusal).
pub const GYRO_TYPE_NAME: &str = "driftless::GyroSample.v4";
/// The layout version of [`GyroSample`] (the `.vN` of [`GYRO_TYPE_NAME`]).
pub const GYRO_VERSION: u32 = 4;
/// The type name of [`GyroSample`] version 1 (104 bytes, before `drift_std`), as a driftless
/// before it publishes it.
pub const GYRO_V1_TYPE_NAME: &str = "driftless::GyroSample";
/// Size of [`GyroSample`] version 1, bytes.
pub const GYRO_V1_SIZE: usize = 104;
/// Size of [`GyroSample`] version 2, bytes (before the accelerometer and the magnetometer).
pub const GYRO_V2_SIZE: usize = 128;
/// Size of [`GyroSample`] version 3, bytes (before the orientation).
pub const GYRO_V3_SIZE: usize = 208;
/// Type name of [`StopSignal`] on the wire; `.v2` names the layout, as for [`GYRO_TYPE_NAME`].
pub const STOP_TYPE_NAME: &str = "driftless::StopSignal.v2";
/// The layout version of [`StopSignal`] (the `.vN` of [`STOP_TYPE_NAME`]).
pub const STOP_VERSION: u32 = 2;
/// The type name of [`StopSignal`] version 1 (24 bytes, before the yaw rate).
pub const STOP_V1_TYPE_NAME: &str = "driftless::StopSignal";
/// Size of [`StopSignal`] version 1, bytes.
pub const STOP_V1_SIZE: usize = 24;

/// [`StopSignal::clock`]: `t_ns` is CLOCK_MONOTONIC ns, the clock of `ingest_ns` (a live
/// publisher).
pub const STOP_CLOCK_MONOTONIC: u32 = 0;
/// [`StopSignal::clock`]: `t_ns` is on the clock of the samples' own `t_ns` (a replay's motion
/// logged beside the rates, e.g. a bag's odometry by its header stamps).
pub const STOP_CLOCK_SAMPLES: u32 = 1;

/// Whether the vehicle stands, and how it moves, as its own sensors say (wheel odometry, a
/// speed over ground, the drive's state): what a vehicle's process publishes for
/// `predict.bias`'s `stop_input` (56 bytes, 8-byte aligned; type name [`STOP_TYPE_NAME`],
/// layout version [`STOP_VERSION`]). Publish it whenever it is known, at any rate; the stage
/// reads the newest at each gyro sample and treats one older than its `stop_max_age_s` as
/// unknown. A yaw rate, where given, teaches the bias about the vehicle's up axis while it
/// drives (`vehicle_up`).
///
/// | offset | type | field |
/// |---:|---|---|
/// | 0 | u64 | `t_ns` when the state was measured: CLOCK_MONOTONIC ns ([`monotonic_ns`](crate::clock::monotonic_ns)), or the samples' own `t_ns` (`clock`) |
/// | 8 | f64 | `speed_m_s` speed, m/s (NaN: not measured) |
/// | 16 | u32 | `stopped` 1: stands, 0: moves, anything else: unknown |
/// | 20 | u32 | `clock` of `t_ns`: [`STOP_CLOCK_MONOTONIC`] (0) or [`STOP_CLOCK_SAMPLES`] (1) |
/// | 24 | f64 | `yaw_rate_rad_s` the vehicle's yaw rate about its up axis, rad/s, counter-clockwise seen from above positive (REP 103) (NaN: not measured) |
/// | 32 | f64 | `speed_std_m_s` 1-sigma of `speed_m_s`, m/s (NaN: not known) |
/// | 40 | f64 | `yaw_rate_std_rad_s` 1-sigma of `yaw_rate_rad_s`, rad/s (NaN: not known) |
/// | 48 | u64 | `period_ns` the yaw rate is the mean over the `period_ns` before `t_ns` (0: not said) |
///
/// [`StopSignal::new`] gives a signal with nothing measured but its stop word.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct StopSignal {
    /// When the state was measured, ns: on CLOCK_MONOTONIC (the clock of `ingest_ns`), or on
    /// the samples' own `t_ns` clock (`clock`).
    pub t_ns: u64,
    /// Speed, m/s; NaN when not measured.
    pub speed_m_s: f64,
    /// 1: the vehicle stands; 0: it moves; anything else: unknown.
    pub stopped: u32,
    /// The clock of `t_ns`: [`STOP_CLOCK_MONOTONIC`] (0, a live publisher's: what version 2
    /// wrote here before it had a name), or [`STOP_CLOCK_SAMPLES`] (a replay's logged motion,
    /// stamped as the samples it was logged beside).
    pub clock: u32,
    /// The vehicle's yaw rate about its up axis, rad/s (counter-clockwise seen from above is
    /// positive, REP 103); NaN when not measured.
    pub yaw_rate_rad_s: f64,
    /// Standard deviation (1 sigma) of `speed_m_s`, m/s; NaN when not known.
    pub speed_std_m_s: f64,
    /// Standard deviation (1 sigma) of `yaw_rate_rad_s`, rad/s; NaN when not known.
    pub yaw_rate_std_rad_s: f64,
    /// The period the yaw rate is the mean over, ns, ending at `t_ns`; 0 when not said.
    pub period_ns: u64,
}

impl StopSignal {
    /// A signal at `t_ns` with `speed_m_s` and the word `stopped`, no yaw rate, nothing else
    /// known.
    pub fn new(t_ns: u64, speed_m_s: f64, stopped: u32) -> Self {
        StopSignal {
            t_ns,
            speed_m_s,
            stopped,
            clock: STOP_CLOCK_MONOTONIC,
            yaw_rate_rad_s: f64::NAN,
            speed_std_m_s: f64::NAN,
            yaw_rate_std_rad_s: f64::NAN,
            period_ns: 0,
        }
    }
}

impl Default for StopSignal {
    /// Never stamped (`t_ns` 0: unknown), nothing measured.
    fn default() -> Self {
        StopSignal::new(0, f64::NAN, u32::MAX)
    }
}

/// A raw IMU sample as a sensor driver publishes it (96 bytes, 8-byte aligned; type name
/// [`RAW_TYPE_NAME`], layout version [`RAW_VERSION`]).
///
/// | offset | type | field |
/// |---:|---|---|
/// | 0 | u64 | `t_ns` sensor timestamp, ns |
/// | 8 | u64 | `seq` sequence number |
/// | 16 | `[f64; 3]` | `rate` x, y, z in the pipeline's `input_units` |
/// | 40 | u32 | `flags` ([`super::RAW_INVALID`], [`RAW_ACCEL`], [`RAW_MAG`], ...) |
/// | 44 | u32 | `epoch` the publisher's run id (see [`GyroSample::epoch`]); a driver may leave it 0 |
/// | 48 | `[f64; 3]` | `accel` specific force x, y, z in the pipeline's `accel_units`; read only with [`RAW_ACCEL`] |
/// | 72 | `[f64; 3]` | `mag` magnetic field x, y, z, tesla; read only with [`RAW_MAG`] |
///
/// The sensors beside the gyro are marked present by their flag, never by a value: a gyro-only
/// driver leaves the flags clear (and the fields 0). A present reading that is not finite is
/// flagged invalid downstream and the last good one held, as for the rate.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C)]
pub struct RawSample {
    /// Sensor timestamp in nanoseconds (any epoch, monotonic per sensor).
    pub t_ns: u64,
    /// Sequence number, +1 per sample; a jump is a gap.
    pub seq: u64,
    /// Angular rate per axis, in the pipeline's input units.
    pub rate: [f64; 3],
    /// Validity flags (bit 0: invalid) and which sensors the sample carries.
    pub flags: u32,
    /// The publisher's run id: when it changes, `seq` starts again (see [`GyroSample::epoch`]).
    /// A driver that sets it (any non-zero value per driver start) lets the daemon tell a
    /// driver restart from lost samples; 0 means "not given".
    pub epoch: u32,
    /// Specific force per axis (what an accelerometer measures), in the pipeline's
    /// `accel_units`; meaningful only when `flags` has [`RAW_ACCEL`].
    pub accel: [f64; 3],
    /// Magnetic field per axis, tesla; meaningful only when `flags` has [`RAW_MAG`].
    pub mag: [f64; 3],
}

impl RawSample {
    /// The accelerometer reading, when the sample carries one.
    pub fn accel_reading(&self) -> Option<[f64; 3]> {
        (self.flags & RAW_ACCEL != 0).then_some(self.accel)
    }

    /// The magnetometer reading, when the sample carries one.
    pub fn mag_reading(&self) -> Option<[f64; 3]> {
        (self.flags & RAW_MAG != 0).then_some(self.mag)
    }
}

/// `drift_std` on an axis where no stage estimated the drift's uncertainty (`predict.none`,
/// `predict.rbf`, a chain without a predict stage): "not provided", as ROS marks an unknown
/// covariance. Never NaN: a subscriber tests `< 0.0`. `accel_std` uses the same mark.
pub const DRIFT_STD_NOT_PROVIDED: f64 = -1.0;

/// A processed IMU sample: every hop after the ingest carries one (264 bytes, 8-byte aligned;
/// type name [`GYRO_TYPE_NAME`], layout version [`GYRO_VERSION`]). It is named for the gyro
/// it corrects; the accelerometer and magnetometer travel beside it, time-aligned.
///
/// | offset | type | field |
/// |---:|---|---|
/// | 0 | u64 | `t_ns` sensor timestamp of this sample, ns |
/// | 8 | u64 | `seq` sequence number, unchanged from the raw sample |
/// | 16 | u64 | `ingest_ns` CLOCK_MONOTONIC ns when the sample completing this output was ingested |
/// | 24 | `[f64; 3]` | `rate` corrected rate, rad/s (= denoised - drift) |
/// | 48 | `[f64; 3]` | `drift` drift estimate, rad/s |
/// | 72 | `[f64; 3]` | `denoised` denoised rate, rad/s |
/// | 96 | u32 | `flags` ([`super::FLAG_WARMING_UP`], [`super::FLAG_INPUT_INVALID`], ...) |
/// | 100 | u32 | `epoch` the stream's run id: `seq` counts within one epoch |
/// | 104 | `[f64; 3]` | `drift_std` 1-sigma of `drift`, rad/s; -1: not provided |
/// | 128 | `[f64; 3]` | `accel` specific force, m/s² (with [`SENSOR_ACCEL`]) |
/// | 152 | `[f64; 3]` | `accel_std` 1-sigma white noise of one `accel` sample, m/s²; -1: not provided |
/// | 176 | `[f64; 3]` | `mag` magnetic field, tesla (with [`SENSOR_MAG`]) |
/// | 200 | u32 | `sensors` which readings are present and valid ([`SENSOR_ACCEL`], ...) |
/// | 204 | u32 | `reserved` 0 |
/// | 208 | `[f64; 4]` | `orientation` quaternion x, y, z, w, body to earth (z up) (with [`SENSOR_ORIENTATION`]) |
/// | 240 | `[f64; 3]` | `orientation_std` 1-sigma about the earth's x, y, z, rad; -1: not provided |
///
/// Each version appends: every field of an older version keeps its offset (and the struct
/// needs no padding); the layout change is told by the type name, not by the offsets.
/// [`Default`] gives zeros, no sensor beside the gyro, no orientation (a zero quaternion, which
/// is no rotation) and every `_std` not provided.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct GyroSample {
    /// Sensor timestamp of this sample in nanoseconds.
    pub t_ns: u64,
    /// Sequence number, passed through every stage unchanged.
    pub seq: u64,
    /// CLOCK_MONOTONIC nanoseconds at the ingest of the sample that completed this output
    /// (see `monotonic_ns`); a subscriber on the same host measures its latency from it.
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
    /// Specific force per axis, m/s² (the accelerometer, converted from the pipeline's
    /// `accel_units`); meaningful only with [`SENSOR_ACCEL`]. As received unless a stage
    /// denoises it.
    pub accel: [f64; 3],
    /// Standard deviation (1 sigma) of one `accel` sample's white noise, m/s² (from the
    /// accelerometer's velocity random walk and the rate); [`DRIFT_STD_NOT_PROVIDED`] where no
    /// stage knows it.
    pub accel_std: [f64; 3],
    /// Magnetic field per axis, tesla; meaningful only with [`SENSOR_MAG`].
    pub mag: [f64; 3],
    /// Which readings beside the rate are present ([`SENSOR_ACCEL`], [`SENSOR_MAG`]) and which
    /// of those were not finite at the input, the last good value held
    /// ([`SENSOR_ACCEL_INVALID`], [`SENSOR_MAG_INVALID`]); and what the attitude stage said of
    /// the orientation ([`SENSOR_ORIENTATION`], ..., [`SENSOR_HEADING_ABSOLUTE`][absolute],
    /// [`SENSOR_MAG_REJECTED`][rejected]). New bits are appended; a reader ignores those it
    /// does not know.
    ///
    /// [absolute]: crate::wire::SENSOR_HEADING_ABSOLUTE
    /// [rejected]: crate::wire::SENSOR_MAG_REJECTED
    pub sensors: u32,
    /// Reserved, 0.
    pub reserved: u32,
    /// Orientation of the body, a unit quaternion (x, y, z, w: ROS's and scipy's order) that
    /// turns body coordinates into an earth frame whose z is up (ENU, REP 103); meaningful
    /// only with [`SENSOR_ORIENTATION`] (an attitude stage ran). The heading is relative (0
    /// where the filter started, for a 6D estimate has no north) unless
    /// [`SENSOR_HEADING_ABSOLUTE`][absolute] says the magnetometer made it absolute.
    ///
    /// [absolute]: crate::wire::SENSOR_HEADING_ABSOLUTE
    pub orientation: [f64; 4],
    /// Standard deviation (1 sigma) of the orientation's error as small rotations about the
    /// earth frame's x, y and z axes, rad: roll and pitch from gravity, and the heading's:
    /// relative, it grows from 0 at the start as the rate's uncertainty is integrated; absolute
    /// ([`SENSOR_HEADING_ABSOLUTE`][absolute]), the magnetometer heading filter's.
    /// [`DRIFT_STD_NOT_PROVIDED`] (-1) where not known.
    ///
    /// [absolute]: crate::wire::SENSOR_HEADING_ABSOLUTE
    pub orientation_std: [f64; 3],
}

impl Default for GyroSample {
    /// Zeros, with `drift_std`, `accel_std` and `orientation_std` not provided (a zero would
    /// claim them known exactly), no sensor beside the gyro and no orientation.
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
            accel: [0.0; 3],
            accel_std: [DRIFT_STD_NOT_PROVIDED; 3],
            mag: [0.0; 3],
            sensors: 0,
            reserved: 0,
            orientation: [0.0; 4],
            orientation_std: [DRIFT_STD_NOT_PROVIDED; 3],
        }
    }
}

impl GyroSample {
    /// The accelerometer reading, m/s², when the sample carries a valid one (present, and
    /// finite at the input: not a held value).
    pub fn accel_reading(&self) -> Option<[f64; 3]> {
        (self.sensors & (SENSOR_ACCEL | SENSOR_ACCEL_INVALID) == SENSOR_ACCEL).then_some(self.accel)
    }

    /// The magnetometer reading, tesla, when the sample carries a valid one.
    pub fn mag_reading(&self) -> Option<[f64; 3]> {
        (self.sensors & (SENSOR_MAG | SENSOR_MAG_INVALID) == SENSOR_MAG).then_some(self.mag)
    }

    /// The orientation (x, y, z, w), when an attitude stage gave one.
    pub fn orientation_estimate(&self) -> Option<[f64; 4]> {
        (self.sensors & SENSOR_ORIENTATION != 0).then_some(self.orientation)
    }
}
