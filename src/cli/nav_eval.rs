//! `driftless nav-eval`: the heading benchmark. Known motion (a built-in profile,
//! [`crate::nav::profiles`], or a truth file, [`crate::io::truth`]) is added to a static gyro log
//! (or to the simulator's noise), every method corrects the sum, and each is judged by the
//! heading error a navigator integrating it would see, window by window, against ZARU with the
//! true stops.
//!
//! Methods: the baselines a navigator already has and the library's estimators
//! ([`crate::nav::eval::Method`]), plus pipelines run through the daemon's own stage code
//! ([`crate::pipeline::offline::Offline`]): the product's chain `denoise.wavelet ->
//! predict.bias` built in at the log's rate with the axis' terms; with `--model`, the paper's
//! `denoise.wavelet -> predict.rbf` and the same with the model's AR(p) in the network's place;
//! and any `--pipeline FILE`.

use super::duration::parse_seconds;
use super::simulate::parse_number;
use super::CliError;
use crate::allan::{allan, chi2::ONE_SIGMA, fit_terms, Kind, TauGrid};
use crate::cli::log_input::{self, BagArgs};
use crate::drift::bias::{own_terms, stillness_from_terms, BiasModel, BiasTerms, ColumnFit};
use crate::drift::PredictorKind;
use crate::io::plot::{self, Panel, PanelStyle, Series};
use crate::io::rate_log::RateLog;
use crate::io::truth::read_truth;
use crate::nav::{
    evaluate, format_table_labelled, fusion, generate, heading_error, summarize_methods,
    BiasEstimator, HeadingAccumulator, HeadingMetrics, Method, MethodSummary, MotionTrace, Profile,
    Setup, Zaru,
};
use crate::pipeline::config::{self, Pipeline};
use crate::pipeline::offline::Offline;
use crate::sim::{SimConfig, Simulator};
use crate::stages::schema::Src;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// Arguments of `driftless nav-eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A static gyro log: CSV (`.gz` too) with rates in deg/s, or a ROS 2 bag (an MCAP file or
    /// a rosbag2 directory, see --topic); or `--sim SENSOR` instead.
    pub input: Option<PathBuf>,
    /// The bag's topic.
    #[command(flatten)]
    pub bag: BagArgs,
    /// Sample rate of the log, Hz (required for CSV; a bag's comes from its stamps; with
    /// `--sim`: default 100).
    #[arg(long, allow_hyphen_values = true)]
    pub rate: Option<String>,
    /// Columns to use, one axis each (repeatable; default: every numeric column but time).
    #[arg(long = "column", value_name = "NAME")]
    pub columns: Vec<String>,
    /// Instead of a log: the simulator's noise of this sensor (adis16405, adxrs450), 3 axes.
    #[arg(long, value_name = "SENSOR")]
    pub sim: Option<String>,
    /// Windows per axis with `--sim`.
    #[arg(long, default_value = "6")]
    pub windows: usize,
    /// Motion profiles, comma separated (stop-and-go, vehicle, continuous, pedestrian) or `all`
    /// (the default without `--truth`).
    #[arg(long, conflicts_with = "truth")]
    pub motion: Option<String>,
    /// Instead of the profiles: a CSV of the true rate (deg/s) at the log's rate, added to every
    /// window. Rate columns: one for every axis, or one per axis in column order; optional
    /// `still...` columns (0/1; one for every rate column or one each) give the oracle's stops,
    /// else still is a rate of exactly 0; an optional time column must step at the log's rate.
    /// Its rows are the window: exactly `--window` samples when that is given.
    #[arg(long, value_name = "FILE.csv")]
    pub truth: Option<PathBuf>,
    /// Length of each window (e.g. 10min, 600s; default 10min, or the `--truth` file's length).
    #[arg(long)]
    pub window: Option<String>,
    /// The start of the log that the Allan fit characterises (`--terms fit`); the windows come
    /// after it, so they are held out.
    #[arg(long, default_value = "33min")]
    pub characterise: String,
    /// Noise terms of the estimators: `fit` (what `driftless allan --stage` takes from the
    /// characterisation part: one set for every axis) or a sensor profile (adis16405,
    /// adxrs450). With `--sim`: the simulated sensor's.
    #[arg(long, default_value = "fit")]
    pub terms: String,
    /// Output step of the log, deg/s (0: not quantised; the ADIS16405's is 0.05).
    #[arg(long, default_value = "0")]
    pub lsb: String,
    /// RBF drift models (`driftless train`, at the log's rate): adds the paper's chain
    /// `denoise.wavelet -> predict.rbf` as a method, and the same chain with the model's AR(p)
    /// baseline in the network's place (`predictor = "ar"`). One model for every axis, or one
    /// per axis in column order (repeat the option): the network works on the drift's levels,
    /// so a model trained on one axis does not carry to another axis' bias.
    #[arg(long = "model", value_name = "MODEL.json")]
    pub models: Vec<PathBuf>,
    /// A pipeline file whose stages after its ingest run offline as one more method
    /// (repeatable). Its rate must be the log's; rates are fed in its `input_units`.
    #[arg(long = "pipeline", value_name = "FILE.toml")]
    pub pipelines: Vec<PathBuf>,
    /// One JSON document on stdout instead of tables.
    #[arg(long)]
    pub json: bool,
    /// SVG of the heading error over time of the first window, per method.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
}

