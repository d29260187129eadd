//! A Kalman filter on the gyro bias whose noise comes from the sensor's own IEEE Std 952 terms,
//! updated by the rate only while the sensor is confirmed still: the estimator a navigator
//! compares with ZARU and with the bias state of an INS filter (docs: `notes/navigation.md`).
//!
//! # Model (one axis, deg/s)
//! measured = bias + white, and while still the true rate is zero, so each still sample is a
//! measurement of the bias. The bias is a sum of states ([`BiasModel`]):
//!
//! - **turn-on bias and rate random walk**: one state with a prior of `initial_sd` and process
//!   noise K^2 dt per sample (IEEE 952 K in deg/s/sqrt(s); K = 0 makes it a constant);
//! - **bias instability B**, three ways ([`Instability`]). The default,
//!   [`Instability::RandomWalk`], adds to that state the random walk whose Allan variance equals
//!   the flicker floor (2 ln2/pi) B^2 at 10 s: no mean reversion, like the gyro bias state of
//!   PX4 EKF2 or ArduPilot EKF3. [`Instability::Flicker`] is a bank of first-order Gauss-Markov
//!   states, one per octave of correlation time, each of stationary variance B^2 ln2/pi: the
//!   flicker PSD B^2/(2 pi f) with Allan floor 0.664 B, the simulator's own construction
//!   ([`crate::sim`]). [`Instability::GaussMarkov`] is the classic single state, sigma = B/0.664.
//!   Measured on heading (docs/navigation.md), the mean-reverting models lose: while moving they
//!   pull the held estimate back towards an old mean, and on the real log the bias has moved.
//! - **measurement noise** per sample: N^2 x rate plus lsb^2/12 (and, for the bank, the flicker
//!   faster than its shortest state). This is the white noise's *low-frequency* PSD, what averaging a still period
//!   feels (N/sqrt(T) over T seconds), not the per-sample variance: real sensors are band-limited
//!   (the real ADIS16405 has 0.32 deg/s per sample where N x sqrt(rate) = 0.38), and quantisation
//!   noise Q (a differenced white angle) has no low-frequency power at all.
//!
//! The filter predicts every sample (the variance grows while moving) and takes a still sample
//! as a measurement H = [1, ..., 1]. O(states^2) per sample, fixed arrays, no allocation.
//!
//! # Stillness and the delay window ([`BiasTracker`])
//! Its own [`StillnessDetector`](crate::drift::stillness::StillnessDetector) on the rate, thresholds from the same terms
//! ([`stillness_from_terms`]). A detector sees motion onset only some samples after it began (the
//! first samples of a slow ramp look still). So a sample enters the filter only once the detector
//! has stayed still for `delay` samples after it: still samples wait in a fixed ring. While they
//! wait, the output is a *provisional* estimate (the filter's estimate combined with the mean of
//! the waiting samples, a scalar update that is not kept), so a stop's measurement is used at once
//! for the output but enters the filter only when it can no longer be the start of a movement.
//!
//! Both ends of a stop are recovered rather than thrown away:
//! - **start**: the detector confirms a stop only after its window (1 s) and settling; the
//!   window's samples, which its test has just judged still, join the stop (`backfill_s`).
//! - **end**: when the detector says moving, the movement's onset is estimated among the waiting
//!   samples (the most likely moving suffix under a likelihood ratio for a mean shift or a
//!   variance rise against the still model); the samples older than the onset by more than
//!   `onset_guard_s` enter the filter, the rest are dropped. A "stop" confirmed for less than
//!   `min_stop_s` is dropped whole: more likely a lull within a movement than a stop.
//!
//! # Start-up
//! A vehicle stands at power-up. From the first sample the tracker takes that rest as given
//! while no test refutes it: each sample waits in the delay window as a still one would, so the
//! output is the estimate so far (the prior combined with every sample seen) from the first
//! sample on, never the raw rate. The detector judges its filling window with thresholds for
//! the samples it holds ([`crate::drift::stillness::Growth`]), and its mean test takes the prior
//! as the reference: a turn at power-up beyond `estimate_sigmas` times `initial_sd` is not a
//! rest. A failed test ends the start-up as the end of any stop ends (the onset estimated,
//! a rest shorter than `min_stop_s` dropped); the full window's confirmation ends it as a stop.
//!
//! # With the accelerometer ([`Aid`], [`BiasTracker::push_with`])
//! The accelerometer's rest test ([`crate::drift::accel_rest`]) judges the whole body. Its
//! "moving" vetoes every axis's stillness and dates the motion's onset: a stop ends there, the
//! samples before it enter the filter. Its "quiet since n samples" cuts the gyro detector's
//! window back to those n samples
//! ([`restart`](crate::drift::stillness::StillnessDetector::restart)): the stop is confirmed when
//! the accelerometer has settled (0.25 s), if the gyro's own tests pass on the samples since
//! the rest began, and is measured from its start. A steady turn at a steady speed does not
//! change the force: the gyro's mean test against the estimate still sees it.
//!
//! # Flags
//! [`BiasMode::Still`]: the detector (or the gate) says still. [`BiasMode::Moving`]: it says
//! moving, before the first stop too. [`BiasMode::Warming`]: the start-up rest is not confirmed
//! yet (the gyro alone: until its first window is full; with a quiet accelerometer: until it
//! has settled), or the detector's first window is not full and the start-up was refuted, so
//! it cannot tell. Apart from the mode, [`BiasStep::informed`] says whether the estimate rests
//! on any still sample (taken or waiting); until then it is the prior (0) with the prior's
//! standard deviation, and a stage flags "warming up": nothing to go on.
//!
//! Files: this one holds the terms and the errors; `filter.rs` the Kalman filter itself
//! ([`BiasModel`], [`BiasFilter`]); `tracker.rs` what feeds it ([`BiasTracker`]: stillness, the
//! delay window, the ends of a stop); `walk.rs` how the filter learns its random walk from the
//! stops ([`WalkLearner`], [`LearnWalk`]); `own_terms.rs` one unit's terms from its still
//! record ([`own_terms`], and its accelerometer's: [`own_accel_terms`]); `accel.rs` the
//! accelerometer's terms a stage reads ([`AccelTerms`]); `odometry.rs` the vehicle's odometry
//! as a measurement of the bias while it drives ([`OdometryAid`]).

