//! The MCAP recording format of `driftless record` (written) and `ingest.mcap` (read back): one
//! channel per recorded service, JSON messages with a JSON Schema each (what Foxglove opens and
//! plots without plugins), and a metadata record with the recording's counts.
//!
//! Layout (docs/wire-types.md, "Recordings (MCAP)"):
//! - topic `/<service>` (e.g. `/demo/corrected`), message encoding `json`, schema encoding
//!   `jsonschema`, schema named after the wire type: [`RAW_SCHEMA`], [`GYRO_SCHEMA`],
//!   [`STATS_SCHEMA`];
//! - log and publish time: the wall clock (CLOCK_REALTIME, ns) when the recorder took the sample;
//!   the sensor time is the message's `t_ns` (exact) and `t_s` (for plots);
//! - rates in rad/s as published (`rate_rad_s.x` ...); raw rates in the pipeline's input units,
//!   named by the channel's `rate_units` metadata, and raw accelerometer readings in its
//!   `accel_units`, named by `accel_units`;
//! - floats as Rust's shortest round-trip text, so every value reads back bit for bit; a
//!   non-finite raw rate (a replayed bad CSV row) is `null` and reads back as NaN;
//! - a metadata record [`METADATA_NAME`] written when the recording stops: per service the
//!   samples, sequence gaps and epochs, and how the recording ended;
//! - chunks compressed with LZ4 (zstd cost the recorder a quarter more CPU per sample, for
//!   files 40% smaller); the reader takes either, so a file rewritten by the `mcap` tools
//!   (`mcap recover` writes zstd) still replays.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Deserializer, Serialize};

use crate::wire::{
    Field, FieldKind, FieldTable, GyroSample, Percentiles, RawSample, StatsSnapshot,
    DRIFT_STD_NOT_PROVIDED, GYRO_FIELDS, RAW_ACCEL, RAW_FIELDS, RAW_MAG, SENSOR_ACCEL, SENSOR_MAG,
    SENSOR_ORIENTATION,
};

use super::mcap_file::{map_mcap, ChannelMessages, McapOpenError};

/// Message encoding of every channel.
pub const MESSAGE_ENCODING: &str = "json";
/// Schema encoding of every channel.
pub const SCHEMA_ENCODING: &str = "jsonschema";
/// Schema name of raw-sample channels.
pub const RAW_SCHEMA: &str = "driftless.RawSample";
/// Schema name of processed-sample channels (every hop after the ingest).
pub const GYRO_SCHEMA: &str = "driftless.GyroSample";
/// Schema name of statistics channels.
pub const STATS_SCHEMA: &str = "driftless.StatsSnapshot";
/// Name of the metadata record `driftless record` writes when it stops.
pub const METADATA_NAME: &str = "driftless.recording";
/// Channel metadata key naming the units of a raw channel's `rate`.
pub const RATE_UNITS_KEY: &str = "rate_units";
/// Channel metadata key naming the units of a raw channel's `accel`.
pub const ACCEL_UNITS_KEY: &str = "accel_units";
/// The recording format's version, in the metadata record. 2: statistics channels hold
/// [`StatsMessage`] (times in ns, as `driftless stats --json`); 1: they held times in s, ms
/// and us (`uptime_s`, `end_to_end_us`, ...).
pub const FORMAT_VERSION: &str = "2";

/// The MCAP topic of a service: `/` and the service name (Foxglove's convention).
pub fn topic(service: &str) -> String {
    format!("/{}", service.trim_start_matches('/'))
}

/// An x, y, z triple.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Xyz {
    /// x axis.
    #[serde(deserialize_with = "nan_if_null")]
    pub x: f64,
    /// y axis.
    #[serde(deserialize_with = "nan_if_null")]
    pub y: f64,
    /// z axis.
    #[serde(deserialize_with = "nan_if_null")]
    pub z: f64,
}

/// JSON has no NaN or infinity: serde_json writes them as `null`; read back as NaN.
fn nan_if_null<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

impl From<[f64; 3]> for Xyz {
    fn from(v: [f64; 3]) -> Self {
        Xyz {
            x: v[0],
            y: v[1],
            z: v[2],
        }
    }
}

impl From<Xyz> for [f64; 3] {
    fn from(v: Xyz) -> Self {
        [v.x, v.y, v.z]
    }
}

/// A quaternion (x, y, z, w) as recorded; a non-finite component is `null`, read back as NaN.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Xyzw {
    /// x.
    #[serde(deserialize_with = "nan_if_null")]
    pub x: f64,
    /// y.
    #[serde(deserialize_with = "nan_if_null")]
    pub y: f64,
    /// z.
    #[serde(deserialize_with = "nan_if_null")]
    pub z: f64,
    /// w (the scalar part).
    #[serde(deserialize_with = "nan_if_null")]
    pub w: f64,
}

impl From<[f64; 4]> for Xyzw {
    fn from(q: [f64; 4]) -> Self {
        Xyzw {
            x: q[0],
            y: q[1],
            z: q[2],
            w: q[3],
        }
    }
}

