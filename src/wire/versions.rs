//! The layout versions of our wire types, and the one refusal of another version.

use super::samples::{
    GyroSample, RawSample, GYRO_TYPE_NAME, GYRO_V1_SIZE, GYRO_V1_TYPE_NAME, GYRO_V2_SIZE,
    GYRO_V3_SIZE, GYRO_VERSION, RAW_TYPE_NAME, RAW_V1_SIZE, RAW_V1_TYPE_NAME, RAW_VERSION,
    STOP_TYPE_NAME, STOP_V1_SIZE, STOP_V1_TYPE_NAME, STOP_VERSION,
};
use super::stats::{
    StatsSnapshot, STATS_TYPE_NAME, STATS_V1_SIZE, STATS_V1_TYPE_NAME, STATS_V2_SIZE,
    STATS_V3_SIZE, STATS_VERSION,
};
use super::StopSignal;

/// One of our wire types whose layout has changed.
struct Versioned {
    /// The type's name without the crate, as `driftless list` shows it.
    short: &'static str,
    /// Version 1's type name; version N > 1 is named `{v1}.vN`.
    v1: &'static str,
    /// The sizes of the earlier versions, bytes: version 1 first.
    old_sizes: &'static [usize],
    /// The current version: its name, number and size, and what it added.
    name: &'static str,
    version: u32,
    size: usize,
    added: &'static str,
}

/// Every type whose layout has changed (docs/wire-types.md#versions).
const VERSIONED: [Versioned; 4] = [
    Versioned {
        short: "RawSample",
        v1: RAW_V1_TYPE_NAME,
        old_sizes: &[RAW_V1_SIZE],
        name: RAW_TYPE_NAME,
        version: RAW_VERSION,
        size: std::mem::size_of::<RawSample>(),
        added: "the accelerometer and the magnetometer",
    },
    Versioned {
        short: "GyroSample",
        v1: GYRO_V1_TYPE_NAME,
        old_sizes: &[GYRO_V1_SIZE, GYRO_V2_SIZE, GYRO_V3_SIZE],
        name: GYRO_TYPE_NAME,
        version: GYRO_VERSION,
        size: std::mem::size_of::<GyroSample>(),
        added: "the orientation",
    },
    Versioned {
        short: "StatsSnapshot",
        v1: STATS_V1_TYPE_NAME,
        old_sizes: &[STATS_V1_SIZE, STATS_V2_SIZE, STATS_V3_SIZE],
        name: STATS_TYPE_NAME,
        version: STATS_VERSION,
        size: std::mem::size_of::<StatsSnapshot>(),
        added: "the odometry",
    },
    Versioned {
        short: "StopSignal",
        v1: STOP_V1_TYPE_NAME,
        old_sizes: &[STOP_V1_SIZE],
        name: STOP_TYPE_NAME,
        version: STOP_VERSION,
        size: std::mem::size_of::<StopSignal>(),
        added: "the yaw rate",
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
    let size = match (version as usize)
        .checked_sub(1)
        .and_then(|i| v.old_sizes.get(i))
    {
        Some(bytes) if version < v.version => format!(", {bytes} bytes"),
        _ => String::new(),
    };
    Some(format!(
        "{what} carries {type_name} (layout v{version}{size}, from {whose} driftless); this \
         driftless reads {} (layout v{}, {} bytes, with {}): run the daemon and its \
         subscribers from one release (docs/wire-types.md#versions)",
        v.name, v.version, v.size, v.added
    ))
}
