//! One table per wire type: each field's name, place in the `#[repr(C)]` layout, unit,
//! presence bit, layout version, and what its consumers call it. The single source of truth
//! of the sample's fields.
//!
//! Generated from it: `tap`'s CSV columns and JSON keys, and the JSON Schemas of a recording's
//! channels. Checked against it by tests: the layout itself (`offset_of!`), the recording's
//! JSON forms, the ROS 2 mapping, and the layouts and Python `struct` formats that
//! docs/wire-types.md, docs/bridge.md and the examples print (`tests/wire_fields.rs`).

use super::flags::{
    FLAG_NAMES, RAW_ACCEL, RAW_FLAG_NAMES, RAW_MAG, SENSOR_ACCEL, SENSOR_MAG, SENSOR_NAMES,
    SENSOR_ORIENTATION,
};
use super::samples::{GyroSample, RawSample, StopSignal, DRIFT_STD_NOT_PROVIDED};
use super::stats::{OdometryStats, Percentiles, StageStats, StatsSnapshot, MAX_STATS_STAGES};
use FieldKind::{F64, U32, U64, U8};
use FieldUnit::{AccelUnits, Hz, InputUnits, MPerS, MPerS2, Ns, Rad, RadPerS, Tesla, Unitless};

/// What one element of a field is, in the little-endian layout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FieldKind {
    /// `u64`.
    U64,
    /// `u32`.
    U32,
    /// `f64`.
    F64,
    /// `u8` (text, NUL-padded).
    U8,
    /// A struct of its own table (`Percentiles`, `StageStats`).
    Struct(&'static FieldTable),
}

impl FieldKind {
    /// Bytes of one element.
    pub const fn size(self) -> usize {
        match self {
            FieldKind::U64 | FieldKind::F64 => 8,
            FieldKind::U32 => 4,
            FieldKind::U8 => 1,
            FieldKind::Struct(t) => t.size,
        }
    }
}

/// The unit of a field's values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldUnit {
    /// None: a count, an id, a word of flags, a unit quaternion.
    Unitless,
    /// Nanoseconds.
    Ns,
    /// Radians per second.
    RadPerS,
    /// The pipeline's `input_units` (a raw rate, as the driver gave it).
    InputUnits,
    /// Metres per second squared.
    MPerS2,
    /// The pipeline's `accel_units` (a raw accelerometer reading, as the driver gave it).
    AccelUnits,
    /// Tesla.
    Tesla,
    /// Radians.
    Rad,
    /// Metres per second.
    MPerS,
    /// Hertz.
    Hz,
}

impl FieldUnit {
    /// The unit as docs/wire-types.md writes it (empty for [`FieldUnit::Unitless`]).
    pub fn text(self) -> &'static str {
        match self {
            FieldUnit::Unitless => "",
            FieldUnit::Ns => "ns",
            FieldUnit::RadPerS => "rad/s",
            FieldUnit::InputUnits => "input_units",
            FieldUnit::MPerS2 => "m/s²",
            FieldUnit::AccelUnits => "accel_units",
            FieldUnit::Tesla => "T",
            FieldUnit::Rad => "rad",
            FieldUnit::MPerS => "m/s",
            FieldUnit::Hz => "Hz",
        }
    }
}

/// Which bit of which word of the same sample says a field is present.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Presence {
    /// The word's field name (`flags` in a raw sample, `sensors` in a gyro sample).
    pub word: &'static str,
    /// The bit ([`RAW_ACCEL`], [`SENSOR_ORIENTATION`], ...).
    pub bit: u32,
}

/// How `driftless tap` shows a field of a sample (besides the stamp, `epoch`, `seq` and
/// `t_ns`, which lead every line).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InTap {
    /// Not shown.
    Hidden,
    /// In the JSON lines only.
    Json,
    /// Its value (x, y, z ... columns), in CSV and JSON.
    Value,
    /// A word: its value, and the names of its set bits under this key (`flag_names`).
    ValueAndNames(&'static str),
    /// A word: only the names of its set bits.
    Names,
}

