//! The recorder of `driftless record`: any of our services into an MCAP file that Foxglove
//! opens and plots without plugins (layout: [`crate::io::recording`]), or a ROS 2 bag of
//! `sensor_msgs/msg/Imu` messages, one topic per service, that `ros2 bag play`, rosbags and
//! Foxglove read ([`crate::transport::ros2::bag`]).
//!
//! The recorder is one more subscriber: the daemon's publishers never wait for it (a full
//! buffer loses the new sample, which the daemon counts and the recorder sees as a `seq` gap).
//! Its buffer is the largest the service allows, drained every eighth of the time it takes to
//! fill at the rate seen (1 to 20 ms).
//!
//! The file is written as `OUT.part` and renamed to `OUT` when the recording stops with its
//! summary and metadata written: a file named `OUT` is always complete. A write error (a full
//! disk) stops the recording and leaves only `OUT.part` (no summary; its finished chunks are
//! readable by `mcap recover`); a SIGKILL leaves the same, missing at most the last second.
//!
//! A sibling of [`crate::io::recording`], not a part of it: it writes bags through
//! [`crate::transport::ros2::bag`], which reads MCAP files with the recording's helpers.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime};

use super::ros2::bag;
use super::ros2::{Imu, ImuMapping, IMU_DEFINITION, IMU_TYPE};
use super::{AnyInput, Carried, Transport, TransportError, WireType};
use crate::io::recording::{
    self, GyroMessage, RawMessage, ServiceCounts, StatsMessage, MESSAGE_ENCODING, METADATA_NAME,
    SCHEMA_ENCODING,
};
use crate::units::{AccelUnit, RateUnit};
use crate::wire::{GYRO_TYPE_NAME, RAW_TYPE_NAME, STATS_TYPE_NAME};

/// How often the open chunk is written out (the most a SIGKILL loses) and progress is shown.
const FLUSH_EVERY: Duration = Duration::from_secs(1);
/// Sleep when every subscriber is empty: an eighth of the time the first buffer to fill takes
/// at the rates seen over the last second (256 samples at 1 kHz: 32 ms), within these bounds
/// (the shortest while nothing comes), so that a recorder wakes the daemon's cores as rarely as
/// its buffers allow.
const MIN_SLEEP: Duration = Duration::from_millis(1);
const MAX_SLEEP: Duration = Duration::from_millis(20);

/// What to record, and how.
#[derive(Debug, Clone)]
pub struct Settings {
    /// The services, each once.
    pub services: Vec<String>,
    /// The file to write (`OUT.part` until the recording stops).
    pub output: PathBuf,
    /// Units of raw services' rates (the pipeline's input_units).
    pub raw_units: Option<RateUnit>,
    /// Units of raw services' accelerometer readings (the pipeline's accel_units).
    pub raw_accel_units: Option<AccelUnit>,
    /// A ROS 2 bag instead of our JSON messages.
    pub ros2: Option<Ros2Bag>,
}

/// How a ROS 2 bag's Imu messages are written.
#[derive(Debug, Clone)]
pub struct Ros2Bag {
    /// `header.frame_id`.
    pub frame_id: String,
    /// White rate noise, 1 sigma of one sample in deg/s (the covariance; None: unknown).
    pub rate_noise: Option<f64>,
    /// The accelerometer's white noise, 1 sigma of one sample in m/s^2, for samples that carry
    /// no `accel_std` (None: their covariance unknown).
    pub accel_noise: Option<f64>,
    /// Factor from raw services' accelerometer units (their pipeline's `accel_units`) to m/s^2
    /// (None: not known; their readings are written "not provided").
    pub raw_accel_to_m_s2: Option<f64>,
}

/// Why a recording did not start or did not end whole.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The user's input: a service no recording holds, an output that cannot be written.
    #[error("{0}")]
    Input(String),
    /// A failure at run time: nothing to read, a write error.
    #[error("{0}")]
    Failed(String),
    /// iceoryx2 refused.
    #[error(transparent)]
    Transport(#[from] TransportError),
}

/// What a recording stored, once its file is complete.
#[derive(Debug, Clone)]
pub struct Summary {
    /// Each service, in the order given.
    pub services: Vec<ServiceSummary>,
    /// What stopped it: `SIGINT`, `SIGTERM`, `--duration`.
    pub stopped_by: &'static str,
    /// The complete file.
    pub output: PathBuf,
    /// Its size, bytes.
    pub bytes: u64,
}

