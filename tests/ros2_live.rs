//! Live ROS 2 against a real ROS 2 (rclpy on Fast DDS, from PyPI): our node's Imu messages
//! reach an rclpy subscriber field for field, an rclpy publisher's reach us, and rclpy's graph
//! lists our node, topic and type (cargo feature `ros2`).
//!
//! DDS speaks only inside a private network namespace with nothing but loopback: the test
//! re-runs itself under `unshare -n` (root; CI runs as root), and never touches the host's
//! network. Without root, or without the rclpy peer (`DRIFTLESS_ROS2_PYTHON`, a Python with
//! tests/ros2/requirements-ros2.txt; `.ci/run` makes one), a test says so in one line and skips.
#![cfg(feature = "ros2")]

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use driftless::transport::ros2::{Imu, ImuMapping, Ros2Node};
use driftless::wire::GyroSample;

/// Set in the child that runs inside the namespace.
const CHILD: &str = "DRIFTLESS_TEST_IN_NETNS";

/// The Python that has rclpy.
const PYTHON: &str = "DRIFTLESS_ROS2_PYTHON";

/// Whether this process may speak DDS: inside a network namespace whose only link is loopback.
/// (`/proc/self/net/dev` is this process's namespace's; `/sys/class/net` is the mounter's.)
fn only_loopback() -> bool {
    std::fs::read_to_string("/proc/self/net/dev").is_ok_and(|dev| {
        dev.lines()
            .skip(2)
            .filter_map(|l| l.split(':').next())
            .all(|name| name.trim() == "lo")
    })
}

