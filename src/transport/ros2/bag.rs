//! ROS 2 bags in and out (issue 30): `sensor_msgs/msg/Imu` messages (and, read, a vehicle's
//! motion and `sensor_msgs/msg/MagneticField`) in rosbag2's MCAP storage,
//! read from a bag a ROS 2 recorder wrote and written so that ROS 2 tools read ours.
//!
//! **CDR by hand.** The Imu message is one fixed layout (two integers, one string, 37 doubles),
//! so its codec ([`Imu::read_cdr`], [`Imu::write_cdr`]) is a few dozen lines that never
//! allocate by a length read from the input, never panic, and name the field where a message
//! ends too soon. The crates were weighed: `cdr` 0.2.4 (no release since 2021) reserves
//! whatever a string or sequence length claims, and `cdr-encoding` 0.11 (RustDDS's, kept up)
//! would bring serde_repr, pastey and a second thiserror for one layout that we check byte by
//! byte against rosbags, and decoded 2-4 times slower than ours in a quick in-memory timing.
//!
//! The CDR is what ROS 2's rmw writes (XCDR1, "plain" CDR): a 4-byte encapsulation header,
//! `00 01` little-endian (what we write) or `00 00` big-endian (also read), then the fields,
//! each aligned to its size relative to the byte after the header; a string is a u32 length
//! that counts its NUL, the bytes, the NUL. Up to 3 bytes of padding may follow the message
//! (as rosbags allows); more is an error.
//!
//! **Reading** ([`Bag`]): an MCAP file, or a rosbag2 directory: the files its `metadata.yaml`
//! lists under `relative_file_paths` (a few lines parsed by hand: the file is flat enough and
//! serde_yaml is deprecated), or, without a metadata.yaml, its `*.mcap` files in name order.
//! Each file must end with its summary (a truncated file or one still being written is refused
//! at open). An Imu topic is one whose schema is named [`IMU_TYPE`] and whose messages are
//! `cdr`. Messages come in file order (not sorted by time), each with its log time; the stamp
//! is the message's own `header.stamp` ([`super::Time::ns`]), which the caller checks for order.
//! Every error is one line naming the file and, past the opening, the topic, the message's
//! number on it (from 1, as [`crate::io::recording`] counts) and its log time. A damaged chunk
//! is decompressed as a stream: the messages before the damage come, then the error.
//!
//! **Writing** ([`ImuBagWriter`]) as `ros2 bag record` (rosbag2_storage_mcap) does: profile
//! `ros2`, schema [`IMU_TYPE`] in `ros2msg` with [`IMU_DEFINITION`], channel encoding `cdr`,
//! channel metadata `offered_qos_profiles` ([`OFFERED_QOS_PROFILES`]) and `topic_type_hash`;
//! log time = publish time = the message's stamp in ns (a recorder would put its receive time;
//! ours has no other clock worth keeping); zstd chunks (rosbag2's own compressed presets are
//! zstd; rosbag2 itself writes uncompressed chunks by default). The file appears whole or not
//! at all ([`crate::io::atomic`]). No `metadata.yaml` is written: `ros2 bag play` and
//! `ros2 bag info` open a bare `.mcap` file since Iron, and read its topics from the summary.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::io::atomic::AtomicFile;
use crate::io::mcap_file::{map_mcap, ChannelMessages, McapOpenError, McapReadError};

use super::imu::{CdrError, Imu, IMU_DEFINITION, IMU_TYPE};
use super::mag::{MagneticField, MAG_TYPE};
use super::motion::{Motion, MotionKind};
use crate::io::{BagError, BagErrorKind};

