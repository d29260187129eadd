//! `ingest.csv`: replay a CSV file at its own rate, a factor faster or as fast as possible,
//! optionally looping.
//! Sequence numbers count from 0 across loops; timestamps keep increasing.
//!
//! Validation reads the header and the first [`CHECKED_ROWS`] rows (a wrong file fails there with
//! file:line:col); the run streams the file from a reader thread in blocks of samples, so memory
//! stays bounded however long the log. A bad row found while replaying is not dropped: it is
//! replayed as a sample marked invalid (the guard holds the last good rate, flags and counts it)
//! and its file:line:col is printed on stderr. A row whose only bad cells are the
//! accelerometer's, the magnetometer's, the stop's or the odometry's keeps its rates: only the
//! unreadable reading is flagged.
//!
//! **A logged odometry while driving.** With `yaw_rate_column` and `motion_output`, each row
//! whose yaw rate cell holds a number is one odometry message (empty or `nan` between them, as
//! an odometry at 50 Hz beside a gyro at 100 Hz or more logs it): it is published on
//! `motion_output` as a `StopSignal` on the samples' clock just before its row's sample, so a
//! `predict.bias` with that `stop_input` (and `vehicle_up`) learns the bias while the vehicle
//! drives, at any pace, on every pass of a loop.
//!
//! ```toml
//! [[stage]]
//! name = "sensor"
//! kind = "ingest.csv"
//! output = "replay/raw"
//! file = "data/replay.csv"       # relative to the pipeline file; gzip-compressed works
//! columns = ["x", "y", "z"]      # one per axis (default x, y, z)
//! accel_columns = ["ax", "ay", "az"]  # the accelerometer, in accel_units (default: none)
//! mag_columns = ["mx", "my", "mz"]    # the magnetometer (default: none)
//! mag_units = "uT"                    # of mag_columns: "T", "gauss" or "uT" (default)
//! time_column = "t"              # seconds (default: i / rate_hz)
//! stop_column = "stopped"        # 1 stands, 0 moves, nan unknown (default: none)
//! yaw_rate_column = "odom_wz"    # the odometry's yaw rate, input_units (default: none)
//! yaw_rate_std_column = "odom_wz_sd"  # its 1-sigma, input_units (default: none)
//! motion_output = "vehicle/stop" # the yaw rate as StopSignals, for predict.bias's stop_input
//! pace = "asap"                  # or "realtime" (default), or 10.0: ten times real time
//! loop = false
//! ```

use std::path::PathBuf;

use toml::Spanned;

use crate::io::content::text_file;
use crate::io::{InputError, RowRead, RowReader};
use crate::rate_log::{Stamps, RATE_TOLERANCE};
use crate::stages::contract::{Kind, Params, Role, Source};
use crate::stages::replay::{BlockReplay, BlockSink, Replay, LOOP, PACE, START_DELAY_S};
use crate::stages::schema::{Context, DefaultValue, Key, Src, Table, Type};
use crate::units::MagUnit;
use crate::wire::{
    RawSample, StopSignal, RAW_ACCEL, RAW_INVALID, RAW_MAG, RAW_VEHICLE_MOVING,
    RAW_VEHICLE_STOPPED, STOP_CLOCK_SAMPLES,
};