/// One recorded service's part of a [`Summary`].
#[derive(Debug, Clone)]
pub struct ServiceSummary {
    /// The service.
    pub service: String,
    /// Its wire type.
    pub wire: WireType,
    /// What was recorded of it.
    pub counts: ServiceCounts,
    /// In a ROS 2 bag: messages carrying a value a stage held or replaced (an Imu message
    /// cannot say it).
    pub held: u64,
    /// In a ROS 2 bag: accelerometer readings written with an unknown covariance (all zeros:
    /// no `accel_std` in the sample, no `--accel-noise`).
    pub accel_unknown: u64,
    /// In a ROS 2 bag: raw accelerometer readings written "not provided", their units not
    /// given (`--raw-accel-units`).
    pub accel_units_unknown: u64,
}

/// What a recording reports about once a second.
#[derive(Debug, Clone)]
pub struct Progress {
    /// Since it started.
    pub elapsed: Duration,
    /// Samples recorded, every service.
    pub samples: u64,
    /// The file's size so far, bytes.
    pub bytes: u64,
    /// Services with sequence gaps new since the last report: (service, newly missing,
    /// missing so far).
    pub new_gaps: Vec<(String, u64, u64)>,
}

/// `OUT.part` while recording; removed on drop unless kept or renamed.
struct Partial {
    part: PathBuf,
    out: PathBuf,
    keep: bool,
}

impl Partial {
    fn create(out: &Path) -> Result<(Partial, File), RecordError> {
        if out.is_dir() {
            return Err(RecordError::Input(format!(
                "cannot write {}: is a directory",
                out.display()
            )));
        }
        let mut name = out.as_os_str().to_owned();
        name.push(".part");
        let part = PathBuf::from(name);
        let file = File::options()
            .write(true)
            .read(true)
            .create_new(true)
            .open(&part)
            .map_err(|e| {
                RecordError::Input(if e.kind() == std::io::ErrorKind::AlreadyExists {
                    format!(
                        "{} exists: another recording is writing it, or one was killed (recover \
                         its chunks with `mcap recover`, or remove it)",
                        part.display()
                    )
                } else {
                    format!("cannot write {}: {e}", part.display())
                })
            })?;
        Ok((
            Partial {
                part,
                out: out.to_path_buf(),
                keep: false,
            },
            file,
        ))
    }
}

impl Drop for Partial {
    fn drop(&mut self) {
        if !self.keep {
            let _ = std::fs::remove_file(&self.part);
        }
    }
}

type McapWriter = mcap::Writer<BufWriter<File>>;

/// One recorded service: its subscriber, channel and counts.
struct Recorded {
    service: String,
    input: AnyInput,
    channel: u16,
    counts: ServiceCounts,
    reported_missing: u64,
    /// In a ROS 2 bag: the message reused for every sample.
    ros2: Option<ImuMapping>,
}

/// A recording that has started: its services subscribed, its channels written.
pub struct Recorder {
    prefix: String,
    services: Vec<String>,
    recorded: Vec<Recorded>,
    /// Dropped before `partial`: a writer dropped unfinished writes its summary.
    writer: McapWriter,
    partial: Partial,
    size_probe: File,
    /// Its node, dropped after its subscribers.
    _node: Transport,
}

/// An MCAP error as a person reads it: an I/O error's own message (the disk is full), not the
/// wrapper's.
fn mcap_error(e: &mcap::McapError) -> String {
    match e {
        mcap::McapError::Io(io) => io.to_string(),
        other => other.to_string(),
    }
}

