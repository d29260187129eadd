//! The heading from the magnetometer (9D) on top of the 6D attitude: pure maths, no I/O.
//!
//! The 6D filter's earth frame is ENU turned about the vertical by a slowly drifting angle
//! (its heading is the integrated gyro's). This filter estimates that angle, `delta`, from the
//! magnetometer: the heading is then `Rz(delta) (x) q_6d`, absolute (magnetic north, or true
//! north with [`MagConfig::declination`]).
//!
//! - **A two-state Kalman filter**: `delta` and its drift rate (what the 6D heading drifts by:
//!   the rate's bias about the vertical that no stop showed, about 0.05 deg/s on BROAD). The
//!   drift rate is a random walk ([`MagConfig::drift_walk`]); the gyro's white noise and a
//!   scale-factor error ([`MagConfig::scale_error`] times the rate) add to `delta`'s variance.
//!   Learning the drift is what lets a good gyro carry the heading through a disturbance, and
//!   makes the heading's uncertainty grow honestly while the magnetometer is not used.
//! - **Readings are gathered over short blocks** ([`MagConfig::block_s`]) in the 6D earth
//!   frame, and judged per block. A block's heading has white noise
//!   ([`MagConfig::heading_noise`]) and an error that persists for seconds (the field's own
//!   inhomogeneity, the inclination's error times tan(dip), soft iron:
//!   [`MagConfig::heading_sys`] over [`MagConfig::heading_sys_time_s`]); the second is why a
//!   block counts as little as it does.
//! - **Rejection.** A block is used only if the field's norm and dip lie within
//!   [`MagConfig::norm_tolerance`] and [`MagConfig::dip_tolerance`] of the reference learnt
//!   from used blocks, if the field stayed constant in the earth frame over the last
//!   [`MagConfig::spread_time_s`] (a magnet moving with the sensor, or one the sensor moves
//!   past, makes it turn with the body: [`MagConfig::spread_tolerance`]), if it has been so for
//!   [`MagConfig::settle_s`], and if its heading agrees with the gyro-propagated one within
//!   [`MagConfig::gate`] standard deviations of both. Otherwise the heading rests on the gyro,
//!   and its standard deviation grows. No NaN ever: a reading that is absent, not finite, zero
//!   or beyond [`super::MAX_READING`] is not used, and says so ([`MagUse`]).
//! - **Hard iron, online** ([`super::hard_iron`]): when the field is not constant with the
//!   current offset, the long window restarts (a magnet came or went); once the rotation in
//!   it showed the offset well enough ([`MagConfig::min_diversity`],
//!   [`MagConfig::max_offset_sd`]) and the field with it matches the reference, the offset is
//!   taken. A block that fits the reference better with no offset drops it again (the magnet
//!   went away while the sensor was still).
//! - **The magnetometer's delay** behind the gyro (filters in the sensor: 12-14 ms on BROAD's
//!   unit) turns the field in the earth frame by the rate times the delay. Each reading is
//!   turned forward by it, `m - delay (w x m)`, and the delay is estimated online from what is
//!   left, by least squares on the used blocks ([`MagConfig::delay`] fixes it instead).

use super::hard_iron::{cross, dot, mat_vec, rotation, Mat3, Sums};
use super::mag_cal::check_soft_iron;
use super::MAX_READING;

/// What the filter learnt of the magnetometer that outlives a run (`attitude.6d`'s
/// `state_file`): the hard iron and the reference field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagLearnt {
    /// The hard-iron offset in use, of readings after [`MagConfig::soft_iron`].
    pub hard_iron: [f64; 3],
    /// Its standard deviation when it was last taken from a fit (None: never learnt here).
    pub hard_iron_sd: Option<f64>,
    /// The reference field's norm (readings' units) and dip (rad), once learnt.
    pub reference: Option<(f64, f64)>,
}

