//! OADEV of 10^7 samples at ~90 log-spaced taus (15 per decade up to m = 2.5e6), the data from
//! splitmix64 exactly as scripts/bench_allantools.py makes it for allantools' `oadev`.
//!
//! `cargo bench --bench allan`; `python3 scripts/bench_allantools.py` runs both side by side.

use criterion::{criterion_group, criterion_main, Criterion};
use driftless::allan::chi2::ONE_SIGMA;
use driftless::allan::{allan, Kind, TauGrid};
use std::hint::black_box;

const SAMPLES: usize = 10_000_000;

/// splitmix64, value = (u >> 11) * 2^-53 - 0.5 (white noise), as the Python side.
fn data() -> Vec<f64> {
    driftless::synthetic::SplitMix64(42)
        .take(SAMPLES)
        .map(|u| u - 0.5)
        .collect()
}

/// m = round(10^(j/15)), j = 0..=96, duplicates removed; taus = m / rate at rate 1.
fn taus() -> Vec<f64> {
    let mut m: Vec<f64> = (0..=96)
        .map(|j| 10f64.powf(f64::from(j) / 15.0).round())
        .collect();
    m.dedup();
    m
}

fn bench(c: &mut Criterion) {
    let y = data();
    let grid = TauGrid::List(taus());
    let points = allan(&y, 1.0, Kind::Oadev, &grid, ONE_SIGMA).expect("long enough");
    eprintln!("{} samples, {} taus", y.len(), points.len());
    let mut g = c.benchmark_group("allan");
    g.sample_size(10);
    g.bench_function("oadev_1e7_samples_log_taus", |b| {
        b.iter(|| allan(black_box(&y), 1.0, Kind::Oadev, &grid, ONE_SIGMA))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
