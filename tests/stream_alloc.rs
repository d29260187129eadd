//! The streaming denoiser allocates nothing per sample: a counting global allocator watches
//! `push` and `flush` after construction.

use driftless::wavelet::stream::{Sigma, StreamConfig, StreamingDenoiser};
use driftless::wavelet::threshold::ThresholdFn;
#[path = "support/alloc_counter.rs"]
mod alloc_counter;

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
        let (allocations, sum) = alloc_counter::allocations_during(|| {
            let mut sum = 0.0;
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
            sum
        });
        assert!(sum.is_finite());
        assert_eq!(allocations, 0, "allocations in push/flush");
    }
}
