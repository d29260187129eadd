//! The paper's Gaussian RBF network (Sheng, Gao & Zhang 2019, eq. 6-7), with optional linear terms.
//!
//! For a feature vector z (the normalised lagged drift values),
//!
//! ```text
//! f(z) = sum_i w_i exp(-|z - c_i|^2 / (2 beta_i^2)) + sum_k a_k z_k + w_0
//! ```
//!
//! with q centres c_i, widths beta_i, weights w_i, bias w_0, and (optionally) linear weights a_k.
//! The output is de-normalised into either the next drift value or its increment over the last
//! one ([`Target`]). Gyro drift is close to a random walk: a pure Gaussian network on levels
//! does worse than persistence, while the increment target or the linear terms let it beat AR(p)
//! (science notes, "Pitfalls").

use super::baselines::Predictor;
use super::MAX_LAGS;
use serde::{Deserialize, Serialize};

/// What the network's output means.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Target {
    /// The next drift value itself (the paper).
    Next,
    /// The next value minus the last one.
    Increment,
}

impl std::str::FromStr for Target {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "next" => Ok(Target::Next),
            "increment" => Ok(Target::Increment),
            _ => Err(format!("unknown target '{s}' (next, increment)")),
        }
    }
}

/// How the lagged values become features.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InputForm {
    /// The p lagged values themselves (the paper): p features.
    Levels,
    /// Each older lag minus the newest: p - 1 features, blind to the drift's level, so a model
    /// trained at one turn-on bias works at another (needs [`Target::Increment`]).
    Relative,
}

impl std::str::FromStr for InputForm {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "levels" => Ok(InputForm::Levels),
            "relative" => Ok(InputForm::Relative),
            _ => Err(format!("unknown input form '{s}' (levels, relative)")),
        }
    }
}

impl InputForm {
    /// Features for `lags` lagged values.
    pub fn features(self, lags: usize) -> usize {
        match self {
            InputForm::Levels => lags,
            InputForm::Relative => lags.saturating_sub(1),
        }
    }
}

/// A trained network. Centres are stored row-major (`centres[i * f + k]`, f features), in
/// normalised feature units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Rbf {
    /// Lagged inputs p.
    pub lags: usize,
    /// How lags become features.
    pub inputs: InputForm,
    /// What the output means.
    pub target: Target,
    /// Per-feature mean removed before scaling.
    pub feature_mean: Vec<f64>,
    /// Per-feature scale (standard deviation) divided out.
    pub feature_scale: Vec<f64>,
    /// Mean of the training target.
    pub target_mean: f64,
    /// Scale of the training target.
    pub target_scale: f64,
    /// Centres, q x f row-major.
    pub centres: Vec<f64>,
    /// Widths beta_i (> 0).
    pub widths: Vec<f64>,
    /// Output weights w_i.
    pub weights: Vec<f64>,
    /// Linear weights a_k on the features (empty: no linear terms).
    pub linear: Vec<f64>,
    /// Bias w_0.
    pub bias: f64,
    /// Cached -1 / (2 beta_i^2).
    #[serde(skip)]
    pub(crate) neg_half_inv_var: Vec<f64>,
}

