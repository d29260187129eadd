//! Threshold functions: `hard`, `soft`, `garrote` and `firm` with `pywt.threshold`'s semantics and
//! formulas, and the paper's `improved` function.
//!
//! The paper (Sheng, Gao & Zhang 2019) garbles its improved function; we use the form in
//! `docs/denoise.md` that has every property the paper promises (for `a >= 0`, `beta > 0`,
//! `kappa > 0`, and with `u = |w| / lambda`):
//!
//! - `|w| >= lambda`: `sgn(w) (|w| - lambda/(1+a) * exp(-beta (u - 1)))`
//! - `|w| <  lambda`: `sgn(w) a/(1+a) |w| exp(kappa (u - 1))`
//!
//! Both branches equal `a lambda / (1+a)` at `|w| = lambda` (continuous); the gap to `w` decays
//! like `exp(-beta (u - 1))` (tends to hard); small coefficients are shrunk, not zeroed, when
//! `a > 0`; `a = 0` zeroes them. `beta -> 0` tends to soft, `beta -> inf` to hard.

use super::transform::widest_vectors;
use super::WaveletError;

/// `pywt.threshold(w, lambda, 'hard')`: keeps `|w| >= lambda`, zeroes the rest.
pub fn hard(w: f64, lambda: f64) -> f64 {
    if w.abs() < lambda {
        0.0
    } else {
        w
    }
}

/// `pywt.threshold(w, lambda, 'soft')`: `w (1 - lambda/|w|)` clipped at 0 (so 0 at `|w| == lambda`).
pub fn soft(w: f64, lambda: f64) -> f64 {
    // PyWavelets' own arithmetic, so values agree to the last bit.
    let gain = 1.0 - lambda / w.abs();
    if gain > 0.0 {
        w * gain
    } else {
        0.0
    }
}

/// `pywt.threshold(w, lambda, 'garrote')`: non-negative garrote, `w (1 - lambda^2/w^2)` clipped at 0.
pub fn garrote(w: f64, lambda: f64) -> f64 {
    let gain = 1.0 - lambda * lambda / (w * w);
    if gain > 0.0 {
        w * gain
    } else {
        0.0
    }
}

/// `pywt.threshold_firm(w, low, high)`: zero up to `low`, linear to `w` at `high`, `w` above.
pub fn firm(w: f64, low: f64, high: f64) -> f64 {
    let magnitude = w.abs();
    if magnitude > high {
        return w;
    }
    let gain = high * (1.0 - low / magnitude) / (high - low);
    if gain > 0.0 {
        w * gain
    } else {
        0.0
    }
}

/// The paper's improved threshold function (see the module docs).
pub fn improved(w: f64, lambda: f64, a: f64, beta: f64, kappa: f64) -> f64 {
    if lambda <= 0.0 {
        return w;
    }
    let magnitude = w.abs();
    let u = magnitude / lambda;
    let shrunk = if magnitude >= lambda {
        magnitude - lambda / (1.0 + a) * (-beta * (u - 1.0)).exp()
    } else {
        a / (1.0 + a) * magnitude * (kappa * (u - 1.0)).exp()
    };
    shrunk.copysign(w)
}

