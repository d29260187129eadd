//! The accelerometer's side of a motion profile: the vehicle's acceleration in the body frame
//! for each sample of a [`MotionTrace`]. It is physically consistent with the profile's rate.
//!
//! A case of the heading benchmark is one gyro axis turning as a ground vehicle's yaw axis.
//! - The vehicle stays level, with its yaw axis the body's z (down). Gravity therefore stays
//!   what the static log's accelerometer reads, and the log supplies it with its real noise
//!   and bias.
//! - The body acceleration is (v', v r, 0): longitudinal at starts and stops, centripetal in
//!   turns ([`crate::sim::force`] derives it). The speed v follows the profile's
//!   [`SpeedProfile`] over each moving stretch of the still mask ([`Profile::speed`]). r is the
//!   trace's true rate.
//! - There is no vibration, no lever arm, and no vertical motion: no profile states any for
//!   the accelerometer.

use super::profiles::{MotionTrace, Profile};
use crate::sim::force::{level_vehicle_acceleration, SpeedProfile, VEHICLE_SPEED, WALKING_SPEED};

impl Profile {
    /// The speed over each moving stretch. Stop-and-go, vehicle and continuous use
    /// [`VEHICLE_SPEED`]: 10 m/s, 5 s ramps. Pedestrian uses [`WALKING_SPEED`]: 1.4 m/s, 1 s
    /// ramps.
    pub fn speed(self) -> SpeedProfile {
        match self {
            Profile::StopAndGo | Profile::Vehicle | Profile::Continuous => VEHICLE_SPEED,
            Profile::Pedestrian => WALKING_SPEED,
        }
    }
}

/// The body-frame acceleration (m/s², gravity not included) at each sample of `trace`. The
/// vehicle moves at `speed` over each moving stretch of the still mask and turns at the
/// trace's true rate; it is 0 while still. Sample i of a stretch of n samples sits
/// (i + 0.5) / rate into it, as the profile's rate envelope does.
pub fn body_acceleration(trace: &MotionTrace, speed: SpeedProfile) -> Vec<[f64; 3]> {
    let n = trace.truth.len();
    let dt = 1.0 / trace.rate_hz;
    let mut out = vec![[0.0; 3]; n];
    let mut start = 0;
    while start < n {
        let end = (start..n)
            .find(|&k| trace.still[k] != trace.still[start])
            .unwrap_or(n);
        if !trace.still[start] {
            let len = (end - start) as f64 * dt;
            let stretch = out[start..end].iter_mut().zip(&trace.truth[start..end]);
            for (i, (a, rate)) in stretch.enumerate() {
                let (v, dv) = speed.at((i as f64 + 0.5) * dt, len);
                *a = level_vehicle_acceleration(v, dv, rate.to_radians());
            }
        }
        start = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nav::profiles::generate;

    #[test]
    fn still_is_zero_and_moving_is_longitudinal_plus_centripetal() {
        let rate = 100.0;
        let trace = generate(Profile::StopAndGo, rate, 300.0, 1).unwrap();
        let acc = body_acceleration(&trace, Profile::StopAndGo.speed());
        for (a, &s) in acc.iter().zip(&trace.still) {
            assert_eq!(a[2], 0.0);
            if s {
                assert_eq!(*a, [0.0; 3]);
            }
        }
        // The first stretch, 60-100 s: speeding up over 5 s, then a 10 deg/s turn at 10 m/s.
        let fwd: f64 = acc[6000..6500].iter().map(|a| a[0]).sum::<f64>() / rate;
        assert!((fwd - 10.0).abs() < 1e-3, "the ramp reaches 10 m/s: {fwd}");
        let side: f64 = acc[7000..9000].iter().map(|a| a[1]).sum::<f64>() / 2000.0;
        let turn: f64 = trace.truth[7000..9000].iter().sum::<f64>() / 2000.0;
        assert!(
            (side - 10.0 * turn.to_radians()).abs() < 1e-9,
            "{side} {turn}"
        );
        assert!((side.abs() - 1.745).abs() < 0.1, "{side}");
        // Back to rest before the stop.
        let back: f64 = acc[9500..10_000].iter().map(|a| a[0]).sum::<f64>() / rate;
        assert!((back + 10.0).abs() < 1e-3, "{back}");
    }

    #[test]
    fn every_profile_states_a_speed_and_stays_plausible() {
        for p in Profile::ALL {
            let trace = generate(p, 100.0, 600.0, 4).unwrap();
            let acc = body_acceleration(&trace, p.speed());
            let worst = acc.iter().map(|a| a[0].hypot(a[1])).fold(0.0, f64::max);
            // Under 1 g: a car's hardest turn (40 deg/s at 10 m/s is 7 m/s²) or a walker's
            // quickest turn (120 deg/s at 1.4 m/s is 2.9 m/s²).
            assert!(worst > 0.5 && worst < 9.0, "{p}: {worst}");
        }
    }
}
