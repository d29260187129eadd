//! The layout versions of `RawSample`, `GyroSample`, `StatsSnapshot` and `StopSignal` between
//! real processes: a service of an older layout (as a driftless before `drift_std`, or before
//! the misses' explanation, publishes it; or a driver built before the accelerometer, or a
//! vehicle's process before the yaw rate) is refused by name by
//! `run`, `tap`, `record`, `stats` and the transport, and a subscriber built for version 1
//! cannot open our current service (iceoryx2 refuses it: it is never handed bytes it would
//! misread).

mod common;

use common::{text, Prefix};
use driftless::transport::{Qos, Transport, TransportError};
use driftless::wire::{
    GyroSample, StatsSnapshot, GYRO_V1_SIZE, GYRO_V1_TYPE_NAME, RAW_V1_SIZE, RAW_V1_TYPE_NAME,
    STATS_V1_SIZE, STATS_V1_TYPE_NAME, STOP_V1_SIZE, STOP_V1_TYPE_NAME,
};
use iceoryx2::prelude::*;

/// `GyroSample` as driftless published it before `drift_std` (layout version 1, 104 bytes).
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[repr(C)]
#[type_name("driftless::GyroSample")]
struct GyroSampleV1 {
    t_ns: u64,
    seq: u64,
    ingest_ns: u64,
    rate: [f64; 3],
    drift: [f64; 3],
    denoised: [f64; 3],
    flags: u32,
    epoch: u32,
}

/// `RawSample` as a driver built before the accelerometer publishes it (layout version 1, 48
/// bytes).
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[repr(C)]
#[type_name("driftless::RawSample")]
struct RawSampleV1 {
    t_ns: u64,
    seq: u64,
    rate: [f64; 3],
    flags: u32,
    epoch: u32,
}

/// `StopSignal` as a vehicle process built before the yaw rate publishes it (layout version 1,
/// 24 bytes).
#[derive(Debug, Clone, Copy, Default, ZeroCopySend)]
#[repr(C)]
#[type_name("driftless::StopSignal")]
struct StopSignalV1 {
    t_ns: u64,
    speed_m_s: f64,
    stopped: u32,
    reserved: u32,
}

/// `StatsSnapshot` as driftless published it before the misses' explanation (layout version
/// 1, 904 bytes): only its size and name matter here.
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("driftless::StatsSnapshot")]
struct StatsSnapshotV1 {
    fields: [u64; 113],
}

fn node(prefix: &Prefix, name: &str) -> Node<ipc::Service> {
    let mut cfg = iceoryx2::config::Config::default();
    cfg.global.prefix = FileName::new(prefix.0.as_bytes()).expect("prefix");
    NodeBuilder::new()
        .name(&NodeName::new(name).expect("name"))
        .config(&cfg)
        .create::<ipc::Service>()
        .expect("node")
}

/// How `driftless list --json` shows the publish-subscribe service `name`.
fn listed(prefix: &Prefix, name: &str) -> serde_json::Value {
    let o = common::driftless(&["list", "--prefix", &prefix.0, "--json"]);
    let (out, err) = text(&o);
    assert_eq!(o.status.code(), Some(0), "list: {err}");
    let doc: serde_json::Value = serde_json::from_str(&out).expect("list --json");
    doc["services"]
        .as_array()
        .expect("services")
        .iter()
        .find(|s| s["name"] == name && s["pattern"] == "publish-subscribe")
        .unwrap_or_else(|| panic!("{name} not listed: {doc:#}"))
        .clone()
}

/// The sentence every one of our tools gives for a version 1 service named `service`.
fn refusal(service: &str) -> String {
    format!(
        "service {service:?} carries driftless::GyroSample (layout v1, 104 bytes, from an older \
         driftless); this driftless reads driftless::GyroSample.v4 (layout v4, 264 bytes, with \
         the orientation): run the daemon and its subscribers from one release \
         (docs/wire-types.md#versions)"
    )
}

