//! `driftless train`: separate the drift of a static log causally, train the RBF network on the
//! first part, score it and the baselines on the held-out part ([`crate::drift::fit`]), and write
//! the model file.

use super::duration::parse_seconds;
use super::CliError;
use crate::cli::log_input::{self, BagArgs};
use crate::cli::num::sig;
use crate::drift::baselines::Score;
use crate::drift::fit::{fit_model, FitError, FitSpec};
use crate::drift::model::{DenoiseSettings, LowbandSettings, Provenance, Separation};
use crate::drift::rbf::{InputForm, Target};
use crate::drift::training::{AdamConfig, CentreMethod, TrainConfig};
use crate::io::model_file::{sha256_file, write_model};
use crate::rate_log::{LogOrigin, RateLog};
use crate::units::RateUnit;
use std::path::{Path, PathBuf};

/// The gyro log `train` fits a model to and `eval` scores one on, as both take it.
#[derive(Debug, clap::Args)]
pub struct GyroLogArgs {
    /// Gyro log: CSV (optionally .gz), or a ROS 2 bag (an MCAP file or a rosbag2 directory, see
    /// --topic); `train` wants a static one.
    pub input: PathBuf,
    /// The bag's topic.
    #[command(flatten)]
    pub bag: BagArgs,
    /// Sample rate of the log, Hz: a CSV log's (`train` needs it, `eval` takes the model's
    /// without it); a bag's comes from its stamps. With `eval` it must be the model's.
    #[arg(long)]
    pub rate: Option<f64>,
    /// Column (default: with `train` the first numeric column that is not time: t, t_s, time,
    /// ...; with `eval` the model's axis).
    #[arg(long)]
    pub column: Option<String>,
    /// Units of the rates: deg/s or rad/s (default: with `train` deg/s, with `eval` the
    /// model's; a bag's are rad/s). With `eval` they must be the model's.
    #[arg(long)]
    pub units: Option<String>,
}

/// Arguments of `driftless train`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The static gyro log.
    #[command(flatten)]
    log: GyroLogArgs,
    /// Lagged drift values fed to the network (p).
    #[arg(long, default_value_t = 4)]
    lags: usize,
    /// RBF centres (q).
    #[arg(long, default_value_t = 40)]
    centres: usize,
    /// First sample of the training range.
    #[arg(long, default_value_t = 0)]
    start: usize,
    /// Training samples.
    #[arg(long, default_value_t = 99_000)]
    train: usize,
    /// Held-out samples right after the training ones, for the scores.
    #[arg(long, default_value_t = 1_000)]
    test: usize,
    /// Centre placement: kmeans (k-means++) or ols (forward selection, as MATLAB newrb).
    #[arg(long, default_value = "kmeans")]
    method: String,
    /// Network output: increment (next minus last) or next (the value, as the paper).
    #[arg(long, default_value = "increment")]
    target: String,
    /// Features: levels (the lags, as the paper) or relative (lags minus the newest).
    #[arg(long, default_value = "levels")]
    inputs: String,
    /// Leave out the linear terms (the paper's pure Gaussian network).
    #[arg(long)]
    no_linear: bool,
    /// Width = this x distance to the nearest other centre.
    #[arg(long, default_value_t = 1.0)]
    width_scale: f64,
    /// Ridge of the output least squares, relative to the normal matrix's mean diagonal.
    #[arg(long, default_value_t = 1e-8)]
    ridge: f64,
    /// Adam refinement epochs (0: none).
    #[arg(long, default_value_t = 0)]
    adam_epochs: usize,
    /// Adam step size.
    #[arg(long, default_value_t = 0.002)]
    learning_rate: f64,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Denoiser wavelet (the daemon's denoise stage should match).
    #[arg(long, default_value = "db6")]
    wavelet: String,
    /// Denoiser levels.
    #[arg(long, default_value_t = 5)]
    level: usize,
    /// Denoiser threshold function.
    #[arg(long, default_value = "improved")]
    threshold: String,
    /// Denoiser noise window, samples.
    #[arg(long, default_value_t = 1024)]
    window: usize,
    /// Denoiser lag, samples.
    #[arg(long, default_value_t = 33)]
    lag: usize,
    /// Level of the low band that defines the drift (same wavelet).
    #[arg(long, default_value_t = 5)]
    drift_level: usize,
    /// Free-running horizon for the multi-step error: "1s", "500ms", or seconds.
    #[arg(
        long,
        default_value = "1",
        value_parser = parse_seconds,
        allow_hyphen_values = true
    )]
    horizon: f64,
    /// Stillness window: "0.5s", "500ms", or seconds.
    #[arg(
        long,
        default_value = "0.5",
        value_parser = parse_seconds,
        allow_hyphen_values = true
    )]
    still_window: f64,
    /// Stillness thresholds = this x the largest statistics on the training log (exit), 2x (enter).
    #[arg(long, default_value_t = 1.5)]
    still_margin: f64,
    /// Output model file (JSON).
    #[arg(short = 'o', long = "output")]
    output: PathBuf,
}

