//! The daemon's statistics on the wire ([`StatsSnapshot`]), published every report interval.

/// Type name of [`StatsSnapshot`] on the wire; `.v4` names the layout, as for
/// [`super::GYRO_TYPE_NAME`].
pub const STATS_TYPE_NAME: &str = "driftless::StatsSnapshot.v4";
/// The layout version of [`StatsSnapshot`] (the `.vN` of [`STATS_TYPE_NAME`]).
pub const STATS_VERSION: u32 = 4;
/// The type name of [`StatsSnapshot`] version 1 (904 bytes, before the misses' explanation).
pub const STATS_V1_TYPE_NAME: &str = "driftless::StatsSnapshot";
/// Size of [`StatsSnapshot`] version 1, bytes.
pub const STATS_V1_SIZE: usize = 904;
/// Size of [`StatsSnapshot`] version 2, bytes (before the stamp faults and the warm start).
pub const STATS_V2_SIZE: usize = 936;
/// Size of [`StatsSnapshot`] version 3, bytes (before the odometry).
pub const STATS_V3_SIZE: usize = 952;
/// [`StatsSnapshot::last_miss_off_cpu_ns`] when it was not measured (an output after an
/// `external` stage, whose sample crossed threads): the miss cannot be explained.
pub const OFF_CPU_NOT_MEASURED: u64 = u64::MAX;

/// Latency percentiles of one histogram, in nanoseconds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C)]
pub struct Percentiles {
    /// Number of recorded values.
    pub count: u64,
    /// Median.
    pub p50: u64,
    /// 99th percentile.
    pub p99: u64,
    /// 99.9th percentile.
    pub p999: u64,
    /// Maximum.
    pub max: u64,
}

/// Most stages a [`StatsSnapshot`] describes.
pub const MAX_STATS_STAGES: usize = 8;

/// One stage in a [`StatsSnapshot`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C)]
pub struct StageStats {
    /// Stage name, UTF-8, NUL-padded (truncated to 32 bytes).
    pub name: [u8; 32],
    /// Samples that entered the stage.
    pub samples_in: u64,
    /// Samples the stage emitted.
    pub samples_out: u64,
    /// Samples a subscriber of the stage's output could not take (its buffer was full).
    pub lost: u64,
    /// Time per sample: compute and the publish of the output.
    pub compute: Percentiles,
}

impl StageStats {
    /// Its name as text (up to the first NUL).
    pub fn name_text(&self) -> String {
        let end = self
            .name
            .iter()
            .position(|&b| b == 0)
            .unwrap_or(self.name.len());
        String::from_utf8_lossy(&self.name[..end]).into_owned()
    }
}

/// The daemon's statistics, published on the pipeline's stats service every report interval.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C)]
pub struct StatsSnapshot {
    /// Nanoseconds since the pipeline started.
    pub uptime_ns: u64,
    /// Samples ingested.
    pub samples_in: u64,
    /// Samples published by the final stage.
    pub samples_out: u64,
    /// Ingest rate over the last interval, Hz.
    pub rate_hz: f64,
    /// Outputs whose end-to-end latency exceeded the deadline.
    pub deadline_misses: u64,
    /// Samples lost by subscribers of any of our services (full buffers).
    pub lost: u64,
    /// Flags raised on input and output: invalid input, gaps, stamp faults, repaired outputs.
    pub flagged: u64,
    /// Sequence numbers missing in the input.
    pub gap_samples: u64,
    /// Per-sample metric records the reporting thread could not take (histograms incomplete).
    pub metric_drops: u64,
    /// The deadline, ns.
    pub deadline_ns: u64,
    /// Algorithmic delay of the chain (sum of the stages' lags / rate), ns.
    pub algorithmic_delay_ns: u64,
    /// End-to-end latency: ingest of the completing sample to publish of the output.
    pub end_to_end: Percentiles,
    /// Number of valid entries in `stages`.
    pub stage_count: u64,
    /// Per-stage statistics.
    pub stages: [StageStats; MAX_STATS_STAGES],
    /// Of `deadline_misses`, those the kernel explains: the time it kept the hot thread off a
    /// CPU between the sample's ingest and its output covers the overshoot (version 2).
    pub deadline_misses_explained: u64,
    /// The latest miss: when, ns since the pipeline started (0: none yet).
    pub last_miss_uptime_ns: u64,
    /// The latest miss's end-to-end latency, ns.
    pub last_miss_e2e_ns: u64,
    /// The hot thread's time off a CPU during the latest miss, ns; [`OFF_CPU_NOT_MEASURED`]
    /// when not measured.
    pub last_miss_off_cpu_ns: u64,
    /// Of `flagged`, samples whose stamp was not believed ([`FLAG_STAMP_FAULT`](crate::wire::flags::FLAG_STAMP_FAULT)); never counted
    /// in `lost` (version 3).
    pub stamp_faults: u64,
    /// How the pipeline's state-keeping stage started: one of the `WARM_START_*` codes.
    pub warm_start: u64,
    /// What the vehicle's odometry did for the bias filter (version 4).
    pub odometry: OdometryStats,
}

