//! The pipeline file (TOML): the only place its schema lives.
//!
//! ```toml
//! name = "demo"              # pipeline name: node name, default stats service "demo/stats"
//! rate_hz = 1000.0           # sample rate of the ingest
//! deadline_us = 1000.0       # end-to-end deadline (default: one sample period)
//! axes = 3                   # 1..=3
//! input_units = "deg/s"      # "deg/s" or "rad/s"; published rates are always rad/s
//! report_interval_s = 2.0    # stderr summary and stats service period
//! realtime_priority = 50     # optional: SCHED_FIFO priority of the hot thread (1..=99)
//! cpu = 1                    # optional: pin the hot thread to this CPU
//!
//! [iceoryx2]
//! prefix = "driftless_"      # file prefix in /dev/shm (env DRIFTLESS_IOX2_PREFIX overrides)
//! buffer_size = 256          # samples a subscriber may hold before it loses new ones
//! max_subscribers = 8        # per service
//! stats_service = "demo/stats"
//!
//! [[stage]]
//! name = "sensor"
//! kind = "ingest.csv"
//! output = "demo/raw"
//! file = "data/replay.csv"
//! ```
//!
//! Every error names the file, line and column (from toml's spans); unknown keys are errors;
//! the stages must form one chain from an ingest to a publish, without cycles or dangling inputs.
//! An `external` stage (run by another process) is a link of the chain like any other; it may
//! not directly follow the ingest, end the chain, or follow another external stage.

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Deserialize;
use toml::de::{DeTable, DeValue};
use toml::Spanned;

use crate::io::InputError;

/// Input units of the raw rates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Units {
    /// Degrees per second.
    DegPerSec,
    /// Radians per second.
    RadPerSec,
}

impl Units {
    /// Factor converting these units to rad/s.
    pub fn to_rad_per_sec(self) -> f64 {
        match self {
            Units::DegPerSec => std::f64::consts::PI / 180.0,
            Units::RadPerSec => 1.0,
        }
    }
}

/// The iceoryx2 settings of a pipeline.
#[derive(Debug, Clone, PartialEq)]
pub struct Iceoryx2Settings {
    /// Prefix of the iceoryx2 files (the env variable `DRIFTLESS_IOX2_PREFIX` overrides it).
    pub prefix: String,
    /// Subscriber buffer size of every service.
    pub buffer_size: usize,
    /// Subscribers per service.
    pub max_subscribers: usize,
    /// The statistics service.
    pub stats_service: String,
}

/// A validated pipeline, stages in chain order (the ingest first, the publish last).
#[derive(Debug, Clone)]
pub struct Pipeline {
    /// The file it was read from.
    pub path: PathBuf,
    /// Pipeline name.
    pub name: String,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// End-to-end deadline.
    pub deadline: Duration,
    /// Number of axes (1..=3); unused axes are 0.
    pub axes: usize,
    /// Units of the raw input.
    pub input_units: Units,
    /// Period of the stderr summary and stats snapshot.
    pub report_interval: Duration,
    /// SCHED_FIFO priority of the hot thread (None: the default scheduler).
    pub realtime_priority: Option<i32>,
    /// CPU the hot thread is pinned to (None: not pinned).
    pub cpu: Option<usize>,
    /// iceoryx2 settings.
    pub iceoryx2: Iceoryx2Settings,
    /// The stages, in chain order.
    pub stages: Vec<StageSpec>,
}

/// One stage of a pipeline.
#[derive(Debug, Clone)]
pub struct StageSpec {
    /// Unique name in the pipeline.
    pub name: String,
    /// Input service (None for the simulator and CSV ingest).
    pub input: Option<String>,
    /// Output service.
    pub output: String,
    /// The kind and its parameters.
    pub kind: StageKind,
}

/// Pacing of a CSV replay.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pace {
    /// At the file's rate (its time column, or the pipeline's `rate_hz`).
    Realtime,
    /// As fast as possible.
    Asap,
}

/// A CSV replay, loaded at validation.
#[derive(Debug, Clone)]
pub struct CsvParams {
    /// The file.
    pub file: PathBuf,
    /// Sensor timestamps, ns (from the time column, or `i / rate_hz`).
    pub t_ns: Vec<u64>,
    /// The rates, one row per sample (unused axes 0).
    pub rates: Vec<[f64; 3]>,
    /// Pacing.
    pub pace: Pace,
    /// Replay again from the start at the end of the file.
    pub looped: bool,
}

/// The simulated sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct SimParams {
    /// Noise profile name.
    pub profile: String,
    /// Random seed.
    pub seed: u64,
    /// True motion: none, sines, steps, turn.
    pub motion: String,
    /// Stop after this many samples (None: run until stopped).
    pub samples: Option<u64>,
}

/// Parameters of `denoise.wavelet` (validated; passed to the streaming denoiser).
#[derive(Debug, Clone, PartialEq)]
pub struct WaveletParams {
    /// Wavelet name, e.g. "db6".
    pub wavelet: String,
    /// Decomposition level.
    pub level: usize,
    /// Threshold function name.
    pub threshold: String,
    /// Firm threshold ratio.
    pub ratio: Option<f64>,
    /// Improved threshold `a`.
    pub a: Option<f64>,
    /// Improved threshold `beta`.
    pub beta: Option<f64>,
    /// Improved threshold `kappa`.
    pub kappa: Option<f64>,
    /// Sliding window length, samples.
    pub window: usize,
    /// Output lag, samples.
    pub lag: usize,
    /// Noise sigma: None for MAD, Some(fixed).
    pub sigma: Option<f64>,
}

