//! What the ROS 2 side says of the bias filter, as Autoware's `gyro_bias_estimator` does: the
//! bias as `geometry_msgs/msg/Vector3Stamped`, and `diagnostic_msgs/msg/DiagnosticArray` on
//! `/diagnostics` with each axis's bias and its sigma, the stillness, the deadline misses and
//! the losses, at WARN once an axis's bias passes a threshold. Both encoded in CDR by hand (as
//! the Imu message is: [`super::Imu`]); [`BiasWindow`] gathers a period's samples into one
//! [`DiagnosticStatus`]. No I/O here: the bridge (`bridge.rs`) publishes what these make.

use super::imu::{CdrError, Time};
use crate::wire::{
    OdometryStats, FLAG_MOVING, FLAG_STILL, FLAG_WARMING_UP, MOUNTING_WRONG_AXIS,
    MOUNTING_WRONG_SIGN,
};

/// The ROS 2 type of the bias message.
pub const VECTOR3_STAMPED_TYPE: &str = "geometry_msgs/msg/Vector3Stamped";
/// The ROS 2 type of the diagnostics message.
pub const DIAGNOSTIC_ARRAY_TYPE: &str = "diagnostic_msgs/msg/DiagnosticArray";
/// Where ROS 2's diagnostics go (`diagnostic_updater`'s topic, read by `diagnostic_aggregator`
/// and `rqt_robot_monitor`).
pub const DIAGNOSTICS_TOPIC: &str = "/diagnostics";

/// Little-endian CDR after the 4-byte encapsulation header, each field aligned to its size
/// relative to the byte after the header (XCDR1, as ROS 2's rmw writes).
struct CdrOut<'a> {
    out: &'a mut Vec<u8>,
}

impl<'a> CdrOut<'a> {
    /// Clear `out` and write the header `00 01 00 00` (plain CDR, little-endian).
    fn new(out: &'a mut Vec<u8>) -> CdrOut<'a> {
        out.clear();
        out.extend_from_slice(&[0, 1, 0, 0]);
        CdrOut { out }
    }

    fn align(&mut self, n: usize) {
        while (self.out.len() - 4) % n != 0 {
            self.out.push(0);
        }
    }

    fn u8(&mut self, v: u8) {
        self.out.push(v);
    }

    fn u32(&mut self, v: u32) {
        self.align(4);
        self.out.extend_from_slice(&v.to_le_bytes());
    }

    fn f64(&mut self, v: f64) {
        self.align(8);
        self.out.extend_from_slice(&v.to_le_bytes());
    }

    /// A length that a CDR sequence or string can hold.
    fn len(n: usize, field: &str) -> Result<u32, CdrError> {
        u32::try_from(n).map_err(|_| CdrError::TooLong(field.to_string(), n))
    }

    /// A string: its length counting the NUL, its bytes, the NUL.
    fn string(&mut self, s: &str, field: &str) -> Result<(), CdrError> {
        let n = Self::len(s.len() + 1, field)?;
        self.u32(n);
        self.out.extend_from_slice(s.as_bytes());
        self.out.push(0);
        Ok(())
    }

    /// A `std_msgs/msg/Header`.
    fn header(&mut self, stamp: Time, frame_id: &str) -> Result<(), CdrError> {
        self.u32(stamp.sec as u32);
        self.u32(stamp.nanosec);
        self.string(frame_id, "header.frame_id")
    }
}

/// A `geometry_msgs/msg/Vector3Stamped`: the bias removed, rad/s, as Autoware's
/// `gyro_bias_estimator` publishes it on `~/output/gyro_bias`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Vector3Stamped {
    /// `header.stamp`.
    pub stamp: Time,
    /// `header.frame_id`.
    pub frame_id: String,
    /// `vector` x, y, z.
    pub vector: [f64; 3],
}

impl Vector3Stamped {
    /// Encode as little-endian CDR, header included, into `out` (cleared first).
    pub fn write_cdr(&self, out: &mut Vec<u8>) -> Result<(), CdrError> {
        let mut w = CdrOut::new(out);
        w.header(self.stamp, &self.frame_id)?;
        for v in self.vector {
            w.f64(v);
        }
        Ok(())
    }
}

