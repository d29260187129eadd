//! `attitude.6d`: the orientation from the corrected gyro and the accelerometer
//! ([`crate::attitude`]: VQF, fed our corrected rate), carried in every sample beside them.
//!
//! ```toml
//! [[stage]]
//! name = "attitude"
//! kind = "attitude.6d"
//! input = "nav/predicted"        # after predict.bias: it integrates the corrected rate
//! output = "nav/attitude"
//! # tau_acc_s = 3.0              # how fast the accelerometer pulls the inclination, s
//! ```
//!
//! What it takes from the stages before it: the corrected rate, the bias `predict.bias`
//! removed (`drift`, from the unit's own Allan terms and the stops both sensors or the vehicle
//! confirm) with its uncertainty (`drift_std`), which VQF takes as its own bias state whenever
//! it changes ([`crate::attitude`]: one bias state, never two), and the gyro's white noise
//! (`predict.bias`'s `arw`) for the heading's uncertainty. The sample gains `orientation` (x, y, z, w, body to an earth
//! frame with z up; the heading relative, 0 where the stage started) and `orientation_std`
//! (about the earth's x, y, z). A sample without a valid accelerometer coasts on the gyro and
//! says so (`SENSOR_ORIENTATION_COASTING`); free fall and shocks are flagged
//! (`SENSOR_ORIENTATION_NO_GRAVITY`). docs/attitude.md gives the method and its figures.
//!
//! With `use_mag = true` the stage reads the magnetometer the samples carry (`mag`, tesla,
//! with `SENSOR_MAG`) and the heading becomes absolute: magnetic north, or true north with
//! `declination_deg` ([`crate::attitude::mag`]: a heading Kalman filter on top of the 6D
//! attitude, a disturbed field rejected, the hard-iron offset and the magnetometer's delay
//! learnt online). Once the field is trusted the sample says so (`SENSOR_HEADING_ABSOLUTE`)
//! and `orientation_std`'s z is the absolute heading's. A reading rejected as disturbed is
//! flagged (`SENSOR_MAG_REJECTED`); it, and a sample without a valid reading, keep the heading
//! on the gyro. The end-of-run summary counts the samples at which the magnetometer corrected
//! the heading and those at which it was rejected.
//!
//! The magnetometer's own calibration, from `driftless mag-cal` (a recorded rotation): the
//! stage turns each reading into `W (m - b)` before its heading filter (`mag_soft_iron` `W`,
//! `mag_hard_iron_ut` `b`); with `mag_hard_iron = true` the filter learns the hard iron on
//! from `b`. With `state_file` what it learnt (the hard iron and the reference field) is saved
//! at shutdown and every `state_every_s`, and is the next start's start value
//! ([`super::attitude_state`]).

use std::path::PathBuf;

use crate::attitude::hard_iron::{mat_vec, Mat3};
use crate::attitude::mag_cal::{check_soft_iron, Calibration};
use crate::attitude::{Attitude, AttitudeConfig, MagConfig, MagUse, Upstream, VqfBias};
use crate::io::InputError;
use crate::stages::attitude_state::{self, Loaded, Owner, StateWriter};
use crate::stages::contract::{Kind, Params, Role, Stage};
use crate::stages::schema::{Context, DefaultValue, Key, Table, Type};
use crate::stages::state_file::{self, WarmStart};
use crate::wire::{
    GyroSample, DRIFT_STD_NOT_PROVIDED, SENSOR_HEADING_ABSOLUTE, SENSOR_MAG_REJECTED,
    SENSOR_ORIENTATION, SENSOR_ORIENTATION_COASTING, SENSOR_ORIENTATION_NO_GRAVITY,
};

