//! `predict.bias`: the gyro bias as a Kalman filter state whose noise comes from the sensor's
//! own IEEE 952 terms ([`crate::drift::bias`]), re-measured while the sensor is still, held
//! (its uncertainty growing) while it moves. No training: the terms of a named sensor, or the
//! terms `driftless allan` measured on one's own static log.
//!
//! ```toml
//! [[stage]]
//! name = "predict"
//! kind = "predict.bias"
//! input = "demo/denoised"
//! output = "demo/predicted"
//! profile = "adis16405"        # a named sensor's terms; or your own, all three at least, as
//! #                            # `driftless allan LOG --rate HZ --stage` prints them:
//! # arw = 2.3                  # N, deg/sqrt(h)
//! # bias_instability = 34.0    # B, deg/h
//! # rrw = 0.0                  # K, deg/h/sqrt(h)
//! # lsb = 0.05                 # output step of the raw rate, input units (0: none)
//! # accel_vrw = 0.2            # the accelerometer's N, m/s/sqrt(h), and B, mg (`allan
//! # accel_bias_instability = 0.3  # --stage` with --accel-column writes both)
//! ```
//!
//! The published rate is the denoised rate minus the estimate. Flags: [`FLAG_STILL`] when every
//! axis is still, [`FLAG_MOVING`] when any axis moves (before the first stop too),
//! [`FLAG_WARMING_UP`] while an axis has nothing to go on: its detector's first window is
//! filling, or no still sample has been seen yet (nothing is subtracted there). Moving before the
//! first stop is therefore `MOVING | WARMING_UP`.

use super::accel_terms::{self, ACCEL_BIAS_INSTABILITY, ACCEL_VRW};
use super::predict::motion_flags;
use crate::drift::accel_rest::AccelRest;
use crate::drift::bias::{
    accel_rest_from_terms, default_walk_bounds, up_from_mount, AccelTerms, BiasMode, BiasModel,
    BiasTerms, BiasTracker, Instability, LearnWalk, TrackerConfig, DEFAULT_INITIAL_SD,
};
use crate::io::InputError;
pub use crate::stages::bias_odometry::VehicleUp;
use crate::stages::bias_odometry::{tilt_deg, up_word, Odometry};
use crate::stages::bias_state::{self, Loaded, Owner, Saved, StateWriter, WarmStart};
use crate::stages::contract::{Kind, Params, Role, Stage};
use crate::stages::contract::{SideInput, SideValue};
use crate::stages::schema::{Context, DefaultValue, Key, Table, Type};
use crate::stages::stop_rule::{StopRule, STOP_MAX_AGE_S, STOP_SPEED_OF_SIGNAL};
use crate::wire::{
    GyroSample, OdometryStats, StopSignal, FLAG_STOP_CONTRADICTED, FLAG_VEHICLE_MOVING,
    FLAG_VEHICLE_STOPPED, SENSOR_ACCEL, STOP_CLOCK_SAMPLES,
};
#[cfg(doc)]
use crate::wire::{FLAG_MOVING, FLAG_STILL, FLAG_WARMING_UP};
use std::path::PathBuf;
use std::time::Duration;

const PROFILE: Key = Key {
    name: "profile",
    ty: Type::Choice(&["adis16405", "adxrs450"]),
    default: DefaultValue::Noted(
        &DefaultValue::Word("adis16405"),
        " (unless arw, bias_instability and rrw are all given)",
    ),
    doc: "the noise terms of a named sensor; with it, any term given replaces that sensor's",
};
const ARW: Key = Key {
    name: "arw",
    ty: Type::Positive(1e6),
    default: DefaultValue::Derived("the profile's (without a profile: required)"),
    doc: "angle random walk N, deg/sqrt(h) (as `driftless allan` prints it)",
};
const BIAS_INSTABILITY: Key = Key {
    name: "bias_instability",
    ty: Type::NonNegative,
    default: DefaultValue::Derived("the profile's (without a profile: required)"),
    doc: "bias instability B, deg/h",
};
const RRW: Key = Key {
    name: "rrw",
    ty: Type::NonNegative,
    default: DefaultValue::Derived("the profile's (without a profile: required)"),
    doc: "rate random walk K, deg/h/sqrt(h)",
};
const QUANTIZATION: Key = Key {
    name: "quantization",
    ty: Type::NonNegative,
    default: DefaultValue::Derived("the profile's (without a profile: 0)"),
    doc: "quantisation noise Q, deg (as `driftless allan` prints it)",
};
const LSB: Key = Key {
    name: "lsb",
    ty: Type::NonNegative,
    default: DefaultValue::Derived("the profile's (without a profile: 0)"),
    doc: "output step of the raw rate, input units (0: not quantised)",
};
const INITIAL_SD: Key = Key {
    name: "initial_sd",
    ty: Type::Positive(1e6),
    default: DefaultValue::Noted(&DefaultValue::Float(DEFAULT_INITIAL_SD), " deg/s"),
    doc: "spread of the turn-on bias before the first stop, input units",
};
const DELAY_S: Key = Key {
    name: "delay_s",
    ty: Type::FloatIn(0.0, 60.0),
    default: DefaultValue::Float(TrackerConfig::DEFAULT_DELAY_S),
    doc: "a still sample enters the filter only after the sensor stayed still this long after it",
};

