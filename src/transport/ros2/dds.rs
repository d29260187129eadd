//! Live ROS 2 topics over DDS (cargo feature `ros2`): a node in the ROS 2 graph that publishes
//! and subscribes `sensor_msgs/msg/Imu`, and subscribes a vehicle's motion
//! (`nav_msgs/msg/Odometry`, `geometry_msgs/msg/TwistStamped`,
//! `geometry_msgs/msg/TwistWithCovarianceStamped`) as a [`Motion`].
//!
//! Built on `ros2-client` 0.12.1 (a pure-Rust DDS, RustDDS): it talks to ROS 2's own DDS
//! (Fast DDS in Kilted) without a ROS install. `r2r` and `rclrs` bind ROS's C client library
//! and need a sourced ROS install to build and run; `rmw_zenoh` would ride on the Zenoh we
//! already ship, but no rmw_zenoh peer installs here to test against (docs/ros2.md).
//!
//! What ros2-client leaves to us, done here:
//! - `ROS_DOMAIN_ID` is read ([`domain_id`]); ros2-client always uses domain 0.
//! - QoS is set explicitly: publishers reliable (they serve both reliable and sensor-data
//!   subscribers) and never blocking (`WhenFull::Fail`: a full send window drops the message
//!   and counts it), subscriptions best effort (they accept both kinds of publisher).
//! - Messages are serde mirrors of the ROS definitions in declaration order; fixed arrays are
//!   CDR tuples (no length), the 36-element covariances `[[f64; 6]; 6]` (serde stops at 32).
//! - No spinner runs: publishing, taking and the graph need none, and who is on a topic comes
//!   from the discovery database ([`Ros2Node::peer_types`]).
//! - A peer whose QoS cannot match ours is said ([`Ros2Node::qos_mismatches`]): ros2-client
//!   drops RustDDS's incompatible-QoS events, so they are read from the participant here.

use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::dds::rustdds::{
    DomainParticipantStatusListener, QosPolicies, StatusEvented as _, Topic, GUID,
};
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{
    Context, ContextOptions, CreateError, MessageTypeName, Name, Node, NodeName, NodeOptions,
    Publisher, QosProfile, Subscription,
};
use serde::{Deserialize, Serialize};

use super::imu::{Imu, Time};
use super::mag::MagneticField;
use super::motion::{Motion, MotionKind};
use crate::transport::TransportError;

/// Wakes a thread when a watched subscription has messages: its descriptor turns readable
/// (edge-triggered: [`DdsReadiness::clear`] before taking everything, then wait again).
pub struct DdsReadiness {
    poll: Poll,
    events: Events,
}

impl DdsReadiness {
    /// A readiness poll with nothing watched yet.
    pub fn new() -> std::io::Result<DdsReadiness> {
        Ok(DdsReadiness {
            poll: Poll::new()?,
            events: Events::with_capacity(16),
        })
    }

    /// Watch an Imu subscription.
    pub fn watch_imu(&self, sub: &mut ImuSubscription, token: usize) -> std::io::Result<()> {
        self.poll
            .registry()
            .register(&mut sub.subscription, Token(token), Interest::READABLE)
    }

    /// Watch a magnetometer subscription.
    pub fn watch_mag(&self, sub: &mut MagSubscription, token: usize) -> std::io::Result<()> {
        self.poll
            .registry()
            .register(&mut sub.subscription, Token(token), Interest::READABLE)
    }

    /// Watch a motion subscription.
    pub fn watch_motion(&self, sub: &mut MotionSubscription, token: usize) -> std::io::Result<()> {
        let (registry, token) = (self.poll.registry(), Token(token));
        match &mut sub.port {
            MotionPort::Odometry(s) => registry.register(s, token, Interest::READABLE),
            MotionPort::Twist(s) => registry.register(s, token, Interest::READABLE),
            MotionPort::TwistCov(s) => registry.register(s, token, Interest::READABLE),
        }
    }

    /// The descriptor that turns readable when a watched subscription has messages.
    pub fn fd(&self) -> std::os::fd::RawFd {
        use std::os::fd::AsRawFd;
        self.poll.as_raw_fd()
    }

