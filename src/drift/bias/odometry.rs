//! [`OdometryAid`]: the vehicle's own yaw rate (wheel odometry) as a measurement of the gyro
//! bias while the vehicle drives, about the vehicle's up axis (the gyro's axis here).
//!
//! # The measurement
//! The odometry reports its yaw rate over its period (T, e.g. 20 ms at 50 Hz), stamped with
//! the end of that period; it arrives some latency later. The gyro samples whose times lie in
//! that period are kept in a short history ([`OdometryAidConfig::history_s`]), so a late
//! message is matched to the gyro of its own stamp, not to the gyro of its arrival. Messages
//! are pooled over a span ([`OdometryAidConfig::span_s`], 0.5 s) and the span gives one
//! measurement of the bias and the odometry's scale:
//!
//! ```text
//! y = mean(gyro over the span's periods) - mean(odometry over the span) = b + s w
//! ```
//!
//! with w the span's mean odometry and the true rate (1 + s) w: s is the odometry's scale
//! error as a correction (tyre radius, track width; it also absorbs the gyro's own scale
//! error: only the ratio of the two is observable without a third reference). Pooling over a
//! span, not one message: encoder ticks quantise the odometry's *angle*, so one message's
//! rate is noisy (a tick per period: 0.02 deg in 20 ms is 1 deg/s) while the angle over a span
//! is exact to two ticks; and a slip burst of 1-3 s stands out of a 0.5 s mean far better
//! than of one message.
//!
//! Its variance, each term independent:
//!
//! ```text
//! r = R_gyro / m                 the gyro's white noise over the m samples averaged
//!   + sum(sd_i^2) / n^2          the odometry's white noise over its n messages (each
//!                                message's own sd where it says one, else `white_sd`)
//!   + tick^2 / 6 / span^2        the angle's quantisation at the span's two ends
//! ```
//!
//! A span is a measurement only while the bias filter's stop gate says the vehicle moves
//! (at a stop the same gyro samples measure the bias already).
//!
//! # The scale: a state of the bias filter
//! s is one more state of the bias filter ([`super::ScaleState`]: a random walk, prior
//! `scale_sd`), with H = [1, ..., 1, w] for a span and [1, ..., 1, 0] for a stop
//! ([`super::BiasFilter::update_scaled`]). The filter carries the covariance of the bias with
//! the scale: where the vehicle turns one way all the time it drives (bias and scale seen
//! only as b + s w), a span's error of the scale is one error shared by every span of the
//! turn, not white noise per span, and the next stop, which measures b alone, corrects the
//! scale learnt in the turn before it. Without spans the scale stays uncorrelated with the
//! bias and every result is the bias filter's alone.
//!
//! # Slip: an innovation test, and a span waits for the next
//! Slip (the wheels turn, the vehicle does not follow: skid-steer turns, ice) makes the
//! odometry wrong for seconds. Each span's innovation against the filter, nu = y - b_hat -
//! s_hat w, is tested as the stop rule tests a stop signal against the gyro: chi-square with
//! one degree of freedom, nu^2 / (H P H^T + r) > `gate` rejects it. A span that passes still
//! waits: it enters the filter only when the next span passes too and agrees with it (z = y -
//! s_hat w; (z1 - z2)^2 / (r1 + r2 + P_s (w1 - w2)^2) <= `gate`: the scale's error is one,
//! shared by the two), so a slip that began at the end of a span (too little of it there to
//! fail the test) is dropped with the span after it. A slip never teaches the bias, nor the
//! scale.
//! Rejected spans are counted, and so are runs of them ([`OdometryDiagnostics`]).
//!
//! Pure: no I/O, fixed buffers sized at construction, nothing allocated per sample.

use super::ScaledView;

/// One odometry message: its yaw rate over its period, stamped with the period's end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometrySample {
    /// The end of the period it measures, s, on the gyro's clock.
    pub stamp_s: f64,
    /// The period it measures, s (its rate's mean is over (stamp - period, stamp]).
    pub period_s: f64,
    /// Yaw rate, deg/s, about the vehicle's up axis (the gyro's axis).
    pub yaw_rate: f64,
    /// The message's own standard deviation of `yaw_rate`, deg/s; NaN (or not > 0): not said,
    /// and [`OdometryAidConfig::white_sd`] stands in.
    pub yaw_rate_sd: f64,
}

