//! Seeded synthetic gyro records with a known truth: the denoising benchmark behind our Table 2.
//!
//! Two regimes at the paper's 50 Hz and 18,000 samples, white Gaussian noise of
//! [`NOISE_SIGMA`] deg/s (about an ADXRS450's at 50 Hz) on top:
//! - **static**: a bias with slow drift only (periods of minutes), what a gyro on a bench reads;
//! - **dynamic**: the same plus manoeuvres: sines between 0.2 and 3 Hz and rate steps.
//!
//! Pure and deterministic: the same seed gives the same record on every machine (ChaCha8).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::PI;

/// Sample rate of the benchmark records (the paper's).
pub const RATE_HZ: f64 = 50.0;
/// Length of the benchmark records (the paper's Table 2).
pub const SAMPLES: usize = 18_000;
/// White noise standard deviation in deg/s.
pub const NOISE_SIGMA: f64 = 0.25;

/// Which kind of motion the truth holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Regime {
    /// Bias and slow drift only.
    Static,
    /// Bias, slow drift, sines (0.2-3 Hz) and rate steps.
    Dynamic,
}

impl Regime {
    /// The regime's name.
    pub fn name(self) -> &'static str {
        match self {
            Regime::Static => "static",
            Regime::Dynamic => "dynamic",
        }
    }
}

impl std::str::FromStr for Regime {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "static" => Ok(Regime::Static),
            "dynamic" => Ok(Regime::Dynamic),
            _ => Err(format!(
                "unknown synthetic regime '{s}' (valid: static, dynamic)"
            )),
        }
    }
}

/// A synthetic record: what a perfect gyro reads, and what ours reads.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// Sample rate in Hz.
    pub rate_hz: f64,
    /// True rate, deg/s.
    pub truth: Vec<f64>,
    /// Truth plus white noise, deg/s.
    pub measured: Vec<f64>,
}

/// The benchmark record of `regime` with `n` samples at [`RATE_HZ`], seeded by `seed`.
pub fn record(regime: Regime, n: usize, seed: u64) -> Record {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, NOISE_SIGMA).expect("a positive constant sigma");
    // Random phases and step times come from the same seeded stream as the noise.
    let mut uniform = || rand::Rng::random::<f64>(&mut rng);
    let phases: [f64; 6] = std::array::from_fn(|_| 2.0 * PI * uniform());
    // Rate steps: a new level every 4-12 s, between -4 and 4 deg/s.
    let mut steps = Vec::new();
    let mut t_step = 0.0;
    let duration = n as f64 / RATE_HZ;
    while t_step < duration {
        steps.push((t_step, 8.0 * uniform() - 4.0));
        t_step += 4.0 + 8.0 * uniform();
    }
    let truth: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 / RATE_HZ;
            let drift = 0.3
                + 0.08 * (2.0 * PI * t / 240.0 + phases[0]).sin()
                + 0.05 * (2.0 * PI * t / 97.0 + phases[1]).sin();
            match regime {
                Regime::Static => drift,
                Regime::Dynamic => {
                    let step = steps
                        .iter()
                        .take_while(|(start, _)| *start <= t)
                        .last()
                        .map_or(0.0, |s| s.1);
                    drift
                        + step
                        + 3.0 * (2.0 * PI * 0.2 * t + phases[2]).sin()
                        + 1.5 * (2.0 * PI * 0.7 * t + phases[3]).sin()
                        + 0.8 * (2.0 * PI * 1.6 * t + phases[4]).sin()
                        + 0.4 * (2.0 * PI * 3.0 * t + phases[5]).sin()
                }
            }
        })
        .collect();
    let measured = truth.iter().map(|s| s + noise.sample(&mut rng)).collect();
    Record {
        rate_hz: RATE_HZ,
        truth,
        measured,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeded_and_noisy_as_promised() {
        let a = record(Regime::Dynamic, 5000, 7);
        assert_eq!(a, record(Regime::Dynamic, 5000, 7));
        assert_ne!(a.measured, record(Regime::Dynamic, 5000, 8).measured);
        let noise: Vec<f64> = a
            .measured
            .iter()
            .zip(&a.truth)
            .map(|(m, t)| m - t)
            .collect();
        let sd = (noise.iter().map(|v| v * v).sum::<f64>() / noise.len() as f64).sqrt();
        assert!((sd / NOISE_SIGMA - 1.0).abs() < 0.05, "noise sd {sd}");
        let s = record(Regime::Static, 5000, 7);
        let spread = s.truth.iter().fold(0.0f64, |m, v| m.max((v - 0.3).abs()));
        assert!(spread < 0.14, "static truth moves too much: {spread}");
    }
}

/// splitmix64 (Steele, Lea & Flood 2014) as uniform doubles `(u >> 11) * 2^-53` in [0, 1), seeded
/// by its state: the exact integer generator that our fixture scripts (`scripts/gen_*.py`)
/// reimplement, so that reference inputs are regenerated bit for bit instead of stored.
#[derive(Debug, Clone)]
pub struct SplitMix64(pub u64);

impl Iterator for SplitMix64 {
    type Item = f64;
    fn next(&mut self) -> Option<f64> {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        Some((z >> 11) as f64 * 2f64.powi(-53))
    }
}
