//! `ingest.mcap`: replay the raw samples of a recording made by `driftless record` (an MCAP file,
//! [`crate::io::recording`]), or the `sensor_msgs/msg/Imu` topic of a ROS 2 bag (an MCAP file
//! or a rosbag2 directory, [`crate::transport::ros2`]), in real time or as fast as possible,
//! optionally looping.
//!
//! A recording's samples enter the pipeline as they were recorded (`seq`, `t_ns`, `epoch`,
//! rates and flags bit for bit), so replaying a recording of a pipeline's raw service through
//! the same stages reproduces what that pipeline published. A bag's message `n` (from 1) enters
//! as `seq` n - 1, `t_ns` its `header.stamp`, `rate` its `angular_velocity` (rad/s: the
//! pipeline's `input_units` must be rad/s), `accel` its `linear_acceleration` with
//! `RAW_ACCEL` unless the message marks it not provided (covariance element 0 = -1; m/s^2: the
//! pipeline's `accel_units` must be m/s^2), `epoch` 0. A message that does not decode enters
//! as an invalid sample (`RAW_INVALID`, its time held, said on stderr): the daemon flags it
//! and keeps serving; a stamp going backwards or leaping enters as it is and is flagged
//! downstream (`stamp_fault`, [`crate::clock::StampCheck`]); a stamp of 0 ("not set") or
//! before 1970 enters with the time held, flagged [`RAW_STAMP_FAULT`]. On later passes of a loop, `seq` and `t_ns` are shifted to keep rising.
//!
//! Validation opens the file (its summary and footer: a truncated file or one still being
//! written fails there), finds the topic and decodes its first [`CHECKED_MESSAGES`] messages (a
//! bag's stamps must give the pipeline's rate within 1 %); the run streams the file chunk by
//! chunk from a reader thread.
//!
//! ```toml
//! [[stage]]
//! name = "sensor"
//! kind = "ingest.mcap"
//! output = "demo/raw"
//! file = "run.mcap"          # relative to the pipeline file
//! topic = "demo/raw"         # default: the file's only raw-sample topic (a bag: Imu topic)
//! pace = "asap"              # or "realtime" (default), or 10.0: ten times real time
//! loop = false
//! # stop_topic = "/odom"     # a bag's vehicle motion (Odometry, twists) as logged stops
//! # stop_speed = 0.02        # m/s: stands at or below (default 0.02)
//! # stop_max_age_s = 0.5     # the last motion message older than this: unknown
//! # motion_output = "vehicle/stop"  # the motion as StopSignals too (its yaw rate), for predict.bias
//! # mag_topic = "/imu/mag"   # a bag's sensor_msgs/msg/MagneticField, joined by stamp
//! # mag_max_age_s = 0.1      # a reading older than this joins no sample
//! ```
//!
//! **Logged stops from a bag.** With `stop_topic`, each Imu sample carries the vehicle's state
//! from the motion topic's last message at or before its stamp (by `header.stamp`, not the
//! clock of the replay): `vehicle_stopped` at or below `stop_speed`, `vehicle_moving` above,
//! neither when that message is older than `stop_max_age_s` or there is none.
//! `predict.bias` takes them as its stop signal at the sample's own time, as it takes a CSV's
//! `stop_column`. The motion messages are read before the replay starts (32 bytes each: 58 MB
//! for 10 hours of 50 Hz odometry), sorted by stamp.
//!
//! **The bag's odometry while driving.** With `motion_output` too, each motion message is also
//! published there as a `StopSignal` stamped with its `header.stamp` on the samples' clock
//! ([`crate::wire::STOP_CLOCK_SAMPLES`]): its speed, its yaw rate (`angular.z`) and the yaw
//! rate's sd from the twist covariance. It goes out just before the first sample stamped at
//! or after it, so a `predict.bias` whose `stop_input` it is (with `vehicle_up`) learns the
//! bias in motion from the bag as it would live, at any pace: the stage times the gyro by the
//! samples' own stamps for such a signal. On the first pass of a loop only.
//!
//! **The magnetometer from a bag.** With `mag_topic`, each Imu sample carries the field
//! (tesla, `RAW_MAG`) of the reading [`MagJoinRule`] picks by stamp, the rule of the live ROS 2
//! side (`transport::ros2`'s `mag.rs`): the newest stamped at most half a sample period after
//! the sample, at most `mag_max_age_s` older than it; else none. A non-finite reading is
//! joined as it came, for the guard to flag (`mag_invalid`). The readings are read before the
//! replay starts (32 bytes each: 115 MB for 10 hours at 100 Hz), sorted by stamp.

