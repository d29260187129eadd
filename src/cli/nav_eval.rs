//! `driftless nav-eval`: the heading benchmark ([`crate::nav_eval`]). Known motion (a built-in
//! profile, [`crate::nav::profiles`], or a truth file, [`crate::io::truth`]) is added to a static
//! gyro log (or to the simulator's noise), every method corrects the sum, and each is judged by
//! the heading error a navigator integrating it would see, window by window, against ZARU with
//! the true stops.
//!
//! Methods: the baselines a navigator already has and the library's estimators
//! ([`crate::nav::eval::Method`]), plus pipelines run through the daemon's own stage code
//! ([`crate::nav_eval::Chain`]): the product's chain `denoise.wavelet -> predict.bias` built in
//! at the log's rate with the axis' terms; with `--model`, the paper's `denoise.wavelet ->
//! predict.rbf` and the same with the model's AR(p) in the network's place; and any
//! `--pipeline FILE`. This file parses the options, opens the inputs and prints.

use super::duration::parse_seconds;
use super::simulate::parse_number;
use super::CliError;
use crate::cli::log_input::{self, BagArgs};
use crate::drift::bias::{AccelTerms, BiasTerms, MG_PER_M_S2, VRW_PER_HOUR};
use crate::drift::PredictorKind;
use crate::io::plot::{self, Panel, PanelStyle, Series};
use crate::io::truth::{read_truth, Truth};
use crate::nav::{format_table_labelled, MethodSummary, Profile};
use crate::nav_eval::{
    Bench, Chain, HeadingTraces, Motion, NavEvalError, OdometryVariant, Outcome, Source,
};
use crate::rate_log::RateLog;
use crate::sim::SimConfig;
use crate::units::AccelUnit;
use serde_json::{json, Value};
use std::path::PathBuf;

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
    /// Columns to use, one axis each (repeatable; default: every numeric column but time and
    /// the accelerometer's).
    #[arg(long = "column", value_name = "NAME")]
    pub columns: Vec<String>,
    /// The accelerometer's columns, x, y, z (give it three times; a CSV log): the unit's static
    /// specific force, time-aligned with the rates. Each motion adds its own force
    /// (longitudinal at starts and stops, centripetal in turns, from the profile's stated
    /// speed), and the product's chain runs a second time on samples that carry it
    /// (gyro+accel), beside the gyro-only one. `--sim adis16405` has its accelerometer built in.
    #[arg(long = "accel-column", value_name = "NAME")]
    pub accel_columns: Vec<String>,
    /// Units of the accelerometer's columns: m/s^2 or g (9.80665 m/s²).
    #[arg(long, default_value = "m/s^2")]
    pub accel_units: String,
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
    /// Judge the heading from this time into each window (e.g. 3s): every method runs from the
    /// window's first sample, and the integration starts here. Without it the start-up is
    /// judged too.
    #[arg(long)]
    pub judge_from: Option<String>,
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
    /// Add the bias filter with the true stops and a wheel odometry derived from each vehicle
    /// profile's motion (stop-and-go, vehicle, continuous), beside the same without it, and
    /// its robustness variants (docs/navigation.md).
    #[arg(long)]
    pub odometry: bool,
    /// One JSON document on stdout instead of tables.
    #[arg(long)]
    pub json: bool,
    /// SVG of the heading error over time of the first window, per method.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
}

impl From<NavEvalError> for CliError {
    fn from(e: NavEvalError) -> Self {
        match e {
            NavEvalError::Input(m) => CliError::input(m),
            NavEvalError::Internal(m) => CliError::internal(m),
        }
    }
}

/// Where the static noise comes from: a log read, or a simulated sensor.
enum Input<'a> {
    Log(Box<RateLog>),
    Sim(&'a str),
}