const LEARN_WALK: Key = Key {
    name: "learn_walk",
    ty: Type::Choice(&["given-stops", "confirmed-stops", "always", "off"]),
    default: DefaultValue::Word(TrackerConfig::DEFAULT_LEARN_WALK.name()),
    doc: "which stops teach the filter how fast this unit's bias wanders: stops given from outside (given-stops), those and the stops both sensors confirm (confirmed-stops: the accelerometer quiet throughout; without one, the same as given-stops), every stop (always: our gyro detector's too), or none (off: keep the terms' walk)",
};
const WALK_MIN: Key = Key {
    name: "walk_min",
    ty: Type::Positive(1e9),
    default: DefaultValue::Derived("the terms' walk / 100"),
    doc: "least walk learnt, as a rate random walk in deg/h/sqrt(h)",
};
const WALK_MAX: Key = Key {
    name: "walk_max",
    ty: Type::Positive(1e9),
    default: DefaultValue::Derived("the terms' walk x 10"),
    doc: "largest walk learnt, deg/h/sqrt(h)",
};

const STOP_INPUT: Key = Key {
    name: "stop_input",
    ty: Type::Str("a service of StopSignal another process publishes"),
    default: DefaultValue::Absent("none: our own stillness detector alone"),
    doc: "the vehicle's stop signal (wheel odometry, speed): trusted while fresh, checked against the gyro; our detector decides while it is stale",
};
const VEHICLE_UP: Key = Key {
    name: "vehicle_up",
    ty: Type::Choice(&["+x", "-x", "+y", "-y", "+z", "-z", "gravity"]),
    default: DefaultValue::Absent(
        "none: a yaw rate on stop_input is refused (an error line at its first message), never used",
    ),
    doc: "which gyro axis, and which way, is the vehicle's up: the yaw rate on stop_input (counter-clockwise seen from above positive) is that axis's rate times its sign. \"gravity\": the axis nearest the accelerometer's specific force over the first second at rest (within 30 deg), the yaw rate unused until then. A configured axis is checked against gravity at the first rest and by the first turns: either disagreeing refuses the yaw rate, said once with the fix",
};
const MOUNT: Key = Key {
    name: "mount",
    ty: Type::Str("a rotation as the Linux IIO mount matrix prints it: \"x0, y0, z0; x1, y1, z1; x2, y2, z2\""),
    default: DefaultValue::Absent("none: vehicle_up says it"),
    doc: "instead of vehicle_up: the rotation from the gyro's frame to the vehicle's (x forward, y left, z up), row by row. Its third row is the vehicle's up in the gyro's frame: the axis nearest it (within 30 deg) takes the yaw rate times the up's component along it. Checked against gravity at the first rest and by the first turns, as vehicle_up is",
};
const ODOMETRY: Key = Key {
    name: "odometry",
    ty: Type::Bool,
    default: DefaultValue::Noted(
        &DefaultValue::Bool(true),
        " (with vehicle_up): a finite yaw rate is used",
    ),
    doc: "true: while the vehicle moves, each stop_input message with a finite yaw rate teaches the bias of the vehicle_up axis (its scale learnt too, slips caught by an innovation test); false: the yaw rate is ignored",
};
const STATE_FILE: Key = Key {
    name: "state_file",
    ty: Type::Str("a file path, relative to the pipeline file"),
    default: DefaultValue::Absent("none: every start is cold"),
    doc: "where the filter's state is saved (at shutdown and every state_every_s) and resumed from at the next start, grown by the time between: corrected from the first sample",
};
const STATE_REQUIRED: Key = Key {
    name: "state_required",
    ty: Type::Bool,
    default: DefaultValue::Noted(
        &DefaultValue::Bool(false),
        ": an unusable state_file costs the warm start, never the start",
    ),
    doc: "true: a state_file that is there but cannot be used (garbage, another pipeline's or other terms', unreadable) stops the pipeline (exit 2), as before this key, instead of a cold start that moves it aside (`<name>.unusable-<UTC time>`); a missing one is still a cold start",
};
const STATE_EVERY_S: Key = Key {
    name: "state_every_s",
    ty: Type::Positive(86_400.0),
    default: DefaultValue::Float(120.0),
    doc: "how often the state is saved while running (a daemon killed without its shutdown resumes from the last save)",
};

/// A walk in (deg/s)^2/s as a rate random walk in deg/h/sqrt(h), the unit of `rrw`.
pub fn walk_to_rrw(walk: f64) -> f64 {
    walk.max(0.0).sqrt() * 216_000.0
}

/// `predict.bias`.
pub const KIND: Kind = Kind {
    name: "predict.bias",
    role: Role::Process,
    summary: "the bias as a Kalman state from the gyro's Allan terms, re-measured while still, held while moving; no training needed",
    keys: &[
        PROFILE,
        ARW,
        BIAS_INSTABILITY,
        RRW,
        QUANTIZATION,
        LSB,
        ACCEL_VRW,
        ACCEL_BIAS_INSTABILITY,
        INITIAL_SD,
        DELAY_S,
        LEARN_WALK,
        WALK_MIN,
        WALK_MAX,
        STOP_INPUT,
        STOP_MAX_AGE_S,
        STOP_SPEED_OF_SIGNAL,
        VEHICLE_UP,
        MOUNT,
        ODOMETRY,
        STATE_FILE,
        STATE_EVERY_S,
        STATE_REQUIRED,
    ],
    parse,
};