/// How [`OdometryAid`] weighs and tests the odometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryAidConfig {
    /// Messages are pooled into one measurement over this long, s.
    pub span_s: f64,
    /// The odometry's white rate noise per message, deg/s.
    pub white_sd: f64,
    /// The odometry's angle resolution (one encoder tick of yaw), deg.
    pub tick_deg: f64,
    /// Prior standard deviation of the scale error s.
    pub scale_sd: f64,
    /// The scale's random walk, per sqrt(s).
    pub scale_walk: f64,
    /// Chi-square bound of the innovation tests (one degree of freedom).
    pub gate: f64,
    /// How far back the gyro is kept for matching a late message, s.
    pub history_s: f64,
    /// Whether the innovation tests run (off only to measure what they are worth).
    pub test: bool,
}

impl Default for OdometryAidConfig {
    /// A 0.5 s span; a 50 Hz odometry with 0.1 deg/s white noise per message and ticks of
    /// 0.02 deg; a scale error of sd 1% (0.5-2% is usual), walking 1e-4 per sqrt(s); the
    /// tests at 10.83 (chi-square, 1 dof, 99.9%); 0.5 s of gyro history (room for 0.4 s of
    /// latency at a 50 Hz odometry).
    fn default() -> Self {
        OdometryAidConfig {
            span_s: 0.5,
            white_sd: 0.1,
            tick_deg: 0.02,
            scale_sd: 0.01,
            scale_walk: 1e-4,
            gate: 10.83,
            history_s: 0.5,
            test: true,
        }
    }
}

/// What the odometry did for the bias so far.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct OdometryDiagnostics {
    /// Spans given to the filter.
    pub accepted: u64,
    /// Spans rejected by the innovation tests (slip, or a model that does not fit).
    pub rejected: u64,
    /// Runs of consecutive rejected spans (each a slip, most likely).
    pub slips: u64,
    /// The longest run of rejected spans.
    pub longest_run: u64,
    /// Messages whose period had left the gyro history (too late) or held no gyro sample.
    pub unmatched: u64,
    /// The scale correction s now.
    pub scale: f64,
    /// Its standard deviation.
    pub scale_sd: f64,
}

/// Whether the odometry's yaw rate turns with the gyro axis it is given as the vehicle's up:
/// the slope of the gyro's span means on the odometry's, both centred (so the bias, however
/// far the filter is from it, drops out), judged once the odometry's means spread by
/// [`MOUNT_SPREAD_DEG_S`] over [`MOUNT_MIN_SPANS`] spans or more.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mounting {
    /// Not enough turning yet; spans are used as they pass the tests.
    Unknown,
    /// The gyro follows the odometry (slope at least [`MOUNT_MIN_SLOPE`]).
    Confirmed {
        /// The slope (1 for a perfect match).
        slope: f64,
    },
    /// The gyro turns against the odometry (slope at most -[`MOUNT_MIN_SLOPE`]): one of the
    /// two has its sign the other way round. No span is used after it.
    WrongSign {
        /// The slope.
        slope: f64,
    },
    /// The gyro axis does not see the odometry's turns: the vehicle's up is another axis.
    /// No span is used after it.
    WrongAxis {
        /// The slope.
        slope: f64,
    },
}

/// The spread (standard deviation) of the odometry's span means the mounting check needs,
/// deg/s: turns and straights, or turns of different rates.
pub const MOUNT_SPREAD_DEG_S: f64 = 3.0;
/// The fewest spans the mounting check judges on.
pub const MOUNT_MIN_SPANS: f64 = 6.0;
/// The least slope of gyro on odometry that says they turn together (a scale error of tens
/// of percent passes; an axis 60 deg off the vertical sees half the turn).
pub const MOUNT_MIN_SLOPE: f64 = 0.5;

/// A span's measurement of the bias and the scale: y = b + s w.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement {
    /// Mean gyro - mean odometry over the span, deg/s.
    pub y: f64,
    /// The odometry's mean rate over the span, deg/s.
    pub w: f64,
    /// The variance of y given b and s, (deg/s)^2.
    pub r: f64,
}

impl Measurement {
    /// The bias it measures with the scale `s`: y - s w.
    fn bias(&self, s: f64) -> f64 {
        self.y - s * self.w
    }
}

/// The odometry's yaw rate as a measurement of the bias while moving (module documentation).
#[derive(Debug, Clone)]
pub struct OdometryAid {
    cfg: OdometryAidConfig,
    /// The gyro's measurement variance per sample, (deg/s)^2 (the bias model's R).
    r_gyro: f64,
    ring_t: Vec<f64>,
    ring_x: Vec<f64>,
    head: usize,
    filled: usize,
    tol: f64,
    // The span being pooled.
    g_sum: f64,
    g_n: usize,
    o_angle: f64,
    o_time: f64,
    o_n: usize,
    /// The sum of the pooled messages' variances, (deg/s)^2.
    o_var: f64,
    pending: Option<Measurement>,
    /// The scale's random walk per sample (variance): the filter's scale state's.
    scale_walk: f64,
    run: u64,
    diag: OdometryDiagnostics,
    // The mounting check: sums over spans of 1, gyro, odometry, their product, odometry^2.
    mount_sums: [f64; 5],
    mounting: Mounting,
}

