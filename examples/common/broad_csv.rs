//! The command line and the input both BROAD examples read (`broad_rates`, `broad_attitude`):
//! the input CSV has a header, then `gx,gy,gz,ax,ay,az,still` per sample, optionally followed
//! by the magnetometer `mx,my,mz` (tesla).

use driftless::pipeline::config::{self, Pipeline};
use std::error::Error;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

/// The command line both examples take, `NAME PIPELINE.toml IN.csv OUT.csv`: the pipeline,
/// the input's columns and the output's path.
pub fn inputs(name: &str) -> Result<(Pipeline, Columns, PathBuf), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [pipeline, input, output] = args.as_slice() else {
        return Err(format!("usage: {name} PIPELINE.toml IN.csv OUT.csv").into());
    };
    Ok((
        config::load(Path::new(pipeline))?,
        read(Path::new(input))?,
        PathBuf::from(output),
    ))
}

/// Rates per axis, the specific force per sample, the true rests, and the magnetometer per
/// sample if the file has its columns.
pub type Columns = (
    Vec<Vec<f64>>,
    Vec<[f64; 3]>,
    Vec<bool>,
    Option<Vec<[f64; 3]>>,
);

/// The rates per axis, the specific force per sample, the true rests and the magnetometer of
/// `path`.
fn read(path: &Path) -> Result<Columns, Box<dyn Error>> {
    let file = BufReader::new(std::fs::File::open(path)?);
    let mut gyro = vec![Vec::new(); 3];
    let mut accel = Vec::new();
    let mut still = Vec::new();
    let mut mag = Vec::new();
    for (i, line) in file.lines().enumerate().skip(1) {
        let line = line?;
        let v: Vec<f64> = line
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("{}:{}: {e}", path.display(), i + 1))?;
        if v.len() != 7 && v.len() != 10 {
            return Err(format!("{}:{}: 7 or 10 columns expected", path.display(), i + 1).into());
        }
        if v.len() == 10 {
            mag.push([v[7], v[8], v[9]]);
        }
        for (a, g) in gyro.iter_mut().enumerate() {
            g.push(v[a]);
        }
        accel.push([v[3], v[4], v[5]]);
        still.push(v[6] != 0.0);
    }
    let mag = (!mag.is_empty()).then_some(mag);
    if mag.as_ref().is_some_and(|m| m.len() != still.len()) {
        return Err(format!(
            "{}: the magnetometer columns in some rows only",
            path.display()
        )
        .into());
    }
    Ok((gyro, accel, still, mag))
}