/// `predict.bias` parameters: the terms (deg/s based) and the tracker's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct BiasParams {
    /// The noise terms, deg/s based.
    pub terms: BiasTerms,
    /// The accelerometer's noise terms (`accel_vrw`, `accel_bias_instability`), m/s^2 based.
    pub accel: AccelTerms,
    /// Stillness gating and delay.
    pub tracker: TrackerConfig,
    /// The vehicle's stop signal, if any.
    pub stop: Option<StopConfig>,
    /// Where the state is saved and resumed from, if anywhere.
    pub state: Option<StateConfig>,
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
    /// `state_required`: a file that cannot be used stops the pipeline.
    pub required: bool,
    /// What the file held when the pipeline was read (what `validate` says). The stage reads
    /// it again when it is built: it may have changed since (an offline run builds the stage
    /// once per case, each saving at its end).
    pub loaded: Loaded,
}

/// How `predict.bias` reads a stop signal ([`StopSignal`]).
#[derive(Debug, Clone, PartialEq)]
pub struct StopConfig {
    /// Its service.
    pub service: String,
    /// How it is judged (`stop_speed`, `stop_max_age_s`).
    pub rule: StopRule,
    /// `vehicle_up` or `mount`: the gyro axis that is the vehicle's up, or gravity's.
    pub up: Option<VehicleUp>,
    /// `odometry`: whether a yaw rate (with `vehicle_up`) teaches the bias while moving.
    pub odometry: bool,
}

impl StopConfig {
    /// What `signal` says at time `now_ns` on its clock (the sample's ingest, or its own time
    /// for a replay's logged signal): stands, moves, or unknown (stale, from the future by
    /// more than its age, or not said).
    pub fn judge(&self, signal: &StopSignal, now_ns: u64) -> Option<bool> {
        if signal.t_ns == 0 {
            return None;
        }
        let stands = match signal.stopped {
            0 => Some(false),
            1 => Some(true),
            _ => None,
        };
        self.rule
            .judge(now_ns.abs_diff(signal.t_ns), signal.speed_m_s, stands)
    }
}

/// `walk_min` and `walk_max` (deg/h/sqrt(h)) as the tracker's learnt walk's range, either
/// one defaulting around the walk `terms` configure; `None` if neither is given.
fn walk_range(t: &mut Table<'_, '_>, terms: &BiasTerms) -> Result<Option<(f64, f64)>, InputError> {
    let walk_min = t.float(&WALK_MIN)?;
    let walk_max = t.float(&WALK_MAX)?;
    if walk_min.is_some() || walk_max.is_some() {
        let configured = BiasModel::new(terms, t.cx.rate_hz, Instability::from_terms(terms))
            .map(|m| m.walk_per_s(t.cx.rate_hz))
            .unwrap_or(0.0);
        let (lo, hi) = default_walk_bounds(configured);
        let from_rrw = |k: f64| (k / 216_000.0).powi(2);
        let (lo, hi) = (walk_min.map_or(lo, from_rrw), walk_max.map_or(hi, from_rrw));
        if lo > hi {
            return Err(t.error(format!(
                "predict.bias: walk_min ({}) is above walk_max ({}) deg/h/sqrt(h)",
                walk_to_rrw(lo),
                walk_to_rrw(hi)
            )));
        }
        return Ok(Some((lo, hi)));
    }
    Ok(None)
}

/// The saved state's settings (`state_file`, `state_every_s`, `state_required`), with the
/// state loaded and checked against this stage now; `None` without a `state_file`.
fn state(
    t: &mut Table<'_, '_>,
    terms: &BiasTerms,
    tracker: &TrackerConfig,
) -> Result<Option<StateConfig>, InputError> {
    let src = t.src;
    Ok(match t.get::<String>(&STATE_FILE)? {
        Some(file) => {
            let path = src.resolve(file.get_ref());
            let every_s = t.float_or_default(&STATE_EVERY_S)?;
            let required = t.bool_or_default(&STATE_REQUIRED)?;
            let owner = Owner {
                pipeline: t.owner.0.to_string(),
                stage: t.owner.1.to_string(),
                axes: t.cx.axes,
                rate_hz: t.cx.rate_hz,
                terms: *terms,
            };
            let probe = BiasTracker::new(terms, t.cx.rate_hz, tracker)
                .map_err(|e| t.error(format!("predict.bias: {e}")))?;
            let loaded = load_checked(&path, &owner, &probe);
            if let (Loaded::Unusable(u), true) = (&loaded, required) {
                return Err(src.span(&file, refusal(u)));
            }
            Some(StateConfig {
                path,
                owner,
                every: ((every_s * t.cx.rate_hz).round() as u64).max(1),
                required,
                loaded,
            })
        }
        None => {
            for key in [&STATE_EVERY_S, &STATE_REQUIRED] {
                if t.has(key) {
                    return Err(t.error(format!("predict.bias: {} needs state_file", key.name)));
                }
            }
            None
        }
    })
}

