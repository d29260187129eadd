//! The Kalman filter on the bias: its model from the terms ([`BiasModel`]) and the filter
//! ([`BiasFilter`]): predict every sample, update on a still one.

use super::*;
use crate::sim::{SimConfig, GM_MAX, GM_MAX_TIME_CONSTANT};
use std::f64::consts::{LN_2, PI};

/// Time scale (s) at which the default random walk matches the flicker floor: the shortest gap
/// between stops worth carrying a bias across. Chosen on the simulator and on windows 0-3 of
/// the real log (10 s beat 1, 30 and 100 s there), then checked on held-out windows.
pub const DEFAULT_MATCH_S: f64 = 10.0;

/// A bias model: diagonal state transition, diagonal process noise, H = [1, ..., 1].
#[derive(Debug, Clone, PartialEq)]
pub struct BiasModel {
    states: usize,
    pub(super) phi: [f64; MAX_STATES],
    pub(super) q: [f64; MAX_STATES],
    pub(super) p0: [f64; MAX_STATES],
    r: f64,
}

impl BiasModel {
    /// The model of `terms` at `rate_hz` with bias instability as `instability`.
    pub fn new(
        terms: &BiasTerms,
        rate_hz: f64,
        instability: Instability,
    ) -> Result<Self, BiasError> {
        terms.check()?;
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(BiasError::BadRate(rate_hz));
        }
        let dt = 1.0 / rate_hz;
        let mut m = BiasModel {
            states: 1,
            phi: [0.0; MAX_STATES],
            q: [0.0; MAX_STATES],
            p0: [0.0; MAX_STATES],
            r: terms.n * terms.n * rate_hz + terms.lsb * terms.lsb / 12.0,
        };
        // State 0: turn-on bias plus rate random walk.
        m.phi[0] = 1.0;
        m.q[0] = terms.k * terms.k * dt;
        m.p0[0] = terms.initial_sd * terms.initial_sd;
        let s2 = terms.b * terms.b * LN_2 / PI;
        match instability {
            Instability::Flicker {
                shortest_s,
                longest_s,
            } => {
                for (name, v) in [("shortest_s", shortest_s), ("longest_s", longest_s)] {
                    if !(v.is_finite() && v > 0.0) {
                        return Err(BiasError::BadTime(name, v));
                    }
                }
                if terms.b > 0.0 {
                    let mut tc = shortest_s;
                    while tc <= longest_s * (1.0 + 1e-9) {
                        if m.states == MAX_STATES {
                            let octaves = (longest_s / shortest_s).log2().floor() as usize + 2;
                            return Err(BiasError::TooManyStates(octaves));
                        }
                        m.push_gm(tc, s2, dt);
                        tc *= 2.0;
                    }
                    // Octaves below the bank (down to the sample time) as white noise.
                    m.r += 2.0 * s2 * shortest_s.max(dt) * rate_hz;
                }
            }
            Instability::RandomWalk { tau_s } => {
                if !(tau_s.is_finite() && tau_s > 0.0) {
                    return Err(BiasError::BadTime("tau_s", tau_s));
                }
                m.q[0] += 3.0 * 2.0 * LN_2 / PI * terms.b * terms.b / tau_s * dt;
            }
            Instability::GaussMarkov { tau_s } => {
                if !(tau_s.is_finite() && tau_s > 0.0) {
                    return Err(BiasError::BadTime("tau_s", tau_s));
                }
                if terms.b > 0.0 {
                    let sd = terms.b / B_FLOOR;
                    m.push_gm(tau_s, sd * sd, dt);
                }
            }
        }
        if !(m.r.is_finite() && m.r > 0.0) {
            return Err(BiasError::NoMeasurementNoise);
        }
        Ok(m)
    }

    fn push_gm(&mut self, tau: f64, var: f64, dt: f64) {
        let phi = (-dt / tau).exp();
        let i = self.states;
        self.phi[i] = phi;
        self.q[i] = var * (1.0 - phi * phi);
        self.p0[i] = var;
        self.states += 1;
    }

    /// The simulator's true bias model ([`crate::sim`]): its exact Gauss-Markov bank for B (one
    /// state per octave from dt/2 to [`GM_MAX_TIME_CONSTANT`], started stationary), K as a random
    /// walk, white N and the LSB's rounding as measurement noise, and a turn-on bias of prior
    /// `initial_sd`. The filter of the physical floor: it knows every noise term. Exact for
    /// Q = 0 (the differenced quantisation noise is not modelled).
    pub fn simulator_truth(cfg: &SimConfig, initial_sd: f64) -> Result<Self, BiasError> {
        let t = cfg.terms;
        let terms = BiasTerms {
            n: t.n,
            b: t.b,
            k: t.k,
            q: t.q,
            lsb: cfg.lsb.unwrap_or(0.0),
            initial_sd,
        };
        terms.check()?;
        if !(cfg.rate_hz.is_finite() && cfg.rate_hz > 0.0) {
            return Err(BiasError::BadRate(cfg.rate_hz));
        }
        let dt = 1.0 / cfg.rate_hz;
        let mut m = BiasModel {
            states: 1,
            phi: [0.0; MAX_STATES],
            q: [0.0; MAX_STATES],
            p0: [0.0; MAX_STATES],
            r: terms.n * terms.n * cfg.rate_hz + terms.lsb * terms.lsb / 12.0,
        };
        m.phi[0] = 1.0;
        m.q[0] = terms.k * terms.k * dt;
        m.p0[0] = initial_sd * initial_sd;
        if t.b > 0.0 {
            let s2 = t.b * t.b * LN_2 / PI;
            let mut tc = 0.5 * dt;
            let mut count = 0;
            while count < GM_MAX && tc <= GM_MAX_TIME_CONSTANT {
                if m.states == MAX_STATES {
                    return Err(BiasError::TooManyStates(MAX_STATES + 1));
                }
                m.push_gm(tc, s2, dt);
                count += 1;
                tc *= 2.0;
            }
        }
        if !(m.r.is_finite() && m.r > 0.0) {
            return Err(BiasError::NoMeasurementNoise);
        }
        Ok(m)
    }

    /// The random walk of the turn-on state, (deg/s)^2 per second at `rate_hz`: the walk a
    /// [`WalkLearner`] starts from.
    pub fn walk_per_s(&self, rate_hz: f64) -> f64 {
        self.q[0] * rate_hz
    }

    /// Number of states.
    pub fn states(&self) -> usize {
        self.states
    }

    /// Measurement noise variance per sample, (deg/s)^2.
    pub fn measurement_variance(&self) -> f64 {
        self.r
    }

    /// Prior variance of the bias (the sum of the states), (deg/s)^2.
    pub fn prior_variance(&self) -> f64 {
        self.p0[..self.states].iter().sum()
    }
}

