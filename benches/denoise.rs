//! Denoising speed: the streaming denoiser per sample (goal <= 1 us per sample per axis for db6 /
//! 5 levels) and batch denoising of 18,000 and 10^6 samples (goal >= 3x PyWavelets'
//! wavedec + threshold + waverec on the same data: `python3 scripts/bench_pywt.py` in the same run),
//! and the transform alone (wavedec + waverec) against PyWavelets'.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use driftless::wavelet::denoise::{denoise, DenoiseConfig};
use driftless::wavelet::stream::{LaneDenoiser, Sigma, StreamConfig, StreamingDenoiser};
use driftless::wavelet::transform::Plan;
use driftless::wavelet::{Mode, Wavelet};
use std::hint::black_box;

/// The same signal as scripts/bench_pywt.py.
fn signal(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| (i as f64 * 0.001).sin() + ((i * 7919) % 1000) as f64 / 1000.0 - 0.5)
        .collect()
}

fn streaming(c: &mut Criterion) {
    let x = signal(100_000);
    let mut group = c.benchmark_group("stream_db6_L5");
    group.throughput(Throughput::Elements(x.len() as u64));
    for lag in [0, StreamConfig::DEFAULT_LAG, 341] {
        group.bench_with_input(BenchmarkId::new("lag", lag), &lag, |b, &lag| {
            let mut d = StreamingDenoiser::new(&StreamConfig {
                lag,
                ..StreamConfig::default()
            })
            .expect("valid settings");
            b.iter(|| {
                let mut acc = 0.0;
                for v in &x {
                    if let Some(y) = d.push(*v) {
                        acc += y;
                    }
                }
                black_box(acc)
            })
        });
    }
    group.bench_function("lag/33/fixed_sigma", |b| {
        let mut d = StreamingDenoiser::new(&StreamConfig {
            sigma: Sigma::Fixed(0.3),
            ..StreamConfig::default()
        })
        .expect("valid settings");
        b.iter(|| {
            let mut acc = 0.0;
            for v in &x {
                if let Some(y) = d.push(*v) {
                    acc += y;
                }
            }
            black_box(acc)
        })
    });
    group.finish();
}

/// Three axes as the daemon's `denoise.wavelet` runs them (db6 / 5 levels / lag 64, windows
/// 1024 and 256): in lock step (`LaneDenoiser<3>`, as shipped) against three one-stream
/// denoisers in turn (before), same data, same run; the outputs are bit-identical (tested).
fn three_axes(c: &mut Criterion) {
    let x = signal(100_000);
    let y: Vec<f64> = x.iter().rev().copied().collect();
    let z: Vec<f64> = x.iter().map(|v| 0.5 * v + 0.1).collect();
    let mut group = c.benchmark_group("stream_3axes_db6_L5_lag64");
    group.throughput(Throughput::Elements(x.len() as u64));
    for window in [1024, 256] {
        let cfg = StreamConfig {
            lag: 64,
            window,
            ..StreamConfig::default()
        };
        group.bench_with_input(BenchmarkId::new("lanes", window), &cfg, |b, cfg| {
            let mut d = LaneDenoiser::<3>::new(cfg).expect("valid settings");
            b.iter(|| {
                let mut acc = 0.0;
                for ((a, b), c) in x.iter().zip(&y).zip(&z) {
                    if let Some(v) = d.push([*a, *b, *c]) {
                        acc += v[0] + v[1] + v[2];
                    }
                }
                black_box(acc)
            })
        });
        group.bench_with_input(
            BenchmarkId::new("three_denoisers", window),
            &cfg,
            |b, cfg| {
                let mut d: Vec<StreamingDenoiser> = (0..3)
                    .map(|_| StreamingDenoiser::new(cfg).expect("valid settings"))
                    .collect();
                b.iter(|| {
                    let mut acc = 0.0;
                    for ((a, b), c) in x.iter().zip(&y).zip(&z) {
                        for (d, v) in d.iter_mut().zip([a, b, c]) {
                            if let Some(v) = d.push(*v) {
                                acc += v;
                            }
                        }
                    }
                    black_box(acc)
                })
            },
        );
    }
    group.finish();
}

fn batch(c: &mut Criterion) {
    let cfg = DenoiseConfig::paper();
    let mut group = c.benchmark_group("batch_db6_L5_improved_universal");
    group.sample_size(20);
    for n in [18_000usize, 1_000_000] {
        let x = signal(n);
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), &x, |b, x| {
            b.iter(|| black_box(denoise(x, &cfg).expect("valid")))
        });
    }
    group.finish();
}

/// The transform alone: `Plan::wavedec` + `Plan::waverec` (db6 / 5 levels / symmetric), against
/// PyWavelets' `waverec(wavedec(x))` in scripts/bench_pywt.py.
fn transform(c: &mut Criterion) {
    let w = Wavelet::by_name("db6").expect("built in");
    let mut group = c.benchmark_group("wavedec_waverec_db6_L5");
    group.sample_size(20);
    for n in [18_000usize, 1_000_000] {
        let x = signal(n);
        let mut plan = Plan::new(&w, Mode::Symmetric, n, 5).expect("long enough");
        let (mut coeffs, mut out) = (vec![0.0; plan.coeffs_len()], vec![0.0; n]);
        group.throughput(Throughput::Elements(n as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), &x, |b, x| {
            b.iter(|| {
                plan.wavedec(x, &mut coeffs);
                plan.waverec(&coeffs, &mut out);
                black_box(out[n / 2])
            })
        });
    }
    group.finish();
}

criterion_group!(benches, streaming, three_axes, batch, transform);
criterion_main!(benches);
