//! The methods that run a pipeline's stages, through the daemon's own stage code
//! ([`crate::pipeline::offline::Offline`]): the product's chain `denoise.wavelet ->
//! predict.bias` built in at the log's rate with each axis' terms, the same reading the true
//! stops as a vehicle's stop signal, the paper's `denoise.wavelet -> predict.rbf` and the same
//! with the model's AR(p) in the network's place, and a user's pipeline file.

use super::NavEvalError;
use crate::drift::bias::{AccelTerms, BiasTerms};
use crate::drift::PredictorKind;
use crate::pipeline::config::{self, Pipeline};
use crate::pipeline::offline::Offline;
use crate::stages::schema::Src;
use std::path::{Path, PathBuf};

/// A method that runs a pipeline's stages.
#[derive(Debug)]
pub struct Chain {
    /// Its column's label.
    pub label: String,
    /// One per axis (each run alone), or one for all axes (a user's file, run lane by lane).
    pub pipelines: Vec<Pipeline>,
    /// Whether its samples carry the accelerometer, when the source has one. Then each axis
    /// runs alone, with its own motion's specific force.
    pub accel: bool,
}

impl Chain {
    /// The product's chain, `denoise.wavelet -> predict.bias`, at `rate` Hz with each axis'
    /// `terms`.
    pub fn bias(rate: f64, terms: &[BiasTerms]) -> Result<Chain, NavEvalError> {
        let pipelines = terms
            .iter()
            .map(|t| {
                let keys = format!("kind = \"predict.bias\"\n{}", t.stage_keys());
                builtin_pipeline(rate, &keys, "<built-in denoise.wavelet -> predict.bias>")
            })
            .collect::<Result<_, _>>()?;
        Ok(Chain {
            label: "denoise.wavelet -> predict.bias (stages)".into(),
            pipelines,
            accel: false,
        })
    }

    /// The product's chain ([`Chain::bias`]) on samples that carry the accelerometer, with the
    /// accelerometer's terms `accel` (None: `predict.bias`'s defaults, the ADIS16405 data
    /// sheet's): what the daemon runs when the sensor gives both.
    pub fn bias_imu(
        rate: f64,
        terms: &[BiasTerms],
        accel: Option<&AccelTerms>,
    ) -> Result<Chain, NavEvalError> {
        let pipelines = terms
            .iter()
            .map(|t| {
                let mut keys = format!("kind = \"predict.bias\"\n{}", t.stage_keys());
                if let Some(a) = accel {
                    keys = format!("{keys}\n{}", a.stage_keys());
                }
                builtin_pipeline(
                    rate,
                    &keys,
                    "<built-in denoise.wavelet -> predict.bias, gyro+accel>",
                )
            })
            .collect::<Result<_, _>>()?;
        Ok(Chain {
            label: "denoise.wavelet -> predict.bias (stages, gyro+accel)".into(),
            pipelines,
            accel: true,
        })
    }

    /// The chain for navigators with the vehicle's stop signal, `denoise.none -> predict.bias`
    /// reading `stop_input`, with each axis' terms: [`Offline::run_series`] publishes each
    /// case's true stops on it. What a navigator whose vehicle says when it stands gets.
    pub fn stop_signal(rate: f64, terms: &[BiasTerms]) -> Result<Chain, NavEvalError> {
        let pipelines = terms
            .iter()
            .map(|t| {
                let keys = format!(
                    "kind = \"predict.bias\"\nstop_input = \"nav-eval/stop\"\n{}",
                    t.stage_keys()
                );
                builtin_pipeline_with(
                    rate,
                    "denoise.none",
                    &keys,
                    "<built-in denoise.none -> predict.bias, stop signal>",
                )
            })
            .collect::<Result<_, _>>()?;
        Ok(Chain {
            label: "denoise.none -> predict.bias (stages; stop signal: the true stops)".into(),
            pipelines,
            accel: false,
        })
    }

