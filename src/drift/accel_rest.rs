//! The accelerometer's half of the rest test: has the body's specific force stayed constant,
//! within the accelerometer's own noise, and since when?
//!
//! At rest an accelerometer feels gravity alone: a constant vector (whatever the body's
//! attitude) plus white noise. A moving vehicle's accelerometer feels its speed changing (starts
//! and stops), its turns (centripetal force, speed times yaw rate, as they begin, change and
//! end), its shake, a walker's steps. It is blind to one motion: a turn so steady, at a speed so
//! steady, on a road so smooth that the force does not change; the gyro's own test against the
//! bias estimate is left to see that one.
//!
//! # The tests (generalised likelihood ratio tests, after Skog et al. 2010)
//! A *quiet run* is the samples since the last evidence of motion. Under "rest" its samples are
//! one constant vector plus white noise of per-axis variance `var`; each test is a chi-square
//! bound on a statistic that follows chi-square under that hypothesis, at the tail of `sigmas`
//! normal standard deviations ([`chi2_ratio`]), `hysteresis` times as far once the run is
//! reported quiet (so that a long rest is rarely cut by noise):
//!
//! - **sample**: the new sample against the run's mean (chi-square, 3 degrees of freedom): a
//!   start, a step, at once. One such sample alone is held out of the run: real accelerometers
//!   spike (ours about once in 10^4 samples, up to a hundred standard deviations), and a motion
//!   lasts longer than one sample, so two in a row are evidence, dated from the first;
//! - **variance**: the variance of the run's newest `window` samples (3 (n - 1) degrees of
//!   freedom): shake and changing forces;
//! - **drift**: the newest `window` samples' mean against the mean of the run's first `window`
//!   (3 degrees of freedom, variance twice the Allan variance at the window's length): a force
//!   that creeps in too slowly for the other two.
//!
//! Skog's SHOE detector adds the gyro's energy and the accelerometer's distance from a known
//! gravity to one statistic. Here the force's magnitude is not compared with gravity (a unit's
//! scale and bias errors put it several noise deviations off, our ADIS16405 reads 1.016 g), and
//! the gyro keeps its own tests ([`crate::drift::stillness`]) against the bias estimate, which a
//! sum would let a quiet accelerometer outvote. The two are joined as VQF's rest detection joins
//! them: rest only if both are quiet.
//!
//! # What it says ([`Aid`])
//! - `Quiet { since }`: no evidence for `since >= settle` samples: the body came to rest then.
//! - `Moving { age }`: evidence now or within the last `settle` samples. When evidence ends a
//!   quiet run, the motion's onset is estimated among the run's newest samples (the most likely
//!   moving suffix, [`moving_llr`] summed over the axes): `age` samples ago.
//! - `Unknown`: no reading, or the first `settle` samples after a reset with no evidence yet.
//!
//! O(1) per sample but the onset estimate (O(window), once per motion), no allocation after
//! construction.

use super::stillness::{chi2_ratio, moving_llr, Aid};
use std::f64::consts::{LN_2, PI};

/// Thresholds of [`AccelRest`], per axis in (m/s^2)^2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelRestConfig {
    /// Samples of the variance and drift tests' windows.
    pub window: usize,
    /// Quiet samples before the run is reported quiet.
    pub settle: usize,
    /// Variance of one still sample, per axis: white noise, rounding and fast flicker.
    pub var: f64,
    /// Variance, per axis, of the difference of two `window`-sample means at rest: twice the
    /// Allan variance at the window's length.
    pub drift_var: f64,
    /// Normal standard deviations whose tail sets the bounds while not yet quiet.
    pub sigmas: f64,
    /// The bounds of a quiet run sit this many times as far (>= 1).
    pub hysteresis: f64,
}

