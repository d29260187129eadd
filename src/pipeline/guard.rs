//! The input guard between the ingest and the first processing stage: units to rad/s, and the
//! checks on every raw sample (non-finite or driver-invalid values, sequence gaps, timestamps
//! going backwards). A bad value is replaced by the last good one, flagged and counted: no NaN
//! or Inf ever enters a stage.

use crate::pipeline::config::Units;
use crate::transport::{
    GyroSample, RawSample, FLAG_GAP_BEFORE, FLAG_INPUT_INVALID, FLAG_TIME_BACKWARDS, RAW_INVALID,
};

/// Counts of what the guard flagged.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GuardCounts {
    /// Samples with a non-finite or driver-invalid rate.
    pub invalid: u64,
    /// Gaps (a sequence jump).
    pub gaps: u64,
    /// Sequence numbers missing in total.
    pub missing: u64,
    /// Timestamps that went backwards.
    pub backwards: u64,
}

/// Turns raw samples into [`GyroSample`]s in rad/s.
#[derive(Debug, Clone)]
pub struct Guard {
    scale: f64,
    axes: usize,
    last_good: [f64; 3],
    last_seq: Option<u64>,
    last_t: Option<u64>,
    /// What was flagged so far.
    pub counts: GuardCounts,
}

impl Guard {
    /// A guard for `axes` axes in `units`.
    pub fn new(units: Units, axes: usize) -> Self {
        Guard {
            scale: units.to_rad_per_sec(),
            axes: axes.clamp(1, 3),
            last_good: [0.0; 3],
            last_seq: None,
            last_t: None,
            counts: GuardCounts::default(),
        }
    }

    /// Check and convert one raw sample ingested at `ingest_ns`.
    pub fn admit(&mut self, raw: &RawSample, ingest_ns: u64) -> GyroSample {
        let mut flags = 0;
        let mut rate = [0.0; 3];
        let driver_invalid = raw.flags & RAW_INVALID != 0;
        let finite = raw.rate[..self.axes].iter().all(|v| v.is_finite());
        if driver_invalid || !finite {
            flags |= FLAG_INPUT_INVALID;
            self.counts.invalid += 1;
            rate = self.last_good;
        } else {
            for (r, v) in rate.iter_mut().zip(&raw.rate).take(self.axes) {
                *r = v * self.scale;
            }
            self.last_good = rate;
        }
        if let Some(prev) = self.last_seq {
            let expected = prev.wrapping_add(1);
            if raw.seq != expected {
                flags |= FLAG_GAP_BEFORE;
                self.counts.gaps += 1;
                if raw.seq > expected {
                    self.counts.missing += raw.seq - expected;
                }
            }
        }
        self.last_seq = Some(raw.seq);
        if let Some(prev) = self.last_t {
            if raw.t_ns < prev {
                flags |= FLAG_TIME_BACKWARDS;
                self.counts.backwards += 1;
            }
        }
        self.last_t = Some(raw.t_ns);
        GyroSample {
            t_ns: raw.t_ns,
            seq: raw.seq,
            ingest_ns,
            rate,
            drift: [0.0; 3],
            denoised: rate,
            flags,
            reserved: 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raw(seq: u64, t_ns: u64, x: f64) -> RawSample {
        RawSample {
            t_ns,
            seq,
            rate: [x, 1.0, 2.0],
            flags: 0,
            reserved: 0,
        }
    }

    #[test]
    fn flags_and_counts_bad_samples() {
        let mut g = Guard::new(Units::RadPerSec, 3);
        assert_eq!(g.admit(&raw(0, 10, 1.0), 0).flags, 0);
        let s = g.admit(&raw(1, 20, f64::NAN), 0);
        assert_eq!(s.flags, FLAG_INPUT_INVALID);
        assert_eq!(s.rate, [1.0, 1.0, 2.0]);
        let s = g.admit(&raw(2, 30, f64::INFINITY), 0);
        assert!(s.rate.iter().all(|v| v.is_finite()));
        assert_eq!(g.admit(&raw(5, 40, 1.0), 0).flags, FLAG_GAP_BEFORE);
        assert_eq!(g.admit(&raw(6, 35, 1.0), 0).flags, FLAG_TIME_BACKWARDS);
        assert_eq!(
            g.counts,
            GuardCounts {
                invalid: 2,
                gaps: 1,
                missing: 2,
                backwards: 1
            }
        );
    }

    #[test]
    fn converts_degrees() {
        let mut g = Guard::new(Units::DegPerSec, 1);
        let s = g.admit(&raw(0, 0, 180.0), 0);
        assert!((s.rate[0] - std::f64::consts::PI).abs() < 1e-15);
        assert_eq!(s.rate[1], 0.0);
    }
}