impl From<Xyzw> for [f64; 4] {
    fn from(q: Xyzw) -> Self {
        [q.x, q.y, q.z, q.w]
    }
}

/// A [`RawSample`] as recorded.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawMessage {
    /// Sequence number.
    pub seq: u64,
    /// The stream's epoch.
    pub epoch: u32,
    /// Sensor timestamp, ns (exact).
    pub t_ns: u64,
    /// Sensor timestamp, s (for plots).
    pub t_s: f64,
    /// Rates in the pipeline's input units (the channel's `rate_units`).
    pub rate: Xyz,
    /// Raw flags (bit 0: invalid).
    pub flags: u32,
    /// The accelerometer in the pipeline's `accel_units`; present exactly when `flags` has
    /// `RAW_ACCEL` (absent in gyro-only samples and in recordings of `RawSample` v1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accel: Option<Xyz>,
    /// The magnetometer, tesla; present exactly when `flags` has `RAW_MAG`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mag_t: Option<Xyz>,
}

impl From<&RawSample> for RawMessage {
    fn from(s: &RawSample) -> Self {
        RawMessage {
            seq: s.seq,
            epoch: s.epoch,
            t_ns: s.t_ns,
            t_s: s.t_ns as f64 * 1e-9,
            rate: s.rate.into(),
            flags: s.flags,
            accel: s.accel_reading().map(Into::into),
            mag_t: s.mag_reading().map(Into::into),
        }
    }
}

impl From<&RawMessage> for RawSample {
    fn from(m: &RawMessage) -> Self {
        RawSample {
            t_ns: m.t_ns,
            seq: m.seq,
            rate: m.rate.into(),
            // The readings say what is present, whatever the flags claimed.
            flags: (m.flags & !(RAW_ACCEL | RAW_MAG))
                | m.accel.map_or(0, |_| RAW_ACCEL)
                | m.mag_t.map_or(0, |_| RAW_MAG),
            epoch: m.epoch,
            accel: m.accel.map_or([0.0; 3], Into::into),
            mag: m.mag_t.map_or([0.0; 3], Into::into),
        }
    }
}

/// A [`GyroSample`] as recorded.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GyroMessage {
    /// Sequence number.
    pub seq: u64,
    /// The stream's epoch.
    pub epoch: u32,
    /// Sensor timestamp, ns (exact).
    pub t_ns: u64,
    /// Sensor timestamp, s (for plots).
    pub t_s: f64,
    /// CLOCK_MONOTONIC ns at the ingest of the sample that completed this output.
    pub ingest_ns: u64,
    /// Corrected rate, rad/s.
    pub rate_rad_s: Xyz,
    /// Drift estimate, rad/s.
    pub drift_rad_s: Xyz,
    /// Denoised rate, rad/s.
    pub denoised_rad_s: Xyz,
    /// Flags (`FLAG_*`).
    pub flags: u32,
    /// 1-sigma of the drift estimate, rad/s (-1: not provided). Absent in recordings made
    /// before `GyroSample` carried it (read as `None`, and as "not provided" on the wire).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drift_std_rad_s: Option<Xyz>,
    /// The accelerometer, m/s²; present exactly when `sensors` has `SENSOR_ACCEL` (absent in
    /// gyro-only streams and in recordings before `GyroSample` v3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accel_m_s2: Option<Xyz>,
    /// 1-sigma white noise of one accelerometer sample, m/s² (-1: not provided); with
    /// `accel_m_s2`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accel_std_m_s2: Option<Xyz>,
    /// The magnetometer, tesla; present exactly when `sensors` has `SENSOR_MAG`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mag_t: Option<Xyz>,
    /// The sensors word (`SENSOR_*`): which readings are present, which were held.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub sensors: u32,
    /// The orientation, body to earth (z up), x, y, z, w; present exactly when `sensors` has
    /// `SENSOR_ORIENTATION` (an attitude stage ran; absent before `GyroSample` v4).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orientation: Option<Xyzw>,
    /// 1-sigma of the orientation about the earth's x, y, z, rad (-1: not provided); with
    /// `orientation`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orientation_std_rad: Option<Xyz>,
}

fn is_zero(v: &u32) -> bool {
    *v == 0
}

impl From<&GyroSample> for GyroMessage {
    fn from(s: &GyroSample) -> Self {
        GyroMessage {
            seq: s.seq,
            epoch: s.epoch,
            t_ns: s.t_ns,
            t_s: s.t_ns as f64 * 1e-9,
            ingest_ns: s.ingest_ns,
            rate_rad_s: s.rate.into(),
            drift_rad_s: s.drift.into(),
            denoised_rad_s: s.denoised.into(),
            flags: s.flags,
            drift_std_rad_s: Some(s.drift_std.into()),
            accel_m_s2: (s.sensors & SENSOR_ACCEL != 0).then(|| s.accel.into()),
            accel_std_m_s2: (s.sensors & SENSOR_ACCEL != 0).then(|| s.accel_std.into()),
            mag_t: (s.sensors & SENSOR_MAG != 0).then(|| s.mag.into()),
            sensors: s.sensors,
            orientation: (s.sensors & SENSOR_ORIENTATION != 0).then(|| s.orientation.into()),
            orientation_std_rad: (s.sensors & SENSOR_ORIENTATION != 0)
                .then(|| s.orientation_std.into()),
        }
    }
}