mod accel;
mod filter;
mod odometry;
mod own_terms;
mod tracker;
mod walk;

pub use accel::{
    AccelTerms, ADIS16405_BIAS_INSTABILITY_MG, ADIS16405_VRW_PER_HOUR, MG_PER_M_S2, VRW_PER_HOUR,
};
pub use filter::{BiasFilter, BiasModel, FilterSnapshot, ScaleState, ScaledView, DEFAULT_MATCH_S};
pub use odometry::up_from_mount;
pub use odometry::{
    GravityUp, Measurement, Mounting, OdometryAid, OdometryAidConfig, OdometryDiagnostics,
    OdometrySample, UpFromGravity, MOUNT_MIN_SLOPE, MOUNT_MIN_SPANS, MOUNT_SPREAD_DEG_S,
    UP_MAX_TILT_DEG,
};
pub use own_terms::{
    accel_stage_key, combined_as, own_accel_terms, own_terms, stage_key, Choice, ColumnFit,
    OwnAccelTerms, OwnTerms, TermChoices,
};
pub use tracker::{
    accel_rest_from_terms, default_walk_bounds, growth_from_terms, stillness_from_terms, Aid,
    BiasMode, BiasStep, BiasTracker, LearnWalk, TrackerConfig, WALK_LONGEST_S, WALK_SHORTEST_S,
};
pub use walk::{LearnerSnapshot, WalkConfig, WalkLearner, WalkReport, GRID};

use crate::sim::SimConfig;
use std::f64::consts::{LN_2, PI};

/// Most states of a bias model.
pub const MAX_STATES: usize = 32;

/// Longest delay window (samples).
pub const MAX_DELAY: usize = 1 << 20;

/// The Allan floor of a flicker bias is `B_FLOOR` x B (sqrt(2 ln 2 / pi)).
pub const B_FLOOR: f64 = 0.664_282_598_7;

/// Why a bias model or tracker cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BiasError {
    /// A noise term is negative or not finite.
    #[error("noise term {0} must be a finite number >= 0, not {1}")]
    BadTerm(&'static str, f64),
    /// Neither N nor the LSB gives measurement noise.
    #[error("the measurement noise is zero: N (angle random walk) or the LSB must be > 0")]
    NoMeasurementNoise,
    /// The prior of the turn-on bias is not a positive number.
    #[error("the turn-on bias prior must be a finite number > 0 (deg/s), not {0}")]
    BadPrior(f64),
    /// The sample rate is not a positive finite number.
    #[error("the sample rate must be a positive number of Hz, not {0}")]
    BadRate(f64),
    /// A time setting is negative or not finite.
    #[error("{0} must be a finite number of seconds >= 0, not {1}")]
    BadTime(&'static str, f64),
    /// A threshold multiplier is not a positive finite number.
    #[error("{0} must be a finite number > 0, not {1}")]
    BadFactor(&'static str, f64),
    /// The model would need more than [`MAX_STATES`] states.
    #[error("the bias model would need {0} states, at most {MAX_STATES}")]
    TooManyStates(usize),
    /// The delay window is longer than [`MAX_DELAY`] samples.
    #[error("a delay of {0} samples is too long (at most {MAX_DELAY})")]
    DelayTooLong(usize),
    /// No default terms for that sensor.
    #[error("no default bias terms for '{0}' (adis16405, adxrs450)")]
    UnknownProfile(String),
    /// The Allan fit could not identify N.
    #[error("the Allan fit has no angle random walk N ({0}): cannot size the measurement noise")]
    NoN(String),
    /// The Allan fit of an accelerometer could not identify its N.
    #[error(
        "the Allan fit has no velocity random walk N ({0}): cannot size the accelerometer's white noise"
    )]
    NoVrw(String),
    /// A column's B is not identified and its curve has no point to read it from.
    #[error("column '{0}': B is not identified ({1}) and the curve has no point to read it from")]
    NoFloor(String, String),
    /// The derived stillness thresholds are invalid.
    #[error("stillness: {0}")]
    Stillness(String),
    /// The walk to learn or its bounds are invalid.
    #[error("learning the walk: {0}")]
    Walk(String),
    /// A saved state does not fit this filter.
    #[error("resuming: {0}")]
    Resume(String),
}

/// Noise terms of one gyro axis in base units (see [`crate::allan::units`]): what the bias
/// filter and its stillness detector are built from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasTerms {
    /// Angle random walk N, deg/sqrt(s).
    pub n: f64,
    /// Bias instability B, deg/s.
    pub b: f64,
    /// Rate random walk K, deg/s/sqrt(s).
    pub k: f64,
    /// Quantisation noise Q, deg (only widens the detector's variance threshold).
    pub q: f64,
    /// Output step of the rate, deg/s (0: none).
    pub lsb: f64,
    /// Standard deviation of the turn-on bias before any still sample, deg/s.
    pub initial_sd: f64,
}

