//! `ingest.sim`: the built-in gyro simulator ([`crate::sim`]), paced in real time from the
//! monotonic clock, or as fast as possible (`pace = "asap"`: throughput and delivery tests).
//! Sensor timestamps are `k / rate` in ns either way; rates are in deg/s.
//!
//! ```toml
//! [[stage]]
//! name = "sensor"
//! kind = "ingest.sim"
//! output = "demo/raw"
//! profile = "adis16405"    # noise terms: adxrs450 (default) or adis16405
//! motion = "sines"         # true motion: none, sines (default), steps, turn
//! seed = 1
//! # samples = 60000        # stop after this many (default: run until stopped)
//! # pace = "asap"          # as fast as possible (default "realtime")
//! ```

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use crate::clock::PaceClock;
use crate::io::InputError;
use crate::sim::{SimConfig, Simulator};
use crate::stages::contract::{Kind, Params, Poll, Role, Source, TrueRate};
use crate::stages::schema::{Context, Key, StageTable, Type, Units};
use crate::transport::RawSample;

const PROFILE: Key = Key {
    name: "profile",
    ty: Type::Choice(&["adxrs450", "adis16405"]),
    default: "\"adxrs450\"",
    doc: "noise profile (IEEE 952 terms of the part)",
};
const SEED: Key = Key {
    name: "seed",
    ty: Type::Int(0, i64::MAX),
    default: "1",
    doc: "random seed",
};
const MOTION: Key = Key {
    name: "motion",
    ty: Type::Choice(&["none", "sines", "steps", "turn", "stop-and-go"]),
    default: "\"sines\"",
    doc: "true motion added to the noise",
};
const SAMPLES: Key = Key {
    name: "samples",
    ty: Type::Int(1, i64::MAX),
    default: "none (until stopped)",
    doc: "stop after this many samples",
};

const PACE: Key = Key {
    name: "pace",
    ty: Type::Choice(&["realtime", "asap"]),
    default: "\"realtime\"",
    doc: "at rate_hz, or as fast as possible",
};

/// `ingest.sim`.
pub const KIND: Kind = Kind {
    name: "ingest.sim",
    role: Role::Ingest { has_input: false },
    summary: "the built-in gyro simulator, in real time or as fast as possible; needs input_units = \"deg/s\"",
    keys: &[PROFILE, SEED, MOTION, SAMPLES, PACE],
    parse,
};

/// The simulated sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct SimParams {
    /// Noise profile name.
    pub profile: String,
    /// Random seed.
    pub seed: u64,
    /// True motion: none, sines, steps, turn, stop-and-go.
    pub motion: String,
    /// Stop after this many samples (None: run until stopped).
    pub samples: Option<u64>,
    /// As fast as possible instead of at the pipeline's rate.
    pub asap: bool,
}

fn parse(t: &mut StageTable<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    let profile = t.choice(&PROFILE, "profile", false)?;
    let seed = t.int(&SEED)?;
    let motion = t.choice(&MOTION, "motion", false)?;
    let samples = t.int(&SAMPLES)?;
    let pace = t.choice(&PACE, "pace", true)?;
    if t.cx.units != Units::DegPerSec {
        return Err(t.src.at(
            t.kind_at,
            "ingest.sim produces deg/s: set input_units = \"deg/s\"",
        ));
    }
    let params = SimParams {
        profile: profile.unwrap_or_else(|| "adxrs450".into()),
        seed: seed.map_or(1, |s| s as u64),
        motion: motion.unwrap_or_else(|| "sines".into()),
        samples: samples.map(|s| s as u64),
        asap: pace.as_deref() == Some("asap"),
    };
    sim_config(&params, t.cx.rate_hz, t.cx.axes)
        .map_err(|e| t.error(format!("ingest.sim: {e}")))?;
    Ok(Box::new(params))
}

impl Params for SimParams {
    fn source(
        &self,
        cx: &Context,
        _transport: &crate::transport::Transport,
        _input: Option<&str>,
    ) -> Result<Box<dyn Source>, String> {
        Ok(Box::new(SimSource::new(self, cx.rate_hz, cx.axes)?))
    }

    fn truth(&self, cx: &Context) -> Option<TrueRate> {
        let motion: crate::sim::Motion = self.motion.parse().ok()?;
        let axes = cx.axes;
        Some(Box::new(move |t| {
            let mut r = [0.0; 3];
            for (axis, v) in r.iter_mut().enumerate().take(axes) {
                *v = motion.rate(axis, axes, t);
            }
            r
        }))
    }
}

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
    asap: bool,
    k: u64,
    start: Option<PaceClock>,
}

impl SimSource {
    /// A paced simulator; stops after `p.samples` if set.
    pub fn new(p: &SimParams, rate_hz: f64, axes: usize) -> Result<Self, String> {
        let cfg = sim_config(p, rate_hz, axes)?;
        Ok(SimSource {
            sim: Simulator::new(&cfg).map_err(|e| e.to_string())?,
            rate_hz,
            limit: p.samples,
            asap: p.asap,
            k: 0,
            start: None,
        })
    }

    /// When the next sample is due, after the first.
    fn offset(&self) -> Duration {
        Duration::from_secs_f64(self.k as f64 / self.rate_hz)
    }
}

impl Source for SimSource {
    fn poll(&mut self, stop: &AtomicBool) -> Poll {
        if self.limit.is_some_and(|n| self.k >= n) {
            return Poll::End;
        }
        let due_ns = if self.asap {
            None
        } else {
            let clock = *self.start.get_or_insert_with(PaceClock::now);
            match clock.wait(self.offset(), stop) {
                Some(due) => Some(due),
                None => return Poll::Idle,
            }
        };
        let s = self.sim.next_sample();
        let raw = RawSample {
            t_ns: (self.k as f64 * 1e9 / self.rate_hz).round() as u64,
            seq: self.k,
            rate: s.measured,
            flags: 0,
            epoch: 0,
        };
        self.k += 1;
        let ingest_ns = crate::clock::ingest_now(due_ns.is_some());
        Poll::Sample(raw, ingest_ns, due_ns.map(|d| ingest_ns.saturating_sub(d)))
    }

    fn next_due(&self) -> Option<std::time::Instant> {
        let clock = self.start.filter(|_| !self.asap)?;
        Some(clock.at(self.offset()))
    }

    fn share_clock(&mut self, clock: PaceClock) {
        self.start = Some(clock);
    }
}
