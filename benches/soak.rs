//! Soak: `pipelines/demo.toml` at 1 kHz while subscribers in other processes join, stall
//! (SIGSTOP / SIGCONT), die (SIGKILL) and rejoin every few seconds.
//!
//! ```text
//! cargo bench --bench soak                               # 60 s
//! DRIFTLESS_SOAK_SECONDS=3600 cargo bench --bench soak   # the hour of issue 13
//! DRIFTLESS_SOAK_SEED=7 ...                              # another schedule of abuse
//! ```
//!
//! Two phases of equal length. In the first, subscribers only join, stall and leave cleanly:
//! each reports what it saw (received, lost, duplicated, reordered, from `seq` within one
//! epoch), and the daemon's count of the corrected service's losses (its stats snapshot) must
//! equal the sum of theirs exactly. In the second, subscribers are also killed: their losses
//! are known only to the daemon (a dead subscriber's buffer fills until the daemon's periodic
//! clean-up removes it), so the check is that the daemon keeps its deadline and its memory.
//! Throughout: the daemon's resident memory is sampled every second (flat after the first
//! tenth of the run), and its final report must show no deadline miss; each miss it does show
//! is printed beside what the bench did in the 3 s before it and the second after, and beside
//! where the hot thread's time went around it: its scheduler statistics (time run, time waiting
//! for a CPU while runnable, `/proc/PID/task/TID/schedstat`) and its CPU's steal, irq and
//! softirq time (`/proc/stat`), sampled every 20 ms. A miss with no wait for a CPU was not
//! caused by another process of this machine (a subscriber included): the guest kernel did not
//! run anything else in the thread's place.
//!
//! `DRIFTLESS_SOAK_CONTROL=1` runs the same daemon for the same time with no subscriber at all:
//! the misses this machine causes by itself, to compare with.
//!
//! The subscribers are this same executable, started again with `--subscriber`.

use std::io::Read as _;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use driftless::transport::{Qos, Transport};
use driftless::wire::{GyroSample, StatsSnapshot};
use rand::{Rng, SeedableRng};
use serde_json::Value;

const PIPELINE: &str = "pipelines/demo.toml";
const SERVICE: &str = "demo/corrected";
const STATS: &str = "demo/stats";
/// Soak subscribers at most (the demo allows 8 per service).
const MAX_SUBSCRIBERS: usize = 5;

fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// What a subscriber saw, counted from `seq` within one epoch.
#[derive(Debug, Default, Clone, Copy)]
struct Seen {
    received: u64,
    lost: u64,
    duplicated: u64,
    reordered: u64,
}

/// Subscriber mode: read `SERVICE` until SIGINT/SIGTERM, then print what was seen as JSON.
fn subscriber(prefix: &str) {
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&stop)).expect("signal handler");
    }
    let node = Transport::new(
        prefix,
        &format!("soak-sub-{}", std::process::id()),
        Qos::default(),
    )
    .expect("node");
    let input = node.open_input::<GyroSample>(SERVICE).expect("subscriber");
    let waker = node.waker(SERVICE).expect("waker");
    let mut seen = Seen::default();
    let mut last: Option<(u32, u64)> = None;
    while !stop.load(Ordering::Relaxed) {
        let _ = waker.wait(Duration::from_millis(50));
        while let Ok(Some(s)) = input.receive() {
            seen.received += 1;
            if let Some((epoch, seq)) = last {
                if epoch == s.epoch {
                    if s.seq > seq + 1 {
                        seen.lost += s.seq - seq - 1;
                    } else if s.seq == seq {
                        seen.duplicated += 1;
                    } else if s.seq < seq {
                        seen.reordered += 1;
                    }
                }
            }
            last = Some((s.epoch, s.seq));
        }
    }
    println!(
        "{{\"received\":{},\"lost\":{},\"duplicated\":{},\"reordered\":{}}}",
        seen.received, seen.lost, seen.duplicated, seen.reordered
    );
}

