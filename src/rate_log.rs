//! A rate log, whatever holds it: a CSV table ([`crate::io::csv_table`]) or the
//! `sensor_msgs/msg/Imu` topic of a ROS 2 bag ([`crate::transport::ros2`]). The offline commands
//! (`allan`, `denoise`, `nav-eval`, `train`, `eval`) read their input through [`read_log`].
//!
//! A bag gives three columns, `x`, `y`, `z`: the messages' `angular_velocity` in rad/s as the
//! message definition has it (REP 103), unconverted, so that the same doubles give the same
//! results from a bag as from a CSV file. Asked for by name, `ax`, `ay`, `az` are its
//! `linear_acceleration` in m/s^2 ([`BAG_ACCEL_COLUMNS`]), refused when the messages mark it
//! not provided. Its rate comes from the stamps ([`Stamps`]): the
//! median interval between consecutive `header.stamp`s, robust to gaps. A stamp that does not
//! rise, a message that does not decode and a non-finite rate are errors naming the file, the
//! topic, the message's number and its log time; gaps and jitter are counted and reported
//! ([`Stamps::irregular`]), never filled in.

use std::path::{Path, PathBuf};

use crate::io::content::{sniff, Content, Sniffed};
use crate::io::csv_table::{read_table, read_table_keeping_time, Table, TimeColumn};
use crate::io::{BagError, BagErrorKind, InputError};
use crate::transport::ros2::bag::{Bag, TopicInfo};
use crate::transport::ros2::seconds_text;
use crate::units::{AccelUnit, MagUnit, RateUnit};

/// The column names a bag's angular velocity is read into.
pub const BAG_COLUMNS: [&str; 3] = ["x", "y", "z"];

/// The column names a bag's linear acceleration is read into, when named.
pub const BAG_ACCEL_COLUMNS: [&str; 3] = ["ax", "ay", "az"];

/// How far a rate given for a bag (a command's `--rate`, a pipeline's `rate_hz`) may lie from
/// its stamps' rate, as a fraction of the reference rate.
pub const RATE_TOLERANCE: f64 = 0.01;

/// An interval further than this fraction from the median interval is irregular.
const IRREGULAR_FRACTION: f64 = 0.5;

/// What a rate log is, for a file that holds something else.
pub const RATE_LOG_TAKES: &str = "a rate log is CSV text (gzip-compressed too) or a ROS 2 bag \
(an MCAP file or a rosbag2 directory)";

/// Whether `path` is read as a ROS 2 bag: a directory (a rosbag2 bag), or a file that holds
/// MCAP, whatever its name ([`crate::io::content`]). Anything else is read as CSV.
pub fn is_bag(path: &Path) -> bool {
    sniff(path).is_ok_and(|s| matches!(s.content, Content::Directory | Content::Mcap))
}

/// What a bag's stamps say about its sampling.
#[derive(Debug, Clone, PartialEq)]
pub struct Stamps {
    /// Messages read.
    pub count: u64,
    /// The first and last stamps, ns since the epoch.
    pub first_ns: i64,
    /// See `first_ns`.
    pub last_ns: i64,
    /// The median interval between consecutive stamps, ns (0 with fewer than 2 messages).
    pub median_interval_ns: i64,
    /// Intervals longer than 1.5x the median: samples missing.
    pub gaps: u64,
    /// The longest interval, ns.
    pub longest_ns: i64,
    /// Intervals shorter than 0.5x the median.
    pub short: u64,
    /// The shortest interval, ns.
    pub shortest_ns: i64,
}

impl Stamps {
    /// The sample rate the stamps give, Hz (from the median interval); None with fewer than
    /// two messages.
    pub fn rate_hz(&self) -> Option<f64> {
        (self.median_interval_ns > 0).then(|| 1e9 / self.median_interval_ns as f64)
    }

