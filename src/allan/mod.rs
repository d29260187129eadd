//! Allan analysis of gyro rate and accelerometer records: deviations with confidence intervals,
//! and the IEEE Std 952 noise terms fitted to them (an accelerometer's are the same model: velocity
//! random walk for N, acceleration random walk for K; [`units::Sensor`] names them).
//!
//! Pure maths: no I/O. The conventions follow allantools 2024.06 for rate ("frequency") data, so
//! results can be checked against it to 1e-9 relative:
//!
//! * [`deviation`]: rates to phase, tau grids, OADEV / ADEV / MDEV / overlapping HDEV, the number
//!   of terms, and the chi-squared confidence interval of each point.
//! * [`edf`]: Greenhall & Riley's equivalent degrees of freedom (allantools `edf_greenhall`).
//! * [`chi2`]: the chi-squared quantiles behind the intervals (no external statistics crate).
//! * [`fit`]: the IEEE Std 952 terms Q, N, B, K, R by a weighted non-negative least-squares fit,
//!   with intervals, plus the classic slope-line read-offs.
//! * [`units`]: rate and acceleration units in, term names and units out, per [`Sensor`].
//! * [`pool`]: several records' curves pooled per tau (never joined end to end), with the
//!   summed degrees of freedom.
//! * [`analysis`]: a record's whole analysis as `driftless allan` reports it: the curve asked
//!   for, the octave curve, the fit and the read-offs, telling its progress.

pub mod analysis;
pub mod chi2;
pub mod deviation;
pub mod edf;
pub mod fit;
pub mod pool;
pub mod units;

pub use crate::units::{AccelUnit, RateUnit, STANDARD_GRAVITY};
pub use deviation::{allan, AllanError, AllanPoint, Kind, NoiseId, TauGrid};
pub use fit::{fit_terms, read_offs, Estimate, FitError, NoiseFit, TermFit};
pub use units::Term;
pub use units::TermUnits;
pub use units::{SampleUnit, Sensor};
