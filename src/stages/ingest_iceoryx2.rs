//! `ingest.iceoryx2`: raw samples that a sensor driver in another process publishes on an
//! iceoryx2 service ([`crate::transport::RawSample`]). The stage sleeps on the event service of
//! the same name (a driver should notify it after each sample) with a timeout, so a driver that
//! does not notify is still read within `poll_timeout_us`.

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use crate::pipeline::stage::{Poll, Source};
use crate::transport::{monotonic_ns, Input, RawSample, Transport, TransportError, Waker};

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
        for attempt in 0..2 {
            match self.input.receive() {
                Ok(Some(s)) => return Poll::Sample(s, monotonic_ns()),
                Ok(None) if attempt == 0 => {
                    // Sleep until the driver notifies (or the timeout), then look again.
                    let _ = self.waker.wait(self.timeout);
                }
                Ok(None) | Err(_) => return Poll::Idle,
            }
        }
        Poll::Idle
    }
}
