//! The stage kinds, one file each: every file owns its kind's keys (with types, ranges and
//! defaults), their validation, how the stage is built, and the line that documents it.
//!
//! | kind | file | role |
//! |---|---|---|
//! | `ingest.sim` | [`ingest_sim`] | simulated sensor, paced in real time or a factor faster |
//! | `ingest.csv` | [`ingest_csv`] | CSV replay, real time, a factor faster or as fast as possible |
//! | `ingest.mcap` | [`ingest_mcap`] | replay of a `driftless record` recording (MCAP), real time, a factor faster or as fast as possible |
//! | `ingest.iceoryx2` | [`ingest_iceoryx2`] | raw samples from a driver in another process |
//! | `denoise.wavelet`, `denoise.none` | [`denoise`] | streaming wavelet denoiser / pass-through |
//! | `predict.none`, `predict.rbf` | [`predict`] | drift estimate 0 / the RBF drift model, gated by stillness |
//! | `predict.bias` | [`predict_bias`] | the bias as a Kalman state from the gyro's Allan terms (no training) |
//! | `external` | [`external`] | a stage run by another process (the daemon only links to it) |
//! | `publish` | [`publish`] | the final guard before the public service |
//!
//! [`replay`] is what the file replays (`ingest.csv`, `ingest.mcap`) share: the reader thread,
//! its blocks of samples and the pacing. [`bias_state`] is `predict.bias`'s saved state (its
//! warm start): the file, its checks and its writer thread.
//!
//! # Adding a stage kind
//! 1. Write `src/stages/<kind>.rs` with: its keys as [`Key`](crate::stages::schema::Key)
//!    constants; a parse function reading them from the
//!    [`StageTable`](crate::stages::schema::StageTable) (it checks types, ranges and anything
//!    else `run` needs, positioning every error) and returning its parameters; a parameters
//!    type implementing [`Params`](crate::stages::contract::Params) (how the stage or source is
//!    built, what `validate` says of it); and a `pub const KIND: Kind` tying them together with
//!    its name, [`Role`](crate::stages::contract::Role) and one-line summary.
//! 2. Add `pub mod <kind>;` below and its `KIND` to [`KINDS`].
//!
//! Nothing else changes: the pipeline file's reader finds the kind in [`KINDS`], rejects keys
//! the kind does not declare (naming the kind a stray key belongs to), and `driftless validate
//! --kinds` and `docs/reference/pipeline-file.md` (generated from it) list the new keys.

pub mod bias_state;
pub mod contract;
pub mod schema;

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
pub mod stop_rule;

pub use bias_state::WarmStart;
pub use contract::{Kind, Params, Poll, Role, Side, SideKind, Source, Stage};

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
