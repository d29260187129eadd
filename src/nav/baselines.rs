//! The baselines every navigation engineer already has, as causal per-sample bias estimators
//! behind one small trait, beside the new estimator ([`crate::drift::bias::BiasTracker`]).
//!
//! All of them see one measured rate sample at a time (deg/s) and the oracle's still flag, which
//! only the oracle variants read, and return the bias estimate to subtract from that very sample.
//! Nothing is allocated per sample.
//!
//! **ZARU, precisely.** A *stop* is a run of consecutive still flags (the oracle's, or a
//! detector's). Let m be the mean of the current stop's samples so far (this sample included)
//! and `min_samples` the least count it is trusted with.
//! - Before any stop has reached `min_samples` samples, the estimate is 0 (nothing measured).
//! - Inside a stop: m once the stop has `min_samples` samples, before that the held estimate.
//! - When a stop ends: if it reached `min_samples`, its mean is held until the next stop reaches
//!   `min_samples`; a shorter stop is ignored.
//!
//! **Power-on bias** is the same for the *first* stop only: once that stop ends, its mean is held
//! for the rest of the run.
//!
//! With the detector, the stops are the [`StillnessDetector`]'s still runs on the measured rate,
//! its mean-shift reference the held estimate (none before the first): what a careful user does,
//! onsets and all.

use crate::drift::bias::{BiasStep, BiasTracker};
use crate::drift::stillness::{StillnessConfig, StillnessDetector};

/// A causal bias estimator, one sample at a time.
pub trait BiasEstimator {
    /// Take a measured rate sample (deg/s) and the oracle's still flag (ignored by estimators
    /// with their own stop detection); return the bias estimate for this sample (deg/s).
    fn push(&mut self, measured: f64, oracle_still: bool) -> f64;

    /// Whether the estimator judged the last sample still (what a "heading hold" would zero).
    fn still(&self) -> bool {
        false
    }
}

/// No correction: the bias estimate is always 0.
#[derive(Debug, Clone, Copy, Default)]
pub struct Raw;

impl BiasEstimator for Raw {
    fn push(&mut self, _measured: f64, _oracle_still: bool) -> f64 {
        0.0
    }
}

/// Where a ZARU takes its stops from.
#[derive(Debug, Clone)]
pub enum Stops {
    /// The oracle's still flags (the truth).
    Oracle,
    /// A stillness detector on the measured rate.
    Detector(StillnessDetector),
}

/// ZARU (zero angular rate update) with stops from the oracle or a detector; or, with
/// `first_only`, power-on bias (see the module documentation for the exact rules).
#[derive(Debug, Clone)]
pub struct Zaru {
    stops: Stops,
    min_samples: usize,
    first_only: bool,
    held: f64,
    has_held: bool,
    in_stop: bool,
    stop_sum: f64,
    stop_origin: f64,
    stop_count: usize,
    done: bool,
}

impl Zaru {
    fn with(stops: Stops, min_samples: usize, first_only: bool) -> Self {
        Zaru {
            stops,
            min_samples: min_samples.max(1),
            first_only,
            held: 0.0,
            has_held: false,
            in_stop: false,
            stop_sum: 0.0,
            stop_origin: 0.0,
            stop_count: 0,
            done: false,
        }
    }

    /// ZARU on the oracle's stops.
    pub fn oracle(min_samples: usize) -> Self {
        Self::with(Stops::Oracle, min_samples, false)
    }

    /// ZARU on a detector's stops.
    pub fn detected(min_samples: usize, detector: StillnessConfig) -> Self {
        Self::with(
            Stops::Detector(StillnessDetector::new(detector)),
            min_samples,
            false,
        )
    }

    /// Power-on bias: the mean of the first (oracle) stop, held.
    pub fn power_on(min_samples: usize) -> Self {
        Self::with(Stops::Oracle, min_samples, true)
    }

    fn mean(&self) -> f64 {
        self.stop_origin + self.stop_sum / self.stop_count as f64
    }
}

impl BiasEstimator for Zaru {
    fn push(&mut self, measured: f64, oracle_still: bool) -> f64 {
        let still = match &mut self.stops {
            Stops::Oracle => oracle_still,
            Stops::Detector(d) => {
                let reference = if self.has_held { self.held } else { f64::NAN };
                d.update(measured, reference)
            }
        } && measured.is_finite()
            && !self.done;
        if still {
            if !self.in_stop {
                self.in_stop = true;
                self.stop_sum = 0.0;
                self.stop_count = 0;
                // Sums relative to the stop's first sample, against cancellation.
                self.stop_origin = measured;
            }
            self.stop_sum += measured - self.stop_origin;
            self.stop_count += 1;
            if self.stop_count >= self.min_samples {
                return self.mean();
            }
        } else if self.in_stop {
            self.in_stop = false;
            if self.stop_count >= self.min_samples {
                self.held = self.mean();
                self.has_held = true;
                self.done = self.first_only;
            }
        }
        self.held
    }

    fn still(&self) -> bool {
        self.in_stop
    }
}

/// The new estimator ([`BiasTracker`]) as a [`BiasEstimator`]: with its own stop detection, or
/// gated by the oracle's still flags.
#[derive(Debug, Clone)]
pub struct Tracked {
    tracker: BiasTracker,
    oracle: bool,
    last: Option<BiasStep>,
}

impl Tracked {
    /// The tracker with its own detector.
    pub fn detected(tracker: BiasTracker) -> Self {
        Tracked {
            tracker,
            oracle: false,
            last: None,
        }
    }

    /// The tracker gated by the oracle's still flags.
    pub fn oracle(tracker: BiasTracker) -> Self {
        Tracked {
            tracker,
            oracle: true,
            last: None,
        }
    }

    /// The last step's full output.
    pub fn last(&self) -> Option<BiasStep> {
        self.last
    }
}

impl BiasEstimator for Tracked {
    fn push(&mut self, measured: f64, oracle_still: bool) -> f64 {
        let s = if self.oracle {
            self.tracker.push_gated(measured, oracle_still)
        } else {
            self.tracker.push(measured)
        };
        self.last = Some(s);
        s.bias
    }

    fn still(&self) -> bool {
        self.tracker.is_still()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zaru_follows_its_documented_rules() {
        let mut z = Zaru::oracle(3);
        // Before any stop: 0.
        assert_eq!(z.push(5.0, false), 0.0);
        // A stop of 1, 2, 3: held (0) until 3 samples, then the running mean.
        assert_eq!(z.push(1.0, true), 0.0);
        assert_eq!(z.push(2.0, true), 0.0);
        assert_eq!(z.push(3.0, true), 2.0);
        assert_eq!(z.push(5.0, true), 2.75);
        // End of the stop: its mean is held.
        assert_eq!(z.push(100.0, false), 2.75);
        // A too-short stop is ignored.
        assert_eq!(z.push(9.0, true), 2.75);
        assert_eq!(z.push(9.0, false), 2.75);
        // The next long stop replaces it.
        for _ in 0..3 {
            z.push(1.0, true);
        }
        assert_eq!(z.push(0.0, false), 1.0);
    }

    #[test]
    fn power_on_keeps_the_first_stop() {
        let mut z = Zaru::power_on(2);
        z.push(1.0, true);
        assert_eq!(z.push(3.0, true), 2.0);
        assert_eq!(z.push(50.0, false), 2.0);
        for _ in 0..10 {
            assert_eq!(z.push(7.0, true), 2.0);
        }
        assert_eq!(Raw.push(3.0, true), 0.0);
    }
}
