//! [`Transport`]: one iceoryx2 node and the services and ports it sets up for a pipeline.

use std::cell::Cell;
use std::fmt::Debug;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use iceoryx2::prelude::*;
use iceoryx2::service::attribute::{AttributeKey, AttributeValue};
use iceoryx2::service::builder::publish_subscribe::Builder as PubSubBuilder;

use super::cleanup::{remove_unsized_segments, restrict_global_segment};
use super::config::{service_name, PubSubFactory, Qos, Svc};
use super::error::TransportError;
use super::permissions::setup;
use super::ports::{Input, Output};
use super::shm_space::{install_sigbus_guard, note_existing, reserve_new, reserve_new_or_count};
use super::trust::node_config;
use super::wake::Waker;
use crate::wire::wire_version_mismatch;

/// How many attributes an [`Transport::announce`]d service holds (iceoryx2's limit).
pub const MAX_ATTRIBUTES: usize = 8;

/// A service that says what its node does ([`Transport::announce`]); it lasts while this does.
pub struct Announcement {
    _notifier: iceoryx2::port::notifier::Notifier<Svc>,
}

/// What a thread beside a pipeline's chain (a side: `sides::Start`) is started with: where its
/// own iceoryx2 node goes, and how the pipeline runs.
pub struct SideStart<'a> {
    /// The pipeline's name.
    pub pipeline: &'a str,
    /// The iceoryx2 prefix the pipeline runs under.
    pub prefix: &'a str,
    /// The side's own iceoryx2 node name.
    pub node: &'a str,
    /// The event service on which it says what it does, for `driftless list`.
    pub announce_as: &'a str,
    /// The pipeline's service settings (every service is built from one `Qos`).
    pub qos: Qos,
    /// The pipeline's rate, Hz.
    pub rate_hz: f64,
    /// The hot thread's CPU, when its pipelines pin it (`cpu`): a side that hands samples to
    /// the hot thread and back may run beside it, so that each hand-over wakes a thread on the
    /// same CPU rather than an idle one.
    pub cpu: Option<usize>,
    /// Set when the pipeline stops: the side returns soon after.
    pub stop: &'a AtomicBool,
}

/// One iceoryx2 node and the ports it creates. Not `Send`: create it in the thread that uses it.
pub struct Transport {
    pub(super) node: Node<Svc>,
    pub(super) qos: Qos,
    pub(super) prefix: String,
}

impl Transport {
    /// Create a node named `node_name` under `prefix`. Creating a node also removes the
    /// resources of dead nodes (a daemon killed with SIGKILL) of the same prefix.
    ///
    /// Refused with [`TransportError::Untrusted`], before anything is created, when another
    /// user controls iceoryx2's root directory, `/dev/shm`, or what stands at the prefix's
    /// global management segment's name there (see `trust.rs`).
    pub fn new(prefix: &str, node_name: &str, qos: Qos) -> Result<Self, TransportError> {
        let cfg = node_config(prefix)?;
        install_sigbus_guard();
        remove_unsized_segments(prefix);
        note_existing(prefix);
        let name = NodeName::new(node_name).map_err(|e| TransportError::Name {
            name: node_name.to_string(),
            reason: format!("{e:?}"),
        })?;
        let node = NodeBuilder::new()
            .name(&name)
            .config(&cfg)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Svc>()
            .map_err(|e| setup("node", node_name, e))?;
        node.try_cleanup_dead_nodes();
        restrict_global_segment(prefix);
        Ok(Transport {
            node,
            qos,
            prefix: prefix.to_string(),
        })
    }

    /// The prefix this node lives under.
    pub fn prefix(&self) -> &str {
        &self.prefix
    }

    /// Reserve all of every shared memory segment this process created under the prefix since
    /// its first node (`fallocate`), so that a full `/dev/shm` fails here, with
    /// [`TransportError::SharedMemoryFull`], and never later with SIGBUS. Call it once the
    /// ports are set up.
    pub fn reserve_shared_memory(&self) -> Result<(), TransportError> {
        reserve_new(&self.prefix)
    }

    /// Like [`Transport::reserve_shared_memory`] for a running process: what cannot be
    /// reserved is counted in [`super::shared_memory_trouble`], and nothing fails.
    pub fn reserve_shared_memory_or_count(&self) {
        reserve_new_or_count(&self.prefix)
    }

    /// Remove the resources of dead nodes of this prefix; returns how many were cleaned.
    pub fn cleanup_dead_nodes(&self) -> u64 {
        self.node.try_cleanup_dead_nodes().cleanups
    }

