//! What every stage that keeps state across runs shares (`predict.bias`'s [`super::bias_state`],
//! `attitude.6d`'s [`super::attitude_state`]): the file read and parsed with its line and
//! column, moved aside when unusable, written atomically by a thread of its own, and how a
//! start went ([`WarmStart`]).
//!
//! - **Written atomically** by a thread of its own (never the hot thread): a temporary file in
//!   the same directory, synced, renamed over the old one, the directory synced. A crash
//!   leaves the old state or the new one, never half of one.
//! - **Unusable** ([`Unusable`]): a file that does not parse (with its line and column),
//!   garbage, or one that cannot be read. A cache must never cost the navigation: the stage
//!   starts cold, says why in one line, and moves the file aside to
//!   `<name>.unusable-<UTC time>` ([`move_aside`], [`cold_unusable`]) so that nothing is lost
//!   and the next save lands where the last one was.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use crossbeam_channel::{bounded, Receiver, Sender};

use crate::stages::schema::Src;

/// Why a `state_file` cannot be used, and whether it can be moved aside.
#[derive(Debug, Clone, PartialEq)]
pub struct Unusable {
    /// One line naming the file (and its line and column where it does not parse).
    pub why: String,
    /// False for a directory: it is not a file we wrote, and is never moved.
    pub movable: bool,
}

impl Unusable {
    /// A file we may move aside, unusable for `why`.
    pub fn movable(why: String) -> Unusable {
        Unusable { why, movable: true }
    }
}

/// What a `state_file` held when the pipeline was read: `T`, a state of this owner.
#[derive(Debug, Clone, PartialEq)]
pub enum Loaded<T> {
    /// No file: the first start.
    Missing,
    /// A state of this owner.
    Saved(T),
    /// A file that cannot be used.
    Unusable(Unusable),
}

impl<T> From<Result<Option<T>, Unusable>> for Loaded<T> {
    fn from(read: Result<Option<T>, Unusable>) -> Self {
        match read {
            Ok(Some(saved)) => Loaded::Saved(saved),
            Ok(None) => Loaded::Missing,
            Err(u) => Loaded::Unusable(u),
        }
    }
}

/// The file at `path` parsed as TOML into `T`: None if there is none; unusable if it cannot be
/// read, is not text, or does not parse as `T` (`not_ours` says what it is not, e.g. "not a
/// bias state driftless wrote", and the error gives the line and column).
pub fn read_toml<T: serde::de::DeserializeOwned>(
    path: &Path,
    not_ours: &str,
) -> Result<Option<T>, Unusable> {
    let shown = path.display();
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) if path.is_dir() => {
            return Err(Unusable {
                why: format!("state_file {shown}: a directory ({e}), not a file"),
                movable: false,
            })
        }
        Err(e) => {
            return Err(Unusable::movable(format!(
                "state_file {shown}: cannot be read: {e}"
            )))
        }
    };
    let text = match String::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => {
            let holds = crate::io::content::classify(e.as_bytes());
            return Err(Unusable::movable(format!(
                "state_file {shown}: {not_ours}: it holds {}",
                holds.what()
            )));
        }
    };
    toml::from_str(&text).map(Some).map_err(|e| {
        let src = Src { path, text: &text };
        let why = format!("{not_ours} ({})", e.message().trim_end());
        Unusable::movable(src.at(e.span().map_or(0, |s| s.start), why).to_string())
    })
}

