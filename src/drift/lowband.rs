//! Causal drift separation: the low band of a rate, one sample at a time.
//!
//! The paper takes the drift to be the wavelet approximation at level J (its Figure 7). Offline
//! that is a non-causal reconstruction; live it cannot be. Here the approximation is the causal
//! stationary (à trous) one: `a_0 = x`, `a_j[t] = sum_k g[k] a_(j-1)[t - k 2^(j-1)]`, with
//! `g` the low-pass filter / sqrt 2 (DC gain 1, so a constant passes unchanged). Its equivalent
//! filter spans `(2^J - 1)(F - 1) + 1` samples (342 for db6 at level 5): the band below about
//! `rate / 2^(J+1)` Hz, delayed by [`LowBand::delay`] samples.
//!
//! Orientation matters: Daubechies filters are extremal-phase. Convolving with `dec_lo` as
//! PyWavelets stores it puts the energy at the end of the filter and delays db6 / level 5 by 298
//! samples; its reverse (`rec_lo`) has the same magnitude response and delays it by 43. The drift
//! estimate is subtracted from the current rate, so its lag turns into added noise near the band
//! edge (on the real ADIS16405 log, OADEV at 1.28 s: 1.40 x raw with 298 samples of lag, 0.96 x
//! with 43): we use the reverse. Cost: `J F` multiply-adds per sample, no allocation after
//! construction.

use crate::wavelet::{Wavelet, WaveletError};

/// The causal level-J approximation of a stream.
#[derive(Debug, Clone)]
pub struct LowBand {
    g: Vec<f64>,
    levels: usize,
    /// One ring per level j (holding `a_(j-1)`), each `mask + 1` long (a power of two).
    rings: Vec<Vec<f64>>,
    masks: Vec<usize>,
    pos: usize,
    started: bool,
}

impl LowBand {
    /// A low band for `wavelet` at `level` (1 to 12).
    pub fn new(wavelet: &str, level: usize) -> Result<Self, WaveletError> {
        let w = Wavelet::by_name(wavelet)?;
        if !(1..=12).contains(&level) {
            return Err(WaveletError::BadParameter(format!(
                "low-band level must be 1 to 12, not {level}"
            )));
        }
        // The decomposition low-pass reversed (= rec_lo): the same magnitude response, but
        // Daubechies filters are extremal-phase, and this orientation puts the energy first, so
        // the cascade lags 43 samples instead of 298 for db6 at level 5.
        let g: Vec<f64> = w
            .dec_lo()
            .iter()
            .rev()
            .map(|v| v / std::f64::consts::SQRT_2)
            .collect();
        let f = g.len();
        let mut rings = Vec::with_capacity(level);
        let mut masks = Vec::with_capacity(level);
        for j in 1..=level {
            let span = (f - 1) * (1 << (j - 1)) + 1;
            let cap = span.next_power_of_two();
            rings.push(vec![0.0; cap]);
            masks.push(cap - 1);
        }
        Ok(LowBand {
            g,
            levels: level,
            rings,
            masks,
            pos: 0,
            started: false,
        })
    }

    /// Samples the equivalent filter spans: `(2^J - 1)(F - 1) + 1`.
    pub fn span(&self) -> usize {
        ((1usize << self.levels) - 1) * (self.g.len() - 1) + 1
    }

    /// Group delay at DC of the equivalent filter, in samples (its centroid).
    pub fn delay(&self) -> f64 {
        // The equivalent filter is the cascade of g upsampled by 2^(j-1): centroids add.
        let c1: f64 = self
            .g
            .iter()
            .enumerate()
            .map(|(k, v)| k as f64 * v)
            .sum::<f64>()
            / self.g.iter().sum::<f64>();
        c1 * ((1usize << self.levels) - 1) as f64
    }

    /// Forget the past.
    pub fn reset(&mut self) {
        self.started = false;
        self.pos = 0;
    }

    /// Push one sample, get the low band at this sample. The first sample fills the history,
    /// so a constant input gives that constant from the start.
    pub fn push(&mut self, x: f64) -> f64 {
        if !self.started {
            for r in &mut self.rings {
                r.fill(x);
            }
            self.started = true;
        }
        self.pos = self.pos.wrapping_add(1);
        let mut a = x;
        for j in 0..self.levels {
            let ring = &mut self.rings[j];
            let mask = self.masks[j];
            let step = 1usize << j;
            ring[self.pos & mask] = a;
            let mut acc = 0.0;
            let mut idx = self.pos;
            for &gk in &self.g {
                acc += gk * ring[idx & mask];
                idx = idx.wrapping_sub(step);
            }
            a = acc;
        }
        a
    }

    /// The low band of a whole record (a fresh filter run over it).
    pub fn run(&mut self, x: &[f64]) -> Vec<f64> {
        self.reset();
        x.iter().map(|&v| self.push(v)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_passes_and_span_matches_db6_level5() {
        let mut lb = LowBand::new("db6", 5).unwrap();
        assert_eq!(lb.span(), 342);
        // The short-delay orientation (the reverse would be 298 samples).
        assert!((lb.delay() - 42.85).abs() < 0.01, "delay {}", lb.delay());
        for _ in 0..1000 {
            assert!((lb.push(2.5) - 2.5).abs() < 1e-12);
        }
    }

    #[test]
    fn impulse_response_has_the_span_and_unit_sum() {
        let mut lb = LowBand::new("db4", 3).unwrap();
        let n = lb.span() + 50;
        let mut x = vec![0.0; n];
        x[0] = 0.0;
        let _ = lb.push(0.0);
        x[1] = 1.0;
        let y: Vec<f64> = x[1..].iter().map(|&v| lb.push(v)).collect();
        let sum: f64 = y.iter().sum();
        assert!((sum - 1.0).abs() < 1e-12, "sum {sum}");
        // Nothing beyond the span.
        assert!(y[lb.span()..].iter().all(|v| v.abs() < 1e-15));
        assert!(y[lb.span() - 1].abs() > 0.0);
        let centroid: f64 = y.iter().enumerate().map(|(k, v)| k as f64 * v).sum();
        assert!((centroid - lb.delay()).abs() < 1e-9);
    }

    #[test]
    fn white_noise_is_attenuated() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let x: Vec<f64> = (0..20000)
            .map(|_| StandardNormal.sample(&mut rng))
            .collect();
        let y = LowBand::new("db6", 5).unwrap().run(&x);
        let var = y[500..].iter().map(|v| v * v).sum::<f64>() / (y.len() - 500) as f64;
        // Level 5 keeps ~1/32 of white power.
        assert!(var < 0.06 && var > 0.015, "var {var}");
    }
}