/// Schema encoding of ROS 2 `.msg` definitions.
pub const SCHEMA_ENCODING: &str = "ros2msg";
/// Message encoding of ROS 2 messages.
pub const MESSAGE_ENCODING: &str = "cdr";
/// The MCAP profile of rosbag2 files.
pub const PROFILE: &str = "ros2";
/// The type hash of sensor_msgs/msg/Imu (REP 2011, as rosbag2 since Jazzy writes it in the
/// channel metadata `topic_type_hash`; the same in Humble to Kilted, checked by rosbags).
pub const IMU_TYPE_HASH: &str =
    "RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b";

/// The QoS a recorder offers our topic, as rosbag2 serializes `offered_qos_profiles`: reliable,
/// keep last 10, volatile, durations infinite (as rmw reports them). The integer form rosbag2
/// wrote through Iron; Jazzy and later detect it and read it too, whereas Iron does not read
/// the names Jazzy writes (`keep_last`) from a bare file without rosbag2's metadata record.
pub const OFFERED_QOS_PROFILES: &str = "- history: 1\n  depth: 10\n  reliability: 1\n  \
durability: 2\n  deadline:\n    sec: 9223372036\n    nsec: 854775807\n  lifespan:\n    \
sec: 9223372036\n    nsec: 854775807\n  liveliness: 1\n  liveliness_lease_duration:\n    \
sec: 9223372036\n    nsec: 854775807\n  avoid_ros_namespace_conventions: false";

pub use crate::io::mcap_file::MAX_CHUNK_BYTES;

/// The channel metadata rosbag2 writes for an Imu topic: [`OFFERED_QOS_PROFILES`] and the
/// type hash.
pub fn imu_channel_metadata() -> BTreeMap<String, String> {
    BTreeMap::from([
        (
            "offered_qos_profiles".to_string(),
            OFFERED_QOS_PROFILES.to_string(),
        ),
        ("topic_type_hash".to_string(), IMU_TYPE_HASH.to_string()),
    ])
}

/// A ROS 2 topic name for a service name: `/` and the name, each character a ROS 2 name
/// cannot hold (anything but letters, digits, `_` and `/`) replaced by `_`.
pub fn topic_for_service(service: &str) -> String {
    let mut t = String::with_capacity(service.len() + 1);
    t.push('/');
    t.extend(service.chars().map(|c| {
        if c.is_ascii_alphanumeric() || c == '_' || c == '/' {
            c
        } else {
            '_'
        }
    }));
    t
}

fn err(kind: BagErrorKind, message: String) -> BagError {
    BagError { kind, message }
}

/// A topic of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    /// Its name (e.g. `/imu/data`).
    pub topic: String,
    /// Its ROS 2 type (the schema's name), empty without a schema.
    pub msg_type: String,
    /// Its schema's encoding (`ros2msg`, `ros2idl`).
    pub schema_encoding: String,
    /// Its message encoding (`cdr`).
    pub message_encoding: String,
    /// Messages on it, from the summaries' statistics (0 without).
    pub messages: u64,
}

impl TopicInfo {
    /// Whether its messages are CDR `sensor_msgs/msg/Imu` (the definition's text, `ros2msg`
    /// or the `ros2idl` rosbag2 falls back to, does not change the CDR layout).
    pub fn is_imu(&self) -> bool {
        self.msg_type == IMU_TYPE && self.message_encoding == MESSAGE_ENCODING
    }

    /// Whether its messages are CDR `sensor_msgs/msg/MagneticField`.
    pub fn is_mag(&self) -> bool {
        self.msg_type == MAG_TYPE && self.message_encoding == MESSAGE_ENCODING
    }

    /// Its motion type, where it is one in CDR ([`MotionKind`]).
    pub fn motion_kind(&self) -> Option<MotionKind> {
        MotionKind::of_type(&self.msg_type).filter(|_| self.message_encoding == MESSAGE_ENCODING)
    }

    fn shown(&self) -> String {
        let ty = if self.msg_type.is_empty() {
            "no schema"
        } else {
            &self.msg_type
        };
        let enc = if self.message_encoding == MESSAGE_ENCODING {
            String::new()
        } else {
            format!(" in {:?}", self.message_encoding)
        };
        format!("{} ({ty}{enc}, {} messages)", self.topic, self.messages)
    }
}

