//! Training the RBF network on a drift series.
//!
//! 1. Rows: the p lagged values ([`InputForm`]) and the target ([`Target`]) for every sample with
//!    p predecessors. Features and target are normalised by their mean and standard deviation;
//!    the normalisation is stored in the model.
//! 2. Centres: seeded k-means++ and Lloyd iterations on a seeded subsample of rows, or forward
//!    selection by orthogonal least squares (Chen, Cowan & Grant 1991, what MATLAB's `newrb` does):
//!    candidates are training rows; each step adds the one whose orthogonalised regressor explains
//!    the most remaining target energy, after the bias (and the linear terms) are accounted for.
//! 3. Widths: beta_i = `width_scale` x the distance from centre i to its nearest other centre.
//! 4. Output weights, linear weights and bias: ridge least squares (normal equations, Cholesky,
//!    `nalgebra`); the ridge is relative to the mean diagonal of the normal matrix.
//! 5. Optional Adam refinement of centres, log-widths and all weights on mini-batches, with
//!    early stopping on a validation split (the last `validation` fraction of rows, in time
//!    order, so the check is on later data); the best validation parameters are kept.
//!
//! Everything random comes from one ChaCha8 stream seeded by `seed`: the same data, settings and
//! seed give bit-identical models.

// Index loops read like the formulas they implement.
#![allow(clippy::needless_range_loop)]

use super::rbf::{InputForm, Rbf, Target};
use super::MAX_LAGS;
use nalgebra::{DMatrix, DVector};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// How centres are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CentreMethod {
    /// Seeded k-means++ initialisation then Lloyd iterations.
    Kmeans,
    /// Forward selection by orthogonal least squares (MATLAB `newrb`).
    Ols,
}

impl std::str::FromStr for CentreMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "kmeans" => Ok(CentreMethod::Kmeans),
            "ols" => Ok(CentreMethod::Ols),
            _ => Err(format!("unknown centre method '{s}' (kmeans, ols)")),
        }
    }
}

/// Adam refinement settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AdamConfig {
    /// Most passes over the training rows.
    pub epochs: usize,
    /// Step size (normalised units).
    pub learning_rate: f64,
    /// Rows per mini-batch.
    pub batch: usize,
    /// Stop after this many epochs without a better validation error.
    pub patience: usize,
    /// Fraction of rows (the last ones) held out for early stopping.
    pub validation: f64,
}

impl Default for AdamConfig {
    fn default() -> Self {
        AdamConfig {
            epochs: 20,
            learning_rate: 0.002,
            batch: 256,
            patience: 3,
            validation: 0.1,
        }
    }
}

/// Everything training needs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    /// Lagged inputs p (the paper: 4).
    pub lags: usize,
    /// Centres q (the paper's figure is not given; 40 by default).
    pub centres: usize,
    /// How centres are chosen.
    pub method: CentreMethod,
    /// How lags become features.
    pub inputs: InputForm,
    /// What the output means.
    pub target: Target,
    /// Linear terms on the features.
    pub linear: bool,
    /// Width = this x nearest-centre distance.
    pub width_scale: f64,
    /// Ridge, relative to the mean diagonal of the normal matrix.
    pub ridge: f64,
    /// Rows used to place centres (a seeded subsample when there are more).
    pub cluster_rows: usize,
    /// Adam refinement, if any.
    pub adam: Option<AdamConfig>,
    /// Seed of every random choice.
    pub seed: u64,
}

impl Default for TrainConfig {
    /// 4 lags, 40 k-means++ centres, level inputs, increment target, linear terms, no Adam.
    fn default() -> Self {
        TrainConfig {
            lags: 4,
            centres: 40,
            method: CentreMethod::Kmeans,
            inputs: InputForm::Levels,
            target: Target::Increment,
            linear: true,
            width_scale: 1.0,
            ridge: 1e-8,
            cluster_rows: 4000,
            adam: None,
            seed: 0,
        }
    }
}

/// Why training could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrainError {
    /// A training value is NaN or infinite.
    #[error("training value {index} is not a finite number")]
    NonFinite {
        /// Index in the training series.
        index: usize,
    },
    /// Too few rows for the lags and centres.
    #[error("{samples} training samples are too few for {lags} lags and {centres} centres (need at least {needed})")]
    TooShort {
        /// Samples given.
        samples: usize,
        /// Lags asked for.
        lags: usize,
        /// Centres asked for.
        centres: usize,
        /// Samples needed.
        needed: usize,
    },
    /// A setting is out of range.
    #[error("{0}")]
    Config(String),
    /// The least-squares problem has no stable solution even with a large ridge.
    #[error("the output weights' normal equations are singular (constant drift series?)")]
    Singular,
}