impl From<&GyroMessage> for GyroSample {
    fn from(m: &GyroMessage) -> Self {
        GyroSample {
            t_ns: m.t_ns,
            seq: m.seq,
            ingest_ns: m.ingest_ns,
            rate: m.rate_rad_s.into(),
            drift: m.drift_rad_s.into(),
            denoised: m.denoised_rad_s.into(),
            flags: m.flags,
            epoch: m.epoch,
            drift_std: m
                .drift_std_rad_s
                .map_or([DRIFT_STD_NOT_PROVIDED; 3], Into::into),
            accel: m.accel_m_s2.map_or([0.0; 3], Into::into),
            accel_std: m
                .accel_std_m_s2
                .map_or([DRIFT_STD_NOT_PROVIDED; 3], Into::into),
            mag: m.mag_t.map_or([0.0; 3], Into::into),
            // The readings say what is present, whatever the word claimed.
            sensors: (m.sensors & !(SENSOR_ACCEL | SENSOR_MAG | SENSOR_ORIENTATION))
                | m.accel_m_s2.map_or(0, |_| SENSOR_ACCEL)
                | m.mag_t.map_or(0, |_| SENSOR_MAG)
                | m.orientation.map_or(0, |_| SENSOR_ORIENTATION),
            reserved: 0,
            orientation: m.orientation.map_or([0.0; 4], Into::into),
            orientation_std: m
                .orientation_std_rad
                .map_or([DRIFT_STD_NOT_PROVIDED; 3], Into::into),
        }
    }
}

/// Latency percentiles, ns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct PercentilesNs {
    /// Values recorded.
    pub count: u64,
    /// Median, ns.
    pub p50: u64,
    /// 99th percentile, ns.
    pub p99: u64,
    /// 99.9th percentile, ns.
    pub p999: u64,
    /// Maximum, ns.
    pub max: u64,
}

impl From<&Percentiles> for PercentilesNs {
    fn from(p: &Percentiles) -> Self {
        PercentilesNs {
            count: p.count,
            p50: p.p50,
            p99: p.p99,
            p999: p.p999,
            max: p.max,
        }
    }
}

/// One stage of a [`StatsMessage`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageMessage {
    /// Stage name.
    pub name: String,
    /// Samples in.
    pub samples_in: u64,
    /// Samples out.
    pub samples_out: u64,
    /// Samples subscribers of its output lost.
    pub lost: u64,
    /// Time per sample (compute and the publish of the output), ns.
    pub compute_ns: PercentilesNs,
}

/// The latest deadline miss of a [`StatsMessage`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LastMissMessage {
    /// When, ns since the pipeline started.
    pub uptime_ns: u64,
    /// Its end-to-end latency, ns.
    pub e2e_ns: u64,
    /// The hot thread's time off a CPU meanwhile, ns (`null`: not measured).
    pub off_cpu_ns: Option<u64>,
    /// Whether the kernel explains it.
    pub explained: bool,
}

/// What the odometry did for the bias filter, in a [`StatsMessage`] ([`crate::wire::OdometryStats`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OdometryMessage {
    /// The gyro axis that is the vehicle's up (`+z`, ...).
    pub up: String,
    /// The mounting check's verdict, in words.
    pub mounting: String,
    /// Spans that passed the slip test.
    pub spans_accepted: u64,
    /// Spans rejected.
    pub spans_rejected: u64,
    /// Slips caught (runs of rejected spans).
    pub slips: u64,
    /// Measurements the bias filter took.
    pub learnt: u64,
    /// The odometry's scale correction.
    #[serde(deserialize_with = "nan_if_null")]
    pub scale: f64,
    /// Its sd.
    #[serde(deserialize_with = "nan_if_null")]
    pub scale_sd: f64,
    /// The bias learnt in motion, rad/s.
    #[serde(deserialize_with = "nan_if_null")]
    pub bias_learnt_rad_s: f64,
}