fn list(topics: &[TopicInfo]) -> String {
    if topics.is_empty() {
        return "none".into();
    }
    topics
        .iter()
        .map(TopicInfo::shown)
        .collect::<Vec<_>>()
        .join(", ")
}

/// One MCAP file of a bag: mapped, its summary read.
struct BagFile {
    path: PathBuf,
    map: memmap2::Mmap,
    summary: mcap::Summary,
}

impl BagFile {
    fn open(path: &Path) -> Result<BagFile, BagError> {
        let shown = path.display();
        let (map, summary) = map_mcap(path).map_err(|e| match e {
            McapOpenError::Io(e) => err(BagErrorKind::Io, format!("{shown}: {e}")),
            McapOpenError::NotMcap(holds) => err(
                BagErrorKind::NotMcap,
                format!(
                    "{shown}: not an MCAP file (no MCAP magic at its start): it holds {}",
                    holds.what()
                ),
            ),
            McapOpenError::Incomplete(why) => err(
                BagErrorKind::Incomplete,
                format!(
                    "{shown}: an incomplete MCAP file ({why}): truncated, or still being \
                     written; a complete bag ends with its summary and footer (`mcap recover` \
                     or `ros2 bag reindex` rebuilds them)"
                ),
            ),
        })?;
        Ok(BagFile {
            path: path.to_path_buf(),
            map,
            summary,
        })
    }

    fn topics(&self) -> Vec<TopicInfo> {
        let counts = self
            .summary
            .stats
            .as_ref()
            .map(|s| &s.channel_message_counts);
        self.summary
            .channels
            .iter()
            .map(|(id, c)| TopicInfo {
                topic: c.topic.clone(),
                msg_type: c.schema.as_ref().map_or(String::new(), |s| s.name.clone()),
                schema_encoding: c
                    .schema
                    .as_ref()
                    .map_or(String::new(), |s| s.encoding.clone()),
                message_encoding: c.message_encoding.clone(),
                messages: counts.and_then(|m| m.get(id).copied()).unwrap_or(0),
            })
            .collect()
    }
}

/// A rosbag2 bag in MCAP storage, opened for reading: one `.mcap` file or a bag directory.
pub struct Bag {
    path: PathBuf,
    files: Vec<BagFile>,
}