impl OdometryAid {
    /// An aid for a gyro at `rate_hz` whose bias model has measurement variance `r_gyro` per
    /// sample ([`super::BiasModel::measurement_variance`]). Refused: a rate, span, history or
    /// gate that is not a finite number > 0, or a noise term < 0.
    pub fn new(cfg: OdometryAidConfig, r_gyro: f64, rate_hz: f64) -> Result<Self, String> {
        for (name, v) in [
            ("rate", rate_hz),
            ("span_s", cfg.span_s),
            ("history_s", cfg.history_s),
            ("gate", cfg.gate),
            ("r_gyro", r_gyro),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} must be a finite number > 0, not {v}"));
            }
        }
        for (name, v) in [
            ("white_sd", cfg.white_sd),
            ("tick_deg", cfg.tick_deg),
            ("scale_sd", cfg.scale_sd),
            ("scale_walk", cfg.scale_walk),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} must be a finite number >= 0, not {v}"));
            }
        }
        let len = ((cfg.history_s * rate_hz).ceil() as usize).max(2);
        Ok(OdometryAid {
            cfg,
            r_gyro,
            ring_t: vec![0.0; len],
            ring_x: vec![0.0; len],
            head: 0,
            filled: 0,
            tol: 0.25 / rate_hz,
            g_sum: 0.0,
            g_n: 0,
            o_angle: 0.0,
            o_time: 0.0,
            o_n: 0,
            o_var: 0.0,
            pending: None,
            scale_walk: cfg.scale_walk * cfg.scale_walk / rate_hz,
            run: 0,
            diag: OdometryDiagnostics {
                scale_sd: cfg.scale_sd,
                ..OdometryDiagnostics::default()
            },
            mount_sums: [0.0; 5],
            mounting: Mounting::Unknown,
        })
    }

    /// One gyro sample (deg/s, the rate the bias filter sees) at time `t_s`.
    pub fn push_gyro(&mut self, t_s: f64, x: f64) {
        let len = self.ring_t.len();
        self.ring_t[self.head] = t_s;
        self.ring_x[self.head] = x;
        self.head = (self.head + 1) % len;
        self.filled = (self.filled + 1).min(len);
    }

    /// The vehicle stands (or the stop gate says so): the span being pooled and the one
    /// waiting are dropped; the next span starts with the next message.
    pub fn stop(&mut self) {
        self.clear_span();
        self.pending = None;
    }

    /// The gyro's times change clock (a replay's logged odometry after a live one): the
    /// history is forgotten with the spans; the scale, the mounting and the counts are kept.
    pub fn restart_history(&mut self) {
        self.stop();
        self.head = 0;
        self.filled = 0;
    }

    fn clear_span(&mut self) {
        self.g_sum = 0.0;
        self.g_n = 0;
        self.o_angle = 0.0;
        self.o_time = 0.0;
        self.o_n = 0;
        self.o_var = 0.0;
    }

    /// The scale state the bias filter carries ([`super::BiasTracker::add_scale`]): its prior
    /// sd and its walk per sample.
    pub fn scale_prior(&self) -> (f64, f64) {
        (self.cfg.scale_sd, self.scale_walk)
    }

    /// One odometry message, arrived now, while the vehicle moves; `now` is the bias filter's
    /// bias and scale now ([`super::BiasFilter::scaled_view`], with the scale's prior until
    /// the filter has the state). Returns the measurement the filter takes now, if a span
    /// waiting for confirmation has just been confirmed (module documentation).
    pub fn push_odometry(&mut self, m: OdometrySample, now: ScaledView) -> Option<Measurement> {
        if !(m.stamp_s.is_finite() && m.period_s > 0.0 && m.yaw_rate.is_finite()) {
            self.diag.unmatched += 1;
            return None;
        }
        let (from, to) = (m.stamp_s - m.period_s + self.tol, m.stamp_s + self.tol);
        let len = self.ring_t.len();
        // The period must lie inside the history: once it is full, its oldest sample must be
        // older than the period's start (a later message has lost its gyro).
        let oldest = self.ring_t[(self.head + len - self.filled) % len];
        if self.filled == len && oldest > from {
            self.diag.unmatched += 1;
            return None;
        }
        let (mut sum, mut n) = (0.0, 0usize);
        for i in 0..self.filled {
            let k = (self.head + len - 1 - i) % len;
            let t = self.ring_t[k];
            if t <= from {
                break;
            }
            if t <= to && self.ring_x[k].is_finite() {
                sum += self.ring_x[k];
                n += 1;
            }
        }
        if n == 0 {
            self.diag.unmatched += 1;
            return None;
        }
        self.g_sum += sum;
        self.g_n += n;
        self.o_angle += m.yaw_rate * m.period_s;
        self.o_time += m.period_s;
        self.o_n += 1;
        let sd = if m.yaw_rate_sd > 0.0 && m.yaw_rate_sd.is_finite() {
            m.yaw_rate_sd
        } else {
            self.cfg.white_sd
        };
        self.o_var += sd * sd;
        if self.o_time + 1e-9 < self.cfg.span_s {
            return None;
        }
        let tick = self.cfg.tick_deg;
        let (gyro, w) = (self.g_sum / self.g_n as f64, self.o_angle / self.o_time);
        let span = Measurement {
            y: gyro - w,
            w,
            r: self.r_gyro / self.g_n as f64
                + self.o_var / (self.o_n * self.o_n) as f64
                + tick * tick / 6.0 / (self.o_time * self.o_time),
        };
        self.clear_span();
        self.check_mounting(gyro, w);
        self.diag.scale = now.scale;
        self.diag.scale_sd = now.scale_var.sqrt();
        match self.mounting {
            Mounting::WrongSign { .. } | Mounting::WrongAxis { .. } => None,
            _ => self.judge(span, now),
        }
    }

    /// The mounting check's sums from a span, and its verdict once the odometry spread
    /// enough (judged once).
    fn check_mounting(&mut self, g: f64, o: f64) {
        if self.mounting != Mounting::Unknown {
            return;
        }
        for (sum, add) in self.mount_sums.iter_mut().zip([1.0, g, o, g * o, o * o]) {
            *sum += add;
        }
        let [n, sg, so, sgo, soo] = self.mount_sums;
        let var_o = soo / n - (so / n) * (so / n);
        if n < MOUNT_MIN_SPANS || var_o < MOUNT_SPREAD_DEG_S * MOUNT_SPREAD_DEG_S {
            return;
        }
        let slope = (sgo / n - (sg / n) * (so / n)) / var_o;
        self.mounting = if slope >= MOUNT_MIN_SLOPE {
            Mounting::Confirmed { slope }
        } else if slope <= -MOUNT_MIN_SLOPE {
            Mounting::WrongSign { slope }
        } else {
            Mounting::WrongAxis { slope }
        };
    }

    /// What the mounting check found so far.
    pub fn mounting(&self) -> Mounting {
        self.mounting
    }

    fn judge(&mut self, span: Measurement, now: ScaledView) -> Option<Measurement> {
        let gate = self.cfg.gate;
        let (predicted, variance) = now.predict(span.w);
        let nu = span.y - predicted;
        if self.cfg.test && nu * nu > gate * (variance + span.r) {
            self.reject(true);
            return None;
        }
        let prev = self.pending.replace(span)?;
        // The two spans share the bias and the scale's error: only the scale's part that
        // their rates do not share is left in the difference.
        let d = span.bias(now.scale) - prev.bias(now.scale);
        let dw = span.w - prev.w;
        if self.cfg.test && d * d > gate * (span.r + prev.r + now.scale_var * dw * dw) {
            // They disagree: the older one may hold the start of a slip; the newer waits.
            self.reject(false);
            return None;
        }
        self.run = 0;
        self.diag.accepted += 1;
        Some(prev)
    }

    /// A span rejected (`both`: the new one failed against the filter, so the waiting one,
    /// unconfirmed, goes with it).
    fn reject(&mut self, both: bool) {
        if both {
            self.pending = None;
        }
        self.diag.rejected += 1;
        if self.run == 0 {
            self.diag.slips += 1;
        }
        self.run += 1;
        self.diag.longest_run = self.diag.longest_run.max(self.run);
    }

    /// What it has done so far, and the scale and its sd as the filter had them at the last
    /// span.
    pub fn diagnostics(&self) -> OdometryDiagnostics {
        self.diag
    }
}

