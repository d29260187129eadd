//! The navigation benchmark: what a navigator judges a gyro correction by, the heading error of
//! the integrated rate, measured against the baselines they already have.
//!
//! - [`profiles`]: known motion (stop-and-go, vehicle, continuous, pedestrian) with the oracle
//!   still mask, deterministic from (rate, duration, seed), to add to a static record.
//! - [`metrics`]: heading error series, final / RMS / max heading error and RMS rate error;
//!   median, worst and per-window ratios over many windows.
//! - [`baselines`]: causal per-sample bias estimators behind [`baselines::BiasEstimator`]: raw,
//!   power-on bias, ZARU with oracle or detected stops, and the new estimator
//!   ([`crate::drift::bias::BiasTracker`]).
//! - [`force`]: the accelerometer's side of a profile: the vehicle's body acceleration at each
//!   sample (longitudinal at starts and stops, centripetal in turns) from its stated speed.
//! - [`mod@odometry`]: a wheel odometry's yaw rate derived from a profile's truth with stated errors
//!   (scale, ticks, noise, slip, latency), and the bias filter given the true stops and it.
//! - [`fusion`]: x-io Fusion's gyroscope bias algorithm, three axes at once, as deployed.
//! - [`eval`]: every method on one window, and summaries against a reference (oracle ZARU).
//!
//! Pure: no I/O. Results on the real ADIS16405 log and the simulator: docs/navigation.md and
//! tests/nav_*.rs.

pub mod baselines;
pub mod eval;
pub mod force;
pub mod fusion;
pub mod metrics;
pub mod odometry;
pub mod profiles;

pub use baselines::{BiasEstimator, Raw, Tracked, Zaru};
pub use eval::{
    evaluate, format_table, format_table_labelled, summarize_methods, EvalError, Method,
    MethodSummary, Setup,
};
pub use force::body_acceleration;
pub use metrics::{
    heading_error, heading_metrics, summarize, HeadingAccumulator, HeadingMetrics, Summary,
};
pub use odometry::{evaluate_odometry, odometry, OdometryModel, OdometryTrace};
pub use profiles::{generate, MotionTrace, Profile, ProfileError};
