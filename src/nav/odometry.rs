//! A wheel odometry's yaw rate for nav-eval's vehicle profiles, derived from the motion truth
//! with stated errors, and the bias filter given the true stops and that odometry
//! ([`evaluate_odometry`]).
//!
//! Each case is a level vehicle whose yaw axis is the gyro's axis. Its odometry ([`OdometryModel`],
//! every error drawn per case from the seed):
//!
//! - **rate**: 50 Hz (or the gyro's rate, if lower), each message the mean yaw rate over its
//!   period, stamped with the period's end: the encoders count the wheels' turn over the
//!   period, so a message sees the body's yaw at the gyro's instants in (stamp - T, stamp].
//!   The profiles' road vibration is the body's yaw, so the wheels see it too.
//! - **scale error**: the odometry reads (1 + e) times the true rate; |e| = `scale_error`
//!   (1%: tyre radius and track width are good to 0.5-2%), its sign drawn per case.
//! - **encoder ticks**: the odometry's *angle* is quantised to `tick_deg` (0.02 deg: a robot
//!   with 4096-count encoders on 0.2 m wheels 0.5 m apart resolves 0.018 deg of yaw), and each
//!   message's rate is that angle's step over its period: about 0.4 deg/s sd per message at
//!   50 Hz, but no drift (the counted angle is exact to a tick).
//! - **white noise**: `white_sd` per message (0.1 deg/s: wheel-speed jitter from the road and
//!   the tyres); with the ticks, about 0.45 deg/s per message at 50 Hz. Unlike the ticks it
//!   drifts: 0.014 deg/sqrt(s) of yaw, below this gyro's angle random walk.
//! - **slip bursts**: `slips` per window (3), each 1-3 s long, starting at a random sample of
//!   a turn (|rate| >= 5 deg/s) and adding f times the true rate, |f| 10-30%, its sign drawn.
//! - **latency**: each message arrives `latency_s` after its stamp (20-50 ms, fixed per case,
//!   drawn); its stamp is honest (the time it measured), so a consumer that keeps the gyro's
//!   recent past matches it exactly.
//! - **an odometry that stops**: none after `ends_at_s` (a dead node, a cable).
//!
//! Pure: no I/O.

use super::eval::{EvalError, Setup};
use super::metrics::{HeadingAccumulator, HeadingMetrics};
use super::profiles::{MotionTrace, ProfileError};
use crate::drift::bias::{
    BiasTracker, OdometryAid, OdometryAidConfig, OdometryDiagnostics, OdometrySample, TrackerConfig,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// A wheel odometry's errors (module documentation). Ranges are (low, high), drawn uniformly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryModel {
    /// Message rate, Hz.
    pub rate_hz: f64,
    /// Scale error |e|: the odometry reads (1 + e) times the true rate.
    pub scale_error: f64,
    /// White noise per message, deg/s.
    pub white_sd: f64,
    /// The angle's resolution, deg.
    pub tick_deg: f64,
    /// Slip bursts per window.
    pub slips: usize,
    /// A burst's length, s.
    pub slip_s: (f64, f64),
    /// A burst's error as a fraction of the true rate (its sign drawn).
    pub slip_frac: (f64, f64),
    /// A burst starts where the true rate is at least this, deg/s (a turn).
    pub slip_min_rate: f64,
    /// Latency from stamp to arrival, s.
    pub latency_s: (f64, f64),
    /// No message is stamped after this, s (None: to the end).
    pub ends_at_s: Option<f64>,
}

impl Default for OdometryModel {
    /// 50 Hz; scale 1%; white 0.1 deg/s; ticks 0.02 deg; 3 slips of 1-3 s, 10-30%, in turns
    /// from 5 deg/s; latency 20-50 ms; never stops.
    fn default() -> Self {
        OdometryModel {
            rate_hz: 50.0,
            scale_error: 0.01,
            white_sd: 0.1,
            tick_deg: 0.02,
            slips: 3,
            slip_s: (1.0, 3.0),
            slip_frac: (0.1, 0.3),
            slip_min_rate: 5.0,
            latency_s: (0.02, 0.05),
            ends_at_s: None,
        }
    }
}

/// One message and the gyro sample at which it has arrived.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryMessage {
    /// The message.
    pub sample: OdometrySample,
    /// The first gyro sample (index) at or after its arrival.
    pub arrival: usize,
}

/// A case's odometry and the errors drawn for it.
#[derive(Debug, Clone, PartialEq)]
pub struct OdometryTrace {
    /// Messages in arrival order.
    pub messages: Vec<OdometryMessage>,
    /// The scale error e drawn.
    pub scale_error: f64,
    /// The latency drawn, s.
    pub latency_s: f64,
    /// The slip bursts, gyro samples [start, end).
    pub slips: Vec<(usize, usize)>,
}