const TAU_ACC_S: Key = Key {
    name: "tau_acc_s",
    ty: Type::Positive(1e3),
    default: DefaultValue::Float(3.0),
    doc: "time constant of the accelerometer's pull on the inclination, s (VQF's tauAcc): \
          longer trusts the gyro more through the body's own accelerations",
};
const VQF_BIAS: Key = Key {
    name: "vqf_bias",
    ty: Type::Choice(&["full", "rest", "off"]),
    default: DefaultValue::Word("full"),
    doc: "VQF's own bias estimation, from `predict.bias`'s estimate whenever that changes: at \
          rest and in motion (full), at rest only, or none (`predict.bias`'s alone)",
};
const MIN_G: Key = Key {
    name: "min_g",
    ty: Type::FloatIn(0.0, 100.0),
    default: DefaultValue::Float(0.5),
    doc: "an accelerometer norm below this many g is flagged free fall (the reading is used)",
};
const MAX_G: Key = Key {
    name: "max_g",
    ty: Type::Positive(1e3),
    default: DefaultValue::Float(4.0),
    doc: "one above this many g is flagged a shock (the reading is used: dropping it biases \
          the low-passed gravity)",
};
const INCLINATION_FLOOR_DEG: Key = Key {
    name: "inclination_floor_deg",
    ty: Type::NonNegative,
    default: DefaultValue::Float(0.3),
    doc: "the inclination's standard deviation with no motion, deg",
};
const INCLINATION_MOTION_GAIN: Key = Key {
    name: "inclination_motion_gain",
    ty: Type::NonNegative,
    default: DefaultValue::Float(0.1),
    doc: "how much of the low-passed |a| - g is left in the inclination (its standard \
          deviation grows by this times it, over g)",
};
const ARW: Key = Key {
    name: "arw",
    ty: Type::Positive(1e6),
    default: DefaultValue::Derived("`predict.bias`'s (without one: 0)"),
    doc: "the gyro's angle random walk N, deg/sqrt(h), that the heading's standard deviation \
          grows by besides the bias's",
};

const USE_MAG: Key = Key {
    name: "use_mag",
    ty: Type::Bool,
    default: DefaultValue::Bool(false),
    doc: "the magnetometer as the heading's reference (9D), when the samples carry one: the \
          heading becomes absolute, its standard deviation the magnetometer filter's; a disturbed \
          field is rejected and the heading rests on the gyro (docs/attitude.md)",
};
const DECLINATION_DEG: Key = Key {
    name: "declination_deg",
    ty: Type::FloatIn(-180.0, 180.0),
    default: DefaultValue::Float(0.0),
    doc: "magnetic declination, deg east of north, added to the heading: 0 gives magnetic north, \
          the site's declination true north (with `use_mag`)",
};
const MAG_NORM_TOLERANCE: Key = Key {
    name: "mag_norm_tolerance",
    ty: Type::Positive(1.0),
    default: DefaultValue::Float(0.1),
    doc: "a field whose norm leaves the learnt reference by more than this fraction is a \
          disturbance (with `use_mag`; VQF's magNormTh)",
};
const MAG_DIP_TOLERANCE_DEG: Key = Key {
    name: "mag_dip_tolerance_deg",
    ty: Type::Positive(90.0),
    default: DefaultValue::Float(10.0),
    doc: "... or whose dip leaves it by more than this, deg (with `use_mag`; VQF's magDipTh)",
};
const MAG_HARD_IRON: Key = Key {
    name: "mag_hard_iron",
    ty: Type::Bool,
    default: DefaultValue::Bool(true),
    doc: "learn the magnetometer's hard-iron offset (a magnet or steel moving with the sensor) \
          online from the rotation (with `use_mag`)",
};
const MAG_DELAY_S: Key = Key {
    name: "mag_delay_s",
    ty: Type::NonNegative,
    default: DefaultValue::Absent("none: estimated online from the rotation"),
    doc: "the magnetometer's delay behind the gyro, s (with `use_mag`)",
};

const MAG_HARD_IRON_UT: Key = Key {
    name: "mag_hard_iron_ut",
    ty: Type::Floats("x, y, z, uT"),
    default: DefaultValue::Absent("none: no offset (the online hard iron starts from 0)"),
    doc: "the magnetometer's hard-iron offset `b` from `driftless mag-cal`, removed before the heading filter; with `mag_hard_iron` the filter learns on from it (with `use_mag`)",
};
const MAG_SOFT_IRON: Key = Key {
    name: "mag_soft_iron",
    ty: Type::Floats("three rows of three: symmetric, positive definite, condition <= 3"),
    default: DefaultValue::Absent("none: the identity"),
    doc: "the magnetometer's soft-iron matrix `W` from `driftless mag-cal`: each reading becomes `W (m - b)` before the heading filter (with `use_mag`)",
};
const STATE_FILE: Key = Key {
    name: "state_file",
    ty: Type::Str("a file path, relative to the pipeline file"),
    default: DefaultValue::Absent("none: every start is cold"),
    doc: "where the magnetometer's learnt hard iron (with its sd) and reference field are saved (at shutdown and every state_every_s) and started from at the next start; an unusable file costs the warm start, never the start: it is moved aside to `<name>.unusable-<UTC time>` (with `use_mag`)",
};
const STATE_EVERY_S: Key = Key {
    name: "state_every_s",
    ty: Type::Positive(86_400.0),
    default: DefaultValue::Float(120.0),
    doc: "how often the state is saved while running (with `state_file`)",
};

