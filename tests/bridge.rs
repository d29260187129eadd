//! `driftless bridge` (feature `zenoh`): a real daemon, a real bridge process and a Zenoh
//! session in this test process, on loopback only (127.0.0.1, a free port, multicast scouting
//! off). Each test has its own iceoryx2 prefix and its own port.
#![cfg(feature = "zenoh")]

mod common;

use std::fmt::Debug;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU16, Ordering};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

use common::{finish, qos, raw, report, signal, start, test_rates, wait_ready, Dir, Prefix};
use driftless::transport::Transport;
use driftless::wire::{GyroSample, RawSample, StatsSnapshot};
use iceoryx2::prelude::ZeroCopySend;
use zenoh::Wait;

const SIGTERM: i32 = 15;
const SIGKILL: i32 = 9;
const SIGSTOP: i32 = 19;
const SIGCONT: i32 = 18;

/// A TCP port nobody listens on now, below the ephemeral range (32768-60999 here): a port the
/// kernel hands out for `bind(0)` can also become the source port of another test's outgoing
/// connection before our listener takes it (a flake seen once); these never do.
fn free_port() -> u16 {
    static NEXT: AtomicU16 = AtomicU16::new(0);
    let base = 20_000 + (std::process::id() % 1000) as u16 * 10;
    loop {
        let port = base + NEXT.fetch_add(1, Ordering::Relaxed) % 2_000;
        if std::net::TcpListener::bind(("127.0.0.1", port)).is_ok() {
            return port;
        }
    }
}

/// This test's Zenoh peer, listening on 127.0.0.1:`port`, no multicast scouting.
fn session(port: u16) -> zenoh::Session {
    let mut cfg = zenoh::Config::default();
    cfg.insert_json5("mode", "\"peer\"").unwrap();
    cfg.insert_json5("listen/endpoints", &format!("[\"tcp/127.0.0.1:{port}\"]"))
        .unwrap();
    cfg.insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    zenoh::open(cfg).wait().expect("zenoh session")
}

/// What arrived on a key: payload bytes, encoding as text.
type Got = (Vec<u8>, String, String);

fn subscribe(
    s: &zenoh::Session,
    key: &str,
) -> (zenoh::pubsub::Subscriber<()>, mpsc::Receiver<Got>) {
    let (tx, rx) = mpsc::channel();
    let sub = s
        .declare_subscriber(key.to_string())
        .callback(move |sample| {
            let _ = tx.send((
                sample.payload().to_bytes().into_owned(),
                sample.encoding().to_string(),
                sample.key_expr().to_string(),
            ));
        })
        .wait()
        .expect("subscriber");
    (sub, rx)
}

/// A bridge process; its stderr lines arrive on a channel (the periodic line keeps coming).
struct Bridge {
    child: Child,
    lines: mpsc::Receiver<String>,
    seen: Vec<String>,
}

impl Bridge {
    fn start(prefix: &Prefix, args: &[&str]) -> Bridge {
        let mut child = Command::new(common::bin())
            .arg("bridge")
            .args(args)
            .args(["--prefix", &prefix.0])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawn bridge");
        let err = child.stderr.take().unwrap();
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(err).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Bridge {
            child,
            lines,
            seen: Vec::new(),
        }
    }

    /// Wait until a line containing `text` came (the lines so far are kept in `seen`).
    fn wait_for(&mut self, text: &str, timeout: Duration) {
        self.wait_for_after(0, text, timeout)
    }

    /// Wait until a line containing `text` came after the first `mark` lines of `seen`.
    fn wait_for_after(&mut self, mark: usize, text: &str, timeout: Duration) {
        let end = Instant::now() + timeout;
        if self.seen.iter().skip(mark).any(|l| l.contains(text)) {
            return;
        }
        while Instant::now() < end {
            if let Ok(line) = self.lines.recv_timeout(Duration::from_millis(50)) {
                let hit = line.contains(text);
                self.seen.push(line);
                if hit {
                    return;
                }
            }
            if let Ok(Some(st)) = self.child.try_wait() {
                while let Ok(l) = self.lines.recv_timeout(Duration::from_millis(100)) {
                    self.seen.push(l);
                }
                panic!("bridge exited ({st}) before {text:?}: {:?}", self.seen);
            }
        }
        panic!(
            "no {text:?} from the bridge within {timeout:?}: {:?}",
            self.seen
        );
    }

