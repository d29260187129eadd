//! The input log of the offline commands: a CSV file or a ROS 2 bag ([`crate::rate_log`]).

use std::path::Path;
use std::str::FromStr;

use super::CliError;
use crate::rate_log::{read_log, RateLog};

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
/// in a bag's stamps, and that it was read by what it holds when its name claims another
/// format.
pub fn open(
    path: &Path,
    columns: &[String],
    bag: &BagArgs,
    keep_time: bool,
) -> Result<RateLog, CliError> {
    let log = read_log(path, columns, bag.topic.as_deref(), keep_time)?;
    for note in [&log.origin.format_note, &log.origin.stamp_note()]
        .into_iter()
        .flatten()
    {
        eprintln!("driftless: warning: {note}");
    }
    Ok(log)
}

/// A CSV input that is not a rate log (a `--truth` file, `takes` saying what it is): refused
/// unless it holds text (gzip-compressed too), with one line on stderr when its name claims
/// another format.
pub fn check_text_input(path: &Path, takes: &str) -> Result<(), CliError> {
    let sniffed = crate::io::content::text_file(path, takes)?;
    if let Some(note) = sniffed.csv_note() {
        eprintln!("driftless: warning: {note}");
    }
    Ok(())
}

/// A unit option's text (`--units`, `--accel-units`) as its unit ([`crate::units`]); the error
/// names the option.
pub fn unit_option<U: FromStr<Err = String>>(
    option: &str,
    given: Option<&str>,
) -> Result<Option<U>, CliError> {
    given
        .map(|u| {
            u.parse()
                .map_err(|e| CliError::input(format!("{option}: {e}")))
        })
        .transpose()
}
