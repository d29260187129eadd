//! Lengths, levels and error cases of the transform API.

use driftless::wavelet::transform::{
    self, dwt_coeff_len, dwt_max_level, idwt_len, min_len_for_level, Mode, Plan,
};
use driftless::wavelet::{Wavelet, WaveletError};

fn wavelet(name: &str) -> Wavelet {
    Wavelet::by_name(name).expect("known wavelet")
}

fn ramp(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| ((i * 37 % 101) as f64 - 50.0) / 7.0)
        .collect()
}

#[test]
fn coefficient_lengths_follow_pywavelets() {
    assert_eq!(dwt_coeff_len(18000, 12, Mode::Symmetric), 9005);
    assert_eq!(dwt_coeff_len(1, 40, Mode::Zero), 20);
    assert_eq!(dwt_coeff_len(7, 4, Mode::Reflect), 5);
    assert_eq!(dwt_coeff_len(7, 4, Mode::Periodization), 4);
    assert_eq!(dwt_coeff_len(8, 4, Mode::Periodization), 4);
    assert_eq!(dwt_coeff_len(0, 4, Mode::Symmetric), 0);
    assert_eq!(idwt_len(9005, 12, Mode::Symmetric), 18000);
    assert_eq!(idwt_len(4, 4, Mode::Periodization), 8);
    assert_eq!(idwt_len(20, 40, Mode::Zero), 2);
    // Fewer than F / 2 coefficients determine no sample (PyWavelets raises there).
    assert_eq!(idwt_len(19, 40, Mode::Zero), 0);
    assert_eq!(idwt_len(3, 40, Mode::Zero), 0);
    let w = wavelet("db20");
    assert!(transform::idwt(&[1.0; 3], &[1.0; 3], &w, Mode::Zero).is_empty());
}

#[test]
fn max_level_is_floor_log2_of_n_over_f_minus_1() {
    assert_eq!(dwt_max_level(18000, 12), 10);
    assert_eq!(dwt_max_level(1, 2), 0);
    assert_eq!(dwt_max_level(2, 2), 1);
    assert_eq!(dwt_max_level(20000, 2), 14);
    assert_eq!(dwt_max_level(38, 40), 0);
    assert_eq!(dwt_max_level(39, 40), 0);
    assert_eq!(dwt_max_level(78, 40), 1);
    assert_eq!(dwt_max_level(0, 12), 0);
    for f in [2, 4, 12, 40, 102] {
        for level in 1..12 {
            let needed = min_len_for_level(f, level);
            assert_eq!(needed, (f - 1) << level);
            assert_eq!(dwt_max_level(needed, f), level, "F={f} level={level}");
            assert_eq!(
                dwt_max_level(needed - 1, f),
                level - 1,
                "F={f} level={level}"
            );
        }
    }
    assert_eq!(min_len_for_level(12, 200), usize::MAX);
}

#[test]
fn db6_symmetric_18000_level_5_has_the_issues_lengths() {
    let w = wavelet("db6");
    let x = ramp(18000);
    let c = transform::wavedec(&x, &w, Mode::Symmetric, 5).expect("level 5 fits");
    let lens: Vec<usize> = c.iter().map(Vec::len).collect();
    assert_eq!(lens, [573, 573, 1135, 2259, 4508, 9005]);
    let plan = Plan::new(&w, Mode::Symmetric, 18000, 5).expect("level 5 fits");
    let plan_lens: Vec<usize> = plan.ranges().iter().map(|r| r.len()).collect();
    assert_eq!(plan_lens, lens);
    assert_eq!(plan.coeffs_len(), lens.iter().sum::<usize>());
    assert_eq!((plan.signal_len(), plan.level()), (18000, 5));
    assert_eq!(plan.ranges()[0].start, 0);
}

#[test]
fn level_zero_is_a_bad_parameter() {
    let w = wavelet("db4");
    let x = ramp(100);
    assert!(matches!(
        transform::wavedec(&x, &w, Mode::Symmetric, 0),
        Err(WaveletError::BadParameter(_))
    ));
    assert!(matches!(
        Plan::new(&w, Mode::Symmetric, 100, 0),
        Err(WaveletError::BadParameter(_))
    ));
}

