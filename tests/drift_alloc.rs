//! The live compensator (and so the `predict.rbf` stage) allocates nothing per sample: a
//! counting global allocator watches `push` after construction, through warming up, still and
//! moving stretches.

use driftless::drift::compensator::{Compensator, Mode};
use driftless::drift::stillness::StillnessConfig;
use driftless::drift::training::{train, TrainConfig};
use driftless::drift::LowBand;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

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
    let mut modes = [0usize; 3];
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    for t in 0..3000 {
        let x = 0.3 + if (1000..2000).contains(&t) { 5.0 } else { 0.0 };
        let s = c.push(x);
        modes[match s.mode {
            Mode::Warming => 0,
            Mode::Still => 1,
            Mode::Moving => 2,
        }] += 1;
    }
    let after = ALLOCATIONS.load(Ordering::Relaxed);
    assert!(
        modes.iter().all(|&m| m > 0),
        "every mode exercised: {modes:?}"
    );
    assert_eq!(after - before, 0, "allocations during push");
}
