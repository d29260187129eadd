//! `predict.bias`'s warm start: the bias filter's state saved to the file its `state_file` key
//! names, at shutdown and every `state_every_s`, and read back at the next start.
//!
//! - **Written atomically** by a thread of its own (never the hot thread): a temporary file in
//!   the same directory, synced, renamed over the old one, the directory synced. A crash
//!   leaves the old state or the new one, never half of one.
//! - **Tied to its owner**: the pipeline and stage names, the axis count, the rate and the
//!   noise terms. A state of another owner (another pipeline's, another sensor's terms) is
//!   refused, as is a file that does not parse (with its line and column): remove it, or point
//!   `state_file` elsewhere, to start cold.
//! - **Grown by the time that passed**: at start each axis's filter resumes from its saved
//!   estimate and covariance, predicted through the wall-clock time since the save
//!   ([`crate::drift::bias::BiasFilter::resume`]). Older than the prior is worth, or saved in
//!   the future (a clock set back), it is not used: the stage starts cold and says why.
//!
//! The file is TOML, one table per axis; `bias_deg_s` and `sd_deg_s` are there for a reader
//! and are not read back.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use crossbeam_channel::{bounded, Sender};
use serde::{Deserialize, Serialize};

use crate::drift::bias::{BiasTerms, FilterSnapshot, LearnerSnapshot, GRID, MAX_STATES};
use crate::stages::schema::Src;

/// The file format's version.
const FORMAT: u32 = 1;

/// Axis names in files and lines.
const AXES: [&str; 3] = ["x", "y", "z"];

/// Who a state belongs to: a state of another owner is refused.
#[derive(Debug, Clone, PartialEq)]
pub struct Owner {
    /// The pipeline's name.
    pub pipeline: String,
    /// The stage's name.
    pub stage: String,
    /// Axes.
    pub axes: usize,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// The stage's noise terms (the sensor's, as far as the stage knows it).
    pub terms: BiasTerms,
}

impl Owner {
    fn terms(&self) -> [f64; 5] {
        let t = &self.terms;
        [t.n, t.b, t.k, t.q, t.lsb]
    }
}

/// A state read back: one filter snapshot per axis and when it was saved.
#[derive(Debug, Clone, PartialEq)]
pub struct Saved {
    /// Per axis.
    pub filters: Vec<FilterSnapshot>,
    /// Wall-clock time of the save, ns since the Unix epoch.
    pub saved_unix_ns: u64,
}

impl Saved {
    /// How long ago it was saved; None if in the future by more than a second (a clock set
    /// back: the time between is unknown).
    pub fn age(&self) -> Option<Duration> {
        let saved = UNIX_EPOCH + Duration::from_nanos(self.saved_unix_ns);
        match SystemTime::now().duration_since(saved) {
            Ok(age) => Some(age),
            Err(e) if e.duration() <= Duration::from_secs(1) => Some(Duration::ZERO),
            Err(_) => None,
        }
    }
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    format: u32,
    pipeline: String,
    stage: String,
    axes: usize,
    rate_hz: f64,
    /// N, B, K, Q, lsb in the filter's base units (deg/s based).
    terms: [f64; 5],
    saved_unix_ns: u64,
    axis: Vec<AxisFile>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct AxisFile {
    name: String,
    bias_deg_s: f64,
    sd_deg_s: f64,
    x: Vec<f64>,
    p: Vec<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    walk: Option<WalkFile>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct WalkFile {
    walk: f64,
    stops: u64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    end_var: Option<f64>,
    ll: Vec<f64>,
}

/// The state in `path` for `owner`: None if there is no file; an error (one line, naming the
/// file, and its line and column where it does not parse) if it cannot be used.
pub fn load(path: &Path, owner: &Owner) -> Result<Option<Saved>, String> {
    let shown = path.display();
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("state_file {shown}: {e}")),
    };
    let cold = "remove it to start cold, or point state_file elsewhere";
    let file: File = toml::from_str(&text).map_err(|e| {
        let src = Src { path, text: &text };
        let why = format!(
            "not a bias state driftless wrote ({}): {cold}",
            e.message().trim_end()
        );
        src.at(e.span().map_or(0, |s| s.start), why).to_string()
    })?;
    if file.format != FORMAT {
        return Err(format!(
            "state_file {shown}: format {} (this driftless reads {FORMAT}): {cold}",
            file.format
        ));
    }
    let same_terms = file
        .terms
        .iter()
        .zip(owner.terms())
        .all(|(a, b)| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()));
    let mismatch = if file.pipeline != owner.pipeline || file.stage != owner.stage {
        Some(format!(
            "it is pipeline {:?} stage {:?}'s, not {:?} {:?}'s",
            file.pipeline, file.stage, owner.pipeline, owner.stage
        ))
    } else if file.axes != owner.axes || file.axis.len() != owner.axes {
        Some(format!(
            "it holds {} axes, this pipeline has {}",
            file.axis.len(),
            owner.axes
        ))
    } else if (file.rate_hz - owner.rate_hz).abs() > 1e-9 * owner.rate_hz {
        Some(format!(
            "it was saved at {} Hz, this pipeline runs at {} Hz",
            file.rate_hz, owner.rate_hz
        ))
    } else if !same_terms {
        Some(
            "it was saved with other noise terms (another sensor's, or terms since changed)"
                .to_string(),
        )
    } else {
        None
    };
    if let Some(why) = mismatch {
        return Err(format!("state_file {shown}: {why}: {cold}"));
    }
    let mut filters = Vec::with_capacity(file.axis.len());
    for (k, a) in file.axis.iter().enumerate() {
        let n = a.x.len();
        let bad = |what: &str| format!("state_file {shown}: axis {}: {what}: {cold}", AXES[k]);
        if n == 0 || n > MAX_STATES || a.p.len() != n || a.p.iter().any(|r| r.len() != n) {
            return Err(bad(
                "its x and p do not hold one state vector and its covariance",
            ));
        }
        let mut snap = FilterSnapshot {
            states: n,
            x: [0.0; MAX_STATES],
            p: [[0.0; MAX_STATES]; MAX_STATES],
            learner: None,
        };
        snap.x[..n].copy_from_slice(&a.x);
        for (row, saved) in snap.p.iter_mut().zip(&a.p) {
            row[..n].copy_from_slice(saved);
        }
        if let Some(w) = &a.walk {
            if w.ll.len() != GRID {
                return Err(bad("its walk's likelihoods are not the learner's grid"));
            }
            let mut ll = [0.0; GRID];
            ll.copy_from_slice(&w.ll);
            snap.learner = Some(LearnerSnapshot {
                ll,
                walk: w.walk,
                stops: w.stops,
                end_var: w.end_var,
            });
        }
        let finite = snap
            .x
            .iter()
            .chain(snap.p.iter().flatten())
            .all(|v| v.is_finite());
        if !finite || snap.variance() <= 0.0 {
            return Err(bad("its values are not a usable estimate"));
        }
        filters.push(snap);
    }
    Ok(Some(Saved {
        filters,
        saved_unix_ns: file.saved_unix_ns,
    }))
}