impl AccelRestConfig {
    /// The thresholds from an accelerometer's noise terms at `rate_hz`: velocity random walk
    /// `vrw` (m/s/sqrt(s); one sample's white variance is vrw^2 rate, its rounding included as
    /// `allan` fits a real unit's) and bias instability `b` (m/s^2; the flicker floor of the
    /// Allan variance is (2 ln 2 / pi) b^2), over windows of `window` samples, reported quiet
    /// after `settle`.
    pub fn from_terms(
        vrw: f64,
        b: f64,
        rate_hz: f64,
        window: usize,
        settle: usize,
        sigmas: f64,
        hysteresis: f64,
    ) -> Result<Self, String> {
        for (name, v) in [("velocity random walk", vrw), ("sample rate", rate_hz)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!(
                    "accelerometer {name} must be a number > 0, not {v}"
                ));
            }
        }
        if !(b.is_finite() && b >= 0.0) {
            return Err(format!(
                "accelerometer bias instability must be a number >= 0, not {b}"
            ));
        }
        if !(sigmas.is_finite() && sigmas > 0.0) {
            return Err(format!(
                "accelerometer rest: sigmas must be > 0, not {sigmas}"
            ));
        }
        if !(hysteresis.is_finite() && hysteresis >= 1.0) {
            return Err(format!(
                "accelerometer rest: hysteresis must be >= 1, not {hysteresis}"
            ));
        }
        let window = window.max(2);
        // As the gyro's [`crate::drift::bias::BiasTerms::sample_variance`]: white, and the
        // flicker's b^2 ln2/pi per octave faster than a second.
        let fast_octaves = rate_hz.max(1.0).log2().ceil() + 1.0;
        let white = vrw * vrw * rate_hz;
        let var = white + fast_octaves * b * b * LN_2 / PI;
        let avar = white / window as f64 + 2.0 * LN_2 / PI * b * b;
        Ok(AccelRestConfig {
            window,
            settle: settle.max(1),
            var,
            drift_var: 2.0 * avar,
            sigmas,
            hysteresis,
        })
    }
}

/// Running sums of vectors relative to an origin (against cancellation near gravity).
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    origin: [f64; 3],
    n: usize,
    sum: [f64; 3],
    sum2: [f64; 3],
}

impl Sums {
    fn add(&mut self, a: &[f64; 3]) {
        if self.n == 0 {
            self.origin = *a;
        }
        for (i, ai) in a.iter().enumerate() {
            let v = ai - self.origin[i];
            self.sum[i] += v;
            self.sum2[i] += v * v;
        }
        self.n += 1;
    }

    fn clear(&mut self) {
        *self = Sums::default();
    }

    fn mean(&self) -> [f64; 3] {
        let n = self.n.max(1) as f64;
        std::array::from_fn(|i| self.origin[i] + self.sum[i] / n)
    }

    /// Sum over the axes of n times the (population) variance.
    fn scatter(&self) -> f64 {
        let n = self.n.max(1) as f64;
        (0..3)
            .map(|i| (self.sum2[i] - self.sum[i] * self.sum[i] / n).max(0.0))
            .sum()
    }
}

/// The accelerometer's rest test (see the module documentation).
#[derive(Debug, Clone)]
pub struct AccelRest {
    cfg: AccelRestConfig,
    ring: Vec<[f64; 3]>,
    pos: usize,
    filled: usize,
    /// The ring's sums, relative to `ring_origin`.
    ring_origin: [f64; 3],
    ring_sum: [f64; 3],
    ring_sum2: [f64; 3],
    /// The quiet run.
    run: Sums,
    /// The mean of the run's first `window` samples.
    anchor: Option<[f64; 3]>,
    /// Evidence of motion was seen since the reset.
    seen_motion: bool,
    /// Samples since the onset of the last motion.
    since_onset: usize,
    /// The last sample was a lone jolt, held out of the run.
    suspect: bool,
    /// The rest noise learnt so far over the terms' (>= 1; see [`AccelRest::push`]).
    scale: f64,
    /// Windows learnt from and the sum of their variances.
    learnt: usize,
    learnt_sum: f64,
    /// Consecutive samples the gyro has judged still.
    gyro_run: usize,
}