/// A `diagnostic_msgs/msg/DiagnosticStatus` level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
#[repr(u8)]
pub enum Level {
    /// `OK` (0).
    Ok = 0,
    /// `WARN` (1).
    Warn = 1,
    /// `ERROR` (2).
    Error = 2,
    /// `STALE` (3): nothing heard for a while.
    Stale = 3,
}

impl Level {
    /// Its name, as `ros2 topic echo` users know it.
    pub fn name(self) -> &'static str {
        match self {
            Level::Ok => "OK",
            Level::Warn => "WARN",
            Level::Error => "ERROR",
            Level::Stale => "STALE",
        }
    }
}

/// A `diagnostic_msgs/msg/DiagnosticStatus`.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnosticStatus {
    /// `level`.
    pub level: Level,
    /// `name`: `node: task`, as `diagnostic_updater` names it.
    pub name: String,
    /// `message`: one line on the state.
    pub message: String,
    /// `hardware_id`.
    pub hardware_id: String,
    /// `values`: key and value, each a string.
    pub values: Vec<(String, String)>,
}

/// A `diagnostic_msgs/msg/DiagnosticArray`.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnosticArray {
    /// `header.stamp`.
    pub stamp: Time,
    /// `header.frame_id` (`diagnostic_updater` leaves it empty).
    pub frame_id: String,
    /// `status`.
    pub status: Vec<DiagnosticStatus>,
}

impl DiagnosticArray {
    /// Encode as little-endian CDR, header included, into `out` (cleared first).
    pub fn write_cdr(&self, out: &mut Vec<u8>) -> Result<(), CdrError> {
        let mut w = CdrOut::new(out);
        w.header(self.stamp, &self.frame_id)?;
        w.u32(CdrOut::len(self.status.len(), "status")?);
        for s in &self.status {
            w.u8(s.level as u8);
            w.string(&s.name, "status.name")?;
            w.string(&s.message, "status.message")?;
            w.string(&s.hardware_id, "status.hardware_id")?;
            w.u32(CdrOut::len(s.values.len(), "status.values")?);
            for (k, v) in &s.values {
                w.string(k, "status.values.key")?;
                w.string(v, "status.values.value")?;
            }
        }
        Ok(())
    }
}

/// What the pipeline's stats say of misses, losses and the odometry (`StatsSnapshot`'s).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PipelineCounts {
    /// Outputs past the deadline.
    pub deadline_misses: u64,
    /// Samples lost by subscribers of the pipeline's services (full buffers).
    pub lost: u64,
    /// Samples missing from the input (sequence gaps).
    pub missing_in_input: u64,
    /// What the vehicle's odometry did for the bias filter (`up` 0: none used).
    pub odometry: OdometryStats,
}

/// One period's corrected samples, gathered for a [`DiagnosticStatus`] (allocation-free per
/// sample).
#[derive(Debug, Clone, Default)]
pub struct BiasWindow {
    /// The latest sample's bias (rad/s), its sigma (rad/s, negative: not provided) and flags.
    last: Option<([f64; 3], [f64; 3], u32)>,
    samples: u64,
    still: u64,
    moving: u64,
    /// Samples seen since the start, over every period.
    total: u64,
}

/// How a [`BiasWindow`] judges and names its status.
#[derive(Debug, Clone, PartialEq)]
pub struct BiasDiagnosticSettings {
    /// `name` of the status (`<node>: gyro_bias`).
    pub name: String,
    /// `hardware_id` (the node's name, as `gyro_bias_estimator` sets it).
    pub hardware_id: String,
    /// WARN once an axis's bias passes this, rad/s.
    pub threshold: f64,
}

/// A value as the shortest decimal that reads back to the same double (Rust's `Display`, no
/// exponent): `0.0015`, `-0.000012`.
fn number(v: f64) -> String {
    format!("{v}")
}