/// Default prior of the turn-on bias (deg/s): wide for a MEMS gyro, so the first stop decides.
pub const DEFAULT_INITIAL_SD: f64 = 1.0;

impl BiasTerms {
    /// Check: N, B, K, Q, lsb finite and >= 0, some measurement noise (N or lsb > 0), prior > 0.
    pub fn check(&self) -> Result<(), BiasError> {
        for (name, v) in [
            ("N", self.n),
            ("B", self.b),
            ("K", self.k),
            ("Q", self.q),
            ("lsb", self.lsb),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(BiasError::BadTerm(name, v));
            }
        }
        if self.n == 0.0 && self.lsb == 0.0 {
            return Err(BiasError::NoMeasurementNoise);
        }
        if !(self.initial_sd.is_finite() && self.initial_sd > 0.0) {
            return Err(BiasError::BadPrior(self.initial_sd));
        }
        Ok(())
    }

    /// Default terms of a named sensor, the simulator's profiles ([`SimConfig::profile`]):
    /// `adis16405` (N, B fitted to the real static log, LSB 0.05 deg/s) and `adxrs450` (the
    /// paper's Table 1 read in deg/s units), with [`DEFAULT_INITIAL_SD`]. A start with no
    /// characterisation of one's own sensor.
    pub fn profile(name: &str) -> Result<Self, BiasError> {
        let cfg =
            SimConfig::profile(name).map_err(|_| BiasError::UnknownProfile(name.to_string()))?;
        let t = cfg.terms;
        Ok(BiasTerms {
            n: t.n,
            b: t.b,
            k: t.k,
            q: t.q,
            lsb: cfg.lsb.unwrap_or(0.0),
            initial_sd: DEFAULT_INITIAL_SD,
        })
    }

    /// The terms as the keys of a `predict.bias` stage table, in the units pipeline files use
    /// (one `key = value` per line: `arw`, `bias_instability`, `rrw`, `quantization`, `lsb`).
    pub fn stage_keys(&self) -> String {
        format!(
            "arw = {:e}\nbias_instability = {:e}\nrrw = {:e}\nquantization = {:e}\nlsb = {:e}",
            self.n * 60.0,
            self.b * 3600.0,
            self.k * 216_000.0,
            self.q,
            self.lsb
        )
    }

    /// Variance of one sample of a still sensor at `rate_hz` ((deg/s)^2): white N^2 rate,
    /// quantisation 2 Q^2 rate^2, rounding lsb^2/12, and the flicker's B^2 ln2/pi per octave
    /// faster than a second.
    pub fn sample_variance(&self, rate_hz: f64) -> f64 {
        let fast_octaves = (rate_hz.max(1.0)).log2().ceil() + 1.0;
        self.n * self.n * rate_hz
            + 2.0 * self.q * self.q * rate_hz * rate_hz
            + self.lsb * self.lsb / 12.0
            + fast_octaves * self.b * self.b * LN_2 / PI
    }
}

/// How bias instability B becomes filter states.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Instability {
    /// One Gauss-Markov state per octave of correlation time from `shortest_s` to at most
    /// `longest_s`, each of stationary variance B^2 ln2/pi: the flicker PSD B^2/(2 pi f) between
    /// those time scales. Slower flicker is left to the turn-on state; faster flicker is added to
    /// the measurement noise as white noise of PSD 2 (B^2 ln2/pi) `shortest_s`.
    Flicker {
        /// Shortest correlation time, s.
        shortest_s: f64,
        /// Longest correlation time, s.
        longest_s: f64,
    },
    /// No mean reversion: B as extra rate random walk on the turn-on state, sized so that its
    /// Allan variance equals the flicker floor at `tau_s` (K_eq^2 tau/3 = (2 ln2/pi) B^2, so
    /// q = 3 (2 ln2/pi) B^2 / tau_s per second). Bias changes of the flicker's size over
    /// `tau_s`, more over longer times, and no pull back to an old mean when the bias has moved:
    /// what INS filters (PX4 EKF2, ArduPilot EKF3) do with their gyro bias state.
    RandomWalk {
        /// Time scale at which the random walk matches the flicker floor, s.
        tau_s: f64,
    },
    /// One first-order Gauss-Markov state, sigma = B / 0.664, correlation time `tau_s`.
    GaussMarkov {
        /// Correlation time, s.
        tau_s: f64,
    },
}

/// Default longest correlation time of the flicker bank when the terms show no rate random walk
/// to end the flat floor (s): an hour, past a navigation leg between stops. Slower flicker acts
/// as a constant within it.
pub const DEFAULT_LONGEST_S: f64 = 3600.0;

impl Instability {
    /// The default: [`Instability::RandomWalk`] matched to the flicker floor at
    /// [`DEFAULT_MATCH_S`]. Measured against the bank and a single Gauss-Markov state on the
    /// simulator and the real ADIS16405 log (docs/navigation.md): the mean-reverting models pull
    /// the held estimate back towards an old mean while moving, which costs heading when the
    /// real bias has moved (it ramps over minutes on the real log).
    pub fn from_terms(_terms: &BiasTerms) -> Self {
        Instability::RandomWalk {
            tau_s: DEFAULT_MATCH_S,
        }
    }