/// Run `driftless nav-eval`.
pub fn run(args: Args) -> Result<(), CliError> {
    // Profiles before the log, so a typo fails at once.
    let profiles = parse_profiles(args.motion.as_deref().unwrap_or("all"))?;
    let given = match &args.rate {
        Some(r) => Some(parse_number("--rate", r)?),
        None => None,
    };
    if !(args.accel_columns.is_empty() || args.accel_columns.len() == 3) {
        return Err(CliError::input(format!(
            "--accel-column: give the accelerometer's 3 columns (x, y, z), not {}",
            args.accel_columns.len()
        )));
    }
    let input = match (&args.input, &args.sim) {
        (Some(p), None) => {
            // The accelerometer's columns are read with the rates, then split off.
            let mut wanted = args.columns.clone();
            if !wanted.is_empty() {
                wanted.extend(args.accel_columns.iter().cloned());
            }
            Input::Log(Box::new(log_input::open(p, &wanted, &args.bag, false)?))
        }
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
            log_input::check_text_input(path, crate::io::truth::TRUTH_TAKES)?;
            Some(read_truth(path, rate)?)
        }
        None => None,
    };
    let window = window_samples(&args, truth.as_ref(), rate)?;
    let judge_from = match &args.judge_from {
        None => 0,
        Some(from) => {
            let n = (parse_seconds(from)
                .map_err(|e| CliError::input(format!("--judge-from {e}")))?
                * rate)
                .round() as usize;
            if n >= window {
                return Err(CliError::input(format!(
                    "--judge-from {from} leaves nothing of a {window}-sample window to judge"
                )));
            }
            n
        }
    };
    let (source, terms) = match input {
        Input::Log(log) => log_source(*log, &args, rate, window)?,
        Input::Sim(s) => {
            if !(1..=1000).contains(&args.windows) {
                return Err(CliError::input("--windows must be 1..=1000"));
            }
            sim_source(s, &args, rate, window)?
        }
    };
    let motions: Vec<Motion> = match &truth {
        Some(t) => vec![Motion::truth(t, source.axes.len(), rate)?],
        None => profiles.into_iter().map(Motion::Profile).collect(),
    };
    // A log's own accelerometer terms with `--terms fit`, as for the gyro; else the stage's
    // defaults (the ADIS16405 data sheet's, what the simulator's has).
    let accel_terms = if source.floor.is_none() && args.terms == "fit" {
        source.fit_accel_terms()?
    } else {
        None
    };
    let chains = chains(&args, &source, &terms, accel_terms.as_ref(), rate)?;
    let odometry = if args.odometry {
        OdometryVariant::all(window as f64 / rate)
    } else {
        Vec::new()
    };
    let bench = Bench {
        source,
        terms,
        accel_terms,
        window,
        motions,
        chains,
        judge_from,
        odometry,
    };
    let outcome = bench.run(args.plot.is_some())?;
    if let (Some(path), Some(traces)) = (&args.plot, &outcome.traces) {
        write_plot(path, &bench, traces)?;
    }
    if args.json {
        print_json(&bench, &outcome);
    } else {
        print_text(&args, &bench, &outcome);
    }
    Ok(())
}

/// The methods that run a pipeline's stages: the product's chain (and, when the source has an
/// accelerometer, the same on samples that carry it), the same with the true stops as the
/// vehicle's stop signal, with `--model` the paper's chain and its AR(p), and each
/// `--pipeline` file.
fn chains(
    args: &Args,
    source: &Source,
    terms: &[BiasTerms],
    accel_terms: Option<&AccelTerms>,
    rate: f64,
) -> Result<Vec<Chain>, CliError> {
    let mut chains = vec![Chain::bias(rate, terms)?];
    if source.accel.is_some() {
        chains.push(Chain::bias_imu(rate, terms, accel_terms)?);
    }
    chains.push(Chain::stop_signal(rate, terms)?);
    if !args.models.is_empty() {
        let axes = source.axes.len();
        chains.push(Chain::rbf(rate, axes, &args.models, PredictorKind::Rbf)?);
        chains.push(Chain::rbf(rate, axes, &args.models, PredictorKind::Ar)?);
    }
    for p in &args.pipelines {
        chains.push(Chain::file(p, rate)?);
    }
    Ok(chains)
}

