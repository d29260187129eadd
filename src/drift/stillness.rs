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
//! **A window that grows** ([`Growth`]): with thresholds for fewer samples than `window`, the
//! detector judges a window that is still filling (at start-up, from the first sample) or one
//! cut back to the samples since another sensor saw the body come to rest
//! ([`StillnessDetector::restart`]). The thresholds for n samples are those of the full window
//! with n in its place: chi-square quantiles (Wilson-Hilferty) of the variance and the spread of
//! an n-sample mean. A failed test ends that: the rest's start is refuted, and the detector
//! waits for a full window again, as without [`Growth`]. A rest confirmed on fewer samples than
//! the window has had less power against a slow turn: it is judged at the exit thresholds, not
//! the wider enter ones, until a full window has passed them ([`StillnessDetector::is_provisional`]).
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

/// Log-likelihood ratio of "moving" (a mean shift and a variance rise of unknown sizes) against
/// "still" for `n` standardised residuals of sum `sum` and sum of squares `sum2` (residual over
/// the still model's standard deviation). A variance *below* the model's counts as still, as a
/// band-limited real sensor's is.
pub fn moving_llr(n: f64, sum: f64, sum2: f64) -> f64 {
    let mean = sum / n;
    let s2 = sum2 / n - mean * mean;
    if s2 > 1.0 {
        0.5 * (sum2 - n - n * s2.ln())
    } else {
        0.5 * sum * mean
    }
}

/// Another sensor's verdict on the whole body at a sample (the accelerometer's,
/// [`crate::drift::accel_rest`]), beside a gyro axis's own detector.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Aid {
    /// No verdict: the gyro alone decides.
    Unknown,
    /// Quiet: no sign of motion for `since` samples, this one included (its own estimate of
    /// when the body came to rest).
    Quiet {
        /// Samples since the rest began.
        since: usize,
    },
    /// Moving, since `age` samples before this one (its own estimate of the onset).
    Moving {
        /// Samples since the onset (0: this sample).
        age: usize,
    },
}

/// Thresholds for a window of fewer samples than the full one (see the module documentation),
/// from the same noise model as the full window's: the still per-sample variance `var`, and
/// the variance of an n-sample mean `mean_white / n + mean_pair / n^2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Growth {
    /// Variance of one still sample.
    pub var: f64,
    /// Part of an n-sample mean's variance that falls as 1/n (white noise and what acts like it).
    pub mean_white: f64,
    /// Part that falls as 1/n^2 (quantisation noise: a differenced white angle telescopes).
    pub mean_pair: f64,
    /// Standard deviations (of a normal tail) above the still value: the exit thresholds.
    pub var_sigmas: f64,
    /// The same for the mean-shift test.
    pub mean_sigmas: f64,
    /// Enter thresholds are this many times as far (>= 1).
    pub hysteresis: f64,
}

/// Upper quantile of chi-square with `k` degrees of freedom, divided by `k`, at the tail
/// probability of `z` standard deviations of a normal (Wilson and Hilferty 1931): for large k
/// it is 1 + z sqrt(2/k), the full window's rule; for small k it follows the chi-square's long
/// right tail, so a short window does not see motion in noise.
pub fn chi2_ratio(k: f64, z: f64) -> f64 {
    let k = k.max(1.0);
    let c = 2.0 / (9.0 * k);
    (1.0 - c + z * c.sqrt()).max(0.0).powi(3)
}

impl Growth {
    /// (variance exit, variance enter, mean exit, mean enter) for a window of `n` samples.
    fn thresholds(&self, n: usize) -> (f64, f64, f64, f64) {
        let k = n.saturating_sub(1).max(1) as f64;
        let nf = n.max(1) as f64;
        let mean_sd = (self.mean_white / nf + self.mean_pair / (nf * nf)).sqrt();
        (
            self.var * chi2_ratio(k, self.var_sigmas),
            self.var * chi2_ratio(k, self.hysteresis * self.var_sigmas),
            self.mean_sigmas * mean_sd,
            self.hysteresis * self.mean_sigmas * mean_sd,
        )
    }
}

