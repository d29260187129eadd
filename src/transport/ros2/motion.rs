//! A vehicle's motion in ROS 2 (`nav_msgs/msg/Odometry`, `geometry_msgs/msg/TwistStamped`,
//! `geometry_msgs/msg/TwistWithCovarianceStamped`): which types, and their stamp and linear
//! velocity decoded from CDR by hand, as the Imu message is ([`super::Imu`]), for a bag's motion
//! topic replayed as logged stops. Live topics decode them through ros2-client (`dds.rs`).

use super::imu::{CdrError, Cursor, Time};

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

/// One motion message: its stamp and linear velocity (m/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// `header.stamp`.
    pub stamp: Time,
    /// The linear velocity, m/s.
    pub linear: [f64; 3],
}

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
        let linear = match kind {
            MotionKind::Odometry => {
                c.skip_string("child_frame_id")?;
                // pose.pose (position 3, orientation 4) and pose.covariance (36).
                c.skip_f64s(7 + 36, "pose")?;
                read_vec3(&mut c, "twist.twist.linear")?
            }
            MotionKind::TwistStamped => read_vec3(&mut c, "twist.linear")?,
            MotionKind::TwistWithCovarianceStamped => read_vec3(&mut c, "twist.twist.linear")?,
        };
        // The rest: angular (3), and the twist's covariance (36) where there is one.
        let rest = match kind {
            MotionKind::TwistStamped => 3,
            _ => 3 + 36,
        };
        c.skip_f64s(rest, "twist's angular velocity and covariance")?;
        c.end()?;
        Ok(Motion { stamp, linear })
    }

    /// The speed: the norm of the linear velocity, m/s.
    pub fn speed(&self) -> f64 {
        self.linear.iter().map(|v| v * v).sum::<f64>().sqrt()
    }
}

fn read_vec3(c: &mut Cursor<'_>, field: &str) -> Result<[f64; 3], CdrError> {
    Ok([
        c.f64(&format!("{field}.x"))?,
        c.f64(&format!("{field}.y"))?,
        c.f64(&format!("{field}.z"))?,
    ])
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
        doubles(&mut b, &[9.0; 3]);
        if kind != MotionKind::TwistStamped {
            doubles(&mut b, &[0.1; 36]);
        }
        b
    }

    #[test]
    fn each_kind_decodes_its_stamp_and_linear_velocity() {
        for (_, kind) in MotionKind::ALL {
            let m = Motion::from_cdr(kind, &encode(kind, [3.0, 4.0, 0.0])).unwrap();
            assert_eq!(m.stamp.ns(), 7_000_000_500, "{kind:?}");
            assert_eq!(m.linear, [3.0, 4.0, 0.0], "{kind:?}");
            assert_eq!(m.speed(), 5.0);
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
