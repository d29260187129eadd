//! [`BiasTracker`]: what decides which samples the filter sees (stillness from the terms,
//! the delay window, the recovered ends of a stop) and what the stage outputs meanwhile.

use super::*;
use crate::drift::accel_rest::AccelRestConfig;
pub use crate::drift::stillness::Aid;
use crate::drift::stillness::{moving_llr, Growth, StillnessConfig, StillnessDetector};

/// Settings of the stillness gating and delay of a [`BiasTracker`], in seconds and in standard
/// deviations of the still statistics (thresholds from the noise terms, see
/// [`stillness_from_terms`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerConfig {
    /// Detector window, s.
    pub window_s: f64,
    /// Quiet time after the window before "still", s.
    pub settle_s: f64,
    /// Delay window: a still sample enters the filter only after the detector stayed still this
    /// long after it, s.
    pub delay_s: f64,
    /// When the detector turns still, this much of its window before the current sample (at
    /// most the window) joins the stop, s: the window's test has just judged those samples
    /// still, so a stop is measured from (nearly) its start, not from when it was confirmed.
    pub backfill_s: f64,
    /// When a movement is detected, the waiting samples older than its estimated onset by more
    /// than this still enter the filter, s (at least the delay: all are dropped, as before
    /// onset estimation).
    pub onset_guard_s: f64,
    /// A stop confirmed for less than this is dropped whole when a movement is detected, s
    /// (no onset estimation: a short "stop" within a movement is likely a lull in it).
    pub min_stop_s: f64,
    /// Variance exit threshold: standard deviations of the window variance above its still value.
    pub var_sigmas: f64,
    /// Mean-shift exit threshold: standard deviations of the window mean.
    pub mean_sigmas: f64,
    /// The enter (back to moving) thresholds are this many times the exit distances (>= 1).
    pub hysteresis: f64,
    /// The mean-shift test tolerates this many standard deviations of the bias estimate.
    pub estimate_sigmas: f64,
    /// How bias instability becomes states (None: [`Instability::from_terms`]).
    pub instability: Option<Instability>,
    /// From which stops the random walk is learnt ([`WalkLearner`]); only the one-state
    /// random-walk model learns, other models keep their terms.
    pub learn_walk: LearnWalk,
    /// Bounds of the learnt walk, (deg/s)^2/s (None: [`default_walk_bounds`]).
    pub walk_range: Option<(f64, f64)>,
}

/// From which stops a [`BiasTracker`] learns its random walk.
///
/// Measured on heading (docs/navigation.md, "Learning the walk"): with the true stops learning
/// lowers the error (real log 0.97x to 0.96x oracle ZARU at the median, worst 4.27x to 3.72x;
/// simulator 1.28 to 1.25 deg); with the stops our own detector finds it does not (1.04x to
/// 1.10x on the real log). So by default only stops given from outside teach it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LearnWalk {
    /// Keep the configured walk.
    Off,
    /// Learn from stops given from outside ([`BiasTracker::push_gated`]): a vehicle's stop
    /// signal, the truth of a benchmark. Stops the tracker's own detector finds are not used.
    GivenStops,
    /// Learn from every stop, detected ones too.
    Always,
    /// Learn from stops given from outside and from stops both sensors confirm: the
    /// accelerometer quiet throughout ([`Aid::Quiet`]). Without an accelerometer, the same as
    /// [`LearnWalk::GivenStops`].
    ConfirmedStops,
}

impl LearnWalk {
    /// Its name in a `predict.bias` table (`learn_walk`).
    pub const fn name(self) -> &'static str {
        match self {
            LearnWalk::Off => "off",
            LearnWalk::GivenStops => "given-stops",
            LearnWalk::Always => "always",
            LearnWalk::ConfirmedStops => "confirmed-stops",
        }
    }
}

/// The walk the default model stands in for matches the flicker floor at
/// [`DEFAULT_MATCH_S`]; the time between stops it carries a bias across spans
/// [`WALK_SHORTEST_S`] to [`WALK_LONGEST_S`]. Matched at those instead, the walk is 10 times
/// larger or 100 times smaller: the bounds of what is learnt, unless Allan intervals give them.
pub const WALK_SHORTEST_S: f64 = 1.0;
/// See [`WALK_SHORTEST_S`].
pub const WALK_LONGEST_S: f64 = 1000.0;