impl BiasWindow {
    /// Take one corrected sample: its bias (`drift`, rad/s), the bias's sigma (`drift_std`,
    /// rad/s; negative: not provided) and its flags.
    pub fn observe(&mut self, drift: [f64; 3], drift_std: [f64; 3], flags: u32) {
        self.last = Some((drift, drift_std, flags));
        self.samples += 1;
        self.total += 1;
        self.still += u64::from(flags & FLAG_STILL != 0);
        self.moving += u64::from(flags & FLAG_MOVING != 0);
    }

    /// The status of the period since the last call (`period_s` long), then start the next
    /// period: STALE without a sample in it; WARN when an axis's bias passes the threshold;
    /// else OK (while the filter warms up, OK and said so). `counts`: the pipeline's, when its
    /// stats were read.
    pub fn report(
        &mut self,
        settings: &BiasDiagnosticSettings,
        period_s: f64,
        counts: Option<PipelineCounts>,
    ) -> DiagnosticStatus {
        let mut values: Vec<(String, String)> = Vec::with_capacity(16);
        let mut put = |k: &str, v: String| values.push((k.to_string(), v));
        let axes = ["x", "y", "z"];
        let (level, message) = match self.last.filter(|_| self.samples > 0) {
            None if self.total == 0 => (Level::Stale, "no corrected sample yet".to_string()),
            None => (
                Level::Stale,
                format!("no corrected sample in the last {} s", number(period_s)),
            ),
            Some((drift, std, flags)) => {
                for (a, name) in axes.iter().enumerate() {
                    put(&format!("gyro_bias_{name}"), number(drift[a]));
                }
                for (a, name) in axes.iter().enumerate() {
                    let sigma = if std[a] >= 0.0 {
                        number(std[a])
                    } else {
                        "not provided".to_string()
                    };
                    put(&format!("gyro_bias_sigma_{name}"), sigma);
                }
                let over: Vec<&str> = axes
                    .iter()
                    .zip(drift)
                    .filter(|(_, b)| b.abs() > settings.threshold)
                    .map(|(n, _)| *n)
                    .collect();
                if !over.is_empty() {
                    (
                        Level::Warn,
                        format!(
                            "gyro bias past {} rad/s on {}: the raw gyro is that far off \
                             (check its calibration or mounting)",
                            number(settings.threshold),
                            over.join(", ")
                        ),
                    )
                } else if flags & FLAG_WARMING_UP != 0 {
                    (
                        Level::Ok,
                        "warming up: the bias is still being learnt".into(),
                    )
                } else {
                    (Level::Ok, "OK".into())
                }
            }
        };
        let (level, message) = match counts.map(|c| c.odometry).filter(|o| o.up != 0) {
            Some(o) => {
                put("vehicle_up", o.up_name().into());
                put("odometry_mounting", o.mounting_name().into());
                put("odometry_spans_used", o.learnt.to_string());
                put("odometry_spans_rejected", o.spans_rejected.to_string());
                put("odometry_slips_caught", o.slips.to_string());
                put("odometry_scale", number(o.scale));
                put("odometry_scale_sigma", number(o.scale_sd));
                put("gyro_bias_learnt_in_motion", number(o.bias_learnt_rad_s));
                let refused = matches!(o.mounting, MOUNTING_WRONG_SIGN | MOUNTING_WRONG_AXIS);
                if refused && level < Level::Warn {
                    (
                        Level::Warn,
                        format!(
                            "the odometry's yaw rate is refused ({}: vehicle_up {}); the bias \
                             learns at stops only (fix vehicle_up, see the daemon's log)",
                            o.mounting_name(),
                            o.up_name()
                        ),
                    )
                } else {
                    (level, message)
                }
            }
            None => (level, message),
        };
        put("gyro_bias_threshold", number(settings.threshold));
        let stillness = match self.last {
            Some((_, _, f)) if f & FLAG_STILL != 0 => "still",
            Some((_, _, f)) if f & FLAG_MOVING != 0 => "moving",
            _ => "unknown",
        };
        put("stillness", stillness.into());
        put("still_samples", self.still.to_string());
        put("moving_samples", self.moving.to_string());
        put("samples", self.samples.to_string());
        if let Some(c) = counts {
            put("deadline_misses", c.deadline_misses.to_string());
            put("lost", c.lost.to_string());
            put("missing_in_input", c.missing_in_input.to_string());
        }
        self.samples = 0;
        self.still = 0;
        self.moving = 0;
        DiagnosticStatus {
            level,
            name: settings.name.clone(),
            message,
            hardware_id: settings.hardware_id.clone(),
            values,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader of the layouts above, for the round trips: strings and sequences as CDR has
    /// them (the length checked against what is left).
    struct Read<'a> {
        b: &'a [u8],
        pos: usize,
    }

    impl Read<'_> {
        fn align(&mut self, n: usize) {
            self.pos += (n - self.pos % n) % n;
        }
        fn u8(&mut self) -> u8 {
            self.pos += 1;
            self.b[self.pos - 1]
        }
        fn u32(&mut self) -> u32 {
            self.align(4);
            self.pos += 4;
            u32::from_le_bytes(self.b[self.pos - 4..self.pos].try_into().unwrap())
        }
        fn string(&mut self) -> String {
            let n = self.u32() as usize;
            assert!(n >= 1 && n <= self.b.len() - self.pos);
            let s = &self.b[self.pos..self.pos + n];
            self.pos += n;
            assert_eq!(s[n - 1], 0, "NUL");
            String::from_utf8(s[..n - 1].to_vec()).unwrap()
        }
    }

