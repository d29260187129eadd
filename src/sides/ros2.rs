//! The `[ros2]` side: the daemon as a node of the ROS 2 graph (docs/ros2.md). A driver's
//! `sensor_msgs/msg/Imu` topic feeds an `ingest.iceoryx2` stage's service, a stage's output
//! goes out as an Imu topic, and a vehicle's motion topic feeds a `predict.bias` stage's
//! `stop_input`. This file owns the table's keys and their check against the chain; the
//! bridge itself is [`crate::transport::ros2`]'s (cargo feature `ros2`).

use serde::Deserialize;
use toml::Spanned;

use super::contract::{Chain, Kind, Ready, Side, Start};
use crate::io::InputError;
use crate::stages::contract::SideInput;
use crate::stages::schema::{DefaultValue, Key, Src, Table, Type};
use crate::stages::stop_rule::DEFAULT_STOP_SPEED_M_S;
use crate::transport::ros2::{
    Direction, MotionKind, Ros2Settings, DEFAULT_MAG_MAX_AGE_S, DIAGNOSTICS_TOPIC,
    DIAGNOSTIC_ARRAY_TYPE, IMU_TYPE, MAG_TYPE, VECTOR3_STAMPED_TYPE,
};
use crate::units::{AccelUnit, RateUnit};

const NODE: Key = Key {
    name: "node",
    ty: Type::Str("a ROS 2 node name"),
    default: DefaultValue::Derived("`driftless_<pipeline>`"),
    doc: "the node's name (a `-` in the pipeline's name becomes `_`)",
};
const NAMESPACE: Key = Key {
    name: "namespace",
    ty: Type::Str("a ROS 2 namespace"),
    default: DefaultValue::Word("/"),
    doc: "the node's namespace",
};
const DEPTH: Key = Key {
    name: "depth",
    ty: Type::Int(1, 100_000),
    default: DefaultValue::Int(100),
    doc: "history depth (keep last) of every topic",
};
const FRAME_ID: Key = Key {
    name: "frame_id",
    ty: Type::Str("a TF frame"),
    default: DefaultValue::Derived("the driver's"),
    doc: "`header.frame_id` of what we publish. Not set: the `imu_in` messages' own frame \
          passes through (a navigator's TF lookup wants the driver's frame); with no \
          `imu_in`, `imu_link`",
};
const RATE_NOISE: Key = Key {
    name: "rate_noise",
    ty: Type::Positive(1e6),
    default: DefaultValue::Derived("from `predict.bias`"),
    doc: "the gyro's white rate noise per sample, deg/s (1 sigma): N in deg/sqrt(h) / 60 x \
          sqrt(rate_hz). Not given, it is `predict.bias`'s N so converted; with no \
          `predict.bias` either, the published covariance is all zeros (\"unknown\")",
};
const IMU_IN: Key = Key {
    name: "imu_in",
    ty: Type::Table("`topic`, `service`, `type` = \"sensor_msgs/msg/Imu\""),
    default: DefaultValue::Absent("none"),
    doc: "a driver node's Imu topic, into the service an `ingest.iceoryx2` stage reads: its \
          angular velocity, and its linear acceleration unless the message marks it not \
          provided (covariance element 0 = -1). The pipeline's `input_units` must be \
          `\"rad/s\"` and its `accel_units` `\"m/s^2\"` (REP 103)",
};
const MAG_IN: Key = Key {
    name: "mag_in",
    ty: Type::Table("`topic`, `type` = \"sensor_msgs/msg/MagneticField\""),
    default: DefaultValue::Absent("none"),
    doc: "a driver node's magnetometer (imu_filter_madgwick's `imu/mag`: the field in tesla), \
          joined by stamp to the samples of `imu_in` (it needs `imu_in`, whose service it \
          feeds): each Imu sample carries the newest reading stamped at most half a sample \
          period after it, if that reading is at most `mag_max_age_s` older; else none. For an \
          `attitude.6d` stage with `use_mag`",
};
const MAG_MAX_AGE_S: Key = Key {
    name: "mag_max_age_s",
    ty: Type::FloatIn(0.001, 10.0),
    default: DefaultValue::Float(DEFAULT_MAG_MAX_AGE_S),
    doc: "a magnetometer reading older than this (s, by stamp) is joined to no Imu sample: the \
          samples go on without one, and the heading rests on the gyro (with `mag_in`; the \
          default serves a magnetometer at 10 Hz or faster)",
};
const IMU_OUT: Key = Key {
    name: "imu_out",
    ty: Type::TableList("`topic`, `service`, `type` = \"sensor_msgs/msg/Imu\""),
    default: DefaultValue::Absent("none"),
    doc: "a stage's output service, published as an Imu topic; repeat the table \
          (`[[ros2.imu_out]]`) for more",
};
const MOTION_IN: Key = Key {
    name: "motion_in",
    ty: Type::Table("`topic`, `service`, `type`"),
    default: DefaultValue::Absent("none; its `type`: `nav_msgs/msg/Odometry`"),
    doc: "the vehicle's motion (`nav_msgs/msg/Odometry`, `geometry_msgs/msg/TwistStamped` or \
          `geometry_msgs/msg/TwistWithCovarianceStamped`), into the service a `predict.bias` \
          stage names as `stop_input` (it must have `stop_speed`)",
};

