//! `driftless denoise`: wavelet-threshold denoise CSV columns (or a synthetic benchmark record).

use super::CliError;
use crate::io::plot::{Panel, Series};
use crate::io::{read_table, read_table_keeping_time, write_table_with_time, Table};
use crate::synthetic::{self, Regime};
use crate::wavelet::denoise::{compare, denoise, Comparison, DenoiseConfig, NoiseSigma, Rule};
use crate::wavelet::threshold::ThresholdFn;
use crate::wavelet::{Mode, Wavelet};
use std::path::{Path, PathBuf};

/// Points per plotted line at most (longer records are thinned evenly).
const PLOT_POINTS: usize = 4000;

/// Arguments of `driftless denoise`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input CSV (with or without a header). Not needed with --synthetic.
    #[arg(required_unless_present = "synthetic")]
    input: Option<PathBuf>,
    /// Column to denoise, by name (repeatable; default: every numeric column but a time column such
    /// as t_s; c0, c1, ... without a header).
    #[arg(long = "column")]
    columns: Vec<String>,
    /// Wavelet: haar, db1..db20, sym2..sym20, coif1..coif17.
    #[arg(long, default_value = "db6")]
    wavelet: String,
    /// Decomposition levels.
    #[arg(long, default_value_t = 5)]
    level: usize,
    /// Signal extension: zero, constant, symmetric, reflect, periodic, smooth, periodization.
    #[arg(long, default_value = "symmetric")]
    mode: String,
    /// Threshold function: hard, soft, garrote, firm, improved.
    #[arg(long, default_value = "improved")]
    threshold: String,
    /// Threshold rule: universal, level-universal, sure, bayes, or a fixed lambda.
    #[arg(long, default_value = "universal")]
    rule: String,
    /// Noise sigma: mad (finest details), mad-per-level, or a fixed value in the data's units.
    #[arg(long, default_value = "mad")]
    sigma: String,
    /// Improved threshold: shrinkage kept below lambda (a >= 0).
    #[arg(long, default_value_t = ThresholdFn::IMPROVED_A)]
    a: f64,
    /// Improved threshold: approach to hard above lambda (beta > 0).
    #[arg(long, default_value_t = ThresholdFn::IMPROVED_BETA)]
    beta: f64,
    /// Improved threshold: fade below lambda (kappa > 0).
    #[arg(long, default_value_t = ThresholdFn::IMPROVED_KAPPA)]
    kappa: f64,
    /// Firm threshold: upper threshold as a multiple of lambda (> 1).
    #[arg(long, default_value_t = ThresholdFn::FIRM_RATIO)]
    firm_ratio: f64,
    /// Write the denoised columns here (same names, full precision; the input's time column
    /// unchanged in its place; gzip if the name ends in .gz).
    #[arg(short = 'o', long = "output")]
    output: Option<PathBuf>,
    /// CSV holding the true signal, to score SNR and MSE against.
    #[arg(long)]
    truth: Option<PathBuf>,
    /// Column of --truth for each denoised column, in order (default: the same names).
    #[arg(long = "truth-column", requires = "truth")]
    truth_columns: Vec<String>,
    /// Run hard, soft, garrote, firm and improved and print one table (the paper's Table 2).
    #[arg(long)]
    compare: bool,
    /// Draw raw against denoised (each function's with --compare) into this SVG.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Use the seeded synthetic benchmark record instead of a file: static or dynamic.
    #[arg(long, conflicts_with_all = ["input", "truth"])]
    synthetic: Option<String>,
    /// Seed of the synthetic record.
    #[arg(long, default_value_t = 1, requires = "synthetic")]
    seed: u64,
    /// Samples of the synthetic record (50 Hz).
    #[arg(long, default_value_t = synthetic::SAMPLES, requires = "synthetic")]
    samples: usize,
}

/// The data to denoise: named columns and, where known, their truths.
struct Data {
    source: String,
    table: Table,
    truths: Vec<Option<Vec<f64>>>,
    truth_source: Option<String>,
}

fn threshold_fn(args: &Args) -> Result<ThresholdFn, CliError> {
    let f = match args.threshold.parse::<ThresholdFn>()? {
        ThresholdFn::Improved { .. } => ThresholdFn::Improved {
            a: args.a,
            beta: args.beta,
            kappa: args.kappa,
        },
        ThresholdFn::Firm { .. } => ThresholdFn::Firm {
            ratio: args.firm_ratio,
        },
        f => f,
    };
    f.validate()?;
    Ok(f)
}

