//! `driftless allan`: Allan deviation of a rate log with intervals, and its IEEE Std 952 noise terms
//! ([`crate::allan::analysis`]); with `--stage`, the `predict.bias` table of the unit's own terms
//! ([`crate::drift::bias::own_terms`]).

use super::CliError;
use crate::allan::analysis::{self, Curve, Progress};
use crate::allan::deviation::{AllanPoint, NoiseId};
use crate::allan::fit::b_read_off_unidentified;
use crate::allan::{
    chi2, edf, Estimate, FitError, Kind, NoiseFit, RateUnit, TauGrid, Term, TermFit, TermUnits,
};
use crate::cli::log_input::{self, BagArgs};
use crate::cli::num::sig;
use crate::drift::bias::{combined_as, own_terms, stage_key, Choice, ColumnFit, OwnTerms};
use crate::io::plot::{self, ErrorPoint, LogLogChart, Series};
use crate::io::{progress, write_table};
use serde_json::{json, Map, Value};
use std::path::{Path, PathBuf};

/// Arguments of `driftless allan`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Rate log: CSV with a header, or headerless (.gz read transparently), or a ROS 2 bag
    /// (an MCAP file or a rosbag2 directory, see --topic).
    pub input: PathBuf,
    /// Sample rate in Hz (required for CSV; a bag's comes from its stamps).
    #[arg(long, allow_hyphen_values = true)]
    pub rate: Option<String>,
    /// The bag's topic.
    #[command(flatten)]
    pub bag: BagArgs,
    /// Column to analyse (repeat for several; default: every numeric column but a time column
    /// named t, t_s, time, time_s or timestamp).
    #[arg(long = "column", value_name = "NAME")]
    pub columns: Vec<String>,
    /// Tau grid: octave, decade, log:P (P per decade), all, or a list of seconds (0.1,1,10).
    #[arg(long, default_value = "octave")]
    pub taus: String,
    /// Deviation: oadev, adev, mdev or hdev (overlapping Hadamard).
    #[arg(long, default_value = "oadev")]
    pub kind: String,
    /// Unit of the samples: deg/s or rad/s (terms are always reported in degree units;
    /// default deg/s, a bag's rad/s).
    #[arg(long)]
    pub units: Option<String>,
    /// Units of the noise terms: datasheet (N deg/sqrt(h), B deg/h, K deg/h/sqrt(h)) or
    /// seconds (deg/sqrt(s), deg/s, deg/s/sqrt(s)); the other is shown beside N.
    #[arg(long, default_value = "datasheet")]
    pub term_units: TermUnits,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Write a log-log SVG plot with error bars and the fitted terms.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// Write the tau table as CSV.
    #[arg(short = 'o', long = "output", value_name = "OUT.csv")]
    pub output: Option<PathBuf>,
    /// Print a ready `predict.bias` [[stage]] table with the fitted terms instead of the tables:
    /// every key given (no sensor's defaults fill in), one set for all axes (N the largest, B
    /// the median, K 0, Q the largest; a term the record cannot identify is never the fit's
    /// guess), and per term and column what was taken and why in its comments.
    #[arg(long, conflicts_with = "json")]
    pub stage: bool,
    /// With --stage: the output step of the raw rate, in the log's units (0: not quantised).
    #[arg(
        long,
        default_value = "0",
        requires = "stage",
        allow_hyphen_values = true
    )]
    pub lsb: String,
}

/// The analysis of one column.
struct ColumnResult {
    name: String,
    samples: usize,
    points: Vec<AllanPoint>,
    fit: Result<NoiseFit, FitError>,
    read_offs: Vec<TermFit>,
    /// The octave OADEV points the fit and the read-offs use (deg/s).
    octave: Vec<AllanPoint>,
}

/// Terms a curve sums from which it shows a progress bar (about half a second here).
const PROGRESS_MIN_TERMS: f64 = 1e9;

/// Terms a grid sums from which it is worth a warning that it will take long.
const WARN_TERMS: f64 = 2e10;