/// The most an axis may lean from the vertical and still be taken for the vehicle's up, deg.
pub const UP_MAX_TILT_DEG: f64 = 30.0;

/// What gravity says of the vehicle's up ([`UpFromGravity`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GravityUp {
    /// Gyro axis `axis` (0, 1, 2) points up with `sign`, leaning `tilt_deg` from the vertical.
    Axis {
        /// The axis.
        axis: usize,
        /// +1 or -1.
        sign: f64,
        /// Its angle from the vertical, deg (at most [`UP_MAX_TILT_DEG`]).
        tilt_deg: f64,
    },
    /// No axis is within [`UP_MAX_TILT_DEG`] of the vertical: the sensor is mounted tilted.
    Tilted {
        /// The least angle of an axis from the vertical, deg.
        tilt_deg: f64,
    },
}

impl GravityUp {
    /// The axis and sign, when one points up.
    pub fn axis(self) -> Option<(usize, f64)> {
        match self {
            GravityUp::Axis { axis, sign, .. } => Some((axis, sign)),
            GravityUp::Tilted { .. } => None,
        }
    }
}

/// The vehicle's up from a mount rotation, as the Linux IIO mount matrix gives it: `m` takes a
/// vector from the gyro's frame into the vehicle's (REP 103: x forward, y left, z up), so its
/// third row is the vehicle's up in the gyro's frame. Returns the gyro axis nearest the up and
/// the up's component along it, `c` (signed, |c| = the cosine of their angle): a vehicle that
/// only yaws turns that axis at `c` times its yaw rate. Refused: a matrix that is not a
/// rotation (rows orthonormal to 0.01, determinant +1), or an up more than
/// [`UP_MAX_TILT_DEG`] from every axis (its roll and pitch rates would leak into the axis).
pub fn up_from_mount(m: [[f64; 3]; 3]) -> Result<(usize, f64), String> {
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return Err("the mount matrix holds a value that is not a finite number".into());
    }
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|k| m[i][k] * m[j][k]).sum();
            let want = if i == j { 1.0 } else { 0.0 };
            if (dot - want).abs() > 0.01 {
                return Err(format!(
                    "the mount matrix is not a rotation: rows {} and {} have a dot product of \
                     {dot:.3}, not {want}",
                    i + 1,
                    j + 1
                ));
            }
        }
    }
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if det < 0.0 {
        return Err("the mount matrix is a mirror (determinant -1), not a rotation".into());
    }
    let up = m[2];
    let axis = (0..3)
        .max_by(|&a, &b| up[a].abs().total_cmp(&up[b].abs()))
        .unwrap_or(2);
    let tilt_deg = up[axis].abs().min(1.0).acos().to_degrees();
    if tilt_deg > UP_MAX_TILT_DEG {
        return Err(format!(
            "the vehicle's up is {tilt_deg:.0} deg from the nearest gyro axis: \
             beyond {UP_MAX_TILT_DEG} deg its roll and pitch rates leak into that axis, so the \
             yaw rate cannot teach its bias"
        ));
    }
    Ok((axis, up[axis]))
}

