//! Our orientation on BROAD's real motion, for docs/scripts/broad/broad_attitude.py.
//!
//! `broad_attitude PIPELINE.toml IN.csv OUT.csv`
//!
//! - `IN.csv`: a header, then `gx,gy,gz,ax,ay,az,still` per sample: rates in the pipeline's
//!   `input_units`, specific force in m/s², `still` 1 in a true rest, else 0.
//! - `OUT.csv`: one orientation per method, `{method}_qw,_qx,_qy,_qz` (body to an earth frame
//!   with z up, heading relative) and its inclination's standard deviation `{method}_incl_sd`
//!   (rad), aligned with the input:
//!   - `imu`: the pipeline's stages after its ingest, run offline on samples that carry the
//!     accelerometer (stillness from both sensors), then [`Attitude`] on their corrected rate
//!     and the accelerometer;
//!   - `stop`: the same with the true rests as the vehicle's stop signal, handed to every
//!     `stop_input` of the pipeline (without one, the same as `imu`).
//!
//!   and the gyro-only chain's corrected rate, `gyro_wx,_wy,_wz` (rad/s), for the harness to
//!   integrate from the truth: what a navigator without an attitude stage gets from us.
//!
//! The stages run as the daemon runs them ([`Offline::run_imu_series`]), from the first sample.

use driftless::attitude::{Attitude, AttitudeConfig};
use driftless::pipeline::offline::Offline;
use std::error::Error;
use std::io::{BufWriter, Write};

#[path = "common/broad_csv.rs"]
mod broad_csv;
use broad_csv::inputs;

fn main() -> Result<(), Box<dyn Error>> {
    let (p, (gyro, accel, still), output) = inputs("broad_attitude")?;
    let axes: Vec<&[f64]> = gyro.iter().map(Vec::as_slice).collect();
    let to_rad = p.input_units.to_rad_per_sec();
    let orient = |rates: Vec<Vec<f64>>| -> Result<Vec<[f64; 5]>, String> {
        let mut f = Attitude::new(p.rate_hz, AttitudeConfig::default())?;
        Ok((0..still.len())
            .map(|k| {
                let w = [rates[0][k], rates[1][k], rates[2][k]].map(|v| v * to_rad);
                let s = f.push(w, Some(accel[k]));
                let [qw, qx, qy, qz] = s.quat;
                [qw, qx, qy, qz, s.inclination_sd]
            })
            .collect())
    };
    let imu = orient(Offline::run_imu_series(&p, &axes, Some(&accel), None)?)?;
    let stop = orient(Offline::run_imu_series(
        &p,
        &axes,
        Some(&accel),
        Some(&still),
    )?)?;
    let gyro_only = Offline::run_imu_series(&p, &axes, None, None)?;

    let mut out = BufWriter::new(std::fs::File::create(output)?);
    writeln!(
        out,
        "imu_qw,imu_qx,imu_qy,imu_qz,imu_incl_sd,stop_qw,stop_qx,stop_qy,stop_qz,stop_incl_sd,\
         gyro_wx,gyro_wy,gyro_wz"
    )?;
    for (k, (a, b)) in imu.iter().zip(&stop).enumerate() {
        let w = [0, 1, 2].map(|i| gyro_only[i][k] * to_rad);
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