/// A [`BiasFilter`]'s state, to carry into a later run ([`BiasFilter::snapshot`],
/// [`BiasFilter::resume`]). Fixed arrays: taking one never allocates.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterSnapshot {
    /// States in use (the model's).
    pub states: usize,
    /// The state estimates, deg/s (the first `states`).
    pub x: [f64; MAX_STATES],
    /// Their covariance, (deg/s)^2 (the first `states` rows and columns).
    pub p: [[f64; MAX_STATES]; MAX_STATES],
    /// The walk learner's, if the filter learns its walk.
    pub learner: Option<LearnerSnapshot>,
    /// The odometry's scale and its variance, if the filter carries one ([`ScaleState`]).
    pub scale: Option<(f64, f64)>,
}

impl FilterSnapshot {
    /// The bias estimate (the sum of the states), deg/s.
    pub fn estimate(&self) -> f64 {
        self.x[..self.states].iter().sum()
    }

    /// Its variance, (deg/s)^2.
    pub fn variance(&self) -> f64 {
        let n = self.states;
        self.p[..n]
            .iter()
            .map(|row| row[..n].iter().sum::<f64>())
            .sum::<f64>()
            .max(0.0)
    }
}

/// The odometry's scale correction s as one more state of the filter ([`BiasFilter::add_scale`]):
/// a span of the odometry measures y = b + s w (w its mean yaw rate), a stop b alone. Kept
/// beside the bias's states, with its covariance with each of them: a stop that moves the bias
/// moves the scale learnt in the turns before it by as much as they were correlated, and a
/// turn's error of the scale is one error shared by every span, not white per span.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaleState {
    /// The estimate of s.
    pub s: f64,
    /// Its variance.
    pub var: f64,
    /// Its covariance with each bias state, deg/s.
    pub cov: [f64; MAX_STATES],
    /// Its random walk per sample (variance).
    walk: f64,
}

