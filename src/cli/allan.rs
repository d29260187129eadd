//! `driftless allan`: Allan deviation of a rate log (and of its accelerometer columns) with
//! intervals, and its IEEE Std 952 noise terms ([`crate::allan::analysis`]); with `--stage`, the
//! `predict.bias` table of the unit's own terms ([`crate::drift::bias::own_terms`], and the
//! accelerometer's: [`crate::drift::bias::own_accel_terms`]). Several logs of one unit pool per
//! tau, never joined ([`crate::allan::pool`]; `pooled` here).

mod pooled;

use super::CliError;
use crate::allan::analysis::{self, Analysis, Curve, Progress};
use crate::allan::deviation::{AllanPoint, NoiseId};
use crate::allan::fit::b_read_off_unidentified;
use crate::allan::{
    chi2, edf, AccelUnit, Estimate, FitError, Kind, NoiseFit, RateUnit, SampleUnit, Sensor,
    TauGrid, Term, TermFit, TermUnits,
};
use crate::cli::log_input::{self, BagArgs};
use crate::cli::num::sig;
use crate::drift::bias::{
    accel_stage_key, combined_as, own_accel_terms, own_terms, stage_key, Choice, ColumnFit,
    TermChoices,
};
use crate::io::plot::{self, ErrorPoint, LogLogChart, Series};
use crate::io::{progress, write_table};
use crate::rate_log::{self, RateLog};
use crate::stages::accel_terms::{ACCEL_BIAS_INSTABILITY, ACCEL_VRW};
use pooled::{Pooling, Reference};
use serde_json::{json, Map, Value};
use std::path::{Path, PathBuf};

/// Arguments of `driftless allan`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Rate log: CSV with a header, or headerless (.gz read transparently), or a ROS 2 bag
    /// (an MCAP file or a rosbag2 directory, see --topic). Several logs of one unit (one per
    /// power-up, one per day) are pooled per tau, never joined end to end: they must share rate,
    /// units and columns.
    #[arg(required = true, value_name = "INPUT")]
    pub inputs: Vec<PathBuf>,
    /// Sample rate in Hz (required for CSV; a bag's comes from its stamps).
    #[arg(long, allow_hyphen_values = true)]
    pub rate: Option<String>,
    /// The bag's topic.
    #[command(flatten)]
    pub bag: BagArgs,
    /// Gyro column to analyse (repeat for several; default: every numeric column but a time
    /// column named t, t_s, time, time_s or timestamp and the --accel-column ones; a bag's x,
    /// y, z).
    #[arg(long = "column", value_name = "NAME")]
    pub columns: Vec<String>,
    /// Accelerometer column to analyse (repeat for several): velocity random walk N
    /// (m/s/sqrt(h)), bias instability B (mg), acceleration random walk K (m/s^2/sqrt(h)). A
    /// bag's are ax, ay, az (linear_acceleration, m/s^2).
    #[arg(long = "accel-column", value_name = "NAME")]
    pub accel_columns: Vec<String>,
    /// Unit of the accelerometer columns: m/s^2 or g (default m/s^2; a bag's are m/s^2).
    #[arg(long, requires = "accel_columns")]
    pub accel_units: Option<String>,
    /// Tau grid: octave, decade, log:P (P per decade), all, or a list of seconds (0.1,1,10).
    #[arg(long, default_value = "octave")]
    pub taus: String,
    /// Deviation: oadev, adev, mdev or hdev (overlapping Hadamard).
    #[arg(long, default_value = "oadev")]
    pub kind: String,
    /// Unit of the gyro samples: deg/s or rad/s (terms are always reported in degree units;
    /// default deg/s, a bag's rad/s).
    #[arg(long)]
    pub units: Option<String>,
    /// Units of the noise terms: datasheet (N deg/sqrt(h), B deg/h, K deg/h/sqrt(h); an
    /// accelerometer's N m/s/sqrt(h), B mg, K m/s^2/sqrt(h)) or seconds (deg/sqrt(s), deg/s,
    /// deg/s/sqrt(s); m/s/sqrt(s), m/s^2, m/s^2/sqrt(s)); the other is shown beside N.
    #[arg(long, default_value = "datasheet")]
    pub term_units: TermUnits,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Write a log-log SVG plot with error bars and the fitted terms (one per sensor: with both,
    /// the accelerometer's goes to FILE-accel.svg).
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// Write the tau table as CSV.
    #[arg(short = 'o', long = "output", value_name = "OUT.csv")]
    pub output: Option<PathBuf>,
    /// Print a ready `predict.bias` `[[stage]]` table with the fitted terms instead of the tables:
    /// every gyro term given (no sensor's defaults fill in), one set for all axes (N the largest, B
    /// the median, K 0, Q the largest; a term the record cannot identify is never the fit's
    /// guess), and per term and column what was taken and why in its comments. With
    /// --accel-column, the accelerometer's accel_vrw and accel_bias_instability too.
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
    /// The unit of its samples, which says the sensor.
    unit: SampleUnit,
    samples: usize,
    points: Vec<AllanPoint>,
    fit: Result<NoiseFit, FitError>,
    read_offs: Vec<TermFit>,
    /// The octave OADEV points the fit and the read-offs use (base unit: deg/s, m/s^2).
    octave: Vec<AllanPoint>,
    /// Per point, how many logs reached its tau: empty for one log.
    logs: Vec<usize>,
}

