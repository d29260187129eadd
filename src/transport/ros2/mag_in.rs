//! The live magnetometer input of the ROS 2 side (`mag_in`, cargo feature `ros2`): a driver's
//! `sensor_msgs/msg/MagneticField` topic taken as it arrives into a [`MagJoin`], and the field
//! each Imu sample of `imu_in` carries ([`super::mag`]'s rule). The bridge's Imu input asks it
//! per sample; it never holds back or changes a sample.

use super::counts::MagCounts;
use super::dds::{MagSubscription, Ros2Node};
use super::mag::{MagJoin, MagJoinRule};
use crate::transport::TransportError;

/// The magnetometer's subscription and its join.
pub struct MagIn {
    topic: String,
    /// Registered on the side's readiness.
    pub sub: MagSubscription,
    join: MagJoin,
    /// Whether the last sample carried a reading (a change is said).
    joined_last: bool,
    /// Times a stream that joined stopped joining, said up to [`SAID_STOPS`] times.
    stops: u64,
    /// What it carried.
    pub counts: MagCounts,
}

/// How many times a magnetometer that stops joining is said on stderr.
const SAID_STOPS: u64 = 3;

impl MagIn {
    /// Subscribe `topic` (best effort, keep last `depth`), joined by `rule`.
    pub fn open(
        topic: &str,
        rule: MagJoinRule,
        depth: usize,
        node: &mut Ros2Node,
    ) -> Result<MagIn, TransportError> {
        Ok(MagIn {
            topic: topic.to_string(),
            sub: node.mag_subscription(topic, depth)?,
            join: MagJoin::new(rule),
            joined_last: false,
            stops: 0,
            counts: MagCounts::default(),
        })
    }

    /// Take every reading that arrived into the join. Returns the first error of a message
    /// that could not be read, and how many could not.
    pub fn pump(&mut self) -> (u64, Option<String>) {
        let (mut unreadable, mut first) = (0, None);
        loop {
            match self.sub.take() {
                Ok(Some(m)) => {
                    self.counts.taken += 1;
                    if !self.join.push(&m) {
                        self.counts.refused += 1;
                    }
                }
                Ok(None) => break,
                Err(e) => {
                    unreadable += 1;
                    first.get_or_insert(e);
                }
            }
        }
        (unreadable, first)
    }

    /// The field an Imu sample stamped `t_ns` carries, and a line to say when the stream
    /// stops joining (the first [`SAID_STOPS`] times) or joins again after that.
    pub fn field_at(&mut self, t_ns: i64) -> (Option<[f64; 3]>, Option<String>) {
        if t_ns <= 0 {
            // A sample without a stamp (flagged a stamp fault) joins nothing, and says nothing
            // of the magnetometer stream.
            self.counts.missing += 1;
            return (None, None);
        }
        let field = self.join.at(t_ns);
        let mut line = None;
        match (field.is_some(), self.joined_last) {
            (true, false) => {
                self.counts.joined += 1;
                if self.stops > 0 && self.stops <= SAID_STOPS {
                    line = Some(format!(
                        "{}: readings join the Imu samples again",
                        self.topic
                    ));
                }
            }
            (true, true) => self.counts.joined += 1,
            (false, was) => {
                self.counts.missing += 1;
                if was {
                    self.stops += 1;
                    if self.stops <= SAID_STOPS {
                        line = Some(format!(
                            "{}: no reading fresh enough for the Imu sample stamped {:.3} s (the \
                             stream stopped or lags past mag_max_age_s): samples go on without \
                             the magnetometer, the heading on the gyro",
                            self.topic,
                            t_ns as f64 * 1e-9
                        ));
                    }
                }
            }
        }
        self.joined_last = field.is_some();
        (field, line)
    }
}