/// Subscribe to `service` with the largest buffer it allows, after checking its type.
fn subscribe(node: &Transport, service: &str, prefix: &str) -> Result<AnyInput, RecordError> {
    let foreign = |other: &str| {
        RecordError::Input(format!(
            "service {service:?} carries {other}, not a driftless type \
             ({RAW_TYPE_NAME}, {GYRO_TYPE_NAME}, {STATS_TYPE_NAME})"
        ))
    };
    let wire = match node
        .carried(service)
        .map_err(|e| RecordError::Failed(e.to_string()))?
    {
        // Nothing to read is a run-time failure (exit 1), as for `tap`: the name may be right.
        Carried::Missing => {
            return Err(RecordError::Failed(format!(
                "no service {service:?} under prefix {prefix:?} (is the pipeline running?)"
            )))
        }
        Carried::OtherVersion(m) => return Err(RecordError::Input(m)),
        Carried::Foreign(other) => return Err(foreign(&other)),
        Carried::Ours(WireType::Stop) => return Err(foreign(WireType::Stop.type_name())),
        Carried::Ours(w) => w,
    };
    node.open_any(service, wire).map_err(|e| {
        let e = e.to_string();
        RecordError::Failed(if e.contains("ExceedsMaxNumberOfSubscribers") {
            format!(
                "service {service:?} has no room for another subscriber (raise max_subscribers \
                 under [iceoryx2] in the pipeline file)"
            )
        } else {
            e
        })
    })
}

/// A bag's subscribers must be of Imu's kind: no stats, and raw rates in known units.
fn check_for_bag(settings: &Settings, service: &str, input: &AnyInput) -> Result<(), RecordError> {
    match input.wire_type() {
        WireType::Stats => Err(RecordError::Input(format!(
            "service {service:?} carries {STATS_TYPE_NAME}: no ROS 2 message holds it; record \
             it without --format ros2"
        ))),
        WireType::Raw if settings.raw_units.is_none() => Err(RecordError::Input(format!(
            "service {service:?} carries raw rates in the pipeline's input_units: give \
             --raw-units so that they are written in rad/s"
        ))),
        _ => Ok(()),
    }
}

/// The channel of one of our services, its messages our JSON.
fn add_channel(
    writer: &mut McapWriter,
    service: &str,
    wire: WireType,
    settings: &Settings,
) -> mcap::McapResult<u16> {
    let (name, schema) = match wire {
        WireType::Raw => (recording::RAW_SCHEMA, recording::raw_schema()),
        WireType::Gyro => (recording::GYRO_SCHEMA, recording::gyro_schema()),
        // Refused before (`subscribe`).
        WireType::Stats | WireType::Stop => (recording::STATS_SCHEMA, recording::stats_schema()),
    };
    let schema_id = writer.add_schema(name, SCHEMA_ENCODING, schema.as_bytes())?;
    let mut meta = BTreeMap::new();
    meta.insert("service".to_string(), service.to_string());
    meta.insert("wire_type".to_string(), wire.type_name().to_string());
    if wire == WireType::Raw {
        for (key, units, flag) in [
            (
                recording::RATE_UNITS_KEY,
                settings.raw_units.map(|u| u.to_string()),
                "input_units (not given: record --raw-units)",
            ),
            (
                recording::ACCEL_UNITS_KEY,
                settings.raw_accel_units.map(|u| u.to_string()),
                "accel_units (not given: record --raw-accel-units)",
            ),
        ] {
            let units = units.unwrap_or_else(|| format!("the pipeline's {flag}"));
            meta.insert(key.to_string(), units);
        }
    }
    writer.add_channel(
        schema_id,
        &recording::topic(service),
        MESSAGE_ENCODING,
        &meta,
    )
}

/// The channel of an Imu topic, as rosbag2 writes it.
fn add_ros2_channel(writer: &mut McapWriter, topic: &str) -> mcap::McapResult<u16> {
    let schema = writer.add_schema(IMU_TYPE, bag::SCHEMA_ENCODING, IMU_DEFINITION.as_bytes())?;
    writer.add_channel(
        schema,
        topic,
        bag::MESSAGE_ENCODING,
        &bag::imu_channel_metadata(),
    )
}