/// Settings of the magnetometer's heading filter (angles in rad, times in s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagConfig {
    /// Magnetic declination, east of north positive: the heading is then from true north
    /// (the ENU yaw turns by minus it).
    pub declination: f64,
    /// A block is disturbed if its field's norm is off the reference by more than this
    /// fraction (VQF's `magNormTh`).
    pub norm_tolerance: f64,
    /// ... or its dip by more than this (VQF's `magDipTh`).
    pub dip_tolerance: f64,
    /// ... or the field's spread in the earth frame over [`MagConfig::spread_time_s`] is over
    /// this fraction of it.
    pub spread_tolerance: f64,
    /// The spread's window.
    pub spread_time_s: f64,
    /// How long a block must have passed those tests before it is used again.
    pub settle_s: f64,
    /// The reference's low-pass, from used blocks.
    pub reference_time_s: f64,
    /// Innovation gate, standard deviations.
    pub gate: f64,
    /// A reading's heading noise (white).
    pub heading_noise: f64,
    /// The error of the magnetometer's heading that persists ...
    pub heading_sys: f64,
    /// ... for about this long.
    pub heading_sys_time_s: f64,
    /// The field's direction is known to this (the site's field, the declination): added to
    /// the published standard deviation.
    pub heading_floor: f64,
    /// The drift rate's standard deviation when the heading is first fixed, rad/s.
    pub drift_sd: f64,
    /// The drift rate's random walk, rad/s/sqrt(s).
    pub drift_walk: f64,
    /// The gyro's scale-factor error: the rate times it adds to the heading's noise ...
    pub scale_error: f64,
    /// ... correlated over this long.
    pub scale_time_s: f64,
    /// The delay's uncertainty left after compensation: the rate times it adds to a block's
    /// heading noise.
    pub residual_delay_s: f64,
    /// Learn the hard-iron offset online.
    pub hard_iron: bool,
    /// The offset's window.
    pub hard_iron_time_s: f64,
    /// The least rotation diversity (least eigenvalue of `M / n`) to take an offset.
    pub min_diversity: f64,
    /// The largest standard deviation of an offset taken, as a fraction of the field.
    pub max_offset_sd: f64,
    /// How much of the way to a new offset one block goes.
    pub offset_gain: f64,
    /// The magnetometer's delay behind the gyro, s; None: estimated online.
    pub delay: Option<f64>,
    /// The delay estimate's prior standard deviation, s, ...
    pub delay_sd: f64,
    /// ... its window ...
    pub delay_time_s: f64,
    /// ... and its bounds, 0 to this, s.
    pub max_delay_s: f64,
    /// A reading's noise, as a fraction of the field (for the delay's least squares).
    pub reading_noise: f64,
    /// The block over which readings are gathered.
    pub block_s: f64,
    /// The soft iron `W` of a calibration (`driftless mag-cal`), applied to every reading
    /// before anything else: the filter sees `W m`. None: the identity.
    pub soft_iron: Option<Mat3>,
    /// The hard-iron offset the filter starts from, of readings after `soft_iron` (`W b` for a
    /// calibration's `b`); learnt on from there with [`MagConfig::hard_iron`], kept without.
    pub hard_iron_start: [f64; 3],
}

impl Default for MagConfig {
    /// The settings measured on BROAD's undisturbed trials (docs/attitude.md), VQF's norm and
    /// dip thresholds.
    fn default() -> Self {
        MagConfig {
            declination: 0.0,
            norm_tolerance: 0.1,
            dip_tolerance: 10f64.to_radians(),
            spread_tolerance: 0.08,
            spread_time_s: 1.0,
            settle_s: 2.0,
            reference_time_s: 30.0,
            gate: 3.0,
            heading_noise: 4f64.to_radians(),
            heading_sys: 1.5f64.to_radians(),
            heading_sys_time_s: 8.0,
            heading_floor: 1f64.to_radians(),
            drift_sd: 0.02f64.to_radians(),
            drift_walk: 0.003f64.to_radians(),
            scale_error: 0.001,
            scale_time_s: 1.0,
            residual_delay_s: 0.005,
            hard_iron: true,
            hard_iron_time_s: 30.0,
            min_diversity: 0.15,
            max_offset_sd: 0.02,
            offset_gain: 0.5,
            delay: None,
            delay_sd: 0.02,
            delay_time_s: 60.0,
            max_delay_s: 0.1,
            reading_noise: 0.03,
            block_s: 0.025,
            soft_iron: None,
            hard_iron_start: [0.0; 3],
        }
    }
}

impl MagConfig {
    /// Check ranges: every number finite; times, tolerances and noises > 0; the rest >= 0.
    pub fn check(&self) -> Result<(), String> {
        let positive = [
            ("norm_tolerance", self.norm_tolerance),
            ("dip_tolerance", self.dip_tolerance),
            ("spread_tolerance", self.spread_tolerance),
            ("spread_time_s", self.spread_time_s),
            ("reference_time_s", self.reference_time_s),
            ("gate", self.gate),
            ("heading_noise", self.heading_noise),
            ("heading_sys", self.heading_sys),
            ("heading_sys_time_s", self.heading_sys_time_s),
            ("hard_iron_time_s", self.hard_iron_time_s),
            ("delay_sd", self.delay_sd),
            ("delay_time_s", self.delay_time_s),
            ("reading_noise", self.reading_noise),
            ("block_s", self.block_s),
        ];
        let non_negative = [
            ("settle_s", self.settle_s),
            ("heading_floor", self.heading_floor),
            ("drift_sd", self.drift_sd),
            ("drift_walk", self.drift_walk),
            ("scale_error", self.scale_error),
            ("scale_time_s", self.scale_time_s),
            ("residual_delay_s", self.residual_delay_s),
            ("min_diversity", self.min_diversity),
            ("max_offset_sd", self.max_offset_sd),
            ("offset_gain", self.offset_gain),
            ("max_delay_s", self.max_delay_s),
            ("delay", self.delay.unwrap_or(0.0)),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!(
                    "attitude: mag {name} must be a number > 0, not {v}"
                ));
            }
        }
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!(
                    "attitude: mag {name} must be a number >= 0, not {v}"
                ));
            }
        }
        if !self.declination.is_finite() {
            return Err("attitude: declination must be a number".into());
        }
        if let Some(w) = &self.soft_iron {
            check_soft_iron(w).map_err(|e| format!("attitude: mag soft iron {e}"))?;
        }
        if !self.hard_iron_start.iter().all(|v| v.is_finite()) {
            return Err("attitude: mag hard iron must hold finite numbers".into());
        }
        Ok(())
    }
}

