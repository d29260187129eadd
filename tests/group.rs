//! Several pipelines in one daemon (`driftless run a.toml b.toml ...`): the real binary, real
//! iceoryx2 services, this test process as the subscriber. Each test has its own prefix.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::{
    collect, csv, external_pipeline, finish, offline_denoised, qos, raw, signal, start, test_rates,
    wait_ready, Dir, Prefix,
};
use driftless::transport::Transport;
use driftless::wire::{GyroSample, RawSample};

const SIGTERM: i32 = 15;

/// Pipeline `name`: `{name}.csv` replayed at `pace` (looping or not) through a db4 / 3-level
/// wavelet denoiser to `{name}/corrected`.
fn imu(name: &str, pace: &str, looped: bool) -> String {
    format!(
        r#"
name = "{name}"
rate_hz = 1000.0
input_units = "deg/s"
report_interval_s = 60.0

[iceoryx2]
buffer_size = 2048

[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "{name}/raw"
file = "{name}.csv"
time_column = "t"
pace = "{pace}"
loop = {looped}

[[stage]]
name = "denoise"
kind = "denoise.wavelet"
input = "{name}/raw"
output = "{name}/denoised"
wavelet = "db4"
level = 3
window = 128
lag = 16

[[stage]]
name = "publish"
kind = "publish"
input = "{name}/denoised"
output = "{name}/corrected"
"#
    )
}

/// A simulated 3-axis IMU `name` at 1 kHz that stops after `samples`.
fn sim(name: &str, samples: usize) -> String {
    format!(
        r#"
name = "{name}"
rate_hz = 1000.0
axes = 3
report_interval_s = 60.0

[[stage]]
name = "sensor"
kind = "ingest.sim"
output = "{name}/raw"
profile = "adis16405"
samples = {samples}

[[stage]]
name = "denoise"
kind = "denoise.wavelet"
input = "{name}/raw"
output = "{name}/denoised"
wavelet = "db6"
level = 5
window = 1024
lag = 64

[[stage]]
name = "publish"
kind = "publish"
input = "{name}/denoised"
output = "{name}/corrected"
"#
    )
}

/// `driftless run FILES... --prefix P --quiet` plus `extra`.
fn start_group(files: &[&Path], prefix: &Prefix, extra: &[&str]) -> std::process::Child {
    let (first, rest) = files.split_first().expect("a pipeline");
    let mut args: Vec<&str> = rest.iter().map(|f| f.to_str().unwrap()).collect();
    args.extend_from_slice(extra);
    start(first, prefix, &args)
}

/// Wait for the daemon `child` to exit 0 (its stderr in the message if not); the resources it
/// used, all threads (from wait4: std's wait does not give them).
fn reap_with_usage(child: &mut std::process::Child) -> libc::rusage {
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: a zeroed rusage is valid; wait4 on our own child, which std has not reaped.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let rc = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    let mut err = String::new();
    if let Some(mut e) = child.stderr.take() {
        let _ = std::io::Read::read_to_string(&mut e, &mut err);
    }
    assert_eq!(rc, pid);
    assert!(
        libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0,
        "stderr: {err}"
    );
    usage
}

fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).expect("report written");
    serde_json::from_str(&text).expect("report is JSON")
}

/// Run `files` in one daemon to their end with a subscriber on each `{name}/corrected`;
/// returns what each subscriber received, the reports and stderr.
fn run_to_end(
    files: &[&Path],
    names: &[&str],
    prefix: &Prefix,
    report: &Path,
) -> (Vec<Vec<GyroSample>>, serde_json::Value, String) {
    let me = Transport::new(&prefix.0, "test", qos(2048)).expect("node");
    let subs: Vec<_> = names
        .iter()
        .map(|n| {
            me.input::<GyroSample>(&format!("{n}/corrected"))
                .expect("subscriber")
        })
        .collect();
    let mut child = start_group(files, prefix, &["--report", report.to_str().unwrap()]);
    // Read while it runs: a publisher's samples go with it.
    let mut got: Vec<Vec<GyroSample>> = names.iter().map(|_| Vec::new()).collect();
    let end = std::time::Instant::now() + Duration::from_secs(30);
    loop {
        let exited = child.try_wait().expect("wait").is_some();
        for (sub, got) in subs.iter().zip(&mut got) {
            while let Some(s) = sub.receive().expect("receive") {
                got.push(s);
            }
        }
        if exited || std::time::Instant::now() > end {
            break;
        }
        std::thread::sleep(Duration::from_micros(500));
    }
    let (code, err) = finish(child, Duration::from_secs(10));
    assert_eq!(code, Some(0), "stderr: {err}");
    (got, read_json(report), err)
}