/// `predict.rbf` parameters: the drift models, loaded and checked against the pipeline at
/// validation, one per axis (a shared model is repeated).
///
/// ```toml
/// [[stage]]
/// name = "predict"
/// kind = "predict.rbf"
/// input = "demo/denoised"
/// output = "demo/predicted"
/// model = "models/adis-x.json"    # one model for every axis, or
/// # models = ["x.json", "y.json", "z.json"]   # one per axis
/// # Stillness overrides (default: the model's calibrated thresholds), in input_units:
/// # still_window = 50, settle = 342, var_enter = 1e-4, var_exit = 5e-5,
/// # mean_enter = 0.02, mean_exit = 0.01
/// ```
#[derive(Debug, Clone)]
pub struct RbfParams {
    /// Model file of each axis.
    pub paths: Vec<PathBuf>,
    /// The model of each axis.
    pub models: Vec<crate::drift::DriftModel>,
    /// The stillness thresholds of each axis (the model's, with the overrides applied).
    pub stillness: Vec<crate::drift::StillnessConfig>,
}

/// A stage kind and its parameters.
#[derive(Debug, Clone)]
pub enum StageKind {
    /// `ingest.sim`: the built-in simulator, paced in real time.
    IngestSim(SimParams),
    /// `ingest.csv`: a CSV replay.
    IngestCsv(CsvParams),
    /// `ingest.iceoryx2`: raw samples from another process.
    IngestIceoryx2 {
        /// How long to sleep waiting for a sample before checking for shutdown.
        poll_timeout: Duration,
    },
    /// `denoise.wavelet`: the streaming wavelet denoiser.
    DenoiseWavelet(WaveletParams),
    /// `denoise.none`: pass-through.
    DenoiseNone,
    /// `predict.none`: no drift removed.
    PredictNone,
    /// `predict.rbf`: the RBF drift model with live stillness-gated compensation.
    PredictRbf(RbfParams),
    /// `external`: a stage that runs in another process: it reads `input` and publishes
    /// `output` (both [`crate::transport::GyroSample`]); the daemon only links to it.
    External {
        /// How long the segment after it sleeps waiting for a sample before checking for
        /// shutdown (a safety net: the external process should notify after each sample).
        poll_timeout: Duration,
    },
    /// `publish`: the final, public service.
    Publish {
        /// Notify the event service of the same name after each sample.
        notify: bool,
    },
}

impl StageKind {
    /// Whether this kind starts a chain.
    pub fn is_ingest(&self) -> bool {
        matches!(
            self,
            StageKind::IngestSim(_) | StageKind::IngestCsv(_) | StageKind::IngestIceoryx2 { .. }
        )
    }

    /// The kind's name as written in pipeline files.
    pub fn name(&self) -> &'static str {
        match self {
            StageKind::IngestSim(_) => "ingest.sim",
            StageKind::IngestCsv(_) => "ingest.csv",
            StageKind::IngestIceoryx2 { .. } => "ingest.iceoryx2",
            StageKind::DenoiseWavelet(_) => "denoise.wavelet",
            StageKind::DenoiseNone => "denoise.none",
            StageKind::PredictNone => "predict.none",
            StageKind::PredictRbf(_) => "predict.rbf",
            StageKind::External { .. } => "external",
            StageKind::Publish { .. } => "publish",
        }
    }
}

/// Every kind, in the order listed in error messages.
pub const KINDS: &[&str] = &[
    "ingest.sim",
    "ingest.csv",
    "ingest.iceoryx2",
    "denoise.wavelet",
    "denoise.none",
    "predict.none",
    "predict.rbf",
    "external",
    "publish",
];