/// The detector's state (see the module documentation).
#[derive(Debug, Clone)]
pub struct StillnessDetector {
    cfg: StillnessConfig,
    growth: Option<Growth>,
    /// The window began at a rest's start (a reset, or [`StillnessDetector::restart`]) and no
    /// test has failed since: a window still filling is judged with the [`Growth`] thresholds.
    growing: bool,
    ring: Vec<f64>,
    pos: usize,
    filled: usize,
    origin: f64,
    sum: f64,
    sum2: f64,
    still: bool,
    /// Still, confirmed on fewer samples than the window; no full window has passed since.
    provisional: bool,
    quiet: usize,
    anchor: f64,
}

impl StillnessDetector {
    /// A detector (thresholds assumed checked), starting in the moving state.
    pub fn new(cfg: StillnessConfig) -> Self {
        StillnessDetector {
            ring: vec![0.0; cfg.window.max(2)],
            cfg,
            growth: None,
            growing: true,
            pos: 0,
            filled: 0,
            origin: 0.0,
            sum: 0.0,
            sum2: 0.0,
            still: false,
            provisional: false,
            quiet: 0,
            anchor: f64::NAN,
        }
    }

    /// The same detector judging windows that are still filling too, with `growth`'s
    /// thresholds for fewer samples than the full window.
    pub fn with_growth(mut self, growth: Growth) -> Self {
        self.growth = Some(growth);
        self
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

    /// Samples in the window now.
    pub fn filled(&self) -> usize {
        self.filled
    }

    /// Whether the sensor is still on a window shorter than the full one that no full window
    /// has confirmed yet: judged at the exit thresholds (no hysteresis) until one does.
    pub fn is_provisional(&self) -> bool {
        self.still && self.provisional
    }

    /// Whether the detector holds a stop's mean as its own reference (see
    /// [`StillnessDetector::update`]).
    pub fn has_anchor(&self) -> bool {
        self.anchor.is_finite()
    }

    /// Forget the last stop's mean, the reference without one from outside: that stop gave
    /// the estimate nothing (a lull within a movement), so it says nothing of the bias.
    pub fn forget_anchor(&mut self) {
        self.anchor = f64::NAN;
    }

    /// Whether the last update passed the exit tests (still, or on its way there: settling).
    pub fn is_quiet(&self) -> bool {
        self.still || self.quiet > 0
    }

    /// The window's samples, oldest first (as many as it holds).
    pub fn window(&self) -> impl Iterator<Item = f64> + '_ {
        let w = self.ring.len();
        let start = (self.pos + w - self.filled) % w;
        (0..self.filled).map(move |i| self.origin + self.ring[(start + i) % w])
    }

    /// Cut the window back to its newest `keep` samples (another sensor saw the body come to
    /// rest that long ago), and judge their variance at once with the [`Growth`] thresholds: if
    /// it passes, they count as quiet samples towards `settle` (the next update still tests
    /// their mean). Nothing without [`Growth`], when still, or if the window holds no more than
    /// `keep`. O(window) once.
    pub fn restart(&mut self, keep: usize) {
        let Some(g) = self.growth else { return };
        if keep >= self.filled || keep == 0 || self.still {
            return;
        }
        let w = self.ring.len();
        let start = (self.pos + w - self.filled) % w;
        for i in 0..self.filled - keep {
            let old = self.ring[(start + i) % w];
            self.sum -= old;
            self.sum2 -= old * old;
        }
        self.filled = keep;
        let (var_exit, ..) = g.thresholds(keep);
        self.growing = self.variance() <= var_exit;
        self.quiet = if self.growing { keep } else { 0 };
    }