impl Recorder {
    /// Create `OUT.part`, subscribe to every service under `prefix` and write their channels.
    pub fn start(settings: &Settings, prefix: &str) -> Result<Recorder, RecordError> {
        let (partial, file) = Partial::create(&settings.output)?;
        let node = Transport::new(
            prefix,
            &format!("driftless-record-{}", std::process::id()),
            Default::default(),
        )?;
        let inputs = settings
            .services
            .iter()
            .map(|s| subscribe(&node, s, prefix))
            .collect::<Result<Vec<_>, _>>()?;
        if settings.ros2.is_some() {
            for (service, input) in settings.services.iter().zip(&inputs) {
                check_for_bag(settings, service, input)?;
            }
        }
        let size_probe = file
            .try_clone()
            .map_err(|e| RecordError::Failed(format!("{}: {e}", partial.part.display())))?;
        let write_error = |e: mcap::McapError| {
            RecordError::Failed(format!(
                "writing {}: {}",
                partial.part.display(),
                mcap_error(&e)
            ))
        };
        let options = if settings.ros2.is_some() {
            // As rosbag2_storage_mcap: profile ros2; zstd as its compressed presets.
            mcap::WriteOptions::new()
                .profile(bag::PROFILE)
                .compression(Some(mcap::Compression::Zstd))
        } else {
            mcap::WriteOptions::new().compression(Some(mcap::Compression::Lz4))
        };
        let mut writer = options
            .library(format!("driftless {}", env!("CARGO_PKG_VERSION")))
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(write_error)?;
        let mut recorded = Vec::with_capacity(inputs.len());
        for (service, input) in settings.services.iter().zip(inputs) {
            let (channel, mapping) = match &settings.ros2 {
                Some(bag) => {
                    let topic = bag::topic_for_service(service);
                    let channel = add_ros2_channel(&mut writer, &topic).map_err(write_error)?;
                    let to_rad = match input.wire_type() {
                        WireType::Raw => settings.raw_units.map_or(1.0, RateUnit::to_rad_per_s),
                        _ => 1.0,
                    };
                    let m = ImuMapping::new(&bag.frame_id, to_rad, bag.rate_noise)
                        .with_accel_noise(bag.accel_noise)
                        .with_raw_accel_units(bag.raw_accel_to_m_s2);
                    (channel, Some(m))
                }
                None => {
                    let channel = add_channel(&mut writer, service, input.wire_type(), settings)
                        .map_err(write_error)?;
                    (channel, None)
                }
            };
            recorded.push(Recorded {
                service: service.clone(),
                input,
                channel,
                counts: ServiceCounts::default(),
                reported_missing: 0,
                ros2: mapping,
            });
        }
        Ok(Recorder {
            _node: node,
            prefix: prefix.to_string(),
            services: settings.services.clone(),
            partial,
            size_probe,
            writer,
            recorded,
        })
    }

    /// What is recorded, one entry per service: `demo/corrected (driftless::GyroSample.v2)`,
    /// or in a bag `demo/corrected as /demo/corrected (sensor_msgs/msg/Imu)`.
    pub fn channels(&self) -> Vec<String> {
        self.recorded
            .iter()
            .map(|r| match r.ros2 {
                Some(_) => format!(
                    "{} as {} ({IMU_TYPE})",
                    r.service,
                    bag::topic_for_service(&r.service)
                ),
                None => format!("{} ({})", r.service, r.input.wire_type().type_name()),
            })
            .collect()
    }

    /// Record until `stop` (then `signal()` names what set it) or `deadline`, reporting to
    /// `progress` about once a second; then write the summary and metadata and rename the file
    /// to its name. A write error keeps `OUT.part`, without a summary.
    pub fn run(
        mut self,
        stop: &AtomicBool,
        signal: fn() -> Option<&'static str>,
        deadline: Option<Duration>,
        mut progress: impl FnMut(&Progress),
    ) -> Result<Summary, RecordError> {
        let started = SystemTime::now();
        let t0 = Instant::now();
        let size_probe = &self.size_probe;
        let outcome = drain(
            &mut self.writer,
            &mut self.recorded,
            deadline.map(|d| t0 + d),
            || {
                stop.load(Ordering::Relaxed)
                    .then(|| signal().unwrap_or("a signal"))
            },
            |samples, new_gaps| {
                progress(&Progress {
                    elapsed: t0.elapsed(),
                    samples,
                    bytes: size_probe.metadata().map_or(0, |m| m.len()),
                    new_gaps,
                })
            },
        );
        let stopped_by = match outcome {
            Ok(how) => how,
            Err(e) => {
                // Keep what was written: no summary, so it cannot pass for a complete file
                // (`into_inner` leaves the writer unfinished, where a drop would finish it).
                self.partial.keep = true;
                let total: u64 = self.recorded.iter().map(|r| r.counts.samples).sum();
                let message = format!(
                    "{e}; recording stopped after {total} samples; {} has no summary (its \
                     finished chunks are readable with `mcap recover`); {} was not written",
                    self.partial.part.display(),
                    self.partial.out.display()
                );
                let Recorder { writer, .. } = self;
                let _ = writer.into_inner();
                return Err(RecordError::Failed(message));
            }
        };
        let meta = self.metadata(started, t0.elapsed(), stopped_by);
        self.finish(meta, stopped_by)
    }