/// e^x for x <= 0 (a positive x is taken as 0, below -746 as -746, where e^x is 0 in f64), within
/// 2 ulp of libm's `exp` (tested), subnormal results included.
///
/// Written out for [`ThresholdFn::apply_all`] because a loop over libm's `exp` cannot vectorise:
/// the batch denoiser spent 28 % of its time there, one call per coefficient. No crate offers a
/// vectorisable f64 `exp` on stable Rust that dispatches on the CPU at run time. Plain
/// multiplications and additions (Rust never fuses them), so every vector unit gives the same
/// bits. One value at a time (the streaming denoiser's [`ThresholdFn::apply`]) libm's table-based
/// `exp` is faster, and stays.
#[inline(always)]
fn exp_nonpositive(x: f64) -> f64 {
    const LOG2E: f64 = std::f64::consts::LOG2_E;
    // ln 2 split so that k * LN2_HI is exact for |k| < 2^11 (Cody and Waite).
    const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
    const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
    // Adding 1.5 * 2^52 rounds to an integer (to nearest), which then sits in the low bits.
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    // 1/n! for n = 0..=13: the Taylor series of e^r, |r| <= ln(2)/2, to 4e-18 relative.
    const C: [f64; 14] = [
        1.0,
        1.0,
        0.5,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5040.0,
        1.0 / 40320.0,
        1.0 / 362_880.0,
        1.0 / 3_628_800.0,
        1.0 / 39_916_800.0,
        1.0 / 479_001_600.0,
        1.0 / 6_227_020_800.0,
    ];
    // max and min (not clamp) take a NaN to -746: the caller's NaN coefficient stays NaN.
    #[allow(clippy::manual_clamp)]
    let x = x.max(-746.0).min(0.0);
    let t = x * LOG2E + SHIFT;
    let kf = t - SHIFT;
    let r = (x - kf * LN2_HI) - kf * LN2_LO;
    // Estrin's scheme: four dependent levels instead of Horner's thirteen.
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let q = |k: usize| C[k] + C[k + 1] * r;
    let (q0, q2, q4, q6, q8, q10, q12) = (q(0), q(2), q(4), q(6), q(8), q(10), q(12));
    let low = (q0 + q2 * r2) + (q4 + q6 * r2) * r4;
    let high = (q8 + q10 * r2) + q12 * r4;
    let p = low + high * r8;
    // 2^k = 2^-k1 * 2^-k2 with k = -(k1 + k2), each factor a normal number, so a subnormal
    // result is rounded once, at the last multiplication.
    let m = (SHIFT.to_bits() as i64 - t.to_bits() as i64) as u64; // -k, 0..=1077
    let (m1, m2) = (m >> 1, m - (m >> 1));
    let scale1 = f64::from_bits((1023 - m1) << 52);
    let scale2 = f64::from_bits((1023 - m2) << 52);
    p * scale1 * scale2
}

/// A threshold function with its shape parameters; `lambda` is supplied at each call.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ThresholdFn {
    /// Keep or kill.
    Hard,
    /// Shrink by lambda.
    Soft,
    /// Non-negative garrote.
    Garrote,
    /// Firm shrinkage between `lambda` and `ratio * lambda` (`ratio > 1`).
    Firm {
        /// Upper threshold as a multiple of lambda.
        ratio: f64,
    },
    /// The paper's improved function.
    Improved {
        /// Shrinkage kept below lambda (`a >= 0`; 0 zeroes small coefficients).
        a: f64,
        /// How fast large coefficients approach `w` (`beta > 0`; large = hard, small = soft).
        beta: f64,
        /// How fast small coefficients fade below lambda (`kappa > 0`).
        kappa: f64,
    },
}

impl ThresholdFn {
    /// Every function name, in the order `--compare` prints them.
    pub const NAMES: [&'static str; 5] = ["hard", "soft", "garrote", "firm", "improved"];

    /// Default upper threshold ratio of `firm`.
    pub const FIRM_RATIO: f64 = 2.0;
    // Defaults chosen on a grid over the synthetic benchmark (seeds 1-5, both regimes; see
    // docs/denoise.md); `tests/table2.rs` checks them on held-out seeds.
    /// Default `a` of `improved`.
    pub const IMPROVED_A: f64 = 0.5;
    /// Default `beta` of `improved`.
    pub const IMPROVED_BETA: f64 = 5.0;
    /// Default `kappa` of `improved`.
    pub const IMPROVED_KAPPA: f64 = 5.0;

    /// The improved function with its documented defaults.
    pub fn improved_default() -> Self {
        ThresholdFn::Improved {
            a: Self::IMPROVED_A,
            beta: Self::IMPROVED_BETA,
            kappa: Self::IMPROVED_KAPPA,
        }
    }

    /// The function's name.
    pub fn name(&self) -> &'static str {
        match self {
            ThresholdFn::Hard => "hard",
            ThresholdFn::Soft => "soft",
            ThresholdFn::Garrote => "garrote",
            ThresholdFn::Firm { .. } => "firm",
            ThresholdFn::Improved { .. } => "improved",
        }
    }