/// Samples per window: `--window`, else the truth file's rows, else 10 minutes. A truth file
/// holds exactly one window: whole samples, one row per sample.
fn window_samples(args: &Args, truth: Option<&Truth>, rate: f64) -> Result<usize, CliError> {
    let window = match (&args.window, truth) {
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
    if let Some(t) = truth {
        if t.rows() != window {
            return Err(CliError::input(format!(
                "{}: {} rows, but a window of {} s at {rate} Hz is {window} samples: a truth file holds exactly one window (leave out --window to take its length)",
                t.path.display(),
                t.rows(),
                window as f64 / rate
            )));
        }
    }
    Ok(window)
}

/// A log's noise after `--characterise`, and the estimators' terms: the Allan fit of that part
/// (`--terms fit`) or a sensor profile's, one set for every axis. The accelerometer's columns,
/// when given, are split off the rates.
fn log_source(
    mut log: RateLog,
    args: &Args,
    rate: f64,
    window: usize,
) -> Result<(Source, Vec<BiasTerms>), CliError> {
    let accel = split_accel(&mut log, args)?;
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
    let mut source = Source::from_log(log, rate, characterise, window)?;
    if let Some(a) = accel {
        source = source.with_accel(a)?;
    }
    let terms = if args.terms == "fit" {
        // What `driftless allan --stage` writes for this record: the user's path itself.
        source.fit_terms(lsb)?
    } else {
        profile_terms(&args.terms)?
    };
    let axes = source.axes.len();
    Ok((source, vec![terms; axes]))
}

/// The accelerometer's columns (`--accel-column`), taken out of the log's table, in m/s².
fn split_accel(log: &mut RateLog, args: &Args) -> Result<Option<Vec<[f64; 3]>>, CliError> {
    if args.accel_columns.is_empty() {
        return Ok(None);
    }
    if log.origin.bag.is_some() {
        return Err(CliError::input(
            "--accel-column: nav-eval reads the accelerometer from a CSV log, not from a bag",
        ));
    }
    let scale = args
        .accel_units
        .parse::<AccelUnit>()
        .map_err(|_| CliError::input(format!("--accel-units {}: m/s^2 or g", args.accel_units)))?
        .to_m_per_s2();
    let table = &mut log.table;
    let mut cols = Vec::with_capacity(3);
    for name in &args.accel_columns {
        let Some(i) = table.names.iter().position(|n| n == name) else {
            return Err(CliError::input(format!(
                "{}: no column {name:?} (--accel-column); it has {}",
                table.path.display(),
                table.names.join(", ")
            )));
        };
        table.names.remove(i);
        cols.push(table.columns.remove(i));
    }
    if table.columns.is_empty() {
        return Err(CliError::input(format!(
            "{}: no rate column left beside the accelerometer's",
            table.path.display()
        )));
    }
    Ok(Some(
        (0..cols[0].len())
            .map(|k| std::array::from_fn(|a| cols[a][k] * scale))
            .collect(),
    ))
}

/// The simulator's noise of `sensor`, 3 axes of `--windows` windows, and its terms (`--terms
/// fit`: the sensor's own).
fn sim_source(
    sensor: &str,
    args: &Args,
    rate: f64,
    window: usize,
) -> Result<(Source, Vec<BiasTerms>), CliError> {
    let mut cfg = SimConfig::profile(sensor).map_err(|e| CliError::input(format!("--sim: {e}")))?;
    cfg.rate_hz = rate;
    cfg.axes = 3;
    let source = Source::simulated(sensor, &cfg, window * args.windows)
        .map_err(|e| CliError::input(format!("--sim: {e}")))?;
    let terms = if args.terms == "fit" {
        profile_terms(sensor)?
    } else {
        profile_terms(&args.terms)?
    };
    Ok((source, vec![terms; 3]))
}

fn profile_terms(name: &str) -> Result<BiasTerms, CliError> {
    BiasTerms::profile(name).map_err(|e| CliError::input(format!("--terms: {e}")))
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

/// The SVG of `--plot`: the first case's heading error over time, per method.
fn write_plot(
    path: &std::path::Path,
    bench: &Bench,
    traces: &HeadingTraces,
) -> Result<(), CliError> {
    let src = &bench.source;
    let panel = Panel {
        title: format!(
            "heading error, {} motion, first window of {} ({})",
            bench.motions[0].label(),
            src.axes[0].0,
            src.name
        ),
        x_label: "time (s)".into(),
        y_label: "heading error (deg)".into(),
        series: traces
            .series
            .iter()
            .map(|(name, h)| Series {
                name: name.clone(),
                points: traces.t.iter().copied().zip(h.iter().copied()).collect(),
            })
            .collect(),
        style: PanelStyle::default(),
    };
    plot::write_panels(path, &[panel])
        .map_err(|e| CliError::input(format!("{}: {e}", path.display())))?;
    eprintln!("wrote {}", path.display());
    Ok(())
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

/// `--json`: one document, every case too, so the worst window can be found and replayed.
fn print_json(bench: &Bench, out: &Outcome) {
    let src = &bench.source;
    let rate = src.rate;
    let labels = &out.labels;
    let terms: Vec<Value> = src
        .axes
        .iter()
        .zip(&bench.terms)
        .map(|((name, _), t)| {
            json!({"axis": name, "arw_deg_per_sqrt_h": t.n * 60.0, "bias_instability_deg_per_h": t.b * 3600.0,
                   "rrw_deg_per_h_per_sqrt_h": t.k * 216_000.0, "lsb_degps": t.lsb})
        })
        .collect();
    let sections: Vec<Value> = out
        .sections
        .iter()
        .map(|s| {
            json!({"profile": s.title, "methods": s.rows.iter().zip(labels)
                .map(|(r, l)| summary_json(r, l)).collect::<Vec<_>>()})
        })
        .collect();
    let cases: Vec<Value> = out
        .cases
        .iter()
        .map(|c| {
            let methods: Vec<Value> = c
                .metrics
                .iter()
                .zip(labels)
                .map(|(m, l)| {
                    json!({"method": l, "rms_heading_deg": m.rms_deg,
                           "final_heading_deg": m.final_deg, "max_heading_deg": m.max_deg,
                           "rms_rate_degps": m.rms_rate})
                })
                .collect();
            json!({"profile": bench.motions[c.motion].label(), "window": c.window,
                   "start_s": bench.window_start(c.window) as f64 / rate,
                   "axis": src.axes[c.axis].0, "methods": methods})
        })
        .collect();
    let odometry: Vec<Value> = out
        .odometry_against_stops(bench)
        .iter()
        .map(|c| {
            json!({"method": c.label, "profile": c.motion, "stops_rms_median": c.stops_rms,
                   "odometry_rms_median": c.odometry_rms,
                   "ratio_to_stops": {"median": c.ratio.median, "p90": c.ratio.p90, "worst": c.ratio.worst},
                   "ratio_to_floored_stops": {"median": c.ratio_floored.median, "p90": c.ratio_floored.p90, "worst": c.ratio_floored.worst},
                   "cases_worse_by_2pct": c.worse, "cases": c.cases})
        })
        .collect();
    println!(
        "{}",
        json!({"source": src.name, "rate_hz": rate, "window_s": bench.window_s(), "judge_from_s": bench.judge_from as f64 / rate,
               "windows_per_axis": out.windows, "axes": src.axes.len(), "terms": terms,
               "accel_terms": bench.accel_terms.map(|a| json!({"vrw_m_s_per_sqrt_h": a.vrw * VRW_PER_HOUR, "bias_instability_mg": a.b * MG_PER_M_S2})),
               "reference": "ZARU oracle", "sections": sections, "cases": cases, "odometry": odometry})
    );
}

/// The tables: the source and its terms, then one table per section.
fn print_text(args: &Args, bench: &Bench, out: &Outcome) {
    let src = &bench.source;
    let rate = src.rate;
    let windows = out.windows;
    println!(
        "{}: {} axes x {windows} windows of {} s per profile ({} cases each), {rate} Hz; windows start after the first {} s{}",
        src.name,
        src.axes.len(),
        bench.window_s(),
        windows * src.axes.len(),
        src.first_window as f64 / rate,
        if args.terms == "fit" && src.floor.is_none() {
            " (the Allan fit's part: held out)"
        } else {
            ""
        }
    );
    if bench.judge_from > 0 {
        println!(
            "  heading judged from {} s into each window (every method runs from its first sample)",
            bench.judge_from as f64 / rate
        );
    }
    for ((name, _), t) in src.axes.iter().zip(&bench.terms) {
        println!(
            "  {name}: N {:.3} deg/sqrt(h), B {:.2} deg/h, K {:.2} deg/h/sqrt(h), lsb {} deg/s",
            t.n * 60.0,
            t.b * 3600.0,
            t.k * 216_000.0,
            t.lsb
        );
    }
    if src.accel.is_some() {
        match &bench.accel_terms {
            Some(a) => println!(
                "  accelerometer: VRW {:.4} m/s/sqrt(h), B {:.3} mg (the same part's fit, one set)",
                a.vrw * VRW_PER_HOUR,
                a.b * MG_PER_M_S2
            ),
            None => println!(
                "  accelerometer: predict.bias's default terms (the ADIS16405 data sheet's)"
            ),
        }
        println!("  accelerometer's force: the source's own at rest, plus each case's vehicle acceleration (longitudinal at starts and stops, centripetal in turns; 10 m/s, 5 s ramps; walking 1.4 m/s, 1 s ramps)");
    }
    println!();
    let names: Vec<&str> = out.labels.iter().map(String::as_str).collect();
    for s in &out.sections {
        print!("{}", format_table_labelled(&s.title, &s.rows, &names));
        println!();
    }
    println!("RMS heading: the RMS over time of the integrated error (deg); final: |error| at the window's end; ref: ZARU with the true stops, per window.");
    let odo = out.odometry_against_stops(bench);
    if !odo.is_empty() {
        println!();
        println!("| odometry against the true stops alone (KF oracle) | profile | stops alone, RMS med | with odometry, RMS med | ratio of medians | per case med | per case, floored p90 | floored worst | cases > 1.02x, floored |");
        println!("|---|---|---:|---:|---:|---:|---:|---:|---:|");
        for c in &odo {
            println!(
                "| {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {} of {} |",
                c.label,
                c.motion,
                c.stops_rms,
                c.odometry_rms,
                c.odometry_rms / c.stops_rms,
                c.ratio.median,
                c.ratio_floored.p90,
                c.ratio_floored.worst,
                c.worse,
                c.cases
            );
        }
    }
}