use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

use toml::Spanned;

use crate::io::content::{sniff, Content};
use crate::io::recording::{self, RawMessage, Recording, RAW_SCHEMA};
use crate::io::InputError;
use crate::io::{BagError, BagErrorKind};
use crate::rate_log::{Stamps, RATE_TOLERANCE};
pub use crate::stages::bag_motion::StopTopic;
use crate::stages::bag_motion::{McapSource, Stops, REPORTED_BAD_MESSAGES};
use crate::stages::contract::{Kind, Params, Role, Source};
use crate::stages::replay::{BlockReplay, BlockSink, Replay, LOOP, PACE, START_DELAY_S};
use crate::stages::schema::{Context, DefaultValue, Key, Src, Table, Type};
use crate::stages::stop_rule::{StopRule, STOP_MAX_AGE_S, STOP_SPEED_OF_TOPIC};
use crate::transport::ros2::bag::Bag;
use crate::transport::ros2::{carry_mag, MagJoinRule, MagReading, DEFAULT_MAG_MAX_AGE_S, IMU_TYPE};
use crate::units::{AccelUnit, RateUnit};
use crate::wire::{RawSample, RAW_ACCEL, RAW_INVALID, RAW_STAMP_FAULT};

const FILE: Key = Key {
    name: "file",
    ty: Type::Str("an MCAP file from `driftless record`, or a ROS 2 bag (an MCAP file or a rosbag2 directory), relative to the pipeline file"),
    default: DefaultValue::Required,
    doc: "the recording or bag to replay; its summary and first 1000 messages of the topic checked at validation, then streamed",
};
const TOPIC: Key = Key {
    name: "topic",
    ty: Type::Str("a recorded raw service: \"demo/raw\" or its topic \"/demo/raw\"; or a bag's sensor_msgs/msg/Imu topic: \"/imu/data\""),
    default: DefaultValue::Derived(
        "the file's only driftless.RawSample topic, else its only sensor_msgs/msg/Imu topic",
    ),
    doc: "which recorded service or Imu topic to replay",
};

const STOP_TOPIC: Key = Key {
    name: "stop_topic",
    ty: Type::Str("a bag's topic of nav_msgs/msg/Odometry, geometry_msgs/msg/TwistStamped or geometry_msgs/msg/TwistWithCovarianceStamped"),
    default: DefaultValue::Absent("none"),
    doc: "the vehicle's motion logged in the bag (wheel odometry): each Imu sample carries whether it stands, from the last motion message by stamp, so `predict.bias` takes the stops by sample time",
};
const MOTION_OUTPUT: Key = Key {
    name: "motion_output",
    ty: Type::Str("a service name: \"vehicle/stop\""),
    default: DefaultValue::Absent("none: the motion gives the samples their stop flags only"),
    doc: "the `stop_topic`'s messages also published here as `StopSignal`s on the samples' clock, with their yaw rate (`angular.z`) and its sd: name it as `predict.bias`'s `stop_input` (with `vehicle_up`) and the bag's odometry teaches the bias while the vehicle drives, at any pace. On the first pass of a loop only",
};
const MAG_TOPIC: Key = Key {
    name: "mag_topic",
    ty: Type::Str("a bag's sensor_msgs/msg/MagneticField topic (tesla): \"/imu/mag\""),
    default: DefaultValue::Absent("none: the samples carry no magnetometer"),
    doc: "the magnetometer logged in the bag, joined by stamp to the Imu samples: each carries the newest reading stamped at most half a sample period after it, if that reading is at most `mag_max_age_s` older; else none (for an `attitude.6d` stage with `use_mag`)",
};
const MAG_MAX_AGE_S: Key = Key {
    name: "mag_max_age_s",
    ty: Type::FloatIn(0.001, 10.0),
    default: DefaultValue::Float(DEFAULT_MAG_MAX_AGE_S),
    doc: "a magnetometer reading older than this (s, by stamp) is joined to no Imu sample (with `mag_topic`; the default serves a magnetometer at 10 Hz or faster)",
};
/// `ingest.mcap`.
pub const KIND: Kind = Kind {
    name: "ingest.mcap",
    role: Role::Ingest { has_input: false },
    summary: "the raw samples of a `driftless record` recording (MCAP) replayed as recorded, or a ROS 2 bag's sensor_msgs/msg/Imu topic (rad/s, stamps as times), at their rate, a factor faster or as fast as possible, optionally looping",
    keys: &[
        FILE,
        TOPIC,
        PACE,
        LOOP,
        START_DELAY_S,
        STOP_TOPIC,
        STOP_SPEED_OF_TOPIC,
        STOP_MAX_AGE_S,
        MOTION_OUTPUT,
        MAG_TOPIC,
        MAG_MAX_AGE_S,
    ],
    parse,
};