/// What the filter predicts of an odometry span of mean rate w, and how sure it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaledView {
    /// The bias estimate, deg/s.
    pub estimate: f64,
    /// Its variance, (deg/s)^2.
    pub variance: f64,
    /// The scale's estimate (0 without a scale state).
    pub scale: f64,
    /// Its variance (0 without a scale state).
    pub scale_var: f64,
    /// The covariance of the bias with the scale, deg/s.
    pub cov: f64,
}

impl ScaledView {
    /// The bias and scale's prediction of y = b + s w, and its variance.
    pub fn predict(&self, w: f64) -> (f64, f64) {
        (
            self.estimate + self.scale * w,
            (self.variance + 2.0 * w * self.cov + w * w * self.scale_var).max(0.0),
        )
    }

    /// The same view of a rate divided by `c` (the gyro axis reads `c` times the vehicle's
    /// yaw rate: its sign, or the up's component along it): the bias over `c`, its variance
    /// over `c^2`, its covariance with the scale over `c`; the scale is the same.
    pub fn over(self, c: f64) -> ScaledView {
        ScaledView {
            estimate: self.estimate / c,
            variance: self.variance / (c * c),
            cov: self.cov / c,
            ..self
        }
    }
}

/// The Kalman filter of a [`BiasModel`]: predict every sample, update with still samples.
#[derive(Debug, Clone)]
pub struct BiasFilter {
    model: BiasModel,
    learner: Option<WalkLearner>,
    dt: f64,
    x: [f64; MAX_STATES],
    p: Box<[[f64; MAX_STATES]; MAX_STATES]>,
    phi2: Box<[[f64; MAX_STATES]; MAX_STATES]>,
    updates: u64,
    scale: Option<Box<ScaleState>>,
    /// Whether a reference other than a stop (the odometry) measured the bias since the last
    /// stop ended: the stop after such a gap does not teach the walk ([`BiasFilter::end_stop`]).
    aided: bool,
}

impl BiasFilter {
    /// A filter at its prior (estimate 0).
    pub fn new(model: BiasModel) -> Self {
        let n = model.states;
        let mut phi2 = Box::new([[0.0; MAX_STATES]; MAX_STATES]);
        for i in 0..n {
            for j in 0..n {
                phi2[i][j] = model.phi[i] * model.phi[j];
            }
        }
        let mut f = BiasFilter {
            model,
            learner: None,
            dt: 1.0,
            x: [0.0; MAX_STATES],
            p: Box::new([[0.0; MAX_STATES]; MAX_STATES]),
            phi2,
            updates: 0,
            scale: None,
            aided: false,
        };
        f.reset();
        f
    }

    /// Add the odometry's scale correction as a state ([`ScaleState`]): prior 0 with sd
    /// `sd`, its random walk `walk` (variance per sample). Without it (or before the first
    /// span) every result is the bias filter's alone: the state is not correlated with the
    /// bias until a span correlates them. A second call changes nothing.
    pub fn add_scale(&mut self, sd: f64, walk: f64) {
        if self.scale.is_none() {
            self.scale = Some(Box::new(ScaleState {
                s: 0.0,
                var: sd * sd,
                cov: [0.0; MAX_STATES],
                walk,
            }));
        }
    }

