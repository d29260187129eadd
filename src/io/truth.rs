//! Truth files for `driftless nav-eval --truth`: a known angular rate to add to a static log's
//! windows instead of a built-in motion profile, with the stops an oracle would know.
//!
//! A CSV (gzip-compressed too) with a header row naming its columns:
//! - rate columns, deg/s: every column that is neither a time nor a still column; one for every
//!   axis, or one per axis in the log's column order ([`Truth::traces`]);
//! - still columns (optional): a name starting with `still`, cells 0 or 1, the oracle's stops;
//!   one for every rate column, or one per rate column in the same order. Without one, a sample
//!   is still where its rate is exactly 0;
//! - a time column (optional, one of [`TIME_COLUMNS`]): not used as a signal, but its steps must
//!   be the log's sample period, so a file written at another rate is refused.
//!
//! One row per sample at the log's rate. A cell that is not a finite number, a still cell that is
//! neither 0 nor 1, a row with a missing field, a time stamp off the log's rate: an error at the
//! file's line and column.

use super::csv_table::{csv_error, field_column, parse_cell, TIME_COLUMNS};
use super::error::InputError;
use crate::nav::MotionTrace;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// A time stamp may be off its place on the log's grid by this fraction of a sample period
/// (written time stamps are rounded), no more.
const TIME_TOLERANCE: f64 = 0.05;

/// A truth file's columns.
#[derive(Debug, Clone, PartialEq)]
pub struct Truth {
    /// The file it came from.
    pub path: PathBuf,
    /// Rate columns: name and values, deg/s.
    pub rates: Vec<(String, Vec<f64>)>,
    /// Still columns: none, one for every rate column, or one per rate column.
    pub still: Vec<Vec<bool>>,
}

impl Truth {
    /// Rows (samples).
    pub fn rows(&self) -> usize {
        self.rates.first().map_or(0, |(_, v)| v.len())
    }

    /// The motion of each of `axes` axes at `rate_hz`: the only rate column for every axis, or
    /// rate column k for axis k; its still column, the only one, or where the rate is exactly 0.
    pub fn traces(&self, axes: usize, rate_hz: f64) -> Result<Vec<MotionTrace>, InputError> {
        let n = self.rates.len();
        if n != 1 && n != axes {
            let names: Vec<&str> = self.rates.iter().map(|(s, _)| s.as_str()).collect();
            return Err(InputError::file(
                &self.path,
                format!(
                    "{n} rate columns ({}) for {axes} axes: give one for every axis, or one per axis",
                    names.join(", ")
                ),
            ));
        }
        Ok((0..axes)
            .map(|a| {
                let i = a.min(n - 1);
                let truth = self.rates[i].1.clone();
                let still = match self.still.len() {
                    0 => truth.iter().map(|&r| r == 0.0).collect(),
                    1 => self.still[0].clone(),
                    _ => self.still[i].clone(),
                };
                MotionTrace {
                    rate_hz,
                    truth,
                    still,
                }
            })
            .collect())
    }
}

/// What a column of a truth file holds.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Role {
    Time,
    Still,
    Rate,
}

/// What a truth file is, for a file that holds something else.
pub const TRUTH_TAKES: &str = "a truth file is CSV text (gzip-compressed too)";

/// Read a truth file sampled at `rate_hz` (module docs); one that does not hold text is
/// refused, saying what it holds.
pub fn read_truth(path: &Path, rate_hz: f64) -> Result<Truth, InputError> {
    let sniffed = super::content::text_file(path, TRUTH_TAKES)?;
    let file = File::open(path).map_err(|source| InputError::Io {
        path: path.display().to_string(),
        source,
    })?;
    let raw = BufReader::new(file);
    if sniffed.is_gzip() {
        read_from(flate2::bufread::MultiGzDecoder::new(raw), path, rate_hz)
    } else {
        read_from(raw, path, rate_hz)
    }
}

/// What each column of the header is (the first time column time, `still...` columns still,
/// the rest rates), and how many rate and still columns there are; refused with no rate column,
/// or a still count that is neither one nor the rates'.
fn column_roles(path: &Path, names: &[String]) -> Result<(Vec<Role>, usize, usize), InputError> {
    // Only the first time column is time; a second one would be a signal named like time.
    let time_at = names
        .iter()
        .position(|n| TIME_COLUMNS.contains(&n.as_str()));
    let roles: Vec<Role> = names
        .iter()
        .enumerate()
        .map(|(i, n)| {
            if Some(i) == time_at {
                Role::Time
            } else if n.to_ascii_lowercase().starts_with("still") {
                Role::Still
            } else {
                Role::Rate
            }
        })
        .collect();
    let count = |r: Role| roles.iter().filter(|&&x| x == r).count();
    let (n_rate, n_still) = (count(Role::Rate), count(Role::Still));
    if n_rate == 0 {
        return Err(InputError::file(
            path,
            format!(
                "no rate column (columns: {}; a time column and `still...` columns are not rates)",
                names.join(", ")
            ),
        ));
    }
    if n_still > 1 && n_still != n_rate {
        return Err(InputError::file(
            path,
            format!(
                "{n_still} still columns for {n_rate} rate columns: give one for every rate column, or one per rate column"
            ),
        ));
    }
    Ok((roles, n_rate, n_still))
}

