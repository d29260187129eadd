//! Discovery: the nodes and services of a prefix as iceoryx2 lists them (`driftless list`),
//! who holds a pipeline, and what is done with a listing: the removal of dead nodes and, once
//! no node is left, of a prefix's leftovers (`cleanup.rs` deletes; it is told the count), and a
//! running daemon's stats snapshot.

use std::fmt::Debug;
use std::time::Duration;

use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;

use super::cleanup::{remove_leftovers_once, remove_node_files, remove_unsized_segments};
use super::config::{service_name, Svc};
use super::error::TransportError;
use super::node::Transport;
use super::permissions::{process_owner, setup};
use super::trust::{listing_config, node_config};
use super::wire_type::WireType;
use super::ZeroCopySend;
use crate::wire::{GyroSample, RawSample, StatsSnapshot, StopSignal};

/// A live iceoryx2 node as the node list describes it: which process, whose, since when.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeHolder {
    /// Process id of the node's owner.
    pub pid: i32,
    /// File name of its executable, when iceoryx2 recorded one.
    pub executable: Option<String>,
    /// The process owner's user name (or `uid N` without one), while the process is visible.
    pub user: Option<String>,
    /// When the node was created (wall clock) and how long ago.
    pub since: Option<(std::time::SystemTime, Duration)>,
}

impl std::fmt::Display for NodeHolder {
    /// `pid 4242 (driftless, user alice, since 2025-06-01T10:00:00Z, 5m 3s ago)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "pid {}", self.pid)?;
        let mut parts: Vec<String> = Vec::new();
        parts.extend(self.executable.clone());
        parts.extend(self.user.as_ref().map(|u| format!("user {u}")));
        if let Some((since, age)) = self.since {
            parts.push(format!(
                "since {}, {} ago",
                humantime::format_rfc3339_seconds(since),
                humantime::format_duration(Duration::from_secs(age.as_secs()))
            ));
        }
        if !parts.is_empty() {
            write!(f, " ({})", parts.join(", "))?;
        }
        Ok(())
    }
}

/// What iceoryx2 can tell of a node from its view: which process, whose (only while it is
/// alive: a dead node's pid may belong to another process by now), since when.
pub(super) fn holder(view: &impl NodeView, alive: bool) -> Option<NodeHolder> {
    let details = view.details().as_ref()?;
    let pid = details.process_id().value();
    let age = view
        .id()
        .creation_time::<Svc>()
        .ok()
        .and_then(|t| t.elapsed().ok());
    Some(NodeHolder {
        pid,
        executable: Some(details.executable().to_string())
            .filter(|e| !e.is_empty() && e != "undefined"),
        user: if alive { process_owner(pid) } else { None },
        since: age.and_then(|a| {
            std::time::SystemTime::now()
                .checked_sub(a)
                .map(|since| (since, a))
        }),
    })
}

/// The state of a node as iceoryx2's node list gives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeLife {
    /// Its process is alive.
    Alive,
    /// Its process died without removing its resources (e.g. SIGKILL); another process may
    /// remove them ([`Transport::remove_dead_nodes`]).
    Dead,
    /// This user may not tell whether it is alive (another user's node).
    Inaccessible,
    /// Its files are incomplete or inconsistent.
    Undefined,
}

impl NodeLife {
    /// `alive`, `dead`, `inaccessible` or `undefined`.
    pub fn as_str(self) -> &'static str {
        match self {
            NodeLife::Alive => "alive",
            NodeLife::Dead => "dead",
            NodeLife::Inaccessible => "inaccessible",
            NodeLife::Undefined => "undefined",
        }
    }
}

/// One node under a prefix.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ListedNode {
    /// iceoryx2's unique node id (what services name their ports' nodes by).
    pub id: u128,
    /// The node's name; empty when its details are unreadable.
    pub name: String,
    /// Alive, dead, ...
    pub life: NodeLife,
    /// Process, user and age, as far as they are known.
    pub holder: Option<NodeHolder>,
}

