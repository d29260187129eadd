//! `driftless record SERVICE... -o run.mcap [--duration D]`: record any of our services into an
//! MCAP file that Foxglove opens and plots without plugins; with `--format ros2`, a ROS 2 bag
//! of `sensor_msgs/msg/Imu` messages, one topic per service. The recorder is
//! [`crate::transport::recorder`]; this file checks the arguments and prints.
//!
//! The recording stops on SIGINT, SIGTERM or `--duration`; a write error (a full disk) stops it
//! with exit code 1 and leaves only `OUT.part`.

use std::path::PathBuf;
use std::time::Duration;

use crate::cli::CliError;
use crate::transport::recorder::{Progress, RecordError, Recorder, Ros2Bag, Settings, Summary};
use crate::transport::{self, WireType};
use crate::units::{AccelUnit, RateUnit};

/// Arguments of `driftless record`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Services to record, e.g. demo/raw demo/corrected demo/stats (any hop of a pipeline).
    #[arg(required = true)]
    pub services: Vec<String>,
    /// The MCAP file to write (it appears when the recording stops; OUT.part until then).
    #[arg(short, long, value_name = "OUT.mcap")]
    pub output: PathBuf,
    /// Stop by itself after this long ("10s", "500ms", "1.5s", "90min", or seconds).
    #[arg(
        long,
        value_parser = crate::cli::duration::parse_duration,
        allow_hyphen_values = true
    )]
    pub duration: Option<Duration>,
    /// Where the pipeline's iceoryx2 files are.
    #[command(flatten)]
    pub iceoryx2: crate::cli::iceoryx2::Iceoryx2Args,
    /// Units of raw services' rates (the pipeline's input_units), stored with their channels
    /// (with --format ros2, needed to write a raw service in rad/s).
    #[arg(long, value_parser = super::unit_arg::<RateUnit>(RateUnit::NAMES))]
    pub raw_units: Option<RateUnit>,
    /// What to write: `mcap`, our samples as JSON that Foxglove plots; or `ros2`, a ROS 2 bag
    /// (profile ros2, sensor_msgs/msg/Imu in CDR, topic /SERVICE) as `ros2 bag record` writes.
    #[arg(long, default_value = "mcap", value_parser = ["mcap", "ros2"])]
    pub format: String,
    /// With --format ros2: the messages' header.frame_id.
    #[arg(long, default_value = crate::transport::ros2::DEFAULT_FRAME_ID)]
    pub frame_id: String,
    /// With --format ros2: the gyro's white rate noise, 1 sigma of one sample in deg/s (N x
    /// sqrt(rate) from `driftless allan`'s N in deg/sqrt(s), or the data sheet's rate noise).
    /// Its square plus the square of the drift's own uncertainty (`drift_std`) is each axis'
    /// angular_velocity_covariance; without it the covariance is all zeros ("unknown").
    #[arg(long, value_name = "DEG_PER_S")]
    pub rate_noise: Option<f64>,
    /// With --format ros2: the accelerometer's white noise, 1 sigma of one sample in m/s^2 (VRW
    /// x sqrt(rate)), for samples that carry no accel_std of their own: its square is each
    /// axis' linear_acceleration_covariance. Without either, the covariance of a reading is all
    /// zeros ("unknown"; robot_localization then trusts it far too much).
    #[arg(long, value_name = "M_PER_S2")]
    pub accel_noise: Option<f64>,
    /// Units of raw services' accelerometer readings (the pipeline's accel_units), stored with
    /// their channels; with --format ros2, needed to write them in m/s^2 (without it a raw
    /// reading is written "not provided").
    #[arg(long, value_parser = super::unit_arg::<AccelUnit>(AccelUnit::NAMES))]
    pub raw_accel_units: Option<AccelUnit>,
}

/// Subscribe to SERVICE... and record them until stopped.
pub fn run(args: Args) -> Result<(), CliError> {
    transport::quiet_logging();
    let mut seen = std::collections::HashSet::new();
    for s in &args.services {
        transport::check_service_name(s)
            .map_err(|e| CliError::input(format!("invalid service name {s:?}: {e}")))?;
        if !seen.insert(s.as_str()) {
            return Err(CliError::input(format!("service {s:?} named twice")));
        }
    }
    let ros2 = args.format == "ros2";
    if let Some(n) = args.rate_noise {
        if !ros2 {
            return Err(CliError::input(
                "--rate-noise is for --format ros2 (the covariance)",
            ));
        }
        if !(n.is_finite() && n >= 0.0) {
            return Err(CliError::input(format!(
                "--rate-noise {n} must be a finite number of deg/s >= 0"
            )));
        }
    }
    if let Some(n) = args.accel_noise {
        if !ros2 {
            return Err(CliError::input(
                "--accel-noise is for --format ros2 (the covariance)",
            ));
        }
        if !(n.is_finite() && n >= 0.0) {
            return Err(CliError::input(format!(
                "--accel-noise {n} must be a finite number of m/s^2 >= 0"
            )));
        }
    }
    if args.frame_id != crate::transport::ros2::DEFAULT_FRAME_ID && !ros2 {
        return Err(CliError::input("--frame-id is for --format ros2"));
    }
    let prefix = args.iceoryx2.resolve(None)?;
    let result = record(&args, &prefix);
    transport::remove_prefix_leftovers(&prefix);
    result
}

