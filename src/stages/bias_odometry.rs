//! `predict.bias`'s odometry: the vehicle's yaw rate on its `stop_input` as a measurement of
//! the up axis's bias while the vehicle drives ([`crate::drift::bias::OdometryAid`], the
//! maths), which gyro axis is up (`vehicle_up`, or `mount`'s rotation, or from gravity at the
//! first rest, and checked by both gravity and the turns), the clock its messages are on, and
//! what it says of itself (the run's summary, the stats service).
//!
//! The up axis reads `c` times the vehicle's yaw rate: its sign for an axis named, the up's
//! component along it for a mount rotation or gravity (the cosine of its tilt, signed). The
//! aid works on the axis's rate divided by `c` (the vehicle's yaw rate plus the bias over
//! `c`), and what it measures goes back to the axis times `c`.

use crate::drift::bias::{
    BiasTracker, GravityUp, Measurement, Mounting, OdometryAid, OdometryAidConfig, OdometrySample,
    UpFromGravity, UP_MAX_TILT_DEG,
};
use crate::wire::{
    OdometryStats, StopSignal, MOUNTING_CONFIRMED, MOUNTING_UNKNOWN, MOUNTING_WRONG_AXIS,
    MOUNTING_WRONG_SIGN, STOP_CLOCK_MONOTONIC, STOP_CLOCK_SAMPLES, UP_AXES, UP_GRAVITY_PENDING,
};

/// `vehicle_up` or `mount`: how the vehicle's up is known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VehicleUp {
    /// Gyro axis `axis` (0, 1, 2) points up, with `sign` (+1 or -1).
    Axis {
        /// The axis.
        axis: usize,
        /// +1 or -1.
        sign: f64,
    },
    /// A mount rotation (`mount`, [`crate::drift::bias::up_from_mount`]): gyro axis `axis`
    /// reads `c` times the vehicle's yaw rate.
    Mount {
        /// The axis nearest the vehicle's up.
        axis: usize,
        /// The up's component along it: signed, at least cos 30 deg in size.
        c: f64,
    },
    /// From the accelerometer at the first rest (`"gravity"`).
    Gravity,
}

impl VehicleUp {
    /// The configured axis and its share `c` of the yaw rate; none for gravity.
    pub fn axis(self) -> Option<(usize, f64)> {
        match self {
            VehicleUp::Axis { axis, sign } => Some((axis, sign)),
            VehicleUp::Mount { axis, c } => Some((axis, c)),
            VehicleUp::Gravity => None,
        }
    }

    /// The words of it, as the summary and the messages give them: `vehicle_up = "-z"`, or
    /// the mount's axis and tilt.
    pub fn describe(self) -> String {
        match self {
            VehicleUp::Axis { axis, sign } => format!("vehicle_up = \"{}\"", up_word(axis, sign)),
            VehicleUp::Mount { axis, c } => format!(
                "mount (its up along the gyro's {}, {:.1} deg from it)",
                up_word(axis, c),
                tilt_deg(c)
            ),
            VehicleUp::Gravity => "vehicle_up = \"gravity\"".into(),
        }
    }
}

/// The tilt of an axis whose share of the yaw rate is `c`, deg.
pub(crate) fn tilt_deg(c: f64) -> f64 {
    c.abs().min(1.0).acos().to_degrees()
}

/// The word of `vehicle_up` for an axis and a sign (or a share, by its sign).
pub(crate) fn up_word(axis: usize, sign: f64) -> &'static str {
    UP_AXES[OdometryStats::up_code(axis, sign) as usize]
}

/// The vehicle's yaw rate as a measurement of the up axis's bias while it moves.
pub(crate) struct Odometry {
    /// The gyro axis that is the vehicle's up, and its share `c` of the yaw rate; `None`
    /// while gravity has not told it yet (`vehicle_up = "gravity"`).
    pub(crate) up: Option<(usize, f64)>,
    /// How the up was set.
    configured: VehicleUp,
    /// The up axis from the accelerometer at the first rest: it checks a configured axis, or
    /// (`"gravity"`) names it.
    gravity: UpFromGravity,
    /// Gravity's refusal of the configured axis (or, with `"gravity"`, of a tilted sensor):
    /// the yaw rate is used no more.
    gravity_refused: bool,
    /// Each axis's white noise per sample, (deg/s)^2: the aid's weight of the gyro.
    r_axes: [f64; 3],
    rate_hz: f64,
    aid: OdometryAid,
    /// The stamp of the last message, ns (its period, when the message does not say it).
    last_t_ns: u64,
    /// The clock the messages (and so the gyro's history) are on ([`StopSignal::clock`]).
    clock: u32,
    /// Measurements the filter took.
    learnt: u64,
    /// What they moved the axis's bias estimate by, summed, deg/s.
    bias_learnt: f64,
}