/// Messages of the topic decoded at validation, so that a wrong file fails there.
pub const CHECKED_MESSAGES: usize = 1000;

/// An MCAP replay: checked at validation, streamed while it runs.
#[derive(Debug, Clone)]
pub struct McapParams {
    /// The recording or bag.
    pub file: PathBuf,
    /// What it holds.
    pub format: Format,
    /// The topic replayed (a recording's: `/` and the service name).
    pub topic: String,
    /// Messages on the topic.
    pub messages: u64,
    /// Pacing, looping, delay.
    pub replay: Replay,
    /// A bag's motion topic as logged stops.
    pub stops: Option<StopTopic>,
    /// Where the motion topic's messages go as stop signals (`motion_output`).
    pub motion_output: Option<String>,
    /// A bag's magnetometer topic, joined to the samples.
    pub mag: Option<MagTopic>,
    /// One line when the file's name claims another format than MCAP (it is read by what it
    /// holds).
    pub note: Option<String>,
}

/// A bag's magnetometer topic joined to its Imu samples (`mag_topic`).
#[derive(Debug, Clone, PartialEq)]
pub struct MagTopic {
    /// The topic.
    pub topic: String,
    /// How its readings join the samples.
    pub rule: MagJoinRule,
}

/// What an MCAP replay reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// A `driftless record` recording's raw samples.
    Recording,
    /// A ROS 2 bag's Imu messages.
    Ros2Bag,
}

/// What `ingest.mcap` replays, for a file that holds something else.
const MCAP_TAKES: &str = "ingest.mcap replays an MCAP file (a `driftless record` recording or a \
ROS 2 bag) or a rosbag2 directory; a CSV log is replayed by kind = \"ingest.csv\"";

fn parse(t: &mut Table<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    parse_file(t).map(|p| Box::new(p) as Box<dyn Params>)
}

