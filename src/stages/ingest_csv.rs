//! `ingest.csv`: replay a CSV file (loaded at validation) at its own rate or as fast as possible,
//! optionally looping. Sequence numbers count from 0 across loops; timestamps keep increasing.
//!
//! ```toml
//! [[stage]]
//! name = "sensor"
//! kind = "ingest.csv"
//! output = "replay/raw"
//! file = "data/replay.csv"       # relative to the pipeline file; .gz works
//! columns = ["x", "y", "z"]      # one per axis (default x, y, z)
//! time_column = "t"              # seconds (default: i / rate_hz)
//! pace = "asap"                  # or "realtime" (default)
//! loop = false
//! ```

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use toml::Spanned;

use crate::io::InputError;
use crate::pipeline::schema::{Context, Key, StageTable, Type};
use crate::pipeline::stage::{Kind, Params, Poll, Role, Source};
use crate::transport::{monotonic_ns, RawSample};

const FILE: Key = Key {
    name: "file",
    ty: Type::Str("a CSV file, relative to the pipeline file; .gz works"),
    default: "required",
    doc: "the log to replay; read and checked at validation",
};
const COLUMNS: Key = Key {
    name: "columns",
    ty: Type::StrList("one column name per axis"),
    default: "[\"x\", \"y\", \"z\"] (first `axes`)",
    doc: "the rate columns",
};
const TIME_COLUMN: Key = Key {
    name: "time_column",
    ty: Type::Str("a column name; seconds, not negative"),
    default: "none (i / rate_hz)",
    doc: "sensor timestamps",
};
const PACE: Key = Key {
    name: "pace",
    ty: Type::Choice(&["realtime", "asap"]),
    default: "\"realtime\"",
    doc: "at the file's rate, or as fast as possible",
};
const LOOP: Key = Key {
    name: "loop",
    ty: Type::Bool,
    default: "false",
    doc: "replay again from the start at the end of the file",
};

/// `ingest.csv`.
pub const KIND: Kind = Kind {
    name: "ingest.csv",
    role: Role::Ingest { has_input: false },
    summary: "a CSV log replayed at its rate or as fast as possible, optionally looping",
    keys: &[FILE, COLUMNS, TIME_COLUMN, PACE, LOOP],
    parse,
};

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

impl Params for CsvParams {
    fn source(
        &self,
        cx: &Context,
        _transport: &crate::transport::Transport,
        _input: Option<&str>,
    ) -> Result<Box<dyn Source>, String> {
        Ok(Box::new(CsvReplay::new(self.clone(), cx.rate_hz)))
    }
}

fn parse(t: &mut StageTable<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    let file_key = t.required_str(&FILE)?;
    let columns_key = t.get::<Vec<String>>(&COLUMNS)?;
    let time_key = t.get::<String>(&TIME_COLUMN)?;
    let pace = t.choice(&PACE, "pace", true)?;
    let looped = t.get::<bool>(&LOOP)?.is_some_and(Spanned::into_inner);
    let (src, rate_hz, axes) = (t.src, t.cx.rate_hz, t.cx.axes);
    let file = src.resolve(file_key.get_ref());
    if !file.is_file() {
        return Err(src.span(&file_key, format!("no such file: {}", file.display())));
    }
    let default_cols: Vec<String> = ["x", "y", "z"][..axes]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let columns = columns_key
        .as_ref()
        .map_or(default_cols, |c| c.get_ref().clone());
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
    let mut wanted = columns.clone();
    if let Some(t) = &time_key {
        wanted.push(t.get_ref().clone());
    }
    let table = crate::io::read_table(&file, &wanted)?;
    let mut cols = Vec::with_capacity(axes);
    for name in &columns {
        match table.column(name) {
            Some(c) => cols.push(c),
            None => {
                let at = columns_key
                    .as_ref()
                    .map_or(file_key.span().start, |c| c.span().start);
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
        return Err(src.span(&file_key, format!("{} has no data rows", file.display())));
    }
    let mut rates = vec![[0.0; 3]; n];
    for (axis, col) in cols.iter().enumerate() {
        for (row, v) in col.iter().enumerate() {
            rates[row][axis] = *v;
        }
    }
    let t_ns: Vec<u64> = match &time_key {
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
    let pace = match pace.as_deref() {
        Some("asap") => Pace::Asap,
        _ => Pace::Realtime,
    };
    Ok(Box::new(CsvParams {
        file,
        t_ns,
        rates,
        pace,
        looped,
    }))
}

/// A CSV replay.
pub struct CsvReplay {
    params: CsvParams,
    next: usize,
    seq: u64,
    loop_offset_ns: u64,
    period_ns: u64,
    start: Option<(Instant, u64)>,
}

impl CsvReplay {
    /// A replay of validated parameters at `rate_hz` (used for the loop seam).
    pub fn new(params: CsvParams, rate_hz: f64) -> Self {
        CsvReplay {
            params,
            next: 0,
            seq: 0,
            loop_offset_ns: 0,
            period_ns: (1e9 / rate_hz).round() as u64,
            start: None,
        }
    }
}

impl Source for CsvReplay {
    fn poll(&mut self, stop: &AtomicBool) -> Poll {
        if self.next == self.params.rates.len() {
            if !self.params.looped {
                return Poll::End;
            }
            let first = self.params.t_ns[0];
            let last = self.params.t_ns[self.params.t_ns.len() - 1];
            self.loop_offset_ns += last.saturating_sub(first) + self.period_ns;
            self.next = 0;
        }
        let t_ns = self.params.t_ns[self.next] + self.loop_offset_ns;
        if self.params.pace == Pace::Realtime {
            let (t0, first_t) = *self.start.get_or_insert((Instant::now(), t_ns));
            let due = t0 + Duration::from_nanos(t_ns.saturating_sub(first_t));
            if !crate::stages::sleep_until(due, stop) {
                return Poll::Idle;
            }
        }
        let sample = RawSample {
            t_ns,
            seq: self.seq,
            rate: self.params.rates[self.next],
            flags: 0,
            epoch: 0,
        };
        self.next += 1;
        self.seq += 1;
        Poll::Sample(sample, monotonic_ns())
    }
}
