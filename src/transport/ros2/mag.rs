//! The magnetometer in ROS 2: `sensor_msgs/msg/MagneticField` (imu_filter_madgwick's
//! `imu/mag`: the field in tesla, with its covariance), its CDR by hand as the Imu message's
//! ([`super::Imu`]), and the one rule that joins it to the Imu samples by stamp
//! ([`MagJoinRule`]), which the live side ([`MagJoin`]) and a bag's replay (`ingest.mcap`'s
//! `mag_topic`) share.
//!
//! **The join.** An Imu sample stamped `t` carries the newest reading whose stamp is at most
//! `t` plus half an Imu period (a reading of the same instant stamped a little after the Imu
//! still belongs to it), if that reading is at most `mag_max_age_s` older than `t`. So:
//! - *Rates differ* (a magnetometer at 100 Hz beside a gyro at 1 kHz): each reading is held
//!   for the Imu samples after it while it is fresh: ten samples carry the same field, as a
//!   driver that reads both chips each cycle would give it. Nothing is interpolated.
//! - *The magnetometer stops* (or lags by more than the age): the samples go on without one
//!   (`RAW_MAG` clear): the attitude stage's heading rests on the gyro, and says so in its
//!   bits. An Imu sample is never held back, dropped or changed for the magnetometer.
//! - *Out of order*: readings are kept in stamp order, so one that arrives late serves the Imu
//!   samples that come after it by stamp and never replaces a newer one; live, one that
//!   arrives after the Imu sample it belongs to was forwarded is too late for it (nothing
//!   waits).
//! - *Not finite*: the reading is joined as it came, with `RAW_MAG`: the guard flags it
//!   (`mag_invalid`) and holds the last good field, as any driver's bad reading; the sample
//!   keeps its rates, and the attitude stage sees no reading.
//! - *No stamp* (0, "not set", or before 1970): the reading cannot be joined and is refused.

use super::imu::{CdrError, Cursor, Time};
use crate::wire::{RawSample, RAW_MAG};

/// The ROS 2 type name of the magnetometer's message (also the MCAP schema name).
pub const MAG_TYPE: &str = "sensor_msgs/msg/MagneticField";

/// The default of `mag_max_age_s`: a reading older than this (s) is no reading. It serves a
/// magnetometer at 10 Hz or faster (imu_filter_madgwick's drivers publish 10 to 100 Hz).
pub const DEFAULT_MAG_MAX_AGE_S: f64 = 0.1;

/// The names of the message's doubles, in order, for errors.
const DOUBLE_NAMES: [&str; 12] = [
    "magnetic_field.x",
    "magnetic_field.y",
    "magnetic_field.z",
    "magnetic_field_covariance[0]",
    "magnetic_field_covariance[1]",
    "magnetic_field_covariance[2]",
    "magnetic_field_covariance[3]",
    "magnetic_field_covariance[4]",
    "magnetic_field_covariance[5]",
    "magnetic_field_covariance[6]",
    "magnetic_field_covariance[7]",
    "magnetic_field_covariance[8]",
];

/// A `sensor_msgs/msg/MagneticField` message: the field in tesla (REP 103), its covariance
/// row major about x, y, z (all zeros: unknown).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MagneticField {
    /// `header.stamp`: when the field was measured.
    pub stamp: Time,
    /// `header.frame_id`.
    pub frame_id: String,
    /// The field x, y, z, tesla.
    pub magnetic_field: [f64; 3],
    /// Its covariance, tesla^2.
    pub magnetic_field_covariance: [f64; 9],
}

impl MagneticField {
    /// Decode a CDR message (encapsulation header included). Never panics: bytes that are not
    /// one are an error naming the field and where.
    pub fn from_cdr(bytes: &[u8]) -> Result<MagneticField, CdrError> {
        let mut m = MagneticField::default();
        m.read_cdr(bytes)?;
        Ok(m)
    }

    /// Decode into `self`, reusing its frame_id's buffer. On an error `self` holds a partly
    /// decoded message.
    pub fn read_cdr(&mut self, bytes: &[u8]) -> Result<(), CdrError> {
        let mut c = Cursor::after_header(bytes)?;
        self.stamp.sec = c.u32("header.stamp.sec")? as i32;
        self.stamp.nanosec = c.u32("header.stamp.nanosec")?;
        c.frame_id_into(&mut self.frame_id)?;
        let values = self
            .magnetic_field
            .iter_mut()
            .chain(&mut self.magnetic_field_covariance);
        for (v, name) in values.zip(DOUBLE_NAMES) {
            *v = c.f64(name)?;
        }
        c.end()
    }