    /// Take the readiness events that woke us (without waiting), so the descriptor turns
    /// readable again only for messages that come after.
    pub fn clear(&mut self) {
        let _ = self
            .poll
            .poll(&mut self.events, Some(std::time::Duration::ZERO));
    }
}

/// The environment variable ROS 2 reads its DDS domain from.
pub const DOMAIN_ENV: &str = "ROS_DOMAIN_ID";

/// The DDS domain in force: `ROS_DOMAIN_ID`, else 0. ROS 2 allows 0 to 232 on Linux (the UDP
/// ports of higher ones collide).
pub fn domain_id() -> Result<u16, String> {
    match std::env::var(DOMAIN_ENV) {
        Err(_) => Ok(0),
        Ok(v) if v.trim().is_empty() => Ok(0),
        Ok(v) => match v.trim().parse::<u16>() {
            Ok(d) if d <= 232 => Ok(d),
            _ => Err(format!(
                "{DOMAIN_ENV}={v:?}: a DDS domain is an integer from 0 to 232"
            )),
        },
    }
}

/// A ROS 2 node: our place in the ROS 2 graph, with its topics.
pub struct Ros2Node {
    // Field order is drop order: the node before its context (ros2-client logs errors when the
    // participant goes first).
    status: DomainParticipantStatusListener,
    node: Node,
    _context: Context,
    name: String,
    /// Our publishers and subscriptions: GUID, topic, and whether it publishes.
    endpoints: Vec<(GUID, String, bool)>,
}

fn setup(what: &'static str, name: &str, e: impl std::fmt::Debug) -> TransportError {
    TransportError::Setup {
        what,
        name: name.to_string(),
        reason: format!("{e:?}"),
    }
}

impl Ros2Node {
    /// A node named `name` in `namespace` (`/` for none) on the domain of [`domain_id`].
    pub fn new(namespace: &str, name: &str) -> Result<Ros2Node, TransportError> {
        let domain = domain_id().map_err(|reason| TransportError::Name {
            name: DOMAIN_ENV.into(),
            reason,
        })?;
        let context = Context::with_options(ContextOptions::new().domain_id(domain))
            .map_err(|e| setup("ROS 2 context", DOMAIN_ENV, e))?;
        let node_name = NodeName::new(namespace, name).map_err(|e| TransportError::Name {
            name: name.into(),
            reason: format!("not a ROS 2 node name: {e:?}"),
        })?;
        let options = NodeOptions::new()
            .enable_rosout(false)
            .start_parameter_services(false);
        let node = context
            .new_node(node_name, options)
            .map_err(|e| setup("ROS 2 node", name, e))?;
        Ok(Ros2Node {
            status: context.domain_participant().status_listener(),
            node,
            _context: context,
            name: name.to_string(),
            endpoints: Vec::new(),
        })
    }

    /// The node's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The DDS domain it is on.
    pub fn domain(&self) -> u16 {
        self.node.domain_id()
    }

    fn topic(
        &self,
        topic: &str,
        ty: (&str, &str),
        qos: &QosProfile,
    ) -> Result<Topic, TransportError> {
        let name = Name::parse(topic).map_err(|e| TransportError::Name {
            name: topic.into(),
            reason: format!("not a ROS 2 topic name: {e:?}"),
        })?;
        self.node
            .create_topic(&name, MessageTypeName::new(ty.0, ty.1), qos)
            .map_err(|e| setup("ROS 2 topic", topic, e))
    }

    /// A publisher of `sensor_msgs/msg/Imu` on `topic`: reliable, keep last `depth`, never
    /// blocking.
    pub fn imu_publisher(
        &mut self,
        topic: &str,
        depth: usize,
    ) -> Result<ImuPublisher, TransportError> {
        Ok(ImuPublisher {
            publisher: self.publisher(topic, ("sensor_msgs", "Imu"), depth)?,
        })
    }