    /// From stamps in file order, ns (a step back counts as a short interval).
    pub fn from_stamps(stamps: &[i64]) -> Stamps {
        let mut intervals: Vec<i64> = stamps.windows(2).map(|w| w[1] - w[0]).collect();
        let mut s = Stamps {
            count: stamps.len() as u64,
            first_ns: stamps.first().copied().unwrap_or(0),
            last_ns: stamps.last().copied().unwrap_or(0),
            median_interval_ns: 0,
            gaps: 0,
            longest_ns: 0,
            short: 0,
            shortest_ns: 0,
        };
        if intervals.is_empty() {
            return s;
        }
        let mid = intervals.len() / 2;
        let median = *intervals.select_nth_unstable(mid).1;
        s.median_interval_ns = median;
        let (lo, hi) = (
            median as f64 * (1.0 - IRREGULAR_FRACTION),
            median as f64 * (1.0 + IRREGULAR_FRACTION),
        );
        s.longest_ns = i64::MIN;
        s.shortest_ns = i64::MAX;
        for &d in &intervals {
            s.gaps += u64::from(d as f64 > hi);
            s.short += u64::from((d as f64) < lo);
            s.longest_ns = s.longest_ns.max(d);
            s.shortest_ns = s.shortest_ns.min(d);
        }
        s
    }

    /// One line on what is irregular in the stamps, None when every interval is within 50 %
    /// of the median.
    pub fn irregular(&self) -> Option<String> {
        if self.gaps == 0 && self.short == 0 {
            return None;
        }
        let period = self.median_interval_ns as f64;
        let mut parts = Vec::new();
        if self.gaps > 0 {
            parts.push(format!(
                "{} gaps (intervals over 1.5x the median {:.6} s; the longest {:.6} s, {:.1} \
                 periods): samples are missing there",
                self.gaps,
                period * 1e-9,
                self.longest_ns as f64 * 1e-9,
                self.longest_ns as f64 / period
            ));
        }
        if self.short > 0 {
            parts.push(format!(
                "{} intervals under half the median (the shortest {:.6} s)",
                self.short,
                self.shortest_ns as f64 * 1e-9
            ));
        }
        Some(parts.join("; "))
    }
}

/// What a bag log was read from.
#[derive(Debug, Clone, PartialEq)]
pub struct BagLog {
    /// The Imu topic read.
    pub topic: String,
    /// What its stamps say.
    pub stamps: Stamps,
}

/// A rate log: its columns, and where they came from.
#[derive(Debug, Clone, PartialEq)]
pub struct RateLog {
    /// The rate columns (a bag's: [`BAG_COLUMNS`], rad/s).
    pub table: Table,
    /// Where they came from.
    pub origin: LogOrigin,
}

/// Where a log's columns came from: the file, and for a bag its topic and stamps.
#[derive(Debug, Clone, PartialEq)]
pub struct LogOrigin {
    /// The file or bag directory.
    pub path: PathBuf,
    /// Set when the log is a bag.
    pub bag: Option<BagLog>,
    /// One line when the file's name claims another format than it holds (it was read by
    /// what it holds): "x.mcap: named .mcap but holds text: read as CSV".
    pub format_note: Option<String>,
}

impl LogOrigin {
    /// The sample rate to use: `given` (a command's `--rate`) for a CSV file, where it is
    /// required; for a bag the stamps' rate, which `given` must match within 1 %.
    pub fn rate(&self, given: Option<f64>) -> Result<f64, String> {
        let shown = self.path.display();
        let Some(bag) = &self.bag else {
            return given.ok_or_else(|| {
                format!(
                    "{shown}: --rate is needed for a CSV log (a bag's rate comes from its stamps)"
                )
            });
        };
        let Some(stamps) = bag.stamps.rate_hz() else {
            return Err(format!(
                "{shown}: topic {}: {} message(s): too few stamps to give a rate",
                bag.topic, bag.stamps.count
            ));
        };
        match given {
            Some(r) if (r - stamps).abs() > RATE_TOLERANCE * stamps => Err(format!(
                "{shown}: topic {}: --rate {r} Hz, but the stamps say {stamps:.6} Hz (median \
                 interval {} ns)",
                bag.topic, bag.stamps.median_interval_ns
            )),
            Some(r) => Ok(r),
            None => Ok(stamps),
        }
    }