#[test]
fn an_old_layout_service_is_refused_by_name_and_an_old_subscriber_cannot_open_ours() {
    assert_eq!(std::mem::size_of::<GyroSampleV1>(), GYRO_V1_SIZE);
    // SAFETY: type_name only returns the static string of the derive attribute.
    assert_eq!(unsafe { GyroSampleV1::type_name() }, GYRO_V1_TYPE_NAME);
    let prefix = Prefix::new("wirever");
    let dir = common::Dir::new();

    // An older driftless's service, from this process with iceoryx2's own API.
    let old = node(&prefix, "old-daemon");
    let old_service = old
        .service_builder(&"old/corrected".try_into().expect("name"))
        .publish_subscribe::<GyroSampleV1>()
        .open_or_create()
        .expect("old service");
    let old_publisher = old_service.publisher_builder().create().expect("publisher");
    old_publisher
        .send_copy(GyroSampleV1::default())
        .expect("send");

    let want = refusal("old/corrected");
    let o = common::driftless(&[
        "tap",
        "old/corrected",
        "--prefix",
        &prefix.0,
        "--count",
        "1",
    ]);
    let (out, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "tap: {err}");
    assert!(out.is_empty(), "nothing printed as samples: {out}");
    assert_eq!(err.trim_end(), format!("driftless: error: {want}"), "tap");

    let file = dir.path("r.mcap");
    let o = common::driftless(&[
        "record",
        "old/corrected",
        "-o",
        file.to_str().unwrap(),
        "--prefix",
        &prefix.0,
        "--duration",
        "1s",
    ]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "record: {err}");
    assert!(err.contains(&want), "record: {err}");

    // `list` names it as ours in another version, not as a foreign type.
    let listed = listed(&prefix, "old/corrected");
    assert_eq!(
        listed["wire_type"], "GyroSample (other version)",
        "{listed}"
    );
    assert_eq!(listed["type"], GYRO_V1_TYPE_NAME, "{listed}");

    // Our transport (the daemon's external stages, nav_subscriber) says the same.
    let me = Transport::new(&prefix.0, "new-subscriber", Qos::default()).expect("node");
    match me.open_input::<GyroSample>("old/corrected") {
        Err(TransportError::Version(m)) => assert_eq!(m, want),
        Err(e) => panic!("not a version refusal: {e}"),
        Ok(_) => panic!("a version 1 service was opened as version 2"),
    }

    // The other way: our service, and a subscriber built for version 1.
    let _ours = me
        .output::<GyroSample>("new/corrected", false)
        .expect("ours");
    let opened = old
        .service_builder(&"new/corrected".try_into().expect("name"))
        .publish_subscribe::<GyroSampleV1>()
        .open();
    match opened {
        Err(e) => assert_eq!(format!("{e:?}"), "IncompatibleTypes"),
        Ok(_) => panic!("a version 1 subscriber opened a version 2 service"),
    }

    drop((old_publisher, old_service, old, me, _ours));
    driftless::transport::remove_prefix_leftovers(&prefix.0);
}

#[test]
fn an_old_stats_service_is_refused_by_name_by_stats_tap_and_list() {
    assert_eq!(std::mem::size_of::<StatsSnapshotV1>(), STATS_V1_SIZE);
    // SAFETY: type_name only returns the static string of the derive attribute.
    assert_eq!(unsafe { StatsSnapshotV1::type_name() }, STATS_V1_TYPE_NAME);
    let prefix = Prefix::new("statsver");
    let dir = common::Dir::new();
    let old = node(&prefix, "old-daemon");
    let old_service = old
        .service_builder(&"old/stats".try_into().expect("name"))
        .publish_subscribe::<StatsSnapshotV1>()
        .open_or_create()
        .expect("old service");
    let _old_publisher = old_service.publisher_builder().create().expect("publisher");
    let want = "service \"old/stats\" carries driftless::StatsSnapshot (layout v1, 904 bytes, \
                from an older driftless); this driftless reads driftless::StatsSnapshot.v4 \
                (layout v4, 1024 bytes, with the odometry): run the daemon and its subscribers \
                from one release (docs/wire-types.md#versions)";

    // `stats` of a pipeline named "old" reads "old/stats".
    let demo = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/demo.toml"))
        .expect("demo.toml");
    let file = dir.write("old.toml", &demo.replace("demo", "old"));
    let o = common::driftless(&[
        "stats",
        file.to_str().unwrap(),
        "--prefix",
        &prefix.0,
        "--once",
    ]);
    let (out, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "stats: {err}");
    assert!(out.is_empty(), "{out}");
    assert_eq!(err.trim_end(), format!("driftless: error: {want}"), "stats");

    let o = common::driftless(&["tap", "old/stats", "--prefix", &prefix.0, "--count", "1"]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "tap: {err}");
    assert_eq!(err.trim_end(), format!("driftless: error: {want}"), "tap");

    let listed = listed(&prefix, "old/stats");
    assert_eq!(
        listed["wire_type"], "StatsSnapshot (other version)",
        "{listed}"
    );

    let me = Transport::new(&prefix.0, "new-stats", Qos::default()).expect("node");
    match me.open_input::<StatsSnapshot>("old/stats") {
        Err(TransportError::Version(m)) => assert_eq!(m, want),
        Err(e) => panic!("not a version refusal: {e}"),
        Ok(_) => panic!("a version 1 stats service was opened as version 2"),
    }
    drop((_old_publisher, old_service, old, me));
    driftless::transport::remove_prefix_leftovers(&prefix.0);
}