fn parse_file(t: &mut Table<'_, '_>) -> Result<McapParams, InputError> {
    let file_key = t.required_str(&FILE)?;
    let topic_key = t.get::<String>(&TOPIC)?;
    let replay = Replay::parse(t)?;
    let stop_key = t.get::<String>(&STOP_TOPIC)?;
    // A motion message says a speed, never whether the vehicle stands: a speed always rules.
    let (rule, set) = StopRule::parse(t, &STOP_SPEED_OF_TOPIC)?;
    if stop_key.is_none() && set.is_some() {
        return Err(t.error("stop_speed and stop_max_age_s need a stop_topic"));
    }
    let motion_key = t.get::<String>(&MOTION_OUTPUT)?;
    let motion_output = match (&motion_key, &stop_key) {
        (Some(k), None) => {
            return Err(t
                .src
                .span(k, "motion_output needs a stop_topic (the bag's motion)"))
        }
        (Some(k), Some(_)) => Some(t.src.service(k)?),
        (None, _) => None,
    };
    let mag_key = t.get::<String>(&MAG_TOPIC)?;
    let mag_age_given = t.has(&MAG_MAX_AGE_S);
    let mag_max_age_s = t.float_or_default(&MAG_MAX_AGE_S)?;
    if mag_key.is_none() && mag_age_given {
        return Err(t.error("mag_max_age_s needs a mag_topic"));
    }
    let mag = mag_key.map(|k| {
        let rule = MagJoinRule::new(t.cx.rate_hz, mag_max_age_s);
        let mag = MagTopic {
            topic: k.get_ref().clone(),
            rule,
        };
        (k, mag)
    });
    let stops = stop_key.map(|k| {
        let stop = StopTopic {
            topic: k.get_ref().clone(),
            rule,
        };
        (k, stop)
    });
    let src = t.src;
    let file = src.resolve(file_key.get_ref());
    if !file.exists() {
        return Err(src.span(&file_key, format!("no such file: {}", file.display())));
    }
    // By what it holds: the name is a hint.
    let sniffed = sniff(&file).map_err(|e| src.span(&file_key, e.to_string()))?;
    match sniffed.content {
        Content::Directory => {
            let p = parse_bag(t, file, &file_key, topic_key.as_ref(), replay, stops, mag)?;
            return Ok(McapParams { motion_output, ..p });
        }
        Content::Mcap => {}
        _ => return Err(src.span(&file_key, sniffed.refuse(MCAP_TAKES).to_string())),
    }
    let note = sniffed.note("read as MCAP");
    let rec = Recording::open(&file).map_err(|e| src.span(&file_key, e))?;
    let channels = rec.channels();
    // A bag's Imu topic, chosen or the only kind of topic the file can replay.
    let is_imu = |c: &recording::ChannelInfo| c.schema == IMU_TYPE;
    let bag = match &topic_key {
        Some(k) => channels
            .iter()
            .any(|c| c.topic == *k.get_ref() && is_imu(c)),
        None => !channels.iter().any(|c| c.schema == RAW_SCHEMA) && channels.iter().any(is_imu),
    };
    if bag {
        let p = parse_bag(t, file, &file_key, topic_key.as_ref(), replay, stops, mag)?;
        return Ok(McapParams {
            note,
            motion_output,
            ..p
        });
    }
    if let Some((k, _)) = &stops {
        return Err(src.span(
            k,
            format!(
                "stop_topic: {} is a `driftless record` recording, not a ROS 2 bag: its raw \
                 samples carry their stop flags already",
                file.display()
            ),
        ));
    }
    if let Some((k, _)) = &mag {
        return Err(src.span(
            k,
            format!(
                "mag_topic: {} is a `driftless record` recording, not a ROS 2 bag: its raw \
                 samples carry their magnetometer already",
                file.display()
            ),
        ));
    }
    let channel = raw_channel(t, &file, &channels, &file_key, topic_key.as_ref())?;
    let at_topic = topic_key
        .as_ref()
        .map_or(file_key.span().start, |k| k.span().start);
    check_channel(t, &file, channel, at_topic)?;
    for m in rec
        .messages::<RawMessage>(&channel.topic)
        .take(CHECKED_MESSAGES)
    {
        m.map_err(|e| src.at(at_topic, e))?;
    }
    Ok(McapParams {
        file,
        format: Format::Recording,
        topic: channel.topic.clone(),
        messages: channel.messages,
        replay,
        stops: None,
        motion_output: None,
        mag: None,
        note,
    })
}

/// The raw-sample channel of a `driftless record` recording to replay: `topic`'s (which must
/// hold raw samples), or the only raw one.
fn raw_channel<'c>(
    t: &Table<'_, '_>,
    file: &std::path::Path,
    channels: &'c [recording::ChannelInfo],
    file_key: &Spanned<String>,
    topic_key: Option<&Spanned<String>>,
) -> Result<&'c recording::ChannelInfo, InputError> {
    let src = t.src;
    let topics = || {
        let list: Vec<String> = channels
            .iter()
            .map(|c| format!("{} ({})", c.topic, c.schema))
            .collect();
        if list.is_empty() {
            "none".to_string()
        } else {
            list.join(", ")
        }
    };
    let raw: Vec<_> = channels.iter().filter(|c| c.schema == RAW_SCHEMA).collect();
    Ok(match topic_key {
        Some(k) => {
            let want = recording::topic(k.get_ref());
            let Some(c) = channels.iter().find(|c| c.topic == want) else {
                return Err(src.span(
                    k,
                    format!(
                        "no topic {want} in {} (topics: {})",
                        file.display(),
                        topics()
                    ),
                ));
            };
            if c.schema != RAW_SCHEMA {
                return Err(src.span(
                    k,
                    format!(
                        "topic {want} of {} holds {:?}, not {RAW_SCHEMA}: ingest.mcap replays a \
                         recorded raw service (e.g. demo/raw)",
                        file.display(),
                        c.schema
                    ),
                ));
            }
            c
        }
        None => match raw.as_slice() {
            [c] => *c,
            [] => {
                return Err(src.span(
                    file_key,
                    format!(
                        "no {RAW_SCHEMA} or {IMU_TYPE} topic in {} (topics: {}): neither a \
                         `driftless record` recording of a raw service nor a ROS 2 bag of an IMU",
                        file.display(),
                        topics()
                    ),
                ))
            }
            several => {
                let names: Vec<&str> = several.iter().map(|c| c.topic.as_str()).collect();
                return Err(src.at(
                    t.start,
                    format!(
                        "{} has several raw topics ({}): choose one with `topic`",
                        file.display(),
                        names.join(", ")
                    ),
                ));
            }
        },
    })
}