    /// Check the shape parameters' ranges.
    pub fn validate(&self) -> Result<(), WaveletError> {
        let bad = |m: String| Err(WaveletError::BadParameter(m));
        match *self {
            ThresholdFn::Firm { ratio } if !(ratio > 1.0 && ratio.is_finite()) => bad(format!(
                "firm ratio must be a finite number > 1, got {ratio}"
            )),
            ThresholdFn::Improved { a, beta, kappa } => {
                if !(a >= 0.0 && a.is_finite()) {
                    bad(format!("improved a must be finite and >= 0, got {a}"))
                } else if !(beta > 0.0 && beta.is_finite()) {
                    bad(format!("improved beta must be finite and > 0, got {beta}"))
                } else if !(kappa > 0.0 && kappa.is_finite()) {
                    bad(format!(
                        "improved kappa must be finite and > 0, got {kappa}"
                    ))
                } else {
                    Ok(())
                }
            }
            _ => Ok(()),
        }
    }

    /// Threshold one coefficient at `lambda`.
    #[inline]
    pub fn apply(&self, w: f64, lambda: f64) -> f64 {
        match *self {
            ThresholdFn::Hard => hard(w, lambda),
            ThresholdFn::Soft => soft(w, lambda),
            ThresholdFn::Garrote => garrote(w, lambda),
            ThresholdFn::Firm { ratio } => firm(w, lambda, ratio * lambda),
            ThresholdFn::Improved { a, beta, kappa } => improved(w, lambda, a, beta, kappa),
        }
    }

    /// Threshold every coefficient of `coeffs` in place: [`Self::apply`] to each, except that
    /// the improved function's exponential is vectorised (within 2 ulp of libm's, so the result
    /// is within 1e-15 of `apply`'s, relative to the coefficient).
    pub fn apply_all(&self, coeffs: &mut [f64], lambda: f64) {
        match *self {
            ThresholdFn::Improved { a, beta, kappa } if lambda > 0.0 => {
                improved_all(coeffs, lambda, a, beta, kappa)
            }
            _ => {
                for c in coeffs {
                    *c = self.apply(*c, lambda);
                }
            }
        }
    }
}

widest_vectors! {
    /// [`improved`] over a slice for `lambda > 0`, on the widest vector unit the CPU has, with
    /// [`exp_nonpositive`]. Without branches, so that it vectorises: both branches' exponents
    /// are <= 0 and share one exponential.
    fn improved_all(coeffs: &mut [f64], lambda: f64, a: f64, beta: f64, kappa: f64) {
        let (above_gain, below_gain) = (lambda / (1.0 + a), a / (1.0 + a));
        for c in coeffs {
            let magnitude = c.abs();
            let u = magnitude / lambda;
            let above = magnitude >= lambda;
            let e = exp_nonpositive(if above {
                -beta * (u - 1.0)
            } else {
                kappa * (u - 1.0)
            });
            let shrunk = if above {
                magnitude - above_gain * e
            } else {
                below_gain * magnitude * e
            };
            *c = shrunk.copysign(*c);
        }
    }
}

impl std::str::FromStr for ThresholdFn {
    type Err = WaveletError;
    /// A function by name, with default shape parameters.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "hard" => Ok(ThresholdFn::Hard),
            "soft" => Ok(ThresholdFn::Soft),
            "garrote" => Ok(ThresholdFn::Garrote),
            "firm" => Ok(ThresholdFn::Firm {
                ratio: Self::FIRM_RATIO,
            }),
            "improved" => Ok(Self::improved_default()),
            _ => Err(WaveletError::UnknownThreshold(s.to_string())),
        }
    }
}

impl std::fmt::Display for ThresholdFn {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Bits of a value as an ordered integer, so that the difference of two is their distance
    /// in ulps (across zero and into the subnormals too).
    fn ordered(v: f64) -> i64 {
        let b = v.to_bits() as i64;
        if b < 0 {
            i64::MIN - b
        } else {
            b
        }
    }

    #[test]
    fn exp_is_within_two_ulp_of_libm() {
        let mut worst = (0, 0.0);
        let mut check = |x: f64| {
            let d = (ordered(exp_nonpositive(x)) - ordered(x.exp())).abs();
            if d > worst.0 {
                worst = (d, x);
            }
        };
        // A dense sweep of [-746, 0], the subnormal end, the edges, and 10^6 spread values.
        for i in 0..=1_000_000 {
            check(-746.0 * f64::from(i) / 1e6);
            check(-708.0 - 38.0 * f64::from(i) / 1e6);
            check(-(f64::from(i) * 1e-6).powi(3));
        }
        for x in [
            0.0,
            -0.0,
            -1e-300,
            -5e-324,
            -0.346_573_590_279_972_6,
            -745.133_219_101_941_1,
        ] {
            check(x);
        }
        eprintln!("worst: {} ulp at x = {:e}", worst.0, worst.1);
        assert!(worst.0 <= 2, "{} ulp at x = {:e}", worst.0, worst.1);
        assert_eq!(exp_nonpositive(-746.0), 0.0);
        assert_eq!(exp_nonpositive(-1e300), 0.0);
        assert_eq!(exp_nonpositive(f64::NEG_INFINITY), 0.0);
        assert_eq!(exp_nonpositive(0.0), 1.0);
    }