/// One field of a wire type.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Field {
    /// The Rust field's name; also docs/wire-types.md's, the Python examples' and `tap`'s.
    pub name: &'static str,
    /// Its byte offset in the `#[repr(C)]` layout (its `offset_of!`).
    pub offset: usize,
    /// What its elements are.
    pub kind: FieldKind,
    /// How many elements: 1 for a scalar, 3 for x, y, z, 4 for a quaternion x, y, z, w.
    pub len: usize,
    /// The unit of its values.
    pub unit: FieldUnit,
    /// The bit that says it is present; `None`: always.
    pub presence: Option<Presence>,
    /// The value that says "not provided" (`-1`, [`DRIFT_STD_NOT_PROVIDED`]), if it has one.
    pub not_provided: Option<f64>,
    /// The layout version it came in (1: the type's first layout).
    pub since: u32,
    /// Its key in the JSON forms of a recording (and of `stats --json`); `None`: not there.
    pub json: Option<&'static str>,
    /// What the recording's JSON Schema says of it (empty: nothing).
    pub about: &'static str,
    /// The names of its bits, for a word of flags.
    pub names: Option<&'static [(u32, &'static str)]>,
    /// How `tap` shows it.
    pub tap: InTap,
    /// The `sensor_msgs/msg/Imu` field it maps to (`ImuMapping`); `None`: none.
    pub ros2: Option<&'static str>,
}

impl Field {
    /// A field of `len` elements of `kind` at `offset`, in `unit`, since layout version
    /// `since`: always present, not in JSON, hidden from `tap`, not mapped to ROS 2.
    const fn new(
        name: &'static str,
        offset: usize,
        kind: FieldKind,
        len: usize,
        unit: FieldUnit,
        since: u32,
    ) -> Field {
        Field {
            name,
            offset,
            kind,
            len,
            unit,
            presence: None,
            not_provided: None,
            since,
            json: None,
            about: "",
            names: None,
            tap: InTap::Hidden,
            ros2: None,
        }
    }

    /// Present only with `bit` set in the field `word`.
    const fn present_with(self, word: &'static str, bit: u32) -> Field {
        Field {
            presence: Some(Presence { word, bit }),
            ..self
        }
    }

    /// `-1` says "not provided".
    const fn may_be_not_provided(self) -> Field {
        Field {
            not_provided: Some(DRIFT_STD_NOT_PROVIDED),
            ..self
        }
    }

    /// Recorded under `key`, described as `about`.
    const fn json(self, key: &'static str, about: &'static str) -> Field {
        Field {
            json: Some(key),
            about,
            ..self
        }
    }