    /// Send `sig` to `other` and wait (up to 20 s) for a line of this bridge containing `text`
    /// after it; returns how long that took.
    fn after(&mut self, other: &Child, sig: i32, text: &str) -> Duration {
        let mark = self.seen.len();
        let sent = Instant::now();
        signal(other, sig);
        self.wait_for_after(mark, text, Duration::from_secs(20));
        sent.elapsed()
    }

    /// Wait for its exit; returns the exit code and every stderr line.
    fn finish(mut self, timeout: Duration) -> (Option<i32>, Vec<String>) {
        let end = Instant::now() + timeout;
        let code = loop {
            if let Some(st) = self.child.try_wait().unwrap() {
                break st.code();
            }
            if Instant::now() > end {
                let _ = self.child.kill();
                let _ = self.child.wait();
                panic!("bridge did not exit within {timeout:?}");
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        while let Ok(l) = self.lines.recv_timeout(Duration::from_millis(500)) {
            self.seen.push(l);
        }
        (code, self.seen)
    }

    /// SIGTERM; it exits 0 with `summary` as its `bridge: done:` line. Returns every line.
    fn stop(self, summary: &str) -> Vec<String> {
        signal(&self.child, SIGTERM);
        let (code, lines) = self.finish(Duration::from_secs(10));
        assert_eq!(code, Some(0), "{lines:?}");
        assert!(
            lines.iter().any(|l| l == summary),
            "{summary:?} in {lines:?}"
        );
        lines
    }
}

/// Decoded at the offsets docs/wire-types.md documents (not with the crate's own decoder).
fn decode_gyro(b: &[u8]) -> GyroSample {
    assert_eq!(b.len(), 264, "a GyroSample (layout v4) is 264 bytes");
    let u64_at = |o: usize| u64::from_le_bytes(b[o..o + 8].try_into().unwrap());
    let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let f3 = |o: usize| [0, 1, 2].map(|i| f64::from_bits(u64_at(o + 8 * i)));
    GyroSample {
        t_ns: u64_at(0),
        seq: u64_at(8),
        ingest_ns: u64_at(16),
        rate: f3(24),
        drift: f3(48),
        denoised: f3(72),
        flags: u32_at(96),
        epoch: u32_at(100),
        drift_std: f3(104),
        accel: f3(128),
        accel_std: f3(152),
        mag: f3(176),
        sensors: u32_at(200),
        reserved: u32_at(204),
        orientation: [0, 1, 2, 3].map(|i| f64::from_bits(u64_at(208 + 8 * i))),
        orientation_std: f3(240),
    }
}

fn bits(s: &GyroSample) -> Vec<u64> {
    let mut v = vec![s.t_ns, s.seq, s.ingest_ns, s.flags as u64, s.epoch as u64];
    for a in [s.rate, s.drift, s.denoised, s.drift_std] {
        v.extend(a.map(f64::to_bits));
    }
    v
}

/// sensor (this test, or the simulator) -> denoise -> predict.bias -> publish.
fn pipeline(head: &str, units: &str, buffer: usize) -> String {
    format!(
        r#"
name = "t"
rate_hz = 1000.0
axes = 3
input_units = "{units}"
report_interval_s = 0.5

[iceoryx2]
buffer_size = {buffer}

[[stage]]
name = "sensor"
{head}
output = "t/raw"

[[stage]]
name = "denoise"
kind = "denoise.wavelet"
wavelet = "db4"
level = 4
window = 256
lag = 32
input = "t/raw"
output = "t/denoised"

[[stage]]
name = "predict"
kind = "predict.bias"
profile = "adis16405"
input = "t/denoised"
output = "t/predicted"

[[stage]]
name = "publish"
kind = "publish"
input = "t/predicted"
output = "t/corrected"
"#
    )
}

/// Sample `i` of a 1 kHz stream started at `t0` is due at `t0 + i + 1` ms.
fn pace(t0: Instant, i: usize) {
    let due = t0 + Duration::from_millis(i as u64 + 1);
    if let Some(wait) = due.checked_duration_since(Instant::now()) {
        std::thread::sleep(wait);
    }
}

/// All `n` outputs of the daemon: `n - lag` while it runs, then the `lag` held by the denoiser,
/// flushed at SIGTERM; the daemon exits 0.
fn through_shutdown(
    corrected: &driftless::transport::Input<GyroSample>,
    daemon: Child,
    n: usize,
    lag: usize,
) -> Vec<GyroSample> {
    let mut got = common::collect(corrected, n - lag, Duration::from_secs(20));
    assert_eq!(got.len(), n - lag);
    signal(&daemon, SIGTERM);
    got.extend(common::collect(corrected, lag, Duration::from_secs(10)));
    let (code, err) = finish(daemon, Duration::from_secs(10));
    assert_eq!(code, Some(0), "{err}");
    got
}

const FROM_TEST: &str = "kind = \"ingest.iceoryx2\"\ninput = \"t/sensor\"";
const FROM_SIM: &str = "kind = \"ingest.sim\"\nprofile = \"adis16405\"\nmotion = \"stop-and-go\"";

#[test]
fn every_sample_crosses_once_in_order_with_the_bits_an_iceoryx2_subscriber_sees() {
    const N: usize = 3000;
    const LAG: usize = 32;
    let prefix = Prefix::new("brorder");
    let dir = Dir::new();
    let file = dir.write("p.toml", &pipeline(FROM_TEST, "rad/s", 4096));
    let port = free_port();
    let zs = session(port);
    let (sub, far) = subscribe(&zs, "driftless/t/corrected");

    let me = Transport::new(&prefix.0, "test", qos(4096)).expect("node");
    let sensor = me.output::<RawSample>("t/sensor", true).expect("sensor");
    let corrected = me.input::<GyroSample>("t/corrected").expect("subscriber");
    let report_path = dir.path("report.json");
    let mut daemon = start(&file, &prefix, &["--report", report_path.to_str().unwrap()]);
    wait_ready(&prefix, "t/stats", &mut daemon);
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let mut bridge = Bridge::start(
        &prefix,
        &[
            "t/corrected",
            "--connect",
            &endpoint,
            "--no-multicast-scouting",
        ],
    );
    bridge.wait_for(
        "bridge: ready: t/corrected (driftless::GyroSample.v4) -> driftless/t/corrected",
        Duration::from_secs(20),
    );
    bridge.wait_for("a Zenoh subscriber matches", Duration::from_secs(20));

    // 1 kHz, paced by this process.
    let input = test_rates(N);
    let t0 = Instant::now();
    for (i, r) in input.iter().enumerate() {
        assert_eq!(
            sensor
                .send(&raw(i as u64, i as u64 * 1_000_000, *r))
                .unwrap(),
            1
        );
        sensor.notify();
        pace(t0, i);
    }
    let near = through_shutdown(&corrected, daemon, N, LAG);
    assert_eq!(near.len(), N, "the iceoryx2 subscriber got everything");

    let mut got = Vec::new();
    let end = Instant::now() + Duration::from_secs(20);
    while got.len() < N && Instant::now() < end {
        if let Ok(g) = far.recv_timeout(Duration::from_millis(50)) {
            got.push(g);
        }
    }
    // Nothing beyond N (no sample twice).
    while let Ok(g) = far.recv_timeout(Duration::from_millis(300)) {
        got.push(g);
    }
    let lines = bridge.stop(&format!(
        "bridge: done: t/corrected -> driftless/t/corrected: {N} forwarded, 0 missing (sequence gaps), 0 put errors"
    ));
    assert!(
        lines
            .iter()
            .any(|l| l.contains(" Hz, ") && l.contains("forwarded")),
        "a rate line each second: {lines:?}"
    );

    assert_eq!(got.len(), N, "every sample across the bridge, none twice");
    let epoch = near[0].epoch;
    for (i, ((payload, encoding, key), mine)) in got.iter().zip(&near).enumerate() {
        assert_eq!(key, "driftless/t/corrected");
        assert_eq!(
            encoding,
            "application/octet-stream;driftless::GyroSample.v4"
        );
        let s = decode_gyro(payload);
        assert_eq!(
            (s.epoch, s.seq),
            (epoch, i as u64),
            "in order, exactly once"
        );
        assert_eq!(s.t_ns, i as u64 * 1_000_000);
        assert_eq!(
            bits(&s),
            bits(mine),
            "sample {i}: the same bits as over iceoryx2"
        );
        // predict.bias's own uncertainty crosses the bridge (none is -1 or NaN).
        assert!(
            s.drift_std.iter().all(|v| v.is_finite() && *v > 0.0),
            "sample {i}: drift_std {:?}",
            s.drift_std
        );
    }
    assert!(
        near.windows(2).all(|w| w[0].rate != w[1].rate),
        "the values change from sample to sample (the comparison means something)"
    );
    let r = report(&dir);
    assert_eq!(r["samples_out"], N as u64);
    assert_eq!(r["lost"], 0, "the bridge kept up: {r}");
    drop(sub);
    zs.close().wait().unwrap();
    drop((sensor, corrected, me));
    driftless::transport::remove_prefix_leftovers(&prefix.0);
    assert!(prefix.leftovers().is_empty(), "{:?}", prefix.leftovers());
}

/// This test's own subscriber of `service`, in its own thread (ports are not Send): every
/// (epoch, seq) it received until `stop`.
fn drain<T: Debug + ZeroCopySend + Copy + 'static>(
    prefix: &str,
    service: &str,
    buffer: usize,
    stop: Arc<AtomicBool>,
    stamp: fn(&T) -> (u32, u64),
) -> std::thread::JoinHandle<Vec<(u32, u64)>> {
    let (prefix, service) = (prefix.to_string(), service.to_string());
    let (tx, rx) = mpsc::channel();
    let h = std::thread::spawn(move || {
        let me = Transport::new(&prefix, "drain", qos(buffer)).expect("node");
        let input = me.open_input::<T>(&service).expect("subscriber");
        tx.send(()).unwrap();
        let mut seen = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            match input.receive().expect("receive") {
                Some(s) => seen.push(stamp(&s)),
                None => std::thread::sleep(Duration::from_micros(200)),
            }
        }
        while let Some(s) = input.receive().expect("receive") {
            seen.push(stamp(&s));
        }
        seen
    });
    rx.recv_timeout(Duration::from_secs(10))
        .expect("drain subscribed");
    h
}

