//! `driftless allan` over several logs of one unit (one per power-up, one per day): each log is
//! analysed alone, then the curves are pooled per tau ([`crate::allan::analysis::pool_analyses`]),
//! never joined end to end (the steps between power-ups would read as bias instability). Here:
//! the checks that the logs can pool, the pooling of each column, and what the output says about
//! the logs.

use crate::allan::analysis::{pool_analyses, Analysis, PooledAnalysis};
use crate::allan::{Kind, SampleUnit};
use crate::cli::CliError;
use crate::io::InputError;
use crate::rate_log::{RateLog, RATE_TOLERANCE};
use serde_json::{json, Value};
use std::path::Path;

/// One pooled log, as the output names it.
#[derive(Debug, Clone)]
pub(super) struct LogInfo {
    /// Its path as given.
    pub name: String,
    /// Its samples.
    pub samples: usize,
    /// The largest tau (s) of its curve: the pooled curve's longer taus come from other logs.
    pub largest_tau: f64,
}

/// The logs behind a pooled result.
#[derive(Debug, Clone)]
pub(super) struct Pooling {
    /// Each log, in the order given.
    pub logs: Vec<LogInfo>,
}

/// What every pooled log must share with the first: its rate, columns and units.
pub(super) struct Reference {
    path: String,
    /// The first log's rate, every log's analysis's.
    pub rate: f64,
    names: Vec<String>,
    units: Vec<SampleUnit>,
}

impl Reference {
    /// The first log's.
    pub fn of(path: &Path, log: &RateLog, units: &[SampleUnit], rate: f64) -> Self {
        Reference {
            path: path.display().to_string(),
            rate,
            names: log.table.names.clone(),
            units: units.to_vec(),
        }
    }

    /// Refused, naming `path`, unless its log has the reference's columns and units and its rate
    /// (a bag's from its stamps) lies within [`RATE_TOLERANCE`] of the reference's.
    pub fn check(
        &self,
        path: &Path,
        log: &RateLog,
        units: &[SampleUnit],
        rate: f64,
    ) -> Result<(), CliError> {
        let (shown, first) = (path.display(), &self.path);
        let refuse = |what: String| {
            Err(CliError::input(format!(
                "{shown}: {what}: logs pooled by `driftless allan` must share rate, units and columns"
            )))
        };
        if log.table.names != self.names {
            return refuse(format!(
                "its columns are {}, {first}'s {}",
                log.table.names.join(", "),
                self.names.join(", ")
            ));
        }
        if let Some(((name, u), r)) = self
            .names
            .iter()
            .zip(units)
            .zip(&self.units)
            .find(|((_, u), r)| u != r)
        {
            return refuse(format!("column '{name}' is in {u}, {first}'s in {r}"));
        }
        if (rate - self.rate).abs() > RATE_TOLERANCE * self.rate {
            return refuse(format!("its rate is {rate} Hz, {first}'s {} Hz", self.rate));
        }
        Ok(())
    }
}

/// Each log's analyses (`per_log[i][c]`: log i, column c, the same columns in each) pooled per
/// column, with what the output says about the logs (`paths` in the order of `per_log`).
pub(super) fn pool_columns(
    kind: Kind,
    paths: &[&Path],
    per_log: Vec<Vec<Analysis>>,
) -> (Vec<PooledAnalysis>, Pooling) {
    let logs = paths
        .iter()
        .zip(&per_log)
        .map(|(p, cols)| LogInfo {
            name: p.display().to_string(),
            samples: cols.first().map_or(0, |c| c.samples),
            largest_tau: cols
                .first()
                .and_then(|c| c.points.last())
                .map_or(0.0, |p| p.tau),
        })
        .collect();
    let columns = per_log.first().map_or(0, Vec::len);
    let mut by_column: Vec<Vec<Analysis>> = (0..columns).map(|_| Vec::new()).collect();
    for cols in per_log {
        for (c, a) in cols.into_iter().enumerate() {
            by_column[c].push(a);
        }
    }
    let pooled = by_column
        .iter()
        .map(|analyses| pool_analyses(kind, analyses))
        .collect();
    (pooled, Pooling { logs })
}

impl Pooling {
    /// The lines printed before the tables.
    pub fn text(&self) -> String {
        let mut out = format!(
            "{} logs pooled per tau, never joined: each log's variance weighted by its number of terms, the EDF summed; a tau counts the logs that reach it\n",
            self.logs.len()
        );
        for (k, l) in self.logs.iter().enumerate() {
            out += &format!(
                "  log {}: {}: {} samples, taus up to {} s\n",
                k + 1,
                l.name,
                l.samples,
                l.largest_tau
            );
        }
        out
    }

    /// `--json`'s `logs` array.
    pub fn json(&self) -> Value {
        self.logs
            .iter()
            .map(|l| json!({"name": l.name, "samples": l.samples, "largest_tau": l.largest_tau}))
            .collect()
    }

    /// One line per log for a plot's notes and `--stage`'s comments.
    pub fn lines(&self) -> Vec<String> {
        self.logs
            .iter()
            .map(|l| {
                format!(
                    "{}: {} samples, taus up to {} s",
                    l.name, l.samples, l.largest_tau
                )
            })
            .collect()
    }

    /// `-o`'s companion `<stem>-logs.csv`: one row per log.
    pub fn write_csv(&self, out: &Path) -> Result<std::path::PathBuf, CliError> {
        let stem = out.file_stem().unwrap_or_default().to_string_lossy();
        let ext = out
            .extension()
            .map_or(String::new(), |e| format!(".{}", e.to_string_lossy()));
        let to = out.with_file_name(format!("{stem}-logs{ext}"));
        let quoted = |s: &str| {
            if s.contains([',', '"', '\n']) {
                format!("\"{}\"", s.replace('"', "\"\""))
            } else {
                s.to_string()
            }
        };
        crate::io::atomic::write_text_atomically(&to, |w| {
            writeln!(w, "log,name,samples,largest_tau_s")?;
            for (k, l) in self.logs.iter().enumerate() {
                writeln!(
                    w,
                    "{},{},{},{}",
                    k + 1,
                    quoted(&l.name),
                    l.samples,
                    l.largest_tau
                )?;
            }
            Ok(())
        })
        .map_err(|source| InputError::Io {
            path: to.display().to_string(),
            source,
        })?;
        Ok(to)
    }
}