const FILE: Key = Key {
    name: "file",
    ty: Type::Str(
        "a CSV file, relative to the pipeline file; gzip-compressed works (told by its content)",
    ),
    default: DefaultValue::Required,
    doc: "the log to replay; its header and first 1000 rows checked at validation, then streamed",
};
const COLUMNS: Key = Key {
    name: "columns",
    ty: Type::StrList("one column name per axis"),
    default: DefaultValue::Noted(&DefaultValue::Words(&["x", "y", "z"]), " (first `axes`)"),
    doc: "the rate columns",
};
const ACCEL_COLUMNS: Key = Key {
    name: "accel_columns",
    ty: Type::StrList("three column names, x, y, z"),
    default: DefaultValue::Absent("none: the samples carry no accelerometer"),
    doc: "the accelerometer's columns, in the pipeline's `accel_units`; carried beside the \
          rates, time-aligned. A bad cell in the rows checked at validation refuses the \
          pipeline, as a rate's; found later, it keeps the row's rates, and the guard holds the \
          last good accelerometer and flags it",
};
const MAG_COLUMNS: Key = Key {
    name: "mag_columns",
    ty: Type::StrList("three column names, x, y, z"),
    default: DefaultValue::Absent("none: the samples carry no magnetometer"),
    doc: "the magnetometer's columns, in `mag_units`; carried beside the rates in tesla, \
          time-aligned. A bad or empty cell in the rows checked at validation refuses the \
          pipeline, as a rate's; found later, it keeps the row's rates, and the guard holds the \
          last good field and flags it",
};
/// Microtesla, as most magnetometers' fields are quoted (and [`MagUnit`]'s default).
const MAG_UNITS_DEFAULT: DefaultValue = DefaultValue::Word(MagUnit::MicroT.name());
const MAG_UNITS: Key = Key {
    name: "mag_units",
    ty: Type::Choice(&MagUnit::NAMES),
    default: DefaultValue::Noted(&MAG_UNITS_DEFAULT, " (with `mag_columns`)"),
    doc: "units of `mag_columns` (`gauss`: 1e-4 T). A key of this stage, not of the pipeline \
          as `accel_units` is: a raw sample carries the field in tesla (`RawSample.v2`, as \
          drivers publish it and recordings keep it), so the replay converts it, where the \
          accelerometer travels in the pipeline's units for the guard to convert",
};
const TIME_COLUMN: Key = Key {
    name: "time_column",
    ty: Type::Str("a column name; seconds, not negative"),
    default: DefaultValue::Absent("none (i / rate_hz)"),
    doc: "sensor timestamps",
};
const STOP_COLUMN: Key = Key {
    name: "stop_column",
    ty: Type::Str("a column name; 1 stands, 0 moves, nan unknown"),
    default: DefaultValue::Absent("none"),
    doc: "the vehicle's stops logged beside the rates (wheel odometry): carried with each sample, so `predict.bias` takes them by sample time, in any replay speed",
};
const YAW_RATE_COLUMN: Key = Key {
    name: "yaw_rate_column",
    ty: Type::Str("a column name; the pipeline's input_units, empty or nan between messages"),
    default: DefaultValue::Absent("none"),
    doc: "the vehicle's yaw rate logged beside the rates (wheel odometry, a car's yaw-rate sensor), counter-clockwise seen from above positive (REP 103): one message per row that holds a number, on the row of its stamp (the end of the period it measured). Needs `motion_output`",
};
const YAW_RATE_STD_COLUMN: Key = Key {
    name: "yaw_rate_std_column",
    ty: Type::Str("a column name; the pipeline's input_units"),
    default: DefaultValue::Absent("none: predict.bias assumes 0.1 deg/s per message"),
    doc: "each message's 1-sigma, on the same rows as `yaw_rate_column` (a value not > 0 says nothing): `predict.bias` weighs each message by it",
};
const MOTION_OUTPUT: Key = Key {
    name: "motion_output",
    ty: Type::Str("a service name: \"vehicle/stop\""),
    default: DefaultValue::Absent("none"),
    doc: "where each `yaw_rate_column` message is published, as a `StopSignal` on the samples' clock just before its row's sample: name it as `predict.bias`'s `stop_input` (with `vehicle_up`) and the log's odometry teaches the bias while the vehicle drives, at any pace. Needs `yaw_rate_column`",
};
/// `ingest.csv`.
pub const KIND: Kind = Kind {
    name: "ingest.csv",
    role: Role::Ingest { has_input: false },
    summary:
        "a CSV log replayed at its rate, a factor faster or as fast as possible, optionally looping",
    keys: &[
        FILE,
        COLUMNS,
        ACCEL_COLUMNS,
        MAG_COLUMNS,
        MAG_UNITS,
        TIME_COLUMN,
        STOP_COLUMN,
        YAW_RATE_COLUMN,
        YAW_RATE_STD_COLUMN,
        MOTION_OUTPUT,
        PACE,
        LOOP,
        START_DELAY_S,
    ],
    parse,
};

/// A CSV replay: checked at validation (the header and the first [`CHECKED_ROWS`] rows), then
/// streamed from the file while it runs.
#[derive(Debug, Clone)]
pub struct CsvParams {
    /// The file.
    pub file: PathBuf,
    /// The rate columns, one per axis.
    pub columns: Vec<String>,
    /// The accelerometer's columns (x, y, z), if any.
    pub accel_columns: Option<Vec<String>>,
    /// The magnetometer's columns (x, y, z), if any.
    pub mag_columns: Option<Vec<String>>,
    /// The unit of the magnetometer's columns (the samples carry tesla).
    pub mag_units: MagUnit,
    /// The time column (seconds), if any; else `t = i / rate_hz`.
    pub time_column: Option<String>,
    /// The stop column (1 stands, 0 moves, NaN unknown), if any.
    pub stop_column: Option<String>,
    /// The odometry's yaw rate column (input units; empty or NaN: no message on the row).
    pub yaw_rate_column: Option<String>,
    /// Its 1-sigma column (input units), if any.
    pub yaw_rate_std_column: Option<String>,
    /// Where the yaw rate goes as stop signals (`motion_output`).
    pub motion_output: Option<String>,
    /// rad/s per input unit, for the yaw rate's stop signals.
    pub rad_per_unit: f64,
    /// The rate's step in the checked rows, input units ([`step_of`]).
    pub step: Option<f64>,
    /// Pacing, looping, delay.
    pub replay: Replay,
    /// One line when the file's name claims another format than CSV text (it is read by what
    /// it holds).
    pub note: Option<String>,
}

/// Data rows checked at validation, so that a wrong file fails there with its position; later
/// rows are checked as they are replayed (a bad one becomes a flagged invalid sample).
pub const CHECKED_ROWS: usize = 1000;