    /// The scale state, if added.
    pub fn scale(&self) -> Option<&ScaleState> {
        self.scale.as_deref()
    }

    /// The bias and the scale as an odometry span sees them.
    pub fn scaled_view(&self) -> ScaledView {
        let (scale, scale_var, cov) = self.scale.as_ref().map_or((0.0, 0.0, 0.0), |sc| {
            let n = self.model.states;
            (sc.s, sc.var, sc.cov[..n].iter().sum())
        });
        ScaledView {
            estimate: self.estimate(),
            variance: self.variance(),
            scale,
            scale_var,
            cov,
        }
    }

    /// Measurement update with an odometry span: y = b + s w of variance `r` (H = [1, ..., 1,
    /// w] on the bias's states and the scale's). Without a scale state, s is 0: y measures the
    /// bias. Like [`BiasFilter::update_with_variance`] it does not feed the walk learner.
    /// Returns the innovation; NaN (ignored) for a non-finite y or w or an r that is not a
    /// finite number > 0.
    pub fn update_scaled(&mut self, y: f64, w: f64, r: f64) -> f64 {
        if !(y.is_finite() && w.is_finite() && r.is_finite() && r > 0.0) {
            return f64::NAN;
        }
        self.aided = true;
        self.correct(y, w, r)
    }

    /// A filter that learns its random walk from the stops ([`WalkLearner`]), starting from
    /// `walk`; `dt` is the sample period (s). Only a one-state model (the default
    /// [`Instability::RandomWalk`]) has a single walk to learn: others are refused.
    pub fn learning(model: BiasModel, walk: WalkConfig, dt: f64) -> Result<Self, BiasError> {
        if model.states != 1 {
            return Err(BiasError::Walk(
                "only the random-walk bias model (one state) can learn its walk".into(),
            ));
        }
        let learner = WalkLearner::new(walk, dt).map_err(BiasError::Walk)?;
        let mut f = BiasFilter::new(model);
        f.model.q[0] = walk.configured * dt;
        f.learner = Some(learner);
        f.dt = dt;
        Ok(f)
    }

    /// What the walk learner has learnt, if the filter learns.
    pub fn walk(&self) -> Option<WalkReport> {
        self.learner.as_ref().map(WalkLearner::report)
    }

    /// A stop ended. If it `teaches`, the walk learner takes its innovation and the walk it
    /// returns is used from now on; if not, the learner only notes where the estimate stands
    /// (the next stop's innovation is measured from here). Nothing without a learner.
    ///
    /// A stop after a gap in which the odometry measured the bias does not teach: the learner
    /// fits the walk to the gaps between stops, the time a filter on stops alone carries the
    /// bias across; a filter that takes a span every 0.5 s carries it only over its own memory
    /// (seconds), and the walk it needs is the one matched there (the configured walk,
    /// [`DEFAULT_MATCH_S`]), not the one the gaps show.
    pub fn end_stop(&mut self, teaches: bool) {
        let (v, r) = (self.variance(), self.model.r);
        let teaches = teaches && !self.aided;
        self.aided = false;
        if let Some(l) = &mut self.learner {
            self.model.q[0] = l.end_stop(v, r, teaches) * self.dt;
        }
    }

    /// Its state now, to carry into a later run.
    pub fn snapshot(&self) -> FilterSnapshot {
        FilterSnapshot {
            states: self.model.states,
            x: self.x,
            p: *self.p,
            learner: self.learner.as_ref().map(WalkLearner::snapshot),
            scale: self.scale.as_ref().map(|sc| (sc.s, sc.var)),
        }
    }