impl AccelRest {
    /// A test with thresholds `cfg`, knowing nothing yet.
    pub fn new(cfg: AccelRestConfig) -> Self {
        AccelRest {
            ring: vec![[0.0; 3]; cfg.window.max(2)],
            cfg,
            pos: 0,
            filled: 0,
            ring_origin: [0.0; 3],
            ring_sum: [0.0; 3],
            ring_sum2: [0.0; 3],
            run: Sums::default(),
            anchor: None,
            seen_motion: false,
            since_onset: 0,
            suspect: false,
            scale: 1.0,
            learnt: 0,
            learnt_sum: 0.0,
            gyro_run: 0,
        }
    }

    /// The thresholds.
    pub fn config(&self) -> &AccelRestConfig {
        &self.cfg
    }

    /// Back to knowing nothing.
    pub fn reset(&mut self) {
        let cfg = self.cfg;
        *self = AccelRest {
            ring: std::mem::take(&mut self.ring),
            ..AccelRest::new(cfg)
        };
    }

    /// Samples in the current quiet run.
    pub fn run(&self) -> usize {
        self.run.n
    }

    /// The per-axis variance of one still sample in force now: the terms', or more, as learnt.
    pub fn rest_variance(&self) -> f64 {
        self.cfg.var * self.scale
    }

    /// One accelerometer sample (m/s^2, specific force; `None`: absent or invalid, which
    /// leaves the state as it is) and the verdict. `gyro_still`: the gyro alone judges the body
    /// still (every axis's own test on its full window). Each whole window of such samples
    /// teaches the rest noise: its variance, if a rest's could be that large (within the
    /// variance test's bound, which keeps a spike or a shake out), joins a running mean, and the
    /// bounds use that mean where it exceeds the terms' (a unit noisier than its data sheet, or
    /// an engine idling at a stop). See the module documentation.
    pub fn push(&mut self, a: Option<[f64; 3]>, gyro_still: bool) -> Aid {
        let Some(a) = a.filter(|a| a.iter().all(|v| v.is_finite())) else {
            return Aid::Unknown;
        };
        self.learn(&a, gyro_still);
        let z = if self.run.n >= self.cfg.settle {
            self.cfg.hysteresis * self.cfg.sigmas
        } else {
            self.cfg.sigmas
        };
        let jolt = self.jolt(&a, z);
        let suspect = std::mem::take(&mut self.suspect);
        if jolt && !suspect {
            // One sample off the run: the first of a motion, or a spike of the sensor (real
            // ones have them: our ADIS16405's accelerometer about one in 10^4 samples). The
            // next sample tells; meanwhile the run's mean stands in for it.
            let m = self.run.mean();
            self.push_ring(&m);
            self.run.add(&m);
            self.suspect = true;
            return self.verdict();
        }
        self.push_ring(&a);
        if jolt || self.evidence(&a, z) {
            let age = if self.run.n > 0 {
                self.onset(&self.run.mean()).max(usize::from(suspect))
            } else {
                self.since_onset + 1
            };
            self.run.clear();
            self.anchor = None;
            self.seen_motion = true;
            self.since_onset = age;
            return Aid::Moving { age };
        }
        self.run.add(&a);
        self.verdict()
    }

    /// The verdict after a sample joined the run.
    fn verdict(&mut self) -> Aid {
        if self.run.n == self.cfg.window {
            self.anchor = Some(self.run.mean());
        }
        self.since_onset += 1;
        if self.run.n >= self.cfg.settle {
            Aid::Quiet { since: self.run.n }
        } else if self.seen_motion {
            Aid::Moving {
                age: self.since_onset,
            }
        } else {
            Aid::Unknown
        }
    }

