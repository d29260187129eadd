//! `driftless list` against real processes: a running pipeline and a tap, a foreign publisher
//! in this process, a daemon killed with SIGKILL, and an empty prefix. Each test has its own
//! iceoryx2 prefix.

mod common;

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{csv_pipeline, finish, signal, start, wait_ready, Dir, Prefix};
use serde_json::Value;

const SIGTERM: i32 = 15;
const SIGKILL: i32 = 9;

/// A CSV replay at 1 kHz, looping, with a stats snapshot every 0.2 s.
fn pipeline() -> String {
    csv_pipeline("realtime", true, 64)
        .replace("report_interval_s = 60.0", "report_interval_s = 0.2")
}

/// `driftless list --prefix P` with `extra`: (exit code, stdout, stderr).
fn list(prefix: &Prefix, extra: &[&str]) -> (Option<i32>, String, String) {
    let o = Command::new(common::bin())
        .args(["list", "--prefix", &prefix.0])
        .args(extra)
        .output()
        .expect("list runs");
    let (out, err) = common::text(&o);
    (o.status.code(), out, err)
}

fn list_json(prefix: &Prefix, extra: &[&str]) -> Value {
    let mut args = vec!["--json"];
    args.extend_from_slice(extra);
    let (code, out, err) = list(prefix, &args);
    assert_eq!(code, Some(0), "stderr: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("not JSON ({e}): {out}"))
}

fn service<'a>(doc: &'a Value, name: &str, pattern: &str) -> &'a Value {
    doc["services"]
        .as_array()
        .expect("services")
        .iter()
        .find(|s| s["name"] == name && s["pattern"] == pattern)
        .unwrap_or_else(|| panic!("no {pattern} service {name} in {doc:#}"))
}

/// The text row of `first` cell (split on runs of spaces).
fn row<'a>(text: &'a str, first: &str) -> Vec<&'a str> {
    text.lines()
        .map(|l| {
            l.split("  ")
                .map(str::trim)
                .filter(|c| !c.is_empty())
                .collect::<Vec<_>>()
        })
        .find(|cells| cells.first() == Some(&first))
        .unwrap_or_else(|| panic!("no row {first:?} in:\n{text}"))
}