fn gyro_stamp(s: &GyroSample) -> (u32, u64) {
    (s.epoch, s.seq)
}

fn raw_stamp(s: &RawSample) -> (u32, u64) {
    (s.epoch, s.seq)
}

fn contiguous(seen: &[(u32, u64)]) -> bool {
    seen.windows(2)
        .all(|w| w[1].0 == w[0].0 && w[1].1 == w[0].1 + 1)
}

#[test]
fn a_bridge_killed_mid_run_costs_the_other_subscribers_nothing() {
    let prefix = Prefix::new("brkill");
    let dir = Dir::new();
    let file = dir.write("p.toml", &pipeline(FROM_SIM, "deg/s", 256));
    let port = free_port();
    let zs = session(port);
    let (sub, far) = subscribe(&zs, "driftless/t/corrected");
    let report_path = dir.path("report.json");
    let mut daemon = start(&file, &prefix, &["--report", report_path.to_str().unwrap()]);
    wait_ready(&prefix, "t/stats", &mut daemon);
    let probe = Transport::new(&prefix.0, "stats-probe", qos(16)).expect("probe node");
    let stats = probe
        .open_input::<StatsSnapshot>("t/stats")
        .expect("the daemon's stats");
    let stop = Arc::new(AtomicBool::new(false));
    let other = drain(&prefix.0, "t/corrected", 256, Arc::clone(&stop), gyro_stamp);
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let mut bridge = Bridge::start(
        &prefix,
        &[
            "t/corrected",
            "--connect",
            &endpoint,
            "--no-multicast-scouting",
        ],
    );
    bridge.wait_for("a Zenoh subscriber matches", Duration::from_secs(20));
    std::thread::sleep(Duration::from_millis(700));
    signal(&bridge.child, SIGKILL);
    let (code, _) = bridge.finish(Duration::from_secs(5));
    assert_eq!(code, None, "killed by a signal");
    // The dead bridge's buffer fills until the daemon's next clean-up (every report interval,
    // 0.5 s here); then it costs nothing more: the loss count stands still while the daemon
    // serves on. Judged on the daemon's own snapshots, however slow a loaded machine is.
    while stats.receive().expect("stats").is_some() {} // snapshots from before the kill
    let (mut last, end) = (
        None::<StatsSnapshot>,
        Instant::now() + Duration::from_secs(60),
    );
    let settled = loop {
        assert!(Instant::now() < end, "losses never settled: {last:?}");
        match stats.receive().expect("stats") {
            Some(s) => match last {
                Some(l) if s.lost == l.lost && s.samples_out >= l.samples_out + 400 => break s,
                _ => last = Some(s),
            },
            None => std::thread::sleep(Duration::from_millis(50)),
        }
    };
    signal(&daemon, SIGTERM);
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "the daemon ran on to its end: {err}");
    stop.store(true, Ordering::Relaxed);
    let seen = other.join().unwrap();

    let r = report(&dir);
    let n = r["samples_out"].as_u64().unwrap();
    assert_eq!(r["samples_in"], n);
    assert!(seen.len() > 1000, "{}", seen.len());
    assert!(contiguous(&seen), "the other subscriber lost nothing");
    assert_eq!(seen.last().unwrap().1 + 1, n, "to the last sample");
    let lost = r["lost"].as_u64().unwrap();
    assert_eq!(
        lost, settled.lost,
        "a dead subscriber is cleaned up, not charged forever"
    );

    eprintln!(
        "daemon with a bridge killed mid-run: {} deadline misses, {lost} lost by the dead bridge",
        r["deadline_misses"]
    );

    let mut far_seqs = Vec::new();
    while let Ok((payload, _, _)) = far.try_recv() {
        let s = decode_gyro(&payload);
        far_seqs.push((s.epoch, s.seq));
    }
    assert!(
        far_seqs.len() > 100,
        "the bridge forwarded before it died: {}",
        far_seqs.len()
    );
    let breaks: Vec<_> = far_seqs
        .windows(2)
        .filter(|w| !(w[1].0 == w[0].0 && w[1].1 == w[0].1 + 1))
        .collect();
    assert!(
        breaks.is_empty(),
        "in order and whole until the kill: {breaks:?} of {}",
        far_seqs.len()
    );
    drop(sub);
    zs.close().wait().unwrap();
}