    /// The builder of the publish-subscribe service `name` with payload `T`.
    fn pubsub_builder<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
    ) -> Result<PubSubBuilder<T, (), Svc>, TransportError> {
        Ok(self
            .node
            .service_builder(&service_name(name)?)
            .publish_subscribe::<T>())
    }

    /// The publish-subscribe service `name`, opened or created with our QoS (one publisher).
    fn pubsub<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
    ) -> Result<PubSubFactory<T>, TransportError> {
        self.pubsub_builder::<T>(name)?
            .history_size(0)
            .enable_safe_overflow(false)
            .subscriber_max_buffer_size(self.qos.buffer_size)
            .max_subscribers(self.qos.max_subscribers)
            .max_publishers(1)
            .open_or_create()
            .map_err(|e| self.open_error(name, e))
    }

    /// The publish-subscribe service `name` as another process created it (no requirements).
    fn existing_pubsub<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
    ) -> Result<PubSubFactory<T>, TransportError> {
        self.pubsub_builder::<T>(name)?
            .open()
            .map_err(|e| self.open_error(name, e))
    }

    /// The event service `name`, opened or created: its notifier wakes its listeners.
    fn event_service(
        &self,
        name: &str,
    ) -> Result<iceoryx2::service::port_factory::event::PortFactory<Svc>, TransportError> {
        self.node
            .service_builder(&service_name(name)?)
            .event()
            .open_or_create()
            .map_err(|e| setup("event service", name, e))
    }

    /// The publishing side of service `name`, with an event service of the same name that is
    /// notified after every send when `notify` is set (so readers can sleep until data comes).
    /// Fails if another process already publishes on it (one publisher per service).
    pub fn output<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
        notify: bool,
    ) -> Result<Output<T>, TransportError> {
        let service = self.pubsub::<T>(name)?;
        self.output_on(service, name, notify)
    }

    /// Like [`Transport::output`] for a service another process may have created first (the
    /// input of an `external` stage, or an external stage's own output): opened without
    /// requirements if it exists, created with our QoS otherwise.
    pub fn external_output<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
        notify: bool,
    ) -> Result<Output<T>, TransportError> {
        if !self.service_exists::<T>(name)? {
            return self.output(name, notify);
        }
        let service = self.existing_pubsub::<T>(name)?;
        self.output_on(service, name, notify)
    }

    fn output_on<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        service: PubSubFactory<T>,
        name: &str,
        notify: bool,
    ) -> Result<Output<T>, TransportError> {
        let publisher = service
            .publisher_builder()
            .backpressure_strategy(BackpressureStrategy::DiscardData)
            .create()
            .map_err(|e| {
                // A service takes one publisher: two drivers never interleave on one.
                setup(
                    "publisher (a service takes one: is another driver or daemon publishing it?)",
                    name,
                    e,
                )
            })?;
        let notifier = if notify {
            Some(
                self.event_service(name)?
                    .notifier_builder()
                    .create()
                    .map_err(|e| setup("notifier", name, e))?,
            )
        } else {
            None
        };
        Ok(Output {
            keeps_history: service.static_config().history_size() > 0,
            service,
            publisher,
            notifier,
            losses: Arc::default(),
            streak: Cell::new(0),
            subscribers: Cell::new(0),
            departed: Cell::new(false),
        })
    }

    /// A subscriber to service `name`, created with our QoS if it does not exist yet.
    pub fn input<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
    ) -> Result<Input<T>, TransportError> {
        subscribe(self.pubsub::<T>(name)?, name, self.qos.buffer_size)
    }

    /// A subscriber to a service another process publishes (a sensor driver, an external
    /// stage): created with our QoS if it does not exist yet; if it does, its creator's settings
    /// are checked, because a small buffer or safe overflow (iceoryx2's defaults: 2 samples,
    /// overwrite the oldest) loses samples under ordinary jitter without the publisher
    /// knowing. Refused ([`TransportError::Qos`]) unless it holds our buffer with safe overflow
    /// off.
    pub fn external_input<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
    ) -> Result<Input<T>, TransportError> {
        if !self.service_exists::<T>(name)? {
            return self.input(name);
        }
        let service = self.existing_pubsub::<T>(name)?;
        let cfg = service.static_config();
        let (buffer, safe_overflow) = (cfg.subscriber_max_buffer_size(), cfg.has_safe_overflow());
        if buffer < self.qos.buffer_size || safe_overflow {
            return Err(TransportError::Qos {
                name: name.to_string(),
                buffer,
                safe_overflow,
                need: self.qos.buffer_size,
            });
        }
        subscribe(service, name, self.qos.buffer_size)
    }

    /// A subscriber to an existing service `name` whatever its creator's QoS (for `tap`,
    /// `stats` and external consumers), with the largest buffer the service allows.
    pub fn open_input<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
    ) -> Result<Input<T>, TransportError> {
        let service = self.existing_pubsub::<T>(name)?;
        let max = service.static_config().subscriber_max_buffer_size();
        subscribe(service, name, max)
    }

    /// A listener on the event service `name` (opened or created), to sleep until a publisher
    /// announces new data.
    pub fn waker(&self, name: &str) -> Result<Waker, TransportError> {
        let listener = self
            .event_service(name)?
            .listener_builder()
            .create()
            .map_err(|e| setup("listener", name, e))?;
        Ok(Waker { listener })
    }

    /// Say what this node does on the event service `name`, as its attributes (key, value; a
    /// key may repeat; at most [`MAX_ATTRIBUTES`], each value at most 256 bytes), for
    /// `driftless list` to show. The service lasts while the returned port does. Any old
    /// service of that name (a dead process's) is replaced.
    pub fn announce(
        &self,
        name: &str,
        attributes: &[(&str, String)],
    ) -> Result<Announcement, TransportError> {
        let mut spec = AttributeSpecifier::new();
        for (key, value) in attributes {
            let bad = |e: &dyn Debug| setup("service attribute", name, e);
            let key = AttributeKey::try_from(*key).map_err(|e| bad(&e))?;
            let value = AttributeValue::try_from(value.as_str()).map_err(|e| bad(&e))?;
            spec = spec.define(&key, &value).map_err(|e| bad(&e))?;
        }
        let event = self
            .node
            .service_builder(&service_name(name)?)
            .event()
            .create_with_attributes(&spec)
            .map_err(|e| setup("event service", name, e))?;
        let notifier = event
            .notifier_builder()
            .create()
            .map_err(|e| setup("notifier", name, e))?;
        Ok(Announcement {
            _notifier: notifier,
        })
    }

    /// A listener on the event service `name` if its publisher created one (the services a
    /// daemon notifies, e.g. the corrected one); `None` otherwise, creating nothing.
    pub fn existing_waker(&self, name: &str) -> Result<Option<Waker>, TransportError> {
        let sn = service_name(name)?;
        let exists = ipc::Service::does_exist(&sn, self.node.config(), MessagingPattern::Event)
            .map_err(|e| setup("service lookup", name, e))?;
        if exists {
            self.waker(name).map(Some)
        } else {
            Ok(None)
        }
    }

    /// An error opening the publish-subscribe service `name`: iceoryx2 says only
    /// `IncompatibleTypes`; when the service carries another layout version of one of our
    /// types, say which and what to do ([`TransportError::Version`]).
    fn open_error(&self, name: &str, e: impl Debug) -> TransportError {
        if format!("{e:?}").contains("IncompatibleTypes") {
            if let Some(m) = self.version_mismatch(name) {
                return TransportError::Version(m);
            }
        }
        setup("service", name, e)
    }

    /// The refusal of service `name` when it carries another layout version of one of our
    /// types (a driftless of another release publishes it), from
    /// [`crate::wire::wire_version_mismatch`]; None otherwise.
    pub fn version_mismatch(&self, name: &str) -> Option<String> {
        let found = self.payload_type_name(name).ok().flatten()?;
        wire_version_mismatch(&format!("service {name:?}"), &found)
    }

    /// The payload type name of the publish-subscribe service `name` (e.g.
    /// `driftless::GyroSample`), or `None` when no such service exists under this prefix.
    pub fn payload_type_name(&self, name: &str) -> Result<Option<String>, TransportError> {
        let sn = service_name(name)?;
        let details =
            ipc::Service::details(&sn, self.node.config(), MessagingPattern::PublishSubscribe)
                .map_err(|e| setup("service lookup", name, e))?;
        Ok(details.map(|d| {
            d.static_details
                .publish_subscribe()
                .message_type_details()
                .payload
                .type_name()
                .to_string()
        }))
    }

    /// Whether a publish-subscribe service `name` of type `T` exists under this prefix.
    pub fn service_exists<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
    ) -> Result<bool, TransportError> {
        let sn = service_name(name)?;
        ipc::Service::does_exist(&sn, self.node.config(), MessagingPattern::PublishSubscribe)
            .map_err(|e| setup("service lookup", name, e))
    }
}

/// A subscriber to `service` (`name` in errors) holding `buffer` samples, as an [`Input`]: the
/// one subscriber builder of [`Transport::input`], [`Transport::external_input`] and
/// [`Transport::open_input`].
fn subscribe<T: Debug + ZeroCopySend + Copy + 'static>(
    service: PubSubFactory<T>,
    name: &str,
    buffer: usize,
) -> Result<Input<T>, TransportError> {
    let subscriber = service
        .subscriber_builder()
        .buffer_size(buffer)
        .create()
        .map_err(|e| setup("subscriber", name, e))?;
    Ok(Input {
        subscriber,
        service,
    })
}