    /// The metadata record: the recording's times, how it stopped, and each service's counts.
    fn metadata(
        &self,
        started: SystemTime,
        took: Duration,
        stopped_by: &str,
    ) -> BTreeMap<String, String> {
        let ended = SystemTime::now();
        let mut meta = BTreeMap::new();
        let mut put = |k: &str, v: String| {
            meta.insert(k.to_string(), v);
        };
        put("format_version", recording::FORMAT_VERSION.into());
        put("driftless_version", env!("CARGO_PKG_VERSION").into());
        put("prefix", self.prefix.clone());
        put("services", self.services.join(","));
        put(
            "started_utc",
            humantime::format_rfc3339_millis(started).to_string(),
        );
        put(
            "ended_utc",
            humantime::format_rfc3339_millis(ended).to_string(),
        );
        put("duration_s", format!("{:.3}", took.as_secs_f64()));
        put("stopped_by", stopped_by.into());
        for r in &self.recorded {
            r.counts.metadata(&r.service, &mut meta);
        }
        meta
    }

    /// Write the metadata and the summary, sync, and rename `OUT.part` to `OUT`.
    fn finish(
        self,
        meta: BTreeMap<String, String>,
        stopped_by: &'static str,
    ) -> Result<Summary, RecordError> {
        let Recorder {
            mut partial,
            mut writer,
            recorded,
            ..
        } = self;
        let part_name = partial.part.display().to_string();
        let write_error =
            |e: &dyn std::fmt::Display| RecordError::Failed(format!("writing {part_name}: {e}"));
        writer
            .write_metadata(&mcap::records::Metadata {
                name: METADATA_NAME.into(),
                metadata: meta,
            })
            .and_then(|()| writer.finish().map(|_| ()))
            .map_err(|e| write_error(&mcap_error(&e)))?;
        let file = writer
            .into_inner()
            .into_inner()
            .map_err(|e| write_error(&e.into_error()))?;
        file.sync_all().map_err(|e| write_error(&e))?;
        std::fs::rename(&partial.part, &partial.out).map_err(|e| {
            RecordError::Failed(format!(
                "cannot rename {} to {}: {e}",
                partial.part.display(),
                partial.out.display()
            ))
        })?;
        partial.keep = true;
        Ok(Summary {
            services: recorded
                .into_iter()
                .map(|r| ServiceSummary {
                    wire: r.input.wire_type(),
                    held: r.ros2.as_ref().map_or(0, |m| m.held),
                    accel_unknown: r.ros2.as_ref().map_or(0, |m| m.accel_unknown),
                    accel_units_unknown: r.ros2.as_ref().map_or(0, |m| m.accel_units_unknown),
                    service: r.service,
                    counts: r.counts,
                })
                .collect(),
            stopped_by,
            bytes: std::fs::metadata(&partial.out).map_or(0, |m| m.len()),
            output: partial.out.clone(),
        })
    }
}

fn realtime_ns() -> u64 {
    SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// Write one message, logged at `now` (the receive time, as `ros2 bag record` logs it).
fn write(
    writer: &mut McapWriter,
    channel: u16,
    seq: u64,
    now: u64,
    data: &[u8],
) -> Result<(), String> {
    writer
        .write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: channel,
                // MCAP's per-channel sequence is 32 bits: the low bits of ours.
                sequence: seq as u32,
                log_time: now,
                publish_time: now,
            },
            data,
        )
        .map_err(|e| format!("write failed: {}", mcap_error(&e)))
}