#[test]
fn a_driver_of_the_old_raw_layout_is_refused_by_name_before_the_run_starts() {
    assert_eq!(std::mem::size_of::<RawSampleV1>(), RAW_V1_SIZE);
    // SAFETY: type_name only returns the static string of the derive attribute.
    assert_eq!(unsafe { RawSampleV1::type_name() }, RAW_V1_TYPE_NAME);
    let prefix = Prefix::new("rawver");
    let dir = common::Dir::new();
    let driver = node(&prefix, "old-driver");
    let service = driver
        .service_builder(&"sensor/raw".try_into().expect("name"))
        .publish_subscribe::<RawSampleV1>()
        .history_size(0)
        .enable_safe_overflow(false)
        .subscriber_max_buffer_size(256)
        .max_publishers(1)
        .open_or_create()
        .expect("old driver's service");
    let _publisher = service.publisher_builder().create().expect("publisher");
    let file = dir.write(
        "old-driver.toml",
        r#"name = "olddrv"
rate_hz = 100.0
input_units = "rad/s"

[[stage]]
name = "sensor"
kind = "ingest.iceoryx2"
input = "sensor/raw"
output = "olddrv/raw"

[[stage]]
name = "out"
kind = "publish"
input = "olddrv/raw"
output = "olddrv/corrected"
"#,
    );
    let o = common::driftless(&[
        "run",
        file.to_str().unwrap(),
        "--prefix",
        &prefix.0,
        "--duration",
        "5s",
    ]);
    let (_, err) = text(&o);
    assert_ne!(o.status.code(), Some(0), "run: {err}");
    assert!(
        err.contains(
            "service \"sensor/raw\" carries driftless::RawSample (layout v1, 48 bytes, from an \
             older driftless); this driftless reads driftless::RawSample.v2 (layout v2, 96 \
             bytes, with the accelerometer and the magnetometer)"
        ),
        "{err}"
    );
    drop((_publisher, service, driver));
    driftless::transport::remove_prefix_leftovers(&prefix.0);
}

#[test]
fn a_vehicle_publishing_the_old_stop_signal_is_refused_by_name_before_the_run_starts() {
    assert_eq!(std::mem::size_of::<StopSignalV1>(), STOP_V1_SIZE);
    // SAFETY: type_name only returns the static string of the derive attribute.
    assert_eq!(unsafe { StopSignalV1::type_name() }, STOP_V1_TYPE_NAME);
    let prefix = Prefix::new("stopver");
    let dir = common::Dir::with_csv(64);
    let vehicle = node(&prefix, "old-vehicle");
    let service = vehicle
        .service_builder(&"vehicle/stop".try_into().expect("name"))
        .publish_subscribe::<StopSignalV1>()
        .history_size(0)
        .enable_safe_overflow(false)
        .subscriber_max_buffer_size(256)
        .open_or_create()
        .expect("old vehicle's service");
    let _publisher = service.publisher_builder().create().expect("publisher");
    let text_ = common::csv_pipeline("asap", false, 256).replace(
        "kind = \"denoise.none\"",
        "kind = \"predict.bias\"\nstop_input = \"vehicle/stop\"",
    );
    assert!(text_.contains("stop_input"), "{text_}");
    let file = dir.write("old-vehicle.toml", &text_);
    let o = common::driftless(&[
        "run",
        file.to_str().unwrap(),
        "--prefix",
        &prefix.0,
        "--duration",
        "5s",
    ]);
    let (_, err) = text(&o);
    assert_ne!(o.status.code(), Some(0), "run: {err}");
    assert!(
        err.contains(
            "service \"vehicle/stop\" carries driftless::StopSignal (layout v1, 24 bytes, from \
             an older driftless); this driftless reads driftless::StopSignal.v2 (layout v2, 56 \
             bytes, with the yaw rate)"
        ),
        "{err}"
    );
    drop((_publisher, service, vehicle));
    driftless::transport::remove_prefix_leftovers(&prefix.0);
}
