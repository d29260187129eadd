//! The `sensor_msgs/msg/Imu` message: its fields, its CDR encoding and decoding (by hand: see
//! [`crate::transport::ros2`] for why), its `ros2msg` definition as rosbag2 records it, and how our
//! samples become one ([`ImuMapping`], for bags and live topics alike).

use crate::wire::{
    GyroSample, RawSample, FLAG_INPUT_INVALID, FLAG_OUTPUT_REPAIRED, RAW_INVALID,
    SENSOR_HEADING_ABSOLUTE,
};

/// The ROS 2 type name of the IMU message (also the MCAP schema name).
pub const IMU_TYPE: &str = "sensor_msgs/msg/Imu";

/// The complete `ros2msg` definition of sensor_msgs/msg/Imu as `ros2 bag record` writes it
/// (rosbag2_cpp's LocalMessageDefinitionSource): the installed `.msg` file verbatim, then each
/// dependency, depth first in sorted order, after a blank line, 80 `=` and `MSG: pkg/Type`.
/// The files are those of Iron and later (ros2/common_interfaces and ros2/rcl_interfaces,
/// rolling, jazzy and iron alike); Humble's Time.msg says `[0, 10e9)` in its last comment.
pub const IMU_DEFINITION: &str = concat!(
    r#"# This is a message to hold data from an IMU (Inertial Measurement Unit)
#
# Accelerations should be in m/s^2 (not in g's), and rotational velocity should be in rad/sec
#
# If the covariance of the measurement is known, it should be filled in (if all you know is the
# variance of each measurement, e.g. from the datasheet, just put those along the diagonal)
# A covariance matrix of all zeros will be interpreted as "covariance unknown", and to use the
# data a covariance will have to be assumed or gotten from some other source
#
# If you have no estimate for one of the data elements (e.g. your IMU doesn't produce an
# orientation estimate), please set element 0 of the associated covariance matrix to -1
# If you are interpreting this message, please check for a value of -1 in the first element of each
# covariance matrix, and disregard the associated estimate.

std_msgs/Header header

geometry_msgs/Quaternion orientation
float64[9] orientation_covariance # Row major about x, y, z axes

geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance # Row major about x, y, z axes

geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance # Row major x, y z
"#,
    "\n================================================================================\n",
    "MSG: geometry_msgs/Quaternion\n",
    r#"# This represents an orientation in free space in quaternion form.

float64 x 0
float64 y 0
float64 z 0
float64 w 1
"#,
    "\n================================================================================\n",
    "MSG: geometry_msgs/Vector3\n",
    r#"# This represents a vector in free space.

# This is semantically different than a point.
# A vector is always anchored at the origin.
# When a transform is applied to a vector, only the rotational component is applied.

float64 x
float64 y
float64 z
"#,
    "\n================================================================================\n",
    "MSG: std_msgs/Header\n",
    r#"# Standard metadata for higher-level stamped data types.
# This is generally used to communicate timestamped data
# in a particular coordinate frame.

# Two-integer timestamp that is expressed as seconds and nanoseconds.
builtin_interfaces/Time stamp

# Transform frame with which this data is associated.
string frame_id
"#,
    "\n================================================================================\n",
    "MSG: builtin_interfaces/Time\n",
    r#"# This message communicates ROS Time defined here:
# https://design.ros2.org/articles/clock_and_time.html

# The seconds component, valid over all int32 values.
int32 sec

# The nanoseconds component, valid in the range [0, 1e9).
uint32 nanosec
"#
);

/// A ROS 2 time (`builtin_interfaces/msg/Time`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Time {
    /// Seconds since the epoch.
    pub sec: i32,
    /// Nanoseconds, in [0, 1e9) in a valid time.
    pub nanosec: u32,
}

impl Time {
    /// The time in ns since the epoch: exact for every (sec, nanosec), a stamp before 1970
    /// negative; compare consecutive stamps with it to find time going backwards.
    pub fn ns(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }

    /// [`Time::ns`] as an MCAP timestamp: None before 1970.
    pub fn ns_u64(self) -> Option<u64> {
        u64::try_from(self.ns()).ok()
    }

    /// The time as exact decimal seconds, `-0.500000000` for half a second before 1970
    /// ([`seconds_text`] of [`Time::ns`]).
    pub fn seconds_text(self) -> String {
        seconds_text(self.ns())
    }

    /// The time `ns` since the epoch; None when its seconds do not fit an i32 (after 2038).
    pub fn from_ns(ns: i64) -> Option<Time> {
        Some(Time {
            sec: i32::try_from(ns.div_euclid(1_000_000_000)).ok()?,
            // In [0, 1e9): fits.
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        })
    }
}

/// `ns` nanoseconds as exact decimal seconds with nine decimals, the sign in front
/// (`-0.500000000`, `1700000000.123456789`).
pub fn seconds_text(ns: i64) -> String {
    let sign = if ns < 0 { "-" } else { "" };
    let a = ns.unsigned_abs();
    format!("{sign}{}.{:09}", a / 1_000_000_000, a % 1_000_000_000)
}

/// A `sensor_msgs/msg/Imu` message. Units as the definition says (REP 103): rad/s, m/s^2;
/// covariances row major about x, y, z; element 0 of a covariance -1 when the estimate is not
/// provided, all zeros when its covariance is unknown.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Imu {
    /// `header.stamp`: when the sample was taken.
    pub stamp: Time,
    /// `header.frame_id`: the frame the data is in (e.g. `imu_link`).
    pub frame_id: String,
    /// Orientation as a quaternion x, y, z, w.
    pub orientation: [f64; 4],
    /// Covariance of the orientation (rad^2).
    pub orientation_covariance: [f64; 9],
    /// Angular velocity x, y, z, rad/s.
    pub angular_velocity: [f64; 3],
    /// Covariance of the angular velocity (rad^2/s^2).
    pub angular_velocity_covariance: [f64; 9],
    /// Linear acceleration x, y, z, m/s^2.
    pub linear_acceleration: [f64; 3],
    /// Covariance of the linear acceleration (m^2/s^4).
    pub linear_acceleration_covariance: [f64; 9],
}