fn uniform(rng: &mut ChaCha8Rng, (lo, hi): (f64, f64)) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

/// The odometry of `motion` under `model`, its errors drawn from `seed`.
pub fn odometry(
    motion: &MotionTrace,
    model: &OdometryModel,
    seed: u64,
) -> Result<OdometryTrace, ProfileError> {
    let rate = motion.rate_hz;
    if !(rate.is_finite() && rate > 0.0) {
        return Err(ProfileError::BadRate(rate));
    }
    if !(model.rate_hz.is_finite() && model.rate_hz > 0.0) {
        return Err(ProfileError::BadRate(model.rate_hz));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(0x0d0);
    let n = motion.truth.len();
    let dt = 1.0 / rate;
    let sign = |rng: &mut ChaCha8Rng| if rng.random::<bool>() { 1.0 } else { -1.0 };
    let e = sign(&mut rng) * model.scale_error;
    let latency = uniform(&mut rng, model.latency_s);
    // Slip bursts start in turns.
    let turns: Vec<usize> = (0..n)
        .filter(|&i| !motion.still[i] && motion.truth[i].abs() >= model.slip_min_rate)
        .collect();
    let mut slips = Vec::new();
    let mut frac = vec![0.0; n];
    if !turns.is_empty() {
        for _ in 0..model.slips {
            let start = turns[rng.random_range(0..turns.len())];
            let len = (uniform(&mut rng, model.slip_s) * rate).round() as usize;
            let f = sign(&mut rng) * uniform(&mut rng, model.slip_frac);
            let end = (start + len).min(n);
            for v in &mut frac[start..end] {
                *v = f;
            }
            slips.push((start, end));
        }
    }
    let m = ((rate / model.rate_hz).round() as usize).max(1);
    let period = m as f64 * dt;
    let tick = model.tick_deg;
    let quantise = |a: f64| {
        if tick > 0.0 {
            (a / tick).round() * tick
        } else {
            a
        }
    };
    let mut angle = 0.0;
    let mut last_q = 0.0;
    let mut messages = Vec::with_capacity(n / m + 1);
    for (i, (&w, &f)) in motion.truth.iter().zip(&frac).enumerate() {
        angle += (1.0 + e) * (1.0 + f) * w * dt;
        // Message j covers samples ((j-1)m, jm] and is stamped at sample jm.
        if i == 0 {
            last_q = quantise(angle);
            continue;
        }
        if i % m != 0 {
            continue;
        }
        let stamp = i as f64 * dt;
        if model.ends_at_s.is_some_and(|end| stamp > end) {
            break;
        }
        let q = quantise(angle);
        let z: f64 = rng.sample(StandardNormal);
        let yaw_rate = (q - last_q) / period + model.white_sd * z;
        last_q = q;
        let arrival = ((stamp + latency) * rate - 1e-6).ceil().max(0.0) as usize;
        messages.push(OdometryMessage {
            sample: OdometrySample {
                stamp_s: stamp,
                period_s: period,
                yaw_rate,
                // The simulated driver states no sd: the aid's default is the model's.
                yaw_rate_sd: f64::NAN,
            },
            arrival,
        });
    }
    Ok(OdometryTrace {
        messages,
        scale_error: e,
        latency_s: latency,
        slips,
    })
}

/// The bias filter gated by the true stops, as [`super::Method::KfOracle`] runs it, plus the
/// odometry while moving ([`OdometryAid`]): the heading figures of its corrected rate and what
/// the odometry did.
pub fn evaluate_odometry(
    measured: &[f64],
    truth: &[f64],
    still: &[bool],
    setup: &Setup,
    odo: &OdometryTrace,
    aid: &OdometryAidConfig,
) -> Result<(HeadingMetrics, OdometryDiagnostics), EvalError> {
    let n = measured.len();
    if n == 0 || truth.len() != n || still.len() != n {
        return Err(EvalError::Lengths(n, truth.len(), still.len()));
    }
    let rate = setup.rate_hz;
    let cfg = TrackerConfig {
        delay_s: 0.0,
        backfill_s: 0.0,
        ..setup.tracker
    };
    let mut tracker = BiasTracker::new(&setup.terms, rate, &cfg)?;
    let r_gyro = tracker.filter().model().measurement_variance();
    let mut aid = OdometryAid::new(*aid, r_gyro, rate).map_err(EvalError::Odometry)?;
    tracker.add_scale(aid.scale_prior());
    let mut acc = HeadingAccumulator::new(1.0 / rate);
    let mut next = 0;
    for (k, ((&x, &t), &s)) in measured.iter().zip(truth).zip(still).enumerate() {
        aid.push_gyro(k as f64 / rate, x);
        let step = tracker.push_gated(x, s);
        let moving = !tracker.is_still();
        if !moving {
            aid.stop();
        }
        let mut bias = step.bias;
        while let Some(m) = odo.messages.get(next).filter(|m| m.arrival <= k) {
            next += 1;
            if !moving {
                continue;
            }
            let now = tracker.filter().scaled_view();
            if let Some(z) = aid.push_odometry(m.sample, now) {
                if tracker.update_in_motion(z) {
                    bias = tracker.filter().estimate();
                }
            }
        }
        if k >= setup.judge_from {
            acc.push(x - bias, t);
        }
    }
    Ok((acc.metrics(), aid.diagnostics()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drift::bias::BiasTerms;
    use crate::nav::profiles::{generate, Profile};

    #[test]
    fn the_odometry_is_the_truth_with_its_stated_errors() {
        let m = generate(Profile::Vehicle, 100.0, 600.0, 4).unwrap();
        let model = OdometryModel {
            white_sd: 0.0,
            slips: 0,
            ..OdometryModel::default()
        };
        let o = odometry(&m, &model, 9).unwrap();
        // Deterministic (compared as text: the unstated sd is NaN, never equal to itself).
        assert_eq!(
            format!("{o:?}"),
            format!("{:?}", odometry(&m, &model, 9).unwrap())
        );
        assert_eq!(o.scale_error.abs(), 0.01);
        assert!((0.02..=0.05).contains(&o.latency_s));
        // 50 Hz, stamped at the period's end, arriving after the latency.
        assert_eq!(o.messages.len(), 29_999);
        let first = o.messages[0];
        assert!((first.sample.stamp_s - 0.02).abs() < 1e-12);
        assert_eq!(
            first.arrival,
            ((0.02 + o.latency_s) * 100.0).ceil() as usize
        );
        // The angle the messages count is the scaled truth's, to a tick.
        let counted: f64 = o
            .messages
            .iter()
            .map(|m| m.sample.yaw_rate * m.sample.period_s)
            .sum();
        let truth: f64 = m.truth[1..].iter().sum::<f64>() / 100.0 * (1.0 + o.scale_error);
        assert!((counted - truth).abs() <= 0.02 + 1e-9, "{counted} {truth}");
        // Slips: in turns, off by 10-30% of the true rate; none before the first turn.
        let slipped = odometry(&m, &OdometryModel::default(), 9).unwrap();
        assert_eq!(slipped.slips.len(), 3);
        for &(s, e) in &slipped.slips {
            assert!(m.truth[s].abs() >= 5.0 && !m.still[s]);
            assert!((100..=300).contains(&(e - s)) || e == m.truth.len());
        }
        let ended = OdometryModel {
            ends_at_s: Some(300.0),
            ..model
        };
        let o = odometry(&m, &ended, 9).unwrap();
        assert!(o.messages.last().unwrap().sample.stamp_s <= 300.0);
    }

    #[test]
    fn the_odometry_learns_the_bias_while_driving() {
        // A constant bias, no stop after the first: the filter with the odometry ends closer.
        let m = generate(Profile::Continuous, 100.0, 600.0, 2).unwrap();
        let bias: Vec<f64> = (0..m.truth.len())
            .map(|k| 0.3 + 0.05 * (k as f64 / 60_000.0))
            .collect();
        let measured: Vec<f64> = m.truth.iter().zip(&bias).map(|(t, b)| t + b).collect();
        let setup = Setup::new(BiasTerms::profile("adis16405").unwrap(), 100.0);
        let o = odometry(&m, &OdometryModel::default(), 1).unwrap();
        let (with, diag) = evaluate_odometry(
            &measured,
            &m.truth,
            &m.still,
            &setup,
            &o,
            &OdometryAidConfig::default(),
        )
        .unwrap();
        let none = OdometryTrace {
            messages: Vec::new(),
            ..o.clone()
        };
        let (without, _) = evaluate_odometry(
            &measured,
            &m.truth,
            &m.still,
            &setup,
            &none,
            &OdometryAidConfig::default(),
        )
        .unwrap();
        // Without messages it is the filter with the true stops (KF oracle) exactly.
        let oracle = crate::nav::evaluate(
            &measured,
            &m.truth,
            &m.still,
            &setup,
            &[crate::nav::Method::KfOracle],
        )
        .unwrap();
        assert_eq!(without, oracle[0]);
        assert!(with.rms_deg < 0.3 * without.rms_deg, "{with:?} {without:?}");
        assert!(diag.accepted > 500 && diag.slips >= 1, "{diag:?}");
    }
}