/// `attitude.6d`.
pub const KIND: Kind = Kind {
    name: "attitude.6d",
    role: Role::Process,
    summary: "the orientation (roll, pitch, relative heading) from the corrected gyro and the \
              accelerometer, with its standard deviation; with `use_mag`, the heading absolute \
              from the magnetometer",
    keys: &[
        TAU_ACC_S,
        VQF_BIAS,
        MIN_G,
        MAX_G,
        INCLINATION_FLOOR_DEG,
        INCLINATION_MOTION_GAIN,
        ARW,
        USE_MAG,
        DECLINATION_DEG,
        MAG_NORM_TOLERANCE,
        MAG_DIP_TOLERANCE_DEG,
        MAG_HARD_IRON,
        MAG_DELAY_S,
        MAG_HARD_IRON_UT,
        MAG_SOFT_IRON,
        STATE_FILE,
        STATE_EVERY_S,
    ],
    parse,
};

/// `attitude.6d` parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct AttitudeParams {
    /// The filter's settings; `arw` as given (None: the chain's).
    pub filter: AttitudeConfig,
    /// Where the magnetometer's learnt state is saved and resumed from, if anywhere.
    pub state: Option<StateConfig>,
    /// The magnetometer's calibration as given (uT; the identity without one).
    pub calibration: Calibration,
}

/// `state_file` and what it held when the pipeline was read.
#[derive(Debug, Clone, PartialEq)]
pub struct StateConfig {
    /// The file.
    pub path: PathBuf,
    /// Who the state belongs to.
    pub owner: Owner,
    /// Saved every this many samples.
    pub every: u64,
    /// What the file held when the pipeline was read (what `validate` says); read again when
    /// the stage is built.
    pub loaded: Loaded,
}

fn parse(t: &mut Table<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    if t.cx.axes != 3 {
        return Err(t.error(format!(
            "attitude.6d needs the three axes of the gyro (the pipeline has axes = {})",
            t.cx.axes
        )));
    }
    let vqf_bias = match t.choice_or_default(&VQF_BIAS, "vqf_bias", true)?.as_str() {
        "rest" => VqfBias::Rest,
        "off" => VqfBias::Off,
        _ => VqfBias::Full,
    };
    let (mag, cal) = mag_config(t)?;
    let filter = AttitudeConfig {
        tau_acc_s: t.float_or_default(&TAU_ACC_S)?,
        vqf_bias,
        min_g: t.float_or_default(&MIN_G)?,
        max_g: t.float_or_default(&MAX_G)?,
        inclination_floor_deg: t.float_or_default(&INCLINATION_FLOOR_DEG)?,
        inclination_motion_gain: t.float_or_default(&INCLINATION_MOTION_GAIN)?,
        // deg/sqrt(h) as predict.bias reads it, to rad/sqrt(s).
        arw: t.float(&ARW)?.map(|n| (n / 60.0).to_radians()),
        mag,
    };
    filter.check().map_err(|e| t.error(e))?;
    let state = state(t, filter.mag.is_some(), &cal)?;
    Ok(Box::new(AttitudeParams {
        filter,
        state,
        calibration: cal,
    }))
}

/// `mag_hard_iron_ut` (uT) and `mag_soft_iron`, checked, each error naming its key.
fn calibration(t: &mut Table<'_, '_>) -> Result<Option<Calibration>, InputError> {
    let src = t.src;
    let b = t.get::<Vec<f64>>(&MAG_HARD_IRON_UT)?;
    let w = t.get::<Vec<Vec<f64>>>(&MAG_SOFT_IRON)?;
    if b.is_none() && w.is_none() {
        return Ok(None);
    }
    let mut cal = Calibration::IDENTITY;
    if let Some(b) = b {
        let v = b.get_ref();
        if v.len() != 3 || !v.iter().all(|x| x.is_finite()) {
            return Err(src.span(
                &b,
                format!("mag_hard_iron_ut must hold 3 finite numbers (x, y, z, uT), not {v:?}"),
            ));
        }
        cal.hard_iron = [v[0], v[1], v[2]];
    }
    if let Some(w) = w {
        let rows = w.get_ref();
        if rows.len() != 3 || rows.iter().any(|r| r.len() != 3) {
            return Err(src.span(
                &w,
                "mag_soft_iron must be three rows of three numbers: [[a, b, c], [b, d, e], [c, e, f]]",
            ));
        }
        let m: Mat3 = [0, 1, 2].map(|i| [rows[i][0], rows[i][1], rows[i][2]]);
        check_soft_iron(&m).map_err(|e| src.span(&w, format!("mag_soft_iron {e}")))?;
        cal.soft_iron = m;
    }
    Ok(Some(cal))
}

