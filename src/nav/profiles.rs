//! Known motion to add to a static gyro record (or to the simulator's noise), with the oracle
//! still mask: the truth a heading benchmark needs.
//!
//! Every profile is deterministic from (rate_hz, duration, seed), starts still (a navigator
//! powers up at rest, and power-on bias needs that first stop), and is exactly zero while still.
//! Moving segments start and end with raised-cosine ramps (0.5 s, or half the segment if
//! shorter), as real motion does: a detector sees a slow onset late, which is what the delay
//! window of [`crate::drift::bias`] is for. The still mask is true exactly on the still segments.
//! The same profile is used for every axis; vary the seed per axis and window. Each profile
//! also states the vehicle's speed ([`Profile::speed`]), from which [`crate::nav::force`] gives
//! the accelerometer its physically consistent force.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::f64::consts::PI;
use std::fmt;
use std::str::FromStr;

/// Most samples a profile may have (2^31).
pub const MAX_SAMPLES: f64 = 2_147_483_648.0;

/// Ramp time at each end of a moving segment, s.
pub const RAMP_S: f64 = 0.5;

/// A built-in motion profile.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Profile {
    /// The stop-and-go: still 60 s, then repeatedly 40 s moving and 20 s still. Moving
    /// is a 10 deg/s turn (its sign alternating, the first one random) plus 5 deg/s at 0.7 Hz
    /// and 2 deg/s at 1.9 Hz (random phases). Regular, long-enough stops: the case ZARU was made
    /// for.
    StopAndGo,
    /// A road vehicle: still 5-30 s, then repeatedly moving 10-120 s and stopped 2-60 s (uniform).
    /// Moving: a turn rate that changes every 2-10 s to a new level (straight with probability
    /// 0.4, otherwise normal with sd 10 deg/s, clipped to +-40) through 1 s cosine blends, plus
    /// road vibration of 0.8 deg/s at 9.3 Hz and 0.5 deg/s at 15.1 Hz (each only below 0.45 x
    /// rate). Short stops test whether a detector can use them at all; long ones reward
    /// averaging.
    Vehicle,
    /// Continuous motion with rare stops: still 10-30 s, then repeatedly moving 150-300 s (the
    /// vehicle's motion) and stopped 5-20 s. The bias must be carried for minutes.
    Continuous,
    /// A walking pedestrian: still 5-15 s, then repeatedly walking 10-60 s and standing 2-15 s.
    /// Walking: a step-rate oscillation (12 deg/s at f and 4 deg/s at 2f, f 1.8-2.0 Hz per walk)
    /// plus a heading change every 5-20 s (a turn of +-30 to +-120 deg over 2-4 s,
    /// raised-cosine rate). Frequent short stops, strong oscillation.
    Pedestrian,
}

impl Profile {
    /// All profiles.
    pub const ALL: [Profile; 4] = [
        Profile::StopAndGo,
        Profile::Vehicle,
        Profile::Continuous,
        Profile::Pedestrian,
    ];

    /// The profile's name (`stop-and-go`, `vehicle`, `continuous`, `pedestrian`).
    pub fn name(self) -> &'static str {
        match self {
            Profile::StopAndGo => "stop-and-go",
            Profile::Vehicle => "vehicle",
            Profile::Continuous => "continuous",
            Profile::Pedestrian => "pedestrian",
        }
    }
}

impl fmt::Display for Profile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Profile {
    type Err = ProfileError;
    fn from_str(s: &str) -> Result<Self, ProfileError> {
        Profile::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| ProfileError::Unknown(s.to_string()))
    }
}

/// A bad profile request.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProfileError {
    /// No profile of that name.
    #[error("unknown motion profile '{0}' (stop-and-go, vehicle, continuous, pedestrian)")]
    Unknown(String),
    /// The rate is not a positive finite number.
    #[error("the sample rate must be a positive number of Hz, not {0}")]
    BadRate(f64),
    /// The duration is not a positive finite number.
    #[error("the duration must be a positive number of seconds, not {0}")]
    BadDuration(f64),
    /// Too many samples.
    #[error("{0} samples is too many for a motion profile (at most 2^31)")]
    TooLong(f64),
}

/// The true rate and the oracle still mask of a profile, one entry per sample.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionTrace {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// True rate, deg/s.
    pub truth: Vec<f64>,
    /// True where the sensor is still (the truth is exactly 0).
    pub still: Vec<bool>,
}

/// Moving parts of the profiles, rendered one sample at a time.
struct Mover {
    rate_hz: f64,
    t: f64,
    // Vehicle: current and previous level, blend start, next change.
    level: f64,
    prev_level: f64,
    blend_start: f64,
    next_change: f64,
    // Pedestrian: step frequency and phases, current turn.
    step_f: f64,
    ph1: f64,
    ph2: f64,
    turn_start: f64,
    turn_len: f64,
    turn_peak: f64,
    next_turn: f64,
}

fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

impl Mover {
    fn new(rate_hz: f64) -> Self {
        Mover {
            rate_hz,
            t: 0.0,
            level: 0.0,
            prev_level: 0.0,
            blend_start: f64::NEG_INFINITY,
            next_change: 0.0,
            step_f: 1.9,
            ph1: 0.0,
            ph2: 0.0,
            turn_start: f64::NEG_INFINITY,
            turn_len: 1.0,
            turn_peak: 0.0,
            next_turn: 0.0,
        }
    }

    fn sine(&self, amp: f64, f: f64, ph: f64) -> f64 {
        if f < 0.45 * self.rate_hz {
            amp * (2.0 * PI * f * self.t + ph).sin()
        } else {
            0.0
        }
    }

    /// Vehicle motion at time t (s since the start of the record).
    fn vehicle(&mut self, rng: &mut ChaCha8Rng) -> f64 {
        if self.t >= self.next_change {
            self.prev_level = self.current_level();
            self.level = if rng.random::<f64>() < 0.4 {
                0.0
            } else {
                let z: f64 = rng.sample(StandardNormal);
                (10.0 * z).clamp(-40.0, 40.0)
            };
            self.blend_start = self.t;
            self.next_change = self.t + uniform(rng, 2.0, 10.0);
        }
        self.current_level() + self.sine(0.8, 9.3, self.ph1) + self.sine(0.5, 15.1, self.ph2)
    }

    fn current_level(&self) -> f64 {
        let u = ((self.t - self.blend_start) / 1.0).clamp(0.0, 1.0);
        let w = 0.5 * (1.0 - (PI * u).cos());
        self.prev_level + (self.level - self.prev_level) * w
    }

    /// Pedestrian motion at time t.
    fn walk(&mut self, rng: &mut ChaCha8Rng) -> f64 {
        if self.t >= self.next_turn {
            self.turn_start = self.t;
            self.turn_len = uniform(rng, 2.0, 4.0);
            let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
            let angle = sign * uniform(rng, 30.0, 120.0);
            // Raised-cosine rate over turn_len integrates to angle with peak 2 angle / len.
            self.turn_peak = 2.0 * angle / self.turn_len;
            self.next_turn = self.t + self.turn_len + uniform(rng, 5.0, 20.0);
        }
        let u = (self.t - self.turn_start) / self.turn_len;
        let turn = if (0.0..1.0).contains(&u) {
            self.turn_peak * 0.5 * (1.0 - (2.0 * PI * u).cos())
        } else {
            0.0
        };
        turn + self.sine(12.0, self.step_f, self.ph1) + self.sine(4.0, 2.0 * self.step_f, self.ph2)
    }
}

/// The raised-cosine envelope of a moving segment of `len` samples at sample `i` in it.
fn envelope(i: usize, len: usize, rate_hz: f64) -> f64 {
    let ramp = (RAMP_S * rate_hz).min(len as f64 / 2.0).max(1.0);
    let from_start = i as f64 + 0.5;
    let from_end = (len - i) as f64 - 0.5;
    let u = (from_start.min(from_end) / ramp).min(1.0);
    0.5 * (1.0 - (PI * u).cos())
}

