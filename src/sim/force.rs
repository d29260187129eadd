//! What the simulated sensor's accelerometer reads: the specific force of its motion, plus the
//! accelerometer's own noise.
//!
//! **Frames.** Body: the sensor's axes. Level and at rest, z points down, as the real ADIS16405
//! log lay (its z reads about -1 g). Navigation: north-east-down, gravity g_n = (0, 0, g) with
//! g = [`STANDARD_GRAVITY`].
//!
//! **Specific force.** An accelerometer at the body's origin reads f_b = C_bn (a_n - g_n).
//! - C_bn is the navigation-to-body rotation, from the attitude ([`Attitude`]) integrated from
//!   the true body rate.
//! - a_n is the origin's acceleration.
//! - Level and at rest, f_b = (0, 0, -g).
//!
//! **A ground vehicle** ([`SpeedProfile`]) has a_n = v' h + v psi' (k x h):
//! - It moves along its heading h (the body x axis on the horizontal): no sideslip, no climb.
//! - Its speed v(t) comes from a stated profile. k points down, psi' is the heading rate.
//! - The sensor sits on its yaw axis, so no lever arm adds to it.
//! - That is longitudinal v' at starts and stops, and centripetal v psi' in turns. Level, that is
//!   f_b = (v', v r, -g) with r the yaw rate: a right turn (r > 0 about z down) pushes +y.
//! - Nothing else: no vibration, no bumps, no lever arm. A profile that wants them must say so,
//!   and how much.
//!
//! **Rate-table motion** (no speed profile): the sensor turns about its own origin, a_n = 0, and
//! f_b is gravity alone, turned into the body frame by the attitude.
//!
//! **The accelerometer** ([`Accelerometer`], [`AccelTerms`]) reads f_b plus its noise. The noise
//! is the gyro simulator's terms in m/s² units (white: velocity random walk; flicker: bias
//! instability), plus a turn-on bias per axis drawn from the seed, then rounded to its LSB. It
//! draws from the seed's streams 3-6, so the gyro's samples (streams 0-2) do not change when it
//! is added.

use super::{Motion, NoiseTerms, SimConfig, SimError, Simulator};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::f64::consts::PI;

pub use crate::units::STANDARD_GRAVITY;

/// A road vehicle's speed: 10 m/s (36 km/h) between 5 s raised-cosine ramps (peak longitudinal
/// acceleration pi 10 / (2 x 5) = 3.1 m/s², 0.32 g; a 10 deg/s turn at speed is 1.75 m/s²
/// sideways).
pub const VEHICLE_SPEED: SpeedProfile = SpeedProfile {
    cruise_m_s: 10.0,
    ramp_s: 5.0,
};

/// A pedestrian's speed: 1.4 m/s, a comfortable walking speed, between 1 s ramps (peak
/// 2.2 m/s²).
pub const WALKING_SPEED: SpeedProfile = SpeedProfile {
    cruise_m_s: 1.4,
    ramp_s: 1.0,
};

/// A vehicle's speed over each moving stretch. From rest it reaches `cruise_m_s` along a
/// raised-cosine ramp of `ramp_s`, holds it, and ramps back to rest at the stretch's end. A
/// stretch shorter than two ramps ramps over half its length each way. Speed and its rate are
/// continuous, so the longitudinal acceleration has no steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedProfile {
    /// Speed between the ramps, m/s.
    pub cruise_m_s: f64,
    /// Length of each ramp, s.
    pub ramp_s: f64,
}

impl SpeedProfile {
    /// Speed (m/s) and its rate of change (m/s²) at `t` s into a moving stretch of `len` s
    /// (both 0 outside it).
    pub fn at(&self, t: f64, len: f64) -> (f64, f64) {
        if !(t > 0.0 && t < len) {
            return (0.0, 0.0);
        }
        let ramp = self.ramp_s.min(len / 2.0);
        let (edge, sign) = if t <= len - t {
            (t, 1.0)
        } else {
            (len - t, -1.0)
        };
        if ramp <= 0.0 || edge >= ramp {
            return (self.cruise_m_s, 0.0);
        }
        let u = edge / ramp;
        let v = self.cruise_m_s * 0.5 * (1.0 - (PI * u).cos());
        let dv = sign * self.cruise_m_s * 0.5 * PI * (PI * u).sin() / ramp;
        (v, dv)
    }