    /// Encode as little-endian CDR, header included, into `out` (cleared first).
    pub fn write_cdr(&self, out: &mut Vec<u8>) -> Result<(), CdrError> {
        let len = u32::try_from(self.frame_id.len() + 1)
            .map_err(|_| CdrError::FrameIdTooLong(self.frame_id.len()))?;
        out.clear();
        out.extend_from_slice(&[0, 1, 0, 0]);
        out.extend_from_slice(&(self.stamp.sec as u32).to_le_bytes());
        out.extend_from_slice(&self.stamp.nanosec.to_le_bytes());
        out.extend_from_slice(&len.to_le_bytes());
        out.extend_from_slice(self.frame_id.as_bytes());
        out.push(0);
        while (out.len() - 4) % 8 != 0 {
            out.push(0);
        }
        for v in self
            .magnetic_field
            .iter()
            .chain(&self.magnetic_field_covariance)
        {
            out.extend_from_slice(&v.to_le_bytes());
        }
        Ok(())
    }

    /// [`MagneticField::write_cdr`] into a new vector.
    pub fn to_cdr(&self) -> Result<Vec<u8>, CdrError> {
        let mut out = Vec::with_capacity(4 + 12 + self.frame_id.len() + 8 + 8 * 12);
        self.write_cdr(&mut out)?;
        Ok(out)
    }

    /// The reading to join: its stamp in ns and the field; None without a stamp to join by (0,
    /// ROS 2's "not set", or before 1970).
    pub fn reading(&self) -> Option<MagReading> {
        let stamp_ns = self.stamp.ns();
        (stamp_ns > 0).then_some(MagReading {
            stamp_ns,
            field: self.magnetic_field,
        })
    }
}

/// One magnetometer reading to join: its stamp (ns since the epoch) and field (tesla).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagReading {
    /// `header.stamp`, ns.
    pub stamp_ns: i64,
    /// The field, tesla, as it came (not finite too: the guard flags it).
    pub field: [f64; 3],
}

/// Which reading an Imu sample carries (the module's doc): the newest at most `lead_ns` after
/// the sample's stamp, if it is at most `max_age_ns` older than it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MagJoinRule {
    /// How far after the Imu stamp a reading may be stamped and still belong to it: half an
    /// Imu period.
    pub lead_ns: i64,
    /// How much older than the Imu stamp a reading may be: `mag_max_age_s`.
    pub max_age_ns: i64,
}

impl MagJoinRule {
    /// The rule for Imu samples at `imu_rate_hz` and readings up to `max_age_s` old.
    pub fn new(imu_rate_hz: f64, max_age_s: f64) -> MagJoinRule {
        MagJoinRule {
            lead_ns: (0.5e9 / imu_rate_hz).round() as i64,
            max_age_ns: (max_age_s * 1e9).round() as i64,
        }
    }

    /// The field an Imu sample stamped `t_ns` carries, of `readings` sorted by stamp (equal
    /// stamps: the later one wins); None when none is fresh.
    pub fn pick(&self, readings: &[MagReading], t_ns: i64) -> Option<[f64; 3]> {
        let until = t_ns.saturating_add(self.lead_ns);
        let k = readings.partition_point(|r| r.stamp_ns <= until);
        let r = readings[..k].last()?;
        (t_ns.saturating_sub(r.stamp_ns) <= self.max_age_ns).then_some(r.field)
    }
}

/// The readings a live join keeps: enough for a magnetometer at 1 kHz to be 0.25 s ahead of
/// the Imu stream it joins.
pub const HELD_READINGS: usize = 256;

/// The live join: readings as they arrive, kept in stamp order (at most [`HELD_READINGS`], the
/// newest), and the field of each Imu sample by [`MagJoinRule`]. Allocates only when made.
#[derive(Debug, Clone)]
pub struct MagJoin {
    rule: MagJoinRule,
    held: Vec<MagReading>,
}

impl MagJoin {
    /// An empty join by `rule`.
    pub fn new(rule: MagJoinRule) -> MagJoin {
        MagJoin {
            rule,
            held: Vec::with_capacity(HELD_READINGS),
        }
    }

    /// A reading arrived: kept in its place by stamp. False when it is not kept: no stamp to
    /// join by ([`MagneticField::reading`]), or older than every reading held when they are
    /// [`HELD_READINGS`].
    pub fn push(&mut self, m: &MagneticField) -> bool {
        let Some(r) = m.reading() else {
            return false;
        };
        let mut at = self.held.partition_point(|h| h.stamp_ns <= r.stamp_ns);
        if self.held.len() == HELD_READINGS {
            if at == 0 {
                return false;
            }
            self.held.remove(0);
            at -= 1;
        }
        self.held.insert(at, r);
        true
    }