    /// A publisher of messages of ROS 2 type `ty` (`pkg/msg/Name`) on `topic` that we encode
    /// in CDR ourselves ([`CdrPublisher`]): reliable, keep last `depth`, never blocking.
    pub fn cdr_publisher(
        &mut self,
        topic: &str,
        ty: &str,
        depth: usize,
    ) -> Result<CdrPublisher, TransportError> {
        let (pkg, name) = match ty.split('/').collect::<Vec<_>>()[..] {
            [pkg, "msg", name] => (pkg, name),
            _ => {
                return Err(TransportError::Name {
                    name: ty.into(),
                    reason: "not a ROS 2 message type (pkg/msg/Name)".into(),
                })
            }
        };
        Ok(CdrPublisher {
            publisher: self.publisher(topic, (pkg, name), depth)?,
        })
    }

    /// A publisher of `ty` (package, name) on `topic`: reliable, keep last `depth`, never
    /// blocking; recorded among our endpoints.
    fn publisher<M: Serialize>(
        &mut self,
        topic: &str,
        ty: (&str, &str),
        depth: usize,
    ) -> Result<Publisher<M>, TransportError> {
        let make = |node: &mut Node, t: &Topic, qos| node.create_publisher(t, Some(qos));
        self.endpoint(topic, ty, depth, true, make, Publisher::guid)
    }

    /// A subscription of `sensor_msgs/msg/Imu` on `topic`: best effort, keep last `depth`.
    pub fn imu_subscription(
        &mut self,
        topic: &str,
        depth: usize,
    ) -> Result<ImuSubscription, TransportError> {
        let make = |node: &mut Node, t: &Topic, qos| node.create_subscription(t, Some(qos));
        let imu = ("sensor_msgs", "Imu");
        let subscription = self.endpoint(topic, imu, depth, false, make, Subscription::guid)?;
        Ok(ImuSubscription { subscription })
    }

    /// A subscription of `sensor_msgs/msg/MagneticField` on `topic`: best effort, keep last
    /// `depth`.
    pub fn mag_subscription(
        &mut self,
        topic: &str,
        depth: usize,
    ) -> Result<MagSubscription, TransportError> {
        let make = |node: &mut Node, t: &Topic, qos| node.create_subscription(t, Some(qos));
        let ty = ("sensor_msgs", "MagneticField");
        let subscription = self.endpoint(topic, ty, depth, false, make, Subscription::guid)?;
        Ok(MagSubscription { subscription })
    }

    /// A subscription of the vehicle's motion on `topic`, as a message of `kind`: best effort,
    /// keep last `depth`.
    pub fn motion_subscription(
        &mut self,
        topic: &str,
        kind: MotionKind,
        depth: usize,
    ) -> Result<MotionSubscription, TransportError> {
        let make = |node: &mut Node, t: &Topic, qos| -> Result<MotionPort, CreateError> {
            let qos = Some(qos);
            Ok(match kind {
                MotionKind::Odometry => MotionPort::Odometry(node.create_subscription(t, qos)?),
                MotionKind::TwistStamped => MotionPort::Twist(node.create_subscription(t, qos)?),
                MotionKind::TwistWithCovarianceStamped => {
                    MotionPort::TwistCov(node.create_subscription(t, qos)?)
                }
            })
        };
        let ty = motion_type(kind);
        let port = self.endpoint(topic, ty, depth, false, make, MotionPort::guid)?;
        Ok(MotionSubscription { port })
    }

    /// One of our endpoints on `topic` of `ty` (package, name), made by `make` with the QoS of
    /// its side, keep last `depth`: a publisher (`publishes`) reliable and never blocking, a
    /// subscription best effort. Recorded among our endpoints: a peer whose QoS cannot match
    /// is said by the endpoint's topic ([`Ros2Node::qos_mismatches`]).
    fn endpoint<E>(
        &mut self,
        topic: &str,
        ty: (&str, &str),
        depth: usize,
        publishes: bool,
        make: impl FnOnce(&mut Node, &Topic, QosProfile) -> Result<E, CreateError>,
        guid: impl FnOnce(&E) -> GUID,
    ) -> Result<E, TransportError> {
        let (qos, what) = if publishes {
            (publish_qos(depth), "ROS 2 publisher")
        } else {
            (subscribe_qos(depth), "ROS 2 subscription")
        };
        let t = self.topic(topic, ty, &qos)?;
        let made = make(&mut self.node, &t, qos).map_err(|e| setup(what, topic, e))?;
        self.endpoints
            .push((guid(&made), topic.to_string(), publishes));
        Ok(made)
    }