    /// The largest longitudinal acceleration of a full ramp, m/s²: pi V / (2 T).
    pub fn peak_accel(&self) -> f64 {
        PI * self.cruise_m_s / (2.0 * self.ramp_s)
    }
}

/// The body-frame acceleration (m/s², gravity not included) of a level ground vehicle at speed
/// `v` (m/s) changing at `dv` (m/s²) and turning at `yaw_rate` (rad/s about z down): (dv,
/// v yaw_rate, 0).
pub fn level_vehicle_acceleration(v: f64, dv: f64, yaw_rate: f64) -> [f64; 3] {
    [dv, v * yaw_rate, 0.0]
}

/// An attitude: the body-to-navigation rotation as a unit quaternion (w, x, y, z), Hamilton
/// convention, navigation frame north-east-down.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Attitude {
    q: [f64; 4],
}

impl Attitude {
    /// Level, heading north: the body axes are the navigation axes.
    pub const LEVEL: Attitude = Attitude {
        q: [1.0, 0.0, 0.0, 0.0],
    };

    /// Turn by the body-frame rotation vector `angle` (rad): q <- q (x) exp(angle / 2).
    pub fn turn(&mut self, angle: [f64; 3]) {
        let n = (angle[0] * angle[0] + angle[1] * angle[1] + angle[2] * angle[2]).sqrt();
        if n == 0.0 {
            return;
        }
        let (s, c) = (0.5 * n).sin_cos();
        let k = s / n;
        let d = [c, angle[0] * k, angle[1] * k, angle[2] * k];
        let q = quat_mul(self.q, d);
        let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        self.q = q.map(|x| x / norm);
    }

    /// A navigation-frame vector in the body frame (C_bn v).
    pub fn to_body(&self, v: [f64; 3]) -> [f64; 3] {
        let [w, x, y, z] = self.q;
        rotate([w, -x, -y, -z], v)
    }

    /// A body-frame vector in the navigation frame (C_nb v).
    pub fn to_nav(&self, v: [f64; 3]) -> [f64; 3] {
        rotate(self.q, v)
    }

    /// Roll, pitch and heading (ZYX Euler angles), rad.
    pub fn euler(&self) -> [f64; 3] {
        let [w, x, y, z] = self.q;
        let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
        let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
        let heading = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
        [roll, pitch, heading]
    }

    /// The heading's rate (rad/s) for the body rate `rate` (rad/s): (q sin(roll) + r cos(roll)) /
    /// cos(pitch).
    pub fn heading_rate(&self, rate: [f64; 3]) -> f64 {
        let [roll, pitch, _] = self.euler();
        (rate[1] * roll.sin() + rate[2] * roll.cos()) / pitch.cos()
    }
}

fn quat_mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// q v q* for a unit quaternion q (w, x, y, z): `v` turned by q.
pub fn rotate(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let p = quat_mul(
        quat_mul(q, [0.0, v[0], v[1], v[2]]),
        [q[0], -q[1], -q[2], -q[3]],
    );
    [p[1], p[2], p[3]]
}

/// The specific force (m/s²) at attitude `att` for the body origin's navigation-frame
/// acceleration `accel_nav` (m/s²): C_bn (a_n - g_n).
pub fn specific_force(att: &Attitude, accel_nav: [f64; 3]) -> [f64; 3] {
    att.to_body([accel_nav[0], accel_nav[1], accel_nav[2] - STANDARD_GRAVITY])
}