/// What became of the magnetometer at a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MagUse {
    /// The sample carries no reading.
    Absent,
    /// Its reading is not finite, zero, or beyond [`super::MAX_READING`].
    Invalid,
    /// The field's norm, dip or constancy left the learnt reference: a disturbance.
    Disturbed,
    /// The field passed those tests but not for [`MagConfig::settle_s`] yet.
    Settling,
    /// Its heading disagreed with the gyro's beyond both uncertainties.
    Inconsistent,
    /// It corrected the heading (the last block's verdict, until the next).
    Used,
}

/// One sample's heading from the magnetometer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagStep {
    /// The angle to turn the 6D attitude by about the vertical, rad (the declination
    /// included); None until the magnetometer fixed the heading once (it stays relative).
    pub offset: Option<f64>,
    /// The absolute heading's standard deviation, rad, when `offset` is given.
    pub sd: Option<f64>,
    /// What became of the magnetometer.
    pub state: MagUse,
}

/// The block being gathered: the hard-iron sums and the delay's.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Block {
    sums: Sums,
    /// Sum of `C (w x m)`, of `|w x m|^2`, and of `C (w x m) . C m`, the reading turned forward.
    u: [f64; 3],
    uu: f64,
    uv: f64,
    /// The largest rate in the block, rad/s.
    rate_max: f64,
    /// Samples in the block, with a reading or not; and whether one was invalid.
    samples: usize,
    invalid: bool,
}

/// The magnetometer's heading filter of one IMU (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct MagHeading {
    cfg: MagConfig,
    dt: f64,
    /// The gyro's angle random walk, rad/sqrt(s).
    arw: f64,
    block_len: usize,
    block: Block,
    short: Sums,
    long: Sums,
    /// The hard-iron offset in use, the readings' units, and its sd when it came from a fit.
    offset: [f64; 3],
    offset_sd: Option<f64>,
    /// The reference came from a saved state: the first block checks it (the sensor may have
    /// moved to another place since).
    reference_resumed: bool,
    /// The heading offset and its drift rate, rad and rad/s, their covariance (dd, dr, rr),
    /// and whether the heading was fixed once.
    delta: f64,
    drift: f64,
    p: [f64; 3],
    absolute: bool,
    /// Time since the last block ended, s.
    since: f64,
    /// The reference field: norm (readings' units) and dip (rad).
    reference: Option<(f64, f64)>,
    /// How long blocks have passed the field's tests, s; whether the last one's spread did.
    ok_for: f64,
    spread_was_ok: bool,
    /// The delay, s, and its information (1/s²).
    delay: f64,
    delay_info: f64,
    verdict: MagUse,
}

/// `a` wrapped into -pi..pi.
fn wrap(a: f64) -> f64 {
    a.sin().atan2(a.cos())
}

/// Norm and dip (rad, positive down) of a field in the earth frame (z up).
fn norm_dip(f: &[f64; 3]) -> (f64, f64) {
    let horizontal = f[0].hypot(f[1]);
    (dot(f, f).sqrt(), (-f[2]).atan2(horizontal))
}

impl MagHeading {
    /// A filter for samples `dt` s apart, of settings already checked, and a gyro of angle
    /// random walk `arw` (rad/sqrt(s)).
    pub fn new(dt: f64, cfg: MagConfig, arw: f64) -> Self {
        let block_len = ((cfg.block_s / dt).round() as usize).max(1);
        MagHeading {
            cfg,
            dt,
            arw,
            block_len,
            block: Block::default(),
            short: Sums::default(),
            long: Sums::default(),
            offset: cfg.hard_iron_start,
            offset_sd: None,
            reference_resumed: false,
            delta: 0.0,
            drift: 0.0,
            p: [0.0, 0.0, cfg.drift_sd * cfg.drift_sd],
            absolute: false,
            since: 0.0,
            reference: None,
            ok_for: 0.0,
            spread_was_ok: true,
            delay: cfg.delay.unwrap_or(0.0),
            delay_info: 0.0,
            verdict: MagUse::Absent,
        }
    }

    /// The hard-iron offset in use (the readings' units).
    pub fn hard_iron(&self) -> [f64; 3] {
        self.offset
    }

