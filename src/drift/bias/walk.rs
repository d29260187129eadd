//! [`WalkLearner`]: how fast this unit's bias wanders, learnt from the stops it sees.
//!
//! The filter's random walk (its process noise q, per second) comes from the Allan terms, but
//! how much a bias moves between stops differs from unit to unit and from what a short Allan
//! record can show. Each stop measures the bias again; the stop's mean against the estimate
//! carried from the last stop is an innovation whose variance the model predicts:
//!
//! ```text
//! d = mean(stop) - estimate(end of last stop)
//! Var d = P_end + R / n + q (gap + T / 3)
//! ```
//!
//! with P_end the estimate's variance at the end of the last stop, R / n the stop mean's white
//! noise (n samples), gap the time between the stops and T / 3 the walk's share within the
//! stop's own averaging (the mean of a walk over T). Matching the innovations' spread to this
//! is innovation-based adaptive estimation (Mehra 1970; Myers and Tapley 1976). Here it is done
//! as a likelihood over a fixed grid of q between bounds: each stop adds its log-likelihood to
//! every candidate, and the q used is the posterior mean of log q. That gives what a moment
//! match does not:
//!
//! - **bounds**: q never leaves the range the terms allow ([`WalkLearner::new`]);
//! - **a start at the configured walk**: a prior on log q around it, so the first stops move
//!   it only as far as their evidence goes;
//! - **robustness**: a Student-t likelihood (4 degrees of freedom), so one odd stop (a
//!   movement taken for a stop, a bump) weighs like an outlier, not like a proof;
//! - **memory**: old stops fade (a factor per stop), so a unit whose bias settles after
//!   warm-up is followed.
//!
//! O(grid) once per stop, nothing per sample but a counter; fixed arrays, no allocation.

/// Candidates of q on the grid.
pub const GRID: usize = 41;

/// Degrees of freedom of the innovations' Student-t likelihood.
const NU: f64 = 4.0;

/// Each stop's evidence is kept with this weight per later stop (memory of about 50 stops).
const FORGET: f64 = 0.98;

/// How learning the walk is set up: its bounds and prior.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WalkConfig {
    /// The configured walk (process noise of the bias per second, (deg/s)^2/s).
    pub configured: f64,
    /// Least walk the terms allow, (deg/s)^2/s.
    pub lo: f64,
    /// Largest walk the terms allow, (deg/s)^2/s.
    pub hi: f64,
}

impl WalkConfig {
    /// Whether the bounds are usable: finite, 0 < lo <= configured <= hi.
    pub fn check(&self) -> Result<(), String> {
        let ok = |v: f64| v.is_finite() && v > 0.0;
        if !(ok(self.lo) && ok(self.hi) && ok(self.configured)) {
            return Err(format!(
                "the walk and its bounds must be finite and > 0 (walk {:e}, bounds {:e}..{:e})",
                self.configured, self.lo, self.hi
            ));
        }
        if !(self.lo <= self.configured && self.configured <= self.hi) {
            return Err(format!(
                "the configured walk {:e} lies outside its bounds {:e}..{:e}",
                self.configured, self.lo, self.hi
            ));
        }
        Ok(())
    }
}

/// What the learner has seen so far.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WalkReport {
    /// The walk in use now, (deg/s)^2/s.
    pub walk: f64,
    /// The configured walk, (deg/s)^2/s.
    pub configured: f64,
    /// Its bounds, (deg/s)^2/s.
    pub lo: f64,
    /// Upper bound, (deg/s)^2/s.
    pub hi: f64,
    /// Stops whose innovation was taken (the first stop has none: nothing carried to it).
    pub stops: u64,
}

/// What a [`WalkLearner`] carries from one run to the next ([`WalkLearner::snapshot`]): the
/// evidence of the stops it saw, not a stop it is inside.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LearnerSnapshot {
    /// The log-likelihood of each candidate walk.
    pub ll: [f64; GRID],
    /// The walk in use, (deg/s)^2/s.
    pub walk: f64,
    /// Stops weighed.
    pub stops: u64,
    /// The variance at the last stop's end; None before the first stop.
    pub end_var: Option<f64>,
}

/// One stop as the filter saw it: the state carried to it and its samples.
#[derive(Debug, Clone, Copy, Default)]
struct Stop {
    /// The estimate before the stop's first sample.
    carried: f64,
    /// Filter steps from the last stop's last sample to this stop's first.
    gap: u64,
    sum: f64,
    n: u64,
}