fn signal(child: &Child, sig: i32) {
    // SAFETY: kill has no memory-safety preconditions.
    unsafe {
        libc::kill(child.id() as i32, sig);
    }
}

fn rss_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Drain the stats subscriber (it must be drained often: a full buffer keeps the oldest
/// snapshots and loses the new ones) and keep the daemon's latest count of losses on the
/// corrected service (the publish stage's output).
fn drain_corrected_lost(
    stats: &driftless::transport::Input<StatsSnapshot>,
    lost: &mut Option<u64>,
) {
    while let Ok(Some(s)) = stats.receive() {
        if let Some(last) = (s.stage_count as usize).checked_sub(1) {
            *lost = Some(s.stages[last].lost);
        }
    }
}

struct Sub {
    child: Child,
    stopped_until: Option<Instant>,
}

/// Stop a subscriber cleanly (resumed first if stalled) and read its report.
fn leave(mut sub: Sub) -> Seen {
    if sub.stopped_until.is_some() {
        signal(&sub.child, libc::SIGCONT);
    }
    // Let it drain what its buffer holds before it is asked to go.
    std::thread::sleep(Duration::from_millis(300));
    signal(&sub.child, libc::SIGINT);
    let mut out = String::new();
    if let Some(mut o) = sub.child.stdout.take() {
        let _ = o.read_to_string(&mut out);
    }
    let _ = sub.child.wait();
    let v: Value = serde_json::from_str(out.trim()).unwrap_or_else(|e| {
        panic!("subscriber report {out:?}: {e}");
    });
    let get = |k: &str| v[k].as_u64().expect("count");
    Seen {
        received: get("received"),
        lost: get("lost"),
        duplicated: get("duplicated"),
        reordered: get("reordered"),
    }
}

/// One sample of where the daemon's hot thread spent its time, and of its CPU's counters.
#[derive(Debug, Clone, Copy)]
struct Probe {
    /// Bench time since the daemon's launch, s.
    t: f64,
    /// The hot thread's time on a CPU, ns (schedstat 1).
    exec_ns: u64,
    /// Its time runnable but waiting for a CPU, ns (schedstat 2).
    wait_ns: u64,
    /// The CPU it last ran on.
    cpu: usize,
    /// That CPU's steal, irq and softirq time, in USER_HZ ticks (10 ms).
    steal: u64,
    irq: u64,
    softirq: u64,
}

/// The daemon's SCHED_FIFO thread (the hot one), if it has one.
fn hot_thread(pid: u32) -> Option<u32> {
    std::fs::read_dir(format!("/proc/{pid}/task"))
        .ok()?
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<u32>().ok())
        .find(|tid| {
            stat_fields(pid, *tid).is_some_and(|f| f.get(38).map(String::as_str) == Some("1"))
        })
}

/// Fields of /proc/PID/task/TID/stat after the command name: index 0 is field 3 (state), so
/// field n of proc(5) is index n - 3.
fn stat_fields(pid: u32, tid: u32) -> Option<Vec<String>> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/task/{tid}/stat")).ok()?;
    let rest = &text[text.rfind(')')? + 1..];
    Some(rest.split_whitespace().map(str::to_string).collect())
}

fn probe(pid: u32, tid: u32, t: f64) -> Option<Probe> {
    let sched = std::fs::read_to_string(format!("/proc/{pid}/task/{tid}/schedstat")).ok()?;
    let mut sched = sched.split_whitespace().map(|v| v.parse::<u64>().ok());
    let (exec_ns, wait_ns) = (sched.next()??, sched.next()??);
    let cpu: usize = stat_fields(pid, tid)?.get(36)?.parse().ok()?;
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    let line = stat
        .lines()
        .find(|l| l.split_whitespace().next() == Some(&format!("cpu{cpu}")))?;
    let v: Vec<u64> = line
        .split_whitespace()
        .skip(1)
        .filter_map(|x| x.parse().ok())
        .collect();
    Some(Probe {
        t,
        exec_ns,
        wait_ns,
        cpu,
        irq: *v.get(5)?,
        softirq: *v.get(6)?,
        steal: *v.get(7)?,
    })
}

