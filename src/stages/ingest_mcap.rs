//! `ingest.mcap`: replay the raw samples of a recording made by `driftless record` (an MCAP file,
//! [`crate::io::recording`]), or the `sensor_msgs/msg/Imu` topic of a ROS 2 bag (an MCAP file
//! or a rosbag2 directory, [`crate::io::ros2`]), in real time or as fast as possible,
//! optionally looping.
//!
//! A recording's samples enter the pipeline as they were recorded (`seq`, `t_ns`, `epoch`,
//! rates and flags bit for bit), so replaying a recording of a pipeline's raw service through
//! the same stages reproduces what that pipeline published. A bag's message `n` (from 1) enters
//! as `seq` n - 1, `t_ns` its `header.stamp`, `rate` its `angular_velocity` (rad/s: the
//! pipeline's `input_units` must be rad/s), `epoch` 0. A message that does not decode enters
//! as an invalid sample (`RAW_INVALID`, its time held, said on stderr): the daemon flags it
//! and keeps serving; a stamp going backwards enters as it is and is flagged downstream
//! (`time_backwards`). On later passes of a loop, `seq` and `t_ns` are shifted to keep rising.
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
//! pace = "asap"              # or "realtime" (default)
//! loop = false
//! ```

use std::path::PathBuf;

use toml::Spanned;

use crate::io::rate_log::{Stamps, RATE_TOLERANCE};
use crate::io::recording::{self, RawMessage, Recording, RAW_SCHEMA};
use crate::io::ros2::{Bag, BagErrorKind, IMU_TYPE};
use crate::io::InputError;
use crate::stages::contract::{Kind, Params, Role, Source};
use crate::stages::replay::{BlockReplay, BlockSink, Replay, LOOP, PACE, START_DELAY_S};
use crate::stages::schema::Units;
use crate::stages::schema::{Context, Key, StageTable, Type};
use crate::transport::{RawSample, RAW_INVALID};

const FILE: Key = Key {
    name: "file",
    ty: Type::Str("an MCAP file from `driftless record`, or a ROS 2 bag (an MCAP file or a rosbag2 directory), relative to the pipeline file"),
    default: "required",
    doc: "the recording or bag to replay; its summary and first 1000 messages of the topic checked at validation, then streamed",
};
const TOPIC: Key = Key {
    name: "topic",
    ty: Type::Str("a recorded raw service: \"demo/raw\" or its topic \"/demo/raw\"; or a bag's sensor_msgs/msg/Imu topic: \"/imu/data\""),
    default: "the file's only driftless.RawSample topic, else its only sensor_msgs/msg/Imu topic",
    doc: "which recorded service or Imu topic to replay",
};

/// `ingest.mcap`.
pub const KIND: Kind = Kind {
    name: "ingest.mcap",
    role: Role::Ingest { has_input: false },
    summary: "the raw samples of a `driftless record` recording (MCAP) replayed as recorded, or a ROS 2 bag's sensor_msgs/msg/Imu topic (rad/s, stamps as times), at their rate or as fast as possible, optionally looping",
    keys: &[FILE, TOPIC, PACE, LOOP, START_DELAY_S],
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
}

/// What an MCAP replay reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// A `driftless record` recording's raw samples.
    Recording,
    /// A ROS 2 bag's Imu messages.
    Ros2Bag,
}