/// The unit a channel's metadata `key` names, when it is a unit of `U` other than `ours`.
fn other_unit<U: std::str::FromStr + PartialEq + std::fmt::Display>(
    metadata: &std::collections::BTreeMap<String, String>,
    key: &str,
    ours: U,
) -> Option<String> {
    let recorded = metadata.get(key)?.parse::<U>().ok()?;
    (recorded != ours).then(|| recorded.to_string())
}

/// A recording's raw channel checked before the replay: its encoding, the units it was
/// recorded in against the pipeline's, and that it has messages.
fn check_channel(
    t: &Table<'_, '_>,
    file: &std::path::Path,
    channel: &recording::ChannelInfo,
    at_topic: usize,
) -> Result<(), InputError> {
    let src = t.src;
    if channel.encoding != recording::MESSAGE_ENCODING {
        return Err(src.at(
            at_topic,
            format!(
                "topic {} of {} is encoded {:?}, not {:?}",
                channel.topic,
                file.display(),
                channel.encoding,
                recording::MESSAGE_ENCODING
            ),
        ));
    }
    // Units the recorder was told (a recording without them, or with a name no unit has, is
    // taken as the pipeline's).
    let md = &channel.metadata;
    for (recorded, ours, pipeline_key) in [
        (
            other_unit(md, recording::RATE_UNITS_KEY, t.cx.units),
            t.cx.units.name(),
            "input_units",
        ),
        (
            other_unit(md, recording::ACCEL_UNITS_KEY, t.cx.accel_units),
            t.cx.accel_units.name(),
            "accel_units",
        ),
    ] {
        if let Some(units) = recorded {
            return Err(src.at(
                at_topic,
                format!(
                    "topic {} of {} was recorded in {units}, but the pipeline's \
                     {pipeline_key} is {ours}",
                    channel.topic,
                    file.display()
                ),
            ));
        }
    }
    if channel.messages == 0 {
        return Err(src.at(
            at_topic,
            format!(
                "topic {} of {} has no messages",
                channel.topic,
                file.display()
            ),
        ));
    }
    Ok(())
}

impl Params for McapParams {
    fn pace(&self) -> Option<crate::clock::Pace> {
        Some(self.replay.pace)
    }

    fn local_source(&self, cx: &Context) -> Result<Box<dyn Source>, String> {
        let (params, period_ns) = (self.clone(), (1e9 / cx.rate_hz).round() as u64);
        // The motion, once the reader thread has read it (before its first sample).
        let logged = Arc::new(OnceLock::new());
        let shared = self.motion_output.is_some().then(|| Arc::clone(&logged));
        let replay = BlockReplay::spawn("driftless-mcap", self.replay, move |sink| {
            match params.format {
                Format::Recording => read_messages(&params, period_ns, sink),
                Format::Ros2Bag => read_bag(&params, period_ns, sink, shared.as_deref()),
            }
        })?;
        Ok(Box::new(McapSource {
            replay,
            motion: self.motion_output.is_some().then_some(logged),
            at: 0,
            t_ns: None,
        }))
    }

    fn motion_output(&self) -> Option<&str> {
        self.motion_output.as_deref()
    }

    fn describe(&self, _input: Option<&str>, _output: &str) -> Vec<String> {
        let mut lines = vec![format!(
            "replays {} messages of {} in {}",
            self.messages,
            self.topic,
            self.file.display()
        )];
        if let Some(s) = &self.stops {
            lines.push(format!("stops from {}: {}", s.topic, s.rule.describe()));
        }
        if let Some(out) = &self.motion_output {
            lines.push(format!(
                "motion out: {out} (StopSignal on the samples' clock: speed, yaw rate and its sd)"
            ));
        }
        if let Some(m) = &self.mag {
            lines.push(format!(
                "magnetometer from {}, joined by stamp: each sample the newest reading up to \
                 {} s after it, at most {} s older; else none",
                m.topic,
                m.rule.lead_ns as f64 * 1e-9,
                m.rule.max_age_ns as f64 * 1e-9
            ));
        }
        lines
    }

