//! Batch wavelet-threshold denoising and the drift / white-noise split (the paper's Figure 7).
//!
//! Decompose with [`Plan`], estimate the noise sigma from the finest details (scikit-image's
//! estimator), pick a threshold per detail level by a [`Rule`], threshold every detail level with a
//! [`ThresholdFn`] (the approximation is kept), reconstruct.

use super::threshold::ThresholdFn;
use super::transform::{Mode, Plan, SPLIT_MIN};
use super::{Wavelet, WaveletError};
use crate::bigbuf::{self, Scratch};
use rayon::prelude::*;

/// Phi^-1(3/4): the median of |N(0, 1)|.
pub const MAD_TO_SIGMA: f64 = 0.6744897501960817;

/// How the noise standard deviation is obtained.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoiseSigma {
    /// median(|finest details|) / 0.6745, exact zeros excluded (scikit-image's `_sigma_est_dwt`).
    Mad,
    /// The same estimator applied to each detail level separately.
    MadPerLevel,
    /// A known sigma, in the signal's units.
    Fixed(f64),
}

/// How each detail level's threshold lambda is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rule {
    /// `sigma sqrt(2 ln N)`, N the signal length (VisuShrink; the paper's rule).
    Universal,
    /// `sigma_j sqrt(2 ln N_j)`, N_j the number of coefficients at level j.
    LevelUniversal,
    /// SureShrink (Donoho & Johnstone 1995, hybrid): the SURE-optimal soft threshold per level,
    /// falling back to universal where the level is too sparse for SURE to be reliable.
    Sure,
    /// BayesShrink (Chang, Yu & Vetterli 2000): `sigma^2 / sigma_x` per level.
    Bayes,
    /// One fixed lambda for every level.
    Fixed(f64),
}

impl Rule {
    /// The rule's name as the command line takes it.
    pub fn name(&self) -> String {
        match self {
            Rule::Universal => "universal".into(),
            Rule::LevelUniversal => "level-universal".into(),
            Rule::Sure => "sure".into(),
            Rule::Bayes => "bayes".into(),
            Rule::Fixed(v) => v.to_string(),
        }
    }
}

impl std::str::FromStr for Rule {
    type Err = WaveletError;
    /// `universal`, `level-universal`, `sure`, `bayes`, or a fixed lambda (a finite number >= 0).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "universal" => Ok(Rule::Universal),
            "level-universal" => Ok(Rule::LevelUniversal),
            "sure" => Ok(Rule::Sure),
            "bayes" => Ok(Rule::Bayes),
            _ => match s.parse::<f64>() {
                Ok(v) if v.is_finite() && v >= 0.0 => Ok(Rule::Fixed(v)),
                _ => Err(WaveletError::UnknownRule(s.to_string())),
            },
        }
    }
}

/// Everything batch denoising needs.
#[derive(Debug, Clone, PartialEq)]
pub struct DenoiseConfig {
    /// Wavelet (the paper: db6).
    pub wavelet: Wavelet,
    /// Signal extension (PyWavelets' default: symmetric).
    pub mode: Mode,
    /// Decomposition levels (the paper: 5).
    pub level: usize,
    /// Threshold function.
    pub threshold: ThresholdFn,
    /// Threshold rule.
    pub rule: Rule,
    /// Noise sigma estimate.
    pub sigma: NoiseSigma,
}

impl DenoiseConfig {
    /// The paper's settings: db6, 5 levels, symmetric, improved threshold, universal rule, MAD sigma.
    pub fn paper() -> Self {
        DenoiseConfig {
            wavelet: Wavelet::by_name("db6").expect("db6 is built in"),
            mode: Mode::Symmetric,
            level: 5,
            threshold: ThresholdFn::improved_default(),
            rule: Rule::Universal,
            sigma: NoiseSigma::Mad,
        }
    }
}

/// The result of [`denoise`].
#[derive(Debug, Clone, PartialEq)]
pub struct Denoised {
    /// The denoised signal, as long as the input.
    pub signal: Vec<f64>,
    /// Noise sigma used at each detail level, finest (level 1) first.
    pub sigma: Vec<f64>,
    /// Threshold lambda applied at each detail level, finest (level 1) first.
    pub lambda: Vec<f64>,
}