/// Run `test` in a private network namespace with loopback up and a multicast route on it,
/// and a private mount namespace with its own `/dev/shm` and iceoryx2 root (Fast DDS's segments
/// and ours stay there: the host's are as they were). True in the child (run the test there);
/// in the parent, waits and fails if the child failed.
fn in_netns(test: &str) -> bool {
    if std::env::var_os(CHILD).is_some() {
        assert!(
            only_loopback(),
            "a DDS test outside a loopback-only namespace"
        );
        return true;
    }
    if std::env::var_os(PYTHON).is_none() {
        eprintln!("{test}: skipped: no rclpy peer ({PYTHON} unset; .ci/run sets it)");
        return false;
    }
    // SAFETY: geteuid cannot fail.
    if unsafe { libc::geteuid() } != 0 {
        eprintln!("{test}: skipped: a private network namespace needs root");
        return false;
    }
    let exe = std::env::current_exe().expect("this test binary");
    let out = Command::new("unshare")
        .args([
            "-n",
            "-m",
            "--propagation",
            "private",
            "sh",
            "-c",
            "mount -t tmpfs -o size=512m,mode=1777 tmpfs /dev/shm && mkdir -p /tmp/iceoryx2 && \
             mount -t tmpfs tmpfs /tmp/iceoryx2 && ip link set lo up && \
             ip route add 224.0.0.0/4 dev lo && exec \"$0\" \"$@\"",
        ])
        .arg(exe)
        .args(["--exact", test, "--nocapture", "--test-threads=1"])
        .env(CHILD, "1")
        .output()
        .expect("unshare runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && stdout.contains("1 passed"),
        "{test} in its namespace failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
    false
}

/// The rclpy peer: `mode` (`listen`, `talk`, `drive`, `wrongtype`) on `topic` for `count`
/// messages.
fn peer(mode: &str, topic: &str, count: usize) -> Child {
    peer_with(mode, topic, count, &[])
}

/// [`peer`] with environment variables.
fn peer_with(mode: &str, topic: &str, count: usize, env: &[(&str, &str)]) -> Child {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/ros2/imu_peer.py");
    Command::new(std::env::var_os(PYTHON).unwrap())
        .args([script, mode, topic, &count.to_string(), "20"])
        .envs(env.iter().copied())
        .env("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
        .env("ROS_DISTRO", "kilted")
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("the rclpy peer runs")
}

fn lines(child: &mut Child) -> Vec<serde_json::Value> {
    let out = child.stdout.take().unwrap();
    BufReader::new(out)
        .lines()
        .map_while(Result::ok)
        .map(|l| serde_json::from_str(&l).unwrap_or_else(|e| panic!("{l}: {e}")))
        .collect()
}

const N: usize = 500;

#[test]
fn our_imu_messages_reach_an_rclpy_subscriber_field_for_field() {
    if !in_netns("our_imu_messages_reach_an_rclpy_subscriber_field_for_field") {
        return;
    }
    let topic = "/driftless_test/corrected";
    let mut listener = peer("listen", topic, N);
    let mut node = Ros2Node::new("/", "driftless_test").unwrap();
    let publisher = node.imu_publisher(topic, 100).unwrap();
    let end = Instant::now() + Duration::from_secs(20);
    while node.peer_types(topic, false).is_empty() {
        assert!(
            Instant::now() < end,
            "the rclpy subscriber was never discovered"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    // Discovery of a reliable reader completes a little after it is listed.
    std::thread::sleep(Duration::from_millis(500));
    let mut mapping = ImuMapping::new("imu_link", 1.0, Some(0.01));
    let mut sent: Vec<Imu> = Vec::new();
    for i in 0..N {
        let s = GyroSample {
            t_ns: 1_700_000_000_000_000_000 + i as u64 * 1_000_000,
            rate: [1e-3 * i as f64, -2e-3 * i as f64, 0.25],
            drift_std: [1e-4, 2e-4, -1.0],
            ..Default::default()
        };
        let imu = mapping.gyro(&s).unwrap().clone();
        publisher.publish(&imu).unwrap();
        sent.push(imu);
        std::thread::sleep(Duration::from_millis(1));
    }
    let got = lines(&mut listener);
    assert!(listener.wait().unwrap().success());
    assert_eq!(got[0]["ready"], true);
    let msgs: Vec<&serde_json::Value> = got.iter().filter(|v| v.get("stamp").is_some()).collect();
    assert_eq!(msgs.len(), N, "every message arrived");
    for (m, imu) in msgs.iter().zip(&sent) {
        assert_eq!(m["stamp"][0], imu.stamp.sec);
        assert_eq!(m["stamp"][1], imu.stamp.nanosec);
        assert_eq!(m["frame_id"], "imu_link");
        let f = |k: &str| -> Vec<f64> {
            m[k].as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect()
        };
        assert_eq!(f("angular_velocity"), imu.angular_velocity);
        assert_eq!(
            f("angular_velocity_covariance"),
            imu.angular_velocity_covariance
        );
        assert_eq!(f("orientation_covariance")[0], -1.0, "not provided");
        assert_eq!(f("linear_acceleration_covariance")[0], -1.0, "not provided");
    }
    let graph = &got.last().unwrap()["graph"];
    let topics = graph["topics"].as_array().unwrap();
    assert!(
        topics
            .iter()
            .any(|t| t[0] == topic && t[1][0] == "sensor_msgs/msg/Imu"),
        "{graph}"
    );
    assert!(
        graph["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n == "driftless_test"),
        "{graph}"
    );
    assert!(
        graph["publishers"]
            .as_array()
            .unwrap()
            .iter()
            .any(|p| p[0] == "driftless_test" && p[1] == "sensor_msgs/msg/Imu"),
        "{graph}"
    );
}

#[test]
fn an_rclpy_publishers_imu_messages_reach_us_field_for_field() {
    if !in_netns("an_rclpy_publishers_imu_messages_reach_us_field_for_field") {
        return;
    }
    let topic = "/driftless_test/imu";
    let mut node = Ros2Node::new("/", "driftless_test").unwrap();
    let sub = node.imu_subscription(topic, 1000).unwrap();
    let mut talker = peer("talk", topic, N);
    let mut got = Vec::new();
    let end = Instant::now() + Duration::from_secs(30);
    while got.len() < N && Instant::now() < end {
        match sub.take().unwrap() {
            Some((m, _)) => got.push(m),
            None => std::thread::sleep(Duration::from_micros(200)),
        }
    }
    assert!(talker.wait().unwrap().success());
    assert_eq!(got.len(), N, "every message arrived");
    for (i, m) in got.iter().enumerate() {
        assert_eq!(m.stamp.sec, 1_700_000_000 + (i / 1000) as i32, "in order");
        assert_eq!(m.stamp.nanosec, (i % 1000) as u32 * 1_000_000);
        assert_eq!(m.frame_id, "peer_imu");
        assert_eq!(
            m.angular_velocity,
            [0.001 * i as f64, -0.002 * i as f64, 0.5]
        );
        let cov: Vec<f64> = (0..9).map(|k| 1e-6 * (k + 1) as f64).collect();
        assert_eq!(m.angular_velocity_covariance.to_vec(), cov);
        assert_eq!(m.orientation_covariance[0], -1.0);
    }
}

/// A unique iceoryx2 prefix for a daemon of this test process.
fn prefix(tag: &str) -> String {
    format!("dlros{}{tag}_", std::process::id())
}

#[test]
fn a_driver_node_feeds_the_daemon_and_a_navigator_node_reads_the_corrected_rate() {
    if !in_netns("a_driver_node_feeds_the_daemon_and_a_navigator_node_reads_the_corrected_rate") {
        return;
    }
    let d = daemon("e2e");
    let mut navigator = navigator(N);
    let mut driver = peer("talk", "/imu/data_raw", N);
    assert!(driver.wait().unwrap().success());
    let got = lines(&mut navigator);
    assert!(navigator.wait().unwrap().success());
    let err = stop(d);

    let msgs: Vec<&serde_json::Value> = got.iter().filter(|v| v.get("stamp").is_some()).collect();
    assert_eq!(msgs.len(), N, "every message through: {err}");
    // Bit for bit what the same stages give offline on the driver's samples, and the
    // covariance ImuMapping gives them.
    let pipeline = concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/ros2.toml");
    let p = driftless::pipeline::config::load(std::path::Path::new(pipeline)).unwrap();
    let mut offline = driftless::pipeline::offline::Offline::new(&p).unwrap();
    // The rate noise per sample from predict.bias's N: 2.3054 deg/sqrt(h) at 1 kHz.
    let n = driftless::drift::bias::BiasTerms::profile("adis16405")
        .unwrap()
        .n;
    let rate_noise = n * 1000f64.sqrt();
    assert!((rate_noise - 1.2151).abs() < 1e-4, "{rate_noise}");
    let mut mapping = ImuMapping::new("imu_link", 1.0, Some(rate_noise));
    let mut want = Vec::new();
    for i in 0..N {
        let raw = driftless::wire::RawSample {
            t_ns: 1_700_000_000_000_000_000 + i as u64 * 1_000_000,
            seq: i as u64,
            rate: [0.001 * i as f64, -0.002 * i as f64, 0.5],
            epoch: 1,
            ..Default::default()
        };
        offline.push(&raw, &mut |s| want.push(mapping.gyro(&s).unwrap().clone()));
    }
    offline.finish(&mut |s| want.push(mapping.gyro(&s).unwrap().clone()));
    assert_eq!(want.len(), N);
    for (i, (m, w)) in msgs.iter().zip(&want).enumerate() {
        let rate = floats(&m["angular_velocity"]);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            bits(&rate),
            bits(&w.angular_velocity),
            "sample {i}: the offline rate"
        );
        let cov = floats(&m["angular_velocity_covariance"]);
        assert_eq!(
            bits(&cov),
            bits(&w.angular_velocity_covariance),
            "sample {i}: covariance"
        );
    }
    let noise = rate_noise.to_radians().powi(2);
    for (i, m) in msgs.iter().enumerate() {
        // The driver's own stamps, in order, once each.
        assert_eq!(m["stamp"][0], 1_700_000_000 + (i / 1000) as i64, "{i}");
        assert_eq!(m["stamp"][1], (i % 1000) as i64 * 1_000_000, "{i}");
        // No frame_id in ros2.toml: the driver's own frame passes through.
        assert_eq!(m["frame_id"], "peer_imu");
        // A gyro-only driver (covariance[0] = -1): no acceleration out either.
        assert_eq!(m["linear_acceleration_covariance"][0], -1.0, "{i}");
        let cov: Vec<f64> = m["angular_velocity_covariance"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        // The rate noise plus the bias filter's drift variance (large while it learns).
        for (k, c) in cov.iter().enumerate() {
            match k {
                0 | 4 | 8 => assert!(c.is_finite() && *c >= noise, "{cov:?}"),
                _ => assert_eq!(*c, 0.0, "{cov:?}"),
            }
        }
        assert_eq!(m["orientation_covariance"][0], -1.0);
    }
    assert!(
        err.contains(&format!(
            "ros2: {N} Imu in (0 invalid, 0 stamp faults, 0 missing by their stamps, 0 new \
             publishers), 0 refused (a second publisher), {N} Imu out"
        )),
        "{err}"
    );
}

#[test]
fn an_odometry_nodes_stops_drive_the_bias_filter() {
    if !in_netns("an_odometry_nodes_stops_drive_the_bias_filter") {
        return;
    }
    let d = daemon("odom");
    let n = 4000;
    let mut driver = peer("drive", "/imu/data_raw", n);
    assert!(driver.wait().unwrap().success());
    let err = stop(d);
    assert!(err.contains(&format!("{n} Imu in")), "{err}");
    // The outputs follow the odometry: moving for the first half, still for the second (both
    // within the stop signal's 10 ms steps and the filter's delay).
    let line = err
        .lines()
        .find(|l| l.starts_with("outputs:"))
        .unwrap_or_else(|| panic!("{err}"));
    let count = |what: &str| -> usize {
        let at = line.find(what).unwrap_or_else(|| panic!("{line}"));
        line[..at]
            .split_whitespace()
            .last()
            .unwrap()
            .parse()
            .unwrap()
    };
    let (still, moving) = (count(" still"), count(" moving"));
    // An odometry message every 10 samples, and each may come a moment after the Imu message
    // of the same instant: the switch is exact to 10 samples, and the first few samples may
    // come before any odometry (neither).
    assert!(moving.abs_diff(n / 2) <= 10, "{line}");
    assert!(still + moving >= n - 10, "{line}");
    assert!(err.contains("motion in"), "{err}");
}

/// `driftless run pipelines/ros2.toml` under a prefix of its own, quiet, stderr captured.
fn daemon(tag: &str) -> Child {
    daemon_command(tag).spawn().expect("the daemon runs")
}

fn daemon_command(tag: &str) -> Command {
    daemon_of(
        std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/ros2.toml")),
        tag,
    )
}

/// `driftless run PIPELINE` under a prefix of its own, quiet, stderr piped.
fn daemon_of(pipeline: &std::path::Path, tag: &str) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_driftless"));
    command
        .arg("run")
        .arg(pipeline)
        .args(["--prefix", &prefix(tag), "--duration", "60s", "-q"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    command
}

/// SIGTERM to the daemon; its stderr once it exited 0.
fn stop(daemon: Child) -> String {
    // SAFETY: kill(2) on our own child.
    unsafe { libc::kill(daemon.id() as i32, libc::SIGTERM) };
    let out = daemon.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    err
}

/// The rclpy navigator on `/imu/corrected`, once it is ready.
fn navigator(count: usize) -> Child {
    ready(peer("listen", "/imu/corrected", count))
}

/// `child` once it printed `ready` and had a second to match the daemon's publisher.
fn ready(mut child: Child) -> Child {
    let mut first = String::new();
    BufReader::new(child.stdout.as_mut().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.contains("ready"), "{first}");
    std::thread::sleep(Duration::from_secs(1));
    child
}

fn received(mut nav: Child) -> usize {
    let got = lines(&mut nav);
    assert!(nav.wait().unwrap().success());
    got.iter().filter(|v| v.get("stamp").is_some()).count()
}

#[test]
fn nan_rates_a_topic_of_another_type_and_a_qos_mismatch_each_get_a_clear_line_and_the_daemon_serves_on(
) {
    if !in_netns(
        "nan_rates_a_topic_of_another_type_and_a_qos_mismatch_each_get_a_clear_line_and_the_daemon_serves_on",
    ) {
        return;
    }
    let d = daemon("faults");
    let nav = navigator(N);
    // A navigator asking for a history we do not keep: it can never match.
    let mut late = ready(peer_with(
        "listen",
        "/imu/corrected",
        N,
        &[("PEER_DURABILITY", "transient_local")],
    ));
    let mut other = peer("wrongtype", "/imu/data_raw", 300);
    let mut driver = peer_with("talk", "/imu/data_raw", N, &[("PEER_NAN_AT", "100,250")]);
    assert!(driver.wait().unwrap().success());
    assert!(other.wait().unwrap().success());
    assert_eq!(received(nav), N, "every message through, the NaN ones held");
    let err = stop(d);
    assert!(
        err.contains("/imu/data_raw: a message with a non-finite rate"),
        "{err}"
    );
    assert!(
        err.contains(
            "a publisher on /imu/data_raw has type geometry_msgs/msg/Vector3Stamped, not \
             sensor_msgs/msg/Imu"
        ),
        "{err}"
    );
    assert!(err.contains("flagged: 2 invalid"), "{err}");
    assert!(err.contains(&format!("{N} Imu in (2 invalid")), "{err}");
    let _ = late.kill();
    let _ = late.wait();
    assert!(
        err.contains(
            "driftless: ros2: a subscriber of /imu/corrected requests a Durability we do not \
             offer, so it gets nothing (it requests reliable, transient local or more; we offer \
             reliable, volatile)"
        ),
        "{err}"
    );
}

#[test]
fn a_restarted_driver_starts_a_new_epoch_and_a_restarted_navigator_gets_data_again() {
    if !in_netns("a_restarted_driver_starts_a_new_epoch_and_a_restarted_navigator_gets_data_again")
    {
        return;
    }
    let d = daemon("restart");
    for run in 0..2 {
        let nav = navigator(N);
        let mut driver = peer("talk", "/imu/data_raw", N);
        assert!(driver.wait().unwrap().success());
        assert_eq!(received(nav), N, "run {run}");
    }
    let err = stop(d);
    assert!(err.contains("/imu/data_raw: a new publisher"), "{err}");
    assert!(
        err.contains(&format!(
            "{} Imu in (0 invalid, 0 stamp faults, 0 missing by their stamps, 1 new \
             publishers), 0 refused",
            2 * N
        )),
        "{err}"
    );
    assert!(
        err.contains(&format!("pipeline ros2: {0} in, {0} out", 2 * N)),
        "{err}"
    );
}

#[test]
fn wild_stamps_are_stamp_faults_not_losses_and_the_samples_after_them_are_served_whole() {
    if !in_netns(
        "wild_stamps_are_stamp_faults_not_losses_and_the_samples_after_them_are_served_whole",
    ) {
        return;
    }
    let n = 800;
    let d = daemon("stamps");
    let mut nav = navigator(n);
    // The farthest stamp ROS 2 holds (2038; the year 2100 does not fit its i32 seconds), a
    // stamp of 0 ("not set"), and one a second back: 500 samples follow the last.
    let mut driver = peer_with(
        "talk",
        "/imu/data_raw",
        n,
        &[("PEER_STAMPS", "100=max,200=zero,300=back")],
    );
    assert!(driver.wait().unwrap().success());
    let got = lines(&mut nav);
    assert!(nav.wait().unwrap().success());
    let err = stop(d);
    let msgs: Vec<&serde_json::Value> = got.iter().filter(|v| v.get("stamp").is_some()).collect();
    assert_eq!(msgs.len(), n, "every message served: {err}");
    for (i, m) in msgs.iter().enumerate() {
        let want = match i {
            100 => [i64::from(i32::MAX), 0],
            200 => [0, 0],
            300 => [1_700_000_000 - 1, 300_000_000],
            _ => [
                1_700_000_000 + (i / 1000) as i64,
                (i % 1000) as i64 * 1_000_000,
            ],
        };
        assert_eq!(m["stamp"], serde_json::json!(want), "message {i}");
    }
    assert!(
        err.contains(&format!(
            "ros2: {n} Imu in (0 invalid, 3 stamp faults, 0 missing by their stamps, 0 new \
             publishers), 0 refused"
        )),
        "{err}"
    );
    assert!(
        err.contains(
            "flagged: 0 invalid, 0 gaps (0 missing from the source, counted as lost), 3 stamp \
             faults (not lost)"
        ),
        "{err}"
    );
    assert!(
        err.contains("nothing lost; 3 stamp faults (flagged, not lost)"),
        "{err}"
    );
    assert!(
        err.contains(&format!("pipeline ros2: {n} in, {n} out")),
        "{err}"
    );
}

#[test]
fn two_publishers_on_one_topic_one_line_one_epoch_and_the_second_refused() {
    if !in_netns("two_publishers_on_one_topic_one_line_one_epoch_and_the_second_refused") {
        return;
    }
    let d = daemon("twin");
    let mut nav = navigator(N);
    let mut twin = peer("twin", "/imu/data_raw", N);
    assert!(twin.wait().unwrap().success());
    let got = lines(&mut nav);
    assert!(nav.wait().unwrap().success());
    let err = stop(d);
    let msgs: Vec<&serde_json::Value> = got.iter().filter(|v| v.get("stamp").is_some()).collect();
    assert_eq!(msgs.len(), N, "one publisher's messages, every one: {err}");
    // The second's rates are the first's negated: none of them mixed in.
    let sign = |m: &serde_json::Value| m["angular_velocity"][2].as_f64().unwrap() > 0.0;
    assert!(
        msgs.iter().all(|m| sign(m) == sign(msgs[0])),
        "two publishers mixed"
    );
    for (i, m) in msgs.iter().enumerate() {
        assert_eq!(
            m["stamp"][1],
            (i % 1000) as i64 * 1_000_000,
            "{i}: in order"
        );
    }
    assert_eq!(
        err.matches("/imu/data_raw: a second publisher (GID ")
            .count(),
        1,
        "said once: {err}"
    );
    assert!(
        err.contains(&format!(
            "ros2: {N} Imu in (0 invalid, 0 stamp faults, 0 missing by their stamps, 0 new \
             publishers), {N} refused (a second publisher)"
        )),
        "{err}"
    );
    assert!(!err.contains("a new epoch"), "{err}");
    assert!(!err.contains("more (source restarts"), "one epoch: {err}");
    assert!(
        err.contains(&format!("pipeline ros2: {N} in, {N} out")),
        "{err}"
    );
}

#[test]
fn the_ros2_tests_leave_the_hosts_dev_shm_as_they_found_it() {
    // The parent side: the host's /dev/shm before and after a DDS exchange in the namespace.
    let fastdds = || -> Vec<String> {
        std::fs::read_dir("/dev/shm")
            .unwrap()
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.contains("fastdds") || n.contains("fastrtps"))
            .collect()
    };
    let before = (std::env::var_os(CHILD).is_none()).then(fastdds);
    if in_netns("the_ros2_tests_leave_the_hosts_dev_shm_as_they_found_it") {
        // The child: an rclpy talker and listener, which use Fast DDS's shared memory.
        let mut listener = ready(peer("listen", "/shm_test", 100));
        let mut talker = peer("talk", "/shm_test", 100);
        assert!(talker.wait().unwrap().success());
        let got = lines(&mut listener);
        assert!(listener.wait().unwrap().success());
        assert!(got.iter().filter(|v| v.get("stamp").is_some()).count() > 0);
        return;
    }
    if let Some(before) = before {
        let new: Vec<String> = fastdds()
            .into_iter()
            .filter(|n| !before.contains(n))
            .collect();
        assert!(new.is_empty(), "new in the host's /dev/shm: {new:?}");
    }
}

/// The Python example at `examples/ros2/NAME.py` with `args`, stdout piped.
fn example(name: &str, args: &[&str]) -> Child {
    let script = format!("{}/examples/ros2/{name}.py", env!("CARGO_MANIFEST_DIR"));
    Command::new(std::env::var_os(PYTHON).unwrap())
        .arg(script)
        .args(args)
        .env("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
        .env("ROS_DISTRO", "kilted")
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("the example runs")
}

/// The last JSON line a child printed.
fn last_json(child: &mut Child) -> serde_json::Value {
    let out = child.stdout.take().unwrap();
    let last = BufReader::new(out)
        .lines()
        .map_while(Result::ok)
        .filter(|l| l.starts_with('{'))
        .last()
        .expect("a JSON line");
    assert!(child.wait().unwrap().success());
    serde_json::from_str(&last).unwrap()
}

#[test]
fn the_ros2_examples_steer_closer_to_the_truth_through_the_daemon() {
    if !in_netns("the_ros2_examples_steer_closer_to_the_truth_through_the_daemon") {
        return;
    }
    let d = daemon("examples");
    let n = 6000;
    let mut nav = ready(example(
        "navigator",
        &["--count", &n.to_string(), "--timeout", "60"],
    ));
    let mut driver = example("driver", &["--duration", "6", "--rate", "1000"]);
    let sent = last_json(&mut driver);
    let got = last_json(&mut nav);
    let err = stop(d);
    assert_eq!(got["messages"], n, "{got} {err}");
    assert_eq!(got["in_order"], true);
    let truth = sent["truth_rad"].as_f64().unwrap();
    let raw = (sent["raw_rad"].as_f64().unwrap() - truth).abs();
    let corrected = (got["heading_rad"].as_f64().unwrap() - truth).abs();
    // The raw gyro's bias turns it 0.024 rad off in 6 s; the daemon learns the bias while the
    // odometry says the vehicle stands.
    assert!(
        corrected < raw / 3.0,
        "corrected {corrected} rad, raw {raw} rad: {err}"
    );
    assert!(got["sigma_rad"].as_f64().unwrap() > 0.0);
}

#[test]
fn validate_describes_the_ros2_side() {
    // No DDS: validate only reads the file.
    let out = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .args([
            "validate",
            concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/ros2.toml"),
        ])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    for line in [
        "  ros2: node /driftless_ros2 on ROS_DOMAIN_ID's domain, depth 100, frame_id the driver's (imu_link until it says one), rate noise 1.2151 deg/s",
        "    in     /imu/data_raw (sensor_msgs/msg/Imu) -> sensor/raw",
        "    out    ros2/corrected -> /imu/corrected (sensor_msgs/msg/Imu)",
        "    motion /odom (nav_msgs/msg/Odometry) -> vehicle/stop",
    ] {
        assert!(text.lines().any(|l| l == line), "{line:?} in\n{text}");
    }
}

#[test]
fn validate_refuses_a_motion_topic_into_a_bias_filter_without_stop_speed() {
    // A ROS 2 motion message says a speed, never "stands": without stop_speed every signal
    // would be unknown, silently.
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/ros2.toml"))
        .unwrap();
    let without = text.replace("stop_speed = 0.05\n", "");
    assert_ne!(without, text);
    let dir = std::env::temp_dir().join(format!("dl_motion_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("ros2.toml");
    std::fs::write(&file, &without).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .arg("validate")
        .arg(&file)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(out.status.code(), Some(2), "{err}");
    let line = without
        .lines()
        .position(|l| l == "service = \"vehicle/stop\"")
        .unwrap()
        + 1;
    assert!(
        err.contains(&format!(
            "{}:{line}:11: motion_in feeds \"vehicle/stop\" with the vehicle's speed only",
            file.display()
        )),
        "{err}"
    );
    assert!(
        err.contains("add stop_speed = 0.02 (m/s, stands at or below) to stage \"predict\""),
        "{err}"
    );
}

#[test]
fn list_shows_the_ros2_side_on_the_domain_in_force_and_a_bad_domain_is_refused() {
    if !in_netns("list_shows_the_ros2_side_on_the_domain_in_force_and_a_bad_domain_is_refused") {
        return;
    }
    let bad = daemon_command("baddomain")
        .env("ROS_DOMAIN_ID", "233")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(bad.status.code(), Some(2), "{err}");
    assert!(
        err.contains("ROS_DOMAIN_ID=\"233\": a DDS domain is an integer from 0 to 232"),
        "{err}"
    );

    let mut d = daemon_command("list")
        .env("ROS_DOMAIN_ID", "7")
        .spawn()
        .unwrap();
    // Wait on the daemon's own progress: its ROS 2 side says, 3 s after it set up, that no
    // peer came. Only then list: a listing taken while the daemon still creates its nodes
    // shows them half made.
    let (tx, rx) = std::sync::mpsc::channel::<String>();
    let stderr = d.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut all = String::new();
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(line.clone());
            all.push_str(&line);
            all.push('\n');
        }
        all
    });
    let up = std::time::Instant::now() + Duration::from_secs(30);
    while let Ok(line) = rx.recv_timeout(up.saturating_duration_since(std::time::Instant::now())) {
        if line.contains("after 3 s") {
            break;
        }
    }
    let list = |json: bool| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_driftless"));
        c.args(["list", "--prefix", &prefix("list"), "--stats-wait", "10ms"]);
        if json {
            c.arg("--json");
        }
        let out = c.output().unwrap();
        assert!(out.status.success(), "{out:?}");
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let doc: serde_json::Value = serde_json::from_str(&list(true)).unwrap();
    let text = list(false);
    // SAFETY: kill(2) on our own child.
    unsafe { libc::kill(d.id() as i32, libc::SIGTERM) };
    let status = d.wait().unwrap();
    let err = reader.join().unwrap();
    assert!(status.success(), "{err}");
    let ros2 = &doc["pipelines"][0]["ros2"];
    assert!(
        !ros2.is_null(),
        "no ROS 2 side listed: {doc}\n{text}\n{err}"
    );
    assert_eq!(ros2["node"], "/driftless_ros2", "{doc}");
    assert_eq!(ros2["domain"], 7, "{doc}");
    let topics: Vec<[&str; 4]> = ros2["topics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            let f = |k: &str| t[k].as_str().unwrap();
            [f("direction"), f("topic"), f("type"), f("service")]
        })
        .collect();
    assert_eq!(
        topics,
        [
            ["in", "/imu/data_raw", "sensor_msgs/msg/Imu", "sensor/raw"],
            [
                "out",
                "/imu/corrected",
                "sensor_msgs/msg/Imu",
                "ros2/corrected"
            ],
            ["stop", "/odom", "nav_msgs/msg/Odometry", "vehicle/stop"],
        ]
    );
    let nodes = doc["pipelines"][0]["nodes"].to_string();
    assert!(nodes.contains("driftless-ros2-ros2"), "{nodes}");
    let row = text
        .lines()
        .find(|l| l.contains("/imu/corrected"))
        .unwrap_or_else(|| panic!("{text}"));
    let cells: Vec<&str> = row.split_whitespace().collect();
    assert_eq!(
        cells,
        [
            "ros2",
            "/driftless_ros2",
            "7",
            "out",
            "/imu/corrected",
            "sensor_msgs/msg/Imu",
            "ros2/corrected"
        ],
        "{text}"
    );
    assert!(
        text.lines()
            .any(|l| l.starts_with("vehicle/stop") && l.contains("StopSignal")),
        "{text}"
    );
}

/// pipelines/ros2.toml with `extra` added to its `[ros2]` table, written to a directory of its
/// own (returned with the file).
fn ros2_pipeline_with(tag: &str, extra: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/ros2.toml"))
        .unwrap();
    let with = text.replacen("[ros2]\n", &format!("[ros2]\n{extra}\n"), 1);
    assert_ne!(with, text);
    let dir = std::env::temp_dir().join(format!("dl_{tag}_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("ros2.toml");
    std::fs::write(&file, with).unwrap();
    (dir, file)
}

#[test]
fn the_bias_and_its_diagnostics_reach_rclpy_and_warn_past_the_threshold() {
    if !in_netns("the_bias_and_its_diagnostics_reach_rclpy_and_warn_past_the_threshold") {
        return;
    }
    // Inline tables: the extra keys go at the top of [ros2], before its sub-tables.
    let (dir, file) = ros2_pipeline_with(
        "diag",
        "bias_out = { topic = \"/imu/gyro_bias\", service = \"ros2/corrected\" }\n\
         diagnostics = { service = \"ros2/corrected\" }\n\
         diagnostics_period_s = 0.25",
    );
    let d = daemon_of(&file, "diag").spawn().unwrap();
    let n = 4000;
    let mut bias = ready(peer("bias", "/imu/gyro_bias", n));
    let diagnostics = ready(peer("diagnostics", "/diagnostics", 100_000));
    // A gyro at rest with a bias of 0.002, -0.001, 0.0005 rad/s; the vehicle moves for the
    // first half, then stands.
    let mut driver = peer("drive", "/imu/data_raw", n);
    assert!(driver.wait().unwrap().success());
    let got = lines(&mut bias);
    assert!(bias.wait().unwrap().success());
    let statuses = statuses_until_served(diagnostics);
    let err = stop(d);
    let _ = std::fs::remove_dir_all(&dir);

    // The bias: one message per sample, with its stamp and the driver's frame.
    let msgs: Vec<&serde_json::Value> = got.iter().filter(|v| v.get("vector").is_some()).collect();
    assert_eq!(msgs.len(), n, "every sample's bias: {err}");
    for (i, m) in msgs.iter().enumerate() {
        assert_eq!(m["stamp"][0], 1_700_000_000 + (i / 1000) as i64, "{i}");
        assert_eq!(m["stamp"][1], (i % 1000) as i64 * 1_000_000, "{i}");
        assert_eq!(m["frame_id"], "peer_imu");
    }
    // Learnt while the vehicle stood: the gyro's own bias.
    let last = &msgs[n - 1]["vector"];
    for (a, truth) in [0.002, -0.001, 0.0005].iter().enumerate() {
        let b = last[a].as_f64().unwrap();
        assert!(
            (b - truth).abs() < 2e-4,
            "axis {a}: {b} against {truth}: {err}"
        );
    }
    // The diagnostics: named as diagnostic_updater names them, with each value.
    let served: Vec<&serde_json::Value> = statuses.iter().filter(|s| s["level"] != 3).collect();
    assert!(!served.is_empty(), "{statuses:?}");
    for s in &statuses {
        assert_eq!(s["name"], "driftless_ros2: gyro_bias");
        assert_eq!(s["hardware_id"], "driftless_ros2");
    }
    let last = served.last().unwrap();
    for key in [
        "gyro_bias_x",
        "gyro_bias_y",
        "gyro_bias_z",
        "gyro_bias_sigma_x",
        "gyro_bias_sigma_y",
        "gyro_bias_sigma_z",
        "gyro_bias_threshold",
        "stillness",
        "still_samples",
        "moving_samples",
        "samples",
        "deadline_misses",
        "lost",
        "missing_in_input",
    ] {
        assert!(last["values"].get(key).is_some(), "{key} in {last}");
    }
    // The x bias (0.002 rad/s) passes the default threshold, 0.0015 rad/s: WARN, naming x.
    assert_eq!(last["level"], 1, "{last}");
    assert!(
        last["message"]
            .as_str()
            .unwrap()
            .contains("past 0.0015 rad/s on x"),
        "{last}"
    );
    assert_eq!(last["values"]["stillness"], "still", "{last}");
    let x: f64 = last["values"]["gyro_bias_x"]
        .as_str()
        .unwrap()
        .parse()
        .unwrap();
    assert!((x - 0.002).abs() < 2e-4, "{last}");
    let sigma: f64 = last["values"]["gyro_bias_sigma_x"]
        .as_str()
        .unwrap()
        .parse()
        .unwrap();
    assert!(sigma > 0.0 && sigma < 1e-3, "{last}");
    // Nothing lost, no deadline missed, and the last status of a silent period is STALE.
    assert_eq!(last["values"]["lost"], "0", "{last}");
    assert_eq!(last["values"]["missing_in_input"], "0", "{last}");
    assert_eq!(statuses.last().unwrap()["level"], 3);
    assert!(
        err.contains(&format!("{n} bias out, ")) && err.contains("diagnostics out (0 not sent)"),
        "{err}"
    );
}

#[test]
fn validate_checks_the_bias_and_diagnostics_tables_against_the_chain() {
    // No DDS: validate only reads the file.
    let validate = |tag: &str, extra: &str| {
        let (dir, file) = ros2_pipeline_with(tag, extra);
        let out = Command::new(env!("CARGO_BIN_EXE_driftless"))
            .arg("validate")
            .arg(&file)
            .output()
            .unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (code, text, err) = validate(
        "vok",
        "bias_out = { topic = \"/imu/gyro_bias\", service = \"ros2/corrected\" }\n\
         diagnostics = { service = \"ros2/predicted\" }\n\
         accel_noise = 0.02",
    );
    assert_eq!(code, Some(0), "{err}");
    // Refused with exit 2 and an error that says `want`.
    let refused = |tag: &str, extra: &str, want: &str| {
        let (code, _, err) = validate(tag, extra);
        assert_eq!(code, Some(2), "{err}");
        assert!(err.contains(want), "{err}");
    };
    for line in [
        "    out    ros2/corrected -> /imu/gyro_bias (geometry_msgs/msg/Vector3Stamped)",
        "    out    ros2/predicted, ros2/stats -> /diagnostics (diagnostic_msgs/msg/DiagnosticArray) every 1 s, WARN past 0.0015 rad/s",
        "    linear_acceleration as received; its covariance from the samples' accel_std, else accel_noise 0.02 m/s^2",
    ] {
        assert!(text.lines().any(|l| l == line), "{line:?} in\n{text}");
    }
    // Before any predict.bias: no bias to report.
    refused(
        "vup",
        "diagnostics = { service = \"ros2/denoised\" }",
        "diagnostics.service \"ros2/denoised\": no predict.bias stage at or before the stage \
             that publishes it, so its samples carry no bias to report",
    );
    refused(
        "vnone",
        "bias_out = { topic = \"/b\", service = \"nowhere/x\" }",
        "bias_out.service \"nowhere/x\" is no stage's output",
    );
    refused(
        "vtype",
        "bias_out = { topic = \"/b\", service = \"ros2/corrected\", type = \"sensor_msgs/msg/Imu\" }",
        "bias_out.type is geometry_msgs/msg/Vector3Stamped",
    );
    refused(
        "vperiod",
        "diagnostics_period_s = 0.0",
        "diagnostics_period_s",
    );
    // A driver's Imu is m/s^2 (REP 103): a pipeline in g cannot take it.
    let (dir, file) = ros2_pipeline_with("vg", "");
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(
        &file,
        text.replacen(
            "input_units = \"rad/s\"\n",
            "input_units = \"rad/s\"\naccel_units = \"g\"\n",
            1,
        ),
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .arg("validate")
        .arg(&file)
        .output()
        .unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains(
            "imu_in: ROS 2 accelerations are m/s^2 (REP 103): set accel_units = \"m/s^2\""
        ),
        "{err}"
    );
}

#[test]
fn validate_checks_the_magnetometer_table() {
    // No DDS: validate only reads the file.
    let validate = |tag: &str, extra: &str, without_imu_in: bool| {
        let (dir, file) = ros2_pipeline_with(tag, extra);
        if without_imu_in {
            let text = std::fs::read_to_string(&file).unwrap();
            let cut = text.replacen(
                "[ros2.imu_in]\ntopic = \"/imu/data_raw\"\nservice = \"sensor/raw\"\n",
                "",
                1,
            );
            assert_ne!(cut, text);
            std::fs::write(&file, cut).unwrap();
        }
        let out = Command::new(env!("CARGO_BIN_EXE_driftless"))
            .arg("validate")
            .arg(&file)
            .output()
            .unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (code, text, err) = validate(
        "mok",
        "mag_in = { topic = \"/imu/mag\" }\nmag_max_age_s = 0.05",
        false,
    );
    assert_eq!(code, Some(0), "{err}");
    for line in [
        "    in     /imu/data_raw (sensor_msgs/msg/Imu) -> sensor/raw",
        "    in     /imu/mag (sensor_msgs/msg/MagneticField) -> sensor/raw",
        "    magnetometer joined to /imu/data_raw by stamp: each sample the newest reading up \
         to half a period after it, at most 0.05 s older; else none (the heading on the gyro)",
    ] {
        assert!(text.lines().any(|l| l == line), "{line:?} in\n{text}");
    }
    // Refused with exit 2 and an error that says `want`.
    for (tag, extra, without_imu_in, want) in [
        (
            "mnoimu",
            "mag_in = { topic = \"/imu/mag\" }",
            true,
            "mag_in: the magnetometer is joined by stamp to the samples of imu_in, and there is \
             no imu_in",
        ),
        (
            "mage",
            "mag_max_age_s = 0.2",
            false,
            "mag_max_age_s is the age limit of mag_in's readings, and there is no mag_in",
        ),
        (
            "mtype",
            "mag_in = { topic = \"/imu/mag\", type = \"sensor_msgs/msg/Imu\" }",
            false,
            "mag_in.type is sensor_msgs/msg/MagneticField",
        ),
        (
            "mserv",
            "mag_in = { topic = \"/imu/mag\", service = \"sensor/raw\" }",
            false,
            "unknown field `service`",
        ),
        (
            "mrange",
            "mag_in = { topic = \"/imu/mag\" }\nmag_max_age_s = 0.0",
            false,
            "mag_max_age_s",
        ),
        (
            "mtopic",
            "mag_in = { topic = \"imu/mag\" }",
            false,
            "an absolute ROS 2 name",
        ),
    ] {
        let (code, _, err) = validate(tag, extra, without_imu_in);
        assert_eq!(code, Some(2), "{tag}: {err}");
        assert!(err.contains(want), "{tag}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{tag}: one line: {err}");
    }
}

/// The driver's specific force of message `i` (tests/ros2/imu_peer.py `accel`, the same IEEE
/// operations in the same order: the same bits).
fn peer_accel(i: usize) -> [f64; 3] {
    let i = i as u64;
    [
        (i * 7919 % 1009) as f64 / 1009.0 * 0.3 - 0.15,
        -0.2 + (i * 104729 % 997) as f64 / 997.0 * 0.1,
        9.80665 + i as f64 / 3.0e4,
    ]
}

/// A JSON array of numbers.
fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// The messages the rclpy navigator got from `daemon` while the rclpy driver sent N Imu with
/// acceleration (every one of them, or the test fails); the daemon stopped.
fn accel_driven(daemon: Child) -> Vec<serde_json::Value> {
    let mut nav = navigator(N);
    let mut driver = peer_with("talk", "/imu/data_raw", N, &[("PEER_ACCEL", "1")]);
    assert!(driver.wait().unwrap().success());
    let got = lines(&mut nav);
    assert!(nav.wait().unwrap().success());
    let err = stop(daemon);
    let msgs: Vec<serde_json::Value> = got
        .into_iter()
        .filter(|v| v.get("stamp").is_some())
        .collect();
    assert_eq!(msgs.len(), N, "every message through: {err}");
    msgs
}

#[test]
fn a_drivers_acceleration_reaches_the_navigator_bit_for_bit_with_a_finite_covariance() {
    if !in_netns(
        "a_drivers_acceleration_reaches_the_navigator_bit_for_bit_with_a_finite_covariance",
    ) {
        return;
    }
    let msgs = accel_driven(daemon("accel"));
    for (i, m) in msgs.iter().enumerate() {
        assert_eq!(
            m["stamp"][1],
            (i % 1000) as i64 * 1_000_000,
            "{i}: in order"
        );
        assert_eq!(m["frame_id"], "peer_imu", "{i}: the driver's frame");
        let a = floats(&m["linear_acceleration"]);
        assert_eq!(
            a.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            peer_accel(i).map(f64::to_bits),
            "{i}: linear_acceleration bit for bit"
        );
        for key in [
            "linear_acceleration_covariance",
            "angular_velocity_covariance",
        ] {
            let c = floats(&m[key]);
            assert!(c.iter().all(|x| x.is_finite()), "{i}: {key} {c:?}");
            assert!(c[0] > 0.0 && c[4] > 0.0 && c[8] > 0.0, "{i}: {key} {c:?}");
        }
        // predict.bias gives each reading its white noise (accel_std: the ADIS16405 profile's
        // VRW at 1 kHz): diagonal, its square, not the driver's covariance.
        let std = driftless::drift::bias::AccelTerms::ADIS16405.white_std(1000.0);
        let var = std * std;
        let c = floats(&m["linear_acceleration_covariance"]);
        assert_eq!(c, [var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, var], "{i}");
        assert_eq!(m["orientation_covariance"][0], -1.0, "{i}: no orientation");
    }
}

#[test]
fn the_attitude_pipeline_fills_the_orientation_and_its_covariance() {
    if !in_netns("the_attitude_pipeline_fills_the_orientation_and_its_covariance") {
        return;
    }
    let pipeline = concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/ros2-attitude.toml");
    let msgs = accel_driven(
        daemon_of(std::path::Path::new(pipeline), "attitude")
            .spawn()
            .expect("the daemon runs"),
    );
    for (i, m) in msgs.iter().enumerate() {
        // The acceleration still passes bit for bit beside the orientation.
        let a = floats(&m["linear_acceleration"]);
        assert_eq!(
            a.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            peer_accel(i).map(f64::to_bits),
            "{i}"
        );
        let q = floats(&m["orientation"]);
        let norm: f64 = q.iter().map(|v| v * v).sum();
        assert!((norm - 1.0).abs() < 1e-9, "{i}: {q:?}");
        // REP 145: roll and pitch from gravity (the same sd about x and y), the relative yaw
        // (no magnetometer) any heading; diagonal, every element finite.
        let c = floats(&m["orientation_covariance"]);
        assert!(c.iter().all(|x| x.is_finite()), "{i}: {c:?}");
        assert!(c[0] > 0.0 && c[0] == c[4], "{i}: {c:?}");
        assert_eq!(c[8], std::f64::consts::PI.powi(2), "{i}: {c:?}");
        assert_eq!([c[1], c[2], c[3], c[5], c[6], c[7]], [0.0; 6], "{i}");
    }
    // The driver turns at 0.5 rad/s about z (and faster and faster about x and y): the
    // orientation follows the rate, it is no constant.
    let first = floats(&msgs[0]["orientation"]);
    let last = floats(&msgs[N - 1]["orientation"]);
    let dot: f64 = first.iter().zip(&last).map(|(a, b)| a * b).sum();
    assert!(dot.abs() < 0.999, "{first:?} {last:?}");
}

/// The yaw of an orientation quaternion (x, y, z, w), body to ENU: anticlockwise from east.
fn yaw_of(q: &[f64]) -> f64 {
    let [x, y, z, w] = [q[0], q[1], q[2], q[3]];
    (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z))
}

/// 9D through the daemon (`pipelines/ros2-9d.toml`: `mag_in`, `attitude.6d` with `use_mag`): an
/// rclpy driver publishes a level gyro at rest at 1 kHz and a MagneticField at 100 Hz of a
/// body turned 30 deg from east, for 4 s of the 5; the rclpy navigator's Imu has an absolute
/// yaw within 3 deg of 30 deg, with the heading filter's variance (not REP 145's relative
/// pi^2) once the field was trusted, and keeps it when the magnetometer stops. Every Imu message goes through; the
/// exit line counts the readings joined (4,000 samples and the 0.1 s after the last reading);
/// a NaN reading is flagged and held by the guard at the samples it joins.
#[test]
fn the_magnetometer_through_the_daemon_makes_the_navigators_yaw_absolute() {
    if !in_netns("the_magnetometer_through_the_daemon_makes_the_navigators_yaw_absolute") {
        return;
    }
    const M: usize = 5000;
    let pipeline = concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/ros2-9d.toml");
    let d = daemon_of(std::path::Path::new(pipeline), "mag")
        .spawn()
        .expect("the daemon runs");
    let mut nav = navigator(M);
    let mut driver = peer_with(
        "mag",
        "/imu/data_raw",
        M,
        &[("PEER_MAG_UNTIL", "4000"), ("PEER_MAG_NAN_AT", "3000")],
    );
    assert!(driver.wait().unwrap().success());
    let got = lines(&mut nav);
    assert!(nav.wait().unwrap().success());
    let err = stop(d);
    let msgs: Vec<&serde_json::Value> = got.iter().filter(|v| v.get("stamp").is_some()).collect();
    assert_eq!(msgs.len(), M, "every message through: {err}");
    let pi2 = std::f64::consts::PI.powi(2);
    let yaw_var = |m: &serde_json::Value| floats(&m["orientation_covariance"])[8];
    // Relative at first (no field trusted yet), then absolute for good.
    assert_eq!(yaw_var(msgs[0]), pi2, "the first yaw is relative");
    let first = msgs
        .iter()
        .position(|m| yaw_var(m) != pi2)
        .unwrap_or_else(|| panic!("the yaw never became absolute: {err}"));
    assert!(first < 1000, "absolute only at message {first}");
    let yaw = |m: &serde_json::Value| yaw_of(&floats(&m["orientation"])).to_degrees();
    for (i, m) in msgs.iter().enumerate() {
        assert_eq!(
            m["stamp"][1],
            (i % 1000) as i64 * 1_000_000,
            "{i}: in order"
        );
        // From the first fix on: never "any heading" again, and the heading the field implies.
        if i >= first {
            let var = yaw_var(m);
            assert!(var.is_finite() && var > 0.0 && var < pi2, "{i}: {var}");
            assert!((yaw(m) - 30.0).abs() < 3.0, "{i}: yaw {} deg", yaw(m));
        }
    }
    // Wide at the first fix; once the field passed its tests for 2 s, used and sure (the
    // heading filter's sd: under 5 deg by the last reading).
    let sd = |i: usize| yaw_var(msgs[i]).sqrt().to_degrees();
    assert!(
        sd(first) > 10.0 && sd(3999) < 5.0,
        "{} {}",
        sd(first),
        sd(3999)
    );
    eprintln!(
        "9D: absolute from message {first} (sd {:.1} deg, yaw {:.2} deg); at 3999 sd {:.2} deg, \
         yaw {:.2} deg; at {} sd {:.2} deg, yaw {:.2} deg",
        yaw_var(msgs[first]).sqrt().to_degrees(),
        yaw(msgs[first]),
        yaw_var(msgs[3999]).sqrt().to_degrees(),
        yaw(msgs[3999]),
        M - 1,
        yaw_var(msgs[M - 1]).sqrt().to_degrees(),
        yaw(msgs[M - 1]),
    );
    // Once the magnetometer stopped, the heading rests on the gyro: its variance grows.
    assert!(yaw_var(msgs[M - 1]) > yaw_var(msgs[4100]), "{err}");
    // The exit line: 400 readings; samples 0..=4090 carry one (the last, at 3.990 s, serves
    // 0.1 s), give or take the few whose reading arrived after them.
    let line = err
        .lines()
        .find(|l| l.contains("MagneticField in"))
        .unwrap_or_else(|| panic!("{err}"));
    assert!(
        line.contains("400 MagneticField in (0 refused: no stamp, or older than all held)"),
        "{line}"
    );
    let count = |what: &str| -> usize {
        let at = line.find(what).unwrap_or_else(|| panic!("{line}"));
        line[..at]
            .split_whitespace()
            .last()
            .unwrap()
            .parse()
            .unwrap()
    };
    let (with_mag, without) = (count(" Imu with a magnetometer reading"), count(" without"));
    assert_eq!(with_mag + without, M, "{line}");
    assert!(with_mag.abs_diff(4091) <= 10, "{line}");
    assert!(err.contains("/imu/mag: no reading fresh enough"), "{err}");
    // The NaN reading at 3 s: carried to the ten samples after it (give or take one whose
    // reading came late), each flagged and held by the guard, never a NaN out (the yaw above).
    let held = err
        .lines()
        .find_map(|l| l.strip_prefix("flagged: "))
        .and_then(|l| {
            l.split(", ")
                .find_map(|p| p.strip_suffix(" accelerometer or magnetometer readings held"))
        })
        .and_then(|n| n.parse::<usize>().ok())
        .unwrap_or_else(|| panic!("{err}"));
    assert!((9..=11).contains(&held), "{held} held: {err}");
}

/// A vehicle that never stops, in rclpy: a 1 kHz Imu driver whose gyro turns about +z with
/// the vehicle, and a 50 Hz odometry node (its yaw rate with a covariance, 30 ms late). The
/// stops teach nothing; the odometry teaches the z bias while driving, and it shows where a
/// navigator looks: the Imu out's covariance shrinks on z alone, and /diagnostics says what
/// the odometry did.
#[test]
fn an_odometry_nodes_yaw_rate_teaches_the_bias_while_driving() {
    if !in_netns("an_odometry_nodes_yaw_rate_teaches_the_bias_while_driving") {
        return;
    }
    let (dir, file) = ros2_pipeline_with(
        "turn",
        "diagnostics = { service = \"ros2/corrected\" }\ndiagnostics_period_s = 0.25",
    );
    let d = daemon_of(&file, "turn").spawn().unwrap();
    let n = 10_000;
    let nav = navigator(n);
    let diagnostics = ready(peer("diagnostics", "/diagnostics", 100_000));
    let mut driver = peer("turn", "/imu/data_raw", n);
    assert!(driver.wait().unwrap().success());
    let got = lines_of(nav);
    // The last status that saw samples.
    let last = statuses_until_served(diagnostics)
        .into_iter()
        .rfind(|s| s["level"] != 3);
    let err = stop(d);
    let _ = std::fs::remove_dir_all(&dir);

    let imus: Vec<&serde_json::Value> = got.iter().filter(|v| v.get("stamp").is_some()).collect();
    assert_eq!(imus.len(), n, "every sample: {err}");
    let var = |i: usize, k: usize| imus[i]["angular_velocity_covariance"][k].as_f64().unwrap();
    // The variance on z fell as its bias was learnt; on x (never learnt: no stop) it did not.
    let (z0, z1) = (var(100, 8), var(n - 1, 8));
    let (x0, x1) = (var(100, 0), var(n - 1, 0));
    assert!(z1 < 0.75 * z0, "z variance {z0} -> {z1}: {err}");
    assert!(x1 >= x0, "x variance {x0} -> {x1}");
    // The corrected z rate during the last straight second is the vehicle's (0), not the bias.
    let straight: Vec<f64> = imus[n - 3000 + 100..n - 2000]
        .iter()
        .map(|m| m["angular_velocity"][2].as_f64().unwrap())
        .collect();
    let mean = straight.iter().sum::<f64>() / straight.len() as f64;
    assert!(
        mean.abs() < 0.0015,
        "z on the straight {mean} rad/s (bias 0.004): {err}"
    );
    let last = last.unwrap_or_else(|| panic!("no diagnostics: {err}"));
    let v = &last["values"];
    assert_eq!(v["vehicle_up"], "+z", "{last}");
    assert_eq!(v["odometry_mounting"], "confirmed", "{last}");
    let num = |k: &str| -> f64 { v[k].as_str().unwrap().parse().unwrap() };
    assert!(num("odometry_spans_used") >= 5.0, "{last}");
    assert!(
        (num("gyro_bias_learnt_in_motion") - 0.004).abs() < 0.0015,
        "{last}"
    );
    assert!((num("gyro_bias_z") - 0.004).abs() < 0.0015, "{last}");
    assert!(err.contains("motion in"), "{err}");
    assert!(
        !err.contains("off this host's clock") && !err.contains("yaw rate is refused"),
        "{err}"
    );
    eprintln!("z variance {z0:.3e} -> {z1:.3e}; straight z {mean:+.5} rad/s; diagnostics {v}");
}

/// The statuses the rclpy `diagnostics` peer prints as they come, until the daemon has served
/// every sample: after statuses of samples, one of a period without any (STALE); the peer is
/// stopped then.
fn statuses_until_served(mut diagnostics: Child) -> Vec<serde_json::Value> {
    let mut statuses: Vec<serde_json::Value> = Vec::new();
    let out = diagnostics.stdout.take().unwrap();
    for line in BufReader::new(out).lines().map_while(Result::ok) {
        let v: serde_json::Value = serde_json::from_str(&line).unwrap();
        let Some(s) = v.get("status").and_then(|s| s.get(0)).cloned() else {
            continue;
        };
        let stale = s["level"] == 3;
        let served = statuses.iter().any(|s| s["level"] != 3);
        statuses.push(s);
        if stale && served {
            break;
        }
    }
    let _ = diagnostics.kill();
    let _ = diagnostics.wait();
    statuses
}

fn lines_of(mut child: Child) -> Vec<serde_json::Value> {
    let got = lines(&mut child);
    assert!(child.wait().unwrap().success());
    got
}