/// The messaging pattern of a listed service.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ServiceKind {
    /// Publish-subscribe: the payload's type name, and which of ours it is (None: foreign).
    PubSub {
        /// The payload's iceoryx2 type name.
        type_name: String,
        /// Our wire type, when it is one.
        wire: Option<WireType>,
    },
    /// An event service (notifiers wake listeners).
    Event,
    /// Request-response or blackboard: listed, not opened.
    Other(&'static str),
}

/// One service under a prefix, with the nodes of its ports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ListedService {
    /// Service name.
    pub name: String,
    /// Pattern and payload type.
    pub kind: ServiceKind,
    /// Node id of each publisher (notifier, for an event service); None when the service could
    /// not be opened (a foreign payload type, another user's service).
    pub senders: Option<Vec<u128>>,
    /// Node id of each subscriber (listener, for an event service); None as for `senders`.
    pub receivers: Option<Vec<u128>>,
    /// Node ids of every node attached to the service (whatever its type: for a foreign
    /// service, who uses it).
    pub nodes: Vec<u128>,
    /// The attributes its creator gave it (key, value), in iceoryx2's order.
    pub attributes: Vec<(String, String)>,
}

/// What runs under a prefix: its nodes and services, as iceoryx2 lists them.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Listing {
    /// Every node, alive or not.
    pub nodes: Vec<ListedNode>,
    /// Every service, sorted by name.
    pub services: Vec<ListedService>,
}

fn view_name(view: &impl NodeView) -> String {
    view.details()
        .as_ref()
        .map(|d| d.name().as_str().to_string())
        .unwrap_or_default()
}

/// A node's name, or its id where its details are gone.
pub fn display_name(node: &ListedNode) -> String {
    if node.name.is_empty() {
        format!("node {:x}", node.id)
    } else {
        node.name.clone()
    }
}

fn listed_node(state: &NodeState<Svc>) -> ListedNode {
    match state {
        NodeState::Alive(v) => ListedNode {
            id: v.id().value(),
            name: view_name(v),
            life: NodeLife::Alive,
            holder: holder(v, true),
        },
        NodeState::Dead(v) => ListedNode {
            id: v.id().value(),
            name: view_name(v),
            life: NodeLife::Dead,
            holder: holder(v, false),
        },
        NodeState::Inaccessible(id) => ListedNode {
            id: id.value(),
            name: String::new(),
            life: NodeLife::Inaccessible,
            holder: None,
        },
        NodeState::Undefined(id) => ListedNode {
            id: id.value(),
            name: String::new(),
            life: NodeLife::Undefined,
            holder: None,
        },
    }
}

/// A node that only looks: creating, dropping it or opening a service with it removes no dead
/// node's resources (iceoryx2 does that by default), so `list` shows the dead as dead.
fn observer(prefix: &str) -> Result<Node<Svc>, TransportError> {
    let mut cfg = node_config(prefix)?;
    remove_unsized_segments(prefix);
    cfg.global.node.cleanup_dead_nodes_on_creation = false;
    cfg.global.node.cleanup_dead_nodes_on_destruction = false;
    cfg.global.service.cleanup_dead_nodes_on_open = false;
    let node_name = format!("driftless-list-{}", std::process::id());
    let name = NodeName::new(&node_name).map_err(|e| TransportError::Name {
        name: node_name.clone(),
        reason: format!("{e:?}"),
    })?;
    NodeBuilder::new()
        .name(&name)
        .config(&cfg)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<Svc>()
        .map_err(|e| setup("node", &node_name, e))
}

