//! A vehicle's motion in ROS 2 (`nav_msgs/msg/Odometry`, `geometry_msgs/msg/TwistStamped`,
//! `geometry_msgs/msg/TwistWithCovarianceStamped`): which types; their stamp, linear velocity,
//! yaw rate (`angular.z`) and the twist covariance's variances, decoded from CDR by hand, as
//! the Imu message is ([`super::Imu`]), for a bag's motion topic replayed as logged stops
//! (live topics decode them through ros2-client, `dds.rs`); and a message as the
//! [`StopSignal`] `predict.bias` reads ([`Motion::stop_signal`]).

use super::imu::{CdrError, Cursor, Time};
use crate::wire::StopSignal;

/// The ROS 2 message a vehicle's motion comes in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionKind {
    /// `nav_msgs/msg/Odometry` (`twist.twist.linear`).
    Odometry,
    /// `geometry_msgs/msg/TwistStamped` (`twist.linear`).
    TwistStamped,
    /// `geometry_msgs/msg/TwistWithCovarianceStamped` (`twist.twist.linear`).
    TwistWithCovarianceStamped,
}

impl MotionKind {
    /// Every kind, by its ROS 2 type name.
    pub const ALL: [(&'static str, MotionKind); 3] = [
        ("nav_msgs/msg/Odometry", MotionKind::Odometry),
        ("geometry_msgs/msg/TwistStamped", MotionKind::TwistStamped),
        (
            "geometry_msgs/msg/TwistWithCovarianceStamped",
            MotionKind::TwistWithCovarianceStamped,
        ),
    ];

    /// The kind of ROS 2 type `name`, if it is one.
    pub fn of_type(name: &str) -> Option<MotionKind> {
        Self::ALL.iter().find(|(n, _)| *n == name).map(|(_, k)| *k)
    }

    /// Its ROS 2 type name.
    pub fn type_name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(_, k)| *k == self)
            .map_or("", |(n, _)| n)
    }
}

/// One motion message: its stamp, velocities and what its covariance says of them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// `header.stamp`.
    pub stamp: Time,
    /// The linear velocity, m/s.
    pub linear: [f64; 3],
    /// `angular.z`: the yaw rate about the vehicle's up (REP 103: counter-clockwise seen from
    /// above is positive), rad/s.
    pub yaw_rate: f64,
    /// The twist covariance's diagonal: linear x, y, z ((m/s)^2), then angular x, y, z
    /// ((rad/s)^2); NaN each where the message has no covariance (`TwistStamped`).
    pub variance: [f64; 6],
}

/// How far before its receipt a motion message's stamp may lie and still be believed, ns:
/// further, and the stamp is on another clock (a simulation's, a wrong one).
pub const MAX_MOTION_STAMP_AGE_NS: u64 = 1_000_000_000;

impl Motion {
    /// Decode a CDR message of `kind` (encapsulation header included). Never panics: bytes
    /// that are not one are an error naming the field and where.
    pub fn from_cdr(kind: MotionKind, bytes: &[u8]) -> Result<Motion, CdrError> {
        let mut c = Cursor::after_header(bytes)?;
        let stamp = Time {
            sec: c.u32("header.stamp.sec")? as i32,
            nanosec: c.u32("header.stamp.nanosec")?,
        };
        c.skip_string("header.frame_id")?;
        let (twist, variance) = match kind {
            MotionKind::Odometry => {
                c.skip_string("child_frame_id")?;
                // pose.pose (position 3, orientation 4) and pose.covariance (36).
                c.skip_f64s(7 + 36, "pose")?;
                (c.f64s::<6>("twist.twist")?, covariance(&mut c)?)
            }
            MotionKind::TwistStamped => (c.f64s::<6>("twist")?, [f64::NAN; 6]),
            MotionKind::TwistWithCovarianceStamped => {
                (c.f64s::<6>("twist.twist")?, covariance(&mut c)?)
            }
        };
        c.end()?;
        Ok(Motion {
            stamp,
            linear: [twist[0], twist[1], twist[2]],
            yaw_rate: twist[5],
            variance,
        })
    }

    /// Its stop signal, received at `received_ns` (CLOCK_MONOTONIC, the clock of `ingest_ns`):
    /// the speed (the norm of the linear velocity, `stopped` unknown: the pipeline's
    /// `stop_speed` decides), the yaw rate, and their standard deviations where the covariance
    /// gives them (a variance not > 0 says nothing). Its time is the header stamp on the
    /// monotonic clock (`realtime_offset_ns`: the system clock minus the monotonic one), so the
    /// odometry's own latency is not taken for motion; a stamp later than the receipt, or more
    /// than `MAX_MOTION_STAMP_AGE_NS` (1 s) before it, is on another clock, and the receipt stands
    /// in (the `bool` says which).
    pub fn stop_signal(&self, received_ns: u64, realtime_offset_ns: i128) -> (StopSignal, bool) {
        let mapped = i128::from(self.stamp.ns()) - realtime_offset_ns;
        let lo = i128::from(received_ns.saturating_sub(MAX_MOTION_STAMP_AGE_NS));
        let believed = (lo..=i128::from(received_ns)).contains(&mapped);
        let t_ns = if believed { mapped as u64 } else { received_ns };
        let sd = |v: f64| if v > 0.0 { v.sqrt() } else { f64::NAN };
        let [vx, vy, vz, _, _, vyaw] = self.variance;
        let mut s = StopSignal::new(t_ns, self.speed(), u32::MAX);
        s.yaw_rate_rad_s = self.yaw_rate;
        s.speed_std_m_s = sd(vx + vy + vz);
        s.yaw_rate_std_rad_s = sd(vyaw);
        (s, believed)
    }

