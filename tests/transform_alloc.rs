//! `Plan::wavedec` / `Plan::waverec` allocate nothing once the plan exists.
//!
//! A counting global allocator is per binary, hence this file of its own. The count is per
//! thread, so the test harness's other threads cannot disturb it.

use driftless::wavelet::transform::{Mode, Plan};
use driftless::wavelet::Wavelet;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

struct Counting;

// SAFETY: forwards to the system allocator; only counts calls on the current thread.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

#[test]
fn planned_transforms_allocate_nothing() {
    // The counter itself must work, or a zero below would prove nothing.
    let before = allocations();
    let v = std::hint::black_box(vec![1.0f64; 16]);
    assert!(allocations() > before);
    drop(v);

    for name in ["haar", "db6", "sym8", "coif17"] {
        let w = Wavelet::by_name(name).expect("known wavelet");
        for mode in Mode::ALL {
            for n in [1023, 4096] {
                let level = 3;
                let mut plan = Plan::new(&w, mode, n, level).expect("level fits");
                let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
                let mut coeffs = vec![0.0; plan.coeffs_len()];
                let mut out = vec![0.0; n];
                let before = allocations();
                for _ in 0..3 {
                    plan.wavedec(&x, &mut coeffs);
                    plan.waverec(&coeffs, &mut out);
                }
                let count = allocations() - before;
                assert_eq!(count, 0, "{name} {mode} n={n}: {count} allocations");
                // And it did the work: the signal comes back.
                let err = x
                    .iter()
                    .zip(&out)
                    .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                assert!(
                    err < 1e-9,
                    "{name} {mode} n={n}: reconstruction error {err}"
                );
            }
        }
    }
}