    fn warnings(&self) -> Vec<String> {
        self.note.iter().cloned().collect()
    }
}

/// A ROS 2 bag's Imu topic, checked: the pipeline's units rad/s, its rate the stamps' (within
/// 1 %) over the first [`CHECKED_MESSAGES`] messages, none of which may be corrupt.
fn parse_bag(
    t: &Table<'_, '_>,
    file: PathBuf,
    file_key: &Spanned<String>,
    topic_key: Option<&Spanned<String>>,
    replay: Replay,
    stops: Option<(Spanned<String>, StopTopic)>,
    mag: Option<(Spanned<String>, MagTopic)>,
) -> Result<McapParams, InputError> {
    let src = t.src;
    let bag = Bag::open(&file).map_err(|e| src.span(file_key, e))?;
    if let Some((k, m)) = &mag {
        check_topic(src, k, "mag_topic", bag.mag_messages(&m.topic))?;
    }
    if let Some((k, stop)) = &stops {
        check_topic(src, k, "stop_topic", bag.motion_messages(&stop.topic))?;
    }
    let topic = match topic_key {
        Some(k) => bag
            .imu_topic(Some(k.get_ref()))
            .map_err(|e| src.span(k, e))?,
        None => bag.imu_topic(None).map_err(|e| src.span(file_key, e))?,
    };
    let at = topic_key.map_or(file_key.span().start, |k| k.span().start);
    let shown = file.display();
    if t.cx.units != RateUnit::RadPerS {
        return Err(src.at(
            at,
            format!(
                "topic {topic} of {shown} is a sensor_msgs/msg/Imu: its angular velocity is in \
                 rad/s (REP 103), but the pipeline's input_units is {}: set input_units = \
                 \"rad/s\"",
                t.cx.units.name()
            ),
        ));
    }
    if t.cx.accel_units != AccelUnit::MPerS2 {
        return Err(src.at(
            at,
            format!(
                "topic {topic} of {shown} is a sensor_msgs/msg/Imu: its linear acceleration is \
                 in m/s^2 (REP 103), but the pipeline's accel_units is {}: set accel_units = \
                 \"m/s^2\"",
                t.cx.accel_units.name()
            ),
        ));
    }
    let mut stamps = Vec::with_capacity(CHECKED_MESSAGES);
    for m in bag
        .imu_messages(&topic)
        .map_err(|e| src.at(at, e))?
        .take(CHECKED_MESSAGES)
    {
        match m {
            Ok(m) => stamps.push(m.msg.stamp.ns()),
            // Replayed as an invalid sample, flagged: not a reason to refuse the bag.
            Err(e) if e.kind == BagErrorKind::Cdr => {}
            Err(e) => return Err(src.at(at, e)),
        }
    }
    let steps = Stamps::from_stamps(&stamps);
    let Some(stamps_hz) = steps.rate_hz() else {
        return Err(src.at(
            at,
            format!(
                "topic {topic} of {shown}: its first {} stamps give no rate (median step {} ns)",
                steps.count, steps.median_interval_ns
            ),
        ));
    };
    if (stamps_hz - t.cx.rate_hz).abs() > RATE_TOLERANCE * t.cx.rate_hz {
        return Err(src.at(
            at,
            format!(
                "topic {topic} of {shown}: its stamps step {} ns at the median ({stamps_hz:.6} \
                 Hz), but the pipeline's rate is {} Hz",
                steps.median_interval_ns, t.cx.rate_hz
            ),
        ));
    }
    let messages = bag
        .topics()
        .iter()
        .find(|i| i.topic == topic)
        .map_or(0, |i| i.messages);
    Ok(McapParams {
        file,
        format: Format::Ros2Bag,
        topic,
        messages,
        replay,
        stops: stops.map(|(_, s)| s),
        // Set by the caller.
        motion_output: None,
        mag: mag.map(|(_, m)| m),
        note: None,
    })
}