    /// The speed: the norm of the linear velocity, m/s.
    pub fn speed(&self) -> f64 {
        self.linear.iter().map(|v| v * v).sum::<f64>().sqrt()
    }
}

/// A twist covariance (row-major 6 x 6): its diagonal.
fn covariance(c: &mut Cursor<'_>) -> Result<[f64; 6], CdrError> {
    let m = c.f64s::<36>("twist.covariance")?;
    Ok(std::array::from_fn(|i| m[i * 7]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Little-endian CDR of a motion message, written field by field here (the bag test
    /// checks against rosbags' own encoding).
    fn encode(kind: MotionKind, linear: [f64; 3]) -> Vec<u8> {
        let mut b = vec![0, 1, 0, 0];
        let align = |b: &mut Vec<u8>, n: usize| {
            while (b.len() - 4) % n != 0 {
                b.push(0);
            }
        };
        let string = |b: &mut Vec<u8>, s: &str| {
            b.extend_from_slice(&((s.len() + 1) as u32).to_le_bytes());
            b.extend_from_slice(s.as_bytes());
            b.push(0);
        };
        let doubles = |b: &mut Vec<u8>, v: &[f64]| {
            align(b, 8);
            for x in v {
                b.extend_from_slice(&x.to_le_bytes());
            }
        };
        b.extend_from_slice(&7u32.to_le_bytes());
        b.extend_from_slice(&500u32.to_le_bytes());
        string(&mut b, "odom");
        if kind == MotionKind::Odometry {
            align(&mut b, 4);
            string(&mut b, "base_link");
            doubles(&mut b, &[0.5; 43]);
        }
        doubles(&mut b, &linear);
        doubles(&mut b, &[7.0, 8.0, 9.0]);
        if kind != MotionKind::TwistStamped {
            let cov: Vec<f64> = (0..36).map(|i| 0.1 + i as f64).collect();
            doubles(&mut b, &cov);
        }
        b
    }

    #[test]
    fn each_kind_decodes_its_stamp_velocities_and_variances() {
        for (_, kind) in MotionKind::ALL {
            let m = Motion::from_cdr(kind, &encode(kind, [3.0, 4.0, 0.0])).unwrap();
            assert_eq!(m.stamp.ns(), 7_000_000_500, "{kind:?}");
            assert_eq!(m.linear, [3.0, 4.0, 0.0], "{kind:?}");
            assert_eq!(m.speed(), 5.0);
            assert_eq!(m.yaw_rate, 9.0, "{kind:?}");
            if kind == MotionKind::TwistStamped {
                assert!(m.variance.iter().all(|v| v.is_nan()));
            } else {
                // The diagonal of a covariance whose element i is 0.1 + i.
                let want: [f64; 6] = std::array::from_fn(|i| 0.1 + (i * 7) as f64);
                assert_eq!(m.variance, want, "{kind:?}");
            }
        }
    }

    fn motion(stamp_ns: i64, variance: [f64; 6]) -> Motion {
        Motion {
            stamp: Time::from_ns(stamp_ns).unwrap(),
            linear: [0.6, 0.8, 0.0],
            yaw_rate: -0.25,
            variance,
        }
    }

    #[test]
    fn a_stop_signal_is_timed_by_the_stamp_on_this_clock_else_by_the_receipt() {
        // The system clock is 1000 s ahead of the monotonic one; received at 50 s monotonic.
        let offset = 1_000_000_000_000i128;
        let received = 50_000_000_000u64;
        let at = |stamp: i64| {
            motion(stamp, [0.01, 0.0, 0.0, 0.0, 0.0, 4e-4]).stop_signal(received, offset)
        };
        // 30 ms old: its own time, on the monotonic clock.
        let (s, believed) = at(1_049_970_000_000);
        assert!(believed);
        assert_eq!(s.t_ns, 49_970_000_000);
        assert_eq!(
            (s.speed_m_s, s.stopped, s.yaw_rate_rad_s),
            (1.0, u32::MAX, -0.25)
        );
        assert!(
            (s.speed_std_m_s - 0.1).abs() < 1e-15 && (s.yaw_rate_std_rad_s - 0.02).abs() < 1e-15
        );
        // From the future, or older than a second: another clock, timed at the receipt.
        for stamp in [1_050_000_000_001, 1_048_999_999_999, 7] {
            let (s, believed) = at(stamp);
            assert!(!believed, "{stamp}");
            assert_eq!(s.t_ns, received, "{stamp}");
        }
        // A variance not > 0 (zeros: not filled in) or absent says no sd.
        for v in [[0.0; 6], [f64::NAN; 6], [-1.0; 6]] {
            let (s, _) = motion(1_049_970_000_000, v).stop_signal(received, offset);
            assert!(
                s.speed_std_m_s.is_nan() && s.yaw_rate_std_rad_s.is_nan(),
                "{v:?}"
            );
        }
    }

    #[test]
    fn a_cut_message_names_the_field_and_never_panics() {
        let full = encode(MotionKind::Odometry, [1.0, 0.0, 0.0]);
        for len in 0..full.len() - 3 {
            assert!(
                Motion::from_cdr(MotionKind::Odometry, &full[..len]).is_err(),
                "{len}"
            );
        }
        let e = Motion::from_cdr(MotionKind::Odometry, &full[..100]).unwrap_err();
        assert!(e.to_string().contains("pose"), "{e}");
        let mut long = full.clone();
        long.extend_from_slice(&[0; 8]);
        assert_eq!(
            Motion::from_cdr(MotionKind::Odometry, &long),
            Err(CdrError::Trailing(8))
        );
    }
}