/// A Zenoh lease of 1 s (zenoh's default is 10 s): how long a peer that stopped answering
/// counts as there. Both ends announce it.
const SHORT_LEASE: &str = "{ transport: { link: { tx: { lease: 1000, keep_alive: 4 } } } }\n";

/// Whether `seen` only moves forward within one epoch (gaps allowed, nothing twice or back).
fn increasing(seen: &[(u32, u64)]) -> bool {
    seen.windows(2).all(|w| w[1].0 == w[0].0 && w[1].1 > w[0].1)
}

#[test]
fn a_remote_subscriber_that_stalls_or_dies_costs_the_daemon_nothing_and_is_reported() {
    let prefix = Prefix::new("brstall");
    let dir = Dir::new();
    let file = dir.write("p.toml", &pipeline(FROM_SIM, "deg/s", 256));
    let lease = dir.write("lease.json5", SHORT_LEASE);
    let lease = lease.to_str().unwrap();
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let report_path = dir.path("report.json");
    let mut daemon = start(&file, &prefix, &["--report", report_path.to_str().unwrap()]);
    wait_ready(&prefix, "t/stats", &mut daemon);
    let stop = Arc::new(AtomicBool::new(false));
    let other = drain(&prefix.0, "t/corrected", 256, Arc::clone(&stop), gyro_stamp);

    // The far end is another process, so that it can be stopped as a dead network would stop
    // it: a reverse bridge from the key into `far/raw`, which this test reads.
    let mut far = Bridge::start(
        &prefix,
        &[
            "--from-zenoh",
            "driftless/t/raw",
            "--to",
            "far/raw",
            "--buffer-size",
            "4096",
            "--listen",
            &endpoint,
            "--no-multicast-scouting",
            "--zenoh-config",
            lease,
        ],
    );
    far.wait_for("bridge: ready: driftless/t/raw", Duration::from_secs(20));
    let far_seen = drain(&prefix.0, "far/raw", 4096, Arc::clone(&stop), raw_stamp);
    let mut bridge = Bridge::start(
        &prefix,
        &[
            "t/raw",
            "--connect",
            &endpoint,
            "--no-multicast-scouting",
            "--zenoh-config",
            lease,
        ],
    );
    bridge.wait_for("a Zenoh subscriber matches", Duration::from_secs(20));
    std::thread::sleep(Duration::from_secs(1));

    // The network stops: nothing comes back from the far end (its TCP window fills, its
    // keep-alives stop).
    let noticed = bridge.after(&far.child, SIGSTOP, "no Zenoh subscriber any more");
    std::thread::sleep(Duration::from_secs(2));
    // It comes back: zenoh reconnects to the --connect endpoint and the stream resumes.
    bridge.after(&far.child, SIGCONT, "a Zenoh subscriber matches");
    std::thread::sleep(Duration::from_secs(1));
    // The far end dies.
    let noticed_death = bridge.after(&far.child, SIGKILL, "no Zenoh subscriber any more");
    let _ = far.finish(Duration::from_secs(5));
    std::thread::sleep(Duration::from_millis(500));

    signal(&daemon, SIGTERM);
    let (code, err) = finish(daemon, Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    stop.store(true, Ordering::Relaxed);
    let seen = other.join().unwrap();
    let far_seen = far_seen.join().unwrap();
    signal(&bridge.child, SIGTERM);
    let (code, lines) = bridge.finish(Duration::from_secs(10));
    assert_eq!(code, Some(0), "{lines:?}");
    let done = lines
        .iter()
        .find(|l| l.starts_with("bridge: done: t/raw -> driftless/t/raw: "))
        .unwrap_or_else(|| panic!("a summary: {lines:?}"));
    assert!(
        done.ends_with(" forwarded, 0 missing (sequence gaps), 0 put errors"),
        "the bridge never fell behind the daemon, the network drops were zenoh's: {done}"
    );

    let r = report(&dir);
    let n = r["samples_out"].as_u64().unwrap();
    assert_eq!(
        r["lost"], 0,
        "the stalled and the dead far end cost the daemon nothing: {r}"
    );
    assert!(
        contiguous(&seen),
        "the daemon's other subscriber lost nothing"
    );
    assert_eq!(seen.last().unwrap().1 + 1, n, "to the last sample");
    assert!(
        increasing(&far_seen),
        "the far end got samples in order, none twice"
    );
    let resumed = far_seen.windows(2).filter(|w| w[1].1 > w[0].1 + 1).count();
    assert!(
        resumed >= 1,
        "what zenoh dropped while the far end was stopped shows as a gap in seq"
    );
    eprintln!(
        "stalled far end reported after {noticed:?}, dead one after {noticed_death:?}; \
         far end got {} samples in {} runs; daemon: {} deadline misses",
        far_seen.len(),
        resumed + 1,
        r["deadline_misses"]
    );
}

#[test]
fn raw_samples_from_zenoh_feed_the_daemons_iceoryx2_ingest() {
    const N: usize = 1500;
    const LAG: usize = 32;
    let prefix = Prefix::new("brrev");
    let dir = Dir::new();
    let file = dir.write("p.toml", &pipeline(FROM_TEST, "rad/s", 512));
    let port = free_port();
    let zs = session(port);
    let endpoint = format!("tcp/127.0.0.1:{port}");
    // The bridge starts first: it creates t/sensor, with the pipeline's buffer, and the daemon
    // accepts it (it refuses services that would lose samples silently).
    let mut bridge = Bridge::start(
        &prefix,
        &[
            "--from-zenoh",
            "remote/raw",
            "--to",
            "t/sensor",
            "--buffer-size",
            "512",
            "--connect",
            &endpoint,
            "--no-multicast-scouting",
        ],
    );
    bridge.wait_for(
        "bridge: ready: remote/raw (driftless::RawSample.v2) -> t/sensor",
        Duration::from_secs(20),
    );
    let me = Transport::new(&prefix.0, "test", qos(4096)).expect("node");
    let corrected = me.input::<GyroSample>("t/corrected").expect("subscriber");
    let report_path = dir.path("report.json");
    let mut daemon = start(&file, &prefix, &["--report", report_path.to_str().unwrap()]);
    wait_ready(&prefix, "t/stats", &mut daemon);

    let publisher = zs
        .declare_publisher("remote/raw")
        .encoding(
            zenoh::bytes::Encoding::APPLICATION_OCTET_STREAM.with_schema("driftless::RawSample.v2"),
        )
        .wait()
        .unwrap();
    let end = Instant::now() + Duration::from_secs(20);
    while !publisher
        .matching_status()
        .wait()
        .map(|m| m.matching())
        .unwrap_or(false)
    {
        assert!(
            Instant::now() < end,
            "the bridge's subscriber never matched"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // Something that is not a RawSample is refused, not published.
    publisher.put(vec![0u8; 12]).wait().unwrap();
    let input = test_rates(N);
    let t0 = Instant::now();
    for (i, r) in input.iter().enumerate() {
        // docs/wire-types.md's layout, written by hand as another language would.
        let mut b = Vec::with_capacity(96);
        b.extend_from_slice(&(i as u64 * 1_000_000).to_le_bytes());
        b.extend_from_slice(&(i as u64).to_le_bytes());
        for v in r {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&0u32.to_le_bytes());
        b.extend_from_slice(&7u32.to_le_bytes());
        // No accelerometer, no magnetometer (flags 0x10, 0x20 clear): 48 bytes of zeros.
        b.extend_from_slice(&[0u8; 48]);
        publisher.put(b).wait().unwrap();
        pace(t0, i);
    }
    let got = through_shutdown(&corrected, daemon, N, LAG);
    let lines = bridge.stop(&format!(
        "bridge: done: remote/raw -> t/sensor: {N} forwarded, 0 missing (sequence gaps), 1 rejected, 0 lost by full iceoryx2 buffers"
    ));
    assert!(
        lines.iter().any(|l| l.contains("payload of 12 bytes")),
        "the refused sample is reported: {lines:?}"
    );
    assert_eq!(got.len(), N);
    for (i, s) in got.iter().enumerate() {
        assert_eq!(s.seq, i as u64, "in order, exactly once");
        assert_eq!(s.t_ns, i as u64 * 1_000_000);
    }
    let r = report(&dir);
    assert_eq!(r["samples_in"], N as u64);
    assert_eq!(r["lost"], 0);
    assert_eq!(r["flagged"]["missing"], 0, "{r}");
    drop(publisher);
    zs.close().wait().unwrap();
}

#[test]
fn bad_endpoints_and_config_files_are_one_line_and_exit_2() {
    let prefix = Prefix::new("brbad");
    let dir = Dir::new();
    let bad_syntax = dir.write(
        "bad.json5",
        "{\n  mode: \"peer\",\n  listen: { endpoints: [ \n}\n",
    );
    let unknown = dir.write("unknown.json5", "{ moode: \"peer\" }\n");
    let missing = dir.path("missing.json5");
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec!["--connect".into(), "127.0.0.1:7447".into()],
            "--connect \"127.0.0.1:7447\": not a Zenoh endpoint",
        ),
        (
            vec!["--listen".into(), "tcp".into()],
            "--listen \"tcp\": not a Zenoh endpoint",
        ),
        (
            vec!["--zenoh-config".into(), bad_syntax.display().to_string()],
            "bad.json5:4:1: not a valid Zenoh configuration: expected array",
        ),
        (
            vec!["--zenoh-config".into(), unknown.display().to_string()],
            "unknown.json5:1:3: not a valid Zenoh configuration: JSON error",
        ),
        (
            vec!["--zenoh-config".into(), missing.display().to_string()],
            "missing.json5: not a valid Zenoh configuration",
        ),
        (
            vec!["--key-prefix".into(), "a//b".into()],
            "\"a//b/t/corrected\" is not a Zenoh key expression",
        ),
        (
            vec!["--mode".into(), "router".into()],
            "invalid value 'router' for '--mode",
        ),
    ];
    for (args, message) in cases {
        let out = Command::new(common::bin())
            .args([
                "bridge",
                "t/corrected",
                "--prefix",
                &prefix.0,
                "--no-multicast-scouting",
            ])
            .args(&args)
            .output()
            .expect("run");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: one line: {err}");
        assert!(err.starts_with("driftless: error: "), "{args:?}: {err}");
        assert!(err.contains(message), "{args:?}: {message:?} in {err}");
    }
    // Valid settings but nothing to read: a run-time failure (exit 1), as for `tap`.
    let port = free_port();
    let out = Command::new(common::bin())
        .args([
            "bridge",
            "t/corrected",
            "--prefix",
            &prefix.0,
            "--no-multicast-scouting",
        ])
        .args(["--listen", &format!("tcp/127.0.0.1:{port}")])
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("no service \"t/corrected\""), "{err}");
    assert!(prefix.leftovers().is_empty(), "{:?}", prefix.leftovers());
}