/// `state_file` and `state_every_s`, with the state loaded; `None` without a `state_file`.
fn state(
    t: &mut Table<'_, '_>,
    on: bool,
    cal: &Calibration,
) -> Result<Option<StateConfig>, InputError> {
    let src = t.src;
    let Some(file) = t.get::<String>(&STATE_FILE)? else {
        if t.has(&STATE_EVERY_S) {
            return Err(t.error("attitude.6d: state_every_s needs state_file"));
        }
        return Ok(None);
    };
    if !on {
        return Err(src.span(
            &file,
            "attitude.6d: state_file keeps the magnetometer's learnt hard iron: it needs use_mag = true",
        ));
    }
    let path = src.resolve(file.get_ref());
    let every_s = t.float_or_default(&STATE_EVERY_S)?;
    let owner = Owner {
        pipeline: t.owner.0.to_string(),
        stage: t.owner.1.to_string(),
        hard_iron_ut: cal.hard_iron,
        soft_iron: cal.soft_iron,
    };
    let loaded = attitude_state::load(&path, &owner);
    Ok(Some(StateConfig {
        path,
        owner,
        every: ((every_s * t.cx.rate_hz).round() as u64).max(1),
        loaded,
    }))
}

/// The magnetometer's settings, with `use_mag` (every key read either way, so none is unknown),
/// and its calibration (uT; the identity without one).
fn mag_config(t: &mut Table<'_, '_>) -> Result<(Option<MagConfig>, Calibration), InputError> {
    let on = t.bool_or_default(&USE_MAG)?;
    let cal = calibration(t)?;
    if let (Some(_), false) = (cal, on) {
        return Err(t.error(
            "attitude.6d: mag_hard_iron_ut and mag_soft_iron calibrate the magnetometer: they need use_mag = true",
        ));
    }
    let cal = cal.unwrap_or(Calibration::IDENTITY);
    let cfg = MagConfig {
        // The filter sees W m and starts from W b; the keys are in uT, the samples in tesla.
        soft_iron: (cal.soft_iron != Calibration::IDENTITY.soft_iron).then_some(cal.soft_iron),
        hard_iron_start: mat_vec(&cal.soft_iron, &cal.hard_iron.map(|v| v * 1e-6)),
        declination: t.float_or_default(&DECLINATION_DEG)?.to_radians(),
        norm_tolerance: t.float_or_default(&MAG_NORM_TOLERANCE)?,
        dip_tolerance: t.float_or_default(&MAG_DIP_TOLERANCE_DEG)?.to_radians(),
        hard_iron: t.bool_or_default(&MAG_HARD_IRON)?,
        delay: t.float(&MAG_DELAY_S)?,
        ..MagConfig::default()
    };
    Ok((on.then_some(cfg), cal))
}

impl AttitudeParams {
    /// The settings the stage runs with in the chain `cx`: `arw` from the chain's
    /// `predict.bias` where the table gives none.
    fn config(&self, cx: &Context) -> AttitudeConfig {
        AttitudeConfig {
            arw: self.filter.arw.or(cx.white_noise.map(f64::to_radians)),
            ..self.filter
        }
    }
}