    /// One line for each peer found since the last call whose QoS cannot match one of our
    /// publishers or subscriptions (it gets nothing from us, or we nothing from it), naming the
    /// topic and the first policy that differs.
    pub fn qos_mismatches(&self) -> Vec<String> {
        use ros2_client::dds::rustdds::DomainParticipantStatusEvent as E;
        let mut lines = Vec::new();
        while let Some(event) = self.status.try_recv_status() {
            let (ours, requested, offered, peer) = match &event {
                E::RemoteReaderQosIncompatible {
                    local_writer,
                    requested_qos,
                    offered_qos,
                    ..
                } => (local_writer, requested_qos, offered_qos, "a subscriber"),
                E::RemoteWriterQosIncompatible {
                    local_reader,
                    requested_qos,
                    offered_qos,
                    ..
                } => (local_reader, requested_qos, offered_qos, "a publisher"),
                _ => continue,
            };
            let Some((_, topic, we_publish)) = self.endpoints.iter().find(|e| e.0 == *ours) else {
                continue;
            };
            let policy = offered
                .compliance_failure_wrt(requested)
                .map_or("QoS".to_string(), |p| format!("{p:?}"));
            let describe = |q: &QosPolicies| {
                format!(
                    "{}, {}",
                    if q.is_reliable() {
                        "reliable"
                    } else {
                        "best effort"
                    },
                    if q.is_volatile() {
                        "volatile"
                    } else {
                        "transient local or more"
                    }
                )
            };
            lines.push(if *we_publish {
                format!(
                    "{peer} of {topic} requests a {policy} we do not offer, so it gets nothing \
                     (it requests {}; we offer {})",
                    describe(requested),
                    describe(offered)
                )
            } else {
                format!(
                    "{peer} of {topic} offers a {policy} we cannot accept, so we get nothing \
                     from it (it offers {}; we request {})",
                    describe(offered),
                    describe(requested)
                )
            });
        }
        lines
    }

    /// The ROS 2 types (`pkg/msg/Type`) of the publishers (`writers`) or subscriptions of other
    /// participants discovered on `topic` (an absolute name): one entry each.
    pub fn peer_types(&self, topic: &str, writers: bool) -> Vec<String> {
        let dds_topic = format!("rt/{}", topic.trim_start_matches('/'));
        let dp = self._context.domain_participant();
        let types: Vec<String> = if writers {
            dp.discovered_writers()
                .into_iter()
                .filter(|w| w.publication_topic_data.topic_name == dds_topic)
                .map(|w| w.publication_topic_data.type_name)
                .collect()
        } else {
            dp.discovered_readers()
                .into_iter()
                .filter(|r| r.subscription_topic_data.topic_name == dds_topic)
                .map(|r| r.subscription_topic_data.type_name().clone())
                .collect()
        };
        types.iter().map(|t| ros_type_name(t)).collect()
    }
}

impl Ros2Node {
    /// The publishers on `topic` that discovery knows now (one that went away leaves within its
    /// lease, at once when it says goodbye).
    pub fn publishers_on(&self, topic: &str) -> Vec<PublisherId> {
        let dds_topic = format!("rt/{}", topic.trim_start_matches('/'));
        self._context
            .domain_participant()
            .discovered_writers()
            .into_iter()
            .filter(|w| w.publication_topic_data.topic_name == dds_topic)
            .map(|w| PublisherId(ros2_client::Gid::from(w.writer_proxy.remote_writer_guid)))
            .collect()
    }
}

/// `rmw_dds_common/msg/Gid` (16 bytes from Iron on).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
struct GidMsg([u8; 16]);

/// `rmw_dds_common/msg/NodeEntitiesInfo`.
#[derive(Debug, Clone, Deserialize)]
struct NodeEntitiesMsg {
    node_namespace: String,
    node_name: String,
    _reader_gid_seq: Vec<GidMsg>,
    writer_gid_seq: Vec<GidMsg>,
}