    /// Start from `snap`, taken `steps` samples ago (a restart: the time between runs), as if
    /// the filter had predicted through them: each state decays and its variance grows by the
    /// model's process noise over the gap, in closed form. Counts as informed (one update).
    /// Refused if `snap` has another number of states or its values are not finite.
    pub fn resume(&mut self, snap: &FilterSnapshot, steps: u64) -> Result<(), BiasError> {
        let n = self.model.states;
        if snap.states != n {
            return Err(BiasError::Resume(format!(
                "the state has {} filter states, this filter {n}",
                snap.states
            )));
        }
        let finite = snap.x[..n].iter().all(|v| v.is_finite())
            && snap.p[..n]
                .iter()
                .all(|r| r[..n].iter().all(|v| v.is_finite()));
        if !finite {
            return Err(BiasError::Resume(
                "the state holds values that are not finite".into(),
            ));
        }
        let k = steps as f64;
        self.x = snap.x;
        *self.p = snap.p;
        for i in 0..n {
            let phi = self.model.phi[i];
            self.x[i] *= phi.powf(k);
            for j in 0..n {
                self.p[i][j] *= (phi * self.model.phi[j]).powf(k);
            }
        }
        if let (Some(l), Some(ls)) = (&mut self.learner, &snap.learner) {
            l.resume(ls, steps);
            self.model.q[0] = l.walk() * self.dt;
        }
        for i in 0..n {
            let (phi, q) = (self.model.phi[i], self.model.q[i]);
            // Sum of phi^(2m) for m < k: the process noise added over k steps.
            let grown = if phi >= 1.0 {
                k
            } else {
                (1.0 - phi.powf(2.0 * k)) / (1.0 - phi * phi)
            };
            self.p[i][i] += q * grown;
        }
        if let Some(sc) = &mut self.scale {
            // The scale is the vehicle's: resumed where saved (its walk over the gap added),
            // no longer correlated with the bias.
            if let Some((s, var)) = snap.scale.filter(|(s, v)| s.is_finite() && v.is_finite()) {
                sc.s = s;
                sc.var = var.max(0.0) + sc.walk * k;
            }
            sc.cov = [0.0; MAX_STATES];
        }
        self.updates = self.updates.max(1);
        Ok(())
    }

    /// Back to the prior.
    pub fn reset(&mut self) {
        if let Some(l) = &mut self.learner {
            l.reset();
            self.model.q[0] = l.walk() * self.dt;
        }
        self.x = [0.0; MAX_STATES];
        for row in self.p.iter_mut() {
            *row = [0.0; MAX_STATES];
        }
        for i in 0..self.model.states {
            self.p[i][i] = self.model.p0[i];
        }
        // The scale is the odometry's: kept, but no longer correlated with the bias's prior.
        if let Some(sc) = &mut self.scale {
            sc.cov = [0.0; MAX_STATES];
        }
        self.aided = false;
        self.updates = 0;
    }

    /// The model.
    pub fn model(&self) -> &BiasModel {
        &self.model
    }

    /// Time update by one sample: the states decay, their variance grows.
    pub fn predict(&mut self) {
        if let Some(l) = &mut self.learner {
            l.step();
        }
        let n = self.model.states;
        for i in 0..n {
            self.x[i] *= self.model.phi[i];
            for j in 0..n {
                self.p[i][j] *= self.phi2[i][j];
            }
            self.p[i][i] += self.model.q[i];
        }
        if let Some(sc) = &mut self.scale {
            for i in 0..n {
                sc.cov[i] *= self.model.phi[i];
            }
            sc.var += sc.walk;
        }
    }

    /// Measurement update with one still sample `z` (deg/s); returns the innovation. A
    /// non-finite sample is ignored (returns NaN).
    pub fn update(&mut self, z: f64) -> f64 {
        if !z.is_finite() {
            return f64::NAN;
        }
        if let Some(l) = &mut self.learner {
            l.sample(z, self.x[..self.model.states].iter().sum());
        }
        self.correct(z, 0.0, self.model.r)
    }

