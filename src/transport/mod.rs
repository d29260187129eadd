//! Everything iceoryx2: the wire types' marking, where its files live, node and port set-up,
//! discovery, clean-up and waking on other processes.
//!
//! This is the only module that imports `iceoryx2` (and its submodule `zenoh/` the only one that
//! imports `zenoh`, feature `zenoh`); the rest of the crate sees plain Rust types
//! ([`crate::wire`]'s [`RawSample`](crate::wire::RawSample),
//! [`GyroSample`](crate::wire::GyroSample), [`StatsSnapshot`](crate::wire::StatsSnapshot)) and
//! the small port wrappers ([`Output`], [`Input`], [`Waker`], [`WakeSet`]). Everything public of
//! its own is re-exported here, so callers write `transport::X` whichever file `X` lives in; the
//! wire types are not (they are `crate::wire`'s, and imported from there):
//!
//! | file | concern |
//! |---|---|
//! | `zero_copy.rs` | our wire types ([`crate::wire`], not re-exported here) marked for iceoryx2 under their type names |
//! | `wire_type.rs` | [`WireType`]: which of them a service carries, and [`AnyInput`] of it |
//! | `config.rs` | prefix, root directory, name checks, the explicit iceoryx2 `Config`, [`Qos`], the service flavour |
//! | `node.rs` | [`Transport`]: one node and the services and ports it sets up; [`SideStart`], what a side's thread starts its node with |
//! | `ports.rs` | [`Output`] and [`Input`] |
//! | `wake.rs` | [`Waker`] and [`WakeSet`]: sleeping until another process notifies |
//! | `discovery.rs` | what runs under a prefix (`driftless list`), who holds a pipeline, what is removed once no node is left |
//! | `names.rs` | iceoryx2's file names, and the prefixes we allow ([`check_prefix`]) |
//! | `shm_space.rs` | room in `/dev/shm`: segments reserved whole, the SIGBUS guard |
//! | `ros2/` | ROS 2 messages, and live topics over DDS (feature `ros2`) |
//! | `zenoh/` | Zenoh sessions, and the bridge of our services over them (feature `zenoh`) |
//! | `cleanup.rs` | what iceoryx2 leaves behind, removed: only what is provably ours |
//! | `trust.rs` | the root directory checked before iceoryx2 uses it, and `/dev/shm` and the global segment's name before a node: none another user controls; every node's and listing's `Config` |
//! | `error.rs`, `permissions.rs` | [`TransportError`], and whose files a refusal is about |
//!
//! The files stand in layers, each using only files below it: `error`, `names` and `zero_copy` on
//! the ground; `config`; `permissions`, `cleanup`, `ports` and `wake`; `trust` and `shm_space`;
//! `node`; `discovery` on top. The clean-up is a leaf that the others call: it deletes what is
//! provably ours and knows nothing of nodes (`discovery` counts them and tells it).
//!
//! # Quality of service
//! One definition ([`Qos`]) is used for every service the daemon creates: history 0, safe
//! overflow off, a publisher never blocks (backpressure strategy `DiscardData`): a subscriber
//! whose buffer is full loses the new sample (it keeps the older ones it has not read) and the
//! publisher counts the loss ([`Output::lost`]: subscribers registered minus served). With no
//! history, a sample sent while nobody subscribes reaches no one, so [`Output::send`] does not
//! loan one then: a hop nobody reads costs a check, not a send. Readers of our services open
//! them without requirements, so they never conflict with the creator's settings.

mod cleanup;
mod config;
mod discovery;
mod error;
mod names;
mod node;
mod permissions;
mod ports;
pub mod recorder;
pub mod ros2;
mod shm_space;
mod trust;
mod wake;
mod wire_type;
mod zero_copy;

#[cfg(feature = "zenoh")]
pub mod zenoh;

/// iceoryx2's marker of a type that can live in shared memory (our wire types derive it); for
/// code generic over them.
pub use iceoryx2::prelude::ZeroCopySend;

pub use config::{
    check_root, check_service_name, quiet_logging, root, set_root, Qos, DEFAULT_PREFIX,
    DEFAULT_ROOT, PREFIX_ENV, ROOT_ENV,
};
pub use discovery::{
    display_name, ListedNode, ListedService, Listing, NodeHolder, NodeLife, ServiceKind,
};
pub use discovery::{remove_prefix_leftovers, remove_prefix_leftovers_settled};
pub use error::TransportError;
pub use names::check_prefix;
pub use node::{Announcement, SideStart, Transport, MAX_ATTRIBUTES};
pub use permissions::user_name;
pub use ports::{Input, Losses, Output};
pub use shm_space::{install_sigbus_guard, shared_memory_trouble, ShmTrouble};
pub use wake::{WakeSet, Waker};
pub use wire_type::{AnyInput, Carried, WireType};

/// The clock of the wire's `ingest_ns` stamps (a subscriber reads its "now" on it).
pub use crate::clock::monotonic_ns;
