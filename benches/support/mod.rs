//! What the daemon benches share: unique iceoryx2 prefixes and their clean-up, the daemon run
//! as a real process, its JSON report, a process's CPU time, and real-time scheduling.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

/// Put the calling thread on SCHED_FIFO at `priority`; says which scheduling it got.
pub fn realtime(priority: i32) -> String {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: a valid sched_param; 0 is the calling thread.
    if unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) } == 0 {
        format!("SCHED_FIFO {priority}")
    } else {
        "default scheduling (SCHED_FIFO not permitted)".into()
    }
}

/// Seconds per measured run: `DRIFTLESS_BENCH_SECONDS`, else `full` under `cargo bench` (which
/// passes --bench) and 2 s when `cargo test --benches` runs the bench as a check.
pub fn bench_seconds(full: f64) -> f64 {
    let quick = !std::env::args().any(|a| a == "--bench");
    std::env::var("DRIFTLESS_BENCH_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(if quick { 2.0 } else { full })
}

/// The 1, 5 and 15 minute load averages (/proc/loadavg), for the machine's load beside a result.
pub fn loadavg() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

pub fn prefix(tag: &str) -> String {
    format!("dlbench{}{tag}_", std::process::id())
}

pub fn clean(prefix: &str) {
    for dir in [
        "/dev/shm",
        "/tmp/iceoryx2/nodes",
        "/tmp/iceoryx2/services",
        "/tmp/iceoryx2",
    ] {
        if let Ok(rd) = std::fs::read_dir(dir) {
            for e in rd.flatten() {
                if e.file_name().to_string_lossy().starts_with(prefix) {
                    let _ = std::fs::remove_file(e.path());
                    let _ = std::fs::remove_dir_all(e.path());
                }
            }
        }
    }
}

/// CPU seconds (user + system) of a live process.
pub fn cpu_seconds(pid: u32) -> f64 {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
        return f64::NAN;
    };
    let Some(after) = stat.rfind(')') else {
        return f64::NAN;
    };
    let fields: Vec<&str> = stat[after + 2..].split_whitespace().collect();
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) } as f64;
    (ticks(11) + ticks(12)) / hz
}

pub fn start_daemon(pipeline: &Path, prefix: &str, report: &Path, extra: &[&str]) -> Child {
    start_group(&[pipeline], prefix, report, extra)
}

/// One daemon running every pipeline of `pipelines` on its hot thread (its report: an array).
pub fn start_group(pipelines: &[&Path], prefix: &str, report: &Path, extra: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_driftless"))
        .arg("run")
        .args(pipelines)
        .args(["--prefix", prefix, "--quiet", "--report"])
        .arg(report)
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn driftless")
}

/// SIGTERM to `child` (a daemon or bridge stops cleanly on it), then [`wait_exit`].
pub fn sigterm_and_wait(child: &mut Child) {
    // SAFETY: kill(2) on our own child.
    unsafe {
        libc::kill(child.id() as i32, libc::SIGTERM);
    }
    wait_exit(child);
}

pub fn wait_exit(child: &mut Child) {
    wait_exit_within(child, Duration::from_secs(30));
}

/// Wait for `child` to exit; kill it after `timeout`.
pub fn wait_exit_within(child: &mut Child, timeout: Duration) {
    let end = Instant::now() + timeout;
    while Instant::now() < end {
        if let Ok(Some(_)) = child.try_wait() {
            return;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    let _ = child.wait();
}

pub fn read_report(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).expect("report");
    serde_json::from_str(&text).expect("json")
}
