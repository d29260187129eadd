//! The simulator allocates nothing per sample: a counting global allocator watches `next_sample`
//! after construction, with every noise process and motion on.

use driftless::sim::{Motion, NoiseTerms, SimConfig, Simulator};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn next_sample_does_not_allocate() {
    let cfg = SimConfig {
        terms: NoiseTerms {
            q: 1e-3,
            n: 0.01,
            b: 0.002,
            k: 1e-4,
            r: 1e-6,
            bias: 0.3,
        },
        rate_hz: 200.0,
        axes: 3,
        seed: 9,
        motion: Motion::Turn,
        lsb: Some(0.01),
    };
    let mut sim = Simulator::new(&cfg).unwrap();
    let mut sum = 0.0;
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    for _ in 0..100_000 {
        let s = sim.next_sample();
        sum += s.measured[0] + s.truth[2];
    }
    let after = ALLOCATIONS.load(Ordering::Relaxed);
    assert_eq!(after - before, 0, "allocations in next_sample");
    assert!(sum.is_finite());
}
