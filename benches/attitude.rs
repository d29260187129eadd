//! Attitude speed: one sample through [`Attitude::push`] (VQF 6D, its bias estimation on), beside
//! one sample of one axis through the bias filter (`BiasTracker::push`, the stage before it), the
//! baseline measured in the same run. Issue 50's goal is the stage's p99.9 <= 5 us at 1 kHz.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use driftless::attitude::{Attitude, AttitudeConfig};
use driftless::drift::bias::BiasTracker;
use std::hint::black_box;

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

fn per_sample(c: &mut Criterion) {
    let x = motion();
    let mut group = c.benchmark_group("per_sample");
    group.throughput(Throughput::Elements(x.len() as u64));
    group.bench_function("attitude_6d", |b| {
        let mut f = Attitude::new(1000.0, AttitudeConfig::default()).expect("valid settings");
        b.iter(|| {
            let mut acc = 0.0;
            for (w, a) in &x {
                acc += f.push(*w, Some(*a), Some([1e-5; 3])).quat[0];
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

criterion_group!(benches, per_sample);
criterion_main!(benches);