#[test]
fn too_deep_a_level_says_how_many_samples_it_needs() {
    let w = wavelet("db6");
    let x = ramp(18000);
    let err = transform::wavedec(&x, &w, Mode::Symmetric, 11).unwrap_err();
    assert_eq!(
        err,
        WaveletError::TooShort {
            level: 11,
            wavelet: "db6".into(),
            needed: 11 * 2048,
            got: 18000
        }
    );
    assert!(err.to_string().contains("22528"), "{err}");
    // Shorter than one level needs: (F - 1) * 2 samples.
    let err = Plan::new(&wavelet("coif17"), Mode::Zero, 150, 1).unwrap_err();
    assert!(
        matches!(
            err,
            WaveletError::TooShort {
                needed: 202,
                got: 150,
                ..
            }
        ),
        "{err:?}"
    );
    assert!(transform::wavedec(&[], &w, Mode::Zero, 1).is_err());
}

#[test]
fn waverec_rejects_inconsistent_coefficients() {
    let w = wavelet("db2");
    let m = Mode::Symmetric;
    assert!(matches!(
        transform::waverec(&[], &w, m),
        Err(WaveletError::BadParameter(_))
    ));
    let bad = vec![vec![1.0; 10], vec![1.0; 7]];
    assert!(matches!(
        transform::waverec(&bad, &w, m),
        Err(WaveletError::BadParameter(_))
    ));
    // Below F / 2 coefficients PyWavelets refuses to reconstruct, and so do we.
    let short = vec![vec![1.0; 2], vec![1.0; 2]];
    assert!(transform::waverec(&short, &wavelet("db4"), m).is_err());
    assert!(transform::waverec(&short, &wavelet("db4"), Mode::Periodization).is_ok());
    // A single band is returned unchanged, as in PyWavelets.
    assert_eq!(
        transform::waverec(&[vec![1.0, 2.0]], &w, m),
        Ok(vec![1.0, 2.0])
    );
}

#[test]
fn waverec_is_one_longer_for_odd_lengths_and_trims_like_pywavelets() {
    let w = wavelet("sym5");
    for n in [101, 1001] {
        let x = ramp(n);
        let c = transform::wavedec(&x, &w, Mode::Symmetric, 3).expect("fits");
        let r = transform::waverec(&c, &w, Mode::Symmetric).expect("consistent");
        assert_eq!(r.len(), n + 1);
        let err = r[..n]
            .iter()
            .zip(&x)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(err < 1e-9, "n={n}: {err}");
    }
    // An approximation one longer than the detail is trimmed, not refused.
    let x = ramp(64);
    let (a, d) = transform::dwt(&x, &w, Mode::Zero);
    let mut longer = a.clone();
    longer.push(123.0);
    let trimmed = transform::waverec(&[longer, d.clone()], &w, Mode::Zero).expect("trimmed");
    assert_eq!(trimmed, transform::idwt(&a, &d, &w, Mode::Zero));
}

#[test]
fn reflect_of_one_sample_is_constant_where_pywavelets_refuses() {
    for name in ["haar", "db4", "coif5"] {
        let w = wavelet(name);
        let r = transform::dwt(&[0.75], &w, Mode::Reflect);
        let c = transform::dwt(&[0.75], &w, Mode::Constant);
        assert_eq!(r, c, "{name}");
        assert_eq!(r.0.len(), w.filter_len() / 2);
    }
}

#[test]
fn into_variants_equal_the_allocating_ones() {
    let w = wavelet("coif3");
    let x = ramp(333);
    for mode in Mode::ALL {
        let (a, d) = transform::dwt(&x, &w, mode);
        let nc = dwt_coeff_len(x.len(), w.filter_len(), mode);
        let (mut a2, mut d2) = (vec![0.0; nc], vec![0.0; nc]);
        transform::dwt_into(&x, &w, mode, &mut a2, &mut d2);
        assert_eq!((a2, d2), (a.clone(), d.clone()), "{mode}");
        let mut r = vec![0.0; idwt_len(nc, w.filter_len(), mode)];
        transform::idwt_into(&a, &d, &w, mode, &mut r);
        assert_eq!(r, transform::idwt(&a, &d, &w, mode), "{mode}");
    }
}

#[test]
#[should_panic(expected = "equal lengths")]
fn idwt_of_unequal_bands_panics() {
    let w = wavelet("db2");
    let _ = transform::idwt(&[1.0; 4], &[1.0; 3], &w, Mode::Symmetric);
}

#[test]
fn modes_parse_and_print_pywavelets_names() {
    for mode in Mode::ALL {
        assert_eq!(mode.name().parse::<Mode>(), Ok(mode));
        assert_eq!(mode.to_string(), mode.name());
    }
    assert!(matches!(
        "antireflect".parse::<Mode>(),
        Err(WaveletError::UnknownMode(_))
    ));
    assert_eq!(Mode::default(), Mode::Symmetric);
}
