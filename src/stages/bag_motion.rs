//! `ingest.mcap`'s vehicle motion from a bag (`stop_topic`): its messages read whole and
//! sorted by stamp, each sample's stop flags from them, and with `motion_output` the messages
//! themselves handed to the runtime as stop signals on the samples' clock
//! ([`crate::stages::Source::logged_motion`]).

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, OnceLock};

use crate::clock::PaceClock;
use crate::io::{BagError, BagErrorKind};
use crate::stages::contract::{Poll, Source};
use crate::stages::replay::BlockReplay;
use crate::stages::stop_rule::StopRule;
use crate::transport::ros2::bag::Bag;
use crate::wire::{StopSignal, RAW_VEHICLE_MOVING, RAW_VEHICLE_STOPPED, STOP_CLOCK_SAMPLES};

/// Undecodable messages of a bag named one by one on stderr; the rest are counted.
pub(crate) const REPORTED_BAD_MESSAGES: u64 = 10;

/// A bag's motion topic read as the vehicle's stops (`stop_topic`).
#[derive(Debug, Clone, PartialEq)]
pub struct StopTopic {
    /// The topic.
    pub topic: String,
    /// How its messages are judged.
    pub rule: StopRule,
}

/// One message of a bag's motion topic, as kept for the replay (32 bytes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Logged {
    /// `header.stamp`, ns.
    stamp: i64,
    /// The norm of the linear velocity, m/s.
    speed: f64,
    /// `angular.z`, rad/s.
    yaw_rate: f64,
    /// Its variance from the twist covariance, (rad/s)^2 (NaN: none).
    yaw_var: f64,
}

impl Logged {
    /// As a stop signal on the samples' clock (the stop judged by the samples' flags).
    fn signal(&self) -> StopSignal {
        let mut s = StopSignal::new(self.stamp as u64, self.speed, u32::MAX);
        s.clock = STOP_CLOCK_SAMPLES;
        s.yaw_rate_rad_s = self.yaw_rate;
        s.yaw_rate_std_rad_s = if self.yaw_var > 0.0 {
            self.yaw_var.sqrt()
        } else {
            f64::NAN
        };
        s
    }
}

/// A bag's motion topic, read whole and sorted by stamp.
pub(crate) struct Stops {
    at: Vec<Logged>,
    rule: StopRule,
}

impl Stops {
    /// Read `s.topic` of `bag`; a message that does not decode is left out (counted on stderr).
    pub(crate) fn read(bag: &Bag, s: &StopTopic) -> Result<Stops, BagError> {
        let mut at = Vec::new();
        let mut bad = 0u64;
        for m in bag.motion_messages(&s.topic)? {
            match m {
                Ok(m) => at.push(Logged {
                    stamp: m.msg.stamp.ns(),
                    speed: m.msg.speed(),
                    yaw_rate: m.msg.yaw_rate,
                    yaw_var: m.msg.variance[5],
                }),
                Err(e) if e.kind == BagErrorKind::Cdr => {
                    bad += 1;
                    if bad <= REPORTED_BAD_MESSAGES {
                        eprintln!("driftless: warning: {e} (left out of the stops)");
                    }
                }
                Err(e) => return Err(e),
            }
        }
        if bad > REPORTED_BAD_MESSAGES {
            eprintln!(
                "driftless: warning: topic {}: {bad} messages that do not decode left out of the stops",
                s.topic
            );
        }
        at.sort_by_key(|m| m.stamp);
        Ok(Stops { at, rule: s.rule })
    }

    /// The raw flags of a sample stamped `t`: from the last motion message at or before it, if
    /// that is at most `max_age_ns` old. `at` (0 at the start of a pass) moves forward with
    /// the stamps; a stamp that goes back is searched for.
    pub(crate) fn flags_at(&self, at: &mut usize, t: i64) -> u32 {
        if *at > 0 && self.at.get(*at - 1).is_some_and(|m| m.stamp > t) {
            *at = self.at.partition_point(|m| m.stamp <= t);
        }
        while self.at.get(*at).is_some_and(|m| m.stamp <= t) {
            *at += 1;
        }
        let said = (*at)
            .checked_sub(1)
            .map(|i| self.at[i])
            .and_then(|m| self.rule.judge(t.abs_diff(m.stamp), m.speed, None));
        match said {
            Some(true) => RAW_VEHICLE_STOPPED,
            Some(false) => RAW_VEHICLE_MOVING,
            None => 0,
        }
    }
}

/// The replay, and with `motion_output` the bag's motion as stop signals on the samples'
/// clock, each handed over with the first sample stamped at or after it (first pass only).
pub(crate) struct McapSource {
    pub(crate) replay: BlockReplay,
    /// The motion, set by the reader thread before its first sample.
    pub(crate) motion: Option<Arc<OnceLock<Arc<Stops>>>>,
    /// The next motion message to hand over.
    pub(crate) at: usize,
    /// The time of the sample `poll` returned last.
    pub(crate) t_ns: Option<u64>,
}

impl Source for McapSource {
    fn poll(&mut self, stop: &AtomicBool) -> Poll {
        let p = self.replay.poll(stop);
        if let Poll::Sample(s, ..) = &p {
            self.t_ns = Some(s.t_ns);
        }
        p
    }

    fn next_due(&self) -> Option<std::time::Instant> {
        self.replay.next_due()
    }

    fn share_clock(&mut self, clock: PaceClock) {
        self.replay.share_clock(clock);
    }

    fn logged_motion(&mut self) -> Option<StopSignal> {
        let t = self.t_ns?;
        let stops = self.motion.as_ref()?.get()?;
        let m = stops
            .at
            .get(self.at)
            .filter(|m| i64::try_from(t).map_or(true, |t| m.stamp <= t))?;
        self.at += 1;
        Some(m.signal())
    }
}
