//! The corrected rates that the BROAD harness (docs/scripts/broad/broad_heading.py) integrates.
//!
//! `broad_rates PIPELINE.toml IN.csv OUT.csv`
//!
//! - `IN.csv`: a header, then `gx,gy,gz,ax,ay,az,still` per sample. Rates are in the pipeline's
//!   `input_units`, specific force in m/s², and `still` is 1 in a true rest, else 0.
//! - `OUT.csv`: three corrected rates per method, in the same units, aligned with the input:
//!   - `zaru_*`: ZARU with the true rests ([`driftless::nav::Zaru::oracle`], 1 s minimum): the
//!     bias is each rest's mean, held while moving.
//!   - `gyro_*`: the pipeline's stages after its ingest, run offline, on samples that carry no
//!     accelerometer.
//!   - `imu_*`: the same stages on samples that carry the accelerometer.
//!   - `stop_*`: `imu_*` with the true rests as the vehicle's stop signal, handed to every
//!     `stop_input` of the pipeline (without one, the same as `imu_*`).
//!
//! The stages run as the daemon runs them ([`Offline::run_imu_series`]), from the first sample:
//! what they publish while warming up is judged too.

use driftless::nav::{BiasEstimator, Zaru};
use driftless::pipeline::offline::Offline;
use std::error::Error;
use std::io::{BufWriter, Write};

#[path = "common/broad_csv.rs"]
mod broad_csv;
use broad_csv::inputs;

fn main() -> Result<(), Box<dyn Error>> {
    let (p, (gyro, accel, still, _), output) = inputs("broad_rates")?;
    let axes: Vec<&[f64]> = gyro.iter().map(Vec::as_slice).collect();

    let min = (p.rate_hz.round() as usize).max(1);
    let zaru: Vec<Vec<f64>> = gyro
        .iter()
        .map(|y| {
            let mut z = Zaru::oracle(min);
            y.iter()
                .zip(&still)
                .map(|(&x, &s)| x - z.push(x, s))
                .collect()
        })
        .collect();
    let gyro_only = Offline::run_imu_series(&p, &axes, None, None)?;
    let with_accel = Offline::run_imu_series(&p, &axes, Some(&accel), None)?;
    let with_stops = Offline::run_imu_series(&p, &axes, Some(&accel), Some(&still))?;

    let mut out = BufWriter::new(std::fs::File::create(output)?);
    writeln!(
        out,
        "zaru_x,zaru_y,zaru_z,gyro_x,gyro_y,gyro_z,imu_x,imu_y,imu_z,stop_x,stop_y,stop_z"
    )?;
    for k in 0..still.len() {
        let row: Vec<String> = [&zaru, &gyro_only, &with_accel, &with_stops]
            .iter()
            .flat_map(|m| m.iter().map(move |axis| format!("{:e}", axis[k])))
            .collect();
        writeln!(out, "{}", row.join(","))?;
    }
    out.flush()?;
    Ok(())
}
