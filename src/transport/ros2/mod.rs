//! ROS 2: its messages, and (cargo feature `ros2`) live topics over DDS.
//!
//! | file | concern |
//! |---|---|
//! | `imu.rs` | `sensor_msgs/msg/Imu`: fields, CDR by hand, and [`ImuMapping`] from our samples |

mod imu;

pub use imu::{seconds_text, CdrError, Imu, ImuMapping, Time, IMU_DEFINITION};