/// Why bytes are not a CDR Imu message (or an Imu cannot be written as one).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// Fewer bytes than the encapsulation header.
    #[error("{0} bytes, shorter than the 4-byte CDR encapsulation header")]
    NoHeader(usize),
    /// An encapsulation other than plain CDR.
    #[error(
        "encapsulation {a:02x} {b:02x} is not plain CDR (00 01 little-endian or 00 00 \
         big-endian){}",
        if *a == 0 && *b >= 6 { "; XCDR2 is not read" } else { "" }
    )]
    Encapsulation {
        /// The header's first byte.
        a: u8,
        /// Its second byte.
        b: u8,
    },
    /// The message ends inside a field.
    #[error("ends inside {field}: {need} bytes needed at byte {at}, the message has {len}")]
    Truncated {
        /// The field cut short.
        field: String,
        /// Where it starts, from the message's first byte.
        at: usize,
        /// Its size (with alignment padding).
        need: usize,
        /// The message's size.
        len: usize,
    },
    /// The string does not end with its NUL.
    #[error("header.frame_id does not end with a NUL byte")]
    NoNul,
    /// The string is not UTF-8.
    #[error("header.frame_id is not UTF-8")]
    NotUtf8,
    /// More than padding after the last field.
    #[error("{0} bytes after the message's last field (at most 3 bytes of padding may follow)")]
    Trailing(usize),
    /// A frame_id too long for a CDR string (writing).
    #[error("header.frame_id of {0} bytes is too long for CDR")]
    FrameIdTooLong(usize),
    /// A string or sequence too long for CDR's 32-bit length (writing): the field, its length.
    #[error("{0} of {1} elements is too long for CDR")]
    TooLong(String, usize),
}

/// The 37 doubles after the header, in order.
const DOUBLES: usize = 4 + 9 + 3 + 9 + 3 + 9;

/// The name of double `i` of [`DOUBLES`], for errors.
fn double_name(i: usize) -> String {
    const GROUPS: [(&str, usize); 6] = [
        ("orientation", 4),
        ("orientation_covariance", 9),
        ("angular_velocity", 3),
        ("angular_velocity_covariance", 9),
        ("linear_acceleration", 3),
        ("linear_acceleration_covariance", 9),
    ];
    let mut i = i;
    for (name, n) in GROUPS {
        if i < n {
            return match n {
                3 | 4 => format!("{name}.{}", ["x", "y", "z", "w"][i]),
                _ => format!("{name}[{i}]"),
            };
        }
        i -= n;
    }
    "the end".into()
}

/// A cursor over the bytes after the encapsulation header (alignment is relative to them).
pub(super) struct Cursor<'a> {
    pub(super) buf: &'a [u8],
    pub(super) pos: usize,
    pub(super) big: bool,
}

impl<'a> Cursor<'a> {
    /// A cursor after the 4-byte encapsulation header of `bytes` (plain CDR, either order).
    pub(super) fn after_header(bytes: &'a [u8]) -> Result<Self, CdrError> {
        if bytes.len() < 4 {
            return Err(CdrError::NoHeader(bytes.len()));
        }
        let big = match (bytes[0], bytes[1]) {
            (0, 1) => false,
            (0, 0) => true,
            (a, b) => return Err(CdrError::Encapsulation { a, b }),
        };
        Ok(Cursor {
            buf: &bytes[4..],
            pos: 0,
            big,
        })
    }

    /// A double, aligned to 8.
    pub(super) fn f64(&mut self, field: &str) -> Result<f64, CdrError> {
        let pad = (8 - self.pos % 8) % 8;
        let s = self.take(pad + 8, || field.to_string())?;
        let mut w = [0u8; 8];
        w.copy_from_slice(&s[pad..]);
        Ok(if self.big {
            f64::from_be_bytes(w)
        } else {
            f64::from_le_bytes(w)
        })
    }

    /// `N` doubles in a row (a fixed array), named `field` as one.
    pub(super) fn f64s<const N: usize>(&mut self, field: &str) -> Result<[f64; N], CdrError> {
        let pad = (8 - self.pos % 8) % 8;
        let big = self.big;
        let s = self.take(pad + 8 * N, || field.to_string())?;
        Ok(std::array::from_fn(|i| {
            let mut w = [0u8; 8];
            w.copy_from_slice(&s[pad + 8 * i..pad + 8 * i + 8]);
            if big {
                f64::from_be_bytes(w)
            } else {
                f64::from_le_bytes(w)
            }
        }))
    }

    /// Step over a string (its length checked against the bytes left, never allocated).
    pub(super) fn skip_string(&mut self, field: &'static str) -> Result<(), CdrError> {
        let len = self.u32(field)? as usize;
        self.take(len, || field.to_string())?;
        Ok(())
    }

    /// `header.frame_id` into `out` (cleared first): its length checked against the bytes left
    /// before anything is taken; a length of 0 (no NUL, not valid CDR, but some writers send it
    /// for "") reads as "".
    pub(super) fn frame_id_into(&mut self, out: &mut String) -> Result<(), CdrError> {
        let len = self.u32("header.frame_id's length")? as usize;
        let text = self.take(len, || "header.frame_id".to_string())?;
        out.clear();
        if let Some((&last, text)) = text.split_last() {
            if last != 0 {
                return Err(CdrError::NoNul);
            }
            out.push_str(std::str::from_utf8(text).map_err(|_| CdrError::NotUtf8)?);
        }
        Ok(())
    }

    /// Step over `n` doubles.
    pub(super) fn skip_f64s(&mut self, n: usize, field: &str) -> Result<(), CdrError> {
        let pad = (8 - self.pos % 8) % 8;
        self.take(pad + 8 * n, || field.to_string())?;
        Ok(())
    }

    /// Fail on more than 3 bytes after the last field.
    pub(super) fn end(&self) -> Result<(), CdrError> {
        let trailing = self.buf.len() - self.pos;
        if trailing > 3 {
            return Err(CdrError::Trailing(trailing));
        }
        Ok(())
    }

    fn take(&mut self, n: usize, field: impl FnOnce() -> String) -> Result<&'a [u8], CdrError> {
        match self.pos.checked_add(n) {
            Some(end) if end <= self.buf.len() => {
                let s = &self.buf[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            _ => Err(CdrError::Truncated {
                field: field(),
                at: self.pos + 4,
                need: n,
                len: self.buf.len() + 4,
            }),
        }
    }

    fn word(&mut self, field: &'static str) -> Result<[u8; 4], CdrError> {
        let pad = (4 - self.pos % 4) % 4;
        let s = self.take(pad + 4, || field.to_string())?;
        let mut w = [0u8; 4];
        w.copy_from_slice(&s[pad..]);
        Ok(w)
    }

    pub(super) fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        let w = self.word(field)?;
        Ok(if self.big {
            u32::from_be_bytes(w)
        } else {
            u32::from_le_bytes(w)
        })
    }
}