#[test]
fn pipelines_sharing_a_daemon_each_publish_every_sample_once_as_they_would_alone() {
    let dir = Dir::new();
    let lengths = [("a", 700), ("b", 300), ("c", 500)];
    let files: Vec<PathBuf> = lengths
        .iter()
        .enumerate()
        .map(|(i, (name, n))| {
            // Different contents per IMU: a different stretch of the same signal.
            let all = csv(*n + 40);
            let rows: Vec<&str> = all.lines().collect();
            let mut text = String::from("t,x,y,z\n");
            for line in &rows[1 + 20 * i..1 + 20 * i + n] {
                text.push_str(line);
                text.push('\n');
            }
            dir.write(&format!("{name}.csv"), &text);
            dir.write(&format!("{name}.toml"), &imu(name, "realtime", false))
        })
        .collect();
    let names: Vec<&str> = lengths.iter().map(|(n, _)| *n).collect();
    let prefix = Prefix::new("group");
    let all: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    let (got, reports, err) = run_to_end(&all, &names, &prefix, &dir.path("report.json"));

    let reports = reports
        .as_array()
        .expect("an array: one report per pipeline");
    assert_eq!(reports.len(), 3);
    for (((name, n), r), got) in lengths.iter().zip(reports).zip(&got) {
        assert_eq!(r["pipeline"], *name, "in the order given");
        assert_eq!(r["samples_in"], *n as u64, "{name}");
        assert_eq!(
            r["samples_out"], *n as u64,
            "{name}: the shorter ones ended first"
        );
        assert_eq!(r["lost"], 0, "{name}");
        assert_eq!(got.len(), *n, "{name}: every sample published");
        for (i, s) in got.iter().enumerate() {
            assert_eq!(s.seq, i as u64, "{name}: in order, exactly once");
        }
        assert!(
            err.contains(&format!("pipeline {name}: {n} in, {n} out")),
            "a final table per pipeline: {err}"
        );
    }

    // Each alone gives the same bits: sharing a thread changes when, not what.
    for ((name, _), (file, shared)) in lengths.iter().zip(files.iter().zip(&got)) {
        let alone_prefix = Prefix::new(&format!("alone{name}"));
        let (alone, report, _) = run_to_end(
            &[file],
            &[name],
            &alone_prefix,
            &dir.path(&format!("{name}.json")),
        );
        assert!(report.is_object(), "one pipeline: one report object");
        assert_eq!(alone[0].len(), shared.len());
        for (a, s) in alone[0].iter().zip(shared) {
            assert_eq!((a.seq, a.t_ns, a.flags), (s.seq, s.t_ns, s.flags));
            assert_eq!(a.rate.map(f64::to_bits), s.rate.map(f64::to_bits), "{name}");
        }
    }
}

#[test]
fn sigterm_drains_every_pipeline_of_the_daemon_and_leaves_nothing_behind() {
    let dir = Dir::new();
    let files: Vec<PathBuf> = ["p", "q"]
        .iter()
        .map(|name| {
            dir.write(&format!("{name}.csv"), &csv(400));
            dir.write(&format!("{name}.toml"), &imu(name, "realtime", true))
        })
        .collect();
    let prefix = Prefix::new("groupterm");
    let report = dir.path("report.json");
    let all: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    let mut child = start_group(&all, &prefix, &["--report", report.to_str().unwrap()]);
    wait_ready(&prefix, "q/stats", &mut child);
    std::thread::sleep(Duration::from_millis(400));
    signal(&child, SIGTERM);
    let (code, err) = finish(child, Duration::from_secs(10));
    assert_eq!(code, Some(0), "stderr: {err}");
    let reports = read_json(&report);
    for r in reports.as_array().expect("array") {
        let n = r["samples_in"].as_u64().unwrap();
        assert!(n > 100, "ran at ~1 kHz for 400 ms: {r}");
        assert_eq!(r["samples_out"], n, "drained: {r}");
    }
    assert!(prefix.leftovers().is_empty(), "{:?}", prefix.leftovers());
}