/// The navigation-frame acceleration of a ground vehicle at attitude `att` with speed `v`
/// (m/s) changing at `dv` (m/s²) and body rate `rate` (rad/s): v' h + v psi' (k x h).
pub fn vehicle_acceleration_nav(att: &Attitude, v: f64, dv: f64, rate: [f64; 3]) -> [f64; 3] {
    let heading = att.euler()[2];
    let (s, c) = heading.sin_cos();
    let turn = v * att.heading_rate(rate);
    // k x h = (-sin, cos, 0) with k down: to the vehicle's right.
    [dv * c - turn * s, dv * s + turn * c, 0.0]
}

/// The speed profile of a [`Motion`], and where the vehicle is in it at `t`: the stop-and-go
/// motion is a vehicle ([`VEHICLE_SPEED`]); the others are rate-table motions (no translation).
pub fn motion_speed(motion: Motion, t: f64) -> Option<(SpeedProfile, f64, f64)> {
    match motion {
        Motion::StopAndGo => {
            let (since, len) = super::stop_and_go_stretch(t)?;
            Some((VEHICLE_SPEED, since, len))
        }
        Motion::None | Motion::Sines | Motion::Steps | Motion::Turn => None,
    }
}

/// The true specific force of a [`Motion`], sample by sample: the attitude integrated from the
/// motion's true rate (level at t = 0), the vehicle's acceleration where the motion is a
/// vehicle's. A sensor with fewer than 3 gyro axes has them as the body's last axes (one axis:
/// z, the yaw axis), so the stop-and-go's turn, on the last axis, is always about z.
#[derive(Debug, Clone)]
pub struct ForceTrack {
    motion: Motion,
    axes: usize,
    rate_hz: f64,
    attitude: Attitude,
    k: u64,
}

impl ForceTrack {
    /// At t = 0, level, for `axes` gyro axes at `rate_hz`.
    pub fn new(motion: Motion, axes: usize, rate_hz: f64) -> ForceTrack {
        ForceTrack {
            motion,
            axes: axes.clamp(1, 3),
            rate_hz,
            attitude: Attitude::LEVEL,
            k: 0,
        }
    }

    /// The body rate (rad/s) of the motion at `t` (s).
    pub fn body_rate(&self, t: f64) -> [f64; 3] {
        let mut r = [0.0; 3];
        let first = 3 - self.axes;
        for a in 0..self.axes {
            r[first + a] = self.motion.rate(a, self.axes, t).to_radians();
        }
        r
    }

    /// The attitude at the next sample.
    pub fn attitude(&self) -> Attitude {
        self.attitude
    }

    /// The true specific force (m/s²) at the next sample; then the attitude moves on to the one
    /// after (the rotation over the step by Simpson's rule on the rate).
    pub fn next_force(&mut self) -> [f64; 3] {
        let dt = 1.0 / self.rate_hz;
        let t = self.k as f64 * dt;
        let rate = self.body_rate(t);
        let accel = match motion_speed(self.motion, t) {
            Some((speed, since, len)) => {
                let (v, dv) = speed.at(since, len);
                vehicle_acceleration_nav(&self.attitude, v, dv, rate)
            }
            None => [0.0; 3],
        };
        let f = specific_force(&self.attitude, accel);
        let mid = self.body_rate(t + 0.5 * dt);
        let end = self.body_rate(t + dt);
        let angle: [f64; 3] = std::array::from_fn(|i| (rate[i] + 4.0 * mid[i] + end[i]) * dt / 6.0);
        self.attitude.turn(angle);
        self.k += 1;
        f
    }
}

/// An accelerometer's noise terms, m/s² based.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelTerms {
    /// Velocity random walk, m/s/sqrt(s) (60 x for m/s/sqrt(h)): white noise of sd
    /// vrw sqrt(rate) per sample.
    pub vrw: f64,
    /// Bias instability, m/s² (flicker noise, as the gyro simulator models it).
    pub bias_instability: f64,
    /// Spread of the turn-on bias, m/s² (1 sigma, drawn per axis from the seed).
    pub turn_on_sd: f64,
    /// Output step, m/s², if the reading is quantised.
    pub lsb: Option<f64>,
}