/// The true rate and still mask of `profile` for `duration_s` seconds at `rate_hz`.
pub fn generate(
    profile: Profile,
    rate_hz: f64,
    duration_s: f64,
    seed: u64,
) -> Result<MotionTrace, ProfileError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(ProfileError::BadRate(rate_hz));
    }
    if !(duration_s.is_finite() && duration_s > 0.0) {
        return Err(ProfileError::BadDuration(duration_s));
    }
    let total = (duration_s * rate_hz).round();
    if total > MAX_SAMPLES {
        return Err(ProfileError::TooLong(total));
    }
    let total = total as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(profile as u64);
    let mut truth = Vec::with_capacity(total);
    let mut still = Vec::with_capacity(total);
    let mut mover = Mover::new(rate_hz);
    let secs = |s: f64| ((s * rate_hz).round() as usize).max(1);
    // Stop-and-go: the turn's sign alternates from a random start; sine phases are random.
    let mut turn_sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
    mover.ph1 = uniform(&mut rng, 0.0, 2.0 * PI);
    mover.ph2 = uniform(&mut rng, 0.0, 2.0 * PI);
    let first = match profile {
        Profile::StopAndGo => 60.0,
        Profile::Vehicle => uniform(&mut rng, 5.0, 30.0),
        Profile::Continuous => uniform(&mut rng, 10.0, 30.0),
        Profile::Pedestrian => uniform(&mut rng, 5.0, 15.0),
    };
    let mut segment_still = true;
    let mut len = secs(first);
    while truth.len() < total {
        let len_here = len.min(total - truth.len());
        if !segment_still {
            // Per-segment randomness of the moving part.
            mover.step_f = uniform(&mut rng, 1.8, 2.0);
            mover.next_turn = truth.len() as f64 / rate_hz + uniform(&mut rng, 1.0, 10.0);
            mover.next_change = truth.len() as f64 / rate_hz;
            mover.prev_level = 0.0;
            mover.level = 0.0;
            mover.blend_start = f64::NEG_INFINITY;
            turn_sign = -turn_sign;
        }
        for i in 0..len_here {
            mover.t = truth.len() as f64 / rate_hz;
            if segment_still {
                truth.push(0.0);
                still.push(true);
                continue;
            }
            let m = match profile {
                Profile::StopAndGo => {
                    10.0 * turn_sign
                        + mover.sine(5.0, 0.7, mover.ph1)
                        + mover.sine(2.0, 1.9, mover.ph2)
                }
                Profile::Vehicle | Profile::Continuous => mover.vehicle(&mut rng),
                Profile::Pedestrian => mover.walk(&mut rng),
            };
            truth.push(m * envelope(i, len, rate_hz));
            still.push(false);
        }
        segment_still = !segment_still;
        let (lo, hi) = match (profile, segment_still) {
            (Profile::StopAndGo, true) => (20.0, 20.0),
            (Profile::StopAndGo, false) => (40.0, 40.0),
            (Profile::Vehicle, true) => (2.0, 60.0),
            (Profile::Vehicle, false) => (10.0, 120.0),
            (Profile::Continuous, true) => (5.0, 20.0),
            (Profile::Continuous, false) => (150.0, 300.0),
            (Profile::Pedestrian, true) => (2.0, 15.0),
            (Profile::Pedestrian, false) => (10.0, 60.0),
        };
        len = secs(uniform(&mut rng, lo, hi));
    }
    Ok(MotionTrace {
        rate_hz,
        truth,
        still,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_seeded_and_still_means_zero() {
        for p in Profile::ALL {
            let a = generate(p, 100.0, 600.0, 7).unwrap();
            assert_eq!(a, generate(p, 100.0, 600.0, 7).unwrap());
            assert_eq!(a.truth.len(), 60_000);
            assert!(a.still[0], "{p} starts still");
            for (&t, &s) in a.truth.iter().zip(&a.still) {
                assert!(!s || t == 0.0);
                assert!(t.is_finite() && t.abs() < 200.0);
            }
            let moving = a.still.iter().filter(|s| !**s).count();
            assert!(moving > 10_000, "{p}: {moving} moving samples");
            if p != Profile::StopAndGo {
                assert_ne!(a, generate(p, 100.0, 600.0, 8).unwrap());
            }
        }
    }

    #[test]
    fn stop_and_go_timing_and_ramps() {
        let a = generate(Profile::StopAndGo, 100.0, 300.0, 1).unwrap();
        assert!(a.still[..6000].iter().all(|&s| s));
        assert!(a.still[6000..10_000].iter().all(|&s| !s));
        assert!(a.still[10_000..12_000].iter().all(|&s| s));
        // Ramped: the first moving sample is small, the middle carries the 10 deg/s turn.
        assert!(a.truth[6000].abs() < 0.1);
        let mean: f64 = a.truth[7000..9000].iter().sum::<f64>() / 2000.0;
        assert!((mean.abs() - 10.0).abs() < 0.5, "{mean}");
    }

    #[test]
    fn stops_have_the_documented_lengths() {
        let a = generate(Profile::Vehicle, 100.0, 3600.0, 3).unwrap();
        let mut runs = Vec::new();
        let mut run = 0usize;
        for w in a.still.windows(2) {
            run += 1;
            if w[0] != w[1] {
                runs.push((w[0], run));
                run = 0;
            }
        }
        for &(s, r) in &runs[1..] {
            let secs = r as f64 / 100.0;
            if s {
                assert!((2.0..=60.01).contains(&secs), "stop {secs}");
            } else {
                assert!((10.0..=120.01).contains(&secs), "move {secs}");
            }
        }
    }

    #[test]
    fn bad_requests_are_refused() {
        assert!(generate(Profile::Vehicle, 0.0, 1.0, 0).is_err());
        assert!(generate(Profile::Vehicle, 100.0, f64::NAN, 0).is_err());
        assert!(generate(Profile::Vehicle, 1e9, 1e9, 0).is_err());
        assert!("walk".parse::<Profile>().is_err());
        for p in Profile::ALL {
            assert_eq!(p.name().parse::<Profile>(), Ok(p));
        }
    }
}