/// median(|x|) / 0.6745 over the nonzero entries of `details` (0 when all are zero), using
/// `scratch` (at least as long as `details`) for the copy. Even counts average the two middle
/// values, as numpy's median does.
///
/// # Panics
/// If `scratch` is shorter than `details`.
pub fn mad_sigma(details: &[f64], scratch: &mut [f64]) -> f64 {
    let scratch = &mut scratch[..details.len()];
    let mut n = 0;
    for &d in details {
        // Branch-free: every value is written, only nonzero ones are kept.
        scratch[n.min(details.len() - 1)] = d.abs();
        n += usize::from(d != 0.0);
    }
    if n == 0 {
        return 0.0;
    }
    // Non-negative finite values order as their bit patterns: integer compares, same order.
    let values = &mut scratch[..n];
    let (below, upper, _) = values.select_nth_unstable_by_key(n / 2, |v| v.to_bits());
    let upper = *upper;
    let median = if n % 2 == 1 {
        upper
    } else {
        let lower = below.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lower + upper)
    };
    median / MAD_TO_SIGMA
}

/// SureShrink's threshold for details `d` with noise `sigma` (hybrid rule), using `scratch`.
fn sure_lambda(d: &[f64], sigma: f64, scratch: &mut Vec<f64>) -> f64 {
    let n = d.len();
    if n == 0 || sigma <= 0.0 {
        return 0.0;
    }
    let nf = n as f64;
    let universal = (2.0 * nf.ln()).sqrt();
    // Sparse levels: SURE is unreliable, use the universal threshold (Donoho & Johnstone 1995).
    let energy: f64 = d.iter().map(|v| (v / sigma).powi(2)).sum();
    let eta = (energy - nf) / nf;
    let critical = nf.log2().powf(1.5) / nf.sqrt();
    if eta <= critical {
        return sigma * universal;
    }
    scratch.clear();
    scratch.extend(d.iter().map(|v| (v / sigma).powi(2)));
    scratch.sort_unstable_by(f64::total_cmp);
    // SURE(t = |x|_(k)) = n - 2k + sum_{i<=k} x_(i)^2 + (n - k) x_(k)^2, k = 1..n (1-based).
    // t = 0 (keep everything) has risk n.
    let (mut best, mut best_risk, mut cumulative) = (0.0, nf, 0.0);
    for (i, &x2) in scratch.iter().enumerate() {
        let k = (i + 1) as f64;
        cumulative += x2;
        let risk = nf - 2.0 * k + cumulative + (nf - k) * x2;
        if risk < best_risk {
            best_risk = risk;
            best = x2.sqrt();
        }
    }
    sigma * best.min(universal)
}

/// BayesShrink's threshold: `sigma^2 / sqrt(max(mean(d^2) - sigma^2, eps))` (scikit-image's form).
fn bayes_lambda(d: &[f64], sigma: f64) -> f64 {
    if d.is_empty() {
        return 0.0;
    }
    let variance = d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64;
    sigma * sigma / (variance - sigma * sigma).max(f64::EPSILON).sqrt()
}

fn check_signal(x: &[f64], cfg: &DenoiseConfig) -> Result<(), WaveletError> {
    // A vectorisable scan first; the position only when there is something to report.
    if x.iter().fold(false, |bad, v| bad | !v.is_finite()) {
        let i = x.iter().position(|v| !v.is_finite()).unwrap_or(0);
        return Err(WaveletError::BadParameter(format!(
            "sample {i} is {}: the signal must be finite",
            x[i]
        )));
    }
    if let NoiseSigma::Fixed(s) = cfg.sigma {
        if !(s >= 0.0 && s.is_finite()) {
            return Err(WaveletError::BadParameter(format!(
                "a fixed sigma must be finite and >= 0, got {s}"
            )));
        }
    }
    cfg.threshold.validate()
}

