//! The IEEE Std 952 noise terms from an Allan deviation curve.
//!
//! **Fit.** sigma^2(tau) = 3Q^2/tau^2 + N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3 + R^2 tau^2/2 is linear
//! in theta = (Q^2, N^2, B^2, K^2, R^2) >= 0. [`fit_terms`] solves the weighted non-negative least
//! squares problem exactly (every support set of the five columns is solved by Householder QR on
//! the scaled, weighted design; the best feasible one is the NNLS optimum), with weights
//! 1 / Var(sigma_hat^2_j), Var = 2 sigma_j^4 / edf_j + (eps sigma_j^2)^2, sigma_j^2 the model's
//! variance (iterated to a fixed point from the measured variances, so noisy points do not pull
//! their own weights). Deterministic, no starting guess.
//!
//! **Model error eps.** Real sensors bend the shortest taus (band limits, resonances) where the
//! EDF run to hundreds of thousands; with sampling noise alone those points would outvote the
//! whole curve. eps = 0 if the weighted residuals are within the sampling noise
//! (chi^2 / dof <= 1); otherwise eps is the relative model error that brings chi^2 / dof to 1
//! (bisection), which both evens out the weights and widens the intervals by the misfit.
//!
//! **Uncertainty.** Cov(theta) on the support is the sandwich B M B, B = (A^T W A)^-1,
//! M = A^T W V W A, with V_ij = [`RHO`]^|log2(tau_i / tau_j)| s_i s_j (s_j^2 the variance above):
//! the points of one curve share the samples and are correlated. A term's interval is chi-squared
//! with Satterthwaite's nu = 2 theta^2 / Var(theta) degrees of freedom, the same form as a
//! deviation's interval. The closing-loop test (tests/allan_closing_loop.rs) checks on simulated
//! records that the 68.3% intervals of N, B and K hold the truth 58% to 78% of the time.
//!
//! **Not identifiable.** A term is reported as `None` with a reason when the fit drives it to zero
//! (its slope is absent), when it never makes up [`MIN_SHARE`] of the model variance at any tau of
//! the record (what the record shows of it is an extrapolation), or when its square is less than
//! two standard deviations above zero ([`MIN_NU`]).
//!
//! **Read-offs.** [`read_offs`] gives the classic slope-line values for comparison: the segment
//! between neighbouring points whose slope is nearest the term's (within 0.2), the line of the
//! term's slope through its geometric middle, read at tau = sqrt 3 (Q), 1 (N), 3 (K), sqrt 2 (R);
//! B = the interior minimum / sqrt(2 ln2/pi) = min / 0.6643.
//!
//! Everything here is in the base units of [`crate::allan::units::Sensor::base_unit`]: pass
//! deviations in deg/s (a gyro's) or m/s^2 (an accelerometer's); the model is the same.

use super::chi2;
use super::deviation::{AllanPoint, NoiseId};
pub use super::units::Term;

/// Correlation between the variance estimates of points one octave apart (rho^octaves between
/// any two points). 0.5 gives the claimed coverage in the closing-loop test; 0 (independent
/// points) covers only ~55% at 68.3% (docs/allan.md).
pub const RHO: f64 = 0.5;

/// A term's square must lie at least 2 standard deviations above zero (nu = 2 (theta/sd)^2 >= 8)
/// to be reported.
pub const MIN_NU: f64 = 8.0;

/// A term must make up at least this share of the model variance at some tau to be identified.
pub const MIN_SHARE: f64 = 0.3;

/// A value with its confidence interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// The value.
    pub value: f64,
    /// Lower end of the interval.
    pub lo: f64,
    /// Upper end of the interval.
    pub hi: f64,
}

/// One term's outcome: an estimate in base units, or the reason there is none.
#[derive(Debug, Clone, PartialEq)]
pub struct TermFit {
    /// Which term.
    pub term: Term,
    /// The estimate (base units), `None` when the record cannot identify the term.
    pub estimate: Option<Estimate>,
    /// Why there is no estimate.
    pub reason: Option<String>,
    /// How many standard deviations above zero the fit put the term's square, where the fit
    /// got that far (it grows about as the square root of the record's length).
    pub sigmas: Option<f64>,
}

