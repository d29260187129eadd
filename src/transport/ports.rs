//! The ports a stage sees: [`Output`] (publish, notify, count losses) and [`Input`] (receive).

use std::cell::Cell;
use std::fmt::Debug;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections as _;
use iceoryx2::prelude::*;

use super::config::{PubSubFactory, Svc};
use super::error::TransportError;

/// What subscribers of one output could not take, readable from another thread.
#[derive(Debug, Default)]
pub struct Losses {
    /// Samples a subscriber could not take (its buffer was full) and that count as lost.
    pub lost: AtomicU64,
    /// Samples a subscriber did not take in its last moments, before it went away: it had
    /// stopped reading (a `tap --count` that has its count). Not lost: nobody wanted them.
    pub left_unread: AtomicU64,
}

/// The sending side of one service. Sending never blocks: a subscriber with a full buffer
/// loses the sample, counted in [`Output::lost`].
///
/// A subscriber that stops reading and then leaves misses the samples between: they count as
/// lost while it stays, and move to [`Losses::left_unread`] once it is gone and every
/// subscriber left is served again (a subscriber still missing samples then was not the one
/// that left, and they stay lost).
pub struct Output<T: Debug + ZeroCopySend + Copy + 'static> {
    pub(super) service: PubSubFactory<T>,
    pub(super) publisher: Publisher<Svc, T, ()>,
    pub(super) notifier: Option<Notifier<Svc>>,
    pub(super) losses: Arc<Losses>,
    /// Samples missed since every subscriber was last served.
    pub(super) streak: Cell<u64>,
    /// Subscribers at the last send.
    pub(super) subscribers: Cell<usize>,
    /// A subscriber went away during a streak: the next send tells whose it was.
    pub(super) departed: Cell<bool>,
    /// The service keeps samples for subscribers that come later (only a service another
    /// process created with a history): every sample is sent, read or not.
    pub(super) keeps_history: bool,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Output<T> {
    /// Connect to the subscribers that exist now, so that the first [`send`](Self::send) does
    /// not pay for it (mapping their shared memory) on the hot path.
    pub fn connect(&self) -> Result<(), TransportError> {
        self.publisher
            .update_connections()
            .map_err(|e| TransportError::Io {
                what: "connect",
                reason: format!("{e:?}"),
            })
    }

    /// Publish a copy of `value` (zero-copy into shared memory); returns the number of
    /// subscribers that received it. Does not notify: call [`Output::notify`] after it.
    /// Allocation-free on our side (iceoryx2 0.10 allocates one small `Arc` per loan).
    ///
    /// With no subscriber registered nothing is loaned: our services keep no history, so a
    /// sample nobody subscribes to is seen by no one, now or later. A subscriber that
    /// registers is served from the next send, the one on which iceoryx2 itself would have
    /// connected it.
    pub fn send(&self, value: &T) -> Result<usize, TransportError> {
        let before = self.service.dynamic_config().number_of_subscribers();
        if !self.keeps_history && before == 0 {
            self.account(0, 0, 0);
            return Ok(0);
        }
        let sample = self
            .publisher
            .loan_uninit()
            .map_err(|e| TransportError::Io {
                what: "loan",
                reason: format!("{e:?}"),
            })?;
        let n = sample
            .write_payload(*value)
            .send()
            .map_err(|e| TransportError::Io {
                what: "send",
                reason: format!("{e:?}"),
            })?;
        let after = self.service.dynamic_config().number_of_subscribers();
        self.account(before.min(after), after, n);
        Ok(n)
    }

    /// Count one send: `expected` subscribers were registered throughout (one that came or went
    /// meanwhile is not owed this sample), `now` are registered after it, `served` took it.
    fn account(&self, expected: usize, now: usize, served: usize) {
        let missed = expected.saturating_sub(served) as u64;
        let streak = self.streak.get();
        if now < self.subscribers.get() && streak > 0 {
            self.departed.set(true);
        }
        self.subscribers.set(now);
        if missed > 0 {
            self.losses.lost.fetch_add(missed, Ordering::Relaxed);
            self.streak.set(streak + missed);
            return;
        }
        if self.departed.get() {
            // Everyone left is served: the streak was the departed subscriber's.
            self.losses.lost.fetch_sub(streak, Ordering::Relaxed);
            self.losses.left_unread.fetch_add(streak, Ordering::Relaxed);
        }
        self.streak.set(0);
        self.departed.set(false);
    }

    /// Wake the readers sleeping on the event service of the same name (if this output was
    /// created with `notify`). A separate call so the caller can timestamp the publish first.
    pub fn notify(&self) {
        if let Some(notifier) = &self.notifier {
            // A failed wake-up only delays a reader until its own timeout.
            let _ = notifier.notify();
        }
    }

    /// Samples that subscribers could not take so far (their buffers were full).
    pub fn lost(&self) -> u64 {
        self.losses.lost.load(Ordering::Relaxed)
    }

    /// A handle on the loss counters, readable from another thread.
    pub fn losses(&self) -> Arc<Losses> {
        Arc::clone(&self.losses)
    }
}

/// The receiving side of one service.
pub struct Input<T: Debug + ZeroCopySend + Copy + 'static> {
    pub(super) subscriber: Subscriber<Svc, T, ()>,
    pub(super) service: PubSubFactory<T>,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Input<T> {
    /// Samples this subscriber holds unread before it loses new ones.
    pub fn buffer_size(&self) -> usize {
        self.subscriber.buffer_size()
    }

    /// How many publishers the service has now (a departed one no longer counts).
    pub fn publishers(&self) -> usize {
        self.service.dynamic_config().number_of_publishers()
    }

    /// The oldest sample not yet taken, copied out of shared memory. Allocation-free.
    pub fn receive(&self) -> Result<Option<T>, TransportError> {
        match self.subscriber.receive() {
            Ok(Some(sample)) => Ok(Some(*sample.payload())),
            Ok(None) => Ok(None),
            Err(e) => Err(TransportError::Io {
                what: "receive",
                reason: format!("{e:?}"),
            }),
        }
    }
}
