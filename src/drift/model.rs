//! The model file: a versioned JSON document holding the network, how its drift was measured, and
//! where it came from.
//!
//! ```json
//! { "format": "driftless-drift-model", "version": 1,
//!   "rate_hz": 50.0, "axis": "gyro_x_degps", "units": "deg/s",
//!   "separation": { "denoise": {...}, "lowband": { "wavelet": "db6", "level": 5 } },
//!   "stillness": {...}, "max_step": 0.001, "network": {...}, "baselines": { "ar": {...} },
//!   "training": {...}, "scores": [...], "provenance": {...} }
//! ```
//!
//! [`DriftModel::from_json`] checks the format tag, the version, every dimension, finiteness and
//! ranges, and says which check failed. Reading and writing files is in
//! [`crate::io::model_file`].

use super::baselines::{Ar, Predictor, Score};
use super::lowband::LowBand;
use super::rbf::Rbf;
use super::stillness::StillnessConfig;
use super::training::TrainConfig;
use crate::units::RateUnit;
use serde::{Deserialize, Serialize};

/// The format tag of a model file.
pub const FORMAT: &str = "driftless-drift-model";
/// The model file version this build writes and reads.
pub const VERSION: u32 = 1;

/// The streaming denoiser settings used before the drift was measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DenoiseSettings {
    /// Wavelet name.
    pub wavelet: String,
    /// Levels.
    pub level: usize,
    /// Threshold function, as `ThresholdFn`'s `Display` writes it.
    pub threshold: String,
    /// Noise window, samples.
    pub window: usize,
    /// Lag, samples.
    pub lag: usize,
}

/// The causal low band that defines the drift.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LowbandSettings {
    /// Wavelet name.
    pub wavelet: String,
    /// Level J.
    pub level: usize,
}

/// How the drift series was separated from the rate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Separation {
    /// The denoiser run first.
    pub denoise: DenoiseSettings,
    /// The low band of its output.
    pub lowband: LowbandSettings,
}

/// Baseline predictors fitted on the same training drift (for `eval`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Baselines {
    /// AR(p) on the same lags.
    pub ar: Ar,
    /// Training mean of the drift.
    pub mean: f64,
}

/// Where the model came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// Input file name as given.
    pub file: String,
    /// SHA-256 of the input file's bytes, hex.
    pub sha256: String,
    /// Column trained on.
    pub column: String,
    /// First training sample (0-based row after the header).
    pub train_start: usize,
    /// Training samples.
    pub train_len: usize,
    /// Held-out test samples right after the training ones.
    pub test_len: usize,
    /// Seed.
    pub seed: u64,
    /// driftless version that trained it.
    pub driftless: String,
}

/// A complete drift model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DriftModel {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`VERSION`] when written by this build.
    pub version: u32,
    /// Sample rate the model was trained at, Hz.
    pub rate_hz: f64,
    /// Axis (column) name.
    pub axis: String,
    /// Units of the rate and the drift (stored by name: `deg/s`, `rad/s`).
    pub units: RateUnit,
    /// How the drift was separated.
    pub separation: Separation,
    /// Default stillness thresholds (calibrated on the training record).
    pub stillness: StillnessConfig,
    /// Largest free-running step, units per sample.
    pub max_step: f64,
    /// The network.
    pub network: Rbf,
    /// Baselines on the same lags.
    pub baselines: Baselines,
    /// Training settings.
    pub training: TrainConfig,
    /// Held-out scores at training time (persistence, mean, AR, RBF).
    pub scores: Vec<Score>,
    /// Where it came from.
    pub provenance: Provenance,
}

/// Which of a model file's predictors drives the compensator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PredictorKind {
    /// The RBF network (the paper's method).
    #[default]
    Rbf,
    /// The AR(p) baseline fitted by least squares on the same training drift and lags.
    Ar,
}

impl PredictorKind {
    /// The names a pipeline file uses (`predictor = "..."`), in [`PredictorKind`] order.
    pub const NAMES: [&'static str; 2] = ["rbf", "ar"];

    /// Its name in a pipeline file.
    pub const fn name(self) -> &'static str {
        match self {
            PredictorKind::Rbf => Self::NAMES[0],
            PredictorKind::Ar => Self::NAMES[1],
        }
    }

    /// The kind named `name` (one of [`PredictorKind::NAMES`]).
    pub fn from_name(name: &str) -> Option<PredictorKind> {
        match name {
            "rbf" => Some(PredictorKind::Rbf),
            "ar" => Some(PredictorKind::Ar),
            _ => None,
        }
    }
}