/// 1 mg in m/s².
const MG: f64 = 1e-3 * STANDARD_GRAVITY;

/// The ADIS16405's accelerometer, from the Analog Devices ADIS16400/ADIS16405 data sheet
/// (Rev. B, Table 1; NaveGo's synthetic example transcribes the same figures).
/// - Velocity random walk: 0.2 m/s/sqrt(h), 1 sigma. That is a noise density of 0.34 mg/sqrt(Hz),
///   3.4 mg per sample at 100 Hz; the real static log reads 3.0-4.3 mg.
/// - In-run bias stability: 0.2 mg, 1 sigma: the Allan deviation's floor, which is 0.664 B, so
///   B = 0.3 mg (as `predict.bias`'s `accel_bias_instability` default takes it). The real
///   log's Allan floor is 0.22-0.29 mg near 10 s.
/// - Initial bias error: 50 mg, 1 sigma (the real log's z axis is 16 mg off 1 g).
/// - Sensitivity: 3.33 mg per LSB (the real log's step).
pub const ADIS16405_ACCEL: AccelTerms = AccelTerms {
    vrw: 0.2 / 60.0,
    bias_instability: 0.3 * MG,
    turn_on_sd: 50.0 * MG,
    lsb: Some(3.33 * MG),
};

impl AccelTerms {
    /// The accelerometer of a named sensor profile ([`SimConfig::profile`]'s names):
    /// `adis16405` ([`ADIS16405_ACCEL`]); None for `adxrs450`, a gyro alone.
    pub fn profile(name: &str) -> Result<Option<AccelTerms>, SimError> {
        match name {
            "adis16405" => Ok(Some(ADIS16405_ACCEL)),
            "adxrs450" => Ok(None),
            _ => Err(SimError::UnknownProfile(name.to_string())),
        }
    }

    /// The 1-sigma white noise of one sample at `rate_hz`, m/s²: the velocity random walk's,
    /// with the LSB's rounding (lsb / sqrt 12) added in quadrature.
    pub fn white_sd(&self, rate_hz: f64) -> f64 {
        let white = self.vrw * rate_hz.sqrt();
        let q = self.lsb.map_or(0.0, |l| l / 12f64.sqrt());
        (white * white + q * q).sqrt()
    }
}

/// A streaming accelerometer: the true specific force in, the reading out (m/s²). O(1) and
/// allocation-free per sample.
#[derive(Debug, Clone)]
pub struct Accelerometer {
    noise: Simulator,
    bias: [f64; 3],
    lsb: Option<f64>,
}

impl Accelerometer {
    /// An accelerometer of `terms` at `rate_hz` whose noise comes from `seed` (streams 3-6).
    pub fn new(terms: &AccelTerms, rate_hz: f64, seed: u64) -> Result<Accelerometer, SimError> {
        for (name, v) in [
            ("VRW", terms.vrw),
            ("accelerometer B", terms.bias_instability),
            ("turn-on bias", terms.turn_on_sd),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(SimError::BadTerm(name, v));
            }
        }
        if let Some(l) = terms.lsb {
            if !(l.is_finite() && l > 0.0) {
                return Err(SimError::BadLsb(l));
            }
        }
        let cfg = SimConfig {
            terms: NoiseTerms {
                q: 0.0,
                n: terms.vrw,
                b: terms.bias_instability,
                k: 0.0,
                r: 0.0,
                bias: 0.0,
            },
            rate_hz,
            axes: 3,
            seed,
            motion: Motion::None,
            lsb: None,
        };
        let noise = Simulator::on_streams(&cfg, 3)?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(6);
        let bias = std::array::from_fn(|_| {
            let z: f64 = StandardNormal.sample(&mut rng);
            terms.turn_on_sd * z
        });
        Ok(Accelerometer {
            noise,
            bias,
            lsb: terms.lsb,
        })
    }

    /// The turn-on bias drawn for each axis, m/s².
    pub fn turn_on_bias(&self) -> [f64; 3] {
        self.bias
    }

    /// What the accelerometer reads for the true specific force `force` (m/s²).
    pub fn measure(&mut self, force: [f64; 3]) -> [f64; 3] {
        let n = self.noise.next_sample().measured;
        std::array::from_fn(|i| {
            let v = force[i] + self.bias[i] + n[i];
            match self.lsb {
                Some(l) => (v / l).round() * l,
                None => v,
            }
        })
    }
}