/// The static noise: one series per axis, deg/s, and where the windows may start.
struct Source {
    name: String,
    rate: f64,
    axes: Vec<(String, Vec<f64>)>,
    first_window: usize,
    terms: Vec<BiasTerms>,
    floor: Option<SimConfig>,
}

/// Where the static noise comes from: a log read, or a simulated sensor.
enum Input<'a> {
    Log(Box<RateLog>),
    Sim(&'a str),
}

/// A method that runs a pipeline's stages.
struct Chain {
    label: String,
    /// One per axis (each run alone), or one for all axes (a user's file, run lane by lane).
    pipelines: Vec<Pipeline>,
}

fn log_source(log: RateLog, args: &Args, rate: f64, window: usize) -> Result<Source, CliError> {
    let mut table = log.table;
    let path = table.path.clone();
    if log.origin.bag.is_some() {
        // A bag's rates are rad/s; the navigation and its terms here are in deg/s.
        for c in &mut table.columns {
            c.iter_mut().for_each(|v| *v = v.to_degrees());
        }
    }
    let characterise = (parse_seconds(&args.characterise)
        .map_err(|e| CliError::input(format!("--characterise {e}")))?
        * rate)
        .round() as usize;
    let lsb = parse_number("--lsb", &args.lsb)?;
    if !(lsb.is_finite() && lsb >= 0.0) {
        return Err(CliError::input(format!(
            "--lsb '{}' must be >= 0",
            args.lsb
        )));
    }
    let rows = table.rows();
    if rows < characterise + window {
        return Err(CliError::input(format!(
            "{}: {rows} rows, but the characterisation ({characterise}) and one window ({window}) need {}",
            path.display(),
            characterise + window
        )));
    }
    let axes: Vec<(String, Vec<f64>)> = table.names.into_iter().zip(table.columns).collect();
    let terms = if args.terms == "fit" {
        // What `driftless allan --stage` writes for this record: the user's path itself.
        let mut fitted = Vec::with_capacity(axes.len());
        for (name, y) in &axes {
            let points = allan(
                &y[..characterise],
                rate,
                Kind::Oadev,
                &TauGrid::Octave,
                ONE_SIGMA,
            )
            .map_err(|e| CliError::input(format!("{}: {name}: {e}", path.display())))?;
            let fit = fit_terms(&points, ONE_SIGMA).map_err(|e| {
                CliError::input(format!(
                    "{}: {name}: no noise terms from the first {characterise} rows ({e}); give --terms adis16405 or a longer --characterise",
                    path.display()
                ))
            })?;
            fitted.push((name.as_str(), fit, points));
        }
        let columns: Vec<ColumnFit> = fitted
            .iter()
            .map(|(name, fit, points)| ColumnFit { name, fit, points })
            .collect();
        let own = own_terms(&columns, lsb)
            .map_err(|e| CliError::input(format!("{}: {e}", path.display())))?;
        vec![own.terms; axes.len()]
    } else {
        vec![profile_terms(&args.terms)?; axes.len()]
    };
    Ok(Source {
        name: path.display().to_string(),
        rate,
        axes,
        first_window: characterise,
        terms,
        floor: None,
    })
}

fn profile_terms(name: &str) -> Result<BiasTerms, CliError> {
    BiasTerms::profile(name).map_err(|e| CliError::input(format!("--terms: {e}")))
}