    /// The units of the log's rates: a bag's are rad/s; `given` (a command's `--units`) must
    /// agree; a CSV log's are `given`, deg/s without it.
    pub fn units(&self, given: Option<RateUnit>) -> Result<RateUnit, String> {
        match (&self.bag, given) {
            (None, given) => Ok(given.unwrap_or(RateUnit::DegPerS)),
            (Some(_), None | Some(RateUnit::RadPerS)) => Ok(RateUnit::RadPerS),
            (Some(bag), Some(other)) => Err(format!(
                "{}: topic {}: a sensor_msgs/msg/Imu angular velocity is in rad/s (REP 103), \
                 not {other}: leave --units out",
                self.path.display(),
                bag.topic
            )),
        }
    }

    /// The units of the log's accelerometer columns: a bag's are m/s^2 (`given`, a command's
    /// `--accel-units`, must agree); a CSV log's are `given`, m/s^2 without it.
    pub fn accel_units(&self, given: Option<AccelUnit>) -> Result<AccelUnit, String> {
        match (&self.bag, given) {
            (None, given) => Ok(given.unwrap_or(AccelUnit::MPerS2)),
            (Some(_), None | Some(AccelUnit::MPerS2)) => Ok(AccelUnit::MPerS2),
            (Some(bag), Some(other)) => Err(format!(
                "{}: topic {}: a sensor_msgs/msg/Imu linear acceleration is in m/s^2 (REP 103), \
                 not {other}: leave --accel-units out",
                self.path.display(),
                bag.topic
            )),
        }
    }

    /// A note for stderr when a bag's stamps are irregular.
    pub fn stamp_note(&self) -> Option<String> {
        let bag = self.bag.as_ref()?;
        bag.stamps.irregular().map(|what| {
            format!(
                "{}: topic {}: irregular stamps: {what}",
                self.path.display(),
                bag.topic
            )
        })
    }
}

/// A CSV rate log (gzip-compressed too), as [`read_table`] or [`read_table_keeping_time`]
/// reads it; `topic` is an error here.
fn read_csv_log(
    path: &Path,
    wanted: &[String],
    topic: Option<&str>,
    keep_time: bool,
    sniffed: &Sniffed,
) -> Result<RateLog, InputError> {
    if let Some(t) = topic {
        return Err(InputError::file(
            path,
            format!("--topic {t}: not a ROS 2 bag (an MCAP file or a rosbag2 directory)"),
        ));
    }
    let table = if keep_time {
        read_table_keeping_time(path, wanted)?
    } else {
        read_table(path, wanted)?
    };
    let origin = LogOrigin {
        path: path.to_path_buf(),
        bag: None,
        format_note: sniffed.csv_note(),
    };
    Ok(RateLog { table, origin })
}

/// The bag columns `wanted` names, as indices into `all` (x, y, z, ax, ay, az); empty, x, y, z.
fn bag_picks(
    path: &Path,
    topic: &str,
    wanted: &[String],
    all: &[&str],
) -> Result<Vec<usize>, InputError> {
    let mut picks = Vec::with_capacity(wanted.len().max(3));
    for w in wanted {
        match all.iter().position(|c| c == w) {
            Some(i) => picks.push(i),
            None => {
                return Err(InputError::file(
                    path,
                    format!(
                        "topic {topic}: no column {w:?}: a bag's columns are x, y, z (its \
                         angular_velocity, rad/s) and ax, ay, az (its linear_acceleration, m/s^2)"
                    ),
                ))
            }
        }
    }
    if picks.is_empty() {
        picks.extend(0..3);
    }
    Ok(picks)
}

/// The table of a bag's picked columns (and its stamps as a time column with `keep_time`).
fn bag_table(
    path: &Path,
    picks: &[usize],
    all: &[&str],
    axes: &mut [Vec<f64>; 6],
    stamps: &[i64],
    keep_time: bool,
) -> Table {
    let time = keep_time.then(|| TimeColumn {
        name: "t_s".into(),
        position: 0,
        cells: stamps.iter().map(|&ns| seconds_text(ns)).collect(),
    });
    Table {
        path: path.to_path_buf(),
        names: picks.iter().map(|&i| all[i].to_string()).collect(),
        // Each axis moved out at its last pick, copied only for a column named twice.
        columns: picks
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                if picks[k + 1..].contains(&i) {
                    axes[i].clone()
                } else {
                    std::mem::take(&mut axes[i])
                }
            })
            .collect(),
        has_header: true,
        time,
    }
}