/// The analysis of the column `name` ([`analysis::analyse`]), with a progress bar for each
/// long curve.
fn analyse(
    y: &[f64],
    rate: f64,
    kind: Kind,
    grid: &TauGrid,
    to_deg: f64,
    name: &str,
) -> Result<ColumnResult, crate::allan::AllanError> {
    let mut bar = None;
    let a = analysis::analyse(y, rate, kind, grid, to_deg, &mut |p| match p {
        Progress::Start {
            curve,
            steps,
            terms,
        } => {
            let msg = match curve {
                Curve::Asked => {
                    if terms > WARN_TERMS {
                        eprintln!(
                            "driftless: warning: {name}: this grid needs {terms:.1e} terms on {} samples and will take long (try --taus log:10)",
                            y.len()
                        );
                    }
                    format!("{name}: {kind}")
                }
                Curve::OctaveForFit => format!("{name}: octave oadev for the fit"),
            };
            let shown = if terms >= PROGRESS_MIN_TERMS {
                0
            } else {
                u64::MAX
            };
            bar = Some(progress::bar(steps as u64, shown, &msg));
        }
        Progress::Step(n) => {
            if let Some(b) = &bar {
                b.inc(n as u64);
            }
        }
        Progress::Done => {
            if let Some(b) = bar.take() {
                b.finish_and_clear();
            }
        }
    })?;
    Ok(ColumnResult {
        name: name.to_string(),
        samples: a.samples,
        points: a.points,
        fit: a.fit,
        read_offs: a.read_offs,
        octave: a.octave,
    })
}

fn term_json(t: &TermFit) -> Value {
    match t.estimate {
        Some(e) => {
            let (unit, f) = t.term.display();
            json!({"value": e.value * f, "unit": unit, "lo": e.lo * f, "hi": e.hi * f})
        }
        None => Value::Null,
    }
}

fn terms_json(terms: &[TermFit]) -> (Value, Value) {
    let mut values = Map::new();
    let mut reasons = Map::new();
    for t in terms {
        values.insert(t.term.name().into(), term_json(t));
        if let Some(r) = &t.reason {
            reasons.insert(t.term.name().into(), Value::String(r.clone()));
        }
    }
    (Value::Object(values), Value::Object(reasons))
}

fn fit_terms_or_reason(fit: &Result<NoiseFit, FitError>) -> Vec<TermFit> {
    match fit {
        Ok(f) => f.terms.clone(),
        Err(e) => Term::ALL
            .iter()
            .map(|&term| TermFit {
                term,
                estimate: None,
                reason: Some(e.to_string()),
                sigmas: None,
            })
            .collect(),
    }
}

/// Which to trust and why, in one line (text output and JSON `trust.why`).
const TRUST_FIT: &str = "trust the fitted terms, not the read-offs: the fit uses every octave tau weighted by its interval and separates the terms; a read-off takes one point or segment as it is, other terms' share and chance included";

/// The same line when no fit was possible.
const TRUST_NONE: &str = "no fit, so no term to trust: a read-off takes one point or segment as it is, other terms' share and chance included";

/// Which to trust and why: the line printed (and JSON `trust.why`) and the terms whose read-off
/// lies outside the fit's interval.
fn trust(
    fit: &Result<NoiseFit, FitError>,
    read_offs: &[TermFit],
    octave: &[AllanPoint],
) -> (String, Vec<Term>) {
    let mut line = String::from(if fit.is_ok() { TRUST_FIT } else { TRUST_NONE });
    let outside = match fit {
        Ok(f) => f.read_offs_outside(read_offs),
        Err(_) => Vec::new(),
    };
    if !outside.is_empty() {
        let names: Vec<&str> = outside.iter().map(|t| t.name()).collect();
        line += &format!(
            "; here the read-off of {} lies outside the fit's interval",
            names.join(", ")
        );
    }
    if let Some(p) = b_read_off_unidentified(octave, read_offs) {
        line += &format!(
            "; the B read-off is the curve's lowest point, at tau {} s with EDF {:.1} and too few tau-spans to identify the noise: the lowest of scattered points can sit low by chance",
            p.tau, p.edf
        );
    }
    (line, outside)
}

