//! `ingest.iceoryx2`: raw samples that a sensor driver in another process publishes on an
//! iceoryx2 service ([`crate::wire::RawSample`]). The daemon's hot thread sleeps on the
//! event service of the same name (a driver should notify it after each sample), together with
//! every other source of the daemon, and with a timeout, so a driver that does not notify is
//! still read within `poll_timeout_us`.
//!
//! ```toml
//! [[stage]]
//! name = "sensor"
//! kind = "ingest.iceoryx2"
//! input = "sensor/raw"        # published by the driver
//! output = "ext/raw"
//! # poll_timeout_us = 1000
//! ```

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use crate::io::InputError;
use crate::stages::contract::{Kind, Params, Poll, Role, Source};
use crate::stages::schema::{Context, Table, POLL_TIMEOUT_US};
use crate::transport::{Input, Transport, TransportError, Waker};
use crate::wire::RawSample;

/// `ingest.iceoryx2`.
pub const KIND: Kind = Kind {
    name: "ingest.iceoryx2",
    role: Role::Ingest { has_input: true },
    summary: "raw samples (driftless::RawSample) a sensor driver publishes on `input` from another process",
    keys: &[POLL_TIMEOUT_US],
    parse,
};

/// `ingest.iceoryx2` parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Iceoryx2Params {
    /// How long to sleep waiting for a sample before checking for shutdown.
    pub poll_timeout: Duration,
}

fn parse(t: &mut Table<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    Ok(Box::new(Iceoryx2Params {
        poll_timeout: t.poll_timeout(&POLL_TIMEOUT_US)?,
    }))
}

impl Params for Iceoryx2Params {
    fn source(
        &self,
        _cx: &Context,
        transport: &Transport,
        input: Option<&str>,
    ) -> Result<Box<dyn Source>, String> {
        let input = input.ok_or("ingest.iceoryx2 needs an input service")?;
        ExternalRaw::new(transport, input, self.poll_timeout)
            .map(|s| Box::new(s) as Box<dyn Source>)
            .map_err(|e| e.to_string())
    }
}

/// Reads a raw service of another process.
pub struct ExternalRaw {
    input: Input<RawSample>,
    waker: Waker,
    timeout: Duration,
}

impl ExternalRaw {
    /// Subscribe to `service` (created with our QoS if the driver has not started yet).
    pub fn new(
        transport: &Transport,
        service: &str,
        timeout: Duration,
    ) -> Result<Self, TransportError> {
        Ok(ExternalRaw {
            input: transport.external_input::<RawSample>(service)?,
            waker: transport.waker(service)?,
            timeout,
        })
    }
}

impl Source for ExternalRaw {
    fn poll(&mut self, _stop: &AtomicBool) -> Poll {
        match self.input.receive() {
            Ok(Some(s)) => Poll::Sample(s, crate::clock::ingest_now(true), None),
            Ok(None) | Err(_) => Poll::Idle,
        }
    }

    fn waker(&self) -> Option<(&Waker, Duration)> {
        Some((&self.waker, self.timeout))
    }
}