/// Read a rate log, by what the file holds whatever its name: a bag (a directory, or an MCAP
/// file) through its Imu topic (`topic`, or its only one), or CSV text (gzip-compressed too)
/// as [`read_table`] (with `keep_time`, [`read_table_keeping_time`]) does; anything else is
/// refused, saying what it holds. `wanted` names columns (a bag's: `x`, `y`, `z`); empty,
/// every rate column. `topic` with a CSV file is an error.
pub fn read_log(
    path: &Path,
    wanted: &[String],
    topic: Option<&str>,
    keep_time: bool,
) -> Result<RateLog, InputError> {
    let sniffed = sniff(path)?;
    let is_bag = matches!(sniffed.content, Content::Directory | Content::Mcap);
    if !is_bag && !sniffed.content.is_text() {
        return Err(sniffed.refuse(RATE_LOG_TAKES));
    }
    if !is_bag {
        return read_csv_log(path, wanted, topic, keep_time, &sniffed);
    }
    let bag = Bag::open(path)?;
    let topic = bag.imu_topic(topic)?;
    // Picks index the six columns a bag has: x, y, z, ax, ay, az.
    let all: Vec<&str> = BAG_COLUMNS
        .iter()
        .chain(&BAG_ACCEL_COLUMNS)
        .copied()
        .collect();
    let picks = bag_picks(path, &topic, wanted, &all)?;
    let accel = picks.iter().any(|&i| i >= 3);
    let needed: [bool; 6] = std::array::from_fn(|i| picks.contains(&i));
    let shown = path.display();
    let mut axes: [Vec<f64>; 6] = Default::default();
    let mut stamps: Vec<i64> = Vec::new();
    for m in bag.imu_messages(&topic)? {
        let m = m?;
        let at = || {
            format!(
                "{shown}: topic {topic}, message {} (log time {} ns)",
                m.number, m.log_time_ns
            )
        };
        let t = m.msg.stamp.ns();
        if let Some(&prev) = stamps.last() {
            if t <= prev {
                return Err(BagError {
                    kind: BagErrorKind::Stamp,
                    message: format!(
                        "{}: stamp {} ns is not after the previous message's {prev} ns: stamps \
                         must rise",
                        at(),
                        t
                    ),
                }
                .into());
            }
        }
        let w = m.msg.angular_velocity;
        let a = m.msg.linear_acceleration;
        if accel && m.msg.linear_acceleration_covariance[0] == -1.0 {
            return Err(BagError {
                kind: BagErrorKind::Value,
                message: format!(
                    "{}: linear_acceleration is marked not provided (covariance[0] = -1): the \
                     topic carries no accelerometer",
                    at()
                ),
            }
            .into());
        }
        let values = [w[0], w[1], w[2], a[0], a[1], a[2]];
        if let Some(i) = picks.iter().copied().find(|&i| !values[i].is_finite()) {
            let field = if i < 3 {
                format!("angular_velocity.{}", BAG_COLUMNS[i])
            } else {
                format!("linear_acceleration.{}", BAG_COLUMNS[i - 3])
            };
            return Err(BagError {
                kind: BagErrorKind::Value,
                message: format!("{}: {field} is {}", at(), values[i]),
            }
            .into());
        }
        stamps.push(t);
        for (i, (col, v)) in axes.iter_mut().zip(values).enumerate() {
            if needed[i] {
                col.push(v);
            }
        }
    }
    if stamps.is_empty() {
        return Err(InputError::file(
            path,
            format!("topic {topic}: no messages"),
        ));
    }
    let table = bag_table(path, &picks, &all, &mut axes, &stamps, keep_time);
    Ok(RateLog {
        table,
        origin: LogOrigin {
            path: path.to_path_buf(),
            bag: Some(BagLog {
                topic,
                stamps: Stamps::from_stamps(&stamps),
            }),
            format_note: sniffed.note("read as a ROS 2 bag"),
        },
    })
}