/// A model file's predictor, the network or its AR baseline, as one type: a stage holds either
/// without boxing, and the choice costs one branch per prediction.
#[derive(Debug, Clone)]
pub enum ModelPredictor {
    /// The network.
    Rbf(Rbf),
    /// The AR(p) baseline.
    Ar(Ar),
}

impl Predictor for ModelPredictor {
    fn lags(&self) -> usize {
        match self {
            ModelPredictor::Rbf(r) => r.lags(),
            ModelPredictor::Ar(a) => a.lags(),
        }
    }

    fn predict(&self, hist: &[f64]) -> f64 {
        match self {
            ModelPredictor::Rbf(r) => r.predict(hist),
            ModelPredictor::Ar(a) => a.predict(hist),
        }
    }
}

/// Why a model file was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// Not JSON, truncated, or fields missing or mistyped.
    #[error("model file is not a valid driftless model ({0})")]
    Parse(String),
    /// Another kind of file.
    #[error("not a driftless drift model (format '{0}', expected '{FORMAT}')")]
    Format(String),
    /// A version this build does not read.
    #[error("model file version {0} is not supported (this build reads version {VERSION})")]
    Version(u32),
    /// Dimensions, ranges or finiteness.
    #[error("model file is inconsistent: {0}")]
    Invalid(String),
}

impl DriftModel {
    /// Parse and check a model document.
    pub fn from_json(text: &str) -> Result<DriftModel, ModelError> {
        // Format and version first, so an old or foreign file gets the right message.
        let head: serde_json::Value =
            serde_json::from_str(text).map_err(|e| ModelError::Parse(e.to_string()))?;
        let format = head.get("format").and_then(|v| v.as_str()).unwrap_or("");
        if format != FORMAT {
            return Err(ModelError::Format(format.to_string()));
        }
        match head.get("version").and_then(|v| v.as_u64()) {
            Some(v) if v == VERSION as u64 => {}
            Some(v) => return Err(ModelError::Version(v.min(u32::MAX as u64) as u32)),
            None => return Err(ModelError::Parse("missing field `version`".into())),
        }
        // The units by name first: the typed parse would refuse an unknown one as unreadable.
        if let Some(units) = head.get("units").and_then(|v| v.as_str()) {
            if units.parse::<RateUnit>().is_err() {
                return Err(ModelError::Invalid(format!(
                    "units '{units}' (expected one of {})",
                    RateUnit::NAMES.join(", ")
                )));
            }
        }
        // Typed parse from the text again: its errors carry line and column.
        let mut m: DriftModel =
            serde_json::from_str(text).map_err(|e| ModelError::Parse(e.to_string()))?;
        m.check().map_err(ModelError::Invalid)?;
        m.network.prepare();
        Ok(m)
    }

    /// The document, pretty-printed.
    pub fn to_json(&self) -> String {
        // Serialising plain numbers and strings cannot fail; non-finite numbers become null and
        // are refused on loading.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Every consistency check of a loaded model.
    pub fn check(&self) -> Result<(), String> {
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return Err(format!("rate_hz must be > 0, not {}", self.rate_hz));
        }
        self.network.check().map_err(|e| format!("network: {e}"))?;
        self.stillness.check()?;
        if !(self.max_step.is_finite() && self.max_step > 0.0) {
            return Err(format!("max_step must be > 0, not {}", self.max_step));
        }
        LowBand::new(
            &self.separation.lowband.wavelet,
            self.separation.lowband.level,
        )
        .map_err(|e| format!("lowband: {e}"))?;
        let ar = &self.baselines.ar;
        if ar.coef.len() != self.network.lags {
            return Err(format!(
                "baselines.ar has {} coefficients for {} lags",
                ar.coef.len(),
                self.network.lags
            ));
        }
        if !ar
            .coef
            .iter()
            .chain([&ar.intercept, &self.baselines.mean])
            .all(|v| v.is_finite())
        {
            return Err("a baseline parameter is NaN or infinite".into());
        }
        Ok(())
    }

    /// The predictor of `kind` (a copy: a compensator owns its predictor).
    pub fn predictor(&self, kind: PredictorKind) -> ModelPredictor {
        match kind {
            PredictorKind::Rbf => ModelPredictor::Rbf(self.network.clone()),
            PredictorKind::Ar => ModelPredictor::Ar(self.baselines.ar.clone()),
        }
    }

    /// The low band this model's drift is measured with.
    pub fn lowband(&self) -> Result<LowBand, String> {
        LowBand::new(
            &self.separation.lowband.wavelet,
            self.separation.lowband.level,
        )
        .map_err(|e| format!("lowband: {e}"))
    }
}