/// The stop signal's settings (`stop_input`, its rule, `vehicle_up`, `odometry`); `None`
/// without a `stop_input`, whose keys then are refused.
fn stop(t: &mut Table<'_, '_>) -> Result<Option<StopConfig>, InputError> {
    let src = t.src;
    let input = t.get::<String>(&STOP_INPUT)?;
    let (rule, set) = StopRule::parse(t, &STOP_SPEED_OF_SIGNAL)?;
    let word = t.choice(&VEHICLE_UP, "vehicle_up", true)?;
    let mount = t.get::<String>(&MOUNT)?;
    let odometry_given = t.has(&ODOMETRY);
    let odometry = t.bool_or_default(&ODOMETRY)?;
    let up = vehicle_up(t, word.as_deref(), mount.as_ref())?;
    Ok(match input {
        Some(v) => Some(StopConfig {
            service: src.service(&v)?,
            rule,
            up,
            odometry,
        }),
        None => {
            let needs = set
                .or(word.map(|_| VEHICLE_UP.name))
                .or(mount.map(|_| MOUNT.name))
                .or(odometry_given.then_some(ODOMETRY.name));
            match needs {
                Some(key) => {
                    return Err(t.error(format!(
                        "predict.bias: {key} needs stop_input (the service of the stop signal)"
                    )))
                }
                None => None,
            }
        }
    })
}

/// The vehicle's up from `vehicle_up`'s `word` or from `mount`, checked against the
/// pipeline's axes.
fn vehicle_up(
    t: &Table<'_, '_>,
    word: Option<&str>,
    mount: Option<&toml::Spanned<String>>,
) -> Result<Option<VehicleUp>, InputError> {
    let axes = t.cx.axes;
    let up =
        match (word, mount) {
            (Some(_), Some(m)) => {
                return Err(t.src.span(
                    m,
                    "predict.bias: give vehicle_up or mount, not both (each says where the up is)",
                ))
            }
            (Some("gravity"), None) if axes < 3 => return Err(t.error(
                "predict.bias: vehicle_up = \"gravity\" needs 3 axes (the up axis is any of them)",
            )),
            (Some("gravity"), None) => VehicleUp::Gravity,
            (Some(word), None) => {
                let axis = match &word[1..] {
                    "x" => 0,
                    "y" => 1,
                    _ => 2,
                };
                let sign = if word.starts_with('-') { -1.0 } else { 1.0 };
                VehicleUp::Axis { axis, sign }
            }
            (None, Some(m)) => {
                let (axis, c) = read_mount(m.get_ref()).map_err(|e| t.src.span(m, e))?;
                VehicleUp::Mount { axis, c }
            }
            (None, None) => return Ok(None),
        };
    match up.axis() {
        Some((axis, _)) if axis >= axes => Err(t.error(format!(
            "predict.bias: {} but the pipeline has {axes} axis(es): name one of its axes",
            up.describe(),
        ))),
        _ => Ok(Some(up)),
    }
}

/// `mount`'s text, as the Linux IIO mount matrix prints it (`"x0, y0, z0; x1, y1, z1; x2, y2,
/// z2"`), as the up axis and its share of the yaw rate ([`up_from_mount`]).
fn read_mount(text: &str) -> Result<(usize, f64), String> {
    let rows: Vec<&str> = text.split(';').collect();
    let mut m = [[0.0; 3]; 3];
    if rows.len() != 3 {
        return Err(format!(
            "mount: three rows separated by ';', got {}",
            rows.len()
        ));
    }
    for (row, text) in m.iter_mut().zip(rows) {
        let cells: Vec<&str> = text.split(',').map(str::trim).collect();
        if cells.len() != 3 {
            return Err(format!(
                "mount: each row three numbers separated by ',', got {:?}",
                text.trim()
            ));
        }
        for (v, cell) in row.iter_mut().zip(cells) {
            *v = cell
                .parse()
                .map_err(|_| format!("mount: {cell:?} is not a number"))?;
        }
    }
    up_from_mount(m).map_err(|e| format!("mount: {e}"))
}