// ---------------------------------------------------------------------------------------------
// Raw (serde) shapes: deny unknown keys; spans on everything checked afterwards.

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTop {
    name: Spanned<String>,
    rate_hz: Spanned<f64>,
    deadline_us: Option<Spanned<f64>>,
    axes: Option<Spanned<i64>>,
    input_units: Option<Spanned<String>>,
    report_interval_s: Option<Spanned<f64>>,
    realtime_priority: Option<Spanned<i64>>,
    cpu: Option<Spanned<i64>>,
    iceoryx2: Option<RawIox>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawIox {
    prefix: Option<Spanned<String>>,
    buffer_size: Option<Spanned<i64>>,
    max_subscribers: Option<Spanned<i64>>,
    stats_service: Option<Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSim {
    name: Spanned<String>,
    #[allow(dead_code)]
    kind: Spanned<String>,
    output: Spanned<String>,
    profile: Option<Spanned<String>>,
    seed: Option<Spanned<i64>>,
    motion: Option<Spanned<String>>,
    samples: Option<Spanned<i64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCsv {
    name: Spanned<String>,
    #[allow(dead_code)]
    kind: Spanned<String>,
    output: Spanned<String>,
    file: Spanned<String>,
    columns: Option<Spanned<Vec<String>>>,
    time_column: Option<Spanned<String>>,
    pace: Option<Spanned<String>>,
    #[serde(rename = "loop")]
    looped: Option<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawIceoryx2 {
    name: Spanned<String>,
    #[allow(dead_code)]
    kind: Spanned<String>,
    input: Spanned<String>,
    output: Spanned<String>,
    poll_timeout_us: Option<Spanned<i64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWavelet {
    name: Spanned<String>,
    #[allow(dead_code)]
    kind: Spanned<String>,
    input: Spanned<String>,
    output: Spanned<String>,
    wavelet: Option<Spanned<String>>,
    level: Option<Spanned<i64>>,
    threshold: Option<Spanned<String>>,
    ratio: Option<Spanned<f64>>,
    a: Option<Spanned<f64>>,
    beta: Option<Spanned<f64>>,
    kappa: Option<Spanned<f64>>,
    window: Option<Spanned<i64>>,
    lag: Option<Spanned<i64>>,
    sigma: Option<Spanned<SigmaSetting>>,
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum SigmaSetting {
    Fixed(f64),
    Named(String),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPassThrough {
    name: Spanned<String>,
    #[allow(dead_code)]
    kind: Spanned<String>,
    input: Spanned<String>,
    output: Spanned<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRbf {
    name: Spanned<String>,
    #[allow(dead_code)]
    kind: Spanned<String>,
    input: Spanned<String>,
    output: Spanned<String>,
    model: Option<Spanned<String>>,
    models: Option<Spanned<Vec<Spanned<String>>>>,
    still_window: Option<Spanned<i64>>,
    settle: Option<Spanned<i64>>,
    var_enter: Option<Spanned<f64>>,
    var_exit: Option<Spanned<f64>>,
    mean_enter: Option<Spanned<f64>>,
    mean_exit: Option<Spanned<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawExternal {
    name: Spanned<String>,
    #[allow(dead_code)]
    kind: Spanned<String>,
    input: Spanned<String>,
    output: Spanned<String>,
    poll_timeout_us: Option<Spanned<i64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPublish {
    name: Spanned<String>,
    #[allow(dead_code)]
    kind: Spanned<String>,
    input: Spanned<String>,
    output: Spanned<String>,
    notify: Option<bool>,
}

// ---------------------------------------------------------------------------------------------

/// Positions errors in one source text.
struct Src<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Src<'_> {
    fn at(&self, offset: usize, message: impl Into<String>) -> InputError {
        let offset = offset.min(self.text.len());
        let before = &self.text[..floor_char_boundary(self.text, offset)];
        let line = before.matches('\n').count() as u64 + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = before[line_start..].chars().count() as u64 + 1;
        InputError::At {
            path: self.path.display().to_string(),
            line,
            column,
            message: message.into(),
        }
    }

    fn span<T>(&self, s: &Spanned<T>, message: impl Into<String>) -> InputError {
        self.at(s.span().start, message)
    }

    fn toml(&self, e: toml::de::Error, fallback: usize) -> InputError {
        let offset = e.span().map_or(fallback, |r| r.start);
        self.at(offset, e.message().trim_end().to_string())
    }
}

fn floor_char_boundary(s: &str, mut i: usize) -> usize {
    while i > 0 && !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

fn de<'i, T: Deserialize<'i>>(src: &Src<'_>, value: Spanned<DeValue<'i>>) -> Result<T, InputError> {
    let start = value.span().start;
    T::deserialize(serde::de::IntoDeserializer::into_deserializer(value))
        .map_err(|e| src.toml(e, start))
}

fn int_in(
    src: &Src<'_>,
    v: &Spanned<i64>,
    what: &str,
    lo: i64,
    hi: i64,
) -> Result<usize, InputError> {
    let x = *v.get_ref();
    if x < lo || x > hi {
        return Err(src.span(v, format!("{what} must be in {lo}..={hi}, got {x}")));
    }
    Ok(x as usize)
}

/// `poll_timeout_us` of a stage that waits on another process's service: 10 us to 1 s, default
/// 1 ms.
fn poll_timeout(src: &Src<'_>, v: Option<&Spanned<i64>>) -> Result<Duration, InputError> {
    Ok(match v {
        Some(p) => Duration::from_micros(int_in(src, p, "poll_timeout_us", 10, 1_000_000)? as u64),
        None => Duration::from_millis(1),
    })
}

fn positive(src: &Src<'_>, v: &Spanned<f64>, what: &str, max: f64) -> Result<f64, InputError> {
    let x = *v.get_ref();
    if !(x.is_finite() && x > 0.0 && x <= max) {
        return Err(src.span(v, format!("{what} must be > 0 and <= {max}, got {x}")));
    }
    Ok(x)
}

fn service(src: &Src<'_>, v: &Spanned<String>) -> Result<String, InputError> {
    crate::transport::check_service_name(v.get_ref())
        .map_err(|e| src.span(v, format!("invalid service name {:?}: {e}", v.get_ref())))?;
    Ok(v.get_ref().clone())
}

/// Read and validate a pipeline file: everything `run` needs is checked here, nothing started.
pub fn load(path: &Path) -> Result<Pipeline, InputError> {
    let text = std::fs::read_to_string(path).map_err(|source| InputError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse(path, &text)
}

/// Validate pipeline text as if read from `path` (relative files resolve against its folder).
pub fn parse(path: &Path, text: &str) -> Result<Pipeline, InputError> {
    let src = Src { path, text };
    let doc = DeTable::parse(text).map_err(|e| src.toml(e, 0))?;
    let doc_span = doc.span();
    let mut top = DeTable::new();
    let mut stage_values: Option<Spanned<DeValue<'_>>> = None;
    for (k, v) in doc.into_inner() {
        if k.get_ref() == "stage" {
            stage_values = Some(v);
        } else {
            top.insert(k, v);
        }
    }
    let raw: RawTop = de(&src, Spanned::new(doc_span.clone(), DeValue::Table(top)))?;

    let name = raw.name.get_ref().clone();
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
    {
        return Err(src.span(
            &raw.name,
            "name must be non-empty ASCII letters, digits, '-' or '_'",
        ));
    }
    let rate_hz = positive(&src, &raw.rate_hz, "rate_hz", 1e6)?;
    let deadline = match &raw.deadline_us {
        Some(d) => Duration::from_secs_f64(positive(&src, d, "deadline_us", 1e9)? * 1e-6),
        None => Duration::from_secs_f64(1.0 / rate_hz),
    };
    let axes = match &raw.axes {
        Some(a) => int_in(&src, a, "axes", 1, 3)?,
        None => 3,
    };
    let input_units = match &raw.input_units {
        None => Units::DegPerSec,
        Some(u) => match u.get_ref().as_str() {
            "deg/s" => Units::DegPerSec,
            "rad/s" => Units::RadPerSec,
            other => {
                return Err(src.span(
                    u,
                    format!("unknown input_units {other:?} (valid: \"deg/s\", \"rad/s\")"),
                ))
            }
        },
    };
    let report_interval = match &raw.report_interval_s {
        Some(r) => Duration::from_secs_f64(positive(&src, r, "report_interval_s", 3600.0)?),
        None => Duration::from_secs(2),
    };
    let realtime_priority = match &raw.realtime_priority {
        Some(p) => Some(int_in(&src, p, "realtime_priority", 1, 99)? as i32),
        None => None,
    };
    let cpu = match &raw.cpu {
        Some(c) => Some(int_in(&src, c, "cpu", 0, 1023)?),
        None => None,
    };
    let iox = raw.iceoryx2.unwrap_or(RawIox {
        prefix: None,
        buffer_size: None,
        max_subscribers: None,
        stats_service: None,
    });
    let prefix = match &iox.prefix {
        Some(p) => {
            crate::transport::check_prefix(p.get_ref())
                .map_err(|e| src.span(p, format!("invalid prefix: {e}")))?;
            p.get_ref().clone()
        }
        None => crate::transport::DEFAULT_PREFIX.to_string(),
    };
    let buffer_size = match &iox.buffer_size {
        Some(b) => int_in(&src, b, "buffer_size", 1, 65_536)?,
        None => 256,
    };
    let max_subscribers = match &iox.max_subscribers {
        Some(m) => int_in(&src, m, "max_subscribers", 2, 64)?,
        None => 8,
    };
    let stats_service = match &iox.stats_service {
        Some(s) => service(&src, s)?,
        None => format!("{name}/stats"),
    };

    let Some(stage_values) = stage_values else {
        return Err(src.at(
            doc_span.end,
            "no [[stage]] entries: a pipeline needs at least an ingest and a publish",
        ));
    };
    let stage_span = stage_values.span();
    let DeValue::Array(array) = stage_values.into_inner() else {
        return Err(src.at(
            stage_span.start,
            "`stage` must be an array of tables ([[stage]])",
        ));
    };
    let mut entries = Vec::new();
    for value in array {
        entries.push(stage(&src, value, rate_hz, axes, input_units)?);
    }
    let stages = chain(&src, entries, stage_span.start)?;
    Ok(Pipeline {
        path: path.to_path_buf(),
        name,
        rate_hz,
        deadline,
        axes,
        input_units,
        report_interval,
        realtime_priority,
        cpu,
        iceoryx2: Iceoryx2Settings {
            prefix,
            buffer_size,
            max_subscribers,
            stats_service,
        },
        stages,
    })
}

/// A parsed stage with the positions the chain check reports.
struct Entry {
    spec: StageSpec,
    name_at: usize,
    input_at: usize,
    output_at: usize,
}

fn stage<'i>(
    src: &Src<'_>,
    value: Spanned<DeValue<'i>>,
    rate_hz: f64,
    axes: usize,
    units: Units,
) -> Result<Entry, InputError> {
    let start = value.span().start;
    let kind = match value.get_ref() {
        DeValue::Table(t) => t
            .iter()
            .find(|(k, _)| k.get_ref() == "kind")
            .map(|(_, v)| (v.span().start, v.get_ref().as_str().map(str::to_string))),
        _ => return Err(src.at(start, "each [[stage]] must be a table")),
    };
    let (kind_at, kind) = match kind {
        None => {
            return Err(src.at(
                start,
                format!("stage without `kind` (valid: {})", KINDS.join(", ")),
            ))
        }
        Some((at, None)) => return Err(src.at(at, "`kind` must be a string")),
        Some((at, Some(k))) => (at, k),
    };
    let entry = |name: &Spanned<String>,
                 input: Option<&Spanned<String>>,
                 output: &Spanned<String>,
                 kind: StageKind|
     -> Result<Entry, InputError> {
        if name.get_ref().is_empty() {
            return Err(src.span(name, "stage name must not be empty"));
        }
        Ok(Entry {
            spec: StageSpec {
                name: name.get_ref().clone(),
                input: input.map(|i| service(src, i)).transpose()?,
                output: service(src, output)?,
                kind,
            },
            name_at: name.span().start,
            input_at: input.map_or(start, |i| i.span().start),
            output_at: output.span().start,
        })
    };
    match kind.as_str() {
        "ingest.sim" => {
            let r: RawSim = de(src, value)?;
            let profile = r
                .profile
                .as_ref()
                .map_or("adxrs450".to_string(), |p| p.get_ref().clone());
            if let Some(p) = &r.profile {
                if !["adxrs450", "adis16405"].contains(&p.get_ref().as_str()) {
                    return Err(src.span(
                        p,
                        format!(
                            "unknown profile {:?} (valid: adxrs450, adis16405)",
                            p.get_ref()
                        ),
                    ));
                }
            }
            let seed = match &r.seed {
                Some(s) => int_in(src, s, "seed", 0, i64::MAX)? as u64,
                None => 1,
            };
            let samples = match &r.samples {
                Some(s) => Some(int_in(src, s, "samples", 1, i64::MAX)? as u64),
                None => None,
            };
            let motion = r
                .motion
                .as_ref()
                .map_or("sines".to_string(), |m| m.get_ref().clone());
            if let Some(m) = &r.motion {
                if m.get_ref().parse::<crate::sim::Motion>().is_err() {
                    return Err(src.span(
                        m,
                        format!(
                            "unknown motion {:?} (valid: none, sines, steps, turn)",
                            m.get_ref()
                        ),
                    ));
                }
            }
            if units != Units::DegPerSec {
                return Err(src.at(
                    kind_at,
                    "ingest.sim produces deg/s: set input_units = \"deg/s\"",
                ));
            }
            let params = SimParams {
                profile,
                seed,
                motion,
                samples,
            };
            crate::stages::ingest_sim::sim_config(&params, rate_hz, axes)
                .map_err(|e| src.at(start, format!("ingest.sim: {e}")))?;
            entry(&r.name, None, &r.output, StageKind::IngestSim(params))
        }
        "ingest.csv" => {
            let r: RawCsv = de(src, value)?;
            let csv = csv_params(src, &r, rate_hz, axes)?;
            entry(&r.name, None, &r.output, StageKind::IngestCsv(csv))
        }
        "ingest.iceoryx2" => {
            let r: RawIceoryx2 = de(src, value)?;
            let poll_timeout = poll_timeout(src, r.poll_timeout_us.as_ref())?;
            entry(
                &r.name,
                Some(&r.input),
                &r.output,
                StageKind::IngestIceoryx2 { poll_timeout },
            )
        }
        "denoise.wavelet" => {
            let r: RawWavelet = de(src, value)?;
            let params = wavelet_params(src, &r)?;
            crate::stages::denoise::check_wavelet(&params)
                .map_err(|e| src.at(start, format!("denoise.wavelet: {e}")))?;
            entry(
                &r.name,
                Some(&r.input),
                &r.output,
                StageKind::DenoiseWavelet(params),
            )
        }
        "denoise.none" | "predict.none" => {
            let r: RawPassThrough = de(src, value)?;
            let k = if kind == "denoise.none" {
                StageKind::DenoiseNone
            } else {
                StageKind::PredictNone
            };
            entry(&r.name, Some(&r.input), &r.output, k)
        }
        "predict.rbf" => {
            let r: RawRbf = de(src, value)?;
            let params = rbf_params(src, &r, start, rate_hz, axes, units)?;
            entry(
                &r.name,
                Some(&r.input),
                &r.output,
                StageKind::PredictRbf(params),
            )
        }
        "external" => {
            let r: RawExternal = de(src, value)?;
            let poll_timeout = poll_timeout(src, r.poll_timeout_us.as_ref())?;
            entry(
                &r.name,
                Some(&r.input),
                &r.output,
                StageKind::External { poll_timeout },
            )
        }
        "publish" => {
            let r: RawPublish = de(src, value)?;
            entry(
                &r.name,
                Some(&r.input),
                &r.output,
                StageKind::Publish {
                    notify: r.notify.unwrap_or(true),
                },
            )
        }
        other => Err(src.at(
            kind_at,
            format!("unknown kind {other:?} (valid: {})", KINDS.join(", ")),
        )),
    }
}

/// A path in the pipeline file, relative to the file's folder.
fn resolve(src: &Src<'_>, rel: &str) -> PathBuf {
    let rel = Path::new(rel);
    if rel.is_absolute() {
        rel.to_path_buf()
    } else {
        src.path
            .parent()
            .map_or_else(|| rel.to_path_buf(), |d| d.join(rel))
    }
}

/// Load every model of a `predict.rbf` stage and check it against the pipeline: it loads, its
/// rate and units are the pipeline's, and there is one per axis (or one shared).
fn rbf_params(
    src: &Src<'_>,
    r: &RawRbf,
    start: usize,
    rate_hz: f64,
    axes: usize,
    units: Units,
) -> Result<RbfParams, InputError> {
    let files: Vec<&Spanned<String>> = match (&r.model, &r.models) {
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
            return Err(src.at(
                start,
                "predict.rbf needs `model` (one model for every axis) or `models` (one per axis)",
            ))
        }
    };
    let unit_name = match units {
        Units::DegPerSec => "deg/s",
        Units::RadPerSec => "rad/s",
    };
    let mut paths = Vec::with_capacity(axes);
    let mut models = Vec::with_capacity(axes);
    let mut stillness = Vec::with_capacity(axes);
    for f in files {
        let path = resolve(src, f.get_ref());
        let m = crate::io::model_file::read_model(&path).map_err(|e| src.span(f, e))?;
        if (m.rate_hz - rate_hz).abs() > 1e-9 * rate_hz {
            return Err(src.span(
                f,
                format!(
                    "model {} was trained at {} Hz but the pipeline runs at {rate_hz} Hz",
                    path.display(),
                    m.rate_hz
                ),
            ));
        }
        if m.units != unit_name {
            return Err(src.span(
                f,
                format!(
                    "model {} is in {} but the pipeline's input_units are {unit_name}",
                    path.display(),
                    m.units
                ),
            ));
        }
        let mut s = m.stillness;
        if let Some(w) = &r.still_window {
            s.window = int_in(src, w, "still_window", 2, 1_000_000)?;
        }
        if let Some(v) = &r.settle {
            s.settle = int_in(src, v, "settle", 0, 100_000_000)?;
        }
        for (field, value) in [
            (&mut s.var_enter, &r.var_enter),
            (&mut s.var_exit, &r.var_exit),
            (&mut s.mean_enter, &r.mean_enter),
            (&mut s.mean_exit, &r.mean_exit),
        ] {
            if let Some(v) = value {
                *field = positive(src, v, "stillness threshold", f64::MAX)?;
            }
        }
        s.check()
            .map_err(|e| src.at(start, format!("predict.rbf: {e}")))?;
        paths.push(path);
        models.push(m);
        stillness.push(s);
    }
    Ok(RbfParams {
        paths,
        models,
        stillness,
    })
}

fn csv_params(
    src: &Src<'_>,
    r: &RawCsv,
    rate_hz: f64,
    axes: usize,
) -> Result<CsvParams, InputError> {
    let rel = Path::new(r.file.get_ref());
    let file = if rel.is_absolute() {
        rel.to_path_buf()
    } else {
        src.path
            .parent()
            .map_or_else(|| rel.to_path_buf(), |d| d.join(rel))
    };
    if !file.is_file() {
        return Err(src.span(&r.file, format!("no such file: {}", file.display())));
    }
    let default_cols: Vec<String> = ["x", "y", "z"][..axes]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let columns = r
        .columns
        .as_ref()
        .map_or(default_cols, |c| c.get_ref().clone());
    if let Some(c) = &r.columns {
        if c.get_ref().len() != axes {
            return Err(src.span(
                c,
                format!(
                    "columns must name {axes} column(s) (one per axis), got {}",
                    c.get_ref().len()
                ),
            ));
        }
    }
    let mut wanted = columns.clone();
    if let Some(t) = &r.time_column {
        wanted.push(t.get_ref().clone());
    }
    let table = crate::io::read_table(&file, &wanted)?;
    let mut cols = Vec::with_capacity(axes);
    for name in &columns {
        match table.column(name) {
            Some(c) => cols.push(c),
            None => {
                let at = r
                    .columns
                    .as_ref()
                    .map_or(r.file.span().start, |c| c.span().start);
                return Err(src.at(
                    at,
                    format!(
                        "{} has no column {name:?} (columns: {})",
                        file.display(),
                        table.names.join(", ")
                    ),
                ));
            }
        }
    }
    let n = table.rows();
    if n == 0 {
        return Err(src.span(&r.file, format!("{} has no data rows", file.display())));
    }
    let mut rates = vec![[0.0; 3]; n];
    for (axis, col) in cols.iter().enumerate() {
        for (row, v) in col.iter().enumerate() {
            rates[row][axis] = *v;
        }
    }
    let t_ns: Vec<u64> = match &r.time_column {
        Some(t) => {
            let Some(col) = table.column(t.get_ref()) else {
                return Err(src.span(
                    t,
                    format!("{} has no column {:?}", file.display(), t.get_ref()),
                ));
            };
            let mut out = Vec::with_capacity(n);
            for (row, &s) in col.iter().enumerate() {
                if s < 0.0 {
                    return Err(src.span(
                        t,
                        format!(
                            "time column {:?} is negative at data row {}",
                            t.get_ref(),
                            row + 1
                        ),
                    ));
                }
                out.push((s * 1e9).round() as u64);
            }
            out
        }
        None => (0..n as u64)
            .map(|i| (i as f64 * 1e9 / rate_hz).round() as u64)
            .collect(),
    };
    let pace = match &r.pace {
        None => Pace::Realtime,
        Some(p) => match p.get_ref().as_str() {
            "realtime" => Pace::Realtime,
            "asap" => Pace::Asap,
            other => {
                return Err(src.span(
                    p,
                    format!("unknown pace {other:?} (valid: \"realtime\", \"asap\")"),
                ))
            }
        },
    };
    Ok(CsvParams {
        file,
        t_ns,
        rates,
        pace,
        looped: r.looped.unwrap_or(false),
    })
}

fn wavelet_params(src: &Src<'_>, r: &RawWavelet) -> Result<WaveletParams, InputError> {
    let wavelet = r
        .wavelet
        .as_ref()
        .map_or("db6".to_string(), |w| w.get_ref().clone());
    if let Some(w) = &r.wavelet {
        crate::wavelet::Wavelet::by_name(w.get_ref()).map_err(|e| src.span(w, e.to_string()))?;
    }
    let level = match &r.level {
        Some(l) => int_in(src, l, "level", 1, 12)?,
        None => 5,
    };
    let threshold = r
        .threshold
        .as_ref()
        .map_or("improved".to_string(), |t| t.get_ref().clone());
    if let Some(t) = &r.threshold {
        const VALID: [&str; 5] = ["hard", "soft", "garrote", "firm", "improved"];
        if !VALID.contains(&t.get_ref().as_str()) {
            return Err(src.span(
                t,
                format!(
                    "unknown threshold function {:?} (valid: {})",
                    t.get_ref(),
                    VALID.join(", ")
                ),
            ));
        }
    }
    let ratio = match &r.ratio {
        Some(v) => {
            if *v.get_ref() <= 1.0 || !v.get_ref().is_finite() {
                return Err(src.span(v, format!("ratio must be > 1, got {}", v.get_ref())));
            }
            Some(*v.get_ref())
        }
        None => None,
    };
    let pos = |v: &Option<Spanned<f64>>, what: &str| -> Result<Option<f64>, InputError> {
        v.as_ref().map(|v| positive(src, v, what, 1e9)).transpose()
    };
    let a = match &r.a {
        Some(v) if !(v.get_ref().is_finite() && *v.get_ref() >= 0.0) => {
            return Err(src.span(v, format!("a must be finite and >= 0, got {}", v.get_ref())))
        }
        Some(v) => Some(*v.get_ref()),
        None => None,
    };
    let beta = pos(&r.beta, "beta")?;
    let kappa = pos(&r.kappa, "kappa")?;
    let window = match &r.window {
        Some(w) => int_in(src, w, "window", 2, 1 << 20)?,
        None => crate::wavelet::stream::StreamConfig::DEFAULT_WINDOW,
    };
    let filter_len = crate::wavelet::Wavelet::by_name(&wavelet)
        .map(|w| w.filter_len())
        .unwrap_or(2);
    let full_lag = crate::wavelet::stream::StreamConfig::full_lag(filter_len, level);
    let lag = match &r.lag {
        Some(l) => int_in(src, l, "lag", 0, full_lag as i64)?,
        None => crate::wavelet::stream::StreamConfig::DEFAULT_LAG.min(full_lag),
    };
    let sigma = match &r.sigma {
        None => None,
        Some(s) => match s.get_ref() {
            SigmaSetting::Named(n) if n == "mad" => None,
            SigmaSetting::Named(n) => {
                return Err(src.span(
                    s,
                    format!("sigma must be \"mad\" or a number > 0, got {n:?}"),
                ))
            }
            SigmaSetting::Fixed(x) if x.is_finite() && *x > 0.0 => Some(*x),
            SigmaSetting::Fixed(x) => {
                return Err(src.span(s, format!("sigma must be \"mad\" or a number > 0, got {x}")))
            }
        },
    };
    Ok(WaveletParams {
        wavelet,
        level,
        threshold,
        ratio,
        a,
        beta,
        kappa,
        window,
        lag,
        sigma,
    })
}

/// Order the stages into one chain ingest -> ... -> publish, or say where it breaks.
fn chain(src: &Src<'_>, entries: Vec<Entry>, at: usize) -> Result<Vec<StageSpec>, InputError> {
    if entries.len() > crate::metrics::MAX_STAGES {
        return Err(src.at(
            at,
            format!(
                "{} stages: a pipeline has at most {}",
                entries.len(),
                crate::metrics::MAX_STAGES
            ),
        ));
    }
    // Unique names and outputs.
    for (i, e) in entries.iter().enumerate() {
        if let Some(prev) = entries[..i].iter().find(|p| p.spec.name == e.spec.name) {
            let pos = src.at(prev.name_at, "");
            return Err(src.at(
                e.name_at,
                format!(
                    "duplicate stage name {:?} (first used at {})",
                    e.spec.name,
                    position(&pos)
                ),
            ));
        }
        if let Some(prev) = entries[..i].iter().find(|p| p.spec.output == e.spec.output) {
            return Err(src.at(
                e.output_at,
                format!(
                    "service {:?} is already the output of stage {:?}: each service has one publisher",
                    e.spec.output, prev.spec.name
                ),
            ));
        }
    }
    let ingests: Vec<&Entry> = entries.iter().filter(|e| e.spec.kind.is_ingest()).collect();
    let Some(ingest) = ingests.first() else {
        return Err(src.at(
            at,
            "no ingest stage (kinds ingest.sim, ingest.csv, ingest.iceoryx2)",
        ));
    };
    if let Some(second) = ingests.get(1) {
        return Err(src.at(
            second.name_at,
            format!(
                "a second ingest stage {:?}: a pipeline has exactly one (the first is {:?})",
                second.spec.name, ingest.spec.name
            ),
        ));
    }
    // Every non-ingest input must be some stage's output.
    for e in entries.iter().filter(|e| !e.spec.kind.is_ingest()) {
        let input = e.spec.input.as_deref().unwrap_or("");
        if !entries.iter().any(|p| p.spec.output == input) {
            return Err(src.at(
                e.input_at,
                format!(
                    "dangling input {input:?}: no stage of this pipeline publishes it (a service of another process is read by ingest.iceoryx2 at the head of the chain, or declared by an `external` stage)"
                ),
            ));
        }
        if e.spec.output == input {
            return Err(src.at(
                e.output_at,
                format!("cycle: stage {:?} reads its own output", e.spec.name),
            ));
        }
    }
    // Walk from the ingest.
    let mut order: Vec<usize> = Vec::with_capacity(entries.len());
    let mut current = entries
        .iter()
        .position(|e| e.spec.kind.is_ingest())
        .unwrap_or(0);
    order.push(current);
    loop {
        let out = &entries[current].spec.output;
        let readers: Vec<usize> = entries
            .iter()
            .enumerate()
            .filter(|(_, e)| !e.spec.kind.is_ingest() && e.spec.input.as_deref() == Some(out))
            .map(|(i, _)| i)
            .collect();
        match readers.as_slice() {
            [] => break,
            [next] => {
                if order.contains(next) {
                    return Err(src.at(entries[*next].input_at, "cycle in the stage chain"));
                }
                order.push(*next);
                current = *next;
            }
            [_, second, ..] => {
                return Err(src.at(
                    entries[*second].input_at,
                    format!("service {out:?} is read by more than one stage: the stages must form one chain"),
                ))
            }
        }
    }
    if let Some(stray) = (0..entries.len()).find(|i| !order.contains(i)) {
        return Err(src.at(
            entries[stray].input_at,
            format!(
                "cycle: stage {:?} is not reachable from the ingest {:?}",
                entries[stray].spec.name, ingest.spec.name
            ),
        ));
    }
    let is_external = |i: usize| matches!(entries[i].spec.kind, StageKind::External { .. });
    for (pos, &i) in order.iter().enumerate() {
        if !is_external(i) {
            continue;
        }
        if pos == 1 {
            return Err(src.at(
                entries[i].input_at,
                format!(
                    "external stage {:?} cannot be the first stage after the ingest: it would read the raw service {:?}; put a daemon stage (e.g. denoise.none) before it",
                    entries[i].spec.name,
                    entries[i].spec.input.as_deref().unwrap_or("")
                ),
            ));
        }
        if pos == order.len() - 1 {
            return Err(src.at(
                entries[i].output_at,
                format!(
                    "external stage {:?} cannot be the last stage: the chain ends at a publish stage the daemon runs",
                    entries[i].spec.name
                ),
            ));
        }
        if is_external(order[pos - 1]) {
            return Err(src.at(
                entries[i].input_at,
                format!(
                    "external stage {:?} follows external stage {:?}: merge them into one external process or put a daemon stage between",
                    entries[i].spec.name,
                    entries[order[pos - 1]].spec.name
                ),
            ));
        }
    }
    let last = &entries[*order.last().unwrap_or(&0)];
    if !matches!(last.spec.kind, StageKind::Publish { .. }) {
        return Err(src.at(
            last.output_at,
            format!(
                "the chain ends at stage {:?} ({}), not at a publish stage",
                last.spec.name,
                last.spec.kind.name()
            ),
        ));
    }
    for &i in &order[1..order.len() - 1] {
        if matches!(entries[i].spec.kind, StageKind::Publish { .. }) {
            return Err(src.at(
                entries[i].name_at,
                "a publish stage must be the last of the chain",
            ));
        }
    }
    if order.len() < 2 {
        return Err(src.at(at, "a pipeline needs an ingest and a publish stage"));
    }
    let mut slots: Vec<Option<Entry>> = entries.into_iter().map(Some).collect();
    Ok(order
        .into_iter()
        .filter_map(|i| slots[i].take().map(|e| e.spec))
        .collect())
}

fn position(e: &InputError) -> Cow<'static, str> {
    match e {
        InputError::At { line, column, .. } => Cow::Owned(format!("{line}:{column}")),
        _ => Cow::Borrowed("?"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEAD: &str = "name = \"t\"\nrate_hz = 500.0\n";
    const INGEST: &str =
        "[[stage]]\nname = \"in\"\nkind = \"ingest.iceoryx2\"\ninput = \"s/raw\"\noutput = \"t/raw\"\n";
    const DENOISE: &str =
        "[[stage]]\nname = \"dn\"\nkind = \"denoise.none\"\ninput = \"t/raw\"\noutput = \"t/dn\"\n";
    const PUBLISH: &str =
        "[[stage]]\nname = \"pub\"\nkind = \"publish\"\ninput = \"t/dn\"\noutput = \"t/out\"\n";

    fn parse_str(text: &str) -> Result<Pipeline, String> {
        parse(Path::new("p.toml"), text).map_err(|e| e.to_string())
    }

    #[test]
    fn stages_are_ordered_as_a_chain_whatever_the_file_order() {
        let p = parse_str(&format!("{HEAD}{PUBLISH}{DENOISE}{INGEST}")).unwrap();
        let names: Vec<&str> = p.stages.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["in", "dn", "pub"]);
        assert_eq!(
            p.deadline,
            Duration::from_millis(2),
            "default: one sample period"
        );
        assert_eq!(p.axes, 3);
        assert_eq!(p.input_units, Units::DegPerSec);
        assert_eq!(p.iceoryx2.stats_service, "t/stats");
    }

    #[test]
    fn a_chain_must_end_at_a_publish() {
        let e = parse_str(&format!("{HEAD}{INGEST}{DENOISE}")).unwrap_err();
        assert!(
            e.starts_with("p.toml:12:10: the chain ends at stage \"dn\""),
            "{e}"
        );
    }

    #[test]
    fn a_service_read_twice_is_not_a_chain() {
        let second = PUBLISH
            .replace("\"pub\"", "\"pub2\"")
            .replace("t/out", "t/out2");
        let e = parse_str(&format!("{HEAD}{INGEST}{DENOISE}{PUBLISH}{second}")).unwrap_err();
        assert!(e.contains("read by more than one stage"), "{e}");
    }

    #[test]
    fn an_external_stage_is_a_link_of_the_chain() {
        let ext = "[[stage]]\nname = \"ext\"\nkind = \"external\"\ninput = \"t/dn\"\noutput = \"t/ext\"\n";
        let publish = PUBLISH.replace("input = \"t/dn\"", "input = \"t/ext\"");
        let p = parse_str(&format!("{HEAD}{publish}{ext}{DENOISE}{INGEST}")).unwrap();
        let names: Vec<&str> = p.stages.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["in", "dn", "ext", "pub"]);
        assert!(matches!(
            p.stages[2].kind,
            StageKind::External { poll_timeout } if poll_timeout == Duration::from_millis(1)
        ));
        // Without the external declaration the publish stage's input dangles.
        let e = parse_str(&format!("{HEAD}{publish}{DENOISE}{INGEST}")).unwrap_err();
        assert!(e.contains("dangling input \"t/ext\""), "{e}");
    }

    #[test]
    fn errors_point_at_the_offending_value() {
        let e = parse_str(&format!(
            "name = \"t\"\nrate_hz = 500.0\naxes = 4\n{INGEST}{PUBLISH}"
        ))
        .unwrap_err();
        assert!(
            e.starts_with("p.toml:3:8: axes must be in 1..=3, got 4"),
            "{e}"
        );
    }
}