    fn read_array(bytes: &[u8]) -> DiagnosticArray {
        assert_eq!(&bytes[..4], &[0, 1, 0, 0]);
        let mut r = Read {
            b: &bytes[4..],
            pos: 0,
        };
        let stamp = Time {
            sec: r.u32() as i32,
            nanosec: r.u32(),
        };
        let frame_id = r.string();
        let n = r.u32();
        let status = (0..n)
            .map(|_| {
                let level = match r.u8() {
                    0 => Level::Ok,
                    1 => Level::Warn,
                    2 => Level::Error,
                    3 => Level::Stale,
                    l => panic!("level {l}"),
                };
                let (name, message, hardware_id) = (r.string(), r.string(), r.string());
                let values = (0..r.u32()).map(|_| (r.string(), r.string())).collect();
                DiagnosticStatus {
                    level,
                    name,
                    message,
                    hardware_id,
                    values,
                }
            })
            .collect();
        assert_eq!(r.pos, r.b.len(), "nothing after the last field");
        DiagnosticArray {
            stamp,
            frame_id,
            status,
        }
    }

    #[test]
    fn a_vector3_stamped_is_the_hand_computed_bytes() {
        let m = Vector3Stamped {
            stamp: Time { sec: 1, nanosec: 2 },
            frame_id: "ab".into(),
            vector: [0.5, -1.0, 1.0],
        };
        let mut b = Vec::new();
        m.write_cdr(&mut b).unwrap();
        let mut want = vec![
            0x00, 0x01, 0x00, 0x00, // CDR little-endian
            0x01, 0x00, 0x00, 0x00, // sec = 1
            0x02, 0x00, 0x00, 0x00, // nanosec = 2
            0x03, 0x00, 0x00, 0x00, // "ab" and its NUL
            b'a', b'b', 0x00, 0x00, // one byte of padding: x at 16 after the header
        ];
        want.extend_from_slice(&0.5f64.to_le_bytes());
        want.extend_from_slice(&(-1.0f64).to_le_bytes());
        want.extend_from_slice(&1.0f64.to_le_bytes());
        assert_eq!(b, want);
        // "imu_link": 9 bytes with its NUL, 3 of padding, x at 24.
        let m = Vector3Stamped {
            frame_id: "imu_link".into(),
            ..m
        };
        m.write_cdr(&mut b).unwrap();
        assert_eq!(b.len(), 4 + 24 + 24, "cleared first");
        assert_eq!(&b[16..28], b"imu_link\0\0\0\0");
        assert_eq!(&b[28..36], &0.5f64.to_le_bytes());
    }