impl Imu {
    /// The accelerometer reading (m/s², REP 103), unless the message marks it not provided
    /// (REP 145: `linear_acceleration_covariance[0]` is -1).
    pub fn accel_reading(&self) -> Option<[f64; 3]> {
        (self.linear_acceleration_covariance[0] != -1.0).then_some(self.linear_acceleration)
    }

    /// Decode a CDR message (encapsulation header included). Never panics: any bytes that are
    /// not an Imu message are an error naming what is wrong and where.
    pub fn from_cdr(bytes: &[u8]) -> Result<Imu, CdrError> {
        let mut imu = Imu::default();
        imu.read_cdr(bytes)?;
        Ok(imu)
    }

    /// Decode into `self`, reusing its frame_id's buffer (what a reader of many messages
    /// calls). On an error `self` holds a partly decoded message.
    pub fn read_cdr(&mut self, bytes: &[u8]) -> Result<(), CdrError> {
        let mut c = Cursor::after_header(bytes)?;
        let big = c.big;
        self.stamp.sec = c.u32("header.stamp.sec")? as i32;
        self.stamp.nanosec = c.u32("header.stamp.nanosec")?;
        // The length is checked against the bytes left before anything is taken: a huge one is
        // an error, never an allocation.
        let len = c.u32("header.frame_id's length")? as usize;
        let text = c.take(len, || "header.frame_id".to_string())?;
        self.frame_id.clear();
        // A length of 0 (no NUL) is not valid CDR, but some writers send it for "".
        if let Some((&last, text)) = text.split_last() {
            if last != 0 {
                return Err(CdrError::NoNul);
            }
            self.frame_id
                .push_str(std::str::from_utf8(text).map_err(|_| CdrError::NotUtf8)?);
        }
        let pad = (8 - c.pos % 8) % 8;
        let first = c.pos + pad;
        let have = c.buf.len().saturating_sub(first) / 8;
        if have < DOUBLES {
            // Name the first double missing, where it starts (with the padding before the
            // first one when that is cut too).
            let (at, need) = if c.buf.len() < first {
                (c.pos, pad + 8)
            } else {
                (first + 8 * have, 8)
            };
            return Err(CdrError::Truncated {
                field: double_name(have),
                at: 4 + at,
                need,
                len: bytes.len(),
            });
        }
        let body = c.take(pad + 8 * DOUBLES, || double_name(0))?;
        let mut values = body[pad..].chunks_exact(8).map(|b| {
            let mut w = [0u8; 8];
            w.copy_from_slice(b);
            if big {
                f64::from_be_bytes(w)
            } else {
                f64::from_le_bytes(w)
            }
        });
        for dst in [
            &mut self.orientation[..],
            &mut self.orientation_covariance[..],
            &mut self.angular_velocity[..],
            &mut self.angular_velocity_covariance[..],
            &mut self.linear_acceleration[..],
            &mut self.linear_acceleration_covariance[..],
        ] {
            for (d, v) in dst.iter_mut().zip(&mut values) {
                *d = v;
            }
        }
        c.end()
    }

    /// Encode as little-endian CDR, header included, into `out` (cleared first), as ROS 2 on
    /// a little-endian machine sends it.
    pub fn write_cdr(&self, out: &mut Vec<u8>) -> Result<(), CdrError> {
        self.write_cdr_in(out, false)
    }

    /// [`Imu::write_cdr`] into a new vector.
    pub fn to_cdr(&self) -> Result<Vec<u8>, CdrError> {
        let mut out = Vec::with_capacity(4 + 12 + self.frame_id.len() + 8 + 8 * DOUBLES);
        self.write_cdr(&mut out)?;
        Ok(out)
    }

    /// Encode in either byte order (big-endian: encapsulation `00 00`).
    fn write_cdr_in(&self, out: &mut Vec<u8>, big: bool) -> Result<(), CdrError> {
        let len = u32::try_from(self.frame_id.len() + 1)
            .map_err(|_| CdrError::FrameIdTooLong(self.frame_id.len()))?;
        let u32b = |v: u32| {
            if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        out.clear();
        out.extend_from_slice(&[0, u8::from(!big), 0, 0]);
        out.extend_from_slice(&u32b(self.stamp.sec as u32));
        out.extend_from_slice(&u32b(self.stamp.nanosec));
        out.extend_from_slice(&u32b(len));
        out.extend_from_slice(self.frame_id.as_bytes());
        out.push(0);
        while (out.len() - 4) % 8 != 0 {
            out.push(0);
        }
        for group in [
            &self.orientation[..],
            &self.orientation_covariance[..],
            &self.angular_velocity[..],
            &self.angular_velocity_covariance[..],
            &self.linear_acceleration[..],
            &self.linear_acceleration_covariance[..],
        ] {
            for v in group {
                out.extend_from_slice(&if big {
                    v.to_be_bytes()
                } else {
                    v.to_le_bytes()
                });
            }
        }
        Ok(())
    }
}

/// Element 0 of a covariance at -1: the estimate is not provided (sensor_msgs/msg/Imu).
pub const NOT_PROVIDED: [f64; 9] = [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];

/// A sample's accelerometer reading, as the Imu message carries it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelReading {
    /// Specific force x, y, z, m/s^2 (REP 103), as the sensor gave it.
    pub value: [f64; 3],
    /// The white noise of one sample per axis, m/s^2 (1 sigma); negative where not provided.
    pub std: [f64; 3],
}

/// The variance of an angle known to be nothing better than any heading, rad^2: an error of up
/// to pi (sd pi). A relative yaw goes out with it, so that a consumer fusing the yaw as
/// absolute (robot_localization, a 9D pipeline) takes next to nothing from it.
const ANY_HEADING_VARIANCE: f64 = std::f64::consts::PI * std::f64::consts::PI;

/// The `orientation_covariance` of an orientation with 1-sigma `std` about the earth's x, y and
/// z (rad, negative: not known) whose heading is `absolute` or relative: see [`ImuMapping`].
fn orientation_covariance(std: [f64; 3], absolute: bool) -> [f64; 9] {
    let var = |sd: f64| {
        if sd >= 0.0 {
            sd * sd
        } else {
            ANY_HEADING_VARIANCE
        }
    };
    let [roll, pitch, yaw] = std;
    let yaw = if absolute {
        var(yaw)
    } else {
        ANY_HEADING_VARIANCE
    };
    diagonal([var(roll), var(pitch), yaw])
}

