//! Numeric CSV tables: read named columns with file/line/column errors, write them back atomically.
//!
//! A first row in which every cell is a number is data (the columns are then named `c0`, `c1`, ...);
//! otherwise it is the header. NaN and Inf cells are errors: a sample is never silently altered
//! (but a [`RowReader`] column whose NaN means "unknown", a replay's stop column, takes it so).
//! A gzip-compressed file is decompressed on the fly, whatever its name
//! ([`crate::io::content`]: its content decides, not its `.gz`).

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use super::csv_fast;
use super::error::InputError;

/// File size from which reading shows a progress bar: about 10^6 rows of a 3-axis log as text
/// (24 bytes a row); gzip packs such logs 4:1 to 8:1 (the real ADIS16405 log: 8:1).
const PROGRESS_MIN_BYTES: u64 = 24_000_000;
const PROGRESS_MIN_BYTES_GZ: u64 = PROGRESS_MIN_BYTES / 8;

/// Column names taken for time stamps, not signals: left out when no column is named.
pub const TIME_COLUMNS: [&str; 5] = ["t", "t_s", "time", "time_s", "timestamp"];

/// Numeric columns read from a CSV file.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// The file it came from.
    pub path: PathBuf,
    /// Column names, from the header or `c0`, `c1`, ...
    pub names: Vec<String>,
    /// One vector per selected column, all of equal length.
    pub columns: Vec<Vec<f64>>,
    /// Whether the file had a header row.
    pub has_header: bool,
    /// The file's time column, when it was asked for ([`read_table_keeping_time`]) and is not
    /// among the selected columns.
    pub time: Option<TimeColumn>,
}

/// A time column carried through unchanged: its cells as the file wrote them.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeColumn {
    /// Its name (one of [`TIME_COLUMNS`]).
    pub name: String,
    /// Where it goes among the selected columns to keep the file's order: the number of selected
    /// columns before it in the file.
    pub position: usize,
    /// Its cells, verbatim.
    pub cells: Vec<String>,
}

impl Table {
    /// Number of data rows.
    pub fn rows(&self) -> usize {
        self.columns.first().map_or(0, Vec::len)
    }

    /// The column named `name`.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.names
            .iter()
            .position(|n| n == name)
            .map(|i| self.columns[i].as_slice())
    }
}

/// The reference reading of a cell: `str::parse::<f64>` of its trimmed text.
pub(crate) fn parse_cell(cell: &[u8]) -> Option<f64> {
    std::str::from_utf8(cell).ok()?.trim().parse::<f64>().ok()
}

/// 1-based character column of field `i` in a record read without quoting surprises.
pub(crate) fn field_column(record: &csv::ByteRecord, i: usize) -> u64 {
    let start = record.range(i).map_or(0, |r| r.start);
    (start + i + 1) as u64
}

/// Read the named columns of a CSV file; when `wanted` is empty, every numeric column but a time
/// column ([`TIME_COLUMNS`]).
pub fn read_table(path: &Path, wanted: &[String]) -> Result<Table, InputError> {
    read_table_impl(path, wanted, false)
}

/// [`read_table`] through the reference path only (the csv crate and `str::parse::<f64>` on
/// every row, as before the fast path): for benchmarks and comparisons.
#[doc(hidden)]
pub fn read_table_reference(path: &Path, wanted: &[String]) -> Result<Table, InputError> {
    let file = File::open(path).map_err(|source| InputError::Io {
        path: path.display().to_string(),
        source,
    })?;
    let raw = BufReader::with_capacity(1 << 20, file);
    read_reference(raw, gzipped(path)?, path, wanted, false)
}

/// The reference path over an opened file, decompressed when `gz`.
fn read_reference<R: std::io::BufRead>(
    raw: R,
    gz: bool,
    path: &Path,
    wanted: &[String],
    keep_time: bool,
) -> Result<Table, InputError> {
    if gz {
        let mut decoder = flate2::bufread::MultiGzDecoder::new(raw);
        let result = read_from(&mut decoder, path, wanted, keep_time);
        // A corrupt stream yields garbage before its checksum fails: a fault found in what it
        // yielded is reported as the corruption (the fast path's reader thread, running ahead,
        // may meet the corruption first: both say the same).
        if matches!(result, Err(InputError::At { .. } | InputError::File { .. })) {
            if let Err(source) = std::io::copy(&mut decoder, &mut std::io::sink()) {
                return Err(InputError::Io {
                    path: path.display().to_string(),
                    source,
                });
            }
        }
        result
    } else {
        read_from(raw, path, wanted, keep_time)
    }
}

/// [`read_table`], and the file's time column (the first header named one of [`TIME_COLUMNS`]
/// that is not selected) kept verbatim in [`Table::time`], for outputs that carry it through.
pub fn read_table_keeping_time(path: &Path, wanted: &[String]) -> Result<Table, InputError> {
    read_table_impl(path, wanted, true)
}

fn read_table_impl(path: &Path, wanted: &[String], keep_time: bool) -> Result<Table, InputError> {
    let shown = path.display().to_string();
    let io_err = |source| InputError::Io {
        path: shown.clone(),
        source,
    };
    let file = File::open(path).map_err(io_err)?;
    let meta = file.metadata().map_err(io_err)?;
    let size = meta.len();
    let gz = gzipped(path)?;
    let min = if gz {
        PROGRESS_MIN_BYTES_GZ
    } else {
        PROGRESS_MIN_BYTES
    };
    let progress = crate::io::progress::bar(size, min, "reading");
    let result = if !gz && meta.is_file() && size > 0 {
        // SAFETY: the map is only read, and dropped before this function returns. Like any
        // reader of a file, it sees whatever another process writes into the file meanwhile;
        // truncating it under us would fault (SIGBUS): input logs are not written while read.
        match unsafe { memmap2::Mmap::map(&file) } {
            Ok(map) => read_mapped(&map, path, wanted, keep_time, &progress),
            Err(_) => read_streamed(path, file, false, wanted, keep_time, &progress),
        }
    } else {
        read_streamed(path, file, gz, wanted, keep_time, &progress)
    };
    progress.finish_and_clear();
    result
}