    #[test]
    fn a_diagnostic_array_is_the_hand_computed_bytes() {
        let a = DiagnosticArray {
            stamp: Time { sec: 7, nanosec: 9 },
            frame_id: String::new(),
            status: vec![DiagnosticStatus {
                level: Level::Warn,
                name: "n".into(),
                message: "mm".into(),
                hardware_id: String::new(),
                values: vec![("k".into(), "vvv".into())],
            }],
        };
        let mut b = Vec::new();
        a.write_cdr(&mut b).unwrap();
        #[rustfmt::skip]
        let want: Vec<u8> = vec![
            0, 1, 0, 0,
            7, 0, 0, 0, 9, 0, 0, 0, // stamp
            1, 0, 0, 0, 0,          // frame_id "": its NUL alone (offsets 8-12)
            0, 0, 0,                // padding to 16
            1, 0, 0, 0,             // one status (16)
            1,                      // level WARN (20)
            0, 0, 0,                // padding to 24
            2, 0, 0, 0, b'n', 0,    // name (24-29)
            0, 0,                   // padding to 32
            3, 0, 0, 0, b'm', b'm', 0, // message (32-38)
            0,                      // padding to 40
            1, 0, 0, 0, 0,          // hardware_id "" (40-44)
            0, 0, 0,                // padding to 48
            1, 0, 0, 0,             // one value (48)
            2, 0, 0, 0, b'k', 0,    // key (52-57)
            0, 0,                   // padding to 60
            4, 0, 0, 0, b'v', b'v', b'v', 0, // value (60-67)
        ];
        assert_eq!(b, want);
        assert_eq!(read_array(&b), a);
    }

    fn settings() -> BiasDiagnosticSettings {
        BiasDiagnosticSettings {
            name: "driftless_ros2: gyro_bias".into(),
            hardware_id: "driftless_ros2".into(),
            threshold: 0.0015,
        }
    }