    /// Learn the rest noise from whole windows the gyro judges still (see [`AccelRest::push`]).
    fn learn(&mut self, a: &[f64; 3], gyro_still: bool) {
        self.gyro_run = if gyro_still { self.gyro_run + 1 } else { 0 };
        let w = self.ring.len();
        if self.gyro_run < w || self.filled < w {
            return;
        }
        // The ring holds the window up to the previous sample; take this one's place in it.
        let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
        for v in self.newest().take(w - 1).chain(std::iter::once(*a)) {
            for i in 0..3 {
                let d = v[i] - self.ring_origin[i];
                sum[i] += d;
                sum2[i] += d * d;
            }
        }
        let n = w as f64;
        let dof = 3.0 * (n - 1.0);
        let scatter: f64 = (0..3)
            .map(|i| (sum2[i] - sum[i] * sum[i] / n).max(0.0))
            .sum();
        let v = scatter / dof;
        if v <= self.rest_variance() * chi2_ratio(dof, self.cfg.hysteresis * self.cfg.sigmas) {
            self.learnt += 1;
            self.learnt_sum += v;
            self.scale = (self.learnt_sum / self.learnt as f64 / self.cfg.var).max(1.0);
        }
        self.gyro_run = 0;
    }

    fn push_ring(&mut self, a: &[f64; 3]) {
        let w = self.ring.len();
        if self.filled == 0 {
            self.ring_origin = *a;
        }
        let v: [f64; 3] = std::array::from_fn(|i| a[i] - self.ring_origin[i]);
        if self.filled == w {
            let old = self.ring[self.pos];
            for (i, o) in old.iter().enumerate() {
                self.ring_sum[i] -= o;
                self.ring_sum2[i] -= o * o;
            }
        } else {
            self.filled += 1;
        }
        self.ring[self.pos] = v;
        self.pos = if self.pos + 1 == w { 0 } else { self.pos + 1 };
        for (i, vi) in v.iter().enumerate() {
            self.ring_sum[i] += vi;
            self.ring_sum2[i] += vi * vi;
        }
    }

    /// The ring's newest samples, newest first (as vectors of m/s^2).
    fn newest(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        let w = self.ring.len();
        (0..self.filled).map(move |k| {
            let v = self.ring[(self.pos + w - 1 - k) % w];
            std::array::from_fn(|i| self.ring_origin[i] + v[i])
        })
    }

    /// Whether `a` lies off the run's mean (whose own spread is var / n) beyond the tail of
    /// `z` standard deviations.
    fn jolt(&self, a: &[f64; 3], z: f64) -> bool {
        let n = self.run.n;
        if n == 0 {
            return false;
        }
        let m = self.run.mean();
        let d2: f64 = (0..3).map(|i| (a[i] - m[i]).powi(2)).sum::<f64>();
        d2 / (self.rest_variance() * (1.0 + 1.0 / n as f64)) > 3.0 * chi2_ratio(3.0, z)
    }

    /// Whether `a` (already in the ring, not yet in the run) makes the run's variance or drift
    /// evidence of motion, at the tail of `z` standard deviations.
    fn evidence(&self, a: &[f64; 3], z: f64) -> bool {
        let c = &self.cfg;
        let n = self.run.n;
        if n == 0 {
            return false;
        }
        // Variance of the run's newest `window` samples, this one included.
        let (count, scatter) = if n < c.window {
            let mut with = self.run;
            with.add(a);
            (with.n, with.scatter())
        } else {
            let w = self.filled as f64;
            let s: f64 = (0..3)
                .map(|i| (self.ring_sum2[i] - self.ring_sum[i] * self.ring_sum[i] / w).max(0.0))
                .sum();
            (self.filled, s)
        };
        let dof = 3.0 * (count as f64 - 1.0);
        if dof > 0.0 && scatter / self.rest_variance() > dof * chi2_ratio(dof, z) {
            return true;
        }
        // Drift: the newest window's mean against the run's first window's.
        if let Some(anchor) = self.anchor {
            if n >= 2 * c.window {
                let w = self.filled as f64;
                let d2: f64 = (0..3)
                    .map(|i| (self.ring_origin[i] + self.ring_sum[i] / w - anchor[i]).powi(2))
                    .sum();
                if d2 / (c.drift_var * self.scale) > 3.0 * chi2_ratio(3.0, z) {
                    return true;
                }
            }
        }
        false
    }

