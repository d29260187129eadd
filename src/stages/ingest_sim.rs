//! `ingest.sim`: the built-in gyro simulator ([`crate::sim`]), paced in real time from the
//! monotonic clock, a factor faster (`pace = 10.0`, as a replay takes it), or as fast as
//! possible (`pace = "asap"`: throughput and delivery tests). Sensor timestamps are `k / rate`
//! in ns at every pace, and the samples are the same; rates are in deg/s.
//!
//! The `adis16405` profile carries its accelerometer in every sample ([`RAW_ACCEL`], in the
//! pipeline's `accel_units`): the specific force of the motion, gravity in the body frame plus
//! the vehicle's acceleration, with the data sheet's noise and bias
//! ([`crate::sim::force`]). The `adxrs450` is a gyro alone: its samples carry no accelerometer.
//! Adding the accelerometer changes no gyro sample.
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
//! # pace = "asap"          # as fast as possible, or 10.0: ten times real time
//! #                        # (default "realtime")
//! ```

use std::sync::atomic::AtomicBool;

use crate::clock::{Pace, PaceClock};
use crate::io::InputError;
use crate::sim::force::SimAccel;
use crate::sim::{SimConfig, Simulator};
use crate::stages::contract::{Kind, Params, Poll, Role, Source, TrueRate};
use crate::stages::replay::{read_pace, PACE_TYPE};
use crate::stages::schema::{Context, DefaultValue, Key, Table, Type};
use crate::units::RateUnit;
use crate::wire::{RawSample, RAW_ACCEL};

const PROFILE: Key = Key {
    name: "profile",
    ty: Type::Choice(&["adxrs450", "adis16405"]),
    default: DefaultValue::Word("adxrs450"),
    doc: "noise profile (IEEE 952 terms of the part): adis16405 also carries its accelerometer, adxrs450 is a gyro alone",
};
const SEED: Key = Key {
    name: "seed",
    ty: Type::Int(0, i64::MAX),
    default: DefaultValue::Int(1),
    doc: "random seed",
};
const MOTION: Key = Key {
    name: "motion",
    ty: Type::Choice(&["none", "sines", "steps", "turn", "stop-and-go"]),
    default: DefaultValue::Word("sines"),
    doc: "true motion added to the noise",
};
const SAMPLES: Key = Key {
    name: "samples",
    ty: Type::Int(1, i64::MAX),
    default: DefaultValue::Absent("none (until stopped)"),
    doc: "stop after this many samples",
};

const PACE: Key = Key {
    name: "pace",
    ty: PACE_TYPE,
    default: DefaultValue::Word("realtime"),
    doc: "at rate_hz, this many times faster (10.0: ten seconds of samples in one; 1.0 is \"realtime\"), or as fast as possible; the same samples at every pace",
};

/// `ingest.sim`.
pub const KIND: Kind = Kind {
    name: "ingest.sim",
    role: Role::Ingest { has_input: false },
    summary: "the built-in gyro simulator, in real time, a factor faster or as fast as possible; needs input_units = \"deg/s\"",
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
    /// At the pipeline's rate, a factor faster, or as fast as possible.
    pub pace: Pace,
}

fn parse(t: &mut Table<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    let profile = t.choice_or_default(&PROFILE, "profile", false)?;
    let seed = t.int_or_default(&SEED)?;
    let motion = t.choice_or_default(&MOTION, "motion", false)?;
    let samples = t.int(&SAMPLES)?;
    let pace = read_pace(t, &PACE)?;
    if t.cx.units != RateUnit::DegPerS {
        return Err(t.src.at(
            t.kind_at,
            "ingest.sim produces deg/s: set input_units = \"deg/s\"",
        ));
    }
    let params = SimParams {
        profile,
        seed: seed as u64,
        motion,
        samples: samples.map(|s| s as u64),
        pace,
    };
    sim_config(&params, t.cx.rate_hz, t.cx.axes)
        .map_err(|e| t.error(format!("ingest.sim: {e}")))?;
    Ok(Box::new(params))
}

impl Params for SimParams {
    fn pace(&self) -> Option<Pace> {
        Some(self.pace)
    }

    fn local_source(&self, cx: &Context) -> Result<Box<dyn Source>, String> {
        Ok(Box::new(SimSource::new(self, cx)?))
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
    /// Its accelerometer, and the factor from m/s² to the pipeline's `accel_units`.
    accel: Option<(SimAccel, f64)>,
    rate_hz: f64,
    limit: Option<u64>,
    pace: Pace,
    k: u64,
    start: Option<PaceClock>,
}

impl SimSource {
    /// A paced simulator at the pipeline's rate, axes and `accel_units`; stops after
    /// `p.samples` if set.
    pub fn new(p: &SimParams, cx: &Context) -> Result<Self, String> {
        let cfg = sim_config(p, cx.rate_hz, cx.axes)?;
        let accel = SimAccel::new(&p.profile, &cfg).map_err(|e| e.to_string())?;
        Ok(SimSource {
            sim: Simulator::new(&cfg).map_err(|e| e.to_string())?,
            accel: accel.map(|a| (a, 1.0 / cx.accel_units.to_m_per_s2())),
            rate_hz: cx.rate_hz,
            limit: p.samples,
            pace: p.pace,
            k: 0,
            start: None,
        })
    }