/// Bad rows reported one by one on stderr before only their count is.
const REPORTED_BAD_ROWS: u64 = 10;

/// The output step of a quantised rate: the smallest difference between two of its distinct
/// finite values (a rate that is not quantised gives a tiny one). None with fewer than two.
pub fn step_of(mut values: Vec<f64>) -> Option<f64> {
    values.retain(|v| v.is_finite());
    values.sort_by(f64::total_cmp);
    // Below this a difference is the decimal text's rounding, not a step.
    let floor = 1e-9 * values.iter().fold(1e-30f64, |m, v| m.max(v.abs()));
    values
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > floor)
        .reduce(f64::min)
}

impl Params for CsvParams {
    fn pace(&self) -> Option<crate::clock::Pace> {
        Some(self.replay.pace)
    }

    fn data_step(&self) -> Option<f64> {
        self.step
    }

    fn warnings(&self) -> Vec<String> {
        self.note.iter().cloned().collect()
    }

    fn describe(&self, _input: Option<&str>, _output: &str) -> Vec<String> {
        let mut lines = Vec::new();
        if let Some(c) = &self.accel_columns {
            lines.push(format!(
                "accelerometer from {} in the pipeline's accel_units",
                c.join(", ")
            ));
        }
        if let Some(c) = &self.mag_columns {
            lines.push(format!(
                "magnetometer from {} in {}, carried in tesla",
                c.join(", "),
                self.mag_units
            ));
        }
        if let (Some(c), Some(out)) = (&self.yaw_rate_column, &self.motion_output) {
            lines.push(format!(
                "motion out: {out} (StopSignal on the samples' clock: the yaw rate of {c}{})",
                self.yaw_rate_std_column
                    .as_ref()
                    .map_or(String::new(), |sd| format!(", its sd {sd}"))
            ));
        }
        lines
    }

    fn motion_output(&self) -> Option<&str> {
        self.motion_output.as_deref()
    }

    fn local_source(&self, cx: &Context) -> Result<Box<dyn Source>, String> {
        let (params, rate_hz) = (self.clone(), cx.rate_hz);
        let replay = BlockReplay::spawn("driftless-csv", self.replay, move |sink| {
            read_rows(&params, rate_hz, sink)
        })?;
        Ok(Box::new(replay))
    }
}

/// What `ingest.csv` replays, for a file that holds something else.
const CSV_TAKES: &str = "ingest.csv replays CSV text (gzip-compressed too); a recording or a \
ROS 2 bag (MCAP) is replayed by kind = \"ingest.mcap\"";