/// Whether `path` is read through a gzip decoder: by its content ([`super::content::sniff`]).
fn gzipped(path: &Path) -> Result<bool, InputError> {
    Ok(super::content::sniff(path)?.is_gzip())
}

/// Threads parsing a mapped file: every core, but only for files worth splitting.
fn parse_threads(bytes: usize) -> usize {
    if bytes < 4 << 20 {
        1
    } else {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    }
}

/// The fields of a row as the fast path reads them.
fn field_plan(head: &Head) -> Vec<csv_fast::Field> {
    (0..head.fields)
        .map(|i| match head.selected.iter().position(|&s| s == i) {
            Some(k) => csv_fast::Field::Value(k),
            None if head.time_index == Some(i) => csv_fast::Field::Time,
            None => csv_fast::Field::Skip,
        })
        .collect()
}

/// A memory-mapped plain file: the header by the csv crate, the rows by the fast path in
/// parallel chunks; anything the fast path does not take exactly goes through the reference.
fn read_mapped(
    bytes: &[u8],
    path: &Path,
    wanted: &[String],
    keep_time: bool,
    progress: &indicatif::ProgressBar,
) -> Result<Table, InputError> {
    let inc = |n: u64| progress.inc(n);
    match fast_mapped(bytes, path, wanted, keep_time, &inc)? {
        Some(table) => Ok(table),
        None => {
            progress.set_position(0);
            read_from(bytes, path, wanted, keep_time)
        }
    }
}