impl Bag {
    /// Open `path`: an MCAP file, or a rosbag2 directory (the files its metadata.yaml lists,
    /// or its `*.mcap` files in name order without one). Every file must be complete.
    pub fn open(path: &Path) -> Result<Bag, BagError> {
        let shown = path.display();
        let meta =
            std::fs::metadata(path).map_err(|e| err(BagErrorKind::Io, format!("{shown}: {e}")))?;
        let paths = if meta.is_dir() {
            bag_files(path)?
        } else {
            vec![path.to_path_buf()]
        };
        let files = paths
            .iter()
            .map(|p| BagFile::open(p))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Bag {
            path: path.to_path_buf(),
            files,
        })
    }

    /// The bag's path as opened.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Its MCAP files, in reading order.
    pub fn files(&self) -> Vec<&Path> {
        self.files.iter().map(|f| f.path.as_path()).collect()
    }

    /// Every topic, by name, its counts summed over the files.
    pub fn topics(&self) -> Vec<TopicInfo> {
        let mut by_name: BTreeMap<String, TopicInfo> = BTreeMap::new();
        for t in self.files.iter().flat_map(BagFile::topics) {
            match by_name.get_mut(&t.topic) {
                Some(have) => have.messages += t.messages,
                None => {
                    by_name.insert(t.topic.clone(), t);
                }
            }
        }
        by_name.into_values().collect()
    }

    /// The topics of type sensor_msgs/msg/Imu ([`TopicInfo::is_imu`]).
    pub fn imu_topics(&self) -> Vec<TopicInfo> {
        self.topics().into_iter().filter(|t| t.is_imu()).collect()
    }

    /// The Imu topic to read: `chosen` when it is one, else the bag's only one. An error lists
    /// the bag's topics (no Imu topic, or `chosen` absent), its Imu topics (several and none
    /// chosen), or says the chosen topic's type.
    pub fn imu_topic(&self, chosen: Option<&str>) -> Result<String, BagError> {
        let shown = self.path.display();
        let topics = self.topics();
        if let Some(name) = chosen {
            return match topics.iter().find(|t| t.topic == name) {
                Some(t) if t.is_imu() => Ok(name.to_string()),
                Some(t) => Err(err(
                    BagErrorKind::NotImu,
                    format!("{shown}: topic {}: not {IMU_TYPE} in cdr", t.shown()),
                )),
                None => Err(err(
                    BagErrorKind::NoSuchTopic,
                    format!("{shown}: no topic {name}; its topics: {}", list(&topics)),
                )),
            };
        }
        let imu: Vec<TopicInfo> = topics.iter().filter(|t| t.is_imu()).cloned().collect();
        match imu.as_slice() {
            [one] => Ok(one.topic.clone()),
            [] => Err(err(
                BagErrorKind::NoImuTopic,
                format!(
                    "{shown}: no {IMU_TYPE} topic; its topics: {}",
                    list(&topics)
                ),
            )),
            several => Err(err(
                BagErrorKind::SeveralImuTopics,
                format!(
                    "{shown}: {} {IMU_TYPE} topics, choose one: {}",
                    several.len(),
                    list(several)
                ),
            )),
        }
    }

    /// The messages of Imu topic `topic` in file order, decoded. The topic is checked first
    /// ([`Bag::imu_topic`]); then each item is a message or an error: a corrupt chunk ends the
    /// iteration, a message that does not decode does not (the next item is the next message).
    pub fn imu_messages<'a>(&'a self, topic: &str) -> Result<ImuMessages<'a>, BagError> {
        let topic = self.imu_topic(Some(topic))?;
        Ok(Messages::new(self, topic, ImuType))
    }

    /// The messages of magnetometer topic `topic` (`sensor_msgs/msg/MagneticField` in CDR), in
    /// file order, decoded as [`Bag::imu_messages`] decodes Imu.
    pub fn mag_messages<'a>(&'a self, topic: &str) -> Result<MagMessages<'a>, BagError> {
        let shown = self.path.display();
        let topics = self.topics();
        match topics.iter().find(|t| t.topic == topic) {
            Some(t) if t.is_mag() => Ok(Messages::new(self, topic.to_string(), MagType)),
            Some(t) => Err(err(
                BagErrorKind::NotImu,
                format!("{shown}: topic {}: not {MAG_TYPE} in cdr", t.shown()),
            )),
            None => Err(err(
                BagErrorKind::NoSuchTopic,
                format!("{shown}: no topic {topic}; its topics: {}", list(&topics)),
            )),
        }
    }

    /// The messages of motion topic `topic` (`nav_msgs/msg/Odometry` or a twist, in CDR), in
    /// file order, decoded as [`Bag::imu_messages`] decodes Imu.
    pub fn motion_messages<'a>(&'a self, topic: &str) -> Result<MotionMessages<'a>, BagError> {
        let shown = self.path.display();
        let topics = self.topics();
        let Some(t) = topics.iter().find(|t| t.topic == topic) else {
            return Err(err(
                BagErrorKind::NoSuchTopic,
                format!("{shown}: no topic {topic}; its topics: {}", list(&topics)),
            ));
        };
        let Some(kind) = t.motion_kind() else {
            let names: Vec<&str> = MotionKind::ALL.iter().map(|(n, _)| *n).collect();
            return Err(err(
                BagErrorKind::NotImu,
                format!(
                    "{shown}: topic {}: not a vehicle's motion in cdr ({})",
                    t.shown(),
                    names.join(", ")
                ),
            ));
        };
        Ok(Messages::new(self, topic.to_string(), MotionType(kind)))
    }
}