    /// Measurement update with a measurement `z` of the bias (deg/s) of variance `r`
    /// ((deg/s)^2) given by the caller, not the model's: a reference other than a still
    /// sample (the vehicle's odometry while it drives, [`super::OdometryAid`]). Returns the
    /// innovation. Unlike [`BiasFilter::update`] it does not feed the walk learner, which
    /// learns from stops alone. A non-finite `z` or an `r` that is not a finite number > 0
    /// is ignored (returns NaN).
    pub fn update_with_variance(&mut self, z: f64, r: f64) -> f64 {
        if !(z.is_finite() && r.is_finite() && r > 0.0) {
            return f64::NAN;
        }
        self.aided = true;
        self.correct(z, 0.0, r)
    }

    /// The Kalman update with H = [1, ..., 1, w] (w on the scale's state: 0 for a stop, and
    /// nothing without a scale state): `y` of variance `r`; the innovation. The scale follows
    /// the bias as far as they are correlated.
    fn correct(&mut self, y: f64, w: f64, r: f64) -> f64 {
        let n = self.model.states;
        let (s_hat, s_var, s_cov) = self
            .scale
            .as_deref()
            .map_or((0.0, 0.0, [0.0; MAX_STATES]), |sc| (sc.s, sc.var, sc.cov));
        // P H^T: the bias's states, then the scale's.
        let mut ph = [0.0; MAX_STATES];
        for (i, v) in ph.iter_mut().enumerate().take(n) {
            *v = self.p[i][..n].iter().sum::<f64>() + w * s_cov[i];
        }
        let ph_s = s_cov[..n].iter().sum::<f64>() + w * s_var;
        let s = (ph[..n].iter().sum::<f64>() + w * ph_s).max(0.0) + r;
        let innovation = y - self.estimate() - s_hat * w;
        for i in 0..n {
            self.x[i] += ph[i] / s * innovation;
            for j in 0..n {
                self.p[i][j] -= ph[i] * ph[j] / s;
            }
        }
        if let Some(sc) = self.scale.as_deref_mut() {
            for (c, phi) in sc.cov[..n].iter_mut().zip(&ph[..n]) {
                *c -= phi * ph_s / s;
            }
            sc.s += ph_s / s * innovation;
            sc.var = (sc.var - ph_s * ph_s / s).max(0.0);
        }
        self.updates += 1;
        innovation
    }

    /// The bias estimate (the sum of the states), deg/s.
    pub fn estimate(&self) -> f64 {
        self.x[..self.model.states].iter().sum()
    }

    /// Variance of the estimate, (deg/s)^2.
    pub fn variance(&self) -> f64 {
        let n = self.model.states;
        self.p[..n]
            .iter()
            .map(|row| row[..n].iter().sum::<f64>())
            .sum::<f64>()
            .max(0.0)
    }

    /// Samples taken so far.
    pub fn updates(&self) -> u64 {
        self.updates
    }