/// The publishers' and subscribers' node ids of a publish-subscribe service of our type `T`.
fn pubsub_ports<T: Debug + ZeroCopySend + Copy + 'static>(
    node: &Node<Svc>,
    name: &ServiceName,
) -> Option<(Vec<u128>, Vec<u128>)> {
    let service = node
        .service_builder(name)
        .publish_subscribe::<T>()
        .open()
        .ok()?;
    let dynamic = service.dynamic_config();
    let (mut senders, mut receivers) = (Vec::new(), Vec::new());
    dynamic.list_publishers(|p| {
        senders.push(p.node_id.value());
        CallbackProgression::Continue
    });
    dynamic.list_subscribers(|s| {
        receivers.push(s.node_id.value());
        CallbackProgression::Continue
    });
    Some((senders, receivers))
}

/// The notifiers' and listeners' node ids of an event service.
fn event_ports(node: &Node<Svc>, name: &ServiceName) -> Option<(Vec<u128>, Vec<u128>)> {
    let service = node.service_builder(name).event().open().ok()?;
    let dynamic = service.dynamic_config();
    let (mut senders, mut receivers) = (Vec::new(), Vec::new());
    dynamic.list_notifiers(|p| {
        senders.push(p.node_id.value());
        CallbackProgression::Continue
    });
    dynamic.list_listeners(|s| {
        receivers.push(s.node_id.value());
        CallbackProgression::Continue
    });
    Some((senders, receivers))
}

impl Transport {
    /// Number of live nodes named `node_name` under `prefix`, other than the caller's.
    pub fn live_nodes_named(prefix: &str, node_name: &str) -> Result<usize, TransportError> {
        Ok(Self::holders_of(prefix, node_name)?.len())
    }

    /// The live nodes named `node_name` under `prefix` (other than the caller's), described as
    /// far as iceoryx2's node list and `/proc` tell: who holds a pipeline.
    pub fn holders_of(prefix: &str, node_name: &str) -> Result<Vec<NodeHolder>, TransportError> {
        let cfg = listing_config(prefix)?;
        let mut holders = Vec::new();
        Node::<Svc>::list(&cfg, |state| {
            if let NodeState::Alive(view) = &state {
                if view.details().as_ref().map(|d| d.name().as_str()) == Some(node_name) {
                    holders.extend(holder(view, true));
                }
            }
            CallbackProgression::Continue
        })
        .map_err(|e| setup("node list", prefix, e))?;
        Ok(holders)
    }

    /// Number of nodes (alive or dead) under `prefix`.
    pub fn node_count(prefix: &str) -> Result<usize, TransportError> {
        let cfg = listing_config(prefix)?;
        let mut count = 0;
        Node::<Svc>::list(&cfg, |_| {
            count += 1;
            CallbackProgression::Continue
        })
        .map_err(|e| setup("node list", prefix, e))?;
        Ok(count)
    }

