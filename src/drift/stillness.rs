//! The stillness detector: is the sensor still, so that the rate's low band is drift?
//!
//! Over the last `window` samples of the (denoised) rate it keeps the mean and the variance, by
//! running sums: O(1) per sample, no allocation after construction. Two tests:
//!
//! - **variance**: var > `var_enter` means motion (vibration, turns starting and stopping);
//! - **mean shift**: |mean - reference| > `mean_enter` means motion, where the reference is the
//!   compensator's current drift estimate. This catches a *constant-rate* turn, whose variance
//!   is that of a still sensor. Without a reference (NaN) the window mean at the start of the
//!   current or last stop stands in; before any stop only the variance test applies.
//!
//! Hysteresis: once moving, the sensor is still again only after both statistics have stayed
//! below the lower `*_exit` thresholds for `settle` consecutive samples. `settle` should be at least
//! the low band's span, so that no motion is left in the low band's memory when it becomes drift
//! again. The detector starts "moving": it must see `settle` quiet samples before the first
//! anchoring.
//!
//! Rotation slower than the drift band itself (a turn building up over minutes) cannot be told
//! from drift by any test on the rate alone.

use serde::{Deserialize, Serialize};

/// Thresholds of the stillness detector, in the rate's units (variance in units squared).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StillnessConfig {
    /// Samples in the window.
    pub window: usize,
    /// Variance above which the sensor is moving.
    pub var_enter: f64,
    /// Variance below which it may be still again.
    pub var_exit: f64,
    /// |mean - drift estimate| above which the sensor is moving.
    pub mean_enter: f64,
    /// |mean - drift estimate| below which it may be still again.
    pub mean_exit: f64,
    /// Consecutive quiet samples before moving turns to still.
    pub settle: usize,
}

impl StillnessConfig {
    /// Check ranges: window >= 2, thresholds finite and > 0, exit <= enter.
    pub fn check(&self) -> Result<(), String> {
        if self.window < 2 {
            return Err(format!(
                "stillness window must be >= 2, not {}",
                self.window
            ));
        }
        for (name, v) in [
            ("var_enter", self.var_enter),
            ("var_exit", self.var_exit),
            ("mean_enter", self.mean_enter),
            ("mean_exit", self.mean_exit),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("stillness {name} must be a number > 0, not {v}"));
            }
        }
        if self.var_exit > self.var_enter || self.mean_exit > self.mean_enter {
            return Err("stillness exit thresholds must not exceed the enter thresholds".into());
        }
        Ok(())
    }

    /// Thresholds from a still record: the largest window variance and mean shift seen on it
    /// (`rate` the denoised rate, `drift` its low band), times `margin` for the exit thresholds
    /// and twice that for the enter thresholds.
    pub fn calibrate(
        rate: &[f64],
        drift: &[f64],
        window: usize,
        settle: usize,
        margin: f64,
    ) -> Self {
        let mut d = StillnessDetector::new(StillnessConfig {
            window,
            var_enter: f64::MAX,
            var_exit: f64::MAX,
            mean_enter: f64::MAX,
            mean_exit: f64::MAX,
            settle,
        });
        let (mut vmax, mut mmax) = (0.0f64, 0.0f64);
        // Skip the start: the low band and the window are filling.
        let skip = settle.max(window);
        for (t, (&x, &r)) in rate.iter().zip(drift).enumerate() {
            d.update(x, r);
            if t >= skip {
                vmax = vmax.max(d.variance());
                mmax = mmax.max((d.mean() - r).abs());
            }
        }
        let tiny = 1e-12;
        StillnessConfig {
            window,
            var_enter: 2.0 * margin * vmax.max(tiny),
            var_exit: margin * vmax.max(tiny),
            mean_enter: 2.0 * margin * mmax.max(tiny),
            mean_exit: margin * mmax.max(tiny),
            settle,
        }
    }
}

/// The detector's state (see the module documentation).
#[derive(Debug, Clone)]
pub struct StillnessDetector {
    cfg: StillnessConfig,
    ring: Vec<f64>,
    pos: usize,
    filled: usize,
    origin: f64,
    sum: f64,
    sum2: f64,
    still: bool,
    quiet: usize,
    anchor: f64,
}