    /// The estimate and variance if `count` more samples of mean `mean` were taken now, without
    /// taking them (one scalar update with measurement variance R / count).
    pub fn with_mean(&self, mean: f64, count: usize) -> (f64, f64) {
        let b = self.estimate();
        let v = self.variance();
        if count == 0 || !mean.is_finite() {
            return (b, v);
        }
        let r = self.model.r / count as f64;
        let g = v / (v + r);
        (b + g * (mean - b), (1.0 - g) * v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> BiasModel {
        let t = crate::drift::bias::tests::terms();
        BiasModel::new(&t, 100.0, Instability::from_terms(&t)).unwrap()
    }

    #[test]
    fn a_scale_state_without_spans_changes_nothing() {
        let mut a = BiasFilter::new(model());
        let mut b = BiasFilter::new(model());
        b.add_scale(0.01, 1e-10);
        for k in 0..5000 {
            a.predict();
            b.predict();
            if k % 3 != 0 {
                let z = 0.3 + 0.01 * ((k * 7919) % 13) as f64;
                a.update(z);
                b.update(z);
            }
        }
        assert_eq!(a.estimate(), b.estimate());
        assert_eq!(a.variance(), b.variance());
        let sc = b.scale().unwrap();
        assert_eq!(sc.s, 0.0);
        assert!((sc.var - (1e-4 + 5000.0 * 1e-10)).abs() < 1e-15, "{sc:?}");
    }

    /// A turn one way only, from the bias's prior, sees b + s w; the stop after it tells b,
    /// and with it s.
    #[test]
    fn a_stop_after_a_turn_corrects_the_scale_learnt_in_it() {
        let (bias, s, w) = (0.3, 0.01, 10.0);
        let mut f = BiasFilter::new(model());
        f.add_scale(0.01, 0.0);
        let stop = |f: &mut BiasFilter, n: usize| {
            for _ in 0..n {
                f.predict();
                f.update(bias);
            }
        };
        for k in 0..4000 {
            f.predict();
            if k % 50 == 0 {
                f.update_scaled(bias + s * w, w, 1e-3);
            }
        }
        let v = f.scaled_view();
        // The spans agree with the bias and the scale together.
        assert!((v.predict(w).0 - (bias + s * w)).abs() < 1e-3, "{v:?}");
        // Correlated: a bias too high goes with a scale too low.
        assert!(v.cov < 0.0, "{v:?}");
        let before = (v.scale - s).abs();
        stop(&mut f, 2000);
        let after = (f.scaled_view().scale - s).abs();
        assert!(after < 0.1 * before, "{before} then {after}");
        assert!(f.scaled_view().scale_var < v.scale_var);
    }

    #[test]
    fn a_stop_after_odometry_does_not_teach_the_walk() {
        let m = model();
        let walk = WalkConfig {
            configured: m.walk_per_s(100.0),
            lo: m.walk_per_s(100.0) / 100.0,
            hi: m.walk_per_s(100.0) * 100.0,
        };
        let mut f = BiasFilter::learning(m, walk, 0.01).unwrap();
        let stops = |f: &BiasFilter| f.walk().unwrap().stops;
        for gap_aided in [false, false, true, false] {
            for _ in 0..500 {
                f.predict();
                f.update(0.3);
            }
            f.end_stop(true);
            for k in 0..1000 {
                f.predict();
                if gap_aided && k == 500 {
                    f.update_scaled(0.3, 0.0, 1e-3);
                }
            }
        }
        // The first stop has nothing to compare; the fourth came after an aided gap.
        assert_eq!(stops(&f), 2);
        for _ in 0..500 {
            f.predict();
            f.update(0.3);
        }
        f.end_stop(true);
        assert_eq!(stops(&f), 3);
    }

    /// The scale is kept across a restart: resumed where it was, its walk over the gap added;
    /// a filter without a scale state takes the bias alone.
    #[test]
    fn a_resumed_filter_keeps_its_scale_grown_by_the_gap() {
        let mut f = BiasFilter::new(model());
        f.add_scale(0.01, 1e-9);
        for k in 0..2000 {
            f.predict();
            let w = if k % 400 < 200 { 10.0 } else { 2.0 };
            if k % 50 == 0 {
                f.update_scaled(0.3 + 0.02 * w, w, 1e-4);
            }
        }
        let snap = f.snapshot();
        let (s, var) = snap.scale.unwrap();
        assert!((s - 0.02).abs() < 0.005 && var < 1e-5, "{s} {var}");
        let mut g = BiasFilter::new(model());
        g.add_scale(0.01, 1e-9);
        g.resume(&snap, 1000).unwrap();
        let sc = g.scale().unwrap();
        assert_eq!(sc.s, s);
        assert!((sc.var - (var + 1e-6)).abs() < 1e-15, "{sc:?}");
        assert_eq!(g.scaled_view().cov, 0.0);
        let mut bare = BiasFilter::new(model());
        bare.resume(&snap, 1000).unwrap();
        assert!(bare.scale().is_none());
        assert!((bare.estimate() - g.estimate()).abs() < 1e-12);
    }
}