/// The vehicle's up from the accelerometer at rest: at rest the specific force points up (it
/// is the reaction to gravity), so the body axis nearest to it, with its sign, is up. Judged
/// once, from the mean over `need` readings taken at rest (the caller's stillness verdict).
#[derive(Debug, Clone)]
pub struct UpFromGravity {
    sum: [f64; 3],
    n: u64,
    need: u64,
    verdict: Option<GravityUp>,
}

impl UpFromGravity {
    /// Judge from `need` readings at rest (at least 1).
    pub fn new(need: u64) -> UpFromGravity {
        UpFromGravity {
            sum: [0.0; 3],
            n: 0,
            need: need.max(1),
            verdict: None,
        }
    }

    /// One specific force `f` (any unit) read at rest; returns the verdict at the reading that
    /// makes it, once. A non-finite reading is left out.
    pub fn push(&mut self, f: [f64; 3]) -> Option<GravityUp> {
        if self.verdict.is_some() || f.iter().any(|v| !v.is_finite()) {
            return None;
        }
        for (s, v) in self.sum.iter_mut().zip(f) {
            *s += v;
        }
        self.n += 1;
        if self.n < self.need {
            return None;
        }
        let norm = self.sum.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm == 0.0 {
            return None;
        }
        let axis = (0..3)
            .max_by(|&a, &b| self.sum[a].abs().total_cmp(&self.sum[b].abs()))
            .unwrap_or(2);
        let tilt_deg = (self.sum[axis].abs() / norm).min(1.0).acos().to_degrees();
        let verdict = if tilt_deg <= UP_MAX_TILT_DEG {
            GravityUp::Axis {
                axis,
                sign: self.sum[axis].signum(),
                tilt_deg,
            }
        } else {
            GravityUp::Tilted { tilt_deg }
        };
        self.verdict = Some(verdict);
        Some(verdict)
    }