    /// The field an Imu sample stamped `t_ns` carries.
    pub fn at(&self, t_ns: i64) -> Option<[f64; 3]> {
        self.rule.pick(&self.held, t_ns)
    }
}

/// `raw` with the joined field, or none: `mag` in tesla and [`RAW_MAG`], or the bit clear.
pub fn carry(raw: &mut RawSample, field: Option<[f64; 3]>) {
    match field {
        Some(f) => {
            raw.mag = f;
            raw.flags |= RAW_MAG;
        }
        None => raw.flags &= !RAW_MAG,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T0: i64 = 1_700_000_000_000_000_000;
    const MS: i64 = 1_000_000;

    fn field(k: i64) -> [f64; 3] {
        [20e-6 + k as f64 * 1e-9, -3e-6, -40e-6]
    }

    fn msg(stamp_ns: i64, f: [f64; 3]) -> MagneticField {
        MagneticField {
            stamp: Time::from_ns(stamp_ns).unwrap(),
            frame_id: "imu_link".into(),
            magnetic_field: f,
            magnetic_field_covariance: [1e-12, 0.0, 0.0, 0.0, 2e-12, 0.0, 0.0, 0.0, 3e-12],
        }
    }

    /// A join at 1 kHz Imu, the default age.
    fn join() -> MagJoin {
        MagJoin::new(MagJoinRule::new(1000.0, DEFAULT_MAG_MAX_AGE_S))
    }

    #[test]
    fn a_message_round_trips_through_its_cdr_and_bad_bytes_are_named() {
        let m = msg(T0 + 123, field(7));
        let bytes = m.to_cdr().unwrap();
        // 4 header + 8 stamp + 4 length + 9 "imu_link\0" + 3 padding to 8 + 12 doubles.
        assert_eq!(bytes.len(), 4 + 8 + 4 + 9 + 3 + 96);
        assert_eq!(MagneticField::from_cdr(&bytes).unwrap(), m);
        let cut = MagneticField::from_cdr(&bytes[..bytes.len() - 4]).unwrap_err();
        assert!(
            cut.to_string().contains("magnetic_field_covariance[8]"),
            "{cut}"
        );
        let mut long = bytes.clone();
        long.extend_from_slice(&[0; 8]);
        assert_eq!(MagneticField::from_cdr(&long), Err(CdrError::Trailing(8)));
        assert!(MagneticField::from_cdr(&[0, 1]).is_err());
    }

    /// The same bytes as the Imu codec's for the header and alignment: the field of an Imu
    /// message with frame_id of any length lands on an 8-byte boundary after the header.
    #[test]
    fn frame_ids_of_every_length_align_the_doubles() {
        for n in 0..20 {
            let mut m = msg(T0, field(1));
            m.frame_id = "f".repeat(n);
            let b = m.to_cdr().unwrap();
            assert_eq!((b.len() - 4) % 8, 0, "{n}");
            assert_eq!(MagneticField::from_cdr(&b).unwrap(), m, "{n}");
        }
    }

    /// A magnetometer at 100 Hz beside a gyro at 1 kHz, stamped on the same clock: each Imu
    /// sample carries the newest reading at or before it, ten samples each.
    #[test]
    fn rates_differ_each_reading_is_held_while_fresh() {
        let mut j = join();
        for i in 0..1000i64 {
            if i % 10 == 0 {
                assert!(j.push(&msg(T0 + i * MS, field(i))));
            }
            assert_eq!(j.at(T0 + i * MS), Some(field(i / 10 * 10)), "{i}");
        }
    }

    /// A reading stamped a little after the Imu sample (less than half a period) is of the
    /// same instant and joins it; one later than that waits for the next sample.
    #[test]
    fn a_reading_up_to_half_a_period_ahead_belongs_to_the_sample() {
        let mut j = join();
        j.push(&msg(T0, field(0)));
        j.push(&msg(T0 + 10 * MS + MS / 2, field(1)));
        assert_eq!(j.at(T0 + 10 * MS), Some(field(1)), "0.5 ms ahead: this one");
        let mut j = join();
        j.push(&msg(T0, field(0)));
        j.push(&msg(T0 + 10 * MS + MS / 2 + 1, field(1)));
        assert_eq!(
            j.at(T0 + 10 * MS),
            Some(field(0)),
            "past half a period: the one before"
        );
        assert_eq!(j.at(T0 + 11 * MS), Some(field(1)));
        // Before any reading: none.
        assert_eq!(j.at(T0 - MS), None);
    }

    /// The magnetometer stops: its last reading serves up to `mag_max_age_s` (0.1 s, inclusive),
    /// then the samples carry none; a new reading is taken at once.
    #[test]
    fn a_stream_that_stops_ages_out_and_comes_back() {
        let mut j = join();
        j.push(&msg(T0, field(0)));
        assert_eq!(j.at(T0 + 100 * MS), Some(field(0)));
        assert_eq!(j.at(T0 + 100 * MS + 1), None);
        assert_eq!(j.at(T0 + 5_000 * MS), None);
        j.push(&msg(T0 + 5_000 * MS, field(5)));
        assert_eq!(j.at(T0 + 5_000 * MS), Some(field(5)));
        // A shorter age.
        let mut j = MagJoin::new(MagJoinRule::new(1000.0, 0.02));
        j.push(&msg(T0, field(0)));
        assert_eq!(j.at(T0 + 20 * MS), Some(field(0)));
        assert_eq!(j.at(T0 + 21 * MS), None);
    }

    /// Readings that arrive out of stamp order take their place: a late one serves the samples
    /// between it and the next, never those after a newer one.
    #[test]
    fn readings_out_of_order_take_their_place_by_stamp() {
        let mut j = join();
        j.push(&msg(T0 + 20 * MS, field(20)));
        j.push(&msg(T0 + 10 * MS, field(10)));
        j.push(&msg(T0, field(0)));
        assert_eq!(j.at(T0 + 5 * MS), Some(field(0)));
        assert_eq!(j.at(T0 + 15 * MS), Some(field(10)));
        assert_eq!(j.at(T0 + 25 * MS), Some(field(20)));
        // Imu samples out of order are answered by their own stamps.
        assert_eq!(j.at(T0 + 12 * MS), Some(field(10)));
        // Equal stamps: the later arrival wins.
        j.push(&msg(T0 + 20 * MS, field(21)));
        assert_eq!(j.at(T0 + 25 * MS), Some(field(21)));
    }

    /// A non-finite reading is joined as it came (the guard flags it and holds the last good
    /// field); the next finite one replaces it. A reading with no stamp is refused.
    #[test]
    fn non_finite_readings_pass_to_the_guard_and_unstamped_ones_are_refused() {
        let mut j = join();
        j.push(&msg(T0, field(0)));
        j.push(&msg(T0 + 10 * MS, [f64::NAN, 1.0, f64::INFINITY]));
        let got = j.at(T0 + 12 * MS).unwrap();
        assert!(got[0].is_nan() && got[2].is_infinite(), "{got:?}");
        j.push(&msg(T0 + 20 * MS, field(2)));
        assert_eq!(j.at(T0 + 20 * MS), Some(field(2)));
        assert!(!j.push(&msg(0, field(3))), "stamp 0: not set");
        assert!(!j.push(&MagneticField {
            stamp: Time {
                sec: -1,
                nanosec: 0
            },
            ..msg(T0, field(4))
        }));
        assert_eq!(j.at(T0 + 20 * MS), Some(field(2)));
        let mut raw = RawSample::default();
        carry(&mut raw, Some(field(2)));
        assert_eq!((raw.mag_reading(), raw.rate), (Some(field(2)), [0.0; 3]));
        carry(&mut raw, None);
        assert_eq!(raw.mag_reading(), None);
    }

    /// The live join keeps the newest [`HELD_READINGS`]; one older than all of them is refused.
    /// On readings in stamp order it answers what the rule answers on all of them at once (the
    /// bag's replay).
    #[test]
    fn the_live_join_answers_as_the_rule_on_the_whole_stream() {
        let rule = MagJoinRule::new(1000.0, DEFAULT_MAG_MAX_AGE_S);
        let mut j = MagJoin::new(rule);
        let mut all = Vec::new();
        for k in 0..1000i64 {
            // A magnetometer at about 300 Hz whose stamps wander by up to 0.7 ms.
            let stamp = T0 + k * 3_333_333 + (k * 7919 % 1400 - 700) * 1000;
            let m = msg(stamp, field(k));
            assert!(j.push(&m));
            all.push(m.reading().unwrap());
            // The samples between this reading and the next, by the live join and the rule.
            for t in (0..4).map(|d| stamp - 2 * MS + d * MS) {
                let mut sorted = all.clone();
                sorted.sort_by_key(|r| r.stamp_ns);
                assert_eq!(j.at(t), rule.pick(&sorted, t), "{k} {t}");
            }
        }
        assert!(!j.push(&msg(T0, field(0))), "older than every held one");
    }
}
