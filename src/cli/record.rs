//! `driftless record SERVICE... -o run.mcap [--duration D]`: record any of our services into an
//! MCAP file that Foxglove opens and plots without plugins (layout: [`crate::io::recording`]);
//! with `--format ros2`, a ROS 2 bag of `sensor_msgs/msg/Imu` messages, one topic per service,
//! that `ros2 bag play`, rosbags and Foxglove read ([`crate::io::ros2`]).
//!
//! The recorder is one more subscriber: the daemon's publishers never wait for it (a full
//! buffer loses the new sample, which the daemon counts and the recorder sees as a `seq` gap).
//! Its buffer is the largest the service allows, drained every eighth of the time it takes to
//! fill at the rate seen (1 to 20 ms).
//!
//! The file is written as `OUT.part` and renamed to `OUT` when the recording stops (SIGINT,
//! SIGTERM, `--duration`) with its summary and metadata written: a file named `OUT` is always
//! complete. A write error (a full disk) stops the recording with exit code 1 and leaves only
//! `OUT.part` (no summary; its finished chunks are readable by `mcap recover`); a SIGKILL leaves
//! the same, missing at most the last second.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime};

use crate::cli::CliError;
use crate::io::recording::{
    self, GyroMessage, RawMessage, ServiceCounts, StatsMessage, MESSAGE_ENCODING, METADATA_NAME,
    SCHEMA_ENCODING,
};
use crate::io::ros2::{self, ImuMapping, IMU_TYPE};
use crate::transport::{
    self, GyroSample, Input, RawSample, StatsSnapshot, Transport, GYRO_TYPE_NAME, RAW_TYPE_NAME,
    STATS_TYPE_NAME,
};

/// Arguments of `driftless record`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Services to record, e.g. demo/raw demo/corrected demo/stats (any hop of a pipeline).
    #[arg(required = true)]
    pub services: Vec<String>,
    /// The MCAP file to write (it appears when the recording stops; OUT.part until then).
    #[arg(short, long, value_name = "OUT.mcap")]
    pub output: PathBuf,
    /// Stop by itself after this long ("10s", "500ms", "1.5s", "90min", or seconds).
    #[arg(
        long,
        value_parser = crate::cli::duration::parse_duration,
        allow_hyphen_values = true
    )]
    pub duration: Option<Duration>,
    /// Where the pipeline's iceoryx2 files are.
    #[command(flatten)]
    pub iceoryx2: crate::cli::iceoryx2::Iceoryx2Args,
    /// Units of raw services' rates (the pipeline's input_units), stored with their channels
    /// (with --format ros2, needed to write a raw service in rad/s).
    #[arg(long, value_parser = ["deg/s", "rad/s"])]
    pub raw_units: Option<String>,
    /// What to write: `mcap`, our samples as JSON that Foxglove plots; or `ros2`, a ROS 2 bag
    /// (profile ros2, sensor_msgs/msg/Imu in CDR, topic /SERVICE) as `ros2 bag record` writes.
    #[arg(long, default_value = "mcap", value_parser = ["mcap", "ros2"])]
    pub format: String,
    /// With --format ros2: the messages' header.frame_id.
    #[arg(long, default_value = crate::transport::ros2::DEFAULT_FRAME_ID)]
    pub frame_id: String,
    /// With --format ros2: the gyro's white rate noise, 1 sigma of one sample in deg/s (N x
    /// sqrt(rate) from `driftless allan`'s N in deg/sqrt(s), or the data sheet's rate noise).
    /// Its square plus the square of the drift's own uncertainty (`drift_std`) is each axis'
    /// angular_velocity_covariance; without it the covariance is all zeros ("unknown").
    #[arg(long, value_name = "DEG_PER_S")]
    pub rate_noise: Option<f64>,
}

/// How often the open chunk is written out (the most a SIGKILL loses) and progress is shown.
const FLUSH_EVERY: Duration = Duration::from_secs(1);
/// Sleep when every subscriber is empty: an eighth of the time the first buffer to fill takes
/// at the rates seen over the last second (256 samples at 1 kHz: 32 ms), within these bounds
/// (the shortest while nothing comes), so that a recorder wakes the daemon's cores as rarely as
/// its buffers allow.
const MIN_SLEEP: Duration = Duration::from_millis(1);
const MAX_SLEEP: Duration = Duration::from_millis(20);

