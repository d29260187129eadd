//! A drift model on a record, as `driftless eval` judges it: the daemon's stages offline (the
//! streaming denoiser, then the live compensator with the model, and with its AR and
//! persistence baselines in its place), the paper's Table 3 (the Allan terms of the raw,
//! denoised and compensated rates) and the drift prediction scores.

use super::baselines::{self, Mean, Persistence, Predictor, Score};
use super::compensator::{Compensator, Mode};
use super::model::DriftModel;
use super::separation::{separate_causal, Separated};
use crate::allan::{self, chi2, Kind, TauGrid, Term};
use serde::Serialize;
use std::ops::Range;

/// The paper's Table 3 ratios (compensated / raw) for Q, N, B.
pub const PAPER_RATIOS: [(Term, f64); 3] = [(Term::Q, 0.46), (Term::N, 0.69), (Term::B, 0.61)];

/// The terms of Table 3, in [`Terms::values`] order.
pub const TERMS: [Term; 4] = [Term::Q, Term::N, Term::B, Term::K];

/// Fewest samples a range is evaluated on.
pub const MIN_SAMPLES: usize = 16;

/// One signal's Allan terms (base units: the record's angle unit per second).
#[derive(Debug, Clone, Serialize)]
pub struct Terms {
    /// Signal name.
    pub signal: String,
    /// Q, N, B, K from the IEEE 952 fit (sqrt of the fitted squares; 0 when absent).
    pub values: [f64; 4],
    /// Whether the fit identified each term (its share of the variance is large enough).
    pub identified: [bool; 4],
    /// Fraction of samples in still, moving and warming-up mode (compensated signals).
    pub modes: Option<[f64; 3]>,
    /// The octave OADEV curve the terms were fitted to: (tau s, deviation).
    pub oadev: Vec<(f64, f64)>,
}

/// The Allan terms of `y` at `rate` Hz, named `signal`.
pub fn allan_terms(signal: &str, y: &[f64], rate: f64) -> Result<Terms, String> {
    let pts = allan::allan(y, rate, Kind::Oadev, &TauGrid::Octave, chi2::ONE_SIGMA)
        .map_err(|e| format!("Allan deviation of {signal}: {e}"))?;
    let fit = allan::fit_terms(&pts, chi2::ONE_SIGMA)
        .map_err(|e| format!("IEEE 952 fit of {signal}: {e}"))?;
    let mut values = [0.0; 4];
    let mut identified = [false; 4];
    for (i, t) in TERMS.iter().enumerate() {
        values[i] = fit.theta[*t as usize].max(0.0).sqrt();
        identified[i] = fit.get(*t).estimate.is_some();
    }
    Ok(Terms {
        signal: signal.into(),
        values,
        identified,
        modes: None,
        oadev: pts.iter().map(|p| (p.tau, p.dev)).collect(),
    })
}

/// One compensator's output over a record, sample by sample.
#[derive(Debug, Clone, Default)]
pub struct Compensated {
    /// The compensated rate.
    pub rate: Vec<f64>,
    /// The drift subtracted.
    pub drift: Vec<f64>,
    /// The compensator's mode.
    pub modes: Vec<Mode>,
}

/// The live compensator with predictor `p` and `m`'s settings over a denoised record.
pub fn compensate<P: Predictor>(
    p: P,
    m: &DriftModel,
    denoised: &[f64],
) -> Result<Compensated, String> {
    let lb = m.lowband()?;
    let mut c = Compensator::new(p, lb, m.stillness, m.max_step)?;
    let mut out = Compensated {
        rate: Vec::with_capacity(denoised.len()),
        drift: Vec::with_capacity(denoised.len()),
        modes: Vec::with_capacity(denoised.len()),
    };
    for &x in denoised {
        let s = c.push(x);
        out.rate.push(s.rate);
        out.drift.push(s.drift);
        out.modes.push(s.mode);
    }
    Ok(out)
}