/// A row-major 3x3 covariance with `v` on its diagonal.
fn diagonal(v: [f64; 3]) -> [f64; 9] {
    let mut cov = [0.0; 9];
    for (a, x) in v.into_iter().enumerate() {
        cov[4 * a] = x;
    }
    cov
}

/// How our samples become `sensor_msgs/msg/Imu` messages: one mapping for the bags `record`
/// writes and the topics the daemon publishes.
/// - `angular_velocity`: the rate in rad/s; the stamp: the sample's time `t_ns`.
/// - `angular_velocity_covariance`: diagonal, the white rate noise's variance per sample plus
///   the drift estimate's variance where a stage gave one (`GyroSample::drift_std`); all zeros
///   ("unknown") without a rate noise.
/// - `linear_acceleration`: the accelerometer's reading as the sample carries it, bit for bit
///   (m/s^2); "not provided" (covariance element 0 = -1) when the sample has none or its
///   reading was not valid (never a held value passed off as a measurement).
/// - `linear_acceleration_covariance` ([`ImuMapping::accel_covariance`]): diagonal, the
///   accelerometer's white noise per sample squared, from the sample's own `accel_std`; where
///   the sample gives none, the `accel_noise` setting's; else the input message's own
///   covariance as received (the driver's, on a live topic); else all zeros ("unknown", said by
///   `validate` and `record`: robot_localization raises a variance under 1e-9 to 1e-9 and
///   trusts such a reading far too much, where a -1 would make it drop the reading unsaid).
/// - `orientation`: the sample's (an `attitude.6d` stage's; x, y, z, w, body to ENU, REP
///   103), with `orientation_covariance` diagonal (REP 145; roll, pitch, yaw variances, rad^2):
///   roll and pitch from `orientation_std` (from gravity); the yaw's from it where the heading
///   is absolute (`SENSOR_HEADING_ABSOLUTE`: the magnetometer's filter). A relative yaw (0
///   where the stage started; REP 145 lets it be arbitrary without a magnetometer) goes out
///   with pi^2, any heading, as does one whose sd the stage did not know: its drift since the
///   start is no absolute heading, and the yaw rate carries what it knows. "Not provided"
///   (covariance element 0 = -1, as sensor_msgs/Imu says) for a sample without one.
pub struct ImuMapping {
    /// The message, filled field by field per sample (its frame_id set once).
    pub imu: Imu,
    /// Factor from the samples' units to rad/s (a raw service in deg/s: pi/180).
    to_rad: f64,
    /// The white rate noise's variance per sample, rad^2/s^2 (None: covariance unknown).
    noise_var: Option<f64>,
    /// The accelerometer's white noise variance per sample, m^2/s^4, for samples that carry
    /// no `accel_std` (None: not set).
    accel_noise_var: Option<f64>,
    /// The input message's own linear_acceleration_covariance, when it gave one.
    accel_cov_in: Option<[f64; 9]>,
    /// Samples mapped whose value a stage held or replaced (flagged input_invalid or
    /// output_repaired; a raw sample marked invalid): an Imu message cannot say it.
    pub held: u64,
    /// Accelerometer readings mapped with an unknown covariance (all zeros: neither the
    /// sample, the `accel_noise` setting nor the input gave one).
    pub accel_unknown: u64,
    /// Factor from raw samples' accelerometer units to m/s^2 (None: not known).
    raw_to_m_s2: Option<f64>,
    /// Raw samples whose accelerometer reading went out "not provided" because its units were
    /// not known.
    pub accel_units_unknown: u64,
}

impl ImuMapping {
    /// Messages in `frame_id` from samples whose rates times `to_rad` are rad/s, with a white
    /// rate noise of `rate_noise_deg` deg/s per sample (1 sigma) when known.
    pub fn new(frame_id: &str, to_rad: f64, rate_noise_deg: Option<f64>) -> ImuMapping {
        ImuMapping {
            imu: Imu {
                frame_id: frame_id.to_string(),
                orientation_covariance: NOT_PROVIDED,
                linear_acceleration_covariance: NOT_PROVIDED,
                ..Imu::default()
            },
            to_rad,
            noise_var: rate_noise_deg.map(|n| n.to_radians().powi(2)),
            accel_noise_var: None,
            accel_cov_in: None,
            held: 0,
            accel_unknown: 0,
            raw_to_m_s2: None,
            accel_units_unknown: 0,
        }
    }

    /// The accelerometer's white noise per sample, m/s^2 (1 sigma), for samples that carry
    /// none (`accel_noise`).
    pub fn with_accel_noise(mut self, accel_noise: Option<f64>) -> ImuMapping {
        self.accel_noise_var = accel_noise.map(|n| n * n);
        self
    }

    /// The input message's own linear_acceleration_covariance (a driver's, as received): used
    /// where neither the sample nor `accel_noise` gives one. One not provided (-1) or not
    /// finite is none.
    pub fn set_input_accel_covariance(&mut self, cov: &[f64; 9]) {
        self.accel_cov_in = (cov[0] != -1.0 && cov.iter().all(|c| c.is_finite())).then_some(*cov);
    }

    /// Put the next messages in `frame_id` (a no-op when they are in it already).
    pub fn set_frame_id(&mut self, frame_id: &str) {
        if self.imu.frame_id != frame_id {
            self.imu.frame_id.clear();
            self.imu.frame_id.push_str(frame_id);
        }
    }

    /// Raw samples' accelerometer readings times `to_m_s2` are m/s^2 (their pipeline's
    /// `accel_units`). Without it, a raw sample's reading goes out "not provided", counted in
    /// [`ImuMapping::accel_units_unknown`]: a reading in unknown units is no reading.
    pub fn with_raw_accel_units(mut self, to_m_s2: Option<f64>) -> ImuMapping {
        self.raw_to_m_s2 = to_m_s2;
        self
    }

    /// A raw sample's message.
    pub fn raw(&mut self, s: &RawSample) -> Result<&Imu, String> {
        let held = s.flags & RAW_INVALID != 0 || !s.rate.iter().all(|v| v.is_finite());
        let reading = s
            .accel_reading()
            .filter(|a| a.iter().all(|v| v.is_finite()));
        self.accel_units_unknown += u64::from(reading.is_some() && self.raw_to_m_s2.is_none());
        let accel = reading.zip(self.raw_to_m_s2).map(|(a, k)| AccelReading {
            value: a.map(|v| v * k),
            std: [-1.0; 3],
        });
        self.fill(s.t_ns, s.rate, [-1.0; 3], accel, held)
    }

