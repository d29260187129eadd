//! Our Table 2: the threshold functions on the seeded synthetic benchmark, scored against the
//! known truth; and the streaming denoiser against the batch one on the same record.

use driftless::quality::snr_db;
use driftless::synthetic::{record, Regime, SAMPLES};
use driftless::wavelet::denoise::{compare, DenoiseConfig};
use driftless::wavelet::stream::{StreamConfig, StreamingDenoiser};

fn table(regime: Regime, seed: u64) -> Vec<(&'static str, f64)> {
    let r = record(regime, SAMPLES, seed);
    compare(&r.measured, Some(&r.truth), &DenoiseConfig::paper())
        .unwrap()
        .iter()
        .map(|c| (c.function.name(), c.snr_db.unwrap()))
        .collect()
}

fn snr_of(rows: &[(&str, f64)], name: &str) -> f64 {
    rows.iter().find(|r| r.0 == name).unwrap().1
}

#[test]
fn dynamic_regime_improved_beats_soft_and_is_near_the_best() {
    // The documented table uses seed 1. The improved function's defaults were chosen on seeds
    // 1-5, so seeds 6-10 are held out: they check the choice, not just the fit.
    for seed in [1, 6, 7, 8, 9, 10] {
        let rows = table(Regime::Dynamic, seed);
        let (improved, soft) = (snr_of(&rows, "improved"), snr_of(&rows, "soft"));
        let best = rows.iter().map(|r| r.1).fold(f64::MIN, f64::max);
        assert!(improved >= soft, "seed {seed}: {rows:?}");
        assert!(improved >= best - 0.5, "seed {seed}: {rows:?}");
    }
}

#[test]
fn static_regime_every_function_improves_on_the_raw_record() {
    let r = record(Regime::Static, SAMPLES, 1);
    let raw = snr_db(&r.truth, &r.measured);
    for (name, snr) in table(Regime::Static, 1) {
        assert!(snr > raw + 10.0, "{name}: {snr} dB vs raw {raw} dB");
    }
}

#[test]
fn streaming_at_the_default_lag_is_within_1_db_of_batch() {
    for seed in 1..=3 {
        let r = record(Regime::Dynamic, SAMPLES, seed);
        let batch = snr_of(&table(Regime::Dynamic, seed), "improved");
        let mut d = StreamingDenoiser::new(&StreamConfig::default()).unwrap();
        let mut out: Vec<f64> = r.measured.iter().filter_map(|v| d.push(*v)).collect();
        out.extend(std::iter::from_fn(|| d.flush()));
        let streaming = snr_db(&r.truth, &out);
        assert!(
            streaming >= batch - 1.0,
            "seed {seed}: streaming {streaming:.2} dB vs batch {batch:.2} dB"
        );
    }
}
