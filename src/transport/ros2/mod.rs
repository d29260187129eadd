//! ROS 2: its messages, and (cargo feature `ros2`) live topics over DDS.
//!
//! | file | concern |
//! |---|---|
//! | `imu.rs` | `sensor_msgs/msg/Imu`: fields, CDR by hand, and [`ImuMapping`] from our samples |
//! | `bag.rs` | rosbag2 bags (MCAP): Imu and motion topics read, Imu topics written |
//! | `mag.rs` | `sensor_msgs/msg/MagneticField`, CDR by hand, and [`MagJoinRule`]: the field joined to the Imu samples by stamp |
//! | `motion.rs` | a vehicle's motion (Odometry, twists): its types and its speed, CDR by hand |
//! | `diagnostics.rs` | the bias as `Vector3Stamped` and the filter's `DiagnosticArray`, CDR by hand |
//! | `counts.rs` | what the ROS 2 side carried, and its line at exit (feature `ros2`) |
//! | `bridge.rs` | the daemon's ROS 2 side: topics to services and back, on its own thread (feature `ros2`) |
//! | `mag_in.rs` | the live magnetometer input: a `MagneticField` topic joined to the Imu input's samples (feature `ros2`) |
//! | `dds.rs` | live topics: a node in the ROS 2 graph, Imu in and out, motion as a stop signal (feature `ros2`) |

pub mod bag;
#[cfg(feature = "ros2")]
mod bridge;
#[cfg(feature = "ros2")]
mod counts;
#[cfg(feature = "ros2")]
mod dds;
mod diagnostics;
mod imu;
mod mag;
#[cfg(feature = "ros2")]
mod mag_in;
mod motion;

#[cfg(feature = "ros2")]
pub use bridge::run_bridge;
#[cfg(feature = "ros2")]
pub use counts::{BridgeCounts, MagCounts};
#[cfg(feature = "ros2")]
pub use dds::{
    domain_id, ros_type_name, CdrPublisher, DdsReadiness, ImuPublisher, ImuSubscription,
    MagSubscription, MotionSubscription, NodeNames, PublisherId, Ros2Node, DOMAIN_ENV,
};

pub use diagnostics::{
    BiasDiagnosticSettings, BiasWindow, DiagnosticArray, DiagnosticStatus, Level, PipelineCounts,
    Vector3Stamped, DIAGNOSTICS_TOPIC, DIAGNOSTIC_ARRAY_TYPE, VECTOR3_STAMPED_TYPE,
};
pub use imu::{
    seconds_text, AccelReading, CdrError, Imu, ImuMapping, Time, IMU_DEFINITION, IMU_TYPE,
    NOT_PROVIDED,
};
pub use mag::{
    carry as carry_mag, MagJoin, MagJoinRule, MagReading, MagneticField, DEFAULT_MAG_MAX_AGE_S,
    HELD_READINGS, MAG_TYPE,
};
pub use motion::{Motion, MotionKind};

/// The frame of the Imu messages we write when neither a `frame_id` setting nor an input says
/// one.
pub const DEFAULT_FRAME_ID: &str = "imu_link";

/// The attribute that names the ROS 2 node on the event service where a pipeline's ROS 2 side
/// says what it does (`driftless list` finds the ROS 2 sides by it).
pub const NODE_KEY: &str = "ros2.node";
/// The attribute of its DDS domain.
pub const DOMAIN_KEY: &str = "ros2.domain";
/// The attribute of each of its topics: `<in|out|stop> <topic> <ROS 2 type> <service>`, or
/// `+N more` when they are more than the attributes hold.
pub const TOPIC_KEY: &str = "ros2.topic";

