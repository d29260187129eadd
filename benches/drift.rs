//! Drift model speed: training on 99,000 samples with 40 centres (goal <= 1 s; k-means++ and OLS
//! centres, ridge weights, no Adam) and prediction per sample per axis (goal <= 200 ns): the
//! network alone, and the whole live compensator step (low band, stillness, prediction).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use driftless::drift::compensator::Compensator;
use driftless::drift::model::{DenoiseSettings, LowbandSettings};
use driftless::drift::separation::separate_causal;
use driftless::drift::stillness::StillnessConfig;
use driftless::drift::training::{train, CentreMethod, TrainConfig};
use driftless::drift::{LowBand, Predictor};
use driftless::sim::{SimConfig, Simulator};
use std::hint::black_box;
use std::time::Duration;

/// The paper's setting: the simulated ADXRS450 at 50 Hz, its causal drift, 100,000 samples.
fn drift() -> (Vec<f64>, Vec<f64>) {
    let mut cfg = SimConfig::profile("adxrs450").expect("built-in profile");
    cfg.seed = 1;
    let mut sim = Simulator::new(&cfg).expect("valid profile");
    let x: Vec<f64> = (0..100_000)
        .map(|_| sim.next_sample().measured[0])
        .collect();
    let d = DenoiseSettings {
        wavelet: "db6".into(),
        level: 5,
        threshold: "improved".into(),
        window: 1024,
        lag: 33,
    };
    let l = LowbandSettings {
        wavelet: "db6".into(),
        level: 5,
    };
    let s = separate_causal(&x, &d, &l).expect("valid settings");
    (s.denoised, s.drift)
}

fn training(c: &mut Criterion) {
    let (_, drift) = drift();
    let series = &drift[1000..100_000];
    let mut group = c.benchmark_group("train_99000_q40");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(8));
    for method in [CentreMethod::Kmeans, CentreMethod::Ols] {
        let cfg = TrainConfig {
            method,
            ..TrainConfig::default()
        };
        group.bench_function(format!("{method:?}").to_lowercase(), |b| {
            b.iter(|| black_box(train(series, &cfg, &mut |_| {}).expect("trains")))
        });
    }
    group.finish();
}

fn prediction(c: &mut Criterion) {
    let (denoised, drift) = drift();
    let model = train(&drift[1000..100_000], &TrainConfig::default(), &mut |_| {}).expect("trains");
    let mut group = c.benchmark_group("predict_q40_p4");
    group.throughput(Throughput::Elements(10_000));
    group.bench_function("network", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for t in 90_000..100_000 {
                acc += model.predict(&drift[t - 4..t]);
            }
            black_box(acc)
        })
    });
    let still = StillnessConfig::calibrate(&denoised, &drift, 25, 342, 1.5);
    let mut comp =
        Compensator::new(&model, LowBand::new("db6", 5).expect("db6"), still, 1e-2).expect("ok");
    group.bench_function("compensator_step", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for &x in &denoised[90_000..100_000] {
                acc += comp.push(x).rate;
            }
            black_box(acc)
        })
    });
    group.finish();
}

criterion_group!(benches, training, prediction);
criterion_main!(benches);
