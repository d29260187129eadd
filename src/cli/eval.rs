//! `driftless eval`: run the daemon's stages offline on a log (streaming denoiser, then the live
//! compensator with the model, and with the AR and persistence baselines in its place), and
//! print the paper's Table 3: the Allan terms of the raw, denoised and compensated rates
//! ([`crate::drift::evaluation`]).

use super::train::{check_rate, read_column, Column, GyroLogArgs};
use super::CliError;
use crate::allan::TermUnits;
use crate::cli::num::sig;
use crate::drift::baselines::Score;
use crate::drift::evaluation::{evaluate, Evaluation, Terms, MIN_SAMPLES, PAPER_RATIOS, TERMS};
use crate::drift::model::DriftModel;
use crate::io::model_file::{read_model, sha256_file};
use crate::io::plot::{write_panels, Panel, PanelStyle, Series};
use crate::units::RateUnit;
use serde::Serialize;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Points per plotted line at most.
const PLOT_POINTS: usize = 4000;

/// Arguments of `driftless eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The gyro log.
    #[command(flatten)]
    log: GyroLogArgs,
    /// Model file from `driftless train`.
    #[arg(long)]
    model: PathBuf,
    /// First sample scored (default: after the model's training range when the file is the
    /// model's training file, else 0). The stages run from sample 0 either way.
    #[arg(long)]
    from: Option<usize>,
    /// Last sample scored, exclusive (default: the end).
    #[arg(long)]
    to: Option<usize>,
    /// Draw the paper's Figures 9-11 into this SVG.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Print the results as JSON instead of tables.
    #[arg(long)]
    json: bool,
    /// Units of the noise terms in Table 3: datasheet (N deg/sqrt(h), B deg/h, K deg/h/sqrt(h))
    /// or seconds (deg/sqrt(s), deg/s, deg/s/sqrt(s)), as `driftless allan`. JSON keeps the
    /// fit's base units (the log's angle unit per second).
    #[arg(long, default_value = "datasheet")]
    term_units: TermUnits,
}

/// The whole evaluation.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// Input file.
    pub file: String,
    /// Column.
    pub column: String,
    /// Rate, Hz.
    pub rate_hz: f64,
    /// Units.
    pub units: RateUnit,
    /// Scored range.
    pub from: usize,
    /// Scored range end (exclusive).
    pub to: usize,
    /// Whether the file is the model's training file.
    pub training_file: bool,
    /// Whether the scored range overlaps the model's training range.
    pub in_sample: bool,
    /// Allan terms: raw, denoised, compensated by RBF, AR, persistence.
    pub table: Vec<Terms>,
    /// One-step and free-running drift prediction scores on the scored range.
    pub prediction: Vec<Score>,
}

fn thin(x0: f64, dt: f64, y: &[f64]) -> Vec<(f64, f64)> {
    let step = (y.len() / PLOT_POINTS).max(1);
    y.iter()
        .enumerate()
        .step_by(step)
        .map(|(i, v)| (x0 + i as f64 * dt, *v))
        .collect()
}

/// Run `driftless eval`.
pub fn run(args: Args) -> Result<(), CliError> {
    let model = read_model(&args.model).map_err(CliError::input)?;
    let rate = model.rate_hz;
    if let Some(r) = args.log.rate {
        check_rate(r)?;
        if (r - rate).abs() > 1e-9 * rate {
            return Err(CliError::input(format!(
                "the log is at {r} Hz but model {} was trained at {rate} Hz",
                args.model.display()
            )));
        }
    }
    if let Some(u) = &args.log.units {
        if u.parse() != Ok(model.units) {
            return Err(CliError::input(format!(
                "the log is in {u} but model {} is in {}",
                args.model.display(),
                model.units
            )));
        }
    }
    let (col, column) = read_log(&args, &model)?;
    let n = col.values.len();
    let hash = sha256_file(&args.log.input).map_err(CliError::input)?;
    let training_file = hash == model.provenance.sha256 && column == model.provenance.column;
    let held_out = model.provenance.train_start + model.provenance.train_len;
    let from = args
        .from
        .unwrap_or(if training_file { held_out } else { 0 });
    let to = args.to.unwrap_or(n).min(n);
    if to < from + MIN_SAMPLES {
        return Err(CliError::input(format!(
            "samples {from}..{to} of {} ({n} samples) are too few to evaluate (need at least \
             {MIN_SAMPLES}; the model's training range ends at {held_out})",
            args.log.input.display()
        )));
    }
    if training_file && from < held_out {
        eprintln!(
            "driftless: warning: samples {from}..{held_out} were used to train the model: \
             scores there are in-sample"
        );
    }
    let e = evaluate(&model, &col.values, from..to).map_err(CliError::input)?;
    if let Some(path) = &args.plot {
        write_plot(path, &model, &col.values, &e, from..to)?;
    }
    let report = Report {
        file: args.log.input.display().to_string(),
        column: col.name.clone(),
        rate_hz: rate,
        units: model.units,
        from,
        to,
        training_file,
        in_sample: training_file && from < held_out,
        table: e.table,
        prediction: e.prediction,
    };
    if args.json {
        let text =
            serde_json::to_string_pretty(&report).map_err(|e| CliError::internal(e.to_string()))?;
        println!("{text}");
    } else {
        print_report(&report, args.term_units);
    }
    Ok(())
}