    /// A word whose bits are `names`.
    const fn names(self, names: &'static [(u32, &'static str)]) -> Field {
        Field {
            names: Some(names),
            ..self
        }
    }

    /// Shown by `tap` as `tap` says.
    const fn tap(self, tap: InTap) -> Field {
        Field { tap, ..self }
    }

    /// Mapped to the Imu message's field `imu`.
    const fn ros2(self, imu: &'static str) -> Field {
        Field {
            ros2: Some(imu),
            ..self
        }
    }

    /// Its size, bytes.
    pub const fn size(&self) -> usize {
        self.kind.size() * self.len
    }

    /// A sample's `bytes` with this field's value changed: an integer moved on by 1000, a
    /// word's bit 20 flipped (no presence bit is), each float grown by half and moved by 1/8
    /// (a known standard deviation stays known). What tests change to see which output of a
    /// consumer (a JSON key, an Imu field) the field reaches.
    pub fn changed_in(&self, bytes: &[u8]) -> Vec<u8> {
        let mut out = bytes.to_vec();
        let at = &mut out[self.offset..self.offset + self.size()];
        match self.kind {
            FieldKind::U64 => {
                for x in at.chunks_exact_mut(8) {
                    let v = u64::from_le_bytes(x[..].try_into().expect("8 bytes"));
                    x.copy_from_slice(&v.wrapping_add(1000).to_le_bytes());
                }
            }
            FieldKind::U32 => {
                for x in at.chunks_exact_mut(4) {
                    x[2] ^= 0x10;
                }
            }
            FieldKind::F64 => {
                for x in at.chunks_exact_mut(8) {
                    let v = f64::from_le_bytes(x[..].try_into().expect("8 bytes"));
                    x.copy_from_slice(&(v * 1.5 + 0.125).to_le_bytes());
                }
            }
            FieldKind::U8 | FieldKind::Struct(_) => at.iter_mut().for_each(|b| *b ^= 1),
        }
        out
    }

    /// Its value in a sample's little-endian bytes (`WireBytes::encode`); `None` when the
    /// bytes are too short.
    pub fn read(&self, bytes: &[u8]) -> Option<FieldValue> {
        let b = bytes.get(self.offset..self.offset + self.size())?;
        let words = |n: usize| b.chunks_exact(n);
        Some(match self.kind {
            FieldKind::U64 => FieldValue::Ints(
                words(8)
                    .map(|w| u64::from_le_bytes(w.try_into().expect("8 bytes")))
                    .collect(),
            ),
            FieldKind::U32 => FieldValue::Ints(
                words(4)
                    .map(|w| u64::from(u32::from_le_bytes(w.try_into().expect("4 bytes"))))
                    .collect(),
            ),
            FieldKind::F64 => FieldValue::Floats(
                words(8)
                    .map(|w| f64::from_le_bytes(w.try_into().expect("8 bytes")))
                    .collect(),
            ),
            FieldKind::U8 | FieldKind::Struct(_) => FieldValue::Bytes(b.to_vec()),
        })
    }
}

/// A field's value, read from a sample's bytes ([`Field::read`]).
#[derive(Debug, Clone, PartialEq)]
pub enum FieldValue {
    /// The elements of a `u64` or `u32` field.
    Ints(Vec<u64>),
    /// The elements of an `f64` field.
    Floats(Vec<f64>),
    /// The bytes of a `u8` or struct field.
    Bytes(Vec<u8>),
}

/// The fields of one wire type, in layout order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldTable {
    /// The Rust type's name (`GyroSample`).
    pub name: &'static str,
    /// Its size, bytes (`size_of`).
    pub size: usize,
    /// Its fields, in layout order.
    pub fields: &'static [Field],
}

impl FieldTable {
    /// The table of `T`, named `name`, of `fields` in layout order.
    const fn of<T>(name: &'static str, fields: &'static [Field]) -> FieldTable {
        FieldTable {
            name,
            size: std::mem::size_of::<T>(),
            fields,
        }
    }

    /// The field named `name`.
    pub fn field(&self, name: &str) -> Option<&'static Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// Whether `f` is present in the sample of `bytes`: always, or by its bit.
    pub fn present(&self, f: &Field, bytes: &[u8]) -> bool {
        let Some(p) = f.presence else {
            return true;
        };
        match self.field(p.word).and_then(|w| w.read(bytes)) {
            Some(FieldValue::Ints(w)) => w.first().is_some_and(|w| w & u64::from(p.bit) != 0),
            _ => false,
        }
    }

    /// A sample's `bytes` with the presence bit of `f` cleared (unchanged for a field that is
    /// always present).
    pub fn without(&self, f: &Field, bytes: &[u8]) -> Vec<u8> {
        let mut out = bytes.to_vec();
        let Some((p, word)) = f.presence.and_then(|p| Some((p, self.field(p.word)?))) else {
            return out;
        };
        let at = &mut out[word.offset..word.offset + 4];
        let w = u32::from_le_bytes(at[..].try_into().expect("4 bytes")) & !p.bit;
        at.copy_from_slice(&w.to_le_bytes());
        out
    }

    /// The size of layout version `version` of this type: where the first field of a later
    /// version starts (the whole type for the current version).
    pub fn size_of_version(&self, version: u32) -> usize {
        self.fields
            .iter()
            .find(|f| f.since > version)
            .map_or(self.size, |f| f.offset)
    }
}