impl Params for AttitudeParams {
    fn stage(&self, cx: &Context) -> Result<Box<dyn Stage>, String> {
        let mut filter = Attitude::new(cx.rate_hz, self.config(cx))?;
        let mut warm = WarmStart::NotConfigured;
        let mut writer = None;
        if let Some(st) = &self.state {
            // Read again: it may have changed since the pipeline was read.
            warm = match attitude_state::load(&st.path, &st.owner) {
                Loaded::Missing => WarmStart::ColdNoFile {
                    path: st.path.clone(),
                },
                Loaded::Saved(saved) => {
                    let age = state_file::age(saved.saved_unix_ns).unwrap_or_default();
                    filter.resume_mag(&saved.learnt);
                    eprintln!(
                        "driftless: warm start from state_file {}, saved {} ago: {}",
                        st.path.display(),
                        humantime::format_duration(std::time::Duration::from_secs(age.as_secs())),
                        attitude_state::describe(&saved.learnt)
                    );
                    WarmStart::Warm {
                        path: st.path.clone(),
                        age,
                    }
                }
                Loaded::Unusable(u) => {
                    state_file::cold_unusable(&st.path, &u, "the magnetometer's hard iron")
                }
            };
            writer = Some((
                attitude_state::start_writer(st.path.clone(), st.owner.clone())?,
                st.every,
            ));
        }
        Ok(Box::new(AttitudeStage {
            writer,
            since_save: 0,
            warm,
            spare: filter.clone(),
            filter,
            last: None,
            coasting: 0,
            no_gravity: 0,
            samples: 0,
            mag_used: 0,
            mag_rejected: 0,
            disturbed: false,
        }))
    }

    fn describe(&self, _input: Option<&str>, _output: &str) -> Vec<String> {
        let f = &self.filter;
        let mut lines = vec![format!(
            "tau_acc {} s, VQF's bias estimation {}, flagged outside {}..{} g; arw {}",
            f.tau_acc_s,
            format!("{:?}", f.vqf_bias).to_lowercase(),
            f.min_g,
            f.max_g,
            f.arw.map_or("from predict.bias".into(), |n| format!(
                "{:.3} deg/sqrt(h)",
                n.to_degrees() * 60.0
            ))
        )];
        if let Some(m) = &f.mag {
            lines.push(format!(
                "magnetometer: heading absolute, declination {} deg; disturbed beyond {} of the \
                 norm or {} deg of dip; hard iron {}; delay {}",
                m.declination.to_degrees(),
                m.norm_tolerance,
                m.dip_tolerance.to_degrees(),
                if m.hard_iron { "learnt" } else { "not learnt" },
                m.delay.map_or("estimated".into(), |d| format!("{d} s"))
            ));
            let c = &self.calibration;
            if *c != Calibration::IDENTITY {
                lines.push(format!(
                    "magnetometer calibration: hard iron {:?} uT, soft iron {:?}",
                    c.hard_iron, c.soft_iron
                ));
            }
        }
        if let Some(st) = &self.state {
            lines.push(match &st.loaded {
                Loaded::Missing => {
                    format!("state: none yet in {}: a cold start", st.path.display())
                }
                Loaded::Saved(saved) => format!(
                    "state: {}: {}",
                    st.path.display(),
                    attitude_state::describe(&saved.learnt)
                ),
                Loaded::Unusable(u) if u.movable => format!(
                    "state: {}: `run` starts cold and moves it aside to {}.unusable-<UTC time>",
                    u.why,
                    st.path.display()
                ),
                Loaded::Unusable(u) => format!("state: {}: `run` starts cold", u.why),
            });
        }
        lines
    }
}

/// The stage: one attitude filter, and what it saw.
pub struct AttitudeStage {
    filter: Attitude,
    /// The magnetometer state's writer and how many samples apart it saves.
    writer: Option<(StateWriter, u64)>,
    since_save: u64,
    /// How the stage started: warm, or cold and why.
    warm: WarmStart,
    /// What `prewarm` runs the filter's code on (a copy of its state; the result dropped),
    /// and the last sample's inputs to run it with.
    spare: Attitude,
    last: Option<Inputs>,
    coasting: u64,
    no_gravity: u64,
    samples: u64,
    /// Samples whose magnetometer block corrected the heading, and those it was rejected at
    /// (disturbed, inconsistent, or settling after either).
    mag_used: u64,
    mag_rejected: u64,
    /// The field's last verdict other than settling was a rejection (not a use).
    disturbed: bool,
}

/// What [`Attitude::push`] takes: the rate, the accelerometer's reading, the bias removed.
type Inputs = (
    [f64; 3],
    Option<[f64; 3]>,
    Option<[f64; 3]>,
    Option<Upstream>,
);

impl Drop for AttitudeStage {
    /// At shutdown: the last state, written before the stage is gone.
    fn drop(&mut self) {
        if let (Some((writer, _)), Some(learnt)) = (self.writer.take(), self.filter.mag_learnt()) {
            if self.samples > 0 {
                writer.finish(learnt);
            }
        }
    }
}

impl Stage for AttitudeStage {
    fn warm_start(&self) -> Option<WarmStart> {
        self.writer.as_ref().map(|_| self.warm.clone())
    }

