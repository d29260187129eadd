//! ROS 2: its messages, and (cargo feature `ros2`) live topics over DDS.
//!
//! | file | concern |
//! |---|---|
//! | `imu.rs` | `sensor_msgs/msg/Imu`: fields, CDR by hand, and [`ImuMapping`] from our samples |
//! | `dds.rs` | live topics: a node in the ROS 2 graph, Imu in and out, motion as a stop signal (feature `ros2`) |

#[cfg(feature = "ros2")]
mod dds;
mod imu;

#[cfg(feature = "ros2")]
pub use dds::{
    domain_id, ImuPublisher, ImuSubscription, MotionKind, MotionSubscription, Ros2Node, DOMAIN_ENV,
};

pub use imu::{seconds_text, CdrError, Imu, ImuMapping, Time, IMU_DEFINITION};