/// The sensor's time stamp, which leads both samples.
const SENSOR_TIME: Field = Field::new("t_ns", 0, U64, 1, Ns, 1)
    .json("t_ns", "sensor time, ns")
    .ros2("header.stamp");

/// A sample's `seq`, which follows its time, described as `about`.
const fn sequence(about: &'static str) -> Field {
    Field::new("seq", 8, U64, 1, Unitless, 1).json("seq", about)
}

/// A sample's angular rate at `offset`, in `unit`, recorded under `key`.
const fn angular_rate(offset: usize, unit: FieldUnit, key: &'static str) -> Field {
    let rate = Field::new("rate", offset, F64, 3, unit, 1).json(key, "");
    rate.tap(InTap::Value).ros2("angular_velocity")
}

/// A sample's `flags` at `offset`: bits of `names`, described as `about`.
const fn flags(offset: usize, names: &'static [(u32, &'static str)], about: &'static str) -> Field {
    let word = Field::new("flags", offset, U32, 1, Unitless, 1).json("flags", about);
    word.names(names).tap(InTap::ValueAndNames("flag_names"))
}

/// A sample's accelerometer reading at `offset`, in `unit`, since layout version `since`.
const fn accelerometer(offset: usize, unit: FieldUnit, since: u32) -> Field {
    let accel = Field::new("accel", offset, F64, 3, unit, since);
    accel.tap(InTap::Value).ros2("linear_acceleration")
}

/// A sample's `epoch` at `offset`.
const fn run_id(offset: usize) -> Field {
    Field::new("epoch", offset, U32, 1, Unitless, 1).json("epoch", "the stream's run id")
}

/// A sample's magnetometer reading at `offset`, since layout version `since`.
const fn magnetometer(offset: usize, since: u32) -> Field {
    Field::new("mag", offset, F64, 3, Tesla, since)
        .json("mag_t", "the magnetometer, tesla; absent: none")
}

/// The fields of [`RawSample`] (docs/wire-types.md, "Layouts").
pub const RAW_FIELDS: FieldTable = FieldTable::of::<RawSample>(
    "RawSample",
    &[
        SENSOR_TIME,
        sequence("sequence number, +1 per sample within an epoch"),
        angular_rate(16, InputUnits, "rate"),
        flags(
            40,
            &RAW_FLAG_NAMES,
            "0x1 invalid, 0x2 vehicle stopped, 0x4 vehicle moving, 0x8 stamp fault, 0x10 accel \
             present, 0x20 mag present",
        ),
        run_id(44),
        accelerometer(48, AccelUnits, 2)
            .present_with("flags", RAW_ACCEL)
            .json(
                "accel",
                "the accelerometer in the pipeline's accel_units; absent: no accelerometer",
            ),
        magnetometer(72, 2).present_with("flags", RAW_MAG),
    ],
);