/// Bounds of the walk learnt around `configured` ((deg/s)^2/s) when no Allan intervals give
/// them: the flicker floor matched at [`WALK_SHORTEST_S`] and at [`WALK_LONGEST_S`] instead of
/// [`DEFAULT_MATCH_S`].
pub fn default_walk_bounds(configured: f64) -> (f64, f64) {
    (
        configured * DEFAULT_MATCH_S / WALK_LONGEST_S,
        configured * DEFAULT_MATCH_S / WALK_SHORTEST_S,
    )
}

impl TrackerConfig {
    /// The default delay window, s (`predict.bias`'s `delay_s`).
    pub const DEFAULT_DELAY_S: f64 = 1.0;
    /// The default of what the walk is learnt from (`predict.bias`'s `learn_walk`).
    pub const DEFAULT_LEARN_WALK: LearnWalk = LearnWalk::GivenStops;
}

impl Default for TrackerConfig {
    /// Window 1 s, settle 0.25 s, delay 1 s, onset guard 0.5 s, shortest stop 0.5 s, backfill
    /// 0.5 s, variance 4 sd, mean 4 sd, hysteresis 1.5, estimate 3 sd, the default instability
    /// ([`Instability::from_terms`]). Measured on heading (docs/navigation.md): the backfill
    /// and the onset estimate let a stop be used from its start to its end.
    fn default() -> Self {
        TrackerConfig {
            window_s: 1.0,
            settle_s: 0.25,
            delay_s: Self::DEFAULT_DELAY_S,
            onset_guard_s: 0.5,
            min_stop_s: 0.5,
            backfill_s: 0.5,
            var_sigmas: 4.0,
            mean_sigmas: 4.0,
            hysteresis: 1.5,
            estimate_sigmas: 3.0,
            instability: None,
            learn_walk: Self::DEFAULT_LEARN_WALK,
            walk_range: None,
        }
    }
}

fn samples(name: &'static str, s: f64, rate_hz: f64) -> Result<usize, BiasError> {
    if !(s.is_finite() && s >= 0.0) {
        return Err(BiasError::BadTime(name, s));
    }
    let n = (s * rate_hz).round();
    if n > MAX_DELAY as f64 {
        return Err(BiasError::DelayTooLong(n as usize));
    }
    Ok(n as usize)
}

/// Stillness thresholds from noise terms: over a window of w samples a still sensor's variance
/// is sigma^2 = [`BiasTerms::sample_variance`] with relative spread sqrt(2/w), and its mean is
/// the bias with spread sqrt(N^2/T + 2 Q^2/T^2 + rest/w), T = w/rate, where rest is sigma^2
/// less its white and quantisation parts. Quantisation noise is a differenced white angle: its
/// window mean telescopes to two samples' worth, so it must not widen the mean test as white
/// noise of the same per-sample variance would (on a sensor with a large Q, such as the
/// ADXRS450's, that hid 10 deg/s turns). Exit thresholds sit
/// `var_sigmas` and `mean_sigmas` of those spreads above; the enter thresholds `hysteresis`
/// times as far.
pub fn stillness_from_terms(
    terms: &BiasTerms,
    rate_hz: f64,
    cfg: &TrackerConfig,
) -> Result<StillnessConfig, BiasError> {
    terms.check()?;
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(BiasError::BadRate(rate_hz));
    }
    for (name, v) in [
        ("var_sigmas", cfg.var_sigmas),
        ("mean_sigmas", cfg.mean_sigmas),
        ("hysteresis", cfg.hysteresis),
        ("estimate_sigmas", cfg.estimate_sigmas),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(BiasError::BadFactor(name, v));
        }
    }
    if cfg.hysteresis < 1.0 {
        return Err(BiasError::BadFactor("hysteresis (>= 1)", cfg.hysteresis));
    }
    let window = samples("window_s", cfg.window_s, rate_hz)?.max(2);
    let settle = samples("settle_s", cfg.settle_s, rate_hz)?;
    let w = window as f64;
    let var = terms.sample_variance(rate_hz);
    let spread = (2.0 / w).sqrt();
    let white = terms.n * terms.n * rate_hz;
    let quant = 2.0 * terms.q * terms.q * rate_hz * rate_hz;
    let t = w / rate_hz;
    let mean_sd = (terms.n * terms.n / t
        + 2.0 * terms.q * terms.q / (t * t)
        + (var - white - quant).max(0.0) / w)
        .sqrt();
    let c = StillnessConfig {
        window,
        var_exit: var * (1.0 + cfg.var_sigmas * spread),
        var_enter: var * (1.0 + cfg.hysteresis * cfg.var_sigmas * spread),
        mean_exit: cfg.mean_sigmas * mean_sd,
        mean_enter: cfg.hysteresis * cfg.mean_sigmas * mean_sd,
        settle,
    };
    c.check().map_err(BiasError::Stillness)?;
    Ok(c)
}