/// `term`'s estimate `e` in `units`: value, unit and interval.
fn format_estimate(term: Term, e: &Estimate, units: TermUnits) -> String {
    let (unit, f) = term.unit_in(units);
    format!(
        "{} {unit}  [{}, {}]",
        sig(e.value * f, 5),
        sig(e.lo * f, 5),
        sig(e.hi * f, 5)
    )
}

fn format_term(t: &TermFit, units: TermUnits) -> String {
    match (t.estimate, &t.reason) {
        (Some(e), _) => {
            let mut s = format_estimate(t.term, &e, units);
            // A second unit where it is customary: N in the other convention, Q in arcsec.
            let alt = match (units, t.term) {
                (TermUnits::Seconds, Term::N) => Some(t.term.display()),
                (TermUnits::Seconds, Term::Q) | (TermUnits::Datasheet, _) => t.term.alternate(),
                (TermUnits::Seconds, _) => None,
            };
            if let Some((alt, g)) = alt {
                s.push_str(&format!("  = {} {alt}", sig(e.value * g, 5)));
            }
            s
        }
        (None, Some(r)) => format!("not identifiable: {r}"),
        (None, None) => "not identifiable".into(),
    }
}

/// The `predict.bias` table of `--stage`: the terms of [`own_terms`], every key written out,
/// and per term and column what was taken and why (`lsb` in the log's units).
fn stage_table(
    results: &[ColumnResult],
    args: &Args,
    rate: f64,
    unit: RateUnit,
    lsb: f64,
) -> Result<String, CliError> {
    let shown = args.input.display();
    let fits = column_fits(results, &shown.to_string(), rate)?;
    if fits.is_empty() {
        return Err(CliError::input(format!("{shown}: no column to analyse")));
    }
    let own = own_terms(&fits, lsb * unit.to_deg_per_s()).map_err(|e| {
        CliError::input(format!(
            "{shown}: {e}: the record cannot give predict.bias its terms"
        ))
    })?;
    let notes = term_notes(&own);
    let mut terms = own.terms;
    // The stage reads lsb in the pipeline's input units, which are the log's here.
    terms.lsb = lsb;
    let columns: Vec<&str> = results.iter().map(|r| r.name.as_str()).collect();
    let samples = results.first().map_or(0, |r| r.samples);
    let mut out = format!(
        "# predict.bias with the noise terms of {shown} ({}; {samples} samples at {rate} Hz, {unit}),\n\
         # from `driftless allan ... --stage`. One set for every axis; each term says how it was\n\
         # taken. Every key is given, so no sensor's defaults fill in. The pipeline's\n\
         # input_units must be {unit} (lsb is in them). Set input and output to your chain's services.\n",
        columns.join(", ")
    );
    for n in notes {
        out.push_str(&n);
        out.push('\n');
    }
    out.push_str(&format!(
        "[[stage]]\nname = \"predict\"\nkind = \"predict.bias\"\ninput = \"nav/denoised\"\noutput = \"nav/predicted\"\n{}\n",
        terms.stage_keys()
    ));
    Ok(out)
}

