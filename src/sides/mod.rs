//! The side kinds, one file each: what runs beside a pipeline's chain and reaches it only
//! through its iceoryx2 services ([`contract`] says what a side is).
//!
//! | table | file | what |
//! |---|---|---|
//! | `[ros2]` | [`ros2`] | the daemon as a ROS 2 node: Imu topics in and out, a vehicle's motion in |
//!
//! Adding a side: ARCHITECTURE.md, "Adding a side or a transport".

pub mod contract;
pub mod ros2;

pub use contract::{Chain, Kind, Ready, Side, SideSpec, Start};

/// Every side kind, in the order listed in messages and documentation.
pub const SIDES: &[&Kind] = &[&ros2::KIND];