/// The thresholds of [`stillness_from_terms`] for a window of fewer samples ([`Growth`]): the
/// same still variance, mean spread and factors, with the window's length left open.
pub fn growth_from_terms(terms: &BiasTerms, rate_hz: f64, cfg: &TrackerConfig) -> Growth {
    let var = terms.sample_variance(rate_hz);
    let white = terms.n * terms.n * rate_hz;
    let quant = 2.0 * terms.q * terms.q * rate_hz * rate_hz;
    Growth {
        var,
        mean_white: white + (var - white - quant).max(0.0),
        mean_pair: quant,
        var_sigmas: cfg.var_sigmas,
        mean_sigmas: cfg.mean_sigmas,
        hysteresis: cfg.hysteresis,
    }
}

/// The accelerometer's rest test ([`AccelRestConfig`]) for `accel`'s terms at `rate_hz`, on
/// the gyro's time scales and tails: its window (`window_s`) and settling (`settle_s`), the
/// tail of `mean_sigmas` standard deviations, `hysteresis` times as far once quiet.
pub fn accel_rest_from_terms(
    accel: &AccelTerms,
    rate_hz: f64,
    cfg: &TrackerConfig,
) -> Result<AccelRestConfig, BiasError> {
    accel.check()?;
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(BiasError::BadRate(rate_hz));
    }
    let window = samples("window_s", cfg.window_s, rate_hz)?.max(2);
    let settle = samples("settle_s", cfg.settle_s, rate_hz)?.max(1);
    AccelRestConfig::from_terms(
        accel.vrw,
        accel.b,
        rate_hz,
        window,
        settle,
        cfg.mean_sigmas,
        cfg.hysteresis,
    )
    .map_err(BiasError::Stillness)
}

/// How a stop ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum End {
    /// The gyro's detector saw it: estimate the onset among the waiting samples.
    Estimate,
    /// Another sensor saw it begin this many samples ago.
    Since(usize),
}

/// What the tracker knows at a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BiasMode {
    /// The detector's first window is not full: still or moving cannot be told yet.
    Warming,
    /// Still (confirmed by the detector, or by the gate).
    Still,
    /// Moving: the estimate is held, its variance grows.
    Moving,
}

/// One sample's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasStep {
    /// Bias estimate, deg/s (subtract it from the rate).
    pub bias: f64,
    /// Its standard deviation, deg/s.
    pub std: f64,
    /// The mode.
    pub mode: BiasMode,
    /// Whether the estimate rests on a still sample (taken by the filter or waiting in the
    /// delay window); false: it is the prior.
    pub informed: bool,
    /// A stop signal said "stands" while the gyro clearly turned: not trusted
    /// ([`BiasTracker::push_signal`]).
    pub contradicted: bool,
}

/// How many of `samples`, counted from the first, form the run most likely moving (the largest
/// [`moving_llr`] of their residuals from `bias`, times `inv_sd`), if that ratio exceeds
/// `floor`.
fn likeliest_moving_run(
    samples: impl Iterator<Item = f64>,
    bias: f64,
    inv_sd: f64,
    floor: f64,
) -> Option<usize> {
    let (mut n, mut sum, mut sum2) = (0.0f64, 0.0f64, 0.0f64);
    let (mut best, mut len) = (floor, None);
    for (i, x) in samples.enumerate() {
        let z = (x - bias) * inv_sd;
        n += 1.0;
        sum += z;
        sum2 += z * z;
        let llr = moving_llr(n, sum, sum2);
        if llr > best {
            best = llr;
            len = Some(i + 1);
        }
    }
    len
}

/// Below this [`moving_llr`], a stop's confirming window holds no movement worth cutting off:
/// the largest of ~100 prefix ratios of still noise stays below it but for about one in 10^3.
const MOVING_EVIDENCE: f64 = 8.0;

/// Still samples waiting until the sensor has stayed still for the window's length after them
/// (see the module documentation): a fixed ring and its running sum.
#[derive(Debug, Clone)]
pub(super) struct DelayWindow {
    ring: Vec<f64>,
    head: usize,
    pub(super) pending: usize,
    sum: f64,
}