fn sim_source(sensor: &str, args: &Args, rate: f64, window: usize) -> Result<Source, CliError> {
    let mut cfg = SimConfig::profile(sensor).map_err(|e| CliError::input(format!("--sim: {e}")))?;
    cfg.rate_hz = rate;
    cfg.axes = 3;
    let n = window * args.windows;
    let mut axes: Vec<(String, Vec<f64>)> = (0..3)
        .map(|a| (format!("sim axis {a}"), Vec::with_capacity(n)))
        .collect();
    let mut sim = Simulator::new(&cfg).map_err(|e| CliError::input(format!("--sim: {e}")))?;
    for _ in 0..n {
        let s = sim.next_sample();
        for (a, (_, y)) in axes.iter_mut().enumerate() {
            y.push(s.measured[a]);
        }
    }
    let terms = if args.terms == "fit" {
        profile_terms(sensor)?
    } else {
        profile_terms(&args.terms)?
    };
    Ok(Source {
        name: format!("simulated {sensor}"),
        rate,
        axes,
        first_window: 0,
        terms: vec![terms; 3],
        floor: Some(cfg),
    })
}

/// A one-axis pipeline at `rate`: `denoise.wavelet` (defaults) then `predict` (its kind and
/// keys, TOML), as a pipeline file would say it.
fn builtin_pipeline(rate: f64, predict: &str, name: &str) -> Result<Pipeline, CliError> {
    builtin_pipeline_with(rate, "denoise.wavelet", predict, name)
}

/// [`builtin_pipeline`] with another denoise kind (its defaults).
fn builtin_pipeline_with(
    rate: f64,
    denoise: &str,
    predict: &str,
    name: &str,
) -> Result<Pipeline, CliError> {
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
    // Errors here come from the user's model (rate, units): exit 2, the model named.
    config::parse(Path::new(name), &text).map_err(CliError::from)
}

/// The product's chain, `denoise.wavelet -> predict.bias`, with each axis' terms.
fn bias_chain(src: &Source) -> Result<Chain, CliError> {
    let pipelines = src
        .terms
        .iter()
        .map(|t| {
            let keys = format!("kind = \"predict.bias\"\n{}", t.stage_keys());
            builtin_pipeline(
                src.rate,
                &keys,
                "<built-in denoise.wavelet -> predict.bias>",
            )
        })
        .collect::<Result<_, _>>()?;
    Ok(Chain {
        label: "denoise.wavelet -> predict.bias (stages)".into(),
        pipelines,
    })
}

/// The chain for navigators with the vehicle's stop signal, `denoise.none -> predict.bias`
/// reading `stop_input`, with each axis' terms: [`Offline::run_series`] publishes each case's
/// true stops on it. What a navigator whose vehicle says when it stands gets.
fn stop_signal_chain(src: &Source) -> Result<Chain, CliError> {
    let pipelines = src
        .terms
        .iter()
        .map(|t| {
            let keys = format!(
                "kind = \"predict.bias\"\nstop_input = \"nav-eval/stop\"\n{}",
                t.stage_keys()
            );
            builtin_pipeline_with(
                src.rate,
                "denoise.none",
                &keys,
                "<built-in denoise.none -> predict.bias, stop signal>",
            )
        })
        .collect::<Result<_, _>>()?;
    Ok(Chain {
        label: "denoise.none -> predict.bias (stages; stop signal: the true stops)".into(),
        pipelines,
    })
}

/// The paper's chain, `denoise.wavelet -> predict.rbf`, with the network or (`predictor =
/// "ar"`) the models' AR(p) baselines in its place: one model for every axis, or one each.
fn rbf_chain(
    src: &Source,
    models: &[PathBuf],
    predictor: PredictorKind,
) -> Result<Chain, CliError> {
    let axes = src.axes.len();
    if models.len() != 1 && models.len() != axes {
        return Err(CliError::input(format!(
            "--model: {} models for {axes} axes (give one, or one per axis)",
            models.len()
        )));
    }
    let name = predictor.name();
    let pipelines = (0..axes)
        .map(|a| {
            let m = &models[a.min(models.len() - 1)];
            let path = std::path::absolute(m)
                .map_err(|e| CliError::input(format!("{}: {e}", m.display())))?;
            let keys = format!(
                "kind = \"predict.rbf\"\nmodel = {:?}\npredictor = \"{name}\"",
                path.display().to_string()
            );
            builtin_pipeline(src.rate, &keys, &format!("--model {}", m.display()))
        })
        .collect::<Result<_, _>>()?;
    Ok(Chain {
        label: match predictor {
            PredictorKind::Rbf => "denoise.wavelet -> predict.rbf (stages)".into(),
            PredictorKind::Ar => "denoise.wavelet -> predict.rbf, predictor ar (stages)".into(),
        },
        pipelines,
    })
}