/// The state as text, saved now.
fn render(owner: &Owner, filters: &[FilterSnapshot], saved_unix_ns: u64) -> String {
    let axis = filters
        .iter()
        .zip(AXES)
        .map(|(f, name)| {
            let n = f.states;
            AxisFile {
                name: name.to_string(),
                bias_deg_s: f.estimate(),
                sd_deg_s: f.variance().sqrt(),
                x: f.x[..n].to_vec(),
                p: f.p[..n].iter().map(|r| r[..n].to_vec()).collect(),
                walk: f.learner.map(|l| WalkFile {
                    walk: l.walk,
                    stops: l.stops,
                    end_var: l.end_var,
                    ll: l.ll.to_vec(),
                }),
            }
        })
        .collect();
    let file = File {
        format: FORMAT,
        pipeline: owner.pipeline.clone(),
        stage: owner.stage.clone(),
        axes: owner.axes,
        rate_hz: owner.rate_hz,
        terms: owner.terms(),
        saved_unix_ns,
        axis,
    };
    let body = toml::to_string(&file).expect("a state of plain values");
    format!("# The bias filter's state, written by driftless's predict.bias (state_file).\n{body}")
}

/// Write `text` to `path` atomically: a temporary file beside it, synced, renamed over it, the
/// directory synced.
fn write_atomically(path: &Path, text: &str) -> std::io::Result<()> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let tmp = dir.join(format!(".{name}.tmp-{}", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(text.as_bytes())?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)?;
        std::fs::File::open(dir)?.sync_all()
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// One save: each axis's filter (fixed size, so that taking one never allocates).
pub struct Snapshot {
    filters: [Option<FilterSnapshot>; 3],
}

impl Snapshot {
    /// The snapshots of up to three axes, in order.
    pub fn new(mut each: impl FnMut(usize) -> Option<FilterSnapshot>) -> Snapshot {
        Snapshot {
            filters: [each(0), each(1), each(2)],
        }
    }
}

/// The thread that writes the state: the hot thread hands it snapshots, never waiting.
pub struct StateWriter {
    tx: Option<Sender<Box<Snapshot>>>,
    spare: crossbeam_channel::Receiver<Box<Snapshot>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl StateWriter {
    /// Start the writer of `path` for `owner`.
    pub fn start(path: PathBuf, owner: Owner) -> Result<StateWriter, String> {
        let (tx, rx) = bounded::<Box<Snapshot>>(1);
        // Boxes go back for reuse: the hot thread never allocates one after the first.
        let (back, spare) = bounded::<Box<Snapshot>>(2);
        for _ in 0..2 {
            let _ = back.send(Box::new(Snapshot::new(|_| None)));
        }
        let thread = std::thread::Builder::new()
            .name("driftless-state".into())
            .spawn(move || {
                let mut failed = false;
                for snap in rx {
                    let filters: Vec<FilterSnapshot> =
                        snap.filters.iter().flatten().cloned().collect();
                    let _ = back.try_send(snap);
                    let now = SystemTime::now()
                        .duration_since(UNIX_EPOCH)
                        .map_or(0, |d| d.as_nanos() as u64);
                    match write_atomically(&path, &render(&owner, &filters, now)) {
                        Ok(()) if failed => {
                            failed = false;
                            eprintln!("driftless: state_file {}: saved again", path.display());
                        }
                        Ok(()) => {}
                        Err(e) if !failed => {
                            failed = true;
                            eprintln!(
                                "driftless: warning: state_file {}: not saved: {e} (the \
                                 pipeline runs on; the next start may be cold)",
                                path.display()
                            );
                        }
                        Err(_) => {}
                    }
                }
            })
            .map_err(|e| format!("cannot start the state writer thread: {e}"))?;
        Ok(StateWriter {
            tx: Some(tx),
            spare,
            thread: Some(thread),
        })
    }

    /// Hand over a snapshot without waiting; skipped if the last is still being written.
    pub fn offer(&self, fill: impl FnOnce(&mut Snapshot)) {
        let Some(tx) = &self.tx else { return };
        if tx.is_full() {
            return;
        }
        let mut snap = self
            .spare
            .try_recv()
            .unwrap_or_else(|_| Box::new(Snapshot::new(|_| None)));
        fill(&mut snap);
        let _ = tx.try_send(snap);
    }

    /// The last snapshot (shutdown): waits until it is written.
    pub fn finish(mut self, last: Snapshot) {
        if let Some(tx) = self.tx.take() {
            let _ = tx.send(Box::new(last));
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for StateWriter {
    fn drop(&mut self) {
        self.tx.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The axes of a state for a line: `x +0.1234 +- 0.0012 deg/s, y ...`.
pub fn describe(filters: &[FilterSnapshot]) -> String {
    filters
        .iter()
        .zip(AXES)
        .map(|(f, a)| format!("{a} {:+.4} +- {:.4}", f.estimate(), f.variance().sqrt()))
        .collect::<Vec<_>>()
        .join(", ")
        + " deg/s"
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drift::bias::{BiasTracker, TrackerConfig};

    fn owner() -> Owner {
        Owner {
            pipeline: "p".into(),
            stage: "predict".into(),
            axes: 2,
            rate_hz: 100.0,
            terms: BiasTerms::profile("adis16405").unwrap(),
        }
    }

    fn learnt() -> Vec<FilterSnapshot> {
        let o = owner();
        (0..2)
            .map(|k| {
                let mut t =
                    BiasTracker::new(&o.terms, o.rate_hz, &TrackerConfig::default()).unwrap();
                for i in 0..3000 {
                    t.push(0.3 * (k as f64 + 1.0) + 0.01 * ((i * 7919) % 13) as f64);
                }
                t.snapshot()
            })
            .collect()
    }

    #[test]
    fn a_state_round_trips_through_its_file() {
        let dir = std::env::temp_dir().join(format!("dl-state-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s.toml");
        let filters = learnt();
        write_atomically(
            &path,
            &render(&owner(), &filters, 1_700_000_000_000_000_000),
        )
        .unwrap();
        let saved = load(&path, &owner()).unwrap().unwrap();
        assert_eq!(saved.filters, filters);
        assert_eq!(saved.saved_unix_ns, 1_700_000_000_000_000_000);
        // Another owner's: refused, naming why.
        for (other, why) in [
            (
                Owner {
                    stage: "q".into(),
                    ..owner()
                },
                "stage \"predict\"'s, not",
            ),
            (Owner { axes: 3, ..owner() }, "holds 2 axes"),
            (
                Owner {
                    rate_hz: 200.0,
                    ..owner()
                },
                "saved at 100 Hz",
            ),
            (
                Owner {
                    terms: BiasTerms::profile("adxrs450").unwrap(),
                    ..owner()
                },
                "other noise terms",
            ),
        ] {
            let e = load(&path, &other).unwrap_err();
            assert!(e.contains(why) && e.contains("start cold"), "{e}");
        }
        // Cut short: refused with a position, never half read.
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(&path, &text[..text.len() / 2]).unwrap();
        let e = load(&path, &owner()).unwrap_err();
        assert!(
            e.contains("s.toml:") && e.contains("not a bias state"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(load(&path, &owner()).unwrap(), None, "no file: cold");
    }
}