const ACCEL_NOISE: Key = Key {
    name: "accel_noise",
    ty: Type::Positive(1e6),
    default: DefaultValue::Derived("the samples' own (`accel_std`)"),
    doc: "the accelerometer's white noise per sample, m/s^2 (1 sigma): VRW in m/s/sqrt(h) / 60 \
          x sqrt(rate_hz). The published `linear_acceleration_covariance` is its square, where \
          a sample carries no `accel_std` of its own. With neither, it is the driver's own \
          covariance as received on `imu_in`; with no `imu_in` either, all zeros \
          (\"unknown\", which robot_localization raises to 1e-9: far too sure)",
};
const BIAS_OUT: Key = Key {
    name: "bias_out",
    ty: Type::Table("`topic`, `service`, `type` = \"geometry_msgs/msg/Vector3Stamped\""),
    default: DefaultValue::Absent("none"),
    doc: "the bias the filter removes (the samples' `drift`, rad/s), one message per sample \
          with its stamp and frame, as Autoware's `gyro_bias_estimator` publishes it. The \
          service: the output of a `predict.bias` stage or of one after it",
};
const DIAGNOSTICS: Key = Key {
    name: "diagnostics",
    ty: Type::Table(
        "`service`, `topic` = \"/diagnostics\", `type` = \"diagnostic_msgs/msg/DiagnosticArray\"",
    ),
    default: DefaultValue::Absent("none"),
    doc: "the bias filter's state, every `diagnostics_period_s`, as `diagnostic_updater` \
          publishes it: each axis's bias and its sigma (rad/s), the stillness, the samples, \
          and the pipeline's deadline misses and losses (its stats). WARN once an axis's bias \
          passes `bias_threshold`; STALE when no sample came in a period. The service: the \
          output of a `predict.bias` stage or of one after it",
};
const DIAGNOSTICS_PERIOD_S: Key = Key {
    name: "diagnostics_period_s",
    ty: Type::FloatIn(0.05, 3600.0),
    default: DefaultValue::Float(1.0),
    doc: "how often the diagnostics are published, s (`diagnostic_updater`'s default period)",
};
const BIAS_THRESHOLD: Key = Key {
    name: "bias_threshold",
    ty: Type::Positive(10.0),
    default: DefaultValue::Float(0.0015),
    doc: "the diagnostics go to WARN once an axis's bias passes this, rad/s (the default is \
          Autoware's `gyro_bias_threshold`; a MEMS gyro's turn-on bias can pass it: set what \
          your unit should stay within)",
};

/// The `[ros2]` side kind.
pub const KIND: Kind = Kind {
    table: "ros2",
    summary: "the daemon as a ROS 2 node: a driver's Imu topic in, stages' outputs out as Imu \
              topics, the bias and its diagnostics out, a vehicle's motion in as a stop signal \
              (cargo feature `ros2`)",
    keys: &[
        NODE,
        NAMESPACE,
        DEPTH,
        FRAME_ID,
        RATE_NOISE,
        ACCEL_NOISE,
        IMU_IN,
        MAG_IN,
        MAG_MAX_AGE_S,
        IMU_OUT,
        BIAS_OUT,
        DIAGNOSTICS,
        DIAGNOSTICS_PERIOD_S,
        BIAS_THRESHOLD,
        MOTION_IN,
    ],
    read,
};

/// One `[ros2.*]` topic table.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTopic {
    topic: Spanned<String>,
    service: Spanned<String>,
    #[serde(rename = "type")]
    ty: Option<Spanned<String>>,
}

/// The `[ros2.mag_in]` table: no service of its own (it feeds `imu_in`'s).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMagTopic {
    topic: Spanned<String>,
    #[serde(rename = "type")]
    ty: Option<Spanned<String>>,
}

