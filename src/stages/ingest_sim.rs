//! `ingest.sim`: the built-in gyro simulator ([`crate::sim`]), paced in real time from the
//! monotonic clock. Sensor timestamps are `k / rate` in ns; rates are in deg/s.

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use crate::pipeline::config::SimParams;
use crate::pipeline::stage::{Poll, Source};
use crate::sim::{SimConfig, Simulator};
use crate::transport::{monotonic_ns, RawSample};

/// The simulator's configuration for validated parameters.
pub fn sim_config(p: &SimParams, rate_hz: f64, axes: usize) -> Result<SimConfig, String> {
    let mut cfg = SimConfig::profile(&p.profile).map_err(|e| e.to_string())?;
    cfg.rate_hz = rate_hz;
    cfg.axes = axes;
    cfg.seed = p.seed;
    cfg.motion = p
        .motion
        .parse()
        .map_err(|e: crate::sim::SimError| e.to_string())?;
    Simulator::new(&cfg).map_err(|e| e.to_string())?;
    Ok(cfg)
}

/// A simulated sensor.
pub struct SimSource {
    sim: Simulator,
    rate_hz: f64,
    limit: Option<u64>,
    k: u64,
    start: Option<Instant>,
}

impl SimSource {
    /// A paced simulator; stops after `p.samples` if set.
    pub fn new(p: &SimParams, rate_hz: f64, axes: usize) -> Result<Self, String> {
        let cfg = sim_config(p, rate_hz, axes)?;
        Ok(SimSource {
            sim: Simulator::new(&cfg).map_err(|e| e.to_string())?,
            rate_hz,
            limit: p.samples,
            k: 0,
            start: None,
        })
    }
}

impl Source for SimSource {
    fn poll(&mut self, stop: &AtomicBool) -> Poll {
        if self.limit.is_some_and(|n| self.k >= n) {
            return Poll::End;
        }
        let start = *self.start.get_or_insert_with(Instant::now);
        let due = start + Duration::from_secs_f64(self.k as f64 / self.rate_hz);
        if !crate::stages::sleep_until(due, stop) {
            return Poll::Idle;
        }
        let s = self.sim.next_sample();
        let raw = RawSample {
            t_ns: (self.k as f64 * 1e9 / self.rate_hz).round() as u64,
            seq: self.k,
            rate: s.measured,
            flags: 0,
            reserved: 0,
        };
        self.k += 1;
        Poll::Sample(raw, monotonic_ns())
    }
}