/// Each column's fit, for [`own_terms`]: refused where a column has none, or no N (then saying
/// how long a record would give it).
fn column_fits<'a>(
    results: &'a [ColumnResult],
    shown: &str,
    rate: f64,
) -> Result<Vec<ColumnFit<'a>>, CliError> {
    let mut fits = Vec::with_capacity(results.len());
    for r in results {
        let fit = r.fit.as_ref().map_err(|e| {
            CliError::input(format!(
                "{shown}: column '{}': no noise terms to give predict.bias ({e})",
                r.name
            ))
        })?;
        // Without N the filter has no measurement noise: say how long a record would do.
        let n = fit.get(Term::N);
        if n.estimate.is_none() {
            let secs = r.samples as f64 / rate;
            let needed = match n.record_to_identify(secs) {
                Some(s) => format!(
                    "about {} of still data",
                    humantime::format_duration(std::time::Duration::from_secs(s as u64))
                ),
                None => "a longer stretch of still data".to_string(),
            };
            return Err(CliError::input(format!(
                "{shown}: column '{}': {} of data cannot identify the angle random walk N ({}): \
                 record {needed}",
                r.name,
                humantime::format_duration(std::time::Duration::from_millis(
                    (secs * 1000.0).round() as u64
                )),
                n.reason.as_deref().unwrap_or("no estimate")
            )));
        }
        fits.push(ColumnFit {
            name: r.name.as_str(),
            fit,
            points: &r.octave,
        });
    }
    Ok(fits)
}

/// The `--stage` table's comments: per term, the value taken and how the columns were
/// combined, and per column what it gave.
fn term_notes(own: &OwnTerms) -> Vec<String> {
    let mut notes = Vec::new();
    for (term, columns) in &own.choices {
        let (key, taken) = stage_key(&own.terms, *term);
        let (u, f) = term.unit_in(TermUnits::Datasheet);
        notes.push(format!(
            "#   {term} ({key}) = {} {u}: {}",
            sig(taken * f, 5),
            combined_as(*term)
        ));
        for (name, choice) in columns {
            let at = |e: &Estimate| format_estimate(*term, e, TermUnits::Datasheet);
            let what = match choice {
                Choice::Identified(e) => at(e),
                Choice::Floor {
                    why,
                    estimate,
                    tau_s,
                    reached,
                } => format!(
                    "not identifiable: {why}; read at the curve's lowest point (tau {tau_s} s{}), {}, is taken",
                    if *reached {
                        ""
                    } else {
                        ", its last: no floor yet, an upper bound"
                    },
                    at(estimate)
                ),
                Choice::Zero(why) => format!("not identifiable: {why}; 0 is taken"),
                Choice::Unused(e) => format!(
                    "{}; not taken: B gives the walk, learnt from the stops where a stop signal gives them",
                    at(e)
                ),
            };
            notes.push(format!("#     {name}: {what}"));
        }
    }
    notes
}

/// Run `driftless allan`.
pub fn run(args: Args) -> Result<(), CliError> {
    let given_rate = match &args.rate {
        Some(r) => {
            let rate = super::simulate::parse_number("--rate", r)?;
            if !(rate.is_finite() && rate > 0.0) {
                return Err(CliError::input(format!(
                    "--rate must be a positive number of Hz, not {rate}"
                )));
            }
            Some(rate)
        }
        None => None,
    };
    let grid: TauGrid = args
        .taus
        .parse()
        .map_err(|e| CliError::input(format!("--taus: {e}")))?;
    let kind: Kind = args
        .kind
        .parse()
        .map_err(|e| CliError::input(format!("--kind: {e}")))?;
    let log = log_input::open(&args.input, &args.columns, &args.bag, false)?;
    let rate = log.origin.rate(given_rate).map_err(CliError::input)?;
    let unit = log_input::rate_unit(&log.origin, args.units.as_deref())?;
    let table = log.table;
    let shown = args.input.display().to_string();
    let mut results = Vec::new();
    for (name, y) in table.names.iter().zip(&table.columns) {
        let r = analyse(y, rate, kind, &grid, unit.to_deg_per_s(), name)
            .map_err(|e| CliError::input(format!("{shown}: column '{name}': {e}")))?;
        results.push(r);
    }
    if let Some(out) = &args.output {
        write_csv(out, &results)?;
    }
    if let Some(path) = &args.plot {
        plot::write_loglog(path, &chart(&results, kind, unit)).map_err(CliError::input)?;
    }
    if args.stage {
        let lsb = super::simulate::parse_number("--lsb", &args.lsb)?;
        if !(lsb.is_finite() && lsb >= 0.0) {
            return Err(CliError::input(format!(
                "--lsb '{}' must be >= 0",
                args.lsb
            )));
        }
        print!("{}", stage_table(&results, &args, rate, unit, lsb)?);
        return Ok(());
    }
    if args.json {
        let columns: Vec<Value> = results
            .iter()
            .map(|r| column_json(r, rate, kind, unit))
            .collect();
        println!("{}", json!({ "columns": columns }));
        return Ok(());
    }
    for r in &results {
        print_column(r, rate, kind, unit, args.term_units);
    }
    Ok(())
}