    /// A flicker bank from 1 s to where the flat floor meets the rate random walk line
    /// ((2 ln2/pi) B^2 = K^2 tau / 3), or [`DEFAULT_LONGEST_S`] when K = 0.
    pub fn flicker_bank(terms: &BiasTerms) -> Self {
        let longest = if terms.k > 0.0 && terms.b > 0.0 {
            (3.0 * 2.0 * LN_2 / PI * terms.b * terms.b / (terms.k * terms.k))
                .clamp(1.0, DEFAULT_LONGEST_S)
        } else {
            DEFAULT_LONGEST_S
        };
        Instability::Flicker {
            shortest_s: 1.0,
            longest_s: longest,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Terms of the bias module's tests: N 0.04, B 0.005, a prior of 1 deg/s.
    pub(crate) fn terms() -> BiasTerms {
        BiasTerms {
            n: 0.04,
            b: 0.005,
            k: 0.0,
            q: 0.0,
            lsb: 0.0,
            initial_sd: 1.0,
        }
    }

    #[test]
    fn bad_terms_are_refused() {
        let mut t = terms();
        t.n = -1.0;
        assert_eq!(t.check(), Err(BiasError::BadTerm("N", -1.0)));
        t.n = f64::NAN;
        assert!(matches!(t.check(), Err(BiasError::BadTerm("N", _))));
        t = terms();
        t.n = 0.0;
        assert_eq!(t.check(), Err(BiasError::NoMeasurementNoise));
        t = terms();
        t.initial_sd = 0.0;
        assert!(BiasTracker::new(&t, 100.0, &TrackerConfig::default()).is_err());
        assert!(
            BiasModel::new(&terms(), f64::INFINITY, Instability::from_terms(&terms())).is_err()
        );
        let cfg = TrackerConfig {
            delay_s: -1.0,
            ..TrackerConfig::default()
        };
        assert!(BiasTracker::new(&terms(), 100.0, &cfg).is_err());
        let cfg = TrackerConfig {
            delay_s: 1e9,
            ..TrackerConfig::default()
        };
        assert!(matches!(
            BiasTracker::new(&terms(), 100.0, &cfg),
            Err(BiasError::DelayTooLong(_))
        ));
        assert!(BiasTerms::profile("nope").is_err());
        let bank = Instability::Flicker {
            shortest_s: 1e-9,
            longest_s: 1e9,
        };
        assert!(matches!(
            BiasModel::new(&terms(), 100.0, bank),
            Err(BiasError::TooManyStates(_))
        ));
    }

    #[test]
    fn a_flicker_bank_has_the_allan_floor_it_is_built_from() {
        // The bank's stationary bias: Allan variance at tau from the states' autocovariance.
        // For a GM of variance s2, time constant T: AVAR(tau) = s2 T/tau^2 (2 tau - 3T + 4T e^-u -
        // T e^-2u), u = tau/T. The sum over the bank at tau = 30 s must be near (2 ln2/pi) B^2.
        let t = terms();
        let m = BiasModel::new(
            &t,
            100.0,
            Instability::Flicker {
                shortest_s: 0.05,
                longest_s: 1e5,
            },
        )
        .unwrap();
        assert!(matches!(
            Instability::flicker_bank(&t),
            Instability::Flicker { longest_s, .. } if longest_s == DEFAULT_LONGEST_S
        ));
        let tau: f64 = 30.0;
        let dt: f64 = 0.01;
        let mut avar = 0.0;
        for i in 1..m.states() {
            let tc = -dt / m.phi[i].ln();
            let u = tau / tc;
            avar += m.p0[i] * tc / (tau * tau)
                * (2.0 * tau - 3.0 * tc + 4.0 * tc * (-u).exp() - tc * (-2.0 * u).exp());
        }
        let floor = 2.0 * LN_2 / PI * t.b * t.b;
        assert!(
            (avar / floor - 1.0).abs() < 0.15,
            "bank AVAR {avar} vs floor {floor}"
        );
    }

    #[test]
    fn the_random_walk_matches_the_floor_at_its_time_scale() {
        // AVAR of a random walk of PSD q: q tau / 3; at tau_s it must be (2 ln2/pi) B^2.
        let t = terms();
        let m = BiasModel::new(&t, 100.0, Instability::RandomWalk { tau_s: 10.0 }).unwrap();
        assert_eq!(m.states(), 1);
        let q_per_s = m.q[0] * 100.0;
        let floor = 2.0 * LN_2 / PI * t.b * t.b;
        assert!((q_per_s * 10.0 / 3.0 / floor - 1.0).abs() < 1e-9);
    }

    #[test]
    fn still_samples_average_like_a_mean() {
        // B = K = 0: the filter is the running mean (with a vague prior).
        let t = BiasTerms { b: 0.0, ..terms() };
        let mut f =
            BiasFilter::new(BiasModel::new(&t, 100.0, Instability::from_terms(&t)).unwrap());
        let xs = [0.3, 0.5, 0.1, 0.7, 0.4];
        for &x in &xs {
            f.predict();
            f.update(x);
        }
        let r = f.model().measurement_variance();
        let mean = 0.4;
        // Posterior mean with prior N(0, 1): mean * 5/r / (5/r + 1).
        let expect = mean * (5.0 / r) / (5.0 / r + 1.0);
        assert!((f.estimate() - expect).abs() < 1e-12, "{}", f.estimate());
        assert!((f.variance() - 1.0 / (5.0 / r + 1.0)).abs() < 1e-12);
    }

    /// The true rate at sample `k` (100 Hz) of 30 s still, then a slow ramp to 5 deg/s over 2 s.
    fn still_then_ramp(k: usize) -> f64 {
        let tt = k as f64 / 100.0;
        if tt < 30.0 {
            0.0
        } else {
            5.0 * ((tt - 30.0) / 2.0).min(1.0)
        }
    }

    #[test]
    fn onset_does_not_leak_and_the_mode_is_truthful() {
        let t = terms();
        let mut tr = BiasTracker::new(&t, 100.0, &TrackerConfig::default()).unwrap();
        let bias = 0.4;
        // 30 s still (constant input: no noise), then a slow ramp to 5 deg/s over 2 s, 20 s moving.
        let mut steps = Vec::new();
        for k in 0..5200 {
            steps.push(tr.push(bias + still_then_ramp(k)));
        }
        // Start-up: from the first sample the body is taken to stand; the estimate so far is
        // subtracted, flagged warming until the detector's window is full and still.
        assert_eq!(steps[0].mode, BiasMode::Warming);
        assert!(steps[0].informed);
        assert!(
            steps[0].bias > 0.0 && steps[0].bias < bias,
            "{:?}",
            steps[0]
        );
        assert_eq!(steps[50].mode, BiasMode::Warming);
        assert!((steps[50].bias - bias).abs() < 1e-2, "{:?}", steps[50]);
        assert_eq!(steps[110].mode, BiasMode::Still);
        assert!(steps[2999].informed);
        assert_eq!(steps[2999].mode, BiasMode::Still);
        assert!((steps[2999].bias - bias).abs() < 1e-3);
        assert_eq!(steps[5199].mode, BiasMode::Moving);
        // Nothing of the ramp entered the filter: the held estimate is the still bias.
        assert!(
            (steps[5199].bias - bias).abs() < 1e-3,
            "leaked: {}",
            steps[5199].bias
        );
        // Its variance grew while moving.
        assert!(steps[5199].std > steps[3000].std);
    }

    #[test]
    fn without_the_delay_the_onset_leaks() {
        // The same ramp with delay 0: the slow start of the ramp is taken as bias, and the
        // detector still takes it (which is why the delay exists).
        let t = terms();
        let cfg = TrackerConfig {
            delay_s: 0.0,
            backfill_s: 0.0,
            ..TrackerConfig::default()
        };
        let mut tr = BiasTracker::new(&t, 100.0, &cfg).unwrap();
        let mut last = None;
        for k in 0..5200 {
            last = Some(tr.push(0.4 + still_then_ramp(k)));
        }
        assert!((last.unwrap().bias - 0.4).abs() > 1e-4);
    }

    #[test]
    fn a_stop_signal_is_used_to_its_end_checked_and_stale_falls_back() {
        let t = terms();
        let cfg = TrackerConfig::default();
        // 10 s still then a turn (0.5 s ramp to 10 deg/s); the signal says "stands" for the
        // still part and "moves" from the turn's first sample.
        let (x, n_still) = stop_then_turn(10.0, 5);
        // From the stop on: a stop signal decides from its first word.
        let x = &x[LEAD..];
        let mut tr = BiasTracker::new(&t, 100.0, &cfg).unwrap();
        let mut flagged = 0;
        for (k, &v) in x.iter().enumerate() {
            let s = tr.push_signal(v, Some(k < n_still));
            flagged += usize::from(s.contradicted);
            if k == 10 {
                // Given stops need no detector window: still from the first samples.
                assert_eq!((s.mode, s.informed), (BiasMode::Still, true));
            }
        }
        assert_eq!(flagged, 0);
        // Every still sample entered the filter (the signal says where the stop ends).
        assert_eq!(tr.filter().updates() as usize, n_still);
        let sd_mean = t.n / 10f64.sqrt();
        assert!((tr.filter().estimate() - 0.4).abs() < 4.0 * sd_mean);

        // A signal that says "stands" through the turn is not trusted there.
        let mut liar = BiasTracker::new(&t, 100.0, &cfg).unwrap();
        let mut flagged = 0;
        let mut last = None;
        for &v in x {
            let s = liar.push_signal(v, Some(true));
            flagged += usize::from(s.contradicted);
            last = Some(s);
        }
        let last = last.unwrap();
        assert!(
            last.contradicted && last.mode == BiasMode::Moving,
            "{last:?}"
        );
        assert!(flagged > 250, "{flagged} of the turn's 300 samples flagged");
        assert!(
            (last.bias - 0.4).abs() < 4.0 * sd_mean,
            "the turn leaked: {last:?}"
        );

        // Unknown (stale) throughout: exactly our detector's verdicts.
        let mut stale = BiasTracker::new(&t, 100.0, &cfg).unwrap();
        let mut own = BiasTracker::new(&t, 100.0, &cfg).unwrap();
        for &v in x {
            assert_eq!(stale.push_signal(v, None), own.push(v));
        }
    }

    #[test]
    fn gated_pushes_and_profiles() {
        let mut tr = BiasTracker::for_profile("adis16405", 100.0).unwrap();
        assert!(tr.delay() == 100);
        let s = tr.push_gated(1.0, false);
        assert_eq!((s.mode, s.informed), (BiasMode::Moving, false));
        let s = tr.push_gated(1.0, true);
        assert_eq!((s.mode, s.informed), (BiasMode::Still, true));
        // Provisional: one sample of variance R ~ 0.15 against the prior's 1 + flicker.
        assert!(
            s.bias > 0.8 && s.bias < 0.95,
            "provisional estimate from the waiting sample: {s:?}"
        );
        // A short stop is dropped: nothing was taken, so nothing to go on again.
        let s = tr.push_gated(1.0, false);
        assert_eq!((s.mode, s.informed, s.bias), (BiasMode::Moving, false, 0.0));
        assert!(tr.push_gated(f64::NAN, true).bias.is_finite());
        tr.reset();
        assert_eq!(tr.filter().updates(), 0);
    }

    /// White noise of `sd` around `bias`, deterministic.
    fn noisy(bias: f64, sd: f64, n: usize, seed: u64) -> Vec<f64> {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                bias + sd * z
            })
            .collect()
    }