/// One rate column of a log, checked for NaN.
pub struct Column {
    /// Its name.
    pub name: String,
    /// Its values.
    pub values: Vec<f64>,
    /// Where it came from (a bag's rate and units).
    pub origin: LogOrigin,
}

/// Read one column (without `column`: the first numeric one that is not a time column, as
/// `driftless simulate` writes; a bag's x) and refuse non-finite values.
pub fn read_column(path: &Path, column: Option<&str>, bag: &BagArgs) -> Result<Column, CliError> {
    let wanted: Vec<String> = column.map(|c| vec![c.to_string()]).unwrap_or_default();
    let RateLog { mut table, origin } = log_input::open(path, &wanted, bag, false)?;
    if table.columns.is_empty() {
        return Err(CliError::input(format!(
            "{}: no numeric column",
            path.display()
        )));
    }
    // Without --column, the reader has already left out time columns.
    let name = table.names[0].clone();
    let values = std::mem::take(&mut table.columns[0]);
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(CliError::input(format!(
            "{}: column {name}, sample {i} (data row {}) is {}: the drift model needs finite rates",
            path.display(),
            i + 1,
            values[i]
        )));
    }
    Ok(Column {
        name,
        values,
        origin,
    })
}

fn parse<T: std::str::FromStr<Err = String>>(what: &str, s: &str) -> Result<T, CliError> {
    s.parse::<T>()
        .map_err(|e| CliError::input(format!("--{what}: {e}")))
}

/// Check a sample rate.
pub fn check_rate(rate: f64) -> Result<(), CliError> {
    if rate.is_finite() && rate > 0.0 {
        Ok(())
    } else {
        Err(CliError::input(format!(
            "--rate must be a positive number of Hz, not {rate}"
        )))
    }
}