fn parse(t: &mut Table<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    let profile = t.choice(&PROFILE, "profile", false)?;
    let arw = t.float(&ARW)?;
    let b = t.float(&BIAS_INSTABILITY)?;
    let k = t.float(&RRW)?;
    let q = t.float(&QUANTIZATION)?;
    let lsb = t.float(&LSB)?;
    let initial_sd = t.float(&INITIAL_SD)?;
    let accel = accel_terms::read(t)?;
    let delay_s = t.float_or_default(&DELAY_S)?;
    // Your own terms, or a named sensor's: never a sensor's terms for the ones you left out
    // unless you name it (a gyro that is not an ADIS16405 must not get its noise silently).
    let given = [
        (ARW.name, arw.is_some()),
        (BIAS_INSTABILITY.name, b.is_some()),
        (RRW.name, k.is_some()),
    ];
    let own = profile.is_none() && given.iter().any(|(_, g)| *g);
    if own {
        let missing: Vec<&str> = given.iter().filter(|(_, g)| !g).map(|(n, _)| *n).collect();
        if !missing.is_empty() {
            return Err(t.error(format!(
                "predict.bias: {} not given: give arw, bias_instability and rrw (`driftless \
                 allan LOG --rate HZ --stage` prints them all), or name the sensor whose terms \
                 fill in the rest (profile = \"adis16405\")",
                missing.join(" and ")
            )));
        }
    }
    let name = profile.as_deref().unwrap_or(PROFILE.default.word());
    let mut terms = BiasTerms::profile(name).map_err(|e| t.error(format!("predict.bias: {e}")))?;
    if own {
        // Not that sensor: what is not given is not there.
        terms.q = 0.0;
        terms.lsb = 0.0;
    }
    // Given terms are in the units `driftless allan` prints; the filter works in deg/s.
    let to_deg = t.cx.units.to_rad_per_s().to_degrees();
    if let Some(n) = arw {
        terms.n = n / 60.0;
    }
    if let Some(b) = b {
        terms.b = b / 3600.0;
    }
    if let Some(k) = k {
        terms.k = k / 3600.0 / 60.0;
    }
    if let Some(q) = q {
        terms.q = q;
    }
    if let Some(l) = lsb {
        terms.lsb = l * to_deg;
    }
    // A given spread is in input units; the default, as its note says, in deg/s.
    terms.initial_sd = initial_sd.map_or(INITIAL_SD.default.float(), |s| s * to_deg);
    let mut tracker = TrackerConfig {
        delay_s,
        ..TrackerConfig::default()
    };
    let learn_walk = t.choice_or_default(&LEARN_WALK, "learn_walk", false)?;
    for l in [
        LearnWalk::Off,
        LearnWalk::GivenStops,
        LearnWalk::ConfirmedStops,
        LearnWalk::Always,
    ] {
        if l.name() == learn_walk {
            tracker.learn_walk = l;
        }
    }
    tracker.walk_range = walk_range(t, &terms)?;
    let stop = stop(t)?;
    let state = state(t, &terms, &tracker)?;
    let params = BiasParams {
        terms,
        accel,
        tracker,
        stop,
        state,
    };
    BiasTracker::new(&params.terms, t.cx.rate_hz, &params.tracker)
        .map_err(|e| t.error(format!("predict.bias: {e}")))?;
    accel_rest_from_terms(&params.accel, t.cx.rate_hz, &params.tracker)
        .map_err(|e| t.error(format!("predict.bias: {e}")))?;
    Ok(Box::new(params))
}

impl Params for BiasParams {
    fn white_noise(&self) -> Option<f64> {
        Some(self.terms.n)
    }

    fn assumed_step(&self) -> Option<f64> {
        Some(self.terms.lsb)
    }

    fn stage(&self, cx: &Context) -> Result<Box<dyn Stage>, String> {
        let mut trackers = Vec::with_capacity(cx.axes);
        for _ in 0..cx.axes {
            trackers.push(
                BiasTracker::new(&self.terms, cx.rate_hz, &self.tracker)
                    .map_err(|e| e.to_string())?,
            );
        }
        let odometry = match &self.stop {
            Some(StopConfig {
                up: Some(up),
                odometry: true,
                ..
            }) => {
                let r = |k: usize| {
                    trackers
                        .get(k)
                        .map_or(0.0, |t| t.filter().model().measurement_variance())
                };
                let odometry = Odometry::new(*up, [r(0), r(1), r(2)], cx.rate_hz)?;
                // The up axis carries the scale from the start (every axis while gravity has
                // not named it), so that a saved one is resumed; it stays apart from the bias
                // until a span.
                for (k, t) in trackers.iter_mut().enumerate() {
                    if up.axis().is_none_or(|(axis, _)| axis == k) {
                        t.add_scale(odometry.scale_prior());
                    }
                }
                Some(odometry)
            }
            _ => None,
        };
        let mut writer = None;
        let mut warm = WarmStart::NotConfigured;
        if let Some(st) = &self.state {
            warm = match load_checked(&st.path, &st.owner, &trackers[0]) {
                Loaded::Missing => WarmStart::ColdNoFile {
                    path: st.path.clone(),
                },
                Loaded::Saved(saved) => resume(&mut trackers, &saved, st, cx.rate_hz),
                // Changed since the pipeline was read.
                Loaded::Unusable(u) if st.required => return Err(refusal(&u)),
                Loaded::Unusable(u) => cold_unusable(&st.path, &u),
            };
            writer = Some((
                bias_state::start_writer(st.path.clone(), st.owner.clone())?,
                st.every,
            ));
        }
        let rest = accel_rest_from_terms(&self.accel, cx.rate_hz, &self.tracker)
            .map_err(|e| e.to_string())?;
        Ok(Box::new(BiasStage {
            odometry,
            fresh: None,
            refused_yaw: false,
            trackers,
            rest: AccelRest::new(rest),
            accel_seen: false,
            learn: self.tracker.learn_walk,
            stop: self.stop.clone(),
            signal: None,
            logged_stops: false,
            writer,
            since_save: 0,
            samples: 0,
            warm,
            accel_std: self.accel.white_std(cx.rate_hz),
        }))
    }

