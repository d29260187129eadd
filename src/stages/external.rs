//! `external`: a stage that lives in another process.
//!
//! ```toml
//! [[stage]]
//! name = "my-filter"
//! kind = "external"
//! input = "demo/denoised"     # published by the daemon; the external process reads it
//! output = "demo/filtered"    # published by the external process; the daemon reads it
//! # poll_timeout_us = 1000    # safety-net timeout of the daemon's wait on `output`
//! ```
//!
//! The daemon does not run it: the pipeline splits into segments at each `external` stage
//! ([`crate::pipeline::runtime`]). The external process must read [`GyroSample`]s from `input`,
//! publish one [`GyroSample`] per sample on `output` with `seq`, `t_ns` and `ingest_ns` passed
//! through unchanged (so losses are counted and end-to-end latency stays measured from the
//! ingest), and notify the event service of the same name as `output` after each sample (as
//! our `publish` stage does) so the daemon sleeps until data arrives.
//!
//! [`relay`] is a reference external process (`driftless relay`, `examples/external_stage.rs`):
//! it applies a fixed scale and offset to `rate` and `denoised` and keeps every other field.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use crate::io::InputError;
use crate::stages::contract::{Kind, Params, Role};
use crate::stages::schema::{Table, POLL_TIMEOUT_US};
use crate::transport::{Qos, Transport, TransportError};
use crate::wire::GyroSample;

/// `external`.
pub const KIND: Kind = Kind {
    name: "external",
    role: Role::External,
    summary: "a stage another process runs: it reads `input` and publishes `output` (both driftless::GyroSample); not first after the ingest, not last, not two in a row",
    keys: &[POLL_TIMEOUT_US],
    parse,
};

/// `external` parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExternalParams {
    /// How long the segment after it sleeps waiting for a sample before checking for
    /// shutdown (a safety net: the external process should notify after each sample).
    pub poll_timeout: Duration,
}

fn parse(t: &mut Table<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    Ok(Box::new(ExternalParams {
        poll_timeout: t.poll_timeout(&POLL_TIMEOUT_US)?,
    }))
}

impl Params for ExternalParams {
    fn poll_timeout(&self) -> Duration {
        self.poll_timeout
    }

    fn describe(&self, input: Option<&str>, output: &str) -> Vec<String> {
        vec![format!(
            "runs in another process: it reads {} and must publish {output} (and notify it)",
            input.unwrap_or("-")
        )]
    }
}

/// Settings of the reference external process.
#[derive(Debug, Clone)]
pub struct RelayOptions {
    /// iceoryx2 prefix (the daemon's).
    pub prefix: String,
    /// Service to read (the external stage's `input`).
    pub input: String,
    /// Service to publish (the external stage's `output`).
    pub output: String,
    /// `rate` and `denoised` are multiplied by this...
    pub scale: f64,
    /// ...then this is added.
    pub offset: f64,
    /// Exit after this many samples (None: until stopped).
    pub count: Option<u64>,
    /// Quality of service for the services it creates (match the pipeline's `[iceoryx2]`).
    pub qos: Qos,
    /// Safety-net timeout of each wait (the daemon notifies after each sample).
    pub poll_timeout: Duration,
    /// Sleep this long before relaying each sample: plays a slow external stage (tests).
    pub delay: Duration,
}

/// The transform of the reference external process: `x * scale + offset` on every axis of
/// `rate` and `denoised`; everything else (seq, timestamps, drift, flags) unchanged.
pub fn transform(s: &GyroSample, scale: f64, offset: f64) -> GyroSample {
    let mut out = *s;
    for v in out.rate.iter_mut().chain(out.denoised.iter_mut()) {
        *v = *v * scale + offset;
    }
    out
}

/// Run the reference external process until `stop` is set or `count` samples were relayed;
/// `ready` is called once its ports exist. Returns the number of samples relayed.
/// Allocation-free per sample.
pub fn relay(
    opts: &RelayOptions,
    stop: &AtomicBool,
    ready: impl FnOnce(),
) -> Result<u64, TransportError> {
    crate::transport::quiet_logging();
    let t = Transport::new(&opts.prefix, "driftless-relay", opts.qos)?;
    let input = t.external_input::<GyroSample>(&opts.input)?;
    let waker = t.waker(&opts.input)?;
    let output = t.external_output::<GyroSample>(&opts.output, true)?;
    ready();
    let mut n = 0u64;
    while !stop.load(Ordering::Relaxed) && opts.count.is_none_or(|c| n < c) {
        match input.receive()? {
            Some(s) => {
                if !opts.delay.is_zero() {
                    std::thread::sleep(opts.delay);
                }
                output.send(&transform(&s, opts.scale, opts.offset))?;
                output.notify();
                n += 1;
            }
            // An error is a signal interrupting the wait: the loop condition decides.
            None => {
                let _ = waker.wait(opts.poll_timeout);
            }
        }
    }
    drop((input, waker, output));
    drop(t);
    crate::transport::remove_prefix_leftovers(&opts.prefix);
    Ok(n)
}