/// The log's column (`--column`, else the model's axis; a bag's x) and its name as asked; a
/// bag's rate and units must be the model's.
fn read_log(args: &Args, model: &DriftModel) -> Result<(Column, String), CliError> {
    let rate = model.rate_hz;
    let is_bag = crate::rate_log::is_bag(&args.log.input);
    let column = match &args.log.column {
        Some(c) => c.clone(),
        // A bag's columns are x, y, z whatever the model's training log called its axis.
        None if is_bag => "x".to_string(),
        None => model.axis.clone(),
    };
    let col = read_column(&args.log.input, Some(&column), &args.log.bag)?;
    if col.origin.bag.is_some() {
        col.origin.rate(Some(rate)).map_err(|e| {
            CliError::input(format!(
                "{e} (model {} is at {rate} Hz)",
                args.model.display()
            ))
        })?;
        let units = col.origin.units(None).map_err(CliError::input)?;
        if units != model.units {
            return Err(CliError::input(format!(
                "{}: a bag's rates are in {units} but model {} is in {}",
                args.log.input.display(),
                args.model.display(),
                model.units
            )));
        }
    }
    Ok((col, column))
}

/// The paper's Figures 9-11 into the SVG at `path`: the RBF's drift prediction, the raw and
/// compensated rate, and their Allan deviations, on the judged range `r` of `raw`.
fn write_plot(
    path: &Path,
    model: &DriftModel,
    raw: &[f64],
    e: &Evaluation,
    r: Range<usize>,
) -> Result<(), CliError> {
    let dt = 1.0 / model.rate_hz;
    let (from, to) = (r.start, r.end);
    let t0 = from as f64 * dt;
    // Table 3's curves of the raw and the RBF-compensated rate, on the same range.
    let allan_series = [(&e.table[0], "raw"), (&e.table[2], "compensated (RBF)")]
        .into_iter()
        .map(|(t, name)| Series {
            name: format!("{name}: log10 OADEV"),
            points: t
                .oadev
                .iter()
                .filter(|p| p.1 > 0.0)
                .map(|p| (p.0.log10(), p.1.log10()))
                .collect(),
        })
        .collect();
    // Figure 9 as the paper: the last 1,000 predictions, where the two lines can be told apart.
    let f9 = to.saturating_sub(1000).max(from)..to;
    let t9 = f9.start as f64 * dt;
    let panels = [
        Panel {
            title: format!(
                "Figure 9: RBF drift prediction against the measured drift (last {} samples)",
                f9.len()
            ),
            x_label: "time (s)".into(),
            y_label: model.units.to_string(),
            series: vec![
                Series {
                    name: "measured drift (causal low band)".into(),
                    points: thin(t9, dt, &e.separated.drift[f9.clone()]),
                },
                Series {
                    name: "RBF prediction".into(),
                    points: thin(t9, dt, &e.rbf.drift[f9.clone()]),
                },
            ],
            style: PanelStyle::default(),
        },
        Panel {
            title: "Figure 10: raw and compensated rate".into(),
            x_label: "time (s)".into(),
            y_label: model.units.to_string(),
            series: vec![
                Series {
                    name: "raw".into(),
                    points: thin(t0, dt, &raw[r.clone()]),
                },
                Series {
                    name: "compensated (RBF)".into(),
                    points: thin(t0, dt, &e.rbf.rate[r.clone()]),
                },
            ],
            style: PanelStyle::default(),
        },
        Panel {
            title: "Figure 11: Allan deviation, raw and compensated".into(),
            x_label: "log10 tau (s)".into(),
            y_label: format!("log10 OADEV ({})", model.units),
            series: allan_series,
            style: PanelStyle::default(),
        },
    ];
    write_panels(path, &panels).map_err(CliError::input)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// The curve point whose tau is nearest `target` on a log scale.
fn nearest(curve: &[(f64, f64)], target: f64) -> Option<&(f64, f64)> {
    curve.iter().min_by(|a, b| {
        let da = (a.0 / target).ln().abs();
        let db = (b.0 / target).ln().abs();
        da.total_cmp(&db)
    })
}

fn print_report(r: &Report, term_units: TermUnits) {
    println!(
        "{}: column {}, {} Hz, samples {}..{}{}",
        r.file,
        r.column,
        r.rate_hz,
        r.from,
        r.to,
        match (r.training_file, r.in_sample) {
            (true, false) => " (held out from the model's training file)",
            (true, true) => " (overlapping the model's training range: in-sample)",
            _ => "",
        }
    );
    println!(
        "Table 3: Allan terms (IEEE 952 fit to octave OADEV), ratio to raw in brackets; \
         * = not identified by the fit; RBF, AR, persistence: the denoised rate compensated \
         with each predictor"
    );
    let mut header = vec!["term", "unit"];
    header.extend(r.table.iter().map(|t| {
        let s = t.signal.as_str();
        s.strip_prefix("compensated (")
            .and_then(|p| p.strip_suffix(')'))
            .unwrap_or(s)
    }));
    header.push("paper ratio");
    let mut table = super::table::new(&header, 2);
    // The fit works in the log's angle unit per second; terms are shown in degrees, in the
    // chosen convention (the same as `driftless allan`).
    let to_deg = r.units.to_deg_per_s();
    let cell = |v: f64, raw: f64, first: bool, mark: &str| {
        if first {
            format!("{}{mark}", sig(v, 4))
        } else if raw > 0.0 {
            format!("{}{mark} ({:.3})", sig(v, 4), v / raw)
        } else {
            // No ratio to an unidentified (zero) raw term.
            format!("{}{mark} (-)", sig(v, 4))
        }
    };
    for (i, term) in TERMS.iter().enumerate() {
        let (unit, f) = term.unit_in(term_units);
        let raw = r.table[0].values[i] * to_deg * f;
        let mut row = vec![term.name().to_string(), unit.to_string()];
        for (j, t) in r.table.iter().enumerate() {
            let mark = if t.identified[i] { "" } else { "*" };
            row.push(cell(t.values[i] * to_deg * f, raw, j == 0, mark));
        }
        row.push(
            PAPER_RATIOS
                .iter()
                .find(|(t, _)| t == term)
                .map_or("-".to_string(), |(_, v)| format!("{v:.2}")),
        );
        table.add_row(row);
    }
    // The fit can leave a term unidentified; deviations at fixed taus always compare.
    for target in [1.0, 10.0, 100.0] {
        // Only taus the record reaches (within a factor of 2 of the target).
        let Some(&(tau, raw)) = nearest(&r.table[0].oadev, target)
            .filter(|p| (p.0 / target).ln().abs() <= std::f64::consts::LN_2)
        else {
            continue;
        };
        let mut row = vec![format!("OADEV {} s", sig(tau, 4)), r.units.to_string()];
        for (j, t) in r.table.iter().enumerate() {
            let v = nearest(&t.oadev, target).map_or(f64::NAN, |p| p.1);
            row.push(cell(v, raw, j == 0, ""));
        }
        row.push(String::new());
        table.add_row(row);
    }
    let mut row = vec!["modes".to_string(), "still/moving/warm".to_string()];
    row.extend(r.table.iter().map(|t| match t.modes {
        Some([s, m, w]) => format!("{s:.3}/{m:.3}/{w:.3}"),
        None => "-".into(),
    }));
    row.push(String::new());
    table.add_row(row);
    println!("{table}");
    println!("drift prediction on the same samples (measured drift as inputs):");
    super::train::print_scores(&r.prediction, r.units, 1.0);
}
