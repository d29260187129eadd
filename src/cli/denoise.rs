//! `driftless denoise`: wavelet-threshold denoise CSV columns (or a synthetic benchmark record).

use super::CliError;
use crate::allan::RateUnit;
use crate::cli::log_input::{self, BagArgs};
use crate::cli::num::sig;
use crate::io::plot::{LineStyle, Panel, PanelStyle, Series};
use crate::io::{read_table, write_table_with_time, Table};
use crate::synthetic::{self, Regime};
use crate::wavelet::denoise::{compare, denoise, Comparison, DenoiseConfig, NoiseSigma, Rule};
use crate::wavelet::threshold::ThresholdFn;
use crate::wavelet::{Mode, Wavelet};
use std::path::PathBuf;
use std::time::Duration;

/// Points per plotted line at most (longer windows are thinned evenly).
const PLOT_POINTS: usize = 4000;

/// The plotted window when none is given: a few seconds, where the functions can be told apart
/// (the paper's Figure 6 shows about as much).
const PLOT_WINDOW: Duration = Duration::from_secs(5);

/// Time columns read as seconds for the plot's time axis (`timestamp` has no agreed unit).
const SECONDS_COLUMNS: [&str; 4] = ["t", "t_s", "time", "time_s"];

/// Arguments of `driftless denoise`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input CSV (with or without a header), or a ROS 2 bag (an MCAP file or a rosbag2
    /// directory, see --topic). Not needed with --synthetic.
    #[arg(required_unless_present = "synthetic")]
    input: Option<PathBuf>,
    /// The bag's topic.
    #[command(flatten)]
    bag: BagArgs,
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
    /// Draw raw against denoised (each function's with --compare), and the error against the
    /// truth beside it when there is one, into this SVG.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Start of the plotted window, from the start of the record (default 0).
    #[arg(
        long,
        requires = "plot",
        value_parser = crate::cli::duration::parse_offset,
        allow_hyphen_values = true
    )]
    plot_from: Option<Duration>,
    /// Length of the plotted window (default 5s).
    #[arg(
        long,
        requires = "plot",
        value_parser = crate::cli::duration::parse_duration,
        allow_hyphen_values = true
    )]
    plot_window: Option<Duration>,
    /// Sample rate of the input, Hz: the plot's time axis (default: the file's time column t,
    /// t_s, time or time_s, read as seconds).
    #[arg(long, conflicts_with = "synthetic")]
    rate: Option<f64>,
    /// Units of the input's rates, for the tables and the plot's axes: deg/s or rad/s
    /// (default deg/s; a bag's are rad/s; the synthetic records are in deg/s).
    #[arg(long, conflicts_with = "synthetic")]
    units: Option<String>,
    /// Use the seeded synthetic benchmark record instead of a file: static or dynamic.
    #[arg(long, conflicts_with_all = ["input", "truth", "topic"])]
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
    /// The units of the table's rates.
    units: RateUnit,
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
            units: RateUnit::DegPerS,
            truths: vec![Some(record.truth)],
            truth_source: Some("the synthetic truth".into()),
        });
    }
    let input = args
        .input
        .as_ref()
        .expect("clap requires input without --synthetic");
    // `-o` carries the input's time column through (a bag's stamps as t_s); the plot takes
    // its time axis from it.
    let keep_time = args.output.is_some() || args.plot.is_some();
    let log = log_input::open(input, &args.columns, &args.bag, keep_time)?;
    let units = log_input::unit_option("--units", args.units.as_deref())?;
    let units = log.origin.units(units).map_err(CliError::input)?;
    let table = log.table;
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
        super::log_input::check_text_input(
            truth_path,
            "--truth is CSV text (gzip-compressed too)",
        )?;
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
        units,
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
    units: RateUnit,
) {
    println!("column {name}: {rows} samples, {}", describe(cfg));
    let sigma = format!("sigma ({units})");
    let lambda = format!("lambda ({units})");
    let mut t = super::table::new(&["level", &sigma, &lambda], 0);
    for (j, (s, l)) in c.denoised.sigma.iter().zip(&c.denoised.lambda).enumerate() {
        t.add_row(vec![(j + 1).to_string(), sig(*s, 6), sig(*l, 6)]);
    }
    println!("{t}");
    println!("  RMS removed  {} {units}", sig(c.rms_removed, 6));
    if let (Some(snr), Some(mse), Some(t)) = (c.snr_db, c.mse, truth) {
        println!(
            "  against {t}: SNR {snr:.2} dB, MSE {} ({units})^2",
            sig(mse, 6)
        );
    }
}

