//! Our orientation on BROAD's real motion, for docs/scripts/broad/broad_attitude.py.
//!
//! `broad_attitude PIPELINE.toml IN.csv OUT.csv`
//!
//! - `PIPELINE.toml`: the chain to judge, with an `attitude.6d` stage: the stages run as the
//!   daemon runs them ([`Offline::run_imu_samples`]), from the first sample.
//! - `IN.csv`: a header, then `gx,gy,gz,ax,ay,az,still` per sample: rates in the pipeline's
//!   `input_units`, specific force in m/s², `still` 1 in a true rest, else 0; optionally
//!   `mx,my,mz`, the magnetometer in tesla, carried in every sample (an attitude stage with
//!   `use_mag` makes the heading absolute from it).
//! - `OUT.csv`: one orientation per method, `{method}_qw,_qx,_qy,_qz` (body to an earth frame
//!   with z up, heading relative or absolute), the standard deviations it publishes for its inclination
//!   `{method}_incl_sd` and its heading `{method}_head_sd` (rad), aligned with the input:
//!   - `imu`: the pipeline on samples that carry the accelerometer (stillness from both
//!     sensors, the orientation from the attitude stage);
//!   - `stop`: the same with the true rests as the vehicle's stop signal, handed to every
//!     `stop_input` of the pipeline (without one, the same as `imu`).
//!
//!   and the gyro-only chain's corrected rate, `gyro_wx,_wy,_wz` (rad/s), for the harness to
//!   integrate from the truth: what a navigator without an attitude stage gets from us.

use driftless::pipeline::offline::Offline;
use driftless::wire::GyroSample;
use std::error::Error;
use std::io::{BufWriter, Write};

#[path = "common/broad_csv.rs"]
mod broad_csv;
use broad_csv::inputs;

/// One published sample's orientation: w, x, y, z, the inclination's and the heading's sd.
fn orientation(s: &Option<GyroSample>) -> Result<[f64; 6], String> {
    let s = s.ok_or("a sample was not published")?;
    let [x, y, z, w] = s
        .orientation_estimate()
        .ok_or("the pipeline has no attitude.6d stage: its samples carry no orientation")?;
    let [sx, _, sz] = s.orientation_std;
    // The stage gives half the inclination's variance about each horizontal axis.
    Ok([w, x, y, z, sx * std::f64::consts::SQRT_2, sz])
}

fn main() -> Result<(), Box<dyn Error>> {
    let (p, (gyro, accel, still, mag), output) = inputs("broad_attitude")?;
    let axes: Vec<&[f64]> = gyro.iter().map(Vec::as_slice).collect();
    let run = |stops: Option<&[bool]>| -> Result<Vec<[f64; 6]>, String> {
        Offline::run_imu_mag_samples(&p, &axes, Some(&accel), mag.as_deref(), stops)?
            .iter()
            .map(orientation)
            .collect()
    };
    let imu = run(None)?;
    let stop = run(Some(&still))?;
    let gyro_only = Offline::run_imu_series(&p, &axes, None, None)?;

    let mut out = BufWriter::new(std::fs::File::create(output)?);
    let cols = |m: &str| {
        ["qw", "qx", "qy", "qz", "incl_sd", "head_sd"]
            .map(|c| format!("{m}_{c}"))
            .join(",")
    };
    writeln!(
        out,
        "{},{},gyro_wx,gyro_wy,gyro_wz",
        cols("imu"),
        cols("stop")
    )?;
    for (k, (a, b)) in imu.iter().zip(&stop).enumerate() {
        let w = [0, 1, 2].map(|i| gyro_only[i][k].to_radians());
        let row: Vec<String> = a
            .iter()
            .chain(b)
            .chain(&w)
            .map(|v| format!("{v:e}"))
            .collect();
        writeln!(out, "{}", row.join(","))?;
    }
    out.flush()?;
    Ok(())
}