/// The `[ros2]` table: the daemon as a ROS 2 node, its topics and the services they feed or
/// come from (docs/ros2.md); the pipeline file's schema reads it.
#[derive(Debug, Clone, PartialEq)]
pub struct Ros2Settings {
    /// Node name (default: `driftless_<pipeline>`, `-` as `_`).
    pub node: String,
    /// Node namespace (default `/`).
    pub namespace: String,
    /// History depth of every topic (default 100).
    pub depth: usize,
    /// `header.frame_id` of the messages we publish; None: the Imu input's own frame, else
    /// `imu_link` (the module docs of `transport::ros2::bridge`).
    pub frame_id: Option<String>,
    /// White rate noise per sample, deg/s (1 sigma): the published covariance's first term.
    /// None: the covariance is unknown (all zeros).
    pub rate_noise: Option<f64>,
    /// A driver node's `sensor_msgs/msg/Imu` topic and the service it feeds (an
    /// `ingest.iceoryx2` stage's input).
    pub imu_in: Option<(String, String)>,
    /// A driver node's `sensor_msgs/msg/MagneticField` topic, joined by stamp to the samples of
    /// `imu_in` (its service), [`MagJoinRule`].
    pub mag_in: Option<String>,
    /// A reading older than this, s, is no reading ([`MagJoinRule::max_age_ns`]).
    pub mag_max_age_s: f64,
    /// Services published as `sensor_msgs/msg/Imu` topics: (service, topic).
    pub imu_out: Vec<(String, String)>,
    /// The vehicle's motion: its topic, its ROS 2 type and the StopSignal service it feeds (a
    /// `predict.bias` stage's `stop_input`).
    pub motion_in: Option<(String, String, String)>,
    /// The accelerometer's white noise per sample, m/s^2 (1 sigma), for samples that carry no
    /// `accel_std` of their own (None: the driver's covariance as received, else unknown).
    pub accel_noise: Option<f64>,
    /// A service whose bias (`drift`, rad/s) goes out as `geometry_msgs/msg/Vector3Stamped`:
    /// (service, topic).
    pub bias_out: Option<(String, String)>,
    /// A service whose bias filter is judged on `diagnostic_msgs/msg/DiagnosticArray`:
    /// (service, topic).
    pub diagnostics: Option<(String, String)>,
    /// How often the diagnostics are published, s.
    pub diagnostics_period_s: f64,
    /// The diagnostics go to WARN once an axis's bias passes this, rad/s.
    pub bias_threshold: f64,
    /// The pipeline's stats service: the diagnostics' misses and losses.
    pub stats_service: String,
}

/// Which way a topic of the ROS 2 side goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// A driver's Imu into a service.
    In,
    /// A service out as a topic (Imu, the bias, the diagnostics).
    Out,
    /// The vehicle's motion into a stop-signal service.
    Stop,
}

impl Direction {
    /// Its name in `driftless list`.
    pub fn name(self) -> &'static str {
        match self {
            Direction::In => "in",
            Direction::Out => "out",
            Direction::Stop => "stop",
        }
    }
}

/// One topic of a ROS 2 side, with its service.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ros2Topic<'a> {
    /// Which way it goes.
    pub direction: Direction,
    /// The ROS 2 topic.
    pub topic: &'a str,
    /// Its ROS 2 type.
    pub ty: &'a str,
    /// The iceoryx2 service it feeds or comes from.
    pub service: &'a str,
}

impl Ros2Settings {
    /// The frame of the messages we publish, in words (`validate`).
    pub fn frame_text(&self) -> String {
        match (&self.frame_id, &self.imu_in) {
            (Some(f), _) => f.clone(),
            (None, Some(_)) => format!("the driver's ({DEFAULT_FRAME_ID} until it says one)"),
            (None, None) => DEFAULT_FRAME_ID.to_string(),
        }
    }

    /// Every topic: the Imu in, the magnetometer in, each Imu out, the bias out, the diagnostics, the motion in, in
    /// that order.
    pub fn topics(&self) -> Vec<Ros2Topic<'_>> {
        let imu_in = self.imu_in.iter().map(|(topic, service)| Ros2Topic {
            direction: Direction::In,
            topic,
            ty: IMU_TYPE,
            service,
        });
        // The magnetometer feeds the Imu input's service, joined to its samples.
        let mag_in = self
            .mag_in
            .iter()
            .zip(&self.imu_in)
            .map(|(topic, (_, service))| Ros2Topic {
                direction: Direction::In,
                topic,
                ty: MAG_TYPE,
                service,
            });
        let imu_out = self.imu_out.iter().map(|(service, topic)| Ros2Topic {
            direction: Direction::Out,
            topic,
            ty: IMU_TYPE,
            service,
        });
        let bias = self.bias_out.iter().map(|(service, topic)| Ros2Topic {
            direction: Direction::Out,
            topic,
            ty: VECTOR3_STAMPED_TYPE,
            service,
        });
        let diagnostics = self.diagnostics.iter().map(|(service, topic)| Ros2Topic {
            direction: Direction::Out,
            topic,
            ty: DIAGNOSTIC_ARRAY_TYPE,
            service,
        });
        let motion = self.motion_in.iter().map(|(topic, ty, service)| Ros2Topic {
            direction: Direction::Stop,
            topic,
            ty,
            service,
        });
        imu_in
            .chain(mag_in)
            .chain(imu_out)
            .chain(bias)
            .chain(diagnostics)
            .chain(motion)
            .collect()
    }
}