    /// What outlives a run: the hard iron, its sd and the reference field.
    pub fn learnt(&self) -> MagLearnt {
        MagLearnt {
            hard_iron: self.offset,
            hard_iron_sd: self.offset_sd,
            reference: self.reference,
        }
    }

    /// Start from what a previous run learnt (a filter of the same settings): its offset, and
    /// its reference field until the first block with readings disagrees with it.
    pub fn resume(&mut self, saved: &MagLearnt) {
        self.offset = saved.hard_iron;
        self.offset_sd = saved.hard_iron_sd;
        self.reference = saved.reference;
        self.reference_resumed = saved.reference.is_some();
    }

    /// The magnetometer's delay behind the gyro in use, s.
    pub fn delay(&self) -> f64 {
        self.delay
    }

    /// One sample: the 6D attitude `q6` (w, x, y, z), the body rate (rad/s; None if it was
    /// not usable) and the magnetometer's reading (any unit; None if the sample has none).
    pub fn push(&mut self, q6: [f64; 4], rate: Option<[f64; 3]>, mag: Option<[f64; 3]>) -> MagStep {
        let mag = match &self.cfg.soft_iron {
            Some(w) => mag.map(|m| mat_vec(w, &m)),
            None => mag,
        };
        // What this sample's reading is, if it cannot be used; else the last block's verdict.
        let unusable = match (mag, rate) {
            (None, _) => Some(MagUse::Absent),
            (Some(m), Some(w)) if dot(&m, &m).sqrt() <= MAX_READING && dot(&m, &m) > 0.0 => {
                self.gather(q6, w, m);
                None
            }
            // Not finite, zero, too large; or no usable rate to turn it into the earth frame.
            (Some(_), _) => {
                self.block.invalid = true;
                Some(MagUse::Invalid)
            }
        };
        if let Some(w) = rate.filter(|w| dot(w, w).sqrt() <= MAX_READING) {
            self.block.rate_max = self.block.rate_max.max(dot(&w, &w).sqrt());
        }
        self.block.samples += 1;
        if self.block.samples >= self.block_len {
            self.end_block();
            self.since = 0.0;
        } else {
            self.since += self.dt;
        }
        let s = self.since;
        let [pdd, pdr, prr] = self.p;
        let var = pdd + 2.0 * s * pdr + s * s * prr;
        MagStep {
            offset: self
                .absolute
                .then(|| wrap(self.delta + self.drift * s - self.cfg.declination)),
            sd: self
                .absolute
                .then(|| (var.max(0.0) + self.cfg.heading_floor * self.cfg.heading_floor).sqrt()),
            state: unusable.unwrap_or(self.verdict),
        }
    }

    /// One valid reading into the block, turned forward by the delay, in the 6D earth frame.
    fn gather(&mut self, q6: [f64; 4], w: [f64; 3], m: [f64; 3]) {
        let c = rotation(q6);
        // The body sees a fixed earth vector turn by -w: m(t) = m(t - delay) - delay (w x m).
        let wxm = cross(&w, &m);
        let mc = [0, 1, 2].map(|i| m[i] - self.delay * wxm[i]);
        let cm = mat_vec(&c, &mc);
        let u = mat_vec(&c, &wxm);
        let b = &mut self.block;
        b.sums.add_reading(&c, &mc, &cm);
        for (sum, add) in b.u.iter_mut().zip(u) {
            *sum += add;
        }
        b.uu += dot(&wxm, &wxm);
        b.uv += dot(&u, &cm);
    }

    /// The Kalman filter's prediction over `t` s, the rate up to `rate_max`.
    fn predict(&mut self, t: f64, rate_max: f64) {
        let c = &self.cfg;
        self.delta += self.drift * t;
        let [dd, dr, rr] = self.p;
        let scale = c.scale_error * rate_max;
        let q = (self.arw * self.arw + scale * scale * c.scale_time_s) * t;
        self.p = [
            dd + 2.0 * t * dr + t * t * rr + q,
            dr + t * rr,
            rr + c.drift_walk * c.drift_walk * t,
        ];
    }