fn noise_sigma(text: &str) -> Result<NoiseSigma, CliError> {
    match text {
        "mad" => Ok(NoiseSigma::Mad),
        "mad-per-level" => Ok(NoiseSigma::MadPerLevel),
        _ => match text.parse::<f64>() {
            Ok(v) if v.is_finite() && v >= 0.0 => Ok(NoiseSigma::Fixed(v)),
            _ => Err(CliError::input(format!(
                "--sigma '{text}' is not valid (valid: mad, mad-per-level, or a finite number >= 0)"
            ))),
        },
    }
}

fn config(args: &Args) -> Result<DenoiseConfig, CliError> {
    if args.level == 0 {
        return Err(CliError::input("--level must be at least 1"));
    }
    Ok(DenoiseConfig {
        wavelet: Wavelet::by_name(&args.wavelet)?,
        mode: args.mode.parse::<Mode>()?,
        level: args.level,
        threshold: threshold_fn(args)?,
        rule: args.rule.parse::<Rule>()?,
        sigma: noise_sigma(&args.sigma)?,
    })
}

fn load(args: &Args) -> Result<Data, CliError> {
    if let Some(regime) = &args.synthetic {
        let regime: Regime = regime.parse().map_err(CliError::input)?;
        if args.samples == 0 {
            return Err(CliError::input("--samples must be at least 1"));
        }
        let record = synthetic::record(regime, args.samples, args.seed);
        return Ok(Data {
            source: format!("synthetic {} record (seed {})", regime.name(), args.seed),
            table: Table {
                path: PathBuf::from(format!("synthetic-{}", regime.name())),
                names: vec!["rate".into()],
                columns: vec![record.measured],
                has_header: true,
                time: None,
            },
            truths: vec![Some(record.truth)],
            truth_source: Some("the synthetic truth".into()),
        });
    }
    let input = args
        .input
        .as_ref()
        .expect("clap requires input without --synthetic");
    // `-o` carries the input's time column through.
    let table = if args.output.is_some() {
        read_table_keeping_time(input, &args.columns)?
    } else {
        read_table(input, &args.columns)?
    };
    let mut truths = vec![None; table.names.len()];
    let mut truth_source = None;
    if let Some(truth_path) = &args.truth {
        if !args.truth_columns.is_empty() && args.truth_columns.len() != table.names.len() {
            return Err(CliError::input(format!(
                "give one --truth-column per denoised column ({} denoised: {})",
                table.names.len(),
                table.names.join(", ")
            )));
        }
        let wanted = if args.truth_columns.is_empty() {
            table.names.clone()
        } else {
            args.truth_columns.clone()
        };
        let truth = read_table(truth_path, &wanted)?;
        if truth.rows() != table.rows() {
            return Err(CliError::input(format!(
                "{}: {} rows, but {} has {}",
                truth_path.display(),
                truth.rows(),
                input.display(),
                table.rows()
            )));
        }
        truths = truth.columns.into_iter().map(Some).collect();
        truth_source = Some(truth_path.display().to_string());
    }
    Ok(Data {
        source: input.display().to_string(),
        table,
        truths,
        truth_source,
    })
}

fn describe(cfg: &DenoiseConfig) -> String {
    let f = match cfg.threshold {
        ThresholdFn::Improved { a, beta, kappa } => {
            format!("improved (a={a}, beta={beta}, kappa={kappa})")
        }
        ThresholdFn::Firm { ratio } => format!("firm (ratio {ratio})"),
        f => f.name().to_string(),
    };
    format!(
        "{} level {} {}, {} threshold, {} rule",
        cfg.wavelet.name(),
        cfg.level,
        cfg.mode,
        f,
        cfg.rule.name()
    )
}

fn print_summary(
    name: &str,
    rows: usize,
    cfg: &DenoiseConfig,
    c: &Comparison,
    truth: Option<&str>,
) {
    println!("column {name}: {rows} samples, {}", describe(cfg));
    println!("  level        sigma       lambda");
    for (j, (s, l)) in c.denoised.sigma.iter().zip(&c.denoised.lambda).enumerate() {
        println!("  {:>5} {:>12.6e} {:>12.6e}", j + 1, s, l);
    }
    println!("  RMS removed  {:.6e}", c.rms_removed);
    if let (Some(snr), Some(mse), Some(t)) = (c.snr_db, c.mse, truth) {
        println!("  against {t}: SNR {snr:.2} dB, MSE {mse:.6e}");
    }
}

