//! The live compensator (and so the `predict.rbf` stage) allocates nothing per sample: a
//! counting global allocator watches `push` after construction, through warming up, still and
//! moving stretches.

use driftless::drift::compensator::{Compensator, Mode};
use driftless::drift::stillness::StillnessConfig;
use driftless::drift::training::{train, TrainConfig};
use driftless::drift::LowBand;
#[path = "support/alloc_counter.rs"]
mod alloc_counter;

#[test]
fn push_allocates_nothing_in_any_mode() {
    let drift: Vec<f64> = (0..5000).map(|i| 0.1 * (i as f64 / 700.0).sin()).collect();
    let model = train(&drift, &TrainConfig::default(), &mut |_| {}).unwrap();
    let still = StillnessConfig {
        window: 20,
        var_enter: 0.02,
        var_exit: 0.01,
        mean_enter: 0.2,
        mean_exit: 0.1,
        settle: 50,
    };
    let mut c = Compensator::new(model, LowBand::new("db6", 5).unwrap(), still, 1e-3).unwrap();
    let (allocations, modes) = alloc_counter::allocations_during(|| {
        let mut modes = [0usize; 3];
        for t in 0..3000 {
            let x = 0.3 + if (1000..2000).contains(&t) { 5.0 } else { 0.0 };
            let s = c.push(x);
            modes[match s.mode {
                Mode::Warming => 0,
                Mode::Still => 1,
                Mode::Moving => 2,
            }] += 1;
        }
        modes
    });
    assert!(
        modes.iter().all(|&m| m > 0),
        "every mode exercised: {modes:?}"
    );
    assert_eq!(allocations, 0, "allocations during push");
}