impl Odometry {
    /// The odometry of `configured`; `r_axes`: each axis's white noise per sample.
    pub(crate) fn new(
        configured: VehicleUp,
        r_axes: [f64; 3],
        rate_hz: f64,
    ) -> Result<Odometry, String> {
        let up = configured.axis();
        // The aid reads the axis divided by c: its noise grows by 1/c^2.
        let r = up.map_or(r_axes[2], |(axis, c)| r_axes[axis] / (c * c));
        Ok(Odometry {
            up,
            configured,
            // One second at rest.
            gravity: UpFromGravity::new(rate_hz.round() as u64),
            gravity_refused: false,
            r_axes,
            rate_hz,
            aid: OdometryAid::new(OdometryAidConfig::default(), r, rate_hz)?,
            last_t_ns: 0,
            clock: STOP_CLOCK_MONOTONIC,
            learnt: 0,
            bias_learnt: 0.0,
        })
    }

    /// The scale state the trackers carry ([`OdometryAid::scale_prior`]).
    pub(crate) fn scale_prior(&self) -> (f64, f64) {
        self.aid.scale_prior()
    }

    /// A specific force read at rest: once gravity has judged, the configured axis is checked
    /// (a disagreement refuses the yaw rate, said once with the fix) or, with `"gravity"`, the
    /// up axis is taken from it.
    pub(crate) fn at_rest(&mut self, f: [f64; 3]) {
        let Some(g) = self.gravity.push(f) else {
            return;
        };
        let said = match (self.configured.axis(), g) {
            (
                None,
                GravityUp::Axis {
                    axis,
                    sign,
                    tilt_deg,
                },
            ) => {
                // The up's share along the axis; the aid weighs the gyro axis it now reads.
                let c = sign * tilt_deg.to_radians().cos();
                if let Ok(aid) = OdometryAid::new(
                    OdometryAidConfig::default(),
                    self.r_axes[axis] / (c * c),
                    self.rate_hz,
                ) {
                    self.aid = aid;
                    self.up = Some((axis, c));
                }
                format!(
                    "vehicle_up from gravity: the gyro's {} points up ({tilt_deg:.1} deg from the \
                     vertical); the odometry's yaw rate teaches its bias while moving",
                    up_word(axis, sign)
                )
            }
            (None, GravityUp::Tilted { tilt_deg }) => {
                self.gravity_refused = true;
                format!(
                    "error: vehicle_up = \"gravity\", but no gyro axis is within \
                     {UP_MAX_TILT_DEG} deg of the vertical (the nearest leans {tilt_deg:.0} deg): \
                     the yaw rate is refused. Give the mount rotation (mount), or mount the IMU \
                     with an axis vertical and set vehicle_up to it"
                )
            }
            (Some((axis, c)), GravityUp::Axis { .. }) if g.axis() == Some((axis, c.signum())) => {
                return
            }
            (
                Some(_),
                GravityUp::Axis {
                    axis: ga,
                    sign: gs,
                    tilt_deg,
                },
            ) => {
                self.gravity_refused = true;
                let up = up_word(ga, gs);
                format!(
                    "error: gravity says the gyro's {up} points up ({tilt_deg:.1} deg from the \
                     vertical, the accelerometer at rest), but {}: the yaw rate is refused from \
                     now on. Set vehicle_up = \"{up}\" (or \"gravity\")",
                    self.configured.describe()
                )
            }
            (Some(_), GravityUp::Tilted { tilt_deg }) => format!(
                "warning: no gyro axis is within {UP_MAX_TILT_DEG} deg of the vertical (the \
                 nearest leans {tilt_deg:.0} deg): gravity cannot check {}; the turns will",
                self.configured.describe()
            ),
        };
        eprintln!("driftless: predict.bias: {said}");
    }