    /// Samples of the turn that [`stop_then_turn`] and [`turn_then_still`] start with: the body
    /// moves at power-up, so the stops they test are not the start-up's.
    const LEAD: usize = 200;

    /// [`LEAD`] samples of a swaying turn (10 deg/s at 0.5 Hz), then `n` still, white noise of
    /// the terms around 0.4.
    fn turn_then_still(n: usize, seed: u64) -> Vec<f64> {
        let t = terms();
        let sd = (t.n * t.n * 100.0).sqrt();
        let mut x = noisy(0.4, sd, LEAD + n, seed);
        for (k, v) in x[..LEAD].iter_mut().enumerate() {
            *v += 10.0 * (std::f64::consts::PI * k as f64 / 100.0).cos();
        }
        x
    }

    #[test]
    fn a_stop_is_measured_from_its_start() {
        // Still after a turn: when the detector confirms the stop, the window's samples before
        // it wait with it (backfill), so the provisional estimate rests on all of them.
        let t = terms();
        let x = turn_then_still(400, 1);
        let cfg = TrackerConfig::default();
        let mut with = BiasTracker::new(&t, 100.0, &cfg).unwrap();
        let mut without = BiasTracker::new(
            &t,
            100.0,
            &TrackerConfig {
                backfill_s: 0.0,
                ..cfg
            },
        )
        .unwrap();
        let first = x
            .iter()
            .position(|&v| with.push(v).mode == BiasMode::Still)
            .unwrap();
        let first_without = x
            .iter()
            .position(|&v| without.push(v).mode == BiasMode::Still)
            .unwrap();
        assert_eq!(first, first_without, "the detector is the same");
        assert_eq!(
            with.delay.pending, 51,
            "the window's last 0.5 s and this sample"
        );
        assert_eq!(without.delay.pending, 1);
        // They wait their delay like any other: nothing in the filter yet.
        assert_eq!(with.filter().updates(), 0);
        assert_eq!(with.delay(), 100);
    }

