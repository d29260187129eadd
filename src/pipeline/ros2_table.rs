//! The `[ros2]` table of a pipeline file: its raw shape and its check against the stages it
//! feeds and reads. It belongs to the pipeline's ROS 2 side, not to the pipeline's own keys
//! (`config.rs` reads those and hands this table here).

use serde::Deserialize;
use toml::Spanned;

use crate::io::InputError;
use crate::pipeline::config::{StageSpec, Units};
use crate::stages::contract::SideKind;
use crate::stages::schema::Src;
use crate::stages::stop_rule::DEFAULT_STOP_SPEED_M_S;
use crate::transport::ros2::{MotionKind, Ros2Settings};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRos2 {
    node: Option<Spanned<String>>,
    namespace: Option<Spanned<String>>,
    depth: Option<Spanned<i64>>,
    frame_id: Option<Spanned<String>>,
    rate_noise: Option<Spanned<f64>>,
    imu_in: Option<Spanned<RawTopic>>,
    #[serde(default)]
    imu_out: Vec<Spanned<RawTopic>>,
    motion_in: Option<Spanned<RawTopic>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTopic {
    topic: Spanned<String>,
    service: Spanned<String>,
    #[serde(rename = "type")]
    ty: Option<Spanned<String>>,
}

/// Check the `[ros2]` table against the stages it feeds and reads.
pub(super) fn ros2_settings(
    src: &Src<'_>,
    pipeline: &str,
    units: Units,
    rate_hz: f64,
    stages: &[StageSpec],
    raw: Spanned<RawRos2>,
) -> Result<Ros2Settings, InputError> {
    if !cfg!(feature = "ros2") {
        return Err(src.span(
            &raw,
            "[ros2] needs a driftless built with ROS 2: cargo build --release --features ros2",
        ));
    }
    let raw = raw.into_inner();
    let topic = |t: &Spanned<String>| -> Result<String, InputError> {
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
    };
    let outputs = |service: &str| stages.iter().any(|s| s.output == service);
    let imu_in = match &raw.imu_in {
        Some(t) => {
            let t = t.get_ref();
            let service = src.service(&t.service)?;
            let ingest = stages
                .iter()
                .find(|s| s.input.as_deref() == Some(service.as_str()));
            if ingest.is_none_or(|s| s.kind.name != "ingest.iceoryx2") {
                return Err(src.span(
                    &t.service,
                    format!("imu_in.service {service:?} is no ingest.iceoryx2 stage's input"),
                ));
            }
            if units != Units::RadPerSec {
                return Err(src.span(
                    &t.service,
                    "imu_in: ROS 2 rates are rad/s (REP 103): set input_units = \"rad/s\"",
                ));
            }
            if let Some(ty) = &t.ty {
                if ty.get_ref() != "sensor_msgs/msg/Imu" {
                    return Err(src.span(ty, "imu_in.type is sensor_msgs/msg/Imu"));
                }
            }
            Some((topic(&t.topic)?, service))
        }
        None => None,
    };
    let mut imu_out = Vec::new();
    for t in &raw.imu_out {
        let t = t.get_ref();
        let service = src.service(&t.service)?;
        if !outputs(&service) {
            return Err(src.span(
                &t.service,
                format!("imu_out.service {service:?} is no stage's output"),
            ));
        }
        if let Some(ty) = &t.ty {
            if ty.get_ref() != "sensor_msgs/msg/Imu" {
                return Err(src.span(ty, "imu_out.type is sensor_msgs/msg/Imu"));
            }
        }
        imu_out.push((service, topic(&t.topic)?));
    }
    let motion_in = match &raw.motion_in {
        Some(t) => {
            let t = t.get_ref();
            let service = src.service(&t.service)?;
            let readers: Vec<(&str, bool)> = stages
                .iter()
                .flat_map(|s| {
                    s.params
                        .side_inputs()
                        .into_iter()
                        .filter_map(|(side, kind)| {
                            let SideKind::Stop { by_speed } = kind;
                            (side == service).then_some((s.name.as_str(), by_speed))
                        })
                })
                .collect();
            if readers.is_empty() {
                return Err(src.span(
                    &t.service,
                    format!("motion_in.service {service:?} is no stage's stop_input"),
                ));
            }
            // A motion message says a speed, never whether the vehicle stands: judged by the
            // stands flag alone, every signal would be unknown.
            if let Some((stage, _)) = readers.iter().find(|(_, by_speed)| !by_speed) {
                return Err(src.span(
                    &t.service,
                    format!(
                        "motion_in feeds {service:?} with the vehicle's speed only (a ROS 2 \
                         motion message says no \"stands\"), but stage {stage:?} reads it \
                         without stop_speed, so it would never learn a stop: add stop_speed = \
                         {DEFAULT_STOP_SPEED_M_S} (m/s, stands at or below) to stage {stage:?}"
                    ),
                ));
            }
            let ty = match &t.ty {
                Some(ty) if MotionKind::of_type(ty.get_ref()).is_some() => ty.get_ref().clone(),
                Some(ty) => {
                    let names: Vec<&str> = MotionKind::ALL.iter().map(|(n, _)| *n).collect();
                    return Err(
                        src.span(ty, format!("motion_in.type: one of {}", names.join(", ")))
                    );
                }
                None => MotionKind::Odometry.type_name().to_string(),
            };
            Some((topic(&t.topic)?, ty, service))
        }
        None => None,
    };
    let node = match &raw.node {
        Some(n) => n.get_ref().clone(),
        None => format!("driftless_{}", pipeline.replace('-', "_")),
    };
    Ok(Ros2Settings {
        node,
        namespace: raw
            .namespace
            .as_ref()
            .map_or_else(|| "/".to_string(), |n| n.get_ref().clone()),
        depth: match &raw.depth {
            Some(d) => src.int_in(d, "depth", 1, 100_000)?,
            None => 100,
        },
        frame_id: raw.frame_id.as_ref().map(|f| f.get_ref().clone()),
        // Not given: the white noise a stage assumes (predict.bias's N), per sample.
        rate_noise: match &raw.rate_noise {
            Some(r) => Some(src.positive(r, "rate_noise", 1e6)?),
            None => stages
                .iter()
                .find_map(|s| s.params.white_noise())
                .map(|n| n * rate_hz.sqrt()),
        },
        imu_in,
        imu_out,
        motion_in,
    })
}