/// A [`StatsSnapshot`] as JSON, the one form: what `driftless stats --json` and `tap --format
/// json` print (`stats` adds `pipeline`) and what a recording's statistics channel holds
/// (since recording format 2; format 1 had times in s, ms and us). Every field; times in ns;
/// `null` where there is nothing (`last_miss` before the first miss, `off_cpu_ns` not
/// measured, a non-finite `rate_hz`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StatsMessage {
    /// Nanoseconds since the pipeline started.
    pub uptime_ns: u64,
    /// Samples ingested.
    pub samples_in: u64,
    /// Samples published by the final stage.
    pub samples_out: u64,
    /// Ingest rate over the last interval, Hz.
    #[serde(deserialize_with = "nan_if_null")]
    pub rate_hz: f64,
    /// The deadline, ns.
    pub deadline_ns: u64,
    /// Outputs later than the deadline.
    pub deadline_misses: u64,
    /// Of `deadline_misses`, those the kernel explains.
    pub deadline_misses_explained: u64,
    /// The latest miss (`null` before the first).
    pub last_miss: Option<LastMissMessage>,
    /// Samples lost by subscribers of any service.
    pub lost: u64,
    /// Samples flagged.
    pub flagged: u64,
    /// Of `flagged`, samples whose stamp was not believed.
    pub stamp_faults: u64,
    /// How the state-keeping stage started, in words.
    pub warm_start: String,
    /// Sequence numbers missing in the input.
    pub gap_samples: u64,
    /// Metric records dropped.
    pub metric_drops: u64,
    /// Algorithmic delay of the chain, ns.
    pub algorithmic_delay_ns: u64,
    /// End-to-end latency, ns.
    pub end_to_end_ns: PercentilesNs,
    /// Per-stage statistics.
    pub stages: Vec<StageMessage>,
    /// What the odometry did (`null`: no stage uses a yaw rate; absent before format 4's
    /// statistics).
    #[serde(default)]
    pub odometry: Option<OdometryMessage>,
}

impl From<&StatsSnapshot> for StatsMessage {
    fn from(s: &StatsSnapshot) -> Self {
        let n = (s.stage_count as usize).min(s.stages.len());
        StatsMessage {
            uptime_ns: s.uptime_ns,
            samples_in: s.samples_in,
            samples_out: s.samples_out,
            rate_hz: s.rate_hz,
            deadline_ns: s.deadline_ns,
            deadline_misses: s.deadline_misses,
            deadline_misses_explained: s.deadline_misses_explained,
            last_miss: s.last_miss_explained().map(|explained| LastMissMessage {
                uptime_ns: s.last_miss_uptime_ns,
                e2e_ns: s.last_miss_e2e_ns,
                off_cpu_ns: s.last_miss_off_cpu(),
                explained,
            }),
            lost: s.lost,
            flagged: s.flagged,
            stamp_faults: s.stamp_faults,
            warm_start: crate::wire::warm_start_name(s.warm_start).to_string(),
            gap_samples: s.gap_samples,
            metric_drops: s.metric_drops,
            algorithmic_delay_ns: s.algorithmic_delay_ns,
            end_to_end_ns: (&s.end_to_end).into(),
            stages: s.stages[..n]
                .iter()
                .map(|st| StageMessage {
                    name: st.name_text(),
                    samples_in: st.samples_in,
                    samples_out: st.samples_out,
                    lost: st.lost,
                    compute_ns: (&st.compute).into(),
                })
                .collect(),
            odometry: (s.odometry.up != 0).then(|| OdometryMessage {
                up: s.odometry.up_name().to_string(),
                mounting: s.odometry.mounting_name().to_string(),
                spans_accepted: s.odometry.spans_accepted,
                spans_rejected: s.odometry.spans_rejected,
                slips: s.odometry.slips,
                learnt: s.odometry.learnt,
                scale: s.odometry.scale,
                scale_sd: s.odometry.scale_sd,
                bias_learnt_rad_s: s.odometry.bias_learnt_rad_s,
            }),
        }
    }
}

impl StatsMessage {
    /// `s` as a JSON value (`stats --json` adds the pipeline's name to it).
    pub fn json(s: &StatsSnapshot) -> serde_json::Value {
        // Plain numbers and strings: serde_json cannot refuse them (a NaN becomes null).
        serde_json::to_value(StatsMessage::from(s)).unwrap_or_default()
    }
}

const XYZ_DEF: &str = r#"{"type":"object","properties":{"x":{"type":["number","null"]},"y":{"type":["number","null"]},"z":{"type":["number","null"]}},"required":["x","y","z"]}"#;

/// The stamp that leads every recorded sample, in this order (`t_s` follows `t_ns`).
const STAMP: [&str; 3] = ["seq", "epoch", "t_ns"];