fn read_from<R: Read>(reader: R, path: &Path, rate_hz: f64) -> Result<Truth, InputError> {
    let shown = path.display().to_string();
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(super::csv_table::CrlfToLf::new(reader));
    let mut row = csv::ByteRecord::new();
    if !rdr
        .read_byte_record(&mut row)
        .map_err(|e| csv_error(path, e))?
    {
        return Err(InputError::file(path, "the file is empty"));
    }
    if row.iter().all(|c| parse_cell(c).is_some()) {
        return Err(InputError::At {
            path: shown,
            line: row.position().map_or(1, |p| p.line()),
            column: 1,
            message: "a truth file needs a header row naming its columns (rates in deg/s, optionally `still` and a time column)".into(),
        });
    }
    let names: Vec<String> = row
        .iter()
        .map(|c| String::from_utf8_lossy(c).trim().to_string())
        .collect();
    let (roles, n_rate, n_still) = column_roles(path, &names)?;
    let mut rates: Vec<(String, Vec<f64>)> = Vec::with_capacity(n_rate);
    let mut still: Vec<Vec<bool>> = Vec::with_capacity(n_still);
    for (n, r) in names.iter().zip(&roles) {
        match r {
            Role::Rate => rates.push((n.clone(), Vec::new())),
            Role::Still => still.push(Vec::new()),
            Role::Time => {}
        }
    }
    let mut t0 = None;
    let mut k = 0usize;
    while rdr
        .read_byte_record(&mut row)
        .map_err(|e| csv_error(path, e))?
    {
        let line = row.position().map_or(0, |p| p.line());
        let (mut ri, mut si) = (0, 0);
        for (i, role) in roles.iter().enumerate() {
            let cell = &row[i];
            let at = |message: String| InputError::At {
                path: shown.clone(),
                line,
                column: field_column(&row, i),
                message: format!("column '{}': {message}", names[i]),
            };
            let v = match parse_cell(cell) {
                Some(v) if v.is_finite() => v,
                Some(v) => return Err(at(format!("{v} is not a finite number"))),
                None => {
                    return Err(at(format!(
                        "'{}' is not a number",
                        String::from_utf8_lossy(cell)
                    )))
                }
            };
            match role {
                Role::Rate => {
                    rates[ri].1.push(v);
                    ri += 1;
                }
                Role::Still => {
                    if v != 0.0 && v != 1.0 {
                        return Err(at(format!("{v} is neither 0 (moving) nor 1 (still)")));
                    }
                    still[si].push(v == 1.0);
                    si += 1;
                }
                Role::Time => {
                    let start = *t0.get_or_insert(v);
                    let want = start + k as f64 / rate_hz;
                    if (v - want).abs() > TIME_TOLERANCE / rate_hz {
                        return Err(at(format!(
                            "time {v} s, but row {} of a file at the log's {rate_hz} Hz is at {want} s",
                            k + 1
                        )));
                    }
                }
            }
        }
        k += 1;
    }
    if k == 0 {
        return Err(InputError::file(
            path,
            "the file has a header but no data rows",
        ));
    }
    Ok(Truth {
        path: path.to_path_buf(),
        rates,
        still,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Truth, InputError> {
        read_from(text.as_bytes(), Path::new("t.csv"), 100.0)
    }

    #[test]
    fn columns_by_role_and_the_still_mask() {
        let t = read("t,x,y,still\n0,0,1.5,1\n0.01,2,0,0\n0.02,0,0,1\n").unwrap();
        assert_eq!(t.rows(), 3);
        assert_eq!(t.rates.len(), 2);
        assert_eq!(t.rates[1], ("y".to_string(), vec![1.5, 0.0, 0.0]));
        let tr = t.traces(2, 100.0).unwrap();
        // One still column for both rate columns.
        assert_eq!(tr[0].still, vec![true, false, true]);
        assert_eq!(tr[1].still, tr[0].still);
        assert_eq!(tr[0].truth, vec![0.0, 2.0, 0.0]);
        // Two rate columns fit neither one nor three axes.
        let e = t.traces(3, 100.0).unwrap_err().to_string();
        assert!(e.contains("2 rate columns (x, y) for 3 axes"), "{e}");
    }

    #[test]
    fn without_a_still_column_still_is_exactly_zero() {
        let t = read("rate\n0\n1e-300\n-0\n").unwrap();
        let tr = t.traces(3, 100.0).unwrap();
        assert_eq!(tr.len(), 3);
        assert_eq!(tr[2].still, vec![true, false, true]);
    }

    #[test]
    fn bad_cells_are_placed() {
        let cases = [
            (
                "x,still\n0,1\n0,0.5\n",
                "t.csv:3:3: column 'still': 0.5 is neither 0",
            ),
            (
                "x\n0\nabc\n",
                "t.csv:3:1: column 'x': 'abc' is not a number",
            ),
            ("x,y\n0,1\n0\n", "t.csv:3:1: this row has 1 fields"),
            ("t,x\n0,0\n0.02,0\n", "t.csv:3:1: column 't': time 0.02 s"),
            ("1,2\n", "t.csv:1:1: a truth file needs a header"),
            (
                "x,still_x,still_y,still_z\n0,1,1,1\n",
                "3 still columns for 1 rate columns",
            ),
            ("time,still\n0,1\n", "no rate column"),
            ("x\n", "header but no data rows"),
        ];
        for (text, want) in cases {
            let e = read(text).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }
}