/// The MCAP files of bag directory `dir`: those its metadata.yaml lists, else `*.mcap` by name.
fn bag_files(dir: &Path) -> Result<Vec<PathBuf>, BagError> {
    let shown = dir.display();
    let io = |e: std::io::Error| err(BagErrorKind::Io, format!("{shown}: {e}"));
    let yaml = dir.join("metadata.yaml");
    let names = if yaml.exists() {
        let text = std::fs::read_to_string(&yaml)
            .map_err(|e| err(BagErrorKind::Io, format!("{}: {e}", yaml.display())))?;
        let names = relative_file_paths(&text).ok_or_else(|| {
            err(
                BagErrorKind::NotMcap,
                format!(
                    "{}: no relative_file_paths: not a rosbag2 metadata file",
                    yaml.display()
                ),
            )
        })?;
        if let Some(other) = names.iter().find(|n| !n.ends_with(".mcap")) {
            let why = if other.ends_with(".db3") {
                "sqlite3 storage: convert the bag to MCAP with `ros2 bag convert`"
            } else {
                "not an MCAP file (a compressed file? decompress it first)"
            };
            return Err(err(
                BagErrorKind::NotMcap,
                format!("{}: lists {other}: {why}", yaml.display()),
            ));
        }
        names
    } else {
        let mut names = Vec::new();
        for entry in std::fs::read_dir(dir).map_err(io)? {
            let name = entry.map_err(io)?.file_name();
            let name = name.to_string_lossy();
            if name.ends_with(".mcap") {
                names.push(name.into_owned());
            }
        }
        names.sort();
        names
    };
    if names.is_empty() {
        return Err(err(
            BagErrorKind::NotMcap,
            format!("{shown}: a directory without MCAP files (no metadata.yaml, no *.mcap)"),
        ));
    }
    Ok(names.into_iter().map(|n| dir.join(n)).collect())
}

/// The list under `relative_file_paths:` of a rosbag2 metadata.yaml, block (yaml-cpp indents
/// the items, ruamel does not) or flow style, plain or quoted; None without the key.
fn relative_file_paths(text: &str) -> Option<Vec<String>> {
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        let t = line.trim_start();
        let Some(rest) = t.strip_prefix("relative_file_paths:") else {
            continue;
        };
        let indent = line.len() - t.len();
        let rest = rest.trim();
        if let Some(flow) = rest.strip_prefix('[') {
            let flow = flow.trim_end().trim_end_matches(']');
            return Some(
                flow.split(',')
                    .map(unquote)
                    .filter(|s| !s.is_empty())
                    .collect(),
            );
        }
        let mut out = Vec::new();
        for l in lines {
            let lt = l.trim_start();
            if lt.is_empty() || lt.starts_with('#') {
                continue;
            }
            match lt.strip_prefix('-') {
                Some(item) if l.len() - lt.len() >= indent => out.push(unquote(item)),
                _ => break,
            }
        }
        return Some(out);
    }
    None
}

fn unquote(s: &str) -> String {
    let s = s.trim();
    if s.len() >= 2 && s.starts_with('\'') && s.ends_with('\'') {
        s[1..s.len() - 1].replace("''", "'")
    } else if s.len() >= 2 && s.starts_with('"') && s.ends_with('"') {
        s[1..s.len() - 1].replace("\\\"", "\"")
    } else {
        s.to_string()
    }
}

/// One message of a topic: decoded, with its log time and number.
#[derive(Debug, Clone, PartialEq)]
pub struct Record<M> {
    /// The message.
    pub msg: M,
    /// Its MCAP log time, ns (a recorder's receive time; the sample's time is its stamp).
    pub log_time_ns: u64,
    /// Its number on the topic, from 1, as errors count.
    pub number: u64,
}