/// A bag's topic beside the Imu (`key` at `k`: `stop_topic`, `mag_topic`), checked: it is of
/// its type (`messages` opened), its first [`CHECKED_MESSAGES`] messages read without a corrupt
/// chunk, and at least one of them decodes.
fn check_topic<M>(
    src: &Src<'_>,
    k: &Spanned<String>,
    key: &str,
    messages: Result<impl Iterator<Item = Result<M, BagError>>, BagError>,
) -> Result<(), InputError> {
    let mut decoded = 0;
    for m in messages.map_err(|e| src.span(k, e))?.take(CHECKED_MESSAGES) {
        match m {
            Ok(_) => decoded += 1,
            Err(e) if e.kind == BagErrorKind::Cdr => {}
            Err(e) => return Err(src.span(k, e)),
        }
    }
    if decoded == 0 {
        return Err(src.span(
            k,
            format!("{key} {}: none of its first messages decodes", k.get_ref()),
        ));
    }
    Ok(())
}

/// The reader thread of a bag: message `n` of the topic as raw sample `n - 1`, its stamp as
/// the time; a message that does not decode as an invalid sample, its time held; `seq` and
/// `t_ns` shifted on later passes. Ends at the end of the bag (without `loop`), at a corrupt
/// chunk (on stderr), or when the replay is dropped.
fn read_bag(
    params: &McapParams,
    period_ns: u64,
    sink: &mut BlockSink,
    motion: Option<&OnceLock<Arc<Stops>>>,
) {
    let shown = params.file.display();
    let bag = match Bag::open(&params.file) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("driftless: error: {e} (the replay ends here)");
            return;
        }
    };
    let Some((stops, mag)) = side_topics(&bag, params, motion) else {
        return;
    };
    let (mut seq_offset, mut t_offset, mut bad) = (0u64, 0u64, 0u64);
    // The last time replayed: what an invalid sample holds.
    let mut held = 0u64;
    loop {
        // Where the stops stand in this pass.
        let mut stop_at = 0;
        let messages = match bag.imu_messages(&params.topic) {
            Ok(m) => m,
            Err(e) => {
                eprintln!("driftless: error: {e} (the replay ends here)");
                return;
            }
        };
        let (mut seq, mut first_t, mut last_t) = (0u64, None::<u64>, 0u64);
        for m in messages {
            let mut s = RawSample {
                t_ns: held,
                seq: seq.wrapping_add(seq_offset),
                rate: [f64::NAN; 3],
                flags: RAW_INVALID,
                ..RawSample::default()
            };
            match m {
                Ok(m) => {
                    s.rate = m.msg.angular_velocity;
                    // 0 is ROS 2's "not set", and before 1970 a stamp has no place on the u64
                    // clock: the time held and the stamp flagged (a stamp fault, not a loss);
                    // the rate is served as it came.
                    s.flags = RAW_STAMP_FAULT;
                    if let Some(t) = m.msg.stamp.ns_u64().filter(|&t| t != 0) {
                        s.flags = stops
                            .as_ref()
                            .map_or(0, |st| st.flags_at(&mut stop_at, m.msg.stamp.ns()));
                        s.t_ns = t.wrapping_add(t_offset);
                        // The magnetometer of this stamp (a sample without a stamp has none).
                        if let Some((readings, rule)) = &mag {
                            carry_mag(&mut s, rule.pick(readings, m.msg.stamp.ns()));
                        }
                        // The loop's span, from real stamps only.
                        first_t.get_or_insert(t);
                        last_t = t;
                    }
                    // The accelerometer as it came, unless the message marks it not provided.
                    if let Some(a) = m.msg.accel_reading() {
                        s.accel = a;
                        s.flags |= RAW_ACCEL;
                    }
                }
                Err(e) if e.kind == BagErrorKind::Cdr => {
                    bad += 1;
                    if seq_offset == 0 && bad <= REPORTED_BAD_MESSAGES {
                        eprintln!(
                            "driftless: warning: {e} (replayed as an invalid sample: flagged)"
                        );
                    }
                }
                Err(e) => {
                    eprintln!("driftless: error: {e} (the replay ends here)");
                    return;
                }
            }
            held = s.t_ns;
            seq += 1;
            if !sink.push(s) {
                return;
            }
        }
        if bad > REPORTED_BAD_MESSAGES && seq_offset == 0 {
            eprintln!(
                "driftless: warning: {shown}: topic {}: {bad} messages that do not decode \
                 replayed as invalid samples",
                params.topic
            );
        }
        let Some(first_t) = first_t else { return };
        if !params.replay.looped {
            return;
        }
        seq_offset = seq_offset.wrapping_add(seq);
        t_offset = t_offset.wrapping_add(last_t.saturating_sub(first_t) + period_ns);
    }
}