/// The fields of [`GyroSample`] (docs/wire-types.md, "Layouts").
pub const GYRO_FIELDS: FieldTable = FieldTable::of::<GyroSample>(
    "GyroSample",
    &[
        SENSOR_TIME,
        sequence("sequence number, unchanged through every stage"),
        Field::new("ingest_ns", 16, U64, 1, Ns, 1)
            .json("ingest_ns", "CLOCK_MONOTONIC ns at the ingest")
            .tap(InTap::Json),
        angular_rate(24, RadPerS, "rate_rad_s"),
        Field::new("drift", 48, F64, 3, RadPerS, 1)
            .json("drift_rad_s", "")
            .tap(InTap::Value),
        Field::new("denoised", 72, F64, 3, RadPerS, 1)
            .json("denoised_rad_s", "")
            .tap(InTap::Value),
        flags(
            96,
            &FLAG_NAMES,
            "0x1 warming up, 0x2 input invalid, 0x4 gap before, 0x8 time backwards, 0x10 drained \
             at shutdown, 0x20 output repaired, 0x40 still, 0x80 moving, 0x100 stop signal \
             contradicted, 0x200 vehicle stopped, 0x400 vehicle moving, 0x800 stamp fault",
        ),
        run_id(100),
        Field::new("drift_std", 104, F64, 3, RadPerS, 2)
            .may_be_not_provided()
            .json(
                "drift_std_rad_s",
                "1-sigma of the drift estimate per axis, rad/s; -1: not provided (absent in \
                 recordings of GyroSample v1)",
            )
            .tap(InTap::Value)
            .ros2("angular_velocity_covariance"),
        accelerometer(128, MPerS2, 3)
            .present_with("sensors", SENSOR_ACCEL)
            .json(
                "accel_m_s2",
                "the accelerometer, m/s²; absent: no accelerometer",
            ),
        Field::new("accel_std", 152, F64, 3, MPerS2, 3)
            .present_with("sensors", SENSOR_ACCEL)
            .may_be_not_provided()
            .json(
                "accel_std_m_s2",
                "1-sigma white noise of one accelerometer sample, m/s²; -1: not provided",
            )
            .tap(InTap::Value)
            .ros2("linear_acceleration_covariance"),
        magnetometer(176, 3).present_with("sensors", SENSOR_MAG),
        Field::new("sensors", 200, U32, 1, Unitless, 3)
            .json(
                "sensors",
                "0x1 accel present, 0x2 mag present, 0x4 accel held (input not finite), 0x8 mag \
                 held, 0x10 orientation present, 0x20 orientation coasting (no accelerometer \
                 used), 0x40 free fall or shock, 0x80 heading absolute (from north, by the \
                 magnetometer), 0x100 magnetometer rejected (a disturbed field); absent: 0",
            )
            .names(&SENSOR_NAMES)
            .tap(InTap::Names),
        Field::new("reserved", 204, U32, 1, Unitless, 3),
        Field::new("orientation", 208, F64, 4, Unitless, 4)
            .present_with("sensors", SENSOR_ORIENTATION)
            .json(
                "orientation",
                "the orientation, body to an earth frame with z up (heading relative, absolute \
                 with sensors 0x80), a unit quaternion; absent: no attitude stage",
            )
            .tap(InTap::Value)
            .ros2("orientation"),
        Field::new("orientation_std", 240, F64, 3, Rad, 4)
            .present_with("sensors", SENSOR_ORIENTATION)
            .may_be_not_provided()
            .json(
                "orientation_std_rad",
                "1-sigma of the orientation about the earth's x, y, z, rad; -1: not provided",
            )
            .tap(InTap::Value)
            .ros2("orientation_covariance"),
    ],
);

/// The fields of [`StopSignal`] (docs/wire-types.md, "Layouts").
pub const STOP_FIELDS: FieldTable = FieldTable::of::<StopSignal>(
    "StopSignal",
    &[
        Field::new("t_ns", 0, U64, 1, Ns, 1),
        Field::new("speed_m_s", 8, F64, 1, MPerS, 1),
        Field::new("stopped", 16, U32, 1, Unitless, 1),
        Field::new("clock", 20, U32, 1, Unitless, 1),
        Field::new("yaw_rate_rad_s", 24, F64, 1, RadPerS, 2),
        Field::new("speed_std_m_s", 32, F64, 1, MPerS, 2),
        Field::new("yaw_rate_std_rad_s", 40, F64, 1, RadPerS, 2),
        Field::new("period_ns", 48, U64, 1, Ns, 2),
    ],
);

/// The fields of [`Percentiles`], a part of [`StatsSnapshot`]; keys as `stats --json` prints
/// them.
pub const PERCENTILES_FIELDS: FieldTable = FieldTable::of::<Percentiles>(
    "Percentiles",
    &[
        Field::new("count", 0, U64, 1, Unitless, 1).json("count", ""),
        Field::new("p50", 8, U64, 1, Ns, 1).json("p50", ""),
        Field::new("p99", 16, U64, 1, Ns, 1).json("p99", ""),
        Field::new("p999", 24, U64, 1, Ns, 1).json("p999", ""),
        Field::new("max", 32, U64, 1, Ns, 1).json("max", ""),
    ],
);