    /// The block judged and used: the heart of the filter (see the module documentation).
    fn end_block(&mut self) {
        let block = std::mem::take(&mut self.block);
        let t = block.samples as f64 * self.dt;
        self.predict(t, block.rate_max);
        let n = block.sums.n;
        if n <= 0.0 {
            self.verdict = if block.invalid {
                MagUse::Invalid
            } else {
                MagUse::Absent
            };
            return;
        }
        let c = self.cfg;
        self.short.fade((-t / c.spread_time_s).exp());
        self.short.add(&block.sums);
        self.long.fade((-t / c.hard_iron_time_s).exp());
        self.long.add(&block.sums);
        let mut field = block.sums.field(&self.offset);
        self.drop_a_gone_offset(&block, &mut field);
        let (norm, dip) = norm_dip(&field);
        if std::mem::take(&mut self.reference_resumed) && !self.matches(norm, dip) {
            // A saved reference this place's field does not match: learnt afresh.
            self.reference = None;
        }
        let mut ok = norm > 0.0 && norm.is_finite();
        if let (true, Some((ref_norm, _))) = (ok, self.reference) {
            let spread_ok = self.short.spread(&self.offset).sqrt() / ref_norm < c.spread_tolerance;
            ok = spread_ok && self.matches(norm, dip);
            if !spread_ok && c.hard_iron {
                // The field turns with the body under this offset: a magnet came or went. The
                // offset's window starts again from the last second's, once when it begins, and
                // again whenever no one offset explains the window (it changed once more).
                let mixed = self
                    .long
                    .fit()
                    .is_some_and(|f| f.residual.sqrt() / ref_norm >= c.spread_tolerance);
                if self.spread_was_ok || mixed {
                    self.long = self.short;
                }
            }
            self.spread_was_ok = spread_ok;
        }
        self.learn_offset();
        self.ok_for = if ok { self.ok_for + t } else { 0.0 };
        self.verdict = if !ok {
            MagUse::Disturbed
        } else if self.reference.is_some() && self.ok_for < c.settle_s {
            MagUse::Settling
        } else {
            self.correct(&block, field, norm, dip, t)
        };
    }

    /// Norm and dip within the tolerances of the reference (true without one).
    fn matches(&self, norm: f64, dip: f64) -> bool {
        self.reference.is_none_or(|(rn, rd)| {
            (norm / rn - 1.0).abs() < self.cfg.norm_tolerance
                && (dip - rd).abs() < self.cfg.dip_tolerance
        })
    }

    /// With an offset in use, a block whose field with none fits the reference better, and
    /// is constant without it, says the magnet went away (while the sensor was still, where
    /// the spread cannot tell): the offset is dropped and its window restarts.
    fn drop_a_gone_offset(&mut self, block: &Block, field: &mut [f64; 3]) {
        let Some((rn, rd)) = self.reference else {
            return;
        };
        if dot(&self.offset, &self.offset) == 0.0 {
            return;
        }
        let miss = |f: &[f64; 3]| {
            let (n, d) = norm_dip(f);
            ((n / rn - 1.0) / self.cfg.norm_tolerance).powi(2)
                + ((d - rd) / self.cfg.dip_tolerance).powi(2)
        };
        let bare = block.sums.field(&[0.0; 3]);
        if miss(&bare) < miss(field)
            && self.short.spread(&[0.0; 3]).sqrt() / rn < self.cfg.spread_tolerance
        {
            self.offset = [0.0; 3];
            self.offset_sd = None;
            *field = bare;
            self.long = self.short;
        }
    }

    /// The long window's hard-iron fit taken (part of the way) when the rotation showed it,
    /// it explains the readings better than the offset in use, and the field with it matches
    /// the reference.
    fn learn_offset(&mut self) {
        let c = &self.cfg;
        let (true, Some((rn, _))) = (c.hard_iron, self.reference) else {
            return;
        };
        let Some(fit) = self.long.fit() else {
            return;
        };
        // Better than the offset in use by more than chance over the window (3 sd, 6
        // parameters).
        let better = self.long.spread(&self.offset) > fit.residual * (1.0 + 54.0 / self.long.n);
        if fit.diversity > c.min_diversity && fit.sd < c.max_offset_sd * rn && better {
            let (norm, dip) = norm_dip(&self.long.field(&fit.b));
            if self.matches(norm, dip) {
                let gain = c.offset_gain;
                for i in 0..3 {
                    self.offset[i] += gain * (fit.b[i] - self.offset[i]);
                }
                self.offset_sd = Some(fit.sd);
            }
        }
    }

    /// The block's heading into the Kalman filter (or fixing it, the first time), gated by
    /// the innovation; then the delay and the reference learn from it.
    fn correct(&mut self, block: &Block, field: [f64; 3], norm: f64, dip: f64, t: f64) -> MagUse {
        let c = self.cfg;
        let n = block.sums.n;
        let measured = field[0].atan2(field[1]);
        let lag = c.residual_delay_s * block.rate_max;
        let persistent = c.heading_sys * c.heading_sys * (c.heading_sys_time_s / t).max(1.0);
        let r = c.heading_noise * c.heading_noise / n + persistent + lag * lag;
        if !self.absolute {
            self.delta = measured;
            self.drift = 0.0;
            self.p = [r, 0.0, c.drift_sd * c.drift_sd];
            self.absolute = true;
        } else {
            let innovation = wrap(measured - self.delta);
            let [dd, dr, rr] = self.p;
            let s = dd + r;
            if innovation * innovation > c.gate * c.gate * s {
                return MagUse::Inconsistent;
            }
            let (k0, k1) = (dd / s, dr / s);
            self.delta = wrap(self.delta + k0 * innovation);
            self.drift += k1 * innovation;
            self.p = [dd - k0 * dd, dr - k0 * dr, rr - k1 * dr];
        }
        if c.delay.is_none() {
            self.learn_delay(block);
        }
        self.reference = Some(match self.reference {
            None => (norm, dip),
            Some((rn, rd)) => {
                let keep = (-t / c.reference_time_s).exp();
                (
                    keep * rn + (1.0 - keep) * norm,
                    keep * rd + (1.0 - keep) * dip,
                )
            }
        });
        MagUse::Used
    }

