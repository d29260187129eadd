//! `driftless mag-cal`: the magnetometer's hard and soft iron from a recorded rotation
//! ([`crate::attitude::mag_cal`]), printed as a summary in comments and a ready `attitude.6d`
//! `[[stage]]` table: the whole output is TOML.

use std::fmt::Write as _;
use std::path::PathBuf;

use super::CliError;
use crate::attitude::mag_cal::{self, Extent, MagCal};
use crate::rate_log::read_mag_log;
use crate::units::MagUnit;

/// `driftless mag-cal`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The rotation: a CSV file (with --mag-columns), a ROS 2 bag with a
    /// sensor_msgs/msg/MagneticField topic, or a `driftless record` recording whose raw or
    /// corrected samples carry the magnetometer. Turn the sensor slowly through every
    /// direction, away from steel and magnets that do not move with it (tumble it so that each
    /// face points along the field in turn).
    #[arg(value_name = "LOG")]
    pub input: PathBuf,
    /// For a CSV file: the magnetometer's three columns, x,y,z.
    #[arg(long, value_name = "X,Y,Z", value_delimiter = ',')]
    pub mag_columns: Vec<String>,
    /// Unit of --mag-columns (a bag's and a recording's are tesla).
    #[arg(
        long,
        default_value = "uT",
        value_parser = super::unit_arg::<MagUnit>(MagUnit::NAMES)
    )]
    pub mag_units: MagUnit,
    /// For a bag: its MagneticField topic (default: its only one); for a recording: the topic
    /// to read (default: its only raw or corrected one, else its only raw one).
    #[arg(long, value_name = "TOPIC")]
    pub topic: Option<String>,
    /// The name of the `attitude.6d` stage in the printed table.
    #[arg(long, default_value = "attitude", value_name = "NAME")]
    pub stage_name: String,
}

/// Run `mag-cal`: exit 2 when the log cannot be read or its coverage is too poor for even the
/// hard iron (the message names the motion that is missing).
pub fn run(args: Args) -> Result<(), CliError> {
    let columns = (!args.mag_columns.is_empty()).then_some(args.mag_columns.as_slice());
    if columns.is_some_and(|c| c.len() != 3) {
        return Err(CliError::input(format!(
            "--mag-columns must name 3 columns (x,y,z), got {}",
            args.mag_columns.len()
        )));
    }
    let log = read_mag_log(&args.input, columns, args.mag_units, args.topic.as_deref())?;
    if let Some(note) = &log.format_note {
        eprintln!("driftless: warning: {note}");
    }
    let cal = mag_cal::fit(&log.readings_ut)
        .map_err(|e| CliError::input(format!("{}: {e}", log.source)))?;
    if let Some(why) = &cal.why_hard_only {
        eprintln!("driftless: warning: the hard iron alone: {why}");
    }
    print!("{}", output(&cal, &log.source, &args.stage_name));
    Ok(())
}

/// A number for the table: enough digits, never an exponent TOML would misread.
fn num(v: f64) -> String {
    format!("{v:.4}")
}

fn vector(v: &[f64; 3]) -> String {
    format!("[{}, {}, {}]", num(v[0]), num(v[1]), num(v[2]))
}

/// The summary (comments) and the table.
fn output(cal: &MagCal, source: &str, stage: &str) -> String {
    let c = &cal.cal;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# driftless mag-cal: {source}, {} readings",
        cal.readings
    );
    let _ = writeln!(
        s,
        "# fitted: {}",
        match cal.extent {
            Extent::Full => "hard and soft iron (the ellipsoid)",
            Extent::HardIron => "the hard iron alone (the sphere): the soft iron is the identity",
        }
    );
    if let Some(why) = &cal.why_hard_only {
        let _ = writeln!(s, "#   why: {why}");
    }
    let sd = cal.hard_iron_sd;
    let _ = writeln!(
        s,
        "# hard iron b: ({:.2} +- {:.2}, {:.2} +- {:.2}, {:.2} +- {:.2}) uT",
        c.hard_iron[0], sd[0], c.hard_iron[1], sd[1], c.hard_iron[2], sd[2]
    );
    let _ = writeln!(s, "# soft iron W (det 1, so |W (m - b)| keeps the field):");
    for row in &c.soft_iron {
        let _ = writeln!(s, "#   {}", vector(row));
    }
    let _ = writeln!(s, "# field magnitude: {:.2} uT", cal.field);
    let _ = writeln!(
        s,
        "# the field's norm, RMS about its mean: {:.3} uT before, {:.3} uT after",
        cal.rms_before, cal.rms_after
    );
    let cover = &cal.coverage;
    let missing = cover.missing_faces();
    let _ = writeln!(
        s,
        "# coverage: {:.0}% of the sphere's directions, spread {:.3} (1/3 for all; soft iron \
         needs {:.0}% and {}){}",
        cover.cells * 100.0,
        cover.spread,
        mag_cal::SOFT_MIN_CELLS * 100.0,
        mag_cal::SOFT_MIN_SPREAD,
        if missing.is_empty() {
            String::new()
        } else {
            format!("; never towards the field: {missing}")
        }
    );
    let _ = writeln!(
        s,
        "# Paste into the pipeline file (or copy the mag_ keys into its attitude.6d stage); with\n\
         # mag_hard_iron = true (the default) the stage learns the hard iron on from b."
    );
    let rows: Vec<String> = c.soft_iron.iter().map(vector).collect();
    let _ = write!(
        s,
        "[[stage]]\nname = \"{stage}\"\nkind = \"attitude.6d\"\ninput = \"nav/predicted\"\n\
         output = \"nav/attitude\"\nuse_mag = true\nmag_hard_iron_ut = {}\nmag_soft_iron = [{}]\n",
        vector(&c.hard_iron),
        rows.join(", ")
    );
    s
}