impl TermFit {
    /// The length of record, s, that would identify the term where one of `secs` s fell short
    /// of [`MIN_NU`]: its significance grows about as the square root of the length, so the
    /// length scales with the square of the shortfall, with a quarter more for chance. None
    /// where the fit did not get as far as a significance.
    pub fn record_to_identify(&self, secs: f64) -> Option<f64> {
        let z = self.sigmas.filter(|&z| z > 0.0)?;
        let z_min = (MIN_NU / 2.0).sqrt();
        Some((secs * (z_min / z).powi(2) * 1.25).ceil())
    }

    fn none(term: Term, reason: String) -> Self {
        TermFit {
            term,
            estimate: None,
            reason: Some(reason),
            sigmas: None,
        }
    }
}

/// The fitted model.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseFit {
    /// Q, N, B, K, R in that order.
    pub terms: Vec<TermFit>,
    /// The fitted squares theta = (Q^2, N^2, B^2, K^2, R^2) in base units (zeros included).
    pub theta: [f64; 5],
    /// The two-sided confidence level of the intervals.
    pub ci: f64,
    /// The tau range (s) of the points fitted.
    pub tau_range: (f64, f64),
}

impl NoiseFit {
    /// The outcome for `term`.
    pub fn get(&self, term: Term) -> &TermFit {
        &self.terms[term as usize]
    }

    /// The model's Allan variance at `tau` ((deg/s)^2).
    pub fn model_variance(&self, tau: f64) -> f64 {
        model(&self.theta, tau)
    }

    /// The terms whose read-off ([`read_offs`], in the same order) lies outside the fitted
    /// term's interval.
    pub fn read_offs_outside(&self, read_offs: &[TermFit]) -> Vec<Term> {
        self.terms
            .iter()
            .zip(read_offs)
            .filter(|(f, r)| match (f.estimate, r.estimate) {
                (Some(f), Some(r)) => r.value < f.lo || r.value > f.hi,
                _ => false,
            })
            .map(|(f, _)| f.term)
            .collect()
    }
}

/// The point the B read-off of `read_offs` was taken at (the curve's lowest, as [`read_offs`]
/// takes it), when the noise type there could not be identified: the lowest of scattered points
/// can sit low by chance, and there the scatter is largest. None when there is no B read-off or
/// its point's noise was identified by the slope.
pub fn b_read_off_unidentified<'a>(
    points: &'a [AllanPoint],
    read_offs: &[TermFit],
) -> Option<&'a AllanPoint> {
    read_offs
        .iter()
        .find(|t| t.term == Term::B && t.estimate.is_some())?;
    let p = points.iter().min_by(|a, b| a.dev.total_cmp(&b.dev))?;
    matches!(p.noise_id, NoiseId::Widest { .. }).then_some(p)
}

/// Why no fit was possible.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// Fewer than three usable points.
    #[error(
        "the record gives only {0} usable (non-zero) Allan points: too short or too constant to fit noise terms (at least 3 needed)"
    )]
    TooFewPoints(usize),
}

fn model(theta: &[f64; 5], tau: f64) -> f64 {
    Term::ALL
        .iter()
        .zip(theta)
        .map(|(t, th)| t.coefficient(tau) * th)
        .sum()
}