/// What the vehicle's odometry (a yaw rate on `predict.bias`'s `stop_input`) did for the bias
/// filter so far: a part of [`StatsSnapshot`] (72 bytes). All zero (`up` 0) when no stage
/// uses a yaw rate.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C)]
pub struct OdometryStats {
    /// The gyro axis that is the vehicle's up: 1 +x, 2 -x, 3 +y, 4 -y, 5 +z, 6 -z;
    /// [`UP_GRAVITY_PENDING`]: from gravity, not told yet; 0: no stage uses a yaw rate
    /// ([`OdometryStats::up_name`]).
    pub up: u64,
    /// The mounting check's verdict: one of the `MOUNTING_*` codes.
    pub mounting: u64,
    /// Spans (0.5 s of messages) that passed the slip test.
    pub spans_accepted: u64,
    /// Spans rejected: slips, or a span that disagreed with the next.
    pub spans_rejected: u64,
    /// Runs of rejected spans: the slips caught.
    pub slips: u64,
    /// Measurements the bias filter took from the odometry.
    pub learnt: u64,
    /// The odometry's learnt scale correction (true yaw rate = (1 + scale) x the odometry's).
    pub scale: f64,
    /// Its standard deviation (1 sigma).
    pub scale_sd: f64,
    /// What the odometry's measurements moved the up axis's bias estimate by, summed, rad/s
    /// (on the gyro's axis, its sign as the gyro's): the bias learnt in motion.
    pub bias_learnt_rad_s: f64,
}

/// [`OdometryStats::up`]: `vehicle_up = "gravity"`, and no rest with the accelerometer yet.
pub const UP_GRAVITY_PENDING: u64 = 7;

/// [`OdometryStats::mounting`]: not judged yet (too little turning).
pub const MOUNTING_UNKNOWN: u64 = 0;
/// [`OdometryStats::mounting`]: the gyro's up axis turns with the odometry.
pub const MOUNTING_CONFIRMED: u64 = 1;
/// [`OdometryStats::mounting`]: they turn against each other; the yaw rate is refused.
pub const MOUNTING_WRONG_SIGN: u64 = 2;
/// [`OdometryStats::mounting`]: the axis does not see the turns; the yaw rate is refused.
pub const MOUNTING_WRONG_AXIS: u64 = 3;

/// The words of [`OdometryStats::up`]'s codes 0 to 6, as `vehicle_up` writes them.
pub const UP_AXES: [&str; 7] = ["none", "+x", "-x", "+y", "-y", "+z", "-z"];

impl OdometryStats {
    /// The code of gyro axis `axis` (0, 1, 2) pointing up with `sign` (> 0: +).
    pub fn up_code(axis: usize, sign: f64) -> u64 {
        1 + 2 * axis as u64 + u64::from(sign < 0.0)
    }

    /// The words of [`OdometryStats::up`]: `+z`, ...; `none`.
    pub fn up_name(&self) -> &'static str {
        match self.up {
            UP_GRAVITY_PENDING => "gravity, not told yet",
            code => UP_AXES.get(code as usize).copied().unwrap_or("none"),
        }
    }

    /// The words of [`OdometryStats::mounting`].
    pub fn mounting_name(&self) -> &'static str {
        match self.mounting {
            MOUNTING_UNKNOWN => "not judged",
            MOUNTING_CONFIRMED => "confirmed",
            MOUNTING_WRONG_SIGN => "refused: wrong sign",
            MOUNTING_WRONG_AXIS => "refused: wrong axis",
            _ => "unknown",
        }
    }
}

/// [`StatsSnapshot::warm_start`]: no stage of the pipeline keeps state across runs.
pub const WARM_START_NONE: u64 = 0;
/// [`StatsSnapshot::warm_start`]: resumed from the saved state.
pub const WARM_START_WARM: u64 = 1;
/// [`StatsSnapshot::warm_start`]: started cold: no saved state yet, or one too old to use.
pub const WARM_START_COLD: u64 = 2;
/// [`StatsSnapshot::warm_start`]: started cold because the saved state could not be used (it
/// was damaged or another sensor's); the file was moved aside.
pub const WARM_START_UNUSABLE: u64 = 3;

/// The words of a [`StatsSnapshot::warm_start`] code.
pub fn warm_start_name(code: u64) -> &'static str {
    match code {
        WARM_START_NONE => "none",
        WARM_START_WARM => "warm",
        WARM_START_COLD => "cold",
        WARM_START_UNUSABLE => "cold, the saved state unusable (moved aside)",
        _ => "unknown",
    }
}

impl StatsSnapshot {
    /// Whether the latest miss was the kernel's ([`crate::clock::miss_explained`]); `None`
    /// when there has been none.
    pub fn last_miss_explained(&self) -> Option<bool> {
        (self.last_miss_uptime_ns > 0).then(|| {
            crate::clock::miss_explained(
                self.last_miss_e2e_ns,
                self.last_miss_off_cpu(),
                self.deadline_ns,
            )
        })
    }

    /// The latest miss's time off a CPU, ns; `None` when not measured.
    pub fn last_miss_off_cpu(&self) -> Option<u64> {
        (self.last_miss_off_cpu_ns != OFF_CPU_NOT_MEASURED).then_some(self.last_miss_off_cpu_ns)
    }
}
