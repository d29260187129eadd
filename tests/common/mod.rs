//! Helpers of the daemon's integration tests: unique iceoryx2 prefixes, pipeline files in a
//! temporary folder, the real binary, and clean-up of /dev/shm.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use driftless::transport::{StatsSnapshot, Transport};

/// A test's own iceoryx2 prefix; its files are removed on drop.
pub struct Prefix(pub String);

impl Prefix {
    pub fn new(test: &str) -> Self {
        let p = Prefix(format!("dlt{}{}_", std::process::id(), test));
        p.clean();
        p
    }

    /// Files left under this prefix in /dev/shm and /tmp/iceoryx2.
    pub fn leftovers(&self) -> Vec<PathBuf> {
        let mut out = Vec::new();
        collect(Path::new("/dev/shm"), &self.0, &mut out);
        collect(Path::new("/tmp/iceoryx2"), &self.0, &mut out);
        out
    }

    pub fn clean(&self) {
        for p in self.leftovers() {
            if p.is_dir() {
                let _ = std::fs::remove_dir_all(&p);
            } else {
                let _ = std::fs::remove_file(&p);
            }
        }
    }
}

impl Drop for Prefix {
    fn drop(&mut self) {
        self.clean();
    }
}

fn collect(dir: &Path, prefix: &str, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let path = e.path();
        if e.file_name().to_string_lossy().starts_with(prefix) {
            out.push(path);
        } else if path.is_dir() {
            collect(&path, prefix, out);
        }
    }
}

pub fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_driftless")
}

/// A folder holding a pipeline file (and its data).
pub struct Dir {
    pub dir: tempfile::TempDir,
}

impl Dir {
    pub fn new() -> Self {
        Dir {
            dir: tempfile::tempdir().expect("tempdir"),
        }
    }

    pub fn write(&self, name: &str, text: &str) -> PathBuf {
        let p = self.dir.path().join(name);
        std::fs::write(&p, text).expect("write");
        p
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }
}

/// A CSV with columns t,x,y,z of `n` deterministic rows.
pub fn csv(n: usize) -> String {
    let mut s = String::from("t,x,y,z\n");
    for i in 0..n {
        let t = i as f64 * 1e-3;
        s.push_str(&format!(
            "{t:.3},{:.6},{:.6},{:.6}\n",
            (t * 7.0).sin() + ((i * 7919) % 13) as f64 * 0.01,
            (t * 3.0).cos(),
            0.5 + ((i * 104_729) % 17) as f64 * 0.02
        ));
    }
    s
}

/// Start `driftless run FILE --prefix P` with extra args; stderr is captured.
pub fn start(pipeline: &Path, prefix: &Prefix, extra: &[&str]) -> Child {
    Command::new(bin())
        .arg("run")
        .arg(pipeline)
        .args(["--prefix", &prefix.0, "--quiet"])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn driftless")
}

/// Wait until the daemon's stats service exists (its chain is set up by then).
pub fn wait_ready(prefix: &Prefix, stats: &str, child: &mut Child) {
    let t = Transport::new(&prefix.0, "probe", Default::default()).expect("probe node");
    let end = Instant::now() + Duration::from_secs(10);
    while Instant::now() < end {
        if t.service_exists::<StatsSnapshot>(stats).unwrap_or(false) {
            return;
        }
        if let Ok(Some(status)) = child.try_wait() {
            panic!("daemon exited early: {status}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    panic!("daemon not ready after 10 s");
}

pub fn signal(child: &Child, sig: i32) {
    // SAFETY: kill(2) on our own child's pid.
    let rc = unsafe { libc::kill(child.id() as i32, sig) };
    assert_eq!(rc, 0, "kill failed");
}

/// Wait for exit with a timeout; returns (code, stderr).
pub fn finish(mut child: Child, timeout: Duration) -> (Option<i32>, String) {
    let end = Instant::now() + timeout;
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            let mut err = String::new();
            if let Some(mut e) = child.stderr.take() {
                let _ = std::io::Read::read_to_string(&mut e, &mut err);
            }
            return (status.code(), err);
        }
        if Instant::now() > end {
            let _ = child.kill();
            let _ = child.wait();
            panic!("daemon did not exit within {timeout:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}
