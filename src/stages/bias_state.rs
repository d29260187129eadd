//! `predict.bias`'s warm start: the bias filter's state saved to the file its `state_file` key
//! names, at shutdown and every `state_every_s`, and read back at the next start.
//!
//! - **Written atomically** by a thread of its own (never the hot thread): a temporary file in
//!   the same directory, synced, renamed over the old one, the directory synced. A crash
//!   leaves the old state or the new one, never half of one.
//! - **Tied to its owner**: the pipeline and stage names, the axis count, the rate and the
//!   noise terms. A state of another owner (another pipeline's, another sensor's terms, terms
//!   since re-measured), a file that does not parse (with its line and column), garbage, or a
//!   file that cannot be read is [`Loaded::Unusable`]. A cache must never cost the
//!   navigation: by default the stage starts cold, says why in one line, and moves the file
//!   aside to `<name>.unusable-<UTC time>` ([`move_aside`]) so that nothing is lost and the
//!   next save lands where the last one was; `state_required = true` refuses it (exit 2).
//! - **Grown by the time that passed**: at start each axis's filter resumes from its saved
//!   estimate and covariance, predicted through the wall-clock time since the save
//!   ([`crate::drift::bias::BiasFilter::resume`]). Older than the prior is worth, or saved in
//!   the future (a clock set back), it is not used: the stage starts cold and says why. Such a
//!   file is ours and whole: it stays, and the next save replaces it.
//!
//! How a start went is a [`WarmStart`], which the built stage gives the runtime
//! ([`crate::stages::Stage::warm_start`]) for `run`'s report.
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

/// What a `state_file` held when the pipeline was read.
#[derive(Debug, Clone, PartialEq)]
pub enum Loaded {
    /// No file: the first start.
    Missing,
    /// A state of this owner.
    Saved(Saved),
    /// A file that cannot be used.
    Unusable(Unusable),
}

/// Why a `state_file` cannot be used, and whether it can be moved aside.
#[derive(Debug, Clone, PartialEq)]
pub struct Unusable {
    /// One line naming the file (and its line and column where it does not parse).
    pub why: String,
    /// False for a directory: it is not a file we wrote, and is never moved.
    pub movable: bool,
}

/// The state in `path` for `owner`: missing, saved, or unusable and why.
pub fn load(path: &Path, owner: &Owner) -> Loaded {
    match read(path, owner) {
        Ok(Some(saved)) => Loaded::Saved(saved),
        Ok(None) => Loaded::Missing,
        Err(u) => Loaded::Unusable(u),
    }
}

fn read(path: &Path, owner: &Owner) -> Result<Option<Saved>, Unusable> {
    let shown = path.display();
    let unusable = |why: String| Unusable { why, movable: true };
    let not_ours = "not a bias state driftless wrote";
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) if path.is_dir() => {
            return Err(Unusable {
                why: format!("state_file {shown}: a directory ({e}), not a file"),
                movable: false,
            })
        }
        Err(e) => return Err(unusable(format!("state_file {shown}: cannot be read: {e}"))),
    };
    let text = match String::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => {
            let holds = crate::io::content::classify(e.as_bytes());
            return Err(unusable(format!(
                "state_file {shown}: {not_ours}: it holds {}",
                holds.what()
            )));
        }
    };
    let file: File = toml::from_str(&text).map_err(|e| {
        let src = Src { path, text: &text };
        let why = format!("{not_ours} ({})", e.message().trim_end());
        unusable(src.at(e.span().map_or(0, |s| s.start), why).to_string())
    })?;
    if file.format != FORMAT {
        return Err(unusable(format!(
            "state_file {shown}: format {} (this driftless reads {FORMAT})",
            file.format
        )));
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
        return Err(unusable(format!("state_file {shown}: {why}")));
    }
    let mut filters = Vec::with_capacity(file.axis.len());
    for (k, a) in file.axis.iter().enumerate() {
        let n = a.x.len();
        let bad = |what: &str| unusable(format!("state_file {shown}: axis {}: {what}", AXES[k]));
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

/// Move an unusable state file aside, beside it: `<name>.unusable-<UTC time>`
/// (`YYYYMMDDTHHMMSSZ`: readable, and sorted by name is sorted by time), `-2`, `-3`, ... after
/// it if that name is taken. Its bytes stay as they were; the next save lands at `path`.
pub fn move_aside(path: &Path) -> std::io::Result<PathBuf> {
    let stamp: String = humantime::format_rfc3339_seconds(SystemTime::now())
        .to_string()
        .chars()
        .filter(|c| !matches!(c, '-' | ':'))
        .collect();
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let base = path.with_file_name(format!("{name}.unusable-{stamp}"));
    let mut aside = base.clone();
    let mut n = 1;
    while aside.symlink_metadata().is_ok() {
        n += 1;
        aside = PathBuf::from(format!("{}-{n}", base.display()));
    }
    std::fs::rename(path, &aside)?;
    Ok(aside)
}

/// How a `predict.bias` started: resumed, or cold and why. The built stage gives it to the
/// runtime ([`crate::stages::Stage::warm_start`]); its [`Display`](std::fmt::Display) is the
/// line `run`'s report prints, [`WarmStart::outcome`] a fixed word for programs.
#[derive(Debug, Clone, PartialEq)]
pub enum WarmStart {
    /// No `state_file`: every start is cold.
    NotConfigured,
    /// Resumed from the state saved this long ago.
    Warm {
        /// The state file.
        path: PathBuf,
        /// How long before the start it was saved.
        age: Duration,
    },
    /// No state file yet (the first start): cold.
    ColdNoFile {
        /// The state file to be.
        path: PathBuf,
    },
    /// Saved so long ago that it is worth no more than the prior: cold; the next save
    /// replaces it.
    ColdTooOld {
        /// The state file.
        path: PathBuf,
        /// How long before the start it was saved.
        age: Duration,
    },
    /// Saved in the future (the clock was set back: the time since is unknown): cold; the
    /// next save replaces it.
    ColdFuture {
        /// The state file.
        path: PathBuf,
    },
    /// The file could not be used ([`Unusable`]): cold.
    ColdUnusable {
        /// The state file.
        path: PathBuf,
        /// Why, one line naming the file.
        why: String,
        /// Where it was moved to, byte for byte; None when it was not moved (a directory, or
        /// the move failed: `why` says).
        moved_to: Option<PathBuf>,
    },
}

impl WarmStart {
    /// A fixed word for programs: `not-configured`, `warm`, `cold-no-file`, `cold-too-old`,
    /// `cold-future`, `cold-unusable`.
    pub fn outcome(&self) -> &'static str {
        match self {
            WarmStart::NotConfigured => "not-configured",
            WarmStart::Warm { .. } => "warm",
            WarmStart::ColdNoFile { .. } => "cold-no-file",
            WarmStart::ColdTooOld { .. } => "cold-too-old",
            WarmStart::ColdFuture { .. } => "cold-future",
            WarmStart::ColdUnusable { .. } => "cold-unusable",
        }
    }

    /// The outcome as the stats service carries it ([`crate::wire::WARM_START_WARM`]
    /// and its siblings; the larger, the worse).
    pub fn code(&self) -> u64 {
        use crate::wire::{WARM_START_COLD, WARM_START_NONE, WARM_START_UNUSABLE, WARM_START_WARM};
        match self {
            WarmStart::NotConfigured => WARM_START_NONE,
            WarmStart::Warm { .. } => WARM_START_WARM,
            WarmStart::ColdNoFile { .. }
            | WarmStart::ColdTooOld { .. }
            | WarmStart::ColdFuture { .. } => WARM_START_COLD,
            WarmStart::ColdUnusable { .. } => WARM_START_UNUSABLE,
        }
    }

    /// Whether the filter resumed from a saved state.
    pub fn is_warm(&self) -> bool {
        matches!(self, WarmStart::Warm { .. })
    }
}

