//! What the daemon benches share: unique iceoryx2 prefixes and their clean-up, the daemon run
//! as a real process, its JSON report, and a process's CPU time.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

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
    Command::new(env!("CARGO_BIN_EXE_driftless"))
        .arg("run")
        .arg(pipeline)
        .args(["--prefix", prefix, "--quiet", "--report"])
        .arg(report)
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn driftless")
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
