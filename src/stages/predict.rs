//! `predict.none` (no drift model) and `predict.rbf` (the RBF drift model with live,
//! stillness-gated compensation: [`crate::drift::compensator`]).
//!
//! ```toml
//! [[stage]]
//! name = "predict"
//! kind = "predict.rbf"
//! input = "demo/denoised"
//! output = "demo/predicted"
//! model = "models/adis-x.json"    # one model for every axis, or
//! # models = ["x.json", "y.json", "z.json"]   # one per axis
//! # predictor = "ar"   # the model's AR(p) baseline in the network's place (default "rbf")
//! # Stillness overrides (default: the model's calibrated thresholds), in input_units:
//! # still_window = 50, settle = 342, var_enter = 1e-4, var_exit = 5e-5,
//! # mean_enter = 0.02, mean_exit = 0.01
//! ```

use std::path::PathBuf;

use toml::Spanned;

use crate::drift::compensator::{Compensator, Mode};
use crate::drift::{ModelPredictor, PredictorKind};
use crate::io::InputError;
use crate::stages::contract::{Kind, Params, Role, Stage};
use crate::stages::schema::{Context, DefaultValue, Key, Table, Type};
use crate::wire::{GyroSample, DRIFT_STD_NOT_PROVIDED, FLAG_MOVING, FLAG_STILL, FLAG_WARMING_UP};

const MODEL: Key = Key {
    name: "model",
    ty: Type::Str("a model file from `driftless train`, relative to the pipeline file"),
    default: DefaultValue::Either("models"),
    doc: "one drift model for every axis",
};
const MODELS: Key = Key {
    name: "models",
    ty: Type::StrList("one model file per axis"),
    default: DefaultValue::Either("model"),
    doc: "one drift model per axis",
};
const PREDICTOR: Key = Key {
    name: "predictor",
    ty: Type::Choice(&PredictorKind::NAMES),
    default: DefaultValue::Word(PredictorKind::Rbf.name()),
    doc: "what predicts the drift: the model's network, or the AR(p) baseline fitted on the same training drift and lags (the same gating and free run)",
};
const STILL_WINDOW: Key = Key {
    name: "still_window",
    ty: Type::Int(2, 1_000_000),
    default: DefaultValue::Derived("the model's"),
    doc: "samples of the stillness detector's window",
};
const SETTLE: Key = Key {
    name: "settle",
    ty: Type::Int(0, 100_000_000),
    default: DefaultValue::Derived("the model's"),
    doc: "quiet samples before moving turns to still",
};
const VAR_ENTER: Key = Key {
    name: "var_enter",
    ty: Type::Positive(f64::MAX),
    default: DefaultValue::Derived("the model's"),
    doc: "window variance above which the sensor is moving (input units squared)",
};
const VAR_EXIT: Key = Key {
    name: "var_exit",
    ty: Type::Positive(f64::MAX),
    default: DefaultValue::Derived("the model's"),
    doc: "window variance below which it may be still again (<= var_enter)",
};
const MEAN_ENTER: Key = Key {
    name: "mean_enter",
    ty: Type::Positive(f64::MAX),
    default: DefaultValue::Derived("the model's"),
    doc: "|window mean - drift| above which the sensor is moving (input units)",
};
const MEAN_EXIT: Key = Key {
    name: "mean_exit",
    ty: Type::Positive(f64::MAX),
    default: DefaultValue::Derived("the model's"),
    doc: "|window mean - drift| below which it may be still again (<= mean_enter)",
};

/// `predict.none`.
pub const NONE_KIND: Kind = Kind {
    name: "predict.none",
    role: Role::Process,
    summary: "no drift model: drift estimate 0",
    keys: &[],
    parse: |_| Ok(Box::new(NoDriftParams)),
};

/// `predict.rbf` (with `predictor = "ar"`: the model's AR(p) baseline in the network's place).
pub const RBF_KIND: Kind = Kind {
    name: "predict.rbf",
    role: Role::Process,
    summary: "the paper's RBF drift model (`driftless train`; or the model's AR(p) baseline in its place), anchored while still, free-running while moving; models must match rate_hz and input_units",
    keys: &[
        MODEL,
        MODELS,
        PREDICTOR,
        STILL_WINDOW,
        SETTLE,
        VAR_ENTER,
        VAR_EXIT,
        MEAN_ENTER,
        MEAN_EXIT,
    ],
    parse: parse_rbf,
};