/// The `[ros2.diagnostics]` table: its topic has a default.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDiagnostics {
    topic: Option<Spanned<String>>,
    service: Spanned<String>,
    #[serde(rename = "type")]
    ty: Option<Spanned<String>>,
}

/// A ROS 2 side, checked against its chain.
#[derive(Debug)]
struct Ros2Side(Ros2Settings);

fn read(t: &mut Table<'_, '_>, chain: &Chain<'_>) -> Result<Box<dyn Side>, InputError> {
    if !cfg!(feature = "ros2") {
        return Err(t.error(
            "[ros2] needs a driftless built with ROS 2: cargo build --release --features ros2",
        ));
    }
    let src = t.src;
    let node = t.get::<String>(&NODE)?;
    let namespace = t.str_or_default(&NAMESPACE, |_| Ok(()))?;
    let depth = t.int_or_default(&DEPTH)?;
    let frame_id = t.get::<String>(&FRAME_ID)?;
    let rate_noise = t.float(&RATE_NOISE)?;
    let accel_noise = t.float(&ACCEL_NOISE)?;
    let diagnostics_period_s = t.float_or_default(&DIAGNOSTICS_PERIOD_S)?;
    let bias_threshold = t.float_or_default(&BIAS_THRESHOLD)?;
    let imu_in = t
        .get::<RawTopic>(&IMU_IN)?
        .map(|raw| imu_in(src, chain, raw.into_inner()))
        .transpose()?;
    let mag_max_age_given = t.has(&MAG_MAX_AGE_S);
    let mag_max_age_s = t.float_or_default(&MAG_MAX_AGE_S)?;
    let mag_in = t
        .get::<RawMagTopic>(&MAG_IN)?
        .map(|raw| mag_in(src, raw, imu_in.is_some()))
        .transpose()?;
    if mag_in.is_none() && mag_max_age_given {
        return Err(t.error(
            "mag_max_age_s is the age limit of mag_in's readings, and there is no mag_in: \
             add mag_in or remove mag_max_age_s",
        ));
    }
    let imu_out = t
        .get::<Vec<Spanned<RawTopic>>>(&IMU_OUT)?
        .map_or_else(Vec::new, Spanned::into_inner)
        .into_iter()
        .map(|raw| imu_out(src, chain, raw.into_inner()))
        .collect::<Result<_, _>>()?;
    let bias_out = t
        .get::<RawTopic>(&BIAS_OUT)?
        .map(|raw| bias_out(src, chain, raw.into_inner()))
        .transpose()?;
    let diagnostics = t
        .get::<RawDiagnostics>(&DIAGNOSTICS)?
        .map(|raw| diagnostics(src, chain, raw.into_inner()))
        .transpose()?;
    let motion_in = t
        .get::<RawTopic>(&MOTION_IN)?
        .map(|raw| motion_in(src, chain, raw.into_inner()))
        .transpose()?;
    Ok(Box::new(Ros2Side(Ros2Settings {
        node: node.map_or_else(
            || format!("driftless_{}", chain.pipeline.replace('-', "_")),
            Spanned::into_inner,
        ),
        namespace,
        depth,
        frame_id: frame_id.map(Spanned::into_inner),
        // Not given: the white noise a stage assumes (predict.bias's N), per sample.
        rate_noise: rate_noise.or_else(|| chain.white_noise().map(|n| n * chain.cx.rate_hz.sqrt())),
        imu_in,
        mag_in,
        mag_max_age_s,
        imu_out,
        motion_in,
        accel_noise,
        bias_out,
        diagnostics,
        diagnostics_period_s,
        bias_threshold,
        stats_service: chain.stats_service.to_string(),
    })))
}

/// A topic name as ROS 2 takes it: absolute, its parts letters, digits and '_'.
fn topic(src: &Src<'_>, t: &Spanned<String>) -> Result<String, InputError> {
    let name = t.get_ref();
    let ok = name.starts_with('/')
        && name.len() > 1
        && !name.ends_with('/')
        && !name.contains("//")
        && !name.contains("__")
        && name[1..].split('/').all(|part| {
            part.chars()
                .next()
                .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
                && part.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        });
    if !ok {
        return Err(src.span(
            t,
            format!(
                "topic {name:?}: an absolute ROS 2 name (/a/b: letters, digits, '_', each part \
                 not starting with a digit, no '__')"
            ),
        ));
    }
    Ok(name.clone())
}

/// A `type` given for `key` is `want`.
fn of_type(
    src: &Src<'_>,
    ty: &Option<Spanned<String>>,
    key: &str,
    want: &str,
) -> Result<(), InputError> {
    match ty {
        Some(ty) if ty.get_ref() != want => Err(src.span(ty, format!("{key}.type is {want}"))),
        _ => Ok(()),
    }
}