/// The fast path over mapped bytes; `None` when it cannot read them exactly like the reference.
fn fast_mapped(
    bytes: &[u8],
    path: &Path,
    wanted: &[String],
    keep_time: bool,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Option<Table>, InputError> {
    let mut rdr = csv_reader(bytes);
    // A head that does not read is reported by the reference path (CRLF-aware line numbers).
    let Ok(head) = read_head(&mut rdr, path, wanted, keep_time) else {
        return Ok(None);
    };
    let fields = field_plan(&head);
    let data = &bytes[head.data_offset.min(bytes.len())..];
    let threads = parse_threads(data.len());
    match csv_fast::parse_parallel(
        data,
        &fields,
        head.selected.len(),
        threads,
        8 << 20,
        progress,
    ) {
        Ok(rows) if rows.len() > 0 => Ok(Some(head.into_table(path, rows))),
        _ => Ok(None),
    }
}

/// A stream (gzip, or a file that cannot be mapped): a reader thread reads (and decompresses)
/// blocks while this thread parses them; anything the fast path does not take exactly is read
/// again from the start through the reference path.
fn read_streamed(
    path: &Path,
    file: File,
    gz: bool,
    wanted: &[String],
    keep_time: bool,
    progress: &indicatif::ProgressBar,
) -> Result<Table, InputError> {
    let shown = path.display().to_string();
    let raw = BufReader::with_capacity(1 << 20, progress.wrap_read(file));
    let source: Box<dyn Read + Send> = if gz {
        Box::new(flate2::bufread::MultiGzDecoder::new(raw))
    } else {
        Box::new(raw)
    };
    let fast = std::thread::scope(|s| -> Result<Option<Table>, InputError> {
        let blocks = csv_fast::Blocks::spawn(s, source);
        let mut recording = csv_fast::Recording::new(&blocks);
        let mut rdr = csv_reader(&mut recording);
        let head = read_head(&mut rdr, path, wanted, keep_time);
        drop(rdr);
        if let Some(source) = recording.error.take() {
            return Err(InputError::Io {
                path: shown.clone(),
                source,
            });
        }
        // A head that does not read is reported by the reference path (CRLF-aware lines).
        let Ok(head) = head else {
            return Ok(None);
        };
        let fields = field_plan(&head);
        let first = &recording.seen[head.data_offset.min(recording.seen.len())..];
        match csv_fast::parse_stream(first, &blocks, &fields, head.selected.len()) {
            Ok(Ok(rows)) if rows.len() > 0 => Ok(Some(head.into_table(path, rows))),
            Ok(Ok(_)) | Err(csv_fast::Bail) => Ok(None),
            Ok(Err(source)) => Err(InputError::Io {
                path: shown.clone(),
                source,
            }),
        }
    })?;
    if let Some(table) = fast {
        return Ok(table);
    }
    // The reference path, from the start.
    let io_err = |source| InputError::Io {
        path: shown.clone(),
        source,
    };
    let file = File::open(path).map_err(io_err)?;
    progress.set_position(0);
    let raw = BufReader::with_capacity(1 << 20, progress.wrap_read(file));
    read_reference(raw, gz, path, wanted, keep_time)
}

pub(crate) fn csv_error(path: &Path, e: csv::Error) -> InputError {
    let shown = path.display().to_string();
    let line = e.position().map(|p| p.line());
    match (e.kind(), line) {
        (
            csv::ErrorKind::UnequalLengths {
                expected_len, len, ..
            },
            Some(line),
        ) => InputError::At {
            path: shown,
            line,
            column: 1,
            message: format!("this row has {len} fields, the first row has {expected_len}"),
        },
        (csv::ErrorKind::Utf8 { .. }, Some(line)) => InputError::At {
            path: shown,
            line,
            column: 1,
            message: "this row is not valid UTF-8".into(),
        },
        _ => InputError::File {
            path: shown,
            message: e.to_string(),
        },
    }
}

/// The csv crate as every reader here uses it (the reference for the fast path).
fn csv_reader<R: Read>(reader: R) -> csv::Reader<R> {
    csv::ReaderBuilder::new()
        .has_headers(false)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(reader)
}

/// What the header and the first data row tell about a file.
pub(crate) struct Head {
    /// Column names, from the header or `c0`, `c1`, ...
    pub names: Vec<String>,
    /// Whether the first row is a header.
    pub has_header: bool,
    /// Fields per row.
    pub fields: usize,
    /// The selected columns' field indices, in output order.
    pub selected: Vec<usize>,
    /// The kept time column's field index.
    pub time_index: Option<usize>,
    /// The first data row.
    pub first: csv::ByteRecord,
    /// Where the data rows start in the input: after the header, else 0.
    pub data_offset: usize,
}

impl Head {
    fn into_table(self, path: &Path, rows: csv_fast::Rows) -> Table {
        let Head {
            names,
            has_header,
            selected,
            time_index,
            ..
        } = self;
        Table {
            path: path.to_path_buf(),
            names: selected.iter().map(|&i| names[i].clone()).collect(),
            columns: rows.columns,
            has_header,
            time: time_index.map(|t| TimeColumn {
                name: names[t].clone(),
                position: selected.iter().filter(|&&i| i < t).count(),
                cells: rows.time,
            }),
        }
    }
}

/// Read the header (if any) and the first data row, and choose the columns: `wanted`, or when
/// it is empty every numeric column but a time column.
pub(crate) fn read_head<R: Read>(
    rdr: &mut csv::Reader<R>,
    path: &Path,
    wanted: &[String],
    keep_time: bool,
) -> Result<Head, InputError> {
    let mut record = csv::ByteRecord::new();
    if !rdr
        .read_byte_record(&mut record)
        .map_err(|e| csv_error(path, e))?
    {
        return Err(InputError::file(path, "the file is empty"));
    }
    let has_header = record.iter().any(|c| parse_cell(c).is_none());
    let data_offset = if has_header {
        rdr.position().byte() as usize
    } else {
        0
    };
    let names: Vec<String> = if has_header {
        record
            .iter()
            .map(|c| String::from_utf8_lossy(c).trim().to_string())
            .collect()
    } else {
        (0..record.len()).map(|i| format!("c{i}")).collect()
    };
    let mut first = record.clone();
    if has_header
        && !rdr
            .read_byte_record(&mut first)
            .map_err(|e| csv_error(path, e))?
    {
        return Err(InputError::file(
            path,
            "the file has a header but no data rows",
        ));
    }
    let selected: Vec<usize> = if wanted.is_empty() {
        let numeric: Vec<usize> = (0..first.len())
            .filter(|&i| parse_cell(&first[i]).is_some())
            .collect();
        if numeric.is_empty() {
            return Err(InputError::file(
                path,
                "no numeric column in the first data row",
            ));
        }
        // A time column (as `driftless simulate` writes) is not a signal, unless it is all there is.
        let signals: Vec<usize> = numeric
            .iter()
            .copied()
            .filter(|&i| !TIME_COLUMNS.contains(&names[i].as_str()))
            .collect();
        if signals.is_empty() {
            numeric
        } else {
            signals
        }
    } else {
        wanted
            .iter()
            .map(|w| {
                names.iter().position(|n| n == w).ok_or_else(|| {
                    InputError::file(
                        path,
                        format!("no column named '{w}' (columns: {})", names.join(", ")),
                    )
                })
            })
            .collect::<Result<_, _>>()?
    };
    let time_index = names.iter().enumerate().position(|(i, n)| {
        keep_time && has_header && TIME_COLUMNS.contains(&n.as_str()) && !selected.contains(&i)
    });
    Ok(Head {
        fields: record.len(),
        names,
        has_header,
        selected,
        time_index,
        first,
        data_offset,
    })
}

/// A data row's selected cells as numbers, or the positioned error of the first bad one.
pub(crate) fn check_row(
    row: &csv::ByteRecord,
    path: &Path,
    names: &[String],
    selected: &[usize],
    mut out: impl FnMut(usize, f64),
) -> Result<(), InputError> {
    for (k, &i) in selected.iter().enumerate() {
        out(k, check_cell(row, path, names, i)?);
    }
    Ok(())
}

/// Cell `i` of a data row as a finite number, or its positioned error.
fn check_cell(
    row: &csv::ByteRecord,
    path: &Path,
    names: &[String],
    i: usize,
) -> Result<f64, InputError> {
    let cell = &row[i];
    let at = |message: String| InputError::At {
        path: path.display().to_string(),
        line: row.position().map_or(0, |p| p.line()),
        column: field_column(row, i),
        message,
    };
    match parse_cell(cell) {
        Some(v) if v.is_finite() => Ok(v),
        Some(v) => Err(at(format!(
            "column '{}': {v} is not a finite sample",
            names[i]
        ))),
        None => Err(at(format!(
            "column '{}': '{}' is not a number",
            names[i],
            String::from_utf8_lossy(cell)
        ))),
    }
}

/// Whether a cell says "not known": empty, or NaN (any spelling `str::parse::<f64>` takes:
/// `nan`, `NaN`, `-nan`).
fn nan_cell(cell: &[u8]) -> bool {
    cell.trim_ascii().is_empty() || parse_cell(cell).is_some_and(f64::is_nan)
}

/// Reads `inner` with every `\r\n` turned into `\n`, so that the csv crate counts lines right
/// in CRLF files: it counts a line at each `\n`, and a record that ended at a `\r` took the
/// position of the next one before that `\n` was read (every error one line short). Cells are
/// unchanged: a line end is not part of a cell, and a quoted cell holding a line end is never a
/// number.
pub(crate) struct CrlfToLf<R> {
    inner: R,
    /// A `\r` ended the last chunk: dropped if a `\n` follows, kept otherwise.
    pending_cr: bool,
}

impl<R: Read> CrlfToLf<R> {
    /// Wrap `inner`.
    pub(crate) fn new(inner: R) -> Self {
        CrlfToLf {
            inner,
            pending_cr: false,
        }
    }
}

impl<R: Read> Read for CrlfToLf<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if buf.len() < 2 {
            // Too small to look ahead (the csv crate reads in 8 KiB): pass through.
            if self.pending_cr && !buf.is_empty() {
                self.pending_cr = false;
                buf[0] = b'\r';
                return Ok(1);
            }
            return self.inner.read(buf);
        }
        loop {
            let held = usize::from(self.pending_cr);
            buf[0] = b'\r';
            let n = self.inner.read(&mut buf[held..])?;
            let end = held + n;
            if n == 0 {
                // End of input: a held `\r` was a lone one.
                self.pending_cr = false;
                return Ok(held);
            }
            let trailing_cr = buf[end - 1] == b'\r';
            let mut w = 0;
            for r in 0..end {
                // buf[r + 1] is still the input's: w <= r.
                if buf[r] == b'\r' && r + 1 < end && buf[r + 1] == b'\n' {
                    continue;
                }
                buf[w] = buf[r];
                w += 1;
            }
            self.pending_cr = trailing_cr;
            if trailing_cr {
                w -= 1;
            }
            if w > 0 {
                return Ok(w);
            }
        }
    }
}