    /// The paper's chain, `denoise.wavelet -> predict.rbf`, for `axes` axes at `rate` Hz, with
    /// the network or (`predictor = "ar"`) the models' AR(p) baselines in its place: one model
    /// for every axis, or one each.
    pub fn rbf(
        rate: f64,
        axes: usize,
        models: &[PathBuf],
        predictor: PredictorKind,
    ) -> Result<Chain, NavEvalError> {
        if models.len() != 1 && models.len() != axes {
            return Err(NavEvalError::Input(format!(
                "--model: {} models for {axes} axes (give one, or one per axis)",
                models.len()
            )));
        }
        let name = predictor.name();
        let pipelines = (0..axes)
            .map(|a| {
                let m = &models[a.min(models.len() - 1)];
                let path = std::path::absolute(m)
                    .map_err(|e| NavEvalError::Input(format!("{}: {e}", m.display())))?;
                let keys = format!(
                    "kind = \"predict.rbf\"\nmodel = {:?}\npredictor = \"{name}\"",
                    path.display().to_string()
                );
                builtin_pipeline(rate, &keys, &format!("--model {}", m.display()))
            })
            .collect::<Result<_, _>>()?;
        Ok(Chain {
            label: match predictor {
                PredictorKind::Rbf => "denoise.wavelet -> predict.rbf (stages)".into(),
                PredictorKind::Ar => "denoise.wavelet -> predict.rbf, predictor ar (stages)".into(),
            },
            pipelines,
            accel: false,
        })
    }

    /// A pipeline file's stages after its ingest, all axes at once: its rate must be `rate`,
    /// and it must run offline (no `external` stage). Its samples carry the accelerometer when
    /// the source has one, as the daemon's would.
    pub fn file(path: &Path, rate: f64) -> Result<Chain, NavEvalError> {
        let p = config::load(path)?;
        if (p.rate_hz - rate).abs() > 1e-9 * rate {
            // Point at the value: the pipeline keeps values, not spans, so read its span again
            // (a text search could land on a comment).
            #[derive(serde::Deserialize)]
            struct Top {
                rate_hz: toml::Spanned<f64>,
            }
            let text = std::fs::read_to_string(path).unwrap_or_default();
            let at = toml::from_str::<Top>(&text).map_or(0, |t| t.rate_hz.span().start);
            return Err(Src { path, text: &text }
                .at(
                    at,
                    format!(
                        "rate_hz is {} Hz but the log is {rate} Hz: nav-eval feeds the log's samples at its own rate",
                        p.rate_hz
                    ),
                )
                .into());
        }
        Offline::new(&p).map_err(|e| NavEvalError::Input(format!("{}: {e}", path.display())))?;
        let kinds: Vec<&str> = p.stages.iter().skip(1).map(|s| s.kind.name).collect();
        let stops = p.stages.iter().any(|s| !s.params.side_inputs().is_empty());
        Ok(Chain {
            label: format!(
                "{} ({}{})",
                path.file_name().map_or_else(
                    || path.display().to_string(),
                    |f| f.to_string_lossy().into_owned()
                ),
                kinds.join(" -> "),
                if stops {
                    "; stop signal: the true stops"
                } else {
                    ""
                }
            ),
            pipelines: vec![p],
            accel: true,
        })
    }

    /// Whether a stage of its pipelines reads a side input (the vehicle's stops): then each
    /// axis runs alone, with its own true stops.
    pub fn reads_stops(&self) -> bool {
        self.pipelines
            .iter()
            .any(|p| p.stages.iter().any(|s| !s.params.side_inputs().is_empty()))
    }
}

/// A one-axis pipeline at `rate`: `denoise.wavelet` (defaults) then `predict` (its kind and
/// keys, TOML), as a pipeline file would say it.
fn builtin_pipeline(rate: f64, predict: &str, name: &str) -> Result<Pipeline, NavEvalError> {
    builtin_pipeline_with(rate, "denoise.wavelet", predict, name)
}

/// [`builtin_pipeline`] with another denoise kind (its defaults).
fn builtin_pipeline_with(
    rate: f64,
    denoise: &str,
    predict: &str,
    name: &str,
) -> Result<Pipeline, NavEvalError> {
    let text = format!(
        r#"name = "nav-eval"
rate_hz = {rate}
axes = 1
input_units = "deg/s"

[[stage]]
name = "sensor"
kind = "ingest.sim"
output = "nav-eval/raw"

[[stage]]
name = "denoise"
kind = "{denoise}"
input = "nav-eval/raw"
output = "nav-eval/denoised"

[[stage]]
name = "predict"
input = "nav-eval/denoised"
output = "nav-eval/predicted"
{predict}

[[stage]]
name = "publish"
kind = "publish"
input = "nav-eval/predicted"
output = "nav-eval/corrected"
"#
    );
    // Errors here come from the user's model (rate, units): bad input, the model named.
    Ok(config::parse(Path::new(name), &text)?)
}
