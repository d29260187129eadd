//! The stage contract.
//!
//! A stage is built from its validated TOML table ([`crate::pipeline::StageSpec`]), then called
//! once per sample with [`Stage::process`], which must not allocate; at shutdown the runtime
//! calls [`Stage::flush`] until it returns `None` to drain what a lagged stage still holds.
//! The runtime, not the stage, owns services, clocks, histograms and shutdown.
//!
//! An ingest is a [`Source`]: the runtime asks it for the next raw sample; a real-time source
//! sleeps until that sample is due.

use std::sync::atomic::AtomicBool;

use crate::transport::{GyroSample, RawSample};

/// A processing stage: one sample in, at most one sample out.
pub trait Stage {
    /// Process one sample. `None`: nothing to emit yet (a lagged stage filling up).
    /// Must not allocate.
    fn process(&mut self, input: &GyroSample) -> Option<GyroSample>;

    /// At shutdown: the next held sample, oldest first; `None` once drained.
    fn flush(&mut self) -> Option<GyroSample> {
        None
    }

    /// Algorithmic delay in samples (output `t` leaves when sample `t + lag` arrives).
    fn lag(&self) -> usize {
        0
    }
}

/// What a source has for the runtime.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Poll {
    /// A raw sample, ingested at `ingest_ns` ([`crate::transport::monotonic_ns`]).
    Sample(RawSample, u64),
    /// Nothing now (a timeout passed): check for shutdown and ask again.
    Idle,
    /// The source is exhausted: drain and stop.
    End,
}

/// An ingest stage.
pub trait Source {
    /// The next raw sample; may sleep until it is due, but returns `Idle` within a few
    /// milliseconds when `stop` is set. Must not allocate.
    fn poll(&mut self, stop: &AtomicBool) -> Poll;
}