/// `rmw_dds_common/msg/ParticipantEntitiesInfo`: what a ROS 2 participant says of its nodes
/// on `ros_discovery_info`. ros2-client reads it only in a spinner, and keeps the writers' GIDs
/// private; this mirror reads them.
#[derive(Debug, Clone, Deserialize)]
struct ParticipantEntitiesMsg {
    _gid: GidMsg,
    node_entities_info_seq: Vec<NodeEntitiesMsg>,
}

/// Which ROS 2 node a publisher belongs to, from `ros_discovery_info`: read when asked, never
/// while messages flow.
pub struct NodeNames {
    reader: ros2_client::dds::rustdds::no_key::DataReader<
        ParticipantEntitiesMsg,
        ros2_client::dds::rustdds::CDRDeserializerAdapter<ParticipantEntitiesMsg>,
    >,
    /// Writer GID to the node's full name.
    known: Vec<([u8; 16], String)>,
}

impl NodeNames {
    /// The node of `publisher`, as far as the participants have said.
    pub fn node_of(&mut self, publisher: PublisherId) -> Option<String> {
        while let Ok(Some(sample)) = self.reader.take_next_sample() {
            for node in &sample.value().node_entities_info_seq {
                let ns = node.node_namespace.trim_end_matches('/');
                let name = format!("{ns}/{}", node.node_name);
                for w in &node.writer_gid_seq {
                    match self.known.iter_mut().find(|(g, _)| *g == w.0) {
                        Some(entry) => entry.1.clone_from(&name),
                        None => self.known.push((w.0, name.clone())),
                    }
                }
            }
        }
        let gid = publisher.0.to_bytes16();
        self.known
            .iter()
            .find(|(g, _)| *g == gid)
            .map(|(_, n)| n.clone())
    }
}

impl Ros2Node {
    /// A reader of `ros_discovery_info`, to name the node of a publisher.
    pub fn node_names(&self) -> Result<NodeNames, TransportError> {
        use ros2_client::dds::rustdds::policy::{
            Durability as DdsDurability, History as DdsHistory,
        };
        use ros2_client::dds::rustdds::{QosPolicyBuilder, TopicKind};
        let dp = self._context.domain_participant();
        let qos = QosPolicyBuilder::new()
            .durability(DdsDurability::TransientLocal)
            .reliable(ros2_client::dds::rustdds::Duration::ZERO)
            .history(DdsHistory::KeepLast { depth: 100 })
            .build();
        let err = |e: String| setup("ros_discovery_info reader", "ros_discovery_info", e);
        let topic = dp
            .create_topic(
                "ros_discovery_info".to_string(),
                "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_".to_string(),
                &qos,
                TopicKind::NoKey,
            )
            .map_err(|e| err(format!("{e:?}")))?;
        let reader = dp
            .create_subscriber(&qos)
            .map_err(|e| err(format!("{e:?}")))?
            .create_datareader_no_key_cdr::<ParticipantEntitiesMsg>(&topic, Some(qos))
            .map_err(|e| err(format!("{e:?}")))?;
        Ok(NodeNames {
            reader,
            known: Vec::new(),
        })
    }
}

/// A DDS type name as ROS 2 writes it (`sensor_msgs::msg::dds_::Imu_`) in ROS 2's own form
/// (`sensor_msgs/msg/Imu`); another name as it is.
pub fn ros_type_name(dds: &str) -> String {
    match dds.split_once("::dds_::") {
        Some((pkg, ty)) => format!("{}/{}", pkg.replace("::", "/"), ty.trim_end_matches('_')),
        None => dds.to_string(),
    }
}

fn publish_qos(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Fail)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