/// The reference path: every row through the csv crate and `str::parse::<f64>`.
fn read_from<R: Read>(
    reader: R,
    path: &Path,
    wanted: &[String],
    keep_time: bool,
) -> Result<Table, InputError> {
    let mut rdr = csv_reader(CrlfToLf::new(reader));
    let head = read_head(&mut rdr, path, wanted, keep_time)?;
    let mut rows = csv_fast::Rows::new(head.selected.len());
    let mut row = head.first.clone();
    loop {
        if let Some(t) = head.time_index {
            rows.time
                .push(String::from_utf8_lossy(&row[t]).into_owned());
        }
        check_row(&row, path, &head.names, &head.selected, |k, v| {
            rows.columns[k].push(v)
        })?;
        if !rdr
            .read_byte_record(&mut row)
            .map_err(|e| csv_error(path, e))?
        {
            break;
        }
    }
    Ok(head.into_table(path, rows))
}

/// What [`RowReader::next_row`] found.
#[derive(Debug)]
pub enum RowRead {
    /// A good row: its selected values were written (NaN only in a column read by
    /// [`RowReader::nan_unknown`]).
    Row,
    /// A bad row (not a number, not finite, ragged), with its position: the reader goes on
    /// after it.
    Bad(InputError),
    /// A row whose cells are all there but some are not finite numbers: the good ones were
    /// written, the bad ones are NaN; `bad` holds their indices among the selected columns,
    /// `error` the first one's position and reason. The reader goes on after it.
    BadCells {
        /// Indices of the bad cells among the selected columns, in order.
        bad: Vec<usize>,
        /// The first bad cell, positioned.
        error: InputError,
    },
    /// The end of the file.
    End,
}

/// The rows of a CSV file one at a time, in bounded memory, for replays: the records of the
/// csv crate (as [`read_table`] reads them), each selected cell by `fast-float2` or, when it
/// does not take the cell, by the reference `str::parse::<f64>` (so the same values bit for
/// bit). Unlike [`read_table`] a bad row does not end the reading: it is returned with its
/// file:line:col, and the next call reads on. A gzip-compressed file is decompressed on the fly.
pub struct RowReader {
    rdr: csv::Reader<Box<dyn Read + Send>>,
    path: PathBuf,
    names: Vec<String>,
    fields: usize,
    selected: Vec<usize>,
    record: csv::ByteRecord,
    /// The first data row, read with the header, still to be returned.
    first_pending: bool,
    /// Per selected column: whether a NaN cell is an unknown value ([`RowReader::nan_unknown`]).
    nan_unknown: Vec<bool>,
}

impl std::fmt::Debug for RowReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RowReader")
            .field("path", &self.path)
            .field("selected", &self.selected)
            .finish_non_exhaustive()
    }
}

impl RowReader {
    /// Open `path` and read its header and first data row; `wanted` names the columns (every
    /// numeric column but a time column when empty), as for [`read_table`].
    pub fn open(path: &Path, wanted: &[String]) -> Result<Self, InputError> {
        let io_err = |source| InputError::Io {
            path: path.display().to_string(),
            source,
        };
        let file = File::open(path).map_err(io_err)?;
        let raw = BufReader::with_capacity(1 << 16, file);
        let source: Box<dyn Read + Send> = if gzipped(path)? {
            Box::new(CrlfToLf::new(flate2::bufread::MultiGzDecoder::new(raw)))
        } else {
            Box::new(CrlfToLf::new(raw))
        };
        // Flexible: a ragged row is reported here with the reference's message, and reading
        // goes on after it.
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .comment(Some(b'#'))
            .from_reader(source);
        let head = read_head(&mut rdr, path, wanted, false)?;
        Ok(RowReader {
            nan_unknown: vec![false; head.selected.len()],
            rdr,
            path: path.to_path_buf(),
            fields: head.fields,
            selected: head.selected,
            names: head.names,
            record: head.first,
            first_pending: true,
        })
    }

    /// Take an empty or NaN cell (`nan`, `NaN`, `-nan`: any spelling `str::parse::<f64>` reads
    /// as NaN) in selected column `k` as an unknown value: written as NaN, the row good. For a
    /// column whose NaN means "not known" (a replay's stop column, an odometry logged at its
    /// own rate); in every other column it stays a bad cell, and an infinity or a cell that is
    /// no number stays one in this column too.
    pub fn nan_unknown(mut self, k: usize) -> Self {
        if let Some(u) = self.nan_unknown.get_mut(k) {
            *u = true;
        }
        self
    }

    /// The selected columns' names, in the order their values are written.
    pub fn names(&self) -> Vec<String> {
        self.selected
            .iter()
            .map(|&i| self.names[i].clone())
            .collect()
    }

    /// Read the next row's selected values into `out` (one per selected column). An I/O error
    /// (a truncated gzip stream, say) is returned as `Err`: the reading cannot go on.
    pub fn next_row(&mut self, out: &mut [f64]) -> Result<RowRead, InputError> {
        if !std::mem::take(&mut self.first_pending) {
            match self.rdr.read_byte_record(&mut self.record) {
                Ok(true) => {}
                Ok(false) => return Ok(RowRead::End),
                Err(e) => {
                    let e = csv_error(&self.path, e);
                    return match e {
                        InputError::At { .. } => Ok(RowRead::Bad(e)),
                        _ => Err(e),
                    };
                }
            }
        }
        let row = &self.record;
        if row.len() != self.fields {
            return Ok(RowRead::Bad(InputError::At {
                path: self.path.display().to_string(),
                line: row.position().map_or(0, |p| p.line()),
                column: 1,
                message: format!(
                    "this row has {} fields, the first row has {}",
                    row.len(),
                    self.fields
                ),
            }));
        }
        let mut fast = true;
        for ((o, &i), &unknown) in out.iter_mut().zip(&self.selected).zip(&self.nan_unknown) {
            // The csv crate's ASCII trim (the reference trims the record), then fast-float2.
            let cell = row[i].trim_ascii();
            match csv_fast::fast_number(cell) {
                Some(v) => *o = v,
                None if unknown && nan_cell(cell) => *o = f64::NAN,
                None => {
                    fast = false;
                    break;
                }
            }
        }
        if fast {
            return Ok(RowRead::Row);
        }
        // The reference decides (and words the error) for the cells fast-float2 left.
        let mut trimmed = row.clone();
        trimmed.trim();
        // Every cell judged on its own, so a reader can keep what is good in the row.
        let (mut bad, mut first) = (Vec::new(), None);
        for (k, &i) in self.selected.iter().enumerate() {
            if self.nan_unknown[k] && nan_cell(&trimmed[i]) {
                out[k] = f64::NAN;
                continue;
            }
            match check_cell(&trimmed, &self.path, &self.names, i) {
                Ok(v) => out[k] = v,
                Err(e) => {
                    out[k] = f64::NAN;
                    bad.push(k);
                    first.get_or_insert(e);
                }
            }
        }
        Ok(match first {
            None => RowRead::Row,
            Some(error) => RowRead::BadCells { bad, error },
        })
    }
}