    /// The verdict, once made.
    pub fn verdict(&self) -> Option<GravityUp> {
        self.verdict
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::terms;
    use super::super::{BiasFilter, BiasModel, Instability};
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_distr::StandardNormal;

    const RATE: f64 = 100.0;
    const BIAS: f64 = 0.3;

    /// A drive for `secs`: the true rate `w(t)`, the gyro = w + BIAS + white noise of the
    /// terms, a 50 Hz odometry reading (1 + e) w (1 + slip(t)) + 0.1 deg/s white, arriving
    /// `latency` s after its stamp; stamped with its period's end, or (`honest` false) with
    /// its arrival. The filter starts at its prior, or (`known`) knowing the bias to 0.01
    /// deg/s as a stop would leave it. Returns the filter and the aid.
    #[allow(clippy::too_many_arguments)]
    fn drive(
        secs: f64,
        w: impl Fn(f64) -> f64,
        e: f64,
        slip: impl Fn(f64) -> f64,
        latency: f64,
        honest: bool,
        known: bool,
        cfg: OdometryAidConfig,
    ) -> (BiasFilter, OdometryAid) {
        let t = terms();
        let model = BiasModel::new(&t, RATE, Instability::from_terms(&t)).unwrap();
        let r = model.measurement_variance();
        let mut f = BiasFilter::new(model);
        if known {
            // A long stop: the bias to about 0.01 deg/s.
            let n = (r / 1e-4) as usize;
            for _ in 0..n {
                f.update(BIAS);
            }
        }
        let mut aid = OdometryAid::new(cfg, r, RATE).unwrap();
        f.add_scale(aid.scale_prior().0, aid.scale_prior().1);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let sd = (t.n * t.n * RATE).sqrt();
        let n = (secs * RATE) as usize;
        let mut queue: Vec<(usize, OdometrySample)> = Vec::new();
        let mut angle = 0.0;
        let mut last = 0.0;
        for k in 0..n {
            let tt = k as f64 / RATE;
            let g: f64 = rng.sample(StandardNormal);
            let x = w(tt) + BIAS + sd * g;
            angle += (1.0 + e) * (1.0 + slip(tt)) * w(tt) / RATE;
            if k > 0 && k % 2 == 0 {
                let o: f64 = rng.sample(StandardNormal);
                let arrival = k + (latency * RATE).round() as usize;
                let stamp = if honest { tt } else { arrival as f64 / RATE };
                let yaw_rate = (angle - last) / 0.02 + 0.1 * o;
                last = angle;
                queue.push((
                    arrival,
                    OdometrySample {
                        stamp_s: stamp,
                        period_s: 0.02,
                        yaw_rate,
                        yaw_rate_sd: f64::NAN,
                    },
                ));
            }
            f.predict();
            aid.push_gyro(tt, x);
            while queue.first().is_some_and(|(a, _)| *a <= k) {
                let (_, m) = queue.remove(0);
                if let Some(z) = aid.push_odometry(m, f.scaled_view()) {
                    f.update_scaled(z.y, z.w, z.r);
                }
            }
        }
        (f, aid)
    }

    fn no_slip(_: f64) -> f64 {
        0.0
    }

    #[test]
    fn a_bias_is_learnt_while_driving_straight() {
        // From the prior (1 deg/s), no stop at all: 60 s straight with road vibration.
        let w = |t: f64| 0.8 * (2.0 * std::f64::consts::PI * 9.3 * t).sin();
        let (f, aid) = drive(
            60.0,
            w,
            0.01,
            no_slip,
            0.03,
            true,
            false,
            Default::default(),
        );
        let sd = f.variance().sqrt();
        assert!(sd < 0.02, "sd {sd}");
        assert!(
            (f.estimate() - BIAS).abs() < 4.0 * sd,
            "{} +- {sd}",
            f.estimate()
        );
        let d = aid.diagnostics();
        assert!(d.accepted > 100 && d.rejected <= 2, "{d:?}");
    }

    /// Turns: 10 deg/s plus 15 deg/s at 0.05 Hz (the scale shows where the rate varies).
    fn turning(t: f64) -> f64 {
        10.0 + 15.0 * (2.0 * std::f64::consts::PI * 0.05 * t).sin()
    }

    #[test]
    fn a_slip_burst_never_teaches_the_bias() {
        // 20% slip for 2 s in a turn (about 5 deg/s of error).
        let slip = |t: f64| if (30.0..32.0).contains(&t) { 0.2 } else { 0.0 };
        let run = |test: bool| {
            let cfg = OdometryAidConfig {
                test,
                ..Default::default()
            };
            drive(40.0, turning, 0.0, slip, 0.03, true, true, cfg)
        };
        let (f, aid) = run(true);
        let d = aid.diagnostics();
        assert!(d.slips >= 1 && d.rejected >= 3, "{d:?}");
        assert!((f.estimate() - BIAS).abs() < 0.02, "{}", f.estimate());
        // Without the test the same burst moves the estimate far more.
        let (blind, _) = run(false);
        assert!(
            (blind.estimate() - BIAS).abs() > 3.0 * (f.estimate() - BIAS).abs(),
            "{} against {}",
            blind.estimate(),
            f.estimate()
        );
        assert!(
            (blind.estimate() - BIAS).abs() > 0.05,
            "{}",
            blind.estimate()
        );
    }

    #[test]
    fn a_late_message_is_matched_to_the_gyro_of_its_stamp() {
        // A fast-changing turn (20 deg/s at 0.5 Hz), messages 100 ms late.
        let w = |t: f64| 20.0 * (2.0 * std::f64::consts::PI * 0.5 * t).sin();
        let (f, aid) = drive(60.0, w, 0.0, no_slip, 0.1, true, false, Default::default());
        assert!((f.estimate() - BIAS).abs() < 0.02, "{}", f.estimate());
        assert!(aid.diagnostics().rejected <= 3, "{:?}", aid.diagnostics());
        // Stamped at arrival instead, the gyro it is matched to is 100 ms off: the tests
        // refuse most spans (a 6 deg/s mismatch at the turn's quickest).
        let (_, blind) = drive(60.0, w, 0.0, no_slip, 0.1, false, false, Default::default());
        assert!(
            blind.diagnostics().rejected > 10 * aid.diagnostics().rejected.max(1),
            "{:?}",
            blind.diagnostics()
        );
    }

    #[test]
    fn the_odometry_scale_is_learnt_in_turns() {
        // The odometry reads 2% high: the correction is 1/1.02 - 1.
        let (f, aid) = drive(
            300.0,
            turning,
            0.02,
            no_slip,
            0.03,
            true,
            true,
            Default::default(),
        );
        let d = aid.diagnostics();
        let s = 1.0 / 1.02 - 1.0;
        assert!((d.scale - s).abs() < 0.003, "{d:?}");
        assert!(d.scale_sd < 0.003, "{d:?}");
        assert!((f.estimate() - BIAS).abs() < 0.02, "{}", f.estimate());
        // Not learning it (a prior of 0) takes the scale error for slip in the turns (most
        // spans refused) and for bias in the rest: the bias ends further off.
        let cfg = OdometryAidConfig {
            scale_sd: 0.0,
            scale_walk: 0.0,
            ..Default::default()
        };
        let (g, blind) = drive(300.0, turning, 0.02, no_slip, 0.03, true, true, cfg);
        let e = blind.diagnostics();
        assert!(e.rejected > 10 * d.rejected.max(1), "{e:?}");
        assert!(
            (g.estimate() - BIAS).abs() > (f.estimate() - BIAS).abs(),
            "{} {}",
            g.estimate(),
            f.estimate()
        );
    }

    /// The mounting check: an odometry that turns with the gyro is confirmed (slope near 1);
    /// one of the other sign, or one whose turns the gyro axis does not see (here ten times
    /// the gyro's), is found within seconds of turning, and then teaches nothing: the bias
    /// stays where the stop left it.
    #[test]
    fn a_wrong_sign_or_axis_is_found_and_never_teaches() {
        let run = |gain: f64| {
            let odo = move |_: f64| gain - 1.0;
            drive(
                120.0,
                turning,
                0.0,
                odo,
                0.03,
                true,
                true,
                Default::default(),
            )
        };
        let (_, right) = run(1.0);
        assert!(
            matches!(right.mounting(), Mounting::Confirmed { slope } if (slope - 1.0).abs() < 0.05),
            "{:?}",
            right.mounting()
        );
        for (gain, wrong) in [(-1.0, "sign"), (10.0, "axis")] {
            let (f, aid) = run(gain);
            let found = match aid.mounting() {
                Mounting::WrongSign { slope } => slope < -0.5 && wrong == "sign",
                Mounting::WrongAxis { slope } => slope.abs() < 0.5 && wrong == "axis",
                _ => false,
            };
            assert!(found, "{wrong}: {:?}", aid.mounting());
            assert!(
                (f.estimate() - BIAS).abs() < 0.02,
                "{wrong}: {}",
                f.estimate()
            );
        }
    }

    #[test]
    fn a_message_that_states_its_sd_is_weighed_by_it() {
        // Two identical straight spans' worth of messages; the second run's messages say
        // 1 deg/s (ten times the default): the measurement's variance grows by the difference
        // over the span's 25 messages, its value is the same.
        let first = |sd: f64| {
            let cfg = OdometryAidConfig::default();
            let mut aid = OdometryAid::new(cfg, 0.0016, RATE).unwrap();
            let mut out = Vec::new();
            for k in 0..300 {
                let t = k as f64 / RATE;
                aid.push_gyro(t, BIAS);
                if k > 0 && k % 2 == 0 {
                    let m = OdometrySample {
                        stamp_s: t,
                        period_s: 0.02,
                        yaw_rate: 0.0,
                        yaw_rate_sd: sd,
                    };
                    let now = ScaledView {
                        estimate: BIAS,
                        variance: 1e-4,
                        scale: 0.0,
                        scale_var: 1e-4,
                        cov: 0.0,
                    };
                    out.extend(aid.push_odometry(m, now));
                }
            }
            out[0]
        };
        let (unsaid, said) = (first(f64::NAN), first(1.0));
        assert_eq!(unsaid.y, said.y);
        let want = (1.0 - 0.01) / 25.0;
        assert!(
            ((said.r - unsaid.r) - want).abs() < 1e-9,
            "{said:?} {unsaid:?}"
        );
        // Zero, negative or infinite: not said.
        for sd in [0.0, -1.0, f64::INFINITY] {
            assert_eq!(first(sd), unsaid, "{sd}");
        }
    }

    #[test]
    fn a_mount_rotation_gives_the_up_axis_and_its_share_or_is_refused() {
        // The IIO documentation's example: x and y swapped, z down (a half turn).
        let flipped = [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]];
        assert_eq!(up_from_mount(flipped), Ok((2, -1.0)));
        let mirror = [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]];
        assert!(up_from_mount(mirror).unwrap_err().contains("mirror"));
        // Pitched 20 deg about y: the up leans toward x.
        let (c, s) = (20f64.to_radians().cos(), 20f64.to_radians().sin());
        let pitched = [[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]];
        let (axis, share) = up_from_mount(pitched).unwrap();
        assert_eq!(axis, 2);
        assert!((share - c).abs() < 1e-12);
        // The vehicle's x up (the sensor on its side), and 40 deg: refused.
        assert_eq!(
            up_from_mount([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),
            Ok((0, 1.0))
        );
        let (c, s) = (40f64.to_radians().cos(), 40f64.to_radians().sin());
        let e = up_from_mount([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]]).unwrap_err();
        assert!(e.contains("up is 40 deg from the nearest gyro axis"), "{e}");
        let e = up_from_mount([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.5, 1.0]]).unwrap_err();
        assert!(e.contains("not a rotation"), "{e}");
        let e = up_from_mount([[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        assert!(e.unwrap_err().contains("finite"));
    }

    #[test]
    fn gravity_names_the_up_axis_with_its_sign_or_says_the_sensor_is_tilted() {
        let judge = |f: [f64; 3]| {
            let mut g = UpFromGravity::new(3);
            assert_eq!(g.push(f), None);
            assert_eq!(g.push([f64::NAN; 3]), None, "left out");
            assert_eq!(g.push(f), None);
            let v = g.push(f).expect("judged at the third reading");
            assert_eq!(g.push(f), None, "once");
            assert_eq!(g.verdict(), Some(v));
            v
        };
        // Level, z down (a gyro mounted upside down): -z is up.
        assert_eq!(judge([0.0, 0.0, -9.81]).axis(), Some((2, -1.0)));
        // On a 20 deg slope about x, y up: +y, leaning 20 deg.
        let a = 20f64.to_radians();
        let v = judge([0.0, 9.81 * a.cos(), 9.81 * a.sin()]);
        let GravityUp::Axis {
            axis,
            sign,
            tilt_deg,
        } = v
        else {
            panic!("{v:?}")
        };
        assert_eq!((axis, sign), (1, 1.0));
        assert!((tilt_deg - 20.0).abs() < 1e-9);
        // 45 deg between x and z: no axis is up.
        let v = judge([6.94, 0.0, 6.94]);
        assert!(
            matches!(v, GravityUp::Tilted { tilt_deg } if (tilt_deg - 45.0).abs() < 1e-9),
            "{v:?}"
        );
        assert_eq!(v.axis(), None);
    }

    #[test]
    fn bad_settings_are_refused() {
        let c = OdometryAidConfig::default();
        assert!(OdometryAid::new(c, 0.1, 0.0).is_err());
        assert!(OdometryAid::new(OdometryAidConfig { span_s: 0.0, ..c }, 0.1, 100.0).is_err());
        assert!(OdometryAid::new(
            OdometryAidConfig {
                white_sd: -1.0,
                ..c
            },
            0.1,
            100.0
        )
        .is_err());
        assert!(OdometryAid::new(c, f64::NAN, 100.0).is_err());
    }
}