fn subscribe_qos(depth: usize) -> QosProfile {
    QosProfile::subscription_default()
        .reliability_best_effort()
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
struct TimeMsg {
    sec: i32,
    nanosec: u32,
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct HeaderMsg {
    stamp: TimeMsg,
    frame_id: String,
}

/// `sensor_msgs/msg/Imu`; vectors and quaternions as CDR tuples (the same bytes as structs).
#[derive(Debug, Clone, Serialize, Deserialize)]
struct ImuMsg {
    header: HeaderMsg,
    orientation: [f64; 4],
    orientation_covariance: [f64; 9],
    angular_velocity: [f64; 3],
    angular_velocity_covariance: [f64; 9],
    linear_acceleration: [f64; 3],
    linear_acceleration_covariance: [f64; 9],
}

impl From<&Imu> for ImuMsg {
    fn from(m: &Imu) -> ImuMsg {
        ImuMsg {
            header: HeaderMsg {
                stamp: TimeMsg {
                    sec: m.stamp.sec,
                    nanosec: m.stamp.nanosec,
                },
                frame_id: m.frame_id.clone(),
            },
            orientation: m.orientation,
            orientation_covariance: m.orientation_covariance,
            angular_velocity: m.angular_velocity,
            angular_velocity_covariance: m.angular_velocity_covariance,
            linear_acceleration: m.linear_acceleration,
            linear_acceleration_covariance: m.linear_acceleration_covariance,
        }
    }
}

impl From<ImuMsg> for Imu {
    fn from(m: ImuMsg) -> Imu {
        Imu {
            stamp: Time {
                sec: m.header.stamp.sec,
                nanosec: m.header.stamp.nanosec,
            },
            frame_id: m.header.frame_id,
            orientation: m.orientation,
            orientation_covariance: m.orientation_covariance,
            angular_velocity: m.angular_velocity,
            angular_velocity_covariance: m.angular_velocity_covariance,
            linear_acceleration: m.linear_acceleration,
            linear_acceleration_covariance: m.linear_acceleration_covariance,
        }
    }
}

/// `sensor_msgs/msg/MagneticField`.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct MagMsg {
    header: HeaderMsg,
    magnetic_field: [f64; 3],
    magnetic_field_covariance: [f64; 9],
}

impl From<MagMsg> for MagneticField {
    fn from(m: MagMsg) -> MagneticField {
        MagneticField {
            stamp: Time {
                sec: m.header.stamp.sec,
                nanosec: m.header.stamp.nanosec,
            },
            frame_id: m.header.frame_id,
            magnetic_field: m.magnetic_field,
            magnetic_field_covariance: m.magnetic_field_covariance,
        }
    }
}

/// Receives [`MagneticField`] messages.
pub struct MagSubscription {
    subscription: Subscription<MagMsg>,
}

impl MagSubscription {
    /// The next message that arrived, if any; never waits. An error is a message that could
    /// not be read.
    pub fn take(&self) -> Result<Option<MagneticField>, String> {
        match self.subscription.take() {
            Ok(m) => Ok(m.map(|(msg, _)| MagneticField::from(msg))),
            Err(e) => Err(format!("{e:?}")),
        }
    }
}

/// `geometry_msgs/msg/Twist`: linear and angular velocity.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
struct TwistMsg {
    linear: [f64; 3],
    angular: [f64; 3],
}

/// `geometry_msgs/msg/TwistWithCovariance`.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
struct TwistCovMsg {
    twist: TwistMsg,
    covariance: [[f64; 6]; 6],
}

/// `geometry_msgs/msg/TwistStamped`.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct TwistStampedMsg {
    header: HeaderMsg,
    twist: TwistMsg,
}

/// `geometry_msgs/msg/TwistWithCovarianceStamped`.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct TwistCovStampedMsg {
    header: HeaderMsg,
    twist: TwistCovMsg,
}

/// `geometry_msgs/msg/PoseWithCovariance`: position, orientation (x, y, z, w), covariance.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
struct PoseCovMsg {
    position: [f64; 3],
    orientation: [f64; 4],
    covariance: [[f64; 6]; 6],
}

/// `nav_msgs/msg/Odometry`.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct OdometryMsg {
    header: HeaderMsg,
    child_frame_id: String,
    pose: PoseCovMsg,
    twist: TwistCovMsg,
}

/// Publishes [`Imu`] messages.
pub struct ImuPublisher {
    publisher: Publisher<ImuMsg>,
}

impl ImuPublisher {
    /// Publish `imu`; never waits. An error says why it was not sent (a full send window of a
    /// reliable subscriber that does not keep up, among others).
    pub fn publish(&self, imu: &Imu) -> Result<(), String> {
        self.publisher
            .publish(ImuMsg::from(imu))
            .map_err(|e| format!("{:?}", e.forget_data()))
    }
}