/// The service `key` reports the bias of: a predict.bias stage's output or a later one's.
fn bias_service(
    src: &Src<'_>,
    chain: &Chain<'_>,
    raw: &Spanned<String>,
    key: &str,
) -> Result<String, InputError> {
    let service = src.service(raw)?;
    if chain.writer(&service).is_none() {
        return Err(src.span(
            raw,
            format!("{key}.service {service:?} is no stage's output"),
        ));
    }
    if !chain.upstream_of(&service, "predict.bias") {
        return Err(src.span(
            raw,
            format!(
                "{key}.service {service:?}: no predict.bias stage at or before the stage \
                 that publishes it, so its samples carry no bias to report"
            ),
        ));
    }
    Ok(service)
}

/// `imu_in`: (topic, service) into an ingest.iceoryx2 stage of a chain in ROS 2's units.
fn imu_in(src: &Src<'_>, chain: &Chain<'_>, raw: RawTopic) -> Result<(String, String), InputError> {
    let service = src.service(&raw.service)?;
    if chain
        .reader(&service)
        .is_none_or(|s| s.kind.name != "ingest.iceoryx2")
    {
        return Err(src.span(
            &raw.service,
            format!("imu_in.service {service:?} is no ingest.iceoryx2 stage's input"),
        ));
    }
    if chain.cx.units != RateUnit::RadPerS {
        return Err(src.span(
            &raw.service,
            "imu_in: ROS 2 rates are rad/s (REP 103): set input_units = \"rad/s\"",
        ));
    }
    if chain.cx.accel_units != AccelUnit::MPerS2 {
        return Err(src.span(
            &raw.service,
            "imu_in: ROS 2 accelerations are m/s^2 (REP 103): set accel_units = \
             \"m/s^2\"",
        ));
    }
    of_type(src, &raw.ty, "imu_in", IMU_TYPE)?;
    Ok((topic(src, &raw.topic)?, service))
}

/// `mag_in`: its topic, which needs `imu_in` (whose samples it joins, on whose service).
fn mag_in(
    src: &Src<'_>,
    raw: Spanned<RawMagTopic>,
    has_imu_in: bool,
) -> Result<String, InputError> {
    if !has_imu_in {
        return Err(src.span(
            &raw,
            "mag_in: the magnetometer is joined by stamp to the samples of imu_in, and there \
             is no imu_in: add imu_in (the driver's sensor_msgs/msg/Imu topic)",
        ));
    }
    let raw = raw.into_inner();
    of_type(src, &raw.ty, "mag_in", MAG_TYPE)?;
    topic(src, &raw.topic)
}

/// One of `imu_out`: (service, topic) of a stage's output.
fn imu_out(
    src: &Src<'_>,
    chain: &Chain<'_>,
    raw: RawTopic,
) -> Result<(String, String), InputError> {
    let service = src.service(&raw.service)?;
    if chain.writer(&service).is_none() {
        return Err(src.span(
            &raw.service,
            format!("imu_out.service {service:?} is no stage's output"),
        ));
    }
    of_type(src, &raw.ty, "imu_out", IMU_TYPE)?;
    Ok((service, topic(src, &raw.topic)?))
}

/// `bias_out`: (service, topic).
fn bias_out(
    src: &Src<'_>,
    chain: &Chain<'_>,
    raw: RawTopic,
) -> Result<(String, String), InputError> {
    let service = bias_service(src, chain, &raw.service, "bias_out")?;
    of_type(src, &raw.ty, "bias_out", VECTOR3_STAMPED_TYPE)?;
    Ok((service, topic(src, &raw.topic)?))
}

/// `diagnostics`: (service, topic; ROS 2's own by default).
fn diagnostics(
    src: &Src<'_>,
    chain: &Chain<'_>,
    raw: RawDiagnostics,
) -> Result<(String, String), InputError> {
    let service = bias_service(src, chain, &raw.service, "diagnostics")?;
    of_type(src, &raw.ty, "diagnostics", DIAGNOSTIC_ARRAY_TYPE)?;
    let topic = match &raw.topic {
        Some(t) => topic(src, t)?,
        None => DIAGNOSTICS_TOPIC.to_string(),
    };
    Ok((service, topic))
}