fn print_table(
    name: &str,
    x: &[f64],
    truth: Option<&[f64]>,
    cfg: &DenoiseConfig,
    table: &[Comparison],
    units: RateUnit,
) {
    println!("column {name}: {} samples, {}", x.len(), describe(cfg));
    let mse_header = format!("MSE (({units})^2)");
    let rms_header = format!("RMS removed ({units})");
    let mut t = super::table::new(&["function", "SNR (dB)", &mse_header, &rms_header], 1);
    if let Some(truth) = truth {
        // The input itself, so the table shows what denoising bought.
        let (snr, mse) = (
            crate::quality::snr_db(truth, x),
            crate::quality::mse(truth, x),
        );
        t.add_row(vec![
            "raw".to_string(),
            format!("{snr:.2}"),
            sig(mse, 6),
            "0".into(),
        ]);
    }
    for c in table {
        t.add_row(vec![
            c.function.name().to_string(),
            c.snr_db.map_or("-".into(), |v| format!("{v:.2}")),
            c.mse.map_or("-".into(), |v| sig(v, 6)),
            sig(c.rms_removed, 6),
        ]);
    }
    println!("{t}");
}

/// Seconds of each sample from the start of the record, when the record has a time base: the
/// synthetic rate, `--rate`, or a time column in seconds. None otherwise.
fn time_axis(args: &Args, data: &Data) -> Result<Option<Vec<f64>>, CliError> {
    let rows = data.table.rows();
    let rate = if args.synthetic.is_some() {
        Some(synthetic::RATE_HZ)
    } else {
        args.rate
    };
    if let Some(rate) = rate {
        if !(rate.is_finite() && rate > 0.0) {
            return Err(CliError::input(format!(
                "--rate {rate} is not a sample rate (a positive number of Hz)"
            )));
        }
        return Ok(Some((0..rows).map(|i| i as f64 / rate).collect()));
    }
    let Some(time) = data
        .table
        .time
        .as_ref()
        .filter(|t| SECONDS_COLUMNS.contains(&t.name.as_str()))
    else {
        return Ok(None);
    };
    let t: Option<Vec<f64>> = time
        .cells
        .iter()
        .map(|c| c.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect();
    Ok(t.and_then(|t| {
        let t0 = *t.first()?;
        Some(t.iter().map(|v| v - t0).collect())
    }))
}

/// The part of the record to plot.
#[derive(Default)]
struct Window {
    /// The samples drawn.
    picked: Vec<usize>,
    /// The window, seconds (on a time axis; cut at the record's end).
    span: Option<(f64, f64)>,
}

/// The samples to plot: those of the window on a time axis, else all of them.
fn window(args: &Args, times: Option<&[f64]>, rows: usize) -> Result<Window, CliError> {
    let Some(t) = times else {
        if args.plot_from.is_some() || args.plot_window.is_some() {
            return Err(CliError::input(
                "--plot-from and --plot-window need a time axis: give --rate HZ (the input has \
                 no time column t, t_s, time or time_s in seconds)",
            ));
        }
        eprintln!(
            "driftless: note: plotting all {rows} samples against their number: give --rate HZ \
             for a time axis and a window of a few seconds"
        );
        return Ok(Window {
            picked: (0..rows).collect(),
            span: None,
        });
    };
    let from = args.plot_from.unwrap_or(Duration::ZERO).as_secs_f64();
    let to = from + args.plot_window.unwrap_or(PLOT_WINDOW).as_secs_f64();
    let picked: Vec<usize> = (0..rows).filter(|&i| t[i] >= from && t[i] < to).collect();
    let end = t.last().copied().unwrap_or(0.0);
    if picked.is_empty() {
        // Rounded to the ms, so a sum of sample periods reads as the user would write it.
        let ms = |s: f64| (s * 1e3).round() / 1e3;
        return Err(CliError::input(format!(
            "--plot-from {} s: the record spans 0 to {} s, no sample to plot",
            ms(from),
            ms(end)
        )));
    }
    Ok(Window {
        picked,
        span: Some((from, to.min(end))),
    })
}

/// `(x, y[i])` for the picked samples, thinned evenly to at most [`PLOT_POINTS`].
fn points(x: &[f64], picked: &[usize], y: impl Fn(usize) -> f64) -> Vec<(f64, f64)> {
    let step = picked.len().div_ceil(PLOT_POINTS).max(1);
    picked.iter().step_by(step).map(|&i| (x[i], y(i))).collect()
}

/// Each function's colour (the legend tells them apart); raw light grey, truth black.
fn colour(f: &ThresholdFn) -> (u8, u8, u8) {
    match f {
        ThresholdFn::Hard => (31, 119, 180),
        ThresholdFn::Soft => (255, 127, 14),
        ThresholdFn::Garrote => (44, 160, 44),
        ThresholdFn::Firm { .. } => (148, 103, 189),
        ThresholdFn::Improved { .. } => (214, 39, 40),
    }
}

const RAW: LineStyle = LineStyle {
    colour: (175, 175, 175),
    width: 1,
};
const TRUTH: LineStyle = LineStyle {
    colour: (0, 0, 0),
    width: 1,
};

/// The paper's Figure 6: per function a row, the signal (raw, truth, denoised) on the left and
/// its error against the truth on the right, over a window of a few seconds; every signal panel
/// on one y scale, every error panel on another, so the rows compare at a glance.
struct Figure<'a> {
    name: &'a str,
    units: RateUnit,
    raw: &'a [f64],
    truth: Option<&'a [f64]>,
    runs: &'a [Comparison],
    /// Seconds from the start, or None (the x axis is then the sample number).
    times: Option<&'a [f64]>,
    window: &'a Window,
}

