//! Baselines for the drift model, and how predictors are scored.
//!
//! Gyro drift is close to a random walk, so predicting the last value (persistence) is hard to
//! beat. Every drift model is reported beside persistence, the training mean, and an AR(p) fitted
//! by least squares on the same p lags:
//!
//! - one-step RMSE on held-out samples, each prediction from measured inputs;
//! - skill = 1 - MSE / MSE_persistence (> 0: better than persistence);
//! - free-running RMSE: from measured inputs at the start of each block of `horizon` samples, the
//!   predictor then feeds on its own outputs (what the live compensator does while moving).

// Index loops read like the formulas they implement.
#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Anything that predicts the next drift value from the last `lags()` values.
pub trait Predictor {
    /// Number of past values the prediction needs.
    fn lags(&self) -> usize;
    /// The next value, from `hist` (oldest first, exactly `lags()` values). Must not allocate.
    fn predict(&self, hist: &[f64]) -> f64;
}

impl<P: Predictor + ?Sized> Predictor for &P {
    fn lags(&self) -> usize {
        (**self).lags()
    }
    fn predict(&self, hist: &[f64]) -> f64 {
        (**self).predict(hist)
    }
}

impl<P: Predictor + ?Sized> Predictor for Box<P> {
    fn lags(&self) -> usize {
        (**self).lags()
    }
    fn predict(&self, hist: &[f64]) -> f64 {
        (**self).predict(hist)
    }
}

/// Predict the last value.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Persistence;

impl Predictor for Persistence {
    fn lags(&self) -> usize {
        1
    }
    fn predict(&self, hist: &[f64]) -> f64 {
        hist[hist.len() - 1]
    }
}

/// Predict a constant (the training mean).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mean(pub f64);

impl Predictor for Mean {
    fn lags(&self) -> usize {
        1
    }
    fn predict(&self, _hist: &[f64]) -> f64 {
        self.0
    }
}

/// AR(p) with intercept: `x[t] = c + sum_k a_k x[t - p + k]` (coefficients oldest first).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ar {
    /// Coefficients, oldest lag first.
    pub coef: Vec<f64>,
    /// Intercept c.
    pub intercept: f64,
}

impl Ar {
    /// Least-squares fit on `series` (every row with p predecessors), with a small ridge only
    /// when the normal equations are numerically singular. `None` when the series has fewer
    /// than `2 p + 2` values or no ridge helps (a constant series).
    pub fn fit(series: &[f64], p: usize) -> Option<Ar> {
        if p == 0 || series.len() < 2 * p + 2 {
            return None;
        }
        // Centre on the mean for conditioning; the intercept absorbs it.
        let m = series.iter().sum::<f64>() / series.len() as f64;
        let dim = p + 1;
        let mut ata = DMatrix::<f64>::zeros(dim, dim);
        let mut atb = DVector::<f64>::zeros(dim);
        let mut row = vec![0.0; dim];
        for t in p..series.len() {
            for k in 0..p {
                row[k] = series[t - p + k] - m;
            }
            row[p] = 1.0;
            let y = series[t] - m;
            for i in 0..dim {
                atb[i] += row[i] * y;
                for j in 0..=i {
                    ata[(i, j)] += row[i] * row[j];
                }
            }
        }
        for i in 0..dim {
            for j in 0..i {
                ata[(j, i)] = ata[(i, j)];
            }
        }
        // A very smooth series makes the lags nearly collinear: add a ridge only as needed.
        let mean_diag = (0..p).map(|i| ata[(i, i)]).sum::<f64>() / p as f64;
        let mut sol = None;
        for ridge in [0.0, 1e-12, 1e-10, 1e-8, 1e-6] {
            let mut reg = ata.clone();
            for i in 0..p {
                reg[(i, i)] += ridge * mean_diag;
            }
            if let Some(ch) = reg.cholesky() {
                sol = Some(ch.solve(&atb));
                break;
            }
        }
        let sol = sol?;
        let coef: Vec<f64> = sol.iter().take(p).copied().collect();
        let sum_a: f64 = coef.iter().sum();
        let intercept = sol[p] + m * (1.0 - sum_a);
        if !coef.iter().all(|v| v.is_finite()) || !intercept.is_finite() {
            return None;
        }
        Some(Ar { coef, intercept })
    }
}

impl Predictor for Ar {
    fn lags(&self) -> usize {
        self.coef.len()
    }
    fn predict(&self, hist: &[f64]) -> f64 {
        self.intercept + self.coef.iter().zip(hist).map(|(a, x)| a * x).sum::<f64>()
    }
}