    fn side_inputs(&self) -> Vec<(String, SideInput)> {
        self.stop
            .iter()
            .map(|s| {
                let by_speed = s.rule.speed_m_s.is_some();
                (s.service.clone(), SideInput::Stop { by_speed })
            })
            .collect()
    }

    fn describe(&self, _input: Option<&str>, _output: &str) -> Vec<String> {
        let t = &self.terms;
        vec![format!(
            "terms: N {:.3} deg/sqrt(h), B {:.2} deg/h, K {:.3} deg/h/sqrt(h), Q {:.3e} deg, lsb {} deg/s; delay {} s",
            t.n * 60.0,
            t.b * 3600.0,
            t.k * 3600.0 * 60.0,
            t.q,
            t.lsb,
            self.tracker.delay_s
        )]
        .into_iter()
        .chain(
            self.stop
                .iter()
                .map(|s| format!("stop signal: {} ({})", s.service, s.rule.describe())),
        )
        .chain(self.stop.iter().filter_map(|s| {
            let up = match s.up? {
                VehicleUp::Axis { axis, sign } => format!("the gyro's {}", up_word(axis, sign)),
                VehicleUp::Mount { axis, c } => format!(
                    "along the gyro's {} ({:.1} deg from it, by mount)",
                    up_word(axis, c),
                    tilt_deg(c)
                ),
                VehicleUp::Gravity => {
                    "from gravity (the accelerometer over the first second at rest)".to_string()
                }
            };
            Some(if s.odometry {
                format!(
                    "odometry: the vehicle's up is {up}: while it moves, its yaw rate on {} \
                     teaches that axis's bias",
                    s.service
                )
            } else {
                format!("odometry: off (odometry = false): the yaw rate on {} is ignored", s.service)
            })
        }))
        .chain(self.state.iter().map(|st| match &st.loaded {
            Loaded::Missing => format!("state: none yet in {}: a cold start", st.path.display()),
            Loaded::Saved(_) => format!("state: {} (a warm start if not too old)", st.path.display()),
            Loaded::Unusable(u) if u.movable => format!(
                "state: {}: `run` starts cold and moves it aside to {}.unusable-<UTC time>",
                u.why,
                st.path.display()
            ),
            Loaded::Unusable(u) => format!("state: {}: `run` starts cold", u.why),
        }))
        .collect()
    }
}

/// The state in `path` for `owner`, and unusable too when its layout is not one `probe` (a
/// cold filter of the stage's) can resume from (a state of another driftless's model).
fn load_checked(path: &std::path::Path, owner: &Owner, probe: &BiasTracker) -> Loaded {
    let loaded = bias_state::load(path, owner);
    if let Loaded::Saved(saved) = &loaded {
        if let Some(e) = saved
            .filters
            .iter()
            .find_map(|f| probe.clone().resume(f, 0).err())
        {
            return Loaded::Unusable(bias_state::Unusable {
                why: format!("state_file {}: {e}", path.display()),
                movable: true,
            });
        }
    }
    loaded
}

/// The refusal of an unusable state under `state_required = true`.
fn refusal(u: &bias_state::Unusable) -> String {
    format!(
        "{}: state_required = true: remove it to start cold, or point state_file elsewhere",
        u.why
    )
}

/// Resume each axis from `saved`, grown by the time since it was saved; or, if that time is
/// unknown or the state is worth no more than the prior by now, start cold. Either way one
/// line says which.
fn resume(
    trackers: &mut [BiasTracker],
    saved: &Saved,
    st: &StateConfig,
    rate_hz: f64,
) -> WarmStart {
    let (shown, path) = (st.path.display(), st.path.clone());
    let Some(age) = saved.age() else {
        eprintln!(
            "driftless: warning: state_file {shown} was saved in the future (the clock was set \
             back?): the time since is unknown, so the filter starts cold"
        );
        return WarmStart::ColdFuture { path };
    };
    let steps = (age.as_secs_f64() * rate_hz).round() as u64;
    let mut fresh = trackers.to_vec();
    for (t, snap) in fresh.iter_mut().zip(&saved.filters) {
        // Checked by load_checked: a layout this filter cannot take is unusable there.
        if let Err(e) = t.resume(snap, steps) {
            let u = bias_state::Unusable {
                why: format!("state_file {shown}: {e}"),
                movable: true,
            };
            return cold_unusable(&st.path, &u);
        }
    }
    // Per axis: one that never learnt (a vehicle that never stopped teaches its up axis
    // alone, by the odometry) starts cold, and the others still resume.
    let worth: Vec<bool> = fresh
        .iter()
        .zip(trackers.iter())
        .map(|(f, cold)| f.filter().variance() < cold.filter().variance())
        .collect();
    let ago = humantime::format_duration(Duration::from_secs(age.as_secs()));
    if !worth.contains(&true) {
        eprintln!(
            "driftless: state_file {shown} is {ago} old: no better than the prior by now, so \
             the filter starts cold"
        );
        return WarmStart::ColdTooOld { path, age };
    }
    for ((t, f), _) in trackers
        .iter_mut()
        .zip(fresh)
        .zip(&worth)
        .filter(|(_, w)| **w)
    {
        *t = f;
    }
    let now: Vec<_> = trackers.iter().map(BiasTracker::snapshot).collect();
    let cold: Vec<&str> = ["x", "y", "z"]
        .iter()
        .zip(&worth)
        .filter(|(_, w)| !**w)
        .map(|(a, _)| *a)
        .collect();
    let cold = if cold.is_empty() {
        String::new()
    } else {
        format!(
            " ({} cold: no better than the prior by now)",
            cold.join(", ")
        )
    };
    eprintln!(
        "driftless: warm start from state_file {shown}, saved {ago} ago: {}{cold}",
        bias_state::describe(&now)
    );
    WarmStart::Warm { path, age }
}

