//! The drift model: separate the gyro's slow drift from its noise, model the drift with the
//! paper's Gaussian RBF network, judge it against simple baselines, and compensate live without
//! ever subtracting real rotation.
//!
//! - [`lowband`]: the causal drift separation (the low band of the rate, one sample at a time).
//! - [`rbf`]: the Gaussian RBF network (the paper's eq. 6-7), with optional linear terms.
//! - [`training`]: centres (k-means++ or OLS forward selection), widths, ridge weights, Adam.
//! - [`baselines`]: persistence, mean and AR(p) predictors; one-step and free-running scores.
//! - [`model`]: the versioned model file (JSON) with its checks.
//! - [`stillness`]: the stillness detector that decides when the low band is drift.
//! - [`accel_rest`]: the accelerometer's half of the rest test (has the force stayed constant,
//!   and since when), beside the gyro's.
//! - [`compensator`]: per-sample live compensation, anchored only while still.
//! - [`evaluation`]: a model on a record, the paper's Table 3 (`driftless eval`).
//! - [`fit`]: a model from a static record, scored on its held-out part (`driftless train`).
//! - [`bias`]: a Kalman filter on the bias with noise from the Allan terms, updated only while
//!   confirmed still (the estimator judged by heading error in [`crate::nav`]).
//!
//! Pure maths: nothing here does I/O ([`crate::io::model_file`] reads and writes model files).
//!
//! # Why the separation is causal
//! Denoising or splitting the whole record before the train/test split lets future samples into
//! the drift the model is tested on (look-ahead leakage), and the daemon cannot see the future
//! either. So the drift the network learns is exactly what the daemon measures: the streaming
//! denoiser's output passed through the causal low band ([`lowband::LowBand`]). A training row
//! at sample t only depends on samples <= t.

pub mod accel_rest;
pub mod baselines;
pub mod bias;
pub mod compensator;
pub mod evaluation;
pub mod fit;
pub mod lowband;
pub mod model;
pub mod rbf;
pub mod separation;
pub mod stillness;
pub mod training;

pub use baselines::Predictor;
pub use bias::{BiasMode, BiasStep, BiasTerms, BiasTracker, TrackerConfig};
pub use compensator::{Compensator, Mode as CompMode, Step};
pub use lowband::LowBand;
pub use model::{DriftModel, ModelError, ModelPredictor, PredictorKind};
pub use rbf::{InputForm, Rbf, Target};
pub use stillness::{StillnessConfig, StillnessDetector};
pub use training::{train, TrainConfig, TrainError};

/// Most lagged inputs a model may have (predictions keep their inputs on the stack).
pub const MAX_LAGS: usize = 32;