    /// A gyro sample's message: its accelerometer reading where it has a valid one (a held
    /// one goes out "not provided").
    pub fn gyro(&mut self, s: &GyroSample) -> Result<&Imu, String> {
        let held = s.flags & (FLAG_INPUT_INVALID | FLAG_OUTPUT_REPAIRED) != 0;
        let accel = s.accel_reading().map(|value| AccelReading {
            value,
            std: s.accel_std,
        });
        let absolute = s.sensors & SENSOR_HEADING_ABSOLUTE != 0;
        (self.imu.orientation, self.imu.orientation_covariance) = match s.orientation_estimate() {
            Some(q) => (q, orientation_covariance(s.orientation_std, absolute)),
            None => ([0.0, 0.0, 0.0, 1.0], NOT_PROVIDED),
        };
        self.fill(s.t_ns, s.rate, s.drift_std, accel, held)
    }

    /// The covariance of a reading whose white noise per axis is `std` (m/s^2, negative
    /// where not provided): see [`ImuMapping`].
    pub fn accel_covariance(&self, std: [f64; 3]) -> [f64; 9] {
        self.accel_covariance_known(std).unwrap_or([0.0; 9])
    }

    /// [`ImuMapping::accel_covariance`], None where it is unknown.
    fn accel_covariance_known(&self, std: [f64; 3]) -> Option<[f64; 9]> {
        if std.iter().all(|s| s.is_finite() && *s >= 0.0) {
            Some(diagonal(std.map(|s| s * s)))
        } else if let Some(var) = self.accel_noise_var {
            Some(diagonal([var; 3]))
        } else {
            self.accel_cov_in
        }
    }

