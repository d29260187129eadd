//! # driftless
//!
//! Real-time cleaning of MEMS gyroscope rates. A sample enters at **ingest** (a sensor driver's
//! iceoryx2 service, a CSV or MCAP replay, or the built-in simulator), passes a **windowed
//! wavelet denoiser** (or none), then a **drift predictor** (by default a Kalman filter on the
//! bias, driven by the gyro's own Allan terms and re-measured at each stop; or the paper's RBF
//! network), and leaves at **publish**; every hop is a zero-copy iceoryx2 service. Offline
//! commands characterise a gyro (Allan deviation, IEEE 952 noise terms), denoise logs, train and
//! evaluate the drift model, and judge every method by the heading error a navigator would see.
//!
//! Layers, from the ground up (ARCHITECTURE.md; `tests/layers.rs` checks them): [`clock`],
//! [`units`], [`wire`] (the types that cross shared memory) and the maths ([`wavelet`],
//! [`allan`], [`sim`], [`drift`], [`attitude`], [`nav`], ...: no I/O, no transport, usable as a
//! library) -> [`io`] (files) -> [`transport`] (iceoryx2, and the ROS 2 and Zenoh rooms) ->
//! [`rate_log`] -> `metrics` -> [`stages`] (the stage contract and every stage kind) -> `sides`
//! (what runs beside a chain) -> [`pipeline`] (the pipeline file, the runtime) -> `nav_eval`
//! (the heading benchmark on the daemon's stages) -> `cli`. Each imports only from below.
//!
//! The library's surface is listed in ARCHITECTURE.md ("The library's surface"). [`cli`],
//! `metrics`, `sides`, `nav_eval` and `bigbuf` are the daemon's inside, public only for its
//! binary, tests and benches; all but `cli` (the commands) are hidden from these docs.

#![warn(missing_docs)]

pub mod allan;
pub mod attitude;
#[doc(hidden)]
pub mod bigbuf;
pub mod cli;
pub mod clock;
pub mod drift;
pub mod io;
#[doc(hidden)]
pub mod metrics;
pub mod nav;
#[doc(hidden)]
pub mod nav_eval;
pub mod pipeline;
pub mod quality;
pub mod rate_log;
#[doc(hidden)]
pub mod sides;
pub mod sim;
pub mod stages;
pub mod synthetic;
pub mod transport;
pub mod units;
pub mod wavelet;
pub mod wire;