/// Now, ns since the Unix epoch (0 if the clock is before it).
pub fn unix_now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// How long ago `saved_unix_ns` was; None if in the future by more than a second (a clock set
/// back: the time between is unknown).
pub fn age(saved_unix_ns: u64) -> Option<Duration> {
    let saved = UNIX_EPOCH + Duration::from_nanos(saved_unix_ns);
    match SystemTime::now().duration_since(saved) {
        Ok(age) => Some(age),
        Err(e) if e.duration() <= Duration::from_secs(1) => Some(Duration::ZERO),
        Err(_) => None,
    }
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

/// A state that cannot be used costs the warm start, never the start: cold, the file moved
/// aside (a directory stays), one line saying why, that `who` (e.g. "the filter") starts cold
/// and where the file went.
pub fn cold_unusable(path: &Path, u: &Unusable, who: &str) -> WarmStart {
    let (moved_to, why, kept) = if u.movable {
        match move_aside(path) {
            Ok(to) => {
                let kept = format!("the file is kept as {}", to.display());
                (Some(to), u.why.clone(), kept)
            }
            Err(e) => (
                None,
                format!("{} (not moved aside: {e})", u.why),
                format!("it could not be moved aside ({e}) and stays"),
            ),
        }
    } else {
        let kept = "no state can be saved there either: point state_file at a file".to_string();
        (None, u.why.clone(), kept)
    };
    eprintln!("driftless: warning: {}: {who} starts cold; {kept}", u.why);
    WarmStart::ColdUnusable {
        path: path.to_path_buf(),
        why,
        moved_to,
    }
}

/// How a stage that keeps state started: resumed, or cold and why. The built stage gives it to
/// the runtime ([`crate::stages::Stage::warm_start`]); its [`Display`](std::fmt::Display) is
/// the line `run`'s report prints, [`WarmStart::outcome`] a fixed word for programs.
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

/// Write `text` to `path` atomically: a temporary file beside it, synced, renamed over it, the
/// directory synced.
pub fn write_atomically(path: &Path, text: &str) -> std::io::Result<()> {
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

/// The thread that writes a state: the hot thread hands it snapshots `S` (boxed, the boxes
/// reused: the hot thread never allocates one after the first), never waiting.
pub struct StateWriter<S: Send + 'static> {
    tx: Option<Sender<Box<S>>>,
    spare: Receiver<Box<S>>,
    empty: fn() -> S,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl<S: Send + 'static> StateWriter<S> {
    /// Start the writer of `path`: `render` makes a snapshot the file's text, given the time of
    /// the save (ns since the Unix epoch); `empty` makes a blank snapshot to fill.
    pub fn start(
        path: PathBuf,
        render: impl Fn(&S, u64) -> String + Send + 'static,
        empty: fn() -> S,
    ) -> Result<StateWriter<S>, String> {
        let (tx, rx) = bounded::<Box<S>>(1);
        let (back, spare) = bounded::<Box<S>>(2);
        for _ in 0..2 {
            let _ = back.send(Box::new(empty()));
        }
        let thread = std::thread::Builder::new()
            .name("driftless-state".into())
            .spawn(move || {
                let mut failed = false;
                for snap in rx {
                    let text = render(&snap, unix_now_ns());
                    let _ = back.try_send(snap);
                    match write_atomically(&path, &text) {
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
            empty,
            thread: Some(thread),
        })
    }

    /// Hand over a snapshot without waiting; skipped if the last is still being written.
    pub fn offer(&self, fill: impl FnOnce(&mut S)) {
        let Some(tx) = &self.tx else { return };
        if tx.is_full() {
            return;
        }
        let mut snap = self
            .spare
            .try_recv()
            .unwrap_or_else(|_| Box::new((self.empty)()));
        fill(&mut snap);
        let _ = tx.try_send(snap);
    }

    /// The last snapshot (shutdown): waits until it is written.
    pub fn finish(mut self, last: S) {
        if let Some(tx) = self.tx.take() {
            let _ = tx.send(Box::new(last));
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl<S: Send + 'static> Drop for StateWriter<S> {
    fn drop(&mut self) {
        self.tx.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Moved aside byte for byte, beside it, and a second one in the same second too; a
    /// directory is unusable and never moved; written atomically through the writer thread.
    #[test]
    fn files_are_moved_aside_and_written_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(&path, [0x1f, 0x8b, 0, 0xff, 0x10]).unwrap();
        let u = read_toml::<toml::Table>(&path, "not a state").unwrap_err();
        assert!(
            u.why
                .ends_with("not a state: it holds a damaged gzip stream"),
            "{u:?}"
        );
        let first = move_aside(&path).unwrap();
        std::fs::write(&path, b"x = ").unwrap();
        let u = read_toml::<toml::Table>(&path, "not a state").unwrap_err();
        assert!(u.why.contains("s.toml:1:") && u.movable, "{u:?}");
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
        assert_ne!(first, second);
        assert_eq!(read_toml::<toml::Table>(&path, "x"), Ok(None), "no file");
        std::fs::create_dir(&path).unwrap();
        let u = read_toml::<toml::Table>(&path, "x").unwrap_err();
        assert!(!u.movable && u.why.contains("a directory"), "{u:?}");
        std::fs::remove_dir(&path).unwrap();

        let writer =
            StateWriter::start(path.clone(), |v: &u32, _| format!("v = {v}\n"), || 0).unwrap();
        writer.offer(|v| *v = 1);
        writer.finish(2);
        let back: toml::Table = read_toml(&path, "x").unwrap().unwrap();
        assert_eq!(back["v"].as_integer(), Some(2));
    }
}
