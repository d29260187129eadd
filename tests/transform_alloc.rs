//! `Plan::wavedec` / `Plan::waverec` allocate nothing once the plan exists.

use driftless::wavelet::transform::{Mode, Plan};
use driftless::wavelet::Wavelet;
#[path = "support/alloc_counter.rs"]
mod alloc_counter;

#[test]
fn planned_transforms_allocate_nothing() {
    for name in ["haar", "db6", "sym8", "coif17"] {
        let w = Wavelet::by_name(name).expect("known wavelet");
        for mode in Mode::ALL {
            for n in [1023, 4096] {
                let level = 3;
                let mut plan = Plan::new(&w, mode, n, level).expect("level fits");
                let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
                let mut coeffs = vec![0.0; plan.coeffs_len()];
                let mut out = vec![0.0; n];
                let (count, ()) = alloc_counter::allocations_during(|| {
                    for _ in 0..3 {
                        plan.wavedec(&x, &mut coeffs);
                        plan.waverec(&coeffs, &mut out);
                    }
                });
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