/// The JSON Schema of a sample's recorded form, generated from its table: a property per
/// field with a JSON key (the stamp first, then layout order), `t_s` beside `t_ns`. Required:
/// the fields of the type's first layout (a recording of an older one lacks later fields, and
/// a field present by a bit may be absent).
fn sample_schema(table: &FieldTable, title: &str, description: &str) -> String {
    let stamp = STAMP.iter().filter_map(|name| table.field(name));
    let rest = table.fields.iter().filter(|f| !STAMP.contains(&f.name));
    let (mut properties, mut required) = (Vec::new(), Vec::new());
    for f in stamp.chain(rest) {
        let Some(key) = f.json else {
            continue;
        };
        properties.push(format!("{}:{}", text(key), property(f)));
        if f.since == 1 && f.presence.is_none() {
            required.push(text(key));
        }
        if f.name == "t_ns" {
            properties.push(r#""t_s":{"type":"number","description":"sensor time, s"}"#.into());
            required.push(text("t_s"));
        }
    }
    format!(
        r#"{{"title":{},"description":{},"type":"object","properties":{{{}}},"required":[{}]}}"#,
        text(title),
        text(description),
        properties.join(","),
        required.join(",")
    )
}

/// `s` as a JSON string.
fn text(s: &str) -> String {
    serde_json::Value::from(s).to_string()
}

/// The JSON Schema of one field's recorded value: an integer, a number, or an object of axes
/// (x, y, z; a quaternion's w), each a number or `null` (not finite).
fn property(f: &Field) -> String {
    let described = |rest: &str| match f.about {
        "" => format!("{{{rest}}}"),
        about => format!(r#"{{{rest},"description":{}}}"#, text(about)),
    };
    match (f.kind, f.len) {
        (FieldKind::U64 | FieldKind::U32, 1) => described(r#""type":"integer""#),
        (FieldKind::F64, 1) => described(r#""type":["number","null"]"#),
        (FieldKind::F64, 3) if f.about.is_empty() => XYZ_DEF.to_string(),
        (FieldKind::F64, 3) => {
            format!(r#"{{"description":{},"allOf":[{XYZ_DEF}]}}"#, text(f.about))
        }
        (FieldKind::F64, len) => {
            let axes = &["x", "y", "z", "w"][..len.min(4)];
            let each: Vec<String> = axes
                .iter()
                .map(|a| format!(r#""{a}":{{"type":["number","null"]}}"#))
                .collect();
            let names: Vec<String> = axes.iter().map(|a| format!(r#""{a}""#)).collect();
            format!(
                r#"{{"description":{},"type":"object","properties":{{{}}},"required":[{}]}}"#,
                text(f.about),
                each.join(","),
                names.join(",")
            )
        }
        // No sample has such a field: any value.
        _ => "{}".to_string(),
    }
}

/// The JSON Schema of raw-sample channels (from [`RAW_FIELDS`]).
pub fn raw_schema() -> String {
    sample_schema(
        &RAW_FIELDS,
        RAW_SCHEMA,
        "A raw IMU sample as the ingest published it; rate in the pipeline's input_units \
         (channel metadata rate_units); null = not finite",
    )
}

/// The JSON Schema of processed-sample channels (from [`GYRO_FIELDS`]).
pub fn gyro_schema() -> String {
    sample_schema(
        &GYRO_FIELDS,
        GYRO_SCHEMA,
        "A processed IMU sample (denoised, drift, corrected rates in rad/s; the accelerometer \
         beside them in m/s²)",
    )
}

/// The JSON Schema of statistics channels.
pub fn stats_schema() -> String {
    const P: &str = r#"{"type":"object","properties":{"count":{"type":"integer"},"p50":{"type":"integer"},"p99":{"type":"integer"},"p999":{"type":"integer"},"max":{"type":"integer"}}}"#;
    format!(
        r#"{{"title":"{STATS_SCHEMA}","description":"The daemon's statistics snapshot, as driftless stats --json prints it; times in ns","type":"object","properties":{{"uptime_ns":{{"type":"integer"}},"samples_in":{{"type":"integer"}},"samples_out":{{"type":"integer"}},"rate_hz":{{"type":["number","null"]}},"deadline_ns":{{"type":"integer"}},"deadline_misses":{{"type":"integer"}},"deadline_misses_explained":{{"type":"integer","description":"of deadline_misses, those the time the kernel kept the hot thread off a CPU explains"}},"last_miss":{{"type":["object","null"],"description":"the latest deadline miss; null before the first","properties":{{"uptime_ns":{{"type":"integer"}},"e2e_ns":{{"type":"integer"}},"off_cpu_ns":{{"type":["integer","null"],"description":"null: not measured"}},"explained":{{"type":"boolean"}}}}}},"lost":{{"type":"integer"}},"flagged":{{"type":"integer"}},"stamp_faults":{{"type":"integer","description":"of flagged, samples whose stamp was not believed"}},"warm_start":{{"type":"string","description":"how the state-keeping stage started"}},"gap_samples":{{"type":"integer"}},"metric_drops":{{"type":"integer"}},"algorithmic_delay_ns":{{"type":"integer"}},"end_to_end_ns":{P},"stages":{{"type":"array","items":{{"type":"object","properties":{{"name":{{"type":"string"}},"samples_in":{{"type":"integer"}},"samples_out":{{"type":"integer"}},"lost":{{"type":"integer"}},"compute_ns":{P}}}}}}},"odometry":{{"type":["object","null"],"description":"what the vehicle's odometry did for the bias filter; null: no stage uses a yaw rate","properties":{{"up":{{"type":"string"}},"mounting":{{"type":"string"}},"spans_accepted":{{"type":"integer"}},"spans_rejected":{{"type":"integer"}},"slips":{{"type":"integer"}},"learnt":{{"type":"integer"}},"scale":{{"type":["number","null"]}},"scale_sd":{{"type":["number","null"]}},"bias_learnt_rad_s":{{"type":["number","null"]}}}}}}}}}}"#
    )
}

/// Counts of one recorded service, as the metadata record keeps them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ServiceCounts {
    /// Samples recorded.
    pub samples: u64,
    /// Sequence numbers missing between recorded samples, within an epoch.
    pub missing: u64,
    /// Jumps in `seq` (each missing one or more).
    pub gaps: u64,
    /// Epochs seen.
    pub epochs: u64,
    /// First and last (epoch, seq) recorded.
    pub first: Option<(u32, u64)>,
    /// Last (epoch, seq) recorded.
    pub last: Option<(u32, u64)>,
}

impl ServiceCounts {
    /// Count one sample's `(epoch, seq)`: a jump within an epoch is a gap; a new epoch starts
    /// counting again (a source or daemon restart, not a loss).
    pub fn count(&mut self, epoch: u32, seq: u64) {
        self.samples += 1;
        match self.last {
            Some((e, prev)) if e == epoch => {
                if seq > prev + 1 {
                    self.gaps += 1;
                    self.missing += seq - prev - 1;
                }
            }
            _ => self.epochs += 1,
        }
        self.first.get_or_insert((epoch, seq));
        self.last = Some((epoch, seq));
    }

    /// Count a sample without a sequence number (statistics snapshots).
    pub fn count_unsequenced(&mut self) {
        self.samples += 1;
    }

    /// The metadata entries of service `service`.
    pub fn metadata(&self, service: &str, out: &mut BTreeMap<String, String>) {
        let mut put = |k: &str, v: String| {
            out.insert(format!("{service}.{k}"), v);
        };
        put("samples", self.samples.to_string());
        if self.first.is_some() {
            put("missing", self.missing.to_string());
            put("gaps", self.gaps.to_string());
            put("epochs", self.epochs.to_string());
        }
        if let (Some((e0, s0)), Some((e1, s1))) = (self.first, self.last) {
            put("first", format!("epoch {e0} seq {s0}"));
            put("last", format!("epoch {e1} seq {s1}"));
        }
    }
}

/// A recording opened for reading: memory-mapped, its summary checked (a file without one is
/// truncated, still being written, or not an MCAP file).
pub struct Recording {
    path: PathBuf,
    map: memmap2::Mmap,
    summary: mcap::Summary,
}

/// A channel of a [`Recording`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelInfo {
    /// Its topic (`/` and the service name).
    pub topic: String,
    /// Its schema's name (e.g. [`RAW_SCHEMA`]), empty without a schema.
    pub schema: String,
    /// Its message encoding.
    pub encoding: String,
    /// Its metadata.
    pub metadata: BTreeMap<String, String>,
    /// Messages on it, from the summary's statistics.
    pub messages: u64,
}

impl Recording {
    /// Open and check `path`: an MCAP file with its summary and footer (what `driftless
    /// record` writes when it stops).
    pub fn open(path: &Path) -> Result<Recording, String> {
        let shown = path.display();
        let (map, summary) = map_mcap(path).map_err(|e| match e {
            McapOpenError::Io(e) => format!("{shown}: {e}"),
            McapOpenError::NotMcap(holds) => format!(
                "{shown}: not an MCAP file (no MCAP magic at its start): it holds {}",
                holds.what()
            ),
            McapOpenError::Incomplete(why) => format!(
                "{shown}: an incomplete MCAP file ({why}): truncated, or still being written; \
                 a complete recording ends with its summary and footer (recover the chunks of a \
                 killed recording with `mcap recover`)"
            ),
        })?;
        Ok(Recording {
            path: path.to_path_buf(),
            map,
            summary,
        })
    }

    /// The file's channels, by topic.
    pub fn channels(&self) -> Vec<ChannelInfo> {
        let counts = self
            .summary
            .stats
            .as_ref()
            .map(|s| &s.channel_message_counts);
        let mut out: Vec<ChannelInfo> = self
            .summary
            .channels
            .iter()
            .map(|(id, c)| ChannelInfo {
                topic: c.topic.clone(),
                schema: c.schema.as_ref().map_or(String::new(), |s| s.name.clone()),
                encoding: c.message_encoding.clone(),
                metadata: c.metadata.clone(),
                messages: counts.and_then(|m| m.get(id).copied()).unwrap_or(0),
            })
            .collect();
        out.sort_by(|a, b| a.topic.cmp(&b.topic));
        out
    }

    /// The metadata records named `name` (the recorder writes one, [`METADATA_NAME`]).
    pub fn metadata(&self, name: &str) -> Result<Vec<BTreeMap<String, String>>, String> {
        self.summary
            .metadata_indexes
            .iter()
            .filter(|i| i.name == name)
            .map(|i| {
                mcap::read::metadata(&self.map, i)
                    .map(|m| m.metadata)
                    .map_err(|e| format!("{}: metadata {name:?}: {e}", self.path.display()))
            })
            .collect()
    }

    /// The messages of `topic` in file order, decoded as `T` ([`RawMessage`], [`GyroMessage`],
    /// [`StatsMessage`]); an undecodable message or a corrupt chunk is an error naming the
    /// file, the topic and the message's index on the topic.
    pub fn messages<'a, T: serde::de::DeserializeOwned + 'a>(
        &'a self,
        topic: &'a str,
    ) -> impl Iterator<Item = Result<T, String>> + 'a {
        TopicMessages {
            shown: self.path.display().to_string(),
            topic,
            messages: ChannelMessages::of_topic(&self.map, &self.summary, topic),
            index: 0,
            _t: std::marker::PhantomData,
        }
    }
}

/// The messages of one topic of a recording, decoded, in file order.
struct TopicMessages<'a, T> {
    shown: String,
    topic: &'a str,
    messages: ChannelMessages<'a>,
    index: u64,
    _t: std::marker::PhantomData<T>,
}

impl<T: serde::de::DeserializeOwned> Iterator for TopicMessages<'_, T> {
    type Item = Result<T, String>;

    fn next(&mut self) -> Option<Self::Item> {
        let decoded = self
            .messages
            .next_with(|_, data| serde_json::from_slice::<T>(data));
        let (shown, topic) = (&self.shown, self.topic);
        Some(match decoded? {
            Ok(decoded) => {
                self.index += 1;
                let index = self.index;
                decoded.map_err(|e| format!("{shown}: message {index} of topic {topic}: {e}"))
            }
            Err(e) => Err(format!("{shown}: {e}")),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_read_back_bit_for_bit() {
        let raw = RawSample {
            t_ns: u64::MAX - 3,
            seq: 1 << 60,
            rate: [0.1 + 0.2, -0.0, f64::MIN_POSITIVE / 3.0],
            flags: 1 | RAW_ACCEL,
            epoch: u32::MAX,
            accel: [0.1 + 0.7, -9.80665, 1e-310],
            mag: [0.0; 3],
        };
        let text = serde_json::to_string(&RawMessage::from(&raw)).unwrap();
        let back: RawMessage = serde_json::from_str(&text).unwrap();
        let back = RawSample::from(&back);
        assert_eq!(back.t_ns, raw.t_ns);
        assert_eq!(back.seq, raw.seq);
        for (a, b) in back.rate.iter().zip(&raw.rate) {
            assert_eq!(a.to_bits(), b.to_bits(), "{text}");
        }
        assert_eq!(back.flags, raw.flags);
        assert_eq!(back.accel.map(f64::to_bits), raw.accel.map(f64::to_bits));
        assert_eq!(back.mag_reading(), None);
        let g = GyroSample {
            t_ns: 5,
            seq: 6,
            ingest_ns: 7,
            rate: [1e-300, -2.5e300, std::f64::consts::PI],
            drift: [1.0 / 3.0, 2.0 / 3.0, -1.0 / 7.0],
            denoised: [0.1, 0.2, 0.3],
            flags: 0x41,
            epoch: 9,
            drift_std: [2.5e-5, DRIFT_STD_NOT_PROVIDED, 1.0 / 9.0],
            accel: [0.3, -0.1, 9.81],
            accel_std: [1e-3, 2e-3, DRIFT_STD_NOT_PROVIDED],
            mag: [2e-5, 0.0, -4e-5],
            sensors: SENSOR_ACCEL
                | SENSOR_MAG
                | SENSOR_ORIENTATION
                | crate::wire::SENSOR_ORIENTATION_COASTING,
            reserved: 0,
            orientation: [0.1 + 0.2, -0.5, 0.5, (1.0f64 - 0.34 - 0.25 - 0.25).sqrt()],
            orientation_std: [1e-3 / 3.0, 2e-3, 0.7],
        };
        let text = serde_json::to_string(&GyroMessage::from(&g)).unwrap();
        let back: GyroMessage = serde_json::from_str(&text).unwrap();
        assert_eq!(GyroSample::from(&back), g);
        // A recording made before the field (and before the accelerometer): read, the
        // uncertainty not provided, gyro-only.
        let old = text
            .split(r#","drift_std_rad_s""#)
            .next()
            .unwrap()
            .to_string()
            + "}";
        assert!(!old.contains("drift_std"), "{old}");
        let back: GyroMessage = serde_json::from_str(&old).expect(&old);
        assert_eq!(back.drift_std_rad_s, None);
        assert_eq!(
            GyroSample::from(&back),
            GyroSample {
                drift_std: [DRIFT_STD_NOT_PROVIDED; 3],
                accel: [0.0; 3],
                accel_std: [DRIFT_STD_NOT_PROVIDED; 3],
                mag: [0.0; 3],
                sensors: 0,
                orientation: [0.0; 4],
                orientation_std: [DRIFT_STD_NOT_PROVIDED; 3],
                ..g
            }
        );
    }

    #[test]
    fn a_non_finite_raw_rate_is_null_and_reads_back_as_nan() {
        let raw = RawSample {
            rate: [f64::NAN, f64::INFINITY, 1.0],
            ..RawSample::default()
        };
        let text = serde_json::to_string(&RawMessage::from(&raw)).unwrap();
        assert!(
            text.contains(r#""rate":{"x":null,"y":null,"z":1.0}"#),
            "{text}"
        );
        let back: RawMessage = serde_json::from_str(&text).unwrap();
        assert!(back.rate.x.is_nan() && back.rate.y.is_nan());
    }

    #[test]
    fn the_stats_form_is_what_stats_json_printed_and_reads_back() {
        use crate::wire::{StageStats, WARM_START_WARM};
        let pct = |base: u64| Percentiles {
            count: base,
            p50: base + 1,
            p99: base + 2,
            p999: base + 3,
            max: base + 4,
        };
        let mut name = [0u8; 32];
        name[..7].copy_from_slice(b"denoise");
        let mut s = StatsSnapshot {
            uptime_ns: 1_500_000_000,
            samples_in: 10,
            samples_out: 9,
            rate_hz: 999.5,
            deadline_misses: 2,
            lost: 3,
            flagged: 4,
            gap_samples: 5,
            metric_drops: 6,
            deadline_ns: 1_000_000,
            algorithmic_delay_ns: 64_000_000,
            end_to_end: pct(100),
            stage_count: 1,
            deadline_misses_explained: 1,
            last_miss_uptime_ns: 1_200_000_000,
            last_miss_e2e_ns: 1_800_000,
            last_miss_off_cpu_ns: crate::wire::OFF_CPU_NOT_MEASURED,
            stamp_faults: 7,
            warm_start: WARM_START_WARM,
            ..StatsSnapshot::default()
        };
        s.stages[0] = StageStats {
            name,
            samples_in: 10,
            samples_out: 9,
            lost: 0,
            compute: pct(200),
        };
        // What `metrics::snapshot_json` printed for `stats --json` before this form.
        let p = |b: u64| serde_json::json!({"count": b, "p50": b + 1, "p99": b + 2, "p999": b + 3, "max": b + 4});
        let was = serde_json::json!({
            "uptime_ns": 1_500_000_000u64, "samples_in": 10, "samples_out": 9, "rate_hz": 999.5,
            "deadline_ns": 1_000_000, "deadline_misses": 2, "deadline_misses_explained": 1,
            "last_miss": {"uptime_ns": 1_200_000_000u64, "e2e_ns": 1_800_000, "off_cpu_ns": null,
                          "explained": false},
            "lost": 3, "flagged": 4, "stamp_faults": 7, "warm_start": "warm", "gap_samples": 5,
            "metric_drops": 6, "algorithmic_delay_ns": 64_000_000, "end_to_end_ns": p(100),
            "stages": [{"name": "denoise", "samples_in": 10, "samples_out": 9, "lost": 0,
                        "compute_ns": p(200)}],
            "odometry": null,
        });
        assert_eq!(StatsMessage::json(&s), was);
        // A recording's message reads back to the same.
        let text = serde_json::to_string(&StatsMessage::from(&s)).unwrap();
        let back: StatsMessage = serde_json::from_str(&text).unwrap();
        assert_eq!(back, StatsMessage::from(&s));
        // Before the first miss, and a rate that is not finite: null.
        s.last_miss_uptime_ns = 0;
        s.rate_hz = f64::NAN;
        let v = StatsMessage::json(&s);
        assert_eq!(v["last_miss"], serde_json::Value::Null);
        assert_eq!(v["rate_hz"], serde_json::Value::Null);
        let back: StatsMessage = serde_json::from_str(&v.to_string()).unwrap();
        assert!(back.rate_hz.is_nan() && back.last_miss.is_none());
        // With the odometry: every field, in words where it is a code.
        s.rate_hz = 999.5;
        s.odometry = crate::wire::OdometryStats {
            up: 6,
            mounting: crate::wire::MOUNTING_CONFIRMED,
            spans_accepted: 40,
            spans_rejected: 3,
            slips: 1,
            learnt: 38,
            scale: -0.0125,
            scale_sd: 0.002,
            bias_learnt_rad_s: 0.0087,
        };
        let v = StatsMessage::json(&s);
        assert_eq!(
            v["odometry"],
            serde_json::json!({"up": "-z", "mounting": "confirmed", "spans_accepted": 40,
                "spans_rejected": 3, "slips": 1, "learnt": 38, "scale": -0.0125,
                "scale_sd": 0.002, "bias_learnt_rad_s": 0.0087})
        );
        let back: StatsMessage = serde_json::from_str(&v.to_string()).unwrap();
        assert_eq!(back, StatsMessage::from(&s));
        // A recording from before the odometry reads as none.
        let mut old = v.clone();
        old.as_object_mut().unwrap().remove("odometry");
        let back: StatsMessage = serde_json::from_str(&old.to_string()).unwrap();
        assert_eq!(back.odometry, None);
    }

    #[test]
    fn schemas_are_json() {
        for s in [raw_schema(), gyro_schema(), stats_schema()] {
            let v: serde_json::Value = serde_json::from_str(&s).expect(&s);
            assert_eq!(v["type"], "object");
        }
    }

    #[test]
    fn gaps_count_within_an_epoch_only() {
        let mut c = ServiceCounts::default();
        for (e, s) in [(1, 5), (1, 6), (1, 9), (2, 0), (2, 1), (2, 3)] {
            c.count(e, s);
        }
        assert_eq!((c.samples, c.gaps, c.missing, c.epochs), (6, 2, 3, 2));
        assert_eq!((c.first, c.last), (Some((1, 5)), Some((2, 3))));
    }
}
