//! Helpers of the daemon's integration tests: unique iceoryx2 prefixes, pipeline files in a
//! temporary folder, the real binary, and clean-up of /dev/shm.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use driftless::transport::{Input, Qos, Transport};
use driftless::wire::{GyroSample, RawSample, StatsSnapshot};

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
        collect_files(Path::new("/dev/shm"), &self.0, &mut out);
        collect_files(Path::new("/tmp/iceoryx2"), &self.0, &mut out);
        out
    }

    pub fn clean(&self) {
        for p in self.leftovers() {
            if p.symlink_metadata().is_ok_and(|m| m.is_dir()) {
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

fn collect_files(dir: &Path, prefix: &str, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let path = e.path();
        if e.file_name().to_string_lossy().starts_with(prefix) {
            out.push(path);
        } else if e.file_type().is_ok_and(|t| t.is_dir()) {
            // file_type does not follow a link: a symlink loop in /dev/shm cannot hang a test.
            collect_files(&path, prefix, out);
        }
    }
}

pub fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_driftless")
}

/// The real binary run with `args` to its end.
pub fn driftless(args: &[&str]) -> std::process::Output {
    Command::new(bin())
        .args(args)
        .output()
        .expect("the binary runs")
}

/// A simulated still log of 300 s at 100 Hz (`driftless simulate`: N 1.5 deg/sqrt(h), B 20
/// deg/h, noise seed `seed`, and `extra` arguments) written to `out`; panics if it fails.
#[allow(dead_code)] // Not every test binary simulates.
pub fn simulated_log(out: &Path, seed: &str, extra: &[&str]) -> String {
    let out_s = out.to_str().unwrap().to_string();
    let mut args = vec![
        "simulate",
        "--N",
        "1.5",
        "--B",
        "20",
        "--rate",
        "100",
        "--duration",
        "300s",
        "--seed",
        seed,
        "-o",
        &out_s,
    ];
    args.extend_from_slice(extra);
    let o = driftless(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out_s
}

/// `driftless ARGS` to its end, or a failure after `limit` (a hang).
pub fn run_within(args: &[&str], limit: Duration) -> (Option<i32>, String) {
    let child = Command::new(bin())
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("driftless runs");
    finish(child, limit)
}

/// A run's stdout and stderr as text.
pub fn text(o: &std::process::Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
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

    /// A folder holding `data.csv` with [`csv`]`(rows)`, the log [`csv_pipeline`] replays.
    pub fn with_csv(rows: usize) -> Self {
        let dir = Dir::new();
        dir.write("data.csv", &csv(rows));
        dir
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

/// Pipeline `c`: `data.csv` (see [`csv`]) replayed at `pace` (`realtime` or `asap`), looping
/// or not, through `denoise.none` to `c/corrected`; a report every 60 s.
pub fn csv_pipeline(pace: &str, looped: bool, buffer: usize) -> String {
    format!(
        r#"
name = "c"
rate_hz = 1000.0
input_units = "deg/s"
report_interval_s = 60.0

[iceoryx2]
buffer_size = {buffer}

[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "c/raw"
file = "data.csv"
time_column = "t"
pace = "{pace}"
loop = {looped}

[[stage]]
name = "denoise"
kind = "denoise.none"
input = "c/raw"
output = "c/denoised"

[[stage]]
name = "publish"
kind = "publish"
input = "c/denoised"
output = "c/corrected"
"#
    )
}

/// Start `driftless run FILE --prefix P` with extra args; stderr is captured.
pub fn start(pipeline: &Path, prefix: &Prefix, extra: &[&str]) -> Child {
    run_command(pipeline, prefix)
        .arg("--quiet")
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn driftless")
}

/// `driftless run FILE --prefix P`, as a user types it (not quiet); the caller adds the rest.
/// The daemon gets SIGTERM when the test's thread ends: a test that fails before stopping it
/// must not leave it running beside the tests after it.
pub fn run_command(pipeline: &Path, prefix: &Prefix) -> Command {
    use std::os::unix::process::CommandExt as _;
    let mut c = Command::new(bin());
    c.arg("run").arg(pipeline).args(["--prefix", &prefix.0]);
    // SAFETY: prctl(2) is async-signal-safe; it only sets the child's parent-death signal.
    unsafe {
        c.pre_exec(|| {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
            Ok(())
        });
    }
    c
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
            panic!("process did not exit within {timeout:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// QoS of a test's own ports: `buffer` samples, as the pipeline under test sets.
pub fn qos(buffer: usize) -> Qos {
    Qos {
        buffer_size: buffer,
        max_subscribers: 8,
    }
}

/// A valid raw sample.
pub fn raw(seq: u64, t_ns: u64, rate: [f64; 3]) -> RawSample {
    RawSample {
        t_ns,
        seq,
        rate,
        ..RawSample::default()
    }
}

/// `n` deterministic 3-axis rates with a sine, a cosine and some roughness, for end-to-end tests.
pub fn test_rates(n: usize) -> Vec<[f64; 3]> {
    (0..n)
        .map(|i| {
            let t = i as f64 * 1e-3;
            [
                (t * 9.0).sin() + 0.3 * ((i * 7919 % 23) as f64 / 23.0 - 0.5),
                (t * 2.0).cos(),
                ((i * 104_729 % 31) as f64 / 31.0) - 0.5,
            ]
        })
        .collect()
}

/// Receive until `n` samples came or `timeout` passed.
pub fn collect(input: &Input<GyroSample>, n: usize, timeout: Duration) -> Vec<GyroSample> {
    let mut got = Vec::with_capacity(n);
    let end = Instant::now() + timeout;
    while got.len() < n && Instant::now() < end {
        match input.receive().expect("receive") {
            Some(s) => got.push(s),
            None => std::thread::sleep(Duration::from_micros(200)),
        }
    }
    got
}

/// The JSON report a run wrote to `report.json` in `dir`.
pub fn report(dir: &Dir) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.path("report.json")).expect("report written");
    serde_json::from_str(&text).expect("report is JSON")
}

/// The subcommands, from `driftless --help` (so a new command is checked without editing this).
pub fn subcommands() -> Vec<String> {
    let help = String::from_utf8(driftless(&["--help"]).stdout).unwrap();
    help.lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next().map(String::from))
        .filter(|c| c != "help")
        .collect()
}

/// Pipeline `name` reading raw samples from `{name}/sensor` (published by the test, as a
/// sensor driver would) through `denoise` and `predict.none` to `{name}/corrected`.
pub fn external_pipeline(name: &str, denoise: &str, buffer: usize) -> String {
    format!(
        r#"
name = "{name}"
rate_hz = 1000.0
axes = 3
input_units = "rad/s"
report_interval_s = 60.0

[iceoryx2]
buffer_size = {buffer}

[[stage]]
name = "sensor"
kind = "ingest.iceoryx2"
input = "{name}/sensor"
output = "{name}/raw"

[[stage]]
name = "denoise"
{denoise}
input = "{name}/raw"
output = "{name}/denoised"

[[stage]]
name = "predict"
kind = "predict.none"
input = "{name}/denoised"
output = "{name}/predicted"

[[stage]]
name = "publish"
kind = "publish"
input = "{name}/predicted"
output = "{name}/corrected"
"#
    )
}

/// What the one-stream denoiser (soft threshold, MAD noise estimate: `threshold = "soft"` in
/// a pipeline) makes of `input`, each axis alone, flushed at the end.
pub fn offline_denoised(
    input: &[[f64; 3]],
    wavelet: &str,
    level: usize,
    window: usize,
    lag: usize,
) -> Vec<[f64; 3]> {
    use driftless::wavelet::stream::{Sigma, StreamConfig, StreamingDenoiser};
    let cfg = StreamConfig {
        wavelet: wavelet.into(),
        level,
        threshold: driftless::wavelet::threshold::ThresholdFn::Soft,
        window,
        lag,
        sigma: Sigma::Mad,
    };
    let mut expected = vec![[0.0; 3]; input.len()];
    for axis in 0..3 {
        let mut d = StreamingDenoiser::new(&cfg).expect("denoiser");
        let mut out = Vec::new();
        for r in input {
            out.extend(d.push(r[axis]));
        }
        while let Some(v) = d.flush() {
            out.push(v);
        }
        assert_eq!(out.len(), input.len());
        for (e, v) in expected.iter_mut().zip(out) {
            e[axis] = v;
        }
    }
    expected
}

/// Set in the child that runs inside a private namespace ([`in_private_shm`]).
const IN_NAMESPACE: &str = "DRIFTLESS_TEST_IN_NAMESPACE";

/// iceoryx2's root directory (in a private namespace, its own tmpfs).
pub const ICEORYX2_ROOT: &str = "/tmp/iceoryx2";

/// Run `test` in a private mount namespace with a tmpfs of `shm_size` on /dev/shm and one on
/// iceoryx2's root: nothing of another test or program is there. Returns true in the child
/// (the caller then runs the scenario); in the parent, waits for the child, fails if it
/// failed, and returns false. Making the namespace needs root (CI runs as root); without it,
/// says so in one line and returns false.
pub fn in_private_shm(test: &str, shm_size: &str) -> bool {
    in_private_mounts(
        test,
        &format!(
            "mount -t tmpfs -o size={shm_size},mode=1777 tmpfs /dev/shm && mkdir -p {ICEORYX2_ROOT} \
             && mount -t tmpfs tmpfs {ICEORYX2_ROOT}"
        ),
    )
}

/// [`in_private_shm`] with a private `/tmp` instead of a private iceoryx2 root: a tmpfs of mode
/// 1777 on each of `/dev/shm` and `/tmp`, where `/tmp/iceoryx2` is not there yet and the test
/// may make it anything (another user's, a link).
pub fn in_private_tmp(test: &str) -> bool {
    // A checkout or test binary under /tmp (a CI clone in a mktemp directory) is bound back
    // into the private /tmp, reached through the shell's cwd in the old one.
    let exe = std::env::current_exe().expect("this test binary");
    let mut keep: Vec<String> = [Path::new(env!("CARGO_MANIFEST_DIR")), exe.as_path()]
        .iter()
        .filter_map(|p| p.strip_prefix("/tmp").ok()?.components().next())
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    keep.dedup();
    let binds: String = keep
        .iter()
        .map(|d| {
            format!(" && mkdir -p '/tmp/{d}' && mount --no-canonicalize --bind './{d}' '/tmp/{d}'")
        })
        .collect();
    in_private_mounts(
        test,
        &format!(
            "cd /tmp && mount -t tmpfs -o size=64m,mode=1777 tmpfs /dev/shm && \
             mount -t tmpfs -o size=64m,mode=1777 tmpfs /tmp{binds}"
        ),
    )
}

/// Run `test` again in a private mount namespace after the shell commands `mounts`.
fn in_private_mounts(test: &str, mounts: &str) -> bool {
    if std::env::var_os(IN_NAMESPACE).is_some() {
        return true;
    }
    // SAFETY: geteuid cannot fail.
    if unsafe { libc::geteuid() } != 0 {
        eprintln!("{test}: skipped: a private mount namespace needs root");
        return false;
    }
    let script = format!("{mounts} && exec \"$0\" \"$@\"");
    let exe = std::env::current_exe().expect("this test binary");
    let out = Command::new("unshare")
        .args(["-m", "--propagation", "private", "sh", "-c", &script])
        .arg(exe)
        .args(["--exact", test, "--nocapture", "--test-threads=1"])
        .env(IN_NAMESPACE, "1")
        .env("RUST_BACKTRACE", "1")
        .output()
        .expect("unshare runs");
    let (stdout, stderr) = text(&out);
    assert!(
        out.status.success() && stdout.contains("1 passed"),
        "{test} in its namespace failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
    false
}

/// 5,000 bytes of a fixed xorshift stream: garbage, the same on every run (a damaged file).
pub fn garbage() -> Vec<u8> {
    let mut s = 0x9e37_79b9_7f4a_7c15u64;
    (0..5000)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 32) as u8
        })
        .collect()
}