impl std::fmt::Display for WarmStart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ago = |age: &Duration| humantime::format_duration(Duration::from_secs(age.as_secs()));
        match self {
            WarmStart::NotConfigured => write!(f, "cold: no state_file"),
            WarmStart::Warm { path, age } => write!(
                f,
                "warm from state_file {}, saved {} ago",
                path.display(),
                ago(age)
            ),
            WarmStart::ColdNoFile { path } => {
                write!(f, "cold: no state_file {} yet", path.display())
            }
            WarmStart::ColdTooOld { path, age } => write!(
                f,
                "cold: state_file {} is {} old, no better than the prior",
                path.display(),
                ago(age)
            ),
            WarmStart::ColdFuture { path } => write!(
                f,
                "cold: state_file {} was saved in the future (the clock was set back?)",
                path.display()
            ),
            WarmStart::ColdUnusable { why, moved_to, .. } => match moved_to {
                Some(to) => write!(f, "cold: {why}; kept as {}", to.display()),
                None => write!(f, "cold: {why}"),
            },
        }
    }
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
        let Loaded::Saved(saved) = load(&path, &owner()) else {
            panic!("its own state")
        };
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
            let Loaded::Unusable(u) = load(&path, &other) else {
                panic!("{why}: refused")
            };
            assert!(u.why.contains(why) && u.movable, "{u:?}");
        }
        // Cut short: refused with a position, never half read.
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(&path, &text[..text.len() / 2]).unwrap();
        let Loaded::Unusable(u) = load(&path, &owner()) else {
            panic!("half a state")
        };
        assert!(
            u.why.contains("s.toml:") && u.why.contains("not a bias state"),
            "{u:?}"
        );
        // Garbage: what it holds.
        std::fs::write(&path, [0x1f, 0x8b, 0, 0xff, 0x10]).unwrap();
        let Loaded::Unusable(u) = load(&path, &owner()) else {
            panic!("garbage")
        };
        assert!(
            u.why
                .ends_with("not a bias state driftless wrote: it holds a damaged gzip stream"),
            "{u:?}"
        );
        // Moved aside byte for byte, beside it, and a second one in the same second too.
        let first = move_aside(&path).unwrap();
        std::fs::write(&path, b"x = ").unwrap();
        let second = move_aside(&path).unwrap();
        assert_eq!(std::fs::read(&first).unwrap(), [0x1f, 0x8b, 0, 0xff, 0x10]);
        assert_eq!(std::fs::read(&second).unwrap(), b"x = ");
        assert!(!path.exists());
        let name = first.file_name().unwrap().to_string_lossy().into_owned();
        let stamp = name.strip_prefix("s.toml.unusable-").unwrap();
        assert!(
            stamp.len() == 16 && stamp.as_bytes()[8] == b'T' && stamp.ends_with('Z'),
            "{name}"
        );
        assert!(
            second.to_string_lossy().ends_with("-2")
                || second.to_string_lossy() > first.to_string_lossy(),
            "{second:?}"
        );
        // A directory: unusable, never moved.
        std::fs::create_dir(&path).unwrap();
        let Loaded::Unusable(u) = load(&path, &owner()) else {
            panic!("a directory")
        };
        assert!(!u.movable && u.why.contains("a directory"), "{u:?}");
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(load(&path, &owner()), Loaded::Missing, "no file: cold");
    }
}