fn print_table(
    name: &str,
    x: &[f64],
    truth: Option<&[f64]>,
    cfg: &DenoiseConfig,
    table: &[Comparison],
) {
    println!("column {name}: {} samples, {}", x.len(), describe(cfg));
    println!(
        "  {:<9} {:>9} {:>13} {:>13}",
        "function", "SNR (dB)", "MSE", "RMS removed"
    );
    if let Some(t) = truth {
        // The input itself, so the table shows what denoising bought.
        let (snr, mse) = (crate::quality::snr_db(t, x), crate::quality::mse(t, x));
        println!("  {:<9} {snr:>9.2} {mse:>13.6e} {:>13.6e}", "raw", 0.0);
    }
    for c in table {
        let snr = c.snr_db.map_or("-".into(), |v| format!("{v:.2}"));
        let mse = c.mse.map_or("-".into(), |v| format!("{v:.6e}"));
        println!(
            "  {:<9} {:>9} {:>13} {:>13.6e}",
            c.function.name(),
            snr,
            mse,
            c.rms_removed
        );
    }
}

fn thinned(y: &[f64], rate: Option<f64>) -> Vec<(f64, f64)> {
    let step = y.len().div_ceil(PLOT_POINTS).max(1);
    let scale = rate.map_or(1.0, |r| 1.0 / r);
    y.iter()
        .enumerate()
        .step_by(step)
        .map(|(i, v)| (i as f64 * scale, *v))
        .collect()
}

fn plot(
    path: &Path,
    name: &str,
    raw: &[f64],
    truth: Option<&[f64]>,
    runs: &[Comparison],
    rate: Option<f64>,
) -> Result<(), CliError> {
    let x_label = if rate.is_some() { "time (s)" } else { "sample" };
    let panels: Vec<Panel> = runs
        .iter()
        .map(|c| {
            let mut series = vec![Series {
                name: "raw".into(),
                points: thinned(raw, rate),
            }];
            if let Some(t) = truth {
                series.push(Series {
                    name: "truth".into(),
                    points: thinned(t, rate),
                });
            }
            series.push(Series {
                name: c.function.name().into(),
                points: thinned(&c.denoised.signal, rate),
            });
            Panel {
                title: format!("{name}: {} threshold", c.function.name()),
                x_label: x_label.into(),
                y_label: name.into(),
                series,
            }
        })
        .collect();
    crate::io::plot::write_panels(path, &panels).map_err(CliError::input)
}

/// Run `driftless denoise`.
pub fn run(args: Args) -> Result<(), CliError> {
    let cfg = config(&args)?;
    let data = load(&args)?;
    let rows = data.table.rows();
    let rate = args.synthetic.as_ref().map(|_| synthetic::RATE_HZ);
    let mut outputs = Vec::with_capacity(data.table.names.len());
    for (k, (name, x)) in data.table.names.iter().zip(&data.table.columns).enumerate() {
        let truth = data.truths[k].as_deref();
        let runs = if args.compare {
            compare(x, truth, &cfg)?
        } else {
            let denoised = denoise(x, &cfg)?;
            vec![Comparison {
                function: cfg.threshold,
                snr_db: truth.map(|t| crate::quality::snr_db(t, &denoised.signal)),
                mse: truth.map(|t| crate::quality::mse(t, &denoised.signal)),
                rms_removed: crate::quality::rms_diff(x, &denoised.signal),
                denoised,
            }]
        };
        if k > 0 {
            println!();
        }
        if args.compare {
            print_table(name, x, truth, &cfg, &runs);
        } else if args.output.is_none() {
            print_summary(name, rows, &cfg, &runs[0], data.truth_source.as_deref());
        }
        if k == 0 {
            if let Some(path) = &args.plot {
                plot(path, name, x, truth, &runs, rate)?;
            }
        }
        let chosen = runs
            .into_iter()
            .find(|c| c.function.name() == cfg.threshold.name())
            .expect("the chosen function is among the runs");
        outputs.push(chosen.denoised.signal);
    }
    if let Some(path) = &args.output {
        let columns: Vec<&[f64]> = outputs.iter().map(Vec::as_slice).collect();
        write_table_with_time(path, data.table.time.as_ref(), &data.table.names, &columns)?;
        eprintln!(
            "denoised {} column(s) of {} into {}",
            columns.len(),
            data.source,
            path.display()
        );
    }
    Ok(())
}