/// Wavelet-threshold denoise `x`.
pub fn denoise(x: &[f64], cfg: &DenoiseConfig) -> Result<Denoised, WaveletError> {
    check_signal(x, cfg)?;
    let mut plan = Plan::new(&cfg.wavelet, cfg.mode, x.len(), cfg.level)?;
    let ranges = plan.ranges().to_vec();
    // ranges = [cA_L, cD_L, ..., cD_1]; level j's details sit at ranges[L + 1 - j].
    let detail = |j: usize| ranges[cfg.level + 1 - j].clone();
    let mut coeffs = Scratch::for_overwrite(plan.coeffs_len());
    plan.wavedec(x, &mut coeffs);
    let mad_scratch = plan.spare();
    let mut scratch = Vec::new();
    let global = match cfg.sigma {
        NoiseSigma::Fixed(s) => s,
        _ => mad_sigma(&coeffs[detail(1)], mad_scratch),
    };
    let n = x.len() as f64;
    let mut sigma = Vec::with_capacity(cfg.level);
    let mut lambda = Vec::with_capacity(cfg.level);
    for j in 1..=cfg.level {
        let d = &mut coeffs[detail(j)];
        let s = match cfg.sigma {
            NoiseSigma::MadPerLevel => mad_sigma(d, mad_scratch),
            _ => global,
        };
        let l = match cfg.rule {
            Rule::Universal => s * (2.0 * n.ln()).sqrt(),
            Rule::LevelUniversal => s * (2.0 * (d.len() as f64).max(1.0).ln()).sqrt(),
            Rule::Sure => sure_lambda(d, s, &mut scratch),
            Rule::Bayes => bayes_lambda(d, s),
            Rule::Fixed(v) => v,
        };
        if d.len() >= SPLIT_MIN {
            d.par_chunks_mut(SPLIT_MIN / 4)
                .for_each(|part| cfg.threshold.apply_all(part, l));
        } else {
            cfg.threshold.apply_all(d, l);
        }
        sigma.push(s);
        lambda.push(l);
    }
    let mut signal = bigbuf::zeroed(x.len());
    plan.waverec(&coeffs, &mut signal);
    Ok(Denoised {
        signal,
        sigma,
        lambda,
    })
}

/// The paper's Figure 7 split of a signal into its low band and the rest.
#[derive(Debug, Clone, PartialEq)]
pub struct Separation {
    /// The approximation at the split level alone, reconstructed: the drift.
    pub drift: Vec<f64>,
    /// Everything else (`x - drift`): white noise on a static log.
    pub noise: Vec<f64>,
}

/// Split `x` into the approximation at `level` (drift) and the details up to it (noise).
pub fn separate(
    x: &[f64],
    wavelet: &Wavelet,
    mode: Mode,
    level: usize,
) -> Result<Separation, WaveletError> {
    let mut plan = Plan::new(wavelet, mode, x.len(), level)?;
    let mut coeffs = Scratch::for_overwrite(plan.coeffs_len());
    plan.wavedec(x, &mut coeffs);
    let approx_end = plan.ranges()[0].end;
    coeffs[approx_end..].fill(0.0);
    let mut drift = bigbuf::zeroed(x.len());
    plan.waverec(&coeffs, &mut drift);
    let noise = x.iter().zip(&drift).map(|(a, b)| a - b).collect();
    Ok(Separation { drift, noise })
}

/// One row of a comparison of threshold functions on the same data (the paper's Table 2).
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// The threshold function.
    pub function: ThresholdFn,
    /// Its output.
    pub denoised: Denoised,
    /// SNR against the truth in dB, when a truth is known.
    pub snr_db: Option<f64>,
    /// MSE against the truth, when a truth is known.
    pub mse: Option<f64>,
    /// RMS of what was removed (input minus output).
    pub rms_removed: f64,
}

