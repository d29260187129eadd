//! Live drift compensation, one sample at a time, that never subtracts real rotation.
//!
//! For each denoised rate sample `x[t]`:
//!
//! 1. the predictor gives the drift `d[t]` from its p inputs (values up to t - 1);
//! 2. the low band ([`LowBand`]) of x is updated, and the stillness detector
//!    ([`StillnessDetector`]) judges the window ending at t, with `d[t]` as its reference;
//! 3. **still**: the measured low band at t becomes the newest input (the model is re-anchored
//!    on measured drift); **moving**: `d[t]` itself becomes the newest input, so the model runs on
//!    its own predictions and the rotation in the low band never enters it;
//! 4. the output is `x[t] - d[t]`, with the mode.
//!
//! While moving, each free-running step is limited to `max_step` (from the training drift), so
//! a model outside its training range cannot run away during a long turn. Until the detector
//! has first seen the sensor still for p samples, there is no drift estimate: the output is
//! the input and the mode is [`Mode::Warming`].
//!
//! O(1) per sample, no allocation after construction.

use super::baselines::Predictor;
use super::lowband::LowBand;
use super::stillness::{StillnessConfig, StillnessDetector};
use super::MAX_LAGS;

/// What the compensator did with a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// No drift estimate yet (never seen still): nothing subtracted.
    Warming,
    /// Still: inputs are the measured drift.
    Still,
    /// Moving: the model runs on its own predictions.
    Moving,
}

/// One compensated sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// Compensated rate: input minus drift.
    pub rate: f64,
    /// Drift subtracted (0 while warming).
    pub drift: f64,
    /// Mode at this sample.
    pub mode: Mode,
}

/// The live compensator around any [`Predictor`].
#[derive(Debug, Clone)]
pub struct Compensator<P: Predictor> {
    predictor: P,
    lowband: LowBand,
    detector: StillnessDetector,
    hist: [f64; MAX_LAGS],
    lags: usize,
    measured: usize,
    anchored: bool,
    max_step: f64,
}

impl<P: Predictor> Compensator<P> {
    /// A compensator (lags <= [`MAX_LAGS`]; `max_step` > 0, infinite for no limit).
    pub fn new(
        predictor: P,
        lowband: LowBand,
        stillness: StillnessConfig,
        max_step: f64,
    ) -> Result<Self, String> {
        stillness.check()?;
        let lags = predictor.lags();
        if !(1..=MAX_LAGS).contains(&lags) {
            return Err(format!(
                "predictor lags must be 1 to {MAX_LAGS}, not {lags}"
            ));
        }
        if max_step.is_nan() || max_step <= 0.0 {
            return Err(format!("max step must be > 0, not {max_step}"));
        }
        Ok(Compensator {
            predictor,
            lowband,
            detector: StillnessDetector::new(stillness),
            hist: [0.0; MAX_LAGS],
            lags,
            measured: 0,
            anchored: false,
            max_step,
        })
    }

    /// The predictor.
    pub fn predictor(&self) -> &P {
        &self.predictor
    }

    /// Forget everything (back to warming).
    pub fn reset(&mut self) {
        self.lowband.reset();
        self.detector.reset();
        self.measured = 0;
        self.anchored = false;
    }

    fn shift_in(&mut self, v: f64) {
        let p = self.lags;
        self.hist.copy_within(1..p, 0);
        self.hist[p - 1] = v;
    }

    /// Whether the detector, its window full, judged the last sample moving: true while warming
    /// too, when the sensor moves before its first stop.
    pub fn is_moving(&self) -> bool {
        self.detector.is_ready() && !self.detector.is_still()
    }

    /// Compensate one sample.
    pub fn push(&mut self, x: f64) -> Step {
        let p = self.lags;
        let drift = if self.anchored {
            let last = self.hist[p - 1];
            let d = self.predictor.predict(&self.hist[..p]);
            if d.is_finite() {
                d.clamp(last - self.max_step, last + self.max_step)
            } else {
                last
            }
        } else {
            f64::NAN
        };
        let low = self.lowband.push(x);
        let still = self.detector.update(x, drift);
        if still {
            self.shift_in(low);
            self.measured += 1;
            if self.measured >= p {
                self.anchored = true;
            }
        } else if self.anchored {
            self.shift_in(drift);
        } else {
            self.measured = 0;
        }
        if drift.is_finite() {
            Step {
                rate: x - drift,
                drift,
                mode: if still { Mode::Still } else { Mode::Moving },
            }
        } else {
            Step {
                rate: x,
                drift: 0.0,
                mode: Mode::Warming,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drift::baselines::Persistence;

    fn still_cfg() -> StillnessConfig {
        StillnessConfig {
            window: 20,
            var_enter: 0.02,
            var_exit: 0.01,
            mean_enter: 0.2,
            mean_exit: 0.1,
            settle: 40,
        }
    }

    #[test]
    fn a_constant_bias_is_removed_and_a_turn_is_kept() {
        let lb = LowBand::new("db2", 3).unwrap();
        let mut c = Compensator::new(Persistence, lb, still_cfg(), 1e-3).unwrap();
        // Still with a bias of 0.7 for 200 samples, a turn of +5 for 300, still again.
        let bias = 0.7;
        let mut out = Vec::new();
        for t in 0..800 {
            let truth = if (200..500).contains(&t) { 5.0 } else { 0.0 };
            out.push((truth, c.push(truth + bias)));
        }
        assert_eq!(out[0].1.mode, Mode::Warming);
        // Settled and anchored well before the turn: bias removed.
        assert!(out[150..200]
            .iter()
            .all(|(_, s)| s.mode == Mode::Still && s.rate.abs() < 1e-9));
        // During the turn: moving, the full 5 deg/s kept (within the step limit's reach).
        for (truth, s) in &out[202..500] {
            assert_eq!(s.mode, Mode::Moving);
            assert!((s.rate - truth).abs() < 1e-6, "{s:?}");
        }
        // After: still again, bias removed.
        assert!(out[700..]
            .iter()
            .all(|(_, s)| s.mode == Mode::Still && s.rate.abs() < 1e-9));
    }
}