/// A message's CDR after the encapsulation header, as we encoded it by hand: serialized byte
/// by byte as a tuple (no length, no alignment), so the bytes on the wire are ours; ros2-client
/// writes the encapsulation header (plain CDR, little-endian, as ours).
struct CdrBody(Vec<u8>);

impl Serialize for CdrBody {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeTuple as _;
        let mut t = s.serialize_tuple(self.0.len())?;
        for b in &self.0 {
            t.serialize_element(b)?;
        }
        t.end()
    }
}

/// Publishes messages encoded by hand (`Vector3Stamped`, `DiagnosticArray`:
/// `diagnostics.rs`).
pub struct CdrPublisher {
    publisher: Publisher<CdrBody>,
}

impl CdrPublisher {
    /// Publish `cdr`, a little-endian CDR message with its encapsulation header (`00 01 00
    /// 00`); never waits. An error says why it was not sent.
    pub fn publish(&self, cdr: &[u8]) -> Result<(), String> {
        match cdr {
            [0, 1, _, _, body @ ..] => self
                .publisher
                .publish(CdrBody(body.to_vec()))
                .map_err(|e| format!("{:?}", e.forget_data())),
            _ => Err("not little-endian plain CDR".into()),
        }
    }
}

/// Which publisher a message came from (a restarted driver is a new one).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PublisherId(ros2_client::Gid);

impl std::fmt::Display for PublisherId {
    /// The GID in hex, as `ros2 topic info --verbose` shows it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}", self.0)
    }
}

/// Receives [`Imu`] messages.
pub struct ImuSubscription {
    subscription: Subscription<ImuMsg>,
}

impl ImuSubscription {
    /// The next message that arrived, if any, with its publisher's id; never waits. An error
    /// is a message that could not be read (a malformed one).
    pub fn take(&self) -> Result<Option<(Imu, PublisherId)>, String> {
        match self.subscription.take() {
            Ok(m) => Ok(m.map(|(msg, info)| (Imu::from(msg), PublisherId(info.publisher_gid())))),
            Err(e) => Err(format!("{e:?}")),
        }
    }
}

/// The package and name of a motion kind's ROS 2 type.
fn motion_type(kind: MotionKind) -> (&'static str, &'static str) {
    match kind {
        MotionKind::Odometry => ("nav_msgs", "Odometry"),
        MotionKind::TwistStamped => ("geometry_msgs", "TwistStamped"),
        MotionKind::TwistWithCovarianceStamped => ("geometry_msgs", "TwistWithCovarianceStamped"),
    }
}

enum MotionPort {
    Odometry(Subscription<OdometryMsg>),
    Twist(Subscription<TwistStampedMsg>),
    TwistCov(Subscription<TwistCovStampedMsg>),
}

impl MotionPort {
    /// Its GUID, whichever message it takes.
    fn guid(&self) -> GUID {
        match self {
            MotionPort::Odometry(s) => s.guid(),
            MotionPort::Twist(s) => s.guid(),
            MotionPort::TwistCov(s) => s.guid(),
        }
    }
}

/// Receives a vehicle's motion.
pub struct MotionSubscription {
    port: MotionPort,
}