    /// Samples since the onset of the motion just detected: the most likely moving suffix of
    /// the run's newest samples and this one, against rest at `mean` (0: this sample).
    fn onset(&self, mean: &[f64; 3]) -> usize {
        let inv_sd = 1.0 / self.rest_variance().sqrt();
        let span = (self.run.n + 1).min(self.filled);
        let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
        let (mut best, mut len) = (f64::NEG_INFINITY, 1);
        for (k, v) in self.newest().take(span).enumerate() {
            for i in 0..3 {
                let z = (v[i] - mean[i]) * inv_sd;
                sum[i] += z;
                sum2[i] += z * z;
            }
            let n = (k + 1) as f64;
            let llr: f64 = (0..3).map(|i| moving_llr(n, sum[i], sum2[i])).sum();
            if llr > best {
                best = llr;
                len = k + 1;
            }
        }
        len - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    const G: [f64; 3] = [0.1, -0.2, -9.8];

    fn cfg() -> AccelRestConfig {
        // 0.2 m/s/sqrt(h) (the ADIS16405 data sheet) at 100 Hz: 0.033 m/s^2 per sample.
        AccelRestConfig::from_terms(0.2 / 60.0, 0.002, 100.0, 100, 25, 4.0, 1.5).unwrap()
    }

    fn noise(n: usize, sd: f64, seed: u64) -> Vec<[f64; 3]> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                std::array::from_fn(|i| {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    G[i] + sd * z
                })
            })
            .collect()
    }

    #[test]
    fn a_rest_is_quiet_after_settling_and_stays_quiet() {
        let c = cfg();
        let mut r = AccelRest::new(c);
        let x = noise(60_000, c.var.sqrt(), 1);
        let mut verdicts = x.iter().map(|a| r.push(Some(*a), false));
        // Nothing known before `settle` samples, with no evidence.
        for _ in 0..24 {
            assert_eq!(verdicts.next(), Some(Aid::Unknown));
        }
        assert_eq!(verdicts.next(), Some(Aid::Quiet { since: 25 }));
        // Ten minutes of rest: never cut.
        let cut = verdicts.filter(|v| !matches!(v, Aid::Quiet { .. })).count();
        assert_eq!(cut, 0);
    }

    #[test]
    fn a_start_is_seen_at_once_and_dated() {
        let c = cfg();
        let mut r = AccelRest::new(c);
        let mut x = noise(1500, c.var.sqrt(), 2);
        // At sample 1000 the vehicle pulls away: 1.5 m/s^2 forward over a 0.5 s raised cosine.
        for (k, a) in x.iter_mut().enumerate().skip(1000) {
            let t = (k - 1000) as f64 / 100.0;
            let u = (t / 0.5).min(1.0);
            a[0] += 1.5 * 0.5 * (1.0 - (PI * u).cos());
        }
        let mut seen = None;
        for (k, a) in x.iter().enumerate() {
            if let Aid::Moving { age } = r.push(Some(*a), false) {
                seen = Some((k, age));
                break;
            }
        }
        let (k, age) = seen.unwrap();
        assert!((1000..1015).contains(&k), "seen at {k}");
        let onset = k - age;
        assert!((995..=1010).contains(&onset), "dated at {onset}");
    }

    #[test]
    fn shake_and_steps_keep_it_moving_and_a_new_rest_counts_from_its_start() {
        let c = cfg();
        let mut r = AccelRest::new(c);
        let mut x = noise(3000, c.var.sqrt(), 3);
        // Steps: 2 m/s^2 vertical at 1.9 Hz from sample 100 to 2000, then rest again (tilted).
        for (k, a) in x.iter_mut().enumerate() {
            if (100..2000).contains(&k) {
                a[2] += 2.0 * (2.0 * PI * 1.9 * k as f64 / 100.0).sin();
            } else if k >= 2000 {
                a[1] += 0.5;
            }
        }
        let v: Vec<Aid> = x.iter().map(|a| r.push(Some(*a), false)).collect();
        assert!(v[150..2000].iter().all(|a| matches!(a, Aid::Moving { .. })));
        let first = (2000..3000)
            .find(|&k| matches!(v[k], Aid::Quiet { .. }))
            .unwrap();
        let Aid::Quiet { since } = v[first] else {
            unreachable!()
        };
        assert!(first - since + 1 >= 2000 && first < 2040, "{first} {since}");
    }

    #[test]
    fn a_creeping_force_is_caught_by_the_drift_test() {
        let c = cfg();
        let mut r = AccelRest::new(c);
        let mut x = noise(4000, c.var.sqrt(), 4);
        // From sample 1000, a lateral force growing by 0.02 m/s^2 per second.
        for (k, a) in x.iter_mut().enumerate().skip(1000) {
            a[1] += 0.02 * (k - 1000) as f64 / 100.0;
        }
        let k = x
            .iter()
            .position(|a| matches!(r.push(Some(*a), false), Aid::Moving { .. }))
            .unwrap();
        assert!((1000..2500).contains(&k), "{k}");
    }

    #[test]
    fn no_reading_is_unknown_and_bad_terms_are_refused() {
        let mut r = AccelRest::new(cfg());
        assert_eq!(r.push(None, false), Aid::Unknown);
        assert_eq!(r.push(Some([f64::NAN, 0.0, 9.8]), false), Aid::Unknown);
        assert_eq!(r.run(), 0);
        assert!(AccelRestConfig::from_terms(0.0, 0.0, 100.0, 100, 25, 4.0, 1.5).is_err());
        assert!(AccelRestConfig::from_terms(0.1, -1.0, 100.0, 100, 25, 4.0, 1.5).is_err());
        assert!(AccelRestConfig::from_terms(0.1, 0.0, 100.0, 100, 25, 4.0, 0.5).is_err());
    }
    #[test]
    fn a_unit_noisier_than_its_terms_is_learnt_at_the_gyros_rests() {
        // The unit's noise is 1.4 times the terms' in variance (the real ADIS16405 against its
        // data sheet): its bounds cut a rest often; learnt at the gyro's rests, rarely.
        let c = cfg();
        let x = noise(60_000, (1.4 * c.var).sqrt(), 5);
        let cuts = |learn: bool| {
            let mut r = AccelRest::new(c);
            let mut quiet = false;
            let mut cuts = 0;
            for a in &x {
                let q = matches!(r.push(Some(*a), learn), Aid::Quiet { .. });
                cuts += usize::from(quiet && !q);
                quiet = q;
            }
            (cuts, r.rest_variance() / c.var)
        };
        let (blind, scale) = cuts(false);
        assert_eq!(scale, 1.0);
        let (learnt, scale) = cuts(true);
        assert!((scale - 1.4).abs() < 0.05, "learnt {scale}");
        assert!(
            blind >= 10 && learnt <= 1,
            "{blind} cuts with the terms, {learnt} learnt"
        );
        // A shake the gyro missed does not teach it: its windows are beyond a rest's bound.
        let mut r = AccelRest::new(c);
        let shaken: Vec<[f64; 3]> = noise(5_000, (10.0 * c.var).sqrt(), 6);
        for a in &shaken {
            r.push(Some(*a), true);
        }
        assert_eq!(r.rest_variance(), c.var);
    }
}