/// A simulated sensor's accelerometer beside its gyro ([`Simulator`]): the true specific force
/// of the gyro's motion ([`ForceTrack`]), read by the sensor's accelerometer
/// ([`Accelerometer`]), sample for sample with the gyro's samples.
#[derive(Debug, Clone)]
pub struct SimAccel {
    track: ForceTrack,
    meter: Accelerometer,
}

impl SimAccel {
    /// The accelerometer of the sensor profile `profile` for the gyro simulated by `cfg` (its
    /// motion, axes, rate and seed); None for a profile without one.
    pub fn new(profile: &str, cfg: &SimConfig) -> Result<Option<SimAccel>, SimError> {
        let Some(terms) = AccelTerms::profile(profile)? else {
            return Ok(None);
        };
        Ok(Some(SimAccel {
            track: ForceTrack::new(cfg.motion, cfg.axes, cfg.rate_hz),
            meter: Accelerometer::new(&terms, cfg.rate_hz, cfg.seed)?,
        }))
    }

    /// The earth's field `earth` (navigation frame, any unit) as a perfect magnetometer in the
    /// body reads it at the next sample: call it before [`SimAccel::next_reading`], which moves
    /// the attitude on. No noise and no hard iron: a stand-in driver's field, for the heading.
    pub fn body_field(&self, earth: [f64; 3]) -> [f64; 3] {
        self.track.attitude().to_body(earth)
    }

    /// The next sample's reading, m/s² (O(1), no allocation).
    pub fn next_reading(&mut self) -> [f64; 3] {
        let f = self.track.next_force();
        self.meter.measure(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
        a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= tol)
    }

    #[test]
    fn the_body_field_turns_with_the_attitude_and_keeps_its_norm() {
        let cfg = SimConfig {
            motion: Motion::Sines,
            axes: 3,
            ..SimConfig::profile("adis16405").unwrap()
        };
        let mut sim = SimAccel::new("adis16405", &cfg).unwrap().unwrap();
        let earth = [20e-6, 0.0, 45e-6];
        assert!(close(sim.body_field(earth), earth, 1e-15), "level at t = 0");
        let mut turned = 0.0f64;
        for _ in 0..5_000 {
            sim.next_reading();
            let m = sim.body_field(earth);
            let norm = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
            assert!((norm - 49.24e-6).abs() < 1e-8, "norm {norm}");
            turned = turned.max((m[0] - earth[0]).abs());
        }
        assert!(turned > 1e-6, "the field never turned: {turned}");
    }

    #[test]
    fn level_and_still_reads_minus_g_on_z() {
        let f = specific_force(&Attitude::LEVEL, [0.0; 3]);
        assert_eq!(f, [0.0, 0.0, -STANDARD_GRAVITY]);
    }

    #[test]
    fn a_roll_of_ninety_degrees_puts_gravity_on_y() {
        // Right wing down (roll +90 deg about x): body y points down, so y reads -g.
        let mut a = Attitude::LEVEL;
        a.turn([PI / 2.0, 0.0, 0.0]);
        let f = specific_force(&a, [0.0; 3]);
        assert!(close(f, [0.0, -STANDARD_GRAVITY, 0.0], 1e-12), "{f:?}");
        assert!((a.euler()[0] - PI / 2.0).abs() < 1e-12);
    }