/// The magnetometer's readings of a log, for `mag-cal`: uT, in the log's order.
#[derive(Debug, Clone, PartialEq)]
pub struct MagLog {
    /// The readings, uT (those a recording marks absent left out).
    pub readings_ut: Vec<[f64; 3]>,
    /// What was read: "x.csv, columns mx, my, mz (uT)" or "x.mcap, topic /nav/raw".
    pub source: String,
    /// One line when the file's name claims another format than it holds.
    pub format_note: Option<String>,
}

/// Why a recording without a magnetometer cannot be calibrated from.
const NO_MAG: &str = "no magnetometer in it: give a ROS 2 bag with a \
sensor_msgs/msg/MagneticField topic, a `driftless record` recording of the raw service, or a CSV \
file with --mag-columns";

/// Read a log's magnetometer, by what the file holds whatever its name: a ROS 2 bag's
/// `sensor_msgs/msg/MagneticField` topic (`topic` or its only one, tesla), a `driftless record`
/// recording (its raw or corrected samples' `mag`, `topic` or its only such topic, else its
/// only raw one) or CSV text (the three `columns`, in `unit`).
pub fn read_mag_log(
    path: &Path,
    columns: Option<&[String]>,
    unit: MagUnit,
    topic: Option<&str>,
) -> Result<MagLog, InputError> {
    let sniffed = sniff(path)?;
    match sniffed.content {
        Content::Directory => read_mag_bag(path, &Bag::open(path)?, topic),
        // An MCAP file is a bag when it has a magnetometer topic, else a recording.
        Content::Mcap => match Bag::open(path) {
            Ok(bag) if bag.topics().iter().any(TopicInfo::is_mag) => {
                read_mag_bag(path, &bag, topic)
            }
            _ => read_mag_recording(path, topic),
        },
        c if c.is_text() => {
            let Some(columns) = columns.filter(|c| c.len() == 3) else {
                return Err(InputError::file(
                    path,
                    "a CSV file: name its magnetometer's three columns with --mag-columns \
                     (x,y,z)",
                ));
            };
            if topic.is_some() {
                return Err(InputError::file(path, "--topic: not an MCAP recording"));
            }
            let table = read_table(path, columns)?;
            let to_ut = unit.to_tesla() * 1e6;
            let n = table.columns.first().map_or(0, Vec::len);
            let readings_ut = (0..n)
                .map(|k| [0, 1, 2].map(|i| table.columns[i][k] * to_ut))
                .collect();
            Ok(MagLog {
                readings_ut,
                source: format!(
                    "{}, columns {} ({unit})",
                    path.display(),
                    columns.join(", ")
                ),
                format_note: sniffed.csv_note(),
            })
        }
        _ => Err(sniffed.refuse(
            "mag-cal reads CSV text (gzip-compressed too) or a `driftless record` recording",
        )),
    }
}

/// A bag's magnetometer topic (see [`read_mag_log`]): every reading in file order, uT; one
/// that does not decode or is not finite stops the read, naming its message.
fn read_mag_bag(path: &Path, bag: &Bag, topic: Option<&str>) -> Result<MagLog, InputError> {
    let mags: Vec<TopicInfo> = bag.topics().into_iter().filter(TopicInfo::is_mag).collect();
    let topic = match (topic, mags.as_slice()) {
        (Some(t), _) => t.to_string(),
        (None, [only]) => only.topic.clone(),
        (None, []) => return Err(InputError::file(path, NO_MAG)),
        (None, _) => {
            let names: Vec<_> = mags.iter().map(|t| t.topic.as_str()).collect();
            return Err(InputError::file(
                path,
                format!(
                    "choose its magnetometer topic with --topic: {}",
                    names.join(", ")
                ),
            ));
        }
    };
    let mut readings_ut = Vec::new();
    for m in bag.mag_messages(&topic)? {
        let m = m?;
        let f = m.msg.magnetic_field;
        if let Some(v) = f.iter().find(|v| !v.is_finite()) {
            return Err(InputError::file(
                path,
                format!(
                    "topic {topic}, message {} (log time {} ns): magnetic_field is {v}",
                    m.number, m.log_time_ns
                ),
            ));
        }
        readings_ut.push(f.map(|v| v * 1e6));
    }
    Ok(MagLog {
        readings_ut,
        source: format!("{}, topic {topic} (tesla)", path.display()),
        format_note: None,
    })
}