    /// The message of a sample at `t_ns` with `rate` (in the samples' units), where a stage
    /// estimated it the drift's 1-sigma per axis (rad/s; negative: not provided), and its
    /// accelerometer reading if it has a valid one; `held` when its rate is not a measurement.
    pub fn fill(
        &mut self,
        t_ns: u64,
        rate: [f64; 3],
        drift_std: [f64; 3],
        accel: Option<AccelReading>,
        held: bool,
    ) -> Result<&Imu, String> {
        let stamp = i64::try_from(t_ns)
            .ok()
            .and_then(Time::from_ns)
            .ok_or_else(|| {
                format!("sample time {t_ns} ns is past 2038: no ROS 2 stamp holds it")
            })?;
        self.imu.stamp = stamp;
        self.imu.angular_velocity = rate.map(|v| v * self.to_rad);
        let mut cov = [0.0; 9];
        if let Some(var) = self.noise_var {
            for a in 0..3 {
                cov[4 * a] = var + drift_std[a].max(0.0).powi(2);
            }
        }
        self.imu.angular_velocity_covariance = cov;
        (
            self.imu.linear_acceleration,
            self.imu.linear_acceleration_covariance,
        ) = match accel {
            Some(a) => {
                let cov = self.accel_covariance_known(a.std);
                self.accel_unknown += u64::from(cov.is_none());
                (a.value, cov.unwrap_or([0.0; 9]))
            }
            None => ([0.0; 3], NOT_PROVIDED),
        };
        self.held += u64::from(held);
        Ok(&self.imu)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::WireBytes;
    use proptest::prelude::*;

    #[test]
    fn seconds_text_is_exact_and_signed() {
        assert_eq!(
            seconds_text(1_700_000_000_123_456_789),
            "1700000000.123456789"
        );
        assert_eq!(seconds_text(0), "0.000000000");
        assert_eq!(seconds_text(-500_000_000), "-0.500000000");
        assert_eq!(seconds_text(-1_250_000_000), "-1.250000000");
        let t = Time::from_ns(-500_000_000).unwrap();
        assert_eq!((t.sec, t.nanosec), (-1, 500_000_000));
        assert_eq!(t.seconds_text(), "-0.500000000");
    }

    const Z: [u8; 8] = [0; 8];
    const ONE: [u8; 8] = [0, 0, 0, 0, 0, 0, 0xf0, 0x3f];
    const MINUS_ONE: [u8; 8] = [0, 0, 0, 0, 0, 0, 0xf0, 0xbf];
    const HALF: [u8; 8] = [0, 0, 0, 0, 0, 0, 0xe0, 0x3f];

    fn small() -> Imu {
        Imu {
            stamp: Time { sec: 1, nanosec: 2 },
            frame_id: "ab".into(),
            orientation: [0.0, 0.0, 0.0, 1.0],
            orientation_covariance: [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            angular_velocity: [0.5, -1.0, 1.0],
            angular_velocity_covariance: [0.0; 9],
            linear_acceleration: [1.0, 0.5, 0.0],
            linear_acceleration_covariance: [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        }
    }

    /// The bytes of `small()`, computed by hand from the CDR rules.
    fn small_bytes() -> Vec<u8> {
        let mut b = vec![
            0x00, 0x01, 0x00, 0x00, // encapsulation: CDR little-endian, options 0
            0x01, 0x00, 0x00, 0x00, // header.stamp.sec = 1 (offset 0 after the header)
            0x02, 0x00, 0x00, 0x00, // header.stamp.nanosec = 2 (offset 4)
            0x03, 0x00, 0x00, 0x00, // frame_id length 3: "ab" and its NUL (offset 8)
            b'a', b'b', 0x00, // offsets 12-14
            0x00, // padding: the first double goes at offset 16, a multiple of 8
        ];
        let doubles: [[u8; 8]; 37] = [
            Z, Z, Z, ONE, // orientation x, y, z, w
            MINUS_ONE, Z, Z, Z, Z, Z, Z, Z, Z, // orientation_covariance
            HALF, MINUS_ONE, ONE, // angular_velocity
            Z, Z, Z, Z, Z, Z, Z, Z, Z, // angular_velocity_covariance
            ONE, HALF, Z, // linear_acceleration
            MINUS_ONE, Z, Z, Z, Z, Z, Z, Z, Z, // linear_acceleration_covariance
        ];
        for d in doubles {
            b.extend_from_slice(&d);
        }
        b
    }

    #[test]
    fn the_cdr_layout_is_the_hand_computed_one() {
        let bytes = small_bytes();
        assert_eq!(bytes.len(), 4 + 16 + 296);
        assert_eq!(small().to_cdr().unwrap(), bytes);
        assert_eq!(Imu::from_cdr(&bytes).unwrap(), small());
        // frame_id "imu_link": 4 + 4 + 4 + 9 bytes, 3 of padding, the first double at 24.
        let imu = Imu {
            frame_id: "imu_link".into(),
            ..small()
        };
        let b = imu.to_cdr().unwrap();
        assert_eq!(&b[12..16], &[9, 0, 0, 0]);
        assert_eq!(&b[16..25], b"imu_link\0");
        assert_eq!(&b[25..28], &[0, 0, 0]);
        assert_eq!(&b[28 + 3 * 8..28 + 4 * 8], &ONE, "orientation.w");
        assert_eq!(b.len(), 4 + 24 + 296);
        // An empty frame_id is its NUL alone.
        let b = Imu::default().to_cdr().unwrap();
        assert_eq!(&b[12..16], &[1, 0, 0, 0]);
        assert_eq!(b.len(), 4 + 16 + 296);
    }

    #[test]
    fn big_endian_reads_the_same_message() {
        let mut be = Vec::new();
        small().write_cdr_in(&mut be, true).unwrap();
        assert_eq!(
            &be[..8],
            &[0, 0, 0, 0, 0, 0, 0, 1],
            "00 00 then sec = 1 big-endian"
        );
        assert_eq!(&be[12..16], &[0, 0, 0, 3]);
        assert_eq!(&be[20 + 3 * 8..20 + 4 * 8], &[0x3f, 0xf0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(Imu::from_cdr(&be).unwrap(), small());
    }

    #[test]
    fn bad_messages_say_what_is_wrong() {
        let good = small_bytes();
        let e = |b: &[u8]| Imu::from_cdr(b).unwrap_err().to_string();
        assert_eq!(
            e(&good[..3]),
            "3 bytes, shorter than the 4-byte CDR encapsulation header"
        );
        let mut x = good.clone();
        x[1] = 0x07;
        assert!(e(&x).contains("00 07 is not plain CDR") && e(&x).contains("XCDR2"));
        assert_eq!(
            e(&good[..10]),
            "ends inside header.stamp.nanosec: 4 bytes needed at byte 8, the message has 10"
        );
        let mut huge = good.clone();
        huge[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert_eq!(
            e(&huge),
            "ends inside header.frame_id: 4294967295 bytes needed at byte 16, the message has 316"
        );
        assert_eq!(
            e(&good[..good.len() - 1]),
            "ends inside linear_acceleration_covariance[8]: 8 bytes needed at byte 308, the \
             message has 315"
        );
        assert!(e(&good[..25]).contains("ends inside orientation.x"));
        assert!(e(&good[..20 + 8 * 14]).contains("ends inside angular_velocity.y"));
        let mut no_nul = good.clone();
        no_nul[18] = b'c';
        assert_eq!(e(&no_nul), "header.frame_id does not end with a NUL byte");
        let mut latin1 = good.clone();
        latin1[16] = 0xe9;
        assert_eq!(e(&latin1), "header.frame_id is not UTF-8");
        let mut padded = good.clone();
        padded.extend_from_slice(&[0, 0, 0]);
        assert_eq!(Imu::from_cdr(&padded).unwrap(), small());
        padded.push(0);
        assert_eq!(
            e(&padded),
            "4 bytes after the message's last field (at most 3 bytes of padding may follow)"
        );
    }

    #[test]
    fn stamps_in_ns() {
        let t = Time {
            sec: 1_700_000_000,
            nanosec: 123_456_789,
        };
        assert_eq!(t.ns(), 1_700_000_000_123_456_789);
        assert_eq!(Time::from_ns(t.ns()), Some(t));
        let before = Time {
            sec: -1,
            nanosec: 999_999_999,
        };
        assert_eq!(before.ns(), -1);
        assert_eq!(before.ns_u64(), None);
        assert_eq!(Time::from_ns(-1), Some(before));
        assert_eq!(
            Time::from_ns(i64::from(i32::MAX) * 1_000_000_000 + 1_000_000_000),
            None
        );
        let extreme = Time {
            sec: i32::MIN,
            nanosec: u32::MAX,
        };
        assert_eq!(
            extreme.ns(),
            i64::from(i32::MIN) * 1_000_000_000 + 4_294_967_295
        );
        assert!(
            t < Time {
                sec: t.sec,
                nanosec: t.nanosec + 1
            }
        );
    }

    #[test]
    fn the_definition_is_rosbag2s_layout() {
        let parts: Vec<&str> = IMU_DEFINITION
            .split(&format!("\n{}\n", "=".repeat(80)))
            .collect();
        assert_eq!(parts.len(), 5);
        assert!(parts[0].starts_with("# This is a message to hold data from an IMU"));
        assert!(
            parts[0].ends_with("float64[9] linear_acceleration_covariance # Row major x, y z\n")
        );
        let headers: Vec<&str> = parts[1..]
            .iter()
            .map(|p| p.lines().next().unwrap())
            .collect();
        assert_eq!(
            headers,
            [
                "MSG: geometry_msgs/Quaternion",
                "MSG: geometry_msgs/Vector3",
                "MSG: std_msgs/Header",
                "MSG: builtin_interfaces/Time"
            ]
        );
        assert!(IMU_DEFINITION.ends_with("uint32 nanosec\n"));
        assert!(!IMU_DEFINITION.lines().any(|l| l.ends_with(' ')));
    }

    #[test]
    fn the_accelerometer_goes_out_bit_for_bit_with_the_covariance_its_noise_gives() {
        let mut m = ImuMapping::new("imu_link", 1.0, Some(0.1));
        // Gyro-only: not provided, zeros.
        let imu = m.fill(5, [0.1; 3], [-1.0; 3], None, false).unwrap();
        assert_eq!(imu.linear_acceleration, [0.0; 3]);
        assert_eq!(imu.linear_acceleration_covariance, NOT_PROVIDED);
        assert!(imu.accel_reading().is_none());
        // Values as they came, -0.0 and a subnormal included.
        let value = [-0.0, 5e-324, 9.80665];
        let reading = AccelReading {
            value,
            std: [0.01, 0.02, 0.03],
        };
        let imu = m
            .fill(5, [0.1; 3], [-1.0; 3], Some(reading), false)
            .unwrap();
        assert_eq!(
            imu.linear_acceleration.map(f64::to_bits),
            value.map(f64::to_bits)
        );
        let diag = |c: &[f64; 9]| [c[0], c[4], c[8]];
        assert_eq!(
            diag(&imu.linear_acceleration_covariance),
            [0.01 * 0.01, 0.02 * 0.02, 0.03 * 0.03]
        );
        assert!(imu.accel_reading().is_some());
        let off: Vec<f64> = (0..9)
            .filter(|k| k % 4 != 0)
            .map(|k| imu.linear_acceleration_covariance[k])
            .collect();
        assert_eq!(off, [0.0; 6]);
        // No accel_std: the setting's noise, else the input's own covariance, else unknown.
        let none = AccelReading {
            value,
            std: [-1.0; 3],
        };
        let mut driver = [0.0; 9];
        driver[0] = 1e-4;
        driver[1] = 2e-5;
        driver[4] = 1e-4;
        driver[8] = 3e-4;
        m.set_input_accel_covariance(&driver);
        assert_eq!(m.accel_covariance([-1.0; 3]), driver, "the driver's own");
        assert_eq!(
            m.accel_covariance([0.01, -1.0, 0.01]),
            driver,
            "all three or none"
        );
        let mut m = m.with_accel_noise(Some(0.5));
        m.set_input_accel_covariance(&driver);
        let imu = m.fill(5, [0.1; 3], [-1.0; 3], Some(none), false).unwrap();
        assert_eq!(
            diag(&imu.linear_acceleration_covariance),
            [0.25; 3],
            "the setting first"
        );
        let mut m = ImuMapping::new("imu_link", 1.0, None);
        m.set_input_accel_covariance(&NOT_PROVIDED);
        assert_eq!(m.accel_covariance([-1.0; 3]), [0.0; 9], "unknown");
        m.set_input_accel_covariance(&[f64::NAN; 9]);
        assert_eq!(
            m.accel_covariance([-1.0; 3]),
            [0.0; 9],
            "a NaN covariance is none"
        );
        let imu = m.fill(5, [0.1; 3], [-1.0; 3], Some(none), false).unwrap();
        assert_eq!(imu.linear_acceleration_covariance, [0.0; 9]);
        assert_eq!(m.accel_unknown, 1, "counted, so that record can say it");
        // The sample's own noise wins over both.
        assert_eq!(diag(&m.accel_covariance([0.0, 0.5, 2.0])), [0.0, 0.25, 4.0]);
    }

    /// REP 145's orientation_covariance: the diagonal of roll, pitch and yaw variances; the
    /// yaw's only for an absolute heading, any heading (pi^2) for a relative or unknown one;
    /// "not provided" (-1) without an orientation.
    #[test]
    fn the_orientation_goes_out_with_its_covariance_and_only_when_given() {
        use crate::wire::{GyroSample, SENSOR_MAG_REJECTED, SENSOR_ORIENTATION};
        let mut m = ImuMapping::new("imu_link", 1.0, Some(0.1));
        let q = [0.1, -0.2, 0.3, (1.0f64 - 0.14).sqrt()];
        let with = GyroSample {
            orientation: q,
            orientation_std: [1e-3, 2e-3, 0.05],
            sensors: SENSOR_ORIENTATION | SENSOR_HEADING_ABSOLUTE,
            ..GyroSample::default()
        };
        let imu = m.gyro(&with).unwrap();
        assert_eq!(imu.orientation.map(f64::to_bits), q.map(f64::to_bits));
        let c = imu.orientation_covariance;
        assert_eq!(
            [c[0], c[4], c[8]],
            [1e-3f64 * 1e-3, 2e-3 * 2e-3, 0.05 * 0.05]
        );
        assert_eq!([c[1], c[2], c[3], c[5], c[6], c[7]], [0.0; 6]);
        // A rejected field changes nothing here: the sd already grew with it.
        let rejected = GyroSample {
            sensors: with.sensors | SENSOR_MAG_REJECTED,
            ..with
        };
        assert_eq!(m.gyro(&rejected).unwrap().orientation_covariance, c);
        // A relative heading (6D, or 9D before the field was trusted): any heading, whatever
        // its drift since the start; roll and pitch as they are.
        let relative = GyroSample {
            sensors: SENSOR_ORIENTATION,
            ..with
        };
        let c = m.gyro(&relative).unwrap().orientation_covariance;
        let pi2 = std::f64::consts::PI.powi(2);
        assert_eq!([c[0], c[4], c[8]], [1e-3f64 * 1e-3, 2e-3 * 2e-3, pi2]);
        // The heading's sd not known: any heading.
        let unknown_yaw = GyroSample {
            orientation_std: [1e-3, 1e-3, -1.0],
            ..with
        };
        let c = m.gyro(&unknown_yaw).unwrap().orientation_covariance;
        assert_eq!(c[8], pi2);
        // The next sample has none: not provided, not the last one's.
        let imu = m.gyro(&GyroSample::default()).unwrap();
        assert_eq!(imu.orientation_covariance, NOT_PROVIDED);
        assert_eq!(imu.orientation, [0.0, 0.0, 0.0, 1.0]);
    }

    /// The Imu message's fields that a sample fills, by name, as bits.
    fn imu_fields(imu: &Imu) -> [(&'static str, Vec<u64>); 7] {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect();
        [
            ("header.stamp", vec![imu.stamp.ns() as u64]),
            ("orientation", bits(&imu.orientation)),
            ("orientation_covariance", bits(&imu.orientation_covariance)),
            ("angular_velocity", bits(&imu.angular_velocity)),
            (
                "angular_velocity_covariance",
                bits(&imu.angular_velocity_covariance),
            ),
            ("linear_acceleration", bits(&imu.linear_acceleration)),
            (
                "linear_acceleration_covariance",
                bits(&imu.linear_acceleration_covariance),
            ),
        ]
    }

    /// The names of the Imu fields that differ between `a` and `b`.
    fn moved(a: &Imu, b: &Imu) -> Vec<&'static str> {
        let (a, b) = (imu_fields(a), imu_fields(b));
        a.iter()
            .zip(&b)
            .filter(|(x, y)| x.1 != y.1)
            .map(|(x, _)| x.0)
            .collect()
    }

    /// Each field of a sample goes to the Imu field its table names (`ros2`), and to no other:
    /// changing it changes that Imu field alone; a field the table maps to none changes none.
    /// A field present by a bit goes out only with its bit.
    fn the_mapping_is_the_table<T: WireBytes>(
        table: &crate::wire::FieldTable,
        sample: &T,
        map: impl Fn(&mut ImuMapping, &T) -> Imu,
    ) {
        let mapping =
            || ImuMapping::new("imu_link", 1.0, Some(0.1)).with_raw_accel_units(Some(1.0));
        let mut bytes = Vec::new();
        sample.encode(&mut bytes);
        let base = map(&mut mapping(), sample);
        let imu_of = |b: &[u8]| map(&mut mapping(), &T::decode(b).unwrap());
        for f in table.fields {
            let want: Vec<&str> = f.ros2.into_iter().collect();
            let got = moved(&base, &imu_of(&f.changed_in(&bytes)));
            assert_eq!(got, want, "{}.{}", table.name, f.name);
            if let (Some(_), Some(imu_field)) = (f.presence, f.ros2) {
                let absent = table.without(f, &bytes);
                let got = moved(&base, &imu_of(&absent));
                assert!(
                    got.contains(&imu_field),
                    "{}.{}: {got:?}",
                    table.name,
                    f.name
                );
            }
        }
    }

    #[test]
    fn each_field_goes_to_the_imu_field_the_table_names() {
        use crate::wire::{
            GYRO_FIELDS, RAW_ACCEL, RAW_FIELDS, RAW_MAG, SENSOR_ACCEL, SENSOR_MAG,
            SENSOR_ORIENTATION,
        };
        // Every reading present (not 0), every standard deviation known and used (the heading
        // absolute, so its sd goes out too); the rest as it may be.
        let gyro = GyroSample {
            t_ns: 1_000_000_000,
            accel: [0.1, 0.2, 9.8],
            drift_std: [0.001, 0.002, 0.003],
            accel_std: [0.01, 0.02, 0.03],
            sensors: SENSOR_ACCEL | SENSOR_MAG | SENSOR_ORIENTATION | SENSOR_HEADING_ABSOLUTE,
            orientation: [0.0, 0.0, 0.6, 0.8],
            orientation_std: [0.01, 0.02, 0.03],
            ..GyroSample::default()
        };
        the_mapping_is_the_table(&GYRO_FIELDS, &gyro, |m, s| m.gyro(s).unwrap().clone());
        // The sensors word reaches the message through one bit: whether the heading is
        // absolute moves the orientation's covariance (its yaw), and nothing else.
        let mut m = ImuMapping::new("imu_link", 1.0, Some(0.1));
        let absolute = m.gyro(&gyro).unwrap().clone();
        let relative = GyroSample {
            sensors: gyro.sensors & !SENSOR_HEADING_ABSOLUTE,
            ..gyro
        };
        let relative = m.gyro(&relative).unwrap().clone();
        assert_eq!(moved(&absolute, &relative), ["orientation_covariance"]);
        let raw = RawSample {
            t_ns: 2_000_000_000,
            flags: RAW_ACCEL | RAW_MAG,
            accel: [0.3, 0.2, 9.7],
            ..RawSample::default()
        };
        the_mapping_is_the_table(&RAW_FIELDS, &raw, |m, s| m.raw(s).unwrap().clone());
    }

    fn bits(imu: &Imu) -> Vec<u64> {
        imu.orientation
            .iter()
            .chain(&imu.orientation_covariance)
            .chain(&imu.angular_velocity)
            .chain(&imu.angular_velocity_covariance)
            .chain(&imu.linear_acceleration)
            .chain(&imu.linear_acceleration_covariance)
            .map(|v| v.to_bits())
            .collect()
    }

    fn any_imu() -> impl Strategy<Value = Imu> {
        (
            any::<i32>(),
            any::<u32>(),
            "\\PC{0,20}",
            proptest::collection::vec(any::<u64>(), 37),
        )
            .prop_map(|(sec, nanosec, frame_id, v)| {
                let f = |i: usize| f64::from_bits(v[i]);
                Imu {
                    stamp: Time { sec, nanosec },
                    frame_id,
                    orientation: std::array::from_fn(f),
                    orientation_covariance: std::array::from_fn(|i| f(4 + i)),
                    angular_velocity: std::array::from_fn(|i| f(13 + i)),
                    angular_velocity_covariance: std::array::from_fn(|i| f(16 + i)),
                    linear_acceleration: std::array::from_fn(|i| f(25 + i)),
                    linear_acceleration_covariance: std::array::from_fn(|i| f(28 + i)),
                }
            })
    }

    proptest! {
        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
            let _ = Imu::from_cdr(&bytes);
            // With a valid header too, so the fields' decoding is reached.
            let mut b = vec![0, 1, 0, 0];
            b.extend_from_slice(&bytes);
            let _ = Imu::from_cdr(&b);
            b[1] = 0;
            let _ = Imu::from_cdr(&b);
        }

        #[test]
        fn any_reading_goes_through_the_mapping_and_cdr_bit_for_bit(
            v in proptest::collection::vec(any::<u64>(), 3),
            std in proptest::collection::vec(0.0f64..10.0, 3),
        ) {
            let value = [f64::from_bits(v[0]), f64::from_bits(v[1]), f64::from_bits(v[2])];
            let mut m = ImuMapping::new("imu_link", 1.0, None);
            let reading = AccelReading { value, std: [std[0], std[1], std[2]] };
            let bytes = m.fill(1, [0.0; 3], [-1.0; 3], Some(reading), false).unwrap().to_cdr().unwrap();
            let back = Imu::from_cdr(&bytes).unwrap();
            prop_assert_eq!(back.linear_acceleration.map(f64::to_bits), value.map(f64::to_bits));
            let c = back.linear_acceleration_covariance;
            prop_assert_eq!([c[0], c[4], c[8]], [std[0] * std[0], std[1] * std[1], std[2] * std[2]]);
        }

        #[test]
        fn every_message_reads_back_bit_for_bit_and_every_truncation_fails(
            imu in any_imu(),
            big in any::<bool>(),
            cut in any::<prop::sample::Index>(),
            len in any::<u32>(),
        ) {
            let mut b = Vec::new();
            imu.write_cdr_in(&mut b, big).unwrap();
            let back = Imu::from_cdr(&b).unwrap();
            prop_assert_eq!((back.stamp, &back.frame_id), (imu.stamp, &imu.frame_id));
            prop_assert_eq!(bits(&back), bits(&imu));
            let n = cut.index(b.len());
            prop_assert!(Imu::from_cdr(&b[..n]).is_err(), "{} of {} bytes decoded", n, b.len());
            // Any string length: an error or (the true one) the message, never a panic.
            let mut bad = b.clone();
            bad[12..16].copy_from_slice(&if big { len.to_be_bytes() } else { len.to_le_bytes() });
            let _ = Imu::from_cdr(&bad);
        }
    }
}