fn file_chain(path: &Path, rate: f64) -> Result<Chain, CliError> {
    let p = config::load(path)?;
    if (p.rate_hz - rate).abs() > 1e-9 * rate {
        // Point at the value: the pipeline keeps values, not spans, so read its span again (a
        // text search could land on a comment).
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
    Offline::new(&p).map_err(|e| CliError::input(format!("{}: {e}", path.display())))?;
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
    })
}

/// The column of x-io Fusion's gyroscope bias algorithm ([`fusion`]).
const FUSION_LABEL: &str = "x-io Fusion bias (imufusion defaults)";

/// The motion added to the windows: a built-in profile, drawn anew for each window and axis
/// (seed `3 w + axis`), or a truth file's motion, the same for every window.
enum Motion {
    Profile(Profile),
    Truth {
        label: String,
        /// One per axis.
        traces: Vec<MotionTrace>,
    },
}

impl Motion {
    fn label(&self) -> String {
        match self {
            Motion::Profile(p) => p.to_string(),
            Motion::Truth { label, .. } => label.clone(),
        }
    }

    /// The motion of each of `axes` axes in window `w`.
    fn traces(
        &self,
        rate: f64,
        window_s: f64,
        w: usize,
        axes: usize,
    ) -> Result<Vec<MotionTrace>, CliError> {
        match self {
            Motion::Profile(p) => (0..axes)
                .map(|a| generate(*p, rate, window_s, (w * 3 + a) as u64))
                .collect::<Result<_, _>>()
                .map_err(|e| CliError::internal(e.to_string())),
            Motion::Truth { traces, .. } => Ok(traces.clone()),
        }
    }
}

/// One evaluated case: a window of one axis under one motion (an index into the motions).
struct Case {
    motion: usize,
    window: usize,
    axis: usize,
    metrics: Vec<HeadingMetrics>,
}

fn metrics_of(corrected: &[f64], truth: &[f64], dt: f64) -> HeadingMetrics {
    let mut acc = HeadingAccumulator::new(dt);
    for (&c, &t) in corrected.iter().zip(truth) {
        // A sample a stage never published (it cannot happen with the shipped stages) counts as
        // uncorrected zero rate, not as silently skipped.
        acc.push(if c.is_finite() { c } else { 0.0 }, t);
    }
    acc.metrics()
}

fn parse_profiles(s: &str) -> Result<Vec<Profile>, CliError> {
    if s == "all" {
        return Ok(Profile::ALL.to_vec());
    }
    s.split(',')
        .map(|p| {
            p.trim()
                .parse::<Profile>()
                .map_err(|e| CliError::input(format!("--motion: {e}")))
        })
        .collect()
}

fn summary_json(s: &MethodSummary, label: &str) -> Value {
    let sum = |x: &crate::nav::Summary| json!({"median": x.median, "p90": x.p90, "worst": x.worst});
    json!({
        "method": label,
        "rms_heading_deg": sum(&s.rms),
        "final_heading_deg": sum(&s.final_abs),
        "max_heading_deg": sum(&s.max),
        "rms_rate_degps": sum(&s.rms_rate),
        "rms_ratio_to_zaru_oracle": sum(&s.rms_ratio),
        "rms_ratio_to_floored_zaru_oracle": sum(&s.rms_ratio_floored),
        "final_ratio_to_zaru_oracle": sum(&s.final_ratio),
    })
}