    fn value<'a>(s: &'a DiagnosticStatus, key: &str) -> &'a str {
        s.values
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
            .unwrap_or_else(|| panic!("no {key} in {:?}", s.values))
    }

    #[test]
    fn the_status_goes_to_warn_past_the_threshold_and_stale_without_samples() {
        let mut w = BiasWindow::default();
        let s = w.report(&settings(), 1.0, None);
        assert_eq!(
            (s.level, s.message.as_str()),
            (Level::Stale, "no corrected sample yet")
        );
        // Below the threshold, still, with the pipeline's counts.
        for i in 0..10 {
            let flags = if i < 4 { FLAG_MOVING } else { FLAG_STILL };
            w.observe([0.001, -0.0014, 0.0], [1e-4, 2e-4, 3e-4], flags);
        }
        let counts = PipelineCounts {
            deadline_misses: 2,
            lost: 3,
            missing_in_input: 4,
            ..PipelineCounts::default()
        };
        let s = w.report(&settings(), 1.0, Some(counts));
        assert_eq!((s.level, s.message.as_str()), (Level::Ok, "OK"));
        assert_eq!(s.name, "driftless_ros2: gyro_bias");
        assert_eq!(s.hardware_id, "driftless_ros2");
        for (k, v) in [
            ("gyro_bias_x", "0.001"),
            ("gyro_bias_y", "-0.0014"),
            ("gyro_bias_z", "0"),
            ("gyro_bias_sigma_x", "0.0001"),
            ("gyro_bias_sigma_z", "0.0003"),
            ("gyro_bias_threshold", "0.0015"),
            ("stillness", "still"),
            ("still_samples", "6"),
            ("moving_samples", "4"),
            ("samples", "10"),
            ("deadline_misses", "2"),
            ("lost", "3"),
            ("missing_in_input", "4"),
        ] {
            assert_eq!(value(&s, k), v, "{k}");
        }
        // Every value reads back to the double it came from.
        let x: f64 = value(&s, "gyro_bias_y").parse().unwrap();
        assert_eq!(x.to_bits(), (-0.0014f64).to_bits());
        // Past it on z (either sign): WARN, naming the axis.
        w.observe([0.001, 0.0, -0.0016], [-1.0; 3], FLAG_MOVING);
        let s = w.report(&settings(), 1.0, None);
        assert_eq!(s.level, Level::Warn);
        assert!(
            s.message.contains("past 0.0015 rad/s on z"),
            "{}",
            s.message
        );
        assert_eq!(value(&s, "gyro_bias_sigma_x"), "not provided");
        assert_eq!(value(&s, "stillness"), "moving");
        assert_eq!(value(&s, "samples"), "1", "a period's own");
        assert!(s.values.iter().all(|(k, _)| k != "lost"), "no stats read");
        // A silent period after samples: STALE, saying how long.
        let s = w.report(&settings(), 0.5, None);
        assert_eq!(s.level, Level::Stale);
        assert_eq!(s.message, "no corrected sample in the last 0.5 s");
        // Warming up, under the threshold: OK, and said.
        w.observe([0.0; 3], [0.01; 3], FLAG_WARMING_UP);
        let s = w.report(&settings(), 1.0, None);
        assert_eq!(s.level, Level::Ok);
        assert!(s.message.starts_with("warming up"), "{}", s.message);
        assert_eq!(value(&s, "stillness"), "unknown");
        assert!(
            s.values.iter().all(|(k, _)| !k.contains("odometry")),
            "no odometry: none said"
        );
    }

    #[test]
    fn the_odometry_is_said_and_a_refused_mounting_warns() {
        let mut w = BiasWindow::default();
        let mut counts = PipelineCounts {
            odometry: OdometryStats {
                up: 6,
                mounting: crate::wire::MOUNTING_CONFIRMED,
                spans_accepted: 41,
                spans_rejected: 5,
                slips: 2,
                learnt: 40,
                scale: -0.0125,
                scale_sd: 0.002,
                bias_learnt_rad_s: 0.0087,
            },
            ..PipelineCounts::default()
        };
        w.observe([0.0, 0.0, 0.001], [1e-4; 3], FLAG_MOVING);
        let s = w.report(&settings(), 1.0, Some(counts));
        assert_eq!((s.level, s.message.as_str()), (Level::Ok, "OK"));
        for (k, v) in [
            ("vehicle_up", "-z"),
            ("odometry_mounting", "confirmed"),
            ("odometry_spans_used", "40"),
            ("odometry_spans_rejected", "5"),
            ("odometry_slips_caught", "2"),
            ("odometry_scale", "-0.0125"),
            ("odometry_scale_sigma", "0.002"),
            ("gyro_bias_learnt_in_motion", "0.0087"),
        ] {
            assert_eq!(value(&s, k), v, "{k}");
        }
        counts.odometry.mounting = MOUNTING_WRONG_SIGN;
        w.observe([0.0; 3], [1e-4; 3], FLAG_MOVING);
        let s = w.report(&settings(), 1.0, Some(counts));
        assert_eq!(s.level, Level::Warn);
        assert!(s.message.contains("refused: wrong sign"), "{}", s.message);
        assert!(s.message.contains("vehicle_up -z"), "{}", s.message);
    }

    #[test]
    fn a_report_encodes_and_reads_back_whole() {
        let mut w = BiasWindow::default();
        w.observe([1e-5, -2.5e-3, 3.0], [1e-6; 3], FLAG_STILL);
        let status = w.report(&settings(), 1.0, Some(PipelineCounts::default()));
        let a = DiagnosticArray {
            stamp: Time {
                sec: 1_700_000_000,
                nanosec: 999_999_999,
            },
            frame_id: String::new(),
            status: vec![status.clone(), status],
        };
        let mut b = Vec::new();
        a.write_cdr(&mut b).unwrap();
        assert_eq!(read_array(&b), a);
    }
}