/// `-o`: the tau table as CSV. Every column has the same grid (it depends only on the length),
/// so one tau column serves.
fn write_csv(out: &Path, results: &[ColumnResult]) -> Result<(), CliError> {
    let mut names = vec!["tau_s".to_string()];
    let mut cols: Vec<Vec<f64>> = vec![results[0].points.iter().map(|p| p.tau).collect()];
    for r in results {
        for (suffix, f) in [
            ("dev", (|p: &AllanPoint| p.dev) as fn(&AllanPoint) -> f64),
            ("lo", |p| p.lo),
            ("hi", |p| p.hi),
            ("n", |p| p.n as f64),
            ("edf", |p| p.edf),
            ("alpha", |p| f64::from(p.alpha)),
            // 1 where the slope identified alpha, 0 where it is the widest plausible one.
            ("identified", |p| {
                f64::from(u8::from(matches!(p.noise_id, NoiseId::Slope)))
            }),
        ] {
            names.push(format!("{}_{suffix}", r.name));
            cols.push(r.points.iter().map(f).collect());
        }
    }
    let refs: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
    write_table(out, &names, &refs)?;
    Ok(())
}

/// One column's object of `--json`.
fn column_json(r: &ColumnResult, rate: f64, kind: Kind, unit: RateUnit) -> Value {
    let points: Vec<Value> = r
        .points
        .iter()
        .map(|p| {
            let (noise_id, plausible) = match p.noise_id {
                NoiseId::Slope => ("slope", Value::Null),
                NoiseId::Widest { lo, hi } => ("widest", json!([lo, hi])),
            };
            json!({"tau": p.tau, "dev": p.dev, "n": p.n, "lo": p.lo, "hi": p.hi,
                   "edf": p.edf, "alpha": p.alpha, "noise_id": noise_id,
                   "alpha_plausible": plausible})
        })
        .collect();
    let (terms, reasons) = terms_json(&fit_terms_or_reason(&r.fit));
    let (ro, _) = terms_json(&r.read_offs);
    let (why, outside) = trust(&r.fit, &r.read_offs, &r.octave);
    let outside: Vec<&str> = outside.iter().map(|t| t.name()).collect();
    let trust = json!({
        "use": if r.fit.is_ok() { "terms" } else { "none" },
        "why": why,
        "read_offs_outside_fit_interval": outside,
    });
    json!({"name": r.name, "samples": r.samples, "rate": rate, "kind": kind.to_string(),
           "unit": unit.to_string(), "ci": chi2::ONE_SIGMA, "points": points,
           "terms": terms, "not_identified": reasons, "read_offs": ro,
           "trust": trust})
}