fn parse(t: &mut Table<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    let file_key = t.required_str(&FILE)?;
    let columns_key = t.get::<Vec<String>>(&COLUMNS)?;
    let accel_key = t.get::<Vec<String>>(&ACCEL_COLUMNS)?;
    let mag_key = t.get::<Vec<String>>(&MAG_COLUMNS)?;
    let mag_units_key = t.get::<String>(&MAG_UNITS)?;
    let time_key = t.get::<String>(&TIME_COLUMN)?;
    let stop_key = t.get::<String>(&STOP_COLUMN)?;
    let yaw_key = t.get::<String>(&YAW_RATE_COLUMN)?;
    let yaw_sd_key = t.get::<String>(&YAW_RATE_STD_COLUMN)?;
    let motion_key = t.get::<String>(&MOTION_OUTPUT)?;
    let replay = Replay::parse(t)?;
    let (src, axes, rate_hz) = (t.src, t.cx.axes, t.cx.rate_hz);
    let motion_output = match (&motion_key, &yaw_key) {
        (Some(k), None) => {
            return Err(src.span(
                k,
                "motion_output needs a yaw_rate_column (what it publishes)",
            ))
        }
        (None, Some(k)) => {
            return Err(src.span(
                k,
                "yaw_rate_column needs a motion_output (the service predict.bias's stop_input \
                 reads it from)",
            ))
        }
        (Some(k), Some(_)) => Some(src.service(k)?),
        (None, None) => None,
    };
    if let (Some(k), None) = (&yaw_sd_key, &yaw_key) {
        return Err(src.span(k, "yaw_rate_std_column needs a yaw_rate_column"));
    }
    let file = src.resolve(file_key.get_ref());
    if !file.exists() {
        return Err(src.span(&file_key, format!("no such file: {}", file.display())));
    }
    // By what it holds: the name is a hint.
    let sniffed = text_file(&file, CSV_TAKES).map_err(|e| src.span(&file_key, e.to_string()))?;
    let columns = columns_key.as_ref().map_or_else(
        || {
            // The default's first `axes` names, as its note says.
            let names = COLUMNS.default.words();
            names[..axes.min(names.len())]
                .iter()
                .map(|s| s.to_string())
                .collect()
        },
        |c| c.get_ref().clone(),
    );
    if let Some(c) = &columns_key {
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
    let accel_columns = three_columns(src, accel_key, ACCEL_COLUMNS.name)?;
    let mag_columns = three_columns(src, mag_key, MAG_COLUMNS.name)?;
    let mag_units = read_mag_units(src, mag_units_key, mag_columns.is_some())?;
    let mut params = CsvParams {
        file,
        columns,
        accel_columns,
        mag_columns,
        mag_units,
        time_column: time_key.as_ref().map(|t| t.get_ref().clone()),
        stop_column: stop_key.map(Spanned::into_inner),
        yaw_rate_column: yaw_key.map(Spanned::into_inner),
        yaw_rate_std_column: yaw_sd_key.map(Spanned::into_inner),
        motion_output,
        rad_per_unit: t.cx.units.to_rad_per_s(),
        step: None,
        replay,
        note: sniffed.csv_note(),
    };
    let layout = Layout::of(&params);
    let (times_ns, rates) = check_rows(
        src,
        &layout,
        &params.file,
        &file_key,
        time_key.as_ref(),
        axes,
    )?;
    // The file's own times must give the pipeline's rate, as a bag's stamps must.
    if let Some(t) = &time_key {
        check_time_rate(src, t, &params.file, &times_ns, rate_hz)?;
    }
    params.step = rates.into_iter().filter_map(step_of).reduce(f64::min);
    Ok(Box::new(params))
}

/// A sensor's column names (`accel_columns`, `mag_columns`): three (x, y, z), or none given.
fn three_columns(
    src: &Src<'_>,
    key: Option<Spanned<Vec<String>>>,
    name: &str,
) -> Result<Option<Vec<String>>, InputError> {
    match key {
        Some(k) if k.get_ref().len() != 3 => Err(src.span(
            &k,
            format!(
                "{name} must name 3 columns (x, y, z), got {}",
                k.get_ref().len()
            ),
        )),
        k => Ok(k.map(Spanned::into_inner)),
    }
}

/// `mag_units`, by [`MagUnit`]'s own names; its default without the key. Refused without
/// `mag_columns`: a unit for columns never named is a table that lost its columns.
fn read_mag_units(
    src: &Src<'_>,
    key: Option<Spanned<String>>,
    has_columns: bool,
) -> Result<MagUnit, InputError> {
    let Some(k) = key else {
        return Ok(MAG_UNITS.default.word().parse().unwrap_or_default());
    };
    if !has_columns {
        return Err(src.span(
            &k,
            "mag_units is the unit of mag_columns, which are not given: name the \
             magnetometer's three columns, or remove mag_units",
        ));
    }
    k.get_ref()
        .parse()
        .map_err(|e: String| src.span(&k, format!("mag_units: {e}")))
}

/// The header, and the first [`CHECKED_ROWS`] rows as the replay will read them (a wrong file
/// fails here): their times (ns, with a time column) and each axis' rates.
fn check_rows(
    src: &Src<'_>,
    layout: &Layout,
    file: &std::path::Path,
    file_key: &Spanned<String>,
    time_key: Option<&Spanned<String>>,
    axes: usize,
) -> Result<(Vec<i64>, Vec<Vec<f64>>), InputError> {
    let mut rows = layout.open(file)?;
    let mut values = vec![0.0; layout.wanted.len()];
    let mut n = 0;
    let mut times_ns: Vec<i64> = Vec::new();
    let mut rates: Vec<Vec<f64>> = vec![Vec::new(); axes];
    while n < CHECKED_ROWS {
        match rows.next_row(&mut values)? {
            RowRead::Row => {}
            RowRead::Bad(e) | RowRead::BadCells { error: e, .. } => return Err(e),
            RowRead::End => break,
        }
        n += 1;
        for (r, v) in rates.iter_mut().zip(&values) {
            r.push(*v);
        }
        if let (Some(t), Some(k)) = (time_key, layout.time) {
            if values[k] < 0.0 {
                return Err(src.span(
                    t,
                    format!("time column {:?} is negative at data row {n}", t.get_ref()),
                ));
            }
            times_ns.push((values[k] * 1e9).round() as i64);
        }
    }
    if n == 0 {
        return Err(src.span(file_key, format!("{} has no data rows", file.display())));
    }
    Ok((times_ns, rates))
}

/// The time column's rate over the checked rows against the pipeline's `rate_hz`.
fn check_time_rate(
    src: &Src<'_>,
    t: &Spanned<String>,
    file: &std::path::Path,
    times_ns: &[i64],
    rate: f64,
) -> Result<(), InputError> {
    let steps = Stamps::from_stamps(times_ns);
    match steps.rate_hz() {
        Some(hz) if (hz - rate).abs() <= RATE_TOLERANCE * rate => Ok(()),
        found => {
            let gives = found.map_or("no rate".to_string(), |hz| format!("{hz:.6} Hz"));
            Err(src.span(
                t,
                format!(
                    "time column {:?} of {}: its first {} rows step {} s at the median \
                     ({gives}), but the pipeline's rate_hz is {rate} Hz: set rate_hz to the \
                     file's rate",
                    t.get_ref(),
                    file.display(),
                    steps.count,
                    steps.median_interval_ns as f64 * 1e-9,
                ),
            ))
        }
    }
}

/// Where each column a replay reads sits in a row of values: the rates, then the
/// accelerometer, the magnetometer, the time, the stop, the yaw rate and its sd.
struct Layout {
    wanted: Vec<String>,
    accel: Option<usize>,
    mag: Option<usize>,
    time: Option<usize>,
    stop: Option<usize>,
    yaw: Option<usize>,
    yaw_sd: Option<usize>,
}

impl Layout {
    fn of(p: &CsvParams) -> Layout {
        let mut wanted = p.columns.clone();
        let mut at = |names: &[String]| {
            let i = wanted.len();
            wanted.extend_from_slice(names);
            i
        };
        let accel = p.accel_columns.as_deref().map(&mut at);
        let mag = p.mag_columns.as_deref().map(&mut at);
        let mut one = |name: &Option<String>| name.as_ref().map(|c| at(std::slice::from_ref(c)));
        let time = one(&p.time_column);
        let stop = one(&p.stop_column);
        let yaw = one(&p.yaw_rate_column);
        let yaw_sd = one(&p.yaw_rate_std_column);
        Layout {
            wanted,
            accel,
            mag,
            time,
            stop,
            yaw,
            yaw_sd,
        }
    }

    /// The columns whose empty or NaN cell is unknown, not bad: the stop, the yaw rate, its sd.
    fn sparse(&self) -> impl Iterator<Item = usize> {
        [self.stop, self.yaw, self.yaw_sd].into_iter().flatten()
    }

    /// Whether selected column `k` is read beside the rates (the accelerometer, the
    /// magnetometer, the stop, the yaw rate): a bad cell there leaves the row's rates good.
    fn beside_rates(&self, k: usize) -> bool {
        let within = |first: Option<usize>| first.is_some_and(|a| (a..a + 3).contains(&k));
        within(self.accel) || within(self.mag) || self.sparse().any(|s| s == k)
    }

    /// The rows of `file` in this layout: an empty or NaN cell in a sparse column is unknown,
    /// not a bad cell.
    fn open(&self, file: &std::path::Path) -> Result<RowReader, InputError> {
        Ok(self
            .sparse()
            .fold(RowReader::open(file, &self.wanted)?, RowReader::nan_unknown))
    }

    /// The odometry message logged on a row of `values` stamped `t_ns` (the samples' clock), if
    /// its yaw rate cell holds one; `rad_per_unit` converts from the input units.
    fn motion(&self, values: &[f64], t_ns: u64, rad_per_unit: f64) -> Option<StopSignal> {
        let yaw = values[self.yaw?];
        if !yaw.is_finite() {
            return None;
        }
        let mut s = StopSignal::new(t_ns, f64::NAN, u32::MAX);
        s.clock = STOP_CLOCK_SAMPLES;
        s.yaw_rate_rad_s = yaw * rad_per_unit;
        s.yaw_rate_std_rad_s = self
            .yaw_sd
            .map(|k| values[k])
            .filter(|sd| *sd > 0.0 && sd.is_finite())
            .map_or(f64::NAN, |sd| sd * rad_per_unit);
        Some(s)
    }
}

/// Three readings from `values[k..k + 3]` times `scale`, all NaN when one is not finite: the
/// sensor is there, its reading unknown, and the guard holds the last good one and flags it.
fn reading(values: &[f64], k: usize, scale: f64) -> [f64; 3] {
    let v: [f64; 3] = std::array::from_fn(|i| values[k + i] * scale);
    if v.iter().all(|x| x.is_finite()) {
        v
    } else {
        [f64::NAN; 3]
    }
}

/// A readable row's sample: its rates, its accelerometer and magnetometer (when the layout has
/// them; the field times `mag_to_t`, in tesla as a raw sample carries it) and its stop flag
/// (when it has a stop column and the cell is known).
fn fill_sample(
    sample: &mut RawSample,
    values: &[f64],
    layout: &Layout,
    axes: usize,
    mag_to_t: f64,
) {
    sample.rate[..axes].copy_from_slice(&values[..axes]);
    if let Some(k) = layout.accel {
        // In the pipeline's accel_units: the guard converts.
        sample.accel = reading(values, k, 1.0);
        sample.flags |= RAW_ACCEL;
    }
    if let Some(k) = layout.mag {
        sample.mag = reading(values, k, mag_to_t);
        sample.flags |= RAW_MAG;
    }
    match layout.stop.map(|k| values[k]) {
        Some(v) if v.is_nan() => {}
        Some(v) if v >= 0.5 => sample.flags |= RAW_VEHICLE_STOPPED,
        Some(_) => sample.flags |= RAW_VEHICLE_MOVING,
        None => {}
    }
}

/// An unreadable row's sample: marked invalid, its rates (and the sensors beside them)
/// unknown.
fn mark_invalid(sample: &mut RawSample, layout: &Layout) {
    sample.rate = [f64::NAN; 3];
    sample.flags = RAW_INVALID;
    // The sensors are still there, their readings unknown.
    if layout.accel.is_some() {
        sample.accel = [f64::NAN; 3];
        sample.flags |= RAW_ACCEL;
    }
    if layout.mag.is_some() {
        sample.mag = [f64::NAN; 3];
        sample.flags |= RAW_MAG;
    }
}

/// The warning for the first pass's `bad`th bad row (data row `i + 1`): the first
/// [`REPORTED_BAD_ROWS`] each with their position, then one line that more are not listed.
fn warn_bad_row(row: &RowRead, bad: u64, shown: &std::path::Display<'_>, i: u64) {
    if bad <= REPORTED_BAD_ROWS {
        let why = match row {
            RowRead::Bad(e) | RowRead::BadCells { error: e, .. } => e.to_string(),
            _ => format!("{shown}: data row {}: negative time", i + 1),
        };
        eprintln!("driftless: warning: {why} (replayed as an invalid sample: flagged)");
    }
    if bad == REPORTED_BAD_ROWS + 1 {
        eprintln!("driftless: warning: {shown}: more bad rows, flagged but not listed");
    }
}

/// The reader thread: the file's rows as raw samples (sequence numbers from 0 across loops,
/// timestamps increasing across loops), a bad row as a sample marked invalid with its position
/// on stderr. Ends at the end of the file (without `loop`), at a read error, or when the replay
/// is dropped.
fn read_rows(params: &CsvParams, rate_hz: f64, sink: &mut BlockSink) {
    let shown = params.file.display();
    let period_ns = (1e9 / rate_hz).round() as u64;
    let axes = params.columns.len().min(3);
    let mag_to_t = params.mag_units.to_tesla();
    let layout = Layout::of(params);
    let wanted = &layout.wanted;
    let mut values = vec![0.0; wanted.len()];
    let (mut seq, mut loop_offset_ns, mut bad, mut pass) = (0u64, 0u64, 0u64, 0u32);
    let mut beside_bad = 0u64;
    loop {
        let mut rows = match layout.open(&params.file) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("driftless: error: {e} (the replay ends here)");
                break;
            }
        };
        let (mut i, mut first_t, mut last_t) = (0u64, None::<u64>, 0u64);
        loop {
            let read = match rows.next_row(&mut values) {
                Ok(r) => r,
                Err(e) => {
                    eprintln!("driftless: error: {e} (the replay ends here)");
                    return;
                }
            };
            let mut sample = RawSample {
                t_ns: last_t,
                seq,
                rate: [0.0; 3],
                ..RawSample::default()
            };
            let time = match layout.time {
                Some(k) => values[k],
                None => i as f64 / rate_hz,
            };
            // A row whose bad cells are only beside the rates (the accelerometer, the
            // magnetometer, the stop, the odometry) keeps its rates: only what is unreadable
            // is flagged.
            let mut motion = None;
            let usable = match &read {
                RowRead::Row => true,
                RowRead::BadCells { bad, .. } => bad.iter().all(|&k| layout.beside_rates(k)),
                _ => false,
            };
            match read {
                RowRead::End => break,
                ref row if usable && time >= 0.0 => {
                    fill_sample(&mut sample, &values, &layout, axes, mag_to_t);
                    if let RowRead::BadCells { error, .. } = row {
                        if pass == 0 {
                            beside_bad += 1;
                            if beside_bad <= REPORTED_BAD_ROWS {
                                eprintln!(
                                    "driftless: warning: {error} (the rates kept; an \
                                     unreadable reading flagged, an odometry cell no message)"
                                );
                            }
                        }
                    }
                    sample.t_ns = if params.time_column.is_some() {
                        (time * 1e9).round() as u64
                    } else {
                        (i as f64 * 1e9 / rate_hz).round() as u64
                    };
                    motion =
                        layout.motion(&values, sample.t_ns + loop_offset_ns, params.rad_per_unit);
                }
                // Not dropped: the sample is replayed marked invalid (the guard holds the last
                // good rate, flags and counts it), its time held, its position on stderr.
                other => {
                    mark_invalid(&mut sample, &layout);
                    if pass == 0 {
                        bad += 1;
                        warn_bad_row(&other, bad, &shown, i);
                    }
                }
            }
            first_t.get_or_insert(sample.t_ns);
            last_t = sample.t_ns;
            sample.t_ns += loop_offset_ns;
            i += 1;
            seq += 1;
            if let Some(m) = motion {
                sink.push_motion(m);
            }
            if !sink.push(sample) {
                return;
            }
        }
        let Some(first_t) = first_t else { break };
        if !params.replay.looped {
            break;
        }
        loop_offset_ns += last_t.saturating_sub(first_t) + period_ns;
        pass = pass.saturating_add(1);
    }
    if bad > 0 {
        eprintln!("driftless: warning: {shown}: {bad} bad row(s) replayed as invalid samples");
    }
    if beside_bad > 0 {
        eprintln!(
            "driftless: warning: {shown}: {beside_bad} row(s) with an unreadable accelerometer, \
             magnetometer, stop or odometry cell: rates kept, each such cell flagged or no message"
        );
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::AtomicBool;

    use super::*;
    use crate::stages::contract::Poll;
    use crate::stages::schema::test_table;
    use crate::units::{AccelUnit, RateUnit};

    /// `ingest.csv`'s table `text`, its `file = "log.csv"` holding `csv` in a fresh folder
    /// (kept while the result lives), under a pipeline at 100 Hz with 3 axes.
    fn parse_csv(
        csv: &str,
        text: &str,
    ) -> (tempfile::TempDir, Result<Box<dyn Params>, InputError>) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("log.csv"), csv).unwrap();
        let path = dir.path().join("p.toml");
        let text = format!("file = \"log.csv\"\npace = \"asap\"\n{text}");
        let src = Src {
            path: &path,
            text: &text,
        };
        let mut t = test_table(&src, 3, None, ("p", "sensor"), |k| {
            KIND.keys
                .iter()
                .find(|key| key.name == k)
                .expect("a key")
                .name
        });
        let parsed = (KIND.parse)(&mut t);
        (dir, parsed)
    }

    /// The pipeline the tables are read under: 100 Hz, 3 axes, deg/s.
    fn context() -> Context {
        Context {
            rate_hz: 100.0,
            axes: 3,
            units: RateUnit::DegPerS,
            accel_units: AccelUnit::MPerS2,
            white_noise: None,
        }
    }

    /// Every raw sample the replay of `params` gives, in order.
    fn replay(params: &dyn Params) -> Vec<RawSample> {
        let cx = context();
        let mut source = params.local_source(&cx).unwrap();
        let stop = AtomicBool::new(false);
        let mut got = Vec::new();
        loop {
            match source.poll(&stop) {
                Poll::Sample(s, _, _) => got.push(s),
                Poll::Idle => {}
                Poll::End => return got,
            }
        }
    }

    /// Rows past the ones validation checks, so that a bad cell near the end is met replaying.
    const ROWS: usize = CHECKED_ROWS + 10;
    /// The row whose `my` cell is empty.
    const BAD: usize = CHECKED_ROWS + 5;

    /// The field of row `i` as logged: microtesla, or gauss with `per` = 100.
    fn field(i: usize, per: f64) -> [f64; 3] {
        [(20.0 + (i % 7) as f64) / per, -3.5 / per, -40.25 / per]
    }

    fn log(per: f64) -> String {
        let mut csv = String::from("x,y,z,mx,my,mz\n");
        for i in 0..ROWS {
            let [mx, my, mz] = field(i, per);
            let my = if i == BAD {
                String::new()
            } else {
                my.to_string()
            };
            csv.push_str(&format!("0.1,0.2,{},{mx},{my},{mz}\n", i as f64 * 1e-3));
        }
        csv
    }

    #[test]
    fn the_magnetometer_is_read_in_its_units_and_carried_in_tesla() {
        for (units, per, to_t) in [("uT", 1.0, 1e-6), ("gauss", 100.0, 1e-4)] {
            let keys = format!("mag_columns = [\"mx\", \"my\", \"mz\"]\nmag_units = \"{units}\"");
            let (_dir, params) = parse_csv(&log(per), &keys);
            let params = params.unwrap();
            assert_eq!(
                params.describe(None, "c/raw"),
                [format!(
                    "magnetometer from mx, my, mz in {units}, carried in tesla"
                )]
            );
            let got = replay(params.as_ref());
            assert_eq!(got.len(), ROWS, "{units}: every row replayed");
            for (i, s) in got.iter().enumerate() {
                assert_eq!(
                    s.flags, RAW_MAG,
                    "{units}: row {i}: the rates good, the field there"
                );
                assert_eq!(s.rate[2], i as f64 * 1e-3, "{units}: row {i}");
                if i == BAD {
                    // An empty cell: the sample kept, its reading unknown (the guard holds the
                    // last good one and flags it).
                    assert!(s.mag.iter().all(|v| v.is_nan()), "{:?}", s.mag);
                } else {
                    let want = field(i, per).map(|v| v * to_t);
                    assert_eq!(s.mag, want, "{units}: row {i}");
                }
            }
        }
    }

    #[test]
    fn a_gyro_only_log_carries_no_magnetometer() {
        let (_dir, params) = parse_csv(&log(1.0), "");
        let params = params.unwrap();
        assert!(params.describe(None, "c/raw").is_empty());
        let got = replay(params.as_ref());
        assert!(got
            .iter()
            .all(|s| s.mag_reading().is_none() && s.flags == 0));
    }

    #[test]
    fn the_magnetometer_keys_are_checked() {
        let refused = |csv: &str, keys: &str| {
            let (_dir, params) = parse_csv(csv, keys);
            match params {
                Ok(_) => panic!("{keys}: not refused"),
                Err(e) => e.to_string(),
            }
        };
        let csv = log(1.0);
        for (keys, want) in [
            (
                "mag_columns = [\"mx\", \"my\"]",
                "mag_columns must name 3 columns (x, y, z), got 2",
            ),
            (
                "mag_units = \"gauss\"",
                "mag_units is the unit of mag_columns, which are not given",
            ),
            (
                "mag_columns = [\"mx\", \"my\", \"mz\"]\nmag_units = \"mT\"",
                "mag_units: unknown magnetometer unit 'mT' (T, gauss or uT)",
            ),
            (
                "mag_columns = [\"mx\", \"my\", \"mw\"]",
                "no column named 'mw'",
            ),
        ] {
            let e = refused(&csv, keys);
            assert!(e.contains(want), "{keys}: {e}");
        }
        // A bad cell in the rows validation checks refuses the file, as a rate's does.
        let early = csv.replacen(",-40.25\n", ",nan\n", 3);
        let e = refused(&early, "mag_columns = [\"mx\", \"my\", \"mz\"]");
        assert!(e.contains("column 'mz'"), "{e}");
    }

    /// The odometry's yaw rate on row `i` (deg/s), logged on even rows only.
    fn wz(i: usize) -> f64 {
        5.0 + (i % 11) as f64 * 0.25
    }

    #[test]
    fn a_logged_yaw_rate_is_handed_out_after_its_rows_sample_in_rad_s() {
        // Odd rows: no message (empty, or `nan` on row 3); an unreadable cell past the checked
        // rows: the rates kept, no message.
        let mut csv = String::from("x,y,z,wz,wz_sd\n");
        for i in 0..ROWS {
            let (w, sd) = match i {
                3 => ("nan".into(), "nan".into()),
                BAD => ("fast".into(), "0.2".into()),
                _ if i % 2 == 1 => (String::new(), String::new()),
                _ => (
                    wz(i).to_string(),
                    if i % 4 == 0 { "0.2" } else { "0" }.into(),
                ),
            };
            csv += &format!("{i},0,0,{w},{sd}\n");
        }
        let keys = "yaw_rate_column = \"wz\"\nyaw_rate_std_column = \"wz_sd\"\n\
                    motion_output = \"vehicle/stop\"";
        let (_dir, params) = parse_csv(&csv, keys);
        let params = params.unwrap();
        assert_eq!(params.motion_output(), Some("vehicle/stop"));
        let cx = context();
        let mut source = params.local_source(&cx).unwrap();
        let (stop, mut samples, mut motion) = (AtomicBool::new(false), Vec::new(), Vec::new());
        loop {
            match source.poll(&stop) {
                Poll::Sample(s, ..) => {
                    samples.push(s);
                    // Asked after every sample, as the runtime does.
                    while let Some(m) = source.logged_motion() {
                        motion.push((samples.len() - 1, m));
                    }
                }
                Poll::Idle => {}
                Poll::End => break,
            }
        }
        assert_eq!(samples.len(), ROWS);
        for (i, s) in samples.iter().enumerate() {
            assert_eq!((s.rate[0], s.flags), (i as f64, 0), "row {i}");
        }
        let rows: Vec<usize> = motion.iter().map(|(row, _)| *row).collect();
        assert_eq!(rows, (0..ROWS).step_by(2).collect::<Vec<_>>());
        for (row, m) in motion {
            assert_eq!((m.t_ns, m.clock), (samples[row].t_ns, STOP_CLOCK_SAMPLES));
            assert!(
                (m.yaw_rate_rad_s - wz(row).to_radians()).abs() < 1e-15,
                "row {row}"
            );
            let sd = m.yaw_rate_std_rad_s;
            match row % 4 {
                0 => assert!((sd - 0.2f64.to_radians()).abs() < 1e-15, "row {row}: {sd}"),
                _ => assert!(sd.is_nan(), "row {row}: a sd of 0 says nothing, got {sd}"),
            }
            assert!(m.speed_m_s.is_nan() && m.stopped == u32::MAX);
        }
    }

    #[test]
    fn the_yaw_rate_keys_come_together() {
        let csv = "x,y,z,wz,sd\n1,2,3,4,0.1\n";
        for (keys, want) in [
            (
                "motion_output = \"vehicle/stop\"",
                "motion_output needs a yaw_rate_column",
            ),
            (
                "yaw_rate_column = \"wz\"",
                "yaw_rate_column needs a motion_output",
            ),
            (
                "yaw_rate_std_column = \"sd\"",
                "yaw_rate_std_column needs a yaw_rate_column",
            ),
            (
                "yaw_rate_column = \"yaw\"\nmotion_output = \"vehicle/stop\"",
                "no column named 'yaw'",
            ),
        ] {
            let (_dir, params) = parse_csv(csv, keys);
            let e = params.err().map(|e| e.to_string()).unwrap_or_default();
            assert!(e.contains(want), "{keys}: {e}");
        }
        let (_dir, params) = parse_csv(csv, "yaw_rate_column = \"wz\"\nmotion_output = \"v/s\"");
        let lines = params.unwrap().describe(None, "c/raw");
        assert_eq!(
            lines,
            ["motion out: v/s (StopSignal on the samples' clock: the yaw rate of wz)"]
        );
    }
}