#[test]
fn simulated_imus_sharing_a_daemon_wake_together() {
    // Four 1 kHz IMUs for 1 s: their samples fall due at the same instants, so the hot thread
    // wakes about once per millisecond for all four (separately it would be four times).
    const N: usize = 1000;
    let dir = Dir::new();
    let files: Vec<PathBuf> = (0..4)
        .map(|i| dir.write(&format!("s{i}.toml"), &sim(&format!("s{i}"), N)))
        .collect();
    let prefix = Prefix::new("groupwake");
    let report = dir.path("report.json");
    let all: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    // Reaped below by wait4, which gives the rusage that std's wait does not.
    #[allow(clippy::zombie_processes)]
    let mut child = start_group(&all, &prefix, &["--report", report.to_str().unwrap()]);
    let usage = reap_with_usage(&mut child);
    for r in read_json(&report).as_array().expect("array") {
        assert_eq!(r["samples_out"], N as u64, "{r}");
        let due = &r["due_to_published_ns"];
        assert_eq!(due["count"], r["end_to_end_ns"]["count"], "{r}");
        assert!(
            due["p50"].as_u64() >= r["end_to_end_ns"]["p50"].as_u64(),
            "due to publish includes the wait: {r}"
        );
    }
    // Voluntary switches of every thread: the hot thread's ~N sleeps, the reporters' polls
    // and the start. Four separate wake-ups per millisecond alone would be 4 N (2.7 N were
    // counted when each kept its own clock, a few microseconds apart).
    let switches = usage.ru_nvcsw as usize;
    assert!(switches < 2 * N, "{switches} voluntary context switches");
    assert!(prefix.leftovers().is_empty(), "{:?}", prefix.leftovers());
}

#[test]
fn sensor_drivers_and_a_simulated_imu_share_a_daemon() {
    // Two IMUs published by drivers (this process; one notifies after each sample, the other
    // never does) and a simulated one, in one daemon. Half of the drivers' samples come while
    // the simulator runs, half after it ended.
    const N: usize = 1200;
    const SIM: usize = 1500;
    let dir = Dir::new();
    let denoise = "kind = \"denoise.wavelet\"\nwavelet = \"db4\"\nlevel = 4\nthreshold = \"soft\"\nwindow = 256\nlag = 32";
    let names = ["d0", "d1"];
    let mut files: Vec<PathBuf> = names
        .iter()
        .map(|n| dir.write(&format!("{n}.toml"), &external_pipeline(n, denoise, 4096)))
        .collect();
    files.push(dir.write("s.toml", &sim("s", SIM)));
    let prefix = Prefix::new("groupdrivers");
    let report = dir.path("report.json");
    let me = Transport::new(&prefix.0, "test", qos(4096)).expect("node");
    let corrected: Vec<_> = names
        .iter()
        .map(|n| {
            me.input::<GyroSample>(&format!("{n}/corrected"))
                .expect("subscriber")
        })
        .collect();
    let sensors: Vec<_> = names
        .iter()
        .zip([true, false])
        .map(|(n, notify)| {
            me.output::<RawSample>(&format!("{n}/sensor"), notify)
                .expect("sensor publisher")
        })
        .collect();
    let all: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    // Reaped below by wait4, which gives the rusage that std's wait does not.
    #[allow(clippy::zombie_processes)]
    let mut child = start_group(&all, &prefix, &["--report", report.to_str().unwrap()]);
    wait_ready(&prefix, "s/stats", &mut child);
    let started = std::time::Instant::now();

    let inputs = [test_rates(N), test_rates(N + 100).split_off(100)];
    let publish = |which: &[usize], range: std::ops::Range<usize>| {
        for i in range {
            for &k in which {
                let sample = raw(i as u64, i as u64 * 1_000_000, inputs[k][i]);
                let delivered = sensors[k].send(&sample).expect("send");
                assert_eq!(delivered, 1, "the daemon subscribes to each sensor");
                sensors[k].notify();
            }
            if i % 64 == 63 {
                std::thread::sleep(Duration::from_millis(2));
            }
        }
    };
    publish(&[0, 1], 0..N / 2);
    let mut got: Vec<Vec<GyroSample>> = corrected
        .iter()
        .map(|c| collect(c, N / 2 - 32, Duration::from_secs(10)))
        .collect();
    // After the simulator's 1.5 s, the driver that does not notify alone: its samples are
    // read at the poll timeout. Then the other, which wakes the daemon.
    std::thread::sleep(Duration::from_millis(1700).saturating_sub(started.elapsed()));
    for k in [1, 0] {
        publish(&[k], N / 2..N);
        got[k].extend(collect(&corrected[k], N / 2, Duration::from_secs(10)));
    }
    // Nothing comes for a while: the daemon sleeps (a waker left readable would spin).
    std::thread::sleep(Duration::from_millis(3000).saturating_sub(started.elapsed()));
    signal(&child, SIGTERM);
    for (c, got) in corrected.iter().zip(&mut got) {
        got.extend(collect(c, 32, Duration::from_secs(10)));
    }
    let usage = reap_with_usage(&mut child);
    let wall = started.elapsed().as_secs_f64();

    for ((name, got), input) in names.iter().zip(&got).zip(&inputs) {
        assert_eq!(got.len(), N, "{name}: every sample once");
        let expected = offline_denoised(input, "db4", 4, 256, 32);
        for (i, (s, e)) in got.iter().zip(&expected).enumerate() {
            assert_eq!(s.seq, i as u64, "{name}: in order");
            assert_eq!(s.rate, *e, "{name}: sample {i} as the offline denoiser");
        }
    }
    let reports = read_json(&report);
    let reports = reports.as_array().expect("array");
    for (r, n) in reports.iter().zip([N, N, SIM]) {
        assert_eq!(r["samples_out"], n as u64, "{r}");
        assert_eq!(r["lost"], 0, "{r}");
    }
    // The simulator kept its pace beside the drivers: woken at its due times, not at a
    // driver's sample or a millisecond's rounding.
    let late = reports[2]["woken_late_ns"]["p50"].as_u64().expect("paced");
    // (With epoll's millisecond timeouts instead of the timer: ~520 us.)
    assert!(late < 350_000, "woken {late} ns late (p50): {}", reports[2]);
    let cpu = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    let busy = cpu(usage.ru_utime) + cpu(usage.ru_stime);
    eprintln!("simulator woken {late} ns late (p50); daemon {busy:.2} s of CPU in {wall:.2} s");
    assert!(busy < 0.5 * wall, "{busy:.2} s of CPU in {wall:.2} s");
}