/// Samples needed to train `centres` centres on `lags` lags: 4 rows per free parameter of the
/// output layer, at least 20 rows, plus the lags.
pub fn samples_needed(lags: usize, centres: usize) -> usize {
    lags + (4 * (centres + lags + 1)).max(20)
}

/// Training rows: features (raw, row-major) and targets.
#[derive(Debug, Clone)]
pub struct Rows {
    /// Features per row.
    pub f: usize,
    /// Features, row-major.
    pub x: Vec<f64>,
    /// Targets.
    pub y: Vec<f64>,
}

/// The rows of `series` for `lags`, `inputs`, `target` (one per sample with p predecessors).
pub fn rows(series: &[f64], lags: usize, inputs: InputForm, target: Target) -> Rows {
    let f = inputs.features(lags);
    let n = series.len().saturating_sub(lags);
    let mut x = Vec::with_capacity(n * f);
    let mut y = Vec::with_capacity(n);
    for t in lags..series.len() {
        let h = &series[t - lags..t];
        let last = h[lags - 1];
        match inputs {
            InputForm::Levels => x.extend_from_slice(h),
            InputForm::Relative => x.extend(h[..lags - 1].iter().map(|v| v - last)),
        }
        y.push(match target {
            Target::Next => series[t],
            Target::Increment => series[t] - last,
        });
    }
    Rows { f, x, y }
}

fn mean_sd(v: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = v.clone().count().max(1) as f64;
    let m = v.clone().sum::<f64>() / n;
    let var = v.map(|a| (a - m) * (a - m)).sum::<f64>() / n;
    let sd = var.sqrt();
    // A constant column keeps scale 1: it carries no information, and dividing by 0 is worse.
    (m, if sd > 1e-300 { sd } else { 1.0 })
}

fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// Train a network on `series` (the drift, oldest first). `progress` receives the fraction done.
pub fn train(
    series: &[f64],
    cfg: &TrainConfig,
    progress: &mut dyn FnMut(f64),
) -> Result<Rbf, TrainError> {
    if !(1..=MAX_LAGS).contains(&cfg.lags) {
        return Err(TrainError::Config(format!(
            "lags must be 1 to {MAX_LAGS}, not {}",
            cfg.lags
        )));
    }
    if cfg.centres == 0 {
        return Err(TrainError::Config("centres must be at least 1".into()));
    }
    if cfg.inputs == InputForm::Relative && (cfg.target != Target::Increment || cfg.lags < 2) {
        return Err(TrainError::Config(
            "relative inputs need the increment target and at least 2 lags".into(),
        ));
    }
    if !(cfg.width_scale.is_finite() && cfg.width_scale > 0.0) {
        return Err(TrainError::Config("width scale must be > 0".into()));
    }
    if !(cfg.ridge.is_finite() && cfg.ridge >= 0.0) {
        return Err(TrainError::Config("ridge must be >= 0".into()));
    }
    if let Some(i) = series.iter().position(|v| !v.is_finite()) {
        return Err(TrainError::NonFinite { index: i });
    }
    let needed = samples_needed(cfg.lags, cfg.centres);
    if series.len() < needed {
        return Err(TrainError::TooShort {
            samples: series.len(),
            lags: cfg.lags,
            centres: cfg.centres,
            needed,
        });
    }
    let raw = rows(series, cfg.lags, cfg.inputs, cfg.target);
    let f = raw.f;
    let n = raw.y.len();
    let mut feature_mean = vec![0.0; f];
    let mut feature_scale = vec![1.0; f];
    for k in 0..f {
        let (m, s) = mean_sd(raw.x.iter().skip(k).step_by(f).copied());
        feature_mean[k] = m;
        feature_scale[k] = s;
    }
    let (target_mean, target_scale) = mean_sd(raw.y.iter().copied());
    let mut z = raw.x;
    for (i, v) in z.iter_mut().enumerate() {
        let k = i % f;
        *v = (*v - feature_mean[k]) / feature_scale[k];
    }
    let y: Vec<f64> = raw
        .y
        .iter()
        .map(|v| (v - target_mean) / target_scale)
        .collect();
    progress(0.05);

    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let fit_rows = match cfg.adam {
        Some(a) if a.epochs > 0 => {
            let v = (n as f64 * a.validation.clamp(0.0, 0.5)) as usize;
            n - v.min(n.saturating_sub(needed - cfg.lags))
        }
        _ => n,
    };
    let q = cfg.centres;
    let mut sub: Vec<usize> = if fit_rows > cfg.cluster_rows.max(q) {
        let mut idx =
            rand::seq::index::sample(&mut rng, fit_rows, cfg.cluster_rows.max(q)).into_vec();
        idx.sort_unstable();
        idx
    } else {
        (0..fit_rows).collect()
    };
    let centres = match cfg.method {
        CentreMethod::Kmeans => kmeans(&z, f, &sub, q, &mut rng),
        CentreMethod::Ols => {
            sub.truncate(sub.len().min(2000));
            ols_select(&z, &y, f, &sub, q, cfg, &mut rng)
        }
    };
    progress(0.4);
    let widths = widths_from_centres(&centres, f, cfg.width_scale);
    // Output and linear weights start at zero: solve_output fits them.
    let mut model = Rbf::new(
        cfg.lags,
        cfg.inputs,
        cfg.target,
        feature_mean,
        feature_scale,
        target_mean,
        target_scale,
        centres,
        widths,
        vec![0.0; q],
        if cfg.linear { vec![0.0; f] } else { Vec::new() },
        0.0,
    )
    .map_err(TrainError::Config)?;
    solve_output(&mut model, &z, &y, fit_rows, cfg.ridge)?;
    progress(0.7);
    if let Some(a) = cfg.adam {
        if a.epochs > 0 && fit_rows < n {
            adam_refine(&mut model, &z, &y, fit_rows, &a, &mut rng, &mut |e| {
                progress(0.7 + 0.3 * e)
            });
        }
    }
    model.check().map_err(TrainError::Config)?;
    progress(1.0);
    Ok(model)
}