    #[test]
    fn the_speed_ramp_integrates_to_its_speed() {
        let p = VEHICLE_SPEED;
        let dt = 1e-3;
        let mut v = 0.0;
        for k in 0..40_000 {
            let t = (k as f64 + 0.5) * dt;
            let (_, dv) = p.at(t, 40.0);
            v += dv * dt;
            if k == 19_999 {
                assert!((v - 10.0).abs() < 1e-6, "{v}");
                assert_eq!(p.at(t, 40.0).0, 10.0);
            }
        }
        assert!(v.abs() < 1e-6, "back to rest: {v}");
        let peak = (0..5000)
            .map(|k| p.at(k as f64 * 1e-3, 40.0).1)
            .fold(0.0, f64::max);
        assert!((peak - p.peak_accel()).abs() < 1e-3, "{peak}");
        // A stretch shorter than two ramps ramps over half of it.
        assert!((p.at(2.0, 4.0).0 - 10.0).abs() < 1e-12);
        assert_eq!(p.at(0.0, 4.0), (0.0, 0.0));
        assert_eq!(p.at(5.0, 4.0), (0.0, 0.0));
    }

    #[test]
    fn a_level_turning_vehicle_reads_its_centripetal_force_sideways() {
        // Heading 30 deg, 10 m/s, turning right at 0.2 rad/s, speeding up at 1 m/s².
        let mut a = Attitude::LEVEL;
        a.turn([0.0, 0.0, PI / 6.0]);
        let rate = [0.0, 0.0, 0.2];
        let f = specific_force(&a, vehicle_acceleration_nav(&a, 10.0, 1.0, rate));
        let level = level_vehicle_acceleration(10.0, 1.0, 0.2);
        assert!(
            close(f, [level[0], level[1], -STANDARD_GRAVITY], 1e-12),
            "{f:?}"
        );
        assert!((level[1] - 2.0).abs() < 1e-12);
    }

    #[test]
    fn the_turn_motion_ends_level_and_its_force_is_gravity() {
        // A rate table: no translation; turns about z keep gravity on z.
        let mut track = ForceTrack::new(Motion::Turn, 3, 100.0);
        for _ in 0..6000 {
            let f = track.next_force();
            assert!(close(f, [0.0, 0.0, -STANDARD_GRAVITY], 1e-9), "{f:?}");
        }
        // +90 deg then -90 deg: heading back to 0.
        assert!(track.attitude().euler()[2].abs() < 1e-9);
    }

    #[test]
    fn sines_tilt_gravity_but_keep_its_size() {
        let mut track = ForceTrack::new(Motion::Sines, 3, 100.0);
        let mut max_xy: f64 = 0.0;
        for _ in 0..3000 {
            let f = track.next_force();
            let n = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
            assert!((n - STANDARD_GRAVITY).abs() < 1e-9);
            max_xy = max_xy.max(f[0].abs()).max(f[1].abs());
        }
        assert!(
            max_xy > 1.0,
            "a tilt of tens of degrees moves gravity: {max_xy}"
        );
    }

    #[test]
    fn stop_and_go_pushes_forward_then_sideways() {
        let rate = 100.0;
        let mut track = ForceTrack::new(Motion::StopAndGo, 3, rate);
        let forces: Vec<[f64; 3]> = (0..10_000).map(|_| track.next_force()).collect();
        // Still for the first 60 s: gravity alone.
        assert!(forces[..6000]
            .iter()
            .all(|f| close(*f, [0.0, 0.0, -STANDARD_GRAVITY], 1e-12)));
        // Speeding up over the first 5 s of the stretch: 3.14 m/s² forward at the ramp's
        // middle, give or take the wobble's tilt of gravity (+-0.45 deg: 0.08 m/s²).
        let fwd = forces[6250][0];
        assert!((fwd - VEHICLE_SPEED.peak_accel()).abs() < 0.15, "{fwd}");
        // At cruise, turning at 10 deg/s (the sines add a little): about 10 x 0.1745 sideways.
        let side: f64 = forces[7500..9000].iter().map(|f| f[1]).sum::<f64>() / 1500.0;
        assert!(
            (side.abs() - 10.0 * 10f64.to_radians()).abs() < 0.05,
            "{side}"
        );
        // Slowing down before the stop: backward.
        assert!(forces[9750][0] < -3.0);
    }