/// A state that cannot be used costs the warm start, never the start (the file moved aside).
fn cold_unusable(path: &std::path::Path, u: &bias_state::Unusable) -> WarmStart {
    crate::stages::state_file::cold_unusable(path, u, "the filter")
}

/// The time of `sample` on the clock of `signal` ([`StopSignal::clock`]).
fn now_of(signal: &StopSignal, sample: &GyroSample) -> u64 {
    if signal.clock == STOP_CLOCK_SAMPLES {
        sample.t_ns
    } else {
        sample.ingest_ns
    }
}

/// One [`BiasTracker`] per axis, in deg/s; samples arrive in rad/s.
pub struct BiasStage {
    /// The vehicle's yaw rate, with `vehicle_up` and `odometry` on.
    odometry: Option<Odometry>,
    /// The stop signal that came since the last sample, if any.
    fresh: Option<StopSignal>,
    /// Whether a yaw rate without `vehicle_up` has been refused (said once).
    refused_yaw: bool,
    trackers: Vec<BiasTracker>,
    /// The accelerometer's rest test, for the whole body (its verdict aids every axis).
    rest: AccelRest,
    /// Whether a sample carried a valid accelerometer reading.
    accel_seen: bool,
    learn: LearnWalk,
    stop: Option<StopConfig>,
    /// The newest stop signal.
    signal: Option<StopSignal>,
    /// Whether samples carried logged stops ([`FLAG_VEHICLE_STOPPED`], [`FLAG_VEHICLE_MOVING`]).
    logged_stops: bool,
    /// The state's writer and how many samples apart it saves.
    writer: Option<(StateWriter, u64)>,
    since_save: u64,
    /// Samples processed (nothing is saved by a stage that took none).
    samples: u64,
    /// How the stage started: warm, or cold and why.
    warm: WarmStart,
    /// The accelerometer's white noise per sample, m/s² (from `accel_vrw`): each sample's
    /// `accel_std`, the weight a navigator (and the ROS 2 covariance) gives its reading.
    accel_std: f64,
}

impl BiasStage {
    fn snapshot(&self) -> bias_state::Snapshot {
        bias_state::Snapshot::new(|k| self.trackers.get(k).map(BiasTracker::snapshot))
    }
}

impl Drop for BiasStage {
    /// At shutdown: the last state, written before the stage is gone.
    fn drop(&mut self) {
        if let Some((writer, _)) = self.writer.take() {
            if self.samples > 0 {
                writer.finish(self.snapshot());
            }
        }
    }
}

impl Stage for BiasStage {
    fn warm_start(&self) -> Option<WarmStart> {
        Some(self.warm.clone())
    }

    fn learnt(&self) -> Vec<String> {
        // Stops given from outside teach it (and, confirmed-stops, those the accelerometer
        // confirms): without a stop signal (or an accelerometer) it cannot learn.
        let given = self.stop.is_some() || self.logged_stops;
        let can = match self.learn {
            LearnWalk::GivenStops => given,
            LearnWalk::ConfirmedStops => given || self.accel_seen,
            LearnWalk::Always | LearnWalk::Off => true,
        };
        let odometry = self.odometry.iter().map(Odometry::learnt);
        if !can {
            return odometry.collect();
        }
        self.trackers
            .iter()
            .zip(["x", "y", "z"])
            .filter_map(|(tr, axis)| {
                let w = tr.filter().walk()?;
                Some(format!(
                    "{axis}: walk {:.1} deg/h/sqrt(h) from {} stops (configured {:.1}, bounds \
                     {:.1}..{:.1}; learn_walk = {})",
                    walk_to_rrw(w.walk),
                    w.stops,
                    walk_to_rrw(w.configured),
                    walk_to_rrw(w.lo),
                    walk_to_rrw(w.hi),
                    self.learn.name()
                ))
            })
            .chain(odometry)
            .collect()
    }

    fn odometry(&self) -> Option<OdometryStats> {
        self.odometry.as_ref().map(Odometry::stats)
    }