enum Port {
    Raw(Input<RawSample>),
    Gyro(Input<GyroSample>),
    Stats(Input<StatsSnapshot>),
}

/// One recorded service: its subscriber, channel and counts.
struct Recorded {
    service: String,
    port: Port,
    channel: u16,
    counts: ServiceCounts,
    reported_missing: u64,
    /// With --format ros2: the message reused for every sample.
    ros2: Option<ImuMapping>,
}

/// A message in CDR into `out`.
fn cdr(imu: &crate::io::ros2::Imu, out: &mut Vec<u8>) -> Result<(), String> {
    imu.write_cdr(out).map_err(|e| e.to_string())
}

/// `OUT.part` while recording; removed on drop unless kept or renamed.
struct Partial {
    part: PathBuf,
    out: PathBuf,
    keep: bool,
}

impl Partial {
    fn create(out: &Path) -> Result<(Partial, File), CliError> {
        if out.is_dir() {
            return Err(CliError::input(format!(
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
                if e.kind() == std::io::ErrorKind::AlreadyExists {
                    CliError::input(format!(
                        "{} exists: another recording is writing it, or one was killed (recover \
                         its chunks with `mcap recover`, or remove it)",
                        part.display()
                    ))
                } else {
                    CliError::input(format!("cannot write {}: {e}", part.display()))
                }
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

/// Subscribe to SERVICE... and record them until stopped.
pub fn run(args: Args) -> Result<(), CliError> {
    transport::quiet_logging();
    let mut seen = std::collections::HashSet::new();
    for s in &args.services {
        transport::check_service_name(s)
            .map_err(|e| CliError::input(format!("invalid service name {s:?}: {e}")))?;
        if !seen.insert(s.as_str()) {
            return Err(CliError::input(format!("service {s:?} named twice")));
        }
    }
    let ros2 = args.format == "ros2";
    if let Some(n) = args.rate_noise {
        if !ros2 {
            return Err(CliError::input(
                "--rate-noise is for --format ros2 (the covariance)",
            ));
        }
        if !(n.is_finite() && n >= 0.0) {
            return Err(CliError::input(format!(
                "--rate-noise {n} must be a finite number of deg/s >= 0"
            )));
        }
    }
    if args.frame_id != crate::transport::ros2::DEFAULT_FRAME_ID && !ros2 {
        return Err(CliError::input("--frame-id is for --format ros2"));
    }
    let prefix = args.iceoryx2.resolve(None)?;
    // Installed in main, before anything exists on disk: a signal ends the recording cleanly.
    let stop = crate::cli::signals::stop_flag();
    let (partial, file) = Partial::create(&args.output)?;
    let result = record(&args, &prefix, partial, file, &stop);
    transport::remove_prefix_leftovers(&prefix);
    result
}

fn record(
    args: &Args,
    prefix: &str,
    mut partial: Partial,
    file: File,
    stop: &AtomicBool,
) -> Result<(), CliError> {
    let node = Transport::new(
        prefix,
        &format!("driftless-record-{}", std::process::id()),
        Default::default(),
    )?;
    let ports = args
        .services
        .iter()
        .map(|s| subscribe(&node, s, prefix))
        .collect::<Result<Vec<_>, _>>()?;
    let ros2 = args.format == "ros2";
    if ros2 {
        for (service, port) in args.services.iter().zip(&ports) {
            match port {
                Port::Stats(_) => {
                    return Err(CliError::input(format!(
                        "service {service:?} carries {STATS_TYPE_NAME}: no ROS 2 message holds \
                         it; record it without --format ros2"
                    )))
                }
                Port::Raw(_) if args.raw_units.is_none() => {
                    return Err(CliError::input(format!(
                        "service {service:?} carries raw rates in the pipeline's input_units: \
                         give --raw-units so that they are written in rad/s"
                    )))
                }
                _ => {}
            }
        }
    }
    let size_probe = file
        .try_clone()
        .map_err(|e| CliError::internal(format!("{}: {e}", partial.part.display())))?;
    let part_name = partial.part.display().to_string();
    let write_error =
        |e: &dyn std::fmt::Display| CliError::internal(format!("writing {part_name}: {e}"));
    let mcap_write_error = |e: mcap::McapError| write_error(&mcap_error(&e));
    let options = if ros2 {
        // As rosbag2_storage_mcap: profile ros2; zstd as its compressed presets.
        mcap::WriteOptions::new()
            .profile(ros2::PROFILE)
            .compression(Some(mcap::Compression::Zstd))
    } else {
        mcap::WriteOptions::new().compression(Some(mcap::Compression::Lz4))
    };
    let mut writer = options
        .library(format!("driftless {}", env!("CARGO_PKG_VERSION")))
        .create(BufWriter::with_capacity(1 << 20, file))
        .map_err(mcap_write_error)?;
    let mut recorded = Vec::with_capacity(ports.len());
    for (service, port) in args.services.iter().zip(ports) {
        let (channel, ros2) = if ros2 {
            let topic = ros2::topic_for_service(service);
            let channel = add_ros2_channel(&mut writer, &topic).map_err(mcap_write_error)?;
            let to_rad = match (&port, args.raw_units.as_deref()) {
                (Port::Raw(_), Some("deg/s")) => std::f64::consts::PI / 180.0,
                _ => 1.0,
            };
            let m = ImuMapping::new(&args.frame_id, to_rad, args.rate_noise);
            (channel, Some(m))
        } else {
            let channel = add_channel(&mut writer, service, &port, args.raw_units.as_deref())
                .map_err(mcap_write_error)?;
            (channel, None)
        };
        recorded.push(Recorded {
            service: service.clone(),
            port,
            channel,
            counts: ServiceCounts::default(),
            reported_missing: 0,
            ros2,
        });
    }
    let listed: Vec<String> = recorded
        .iter()
        .map(|r| match r.ros2 {
            Some(_) => format!(
                "{} as {} ({IMU_TYPE})",
                r.service,
                ros2::topic_for_service(&r.service)
            ),
            None => format!("{} ({})", r.service, r.port.type_name()),
        })
        .collect();
    eprintln!(
        "driftless: recording {} to {} (Ctrl-C to stop)",
        listed.join(", "),
        args.output.display()
    );
    let started = SystemTime::now();
    let t0 = Instant::now();
    let bar = args.duration.map(crate::io::progress::timed);
    let outcome = drain(
        &mut writer,
        &mut recorded,
        args.duration.map(|d| t0 + d),
        stop,
        |total| {
            if let Some(bar) = &bar {
                let size = size_probe.metadata().map_or(0, |m| m.len());
                bar.set_position(t0.elapsed().as_millis() as u64);
                bar.set_message(format!(
                    "{:.0} s, {total} samples, {:.1} MB",
                    t0.elapsed().as_secs_f64(),
                    size as f64 / 1e6
                ));
            }
        },
    );
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    if ros2 && args.rate_noise.is_none() {
        eprintln!(
            "driftless: note: no --rate-noise: angular_velocity_covariance written as all zeros \
             (unknown to the reader)"
        );
    }
    let stopped_by = match outcome {
        Ok(how) => how,
        Err(e) => {
            // Keep what was written: no summary, so it cannot pass for a complete file.
            let _ = writer.into_inner();
            partial.keep = true;
            let total: u64 = recorded.iter().map(|r| r.counts.samples).sum();
            return Err(CliError::internal(format!(
                "{e}; recording stopped after {total} samples; {} has no summary (its finished \
                 chunks are readable with `mcap recover`); {} was not written",
                partial.part.display(),
                partial.out.display()
            )));
        }
    };
    let ended = SystemTime::now();
    let mut meta = BTreeMap::new();
    let mut put = |k: &str, v: String| {
        meta.insert(k.to_string(), v);
    };
    put("format_version", recording::FORMAT_VERSION.into());
    put("driftless_version", env!("CARGO_PKG_VERSION").into());
    put("prefix", prefix.into());
    put("services", args.services.join(","));
    put(
        "started_utc",
        humantime::format_rfc3339_millis(started).to_string(),
    );
    put(
        "ended_utc",
        humantime::format_rfc3339_millis(ended).to_string(),
    );
    put("duration_s", format!("{:.3}", t0.elapsed().as_secs_f64()));
    put("stopped_by", stopped_by.into());
    for r in &recorded {
        r.counts.metadata(&r.service, &mut meta);
    }
    writer
        .write_metadata(&mcap::records::Metadata {
            name: METADATA_NAME.into(),
            metadata: meta,
        })
        .and_then(|()| writer.finish().map(|_| ()))
        .map_err(mcap_write_error)?;
    let file = writer
        .into_inner()
        .into_inner()
        .map_err(|e| write_error(&e.into_error()))?;
    file.sync_all().map_err(|e| write_error(&e))?;
    std::fs::rename(&partial.part, &partial.out).map_err(|e| {
        CliError::internal(format!(
            "cannot rename {} to {}: {e}",
            partial.part.display(),
            partial.out.display()
        ))
    })?;
    partial.keep = true;
    for r in &recorded {
        let c = &r.counts;
        if matches!(r.port, Port::Stats(_)) {
            eprintln!("{}: {} snapshots", r.service, c.samples);
        } else {
            eprintln!(
                "{}: {} samples, {} missing (sequence gaps), {} epoch(s)",
                r.service, c.samples, c.missing, c.epochs
            );
            if let Some(m) = r.ros2.as_ref().filter(|m| m.held > 0) {
                eprintln!(
                    "driftless: warning: {}: {} message(s) carry a value a stage held or \
                     replaced (flagged input_invalid or output_repaired on the wire; an Imu \
                     message cannot say it)",
                    r.service, m.held
                );
            }
        }
    }
    let size = std::fs::metadata(&partial.out).map_or(0, |m| m.len());
    eprintln!(
        "wrote {} ({:.1} MB, stopped by {stopped_by})",
        partial.out.display(),
        size as f64 / 1e6
    );
    Ok(())
}

/// Subscribe to `service` with the largest buffer it allows, after checking its type.
fn subscribe(node: &Transport, service: &str, prefix: &str) -> Result<Port, CliError> {
    let type_name = node
        .payload_type_name(service)
        .map_err(|e| CliError::internal(e.to_string()))?;
    let Some(type_name) = type_name else {
        // Nothing to read is a run-time failure (exit 1), as for `tap`: the name may be right.
        return Err(CliError::internal(format!(
            "no service {service:?} under prefix {prefix:?} (is the pipeline running?)"
        )));
    };
    let opened = match type_name.as_str() {
        RAW_TYPE_NAME => node.open_input(service).map(Port::Raw),
        GYRO_TYPE_NAME => node.open_input(service).map(Port::Gyro),
        STATS_TYPE_NAME => node.open_input(service).map(Port::Stats),
        other => {
            if let Some(m) =
                crate::transport::wire_version_mismatch(&format!("service {service:?}"), other)
            {
                return Err(CliError::input(m));
            }
            return Err(CliError::input(format!(
                "service {service:?} carries {other}, not a driftless type \
                 ({RAW_TYPE_NAME}, {GYRO_TYPE_NAME}, {STATS_TYPE_NAME})"
            )));
        }
    };
    opened.map_err(|e| {
        let e = e.to_string();
        if e.contains("ExceedsMaxNumberOfSubscribers") {
            CliError::internal(format!(
                "service {service:?} has no room for another subscriber (raise max_subscribers \
                 under [iceoryx2] in the pipeline file)"
            ))
        } else {
            CliError::internal(e)
        }
    })
}

impl Port {
    fn buffer_size(&self) -> usize {
        match self {
            Port::Raw(i) => i.buffer_size(),
            Port::Gyro(i) => i.buffer_size(),
            Port::Stats(i) => i.buffer_size(),
        }
    }

    fn type_name(&self) -> &'static str {
        match self {
            Port::Raw(_) => RAW_TYPE_NAME,
            Port::Gyro(_) => GYRO_TYPE_NAME,
            Port::Stats(_) => STATS_TYPE_NAME,
        }
    }
}

fn add_channel(
    writer: &mut McapWriter,
    service: &str,
    port: &Port,
    raw_units: Option<&str>,
) -> mcap::McapResult<u16> {
    let (name, schema) = match port {
        Port::Raw(_) => (recording::RAW_SCHEMA, recording::raw_schema()),
        Port::Gyro(_) => (recording::GYRO_SCHEMA, recording::gyro_schema()),
        Port::Stats(_) => (recording::STATS_SCHEMA, recording::stats_schema()),
    };
    let schema_id = writer.add_schema(name, SCHEMA_ENCODING, schema.as_bytes())?;
    let mut meta = BTreeMap::new();
    meta.insert("service".to_string(), service.to_string());
    meta.insert("wire_type".to_string(), port.type_name().to_string());
    if matches!(port, Port::Raw(_)) {
        meta.insert(
            recording::RATE_UNITS_KEY.to_string(),
            raw_units
                .unwrap_or("the pipeline's input_units (not given: record --raw-units)")
                .to_string(),
        );
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
    let schema = writer.add_schema(
        IMU_TYPE,
        ros2::SCHEMA_ENCODING,
        ros2::IMU_DEFINITION.as_bytes(),
    )?;
    writer.add_channel(
        schema,
        topic,
        ros2::MESSAGE_ENCODING,
        &ros2::imu_channel_metadata(),
    )
}

/// An MCAP error as a person reads it: an I/O error's own message (the disk is full), not the
/// wrapper's.
fn mcap_error(e: &mcap::McapError) -> String {
    match e {
        mcap::McapError::Io(io) => io.to_string(),
        other => other.to_string(),
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

/// Take every sample of every service until a signal or the deadline, then once more; returns
/// what stopped it.
fn drain(
    writer: &mut McapWriter,
    recorded: &mut [Recorded],
    deadline: Option<Instant>,
    stop: &AtomicBool,
    mut progress: impl FnMut(u64),
) -> Result<&'static str, String> {
    let mut json = Vec::with_capacity(1024);
    let mut last_flush = Instant::now();
    let mut since_flush = vec![0u64; recorded.len()];
    let mut sleep = MIN_SLEEP;
    loop {
        let stopped_by = if stop.load(Ordering::Relaxed) {
            Some(crate::cli::signals::stopped_by().unwrap_or("a signal"))
        } else if deadline.is_some_and(|d| Instant::now() >= d) {
            Some("--duration")
        } else {
            None
        };
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
                .map(|(r, n)| r.port.buffer_size() as f64 * secs / *n as f64 / 8.0)
                .reduce(f64::min)
                .unwrap_or(0.0);
            sleep = Duration::from_secs_f64(
                sleep_s.clamp(MIN_SLEEP.as_secs_f64(), MAX_SLEEP.as_secs_f64()),
            );
            since_flush.iter_mut().for_each(|n| *n = 0);
            writer
                .flush()
                .map_err(|e| format!("write failed: {}", mcap_error(&e)))?;
            for r in recorded.iter_mut() {
                r.report_gaps();
            }
            progress(recorded.iter().map(|r| r.counts.samples).sum());
        }
        if got == 0 {
            std::thread::sleep(sleep);
        }
    }
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
            // With --format ros2, a sensor_msgs/msg/Imu in CDR; else our JSON.
            let received = match &self.port {
                Port::Raw(i) => i.receive().map(|s| {
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
                Port::Gyro(i) => i.receive().map(|s| {
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
                // Refused at start with --format ros2.
                Port::Stats(i) => i.receive().map(|s| {
                    s.map(|s| {
                        self.counts.count_unsequenced();
                        serde_json::to_writer(&mut *json, &StatsMessage::from(&s))
                            .map(|()| self.counts.samples)
                            .map_err(|e| e.to_string())
                    })
                }),
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

    /// New sequence gaps since the last report, on stderr (at most once a second).
    fn report_gaps(&mut self) {
        if self.counts.missing > self.reported_missing {
            let _ = writeln!(
                std::io::stderr(),
                "driftless: warning: {}: {} sample(s) missing (sequence gaps), {} so far",
                self.service,
                self.counts.missing - self.reported_missing,
                self.counts.missing
            );
            self.reported_missing = self.counts.missing;
        }
    }
}