/// Take every sample of every service until `stopped` says what stopped it or the deadline
/// passes, then once more; returns what stopped it.
fn drain(
    writer: &mut McapWriter,
    recorded: &mut [Recorded],
    deadline: Option<Instant>,
    stopped: impl Fn() -> Option<&'static str>,
    mut progress: impl FnMut(u64, Vec<(String, u64, u64)>),
) -> Result<&'static str, String> {
    let mut json = Vec::with_capacity(1024);
    let mut last_flush = Instant::now();
    let mut since_flush = vec![0u64; recorded.len()];
    let mut sleep = MIN_SLEEP;
    loop {
        let stopped_by = stopped().or_else(|| {
            deadline
                .is_some_and(|d| Instant::now() >= d)
                .then_some("--duration")
        });
        let now = realtime_ns();
        let mut got = 0;
        for (r, n) in recorded.iter_mut().zip(&mut since_flush) {
            let taken = r.take_all(writer, now, &mut json)?;
            *n += taken;
            got += taken;
        }
        if let Some(how) = stopped_by {
            return Ok(how);
        }
        if last_flush.elapsed() >= FLUSH_EVERY {
            let secs = last_flush.elapsed().as_secs_f64();
            last_flush = Instant::now();
            // Nothing came: no rate to go by, so stay ready for a burst.
            let sleep_s = recorded
                .iter()
                .zip(&since_flush)
                .filter(|(_, n)| **n > 0)
                .map(|(r, n)| r.input.buffer_size() as f64 * secs / *n as f64 / 8.0)
                .reduce(f64::min)
                .unwrap_or(0.0);
            sleep = Duration::from_secs_f64(
                sleep_s.clamp(MIN_SLEEP.as_secs_f64(), MAX_SLEEP.as_secs_f64()),
            );
            since_flush.iter_mut().for_each(|n| *n = 0);
            writer
                .flush()
                .map_err(|e| format!("write failed: {}", mcap_error(&e)))?;
            let new_gaps = recorded.iter_mut().filter_map(Recorded::new_gaps).collect();
            progress(recorded.iter().map(|r| r.counts.samples).sum(), new_gaps);
        }
        if got == 0 {
            std::thread::sleep(sleep);
        }
    }
}

/// A message in CDR into `out`.
fn cdr(imu: &Imu, out: &mut Vec<u8>) -> Result<(), String> {
    imu.write_cdr(out).map_err(|e| e.to_string())
}

impl Recorded {
    /// Write every sample waiting in this service's buffer; returns how many.
    fn take_all(
        &mut self,
        writer: &mut McapWriter,
        now: u64,
        json: &mut Vec<u8>,
    ) -> Result<u64, String> {
        let mut n = 0;
        loop {
            json.clear();
            // In a bag, a sensor_msgs/msg/Imu in CDR; else our JSON.
            let received = match &self.input {
                AnyInput::Raw(i) => i.receive().map(|s| {
                    s.map(|s| {
                        self.counts.count(s.epoch, s.seq);
                        match &mut self.ros2 {
                            Some(m) => m.raw(&s).and_then(|imu| cdr(imu, json)),
                            None => serde_json::to_writer(&mut *json, &RawMessage::from(&s))
                                .map_err(|e| e.to_string()),
                        }
                        .map(|()| s.seq)
                    })
                }),
                AnyInput::Gyro(i) => i.receive().map(|s| {
                    s.map(|s| {
                        self.counts.count(s.epoch, s.seq);
                        match &mut self.ros2 {
                            Some(m) => m.gyro(&s).and_then(|imu| cdr(imu, json)),
                            None => serde_json::to_writer(&mut *json, &GyroMessage::from(&s))
                                .map_err(|e| e.to_string()),
                        }
                        .map(|()| s.seq)
                    })
                }),
                // Refused in a bag at start.
                AnyInput::Stats(i) => i.receive().map(|s| {
                    s.map(|s| {
                        self.counts.count_unsequenced();
                        serde_json::to_writer(&mut *json, &StatsMessage::from(&s))
                            .map(|()| self.counts.samples)
                            .map_err(|e| e.to_string())
                    })
                }),
                // Refused at start.
                AnyInput::Stop(_) => Ok(None),
            }
            .map_err(|e| format!("{}: {e}", self.service))?;
            let Some(encoded) = received else {
                return Ok(n);
            };
            let seq = encoded.map_err(|e| format!("{}: {e}", self.service))?;
            write(writer, self.channel, seq, now, json)?;
            n += 1;
        }
    }

    /// Sequence gaps new since the last report: (service, newly missing, missing so far).
    fn new_gaps(&mut self) -> Option<(String, u64, u64)> {
        let missing = self.counts.missing;
        (missing > self.reported_missing).then(|| {
            let new = missing - self.reported_missing;
            self.reported_missing = missing;
            (self.service.clone(), new, missing)
        })
    }
}
