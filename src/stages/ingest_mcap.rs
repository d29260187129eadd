//! `ingest.mcap`: replay the raw samples of a recording made by `driftless record` (an MCAP file,
//! [`crate::io::recording`]) in real time or as fast as possible, optionally looping. The
//! samples enter the pipeline as they were recorded (`seq`, `t_ns`, `epoch`, rates and flags
//! bit for bit), so replaying a recording of a pipeline's raw service through the same stages
//! reproduces what that pipeline published. On later passes of a loop, `seq` and `t_ns` are
//! shifted to keep rising.
//!
//! Validation opens the file (its summary and footer: a truncated file or one still being
//! written fails there), finds the topic and decodes its first [`CHECKED_MESSAGES`] messages;
//! the run streams the file chunk by chunk from a reader thread.
//!
//! ```toml
//! [[stage]]
//! name = "sensor"
//! kind = "ingest.mcap"
//! output = "demo/raw"
//! file = "run.mcap"          # relative to the pipeline file
//! topic = "demo/raw"         # default: the file's only raw-sample topic
//! pace = "asap"              # or "realtime" (default)
//! loop = false
//! ```

use std::path::PathBuf;

use toml::Spanned;

use crate::io::recording::{self, RawMessage, Recording, RAW_SCHEMA};
use crate::io::InputError;
use crate::stages::contract::{Kind, Params, Role, Source};
use crate::stages::replay::{BlockReplay, BlockSink, Pace, LOOP, PACE};
use crate::stages::schema::{Context, Key, StageTable, Type};
use crate::transport::RawSample;

const FILE: Key = Key {
    name: "file",
    ty: Type::Str("an MCAP file from `driftless record`, relative to the pipeline file"),
    default: "required",
    doc: "the recording to replay; its summary and first 1000 messages of the topic checked at validation, then streamed",
};
const TOPIC: Key = Key {
    name: "topic",
    ty: Type::Str("a recorded raw service: \"demo/raw\" or its topic \"/demo/raw\""),
    default: "the file's only driftless.RawSample topic",
    doc: "which recorded service to replay",
};

/// `ingest.mcap`.
pub const KIND: Kind = Kind {
    name: "ingest.mcap",
    role: Role::Ingest { has_input: false },
    summary: "the raw samples of a `driftless record` recording (MCAP) replayed as recorded, at their rate or as fast as possible, optionally looping",
    keys: &[FILE, TOPIC, PACE, LOOP],
    parse,
};

/// Messages of the topic decoded at validation, so that a wrong file fails there.
pub const CHECKED_MESSAGES: usize = 1000;

/// An MCAP replay: checked at validation, streamed while it runs.
#[derive(Debug, Clone)]
pub struct McapParams {
    /// The recording.
    pub file: PathBuf,
    /// The topic replayed (`/` and the service name).
    pub topic: String,
    /// Messages on the topic.
    pub messages: u64,
    /// Pacing.
    pub pace: Pace,
    /// Replay again from the start at the end of the file.
    pub looped: bool,
}

fn parse(t: &mut StageTable<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    let file_key = t.required_str(&FILE)?;
    let topic_key = t.get::<String>(&TOPIC)?;
    let pace = Pace::from_key(t.choice(&PACE, "pace", true)?.as_deref());
    let looped = t.get::<bool>(&LOOP)?.is_some_and(Spanned::into_inner);
    let src = t.src;
    let file = src.resolve(file_key.get_ref());
    if !file.is_file() {
        return Err(src.span(&file_key, format!("no such file: {}", file.display())));
    }
    let rec = Recording::open(&file).map_err(|e| src.span(&file_key, e))?;
    let channels = rec.channels();
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
                        "no {RAW_SCHEMA} topic in {} (topics: {}): not a `driftless record` \
                         recording of a raw service",
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
        topic: channel.topic.clone(),
        messages: channel.messages,
        pace,
        looped,
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
        let replay = BlockReplay::spawn("driftless-mcap", self.pace, move |sink| {
            read_messages(&params, period_ns, sink)
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
        if !params.looped {
            return;
        }
        seq_offset = seq_offset.wrapping_add(s1.wrapping_sub(s0).wrapping_add(1));
        t_offset = t_offset.wrapping_add(t1.saturating_sub(t0) + period_ns);
    }
}