/// Mean squared one-step error of `p` on `series[start..end]` (targets), each from the measured
/// values before it. Targets with fewer than `lags` predecessors are skipped.
pub fn one_step_mse(p: &dyn Predictor, series: &[f64], start: usize, end: usize) -> f64 {
    let lags = p.lags();
    let start = start.max(lags);
    let end = end.min(series.len());
    if end <= start {
        return f64::NAN;
    }
    let mut s = 0.0;
    for t in start..end {
        let e = p.predict(&series[t - lags..t]) - series[t];
        s += e * e;
    }
    s / (end - start) as f64
}

/// Free-running RMSE over `series[start..end]`: in each block of `horizon` targets the predictor
/// starts from measured values and then feeds on its own predictions.
pub fn free_running_rmse(
    p: &dyn Predictor,
    series: &[f64],
    start: usize,
    end: usize,
    horizon: usize,
) -> f64 {
    let lags = p.lags();
    let start = start.max(lags);
    let end = end.min(series.len());
    if end <= start || horizon == 0 {
        return f64::NAN;
    }
    let mut hist = vec![0.0; lags];
    let mut s = 0.0;
    let mut n = 0usize;
    let mut t0 = start;
    while t0 < end {
        hist.copy_from_slice(&series[t0 - lags..t0]);
        for t in t0..(t0 + horizon).min(end) {
            let y = p.predict(&hist);
            let e = y - series[t];
            s += e * e;
            n += 1;
            hist.rotate_left(1);
            hist[lags - 1] = y;
        }
        t0 += horizon;
    }
    (s / n as f64).sqrt()
}

/// One predictor's scores on held-out data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Score {
    /// Predictor name.
    pub name: String,
    /// One-step RMSE.
    pub rmse: f64,
    /// 1 - MSE / MSE_persistence.
    pub skill: f64,
    /// Free-running RMSE over blocks of `horizon` samples.
    pub free_rmse: f64,
}

/// Score `p` against persistence on the same targets.
pub fn score(
    name: &str,
    p: &dyn Predictor,
    series: &[f64],
    start: usize,
    end: usize,
    horizon: usize,
) -> Score {
    // Persistence on the same targets as p (the first target needs p's lags).
    let s0 = start.max(p.lags());
    let mse = one_step_mse(p, series, s0, end);
    let mse_p = one_step_mse(&Persistence, series, s0, end);
    Score {
        name: name.to_string(),
        rmse: mse.sqrt(),
        skill: skill(mse, mse_p),
        free_rmse: free_running_rmse(p, series, s0, end, horizon),
    }
}

/// 1 - mse / mse_persistence (NaN when persistence is perfect).
pub fn skill(mse: f64, mse_persistence: f64) -> f64 {
    if mse_persistence > 0.0 {
        1.0 - mse / mse_persistence
    } else {
        f64::NAN
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn persistence_and_mean_by_hand() {
        let x = [1.0, 2.0, 4.0, 7.0];
        // Persistence errors on targets 1..4: 1, 2, 3 -> MSE 14/3.
        assert!((one_step_mse(&Persistence, &x, 1, 4) - 14.0 / 3.0).abs() < 1e-12);
        // Mean 3: errors on targets 1..4: -1, 1, 4 -> 18/3.
        assert!((one_step_mse(&Mean(3.0), &x, 1, 4) - 6.0).abs() < 1e-12);
        assert!((skill(6.0, 14.0 / 3.0) - (1.0 - 18.0 / 14.0)).abs() < 1e-12);
    }

    #[test]
    fn ar_recovers_a_known_process_exactly() {
        // x[t] = 0.5 + 0.3 x[t-2] + 0.6 x[t-1], noise-free after a start: exact fit.
        let mut x = vec![1.0, -2.0];
        for t in 2..50 {
            let v = 0.5 + 0.3 * x[t - 2] + 0.6 * x[t - 1];
            x.push(v + if t % 3 == 0 { 0.01 } else { 0.0 } * 0.0);
        }
        let ar = Ar::fit(&x, 2).unwrap();
        assert!((ar.coef[0] - 0.3).abs() < 1e-9, "{:?}", ar);
        assert!((ar.coef[1] - 0.6).abs() < 1e-9);
        assert!((ar.intercept - 0.5).abs() < 1e-9);
        assert!(one_step_mse(&ar, &x, 2, 50) < 1e-18);
    }

    #[test]
    fn free_running_by_hand() {
        // Persistence free-running from x[0] over blocks of 2: targets 1,2 from x0; 3,4 from x2.
        let x = [0.0, 1.0, 2.0, 3.0, 5.0];
        // Block 1: predicts 0, 0 for 1, 2 -> errors 1, 2. Block 2: predicts 2, 2 for 3, 5 -> 1, 3.
        let want = ((1.0 + 4.0 + 1.0 + 9.0) / 4.0f64).sqrt();
        assert!((free_running_rmse(&Persistence, &x, 1, 5, 2) - want).abs() < 1e-12);
    }

    #[test]
    fn too_short_for_ar() {
        assert!(Ar::fit(&[1.0, 2.0, 3.0], 2).is_none());
    }
}