    /// Every node and service under `prefix` (iceoryx2's `Node::list` and `Service::list`), with
    /// the nodes of each service's ports. Removes nothing: a dead node is listed as dead. The
    /// ports are read through a node of this process that exists only during the call (and is
    /// not in the listing); nothing is created when the prefix holds no service.
    pub fn list(prefix: &str) -> Result<Listing, TransportError> {
        use iceoryx2::service::static_config::messaging_pattern::MessagingPattern as Static;
        let cfg = listing_config(prefix)?;
        let mut listing = Listing::default();
        let mut found = Vec::new();
        Svc::list(&cfg, |details| {
            found.push(details);
            CallbackProgression::Continue
        })
        .map_err(|e| setup("service list", prefix, e))?;
        let observer = if found.is_empty() {
            None
        } else {
            Some(observer(prefix)?)
        };
        for details in found {
            let st = &details.static_details;
            let name = *st.name();
            let attributes = st
                .attributes()
                .iter()
                .map(|a| (a.key().to_string(), a.value().to_string()))
                .collect();
            let kind = match st.messaging_pattern() {
                Static::PublishSubscribe(ps) => {
                    let payload = &ps.message_type_details().payload;
                    let type_name = payload.type_name().to_string();
                    ServiceKind::PubSub {
                        wire: WireType::of(&type_name, payload.size()),
                        type_name,
                    }
                }
                Static::Event(_) => ServiceKind::Event,
                Static::RequestResponse(_) => ServiceKind::Other("request-response"),
                Static::Blackboard(_) => ServiceKind::Other("blackboard"),
                _ => ServiceKind::Other("other"),
            };
            let ports = observer.as_ref().and_then(|node| match &kind {
                ServiceKind::PubSub {
                    wire: Some(WireType::Raw),
                    ..
                } => pubsub_ports::<RawSample>(node, &name),
                ServiceKind::PubSub {
                    wire: Some(WireType::Gyro),
                    ..
                } => pubsub_ports::<GyroSample>(node, &name),
                ServiceKind::PubSub {
                    wire: Some(WireType::Stats),
                    ..
                } => pubsub_ports::<StatsSnapshot>(node, &name),
                ServiceKind::PubSub {
                    wire: Some(WireType::Stop),
                    ..
                } => pubsub_ports::<StopSignal>(node, &name),
                ServiceKind::Event => event_ports(node, &name),
                _ => None,
            });
            // Listed before the observer opened anything; kept clean of it all the same.
            let observer_id = observer.as_ref().map(|n| n.id().value());
            let mut nodes: Vec<u128> = details
                .dynamic_details
                .map(|d| d.nodes.iter().map(|n| n.node_id().value()).collect())
                .unwrap_or_default();
            let (senders, receivers) = ports.unzip();
            // A port read after the service list may belong to a node that attached in between:
            // the node of every listed port is among the service's nodes.
            for id in senders.iter().chain(receivers.iter()).flatten() {
                if !nodes.contains(id) {
                    nodes.push(*id);
                }
            }
            nodes.retain(|id| Some(*id) != observer_id);
            listing.services.push(ListedService {
                name: name.as_str().to_string(),
                kind,
                senders,
                receivers,
                nodes,
                attributes,
            });
        }
        listing
            .services
            .sort_by(|a, b| (&a.name, kind_rank(&a.kind)).cmp(&(&b.name, kind_rank(&b.kind))));
        // Nodes last, so every node a port above belongs to is listed (unless it ended since);
        // the observer is gone by then, so it is not listed.
        drop(observer);
        Node::<Svc>::list(&cfg, |state| {
            listing.nodes.push(listed_node(&state));
            CallbackProgression::Continue
        })
        .map_err(|e| setup("node list", prefix, e))?;
        Ok(listing)
    }

    /// Remove the resources of every dead node under `prefix` (its ports, and its services
    /// when no live node uses them); returns the nodes removed. A process killed while it was
    /// creating a port leaves a port tag that iceoryx2 0.10's own clean-up stops at (it then
    /// keeps listing the node as dead, and reports it cleaned up): what is left of such a dead
    /// node (its directory, its monitor files) is removed here.
    pub fn remove_dead_nodes(prefix: &str) -> Result<Vec<ListedNode>, TransportError> {
        // iceoryx2 deletes through these directories: checked as for a node.
        let cfg = node_config(prefix)?;
        remove_unsized_segments(prefix);
        let dead_nodes = |cfg: &Config| -> Result<Vec<ListedNode>, TransportError> {
            let mut dead = Vec::new();
            Node::<Svc>::list(cfg, |state| {
                if matches!(state, NodeState::Dead(_)) {
                    dead.push(listed_node(&state));
                }
                CallbackProgression::Continue
            })
            .map_err(|e| setup("node list", prefix, e))?;
            Ok(dead)
        };
        let before = dead_nodes(&cfg)?;
        let mut failures = std::collections::HashMap::new();
        Node::<Svc>::list(&cfg, |state| {
            if let NodeState::Dead(view) = state {
                let id = view.id().value();
                if let Err(e) = view.try_remove_stale_resources() {
                    failures.insert(id, format!("{e:?}"));
                }
            }
            CallbackProgression::Continue
        })
        .map_err(|e| setup("node list", prefix, e))?;
        for node in dead_nodes(&cfg)? {
            remove_node_files(prefix, node.id);
        }
        let left = dead_nodes(&cfg)?;
        if !left.is_empty() {
            let names: Vec<String> = left
                .iter()
                .map(|n| {
                    let why = failures.get(&n.id).map_or("", String::as_str);
                    format!("{} ({why})", display_name(n))
                })
                .collect();
            return Err(TransportError::Io {
                what: "removing dead nodes",
                reason: names.join(", "),
            });
        }
        Ok(before)
    }