impl DelayWindow {
    fn new(len: usize) -> Self {
        DelayWindow {
            ring: vec![0.0; len],
            head: 0,
            pending: 0,
            sum: 0.0,
        }
    }

    /// A still sample in; the oldest waiting one, if the window is full, into `filter`. A
    /// non-finite sample is skipped.
    fn push(&mut self, x: f64, filter: &mut BiasFilter) {
        if !x.is_finite() {
            return;
        }
        let d = self.ring.len();
        if d == 0 {
            filter.update(x);
            return;
        }
        if self.pending == d {
            let old = self.ring[self.head];
            filter.update(old);
            self.sum -= old;
        } else {
            self.pending += 1;
        }
        self.ring[self.head] = x;
        self.head = if self.head + 1 == d { 0 } else { self.head + 1 };
        self.sum += x;
    }

    /// A movement was detected at `moving` (not waiting): find where it began among the
    /// waiting samples, put those older than its onset by more than `guard` samples into
    /// `filter`, and drop the rest. The onset is the start of the most likely moving suffix
    /// (`moving` included) under [`moving_llr`] against "still around `bias` with per-sample
    /// variance `var`". O(waiting) once per movement, no allocation.
    fn release_before_onset(
        &mut self,
        moving: f64,
        bias: f64,
        var: f64,
        guard: usize,
        filter: &mut BiasFilter,
    ) {
        let d = self.ring.len();
        if self.pending > 0 && var > 0.0 && moving.is_finite() && bias.is_finite() {
            let inv_sd = 1.0 / var.sqrt();
            let newest = (self.head + d - 1) % d;
            let ring = &self.ring;
            let waiting = (1..=self.pending).map(|age| ring[(newest + d - (age - 1)) % d]);
            let best_len = likeliest_moving_run(
                std::iter::once(moving).chain(waiting),
                bias,
                inv_sd,
                f64::NEG_INFINITY,
            )
            .unwrap_or(0);
            let keep = self
                .pending
                .saturating_sub((best_len + guard).saturating_sub(1));
            let oldest = (self.head + d - self.pending) % d;
            for i in 0..keep {
                filter.update(self.ring[(oldest + i) % d]);
            }
        }
        self.clear();
    }

    /// Put every waiting sample but the newest `newest` into `filter`, oldest first; drop the
    /// rest.
    fn release_older_than(&mut self, newest: usize, filter: &mut BiasFilter) {
        let d = self.ring.len();
        let oldest = (self.head + d - self.pending) % d.max(1);
        for i in 0..self.pending.saturating_sub(newest) {
            filter.update(self.ring[(oldest + i) % d]);
        }
        self.clear();
    }

    /// Put every waiting sample into `filter`, oldest first.
    fn release_all(&mut self, filter: &mut BiasFilter) {
        let d = self.ring.len();
        let oldest = (self.head + d - self.pending) % d.max(1);
        for i in 0..self.pending {
            filter.update(self.ring[(oldest + i) % d]);
        }
        self.clear();
    }

    /// Drop every waiting sample.
    fn clear(&mut self) {
        self.head = 0;
        self.pending = 0;
        self.sum = 0.0;
    }

    /// The mean and count of the waiting samples.
    fn mean(&self) -> Option<(f64, usize)> {
        (self.pending > 0).then(|| (self.sum / self.pending as f64, self.pending))
    }
}

/// The live bias estimator of one axis: a [`BiasFilter`], its own [`StillnessDetector`], and the
/// delay window (see the module documentation).
#[derive(Debug, Clone)]
pub struct BiasTracker {
    filter: BiasFilter,
    detector: StillnessDetector,
    estimate_sigmas: f64,
    backfill: usize,
    guard: usize,
    still_var: f64,
    min_run: usize,
    run: usize,
    /// Samples of the current stop that the detector judged on its full window (or given from
    /// outside, or of a rest since power-up): what `min_run` counts. A stop confirmed on a
    /// window cut back to the accelerometer's rest has had less power against a slow turn.
    full_run: usize,
    /// The current stop began at start-up.
    stop_at_startup: bool,
    pub(super) delay: DelayWindow,
    mode: BiasMode,
    learn: LearnWalk,
    /// Whether a still sample of the current stop came from the tracker's own detector (such a
    /// stop does not teach the walk under [`LearnWalk::GivenStops`]).
    stop_detected: bool,
    /// Whether a still sample of the current stop was judged by the gyro alone (no stop signal,
    /// no quiet accelerometer).
    stop_gyro_only: bool,
    /// The newest samples, for the check of a stop signal against the gyro.
    recent: RecentMean,
    /// Start-up: from the first sample until the detector's first verdict, the body is taken
    /// to stand (it does at power-up) while no test says otherwise.
    startup: bool,
}