impl MotionSubscription {
    /// The next motion message that arrived, if any; never waits. An error is a message that
    /// could not be read.
    pub fn take(&self) -> Result<Option<Motion>, String> {
        let taken = match &self.port {
            MotionPort::Odometry(s) => s
                .take()
                .map(|m| m.map(|(m, _)| (m.header, m.twist.twist, Some(m.twist.covariance)))),
            MotionPort::Twist(s) => s.take().map(|m| m.map(|(m, _)| (m.header, m.twist, None))),
            MotionPort::TwistCov(s) => s
                .take()
                .map(|m| m.map(|(m, _)| (m.header, m.twist.twist, Some(m.twist.covariance)))),
        }
        .map_err(|e| format!("{e:?}"))?;
        let Some((header, twist, covariance)) = taken else {
            return Ok(None);
        };
        Ok(Some(Motion {
            stamp: Time {
                sec: header.stamp.sec,
                nanosec: header.stamp.nanosec,
            },
            linear: twist.linear,
            yaw_rate: twist.angular[2],
            variance: covariance.map_or([f64::NAN; 6], |c| std::array::from_fn(|i| c[i][i])),
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_domain_comes_from_ros_domain_id_and_is_checked() {
        // One test touches the variable: tests run in parallel threads of one process.
        for (v, want) in [
            (None, Ok(0)),
            (Some(""), Ok(0)),
            (Some("42"), Ok(42)),
            (Some(" 7 "), Ok(7)),
            (Some("232"), Ok(232)),
        ] {
            match v {
                Some(v) => std::env::set_var(DOMAIN_ENV, v),
                None => std::env::remove_var(DOMAIN_ENV),
            }
            assert_eq!(domain_id(), want, "{v:?}");
        }
        for bad in ["233", "-1", "x"] {
            std::env::set_var(DOMAIN_ENV, bad);
            assert!(domain_id().unwrap_err().contains("0 to 232"), "{bad}");
        }
        std::env::remove_var(DOMAIN_ENV);
    }

    #[test]
    fn an_imu_round_trips_through_its_mirror() {
        let imu = Imu {
            stamp: Time {
                sec: 1_700_000_000,
                nanosec: 123_456_789,
            },
            frame_id: "imu_link".into(),
            orientation: [0.0, 0.0, 0.0, 1.0],
            orientation_covariance: [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            angular_velocity: [0.1, -0.2, 0.3],
            angular_velocity_covariance: [1e-6, 0.0, 0.0, 0.0, 2e-6, 0.0, 0.0, 0.0, 3e-6],
            linear_acceleration: [0.0; 3],
            linear_acceleration_covariance: [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        };
        assert_eq!(Imu::from(ImuMsg::from(&imu)), imu);
    }

    /// Our hand codec of MagneticField (bags) reads what RustDDS's CDR writes of the live
    /// mirror, and writes the same bytes.
    #[test]
    fn the_hand_magnetic_field_codec_agrees_with_the_live_mirror() {
        use ros2_client::dds::rustdds::no_key::SerializerAdapter as _;
        use ros2_client::dds::rustdds::CDRSerializerAdapter;
        for frame in ["", "m", "imu_link", "a_longer_frame_id"] {
            let msg = MagMsg {
                header: HeaderMsg {
                    stamp: TimeMsg {
                        sec: 1_700_000_001,
                        nanosec: 5,
                    },
                    frame_id: frame.into(),
                },
                magnetic_field: [2e-5, -3e-6, -4e-5],
                magnetic_field_covariance: [1e-12, 0.0, 0.0, 0.0, 2e-12, 0.0, 0.0, 0.0, 3e-12],
            };
            let body = CDRSerializerAdapter::<MagMsg>::to_bytes(&msg).unwrap();
            let mut bytes = vec![0, 1, 0, 0];
            bytes.extend_from_slice(&body);
            let ours = MagneticField::from_cdr(&bytes).unwrap();
            assert_eq!(ours, MagneticField::from(msg), "{frame:?}");
            let mut back = ours.to_cdr().unwrap();
            // RustDDS pads nothing after the last field; ours neither.
            assert_eq!(back.split_off(4), body.as_ref(), "{frame:?}");
        }
    }

    #[test]
    fn a_hand_encoded_body_serializes_as_its_own_bytes() {
        use ros2_client::dds::rustdds::no_key::SerializerAdapter as _;
        use ros2_client::dds::rustdds::CDRSerializerAdapter;
        let body = vec![1u8, 0, 0, 0, 2, 0, 0, 0, 3, 0, 0, 0, b'a', b'b', 0];
        let out = CDRSerializerAdapter::<CdrBody>::to_bytes(&CdrBody(body.clone())).unwrap();
        assert_eq!(out.as_ref(), &body[..], "no length, no padding");
    }

    #[test]
    fn dds_type_names_read_as_ros_2_writes_them() {
        assert_eq!(
            ros_type_name("sensor_msgs::msg::dds_::Imu_"),
            "sensor_msgs/msg/Imu"
        );
        assert_eq!(
            ros_type_name("geometry_msgs::msg::dds_::TwistStamped_"),
            "geometry_msgs/msg/TwistStamped"
        );
        assert_eq!(ros_type_name("Other"), "Other");
    }
}
