//! Attitude speed, in two parts.
//!
//! 1. **Paced, as the daemon runs it**: the stages of `pipelines/navigator-attitude.toml`,
//!    built from the file, take one sample every millisecond on a thread that sleeps between
//!    them (so each call meets the caches the sleep left, as in the daemon). Each stage's
//!    `process` is timed alone: the daemon's per-stage figure also holds the publish of the
//!    stage's output, the same for every stage. The baseline is `predict.bias` in the same run.
//!    Issue 50's goal: `attitude.6d`'s p99.9 <= 5 us at 1 kHz. Beside them, the attitude stage
//!    of `pipelines/navigator-9d.toml` (`use_mag`) takes the same input with a magnetometer
//!    reading: issue 61's goal, its p50 <= 1.5x the 6D stage's.
//! 2. **Hot loop** (criterion): one sample through [`Attitude::push`] (VQF 6D, its bias
//!    estimation on), and through [`Attitude::push_mag`] with the magnetometer (9D, issue 61's
//!    goal: p50 <= 1.5x 6D's), beside one sample of one axis through `BiasTracker::push`.

mod support;

use criterion::{criterion_group, Criterion, Throughput};
use driftless::attitude::{Attitude, AttitudeConfig, MagConfig, Upstream};
use driftless::drift::bias::BiasTracker;
use driftless::wire::{GyroSample, SENSOR_ACCEL, SENSOR_MAG};
use hdrhistogram::Histogram;
use std::hint::black_box;
use std::time::{Duration, Instant};

/// A body swaying about all three axes, 10 s at 1 kHz: rates (rad/s) and a specific force
/// (m/s²) near gravity.
fn motion() -> Vec<([f64; 3], [f64; 3])> {
    (0..10_000)
        .map(|k| {
            let t = k as f64 / 1000.0;
            let w = [0.5 * t.sin(), 0.3 * (1.3 * t).cos(), 0.2 * (0.7 * t).sin()];
            let a = [0.8 * (0.9 * t).sin(), 0.6 * (1.1 * t).cos(), 9.81];
            (w, a)
        })
        .collect()
}

/// The magnetometer at sample `k` (tesla): a field of 45 uT whose direction in the body wanders
/// with the sway.
fn field(k: usize) -> [f64; 3] {
    let t = k as f64 / 1000.0;
    [20e-6 * (0.3 * t).sin(), 20e-6 * (0.3 * t).cos(), -40e-6]
}

fn per_sample(c: &mut Criterion) {
    let x = motion();
    let mut group = c.benchmark_group("per_sample");
    group.throughput(Throughput::Elements(x.len() as u64));
    group.bench_function("attitude_6d", |b| {
        let mut f = Attitude::new(1000.0, AttitudeConfig::default()).expect("valid settings");
        // The bias removed before, as predict.bias hands it on while moving: held.
        let upstream = Upstream {
            bias: [2e-3, -1e-3, 5e-4],
            sd: [1e-5; 3],
        };
        b.iter(|| {
            let mut acc = 0.0;
            for (w, a) in &x {
                acc += f.push(*w, Some(*a), Some(upstream)).quat[0];
            }
            black_box(acc)
        })
    });
    group.bench_function("attitude_9d", |b| {
        let cfg = AttitudeConfig {
            mag: Some(MagConfig::default()),
            ..AttitudeConfig::default()
        };
        let mut f = Attitude::new(1000.0, cfg).expect("valid settings");
        let upstream = Upstream {
            bias: [2e-3, -1e-3, 5e-4],
            sd: [1e-5; 3],
        };
        let mag: Vec<[f64; 3]> = (0..x.len()).map(field).collect();
        b.iter(|| {
            let mut acc = 0.0;
            for ((w, a), m) in x.iter().zip(&mag) {
                acc += f.push_mag(*w, Some(*a), Some(*m), Some(upstream)).quat[0];
            }
            black_box(acc)
        })
    });
    group.bench_function("bias_tracker_one_axis", |b| {
        let mut tr = BiasTracker::for_profile("adis16405", 1000.0).expect("built-in profile");
        b.iter(|| {
            let mut acc = 0.0;
            for (w, _) in &x {
                acc += tr.push(w[0].to_degrees()).bias;
            }
            black_box(acc)
        })
    });
    group.finish();
}