/// One message of an Imu topic.
pub type ImuRecord = Record<Imu>;

/// What a topic's messages are and how they decode.
pub trait TopicType {
    /// The decoded message.
    type Msg;
    /// The type's name, for errors.
    fn name(&self) -> &'static str;
    /// Whether a topic holds this type.
    fn accepts(&self, t: &TopicInfo) -> bool;
    /// Decode one message's CDR.
    fn decode(&self, bytes: &[u8]) -> Result<Self::Msg, CdrError>;
}

/// `sensor_msgs/msg/Imu`.
pub struct ImuType;

impl TopicType for ImuType {
    type Msg = Imu;
    fn name(&self) -> &'static str {
        IMU_TYPE
    }
    fn accepts(&self, t: &TopicInfo) -> bool {
        t.is_imu()
    }
    fn decode(&self, bytes: &[u8]) -> Result<Imu, CdrError> {
        Imu::from_cdr(bytes)
    }
}

/// `sensor_msgs/msg/MagneticField`.
pub struct MagType;

impl TopicType for MagType {
    type Msg = MagneticField;
    fn name(&self) -> &'static str {
        MAG_TYPE
    }
    fn accepts(&self, t: &TopicInfo) -> bool {
        t.is_mag()
    }
    fn decode(&self, bytes: &[u8]) -> Result<MagneticField, CdrError> {
        MagneticField::from_cdr(bytes)
    }
}

/// A vehicle's motion of one [`MotionKind`].
pub struct MotionType(pub MotionKind);

impl TopicType for MotionType {
    type Msg = Motion;
    fn name(&self) -> &'static str {
        self.0.type_name()
    }
    fn accepts(&self, t: &TopicInfo) -> bool {
        t.motion_kind() == Some(self.0)
    }
    fn decode(&self, bytes: &[u8]) -> Result<Motion, CdrError> {
        Motion::from_cdr(self.0, bytes)
    }
}

/// The messages of one Imu topic of a [`Bag`] ([`Bag::imu_messages`]).
pub type ImuMessages<'a> = Messages<'a, ImuType>;
/// The messages of one magnetometer topic of a [`Bag`] ([`Bag::mag_messages`]).
pub type MagMessages<'a> = Messages<'a, MagType>;
/// The messages of one motion topic of a [`Bag`] ([`Bag::motion_messages`]).
pub type MotionMessages<'a> = Messages<'a, MotionType>;

/// The messages of one topic of a [`Bag`], in file order, decoded as `T` says.
pub struct Messages<'a, T: TopicType> {
    bag: &'a Bag,
    topic: String,
    ty: T,
    /// The file being read (its index in the bag).
    file: usize,
    /// The current file's messages of the topic (None between files).
    reader: Option<ChannelMessages<'a>>,
    number: u64,
    last_log_time: Option<u64>,
    failed: bool,
}

impl<'a, T: TopicType> Messages<'a, T> {
    fn new(bag: &'a Bag, topic: String, ty: T) -> Self {
        Messages {
            bag,
            topic,
            ty,
            file: 0,
            reader: None,
            number: 0,
            last_log_time: None,
            failed: false,
        }
    }
    /// The topic read.
    pub fn topic(&self) -> &str {
        &self.topic
    }

    /// Where the reading stands, for an error that is not one message's: the file, the topic,
    /// the last message read.
    fn after(&self) -> String {
        let file = self.bag.files[self.file].path.display();
        match self.last_log_time {
            Some(t) => format!(
                "{file}: topic {}, after message {} (log time {t} ns)",
                self.topic, self.number
            ),
            None => format!("{file}: topic {}, before its first message", self.topic),
        }
    }