impl From<RecordError> for CliError {
    fn from(e: RecordError) -> Self {
        match e {
            RecordError::Input(m) => CliError::input(m),
            RecordError::Failed(m) => CliError::internal(m),
            RecordError::Transport(e) => e.into(),
        }
    }
}

fn record(args: &Args, prefix: &str) -> Result<(), CliError> {
    let settings = Settings {
        services: args.services.clone(),
        output: args.output.clone(),
        raw_units: args.raw_units,
        raw_accel_units: args.raw_accel_units,
        ros2: (args.format == "ros2").then(|| Ros2Bag {
            frame_id: args.frame_id.clone(),
            rate_noise: args.rate_noise,
            accel_noise: args.accel_noise,
            raw_accel_to_m_s2: args.raw_accel_units.map(AccelUnit::to_m_per_s2),
        }),
    };
    // Installed in main, before anything exists on disk: a signal ends the recording cleanly.
    let stop = crate::cli::signals::stop_flag();
    let recorder = Recorder::start(&settings, prefix)?;
    eprintln!(
        "driftless: recording {} to {} (Ctrl-C to stop)",
        recorder.channels().join(", "),
        args.output.display()
    );
    let bar = args.duration.map(crate::io::progress::timed);
    let outcome = recorder.run(
        &stop,
        crate::cli::signals::stopped_by,
        args.duration,
        |p: &Progress| {
            for (service, new, total) in &p.new_gaps {
                eprintln!(
                    "driftless: warning: {service}: {new} sample(s) missing (sequence gaps), \
                     {total} so far"
                );
            }
            if let Some(bar) = &bar {
                bar.set_position(p.elapsed.as_millis() as u64);
                bar.set_message(format!(
                    "{:.0} s, {} samples, {:.1} MB",
                    p.elapsed.as_secs_f64(),
                    p.samples,
                    p.bytes as f64 / 1e6
                ));
            }
        },
    );
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    if settings.ros2.is_some() && args.rate_noise.is_none() {
        eprintln!(
            "driftless: note: no --rate-noise: angular_velocity_covariance written as all zeros \
             (unknown to the reader)"
        );
    }
    let summary = outcome?;
    let no_units: u64 = summary.services.iter().map(|s| s.accel_units_unknown).sum();
    if no_units > 0 {
        eprintln!(
            "driftless: note: {no_units} raw accelerometer reading(s) written \"not provided\": \
             give --raw-accel-units (the pipeline's accel_units) to write them in m/s^2"
        );
    }
    let unknown: u64 = summary.services.iter().map(|s| s.accel_unknown).sum();
    if unknown > 0 {
        eprintln!(
            "driftless: note: {unknown} accelerometer reading(s) with no accel_std and no \
             --accel-noise: linear_acceleration_covariance written as all zeros (unknown to the \
             reader; robot_localization raises it to 1e-9 and trusts the reading far too much)"
        );
    }
    print_summary(&summary);
    Ok(())
}

/// Each service's counts, and the file written.
fn print_summary(summary: &Summary) {
    for s in &summary.services {
        let c = &s.counts;
        if s.wire == WireType::Stats {
            eprintln!("{}: {} snapshots", s.service, c.samples);
        } else {
            eprintln!(
                "{}: {} samples, {} missing (sequence gaps), {} epoch(s)",
                s.service, c.samples, c.missing, c.epochs
            );
            if s.held > 0 {
                eprintln!(
                    "driftless: warning: {}: {} message(s) carry a value a stage held or \
                     replaced (flagged input_invalid or output_repaired on the wire; an Imu \
                     message cannot say it)",
                    s.service, s.held
                );
            }
        }
    }
    eprintln!(
        "wrote {} ({:.1} MB, stopped by {})",
        summary.output.display(),
        summary.bytes as f64 / 1e6,
        summary.stopped_by
    );
}