/// Run `driftless nav-eval`.
pub fn run(args: Args) -> Result<(), CliError> {
    // Profiles before the log, so a typo fails at once.
    let profiles = parse_profiles(args.motion.as_deref().unwrap_or("all"))?;
    let given = match &args.rate {
        Some(r) => Some(parse_number("--rate", r)?),
        None => None,
    };
    let input = match (&args.input, &args.sim) {
        (Some(p), None) => Input::Log(Box::new(log_input::open(
            p,
            &args.columns,
            &args.bag,
            false,
        )?)),
        (None, Some(s)) => Input::Sim(s),
        (Some(_), Some(_)) => return Err(CliError::input("give a log or --sim, not both")),
        (None, None) => return Err(CliError::input("give a static log, or --sim SENSOR")),
    };
    let rate = match &input {
        Input::Log(log) => log.origin.rate(given).map_err(CliError::input)?,
        Input::Sim(_) => given.unwrap_or(100.0),
    };
    if !(rate.is_finite() && rate > 0.0 && rate <= 1e6) {
        return Err(CliError::input(format!(
            "--rate {rate} must be in (0, 1e6] Hz"
        )));
    }
    // A truth file before the windows: its length is the window's.
    let truth = match &args.truth {
        Some(path) => {
            super::log_input::check_text_input(path, crate::io::truth::TRUTH_TAKES)?;
            Some(read_truth(path, rate)?)
        }
        None => None,
    };
    let window = match (&args.window, &truth) {
        (Some(w), _) => {
            let window_s =
                parse_seconds(w).map_err(|e| CliError::input(format!("--window {e}")))?;
            (window_s * rate).round() as usize
        }
        (None, Some(t)) => t.rows(),
        (None, None) => (600.0 * rate).round() as usize,
    };
    if window < 2 {
        return Err(CliError::input("--window holds fewer than 2 samples"));
    }
    // Whole samples: a truth file's motion is exactly one row per sample.
    let window_s = window as f64 / rate;
    if let Some(t) = &truth {
        if t.rows() != window {
            return Err(CliError::input(format!(
                "{}: {} rows, but a window of {} s at {rate} Hz is {window} samples: a truth file holds exactly one window (leave out --window to take its length)",
                t.path.display(),
                t.rows(),
                window_s
            )));
        }
    }
    let src = match input {
        Input::Log(log) => log_source(*log, &args, rate, window)?,
        Input::Sim(s) => {
            if !(1..=1000).contains(&args.windows) {
                return Err(CliError::input("--windows must be 1..=1000"));
            }
            sim_source(s, &args, rate, window)?
        }
    };
    let motions: Vec<Motion> = match &truth {
        Some(t) => vec![Motion::Truth {
            label: format!(
                "truth {}",
                t.path.file_name().map_or_else(
                    || t.path.display().to_string(),
                    |f| f.to_string_lossy().into_owned()
                )
            ),
            traces: t.traces(src.axes.len(), rate)?,
        }],
        None => profiles.into_iter().map(Motion::Profile).collect(),
    };
    let mut chains = vec![bias_chain(&src)?, stop_signal_chain(&src)?];
    if !args.models.is_empty() {
        chains.push(rbf_chain(&src, &args.models, PredictorKind::Rbf)?);
        chains.push(rbf_chain(&src, &args.models, PredictorKind::Ar)?);
    }
    for p in &args.pipelines {
        chains.push(file_chain(p, rate)?);
    }
    let mut methods = vec![
        Method::Raw,
        Method::PowerOn,
        Method::ZaruOracle,
        Method::ZaruDetected,
        Method::ZaruDenoised,
        Method::KfDetected,
        Method::KfOracle,
        Method::KfOracleFixed,
    ];
    if src.floor.is_some() {
        methods.push(Method::Floor);
    }
    let mut labels: Vec<String> = methods.iter().map(|m| m.label().to_string()).collect();
    labels.push(FUSION_LABEL.into());
    labels.extend(chains.iter().map(|c| c.label.clone()));

    let windows = (src.axes[0].1.len() - src.first_window) / window;
    let dt = 1.0 / rate;
    let mut cases: Vec<Case> = Vec::new();
    let mut plot_traces: Option<(Vec<f64>, Vec<Vec<f64>>)> = None;
    for (mi, motion) in motions.iter().enumerate() {
        for w in 0..windows {
            let start = src.first_window + w * window;
            let motion_traces = motion.traces(rate, window_s, w, src.axes.len())?;
            let measured: Vec<Vec<f64>> = src
                .axes
                .iter()
                .zip(&motion_traces)
                .map(|((_, y), m)| {
                    y[start..start + window]
                        .iter()
                        .zip(&m.truth)
                        .map(|(x, t)| x + t)
                        .collect()
                })
                .collect();
            // Each axis alone, the others still: nav-eval gives every axis its own motion, so
            // a case is one axis of a vehicle whose stops are that axis's (Fusion waits for all
            // three axes to be still; other axes' unrelated motion would only handicap it).
            let fusion_out: Vec<Vec<f64>> = measured
                .iter()
                .map(|y| fusion::correct(&[y], rate).remove(0))
                .collect();
            // Stage methods: per-axis pipelines one axis at a time, a file's all axes at once.
            // A chain reading a stop signal gets each axis's true stops, so it runs each axis
            // alone (the axes' motions, and so their stops, differ).
            let mut chain_out: Vec<Vec<Vec<f64>>> = Vec::with_capacity(chains.len());
            for c in &chains {
                let reads_stops = c
                    .pipelines
                    .iter()
                    .any(|p| p.stages.iter().any(|s| !s.params.side_inputs().is_empty()));
                if c.pipelines.len() > 1 || reads_stops {
                    let mut per_axis = Vec::with_capacity(src.axes.len());
                    for (a, y) in measured.iter().enumerate() {
                        let p = &c.pipelines[a.min(c.pipelines.len() - 1)];
                        let stops = reads_stops.then_some(motion_traces[a].still.as_slice());
                        per_axis
                            .extend(Offline::run_series(p, &[y], stops).map_err(CliError::input)?);
                    }
                    chain_out.push(per_axis);
                } else {
                    let inputs: Vec<&[f64]> = measured.iter().map(Vec::as_slice).collect();
                    chain_out.push(
                        Offline::run_series(&c.pipelines[0], &inputs, None)
                            .map_err(CliError::input)?,
                    );
                }
            }
            for (a, m) in motion_traces.iter().enumerate() {
                let mut setup = Setup::new(src.terms[a], rate);
                if let Some(cfg) = &src.floor {
                    setup.floor = Some(
                        BiasModel::simulator_truth(cfg, setup.terms.initial_sd)
                            .map_err(|e| CliError::internal(e.to_string()))?,
                    );
                }
                let mut metrics = evaluate(&measured[a], &m.truth, &m.still, &setup, &methods)
                    .map_err(|e| CliError::input(format!("{}: {e}", src.name)))?;
                metrics.push(metrics_of(&fusion_out[a], &m.truth, dt));
                for out in &chain_out {
                    metrics.push(metrics_of(&out[a], &m.truth, dt));
                }
                if plot_traces.is_none() && args.plot.is_some() {
                    plot_traces = Some(traces(&measured[a], m, &chain_out, a, &setup)?);
                }
                cases.push(Case {
                    motion: mi,
                    window: w,
                    axis: a,
                    metrics,
                });
            }
        }
    }

    let table = |title: &str, sel: &dyn Fn(&Case) -> bool| -> (String, Vec<MethodSummary>) {
        let res: Vec<Vec<HeadingMetrics>> = cases
            .iter()
            .filter(|c| sel(c))
            .map(|c| c.metrics.clone())
            .collect();
        // Chain columns have no `Method`: a placeholder that is never the reference, relabelled
        // on output.
        let all: Vec<Method> = (0..labels.len())
            .map(|i| methods.get(i).copied().unwrap_or(Method::KfDenoised))
            .collect();
        (
            title.to_string(),
            summarize_methods(&all, &res, Method::ZaruOracle),
        )
    };
    let mut sections: Vec<(String, Vec<MethodSummary>)> = motions
        .iter()
        .enumerate()
        .map(|(i, m)| table(&m.label(), &|c: &Case| c.motion == i))
        .collect();
    if motions.len() > 1 {
        sections.push(table("all profiles", &|_| true));
    }

    if let (Some(path), Some((t, series))) = (&args.plot, &plot_traces) {
        let mut names = vec![
            "power-on".to_string(),
            "ZARU oracle".into(),
            "ZARU detected".into(),
        ];
        names.extend(chains.iter().map(|c| c.label.clone()));
        let panel = Panel {
            title: format!(
                "heading error, {} motion, first window of {} ({})",
                motions[0].label(),
                src.axes[0].0,
                src.name
            ),
            x_label: "time (s)".into(),
            y_label: "heading error (deg)".into(),
            series: names
                .into_iter()
                .zip(series)
                .map(|(name, h)| Series {
                    name,
                    points: t.iter().copied().zip(h.iter().copied()).collect(),
                })
                .collect(),
            style: PanelStyle::default(),
        };
        plot::write_panels(path, &[panel])
            .map_err(|e| CliError::input(format!("{}: {e}", path.display())))?;
        eprintln!("wrote {}", path.display());
    }

    let cases_per = windows * src.axes.len();
    if args.json {
        let terms: Vec<Value> = src
            .axes
            .iter()
            .zip(&src.terms)
            .map(|((name, _), t)| {
                json!({"axis": name, "arw_deg_per_sqrt_h": t.n * 60.0, "bias_instability_deg_per_h": t.b * 3600.0,
                       "rrw_deg_per_h_per_sqrt_h": t.k * 216_000.0, "lsb_degps": t.lsb})
            })
            .collect();
        let sections: Vec<Value> = sections
            .iter()
            .map(|(title, rows)| {
                json!({"profile": title, "methods": rows.iter().zip(&labels)
                    .map(|(r, l)| summary_json(r, l)).collect::<Vec<_>>()})
            })
            .collect();
        // Every case too, so the worst window can be found and replayed.
        let cases: Vec<Value> = cases
            .iter()
            .map(|c| {
                let methods: Vec<Value> = c
                    .metrics
                    .iter()
                    .zip(&labels)
                    .map(|(m, l)| {
                        json!({"method": l, "rms_heading_deg": m.rms_deg,
                               "final_heading_deg": m.final_deg, "max_heading_deg": m.max_deg,
                               "rms_rate_degps": m.rms_rate})
                    })
                    .collect();
                json!({"profile": motions[c.motion].label(), "window": c.window,
                       "start_s": (src.first_window + c.window * window) as f64 / rate,
                       "axis": src.axes[c.axis].0, "methods": methods})
            })
            .collect();
        println!(
            "{}",
            json!({"source": src.name, "rate_hz": rate, "window_s": window_s,
                   "windows_per_axis": windows, "axes": src.axes.len(), "terms": terms,
                   "reference": "ZARU oracle", "sections": sections, "cases": cases})
        );
        return Ok(());
    }
    println!(
        "{}: {} axes x {windows} windows of {window_s} s per profile ({cases_per} cases each), {rate} Hz; windows start after the first {} s{}",
        src.name,
        src.axes.len(),
        src.first_window as f64 / rate,
        if args.terms == "fit" && src.floor.is_none() {
            " (the Allan fit's part: held out)"
        } else {
            ""
        }
    );
    for ((name, _), t) in src.axes.iter().zip(&src.terms) {
        println!(
            "  {name}: N {:.3} deg/sqrt(h), B {:.2} deg/h, K {:.2} deg/h/sqrt(h), lsb {} deg/s",
            t.n * 60.0,
            t.b * 3600.0,
            t.k * 216_000.0,
            t.lsb
        );
    }
    println!();
    for (title, rows) in &sections {
        let names: Vec<&str> = labels.iter().map(String::as_str).collect();
        print!("{}", format_table_labelled(title, rows, &names));
        println!();
    }
    println!("RMS heading: the RMS over time of the integrated error (deg); final: |error| at the window's end; ref: ZARU with the true stops, per window.");
    Ok(())
}