/// A stop signal is not trusted while the mean of the last [`CHECK_S`] of rate lies more than
/// [`CHECK_SIGMAS`] of its still spread (plus the estimate's `estimate_sigmas`) from the bias
/// estimate: the gyro clearly turns.
pub const CHECK_S: f64 = 0.1;
/// See [`CHECK_S`].
pub const CHECK_SIGMAS: f64 = 6.0;

/// The mean of the last `len` samples: a fixed ring and its sum.
#[derive(Debug, Clone)]
struct RecentMean {
    ring: Vec<f64>,
    head: usize,
    filled: usize,
    sum: f64,
}

impl RecentMean {
    fn new(len: usize) -> Self {
        RecentMean {
            ring: vec![0.0; len.max(1)],
            head: 0,
            filled: 0,
            sum: 0.0,
        }
    }

    fn push(&mut self, x: f64) {
        if !x.is_finite() {
            return;
        }
        let len = self.ring.len();
        if self.filled == len {
            self.sum -= self.ring[self.head];
        } else {
            self.filled += 1;
        }
        self.ring[self.head] = x;
        self.head = (self.head + 1) % len;
        self.sum += x;
    }

    fn mean(&self) -> Option<f64> {
        (self.filled > 0).then(|| self.sum / self.filled as f64)
    }

    fn clear(&mut self) {
        self.head = 0;
        self.filled = 0;
        self.sum = 0.0;
    }
}

impl BiasTracker {
    /// A tracker for `terms` at `rate_hz` (model from `cfg.instability`, thresholds from
    /// [`stillness_from_terms`]).
    pub fn new(terms: &BiasTerms, rate_hz: f64, cfg: &TrackerConfig) -> Result<Self, BiasError> {
        let instability = cfg
            .instability
            .unwrap_or_else(|| Instability::from_terms(terms));
        let model = BiasModel::new(terms, rate_hz, instability)?;
        let configured = model.walk_per_s(rate_hz);
        let mut tracker = Self::with_model(model.clone(), terms, rate_hz, cfg)?;
        if cfg.learn_walk != LearnWalk::Off && model.states() == 1 && configured > 0.0 {
            let (lo, hi) = cfg
                .walk_range
                .unwrap_or_else(|| default_walk_bounds(configured));
            let walk = WalkConfig {
                configured: configured.clamp(lo, hi),
                lo,
                hi,
            };
            tracker.filter = BiasFilter::learning(model, walk, 1.0 / rate_hz)?;
        }
        Ok(tracker)
    }

    /// A tracker around any bias model (e.g. [`BiasModel::simulator_truth`]); the detector's
    /// thresholds still come from `terms`.
    pub fn with_model(
        model: BiasModel,
        terms: &BiasTerms,
        rate_hz: f64,
        cfg: &TrackerConfig,
    ) -> Result<Self, BiasError> {
        let still = stillness_from_terms(terms, rate_hz, cfg)?;
        let delay = samples("delay_s", cfg.delay_s, rate_hz)?;
        let backfill = samples("backfill_s", cfg.backfill_s, rate_hz)?.min(still.window);
        Ok(BiasTracker {
            filter: BiasFilter::new(model),
            detector: StillnessDetector::new(still)
                .with_growth(growth_from_terms(terms, rate_hz, cfg)),
            estimate_sigmas: cfg.estimate_sigmas,
            backfill,
            guard: samples("onset_guard_s", cfg.onset_guard_s, rate_hz)?,
            still_var: terms.sample_variance(rate_hz),
            min_run: samples("min_stop_s", cfg.min_stop_s, rate_hz)?,
            run: 0,
            full_run: 0,
            stop_at_startup: false,
            // Backfilled samples wait their `delay` like the rest: room for both.
            delay: DelayWindow::new(delay + backfill),
            mode: BiasMode::Warming,
            learn: cfg.learn_walk,
            stop_detected: false,
            stop_gyro_only: false,
            recent: RecentMean::new(samples("check", CHECK_S, rate_hz)?),
            startup: true,
        })
    }