#[test]
fn pipelines_that_cannot_share_a_daemon_are_refused_before_anything_starts() {
    let dir = Dir::new();
    dir.write("a.csv", &csv(50));
    let a = dir.write("a.toml", &imu("a", "asap", false));
    // Another pipeline publishing a's raw service.
    let clash = dir.write(
        "clash.toml",
        &imu("a", "asap", false)
            .replacen("name = \"a\"", "name = \"b\"", 1)
            .replace("\"a/denoised\"", "\"b/denoised\"")
            .replace("\"a/corrected\"", "\"b/corrected\""),
    );
    let pinned = |name: &str, cpu: u32| {
        let text = imu(name, "asap", false).replace(
            "report_interval_s = 60.0",
            &format!("report_interval_s = 60.0\ncpu = {cpu}"),
        );
        dir.write(&format!("{name}.csv"), &csv(50));
        dir.write(&format!("{name}.toml"), &text)
    };
    let (p0, p1) = (pinned("p0", 0), pinned("p1", 1));
    let show = |p: &Path| p.display().to_string();
    let cases: [(&[&Path], Vec<String>); 3] = [
        (
            &[&a, &a],
            vec![
                format!("{} and {} are both pipeline \"a\"", show(&a), show(&a)),
                "rename one".into(),
            ],
        ),
        (
            &[&a, &clash],
            vec![format!(
                "{} and {} both publish \"a/raw\"",
                show(&a),
                show(&clash)
            )],
        ),
        (
            &[&p0, &a, &p1],
            vec![format!(
                "{} sets cpu = 0 and {} sets cpu = 1",
                show(&p0),
                show(&p1)
            )],
        ),
    ];
    for (i, (files, wanted)) in cases.iter().enumerate() {
        let prefix = Prefix::new(&format!("grouprefuse{i}"));
        let report = dir.path(&format!("r{i}.json"));
        let child = start_group(files, &prefix, &["--report", report.to_str().unwrap()]);
        let (code, err) = finish(child, Duration::from_secs(10));
        assert_eq!(code, Some(2), "case {i}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
        for w in wanted {
            assert!(err.contains(w.as_str()), "case {i}: '{w}' not in: {err}");
        }
        assert!(!report.exists(), "case {i}: nothing ran");
        assert!(prefix.leftovers().is_empty(), "{:?}", prefix.leftovers());
        // `validate` with the same files says the same.
        let mut args = vec!["validate"];
        args.extend(files.iter().map(|f| f.to_str().unwrap()));
        let out = common::driftless(&args);
        let (_, err) = common::text(&out);
        assert_eq!(out.status.code(), Some(2), "validate, case {i}: {err}");
        assert!(
            err.contains(wanted[0].as_str()),
            "validate, case {i}: {err}"
        );
    }
    let out = common::driftless(&["validate", a.to_str().unwrap(), p0.to_str().unwrap()]);
    let (stdout, err) = common::text(&out);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(
        stdout.contains("the 2 pipelines can share one daemon"),
        "{stdout}"
    );
}
