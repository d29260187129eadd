//! The heading benchmark of `driftless nav-eval`, as a library. Known motion (a built-in
//! profile, [`crate::nav::profiles`], or a truth file, [`crate::io::truth`]) is added to windows
//! of a static gyro record (or of the simulator's noise), every method corrects the sum, and each
//! is judged by the heading error a navigator integrating it would see, window by window, against
//! ZARU with the true stops.
//!
//! - [`source`]: the static noise ([`Source`]) and the noise terms of its characterisation part.
//! - [`chains`]: the methods that run a pipeline's stages offline ([`Chain`]): the product's
//!   chain, the same reading the true stops as a vehicle's stop signal, the paper's RBF chain and
//!   its AR(p), and any pipeline file.
//! - [`mod@bench`]: the window loop ([`Bench::run`]) and what it finds ([`Outcome`]).
//!
//! The room sits above [`crate::pipeline`] (it runs the daemon's stages,
//! [`crate::pipeline::offline::Offline`]) and below [`crate::cli`], which parses the command's
//! options, opens its inputs, and prints. Its errors are the command's: a message may name the
//! option a value came from.

pub mod bench;
pub mod chains;
pub mod source;

pub use bench::{
    Bench, Case, HeadingTraces, Motion, OdometryComparison, OdometryVariant, Outcome, Section,
    FUSION_LABEL,
};
pub use chains::Chain;
pub use source::Source;

/// Why the benchmark cannot run.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NavEvalError {
    /// The inputs cannot be judged: a record too short, a model or pipeline that does not fit,
    /// terms the record cannot give.
    #[error("{0}")]
    Input(String),
    /// A failure that is not the inputs' fault (a built-in motion or noise model refused).
    #[error("{0}")]
    Internal(String),
}

impl From<crate::io::InputError> for NavEvalError {
    fn from(e: crate::io::InputError) -> Self {
        NavEvalError::Input(e.to_string())
    }
}
