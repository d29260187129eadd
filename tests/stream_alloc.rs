//! The streaming denoiser allocates nothing per sample: a counting global allocator watches
//! `push` and `flush` after construction.

use driftless::wavelet::stream::{Sigma, StreamConfig, StreamingDenoiser};
use driftless::wavelet::threshold::ThresholdFn;
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
fn push_and_flush_allocate_nothing() {
    for (threshold, sigma, lag) in [
        (ThresholdFn::improved_default(), Sigma::Mad, 33),
        (ThresholdFn::Soft, Sigma::Fixed(0.1), 341),
        (ThresholdFn::Hard, Sigma::Mad, 0),
    ] {
        let mut d = StreamingDenoiser::new(&StreamConfig {
            threshold,
            sigma,
            lag,
            ..StreamConfig::default()
        })
        .unwrap();
        let mut sum = 0.0;
        let before = ALLOCATIONS.load(Ordering::Relaxed);
        // Several windows' worth, so the noise tracker's window fills and slides.
        for i in 0..5000 {
            let x = (i as f64 * 0.01).sin() + ((i * 7919) % 101) as f64 * 1e-3;
            if let Some(y) = d.push(if i == 2500 { f64::NAN } else { x }) {
                sum += y;
            }
        }
        while let Some(y) = d.flush() {
            sum += y;
        }
        let after = ALLOCATIONS.load(Ordering::Relaxed);
        assert!(sum.is_finite());
        assert_eq!(
            after - before,
            0,
            "{} allocations in push/flush",
            after - before
        );
    }
}