/// Learns the bias filter's random walk from the innovations at each stop (module docs).
#[derive(Debug, Clone)]
pub struct WalkLearner {
    cfg: WalkConfig,
    dt: f64,
    ln_q: [f64; GRID],
    ln_prior: [f64; GRID],
    ll: [f64; GRID],
    walk: f64,
    /// Steps since the last stop's last sample.
    since: u64,
    /// The variance at the last stop's last sample; None before the first stop.
    end_var: Option<f64>,
    open: Option<Stop>,
    stops: u64,
}

impl WalkLearner {
    /// A learner for a filter stepping every `dt` seconds. The prior on log q is a normal
    /// around the configured walk whose standard deviation is a quarter of the bounds' span:
    /// the bounds are two standard deviations away on the wider side.
    pub fn new(cfg: WalkConfig, dt: f64) -> Result<Self, String> {
        cfg.check()?;
        if !(dt.is_finite() && dt > 0.0) {
            return Err(format!("the sample period must be > 0 s, not {dt}"));
        }
        let (lo, hi) = (cfg.lo.ln(), cfg.hi.ln());
        let centre = cfg.configured.ln();
        let sd = ((hi - lo) / 4.0).max(1e-9);
        let mut ln_q = [0.0; GRID];
        let mut ln_prior = [0.0; GRID];
        for j in 0..GRID {
            let v = lo + (hi - lo) * j as f64 / (GRID - 1) as f64;
            ln_q[j] = v;
            ln_prior[j] = -0.5 * ((v - centre) / sd).powi(2);
        }
        Ok(WalkLearner {
            cfg,
            dt,
            ln_q,
            ln_prior,
            ll: [0.0; GRID],
            walk: cfg.configured,
            since: 0,
            end_var: None,
            open: None,
            stops: 0,
        })
    }

    /// The walk to use now, (deg/s)^2/s.
    pub fn walk(&self) -> f64 {
        self.walk
    }

    /// The filter stepped one sample.
    pub fn step(&mut self) {
        self.since += 1;
    }

    /// A still sample `z` enters the filter, whose estimate before it is `estimate`.
    pub fn sample(&mut self, z: f64, estimate: f64) {
        let stop = self.open.get_or_insert(Stop {
            carried: estimate,
            gap: self.since,
            ..Stop::default()
        });
        stop.sum += z;
        stop.n += 1;
        self.since = 0;
    }

    /// The stop whose samples came since the last call ended; `variance` is the filter's at its
    /// last sample and `r` the measurement noise per sample. Only a stop that `teaches` is
    /// weighed (one the tracker trusts); any stop becomes the point the next is measured from.
    /// Returns the walk to use from now on. Nothing changes if no sample came.
    pub fn end_stop(&mut self, variance: f64, r: f64, teaches: bool) -> f64 {
        let Some(stop) = self.open.take() else {
            return self.walk;
        };
        let last_end = self.end_var.replace(variance);
        let (Some(end_var), true) = (last_end, teaches) else {
            // The first stop: what it is compared with is the turn-on prior, not a walk.
            // An untrusted one: its innovation may hold a movement taken for a stop.
            return self.walk;
        };
        let n = stop.n as f64;
        let d = stop.sum / n - stop.carried;
        // The part of the carried variance that is not the walk over the gap.
        let base = end_var.max(0.0) + r / n;
        let steps = stop.gap as f64 + n / 3.0;
        let span = steps * self.dt;
        if !(d.is_finite() && base.is_finite() && span > 0.0) {
            return self.walk;
        }
        for (ll, &ln_q) in self.ll.iter_mut().zip(&self.ln_q) {
            let s = base + ln_q.exp() * span;
            *ll = FORGET * *ll - 0.5 * s.ln() - 0.5 * (NU + 1.0) * (1.0 + d * d / (NU * s)).ln();
        }
        self.stops += 1;
        self.walk = self.posterior_walk();
        self.walk
    }

    /// The posterior mean of log q, exponentiated.
    fn posterior_walk(&self) -> f64 {
        let mut best = f64::NEG_INFINITY;
        for j in 0..GRID {
            best = best.max(self.ll[j] + self.ln_prior[j]);
        }
        let (mut w, mut m) = (0.0, 0.0);
        for j in 0..GRID {
            let p = (self.ll[j] + self.ln_prior[j] - best).exp();
            w += p;
            m += p * self.ln_q[j];
        }
        (m / w).exp().clamp(self.cfg.lo, self.cfg.hi)
    }

    /// What it has learnt.
    pub fn report(&self) -> WalkReport {
        WalkReport {
            walk: self.walk,
            configured: self.cfg.configured,
            lo: self.cfg.lo,
            hi: self.cfg.hi,
            stops: self.stops,
        }
    }