    fn process(&mut self, input: &GyroSample) -> Option<GyroSample> {
        let mut out = *input;
        let upstream = input
            .drift_std
            .iter()
            .all(|s| *s >= 0.0)
            .then_some(Upstream {
                bias: input.drift,
                sd: input.drift_std,
            });
        let inputs = (
            input.rate,
            input.accel_reading(),
            input.mag_reading(),
            upstream,
        );
        self.last = Some(inputs);
        let step = self.filter.push_mag(inputs.0, inputs.1, inputs.2, inputs.3);
        let rejected = match step.mag {
            Some(MagUse::Used) => {
                self.mag_used += 1;
                self.disturbed = false;
                false
            }
            Some(MagUse::Disturbed | MagUse::Inconsistent) => {
                self.disturbed = true;
                true
            }
            // Settling after a disturbance is its end, not yet trusted: rejected. The 2 s of
            // settling after the first fix are no disturbance.
            Some(MagUse::Settling) => self.disturbed,
            _ => false,
        };
        if rejected {
            out.sensors |= SENSOR_MAG_REJECTED;
            self.mag_rejected += 1;
        }
        if step.heading_absolute {
            out.sensors |= SENSOR_HEADING_ABSOLUTE;
        }
        let [w, x, y, z] = step.quat;
        out.orientation = [x, y, z, w];
        // The inclination's error is a tilt in any horizontal direction: half its variance
        // about each horizontal axis. The heading's sd is the magnetometer filter's once the
        // heading is absolute (`Attitude::push_mag`), the relative one's before.
        let tilt = step.inclination_sd * std::f64::consts::FRAC_1_SQRT_2;
        out.orientation_std = [
            tilt,
            tilt,
            step.heading_sd.unwrap_or(DRIFT_STD_NOT_PROVIDED),
        ];
        out.sensors |= SENSOR_ORIENTATION;
        if step.coasting {
            out.sensors |= SENSOR_ORIENTATION_COASTING;
            self.coasting += 1;
        }
        if step.no_gravity {
            out.sensors |= SENSOR_ORIENTATION_NO_GRAVITY;
            self.no_gravity += 1;
        }
        self.samples += 1;
        if let Some((writer, every)) = &self.writer {
            self.since_save += 1;
            if self.since_save >= *every {
                self.since_save = 0;
                if let Some(learnt) = self.filter.mag_learnt() {
                    writer.offer(|s| *s = learnt);
                }
            }
        }
        Some(out)
    }

    /// After a sleep VQF's code has left the cache more than its state (`benches/attitude.rs`):
    /// run it once on a copy, with the last sample.
    fn prewarm(&mut self) {
        if let Some((rate, accel, mag, upstream)) = self.last {
            self.spare.clone_from(&self.filter);
            std::hint::black_box(self.spare.push_mag(rate, accel, mag, upstream));
        }
    }