/// Run `driftless train`.
pub fn run(args: Args) -> Result<(), CliError> {
    if let Some(r) = args.log.rate {
        check_rate(r)?;
    }
    let units = args
        .log
        .units
        .as_deref()
        .map(|u| {
            u.parse::<RateUnit>().map_err(|_| {
                CliError::input(format!(
                    "--units '{u}' (valid: {})",
                    RateUnit::NAMES.join(", ")
                ))
            })
        })
        .transpose()?;
    let col = read_column(&args.log.input, args.log.column.as_deref(), &args.log.bag)?;
    let rate = col.origin.rate(args.log.rate).map_err(CliError::input)?;
    let units = col.origin.units(units).map_err(CliError::input)?;
    let spec = fit_spec(&args, rate)?;
    let n = col.values.len();
    let end = args.start + args.train + args.test;
    if end > n {
        return Err(CliError::input(format!(
            "{} has {n} samples; --start {} --train {} --test {} needs {end}",
            args.log.input.display(),
            args.start,
            args.train,
            args.test
        )));
    }
    if args.test == 0 {
        return Err(CliError::input("--test must be at least 1"));
    }
    let bar = crate::io::progress::bar(1000, 0, "training");
    let fitted = fit_model(&col.values[args.start..end], &spec, &mut |f| {
        bar.set_position((f * 1000.0) as u64)
    });
    bar.finish_and_clear();
    let fitted = fitted.map_err(|e| match e {
        FitError::TooLittleData {
            train,
            lags,
            centres,
            warm_up,
            lag,
            needed,
        } => CliError::input(format!(
            "--train {train} is too little data for {lags} lags and {centres} centres after the \
             {warm_up}-sample warm-up and the {lag}-sample denoiser lag (need at least {needed})"
        )),
        e => CliError::input(e.to_string()),
    })?;
    let (warm, t_end) = (fitted.warm_up, fitted.train_end);
    let provenance = Provenance {
        file: args.log.input.display().to_string(),
        sha256: sha256_file(&args.log.input).map_err(CliError::input)?,
        column: col.name.clone(),
        train_start: args.start,
        train_len: args.train,
        test_len: args.test,
        seed: args.seed,
        driftless: env!("CARGO_PKG_VERSION").into(),
    };
    let model = fitted.into_model(&spec, rate, col.name.clone(), units, provenance);
    model.check().map_err(CliError::internal)?;
    write_model(&args.output, &model).map_err(CliError::input)?;
    let (t0, t1) = (args.train, args.train + args.test);
    println!(
        "{}: column {}, {} Hz; trained on samples {}..{} (drift {}..{} after warm-up and lag), \
         held out {}..{}",
        args.log.input.display(),
        col.name,
        rate,
        args.start,
        args.start + args.train,
        args.start + warm,
        args.start + t_end,
        args.start + t0,
        args.start + t1
    );
    let scores = &model.scores;
    print_scores(scores, units, args.horizon);
    let rbf = &scores[3];
    let ar_s = &scores[2];
    println!(
        "model skill vs persistence: {:+.4}; vs AR({}): {}",
        rbf.skill,
        spec.training.lags,
        if rbf.rmse < ar_s.rmse {
            "better"
        } else {
            "NOT better (AR is at least as good on this data)"
        }
    );
    eprintln!("wrote {}", args.output.display());
    Ok(())
}

/// The fit's settings from the options, checked (horizon and stillness window in samples at
/// `rate`).
fn fit_spec(args: &Args, rate: f64) -> Result<FitSpec, CliError> {
    for (name, v) in [
        ("horizon", args.horizon),
        ("still-window", args.still_window),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(CliError::input(format!(
                "--{name} must be a positive number of seconds, not {v}"
            )));
        }
    }
    let horizon = (args.horizon * rate).round().max(1.0) as usize;
    let still_window = (args.still_window * rate).round().max(2.0) as usize;
    if still_window > args.train {
        return Err(CliError::input(format!(
            "--still-window {} s is {still_window} samples, more than the {} training samples",
            args.still_window, args.train
        )));
    }
    if !(args.still_margin.is_finite() && args.still_margin >= 1.0) {
        return Err(CliError::input("--still-margin must be >= 1"));
    }
    let training = TrainConfig {
        lags: args.lags,
        centres: args.centres,
        method: parse::<CentreMethod>("method", &args.method)?,
        inputs: parse::<InputForm>("inputs", &args.inputs)?,
        target: parse::<Target>("target", &args.target)?,
        linear: !args.no_linear,
        width_scale: args.width_scale,
        ridge: args.ridge,
        adam: (args.adam_epochs > 0).then_some(AdamConfig {
            epochs: args.adam_epochs,
            learning_rate: args.learning_rate,
            ..AdamConfig::default()
        }),
        seed: args.seed,
        ..TrainConfig::default()
    };
    let separation = Separation {
        denoise: DenoiseSettings {
            wavelet: args.wavelet.clone(),
            level: args.level,
            threshold: args.threshold.clone(),
            window: args.window,
            lag: args.lag,
        },
        lowband: LowbandSettings {
            wavelet: args.wavelet.clone(),
            level: args.drift_level,
        },
    };
    Ok(FitSpec {
        separation,
        training,
        train: args.train,
        test: args.test,
        horizon,
        still_window,
        still_margin: args.still_margin,
    })
}

/// The baselines table.
pub fn print_scores(scores: &[Score], units: RateUnit, horizon_s: f64) {
    let rmse = format!("rmse ({units})");
    let free = format!("free-run rmse ({horizon_s} s, {units})");
    let mut t = super::table::new(&["predictor", &rmse, "skill", &free], 1);
    for s in scores {
        t.add_row(vec![
            s.name.clone(),
            sig(s.rmse, 5),
            format!("{:.4}", s.skill),
            sig(s.free_rmse, 5),
        ]);
    }
    println!("{t}");
}