/// Write equal-length columns with a header, at full precision (every value round-trips exactly).
///
/// The file appears whole or not at all: it is written to a temporary file beside `path`, then
/// renamed. A name ending in `.gz` is written gzip-compressed.
pub fn write_table(path: &Path, names: &[String], columns: &[&[f64]]) -> Result<(), InputError> {
    write_table_with_time(path, None, names, columns)
}

/// [`write_table`], with a time column (as [`read_table_keeping_time`] read it) put back in its
/// place among the columns, its cells unchanged.
pub fn write_table_with_time(
    path: &Path,
    time: Option<&TimeColumn>,
    names: &[String],
    columns: &[&[f64]],
) -> Result<(), InputError> {
    let io_err = |source| InputError::Io {
        path: path.display().to_string(),
        source,
    };
    let rows = columns.first().map_or(0, |c| c.len());
    if let Some(t) = time {
        if t.cells.len() != rows || t.position > columns.len() {
            return Err(InputError::file(
                path,
                "the time column does not match the columns",
            ));
        }
    }
    super::atomic::write_text_atomically(path, |w| {
        let mut header: Vec<&str> = names.iter().map(String::as_str).collect();
        if let Some(t) = time {
            header.insert(t.position, &t.name);
        }
        writeln!(w, "{}", header.join(","))?;
        let time_at = |k: usize| time.filter(|t| t.position == k);
        let mut line = String::new();
        let mut ryu_buf = ryu::Buffer::new();
        for r in 0..rows {
            line.clear();
            for (k, c) in columns.iter().enumerate() {
                if let Some(t) = time_at(k) {
                    line.push_str(&t.cells[r]);
                    line.push(',');
                }
                push_display(&mut line, c[r], &mut ryu_buf);
                line.push(',');
            }
            if let Some(t) = time_at(columns.len()) {
                line.push_str(&t.cells[r]);
                line.push(',');
            }
            line.pop(); // the last comma
            line.push('\n');
            w.write_all(line.as_bytes())?;
        }
        Ok(())
    })
    .map_err(io_err)
}

/// Whether the finite `v` is exactly halfway between the decimal `digits` x 10^`k` and its
/// neighbour one unit in the last digit away: then two candidates are equally short and equally
/// close. Exactly `|v| = c 10^(k-1)` with `c = 10 D +- 5 = 5 (2 D +- 1)`, so with
/// `|v| = m 2^e`, m odd: `e = k - 1` and `m = (2 D +- 1) 5^k` (or `m 5^-k = 2 D +- 1` for
/// k < 0). This needs 5^|k| below 2^53 and a D of 16 or more digits (a decimal step of a
/// shorter D is wider than the value's rounding interval), so the check is cheap and rare.
fn is_decimal_tie(v: f64, digits: &[u8], k: i32) -> bool {
    if digits.len() < 16 || digits.len() > 19 {
        return false;
    }
    let d = digits
        .iter()
        .fold(0u128, |acc, &b| acc * 10 + u128::from(b - b'0'));
    let bits = v.abs().to_bits();
    let (exp, frac) = ((bits >> 52) as i32, bits & ((1 << 52) - 1));
    let (mut m, mut e) = if exp == 0 {
        (frac, -1074)
    } else {
        (frac | 1 << 52, exp - 1075)
    };
    if m == 0 {
        return false;
    }
    e += m.trailing_zeros() as i32;
    m >>= m.trailing_zeros();
    if e != k - 1 || k.unsigned_abs() > 27 {
        return false;
    }
    let m = u128::from(m);
    let five = 5u128.pow(k.unsigned_abs());
    [2 * d + 1, 2 * d - 1]
        .into_iter()
        .any(|c| if k >= 0 { m == c * five } else { m * five == c })
}