    /// Start reading file `self.file`: its channels of the topic, which must be Imu.
    fn start_file(&mut self) -> Result<(), BagError> {
        let f = &self.bag.files[self.file];
        let mut channels = BTreeMap::new();
        for (id, c) in &f.summary.channels {
            let mine = c.topic == self.topic;
            if mine {
                let t = f
                    .topics()
                    .into_iter()
                    .find(|t| t.topic == self.topic)
                    .filter(|t| self.ty.accepts(t));
                if t.is_none() {
                    return Err(err(
                        BagErrorKind::NotImu,
                        format!(
                            "{}: topic {} is not {} in cdr in this file",
                            f.path.display(),
                            self.topic,
                            self.ty.name()
                        ),
                    ));
                }
            }
            channels.insert(*id, mine);
        }
        self.reader = Some(ChannelMessages::new(&f.map[..], channels));
        Ok(())
    }

    /// The next message of the current file, None at its end.
    fn next_in_file(&mut self) -> Option<Result<Record<T::Msg>, BagError>> {
        let ty = &self.ty;
        let read = self
            .reader
            .as_mut()?
            .next_with(|header, data| (header.log_time, ty.decode(data)));
        let (log_time, decoded) = match read {
            Some(Ok(read)) => read,
            Some(Err(e)) => {
                let message = match e {
                    McapReadError::Record(e) => format!("{}: a corrupt record: {e}", self.after()),
                    McapReadError::Chunk(e) => {
                        format!("{}: a corrupt or truncated chunk: {e}", self.after())
                    }
                    McapReadError::UnknownChannel(_) => format!("{}: {e}", self.after()),
                };
                return Some(Err(err(BagErrorKind::Corrupt, message)));
            }
            None => {
                self.reader = None;
                return None;
            }
        };
        self.number += 1;
        self.last_log_time = Some(log_time);
        Some(match decoded {
            Ok(msg) => Ok(Record {
                msg,
                log_time_ns: log_time,
                number: self.number,
            }),
            Err(e) => Err(err(
                BagErrorKind::Cdr,
                format!(
                    "{}: topic {}, message {} (log time {log_time} ns): not a CDR {}: {e}",
                    self.bag.files[self.file].path.display(),
                    self.topic,
                    self.number,
                    self.ty.name()
                ),
            )),
        })
    }
}

impl<T: TopicType> Iterator for Messages<'_, T> {
    type Item = Result<Record<T::Msg>, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        while !self.failed && self.file < self.bag.files.len() {
            if self.reader.is_none() {
                if let Err(e) = self.start_file() {
                    self.failed = true;
                    return Some(Err(e));
                }
            }
            match self.next_in_file() {
                Some(Ok(r)) => return Some(Ok(r)),
                Some(Err(e)) => {
                    // A message that does not decode leaves the file's framing intact: the
                    // caller may read on (a replay flags it and keeps serving).
                    self.failed = e.kind != BagErrorKind::Cdr;
                    return Some(Err(e));
                }
                None => self.file += 1,
            }
        }
        None
    }
}

/// Writes `sensor_msgs/msg/Imu` messages on one topic to an MCAP file as `ros2 bag record`
/// does (see the module's doc); the file appears at its path only at [`ImuBagWriter::finish`].
pub struct ImuBagWriter {
    path: PathBuf,
    /// Owns the temporary file: dropped unfinished, it is removed.
    tmp: AtomicFile,
    writer: mcap::Writer<BufWriter<File>>,
    channel: u16,
    buf: Vec<u8>,
    count: u64,
}