/// Denoise `x` with each of hard, soft, garrote, firm and improved (other settings from `cfg`;
/// `cfg`'s own function keeps its parameters), scoring against `truth` when given.
pub fn compare(
    x: &[f64],
    truth: Option<&[f64]>,
    cfg: &DenoiseConfig,
) -> Result<Vec<Comparison>, WaveletError> {
    // The chosen function keeps its parameters; the others run with their defaults.
    let functions = ThresholdFn::NAMES.map(|name| {
        if name == cfg.threshold.name() {
            cfg.threshold
        } else {
            name.parse().expect("NAMES parse")
        }
    });
    functions
        .into_iter()
        .map(|function| {
            let denoised = denoise(
                x,
                &DenoiseConfig {
                    threshold: function,
                    ..cfg.clone()
                },
            )?;
            Ok(Comparison {
                function,
                snr_db: truth.map(|t| crate::quality::snr_db(t, &denoised.signal)),
                mse: truth.map(|t| crate::quality::mse(t, &denoised.signal)),
                rms_removed: crate::quality::rms_diff(x, &denoised.signal),
                denoised,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Work buffers come back from the pool holding what an earlier call left: a call that read
    /// one before writing it would give different bits (NaN here) on the second run.
    #[test]
    fn reused_work_buffers_change_nothing() {
        let n = 300_001;
        let x: Vec<f64> = crate::synthetic::SplitMix64(7)
            .take(n)
            .map(|u| u - 0.5)
            .collect();
        let cfg = DenoiseConfig::paper();
        let first = denoise(&x, &cfg).expect("valid");
        let split = separate(&x, &cfg.wavelet, cfg.mode, 3).expect("valid");
        for len in [n / 2 + 6, n / 2, n + 40, 3 * n] {
            let mut poison = Scratch::for_overwrite(len);
            poison.fill(f64::NAN);
        }
        let again = denoise(&x, &cfg).expect("valid");
        let split_again = separate(&x, &cfg.wavelet, cfg.mode, 3).expect("valid");
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&again.signal), bits(&first.signal));
        assert_eq!(bits(&split_again.drift), bits(&split.drift));
        assert!(again.signal.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn mad_sigma_matches_numpy_median_and_skips_zeros() {
        let mut s = vec![0.0; 6];
        // nonzero |d| = [1, 2, 3, 4] -> median 2.5
        let v = mad_sigma(&[0.0, -1.0, 2.0, 0.0, -3.0, 4.0], &mut s);
        assert!((v - 2.5 / MAD_TO_SIGMA).abs() < 1e-15);
        let v = mad_sigma(&[5.0, -1.0, 2.0], &mut s);
        assert!((v - 2.0 / MAD_TO_SIGMA).abs() < 1e-15);
        assert_eq!(mad_sigma(&[0.0, 0.0], &mut s), 0.0);
    }

    #[test]
    fn rules_parse_and_list_choices() {
        assert_eq!("sure".parse::<Rule>().unwrap(), Rule::Sure);
        assert_eq!("0.25".parse::<Rule>().unwrap(), Rule::Fixed(0.25));
        let e = "median".parse::<Rule>().unwrap_err().to_string();
        assert!(e.contains("universal, level-universal, sure, bayes"), "{e}");
        assert!("-1".parse::<Rule>().is_err());
        assert!("NaN".parse::<Rule>().is_err());
    }

    #[test]
    fn sure_picks_small_threshold_on_dense_signal_and_universal_on_noise() {
        let mut s = Vec::new();
        // Pure unit noise (deterministic, roughly Gaussian-looking): sparse -> universal.
        let noise: Vec<f64> = (0..1024)
            .map(|i| ((i * 7919 % 1000) as f64 / 1000.0 - 0.5) * 0.2)
            .collect();
        let l = sure_lambda(&noise, 1.0, &mut s);
        assert!((l - (2.0 * 1024f64.ln()).sqrt()).abs() < 1e-12, "{l}");
        // A dense strong signal: SURE's optimum is well below universal.
        let dense: Vec<f64> = (0..1024).map(|i| 5.0 + (i % 7) as f64).collect();
        assert!(sure_lambda(&dense, 1.0, &mut s) < 1.0);
    }

    #[test]
    fn separation_splits_drift_from_white_noise() {
        use rand::SeedableRng;
        use rand_distr::Distribution;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let white = rand_distr::Normal::new(0.0, 0.3).unwrap();
        let drift: Vec<f64> = (0..20_000)
            .map(|i| 0.5 + 0.1 * (i as f64 / 3000.0).sin())
            .collect();
        let noise: Vec<f64> = (0..drift.len()).map(|_| white.sample(&mut rng)).collect();
        let x: Vec<f64> = drift.iter().zip(&noise).map(|(d, n)| d + n).collect();
        let w = Wavelet::by_name("db6").unwrap();
        let split = separate(&x, &w, Mode::Symmetric, 6).unwrap();
        for ((d, n), v) in split.drift.iter().zip(&split.noise).zip(&x) {
            assert!((d + n - v).abs() < 1e-12);
        }
        // The low band keeps 1/64 of the white noise's power: its error is ~0.3/8 = 0.04.
        let err = crate::quality::rms_diff(&split.drift, &drift);
        assert!(err < 0.06, "drift error {err}");
        let noise_sd = crate::quality::rms_diff(&split.noise, &vec![0.0; x.len()]);
        assert!((noise_sd / 0.3 - 1.0).abs() < 0.02, "noise sd {noise_sd}");
        assert!(separate(&x[..100], &w, Mode::Symmetric, 6).is_err());
    }

    #[test]
    fn bayes_kills_pure_noise_level() {
        assert!(bayes_lambda(&[0.1, -0.1], 1.0) > 1e6);
        let l = bayes_lambda(&[3.0, -3.0, 3.0, -3.0], 1.0);
        assert!((l - 1.0 / 8f64.sqrt()).abs() < 1e-12);
    }
}