    /// A turn ([`LEAD`] samples), a stop of `still_s`, then a 10 deg/s turn through a 0.5 s
    /// raised-cosine ramp; and the stop's length in samples.
    fn stop_then_turn(still_s: f64, seed: u64) -> (Vec<f64>, usize) {
        let n_still = (still_s * 100.0) as usize;
        let mut x = turn_then_still(n_still + 300, seed);
        let end = LEAD + n_still;
        for (k, v) in x.iter_mut().enumerate().skip(end) {
            let tt = (k - end) as f64 / 100.0;
            let ramp = if tt < 0.5 {
                0.5 * (1.0 - (std::f64::consts::PI * tt / 0.5).cos())
            } else {
                1.0
            };
            *v += 10.0 * ramp;
        }
        (x, n_still)
    }

    #[test]
    fn a_stop_is_used_up_to_the_movements_onset() {
        let t = terms();
        let cfg = TrackerConfig::default();
        let old = TrackerConfig {
            onset_guard_s: 10.0,
            ..cfg
        };
        for seed in 0..20 {
            let (x, n_still) = stop_then_turn(10.0, seed);
            let mut tr = BiasTracker::new(&t, 100.0, &cfg).unwrap();
            let mut dropped = BiasTracker::new(&t, 100.0, &old).unwrap();
            let mut last = None;
            for &v in &x {
                last = Some(tr.push(v));
                dropped.push(v);
            }
            let last = last.unwrap();
            assert_eq!(last.mode, BiasMode::Moving);
            let used = tr.filter().updates() as usize;
            // Everything but the confirmation not backfilled (75 samples), the guard (50) and a
            // few samples of the ramp's unseen start; the old rules used about 775.
            assert!(
                used + 75 + 50 + 40 >= n_still && used <= n_still,
                "seed {seed}: {used} of {n_still}"
            );
            assert!(dropped.filter().updates() as usize + 200 <= n_still);
            // And nothing of the turn leaked: within 4 sd of the mean of 10 s.
            let sd_mean = t.n / 10f64.sqrt();
            assert!(
                (last.bias - 0.4).abs() < 4.0 * sd_mean,
                "seed {seed}: {}",
                last.bias
            );
        }
    }

    #[test]
    fn a_short_lull_is_not_a_stop() {
        // Confirmed still for 0.3 s (< min_stop_s), then moving: nothing enters the filter.
        let t = terms();
        let cfg = TrackerConfig::default();
        let (x, _) = stop_then_turn(1.25 + 0.01 + 0.3, 3);
        let mut tr = BiasTracker::new(&t, 100.0, &cfg).unwrap();
        let mut still = 0;
        for &v in &x {
            if tr.push(v).mode == BiasMode::Still {
                still += 1;
            }
        }
        assert!(still > 0 && still < 50, "{still}");
        assert_eq!(tr.filter().updates(), 0);
    }