impl Figure<'_> {
    fn panels(&self) -> Vec<Panel> {
        let index: Vec<f64>;
        let (x, x_label) = match self.times {
            Some(t) => (t, "time (s)"),
            None => {
                index = (0..self.raw.len()).map(|i| i as f64).collect();
                (index.as_slice(), "sample")
            }
        };
        let picked = &self.window.picked;
        let x_range = self
            .window
            .span
            .unwrap_or((x[picked[0]], x[picked[picked.len() - 1]]));
        let units = self.units;
        let mut panels = Vec::new();
        for c in self.runs {
            let f = c.function.name();
            let own = LineStyle {
                colour: colour(&c.function),
                width: 2,
            };
            let mut signal = vec![Series {
                name: "raw".into(),
                points: points(x, picked, |i| self.raw[i]),
            }];
            let mut lines = vec![RAW];
            if let Some(t) = self.truth {
                signal.push(Series {
                    name: "truth".into(),
                    points: points(x, picked, |i| t[i]),
                });
                lines.push(TRUTH);
            }
            signal.push(Series {
                name: f.into(),
                points: points(x, picked, |i| c.denoised.signal[i]),
            });
            lines.push(own);
            let snr = c
                .snr_db
                .map_or(String::new(), |v| format!(", SNR {v:.2} dB"));
            panels.push(Panel {
                title: format!("{}: {f} threshold{snr}", self.name),
                x_label: x_label.into(),
                y_label: format!("{} ({units})", self.name),
                series: signal,
                style: PanelStyle {
                    x_range: Some(x_range),
                    y_range: None,
                    lines,
                    legend_on_top: true,
                },
            });
            if let Some(t) = self.truth {
                let rms = c.mse.map_or(String::new(), |m| {
                    format!(": RMS {:.3} {units} over the record", m.sqrt())
                });
                panels.push(Panel {
                    title: format!("{f} - truth{rms}"),
                    x_label: x_label.into(),
                    y_label: format!("error ({units})"),
                    series: vec![
                        Series {
                            name: "raw - truth".into(),
                            points: points(x, picked, |i| self.raw[i] - t[i]),
                        },
                        Series {
                            name: format!("{f} - truth"),
                            points: points(x, picked, |i| c.denoised.signal[i] - t[i]),
                        },
                    ],
                    style: PanelStyle {
                        x_range: Some(x_range),
                        y_range: None,
                        lines: vec![RAW, own],
                        legend_on_top: true,
                    },
                });
            }
        }
        // One y scale per column: signal panels together, error panels together.
        let columns = self.columns();
        for col in 0..columns {
            let column = panels.iter().skip(col).step_by(columns);
            let (_, (y0, y1)) = crate::io::plot::bounds(column.flat_map(|p| &p.series));
            // Room above the data for the legend, so it hides none of it.
            let y_range = (y0, y1 + 0.45 * (y1 - y0));
            for p in panels.iter_mut().skip(col).step_by(columns) {
                p.style.y_range = Some(y_range);
            }
        }
        panels
    }

    fn columns(&self) -> usize {
        if self.truth.is_some() {
            2
        } else {
            1
        }
    }
}

/// Run `driftless denoise`.
pub fn run(args: Args) -> Result<(), CliError> {
    let cfg = config(&args)?;
    let data = load(&args)?;
    let units = data.units;
    let rows = data.table.rows();
    let (times, shown) = match &args.plot {
        Some(_) => {
            let times = time_axis(&args, &data)?;
            let shown = window(&args, times.as_deref(), rows)?;
            (times, shown)
        }
        None => (None, Window::default()),
    };
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
            print_table(name, x, truth, &cfg, &runs, units);
        } else if args.output.is_none() {
            print_summary(
                name,
                rows,
                &cfg,
                &runs[0],
                data.truth_source.as_deref(),
                units,
            );
        }
        if k == 0 {
            if let Some(path) = &args.plot {
                let figure = Figure {
                    name,
                    units,
                    raw: x,
                    truth,
                    runs: &runs,
                    times: times.as_deref(),
                    window: &shown,
                };
                crate::io::plot::write_grid(path, &figure.panels(), figure.columns())
                    .map_err(CliError::input)?;
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