    /// One sample (`x` deg/s, the up axis's rate as the filter sees it) at ingest time
    /// `ingest_ns` and sample time `t_ns`, and the message that came with it, if any; `tracker`
    /// is that axis's, after the sample. The gyro is timed on the clock of the messages
    /// ([`StopSignal::clock`]); a message on the other one switches it, and the gyro's history
    /// starts again.
    pub(crate) fn push(
        &mut self,
        tracker: &mut BiasTracker,
        x: f64,
        (ingest_ns, t_ns): (u64, u64),
        message: Option<&StopSignal>,
    ) {
        let Some((_, c)) = self.up.filter(|_| !self.gravity_refused) else {
            return;
        };
        if let Some(m) = message.filter(|m| m.clock != self.clock) {
            self.clock = m.clock;
            self.aid.restart_history();
            self.last_t_ns = 0;
        }
        let now_ns = if self.clock == STOP_CLOCK_SAMPLES {
            t_ns
        } else {
            ingest_ns
        };
        self.aid.push_gyro(now_ns as f64 * 1e-9, x / c);
        let moving = !tracker.is_still();
        if !moving {
            self.aid.stop();
        }
        let Some(m) = message.filter(|m| m.yaw_rate_rad_s.is_finite() && m.t_ns != 0) else {
            return;
        };
        let period_ns = if m.period_ns > 0 {
            m.period_ns
        } else {
            m.t_ns.saturating_sub(self.last_t_ns)
        };
        let first = self.last_t_ns == 0;
        self.last_t_ns = m.t_ns;
        // Without a period, the first message only starts the clock; a gap over 1 s is no period.
        if !moving || (m.period_ns == 0 && (first || period_ns > 1_000_000_000)) {
            return;
        }
        let sample = OdometrySample {
            stamp_s: m.t_ns as f64 * 1e-9,
            period_s: period_ns as f64 * 1e-9,
            yaw_rate: m.yaw_rate_rad_s.to_degrees(),
            yaw_rate_sd: m.yaw_rate_std_rad_s.to_degrees(),
        };
        let now = tracker.filter().scaled_view().over(c);
        let judged = self.aid.mounting() != Mounting::Unknown;
        if let Some(z) = self.aid.push_odometry(sample, now) {
            let before = tracker.filter().estimate();
            // Back on the gyro axis: y and w times c, r times c^2; the scale is the same.
            let z = Measurement {
                y: c * z.y,
                w: c * z.w,
                r: c * c * z.r,
            };
            if tracker.update_in_motion(z) {
                self.learnt += 1;
                self.bias_learnt += tracker.filter().estimate() - before;
            }
        }
        if !judged {
            if let Some(why) = self.mounting_refused() {
                eprintln!("driftless: predict.bias: {why}");
            }
        }
    }

    /// Why the yaw rate is refused, once the mounting check found it does not turn with the
    /// `vehicle_up` axis; the fix named.
    fn mounting_refused(&self) -> Option<String> {
        let (axis, sign) = self.up?;
        // The words are built only for the one line said: this runs at each message until the
        // verdict.
        let up = || up_word(axis, sign);
        match self.aid.mounting() {
            Mounting::WrongSign { slope } => {
                let other = up_word(axis, -sign);
                Some(format!(
                    "the yaw rate turns against the gyro's {} axis (slope {slope:+.2} over the \
                     first turns): one of the two has the other sign. The yaw rate is refused \
                     from now on. If the gyro's {other} points up, set vehicle_up = \"{other}\"; \
                     else the odometry's yaw rate must be counter-clockwise seen from above \
                     (ROS's angular.z)",
                    up()
                ))
            }
            Mounting::WrongAxis { slope } => Some(format!(
                "the gyro's {} axis does not see the odometry's turns (slope {slope:+.2} over \
                 the first turns): the vehicle's up is another axis. The yaw rate is refused \
                 from now on. Set vehicle_up to the gyro axis that points up",
                up()
            )),
            Mounting::Unknown | Mounting::Confirmed { .. } => None,
        }
    }

    /// The up's words: the axis, the mount's, or gravity's (and whether told yet).
    fn up_text(&self) -> String {
        match (self.configured, self.up) {
            (VehicleUp::Axis { axis, sign }, _) => format!("vehicle_up = {}", up_word(axis, sign)),
            (VehicleUp::Mount { axis, c }, _) => format!(
                "{} from mount, {:.1} deg from it",
                up_word(axis, c),
                tilt_deg(c)
            ),
            (VehicleUp::Gravity, Some((axis, c))) => format!(
                "vehicle_up = {} from gravity, {:.1} deg from it",
                up_word(axis, c),
                tilt_deg(c)
            ),
            (VehicleUp::Gravity, None) => {
                "vehicle_up = gravity, not told (no rest with the accelerometer)".into()
            }
        }
    }