/// Part 1: the chain's stages after the ingest, one sample a millisecond, each `process` timed
/// alone; every other sample prewarmed as `prewarm_us = 150` would (the stages' `prewarm`,
/// 150 us before the sample is due), so that both are measured in the same run.
fn paced() {
    const PREWARM: Duration = Duration::from_micros(150);
    let secs = support::bench_seconds(20.0);
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/navigator-attitude.toml");
    let p = driftless::pipeline::config::load(&path).expect("shipped pipeline");
    let cx = p.context();
    let mut stages: Vec<_> = p.stages[1..]
        .iter()
        .map(|s| {
            let stage = s.params.stage(&cx).expect("stage");
            (s.name.clone(), s.kind.name, stage)
        })
        .collect();
    let att6 = stages
        .iter()
        .position(|(_, k, _)| *k == "attitude.6d")
        .expect("attitude.6d in the shipped pipeline");
    // The 9D stage, last in the table: it takes the 6D stage's input with the magnetometer.
    let path9 =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/navigator-9d.toml");
    let p9 = driftless::pipeline::config::load(&path9).expect("shipped pipeline");
    let s9 = p9
        .stages
        .iter()
        .find(|s| s.kind.name == "attitude.6d")
        .expect("attitude.6d in navigator-9d.toml");
    stages.push((
        format!("{} (navigator-9d.toml, use_mag)", s9.name),
        s9.kind.name,
        s9.params.stage(&p9.context()).expect("stage"),
    ));
    let att9 = stages.len() - 1;
    // [plain, prewarmed] per stage.
    let mut hist: Vec<[Histogram<u64>; 2]> = stages
        .iter()
        .map(|_| std::array::from_fn(|_| Histogram::new(3).expect("histogram")))
        .collect();
    let scheduling = p
        .realtime_priority
        .map_or("default scheduling".into(), support::realtime);
    let period = Duration::from_secs_f64(1.0 / p.rate_hz);
    let x = motion();
    let sleep_until = |t: Instant| {
        if let Some(wait) = t.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
    };
    let mut due = Instant::now();
    for k in 0..(secs * p.rate_hz) as usize {
        due += period;
        let warmed = k % 2;
        if warmed == 1 {
            sleep_until(due - PREWARM);
            for (_, _, stage) in &mut stages {
                stage.prewarm();
            }
        }
        sleep_until(due);
        let (w, a) = x[k % x.len()];
        let mut s = GyroSample {
            seq: k as u64,
            rate: w.map(f64::to_degrees),
            accel: a,
            sensors: SENSOR_ACCEL,
            ..GyroSample::default()
        };
        for i in 0..att9 {
            // The 6D and 9D stages take the same input, in turns first; only the first is
            // timed, as the daemon runs one of them (the second meets the code the first left
            // in the cache).
            let turn: &[usize] = match i {
                i if i != att6 => &[i],
                _ if (k / 2) % 2 == 0 => &[att6, att9],
                _ => &[att9, att6],
            };
            let mut next = None;
            for &j in turn {
                let input = if j == att9 {
                    GyroSample {
                        mag: field(k % x.len()),
                        sensors: s.sensors | SENSOR_MAG,
                        ..s
                    }
                } else {
                    s
                };
                let t0 = Instant::now();
                let out = stages[j].2.process(&input);
                let ns = t0.elapsed().as_nanos() as u64;
                if j == turn[0] {
                    hist[j][warmed].record(ns.max(1)).expect("in range");
                }
                if j != att9 {
                    next = out;
                }
            }
            match next {
                Some(out) => s = black_box(out),
                None => break,
            }
        }
    }
    let us = |ns: u64| ns as f64 / 1000.0;
    let pct = |h: &Histogram<u64>| {
        format!(
            "{:.2} / {:.2} / {:.2} / {:.1}",
            us(h.value_at_quantile(0.5)),
            us(h.value_at_quantile(0.99)),
            us(h.value_at_quantile(0.999)),
            us(h.max())
        )
    };
    println!(
        "{} at {} Hz for {secs} s, {scheduling}; load average {}",
        path.file_name().unwrap().to_string_lossy(),
        p.rate_hz,
        support::loadavg()
    );
    println!("| stage | kind | process p50 / p99 / p99.9 / max us | prewarmed 150 us before |");
    println!("|---|---|---:|---:|");
    for ((name, kind, _), [plain, warmed]) in stages.iter().zip(&hist) {
        println!("| {name} | {kind} | {} | {} |", pct(plain), pct(warmed));
    }
    let att = &hist[att6];
    for (label, h) in [("", &att[0]), (", prewarmed", &att[1])] {
        let p999 = h.value_at_quantile(0.999);
        println!(
            "  goal attitude.6d p99.9 <= 5 us{label}: {} ({:.2} us)",
            p999 <= 5_000,
            us(p999)
        );
    }
    for (label, w) in [("", 0), (", prewarmed", 1)] {
        let (p6, p9) = (
            hist[att6][w].value_at_quantile(0.5).max(1),
            hist[att9][w].value_at_quantile(0.5),
        );
        println!(
            "  goal 9D (use_mag) p50 <= 1.5x 6D's{label}: {} (x{:.2}: {:.2} us against {:.2})",
            p9 as f64 <= 1.5 * p6 as f64,
            p9 as f64 / p6 as f64,
            us(p9),
            us(p6)
        );
    }
}

criterion_group!(benches, per_sample);

fn main() {
    paced();
    benches();
    Criterion::default().configure_from_args().final_summary();
}