    /// The vectorised slice path gives the same bits on every vector unit, NaN and infinities
    /// included, within 1e-15 (relative to the coefficient) of `apply`, which uses libm's `exp`.
    #[test]
    fn improved_all_matches_apply_on_every_vector_unit() {
        let (a, beta, kappa, lambda) = (0.3, 2.0, 4.0, 0.7);
        let f = ThresholdFn::Improved { a, beta, kappa };
        let mut w: Vec<f64> = (0..20_000)
            .map(|i| (f64::from(i) * 0.618_034).sin() * 3.0 * (f64::from(i % 7) - 3.0))
            .collect();
        w.extend([
            0.0,
            -0.0,
            lambda,
            -lambda,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ]);
        w.extend([
            5e-324,
            -1e-310,
            1e300,
            lambda * (1.0 - 1e-16),
            lambda * 1000.0,
        ]);
        let mut want = w.clone();
        improved_all::portable(&mut want, lambda, a, beta, kappa);
        let mut units: Vec<(&str, Vec<f64>)> = Vec::new();
        let mut got = w.clone();
        f.apply_all(&mut got, lambda);
        units.push(("dispatched", got));
        #[cfg(target_arch = "x86_64")]
        for (unit, has) in [
            ("avx512f", std::is_x86_feature_detected!("avx512f")),
            ("avx2", std::is_x86_feature_detected!("avx2")),
        ] {
            if !has {
                eprintln!("this CPU has no {unit}: its kernel is not checked here");
                continue;
            }
            let mut got = w.clone();
            // SAFETY: the CPU has the unit (checked above).
            unsafe {
                if unit == "avx2" {
                    improved_all::avx2(&mut got, lambda, a, beta, kappa);
                } else {
                    improved_all::avx512(&mut got, lambda, a, beta, kappa);
                }
            }
            units.push((unit, got));
        }
        for (unit, got) in &units {
            for (i, (g, e)) in got.iter().zip(&want).enumerate() {
                assert_eq!(
                    g.to_bits(),
                    e.to_bits(),
                    "{unit}: w = {:e}: {g:e} vs {e:e}",
                    w[i]
                );
            }
        }
        for (&v, &g) in w.iter().zip(&want) {
            let one = f.apply(v, lambda);
            let close = g.to_bits() == one.to_bits() || (g - one).abs() <= 1e-15 * v.abs();
            assert!(close, "w = {v:e}: {g:e} vs apply's {one:e}");
        }
    }

    #[test]
    fn pywt_edge_semantics() {
        // pywt: hard keeps |w| == lambda, soft/garrote give 0 there; firm is linear in between.
        assert_eq!(hard(2.0, 2.0), 2.0);
        assert_eq!(hard(-1.999, 2.0), 0.0);
        assert_eq!(soft(2.0, 2.0), 0.0);
        assert_eq!(soft(-3.0, 2.0), -1.0);
        assert_eq!(garrote(2.0, 2.0), 0.0);
        assert_eq!(garrote(4.0, 2.0), 3.0);
        assert_eq!(firm(1.0, 1.0, 3.0), 0.0);
        assert_eq!(firm(2.0, 1.0, 3.0), 1.5);
        assert_eq!(firm(-3.5, 1.0, 3.0), -3.5);
        assert_eq!(soft(0.0, 1.0), 0.0);
        assert_eq!(garrote(0.0, 1.0), 0.0);
        assert_eq!(firm(0.0, 1.0, 2.0), 0.0);
    }