/// One column's tables: the curve, the fitted terms beside the read-offs, which to trust.
fn print_column(r: &ColumnResult, rate: f64, kind: Kind, unit: RateUnit, term_units: TermUnits) {
    println!(
        "{} ({} samples at {} Hz): {kind} in {unit}, {:.1}% chi-squared intervals (Greenhall EDF)",
        r.name,
        r.samples,
        rate,
        chi2::ONE_SIGMA * 100.0
    );
    println!(
        "{:>12} {:>14} {:>14} {:>14} {:>10} {:>10} {:>6}",
        "tau (s)", "dev", "lo", "hi", "n", "edf", "alpha"
    );
    let mut widest = None;
    for p in &r.points {
        let alpha = match p.noise_id {
            NoiseId::Slope => p.alpha.to_string(),
            NoiseId::Widest { lo, hi } => {
                widest.get_or_insert((lo, hi));
                format!("{}*", p.alpha)
            }
        };
        println!(
            "{:>12.6} {:>14} {:>14} {:>14} {:>10} {:>10.1} {:>6}",
            p.tau,
            sig(p.dev, 7),
            sig(p.lo, 7),
            sig(p.hi, 7),
            p.n,
            p.edf,
            alpha
        );
    }
    if let Some((lo, hi)) = widest {
        println!(
            "* noise type not identified (fewer than {} tau-spans at about 2 tau): of alpha {lo}..{hi} (the floor up to the last one identified), the one with the widest interval",
            edf::MIN_SPANS
        );
    }
    let fitted = fit_terms_or_reason(&r.fit);
    match &r.fit {
        Ok(f) => println!(
            "IEEE 952 terms (weighted NNLS fit of octave OADEV, tau {} s to {} s) | slope read-off:",
            f.tau_range.0, f.tau_range.1
        ),
        Err(_) => println!("IEEE 952 terms | slope read-off:"),
    }
    for (t, ro) in fitted.iter().zip(&r.read_offs) {
        println!(
            "  {}  {}  | {}",
            t.term,
            format_term(t, term_units),
            format_term(ro, term_units)
        );
    }
    println!(
        "Which to trust: {}",
        trust(&r.fit, &r.read_offs, &r.octave).0
    );
    println!();
}

fn chart(results: &[ColumnResult], kind: Kind, unit: RateUnit) -> LogLogChart {
    let to_deg = unit.to_deg_per_s();
    let mut lines = Vec::new();
    let mut notes = Vec::new();
    for r in results {
        let Ok(fit) = &r.fit else { continue };
        let (t0, t1) = (r.points[0].tau, r.points[r.points.len() - 1].tau);
        let taus: Vec<f64> = (0..=100)
            .map(|i| t0 * (t1 / t0).powf(f64::from(i) / 100.0))
            .collect();
        lines.push(Series {
            name: format!("{}: fitted model", r.name),
            points: taus
                .iter()
                .map(|&t| (t, fit.model_variance(t).sqrt() / to_deg))
                .collect(),
        });
        for (k, t) in fit.terms.iter().enumerate() {
            if t.estimate.is_none() || results.len() > 1 {
                continue;
            }
            lines.push(Series {
                name: format!("{} line (slope {:+})", t.term, t.term.slope()),
                points: taus
                    .iter()
                    .map(|&tau| {
                        (
                            tau,
                            (t.term.coefficient(tau) * fit.theta[k]).sqrt() / to_deg,
                        )
                    })
                    .collect(),
            });
        }
        notes.push(format!(
            "{} ({:.1}% intervals):",
            r.name,
            chi2::ONE_SIGMA * 100.0
        ));
        for t in &fit.terms {
            let (unit, f) = t.term.display();
            notes.push(match t.estimate {
                Some(e) => format!(
                    "  {} = {:.4} {unit} [{:.4}, {:.4}]",
                    t.term,
                    e.value * f,
                    e.lo * f,
                    e.hi * f
                ),
                None => format!("  {}: not identifiable", t.term),
            });
        }
    }
    LogLogChart {
        title: format!(
            "{} with {:.1}% intervals and IEEE 952 terms",
            kind.to_string().to_uppercase(),
            chi2::ONE_SIGMA * 100.0
        ),
        x_label: "tau (s)".into(),
        y_label: format!("{kind} ({unit})"),
        curves: results
            .iter()
            .map(|r| {
                (
                    r.name.clone(),
                    r.points
                        .iter()
                        .map(|p| ErrorPoint {
                            x: p.tau,
                            y: p.dev,
                            lo: p.lo,
                            hi: p.hi,
                        })
                        .collect(),
                )
            })
            .collect(),
        lines,
        notes,
    }
}
