//! The vehicle's stop rule: whether a stop signal says the vehicle stands, moves, or nothing.
//! One definition, keys and judgment, for every stage that reads the vehicle's motion:
//! `ingest.mcap`'s `stop_topic` (a bag's motion messages, judged by sample time) and
//! `predict.bias`'s `stop_input` (a live [`crate::wire::StopSignal`], judged by its age
//! at ingest).

use crate::io::InputError;
use crate::stages::schema::{DefaultValue, Key, Table, Type};

/// A `stop_speed` key whose default is `default`: the key and its meaning are the rule's, its
/// default the stage's (a motion topic says only a speed; a stop signal says whether it stands).
pub const fn stop_speed(default: DefaultValue) -> Key {
    Key {
        name: "stop_speed",
        ty: Type::Positive(100.0),
        default,
        doc: "stands when the vehicle's speed is at most this, m/s (a NaN speed: unknown); a signal that says only a speed (a ROS 2 motion topic) needs it",
    }
}

/// `stop_speed` of a motion topic (`ingest.mcap`'s `stop_topic`): a speed always rules.
pub const STOP_SPEED_OF_TOPIC: Key = stop_speed(DefaultValue::Float(DEFAULT_STOP_SPEED_M_S));

/// `stop_speed` of a stop signal (`predict.bias`'s `stop_input`): by default its own stands
/// flag decides.
pub const STOP_SPEED_OF_SIGNAL: Key = stop_speed(DefaultValue::Absent(
    "none: the signal's stopped field decides",
));

/// `stop_max_age_s`.
pub const STOP_MAX_AGE_S: Key = Key {
    name: "stop_max_age_s",
    ty: Type::Positive(60.0),
    default: DefaultValue::Float(0.5),
    doc: "a motion message or stop signal older than this (its time against the sample's) says nothing: unknown, never still",
};

/// The speed at or below which a motion topic's vehicle stands when `stop_speed` is not set
/// ([`STOP_SPEED_OF_TOPIC`]'s default; the value the `[ros2]` table's check suggests), m/s.
pub const DEFAULT_STOP_SPEED_M_S: f64 = 0.02;

/// How a stage judges the vehicle's motion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StopRule {
    /// Stands at or below this speed, m/s; None: the signal's own stands flag decides.
    pub speed_m_s: Option<f64>,
    /// Older than this a signal says nothing, ns.
    pub max_age_ns: u64,
}

impl StopRule {
    /// The rule of a stage's table, `speed` being its `stop_speed` key (one of [`stop_speed`]'s,
    /// whose default applies); and the first of the two keys that was set (a stage without a
    /// stop source refuses them).
    pub fn parse(
        t: &mut Table<'_, '_>,
        speed: &Key,
    ) -> Result<(StopRule, Option<&'static str>), InputError> {
        let set = [speed, &STOP_MAX_AGE_S]
            .into_iter()
            .find(|k| t.has(k))
            .map(|k| k.name);
        let speed_m_s = match speed.default.value() {
            Some(_) => Some(t.float_or_default(speed)?),
            None => t.float(speed)?,
        };
        let rule = StopRule {
            speed_m_s,
            max_age_ns: (t.float_or_default(&STOP_MAX_AGE_S)? * 1e9) as u64,
        };
        Ok((rule, set))
    }

    /// What a signal `age_ns` old says: stands (`Some(true)`), moves, or nothing (stale, a
    /// speed that is not a number, or no stands flag where the rule has no speed).
    pub fn judge(&self, age_ns: u64, speed_m_s: f64, stands: Option<bool>) -> Option<bool> {
        if age_ns > self.max_age_ns {
            return None;
        }
        match self.speed_m_s {
            Some(limit) => speed_m_s.is_finite().then(|| speed_m_s.abs() <= limit),
            None => stands,
        }
    }

    /// The rule in words (`validate`).
    pub fn describe(&self) -> String {
        format!(
            "unknown after {} s; stands {}",
            self.max_age_ns as f64 * 1e-9,
            match self.speed_m_s {
                Some(v) => format!("at or below {v} m/s"),
                None => "by its stopped field".into(),
            }
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_decides_where_set_else_the_stands_flag_and_stale_is_unknown() {
        let by_speed = StopRule {
            speed_m_s: Some(0.02),
            max_age_ns: 500_000_000,
        };
        assert_eq!(by_speed.judge(0, 0.02, None), Some(true));
        assert_eq!(by_speed.judge(0, -0.01, Some(false)), Some(true));
        assert_eq!(by_speed.judge(0, 0.03, Some(true)), Some(false));
        assert_eq!(by_speed.judge(0, f64::NAN, Some(true)), None);
        assert_eq!(by_speed.judge(500_000_001, 0.0, None), None);
        let by_flag = StopRule {
            speed_m_s: None,
            ..by_speed
        };
        assert_eq!(by_flag.judge(0, 0.0, None), None);
        assert_eq!(by_flag.judge(0, 9.0, Some(true)), Some(true));
        assert_eq!(by_flag.judge(0, 0.0, Some(false)), Some(false));
    }
}