    #[test]
    fn a_start_up_rest_is_corrected_from_the_first_sample() {
        // Still at power-up: every output carries the estimate so far, flagged warming, until
        // the gyro's full window confirms the rest (1 s + one sample), never the prior's 0.
        let t = terms();
        let sd = (t.n * t.n * 100.0).sqrt();
        let x = noisy(0.4, sd, 300, 7);
        let mut tr = BiasTracker::new(&t, 100.0, &TrackerConfig::default()).unwrap();
        let steps: Vec<BiasStep> = x.iter().map(|&v| tr.push(v)).collect();
        for (k, s) in steps.iter().enumerate().take(99) {
            assert_eq!((s.mode, s.informed), (BiasMode::Warming, true), "{k}");
            // The estimate is the mean so far (with the prior's small pull to 0).
            let mean = x[..=k].iter().sum::<f64>() / (k + 1) as f64;
            assert!(
                (s.bias - mean).abs() < 0.4 * (1.0 / (k as f64 + 1.0)).sqrt(),
                "{k}: {s:?}"
            );
        }
        assert_eq!(steps[100].mode, BiasMode::Still);
        assert!((steps[299].bias - 0.4).abs() < 4.0 * t.n / 3f64.sqrt());
    }

    #[test]
    fn a_turn_at_power_up_is_not_taken_for_the_bias() {
        // A steady 10 deg/s turn from the first sample: its variance is a still sensor's, but
        // the turn-on bias's prior (1 deg/s) cannot explain it; nothing is subtracted.
        let t = terms();
        let sd = (t.n * t.n * 100.0).sqrt();
        let x = noisy(10.4, sd, 300, 8);
        let mut tr = BiasTracker::new(&t, 100.0, &TrackerConfig::default()).unwrap();
        for (k, &v) in x.iter().enumerate().take(100) {
            let s = tr.push(v);
            assert!(!s.informed && s.bias == 0.0, "{k}: {s:?}");
        }
    }

    #[test]
    fn motion_during_the_start_up_ends_it_and_keeps_what_came_before() {
        // 0.8 s still, then a 10 deg/s turn through a 0.5 s ramp.
        let t = terms();
        let sd = (t.n * t.n * 100.0).sqrt();
        let mut x = noisy(0.4, sd, 400, 9);
        for (k, v) in x.iter_mut().enumerate().skip(80) {
            let tt = (k - 80) as f64 / 100.0;
            *v += 10.0 * 0.5 * (1.0 - (std::f64::consts::PI * (tt / 0.5).min(1.0)).cos());
        }
        let mut tr = BiasTracker::new(&t, 100.0, &TrackerConfig::default()).unwrap();
        let steps: Vec<BiasStep> = x.iter().map(|&v| tr.push(v)).collect();
        let end = steps
            .iter()
            .position(|s| s.mode != BiasMode::Warming)
            .unwrap();
        assert!((80..140).contains(&end), "start-up ended at {end}");
        assert_eq!(steps[399].mode, BiasMode::Moving);
        // The still part (beyond min_stop_s) entered the filter, the turn did not.
        let used = tr.filter().updates() as usize;
        assert!(used > 0 && used <= 80, "{used}");
        assert!((steps[399].bias - 0.4).abs() < 4.0 * t.n / (used as f64 / 100.0).sqrt());
    }

    #[test]
    fn a_quiet_accelerometer_confirms_a_stop_from_its_start_and_dates_its_end() {
        let t = terms();
        let cfg = TrackerConfig::default();
        // A swaying turn, 10 s still, a turn: the accelerometer (here, the truth) is quiet
        // from the stop's first sample and sees the turn begin.
        let (x, n_still) = stop_then_turn(10.0, 11);
        let (start, end) = (LEAD, LEAD + n_still);
        let settle = 25;
        let aid = |k: usize| {
            if (start..end).contains(&k) && k - start + 1 >= settle {
                Aid::Quiet {
                    since: k - start + 1,
                }
            } else if k >= end {
                Aid::Moving { age: k - end }
            } else {
                Aid::Moving { age: 0 }
            }
        };
        let mut aided = BiasTracker::new(&t, 100.0, &cfg).unwrap();
        let mut alone = BiasTracker::new(&t, 100.0, &cfg).unwrap();
        let mut first = (None, None);
        for (k, &v) in x.iter().enumerate() {
            let a = aided.push_with(v, aid(k));
            let g = alone.push(v);
            if a.mode == BiasMode::Still && first.0.is_none() {
                first.0 = Some(k);
            }
            if g.mode == BiasMode::Still && first.1.is_none() && k > LEAD {
                first.1 = Some(k);
            }
        }
        // Confirmed when the accelerometer has settled (0.25 s), not after the gyro's window.
        assert_eq!(first.0, Some(start + settle - 1));
        assert!(first.1.unwrap() >= start + 100, "{first:?}");
        // The whole stop but its first sample's wait measured the bias, and the turn did not.
        let used = aided.filter().updates() as usize;
        assert!(
            used + 1 >= n_still && used <= n_still,
            "{used} of {n_still}"
        );
        assert!(alone.filter().updates() < aided.filter().updates());
        let sd_mean = t.n / 10f64.sqrt();
        assert!((aided.filter().estimate() - 0.4).abs() < 4.0 * sd_mean);
        // The accelerometer's "moving" vetoes a still gyro.
        let mut vetoed = BiasTracker::new(&t, 100.0, &cfg).unwrap();
        for &v in &x[start..end] {
            assert_ne!(
                vetoed.push_with(v, Aid::Moving { age: 0 }).mode,
                BiasMode::Still
            );
        }
    }

