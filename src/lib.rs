//! # driftless
//!
//! Real-time cleaning of MEMS gyroscope rates. A sample enters at **ingest** (a sensor service, a
//! CSV replay or the built-in simulator), passes a **windowed wavelet denoiser**, then a **drift
//! predictor** (an RBF network trained on the gyro's drift), and leaves at **publish**; every hop is
//! a zero-copy iceoryx2 service. Offline commands characterise a gyro (Allan deviation, IEEE 952
//! noise terms), denoise logs, and train and evaluate the drift model.
//!
//! The maths modules ([`wavelet`], ...) are pure: no I/O, no transport, usable as a library.
//! Layers, from the ground up: maths -> pipeline and stages -> transport -> [`cli`].

#![warn(missing_docs)]

pub mod allan;
pub mod bigbuf;
pub mod cli;
pub mod drift;
pub mod io;
pub mod metrics;
pub mod nav;
pub mod pipeline;
pub mod quality;
pub mod sim;
pub mod stages;
pub mod synthetic;
pub mod transport;
pub mod wavelet;