fn parse(t: &mut StageTable<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    let file_key = t.required_str(&FILE)?;
    let topic_key = t.get::<String>(&TOPIC)?;
    let replay = Replay::parse(t)?;
    let src = t.src;
    let file = src.resolve(file_key.get_ref());
    if file.is_dir() {
        return parse_bag(t, file, &file_key, topic_key.as_ref(), replay);
    }
    if !file.is_file() {
        return Err(src.span(&file_key, format!("no such file: {}", file.display())));
    }
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
        return parse_bag(t, file, &file_key, topic_key.as_ref(), replay);
    }
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
    let channel = match &topic_key {
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
                    &file_key,
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
    };
    let at_topic = topic_key
        .as_ref()
        .map_or(file_key.span().start, |k| k.span().start);
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
    if let Some(units) = channel.metadata.get(recording::RATE_UNITS_KEY) {
        let ours = t.cx.units.name();
        if (units == "deg/s" || units == "rad/s") && units != ours {
            return Err(src.at(
                at_topic,
                format!(
                    "topic {} of {} was recorded in {units}, but the pipeline's input_units is \
                     {ours}",
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
    for m in rec
        .messages::<RawMessage>(&channel.topic)
        .take(CHECKED_MESSAGES)
    {
        m.map_err(|e| src.at(at_topic, e))?;
    }
    Ok(Box::new(McapParams {
        file,
        format: Format::Recording,
        topic: channel.topic.clone(),
        messages: channel.messages,
        replay,
    }))
}

impl Params for McapParams {
    fn source(
        &self,
        cx: &Context,
        _transport: &crate::transport::Transport,
        _input: Option<&str>,
    ) -> Result<Box<dyn Source>, String> {
        let (params, period_ns) = (self.clone(), (1e9 / cx.rate_hz).round() as u64);
        let replay = BlockReplay::spawn("driftless-mcap", self.replay, move |sink| {
            match params.format {
                Format::Recording => read_messages(&params, period_ns, sink),
                Format::Ros2Bag => read_bag(&params, period_ns, sink),
            }
        })?;
        Ok(Box::new(replay))
    }

    fn describe(&self, _input: Option<&str>, _output: &str) -> Vec<String> {
        vec![format!(
            "replays {} messages of {} in {}",
            self.messages,
            self.topic,
            self.file.display()
        )]
    }
}

/// A ROS 2 bag's Imu topic, checked: the pipeline's units rad/s, its rate the stamps' (within
/// 1 %) over the first [`CHECKED_MESSAGES`] messages, none of which may be corrupt.
fn parse_bag(
    t: &StageTable<'_, '_>,
    file: PathBuf,
    file_key: &Spanned<String>,
    topic_key: Option<&Spanned<String>>,
    replay: Replay,
) -> Result<Box<dyn Params>, InputError> {
    let src = t.src;
    let bag = Bag::open(&file).map_err(|e| src.span(file_key, e))?;
    let topic = match topic_key {
        Some(k) => bag
            .imu_topic(Some(k.get_ref()))
            .map_err(|e| src.span(k, e))?,
        None => bag.imu_topic(None).map_err(|e| src.span(file_key, e))?,
    };
    let at = topic_key.map_or(file_key.span().start, |k| k.span().start);
    let shown = file.display();
    if t.cx.units != Units::RadPerSec {
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
    let mut stamps = Vec::with_capacity(CHECKED_MESSAGES);
    for m in bag
        .imu_messages(&topic)
        .map_err(|e| src.at(at, e))?
        .take(CHECKED_MESSAGES)
    {
        match m {
            Ok(m) => stamps.push(m.imu.stamp.ns()),
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
    Ok(Box::new(McapParams {
        file,
        format: Format::Ros2Bag,
        topic,
        messages,
        replay,
    }))
}

/// The reader thread of a bag: message `n` of the topic as raw sample `n - 1`, its stamp as
/// the time; a message that does not decode as an invalid sample, its time held; `seq` and
/// `t_ns` shifted on later passes. Ends at the end of the bag (without `loop`), at a corrupt
/// chunk (on stderr), or when the replay is dropped.
fn read_bag(params: &McapParams, period_ns: u64, sink: &mut BlockSink) {
    let shown = params.file.display();
    let bag = match Bag::open(&params.file) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("driftless: error: {e} (the replay ends here)");
            return;
        }
    };
    let (mut seq_offset, mut t_offset, mut bad) = (0u64, 0u64, 0u64);
    // The last time replayed: what an invalid sample holds.
    let mut held = 0u64;
    loop {
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
                epoch: 0,
            };
            match m {
                Ok(m) => {
                    s.rate = m.imu.angular_velocity;
                    // Before 1970 a stamp has no place on the u64 clock: held, flagged invalid.
                    if let Some(t) = m.imu.stamp.ns_u64() {
                        s.flags = 0;
                        s.t_ns = t.wrapping_add(t_offset);
                        // The loop's span, from real stamps only.
                        first_t.get_or_insert(t);
                        last_t = t;
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

/// Undecodable messages of a bag named one by one on stderr; the rest are counted.
const REPORTED_BAD_MESSAGES: u64 = 10;

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
