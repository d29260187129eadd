//! What the ROS 2 side carried, counted on its thread and said in one line at exit
//! ([`BridgeCounts`]; the magnetometer's part, [`MagCounts`]).

/// What the bridge carried.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BridgeCounts {
    /// Imu messages taken from the driver's topic.
    pub imu_in: u64,
    /// Of those, with a non-finite rate (flagged invalid).
    pub imu_in_invalid: u64,
    /// Samples missing from the driver's topic, by its stamps.
    pub imu_in_missing: u64,
    /// Of `imu_in`, with a stamp not believed (flagged; never a loss).
    pub imu_in_stamp_faults: u64,
    /// Imu messages refused: from a second publisher while the first one publishes.
    pub imu_in_refused: u64,
    /// Messages on an input topic that could not be read (malformed).
    pub unreadable: u64,
    /// Times the driver's topic changed publisher (a restart: each a new epoch).
    pub imu_in_publishers: u64,
    /// Imu messages published.
    pub imu_out: u64,
    /// Imu messages not published (a full send window, a stamp no ROS time holds).
    pub imu_out_failed: u64,
    /// Motion messages taken.
    pub motion_in: u64,
    /// Bias messages published.
    pub bias_out: u64,
    /// Diagnostics published.
    pub diagnostics_out: u64,
    /// Bias and diagnostics messages not published.
    pub other_out_failed: u64,
    /// The magnetometer joined to the Imu input (`mag_in`).
    pub mag: MagCounts,
}

impl std::fmt::Display for BridgeCounts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} Imu in ({} invalid, {} stamp faults, {} missing by their stamps, {} new \
             publishers), {} refused (a second publisher), {} Imu out ({} not sent), {} motion \
             in, {} unreadable{}{}",
            self.imu_in,
            self.imu_in_invalid,
            self.imu_in_stamp_faults,
            self.imu_in_missing,
            self.imu_in_publishers,
            self.imu_in_refused,
            self.imu_out,
            self.imu_out_failed,
            self.motion_in,
            self.unreadable,
            if self.bias_out + self.diagnostics_out + self.other_out_failed > 0 {
                format!(
                    ", {} bias out, {} diagnostics out ({} not sent)",
                    self.bias_out, self.diagnostics_out, self.other_out_failed
                )
            } else {
                String::new()
            },
            if self.mag.any() {
                format!(", {}", self.mag)
            } else {
                String::new()
            }
        )
    }
}

/// What the magnetometer input carried.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MagCounts {
    /// MagneticField messages taken.
    pub taken: u64,
    /// Of those, refused: no stamp to join by (0, or before 1970), or older than every
    /// reading held.
    pub refused: u64,
    /// Imu samples that carried a reading.
    pub joined: u64,
    /// Imu samples that carried none (no reading fresh enough: the stream stopped, lags, or
    /// had not started).
    pub missing: u64,
}

impl MagCounts {
    /// Whether anything was counted (a side without `mag_in` counts nothing).
    pub fn any(&self) -> bool {
        *self != MagCounts::default()
    }
}

impl std::fmt::Display for MagCounts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} MagneticField in ({} refused: no stamp, or older than all held), {} Imu with a magnetometer reading, {} \
             without",
            self.taken, self.refused, self.joined, self.missing
        )
    }
}