/// `predict.none` parameters (it has none).
#[derive(Debug, Clone, Copy)]
struct NoDriftParams;

impl Params for NoDriftParams {
    fn stage(&self, _cx: &Context) -> Result<Box<dyn Stage>, String> {
        Ok(Box::new(NoDrift))
    }
}

/// `predict.rbf` parameters: the drift models, loaded and checked against the pipeline at
/// validation, one per axis (a shared model is repeated).
#[derive(Debug, Clone)]
pub struct RbfParams {
    /// Model file of each axis.
    pub paths: Vec<PathBuf>,
    /// The model of each axis.
    pub models: Vec<crate::drift::DriftModel>,
    /// The stillness thresholds of each axis (the model's, with the overrides applied).
    pub stillness: Vec<crate::drift::StillnessConfig>,
    /// The network, or the models' AR(p) baselines in its place.
    pub predictor: PredictorKind,
}

impl Params for RbfParams {
    fn stage(&self, cx: &Context) -> Result<Box<dyn Stage>, String> {
        Ok(Box::new(RbfDrift::new(self, cx)?))
    }

    fn describe(&self, _input: Option<&str>, _output: &str) -> Vec<String> {
        self.paths
            .iter()
            .zip(&self.models)
            .enumerate()
            .map(|(axis, (path, m))| {
                let predictor = match self.predictor {
                    PredictorKind::Rbf => format!(
                        "{} lags, {} centres",
                        m.network.lags,
                        m.network.centre_count()
                    ),
                    PredictorKind::Ar => format!("its AR({}) baseline", m.baselines.ar.coef.len()),
                };
                format!(
                    "axis {axis}: model {} ({} Hz, {}, {predictor}, trained on {} [{}])",
                    path.display(),
                    m.rate_hz,
                    m.units,
                    m.provenance.file,
                    m.provenance.column
                )
            })
            .collect()
    }
}

/// Load every model of a `predict.rbf` stage and check it against the pipeline: it loads, its
/// rate and units are the pipeline's, and there is one per axis (or one shared).
fn parse_rbf(t: &mut Table<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    let model = t.get::<String>(&MODEL)?;
    let models = t.get::<Vec<Spanned<String>>>(&MODELS)?;
    let predictor = t.choice_or_default(&PREDICTOR, "predictor", true)?;
    // One of the key's choices, PredictorKind::NAMES.
    let predictor = PredictorKind::from_name(&predictor).unwrap_or_default();
    let still_window = t.int(&STILL_WINDOW)?;
    let settle = t.int(&SETTLE)?;
    let mut thresholds = [None; 4];
    for (slot, key) in thresholds
        .iter_mut()
        .zip([&VAR_ENTER, &VAR_EXIT, &MEAN_ENTER, &MEAN_EXIT])
    {
        *slot = t.float(key)?;
    }
    let (src, cx) = (t.src, t.cx);
    let axes = cx.axes;
    let files: Vec<&Spanned<String>> = match (&model, &models) {
        (Some(m), None) => vec![m; axes],
        (None, Some(list)) => {
            if list.get_ref().len() != axes {
                return Err(src.span(
                    list,
                    format!(
                        "`models` lists {} model(s) but the pipeline has {axes} axes (one per axis, or a shared `model`)",
                        list.get_ref().len()
                    ),
                ));
            }
            list.get_ref().iter().collect()
        }
        (Some(m), Some(_)) => {
            return Err(src.span(
                m,
                "give `model` (shared) or `models` (one per axis), not both",
            ))
        }
        (None, None) => {
            return Err(t.error(
                "predict.rbf needs `model` (one model for every axis) or `models` (one per axis)",
            ))
        }
    };
    let mut paths = Vec::with_capacity(axes);
    let mut loaded = Vec::with_capacity(axes);
    let mut stillness = Vec::with_capacity(axes);
    for f in files {
        let path = src.resolve(f.get_ref());
        let m = crate::io::model_file::read_model(&path).map_err(|e| src.span(f, e))?;
        if (m.rate_hz - cx.rate_hz).abs() > 1e-9 * cx.rate_hz {
            return Err(src.span(
                f,
                format!(
                    "model {} was trained at {} Hz but the pipeline runs at {} Hz",
                    path.display(),
                    m.rate_hz,
                    cx.rate_hz
                ),
            ));
        }
        if m.units != cx.units {
            return Err(src.span(
                f,
                format!(
                    "model {} is in {} but the pipeline's input_units are {}",
                    path.display(),
                    m.units,
                    cx.units
                ),
            ));
        }
        let mut s = m.stillness;
        if let Some(w) = still_window {
            s.window = w;
        }
        if let Some(v) = settle {
            s.settle = v;
        }
        for (field, value) in [
            &mut s.var_enter,
            &mut s.var_exit,
            &mut s.mean_enter,
            &mut s.mean_exit,
        ]
        .into_iter()
        .zip(thresholds)
        {
            if let Some(v) = value {
                *field = v;
            }
        }
        s.check()
            .map_err(|e| t.error(format!("predict.rbf: {e}")))?;
        paths.push(path);
        loaded.push(m);
        stillness.push(s);
    }
    Ok(Box::new(RbfParams {
        paths,
        models: loaded,
        stillness,
        predictor,
    }))
}