    /// Back to the initial (moving, empty) state.
    pub fn reset(&mut self) {
        self.pos = 0;
        self.filled = 0;
        self.sum = 0.0;
        self.sum2 = 0.0;
        self.still = false;
        self.provisional = false;
        self.quiet = 0;
        self.anchor = f64::NAN;
        self.growing = true;
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
        let (var_exit, var_enter, mean_exit, mean_enter) = if self.filled < w {
            match self.growth {
                Some(g) if self.growing => g.thresholds(self.filled),
                _ => {
                    self.still = false;
                    self.quiet = 0;
                    return false;
                }
            }
        } else {
            (
                self.cfg.var_exit,
                self.cfg.var_enter,
                self.cfg.mean_exit,
                self.cfg.mean_enter,
            )
        };
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
        // A rest confirmed on a short window keeps to the exit thresholds: the hysteresis must
        // not hold a slow turn that a full window would never have let in.
        let (var_enter, mean_enter) = if self.provisional {
            (var_exit, mean_exit)
        } else {
            (var_enter, mean_enter)
        };
        if self.still {
            if var > var_enter || shift > mean_enter + tol {
                self.still = false;
                self.provisional = false;
                self.quiet = 0;
                self.growing = false;
            } else if self.filled == w {
                self.provisional = false;
            }
        } else if var <= var_exit && shift <= mean_exit + tol {
            self.quiet += 1;
            if self.quiet >= self.cfg.settle {
                self.still = true;
                self.provisional = self.filled < w;
                self.anchor = self.mean();
            }
        } else {
            self.quiet = 0;
            self.growing = false;
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
    fn growth() -> Growth {
        // Unit variance per sample; a mean of n samples has variance 1/n.
        Growth {
            var: 1.0,
            mean_white: 1.0,
            mean_pair: 0.0,
            var_sigmas: 4.0,
            mean_sigmas: 4.0,
            hysteresis: 1.5,
        }
    }

    #[test]
    fn chi_square_bounds_follow_the_tail() {
        // k = 2: the survival function is exp(-x/2), so the exact bound at the tail of 4 normal
        // standard deviations (3.167e-5) is -2 ln(3.167e-5) / 2 = 10.36 per degree of freedom.
        let exact = -2.0 * 3.167e-5f64.ln() / 2.0;
        let wh = chi2_ratio(2.0, 4.0);
        assert!((wh / exact - 1.0).abs() < 0.1, "{wh} vs {exact}");
        // Many degrees of freedom: the normal rule of the full window.
        let k = 1.0e4;
        assert!((chi2_ratio(k, 4.0) - (1.0 + 4.0 * (2.0 / k).sqrt())).abs() < 2e-3);
        assert!(chi2_ratio(10.0, 6.0) > chi2_ratio(10.0, 4.0));
    }

    #[test]
    fn a_growing_window_is_judged_and_a_failure_ends_it() {
        let mut d = StillnessDetector::new(cfg()).with_growth(Growth {
            var: 0.01,
            mean_white: 0.01,
            ..growth()
        });
        // From a reset the window is judged while it fills: still after `settle` samples.
        let states: Vec<bool> = (0..6)
            .map(|i| d.update(1.0 + (i % 2) as f64 * 0.1, 1.0))
            .collect();
        assert!(!states[3] && states[4], "{states:?}");
        // A failed test refutes the rest: the next still waits for a full window.
        d.reset();
        d.update(1.0, 1.0);
        d.update(9.0, 1.0);
        assert!(!d.is_quiet());
        let back: Vec<bool> = (0..20).map(|_| d.update(1.0, 1.0)).collect();
        let first = back.iter().position(|&s| s).unwrap();
        assert!(first >= 8 + 5 - 1, "still after {first}");
    }

    #[test]
    fn a_restart_judges_the_samples_since_the_rest_began() {
        let mut d = StillnessDetector::new(cfg()).with_growth(Growth {
            var: 0.01,
            mean_white: 0.01,
            ..growth()
        });
        // Motion fills the window, then 6 quiet samples: the full window is not still yet.
        for i in 0..10 {
            d.update(5.0 * (i % 2) as f64, f64::NAN);
        }
        for _ in 0..6 {
            assert!(!d.update(1.0, f64::NAN));
        }
        // Another sensor says the rest began 7 samples ago (6 in the window and this one).
        d.restart(6);
        assert_eq!(d.filled(), 6);
        assert!((d.mean() - 1.0).abs() < 1e-12 && d.variance() < 1e-12);
        assert!(
            d.update(1.0, f64::NAN),
            "quiet since the rest began: settled"
        );
        assert_eq!(d.window().count(), 7);
        // Without growth a restart does nothing.
        let mut plain = StillnessDetector::new(cfg());
        for i in 0..10 {
            plain.update(5.0 * (i % 2) as f64, f64::NAN);
        }
        plain.restart(3);
        assert_eq!(plain.filled(), 10);
    }
}
