//! Property tests: perfect reconstruction, and the plan equal to the free functions.
//!
//! Perfect reconstruction is measured as max |x - waverec(wavedec(x))| over the data's scale,
//! max(max |x|, max |coefficient|) (smooth mode extrapolates, so edge coefficients can dwarf x).
//! It holds to 1e-12 for haar, db and coif. PyWavelets' sym filters (which ours equal bit for bit)
//! are themselves orthonormal only to ~1.5e-11 (see `families.rs`), so neither PyWavelets nor
//! this crate can reconstruct sym signals better than ~1e-10; that is their bound here.

use driftless::wavelet::transform::{self, dwt_max_level, Mode, Plan};
use driftless::wavelet::Wavelet;
use proptest::prelude::*;

fn tolerance(w: &Wavelet) -> f64 {
    if w.name().starts_with("sym") {
        1e-10
    } else {
        1e-12
    }
}

fn signal(seed: u64, n: usize) -> Vec<f64> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 * 2f64.powi(-53) - 0.5) * 4.0
        })
        .collect()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

fn rel_err(x: &[f64], rec: &[f64], scale: f64) -> f64 {
    x.iter()
        .zip(rec)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
        / scale
}

fn any_wavelet() -> impl Strategy<Value = Wavelet> {
    let names: Vec<&'static str> = Wavelet::names().collect();
    prop::sample::select(names).prop_map(|n| Wavelet::by_name(n).expect("listed name"))
}

fn any_mode() -> impl Strategy<Value = Mode> {
    prop::sample::select(Mode::ALL.to_vec())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn multilevel_reconstruction_is_perfect(
        w in any_wavelet(),
        mode in any_mode(),
        n in 1usize..6000,
        seed in any::<u64>(),
        depth in 0.0f64..1.0,
    ) {
        let top = dwt_max_level(n, w.filter_len());
        prop_assume!(top >= 1);
        let level = 1 + ((top - 1) as f64 * depth).round() as usize;
        let x = signal(seed, n);
        let c = transform::wavedec(&x, &w, mode, level).expect("level within max");
        let rec = transform::waverec(&c, &w, mode).expect("own coefficients");
        prop_assert!(rec.len() == n || rec.len() == n + 1);
        let scale = c.iter().map(|b| max_abs(b)).fold(max_abs(&x), f64::max);
        let err = rel_err(&x, &rec, scale);
        prop_assert!(err <= tolerance(&w), "{} {mode} n={n} level={level}: {err:e}", w.name());

        // The plan gives bit-identical results.
        let mut plan = Plan::new(&w, mode, n, level).expect("same parameters");
        let mut flat = vec![0.0; plan.coeffs_len()];
        plan.wavedec(&x, &mut flat);
        let planned: Vec<Vec<f64>> =
            plan.ranges().iter().map(|r| flat[r.clone()].to_vec()).collect();
        prop_assert_eq!(&planned, &c);
        let mut out = vec![0.0; n];
        plan.waverec(&flat, &mut out);
        prop_assert_eq!(&out[..], &rec[..n]);
    }

    #[test]
    fn single_level_reconstruction_is_perfect_for_any_length(
        w in any_wavelet(),
        mode in any_mode(),
        n in 1usize..200,
        seed in any::<u64>(),
    ) {
        let x = signal(seed, n);
        let (a, d) = transform::dwt(&x, &w, mode);
        let rec = transform::idwt(&a, &d, &w, mode);
        prop_assert!(rec.len() == n || rec.len() == n + 1, "len {} for n={n}", rec.len());
        let scale = max_abs(&x).max(max_abs(&a)).max(max_abs(&d));
        let err = rel_err(&x, &rec, scale);
        prop_assert!(err <= tolerance(&w), "{} {mode} n={n}: {err:e}", w.name());
    }
}
