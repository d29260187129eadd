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