    /// The next sample's sensor time.
    fn t_ns(&self) -> u64 {
        (self.k as f64 * 1e9 / self.rate_hz).round() as u64
    }
}

impl Source for SimSource {
    fn poll(&mut self, stop: &AtomicBool) -> Poll {
        if self.limit.is_some_and(|n| self.k >= n) {
            return Poll::End;
        }
        let due_ns = match self.pace.due_after(self.t_ns()) {
            None => None,
            Some(offset) => {
                let clock = *self.start.get_or_insert_with(PaceClock::now);
                match clock.wait(offset, stop) {
                    Some(due) => Some(due),
                    None => return Poll::Idle,
                }
            }
        };
        let s = self.sim.next_sample();
        let mut raw = RawSample {
            t_ns: self.t_ns(),
            seq: self.k,
            rate: s.measured,
            ..RawSample::default()
        };
        if let Some((accel, to_units)) = &mut self.accel {
            raw.accel = accel.next_reading().map(|v| v * *to_units);
            raw.flags |= RAW_ACCEL;
        }
        self.k += 1;
        let ingest_ns = crate::clock::ingest_now(due_ns.is_some());
        Poll::Sample(raw, ingest_ns, due_ns.map(|d| ingest_ns.saturating_sub(d)))
    }

    fn next_due(&self) -> Option<std::time::Instant> {
        Some(self.start?.at(self.pace.due_after(self.t_ns())?))
    }

    fn share_clock(&mut self, clock: PaceClock) {
        self.start = Some(clock);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::units::{AccelUnit, RateUnit};

    fn cx(rate_hz: f64, accel_units: AccelUnit) -> Context {
        Context {
            rate_hz,
            axes: 3,
            units: RateUnit::DegPerS,
            accel_units,
            white_noise: None,
        }
    }

    fn samples(p: &SimParams, cx: &Context) -> Vec<RawSample> {
        let stop = AtomicBool::new(false);
        let mut source = SimSource::new(p, cx).unwrap();
        let mut got = Vec::new();
        while let Poll::Sample(raw, ..) = source.poll(&stop) {
            got.push(raw);
        }
        got
    }

    /// The ADIS16405 carries its accelerometer, in the pipeline's units, beside the very gyro
    /// samples it had without it; the ADXRS450, a gyro alone, carries none.
    #[test]
    fn the_adis16405_carries_its_accelerometer_and_the_adxrs450_none() {
        let mut p = SimParams {
            profile: "adis16405".into(),
            seed: 3,
            motion: "stop-and-go".into(),
            samples: Some(10_000),
            pace: Pace::Asap,
        };
        let ms2 = samples(&p, &cx(100.0, AccelUnit::MPerS2));
        let g = samples(&p, &cx(100.0, AccelUnit::G));
        let mut gyro = Simulator::new(&sim_config(&p, 100.0, 3).unwrap()).unwrap();
        for (a, b) in ms2.iter().zip(&g) {
            assert_eq!(a.rate, gyro.next_sample().measured, "the gyro unchanged");
            assert_eq!(a.flags & RAW_ACCEL, RAW_ACCEL);
            for i in 0..3 {
                assert!((a.accel[i] - b.accel[i] * 9.80665).abs() < 1e-12);
            }
        }
        // Still, level, z down: about -1 g on z (50 mg turn-on bias, 1 sigma).
        assert!((ms2[100].accel[2] + 9.80665).abs() < 2.0);
        // Turning at 10 m/s: centripetal force sideways (1.75 m/s²) against the still mean.
        let mean = |r: std::ops::Range<usize>| {
            ms2[r.clone()].iter().map(|s| s.accel[1]).sum::<f64>() / r.len() as f64
        };
        assert!((mean(7500..9000) - mean(0..6000)).abs() > 1.5);
        p.profile = "adxrs450".into();
        for s in samples(&p, &cx(100.0, AccelUnit::MPerS2)) {
            assert_eq!(s.flags & RAW_ACCEL, 0);
            assert_eq!(s.accel_reading(), None);
        }
    }

    #[test]
    fn at_pace_10_the_simulator_takes_its_samples_ten_times_as_often_and_the_same() {
        let params = |pace| SimParams {
            profile: "adxrs450".into(),
            seed: 7,
            motion: "sines".into(),
            samples: Some(30),
            pace,
        };
        let stop = AtomicBool::new(false);
        let take = |source: &mut SimSource| {
            let mut got = Vec::new();
            while let Poll::Sample(raw, ingest, late) = source.poll(&stop) {
                got.push((raw, ingest, late));
            }
            got
        };
        let cx = cx(1000.0, AccelUnit::MPerS2);
        let mut fast = SimSource::new(&params(Pace::Times(10.0)), &cx).unwrap();
        let Poll::Sample(first, ..) = fast.poll(&stop) else {
            panic!("the first sample at once")
        };
        let clock = PaceClock::now();
        fast.share_clock(clock);
        assert_eq!(
            fast.next_due(),
            Some(clock.at(std::time::Duration::from_micros(100)))
        );
        let mut paced = vec![(first, 0, None)];
        paced.extend(take(&mut fast));
        let asap = take(&mut SimSource::new(&params(Pace::Asap), &cx).unwrap());
        assert_eq!(paced.len(), 30);
        for ((p, _, late), (a, _, none)) in paced[1..].iter().zip(&asap[1..]) {
            assert_eq!(p, a, "the same sample at any pace");
            assert!(late.is_some() && none.is_none());
        }
        // Each taken no earlier than a tenth of its sensor time after the clock's start.
        let start = paced[1].1 - paced[1].2.unwrap() - 100_000;
        for (raw, ingest, _) in &paced[1..] {
            assert!(ingest - start >= raw.t_ns / 10, "{}", raw.seq);
        }
    }
}