    /// The default tracker of a named sensor ([`BiasTerms::profile`], [`TrackerConfig::default`]).
    pub fn for_profile(name: &str, rate_hz: f64) -> Result<Self, BiasError> {
        Self::new(
            &BiasTerms::profile(name)?,
            rate_hz,
            &TrackerConfig::default(),
        )
    }

    /// The filter.
    pub fn filter(&self) -> &BiasFilter {
        &self.filter
    }

    /// The detector's thresholds.
    pub fn stillness(&self) -> &StillnessConfig {
        self.detector.config()
    }

    /// The delay window, samples.
    pub fn delay(&self) -> usize {
        self.delay.ring.len() - self.backfill
    }

    /// Whether the last sample was judged still.
    pub fn is_still(&self) -> bool {
        self.mode == BiasMode::Still
    }

    /// The filter's state, to carry into a later run ([`BiasTracker::resume`]). The samples
    /// still waiting in the delay window are not in it: a stop cut short by a stop of the
    /// daemon loses at most its last `delay_s`.
    pub fn snapshot(&self) -> FilterSnapshot {
        self.filter.snapshot()
    }

    /// Start from `snap`, taken `steps` samples ago ([`BiasFilter::resume`]): corrected from
    /// the first sample, with the estimate's variance grown over the gap.
    pub fn resume(&mut self, snap: &FilterSnapshot, steps: u64) -> Result<(), BiasError> {
        self.filter.resume(snap, steps)
    }

    /// Forget everything (back to warming at the prior).
    pub fn reset(&mut self) {
        self.filter.reset();
        self.detector.reset();
        self.delay.clear();
        self.run = 0;
        self.full_run = 0;
        self.stop_at_startup = false;
        self.mode = BiasMode::Warming;
        self.stop_detected = false;
        self.stop_gyro_only = false;
        self.recent.clear();
        self.startup = true;
    }

    /// One rate sample (deg/s) with the tracker's own stillness detection.
    pub fn push(&mut self, x: f64) -> BiasStep {
        self.push_with(x, Aid::Unknown)
    }

    /// One rate sample (deg/s) with the tracker's own stillness detection, aided by another
    /// sensor's verdict on the whole body ([`Aid`]): its "moving" vetoes stillness and says
    /// where the motion began; its "quiet since" lets the detector judge only the samples since
    /// the body came to rest, so a stop is confirmed (and measured) from its start.
    pub fn push_with(&mut self, x: f64, aid: Aid) -> BiasStep {
        if let Aid::Quiet { since } = aid {
            if self.run == 0 {
                // The window holds the samples before this one: `since - 1` of them are the rest's.
                self.detector.restart(since.saturating_sub(1));
            }
        }
        let (gyro, turned) = self.detect(x);
        let vetoed = matches!(aid, Aid::Moving { .. });
        let still = gyro && !vetoed;
        if still && self.run == 0 && self.backfill > 0 {
            match aid {
                // The gyro's stop begins now, or the accelerometer's quiet lets it resume: the
                // samples since the rest began (as the accelerometer dates it) join it.
                Aid::Quiet { since } => self.backfill_stop(since.saturating_sub(1)),
                Aid::Unknown if turned => self.backfill_stop(usize::MAX),
                _ => {}
            }
        }
        let end = match aid {
            Aid::Moving { age } => End::Since(age),
            _ => End::Estimate,
        };
        self.own_step(x, still, vetoed, matches!(aid, Aid::Quiet { .. }), end)
    }

    /// Whether the gyro alone (this axis's detector on its full window) says still, whatever
    /// another sensor says.
    pub fn gyro_still(&self) -> bool {
        self.detector.is_still() && self.detector.is_ready()
    }

    /// The step of our own detector's verdict `still` on `x` (`vetoed`: another sensor says
    /// moving). At start-up a quiet sample counts as still (provisional, flagged warming) until
    /// the detector confirms or a test fails.
    fn own_step(&mut self, x: f64, still: bool, vetoed: bool, sure: bool, end: End) -> BiasStep {
        // At start-up a stop is confirmed on a window shorter than the detector's only when a
        // second sensor is quiet too; the gyro alone waits for its full window, as it always has.
        let confirmed = still && (!self.startup || sure || self.detector.is_ready());
        let provisional =
            self.startup && !confirmed && !vetoed && x.is_finite() && self.detector.is_quiet();
        if self.run == 0 {
            self.stop_at_startup = self.startup;
        }
        if self.startup && !provisional {
            self.startup = false;
        }
        let mode = if provisional {
            BiasMode::Warming
        } else if confirmed {
            BiasMode::Still
        } else if self.detector.is_ready() || !self.startup {
            BiasMode::Moving
        } else {
            BiasMode::Warming
        };
        self.step_end(x, confirmed || provisional, mode, false, sure, end)
    }

