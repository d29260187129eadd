//! Write a simulated gyro log as CSV (first axis; with its truth column).
//!
//! `cargo run --release --example simlog -- PROFILE SAMPLES SEED OUT.csv [MOTION]`
//! e.g. `... -- adxrs450 100000 1 /tmp/adxrs450.csv` for the paper's Table 3 record.

use driftless::io::write_table;
use driftless::sim::{SimConfig, Simulator};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().collect();
    if a.len() < 5 {
        return Err("usage: simlog PROFILE SAMPLES SEED OUT.csv [MOTION]".into());
    }
    let mut cfg = SimConfig::profile(&a[1])?;
    let n: usize = a[2].parse()?;
    cfg.seed = a[3].parse()?;
    if let Some(m) = a.get(5) {
        cfg.motion = m.parse()?;
    }
    let mut sim = Simulator::new(&cfg)?;
    let (mut rate, mut truth) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for _ in 0..n {
        let s = sim.next_sample();
        rate.push(s.measured[0]);
        truth.push(s.truth[0]);
    }
    write_table(
        Path::new(&a[4]),
        &["rate_degps".into(), "truth_degps".into()],
        &[&rate, &truth],
    )?;
    Ok(())
}