/// A bag's magnetometer readings, sorted by stamp, and how they join the samples.
type MagSide = (Vec<MagReading>, MagJoinRule);

/// The bag's topics beside the Imu, read whole before the replay: the stops (shared with the
/// hot thread for `motion_output`) and the magnetometer's readings. `None` (said on stderr)
/// when one cannot be read: the replay ends.
fn side_topics(
    bag: &Bag,
    params: &McapParams,
    motion: Option<&OnceLock<Arc<Stops>>>,
) -> Option<(Option<Arc<Stops>>, Option<MagSide>)> {
    let fail = |e: BagError| eprintln!("driftless: error: {e} (the replay ends here)");
    let stops = match &params.stops {
        Some(s) => match Stops::read(bag, s) {
            Ok(stops) => {
                let stops = Arc::new(stops);
                if let Some(m) = motion {
                    let _ = m.set(Arc::clone(&stops));
                }
                Some(stops)
            }
            Err(e) => {
                fail(e);
                return None;
            }
        },
        None => None,
    };
    let mag = match &params.mag {
        Some(m) => match mag_readings(bag, &m.topic) {
            Ok(readings) => Some((readings, m.rule)),
            Err(e) => {
                fail(e);
                return None;
            }
        },
        None => None,
    };
    Some((stops, mag))
}

/// A bag's magnetometer topic, read whole and sorted by stamp (a stable sort: of equal stamps
/// the later in the file wins, as live); a message that does not decode or has no stamp is
/// left out (counted on stderr).
fn mag_readings(bag: &Bag, topic: &str) -> Result<Vec<MagReading>, BagError> {
    let mut at = Vec::new();
    let (mut bad, mut unstamped) = (0u64, 0u64);
    for m in bag.mag_messages(topic)? {
        match m {
            Ok(m) => match m.msg.reading() {
                Some(r) => at.push(r),
                None => unstamped += 1,
            },
            Err(e) if e.kind == BagErrorKind::Cdr => {
                bad += 1;
                if bad <= REPORTED_BAD_MESSAGES {
                    eprintln!("driftless: warning: {e} (left out of the magnetometer)");
                }
            }
            Err(e) => return Err(e),
        }
    }
    if bad + unstamped > 0 {
        eprintln!(
            "driftless: warning: topic {topic}: {bad} messages that do not decode and \
             {unstamped} without a stamp left out of the magnetometer"
        );
    }
    at.sort_by_key(|r| r.stamp_ns);
    Ok(at)
}

/// The reader thread: the topic's messages as raw samples, as recorded on the first pass,
/// `seq` and `t_ns` shifted on later ones. Ends at the end of the file (without `loop`), at a
/// read error (on stderr), or when the replay is dropped.
fn read_messages(params: &McapParams, period_ns: u64, sink: &mut BlockSink) {
    let rec = match Recording::open(&params.file) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("driftless: error: {e} (the replay ends here)");
            return;
        }
    };
    let (mut seq_offset, mut t_offset) = (0u64, 0u64);
    loop {
        let mut span: Option<((u64, u64), (u64, u64))> = None; // first and last (seq, t_ns)
        for m in rec.messages::<RawMessage>(&params.topic) {
            let m = match m {
                Ok(m) => m,
                Err(e) => {
                    eprintln!("driftless: error: {e} (the replay ends here)");
                    return;
                }
            };
            let mut s = RawSample::from(&m);
            let first = span.map_or((s.seq, s.t_ns), |(f, _)| f);
            span = Some((first, (s.seq, s.t_ns)));
            s.seq = s.seq.wrapping_add(seq_offset);
            s.t_ns = s.t_ns.wrapping_add(t_offset);
            if !sink.push(s) {
                return;
            }
        }
        let Some(((s0, t0), (s1, t1))) = span else {
            return;
        };
        if !params.replay.looped {
            return;
        }
        seq_offset = seq_offset.wrapping_add(s1.wrapping_sub(s0).wrapping_add(1));
        t_offset = t_offset.wrapping_add(t1.saturating_sub(t0) + period_ns);
    }
}