#[test]
fn a_running_pipeline_a_tap_and_a_foreign_service_are_listed_with_types_and_ports() {
    let prefix = Prefix::new("lsrun");
    let dir = Dir::with_csv(500);
    let file = dir.write("p.toml", &pipeline());
    let mut daemon = start(&file, &prefix, &[]);
    wait_ready(&prefix, "c/stats", &mut daemon);
    let tap = Command::new(common::bin())
        .args(["tap", "c/corrected", "--prefix", &prefix.0, "--hz"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("tap");

    // A publisher of a type that is not ours, from this process, with iceoryx2's own API.
    use iceoryx2::prelude::{ipc, FileName, NodeBuilder, NodeName, SemanticString as _};
    let mut cfg = iceoryx2::config::Config::default();
    cfg.global.prefix = FileName::new(prefix.0.as_bytes()).expect("prefix");
    let node = NodeBuilder::new()
        .name(&NodeName::new("foreign-driver").expect("name"))
        .config(&cfg)
        .create::<ipc::Service>()
        .expect("node");
    let foreign = node
        .service_builder(&"x/foreign".try_into().expect("name"))
        .publish_subscribe::<u64>()
        .open_or_create()
        .expect("foreign service");
    let _publisher = foreign.publisher_builder().create().expect("publisher");

    // The tap's subscriber is there once list counts it.
    let end = Instant::now() + Duration::from_secs(10);
    let doc = loop {
        let doc = list_json(&prefix, &[]);
        if service(&doc, "c/corrected", "publish-subscribe")["subscribers"] == 1 {
            break doc;
        }
        assert!(Instant::now() < end, "the tap never showed up: {doc:#}");
        std::thread::sleep(Duration::from_millis(100));
    };

    let pipes = doc["pipelines"].as_array().expect("pipelines");
    assert_eq!(pipes.len(), 1, "{doc:#}");
    let p = &pipes[0];
    assert_eq!(p["name"], "c");
    assert_eq!(p["state"], "alive");
    assert_eq!(p["pid"], daemon.id());
    assert_eq!(p["stats_service"], "c/stats");
    let rate = p["rate_hz"]
        .as_f64()
        .expect("a rate from the stats snapshot");
    assert!((200.0..5000.0).contains(&rate), "rate {rate}");
    // SAFETY: getuid cannot fail.
    let me = driftless::transport::user_name(unsafe { libc::getuid() }).expect("user");
    assert_eq!(p["user"], me.as_str());
    assert!(p["uptime_s"].as_f64().expect("uptime") >= 0.0);

    for (name, wire, type_name, subscribers) in [
        // The daemon reads none of its hops back; the tap reads the last.
        ("c/raw", "RawSample", "driftless::RawSample.v2", 0),
        ("c/denoised", "GyroSample", "driftless::GyroSample.v4", 0),
        ("c/corrected", "GyroSample", "driftless::GyroSample.v4", 1),
        ("c/stats", "StatsSnapshot", "driftless::StatsSnapshot.v4", 0),
    ] {
        let s = service(&doc, name, "publish-subscribe");
        assert_eq!(s["wire_type"], wire, "{s}");
        assert_eq!(s["type"], type_name, "{s}");
        assert_eq!(s["publishers"], 1, "{s}");
        assert_eq!(s["subscribers"], subscribers, "{s}");
        assert_eq!(s["published_by"], serde_json::json!(["c"]), "{s}");
    }
    let event = service(&doc, "c/corrected", "event");
    assert_eq!(event["notifiers"], 1, "{event}");
    let f = service(&doc, "x/foreign", "publish-subscribe");
    assert_eq!(f["wire_type"], "foreign", "{f}");
    assert_eq!(f["type"], "u64", "{f}");
    assert!(f["publishers"].is_null(), "not opened, not counted: {f}");
    assert_eq!(f["nodes"], serde_json::json!(["foreign-driver"]), "{f}");
    assert_eq!(
        service(&doc, "c/corrected", "publish-subscribe")["nodes"],
        serde_json::json!(["c", format!("driftless-tap-{}", tap.id())])
    );

    let nodes = doc["nodes"].as_array().expect("nodes");
    let tap_node = nodes
        .iter()
        .find(|n| n["pid"] == tap.id())
        .unwrap_or_else(|| panic!("no tap node: {doc:#}"));
    assert_eq!(tap_node["state"], "alive");
    assert!(tap_node["pipeline"].is_null());
    assert!(nodes
        .iter()
        .any(|n| n["name"] == "foreign-driver" && n["pid"] == std::process::id()));

    // The same as tables, in 80 columns.
    let (code, out, err) = list(&prefix, &[]);
    assert_eq!(code, Some(0), "stderr: {err}");
    for line in out.lines() {
        assert!(line.chars().count() <= 80, "{} columns: {line}", line.len());
    }
    let c = row(&out, "c");
    assert_eq!(c[1..4], ["alive", &daemon.id().to_string(), &me], "{out}");
    assert!(c[5].ends_with(" Hz"), "{out}");
    assert_eq!(
        row(&out, &format!("driftless-tap-{}", tap.id()))[1],
        "alive",
        "{out}"
    );
    assert_eq!(
        row(&out, "c/corrected"),
        ["c/corrected", "GyroSample", "1", "1", "c"],
        "{out}"
    );
    assert_eq!(
        row(&out, "x/foreign"),
        ["x/foreign", "foreign", "?", "?", "?"],
        "{out}"
    );

    drop(_publisher);
    drop(foreign);
    drop(node);
    signal(&tap, SIGTERM);
    let _ = finish(tap, Duration::from_secs(10));
    signal(&daemon, SIGTERM);
    let (code, err) = finish(daemon, Duration::from_secs(10));
    assert_eq!(code, Some(0), "stderr: {err}");
}

#[test]
fn a_killed_daemon_is_listed_dead_and_clean_removes_it() {
    let prefix = Prefix::new("lskill");
    let dir = Dir::with_csv(500);
    let file = dir.write("p.toml", &pipeline());
    let mut daemon = start(&file, &prefix, &[]);
    wait_ready(&prefix, "c/stats", &mut daemon);
    let pid = daemon.id();
    signal(&daemon, SIGKILL);
    let _ = finish(daemon, Duration::from_secs(10));

    let doc = list_json(&prefix, &[]);
    let p = &doc["pipelines"][0];
    assert_eq!(p["name"], "c", "{doc:#}");
    assert_eq!(p["state"], "dead", "{doc:#}");
    assert_eq!(p["pid"], pid);
    assert!(p["rate_hz"].is_null());
    assert!(doc["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .all(|n| n["state"] == "dead"));
    assert_eq!(
        service(&doc, "c/corrected", "publish-subscribe")["published_by"],
        serde_json::json!(["c (dead)"])
    );
    let (code, out, _) = list(&prefix, &[]);
    assert_eq!(code, Some(0));
    assert_eq!(row(&out, "c")[1..3], ["dead", &pid.to_string()], "{out}");
    // Listing removed nothing.
    assert_eq!(list_json(&prefix, &[])["pipelines"][0]["state"], "dead");

    let (code, out, err) = list(&prefix, &["--clean"]);
    assert_eq!(code, Some(0), "stderr: {err}");
    assert!(
        err.starts_with(&format!(
            "removed 2 dead nodes under prefix {:?}: ",
            prefix.0
        )),
        "{err}"
    );
    assert!(err.contains(&format!("driftless-c (pid {pid})")), "{err}");
    assert!(!out.contains("dead"), "{out}");
    let doc = list_json(&prefix, &[]);
    assert_eq!(doc["pipelines"], serde_json::json!([]), "{doc:#}");
    assert_eq!(doc["nodes"], serde_json::json!([]), "{doc:#}");
    assert_eq!(doc["services"], serde_json::json!([]), "{doc:#}");
    let left = prefix.leftovers();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn an_empty_prefix_lists_nothing_exits_zero_and_creates_nothing() {
    let prefix = Prefix::new("lsnone");
    let (code, out, err) = list(&prefix, &[]);
    assert_eq!(code, Some(0), "stderr: {err}");
    assert_eq!(out, format!("prefix {:?}: nothing running\n", prefix.0));
    assert!(err.is_empty(), "{err}");
    let doc = list_json(&prefix, &["--clean"]);
    assert_eq!(doc["prefix"], prefix.0.as_str());
    for key in ["pipelines", "nodes", "services", "removed_dead_nodes"] {
        assert_eq!(doc[key], serde_json::json!([]), "{key}: {doc:#}");
    }
    assert!(prefix.leftovers().is_empty(), "{:?}", prefix.leftovers());
}

#[test]
fn clean_removes_daemons_killed_at_any_point_of_their_start() {
    // Killed while creating a port, a node leaves files that iceoryx2 0.10's own clean-up stops
    // at; `--clean` must leave nothing of any of them.
    let dir = Dir::with_csv(500);
    let file = dir.write("p.toml", &pipeline());
    for (k, delay_ms) in (0..60).step_by(5).enumerate() {
        let prefix = Prefix::new(&format!("lsstart{k}"));
        let daemon = start(&file, &prefix, &[]);
        std::thread::sleep(Duration::from_millis(delay_ms));
        signal(&daemon, SIGKILL);
        let _ = finish(daemon, Duration::from_secs(10));
        let (code, _, err) = list(&prefix, &["--clean"]);
        assert_eq!(code, Some(0), "killed after {delay_ms} ms: {err}");
        let doc = list_json(&prefix, &[]);
        assert_eq!(
            doc["nodes"],
            serde_json::json!([]),
            "after {delay_ms} ms: {doc:#}"
        );
        let left = prefix.leftovers();
        assert!(
            left.is_empty(),
            "after {delay_ms} ms, left behind: {left:?}"
        );
    }
}

#[test]
fn a_segment_a_killed_process_never_sized_does_not_hang_the_clean_up() {
    // A process killed between creating a shared memory segment and sizing it leaves a
    // write-only segment of size 0, which iceoryx2 0.10 waits on forever when it cleans up the
    // dead node. Made here from a real killed daemon's service segment.
    use std::os::unix::fs::PermissionsExt;
    let dir = Dir::with_csv(500);
    let file = dir.write("p.toml", &pipeline());
    let prefix = Prefix::new("lsunsized");
    let mut daemon = start(&file, &prefix, &[]);
    wait_ready(&prefix, "c/stats", &mut daemon);
    signal(&daemon, SIGKILL);
    let _ = finish(daemon, Duration::from_secs(10));
    let segment = std::fs::read_dir("/dev/shm")
        .expect("/dev/shm")
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            name.starts_with(&prefix.0) && name.ends_with(".dynamic")
        })
        .expect("the killed daemon's service segments");
    std::fs::OpenOptions::new()
        .write(true)
        .open(&segment)
        .and_then(|f| f.set_len(0))
        .expect("truncate");
    std::fs::set_permissions(&segment, std::fs::Permissions::from_mode(0o200)).expect("chmod");
    // Older than a second: not a segment some live process is creating right now.
    std::thread::sleep(Duration::from_millis(1100));
    let child = Command::new(common::bin())
        .args(["list", "--clean", "--prefix", &prefix.0])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("list runs");
    let (code, err) = finish(child, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(list_json(&prefix, &[])["nodes"], serde_json::json!([]));
    let left = prefix.leftovers();
    assert!(left.is_empty(), "left behind: {left:?}");
}
