//! `ingest.csv`: replay a CSV file at its own rate, a factor faster or as fast as possible,
//! optionally looping.
//! Sequence numbers count from 0 across loops; timestamps keep increasing.
//!
//! Validation reads the header and the first [`CHECKED_ROWS`] rows (a wrong file fails there with
//! file:line:col); the run streams the file from a reader thread in blocks of samples, so memory
//! stays bounded however long the log. A bad row found while replaying is not dropped: it is
//! replayed as a sample marked invalid (the guard holds the last good rate, flags and counts it)
//! and its file:line:col is printed on stderr. A row whose only bad cells are the accelerometer's
//! or the stop's keeps its rates: only the unreadable reading is flagged.
//!
//! ```toml
//! [[stage]]
//! name = "sensor"
//! kind = "ingest.csv"
//! output = "replay/raw"
//! file = "data/replay.csv"       # relative to the pipeline file; gzip-compressed works
//! columns = ["x", "y", "z"]      # one per axis (default x, y, z)
//! accel_columns = ["ax", "ay", "az"]  # the accelerometer, in accel_units (default: none)
//! time_column = "t"              # seconds (default: i / rate_hz)
//! stop_column = "stopped"        # 1 stands, 0 moves, nan unknown (default: none)
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
use crate::stages::schema::{Context, DefaultValue, Key, Table, Type};
use crate::wire::{RawSample, RAW_ACCEL, RAW_INVALID, RAW_VEHICLE_MOVING, RAW_VEHICLE_STOPPED};

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
        TIME_COLUMN,
        STOP_COLUMN,
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
    /// The time column (seconds), if any; else `t = i / rate_hz`.
    pub time_column: Option<String>,
    /// The stop column (1 stands, 0 moves, NaN unknown), if any.
    pub stop_column: Option<String>,
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
    let time_key = t.get::<String>(&TIME_COLUMN)?;
    let stop_key = t.get::<String>(&STOP_COLUMN)?;
    let replay = Replay::parse(t)?;
    let (src, axes, rate_hz) = (t.src, t.cx.axes, t.cx.rate_hz);
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
    if let Some(a) = &accel_key {
        if a.get_ref().len() != 3 {
            return Err(src.span(
                a,
                format!(
                    "accel_columns must name 3 columns (x, y, z), got {}",
                    a.get_ref().len()
                ),
            ));
        }
    }
    let accel_columns = accel_key.map(Spanned::into_inner);
    let time_column = time_key.as_ref().map(|t| t.get_ref().clone());
    let stop_column = stop_key.map(Spanned::into_inner);
    let layout = Layout::of(&columns, &accel_columns, &time_column, &stop_column);
    let at_time = columns.len() + accel_columns.as_ref().map_or(0, Vec::len);
    // The header, and the first rows as the replay will read them: a wrong file fails here.
    let mut rows = layout.open(&file)?;
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
        if let Some(t) = &time_key {
            if values[at_time] < 0.0 {
                return Err(src.span(
                    t,
                    format!("time column {:?} is negative at data row {n}", t.get_ref()),
                ));
            }
            times_ns.push((values[at_time] * 1e9).round() as i64);
        }
    }
    if n == 0 {
        return Err(src.span(&file_key, format!("{} has no data rows", file.display())));
    }
    // The file's own times must give the pipeline's rate, as a bag's stamps must.
    if let Some(t) = &time_key {
        let steps = Stamps::from_stamps(&times_ns);
        let rate = rate_hz;
        match steps.rate_hz() {
            Some(hz) if (hz - rate).abs() <= RATE_TOLERANCE * rate => {}
            found => {
                let gives = found.map_or("no rate".to_string(), |hz| format!("{hz:.6} Hz"));
                return Err(src.span(
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
                ));
            }
        }
    }
    Ok(Box::new(CsvParams {
        file,
        columns,
        accel_columns,
        time_column,
        stop_column,
        step: rates.into_iter().filter_map(step_of).reduce(f64::min),
        replay,
        note: sniffed.csv_note(),
    }))
}