/// k-means++ seeding (D^2 weighting) then Lloyd iterations, on the rows `sub` of `z`.
fn kmeans(z: &[f64], f: usize, sub: &[usize], q: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let row = |i: usize| &z[sub[i] * f..sub[i] * f + f];
    let m = sub.len();
    let mut c = Vec::with_capacity(q * f);
    c.extend_from_slice(row(rng.random_range(0..m)));
    let mut d2: Vec<f64> = (0..m).map(|i| dist2(row(i), &c[0..f])).collect();
    while c.len() < q * f {
        let total: f64 = d2.iter().sum();
        let pick = if total > 0.0 {
            let mut u = rng.random::<f64>() * total;
            let mut pick = m - 1;
            for (i, &d) in d2.iter().enumerate() {
                if u < d {
                    pick = i;
                    break;
                }
                u -= d;
            }
            pick
        } else {
            rng.random_range(0..m)
        };
        let start = c.len();
        c.extend_from_slice(row(pick));
        for (i, d) in d2.iter_mut().enumerate() {
            *d = d.min(dist2(row(i), &c[start..start + f]));
        }
    }
    let mut assign = vec![usize::MAX; m];
    let mut sums = vec![0.0; q * f];
    let mut counts = vec![0usize; q];
    for _ in 0..30 {
        let mut changed = false;
        for i in 0..m {
            let r = row(i);
            let mut best = 0;
            let mut bd = f64::INFINITY;
            for j in 0..q {
                let d = dist2(r, &c[j * f..j * f + f]);
                if d < bd {
                    bd = d;
                    best = j;
                }
            }
            if assign[i] != best {
                assign[i] = best;
                changed = true;
            }
        }
        if !changed {
            break;
        }
        sums.fill(0.0);
        counts.fill(0);
        for i in 0..m {
            let j = assign[i];
            counts[j] += 1;
            for (s, v) in sums[j * f..j * f + f].iter_mut().zip(row(i)) {
                *s += v;
            }
        }
        for j in 0..q {
            // An emptied cluster keeps its centre.
            if counts[j] > 0 {
                for k in 0..f {
                    c[j * f + k] = sums[j * f + k] / counts[j] as f64;
                }
            }
        }
    }
    c
}