    /// One snapshot from each of the StatsSnapshot services `names` under `prefix`: the next one
    /// each publishes within `timeout` (the daemon keeps no history), None where none came.
    pub fn read_stats(
        prefix: &str,
        names: &[String],
        timeout: Duration,
    ) -> Result<Vec<Option<StatsSnapshot>>, TransportError> {
        let mut got = vec![None; names.len()];
        if names.is_empty() {
            return Ok(got);
        }
        let node = observer(prefix)?;
        let mut subscribers = Vec::new();
        for name in names {
            let sub = node
                .service_builder(&service_name(name)?)
                .publish_subscribe::<StatsSnapshot>()
                .open()
                .ok()
                .and_then(|s| s.subscriber_builder().create().ok());
            subscribers.push(sub);
        }
        let end = std::time::Instant::now() + timeout;
        loop {
            for (slot, sub) in got.iter_mut().zip(&subscribers) {
                if let (None, Some(sub)) = (&slot, sub) {
                    if let Ok(Some(sample)) = sub.receive() {
                        *slot = Some(*sample.payload());
                    }
                }
            }
            let waiting = got
                .iter()
                .zip(&subscribers)
                .any(|(g, s)| g.is_none() && s.is_some());
            if !waiting || std::time::Instant::now() >= end {
                return Ok(got);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

/// Remove the files of `prefix` that iceoryx2 leaves once no node of it is left (the
/// per-prefix management segment in `/dev/shm`, and whatever a killed process left). Does
/// nothing while a node of the prefix is alive, or if the nodes cannot be listed. Only files
/// taken stock of before the nodes are counted are deleted, and a node's details made within
/// the last second are left (they may be a node not listed yet): see `cleanup.rs`.
pub fn remove_prefix_leftovers(prefix: &str) {
    remove_leftovers_once(prefix, || Transport::node_count(prefix).ok());
}

/// [`remove_prefix_leftovers`], and if it left a node's details as too young (a start killed
/// within the last second looks like one in progress), again once they are settled: what an
/// explicit clean (`driftless list --clean`) does, at most a second later.
pub fn remove_prefix_leftovers_settled(prefix: &str) {
    if let Some(wait) = remove_leftovers_once(prefix, || Transport::node_count(prefix).ok()) {
        std::thread::sleep(wait);
        remove_leftovers_once(prefix, || Transport::node_count(prefix).ok());
    }
}

fn kind_rank(kind: &ServiceKind) -> u8 {
    match kind {
        ServiceKind::PubSub { .. } => 0,
        ServiceKind::Event => 1,
        ServiceKind::Other(_) => 2,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_holder_reads_as_pid_executable_user_and_age() {
        let since = std::time::UNIX_EPOCH + Duration::from_secs(1_750_000_000);
        let h = NodeHolder {
            pid: 4242,
            executable: Some("driftless".into()),
            user: Some("alice".into()),
            since: Some((since, Duration::from_millis(303_900))),
        };
        assert_eq!(
            h.to_string(),
            "pid 4242 (driftless, user alice, since 2025-06-15T15:06:40Z, 5m 3s ago)"
        );
        let bare = NodeHolder {
            pid: 7,
            executable: None,
            user: None,
            since: None,
        };
        assert_eq!(bare.to_string(), "pid 7");
    }
}