/// What the probes say of the span around `at` (the probes just before and just after it,
/// widened by the 50 ms the daemon's miss times may be off).
fn around(probes: &[Probe], at: f64) -> String {
    let before = probes.iter().rev().find(|p| p.t <= at - 0.05);
    let after = probes.iter().find(|p| p.t >= at + 0.05);
    match (before, after) {
        (Some(a), Some(b)) => format!(
            "hot thread over {:.0} ms: waited {:.3} ms for a CPU, ran {:.3} ms; CPU {}{}: steal {} irq {} \
             softirq {} ticks",
            (b.t - a.t) * 1e3,
            (b.wait_ns - a.wait_ns) as f64 / 1e6,
            (b.exec_ns - a.exec_ns) as f64 / 1e6,
            b.cpu,
            if a.cpu == b.cpu { "" } else { " (moved)" },
            b.steal.saturating_sub(a.steal),
            b.irq.saturating_sub(a.irq),
            b.softirq.saturating_sub(a.softirq)
        ),
        _ => "no probe around it".into(),
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--subscriber") {
        subscriber(&args[i + 1]);
        return;
    }
    if args.iter().any(|a| a == "--list") {
        return; // `cargo bench -- --list`
    }
    let secs = env_u64("DRIFTLESS_SOAK_SECONDS", 60).max(20);
    let control = env_u64("DRIFTLESS_SOAK_CONTROL", 0) != 0;
    let seed = env_u64("DRIFTLESS_SOAK_SEED", 1);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let prefix = format!("dlsoak{}_", std::process::id());
    let report = std::env::temp_dir().join(format!("{prefix}report.json"));
    let me = std::env::current_exe().expect("own path");

    let mut daemon = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .arg("run")
        .arg(root.join(PIPELINE))
        .args(["--prefix", &prefix, "--quiet", "--report"])
        .arg(&report)
        .args(["--duration", &format!("{}s", secs + 5)])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn driftless");
    // The daemon's report times its misses from its reporter's start, a little after this.
    let launched = Instant::now();
    let mut log: Vec<(f64, &'static str)> = Vec::new();
    let mut note = |what: &'static str| log.push((launched.elapsed().as_secs_f64(), what));
    let watcher = Transport::new(&prefix, "soak-watch", Qos::default()).expect("node");
    let start = Instant::now();
    let stats = loop {
        if let Ok(s) = watcher.open_input::<StatsSnapshot>(STATS) {
            break s;
        }
        assert!(start.elapsed() < Duration::from_secs(20), "daemon not up");
        std::thread::sleep(Duration::from_millis(50));
    };
    let spawn = || Sub {
        child: Command::new(&me)
            .args(["--subscriber", &prefix])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn subscriber"),
        stopped_until: None,
    };

    let hot = hot_thread(daemon.id());
    let mut probes: Vec<Probe> = Vec::new();
    let t0 = Instant::now();
    let phase = Duration::from_secs(secs / 2);
    let mut subs: Vec<Sub> = Vec::new();
    let mut seen = Seen::default();
    let (mut joins, mut stalls, mut kills, mut leaves) = (0u64, 0u64, 0u64, 0u64);
    let mut rss: Vec<(f64, u64)> = Vec::new();
    let mut next_action = Instant::now();
    let mut next_rss = Instant::now();
    let mut phase_a_daemon_lost = None;
    let mut daemon_lost = None;
    while t0.elapsed() < 2 * phase {
        let now = Instant::now();
        if let Some(p) =
            hot.and_then(|tid| probe(daemon.id(), tid, launched.elapsed().as_secs_f64()))
        {
            probes.push(p);
        }
        let killing = t0.elapsed() >= phase;
        if control {
            // No subscriber: nothing to do but watch.
        } else if killing && phase_a_daemon_lost.is_none() {
            // End of phase A: every subscriber leaves cleanly and reports.
            note("end of phase 1: every subscriber leaves");
            for s in subs.drain(..) {
                seen = add(seen, leave(s));
                leaves += 1;
            }
            // Two report intervals: the snapshot then holds every loss of phase A.
            std::thread::sleep(Duration::from_secs(5));
            drain_corrected_lost(&stats, &mut daemon_lost);
            phase_a_daemon_lost = daemon_lost;
        }
        drain_corrected_lost(&stats, &mut daemon_lost);
        for s in &mut subs {
            if s.stopped_until.is_some_and(|u| now >= u) {
                signal(&s.child, libc::SIGCONT);
                s.stopped_until = None;
                note("continue (SIGCONT)");
            }
        }
        if !control && now >= next_action {
            let roll: f64 = rng.random();
            if subs.len() < 2 || (roll < 0.35 && subs.len() < MAX_SUBSCRIBERS) {
                subs.push(spawn());
                joins += 1;
                note("join");
            } else if roll < 0.65 {
                let i = rng.random_range(0..subs.len());
                if subs[i].stopped_until.is_none() {
                    signal(&subs[i].child, libc::SIGSTOP);
                    subs[i].stopped_until =
                        Some(now + Duration::from_millis(rng.random_range(100..3000)));
                    stalls += 1;
                    note("stall (SIGSTOP)");
                }
            } else if killing && roll < 0.85 {
                let i = rng.random_range(0..subs.len());
                let mut s = subs.swap_remove(i);
                signal(&s.child, libc::SIGKILL);
                let _ = s.child.wait();
                kills += 1;
                note("kill (SIGKILL)");
            } else {
                let i = rng.random_range(0..subs.len());
                let s = subs.swap_remove(i);
                let got = leave(s);
                note("leave");
                if !killing {
                    seen = add(seen, got);
                }
                leaves += 1;
            }
            next_action = now + Duration::from_millis(rng.random_range(500..3000));
        }
        if now >= next_rss {
            if let Some(kib) = rss_kib(daemon.id()) {
                rss.push((t0.elapsed().as_secs_f64(), kib));
            }
            next_rss = now + Duration::from_secs(1);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    for s in subs.drain(..) {
        signal(&s.child, libc::SIGKILL);
        let mut s = s;
        let _ = s.child.wait();
    }
    signal(&daemon, libc::SIGINT);
    let _ = daemon.wait();
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&report).expect("report"))
        .expect("report JSON");
    let _ = std::fs::remove_file(&report);
    // What this run's own nodes (the watcher, killed subscribers) left under its prefix.
    drop((stats, watcher));
    driftless::transport::remove_prefix_leftovers(&prefix);

    let warm = rss
        .iter()
        .filter(|(t, _)| *t >= secs as f64 / 10.0)
        .map(|(_, k)| *k);
    let (lo, hi) = warm.fold((u64::MAX, 0), |(lo, hi), k| (lo.min(k), hi.max(k)));
    let misses = r["deadline_misses"].as_u64().unwrap_or(u64::MAX);
    let woken_late = r["woken_late_over_deadline"].as_u64().unwrap_or(u64::MAX);
    let daemon_a = phase_a_daemon_lost.unwrap_or(u64::MAX);
    if control {
        println!("soak CONTROL: {secs} s of pipelines/demo.toml at 1 kHz with no subscriber");
    } else {
        println!(
            "soak: {secs} s of pipelines/demo.toml at 1 kHz, seed {seed}; {joins} joins, {stalls} stalls \
             (SIGSTOP 0.1-3 s), {kills} kills (second half only), {leaves} clean leaves"
        );
    }
    match (probes.first(), probes.last()) {
        (Some(a), Some(b)) => println!(
            "  hot thread: ran {:.1} s, waited {:.3} ms for a CPU in all (most in one 20 ms probe: \
             {:.3} ms); steal on CPU {} {} ticks",
            (b.exec_ns - a.exec_ns) as f64 / 1e9,
            (b.wait_ns - a.wait_ns) as f64 / 1e6,
            probes
                .windows(2)
                .map(|w| w[1].wait_ns - w[0].wait_ns)
                .max()
                .unwrap_or(0) as f64
                / 1e6,
            b.cpu,
            b.steal.saturating_sub(a.steal)
        ),
        _ => println!("  hot thread: not found (no SCHED_FIFO thread: no probes)"),
    }
    println!(
        "  daemon: {} samples in, {} out, e2e p99 {:.1} us, max {:.1} us, deadline misses {misses}, lost {} in all",
        r["samples_in"],
        r["samples_out"],
        r["end_to_end_ns"]["p99"].as_f64().unwrap_or(f64::NAN) / 1e3,
        r["end_to_end_ns"]["max"].as_f64().unwrap_or(f64::NAN) / 1e3,
        r["lost"]
    );
    println!(
        "  woken late (after the sample was due; not in e2e): p50 {:.1} us, p99 {:.1} us, max {:.1} us, \
         {woken_late} over the deadline",
        r["woken_late_ns"]["p50"].as_f64().unwrap_or(f64::NAN) / 1e3,
        r["woken_late_ns"]["p99"].as_f64().unwrap_or(f64::NAN) / 1e3,
        r["woken_late_ns"]["max"].as_f64().unwrap_or(f64::NAN) / 1e3,
    );
    println!(
        "  resident memory after the first tenth: {lo} .. {hi} KiB ({} samples)",
        rss.len()
    );
    if !control {
        println!(
            "  phase 1 (no kills): subscribers received {}, lost {}, duplicated {}, reordered {}; the daemon counted {daemon_a} lost",
            seen.received, seen.lost, seen.duplicated, seen.reordered
        );
    }
    let goals = [
        ("no deadline miss", misses == 0),
        ("memory flat (growth < 1 MiB)", hi.saturating_sub(lo) < 1024),
        ("no sample taken over the deadline late", woken_late == 0),
        (
            "no duplicate or reordered sample",
            seen.duplicated == 0 && seen.reordered == 0,
        ),
        ("every loss counted exactly", daemon_a == seen.lost),
    ];
    // The control has no subscriber: only its timing and memory mean anything.
    for (goal, ok) in goals.iter().take(if control { 3 } else { goals.len() }) {
        println!("  goal {goal}: {ok}");
    }
    // Each miss beside what the bench did around it (bench time since the daemon's launch;
    // the daemon's own clock starts a little later and its records arrive up to ~50 ms late).
    for m in r["misses"].as_array().into_iter().flatten() {
        let at = m["at_s"].as_f64().unwrap_or(f64::NAN);
        let near: Vec<String> = log
            .iter()
            .filter(|(t, _)| (at - 3.0..=at + 1.0).contains(t))
            .map(|(t, what)| format!("{:+.2} s {what}", t - at))
            .collect();
        println!(
            "  miss at {at:.2} s: {:.1} us end to end, stage compute {} ns; around it: {}; {}",
            m["e2e_ns"].as_f64().unwrap_or(f64::NAN) / 1e3,
            m["stage_ns"],
            if near.is_empty() {
                "nothing".to_string()
            } else {
                near.join(", ")
            },
            around(&probes, at)
        );
    }
}

fn add(a: Seen, b: Seen) -> Seen {
    Seen {
        received: a.received + b.received,
        lost: a.lost + b.lost,
        duplicated: a.duplicated + b.duplicated,
        reordered: a.reordered + b.reordered,
    }
}