/// A recording's magnetometer (see [`read_mag_log`]).
fn read_mag_recording(path: &Path, topic: Option<&str>) -> Result<MagLog, InputError> {
    use crate::io::recording::{GyroMessage, RawMessage, Recording, GYRO_SCHEMA, RAW_SCHEMA};
    let rec = Recording::open(path).map_err(|e| InputError::file(path, e))?;
    let ours: Vec<_> = rec
        .channels()
        .into_iter()
        .filter(|c| c.schema == RAW_SCHEMA || c.schema == GYRO_SCHEMA)
        .collect();
    let raw: Vec<_> = ours.iter().filter(|c| c.schema == RAW_SCHEMA).collect();
    let channel = match topic {
        Some(t) => ours
            .iter()
            .find(|c| c.topic == t || c.topic == format!("/{t}")),
        None if ours.len() == 1 => ours.first(),
        // A pipeline's recording: its raw samples, as the sensor gave them.
        None => (raw.len() == 1).then(|| raw[0]),
    };
    let Some(channel) = channel else {
        let topics: Vec<_> = ours.iter().map(|c| c.topic.as_str()).collect();
        let why = match (ours.is_empty(), topic) {
            (true, _) => NO_MAG.to_string(),
            (false, Some(t)) => format!(
                "--topic {t}: no such topic of raw or corrected samples; it has {}",
                topics.join(", ")
            ),
            (false, None) => format!("choose its topic with --topic: {}", topics.join(", ")),
        };
        return Err(InputError::file(path, why));
    };
    let to_ut = |m: [f64; 3]| m.map(|v| v * 1e6);
    let mut readings_ut = Vec::new();
    if channel.schema == RAW_SCHEMA {
        for m in rec.messages::<RawMessage>(&channel.topic) {
            let m = m.map_err(|e| InputError::file(path, e))?;
            readings_ut.extend(m.mag_t.map(|x| to_ut(x.into())));
        }
    } else {
        for m in rec.messages::<GyroMessage>(&channel.topic) {
            let m = m.map_err(|e| InputError::file(path, e))?;
            readings_ut.extend(m.mag_t.map(|x| to_ut(x.into())));
        }
    }
    Ok(MagLog {
        readings_ut,
        source: format!("{}, topic {}", path.display(), channel.topic),
        format_note: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::recording::{self, RawMessage};
    use crate::wire::{RawSample, RAW_MAG};

    /// A recording of raw samples, every third without the magnetometer: its readings in uT,
    /// the absent ones left out; a CSV without --mag-columns is refused saying why.
    #[test]
    fn a_recordings_magnetometer_is_read_in_ut() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rec.mcap");
        let mut w = mcap::Writer::new(std::io::BufWriter::new(
            std::fs::File::create(&path).unwrap(),
        ))
        .unwrap();
        let schema = w
            .add_schema(
                recording::RAW_SCHEMA,
                recording::SCHEMA_ENCODING,
                recording::raw_schema().as_bytes(),
            )
            .unwrap();
        let channel = w
            .add_channel(
                schema,
                "/nav/raw",
                recording::MESSAGE_ENCODING,
                &Default::default(),
            )
            .unwrap();
        for k in 0..30u64 {
            let with_mag = k % 3 != 0;
            let s = RawSample {
                seq: k,
                t_ns: k * 10_000_000,
                flags: if with_mag { RAW_MAG } else { 0 },
                mag: [k as f64 * 1e-6, -20e-6, 40e-6],
                ..RawSample::default()
            };
            let data = serde_json::to_vec(&RawMessage::from(&s)).unwrap();
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: k as u32,
                log_time: s.t_ns,
                publish_time: s.t_ns,
            };
            w.write_to_known_channel(&header, &data).unwrap();
        }
        w.finish().unwrap();
        drop(w);
        let log = read_mag_log(&path, None, MagUnit::MicroT, None).unwrap();
        assert_eq!(log.readings_ut.len(), 20);
        let first = log.readings_ut[0];
        assert!(
            (first[0] - 1.0).abs() < 1e-9 && (first[1] + 20.0).abs() < 1e-9,
            "{first:?}"
        );
        assert!(log.source.ends_with("topic /nav/raw"), "{}", log.source);
        let other = read_mag_log(&path, None, MagUnit::MicroT, Some("/nav/other"));
        let e = other.unwrap_err().to_string();
        assert!(
            e.contains("--topic /nav/other: no such topic") && e.ends_with("it has /nav/raw"),
            "{e}"
        );

        let csv = dir.path().join("m.csv");
        std::fs::write(&csv, "mx,my,mz\n0.1,0.2,0.3\n").unwrap();
        let e = read_mag_log(&csv, None, MagUnit::Gauss, None).unwrap_err();
        assert!(e.to_string().contains("--mag-columns"), "{e}");
        let cols = ["mx", "my", "mz"].map(String::from);
        let log = read_mag_log(&csv, Some(&cols), MagUnit::Gauss, None).unwrap();
        // 1 gauss is 100 uT.
        assert!((log.readings_ut[0][2] - 30.0).abs() < 1e-9, "{log:?}");
    }

    /// A ROS 2 bag's MagneticField topic: its readings in uT, the topic named in the source; a
    /// reading that is not finite names its message; a bag without one says what to give.
    #[test]
    fn a_bags_magnetometer_is_read_in_ut() {
        use crate::transport::ros2::{Imu, MagneticField, Time, IMU_TYPE, MAG_TYPE};
        let dir = tempfile::tempdir().unwrap();
        let write = |name: &str, ty: &str, messages: Vec<Vec<u8>>| {
            let path = dir.path().join(name);
            let mut w = mcap::WriteOptions::new()
                .profile("ros2")
                .create(std::io::BufWriter::new(
                    std::fs::File::create(&path).unwrap(),
                ))
                .unwrap();
            let schema = w.add_schema(ty, "ros2msg", b"").unwrap();
            let channel = w
                .add_channel(schema, "/imu/mag", "cdr", &Default::default())
                .unwrap();
            for (k, data) in messages.iter().enumerate() {
                let t = 1_000_000_000 + k as u64 * 10_000_000;
                let header = mcap::records::MessageHeader {
                    channel_id: channel,
                    sequence: k as u32,
                    log_time: t,
                    publish_time: t,
                };
                w.write_to_known_channel(&header, data).unwrap();
            }
            w.finish().unwrap();
            path
        };
        let field = |k: i64, x: f64| MagneticField {
            stamp: Time::from_ns(1_000_000_000 + k * 10_000_000).unwrap(),
            magnetic_field: [x, -20e-6, 40e-6],
            ..MagneticField::default()
        };
        let cdr = |m: MagneticField| m.to_cdr().unwrap();
        let good = write(
            "mag.mcap",
            MAG_TYPE,
            (0..5).map(|k| cdr(field(k, k as f64 * 1e-6))).collect(),
        );
        let log = read_mag_log(&good, None, MagUnit::MicroT, None).unwrap();
        assert_eq!(log.readings_ut.len(), 5);
        assert!((log.readings_ut[3][0] - 3.0).abs() < 1e-9, "{log:?}");
        assert!((log.readings_ut[3][2] - 40.0).abs() < 1e-9, "{log:?}");
        assert!(
            log.source.ends_with("topic /imu/mag (tesla)"),
            "{}",
            log.source
        );
        let bad = write(
            "nan.mcap",
            MAG_TYPE,
            vec![cdr(field(0, 1e-6)), cdr(field(1, f64::NAN))],
        );
        let e = read_mag_log(&bad, None, MagUnit::MicroT, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("message 2") && e.contains("is NaN"), "{e}");
        let imu = Imu {
            stamp: Time::from_ns(1_000_000_000).unwrap(),
            ..Imu::default()
        };
        let none = write("imu.mcap", IMU_TYPE, vec![imu.to_cdr().unwrap()]);
        let e = read_mag_log(&none, None, MagUnit::MicroT, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no magnetometer in it"), "{e}");
    }
}
