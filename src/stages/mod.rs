//! The stage kinds, one file each: every file owns its kind's keys (with types, ranges and
//! defaults), their validation, how the stage is built, and the line that documents it.
//!
//! | kind | file | role |
//! |---|---|---|
//! | `ingest.sim` | [`ingest_sim`] | simulated sensor, paced in real time |
//! | `ingest.csv` | [`ingest_csv`] | CSV replay, real time or as fast as possible |
//! | `ingest.mcap` | [`ingest_mcap`] | replay of a `driftless record` recording (MCAP), real time or as fast as possible |
//! | `ingest.iceoryx2` | [`ingest_iceoryx2`] | raw samples from a driver in another process |
//! | `denoise.wavelet`, `denoise.none` | [`denoise`] | streaming wavelet denoiser / pass-through |
//! | `predict.none`, `predict.rbf` | [`predict`] | drift estimate 0 / the RBF drift model, gated by stillness |
//! | `predict.bias` | [`predict_bias`] | the bias as a Kalman state from the gyro's Allan terms (no training) |
//! | `external` | [`external`] | a stage run by another process (the daemon only links to it) |
//! | `publish` | [`publish`] | the final guard before the public service |
//!
//! [`replay`] is what the file replays (`ingest.csv`, `ingest.mcap`) share: the reader thread,
//! its blocks of samples and the pacing.
//!
//! # Adding a stage kind
//! 1. Write `src/stages/<kind>.rs` with: its keys as [`Key`](crate::pipeline::schema::Key)
//!    constants; a parse function reading them from the
//!    [`StageTable`](crate::pipeline::schema::StageTable) (it checks types, ranges and anything
//!    else `run` needs, positioning every error) and returning its parameters; a parameters
//!    type implementing [`Params`](crate::pipeline::stage::Params) (how the stage or source is
//!    built, what `validate` says of it); and a `pub const KIND: Kind` tying them together with
//!    its name, [`Role`](crate::pipeline::stage::Role) and one-line summary.
//! 2. Add `pub mod <kind>;` below and its `KIND` to [`KINDS`].
//!
//! Nothing else changes: the pipeline file's reader finds the kind in [`KINDS`], rejects keys
//! the kind does not declare (naming the kind a stray key belongs to), and `driftless validate
//! --kinds` and the stage table of `docs/daemon.md` list the new keys.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::pipeline::config::{Pipeline, StageSpec};
use crate::pipeline::stage::{Kind, Stage};

pub mod denoise;
pub mod external;
pub mod ingest_csv;
pub mod ingest_iceoryx2;
pub mod ingest_mcap;
pub mod ingest_sim;
pub mod predict;
pub mod predict_bias;
pub mod publish;
pub mod replay;

/// Every stage kind, in the order listed in messages and documentation.
pub const KINDS: &[&Kind] = &[
    &ingest_sim::KIND,
    &ingest_csv::KIND,
    &ingest_mcap::KIND,
    &ingest_iceoryx2::KIND,
    &denoise::WAVELET_KIND,
    &denoise::NONE_KIND,
    &predict::NONE_KIND,
    &predict::RBF_KIND,
    &predict_bias::KIND,
    &external::KIND,
    &publish::KIND,
];

/// Build the processing stage of a validated spec, as the daemon does. Errors are parameter
/// errors that validation should already have caught.
pub fn build(spec: &StageSpec, pipeline: &Pipeline) -> Result<Box<dyn Stage>, String> {
    spec.params.stage(&pipeline.context())
}

/// The clock of a paced source: when its first sample is due, as an instant to sleep until and
/// as [`monotonic_ns`](crate::transport::monotonic_ns) to measure lateness on. Pipelines that
/// share one hot thread share one ([`Source::share_clock`](crate::pipeline::stage::Source)).
#[derive(Debug, Clone, Copy)]
pub struct PaceClock {
    start: Instant,
    start_ns: u64,
}

impl PaceClock {
    /// A clock starting now.
    pub fn now() -> Self {
        PaceClock {
            start: Instant::now(),
            start_ns: crate::transport::monotonic_ns(),
        }
    }

    /// The instant `offset` after the start.
    pub(crate) fn at(&self, offset: Duration) -> Instant {
        self.start + offset
    }

    /// Sleep until `offset` after the start (noticing `stop`); returns when that was due, in
    /// monotonic ns, or None when stopped first.
    pub(crate) fn wait(&self, offset: Duration, stop: &AtomicBool) -> Option<u64> {
        sleep_until(self.at(offset), stop)
            .then(|| self.start_ns.saturating_add(offset.as_nanos() as u64))
    }
}

/// Sleep until `due` (a monotonic instant), in slices short enough to notice `stop`.
/// Returns false when stopped first.
pub(crate) fn sleep_until(due: Instant, stop: &AtomicBool) -> bool {
    const SLICE: Duration = Duration::from_millis(20);
    loop {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        let now = Instant::now();
        if now >= due {
            return true;
        }
        std::thread::sleep((due - now).min(SLICE));
    }
}