impl StillnessDetector {
    /// A detector (thresholds assumed checked), starting in the moving state.
    pub fn new(cfg: StillnessConfig) -> Self {
        StillnessDetector {
            ring: vec![0.0; cfg.window.max(2)],
            cfg,
            pos: 0,
            filled: 0,
            origin: 0.0,
            sum: 0.0,
            sum2: 0.0,
            still: false,
            quiet: 0,
            anchor: f64::NAN,
        }
    }

    /// The thresholds.
    pub fn config(&self) -> &StillnessConfig {
        &self.cfg
    }

    /// Mean of the window.
    pub fn mean(&self) -> f64 {
        self.origin + self.sum / self.filled.max(1) as f64
    }

    /// Variance of the window (population).
    pub fn variance(&self) -> f64 {
        let n = self.filled.max(1) as f64;
        let m = self.sum / n;
        (self.sum2 / n - m * m).max(0.0)
    }

    /// Whether the last update judged the sensor still.
    pub fn is_still(&self) -> bool {
        self.still
    }

    /// Whether the window is full, so that "not still" means moving.
    pub fn is_ready(&self) -> bool {
        self.filled == self.ring.len()
    }

    /// The window's samples, oldest first (as many as it holds).
    pub fn window(&self) -> impl Iterator<Item = f64> + '_ {
        let w = self.ring.len();
        let start = if self.filled == w { self.pos } else { 0 };
        (0..self.filled).map(move |i| self.origin + self.ring[(start + i) % w])
    }

    /// Back to the initial (moving, empty) state.
    pub fn reset(&mut self) {
        self.pos = 0;
        self.filled = 0;
        self.sum = 0.0;
        self.sum2 = 0.0;
        self.still = false;
        self.quiet = 0;
        self.anchor = f64::NAN;
    }

    /// Take one rate sample and the current drift estimate (NaN: none yet); returns whether the
    /// sensor is still.
    pub fn update(&mut self, x: f64, reference: f64) -> bool {
        self.update_with_tolerance(x, reference, 0.0)
    }

    /// As [`update`](Self::update), with both mean-shift thresholds raised by `tolerance` (>= 0,
    /// same units as the rate): the uncertainty of the reference itself. A reference that is only
    /// known to +-0.02 must not turn a still sensor into a moving one because it is 0.02 off,
    /// else a poor first estimate could never be corrected (the sensor would never be still
    /// again). A non-finite or negative tolerance counts as 0.
    pub fn update_with_tolerance(&mut self, x: f64, reference: f64, tolerance: f64) -> bool {
        let tol = if tolerance.is_finite() && tolerance > 0.0 {
            tolerance
        } else {
            0.0
        };
        if self.filled == 0 {
            // Sums are kept relative to the first sample, against cancellation at large biases.
            self.origin = x;
        }
        let v = x - self.origin;
        let w = self.ring.len();
        if self.filled == w {
            let old = self.ring[self.pos];
            self.sum -= old;
            self.sum2 -= old * old;
        } else {
            self.filled += 1;
        }
        self.ring[self.pos] = v;
        self.pos = if self.pos + 1 == w { 0 } else { self.pos + 1 };
        self.sum += v;
        self.sum2 += v * v;
        if self.filled < w {
            self.still = false;
            self.quiet = 0;
            return false;
        }
        let var = self.variance();
        // With no reference from outside, a stop is its own: the window mean when it began.
        // Without it, a constant-rate turn that starts inside a first stop would never end it
        // where the variance test cannot see the turn (a noisy sensor).
        let reference = if reference.is_finite() {
            reference
        } else {
            self.anchor
        };
        let shift = if reference.is_finite() {
            (self.mean() - reference).abs()
        } else {
            0.0
        };
        if self.still {
            if var > self.cfg.var_enter || shift > self.cfg.mean_enter + tol {
                self.still = false;
                self.quiet = 0;
            }
        } else if var <= self.cfg.var_exit && shift <= self.cfg.mean_exit + tol {
            self.quiet += 1;
            if self.quiet >= self.cfg.settle {
                self.still = true;
                self.anchor = self.mean();
            }
        } else {
            self.quiet = 0;
        }
        self.still
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> StillnessConfig {
        StillnessConfig {
            window: 10,
            var_enter: 0.04,
            var_exit: 0.02,
            mean_enter: 0.5,
            mean_exit: 0.25,
            settle: 5,
        }
    }

    #[test]
    fn statistics_by_hand() {
        let mut d = StillnessDetector::new(cfg());
        for i in 0..25 {
            d.update(100.0 + (i % 2) as f64 * 0.2, f64::NAN);
        }
        assert!((d.mean() - 100.1).abs() < 1e-9);
        assert!((d.variance() - 0.01).abs() < 1e-9);
    }

    #[test]
    fn hysteresis_and_settling() {
        let mut d = StillnessDetector::new(cfg());
        // Window fills at sample 10, then 5 quiet samples: still from the 14th (index 13).
        let states: Vec<bool> = (0..16).map(|_| d.update(1.0, 1.0)).collect();
        assert!(!states[12] && states[14]);
        // A constant offset of 1 (a constant-rate turn): the mean test trips.
        let mut moved = false;
        for _ in 0..10 {
            moved |= !d.update(2.0, 1.0);
        }
        assert!(moved && !d.is_still());
        // Back at the reference: still only after the window clears and settle quiet samples.
        let back: Vec<bool> = (0..30).map(|_| d.update(1.0, 1.0)).collect();
        let first = back.iter().position(|&s| s).unwrap();
        assert!(first >= 5, "re-anchored after {first}");
    }

    #[test]
    fn calibration_brackets_the_still_statistics() {
        let x: Vec<f64> = (0..500).map(|i| ((i * 7919) % 13) as f64 * 0.01).collect();
        let r = vec![0.06; 500];
        let c = StillnessConfig::calibrate(&x, &r, 20, 30, 1.5);
        assert!(c.check().is_ok());
        let mut d = StillnessDetector::new(c);
        let still = x.iter().filter(|&&v| d.update(v, 0.06)).count();
        assert!(still > 400, "{still}");
    }

    #[test]
    fn tolerance_widens_the_mean_test_only() {
        let mut plain = StillnessDetector::new(cfg());
        let mut tolerant = StillnessDetector::new(cfg());
        // A reference 0.4 off: beyond mean_exit (0.25), within 0.25 + 0.2.
        for _ in 0..30 {
            plain.update(1.4, 1.0);
            tolerant.update_with_tolerance(1.4, 1.0, 0.2);
        }
        assert!(!plain.is_still() && tolerant.is_still());
        // Variance still trips the tolerant detector.
        for i in 0..10 {
            tolerant.update_with_tolerance(1.4 + (i % 2) as f64, 1.0, 0.2);
        }
        assert!(!tolerant.is_still());
    }

    #[test]
    fn bad_thresholds_are_refused() {
        let mut c = cfg();
        c.var_exit = 1.0;
        assert!(c.check().is_err());
        c = cfg();
        c.mean_enter = f64::NAN;
        assert!(c.check().is_err());
    }

    #[test]
    fn without_a_reference_a_stop_is_its_own() {
        // No reference ever (NaN): a constant offset of 1 with a still variance (a steady turn
        // on a sensor whose noise hides its start) ends the stop against the stop's own mean.
        let mut d = StillnessDetector::new(cfg());
        for i in 0..20 {
            d.update(1.0 + (i % 2) as f64 * 0.1, f64::NAN);
        }
        assert!(d.is_still());
        let mut moved = false;
        for i in 0..10 {
            moved |= !d.update(2.0 + (i % 2) as f64 * 0.1, f64::NAN);
        }
        assert!(moved);
        d.reset();
        for i in 0..20 {
            d.update(5.0 + (i % 2) as f64 * 0.1, f64::NAN);
        }
        assert!(d.is_still(), "a reset forgets the old stop");
    }
}