    fn side(&mut self, _slot: usize, value: &SideValue) {
        let SideValue::Stop(s) = value;
        self.signal = Some(*s);
        self.fresh = Some(*s);
        if let Some(cfg) = &self.stop {
            if cfg.up.is_none() && cfg.odometry && s.yaw_rate_rad_s.is_finite() && !self.refused_yaw
            {
                self.refused_yaw = true;
                eprintln!(
                    "driftless: error: {} carries a yaw rate, but predict.bias does not know \
                     which gyro axis is the vehicle's up: the yaw rate is refused (not used). \
                     Set vehicle_up = \"+z\" (or -z, +x, -x, +y, -y: the axis pointing up, \
                     its sign) in the predict.bias table, or odometry = false to ignore the \
                     yaw rate (docs/navigation.md#feeding-the-odometry-to-the-daemon)",
                    cfg.service
                );
            }
        }
    }

    fn process(&mut self, input: &GyroSample) -> Option<GyroSample> {
        let mut out = *input;
        let (mut still, mut moving, mut warming) = (true, false, false);
        // A stop logged with the sample (a replay's stop column) is the signal at its own
        // time; else the stop service's newest, judged by its age.
        let logged = if input.flags & FLAG_VEHICLE_STOPPED != 0 {
            Some(true)
        } else if input.flags & FLAG_VEHICLE_MOVING != 0 {
            Some(false)
        } else {
            None
        };
        self.logged_stops |= logged.is_some();
        let stopped = logged.or_else(|| match (&self.stop, &self.signal) {
            (Some(cfg), Some(s)) => cfg.judge(s, now_of(s, input)),
            _ => None,
        });
        let given = self.stop.is_some() || self.logged_stops;
        // Absent or invalid: unknown, and the gyro alone decides.
        let accel = input.accel_reading();
        self.accel_seen |= accel.is_some();
        // The gyro's own verdict (each axis's full-window test, before this sample) teaches the
        // accelerometer its rest noise.
        let gyro_still = self.trackers.iter().all(BiasTracker::gyro_still);
        let aid = self.rest.push(accel, gyro_still);
        for (axis, tr) in self.trackers.iter_mut().enumerate() {
            let x = input.denoised[axis].to_degrees();
            let step = if given {
                tr.push_signal_with(x, stopped, aid)
            } else {
                tr.push_with(x, aid)
            };
            if step.contradicted {
                out.flags |= FLAG_STOP_CONTRADICTED;
            }
            out.drift[axis] = step.bias.to_radians();
            // The filter's own 1-sigma of what it removed (the prior's before the first stop).
            out.drift_std[axis] = step.std.to_radians();
            out.rate[axis] = input.denoised[axis] - out.drift[axis];
            match step.mode {
                BiasMode::Still => {}
                BiasMode::Moving => (still, moving) = (false, true),
                BiasMode::Warming => (still, warming) = (false, true),
            }
            warming |= !step.informed;
        }
        let fresh = self.fresh.take();
        if let Some(o) = &mut self.odometry {
            if let Some(f) = accel.filter(|_| still) {
                o.at_rest(f);
            }
            if let Some((axis, _)) = o.up {
                let x = input.denoised[axis].to_degrees();
                let now = (input.ingest_ns, input.t_ns);
                o.push(&mut self.trackers[axis], x, now, fresh.as_ref());
            }
        }
        out.flags |= motion_flags(still, moving, warming);
        self.samples += 1;
        if let Some((writer, every)) = &self.writer {
            self.since_save += 1;
            if self.since_save >= *every {
                self.since_save = 0;
                writer.offer(|snap| *snap = self.snapshot());
            }
        }
        if out.sensors & SENSOR_ACCEL != 0 {
            out.accel_std = [self.accel_std; 3];
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signal(t_ns: u64, speed_m_s: f64, stopped: u32) -> StopSignal {
        StopSignal::new(t_ns, speed_m_s, stopped)
    }

    #[test]
    fn a_stop_signal_is_judged_by_age_then_speed_or_flag() {
        let by_flag = StopConfig {
            service: "v/stop".into(),
            rule: StopRule {
                max_age_ns: 500_000_000,
                speed_m_s: None,
            },
            up: None,
            odometry: true,
        };
        let now = 10_000_000_000;
        assert_eq!(
            by_flag.judge(&signal(now - 1000, f64::NAN, 1), now),
            Some(true)
        );
        assert_eq!(by_flag.judge(&signal(now, 3.0, 0), now), Some(false));
        assert_eq!(by_flag.judge(&signal(now, 0.0, 7), now), None, "unknown");
        // Stale, or from the future by more than the age: unknown, never still.
        assert_eq!(by_flag.judge(&signal(now - 600_000_000, 0.0, 1), now), None);
        assert_eq!(by_flag.judge(&signal(now + 600_000_000, 0.0, 1), now), None);
        assert_eq!(
            by_flag.judge(&signal(0, 0.0, 1), now),
            None,
            "never stamped"
        );
        let by_speed = StopConfig {
            rule: StopRule {
                speed_m_s: Some(0.05),
                ..by_flag.rule
            },
            ..by_flag
        };
        assert_eq!(by_speed.judge(&signal(now, 0.04, 0), now), Some(true));
        assert_eq!(by_speed.judge(&signal(now, -0.04, 0), now), Some(true));
        assert_eq!(by_speed.judge(&signal(now, 0.2, 1), now), Some(false));
        assert_eq!(by_speed.judge(&signal(now, f64::NAN, 1), now), None);
    }
}