    /// The accelerometer's verdict for a body at rest over `rests` (first sample, end) and
    /// moving elsewhere, as [`crate::drift::accel_rest`] gives it: quiet once settled
    /// ([`TrackerConfig::default`]'s 0.25 s), dated from the rest's first sample.
    fn accel_aid(rests: &[(usize, usize)], k: usize) -> Aid {
        let settle = 25;
        match rests.iter().find(|(s, e)| (*s..*e).contains(&k)) {
            Some(&(s, _)) if k - s + 1 >= settle => Aid::Quiet { since: k - s + 1 },
            Some(&(s, _)) => Aid::Moving { age: k - s + 1 },
            None => {
                let end = rests.iter().filter(|(_, e)| *e <= k).map(|(_, e)| *e).max();
                Aid::Moving {
                    age: end.map_or(0, |e| k - e),
                }
            }
        }
    }

    #[test]
    fn a_slow_turn_at_a_steady_force_is_no_stop() {
        // 20 s at rest; a 10 deg/s turn; 1.5 s of a gentle 0.25 deg/s turn at a steady force
        // (a car at constant speed on a bend: the accelerometer is quiet); the 10 deg/s turn
        // again. The accelerometer's quiet lets the detector judge the samples since it
        // began, where the mean bound (0.32 deg/s on 25 samples) is twice the full window's:
        // such a stop must pass the full window's test, without the hysteresis, before it
        // counts, and then nothing of the turn may reach the estimate, as with the gyro alone.
        let t = terms();
        let sd = (t.n * t.n * 100.0).sqrt();
        let (rest, turn, gentle) = (2000, 500, 150);
        let lull = rest + turn..rest + turn + gentle;
        for seed in 0..20 {
            let mut x = noisy(0.4, sd, rest + turn + gentle + turn, 21 + seed);
            for (k, v) in x.iter_mut().enumerate().skip(rest) {
                *v += if lull.contains(&k) { 0.25 } else { 10.0 };
            }
            let rests = [(0, rest), (lull.start, lull.end)];
            let cfg = TrackerConfig::default();
            let mut aided = BiasTracker::new(&t, 100.0, &cfg).unwrap();
            let mut alone = BiasTracker::new(&t, 100.0, &cfg).unwrap();
            let mut before = f64::NAN;
            for (k, &v) in x.iter().enumerate() {
                let s = aided.push_with(v, accel_aid(&rests, k));
                alone.push(v);
                if k == lull.start - 1 {
                    before = s.bias;
                }
            }
            // 0.01 deg/s: a 25th of the turn's rate, several times the walk over 7 s.
            for (name, tr) in [("gyro alone", &alone), ("gyro+accel", &aided)] {
                let after = tr.filter().estimate();
                assert!(
                    (after - before).abs() < 0.01,
                    "seed {seed}, {name}: the gentle turn moved the estimate from {before} to {after}"
                );
            }
        }
    }

    #[test]
    fn a_false_start_up_rest_does_not_become_the_reference() {
        // At power-up the body turns slowly (0.5 deg/s, within the turn-on bias's spread) with
        // the accelerometer quiet for 0.4 s: a start-up rest, confirmed, then cut short by motion
        // before any of it reached the filter. Then 20 s of true rest at the bias (0.4 deg/s):
        // the tracker must find it, though the false rest's mean (0.9) is far from it.
        let t = terms();
        let sd = (t.n * t.n * 100.0).sqrt();
        let (false_rest, turn, rest) = (40, 300, 2000);
        let mut x = noisy(0.4, sd, false_rest + turn + rest, 5);
        for (k, v) in x.iter_mut().enumerate() {
            if k < false_rest {
                *v += 0.5;
            } else if k < false_rest + turn {
                *v += 10.0 * (std::f64::consts::PI * k as f64 / 100.0).sin();
            }
        }
        let rests = [(0, false_rest), (false_rest + turn, x.len())];
        let mut tr = BiasTracker::new(&t, 100.0, &TrackerConfig::default()).unwrap();
        let steps: Vec<BiasStep> = x
            .iter()
            .enumerate()
            .map(|(k, &v)| tr.push_with(v, accel_aid(&rests, k)))
            .collect();
        assert!(
            steps[..false_rest]
                .iter()
                .any(|s| s.mode == BiasMode::Still),
            "the false rest was confirmed: the case this test is about"
        );
        assert_eq!(steps[false_rest + turn - 1].mode, BiasMode::Moving);
        let last = steps.last().unwrap();
        assert_eq!(last.mode, BiasMode::Still);
        assert!(
            (last.bias - 0.4).abs() < 4.0 * t.n / 10f64.sqrt(),
            "{last:?}"
        );
    }

    #[test]
    fn quantisation_noise_does_not_hide_a_turn() {
        // The ADXRS450's Q at 100 Hz: about 13 deg/s per sample, but its 1 s window mean
        // telescopes to 0.13 deg/s; the mean test must stay near that, not 13/sqrt(100).
        let t = BiasTerms::profile("adxrs450").unwrap();
        let c = stillness_from_terms(&t, 100.0, &TrackerConfig::default()).unwrap();
        assert!(c.mean_enter < 1.0, "{c:?}");
        assert!(c.mean_exit > 0.3, "{c:?}");
    }
}