    fn learnt(&self) -> Vec<String> {
        let mut lines = vec![format!(
            "attitude: {} samples, {} coasting on the gyro (no valid accelerometer), {} in free \
             fall or a shock",
            self.samples, self.coasting, self.no_gravity
        )];
        if self.filter.config().mag.is_some() {
            lines.push(format!(
                "attitude: the magnetometer corrected the heading at {} samples and was rejected \
                 at {} (a disturbed field: the heading rested on the gyro)",
                self.mag_used, self.mag_rejected
            ));
        }
        if let Some(l) = self.filter.mag_learnt() {
            lines.push(format!(
                "attitude: magnetometer {}",
                attitude_state::describe(&l)
            ));
        }
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::allan::STANDARD_GRAVITY;
    use crate::units::{AccelUnit, RateUnit};
    use crate::wire::{SENSOR_ACCEL, SENSOR_ACCEL_INVALID, SENSOR_MAG, SENSOR_MAG_INVALID};

    fn cx(white_noise: Option<f64>) -> Context {
        Context {
            rate_hz: 100.0,
            axes: 3,
            units: RateUnit::DegPerS,
            accel_units: AccelUnit::MPerS2,
            white_noise,
        }
    }

    fn stage(white_noise: Option<f64>) -> Box<dyn Stage> {
        AttitudeParams {
            filter: AttitudeConfig::default(),
            state: None,
            calibration: Calibration::IDENTITY,
        }
        .stage(&cx(white_noise))
        .unwrap()
    }

    /// A body tilted 20 deg about x, still: the sample carries its orientation, every other
    /// field as it came.
    #[test]
    fn the_sample_gains_its_orientation_and_keeps_the_rest() {
        let mut s = stage(Some(0.002));
        let tilt = 20f64.to_radians();
        let input = GyroSample {
            seq: 7,
            rate: [1e-4, -2e-4, 3e-4],
            drift: [1e-3, 0.0, 0.0],
            drift_std: [1e-5, 1e-5, 2e-5],
            accel: [0.0, tilt.sin(), tilt.cos()].map(|v| v * STANDARD_GRAVITY),
            sensors: SENSOR_ACCEL,
            ..GyroSample::default()
        };
        let mut out = None;
        for _ in 0..1000 {
            out = s.process(&input);
        }
        let out = out.unwrap();
        let kept = GyroSample {
            orientation: input.orientation,
            orientation_std: input.orientation_std,
            sensors: input.sensors,
            ..out
        };
        assert_eq!(kept, input);
        assert_eq!(out.sensors, SENSOR_ACCEL | SENSOR_ORIENTATION);
        let [x, _, _, w] = out.orientation;
        // A rotation of 20 deg about x takes the body's up, (0, sin 20, cos 20), to the
        // earth's (x, y, z, w order).
        let about_x = 2.0 * x.atan2(w);
        assert!((about_x.to_degrees() - 20.0).abs() < 0.5, "{out:?}");
        assert!(out.orientation_std.iter().all(|s| *s > 0.0), "{out:?}");
        // 10 s at 2e-5 rad/s on z (the body's z is 20 deg off the vertical) and N 0.002 deg/s.
        let h = out.orientation_std[2];
        assert!(h > 2e-5 * 10.0 * tilt.cos() && h < 1e-3, "{h}");
        assert!(s.learnt()[0].starts_with("attitude: 1000 samples, 0 coasting"));
    }

    /// No accelerometer, a held one, no drift_std: flagged coasting, the heading's sd not
    /// provided, never a NaN.
    #[test]
    fn without_the_accelerometer_it_coasts_and_says_so() {
        let mut s = stage(None);
        for sensors in [0, SENSOR_ACCEL | SENSOR_ACCEL_INVALID] {
            let out = s
                .process(&GyroSample {
                    accel: [f64::NAN; 3],
                    sensors,
                    ..GyroSample::default()
                })
                .unwrap();
            assert_eq!(
                out.sensors & (SENSOR_ORIENTATION | SENSOR_ORIENTATION_COASTING),
                SENSOR_ORIENTATION | SENSOR_ORIENTATION_COASTING
            );
            assert_eq!(out.orientation_std[2], DRIFT_STD_NOT_PROVIDED);
            assert!(out.orientation.iter().all(|v| v.is_finite()));
        }
    }

    /// A stage with `use_mag` at its defaults, at 100 Hz.
    fn mag_stage() -> Box<dyn Stage> {
        AttitudeParams {
            filter: AttitudeConfig {
                mag: Some(MagConfig::default()),
                ..AttitudeConfig::default()
            },
            state: None,
            calibration: Calibration::IDENTITY,
        }
        .stage(&cx(Some(0.002)))
        .unwrap()
    }

    /// A level body, still, turned `yaw` anticlockwise from ENU, in a field of 20 uT north and
    /// 40 uT down (tesla, as the wire carries it).
    fn still_in_field(yaw: f64) -> GyroSample {
        GyroSample {
            drift_std: [1e-5; 3],
            accel: [0.0, 0.0, STANDARD_GRAVITY],
            // The field in the body: Rz(-yaw) (0, 20, -40) uT.
            mag: [20e-6 * yaw.sin(), 20e-6 * yaw.cos(), -40e-6],
            sensors: SENSOR_ACCEL | SENSOR_MAG,
            ..GyroSample::default()
        }
    }

    /// With `use_mag`, a level body turned 30 deg anticlockwise from ENU (yaw 30 deg), still,
    /// in a field of 20 uT north and 40 uT down (tesla, as the wire carries it): the heading becomes
    /// absolute, its standard deviation the magnetometer's; a sample whose reading is invalid
    /// or absent keeps it, and never a NaN.
    #[test]
    fn with_use_mag_the_heading_is_absolute() {
        let mut s = mag_stage();
        let yaw_true = 30f64.to_radians();
        let input = still_in_field(yaw_true);
        let mut out = None;
        for _ in 0..1000 {
            out = s.process(&input);
        }
        let out = out.unwrap();
        let bits = SENSOR_HEADING_ABSOLUTE | SENSOR_MAG_REJECTED;
        assert_eq!(out.sensors & bits, SENSOR_HEADING_ABSOLUTE, "{out:?}");
        let [_, _, yaw] = crate::attitude::roll_pitch_yaw(out.orientation);
        assert!((yaw - yaw_true).to_degrees().abs() < 1.0, "{out:?}");
        let sd = out.orientation_std[2];
        assert!(sd > 0.5f64.to_radians() && sd < 5f64.to_radians(), "{sd}");
        for sensors in [SENSOR_ACCEL, SENSOR_ACCEL | SENSOR_MAG | SENSOR_MAG_INVALID] {
            let o = s
                .process(&GyroSample {
                    mag: [f64::NAN; 3],
                    sensors,
                    ..input
                })
                .unwrap();
            assert!(o.orientation.iter().all(|v| v.is_finite()), "{o:?}");
            let [_, _, y] = crate::attitude::roll_pitch_yaw(o.orientation);
            assert!((y - yaw).abs() < 1e-3, "{o:?}");
        }
        let learnt = s.learnt();
        assert!(
            learnt[1].starts_with("attitude: the magnetometer corrected"),
            "{learnt:?}"
        );
    }

    /// With `use_mag`, still in a clean field: no sample says the heading is absolute before
    /// the field was trusted (no reading yet, then the first block still open), and every
    /// sample from the first trusted block on does, with the magnetometer filter's sd; a magnet
    /// brought close (30 uT more, fixed in the body) is flagged rejected while the heading
    /// stays absolute on the gyro, and the flag clears once it is gone and the field settled.
    #[test]
    fn the_sensors_word_says_when_the_heading_is_absolute_and_the_field_rejected() {
        let mut s = mag_stage();
        let yaw_true = 30f64.to_radians();
        let clean = still_in_field(yaw_true);
        let bits = SENSOR_HEADING_ABSOLUTE | SENSOR_MAG_REJECTED;
        let mut run = |input: &GyroSample, n: usize| -> Vec<GyroSample> {
            (0..n).map(|_| s.process(input).unwrap()).collect()
        };
        let without = run(
            &GyroSample {
                sensors: SENSOR_ACCEL,
                ..clean
            },
            100,
        );
        assert!(without.iter().all(|o| o.sensors & bits == 0));
        let trusted = run(&clean, 500);
        let first = trusted
            .iter()
            .position(|o| o.sensors & SENSOR_HEADING_ABSOLUTE != 0)
            .expect("the heading became absolute");
        // 100 samples before, the 25 ms block (3 samples) holds one: the first reading does
        // not end it, the next two do.
        assert!((1..=2).contains(&first), "{first}");
        assert!(trusted[first..]
            .iter()
            .all(|o| o.sensors & bits == SENSOR_HEADING_ABSOLUTE));
        // The relative heading's sd (0 at the start, 1e-5 rad/s since) becomes the
        // magnetometer's, with its 1 deg floor.
        assert!(trusted[first - 1].orientation_std[2] < 1e-3, "{trusted:?}");
        assert!(trusted[first].orientation_std[2] >= 1f64.to_radians());
        let settled_sd = trusted[499].orientation_std[2];

        let mut magnet = clean;
        magnet.mag[0] += 30e-6;
        let near = run(&magnet, 300);
        let r = near
            .iter()
            .position(|o| o.sensors & SENSOR_MAG_REJECTED != 0)
            .expect("the magnet was rejected");
        assert!(r <= 3, "{r}");
        assert!(near[r..].iter().all(|o| o.sensors & bits == bits));
        let [_, _, yaw] = crate::attitude::roll_pitch_yaw(near[299].orientation);
        assert!((yaw - yaw_true).to_degrees().abs() < 1.0, "{:?}", near[299]);
        assert!(near[299].orientation_std[2] > settled_sd, "{:?}", near[299]);

        // Gone: rejected while the spread's 1 s window still holds it (about 4 s for 30 uT to
        // fade under 8% of the field) and 2 s after (settling), then used again.
        let back = run(&clean, 1000);
        assert_ne!(back[50].sensors & SENSOR_MAG_REJECTED, 0, "{:?}", back[50]);
        assert_eq!(
            back[999].sensors & bits,
            SENSOR_HEADING_ABSOLUTE,
            "{:?}",
            back[999]
        );
    }
}