impl Rbf {
    /// Assemble a network (checked by [`Rbf::check`]).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        lags: usize,
        inputs: InputForm,
        target: Target,
        feature_mean: Vec<f64>,
        feature_scale: Vec<f64>,
        target_mean: f64,
        target_scale: f64,
        centres: Vec<f64>,
        widths: Vec<f64>,
        weights: Vec<f64>,
        linear: Vec<f64>,
        bias: f64,
    ) -> Result<Rbf, String> {
        let mut r = Rbf {
            lags,
            inputs,
            target,
            feature_mean,
            feature_scale,
            target_mean,
            target_scale,
            centres,
            widths,
            weights,
            linear,
            bias,
            neg_half_inv_var: Vec::new(),
        };
        r.check()?;
        r.prepare();
        Ok(r)
    }

    /// Number of features f.
    pub fn features(&self) -> usize {
        self.inputs.features(self.lags)
    }

    /// Number of centres q.
    pub fn centre_count(&self) -> usize {
        self.widths.len()
    }

    /// Check dimensions, finiteness and ranges; call [`Rbf::prepare`] after changing parameters.
    pub fn check(&self) -> Result<(), String> {
        if !(1..=MAX_LAGS).contains(&self.lags) {
            return Err(format!("lags must be 1 to {MAX_LAGS}, not {}", self.lags));
        }
        if self.inputs == InputForm::Relative && self.target != Target::Increment {
            return Err("relative inputs need the increment target".into());
        }
        if self.inputs == InputForm::Relative && self.lags < 2 {
            return Err("relative inputs need at least 2 lags".into());
        }
        let f = self.features();
        let q = self.widths.len();
        let dims = [
            ("feature_mean", self.feature_mean.len(), f),
            ("feature_scale", self.feature_scale.len(), f),
            ("centres", self.centres.len(), q * f),
            ("weights", self.weights.len(), q),
        ];
        for (name, got, want) in dims {
            if got != want {
                return Err(format!(
                    "{name} has {got} values, expected {want} ({q} centres, {f} features)"
                ));
            }
        }
        if !self.linear.is_empty() && self.linear.len() != f {
            return Err(format!(
                "linear has {} values, expected 0 or {f}",
                self.linear.len()
            ));
        }
        let all = self
            .feature_mean
            .iter()
            .chain(&self.feature_scale)
            .chain(&self.centres)
            .chain(&self.widths)
            .chain(&self.weights)
            .chain(&self.linear)
            .chain([&self.bias, &self.target_mean, &self.target_scale]);
        if all.into_iter().any(|v| !v.is_finite()) {
            return Err("a parameter is NaN or infinite".into());
        }
        if self.widths.iter().any(|&b| b <= 0.0) {
            return Err("a width is not positive".into());
        }
        if self.feature_scale.iter().any(|&s| s <= 0.0) || self.target_scale <= 0.0 {
            return Err("a normalisation scale is not positive".into());
        }
        Ok(())
    }

    /// Recompute cached values from the parameters (after loading or training).
    pub fn prepare(&mut self) {
        self.neg_half_inv_var = self.widths.iter().map(|b| -0.5 / (b * b)).collect();
    }

    /// Normalised features of `hist` (oldest first, `lags` long) into `z`.
    #[inline]
    pub fn features_of(&self, hist: &[f64], z: &mut [f64]) {
        let p = self.lags;
        match self.inputs {
            InputForm::Levels => {
                for k in 0..p {
                    z[k] = (hist[k] - self.feature_mean[k]) / self.feature_scale[k];
                }
            }
            InputForm::Relative => {
                let last = hist[p - 1];
                for k in 0..p - 1 {
                    z[k] = (hist[k] - last - self.feature_mean[k]) / self.feature_scale[k];
                }
            }
        }
    }

    /// The network's raw output on normalised features (the normalised target).
    #[inline]
    pub fn output(&self, z: &[f64]) -> f64 {
        let f = z.len();
        let mut y = self.bias;
        for (k, a) in self.linear.iter().enumerate() {
            y += a * z[k];
        }
        for (i, (&w, &h)) in self.weights.iter().zip(&self.neg_half_inv_var).enumerate() {
            let c = &self.centres[i * f..i * f + f];
            let mut d2 = 0.0;
            for k in 0..f {
                let d = z[k] - c[k];
                d2 += d * d;
            }
            let e = d2 * h;
            // Beyond -30 the term is below 1e-13 of w (normalised units): skip the exp.
            if e > -30.0 {
                y += w * e.exp();
            }
        }
        y
    }

    /// De-normalise an output into the next drift value, given the newest input.
    #[inline]
    pub fn to_value(&self, out: f64, last: f64) -> f64 {
        let t = out * self.target_scale + self.target_mean;
        match self.target {
            Target::Next => t,
            Target::Increment => last + t,
        }
    }
}

impl Predictor for Rbf {
    fn lags(&self) -> usize {
        self.lags
    }

    fn predict(&self, hist: &[f64]) -> f64 {
        let mut z = [0.0; MAX_LAGS];
        let f = self.features();
        self.features_of(hist, &mut z[..f]);
        let out = self.output(&z[..f]);
        self.to_value(out, hist[self.lags - 1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_centre_by_hand() {
        // f(z) = 2 exp(-|z - 1|^2 / 2) + 0.5 z + 0.1 on z = (x - 1) / 2; target next.
        let r = Rbf::new(
            1,
            InputForm::Levels,
            Target::Next,
            vec![1.0],
            vec![2.0],
            0.0,
            1.0,
            vec![1.0],
            vec![1.0],
            vec![2.0],
            vec![0.5],
            0.1,
        )
        .unwrap();
        let x = 5.0; // z = 2
        let want = 2.0 * (-0.5f64).exp() + 0.5 * 2.0 + 0.1;
        assert!((r.predict(&[x]) - want).abs() < 1e-15);
    }

    #[test]
    fn relative_increment_is_translation_invariant() {
        let r = Rbf::new(
            3,
            InputForm::Relative,
            Target::Increment,
            vec![0.0, 0.0],
            vec![1.0, 1.0],
            0.0,
            1.0,
            vec![0.5, -0.5],
            vec![1.3],
            vec![0.7],
            vec![0.1, 0.2],
            0.05,
        )
        .unwrap();
        let a = r.predict(&[1.0, 1.2, 1.1]);
        let b = r.predict(&[101.0, 101.2, 101.1]);
        assert!((b - a - 100.0).abs() < 1e-9);
    }

    #[test]
    fn bad_dimensions_and_values_are_refused() {
        let ok = |widths: Vec<f64>, centres: Vec<f64>| {
            Rbf::new(
                2,
                InputForm::Levels,
                Target::Next,
                vec![0.0; 2],
                vec![1.0; 2],
                0.0,
                1.0,
                centres,
                widths,
                vec![1.0],
                vec![],
                0.0,
            )
        };
        assert!(ok(vec![1.0], vec![0.0, 0.0]).is_ok());
        assert!(ok(vec![1.0], vec![0.0]).unwrap_err().contains("centres"));
        assert!(ok(vec![0.0], vec![0.0, 0.0]).unwrap_err().contains("width"));
        assert!(ok(vec![1.0], vec![f64::NAN, 0.0])
            .unwrap_err()
            .contains("NaN"));
    }
}