/// `motion_in`: (topic, message type, service) into stages that judge a stop by the speed.
fn motion_in(
    src: &Src<'_>,
    chain: &Chain<'_>,
    raw: RawTopic,
) -> Result<(String, String, String), InputError> {
    let service = src.service(&raw.service)?;
    let readers = chain.side_readers(&service);
    if readers.is_empty() {
        return Err(src.span(
            &raw.service,
            format!("motion_in.service {service:?} is no stage's stop_input"),
        ));
    }
    // A motion message says a speed, never whether the vehicle stands: judged by the
    // stands flag alone, every signal would be unknown.
    let by_stands = readers
        .iter()
        .find(|(_, kind)| *kind == SideInput::Stop { by_speed: false });
    if let Some((stage, _)) = by_stands {
        let stage = &stage.name;
        return Err(src.span(
            &raw.service,
            format!(
                "motion_in feeds {service:?} with the vehicle's speed only (a ROS 2 \
                 motion message says no \"stands\"), but stage {stage:?} reads it \
                 without stop_speed, so it would never learn a stop: add stop_speed = \
                 {DEFAULT_STOP_SPEED_M_S} (m/s, stands at or below) to stage {stage:?}"
            ),
        ));
    }
    let ty = match &raw.ty {
        Some(ty) if MotionKind::of_type(ty.get_ref()).is_some() => ty.get_ref().clone(),
        Some(ty) => {
            let names: Vec<&str> = MotionKind::ALL.iter().map(|(n, _)| *n).collect();
            return Err(src.span(ty, format!("motion_in.type: one of {}", names.join(", "))));
        }
        None => MotionKind::Odometry.type_name().to_string(),
    };
    Ok((topic(src, &raw.topic)?, ty, service))
}

impl Side for Ros2Side {
    fn describe(&self) -> Vec<String> {
        let r = &self.0;
        let noise = r.rate_noise.map_or("covariance unknown".into(), |n| {
            format!("rate noise {n:.4} deg/s")
        });
        let mut lines = vec![format!(
            "node {}{} on ROS_DOMAIN_ID's domain, depth {}, frame_id {}, {noise}",
            r.namespace.trim_end_matches('/').to_string() + "/",
            r.node,
            r.depth,
            r.frame_text()
        )];
        for t in r.topics() {
            let (topic, ty, service) = (t.topic, t.ty, t.service);
            lines.push(match t.direction {
                Direction::In => format!("  in     {topic} ({ty}) -> {service}"),
                Direction::Out if ty == DIAGNOSTIC_ARRAY_TYPE => format!(
                    "  out    {service}, {} -> {topic} ({ty}) every {} s, WARN past {} rad/s",
                    r.stats_service, r.diagnostics_period_s, r.bias_threshold
                ),
                Direction::Out => format!("  out    {service} -> {topic} ({ty})"),
                Direction::Stop => format!("  motion {topic} ({ty}) -> {service}"),
            });
        }
        if let (Some(_), Some((imu, _))) = (&r.mag_in, &r.imu_in) {
            lines.push(format!(
                "  magnetometer joined to {imu} by stamp: each sample the newest reading up to \
                 half a period after it, at most {} s older; else none (the heading on the gyro)",
                r.mag_max_age_s
            ));
        }
        if !r.imu_out.is_empty() {
            // Where linear_acceleration_covariance comes from when a sample has no accel_std.
            lines.push(match (r.accel_noise, &r.imu_in) {
                (Some(n), _) => format!(
                    "  linear_acceleration as received; its covariance from the samples' \
                     accel_std, else accel_noise {n} m/s^2"
                ),
                (None, Some(_)) => "  linear_acceleration as received; its covariance from the \
                                    samples' accel_std, else the driver's own"
                    .into(),
                (None, None) => "  linear_acceleration as received; its covariance from the \
                                 samples' accel_std, else all zeros (unknown: set accel_noise)"
                    .into(),
            });
        }
        lines
    }

    #[cfg(feature = "ros2")]
    fn check_environment(&self) -> Result<(), String> {
        crate::transport::ros2::domain_id().map(|_| ())
    }

    #[cfg(feature = "ros2")]
    fn run(&self, start: &Start<'_>, ready: Ready<'_>) -> Result<String, String> {
        crate::transport::ros2::run_bridge(&self.0, start, ready)
            .map(|counts| counts.to_string())
            .map_err(|e| e.to_string())
    }

    #[cfg(not(feature = "ros2"))]
    fn run(&self, _: &Start<'_>, ready: Ready<'_>) -> Result<String, String> {
        // `read` refuses the table in a build without the bridge.
        let why = "built without ROS 2".to_string();
        ready(Err(why.clone()));
        Err(why)
    }
}