impl ColumnResult {
    fn sensor(&self) -> Sensor {
        self.unit.sensor()
    }

    /// The column `name` of samples in `unit`, analysed as `a` (one log's: no `logs`).
    fn of(name: String, unit: SampleUnit, a: Analysis) -> Self {
        ColumnResult {
            name,
            unit,
            samples: a.samples,
            points: a.points,
            fit: a.fit,
            read_offs: a.read_offs,
            octave: a.octave,
            logs: Vec::new(),
        }
    }

    /// The analysis back, for pooling.
    fn into_analysis(self) -> Analysis {
        Analysis {
            samples: self.samples,
            points: self.points,
            octave: self.octave,
            fit: self.fit,
            read_offs: self.read_offs,
        }
    }
}

/// Terms a curve sums from which it shows a progress bar (about half a second here).
const PROGRESS_MIN_TERMS: f64 = 1e9;

/// Terms a grid sums from which it is worth a warning that it will take long.
const WARN_TERMS: f64 = 2e10;

/// The analysis of the column `name` of samples in `unit` ([`analysis::analyse`]), with a
/// progress bar for each long curve.
fn analyse(
    y: &[f64],
    rate: f64,
    kind: Kind,
    grid: &TauGrid,
    unit: SampleUnit,
    name: &str,
) -> Result<ColumnResult, crate::allan::AllanError> {
    let mut bar = None;
    let a = analysis::analyse(y, rate, kind, grid, unit.to_base(), &mut |p| match p {
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
    Ok(ColumnResult::of(name.to_string(), unit, a))
}

fn term_json(t: &TermFit, sensor: Sensor) -> Value {
    match t.estimate {
        Some(e) => {
            let (unit, f) = sensor.display(t.term);
            json!({"value": e.value * f, "unit": unit, "lo": e.lo * f, "hi": e.hi * f})
        }
        None => Value::Null,
    }
}

fn terms_json(terms: &[TermFit], sensor: Sensor) -> (Value, Value) {
    let mut values = Map::new();
    let mut reasons = Map::new();
    for t in terms {
        values.insert(t.term.name().into(), term_json(t, sensor));
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

/// `term`'s estimate `e` of a `sensor` in `units`: value, unit and interval.
fn format_estimate(sensor: Sensor, term: Term, e: &Estimate, units: TermUnits) -> String {
    let (unit, f) = sensor.unit_in(term, units);
    format!(
        "{} {unit}  [{}, {}]",
        sig(e.value * f, 5),
        sig(e.lo * f, 5),
        sig(e.hi * f, 5)
    )
}

fn format_term(t: &TermFit, units: TermUnits, sensor: Sensor) -> String {
    match (t.estimate, &t.reason) {
        (Some(e), _) => {
            let mut s = format_estimate(sensor, t.term, &e, units);
            // A second unit where it is customary: N in the other convention, Q in arcsec.
            let alt = match (units, t.term) {
                (TermUnits::Seconds, Term::N) => Some(sensor.display(t.term)),
                (TermUnits::Seconds, Term::Q) | (TermUnits::Datasheet, _) => {
                    sensor.alternate(t.term)
                }
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

/// The `predict.bias` table of `--stage`: the terms of [`own_terms`] (of the gyro columns) and
/// of [`own_accel_terms`] (of the accelerometer's, if any), every key written out, and per term
/// and column what was taken and why (`lsb` in the gyro columns' units).
fn stage_table(
    results: &[ColumnResult],
    shown: &str,
    pooling: Option<&Pooling>,
    rate: f64,
    lsb: f64,
) -> Result<String, CliError> {
    let (gyro, accel): (Vec<&ColumnResult>, Vec<&ColumnResult>) =
        results.iter().partition(|r| r.sensor() == Sensor::Gyro);
    let Some(unit) = gyro.first().map(|r| r.unit) else {
        return Err(CliError::input(format!(
            "{shown}: no gyro column to give predict.bias its terms (name them with --column)"
        )));
    };
    let refused = |e| {
        CliError::input(format!(
            "{shown}: {e}: the record cannot give predict.bias its terms"
        ))
    };
    let own =
        own_terms(&column_fits(&gyro, shown, rate)?, lsb * unit.to_base()).map_err(refused)?;
    let mut notes = term_notes(Sensor::Gyro, &own.choices, |t| stage_key(&own.terms, t));
    let mut terms = own.terms;
    // The stage reads lsb in the pipeline's input units, which are the log's here.
    terms.lsb = lsb;
    let mut keys = terms.stage_keys();
    let mut columns: Vec<&str> = gyro.iter().map(|r| r.name.as_str()).collect();
    let mut units = format!("{unit}");
    if let Some(a) = accel.first() {
        let own = own_accel_terms(&column_fits(&accel, shown, rate)?).map_err(refused)?;
        notes.extend(term_notes(Sensor::Accel, &own.choices, |t| {
            accel_stage_key(&own.terms, t)
        }));
        notes.push(format!(
            "#   the accelerometer's white noise per sample: accel_vrw / 60 x sqrt(rate_hz), {} m/s^2 at {rate} Hz",
            sig(own.terms.white_std(rate), 4)
        ));
        keys = format!("{keys}\n{}", own.terms.stage_keys());
        columns.extend(accel.iter().map(|r| r.name.as_str()));
        units = format!("{units}; the accelerometer's {}", a.unit);
    } else {
        notes.push(format!(
            "#   {} and {} are not given: the stage takes their defaults (the ADIS16405 data sheet's); --accel-column measures them",
            ACCEL_VRW.name, ACCEL_BIAS_INSTABILITY.name
        ));
    }
    let samples = results.first().map_or(0, |r| r.samples);
    let samples = match pooling {
        Some(p) => format!("{samples} samples in {} logs", p.logs.len()),
        None => format!("{samples} samples"),
    };
    let mut out = format!(
        "# predict.bias with the noise terms of {shown} ({}; {samples} at {rate} Hz, {units}),\n\
         # from `driftless allan ... --stage`. One set for every axis; each term says how it was\n\
         # taken. Every gyro term is given, so no sensor's defaults fill in. The pipeline's\n\
         # input_units must be {unit} (lsb is in them). Set input and output to your chain's services.\n",
        columns.join(", ")
    );
    if let Some(p) = pooling {
        out.push_str("# The logs, pooled per tau (never joined):\n");
        for line in p.lines() {
            out.push_str(&format!("#   {line}\n"));
        }
    }
    for n in notes {
        out.push_str(&n);
        out.push('\n');
    }
    out.push_str(&format!(
        "[[stage]]\nname = \"predict\"\nkind = \"predict.bias\"\ninput = \"nav/denoised\"\noutput = \"nav/predicted\"\n{keys}\n",
    ));
    Ok(out)
}

/// Each column's fit, for [`own_terms`] and [`own_accel_terms`]: refused where a column has
/// none, or no N (then saying how long a record would give it).
fn column_fits<'a>(
    results: &[&'a ColumnResult],
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
                "{shown}: column '{}': {} of data cannot identify the {} N ({}): \
                 record {needed}",
                r.name,
                humantime::format_duration(std::time::Duration::from_millis(
                    (secs * 1000.0).round() as u64
                )),
                r.sensor().term_name(Term::N),
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

/// The `--stage` table's comments for one sensor: per term, the value taken (`key` gives its
/// stage key and value) and how the columns were combined, and per column what it gave.
fn term_notes(
    sensor: Sensor,
    choices: &[TermChoices],
    key: impl Fn(Term) -> (&'static str, f64),
) -> Vec<String> {
    let mut notes = Vec::new();
    for (term, columns) in choices {
        let (key, taken) = key(*term);
        let (u, f) = sensor.unit_in(*term, TermUnits::Datasheet);
        let whose = match sensor {
            Sensor::Gyro => String::new(),
            Sensor::Accel => format!(", the accelerometer's {}", sensor.term_name(*term)),
        };
        notes.push(format!(
            "#   {term}{whose} ({key}) = {} {u}: {}",
            sig(taken * f, 5),
            combined_as(*term)
        ));
        for (name, choice) in columns {
            let at = |e: &Estimate| format_estimate(sensor, *term, e, TermUnits::Datasheet);
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
    let (results, rate, pooling) = analyse_logs(&args, given_rate, kind, &grid)?;
    let shown = match &pooling {
        Some(p) => format!("{} pooled logs", p.logs.len()),
        None => args.inputs[0].display().to_string(),
    };
    if let Some(out) = &args.output {
        write_csv(out, &results)?;
        if let Some(p) = &pooling {
            let to = p.write_csv(out)?;
            eprintln!("driftless: the pooled logs are listed in {}", to.display());
        }
    }
    if let Some(path) = &args.plot {
        write_plots(path, &results, kind, pooling.as_ref())?;
    }
    if args.stage {
        let lsb = super::simulate::parse_number("--lsb", &args.lsb)?;
        if !(lsb.is_finite() && lsb >= 0.0) {
            return Err(CliError::input(format!(
                "--lsb '{}' must be >= 0",
                args.lsb
            )));
        }
        print!(
            "{}",
            stage_table(&results, &shown, pooling.as_ref(), rate, lsb)?
        );
        return Ok(());
    }
    if args.json {
        let columns: Vec<Value> = results.iter().map(|r| column_json(r, rate, kind)).collect();
        let mut out = json!({ "columns": columns });
        if let Some(p) = &pooling {
            out["pooled"] = p.logs.len().into();
            out["logs"] = p.json();
        }
        println!("{out}");
        return Ok(());
    }
    if let Some(p) = &pooling {
        println!("{}", p.text());
    }
    for r in &results {
        print_column(r, rate, kind, args.term_units);
    }
    Ok(())
}

/// Each log read and analysed in turn (one log's samples in memory at a time) at the first log's
/// rate; several are pooled ([`pooled::pool_columns`]) after each was checked against the first.
fn analyse_logs(
    args: &Args,
    given_rate: Option<f64>,
    kind: Kind,
    grid: &TauGrid,
) -> Result<(Vec<ColumnResult>, f64, Option<Pooling>), CliError> {
    let several = args.inputs.len() > 1;
    let mut per_log = Vec::with_capacity(args.inputs.len());
    let mut reference: Option<Reference> = None;
    let given = (
        log_input::unit_option("--units", args.units.as_deref())?,
        log_input::unit_option("--accel-units", args.accel_units.as_deref())?,
    );
    for path in &args.inputs {
        let (log, units) = read_columns(args, path, given)?;
        let own_rate = log.origin.rate(given_rate).map_err(CliError::input)?;
        let rate = match &reference {
            Some(r) => {
                r.check(path, &log, &units, own_rate)?;
                r.rate
            }
            None => {
                reference
                    .insert(Reference::of(path, &log, &units, own_rate))
                    .rate
            }
        };
        let shown = path.display().to_string();
        let table = log.table;
        let mut results = Vec::new();
        for ((name, y), &unit) in table.names.iter().zip(&table.columns).zip(&units) {
            let label = match several {
                true => format!("{shown}: {name}"),
                false => name.clone(),
            };
            let mut r = analyse(y, rate, kind, grid, unit, &label)
                .map_err(|e| CliError::input(format!("{shown}: column '{name}': {e}")))?;
            r.name.clone_from(name);
            results.push(r);
        }
        per_log.push(results);
    }
    let Some(rate) = reference.map(|r| r.rate) else {
        return Err(CliError::input("no log given"));
    };
    if !several {
        return Ok((per_log.into_iter().flatten().collect(), rate, None));
    }
    // The columns' names and units are the first log's (every log was checked against it).
    let named: Vec<(String, SampleUnit)> = per_log
        .first()
        .map(|cols| cols.iter().map(|r| (r.name.clone(), r.unit)).collect())
        .unwrap_or_default();
    let analyses = per_log
        .into_iter()
        .map(|cols| cols.into_iter().map(ColumnResult::into_analysis).collect())
        .collect();
    let paths: Vec<&Path> = args.inputs.iter().map(PathBuf::as_path).collect();
    let (pooled, pooling) = pooled::pool_columns(kind, &paths, analyses);
    let results = named
        .into_iter()
        .zip(pooled)
        .map(|((name, unit), p)| ColumnResult {
            logs: p.logs,
            ..ColumnResult::of(name, unit, p.analysis)
        })
        .collect();
    Ok((results, rate, Some(pooling)))
}

/// The columns to analyse of the log at `path` and the unit of each: the gyro's (`--column`, or
/// every other numeric column) in `--units`, the accelerometer's (`--accel-column`) in
/// `--accel-units` (`given`, parsed).
fn read_columns(
    args: &Args,
    path: &Path,
    given: (Option<RateUnit>, Option<AccelUnit>),
) -> Result<(RateLog, Vec<SampleUnit>), CliError> {
    let accel = &args.accel_columns;
    if let Some(both) = args.columns.iter().find(|c| accel.contains(c)) {
        return Err(CliError::input(format!(
            "column '{both}' is named by both --column and --accel-column: a column is one sensor's"
        )));
    }
    let bag = rate_log::is_bag(path);
    // Without --column the gyro's are the rest: every numeric column of a CSV file, read all
    // at once; a bag's x, y, z.
    let wanted: Vec<String> = match (args.columns.is_empty(), accel.is_empty(), bag) {
        (true, true, _) | (true, false, false) => Vec::new(),
        (true, false, true) => rate_log::BAG_COLUMNS
            .iter()
            .map(|c| c.to_string())
            .chain(accel.iter().cloned())
            .collect(),
        (false, _, _) => args.columns.iter().chain(accel).cloned().collect(),
    };
    let log = log_input::open(path, &wanted, &args.bag, false)?;
    let gyro = SampleUnit::Rate(log.origin.units(given.0).map_err(CliError::input)?);
    let accel_unit = log.origin.accel_units(given.1).map_err(CliError::input)?;
    for name in accel {
        if !log.table.names.contains(name) {
            return Err(CliError::input(format!(
                "{}: no column named '{name}' (columns: {})",
                path.display(),
                log.table.names.join(", ")
            )));
        }
    }
    let units: Vec<SampleUnit> = log
        .table
        .names
        .iter()
        .map(|n| match accel.contains(n) {
            true => SampleUnit::Accel(accel_unit),
            false => gyro,
        })
        .collect();
    gravity_check(&log, &units, accel_unit);
    Ok((log, units))
}

/// A warning when three accelerometer axes read a gravity that says another unit than the one
/// given (a still unit reads 1 g, 9.8 m/s^2, whatever its attitude).
fn gravity_check(log: &RateLog, units: &[SampleUnit], given: AccelUnit) {
    let means: Vec<f64> = log
        .table
        .columns
        .iter()
        .zip(units)
        .filter(|(_, u)| matches!(u, SampleUnit::Accel(_)))
        .map(|(y, _)| y.iter().sum::<f64>() / y.len().max(1) as f64)
        .collect();
    if means.len() != 3 {
        return;
    }
    let norm = means.iter().map(|m| m * m).sum::<f64>().sqrt();
    if let Some(seems) = AccelUnit::implied_by_gravity(norm).filter(|&u| u != given) {
        eprintln!(
            "driftless: warning: {}: the accelerometer columns read a gravity of {} {given}, as a still unit does in {seems}: are they in {seems} (--accel-units {seems})?",
            log.origin.path.display(),
            sig(norm, 4)
        );
    }
}

/// `-o`: the tau table as CSV. Every column has the same grid (it depends only on the length),
/// so one tau column serves; pooled, a `logs` column beside it.
fn write_csv(out: &Path, results: &[ColumnResult]) -> Result<(), CliError> {
    let mut names = vec!["tau_s".to_string()];
    let mut cols: Vec<Vec<f64>> = vec![results[0].points.iter().map(|p| p.tau).collect()];
    // Pooled: how many logs reached each tau (the same for every column: it depends only on
    // the logs' lengths).
    if !results[0].logs.is_empty() {
        names.push("logs".to_string());
        cols.push(results[0].logs.iter().map(|&k| k as f64).collect());
    }
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
fn column_json(r: &ColumnResult, rate: f64, kind: Kind) -> Value {
    let points: Vec<Value> = r
        .points
        .iter()
        .enumerate()
        .map(|(j, p)| {
            let (noise_id, plausible) = match p.noise_id {
                NoiseId::Slope => ("slope", Value::Null),
                NoiseId::Widest { lo, hi } => ("widest", json!([lo, hi])),
            };
            let mut point = json!({"tau": p.tau, "dev": p.dev, "n": p.n, "lo": p.lo, "hi": p.hi,
                   "edf": p.edf, "alpha": p.alpha, "noise_id": noise_id,
                   "alpha_plausible": plausible});
            if let Some(&k) = r.logs.get(j) {
                point["logs"] = k.into();
            }
            point
        })
        .collect();
    let sensor = r.sensor();
    let (terms, reasons) = terms_json(&fit_terms_or_reason(&r.fit), sensor);
    let (ro, _) = terms_json(&r.read_offs, sensor);
    let names: Map<String, Value> = Term::ALL
        .iter()
        .map(|&t| (t.name().to_string(), sensor.term_name(t).into()))
        .collect();
    let (why, outside) = trust(&r.fit, &r.read_offs, &r.octave);
    let outside: Vec<&str> = outside.iter().map(|t| t.name()).collect();
    let trust = json!({
        "use": if r.fit.is_ok() { "terms" } else { "none" },
        "why": why,
        "read_offs_outside_fit_interval": outside,
    });
    json!({"name": r.name, "sensor": sensor.word(), "samples": r.samples, "rate": rate,
           "kind": kind.to_string(), "unit": r.unit.to_string(), "ci": chi2::ONE_SIGMA,
           "points": points, "term_names": names, "terms": terms,
           "not_identified": reasons, "read_offs": ro, "trust": trust})
}

/// The terms' names for `sensor`, as the terms' header lists them ("Q quantisation noise, ...").
fn legend(sensor: Sensor) -> String {
    Term::ALL
        .iter()
        .map(|&t| format!("{t} {}", sensor.term_name(t)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// One column's tables: the curve, the fitted terms beside the read-offs, which to trust.
fn print_column(r: &ColumnResult, rate: f64, kind: Kind, term_units: TermUnits) {
    let (sensor, unit) = (r.sensor(), r.unit);
    let whose = match sensor {
        Sensor::Gyro => "",
        Sensor::Accel => "accelerometer, ",
    };
    let pooled = !r.logs.is_empty();
    let (samples, logs_head) = match pooled {
        true => (
            format!("{} samples in {} logs", r.samples, r.logs[0]),
            " logs",
        ),
        false => (format!("{} samples", r.samples), ""),
    };
    println!(
        "{} ({whose}{samples} at {} Hz): {kind} in {unit}, {:.1}% chi-squared intervals (Greenhall EDF)",
        r.name,
        rate,
        chi2::ONE_SIGMA * 100.0
    );
    println!(
        "{:>12} {:>14} {:>14} {:>14} {:>10} {:>10} {:>6}{logs_head}",
        "tau (s)", "dev", "lo", "hi", "n", "edf", "alpha"
    );
    let mut widest = None;
    for (j, p) in r.points.iter().enumerate() {
        let alpha = match p.noise_id {
            NoiseId::Slope => p.alpha.to_string(),
            NoiseId::Widest { lo, hi } => {
                widest.get_or_insert((lo, hi));
                format!("{}*", p.alpha)
            }
        };
        let logs = r.logs.get(j).map_or(String::new(), |k| format!(" {k:>4}"));
        println!(
            "{:>12.6} {:>14} {:>14} {:>14} {:>10} {:>10.1} {:>6}{logs}",
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
    let legend = legend(sensor);
    match &r.fit {
        Ok(f) => println!(
            "IEEE 952 terms ({legend}; weighted NNLS fit of octave OADEV, tau {} s to {} s) | slope read-off:",
            f.tau_range.0, f.tau_range.1
        ),
        Err(_) => println!("IEEE 952 terms ({legend}) | slope read-off:"),
    }
    for (t, ro) in fitted.iter().zip(&r.read_offs) {
        println!(
            "  {}  {}  | {}",
            t.term,
            format_term(t, term_units, sensor),
            format_term(ro, term_units, sensor)
        );
    }
    println!(
        "Which to trust: {}",
        trust(&r.fit, &r.read_offs, &r.octave).0
    );
    println!();
}

/// `--plot`: one chart per sensor, as the columns' units differ: the gyro's (or the only
/// sensor's) to `path`, the accelerometer's beside the gyro's to `<stem>-accel.<ext>`.
fn write_plots(
    path: &Path,
    results: &[ColumnResult],
    kind: Kind,
    pooling: Option<&Pooling>,
) -> Result<(), CliError> {
    let (gyro, accel): (Vec<&ColumnResult>, Vec<&ColumnResult>) =
        results.iter().partition(|r| r.sensor() == Sensor::Gyro);
    if !gyro.is_empty() {
        plot::write_loglog(path, &chart(&gyro, kind, pooling)).map_err(CliError::input)?;
    }
    if !accel.is_empty() {
        let to = if gyro.is_empty() {
            path.to_path_buf()
        } else {
            let stem = path.file_stem().unwrap_or_default().to_string_lossy();
            let ext = path
                .extension()
                .map_or(String::new(), |e| format!(".{}", e.to_string_lossy()));
            path.with_file_name(format!("{stem}-accel{ext}"))
        };
        plot::write_loglog(&to, &chart(&accel, kind, pooling)).map_err(CliError::input)?;
        if !gyro.is_empty() {
            eprintln!(
                "driftless: the accelerometer's plot is {} (the gyro's {})",
                to.display(),
                path.display()
            );
        }
    }
    Ok(())
}

/// The chart of `results`, columns of one sensor in one unit (pooled from `pooling`'s logs).
fn chart(results: &[&ColumnResult], kind: Kind, pooling: Option<&Pooling>) -> LogLogChart {
    let Some(first) = results.first() else {
        unreachable!("a chart of no column")
    };
    let (sensor, unit) = (first.sensor(), first.unit);
    let to_base = unit.to_base();
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
                .map(|&t| (t, fit.model_variance(t).sqrt() / to_base))
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
                            (t.term.coefficient(tau) * fit.theta[k]).sqrt() / to_base,
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
            let (unit, f) = sensor.display(t.term);
            let name = sensor.term_name(t.term);
            notes.push(match t.estimate {
                Some(e) => format!(
                    "  {} = {} {unit} [{}, {}], {name}",
                    t.term,
                    sig(e.value * f, 4),
                    sig(e.lo * f, 4),
                    sig(e.hi * f, 4)
                ),
                None => format!("  {}: not identifiable ({name})", t.term),
            });
        }
    }
    let whose = match sensor {
        Sensor::Gyro => "",
        Sensor::Accel => " of the accelerometer",
    };
    let mut pooled = String::new();
    if let Some(p) = pooling {
        pooled = format!(", {} logs pooled per tau", p.logs.len());
        notes.push(format!(
            "{} logs pooled per tau (never joined):",
            p.logs.len()
        ));
        notes.extend(p.lines().into_iter().map(|l| format!("  {l}")));
    }
    LogLogChart {
        title: format!(
            "{}{whose} with {:.1}% intervals and IEEE 952 terms{pooled}",
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