/// Forward selection of centres among training rows by orthogonal least squares.
fn ols_select(
    z: &[f64],
    y: &[f64],
    f: usize,
    sub: &[usize],
    q: usize,
    cfg: &TrainConfig,
    rng: &mut ChaCha8Rng,
) -> Vec<f64> {
    let m = sub.len();
    let mut cand: Vec<usize> = sub.to_vec();
    cand.shuffle(rng);
    cand.truncate(300.max(q).min(m));
    let nc = cand.len();
    // Candidate spread: a typical spacing of q points over +-2 standard deviations per feature.
    let spread = cfg.width_scale * 4.0 / (q as f64).powf(1.0 / f as f64);
    let h = -0.5 / (spread * spread);
    let zr = |i: usize| &z[i * f..i * f + f];
    // Regressors (column-major, m rows each) and the fixed columns: bias, then linear features.
    let mut w: Vec<f64> = Vec::with_capacity(nc * m);
    for &c in &cand {
        for &r in sub {
            w.push((dist2(zr(r), zr(c)) * h).exp());
        }
    }
    let mut fixed: Vec<Vec<f64>> = vec![vec![1.0; m]];
    if cfg.linear {
        for k in 0..f {
            fixed.push(sub.iter().map(|&r| z[r * f + k]).collect());
        }
    }
    let ys: Vec<f64> = sub.iter().map(|&r| y[r]).collect();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut basis: Vec<Vec<f64>> = Vec::new();
    let orth = |v: &mut [f64], basis: &[Vec<f64>]| {
        for b in basis {
            let bb = dot(b, b);
            if bb > 0.0 {
                let a = dot(b, v) / bb;
                v.iter_mut().zip(b).for_each(|(x, y)| *x -= a * y);
            }
        }
    };
    for mut col in fixed {
        orth(&mut col, &basis);
        basis.push(col);
    }
    for j in 0..nc {
        orth(&mut w[j * m..(j + 1) * m], &basis);
    }
    let mut used = vec![false; nc];
    let mut chosen = Vec::with_capacity(q);
    for _ in 0..q.min(nc) {
        let mut best = None;
        let mut best_err = -1.0;
        for j in 0..nc {
            if used[j] {
                continue;
            }
            let col = &w[j * m..(j + 1) * m];
            let ww = dot(col, col);
            if ww < 1e-12 * m as f64 {
                continue;
            }
            let wy = dot(col, &ys);
            let err = wy * wy / ww;
            if err > best_err {
                best_err = err;
                best = Some(j);
            }
        }
        let Some(b) = best else { break };
        used[b] = true;
        chosen.push(b);
        let qk: Vec<f64> = w[b * m..(b + 1) * m].to_vec();
        let qq = dot(&qk, &qk);
        for j in 0..nc {
            if !used[j] {
                let col = &mut w[j * m..(j + 1) * m];
                let a = dot(&qk, col) / qq;
                col.iter_mut().zip(&qk).for_each(|(x, y)| *x -= a * y);
            }
        }
    }
    // Fewer independent candidates than q: fill with the unused ones in order.
    for j in 0..nc {
        if chosen.len() >= q {
            break;
        }
        if !used[j] {
            chosen.push(j);
        }
    }
    let mut c = Vec::with_capacity(q * f);
    for &j in chosen.iter().take(q) {
        c.extend_from_slice(zr(cand[j]));
    }
    // Still short (tiny data): repeat the last centre; its width comes from the fallback.
    while c.len() < q * f {
        let last: Vec<f64> = c[c.len() - f..].to_vec();
        c.extend_from_slice(&last);
    }
    c
}

/// beta_i = scale x distance to the nearest other centre; coincident or lone centres take the
/// mean of the positive distances (or 1 in normalised units).
fn widths_from_centres(c: &[f64], f: usize, scale: f64) -> Vec<f64> {
    let q = c.len() / f;
    let mut nn = vec![f64::INFINITY; q];
    for i in 0..q {
        for j in 0..q {
            if i != j {
                let d = dist2(&c[i * f..i * f + f], &c[j * f..j * f + f]).sqrt();
                if d > 1e-9 && d < nn[i] {
                    nn[i] = d;
                }
            }
        }
    }
    let pos: Vec<f64> = nn.iter().copied().filter(|d| d.is_finite()).collect();
    let fallback = if pos.is_empty() {
        1.0
    } else {
        pos.iter().sum::<f64>() / pos.len() as f64
    };
    nn.iter()
        .map(|&d| scale * if d.is_finite() { d } else { fallback })
        .collect()
}

/// The design row of one feature vector: [phi_1..phi_q, z_1..z_f (if linear), 1].
fn design_row(m: &Rbf, z: &[f64], out: &mut [f64]) {
    let f = z.len();
    let q = m.widths.len();
    for i in 0..q {
        out[i] = (dist2(z, &m.centres[i * f..i * f + f]) * m.neg_half_inv_var[i]).exp();
    }
    let mut k = q;
    if !m.linear.is_empty() {
        out[k..k + f].copy_from_slice(z);
        k += f;
    }
    out[k] = 1.0;
}