/// A count of a [`StatsSnapshot`] (or a stage's) at `offset` since version `since`, under the same JSON key.
const fn count(name: &'static str, offset: usize, since: u32) -> Field {
    Field::new(name, offset, U64, 1, Unitless, since).json(name, "")
}

/// A time of a [`StatsSnapshot`], ns, at `offset` since version `since`, under `key`.
const fn time(name: &'static str, offset: usize, since: u32, key: &'static str) -> Field {
    Field::new(name, offset, U64, 1, Ns, since).json(key, "")
}

/// The [`Percentiles`] of a [`StatsSnapshot`] at `offset`, under `key`.
const fn percentiles(name: &'static str, offset: usize, key: &'static str) -> Field {
    let kind = FieldKind::Struct(&PERCENTILES_FIELDS);
    Field::new(name, offset, kind, 1, Ns, 1).json(key, "")
}

/// The fields of [`StageStats`], a part of [`StatsSnapshot`].
pub const STAGE_STATS_FIELDS: FieldTable = FieldTable::of::<StageStats>(
    "StageStats",
    &[
        Field::new("name", 0, U8, 32, Unitless, 1).json("name", ""),
        count("samples_in", 32, 1),
        count("samples_out", 40, 1),
        count("lost", 48, 1),
        percentiles("compute", 56, "compute_ns"),
    ],
);

/// The fields of [`OdometryStats`], a part of [`StatsSnapshot`].
pub const ODOMETRY_STATS_FIELDS: FieldTable = FieldTable::of::<OdometryStats>(
    "OdometryStats",
    &[
        Field::new("up", 0, U64, 1, Unitless, 1).json("up", ""),
        Field::new("mounting", 8, U64, 1, Unitless, 1).json("mounting", ""),
        count("spans_accepted", 16, 1),
        count("spans_rejected", 24, 1),
        count("slips", 32, 1),
        count("learnt", 40, 1),
        Field::new("scale", 48, F64, 1, Unitless, 1).json("scale", ""),
        Field::new("scale_sd", 56, F64, 1, Unitless, 1).json("scale_sd", ""),
        Field::new("bias_learnt_rad_s", 64, F64, 1, RadPerS, 1).json("bias_learnt_rad_s", ""),
    ],
);

/// A [`StageStats`], as an element of a field.
const STAGES: FieldKind = FieldKind::Struct(&STAGE_STATS_FIELDS);

/// An [`OdometryStats`], as a field.
const ODOMETRY: FieldKind = FieldKind::Struct(&ODOMETRY_STATS_FIELDS);

/// The fields of [`StatsSnapshot`] (docs/wire-types.md, "Layouts"), with the keys of its JSON
/// form (`stats --json`, a recording's statistics channel; `a.b`: key `b` of object `a`).
pub const STATS_FIELDS: FieldTable = FieldTable::of::<StatsSnapshot>(
    "StatsSnapshot",
    &[
        time("uptime_ns", 0, 1, "uptime_ns"),
        count("samples_in", 8, 1),
        count("samples_out", 16, 1),
        Field::new("rate_hz", 24, F64, 1, Hz, 1).json("rate_hz", ""),
        count("deadline_misses", 32, 1),
        count("lost", 40, 1),
        count("flagged", 48, 1),
        count("gap_samples", 56, 1),
        count("metric_drops", 64, 1),
        time("deadline_ns", 72, 1, "deadline_ns"),
        time("algorithmic_delay_ns", 80, 1, "algorithmic_delay_ns"),
        percentiles("end_to_end", 88, "end_to_end_ns"),
        // Not in the JSON form: the length of its `stages`.
        Field::new("stage_count", 128, U64, 1, Unitless, 1),
        Field::new("stages", 136, STAGES, MAX_STATS_STAGES, Unitless, 1).json("stages", ""),
        count("deadline_misses_explained", 904, 2),
        time("last_miss_uptime_ns", 912, 2, "last_miss.uptime_ns"),
        time("last_miss_e2e_ns", 920, 2, "last_miss.e2e_ns"),
        time("last_miss_off_cpu_ns", 928, 2, "last_miss.off_cpu_ns"),
        count("stamp_faults", 936, 3),
        Field::new("warm_start", 944, U64, 1, Unitless, 3).json("warm_start", ""),
        Field::new("odometry", 952, ODOMETRY, 1, Unitless, 4).json("odometry", ""),
    ],
);

