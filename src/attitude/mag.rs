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

use super::hard_iron::{cross, dot, mat_vec, rotation, Sums};
use super::MAX_READING;

/// Settings of the magnetometer's heading filter (angles in rad, times in s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagConfig {
    /// Magnetic declination, added to the heading: east of north positive (true north).
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
    /// The hard-iron offset in use, the readings' units.
    offset: [f64; 3],
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
    /// How long blocks have passed the field's tests, s.
    ok_for: f64,
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
            offset: [0.0; 3],
            delta: 0.0,
            drift: 0.0,
            p: [0.0, 0.0, cfg.drift_sd * cfg.drift_sd],
            absolute: false,
            since: 0.0,
            reference: None,
            ok_for: 0.0,
            delay: cfg.delay.unwrap_or(0.0),
            delay_info: 0.0,
            verdict: MagUse::Absent,
        }
    }

    /// The hard-iron offset in use (the readings' units).
    pub fn hard_iron(&self) -> [f64; 3] {
        self.offset
    }

    /// The magnetometer's delay behind the gyro in use, s.
    pub fn delay(&self) -> f64 {
        self.delay
    }

    /// One sample: the 6D attitude `q6` (w, x, y, z), the body rate (rad/s; None if it was
    /// not usable) and the magnetometer's reading (any unit; None if the sample has none).
    pub fn push(&mut self, q6: [f64; 4], rate: Option<[f64; 3]>, mag: Option<[f64; 3]>) -> MagStep {
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
                .then(|| wrap(self.delta + self.drift * s + self.cfg.declination)),
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
        for i in 0..3 {
            b.u[i] += u[i];
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
        let mut ok = norm > 0.0 && norm.is_finite();
        if let (true, Some((ref_norm, _))) = (ok, self.reference) {
            let spread_ok = self.short.spread(&self.offset).sqrt() / ref_norm < c.spread_tolerance;
            ok = spread_ok && self.matches(norm, dip);
            if !spread_ok && c.hard_iron {
                // The field turns with the body under this offset: a magnet came or went. The
                // offset's window starts again from the last second's.
                self.long = self.short;
            }
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