/// Ridge least squares for the output layer on the first `rows` rows.
fn solve_output(
    m: &mut Rbf,
    z: &[f64],
    y: &[f64],
    rows: usize,
    ridge: f64,
) -> Result<(), TrainError> {
    let f = m.features();
    let q = m.widths.len();
    let dim = q + m.linear.len() + 1;
    const BLOCK: usize = 2048;
    let mut ata = DMatrix::<f64>::zeros(dim, dim);
    let mut atb = DVector::<f64>::zeros(dim);
    let mut a = DMatrix::<f64>::zeros(BLOCK, dim);
    let mut row = vec![0.0; dim];
    let mut start = 0;
    while start < rows {
        let len = BLOCK.min(rows - start);
        if len < BLOCK {
            a = DMatrix::<f64>::zeros(len, dim);
        }
        let mut b = DVector::<f64>::zeros(len);
        for r in 0..len {
            let t = start + r;
            design_row(m, &z[t * f..t * f + f], &mut row);
            for (j, v) in row.iter().enumerate() {
                a[(r, j)] = *v;
            }
            b[r] = y[t];
        }
        ata.gemm_tr(1.0, &a, &a, 1.0);
        atb.gemv_tr(1.0, &a, &b, 1.0);
        start += len;
    }
    let mean_diag = (0..dim - 1).map(|i| ata[(i, i)]).sum::<f64>() / (dim - 1).max(1) as f64;
    let mut lambda = ridge * mean_diag.max(1e-300);
    for _ in 0..8 {
        let mut reg = ata.clone();
        for i in 0..dim - 1 {
            reg[(i, i)] += lambda;
        }
        if let Some(ch) = reg.cholesky() {
            let w = ch.solve(&atb);
            if w.iter().all(|v| v.is_finite()) {
                m.weights.copy_from_slice(&w.as_slice()[..q]);
                let nl = m.linear.len();
                m.linear.copy_from_slice(&w.as_slice()[q..q + nl]);
                m.bias = w[dim - 1];
                return Ok(());
            }
        }
        lambda = if lambda > 0.0 {
            lambda * 100.0
        } else {
            1e-10 * mean_diag.max(1e-300)
        };
    }
    Err(TrainError::Singular)
}

fn mse_on(m: &Rbf, z: &[f64], y: &[f64], range: std::ops::Range<usize>) -> f64 {
    let f = m.features();
    let n = range.len().max(1) as f64;
    range
        .map(|t| {
            let e = m.output(&z[t * f..t * f + f]) - y[t];
            e * e
        })
        .sum::<f64>()
        / n
}