/// Where each column a replay reads sits in a row of values: the rates, then the
/// accelerometer, the time and the stop.
struct Layout {
    wanted: Vec<String>,
    accel: Option<usize>,
    time: Option<usize>,
    stop: Option<usize>,
}

impl Layout {
    fn of(
        columns: &[String],
        accel: &Option<Vec<String>>,
        time: &Option<String>,
        stop: &Option<String>,
    ) -> Layout {
        let mut wanted = columns.to_vec();
        let mut at = |names: &[String]| {
            let i = wanted.len();
            wanted.extend_from_slice(names);
            i
        };
        let accel = accel.as_deref().map(&mut at);
        let time = time.as_ref().map(|t| at(std::slice::from_ref(t)));
        let stop = stop.as_ref().map(|s| at(std::slice::from_ref(s)));
        Layout {
            wanted,
            accel,
            time,
            stop,
        }
    }

    /// The rows of `file` in this layout: a NaN in the stop column is unknown, not a bad cell.
    fn open(&self, file: &std::path::Path) -> Result<RowReader, InputError> {
        let rows = RowReader::open(file, &self.wanted)?;
        Ok(match self.stop {
            Some(k) => rows.nan_unknown(k),
            None => rows,
        })
    }
}

/// A readable row's sample: its rates, its accelerometer (when the layout has one) and its
/// stop flag (when it has a stop column and the cell is known).
fn fill_sample(sample: &mut RawSample, values: &[f64], layout: &Layout, axes: usize) {
    sample.rate[..axes].copy_from_slice(&values[..axes]);
    if let Some(k) = layout.accel {
        sample.accel.copy_from_slice(&values[k..k + 3]);
        if sample.accel.iter().any(|v| !v.is_finite()) {
            // The accelerometer is there, its reading unknown: the guard holds
            // the last good one and flags it.
            sample.accel = [f64::NAN; 3];
        }
        sample.flags |= RAW_ACCEL;
    }
    match layout.stop.map(|k| values[k]) {
        Some(v) if v.is_nan() => {}
        Some(v) if v >= 0.5 => sample.flags |= RAW_VEHICLE_STOPPED,
        Some(_) => sample.flags |= RAW_VEHICLE_MOVING,
        None => {}
    }
}

/// An unreadable row's sample: marked invalid, its rates (and accelerometer) unknown.
fn mark_invalid(sample: &mut RawSample, layout: &Layout) {
    sample.rate = [f64::NAN; 3];
    sample.flags = RAW_INVALID;
    if layout.accel.is_some() {
        // The accelerometer is still there, its reading unknown.
        sample.accel = [f64::NAN; 3];
        sample.flags |= RAW_ACCEL;
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
    let layout = Layout::of(
        &params.columns,
        &params.accel_columns,
        &params.time_column,
        &params.stop_column,
    );
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
            // A row whose bad cells are only beside the rates (the accelerometer, the stop)
            // keeps its rates: only what is unreadable is flagged.
            let beside = |k: usize| {
                layout.accel.is_some_and(|a| (a..a + 3).contains(&k)) || layout.stop == Some(k)
            };
            let usable = match &read {
                RowRead::Row => true,
                RowRead::BadCells { bad, .. } => bad.iter().all(|&k| beside(k)),
                _ => false,
            };
            match read {
                RowRead::End => break,
                ref row if usable && time >= 0.0 => {
                    fill_sample(&mut sample, &values, &layout, axes);
                    if let RowRead::BadCells { error, .. } = row {
                        if pass == 0 {
                            beside_bad += 1;
                            if beside_bad <= REPORTED_BAD_ROWS {
                                eprintln!(
                                    "driftless: warning: {error} (the rates kept; the \
                                     unreadable cells flagged)"
                                );
                            }
                        }
                    }
                    sample.t_ns = if params.time_column.is_some() {
                        (time * 1e9).round() as u64
                    } else {
                        (i as f64 * 1e9 / rate_hz).round() as u64
                    };
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
            "driftless: warning: {shown}: {beside_bad} row(s) with an unreadable accelerometer \
             or stop cell: rates kept, the cell flagged"
        );
    }
}