/// Every wire type's table, and its parts'.
pub const TABLES: [&FieldTable; 7] = [
    &RAW_FIELDS,
    &GYRO_FIELDS,
    &STOP_FIELDS,
    &STATS_FIELDS,
    &PERCENTILES_FIELDS,
    &STAGE_STATS_FIELDS,
    &ODOMETRY_STATS_FIELDS,
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::{
        WireBytes, GYRO_V1_SIZE, GYRO_V2_SIZE, GYRO_V3_SIZE, GYRO_VERSION, RAW_V1_SIZE,
        RAW_VERSION, STATS_V1_SIZE, STATS_V2_SIZE, STATS_V3_SIZE, STATS_VERSION, STOP_V1_SIZE,
        STOP_VERSION,
    };

    /// The table of `$ty` holds exactly the fields listed, each at its `offset_of!` with its
    /// `size_of_val`, in layout order, with no gap between them or after the last.
    macro_rules! the_table_is_the_layout {
        ($table:expr, $ty:ident { $($f:ident),+ $(,)? }) => {{
            let table: &FieldTable = &$table;
            let v = $ty::default();
            let rust = [$((
                stringify!($f),
                std::mem::offset_of!($ty, $f),
                std::mem::size_of_val(&v.$f),
            )),+];
            let ours: Vec<_> = table.fields.iter().map(|f| (f.name, f.offset, f.size())).collect();
            assert_eq!(ours, rust, "{}", table.name);
            assert_eq!(table.size, std::mem::size_of::<$ty>(), "{}", table.name);
            let mut end = 0;
            for f in table.fields {
                assert_eq!(f.offset, end, "{}.{}: a gap before it", table.name, f.name);
                end = f.offset + f.size();
            }
            assert_eq!(end, table.size, "{}: a gap after its last field", table.name);
        }};
    }

    #[test]
    fn every_table_is_its_types_layout() {
        the_table_is_the_layout!(
            RAW_FIELDS,
            RawSample {
                t_ns,
                seq,
                rate,
                flags,
                epoch,
                accel,
                mag
            }
        );
        the_table_is_the_layout!(
            GYRO_FIELDS,
            GyroSample {
                t_ns,
                seq,
                ingest_ns,
                rate,
                drift,
                denoised,
                flags,
                epoch,
                drift_std,
                accel,
                accel_std,
                mag,
                sensors,
                reserved,
                orientation,
                orientation_std
            }
        );
        the_table_is_the_layout!(
            STOP_FIELDS,
            StopSignal {
                t_ns,
                speed_m_s,
                stopped,
                clock,
                yaw_rate_rad_s,
                speed_std_m_s,
                yaw_rate_std_rad_s,
                period_ns
            }
        );
        the_table_is_the_layout!(
            STATS_FIELDS,
            StatsSnapshot {
                uptime_ns,
                samples_in,
                samples_out,
                rate_hz,
                deadline_misses,
                lost,
                flagged,
                gap_samples,
                metric_drops,
                deadline_ns,
                algorithmic_delay_ns,
                end_to_end,
                stage_count,
                stages,
                deadline_misses_explained,
                last_miss_uptime_ns,
                last_miss_e2e_ns,
                last_miss_off_cpu_ns,
                stamp_faults,
                warm_start,
                odometry
            }
        );
        the_table_is_the_layout!(
            ODOMETRY_STATS_FIELDS,
            OdometryStats {
                up,
                mounting,
                spans_accepted,
                spans_rejected,
                slips,
                learnt,
                scale,
                scale_sd,
                bias_learnt_rad_s
            }
        );
        the_table_is_the_layout!(
            PERCENTILES_FIELDS,
            Percentiles {
                count,
                p50,
                p99,
                p999,
                max
            }
        );
        the_table_is_the_layout!(
            STAGE_STATS_FIELDS,
            StageStats {
                name,
                samples_in,
                samples_out,
                lost,
                compute
            }
        );
    }

    /// Each older version's size is where the first field of a later version starts, and the
    /// newest field came in the current version.
    #[test]
    fn the_versions_are_the_tables_appends() {
        for (table, version, old) in [
            (&RAW_FIELDS, RAW_VERSION, &[RAW_V1_SIZE][..]),
            (
                &GYRO_FIELDS,
                GYRO_VERSION,
                &[GYRO_V1_SIZE, GYRO_V2_SIZE, GYRO_V3_SIZE],
            ),
            (
                &STATS_FIELDS,
                STATS_VERSION,
                &[STATS_V1_SIZE, STATS_V2_SIZE, STATS_V3_SIZE],
            ),
            (&STOP_FIELDS, STOP_VERSION, &[STOP_V1_SIZE][..]),
        ] {
            let sizes: Vec<usize> = (1..version).map(|v| table.size_of_version(v)).collect();
            assert_eq!(sizes, old, "{}", table.name);
            assert_eq!(table.size_of_version(version), table.size, "{}", table.name);
            let last = table.fields.iter().map(|f| f.since).max();
            assert_eq!(last, Some(version), "{}", table.name);
            // Versions only append.
            assert!(table.fields.windows(2).all(|w| w[0].since <= w[1].since));
        }
    }

    /// A presence bit names a word of the same table, a bit that word's names know; a word
    /// with names is a `u32`.
    #[test]
    fn presence_bits_are_named_bits_of_a_word_of_the_same_sample() {
        for table in TABLES {
            for f in table.fields {
                if let Some(p) = f.presence {
                    let word = table.field(p.word).expect(p.word);
                    let names = word.names.unwrap_or_else(|| panic!("{}: no names", p.word));
                    assert!(names.iter().any(|&(b, _)| b == p.bit), "{}", f.name);
                    assert!(
                        f.since > 1,
                        "{}: present by a bit, yet in version 1",
                        f.name
                    );
                }
                if f.names.is_some() {
                    assert_eq!((f.kind, f.len), (U32, 1), "{}", f.name);
                }
                if let Some(key) = f.json {
                    assert!(!key.is_empty(), "{}", f.name);
                }
            }
        }
    }

    #[test]
    fn fields_read_from_the_wire_bytes() {
        let g = GyroSample {
            t_ns: u64::MAX - 1,
            flags: 0x41,
            accel: [0.5, -1.5, 9.75],
            sensors: SENSOR_ACCEL,
            ..GyroSample::default()
        };
        let mut bytes = Vec::new();
        g.encode(&mut bytes);
        let read = |name: &str| GYRO_FIELDS.field(name).unwrap().read(&bytes).unwrap();
        assert_eq!(read("t_ns"), FieldValue::Ints(vec![u64::MAX - 1]));
        assert_eq!(read("flags"), FieldValue::Ints(vec![0x41]));
        assert_eq!(read("accel"), FieldValue::Floats(vec![0.5, -1.5, 9.75]));
        assert_eq!(read("drift_std"), FieldValue::Floats(vec![-1.0; 3]));
        let present = |name: &str| GYRO_FIELDS.present(GYRO_FIELDS.field(name).unwrap(), &bytes);
        assert!(present("accel") && present("accel_std") && present("rate"));
        assert!(!present("mag") && !present("orientation"));
        let accel = GYRO_FIELDS.field("accel").unwrap();
        let gone = GYRO_FIELDS.without(accel, &bytes);
        assert!(!GYRO_FIELDS.present(accel, &gone));
        let moved = accel.changed_in(&bytes);
        assert_eq!(
            accel.read(&moved),
            Some(FieldValue::Floats(vec![0.875, -2.125, 14.75]))
        );
        assert_eq!(
            (&moved[..128], &moved[152..]),
            (&bytes[..128], &bytes[152..])
        );
        let orientation_std = GYRO_FIELDS.field("orientation_std").unwrap();
        assert_eq!(orientation_std.read(&bytes[..263]), None);
    }
}