/// Drift estimate 0; its uncertainty not provided (nothing estimated it).
pub struct NoDrift;

impl Stage for NoDrift {
    fn process(&mut self, input: &GyroSample) -> Option<GyroSample> {
        let mut out = *input;
        out.drift = [0.0; 3];
        out.drift_std = [DRIFT_STD_NOT_PROVIDED; 3];
        out.rate = out.denoised;
        Some(out)
    }
}

/// `predict.rbf`: one compensator per axis, around the model's network or its AR(p) baseline
/// (`predictor`). The published rate is the denoised rate minus the
/// predicted drift. Flags: [`FLAG_STILL`] when every axis is still, [`FLAG_MOVING`] when any axis
/// is moving (before its first stop too), [`FLAG_WARMING_UP`] while an axis has never been still
/// (nothing subtracted there).
/// The models work in the pipeline's input units; samples arrive in rad/s and are scaled.
pub struct RbfDrift {
    comps: Vec<Compensator<ModelPredictor>>,
    /// rad/s per model unit.
    scale: f64,
}

impl RbfDrift {
    /// Build from validated parameters (the models were checked against the pipeline).
    pub fn new(p: &RbfParams, cx: &Context) -> Result<Self, String> {
        let mut comps = Vec::with_capacity(p.models.len());
        for (m, s) in p.models.iter().zip(&p.stillness) {
            comps.push(Compensator::new(
                m.predictor(p.predictor),
                m.lowband()?,
                *s,
                m.max_step,
            )?);
        }
        Ok(RbfDrift {
            comps,
            scale: cx.units.to_rad_per_s(),
        })
    }
}

impl Stage for RbfDrift {
    fn process(&mut self, input: &GyroSample) -> Option<GyroSample> {
        let mut out = *input;
        let (mut still, mut moving, mut warming) = (true, false, false);
        // The RBF model gives no uncertainty of its prediction: not provided (an honest -1
        // rather than a number no filter computed).
        out.drift_std = [DRIFT_STD_NOT_PROVIDED; 3];
        for (axis, c) in self.comps.iter_mut().enumerate() {
            let step = c.push(input.denoised[axis] / self.scale);
            out.drift[axis] = step.drift * self.scale;
            out.rate[axis] = input.denoised[axis] - out.drift[axis];
            match step.mode {
                Mode::Still => {}
                Mode::Moving => (still, moving) = (false, true),
                Mode::Warming => (still, warming) = (false, true),
            }
            moving |= c.is_moving();
        }
        out.flags |= motion_flags(still, moving, warming);
        Some(out)
    }
}

/// The flags of a drift predictor's sample from its axes: [`FLAG_MOVING`] if any axis moves,
/// else [`FLAG_STILL`] if every axis is still; [`FLAG_WARMING_UP`] if any axis has nothing to go
/// on.
pub fn motion_flags(all_still: bool, any_moving: bool, any_warming: bool) -> u32 {
    let mut flags = 0;
    if any_moving {
        flags |= FLAG_MOVING;
    } else if all_still {
        flags |= FLAG_STILL;
    }
    if any_warming {
        flags |= FLAG_WARMING_UP;
    }
    flags
}