/// Least squares min |A x - b| for a tall (rows x cols) matrix by Householder QR. Returns x and
/// the inverse of R (upper triangular, so (A^T A)^-1 = Rinv Rinv^T), or None if rank-deficient.
// Matrix code reads best with explicit indices.
#[allow(clippy::needless_range_loop)]
fn qr_solve(a: &[Vec<f64>], b: &[f64], cols: usize) -> Option<(Vec<f64>, Vec<Vec<f64>>)> {
    let rows = a.len();
    if rows < cols {
        return None;
    }
    let mut m: Vec<Vec<f64>> = a.to_vec();
    let mut rhs = b.to_vec();
    let mut diag_max: f64 = 0.0;
    for k in 0..cols {
        let norm = (k..rows).map(|i| m[i][k] * m[i][k]).sum::<f64>().sqrt();
        if norm == 0.0 {
            return None;
        }
        let alpha = if m[k][k] > 0.0 { -norm } else { norm };
        let mut v: Vec<f64> = (k..rows).map(|i| m[i][k]).collect();
        v[0] -= alpha;
        let vnorm2: f64 = v.iter().map(|x| x * x).sum();
        if vnorm2 > 0.0 {
            for j in k..cols {
                let dot: f64 = (k..rows).map(|i| v[i - k] * m[i][j]).sum();
                let f = 2.0 * dot / vnorm2;
                for i in k..rows {
                    m[i][j] -= f * v[i - k];
                }
            }
            let dot: f64 = (k..rows).map(|i| v[i - k] * rhs[i]).sum();
            let f = 2.0 * dot / vnorm2;
            for i in k..rows {
                rhs[i] -= f * v[i - k];
            }
        }
        diag_max = diag_max.max(m[k][k].abs());
    }
    if (0..cols).any(|k| m[k][k].abs() <= 1e-10 * diag_max) {
        return None;
    }
    // Back-substitution for x and for R^-1.
    let mut x = vec![0.0; cols];
    for k in (0..cols).rev() {
        let s: f64 = (k + 1..cols).map(|j| m[k][j] * x[j]).sum();
        x[k] = (rhs[k] - s) / m[k][k];
    }
    let mut rinv = vec![vec![0.0; cols]; cols];
    for c in 0..cols {
        for k in (0..=c).rev() {
            let e = if k == c { 1.0 } else { 0.0 };
            let s: f64 = (k + 1..=c).map(|j| m[k][j] * rinv[j][c]).sum();
            rinv[k][c] = (e - s) / m[k][k];
        }
    }
    Some((x, rinv))
}

/// Weighted NNLS solution and the covariance of the non-zero entries.
fn nnls(points: &[AllanPoint], weights: &[f64]) -> Option<([f64; 5], [[f64; 5]; 5])> {
    let mut best: Option<(f64, [f64; 5], [[f64; 5]; 5])> = None;
    for mask in 1u32..32 {
        let support: Vec<usize> = (0..5).filter(|k| mask & (1 << k) != 0).collect();
        // Scaled, weighted design: row j times sqrt(w_j), column k divided by its norm.
        let raw: Vec<Vec<f64>> = points
            .iter()
            .zip(weights)
            .map(|(p, w)| {
                support
                    .iter()
                    .map(|&k| Term::ALL[k].coefficient(p.tau) * w.sqrt())
                    .collect()
            })
            .collect();
        let scale: Vec<f64> = (0..support.len())
            .map(|c| raw.iter().map(|r| r[c] * r[c]).sum::<f64>().sqrt())
            .collect();
        let a: Vec<Vec<f64>> = raw
            .iter()
            .map(|r| r.iter().zip(&scale).map(|(v, s)| v / s).collect())
            .collect();
        let b: Vec<f64> = points
            .iter()
            .zip(weights)
            .map(|(p, w)| p.dev * p.dev * w.sqrt())
            .collect();
        let Some((x, rinv)) = qr_solve(&a, &b, support.len()) else {
            continue;
        };
        if x.iter().any(|&v| v <= 0.0) {
            continue;
        }
        let mut theta = [0.0; 5];
        for (c, &k) in support.iter().enumerate() {
            theta[k] = x[c] / scale[c];
        }
        let resid: f64 = points
            .iter()
            .zip(weights)
            .map(|(p, w)| w * (p.dev * p.dev - model(&theta, p.tau)).powi(2))
            .sum();
        if best.as_ref().is_none_or(|(r, _, _)| resid < *r) {
            let mut cov = [[0.0; 5]; 5];
            for (c1, &k1) in support.iter().enumerate() {
                for (c2, &k2) in support.iter().enumerate() {
                    let s: f64 = (0..support.len()).map(|j| rinv[c1][j] * rinv[c2][j]).sum();
                    cov[k1][k2] = s / (scale[c1] * scale[c2]);
                }
            }
            best = Some((resid, theta, cov));
        }
    }
    best.map(|(_, t, c)| (t, c))
}

/// One weighted NNLS fit at relative model error `eps`, iterated to a fixed point of the weights.
struct WlsFit {
    theta: [f64; 5],
    bread: [[f64; 5]; 5],
    var_model: Vec<f64>,
    chi2_per_dof: f64,
}