    /// What gravity said of the mounting, for the summary.
    fn gravity_text(&self) -> &'static str {
        match (self.gravity.verdict(), self.gravity_refused) {
            (None, _) => "gravity: not judged",
            (Some(GravityUp::Axis { .. }), false) if self.configured == VehicleUp::Gravity => {
                "gravity: named it"
            }
            (Some(_), true) => "gravity: refused",
            (Some(GravityUp::Tilted { .. }), false) => "gravity: tilted, no check",
            (Some(GravityUp::Axis { .. }), false) => "gravity: agrees",
        }
    }

    /// What it did, for the stats service.
    pub(crate) fn stats(&self) -> OdometryStats {
        let d = self.aid.diagnostics();
        let mounting = match (self.gravity_refused, self.gravity.verdict(), self.up) {
            (true, Some(GravityUp::Axis { axis, .. }), Some((up, _))) if axis == up => {
                MOUNTING_WRONG_SIGN
            }
            (true, _, _) => MOUNTING_WRONG_AXIS,
            _ => match self.aid.mounting() {
                Mounting::Unknown => MOUNTING_UNKNOWN,
                Mounting::Confirmed { .. } => MOUNTING_CONFIRMED,
                Mounting::WrongSign { .. } => MOUNTING_WRONG_SIGN,
                Mounting::WrongAxis { .. } => MOUNTING_WRONG_AXIS,
            },
        };
        OdometryStats {
            up: self.up.map_or(UP_GRAVITY_PENDING, |(axis, sign)| {
                OdometryStats::up_code(axis, sign)
            }),
            mounting,
            spans_accepted: d.accepted,
            spans_rejected: d.rejected,
            slips: d.slips,
            learnt: self.learnt,
            scale: d.scale,
            scale_sd: d.scale_sd,
            bias_learnt_rad_s: self.bias_learnt.to_radians(),
        }
    }

    /// The summary line of what it did.
    pub(crate) fn learnt(&self) -> String {
        let d = self.aid.diagnostics();
        let mounting = if self.gravity_refused {
            "refused: gravity disagreed".to_string()
        } else {
            match self.aid.mounting() {
                Mounting::Unknown => "not judged by the turns (too little turning)".to_string(),
                Mounting::Confirmed { slope } => {
                    format!("confirmed by the turns (slope {slope:.2})")
                }
                Mounting::WrongSign { .. } | Mounting::WrongAxis { .. } => {
                    "refused: it did not turn with the gyro".to_string()
                }
            }
        };
        format!(
            "odometry ({}, {mounting}, {}): {} spans accepted ({} taught the \
             filter), {} rejected in {} slips (longest {} spans), {} messages unmatched; \
             odometry scale {:+.2} % +- {:.2} %",
            self.up_text(),
            self.gravity_text(),
            d.accepted,
            self.learnt,
            d.rejected,
            d.slips,
            d.longest_run,
            d.unmatched,
            d.scale * 100.0,
            d.scale_sd * 100.0
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vehicle driving at 200 Hz with the gyro's up its -z (bias 0.5 deg/s), its odometry
    /// at 50 Hz without a period (taken from the stamps); `stands`: it stands still, and says so.
    fn drive(stands: bool) -> (BiasTracker, Odometry) {
        let minus_z = VehicleUp::Axis {
            axis: 2,
            sign: -1.0,
        };
        drive_mounted(stands, minus_z, -1.0)
    }

    /// [`drive`], the gyro's z reading `c` times the yaw rate, the odometry told `up`.
    fn drive_mounted(stands: bool, up: VehicleUp, c: f64) -> (BiasTracker, Odometry) {
        let rate = 200.0;
        let mut tracker = BiasTracker::for_profile("adis16405", rate).unwrap();
        let r_gyro = tracker.filter().model().measurement_variance();
        let mut odo = Odometry::new(up, [r_gyro; 3], rate).unwrap();
        // As the stage builds it: the tracker carries the scale from the start.
        tracker.add_scale(odo.scale_prior());
        for i in 0..2000u64 {
            let turn = if stands {
                0.0
            } else {
                [0.0, 12.0, -6.0][(i / 300 % 3) as usize]
            };
            let x = 0.5 + c * turn + 0.2 * ((i * 7919 % 101) as f64 / 101.0 - 0.5);
            let t_ns = 1_000_000_000 + i * 5_000_000;
            tracker.push_signal_with(x, Some(stands), crate::drift::stillness::Aid::Unknown);
            let mut m = StopSignal::new(t_ns, 2.0, u32::from(stands));
            m.yaw_rate_rad_s = turn.to_radians();
            let message = (i % 4 == 3).then_some(&m);
            odo.push(&mut tracker, x, (t_ns, 0), message);
        }
        (tracker, odo)
    }

    #[test]
    fn the_yaw_rate_teaches_the_up_axis_with_its_sign_while_moving_only() {
        let (tracker, odo) = drive(false);
        let d = odo.aid.diagnostics();
        assert!(odo.learnt > 5 && d.accepted > 5, "{d:?}");
        let b = tracker.filter().estimate();
        assert!((b - 0.5).abs() < 0.1, "bias {b}, {d:?}");
        assert!(odo.learnt().contains("vehicle_up = -z"), "{}", odo.learnt());
        // At a stop the odometry teaches nothing (the stop does).
        let (_, odo) = drive(true);
        assert_eq!(odo.learnt, 0);
        assert_eq!(odo.aid.diagnostics().accepted, 0);
    }

    /// Tilted 25 deg, upside down: the mount's share of the yaw rate on -z teaches the bias in
    /// turns and straights alike. Told only the axis, the turns' missing 9 % looks like slip:
    /// they are rejected, and only the straights teach.
    #[test]
    fn a_mounts_share_of_the_yaw_rate_teaches_a_tilted_axis_in_turns_too() {
        let c = -(25f64.to_radians().cos());
        let (tracker, odo) = drive_mounted(false, VehicleUp::Mount { axis: 2, c }, c);
        let b = tracker.filter().estimate();
        let d = odo.aid.diagnostics();
        assert!((b - 0.5).abs() < 0.05, "bias {b}: {}", odo.learnt());
        assert!(d.accepted > 15 && d.rejected == 0, "{}", odo.learnt());
        assert!(d.scale.abs() < 0.005, "{}", odo.learnt());
        assert!(
            odo.learnt().contains("-z from mount, 25.0 deg from it"),
            "{}",
            odo.learnt()
        );
        let minus_z = VehicleUp::Axis {
            axis: 2,
            sign: -1.0,
        };
        let (_, odo) = drive_mounted(false, minus_z, c);
        let d = odo.aid.diagnostics();
        assert!(d.rejected > d.accepted, "{}", odo.learnt());
    }

    #[test]
    fn gravity_names_checks_or_cannot_check_the_up_axis() {
        let at_rest = |up: VehicleUp, f: [f64; 3]| {
            let mut o = Odometry::new(up, [1e-2; 3], 100.0).unwrap();
            for _ in 0..100 {
                o.at_rest(f);
            }
            o
        };
        let minus_z = VehicleUp::Axis {
            axis: 2,
            sign: -1.0,
        };
        let down = [0.1, 0.0, -9.8];
        let tilted = [6.9, 0.0, 6.9];
        // Named: -z, and no longer pending in the stats.
        let o = at_rest(VehicleUp::Gravity, down);
        let (axis, c) = o.up.unwrap();
        // The up's share along -z: the cosine of its 0.6 deg tilt.
        assert_eq!((axis, o.gravity_refused), (2, false));
        assert!(
            (c + 9.8 / (0.01f64 + 9.8 * 9.8).sqrt()).abs() < 1e-12,
            "{c}"
        );
        assert_eq!(o.stats().up_name(), "-z");
        assert_eq!(
            Odometry::new(VehicleUp::Gravity, [1e-2; 3], 100.0)
                .unwrap()
                .stats()
                .up,
            UP_GRAVITY_PENDING
        );
        // Checked: agrees, or refuses (the sign, or the axis).
        assert!(!at_rest(minus_z, down).gravity_refused);
        let o = at_rest(VehicleUp::Axis { axis: 2, sign: 1.0 }, down);
        assert!(o.gravity_refused);
        assert_eq!(o.stats().mounting, MOUNTING_WRONG_SIGN);
        let o = at_rest(VehicleUp::Axis { axis: 0, sign: 1.0 }, down);
        assert_eq!(o.stats().mounting, MOUNTING_WRONG_AXIS);
        // Tilted 45 deg: a configured axis is left to the turns; "gravity" is refused.
        assert!(!at_rest(minus_z, tilted).gravity_refused);
        let o = at_rest(VehicleUp::Gravity, tilted);
        assert!(o.gravity_refused && o.up.is_none());
        assert_eq!(o.stats().mounting, MOUNTING_WRONG_AXIS);
    }
}