    /// Least squares of the delay left in a used block: the field the filter expects,
    /// `Rz(-delta) (0, H, -Z)`, against the readings turned forward; what is left along
    /// `C (w x m)` is the delay still missing.
    fn learn_delay(&mut self, block: &Block) {
        let Some((rn, rd)) = self.reference else {
            return;
        };
        let c = &self.cfg;
        let (h, z) = (rn * rd.cos(), rn * rd.sin());
        let expected = [h * self.delta.sin(), h * self.delta.cos(), -z];
        let n = block.sums.n;
        let cb = mat_vec(&block.sums.c, &self.offset);
        let left = block.uv - dot(&cb, &block.u) / n - dot(&expected, &block.u);
        let s2 = (c.reading_noise * rn).powi(2);
        let keep = (-(block.samples as f64) * self.dt / c.delay_time_s).exp();
        self.delay_info =
            (keep * self.delay_info).max(1.0 / (c.delay_sd * c.delay_sd)) + block.uu / s2;
        let step = (left / s2) / self.delay_info;
        if step.is_finite() {
            self.delay = (self.delay + step).clamp(0.0, c.max_delay_s);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RATE: f64 = 100.0;
    /// The earth's field, tesla: 20 uT north, 40 uT down (a dip of 63 deg).
    const FIELD: [f64; 3] = [0.0, 20e-6, -40e-6];

    fn mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        [
            a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
            a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
            a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
            a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
        ]
    }

    /// `C^T v`: an earth vector in the body at the attitude `q`.
    fn to_body(q: [f64; 4], v: &[f64; 3]) -> [f64; 3] {
        let c = rotation(q);
        [0, 1, 2].map(|i| (0..3).map(|j| c[j][i] * v[j]).sum())
    }

    /// A body turning about every axis (rad/s at time t): what a hand or a vehicle on rough
    /// ground shows the magnetometer.
    fn rate_at(t: f64) -> [f64; 3] {
        [
            0.8 * (0.5 * t).sin(),
            0.6 * (0.3 * t + 1.0).cos(),
            1.5 * (0.2 * t).sin(),
        ]
    }

    /// A small deterministic noise in -1..1 (no RNG needed).
    fn jitter(k: usize, axis: usize) -> f64 {
        ((k * 7919 + axis * 104_729) as f64 * 0.618_034).fract() * 2.0 - 1.0
    }

    /// Runs `secs` s of the turning body through a filter: the 6D attitude is the truth turned
    /// by `-delta0` about the vertical (what the 6D filter's relative heading is), the reading
    /// is the field in the body plus `extra(t, truth)` (tesla), with 0.3 uT of noise and
    /// `delay` s behind the gyro. Calls `each(t, step, truth)` at every sample.
    fn run(
        f: &mut MagHeading,
        secs: f64,
        delta0: f64,
        delay: f64,
        extra: impl Fn(f64, [f64; 4]) -> [f64; 3],
        mut each: impl FnMut(f64, MagStep),
    ) {
        let dt = 1.0 / RATE;
        let turn = [(-delta0 / 2.0).cos(), 0.0, 0.0, (-delta0 / 2.0).sin()];
        let mut truth = [1.0, 0.0, 0.0, 0.0];
        let mut past = std::collections::VecDeque::new();
        let lag = (delay / dt).round() as usize;
        for k in 0..(secs * RATE) as usize {
            let t = k as f64 * dt;
            let w = rate_at(t);
            past.push_back(truth);
            if past.len() > lag + 1 {
                past.pop_front();
            }
            let seen = past[0];
            let mut m = to_body(seen, &FIELD);
            let add = extra(t, seen);
            for (i, v) in m.iter_mut().enumerate() {
                *v += add[i] + 0.3e-6 * jitter(k, i);
            }
            each(t, f.push(mul(turn, truth), Some(w), Some(m)));
            let a = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt() * dt;
            if a > 0.0 {
                let s = (a / 2.0).sin() / (a / dt);
                truth = mul(truth, [(a / 2.0).cos(), w[0] * s, w[1] * s, w[2] * s]);
                let n = truth.iter().map(|v| v * v).sum::<f64>().sqrt();
                truth = truth.map(|v| v / n);
            }
        }
    }

    fn filter(cfg: MagConfig) -> MagHeading {
        MagHeading::new(1.0 / RATE, cfg, 0.005f64.to_radians())
    }

    fn off_deg(step: &MagStep, delta0: f64) -> f64 {
        wrap(step.offset.unwrap() - delta0).to_degrees()
    }

    /// A clean field: the heading offset of the 6D frame is found, the standard deviation
    /// covers the error, and the delay is learnt from the rotation.
    #[test]
    fn a_clean_field_fixes_the_heading_and_learns_the_delay() {
        let delta0 = 0.7;
        let mut f = filter(MagConfig::default());
        let mut last = None;
        run(
            &mut f,
            60.0,
            delta0,
            0.02,
            |_, _| [0.0; 3],
            |_, s| last = Some(s),
        );
        let s = last.unwrap();
        assert_eq!(s.state, MagUse::Used);
        let err = off_deg(&s, delta0);
        assert!(err.abs() < 1.0, "{err} deg");
        assert!(s.sd.unwrap().to_degrees() > err.abs() / 2.0, "{s:?}");
        assert!((f.delay() - 0.02).abs() < 0.004, "delay {}", f.delay());
        assert_eq!(f.hard_iron(), [0.0; 3]);
    }

    /// Soft and hard iron from the start (steel that stretches the field 8% along x, a
    /// magnet): without a calibration the field turns with the body and is rejected; with
    /// `mag-cal`'s (the filter sees `W m`, starts from `W b`, learns nothing) it is used and
    /// the heading is right; a saved state resumes the offset and the reference.
    #[test]
    fn a_calibration_is_applied_before_the_filter() {
        let delta0 = 1.0;
        let b = [9e-6, -6e-6, 5e-6];
        let soft_inv = [[1.08, 0.03, 0.0], [0.03, 0.95, 0.0], [0.0, 0.0, 1.0]];
        let distort = |_: f64, seen: [f64; 4]| {
            let h = to_body(seen, &FIELD);
            let m = mat_vec(&soft_inv, &h);
            [0, 1, 2].map(|i| m[i] - h[i] + b[i])
        };
        let w = nalgebra::Matrix3::from_fn(|i, j| soft_inv[i][j])
            .try_inverse()
            .unwrap();
        let w: Mat3 = [0, 1, 2].map(|i| [0, 1, 2].map(|j| w[(i, j)]));
        let calibrated = MagConfig {
            hard_iron: false,
            soft_iron: Some(w),
            hard_iron_start: mat_vec(&w, &b),
            ..MagConfig::default()
        };
        let bare = MagConfig {
            hard_iron: false,
            ..MagConfig::default()
        };
        let mut used = [0; 2];
        let mut worst = 0.0f64;
        for (k, cfg) in [bare, calibrated].into_iter().enumerate() {
            let mut f = filter(cfg);
            run(&mut f, 40.0, delta0, 0.0, distort, |t, s| {
                if t > 10.0 && s.state == MagUse::Used {
                    used[k] += 1;
                    if k == 1 {
                        worst = worst.max(off_deg(&s, delta0).abs());
                    }
                }
            });
            if k == 1 {
                let learnt = f.learnt();
                let (norm, _) = learnt.reference.unwrap();
                assert!(
                    (norm / dot(&FIELD, &FIELD).sqrt() - 1.0).abs() < 0.02,
                    "{learnt:?}"
                );
                let mut again = filter(cfg);
                again.resume(&learnt);
                assert_eq!(again.learnt(), learnt);
            }
        }
        assert!(used[1] > 2500 && used[0] < used[1] / 2, "{used:?}");
        assert!(worst < 2.0, "heading off by {worst} deg");
    }

    /// A magnet fixed to the sensor from 20 s on (a hard-iron offset of 12 uT): rejected at
    /// once, the heading rests on the gyro meanwhile, and the rotation teaches the offset, so
    /// the magnetometer is used again with it.
    #[test]
    fn a_magnet_attached_mid_run_is_learnt_as_hard_iron() {
        let delta0 = -2.0;
        let b = [9e-6, -6e-6, 5e-6];
        let mut f = filter(MagConfig::default());
        let (mut worst, mut rejected, mut used_late) = (0.0f64, 0, 0);
        run(
            &mut f,
            90.0,
            delta0,
            0.0,
            |t, _| if t >= 20.0 { b } else { [0.0; 3] },
            |t, s| {
                if t > 10.0 {
                    worst = worst.max(off_deg(&s, delta0).abs());
                }
                if (20.0..25.0).contains(&t) && s.state != MagUse::Used {
                    rejected += 1;
                }
                if t > 70.0 && s.state == MagUse::Used {
                    used_late += 1;
                }
            },
        );
        assert!(worst < 2.0, "heading off by {worst} deg");
        assert!(
            rejected > 400,
            "{rejected} of 500 samples rejected after it came"
        );
        assert!(
            used_late > 1500,
            "used at {used_late} of 2000 samples at the end"
        );
        let learnt = f.hard_iron();
        for i in 0..3 {
            assert!((learnt[i] - b[i]).abs() < 1e-6, "{learnt:?} vs {b:?}");
        }
    }

    /// A magnet the sensor moves past from 20 to 50 s (a field that changes in the earth frame,
    /// up to half the earth's): rejected, the heading stays within 1 deg of the gyro's, its
    /// standard deviation grows meanwhile, and the field is used again once it is gone.
    #[test]
    fn a_magnet_nearby_is_rejected_and_the_heading_stays_the_gyros() {
        let delta0 = 0.3;
        let mut f = filter(MagConfig::default());
        let (mut worst, mut sd_before, mut sd_during, mut used_after) = (0.0f64, 0.0, 0.0, 0);
        run(
            &mut f,
            80.0,
            delta0,
            0.0,
            |t, seen| {
                if !(20.0..50.0).contains(&t) {
                    return [0.0; 3];
                }
                let s = (0.5 * (t - 20.0)).sin();
                to_body(seen, &[12e-6 * s, -8e-6 * s.abs(), 6e-6])
            },
            |t, s| {
                if t > 10.0 {
                    worst = worst.max(off_deg(&s, delta0).abs());
                }
                if (19.0..19.01).contains(&t) {
                    sd_before = s.sd.unwrap();
                }
                if (49.0..49.01).contains(&t) {
                    sd_during = s.sd.unwrap();
                }
                if t > 60.0 && s.state == MagUse::Used {
                    used_after += 1;
                }
            },
        );
        assert!(worst < 1.0, "heading off by {worst} deg");
        assert!(sd_during > 1.1 * sd_before, "{sd_before} -> {sd_during}");
        assert!(
            used_after > 1500,
            "used at {used_after} of 2000 samples after"
        );
    }

    /// Absent, not finite, zero, huge or saturated readings: never a NaN, and each says so;
    /// the heading stays where it was, its standard deviation grows.
    #[test]
    fn no_reading_makes_a_nan() {
        let mut f = filter(MagConfig::default());
        let delta0 = 1.0;
        let mut last = None;
        run(
            &mut f,
            20.0,
            delta0,
            0.0,
            |_, _| [0.0; 3],
            |_, s| last = Some(s),
        );
        let before = last.unwrap();
        let q6 = [1.0, 0.0, 0.0, 0.0];
        let w = Some([0.0, 0.0, 0.1]);
        let bad: [(Option<[f64; 3]>, MagUse); 6] = [
            (None, MagUse::Absent),
            (Some([f64::NAN, 1e-5, 0.0]), MagUse::Invalid),
            (Some([f64::INFINITY; 3]), MagUse::Invalid),
            (Some([0.0; 3]), MagUse::Invalid),
            (Some([1e300, 0.0, 0.0]), MagUse::Invalid),
            (Some([f64::MIN_POSITIVE / 4.0, 0.0, 0.0]), MagUse::Invalid),
        ];
        for (m, want) in bad {
            for _ in 0..300 {
                let s = f.push(q6, w, m);
                assert_eq!(s.state, want, "{m:?}");
                assert!(
                    s.offset.unwrap().is_finite() && s.sd.unwrap().is_finite(),
                    "{s:?}"
                );
            }
        }
        // A reading with no usable rate cannot be placed in the earth frame.
        assert_eq!(f.push(q6, None, Some([1e-5; 3])).state, MagUse::Invalid);
        // Saturated: every axis at the sensor's limit, 4.9 gauss (a magnet on the sensor).
        let mut s = f.push(q6, w, Some([4.9e-4; 3]));
        for _ in 0..300 {
            s = f.push(q6, w, Some([4.9e-4; 3]));
        }
        assert_eq!(s.state, MagUse::Disturbed);
        let drift = wrap(s.offset.unwrap() - before.offset.unwrap())
            .abs()
            .to_degrees();
        assert!(drift < 1.0, "{drift} deg: {s:?}");
        assert!(s.sd.unwrap() > before.sd.unwrap(), "{before:?} -> {s:?}");
        // Never a reading: the heading stays relative.
        let mut never = filter(MagConfig::default());
        let s = never.push(q6, w, None);
        assert_eq!((s.offset, s.sd, s.state), (None, None, MagUse::Absent));
    }

    #[test]
    fn bad_settings_are_refused() {
        assert!(MagConfig::default().check().is_ok());
        for bad in [
            MagConfig {
                norm_tolerance: 0.0,
                ..MagConfig::default()
            },
            MagConfig {
                delay: Some(f64::NAN),
                ..MagConfig::default()
            },
            MagConfig {
                declination: f64::INFINITY,
                ..MagConfig::default()
            },
            MagConfig {
                drift_walk: -1.0,
                ..MagConfig::default()
            },
        ] {
            assert!(bad.check().is_err(), "{bad:?}");
        }
    }
}