    /// Our detector's verdict on `x`, and whether it has just turned still.
    fn detect(&mut self, x: f64) -> (bool, bool) {
        // The filter's estimate is the reference once it has measured the bias; before, a
        // stop's own mean (the detector's anchor) is a closer one than the prior. With
        // neither, the prior: a turn far beyond the turn-on bias's spread (`initial_sd`) is no
        // rest, at power-up or after a stop that proved a lull.
        let (reference, tol) = if self.filter.updates() > 0 || !self.detector.has_anchor() {
            (
                self.filter.estimate(),
                self.estimate_sigmas * self.filter.variance().sqrt(),
            )
        } else {
            (f64::NAN, 0.0)
        };
        let was_still = self.detector.is_still();
        let still = x.is_finite() && self.detector.update_with_tolerance(x, reference, tol);
        (still, still && !was_still)
    }

    /// The stop began before the detector confirmed it: the last `backfill` samples of its
    /// window before this one (at most `limit`: the accelerometer's rest may be younger) join
    /// it (the filter's time update already ran for them), all but those up to `guard` after
    /// the end of a movement still in the window. That end is the
    /// end of the most likely moving prefix under [`moving_llr`] against the mean of the
    /// window's newest half, if that prefix is evidence of movement at all
    /// ([`MOVING_EVIDENCE`]). O(window) once per stop, no allocation.
    fn backfill_stop(&mut self, limit: usize) {
        let w = self.detector.filled();
        if w < 2 {
            return;
        }
        let half = (w / 2).max(1);
        let bias = self.detector.window().skip(w - half).sum::<f64>() / half as f64;
        let inv_sd = 1.0 / self.still_var.sqrt();
        let first = likeliest_moving_run(
            self.detector.window().take(w - 1),
            bias,
            inv_sd,
            MOVING_EVIDENCE,
        )
        .map_or(0, |len| len + self.guard);
        let first = first.max((w - 1).saturating_sub(self.backfill.min(limit)));
        for v in self
            .detector
            .window()
            .skip(first)
            .take((w - 1).saturating_sub(first))
        {
            self.delay.push(v, &mut self.filter);
        }
    }

    /// One rate sample with stillness decided outside (a known stop, another sensor): the same
    /// filter and delay window, the tracker's detector unused.
    pub fn push_gated(&mut self, x: f64, still: bool) -> BiasStep {
        self.step(x, still, true, true)
    }

    /// One rate sample with a stop signal from outside (a vehicle's own sensors), `None`
    /// when it is unknown or stale. Our detector runs on every sample: it decides while the
    /// signal is unknown, and a signal of "stands" while the gyro clearly turns (the mean of
    /// the last `CHECK_S` beyond `CHECK_SIGMAS` from the estimate) is not trusted: the
    /// sample counts as moving and [`BiasStep::contradicted`] says so. "Moves" is trusted.
    pub fn push_signal(&mut self, x: f64, stopped: Option<bool>) -> BiasStep {
        self.push_signal_with(x, stopped, Aid::Unknown)
    }

    /// [`push_signal`](Self::push_signal) with another sensor's verdict, which aids our
    /// detector while the signal is unknown ([`push_with`](Self::push_with)).
    pub fn push_signal_with(&mut self, x: f64, stopped: Option<bool>, aid: Aid) -> BiasStep {
        self.recent.push(x);
        let Some(stands) = stopped else {
            return self.push_with(x, aid);
        };
        // The signal decides from its first word: no start-up guess.
        self.startup = false;
        self.detect(x);
        if !stands {
            return self.step(x, false, true, true);
        }
        let (estimate, var) = self.output();
        let spread = (self.still_var / self.recent.filled.max(1) as f64).sqrt();
        let limit = CHECK_SIGMAS * spread + self.estimate_sigmas * var.sqrt();
        let turning = self
            .recent
            .mean()
            .is_some_and(|m| (m - estimate).abs() > limit);
        // A contradicted sample's verdict is ours, not the signal's.
        let mut step = self.step(x, !turning, true, !turning);
        step.contradicted = turning;
        step
    }