/// Append `v` exactly as `{}` prints an f64 (the shortest text that parses back to the same
/// value, never an exponent), several times faster: `ryu` finds the shortest digits, laid out
/// here as `Display` does; a value exactly halfway between two shortest candidates, where the
/// two break the tie differently, goes through `Display` itself.
fn push_display(out: &mut String, v: f64, buf: &mut ryu::Buffer) {
    if !v.is_finite() {
        use std::fmt::Write as _;
        let _ = write!(out, "{v}");
        return;
    }
    let text = buf.format_finite(v);
    let (negative, text) = match text.strip_prefix('-') {
        Some(t) => (true, t),
        None => (false, text),
    };
    let (mantissa, exp) = match text.split_once('e') {
        Some((m, e)) => (m, e.parse::<i32>().unwrap_or(0)),
        None => (text, 0),
    };
    let (int, frac) = mantissa.split_once('.').unwrap_or((mantissa, ""));
    // The significant digits and where the decimal point goes among them.
    let mut digits = [0u8; 40];
    let mut n = 0;
    for &d in int.as_bytes().iter().chain(frac.as_bytes()) {
        if n < digits.len() {
            digits[n] = d;
            n += 1;
        }
    }
    let mut point = int.len() as i32 + exp;
    let mut first = 0;
    while first + 1 < n && digits[first] == b'0' {
        first += 1;
        point -= 1;
    }
    while n > first + 1 && digits[n - 1] == b'0' {
        n -= 1;
    }
    let digits = &digits[first..n];
    if is_decimal_tie(v, digits, point - digits.len() as i32) {
        // v lies exactly halfway between two shortest candidates, and there ryu and `Display`
        // break the tie differently (-90841218690893.125: ryu ...893.13, `{}` ...893.12; found
        // by the proptest below). `{}` is the reference.
        use std::fmt::Write as _;
        let _ = write!(out, "{v}");
        return;
    }
    if digits == b"0" {
        out.push_str(if negative { "-0" } else { "0" });
        return;
    }
    if negative {
        out.push('-');
    }
    let len = digits.len() as i32;
    // ASCII digits only: each byte is a char.
    let push = |out: &mut String, d: &[u8]| out.extend(d.iter().map(|&b| b as char));
    if point <= 0 {
        out.push_str("0.");
        out.extend(std::iter::repeat_n('0', (-point) as usize));
        push(out, digits);
    } else if point >= len {
        push(out, digits);
        out.extend(std::iter::repeat_n('0', (point - len) as usize));
    } else {
        push(out, &digits[..point as usize]);
        out.push('.');
        push(out, &digits[point as usize..]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_str(text: &str, wanted: &[&str]) -> Result<Table, InputError> {
        let wanted: Vec<String> = wanted.iter().map(|s| s.to_string()).collect();
        read_from(text.as_bytes(), Path::new("t.csv"), &wanted, false)
    }

    #[test]
    fn header_and_numeric_columns() {
        let t = read_str("step,label,x\n0,a,1.5\n1,b,-2e-3\n", &[]).unwrap();
        assert_eq!(t.names, ["step", "x"]);
        assert_eq!(t.columns, vec![vec![0.0, 1.0], vec![1.5, -2e-3]]);
        assert!(t.has_header);
    }

    #[test]
    fn time_column_is_left_out_unless_named_or_alone() {
        let t = read_str("t_s,gyro_x\n0,1.5\n0.02,2\n", &[]).unwrap();
        assert_eq!(t.names, ["gyro_x"]);
        let t = read_str("t_s,gyro_x\n0,1.5\n", &["t_s"]).unwrap();
        assert_eq!(t.names, ["t_s"]);
        let t = read_str("time\n0\n1\n", &[]).unwrap();
        assert_eq!(t.names, ["time"]);
    }

    #[test]
    fn headerless_columns_are_numbered() {
        let t = read_str("1,2\n3,4\n", &[]).unwrap();
        assert_eq!(t.names, ["c0", "c1"]);
        assert!(!t.has_header);
        assert_eq!(t.column("c1"), Some(&[2.0, 4.0][..]));
    }

    #[test]
    fn bad_cell_names_line_and_column() {
        let e = read_str("a,b\n1,2\n3,x\n", &[]).unwrap_err().to_string();
        assert_eq!(e, "t.csv:3:3: column 'b': 'x' is not a number");
        let e = read_str("a,b\n1,2\n3,NaN\n", &[]).unwrap_err().to_string();
        assert_eq!(e, "t.csv:3:3: column 'b': NaN is not a finite sample");
        let e = read_str("a,b\n1,inf\n", &["b"]).unwrap_err().to_string();
        assert_eq!(e, "t.csv:2:3: column 'b': inf is not a finite sample");
    }

    #[test]
    fn unknown_column_lists_the_valid_ones() {
        let e = read_str("a,b\n1,2\n", &["z"]).unwrap_err().to_string();
        assert_eq!(e, "t.csv: no column named 'z' (columns: a, b)");
    }

    #[test]
    fn empty_and_header_only_files() {
        assert_eq!(
            read_str("", &[]).unwrap_err().to_string(),
            "t.csv: the file is empty"
        );
        assert_eq!(
            read_str("a,b\n", &[]).unwrap_err().to_string(),
            "t.csv: the file has a header but no data rows"
        );
    }

    #[test]
    fn crlf_becomes_lf_across_any_chunking_and_lone_cr_stays() {
        let input = b"t,x\r\n0,1\r\n\r1,2\r\r\n2,3\r";
        let want = b"t,x\n0,1\n\r1,2\r\n2,3\r".to_vec();
        /// Hands out at most `max` bytes per read, to split `\r\n` across reads.
        struct Trickle<'a>(&'a [u8], usize);
        impl Read for Trickle<'_> {
            fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
                let n = self.0.len().min(self.1).min(buf.len());
                buf[..n].copy_from_slice(&self.0[..n]);
                self.0 = &self.0[n..];
                Ok(n)
            }
        }
        for max in 1..input.len() + 1 {
            for buf_len in [1, 2, 3, 7, 64] {
                let mut r = CrlfToLf::new(Trickle(input, max));
                let mut got = Vec::new();
                let mut buf = vec![0; buf_len];
                loop {
                    let n = r.read(&mut buf).unwrap();
                    if n == 0 {
                        break;
                    }
                    got.extend_from_slice(&buf[..n]);
                }
                if buf_len >= 2 {
                    assert_eq!(got, want, "chunks of {max}, buffer {buf_len}");
                } else {
                    // One byte at a time nothing is looked ahead: the input as it is.
                    assert_eq!(got, input, "chunks of {max}, buffer 1");
                }
            }
        }
    }

    #[test]
    fn crlf_files_report_the_right_line() {
        let dir = tempfile::tempdir().unwrap();
        for (name, eol) in [("lf.csv", "\n"), ("crlf.csv", "\r\n")] {
            let path = dir.path().join(name);
            std::fs::write(&path, ["t,x", "0,1", "1,abc", "2,3", ""].join(eol)).unwrap();
            let e = read_table(&path, &[]).unwrap_err().to_string();
            assert!(e.contains(&format!("{name}:3:3: column 'x'")), "{e}");
        }
    }

    #[test]
    fn ragged_row_is_positioned() {
        let e = read_str("a,b\n1,2\n3\n", &[]).unwrap_err().to_string();
        assert_eq!(e, "t.csv:3:1: this row has 1 fields, the first row has 2");
    }

    #[test]
    fn gzip_is_read_transparently() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("g.csv.gz");
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        std::io::Write::write_all(&mut enc, b"x\n1\n2\n").unwrap();
        std::fs::write(&p, enc.finish().unwrap()).unwrap();
        assert_eq!(read_table(&p, &[]).unwrap().columns, vec![vec![1.0, 2.0]]);
    }

    #[test]
    fn the_time_column_is_kept_verbatim_in_its_place_when_asked_for() {
        let text = "gyro_x,t_s,gyro_y\n1,0.000,2\n3,0.010,4\n";
        let wanted: Vec<String> = Vec::new();
        let t = read_from(text.as_bytes(), Path::new("t.csv"), &wanted, true).unwrap();
        assert_eq!(t.names, ["gyro_x", "gyro_y"]);
        let time = t.time.clone().expect("time kept");
        assert_eq!((time.name.as_str(), time.position), ("t_s", 1));
        assert_eq!(time.cells, ["0.000", "0.010"]);
        assert_eq!(read_str(text, &[]).unwrap().time, None, "only when asked");
        let named = read_from(text.as_bytes(), Path::new("t.csv"), &["t_s".into()], true);
        assert_eq!(
            named.unwrap().time,
            None,
            "a selected time column is a signal"
        );

        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("o.csv");
        let cols: Vec<&[f64]> = t.columns.iter().map(Vec::as_slice).collect();
        write_table_with_time(&p, t.time.as_ref(), &t.names, &cols).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), text);
        for position in [0, 2] {
            let first = TimeColumn {
                position,
                ..time.clone()
            };
            write_table_with_time(&p, Some(&first), &t.names, &cols).unwrap();
            let want = if position == 0 {
                "t_s,gyro_x,gyro_y\n0.000,1,2\n0.010,3,4\n"
            } else {
                "gyro_x,gyro_y,t_s\n1,2,0.000\n3,4,0.010\n"
            };
            assert_eq!(std::fs::read_to_string(&p).unwrap(), want);
        }
    }

    #[test]
    fn a_gz_output_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("o.csv.gz");
        write_table(&p, &["x".into()], &[&[1.5, -2.0]]).unwrap();
        assert_eq!(&std::fs::read(&p).unwrap()[..2], &[0x1f, 0x8b]);
        assert_eq!(read_table(&p, &[]).unwrap().columns, vec![vec![1.5, -2.0]]);
    }

    /// Every way in: the fast path over mapped bytes (1 and 3 threads), the streamed fast path
    /// (plain and gzip), and `read_table` on a file, all against the reference.
    fn all_paths_agree(text: &[u8], wanted: &[&str], keep_time: bool) -> Option<bool> {
        let wanted: Vec<String> = wanted.iter().map(|s| s.to_string()).collect();
        let p = Path::new("t.csv");
        let show = |r: &Result<Table, InputError>| match r {
            Ok(t) => {
                format!("{:?} {:?} {:?}", t.names, t.time, t.has_header)
                    + &format!(
                        "{:?}",
                        t.columns
                            .iter()
                            .map(|c| c.iter().map(|v| v.to_bits()).collect::<Vec<_>>())
                            .collect::<Vec<_>>()
                    )
            }
            Err(e) => e.to_string(),
        };
        let reference = show(&read_from(text, p, &wanted, keep_time));
        let fast = fast_mapped(text, p, &wanted, keep_time, &|_| {});
        let took = matches!(fast, Ok(Some(_)));
        if let Ok(Some(t)) = fast {
            assert_eq!(show(&Ok(t)), reference, "mapped fast path on {text:?}");
        }
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("t.csv");
        std::fs::write(&plain, text).unwrap();
        let gz = dir.path().join("t.csv.gz");
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        std::io::Write::write_all(&mut enc, text).unwrap();
        std::fs::write(&gz, enc.finish().unwrap()).unwrap();
        let bar = indicatif::ProgressBar::hidden();
        let fix = |s: String, f: &Path| s.replace(&f.display().to_string(), "t.csv");
        for (f, gzip) in [(&plain, false), (&gz, true)] {
            let file = File::open(f).unwrap();
            let r = read_streamed(f, file, gzip, &wanted, keep_time, &bar);
            assert_eq!(
                fix(show(&r), f),
                reference,
                "streamed (gzip {gzip}) on {text:?}"
            );
        }
        if !text.is_empty() {
            let r = read_table_impl(&plain, &wanted, keep_time);
            assert_eq!(fix(show(&r), &plain), reference, "read_table on {text:?}");
        }
        Some(took)
    }

    #[test]
    fn the_fast_path_reads_what_the_reference_reads_or_steps_aside() {
        let fast: &[&str] = &[
            "x\n1\n2\n",
            "t_s,x,y\n0,1.5,-2\n0.01,2.5,3e-3\n",
            "# made by hand\nx,y\n\n1,2\n# note\n3,4\n\n",
            "x,y\r\n1,2\r\n3,4\r\n",
            "x , y \n 1 ,\t2\n3,4", // spaces, tabs, no final newline
            "1,2\n3,4\n",           // no header
            "a,label,b\n1,cat,2\n3,dog,4\n",
        ];
        for t in fast {
            assert_eq!(
                all_paths_agree(t.as_bytes(), &[], false),
                Some(true),
                "{t:?}"
            );
            assert_eq!(
                all_paths_agree(t.as_bytes(), &[], true),
                Some(true),
                "{t:?}"
            );
        }
        let others: &[&str] = &[
            "",
            "x\n",
            "x,y\n1,2\n3\n",         // ragged
            "x,y\n1,2\n3,4,5\n",     // ragged
            "x,y\n1,2\n3,z\n",       // not a number
            "x,y\n1,2\n3,NaN\n",     // not finite
            "x,y\n1,2\n3,1e999\n",   // overflows to inf
            "x,y\n1,\"2\"\n3,4\n",   // quoted
            "x,y\n1,\"2\n\"\n3,4\n", // quoted across lines
            "x,y\r1,2\r3,4\r",       // CR line ends
            "\u{feff}x,y\n1,2\n",    // BOM
            "\u{feff}1,2\n3,4\n",    // BOM, no header
            "x,y\n1,2\n3,4\u{a0}\n", // no-break space
            "x,y\n1,2\n3,\x0c4\n",   // form feed
            "label\nabc\n",          // nothing numeric
            "x,y\n1,2\n  \n3,4\n",   // a line of spaces is a record
            "x\n1\n#2\n 3\n",
        ];
        for t in others {
            all_paths_agree(t.as_bytes(), &[], false);
            all_paths_agree(t.as_bytes(), &["y"], false);
        }
        all_paths_agree(b"x,y\n1,2\n\xff,4\n", &[], false); // not UTF-8
        all_paths_agree(b"x,t\n1,\xff\n", &[], true);
        assert_eq!(
            all_paths_agree(b"t_s,x,y\n0,1,2\n1,3,4\n", &["y", "t_s"], true),
            Some(true)
        );
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(300))]
        #[test]
        fn random_files_read_the_same_on_every_path(
            cells in proptest::collection::vec(
                proptest::sample::select(vec![
                    "1", "-2.5", "3e-3", " 4 ", "\t.5", "1e999", "nan", "x", "", "\"7\"",
                    "8\r", "#9", "1,2", "0.1", "\u{a0}1",
                ]),
                1..40,
            ),
            width in 1usize..4,
            seps in proptest::collection::vec(proptest::sample::select(vec!["\n", "\r\n", "\n\n", "\n#c\n"]), 40),
            header in proptest::bool::ANY,
        ) {
            let mut text = String::new();
            if header {
                text.push_str(&(0..width).map(|i| format!("c{i}x")).collect::<Vec<_>>().join(","));
                text.push('\n');
            }
            for (k, row) in cells.chunks(width).enumerate() {
                text.push_str(&row.join(","));
                text.push_str(seps[k % seps.len()]);
            }
            all_paths_agree(text.as_bytes(), &[], false);
        }
    }

    fn display_fast(v: f64) -> String {
        let mut s = String::new();
        push_display(&mut s, v, &mut ryu::Buffer::new());
        s
    }

    #[test]
    fn fast_output_is_display_text_exactly() {
        for v in [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.1,
            0.30000000000000004,
            1e-7,
            1.5e-7,
            123456.789,
            1e15,
            1e16,
            1.2345e16,
            1e21,
            1e22,
            1e100,
            1e-300,
            5e-324,
            f64::MAX,
            f64::MIN_POSITIVE,
            -2.5e-5,
            -(90841218690893.0 + 0.125), // exact ties (clippy would round the literals)
            -(1295194815783816.0 + 0.25),
            100.0,
            0.001,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ] {
            assert_eq!(display_fast(v), format!("{v}"), "{v:e}");
        }
    }

    proptest::proptest! {
        #[test]
        fn fast_output_of_any_float_is_display_text_and_parses_back(bits in proptest::prelude::any::<u64>()) {
            let v = f64::from_bits(bits);
            let text = display_fast(v);
            proptest::prop_assert_eq!(&text, &format!("{v}"));
            if v.is_finite() {
                proptest::prop_assert_eq!(text.parse::<f64>().map(f64::to_bits), Ok(bits));
            }
        }

        /// Exact ties between two shortest candidates, which random bits almost never hit:
        /// n + f/4 with n in [2^50, 2^51) (a quarter is the step there; .25 and .75 tie at 17
        /// digits) and n + f/64 with n in [2^46, 2^47) (ties at 16 digits).
        #[test]
        fn fast_output_breaks_ties_as_display(n in 0u64..(1 << 46), f in 0u64..64, neg in proptest::prelude::any::<bool>()) {
            let sign = if neg { -1.0 } else { 1.0 };
            for v in [
                ((1u64 << 50) + n) as f64 + (f % 4) as f64 / 4.0,
                ((1u64 << 46) + n) as f64 + f as f64 / 64.0,
            ] {
                let v = sign * v;
                proptest::prop_assert_eq!(display_fast(v), format!("{v}"));
            }
        }
    }

    #[test]
    fn write_round_trips_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("o.csv");
        let x = [0.1 + 0.2, -1e-300, 123456789.12345679, f64::MIN_POSITIVE];
        write_table(&p, &["x".into()], &[&x]).unwrap();
        let t = read_table(&p, &[]).unwrap();
        assert_eq!(t.columns[0], x);
    }

    /// A column read with `nan_unknown` takes each spelling of NaN, and an empty cell, as an
    /// unknown value (a good row), in the first data row and later ones, by the fast path and beside a cell that sends
    /// the row to the reference path; an infinity or a word there, and a NaN in any other
    /// column, stay bad cells with their positions.
    #[test]
    fn a_nan_unknown_column_takes_nan_as_unknown_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.csv");
        std::fs::write(
            &p,
            "x,stop\n1,nan\n2,NaN\n3, -nan \n4,1\nabc,NAN\n6,inf\n7,abc\nnan,0\n10,\n11, \n",
        )
        .unwrap();
        let wanted = ["x".to_string(), "stop".to_string()];
        let mut rows = RowReader::open(&p, &wanted).unwrap().nan_unknown(1);
        let mut out = [0.0; 2];
        let mut got = Vec::new();
        loop {
            let read = rows.next_row(&mut out).unwrap();
            got.push(match read {
                RowRead::End => break,
                RowRead::Row => format!("{} {}", out[0], out[1]),
                RowRead::Bad(e) => format!("bad {e}"),
                RowRead::BadCells { bad, error } => format!("{bad:?} {error}"),
            });
        }
        assert_eq!(
            got,
            [
                "1 NaN",
                "2 NaN",
                "3 NaN",
                "4 1",
                "[0] t.csv:6:1: column 'x': 'abc' is not a number",
                "[1] t.csv:7:3: column 'stop': inf is not a finite sample",
                "[1] t.csv:8:3: column 'stop': 'abc' is not a number",
                "[0] t.csv:9:1: column 'x': NaN is not a finite sample",
                "10 NaN",
                "11 NaN",
            ]
            .map(|s| s.replace("t.csv", &p.display().to_string()))
        );
        // Without it, a NaN stays a bad cell.
        let mut rows = RowReader::open(&p, &wanted).unwrap();
        assert!(matches!(
            rows.next_row(&mut out).unwrap(),
            RowRead::BadCells { bad, .. } if bad == [1]
        ));
    }
}
