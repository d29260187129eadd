//! Numeric CSV tables: read named columns with file/line/column errors, write them back atomically.
//!
//! A first row in which every cell is a number is data (the columns are then named `c0`, `c1`, ...);
//! otherwise it is the header. NaN and Inf cells are errors: a sample is never silently altered.
//! Files ending in `.gz` are decompressed on the fly.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// File size from which reading shows a progress bar: about 10^6 rows of a 3-axis log as text
/// (24 bytes a row); gzip packs such logs 4:1 to 8:1 (the real ADIS16405 log: 8:1).
const PROGRESS_MIN_BYTES: u64 = 24_000_000;
const PROGRESS_MIN_BYTES_GZ: u64 = PROGRESS_MIN_BYTES / 8;

/// Column names taken for time stamps, not signals: left out when no column is named.
pub const TIME_COLUMNS: [&str; 5] = ["t", "t_s", "time", "time_s", "timestamp"];

/// A bad input file, with the position of the fault where there is one.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The file could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// A fault at a place in the file (1-based line and column).
    #[error("{path}:{line}:{column}: {message}")]
    At {
        /// The file.
        path: String,
        /// 1-based line.
        line: u64,
        /// 1-based column (characters from the start of the line).
        column: u64,
        /// What is wrong there.
        message: String,
    },
    /// A fault of the file as a whole.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: String,
        /// What is wrong with it.
        message: String,
    },
}

impl InputError {
    /// A whole-file error.
    pub fn file(path: &Path, message: impl Into<String>) -> Self {
        InputError::File {
            path: path.display().to_string(),
            message: message.into(),
        }
    }
}

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
    let size = file.metadata().map_err(io_err)?.len();
    let gz = super::atomic::is_gzip(path);
    let min = if gz {
        PROGRESS_MIN_BYTES_GZ
    } else {
        PROGRESS_MIN_BYTES
    };
    let progress = crate::io::progress::bar(size, min, "reading");
    let raw = BufReader::with_capacity(1 << 20, progress.wrap_read(file));
    let result = if gz {
        read_from(
            flate2::bufread::MultiGzDecoder::new(raw),
            path,
            wanted,
            keep_time,
        )
    } else {
        read_from(raw, path, wanted, keep_time)
    };
    progress.finish_and_clear();
    result
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

fn read_from<R: Read>(
    reader: R,
    path: &Path,
    wanted: &[String],
    keep_time: bool,
) -> Result<Table, InputError> {
    let shown = path.display().to_string();
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(reader);
    let mut record = csv::ByteRecord::new();
    if !rdr
        .read_byte_record(&mut record)
        .map_err(|e| csv_error(path, e))?
    {
        return Err(InputError::file(path, "the file is empty"));
    }
    let has_header = record.iter().any(|c| parse_cell(c).is_none());
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
    let mut time_cells = Vec::new();
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); selected.len()];
    let mut row = first;
    loop {
        let line = row.position().map_or(0, |p| p.line());
        if let Some(t) = time_index {
            time_cells.push(String::from_utf8_lossy(&row[t]).into_owned());
        }
        for (out, &i) in columns.iter_mut().zip(&selected) {
            let cell = &row[i];
            let at = |message: String| InputError::At {
                path: shown.clone(),
                line,
                column: field_column(&row, i),
                message,
            };
            match parse_cell(cell) {
                Some(v) if v.is_finite() => out.push(v),
                Some(v) => {
                    return Err(at(format!(
                        "column '{}': {v} is not a finite sample",
                        names[i]
                    )))
                }
                None => {
                    return Err(at(format!(
                        "column '{}': '{}' is not a number",
                        names[i],
                        String::from_utf8_lossy(cell)
                    )))
                }
            }
        }
        if !rdr
            .read_byte_record(&mut row)
            .map_err(|e| csv_error(path, e))?
        {
            break;
        }
    }
    Ok(Table {
        path: path.to_path_buf(),
        names: selected.iter().map(|&i| names[i].clone()).collect(),
        columns,
        has_header,
        time: time_index.map(|t| TimeColumn {
            name: names[t].clone(),
            position: selected.iter().filter(|&&i| i < t).count(),
            cells: time_cells,
        }),
    })
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
        for r in 0..rows {
            line.clear();
            for (k, c) in columns.iter().enumerate() {
                if let Some(t) = time_at(k) {
                    line.push_str(&t.cells[r]);
                    line.push(',');
                }
                // `{}` on f64 prints the shortest text that parses back to the same value.
                use std::fmt::Write as _;
                let _ = write!(line, "{},", c[r]);
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

    #[test]
    fn write_round_trips_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("o.csv");
        let x = [0.1 + 0.2, -1e-300, 123456789.12345679, f64::MIN_POSITIVE];
        write_table(&p, &["x".into()], &[&x]).unwrap();
        let t = read_table(&p, &[]).unwrap();
        assert_eq!(t.columns[0], x);
    }
}