impl ImuBagWriter {
    /// Start a bag for `path` with one Imu topic, `topic` (a ROS 2 name: `/imu/data`).
    pub fn create(path: &Path, topic: &str) -> Result<ImuBagWriter, BagError> {
        let shown = path.display();
        if !topic.starts_with('/') || topic.len() < 2 || topic.contains(char::is_whitespace) {
            return Err(err(
                BagErrorKind::Write,
                format!("{shown}: topic {topic:?} is not a ROS 2 topic name (like /imu/data)"),
            ));
        }
        let io = |e: std::io::Error| err(BagErrorKind::Io, format!("{shown}: {e}"));
        let mcap_err = |e: mcap::McapError| err(BagErrorKind::Io, format!("{shown}: {e}"));
        let tmp = AtomicFile::create(path).map_err(io)?;
        let file = tmp.file().try_clone().map_err(io)?;
        let mut writer = mcap::WriteOptions::new()
            .profile(PROFILE)
            .library(format!("driftless {}", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Zstd))
            // One thread: no worker threads in the caller's process, and the same bytes on
            // every machine.
            .compression_threads(0)
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(mcap_err)?;
        let schema = writer
            .add_schema(IMU_TYPE, SCHEMA_ENCODING, IMU_DEFINITION.as_bytes())
            .map_err(mcap_err)?;
        let channel = writer
            .add_channel(schema, topic, MESSAGE_ENCODING, &imu_channel_metadata())
            .map_err(mcap_err)?;
        Ok(ImuBagWriter {
            path: path.to_path_buf(),
            tmp,
            writer,
            channel,
            buf: Vec::with_capacity(512),
            count: 0,
        })
    }

    /// Write one message; its stamp is its log and publish time, so a stamp before 1970 is
    /// refused.
    pub fn write(&mut self, imu: &Imu) -> Result<(), BagError> {
        let shown = self.path.display();
        let n = self.count + 1;
        let time = imu.stamp.ns_u64().ok_or_else(|| {
            err(
                BagErrorKind::Write,
                format!(
                    "{shown}: message {n}: stamp {} s is before 1970 and cannot be an MCAP log \
                     time",
                    imu.stamp.seconds_text()
                ),
            )
        })?;
        imu.write_cdr(&mut self.buf)
            .map_err(|e| err(BagErrorKind::Write, format!("{shown}: message {n}: {e}")))?;
        self.writer
            .write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: self.channel,
                    // rosbag2 writes 0.
                    sequence: 0,
                    log_time: time,
                    publish_time: time,
                },
                &self.buf,
            )
            .map_err(|e| err(BagErrorKind::Io, format!("{shown}: message {n}: {e}")))?;
        self.count = n;
        Ok(())
    }

    /// Messages written so far.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Write the summary and make the file appear at its path; the messages written.
    pub fn finish(mut self) -> Result<u64, BagError> {
        let shown = self.path.display().to_string();
        let io = |e: &dyn std::fmt::Display| err(BagErrorKind::Io, format!("{shown}: {e}"));
        self.writer.finish().map_err(|e| io(&e))?;
        let mut w = self.writer.into_inner();
        w.flush().map_err(|e| io(&e))?;
        w.get_ref().sync_all().map_err(|e| io(&e))?;
        drop(w);
        self.tmp.commit().map_err(|e| io(&e))?;
        Ok(self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metadata_yaml_file_lists() {
        let yaml_cpp = "rosbag2_bagfile_information:\n  version: 9\n  relative_file_paths:\n    \
                        - rosbag2_0.mcap\n    - \"rosbag2_1.mcap\"\n  files:\n    - path: x\n";
        assert_eq!(
            relative_file_paths(yaml_cpp).unwrap(),
            ["rosbag2_0.mcap", "rosbag2_1.mcap"]
        );
        let ruamel =
            "a:\n  relative_file_paths:\n  - imu.mcap\n  - 'it''s.mcap'\n  ros_distro: x\n";
        assert_eq!(
            relative_file_paths(ruamel).unwrap(),
            ["imu.mcap", "it's.mcap"]
        );
        let flow = "  relative_file_paths: [a.mcap, 'b.mcap']\n";
        assert_eq!(relative_file_paths(flow).unwrap(), ["a.mcap", "b.mcap"]);
        assert_eq!(relative_file_paths("version: 9\n"), None);
    }
}