/// Heading error traces of one case: power-on, ZARU oracle, ZARU detected, then each chain.
fn traces(
    measured: &[f64],
    m: &MotionTrace,
    chains: &[Vec<Vec<f64>>],
    axis: usize,
    setup: &Setup,
) -> Result<(Vec<f64>, Vec<Vec<f64>>), CliError> {
    let dt = 1.0 / setup.rate_hz;
    let min = (setup.zaru_min_s * setup.rate_hz).round().max(1.0) as usize;
    // Keep the SVG small: at most about 4000 points per line.
    let step = (measured.len() / 4000).max(1);
    let thin = |c: &[f64]| -> Vec<f64> {
        heading_error(c, &m.truth, dt)
            .into_iter()
            .step_by(step)
            .collect()
    };
    let t: Vec<f64> = (0..measured.len())
        .step_by(step)
        .map(|k| k as f64 * dt)
        .collect();
    let correct = |mut est: Zaru| -> Vec<f64> {
        measured
            .iter()
            .zip(&m.still)
            .map(|(&x, &s)| x - est.push(x, s))
            .collect()
    };
    let detector = stillness_from_terms(&setup.terms, setup.rate_hz, &setup.tracker)
        .map_err(|e| CliError::input(e.to_string()))?;
    let mut series = vec![
        thin(&correct(Zaru::power_on(min))),
        thin(&correct(Zaru::oracle(min))),
        thin(&correct(Zaru::detected(min, detector))),
    ];
    series.extend(chains.iter().map(|c| thin(&c[axis])));
    Ok((t, series))
}