    /// What it has learnt, to carry into a later run ([`WalkLearner::resume`]).
    pub fn snapshot(&self) -> LearnerSnapshot {
        LearnerSnapshot {
            ll: self.ll,
            walk: self.walk,
            stops: self.stops,
            end_var: self.end_var,
        }
    }

    /// Carry on from `snap`, `steps` samples after it was taken (the gap to the next stop
    /// includes them). The walk is kept within this learner's bounds.
    pub fn resume(&mut self, snap: &LearnerSnapshot, steps: u64) {
        self.ll = snap.ll;
        self.stops = snap.stops;
        self.end_var = snap.end_var;
        self.walk = snap.walk.clamp(self.cfg.lo, self.cfg.hi);
        self.open = None;
        self.since = steps;
    }

    /// Forget every stop (back to the configured walk).
    pub fn reset(&mut self) {
        self.ll = [0.0; GRID];
        self.walk = self.cfg.configured;
        self.since = 0;
        self.end_var = None;
        self.open = None;
        self.stops = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    /// Stops of `n` samples every `gap` steps at 100 Hz on a bias walking with `q` per second,
    /// white noise of variance `r`; the learner fed as the filter would (the carried estimate
    /// is the last stop's mean, its variance r / n). Returns the learnt walk.
    fn learn(q: f64, configured: f64, stops: usize, odd: Option<usize>, seed: u64) -> f64 {
        let dt = 0.01;
        let (r, n, gap) = (0.2f64, 2000u64, 4000u64);
        let (lo, hi) = (configured / 100.0, configured * 10.0);
        let cfg = WalkConfig { configured, lo, hi };
        let mut l = WalkLearner::new(cfg, dt).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut z = || -> f64 { StandardNormal.sample(&mut rng) };
        let (mut bias, mut carried) = (0.0f64, 0.0f64);
        for s in 0..stops {
            for _ in 0..gap {
                l.step();
                bias += (q * dt).sqrt() * z();
            }
            let mut sum = 0.0;
            for k in 0..n {
                bias += (q * dt).sqrt() * z();
                let mut x = bias + r.sqrt() * z();
                if odd == Some(s) && k < n / 2 {
                    x += 0.5; // half the stop a slow turn taken for still
                }
                l.sample(x, carried);
                l.step();
                sum += x;
            }
            carried = sum / n as f64;
            l.end_stop(r / n as f64, r, true);
        }
        l.walk()
    }

    #[test]
    fn it_finds_a_walk_smaller_or_larger_than_configured() {
        let configured = 1e-5;
        for (truth, seed) in [(1e-6, 1), (2e-6, 2), (5e-5, 3)] {
            let mut logs = Vec::new();
            for k in 0..5 {
                logs.push((learn(truth, configured, 60, None, seed * 10 + k) / truth).ln());
            }
            let mean = logs.iter().sum::<f64>() / logs.len() as f64;
            assert!(
                mean.abs() < 2f64.ln(),
                "truth {truth}: learnt/truth {:.2} (log mean of 5 runs)",
                mean.exp()
            );
        }
    }

    #[test]
    fn one_odd_stop_does_not_throw_it_and_bounds_hold() {
        let configured = 1e-5;
        let clean = learn(2e-6, configured, 30, None, 7);
        let odd = learn(2e-6, configured, 30, Some(15), 7);
        assert!(
            odd / clean < 3.0,
            "clean {clean:e}, with an odd stop {odd:e}"
        );
        // A walk far outside the bounds stays within them: below, where the stops' noise
        // hides any walk, somewhere under the configured one; above, at the upper bound.
        let low = learn(1e-9, configured, 60, None, 8);
        assert!(
            low >= configured / 100.0 && low < configured / 3.0,
            "{low:e}"
        );
        let high = learn(1.0, configured, 60, None, 9);
        assert!(
            high <= configured * 10.0 && high > configured * 5.0,
            "{high:e}"
        );
    }

    #[test]
    fn untrusted_and_first_stops_teach_nothing() {
        let cfg = WalkConfig {
            configured: 1e-5,
            lo: 1e-7,
            hi: 1e-4,
        };
        let mut l = WalkLearner::new(cfg, 0.01).unwrap();
        for stop in 0..5 {
            for _ in 0..100 {
                l.step();
            }
            l.sample(if stop % 2 == 0 { 1.0 } else { -1.0 }, 0.0);
            l.end_stop(1e-4, 0.2, stop == 0);
        }
        assert_eq!(l.report().stops, 0);
        assert_eq!(l.walk(), 1e-5);
        assert!(WalkLearner::new(WalkConfig { lo: 1e-3, ..cfg }, 0.01).is_err());
        assert!(WalkLearner::new(cfg, 0.0).is_err());
    }
}
