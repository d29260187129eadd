//! The bias tracker (and so a stage built on it) allocates nothing per sample: a counting global
//! allocator watches `push` and `push_gated` after construction, through warming, still (with
//! the delay window filling and draining) and moving stretches, and the nav baselines too.

use driftless::drift::bias::{BiasMode, BiasTerms, BiasTracker, TrackerConfig};
use driftless::nav::{BiasEstimator, Zaru};
#[path = "support/alloc_counter.rs"]
mod alloc_counter;

fn rate(t: usize) -> f64 {
    // Noise-like wiggle, a 4 s stop every 10 s, motion otherwise.
    let noise = 0.3 * ((t * 7919 % 97) as f64 / 97.0 - 0.5);
    let moving = t % 1000 >= 400;
    0.4 + noise
        + if moving {
            10.0 + 5.0 * (t as f64 * 0.04).sin()
        } else {
            0.0
        }
}

#[test]
fn push_allocates_nothing_in_any_mode() {
    let terms = BiasTerms::profile("adis16405").unwrap();
    let mut tracker = BiasTracker::new(&terms, 100.0, &TrackerConfig::default()).unwrap();
    let mut gated = tracker.clone();
    let still_cfg = *tracker.stillness();
    let mut zaru = Zaru::detected(100, still_cfg);
    let (allocations, modes) = alloc_counter::allocations_during(|| {
        let mut modes = [0usize; 3];
        for t in 0..6000 {
            let x = rate(t);
            let s = tracker.push(x);
            modes[match s.mode {
                BiasMode::Warming => 0,
                BiasMode::Still => 1,
                BiasMode::Moving => 2,
            }] += 1;
            gated.push_gated(x, t % 1000 < 400);
            zaru.push(x, false);
        }
        modes
    });
    assert!(
        modes.iter().all(|&m| m > 0),
        "every mode exercised: {modes:?}"
    );
    assert!(tracker.filter().updates() > 0, "the delay window drained");
    assert_eq!(allocations, 0, "allocations during push");
}

/// The `predict.bias` stage as the daemon builds it from a pipeline file: `process` allocates
/// nothing per sample, and every flag state is exercised.
#[test]
fn the_predict_bias_stage_allocates_nothing_per_sample() {
    use driftless::pipeline::config;
    use driftless::wire::{GyroSample, FLAG_MOVING, FLAG_STILL};
    let dir = tempfile::tempdir().unwrap();
    let text = r#"
name = "a"
rate_hz = 100.0
axes = 3
input_units = "deg/s"
[[stage]]
name = "sensor"
kind = "ingest.sim"
output = "a/raw"
[[stage]]
name = "predict"
kind = "predict.bias"
input = "a/raw"
output = "a/predicted"
[[stage]]
name = "publish"
kind = "publish"
input = "a/predicted"
output = "a/corrected"
"#;
    let file = dir.path().join("p.toml");
    std::fs::write(&file, text).unwrap();
    let p = config::load(&file).expect("valid pipeline");
    let spec = p.stages.iter().find(|s| s.name == "predict").unwrap();
    let mut stage = spec.params.stage(&p.context()).expect("stage");
    let (allocations, flags) = alloc_counter::allocations_during(|| {
        let mut flags = [0usize; 2];
        for t in 0..20_000usize {
            let mut s = GyroSample {
                seq: t as u64,
                ..GyroSample::default()
            };
            s.denoised = [rate(t).to_radians(); 3];
            let out = stage.process(&s).expect("one out per in");
            flags[0] += usize::from(out.flags & FLAG_STILL != 0);
            flags[1] += usize::from(out.flags & FLAG_MOVING != 0);
        }
        flags
    });
    assert!(
        flags.iter().all(|&n| n > 1000),
        "still and moving: {flags:?}"
    );
    assert_eq!(allocations, 0, "allocations in predict.bias process");
}