/// Adam on centres, log-widths, weights, linear weights and bias; early stopping on rows
/// `fit_rows..`.
fn adam_refine(
    m: &mut Rbf,
    z: &[f64],
    y: &[f64],
    fit_rows: usize,
    a: &AdamConfig,
    rng: &mut ChaCha8Rng,
    progress: &mut dyn FnMut(f64),
) {
    let f = m.features();
    let q = m.widths.len();
    let nl = m.linear.len();
    // Parameter layout: centres (q f), log widths (q), weights (q), linear (nl), bias (1).
    let np = q * f + q + q + nl + 1;
    let pack = |m: &Rbf| {
        let mut p = Vec::with_capacity(np);
        p.extend_from_slice(&m.centres);
        p.extend(m.widths.iter().map(|b| b.ln()));
        p.extend_from_slice(&m.weights);
        p.extend_from_slice(&m.linear);
        p.push(m.bias);
        p
    };
    let unpack = |m: &mut Rbf, p: &[f64]| {
        m.centres.copy_from_slice(&p[..q * f]);
        for (w, s) in m.widths.iter_mut().zip(&p[q * f..q * f + q]) {
            *w = s.exp().clamp(1e-6, 1e6);
        }
        m.weights.copy_from_slice(&p[q * f + q..q * f + 2 * q]);
        m.linear
            .copy_from_slice(&p[q * f + 2 * q..q * f + 2 * q + nl]);
        m.bias = p[np - 1];
        m.prepare();
    };
    let mut theta = pack(m);
    let mut best = theta.clone();
    let mut best_val = mse_on(m, z, y, fit_rows..y.len());
    let (b1, b2, eps) = (0.9f64, 0.999f64, 1e-8);
    let mut m1 = vec![0.0; np];
    let mut m2 = vec![0.0; np];
    let mut g = vec![0.0; np];
    let mut phi = vec![0.0; q];
    let mut order: Vec<usize> = (0..fit_rows).collect();
    let mut step = 0i32;
    let mut stale = 0;
    for epoch in 0..a.epochs {
        order.shuffle(rng);
        for batch in order.chunks(a.batch.max(1)) {
            g.fill(0.0);
            for &t in batch {
                let zt = &z[t * f..t * f + f];
                let mut out = m.bias;
                for k in 0..nl {
                    out += m.linear[k] * zt[k];
                }
                for i in 0..q {
                    phi[i] =
                        (dist2(zt, &m.centres[i * f..i * f + f]) * m.neg_half_inv_var[i]).exp();
                    out += m.weights[i] * phi[i];
                }
                let e = out - y[t];
                for i in 0..q {
                    let c = &m.centres[i * f..i * f + f];
                    let inv_b2 = -2.0 * m.neg_half_inv_var[i];
                    let wpe = e * m.weights[i] * phi[i];
                    let mut d2 = 0.0;
                    for k in 0..f {
                        let d = zt[k] - c[k];
                        d2 += d * d;
                        g[i * f + k] += wpe * d * inv_b2;
                    }
                    g[q * f + i] += wpe * d2 * inv_b2;
                    g[q * f + q + i] += e * phi[i];
                }
                for k in 0..nl {
                    g[q * f + 2 * q + k] += e * zt[k];
                }
                g[np - 1] += e;
            }
            step += 1;
            let scale = 1.0 / batch.len() as f64;
            let c1 = 1.0 - b1.powi(step);
            let c2 = 1.0 - b2.powi(step);
            for j in 0..np {
                let gj = g[j] * scale;
                m1[j] = b1 * m1[j] + (1.0 - b1) * gj;
                m2[j] = b2 * m2[j] + (1.0 - b2) * gj * gj;
                theta[j] -= a.learning_rate * (m1[j] / c1) / ((m2[j] / c2).sqrt() + eps);
            }
            unpack(m, &theta);
        }
        let val = mse_on(m, z, y, fit_rows..y.len());
        if val.is_finite() && val < best_val {
            best_val = val;
            best.copy_from_slice(&theta);
            stale = 0;
        } else {
            stale += 1;
        }
        progress((epoch + 1) as f64 / a.epochs as f64);
        if stale >= a.patience {
            break;
        }
    }
    unpack(m, &best);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drift::baselines::Predictor;

    fn series(n: usize, seed: u64) -> Vec<f64> {
        // A smooth random-walk-like drift: integrated AR(1) noise.
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (mut v, mut x) = (0.0, 0.0);
        (0..n)
            .map(|_| {
                let e: f64 = StandardNormal.sample(&mut rng);
                v = 0.95 * v + 0.01 * e;
                x += v;
                x
            })
            .collect()
    }

    #[test]
    fn too_short_and_nan_are_refused() {
        let cfg = TrainConfig::default();
        let e = train(&[0.0; 50], &cfg, &mut |_| {}).unwrap_err();
        assert!(matches!(e, TrainError::TooShort { .. }), "{e}");
        let mut s = series(2000, 1);
        s[700] = f64::NAN;
        assert_eq!(
            train(&s, &cfg, &mut |_| {}).unwrap_err(),
            TrainError::NonFinite { index: 700 }
        );
    }

    #[test]
    fn ols_and_adam_run_and_fit() {
        let s = series(5000, 2);
        for cfg in [
            TrainConfig {
                method: CentreMethod::Ols,
                centres: 10,
                ..TrainConfig::default()
            },
            TrainConfig {
                centres: 10,
                adam: Some(AdamConfig {
                    epochs: 3,
                    ..AdamConfig::default()
                }),
                ..TrainConfig::default()
            },
        ] {
            let m = train(&s, &cfg, &mut |_| {}).unwrap();
            assert_eq!(m.centre_count(), 10);
            // Far better than persistence on this smooth series (it has momentum).
            let e: f64 = (4000..5000)
                .map(|t| (m.predict(&s[t - 4..t]) - s[t]).powi(2))
                .sum();
            let p: f64 = (4000..5000).map(|t| (s[t - 1] - s[t]).powi(2)).sum();
            assert!(e < 0.5 * p, "{:?}: {e} vs persistence {p}", cfg.method);
        }
    }
}