    #[test]
    fn pywt_reference_values() {
        // pywt 1.9.0: pywt.threshold(np.array([-3.7, -1.2, 0.4, 2.5, 5.0]), 1.5, mode) and
        // pywt.threshold_firm(same, 1.5, 3.0), printed with repr().
        let w = [-3.7, -1.2, 0.4, 2.5, 5.0];
        let soft_ref = [-2.2, 0.0, 0.0, 1.0, 3.5];
        let garrote_ref = [-3.091891891891892, 0.0, 0.0, 1.6, 4.55];
        let firm_ref = [-3.7, 0.0, 0.0, 2.0000000000000004, 5.0];
        for i in 0..w.len() {
            assert_eq!(soft(w[i], 1.5), soft_ref[i], "soft {}", w[i]);
            assert_eq!(garrote(w[i], 1.5), garrote_ref[i], "garrote {}", w[i]);
            assert_eq!(firm(w[i], 1.5, 3.0), firm_ref[i], "firm {}", w[i]);
        }
    }

    #[test]
    fn improved_zero_below_threshold_at_a_zero() {
        for w in [0.1, 0.5, 0.999, -0.7] {
            assert_eq!(improved(w, 1.0, 0.0, 1.0, 2.0), 0.0);
        }
    }

    #[test]
    fn improved_keeps_sign_and_nonzero_below_threshold_with_a() {
        let v = improved(-0.5, 1.0, 0.5, 1.0, 2.0);
        assert!(v < 0.0 && v > -0.5, "{v}");
    }

    #[test]
    fn improved_limits_in_beta() {
        // beta -> 0: soft; beta -> inf: hard (above lambda, a = 0).
        assert!((improved(3.0, 1.0, 0.0, 1e-12, 2.0) - soft(3.0, 1.0)).abs() < 1e-9);
        assert!((improved(3.0, 1.0, 0.0, 1e6, 2.0) - hard(3.0, 1.0)).abs() < 1e-9);
    }

    #[test]
    fn names_round_trip_and_errors_list_choices() {
        for n in ThresholdFn::NAMES {
            assert_eq!(n.parse::<ThresholdFn>().unwrap().name(), n);
        }
        let e = "medium".parse::<ThresholdFn>().unwrap_err().to_string();
        assert!(e.contains("hard, soft, garrote, firm, improved"), "{e}");
        assert!(ThresholdFn::Firm { ratio: 1.0 }.validate().is_err());
        assert!(ThresholdFn::Improved {
            a: -1.0,
            beta: 1.0,
            kappa: 1.0
        }
        .validate()
        .is_err());
        assert!(ThresholdFn::improved_default().validate().is_ok());
    }

    proptest! {
        #[test]
        fn improved_is_continuous_at_lambda(
            lambda in 1e-6f64..1e6, a in 0.0f64..10.0, beta in 1e-3f64..50.0, kappa in 1e-3f64..50.0
        ) {
            let below = improved(lambda * (1.0 - 1e-12), lambda, a, beta, kappa);
            let at = improved(lambda, lambda, a, beta, kappa);
            let expected = a * lambda / (1.0 + a);
            prop_assert!((at - expected).abs() <= 1e-12 * lambda);
            prop_assert!((below - at).abs() <= 1e-9 * lambda);
        }

        #[test]
        fn improved_tends_to_hard_for_large_coefficients(
            lambda in 1e-6f64..1e6, a in 0.0f64..10.0, beta in 0.5f64..50.0, kappa in 1e-3f64..50.0,
            sign in prop::bool::ANY
        ) {
            let w = if sign { 40.0 * lambda } else { -40.0 * lambda };
            let gap = (improved(w, lambda, a, beta, kappa) - w).abs();
            // The gap is lambda/(1+a) exp(-beta (u - 1)): below 1e-8 lambda at u = 40, beta >= 0.5.
            prop_assert!(gap <= 1e-8 * lambda, "gap {}", gap);
        }

        #[test]
        fn improved_shrinks_and_is_odd_and_monotone(
            w in -1e3f64..1e3, lambda in 1e-3f64..1e2, a in 0.0f64..10.0, beta in 1e-3f64..50.0,
            kappa in 1e-3f64..50.0
        ) {
            let v = improved(w, lambda, a, beta, kappa);
            prop_assert!(v.abs() <= w.abs());
            prop_assert_eq!(improved(-w, lambda, a, beta, kappa), -v);
            let v2 = improved(w.abs() * 1.01 + 1e-9, lambda, a, beta, kappa);
            prop_assert!(v2 >= v.abs() - 1e-12 * lambda.max(w.abs()));
        }
    }
}