/// Fraction of `modes` still, moving and warming up.
pub fn mode_fractions(modes: &[Mode]) -> [f64; 3] {
    let n = modes.len().max(1) as f64;
    let count = |m: Mode| modes.iter().filter(|&&v| v == m).count() as f64 / n;
    [
        count(Mode::Still),
        count(Mode::Moving),
        count(Mode::Warming),
    ]
}

/// A model run over a whole record and judged on a range of it.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// The record's denoised rate and drift, as the daemon measures them.
    pub separated: Separated,
    /// The compensator with the model's network.
    pub rbf: Compensated,
    /// Table 3: raw, denoised, then compensated with the RBF, the AR and persistence, each on
    /// the judged range.
    pub table: Vec<Terms>,
    /// One-step and free-running (1 s) drift prediction scores on the judged range, the
    /// measured drift as inputs: persistence, mean, AR(p), RBF.
    pub prediction: Vec<Score>,
}

/// Run `model` over the whole of `x` (the stages start at sample 0) and judge it on `range`.
pub fn evaluate(model: &DriftModel, x: &[f64], range: Range<usize>) -> Result<Evaluation, String> {
    if range.end > x.len() || range.len() < MIN_SAMPLES {
        return Err(format!(
            "samples {}..{} of a record of {} are too few to evaluate (need at least {MIN_SAMPLES})",
            range.start,
            range.end,
            x.len()
        ));
    }
    let rate = model.rate_hz;
    let sep = separate_causal(x, &model.separation.denoise, &model.separation.lowband)?;
    let net = &model.network;
    let ar = &model.baselines.ar;
    let rbf = compensate(net, model, &sep.denoised)?;
    let by_ar = compensate(ar, model, &sep.denoised)?;
    let persistence = compensate(Persistence, model, &sep.denoised)?;
    let r = range.clone();
    let mut table = vec![
        allan_terms("raw", &x[r.clone()], rate)?,
        allan_terms("denoised", &sep.denoised[r.clone()], rate)?,
    ];
    for (name, c) in [
        ("compensated (RBF)", &rbf),
        ("compensated (AR)", &by_ar),
        ("compensated (persistence)", &persistence),
    ] {
        let mut t = allan_terms(name, &c.rate[r.clone()], rate)?;
        t.modes = Some(mode_fractions(&c.modes[r.clone()]));
        table.push(t);
    }
    let horizon = rate.round().max(1.0) as usize;
    let prediction: Vec<Score> = [
        ("persistence", &Persistence as &dyn Predictor),
        ("mean", &Mean(model.baselines.mean)),
        (&format!("AR({})", ar.coef.len()), ar),
        (&format!("RBF({} centres)", net.centre_count()), net),
    ]
    .iter()
    .map(|(name, p)| baselines::score(name, *p, &sep.drift, range.start, range.end, horizon))
    .collect();
    Ok(Evaluation {
        separated: sep,
        rbf,
        table,
        prediction,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mode_fractions_sum_to_one() {
        let m = [Mode::Still, Mode::Still, Mode::Moving, Mode::Warming];
        assert_eq!(mode_fractions(&m), [0.5, 0.25, 0.25]);
        assert_eq!(mode_fractions(&[]), [0.0; 3]);
    }

    #[test]
    fn the_terms_of_white_noise_are_n_alone() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        // Seeded white noise of 0.1 deg/s at 100 Hz: N = 0.1 / sqrt(100) deg/sqrt(s).
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let normal = Normal::new(0.0, 0.1).unwrap();
        let y: Vec<f64> = (0..200_000).map(|_| normal.sample(&mut rng)).collect();
        let t = allan_terms("white", &y, 100.0).unwrap();
        assert!(t.identified[1], "{t:?}");
        assert!((t.values[1] / 0.01 - 1.0).abs() < 0.05, "{t:?}");
        assert!(allan_terms("short", &y[..2], 100.0)
            .unwrap_err()
            .starts_with("Allan deviation of short"));
    }
}
