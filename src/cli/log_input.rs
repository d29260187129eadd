//! The input log of the offline commands: a CSV file or a ROS 2 bag ([`crate::io::rate_log`]).

use std::path::Path;

use super::CliError;
use crate::allan::RateUnit;
use crate::io::rate_log::{read_log, LogOrigin, RateLog};

/// The options a command that reads a log takes for a ROS 2 bag.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct BagArgs {
    /// For a ROS 2 bag input (an MCAP file or a rosbag2 directory): its sensor_msgs/msg/Imu
    /// topic (default: its only one). A bag's columns are x, y, z (angular_velocity, rad/s);
    /// its rate comes from the header stamps.
    #[arg(long, value_name = "TOPIC")]
    pub topic: Option<String>,
}

/// Read the log at `path` (its `columns`, all without), saying on stderr what is irregular
/// in a bag's stamps.
pub fn open(
    path: &Path,
    columns: &[String],
    bag: &BagArgs,
    keep_time: bool,
) -> Result<RateLog, CliError> {
    let log = read_log(path, columns, bag.topic.as_deref(), keep_time)?;
    if let Some(note) = log.origin.stamp_note() {
        eprintln!("driftless: warning: {note}");
    }
    Ok(log)
}

/// The unit of a log's rates: a bag's rad/s (`given` must agree), else `given`, deg/s
/// without it.
pub fn rate_unit(origin: &LogOrigin, given: Option<&str>) -> Result<RateUnit, CliError> {
    origin
        .units(given)
        .map_err(CliError::input)?
        .parse()
        .map_err(|e| CliError::input(format!("--units: {e}")))
}