    #[test]
    fn the_accelerometer_reads_the_force_with_the_data_sheet_noise() {
        let rate = 100.0;
        let mut acc = Accelerometer::new(&ADIS16405_ACCEL, rate, 5).unwrap();
        let g = [0.0, 0.0, -STANDARD_GRAVITY];
        let n = 100_000;
        let reads: Vec<[f64; 3]> = (0..n).map(|_| acc.measure(g)).collect();
        let lsb = ADIS16405_ACCEL.lsb.unwrap();
        for axis in 0..3 {
            let x: Vec<f64> = reads.iter().map(|r| r[axis]).collect();
            let mean = x.iter().sum::<f64>() / n as f64;
            let sd = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
            // The turn-on bias shows in the mean (within a few bias-instability sigmas).
            let want = g[axis] + acc.turn_on_bias()[axis];
            assert!((mean - want).abs() < 0.01, "{axis}: {mean} vs {want}");
            // Per-sample spread: the white term and the rounding, a little flicker on top.
            let white = ADIS16405_ACCEL.white_sd(rate);
            assert!(
                sd > white * 0.97 && sd < white * 1.1,
                "{axis}: {sd} vs {white}"
            );
            assert!(x
                .iter()
                .all(|v| ((v / lsb) - (v / lsb).round()).abs() < 1e-6));
        }
        // Seeded: the same seed gives the same readings, another seed others.
        let mut again = Accelerometer::new(&ADIS16405_ACCEL, rate, 5).unwrap();
        assert_eq!(again.measure(g), reads[0]);
        let other = Accelerometer::new(&ADIS16405_ACCEL, rate, 6).unwrap();
        assert_ne!(other.turn_on_bias(), acc.turn_on_bias());
    }

    #[test]
    fn a_simulated_sensor_carries_its_accelerometer_and_a_gyro_alone_none() {
        let mut cfg = SimConfig::profile("adis16405").unwrap();
        cfg.motion = Motion::StopAndGo;
        let mut acc = SimAccel::new("adis16405", &cfg).unwrap().unwrap();
        let reads: Vec<[f64; 3]> = (0..10_000).map(|_| acc.next_reading()).collect();
        let mean = |r: std::ops::Range<usize>, a: usize| {
            reads[r.clone()].iter().map(|x| x[a]).sum::<f64>() / r.len() as f64
        };
        // Still: about -g on z (the turn-on bias is 50 mg at 1 sigma).
        assert!((mean(0..6000, 2) + STANDARD_GRAVITY).abs() < 2.0);
        // Turning at speed: sideways by about 1.75 m/s² against the still mean.
        let side = mean(7500..9000, 1) - mean(0..6000, 1);
        assert!((side.abs() - 1.745).abs() < 0.1, "{side}");
        let mut gyro_only = SimConfig::profile("adxrs450").unwrap();
        gyro_only.motion = Motion::Sines;
        assert!(SimAccel::new("adxrs450", &gyro_only).unwrap().is_none());
    }

    #[test]
    fn profiles_name_their_accelerometer() {
        assert_eq!(
            AccelTerms::profile("adis16405").unwrap(),
            Some(ADIS16405_ACCEL)
        );
        assert_eq!(AccelTerms::profile("adxrs450").unwrap(), None);
        assert!(AccelTerms::profile("nope").is_err());
        let bad = AccelTerms {
            vrw: -1.0,
            ..ADIS16405_ACCEL
        };
        assert!(Accelerometer::new(&bad, 100.0, 1).is_err());
    }
}