fn fit_with_model_error(points: &[AllanPoint], eps: f64) -> Option<WlsFit> {
    let mut var_model: Vec<f64> = points.iter().map(|p| p.dev * p.dev).collect();
    let mut result = None;
    for _ in 0..50 {
        let weights: Vec<f64> = points
            .iter()
            .zip(&var_model)
            .map(|(p, v)| 1.0 / (2.0 * v * v / p.edf + (eps * v).powi(2)))
            .collect();
        let (theta, bread) = nnls(points, &weights)?;
        let next: Vec<f64> = points
            .iter()
            .zip(&var_model)
            .map(|(p, old)| model(&theta, p.tau).max(old * 1e-6))
            .collect();
        let change = next
            .iter()
            .zip(&var_model)
            .map(|(a, b)| ((a - b) / b).abs())
            .fold(0.0, f64::max);
        var_model = next;
        let chi2: f64 = points
            .iter()
            .zip(&weights)
            .map(|(p, w)| w * (p.dev * p.dev - model(&theta, p.tau)).powi(2))
            .sum();
        let p = theta.iter().filter(|&&t| t > 0.0).count();
        let dof = points.len().saturating_sub(p).max(1);
        result = Some(WlsFit {
            theta,
            bread,
            var_model: var_model.clone(),
            chi2_per_dof: chi2 / dof as f64,
        });
        if change < 1e-12 {
            break;
        }
    }
    result
}

/// Model error: if the residuals exceed the sampling noise (chi^2 / dof > 1), find the
/// relative model error eps that brings chi^2 / dof to 1 (bisection on log eps); the fit with
/// it, and eps (0 when the first fit needs none).
fn with_model_error(points: &[AllanPoint], first: WlsFit) -> (WlsFit, f64) {
    let mut best = first;
    let mut eps = 0.0;
    if best.chi2_per_dof > 1.0 {
        let (mut lo, mut hi) = (1e-6_f64.ln(), 10f64.ln());
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            match fit_with_model_error(points, mid.exp()) {
                Some(f) if f.chi2_per_dof > 1.0 => lo = mid,
                _ => hi = mid,
            }
        }
        eps = hi.exp();
        if let Some(f) = fit_with_model_error(points, eps) {
            best = f;
        }
    }
    (best, eps)
}

/// The terms' covariance by the sandwich: Cov = B M B, B = (A^T W A)^-1, M = A^T W V W A,
/// V_ij = rho^octaves(i, j) s_i s_j with s_j^2 = 2 sigma_j^4 / edf_j + (eps sigma_j^2)^2 the
/// variance the weights assume.
fn sandwich_cov(points: &[AllanPoint], fit: &WlsFit, eps: f64) -> [[f64; 5]; 5] {
    let WlsFit {
        theta,
        bread,
        var_model,
        ..
    } = fit;
    let support: Vec<usize> = (0..5).filter(|&k| theta[k] > 0.0).collect();
    let sd: Vec<f64> = points
        .iter()
        .zip(var_model)
        .map(|(p, v)| (2.0 * v * v / p.edf + (eps * v).powi(2)).sqrt())
        .collect();
    let mut meat = [[0.0; 5]; 5];
    for (i, pi) in points.iter().enumerate() {
        for (j, pj) in points.iter().enumerate() {
            let octaves = (pi.tau / pj.tau).log2().abs();
            let c = RHO.powf(octaves) / (sd[i] * sd[j]);
            for &k in &support {
                for &l in &support {
                    meat[k][l] +=
                        c * Term::ALL[k].coefficient(pi.tau) * Term::ALL[l].coefficient(pj.tau);
                }
            }
        }
    }
    let mut cov = [[0.0; 5]; 5];
    for &k in &support {
        for &l in &support {
            let mut s = 0.0;
            for &i in &support {
                for &j in &support {
                    s += bread[k][i] * meat[i][j] * bread[j][l];
                }
            }
            cov[k][l] = s;
        }
    }
    cov
}