    /// Add the odometry's scale to the filter's states ([`BiasFilter::add_scale`]; `scale`:
    /// its prior sd and its walk per sample, [`super::OdometryAid::scale_prior`]); once.
    pub fn add_scale(&mut self, scale: (f64, f64)) {
        self.filter.add_scale(scale.0, scale.1);
    }

    /// An odometry span while the body moves ([`super::OdometryAid`]): y = mean gyro - mean
    /// odometry = b + s w of variance r, w the odometry's mean rate
    /// ([`BiasFilter::update_scaled`]; the scale a state once [`Self::add_scale`] added it),
    /// taken only between stops: during a stop the same gyro samples already measure the
    /// bias, and taking them twice would count their noise twice. Returns whether it was taken.
    pub fn update_in_motion(&mut self, m: Measurement) -> bool {
        if self.mode == BiasMode::Still || self.delay.pending > 0 {
            return false;
        }
        let Measurement { y, w, r } = m;
        self.filter.update_scaled(y, w, r).is_finite()
    }

    /// The estimate and its variance as output now: the filter's, with the waiting samples'
    /// mean as a provisional measurement.
    fn output(&self) -> (f64, f64) {
        match self.delay.mean() {
            Some((mean, count)) => self.filter.with_mean(mean, count),
            None => (self.filter.estimate(), self.filter.variance()),
        }
    }

    /// `known`: whether "not still" means moving (false while the detector's window fills);
    /// `given`: whether stillness came from outside.
    fn step(&mut self, x: f64, still: bool, known: bool, given: bool) -> BiasStep {
        let mode = if still && x.is_finite() {
            BiasMode::Still
        } else if known {
            BiasMode::Moving
        } else {
            BiasMode::Warming
        };
        self.step_end(x, still, mode, given, given, End::Estimate)
    }

    /// `still`: the sample measures the bias (it waits, then enters the filter); `mode`: what
    /// the step says; `given`: stillness came from outside; `sure`: from outside or confirmed
    /// by a second sensor; `end`: how a stop that ends here is cut.
    fn step_end(
        &mut self,
        x: f64,
        still: bool,
        mode: BiasMode,
        given: bool,
        sure: bool,
        end: End,
    ) -> BiasStep {
        self.filter.predict();
        let still = still && x.is_finite();
        if still {
            self.delay.push(x, &mut self.filter);
            self.run += 1;
            let full = self.detector.is_ready() && !self.detector.is_provisional();
            self.full_run += usize::from(given || self.stop_at_startup || full);
            self.stop_detected |= !given;
            self.stop_gyro_only |= !sure;
        } else {
            match self.delay.mean() {
                // A stop confirmed for less than `min_run` is more likely a lull within a
                // movement (a zero-mean oscillation whose window mean passed) than a stop.
                // A stop given from outside ends where it says: every waiting sample is
                // still (our detector sees an end late, so its onset is estimated).
                Some(_) if self.full_run >= self.min_run && given && !self.stop_detected => {
                    self.delay.release_all(&mut self.filter)
                }
                Some(_) if self.full_run >= self.min_run && matches!(end, End::Since(_)) => {
                    let End::Since(age) = end else { unreachable!() };
                    self.delay.release_older_than(age, &mut self.filter)
                }
                Some((mean, count)) if self.full_run >= self.min_run => {
                    let (bias, _) = self.filter.with_mean(mean, count);
                    self.delay.release_before_onset(
                        x,
                        bias,
                        self.still_var,
                        self.guard,
                        &mut self.filter,
                    );
                }
                _ => self.delay.clear(),
            }
            if self.run > 0 && self.filter.updates() == 0 {
                // Nothing of the stop measured the bias: its mean must not be the detector's
                // reference, or a rest elsewhere could never pass the mean test again.
                self.detector.forget_anchor();
            }
            if self.run > 0 {
                // A stop teaches the walk only if it came from where this tracker trusts.
                let teaches = match self.learn {
                    LearnWalk::Off => false,
                    LearnWalk::GivenStops => !self.stop_detected,
                    LearnWalk::Always => true,
                    LearnWalk::ConfirmedStops => !self.stop_gyro_only,
                };
                self.filter.end_stop(teaches);
            }
            self.run = 0;
            self.full_run = 0;
            self.stop_detected = false;
            self.stop_gyro_only = false;
        }
        let (bias, var) = self.output();
        self.mode = mode;
        BiasStep {
            bias,
            std: var.sqrt(),
            mode: self.mode,
            informed: self.delay.pending > 0 || self.filter.updates() > 0,
            contradicted: false,
        }
    }
}