/// Fit the IEEE Std 952 terms to Allan deviation points in deg/s (intended: octave-spaced OADEV
/// with their EDF), with intervals at two-sided confidence `ci`.
pub fn fit_terms(points: &[AllanPoint], ci: f64) -> Result<NoiseFit, FitError> {
    let points: Vec<AllanPoint> = points
        .iter()
        .copied()
        .filter(|p| p.dev > 0.0 && p.edf > 0.0 && p.tau > 0.0)
        .collect();
    if points.len() < 3 {
        return Err(FitError::TooFewPoints(points.len()));
    }
    let Some(first) = fit_with_model_error(&points, 0.0) else {
        return Err(FitError::TooFewPoints(points.len()));
    };
    let (best, eps) = with_model_error(&points, first);
    let cov = sandwich_cov(&points, &best, eps);
    let theta = best.theta;
    let tau_range = (points[0].tau, points[points.len() - 1].tau);
    let terms = Term::ALL
        .iter()
        .enumerate()
        .map(|(k, &term)| {
            let slope = term.slope();
            if theta[k] <= 0.0 {
                return TermFit::none(
                    term,
                    format!(
                        "fitted to zero: no slope {slope:+} region between tau {} s and {} s",
                        tau_range.0, tau_range.1
                    ),
                );
            }
            let share = points
                .iter()
                .map(|p| term.coefficient(p.tau) * theta[k] / model(&theta, p.tau))
                .fold(0.0, f64::max);
            if share < MIN_SHARE {
                return TermFit::none(
                    term,
                    format!(
                        "never dominant (at most {:.0}% of sigma^2 between tau {} s and {} s): the record shows no slope {slope:+} region",
                        share * 100.0,
                        tau_range.0,
                        tau_range.1
                    ),
                );
            }
            let var = cov[k][k];
            let nu = 2.0 * theta[k] * theta[k] / var;
            let sigmas = Some((nu / 2.0).sqrt());
            if nu < MIN_NU {
                return TermFit {
                    sigmas,
                    ..TermFit::none(
                        term,
                        format!(
                            "not significant: {}^2 is only {:.1} standard deviations above zero",
                            term.name(),
                            (nu / 2.0).sqrt()
                        ),
                    )
                };
            }
            let value = theta[k].sqrt();
            let (lo, hi) = chi2::confidence_interval(value, nu, ci);
            TermFit {
                term,
                estimate: Some(Estimate { value, lo, hi }),
                reason: None,
                sigmas,
            }
        })
        .collect();
    Ok(NoiseFit {
        terms,
        theta,
        ci,
        tau_range,
    })
}

/// The classic slope-line read-offs (base units) from a deviation curve in deg/s, each with the
/// interval carried over from the points it was read from.
pub fn read_offs(points: &[AllanPoint]) -> Vec<TermFit> {
    let b_factor = (2.0 * std::f64::consts::LN_2 / std::f64::consts::PI).sqrt();
    Term::ALL
        .iter()
        .map(|&term| {
            if points.len() < 3 {
                return TermFit::none(term, "fewer than 3 points".into());
            }
            if term == Term::B {
                let (j, p) = points
                    .iter()
                    .enumerate()
                    .min_by(|a, b| a.1.dev.total_cmp(&b.1.dev))
                    .unwrap_or((0, &points[0]));
                if j == 0 || j + 1 == points.len() {
                    return TermFit::none(
                        term,
                        "the curve has no interior minimum (no flat floor)".into(),
                    );
                }
                return TermFit {
                    term,
                    estimate: Some(Estimate {
                        value: p.dev / b_factor,
                        lo: p.lo / b_factor,
                        hi: p.hi / b_factor,
                    }),
                    reason: None,
                    sigmas: None,
                };
            }
            let target = term.slope();
            let best = points
                .windows(2)
                .map(|w| {
                    let s = (w[1].dev / w[0].dev).ln() / (w[1].tau / w[0].tau).ln();
                    ((s - target).abs(), w)
                })
                .filter(|(d, _)| d.is_finite() && *d <= 0.2)
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let Some((_, w)) = best else {
                return TermFit::none(
                    term,
                    format!("no segment with slope {target:+} (within 0.2)"),
                );
            };
            let tau_m = (w[0].tau * w[1].tau).sqrt();
            let dev_m = (w[0].dev * w[1].dev).sqrt();
            let lo_ratio = ((w[0].lo / w[0].dev) * (w[1].lo / w[1].dev)).sqrt();
            let hi_ratio = ((w[0].hi / w[0].dev) * (w[1].hi / w[1].dev)).sqrt();
            let tau_read: f64 = match term {
                Term::Q => 3f64.sqrt(),
                Term::N => 1.0,
                Term::K => 3.0,
                _ => 2f64.sqrt(),
            };
            let value = dev_m * (tau_read / tau_m).powf(target);
            TermFit {
                term,
                estimate: Some(Estimate {
                    value,
                    lo: value * lo_ratio,
                    hi: value * hi_ratio,
                }),
                reason: None,
                sigmas: None,
            }
        })
        .collect()
}
