//! Equivalent degrees of freedom (EDF) of Allan-type variances: Greenhall & Riley's algorithm
//! ("Uncertainty of stability variances based on finite differences", PTTI 2003; C. Greenhall,
//! W. Riley 2004), exactly as allantools 2024.06 implements it in `ci.edf_greenhall`.
//!
//! It needs the power-law noise type alpha (S_y(f) ~ f^alpha) at each averaging factor; the
//! deviation module identifies it from the local slope of the deviation curve where the record
//! holds enough tau-spans for that ([`MIN_SPANS`]), and otherwise takes the plausible alpha with the
//! fewest degrees of freedom ([`widest_alpha`]).
//!
//! **Bounds.** An Allan-type variance estimate is a quadratic form in Gaussian data,
//! V = (1/n) sum_i Z_i^2 over its n terms (second or third differences). With lambda_k the
//! eigenvalues of the form (on the data's covariance), E V ~ sum lambda_k and
//! Var V ~ 2 sum lambda_k^2, so Greenhall & Riley's EDF = 2 (E V)^2 / Var V =
//! (sum lambda_k)^2 / sum lambda_k^2 lies between 1 and the number of non-zero eigenvalues
//! (Cauchy-Schwarz), which is at most the rank of the form, at most n. So 1 <= EDF <= n for any
//! noise: [`edf_bounds`]. Greenhall's exact sums obey it by construction (their M is n and their
//! basic sum is at least its first term); the clamp in the deviation module is a guard.
//!
//! A bound by the number of non-overlapping tau-spans T/tau (the non-overlapped ADEV has exactly
//! spans - 1 terms) does *not* hold for the overlapping estimators: their extra terms carry real
//! information. OADEV's EDF is about 1.5 x spans for white rate noise and about n/2 for white
//! phase noise at any tau (NIST SP1065 Table 5: (N+1)(N-2m) / (2(N-m))). What protects the long-tau
//! end is the noise type: see [`widest_alpha`].

/// Power-law noise exponent alpha of the rate ("frequency") PSD from the log-log slope `mu` of the
/// Allan *variance* (mu = -alpha - 1 for -3 < alpha < 1): white phase (quantisation) 2, white rate
/// (angle random walk) 0, flicker rate (bias instability) -1, random-walk rate -2. Flicker phase
/// (alpha = 1) shares white phase's slope and is never chosen. Limits: -2 for Allan-type
/// variances, -4 for Hadamard (`d` = 3).
pub fn alpha_from_slope(mu: f64, d: u32) -> i32 {
    if mu < -1.5 {
        return 2;
    }
    let alpha = (-mu - 1.0).round() as i32;
    let floor = if d >= 3 { -4 } else { -2 };
    alpha.clamp(floor, 0)
}

fn sw(t: f64, alpha: i32) -> f64 {
    match alpha {
        2 => -t.abs(),
        1 if t == 0.0 => 0.0,
        1 => t * t * t.abs().ln(),
        0 => t.powi(3).abs(),
        -1 if t == 0.0 => 0.0,
        -1 => t.powi(4) * t.abs().ln(),
        -2 => t.powi(5).abs(),
        -3 if t == 0.0 => 0.0,
        -3 => t.powi(6) * t.abs().ln(),
        _ => t.powi(7).abs(),
    }
}

fn sx(t: f64, f: f64, alpha: i32) -> f64 {
    if f.is_infinite() {
        return sw(t, alpha + 2);
    }
    f * f * (2.0 * sw(t, alpha) - sw(t - 1.0 / f, alpha) - sw(t + 1.0 / f, alpha))
}

fn sz(t: f64, f: f64, alpha: i32, d: u32) -> f64 {
    let s = |dt: f64| sx(t + dt, f, alpha);
    match d {
        1 => 2.0 * s(0.0) - s(-1.0) - s(1.0),
        2 => 6.0 * s(0.0) - 4.0 * s(-1.0) - 4.0 * s(1.0) + s(-2.0) + s(2.0),
        _ => {
            20.0 * s(0.0) - 15.0 * s(-1.0) - 15.0 * s(1.0) + 6.0 * s(-2.0) + 6.0 * s(2.0)
                - s(-3.0)
                - s(3.0)
        }
    }
}

fn basic_sum(j: f64, m: f64, s: f64, f: f64, alpha: i32, d: u32) -> f64 {
    let first = sz(0.0, f, alpha, d).powi(2);
    let second = (1.0 - j / m) * sz(j / s, f, alpha, d).powi(2);
    let mut third = 0.0;
    let mut k = 1.0;
    while k < j {
        third += 2.0 * (1.0 - k / m) * sz(k / s, f, alpha, d).powi(2);
        k += 1.0;
    }
    first + second + third
}

fn table1(alpha: i32, d: u32) -> (f64, f64) {
    const T: [[(f64, f64); 3]; 7] = [
        [
            (2.0 / 3.0, 1.0 / 3.0),
            (7.0 / 9.0, 1.0 / 2.0),
            (22.0 / 25.0, 2.0 / 3.0),
        ],
        [(0.840, 0.345), (0.997, 0.616), (1.141, 0.843)],
        [(1.079, 0.368), (1.033, 0.607), (1.184, 0.848)],
        [(-1.0, -1.0), (1.048, 0.534), (1.180, 0.816)],
        [(-1.0, -1.0), (1.302, 0.535), (1.175, 0.777)],
        [(-1.0, -1.0), (-1.0, -1.0), (1.194, 0.703)],
        [(-1.0, -1.0), (-1.0, -1.0), (1.489, 0.702)],
    ];
    T[(2 - alpha) as usize][(d - 1) as usize]
}

fn table2(alpha: i32, d: u32) -> (f64, f64) {
    const T: [[(f64, f64); 3]; 7] = [
        [
            (3.0 / 2.0, 1.0 / 2.0),
            (35.0 / 18.0, 1.0),
            (231.0 / 100.0, 3.0 / 2.0),
        ],
        [(78.6, 25.2), (790.0, 410.0), (9950.0, 6520.0)],
        [
            (2.0 / 3.0, 1.0 / 6.0),
            (2.0 / 3.0, 1.0 / 3.0),
            (7.0 / 9.0, 1.0 / 2.0),
        ],
        [(-1.0, -1.0), (0.852, 0.375), (0.997, 0.617)],
        [(-1.0, -1.0), (1.079, 0.368), (1.033, 0.607)],
        [(-1.0, -1.0), (-1.0, -1.0), (1.053, 0.553)],
        [(-1.0, -1.0), (-1.0, -1.0), (1.302, 0.535)],
    ];
    T[(2 - alpha) as usize][(d - 1) as usize]
}

fn table3(d: u32) -> (f64, f64) {
    [(6.0, 4.0), (15.23, 12.0), (47.8, 40.0)][(d - 1) as usize]
}

fn binom(n: u32, k: u32) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * f64::from(n - i) / f64::from(i + 1))
}

/// Greenhall's EDF for a variance of difference order `d` (1 first difference, 2 Allan, 3
/// Hadamard) at averaging factor `m`, from `n` phase samples, for noise exponent `alpha`
/// (-4..=2, with alpha + 2d > 1); `overlapping` for OADEV/OHDEV/MDEV, `modified` for MDEV.
///
/// allantools raises `NotImplementedError` for white phase noise with a non-modified variance
/// when ceil(M/S) <= d (only at the very last taus); this uses the exact sum there (see
/// `white_phase_inv_edf` in the source).
pub fn edf_greenhall(
    alpha: i32,
    d: u32,
    m: usize,
    n: usize,
    overlapping: bool,
    modified: bool,
) -> f64 {
    let alpha = alpha.clamp(-4, 2);
    let mf = m as f64;
    let f = if modified { 1.0 } else { mf };
    let s = if overlapping { mf } else { 1.0 };
    let df = f64::from(d);
    let l = mf / f + mf * df;
    let big_m = 1.0 + (s * (n as f64 - l) / mf).floor();
    let j = big_m.min((df + 1.0) * s);
    let j_max = 100.0;
    let r = big_m / s;
    let inv = if modified {
        if j <= j_max {
            basic_sum(j, big_m, s, 1.0, alpha, d) / (sz(0.0, 1.0, alpha, d).powi(2) * big_m)
        } else if r > df + 1.0 {
            let (a0, a1) = table1(alpha, d);
            (a0 - a1 / r) / r
        } else {
            let mp = j_max / r;
            basic_sum(j_max, j_max, mp, 1.0, alpha, d) / (sz(0.0, f, alpha, d).powi(2) * j_max)
        }
    } else if alpha <= 0 {
        if j <= j_max {
            let mp = if mf * (df + 1.0) <= j_max {
                mf
            } else {
                f64::INFINITY
            };
            basic_sum(j, big_m, s, mp, alpha, d) / (sz(0.0, mp, alpha, d).powi(2) * big_m)
        } else if r > df + 1.0 {
            let (a0, a1) = table2(alpha, d);
            (a0 - a1 / r) / r
        } else {
            let mp = j_max / r;
            basic_sum(j_max, j_max, mp, f64::INFINITY, alpha, d)
                / (sz(0.0, f64::INFINITY, alpha, d).powi(2) * j_max)
        }
    } else if alpha == 1 {
        if j <= j_max {
            basic_sum(j, big_m, s, mf, 1, d) / (sz(0.0, mf, 1, d).powi(2) * big_m)
        } else if r > df + 1.0 {
            let (a0, a1) = table2(alpha, d);
            let (b0, b1) = table3(d);
            (a0 - a1 / r) / ((b0 + b1 * mf.ln()).powi(2) * r)
        } else {
            let mp = j_max / r;
            let (b0, b1) = table3(d);
            basic_sum(j_max, j_max, mp, mp, 1, d) / ((b0 + b1 * mf.ln()).powi(2) * j_max)
        }
    } else if r.ceil() > df {
        let a0 = binom(4 * d, 2 * d) / binom(2 * d, d).powi(2);
        let a1 = df / 2.0;
        (a0 - a1 / r) / big_m
    } else {
        white_phase_inv_edf(d, big_m, s)
    };
    1.0 / inv
}

/// 1 / EDF for white phase noise (alpha = 2) and a non-modified variance, exactly. The phase
/// samples are independent, so term i and term j are correlated only when their filters overlap:
/// at a lag of k filter steps (k = 1..d, S terms per step) the covariance is (-1)^k C(2d, d+k)
/// times the variance of one phase sample, and
/// 1 / EDF = sum_{|k| <= d} C(2d, d+k)^2 (M - |k| S)_+ / (C(2d, d)^2 M^2).
/// For M > d S this is Greenhall's case-4 formula (a0 - a1 / r) / M, a0 = C(4d, 2d) / C(2d, d)^2,
/// a1 = d / 2; allantools raises `NotImplementedError` for ceil(M / S) <= d, the last taus, where
/// the large-r formula goes negative.
fn white_phase_inv_edf(d: u32, big_m: f64, s: f64) -> f64 {
    let c0 = binom(2 * d, d);
    let mut sum = 0.0;
    for k in 0..=d {
        let weight = if k == 0 { 1.0 } else { 2.0 };
        let pairs = (big_m - f64::from(k) * s).max(0.0);
        sum += weight * binom(2 * d, d + k).powi(2) * pairs;
    }
    sum / (c0 * c0 * big_m * big_m)
}

/// The hard bounds on the EDF of a variance estimate with `terms` terms (see the module notes): at
/// least 1, at most `terms`, whatever the noise.
pub fn edf_bounds(terms: usize) -> (f64, f64) {
    (1.0, (terms as f64).max(1.0))
}

/// Fewest non-overlapping tau-spans at every averaging factor the noise identification looks at
/// for it to count as identified: the length below which allantools 2024.6's `autocorr_noise_id`
/// refuses (it decimates to one value per tau-span and raises `NotImplementedError` below 30). For
/// our slope identification it is the span count at the far neighbour (about 2 tau): there the
/// variance has an EDF of about 30 (21 to 45 for alpha -2 to 0 in OADEV), so the log of the
/// variance ratio over the factor 4 in tau has a standard deviation of about sqrt(2/30 + 2/120),
/// the slope about 0.21, and the rounding to an integer alpha (0.5 away) is wrong in about 2% of
/// records. At half as many spans it would be wrong in about 10%.
pub const MIN_SPANS: usize = 30;

/// Non-overlapping tau-spans of averaging factor `m` in a record of `phase_len` phase points: the
/// number of independent averages of m rate samples, floor((phase_len - 1) / m).
pub fn tau_spans(phase_len: usize, m: usize) -> usize {
    phase_len.saturating_sub(1) / m.max(1)
}

/// The most negative alpha of difference order `d` (Greenhall needs alpha + 2d > 1; the slope
/// identification stops at -2 for Allan-type, -4 for Hadamard variances).
pub fn alpha_floor(d: u32) -> i32 {
    if d >= 3 {
        -4
    } else {
        -2
    }
}

/// Of the noise types `lo..=hi`, the one whose EDF (arguments as [`edf_greenhall`]) is smallest,
/// i.e. whose interval is widest, with that EDF.
///
/// Used where the record holds too few tau-spans to identify the noise ([`MIN_SPANS`]). The
/// plausible types there run from the floor of the variance ([`alpha_floor`]) up to the last alpha
/// identified at a shorter tau: in a sum of independent power-law noises the log-log variance
/// curve is a log-sum-exp of straight lines, hence convex, so its slope can only rise with tau and
/// alpha can only fall. (So a white-phase type, alpha 2, is never plausible past a white- or
/// flicker-rate region.) Taking the smallest EDF over them keeps the interval at least as wide as
/// the true type's, whichever it is. For OADEV, MDEV and HDEV that is the reddest type, whatever
/// the upper end; for the non-overlapped ADEV it is mostly the bluest (its EDF mostly rises as the
/// noise reddens), so there the upper end matters. A band-limited term (a single Gauss-Markov
/// bias, a sine) bends the curve down again and breaks the convexity; the ADEV point then keeps
/// at most its number of terms ([`edf_bounds`]), which past [`MIN_SPANS`] is under 30.
pub fn widest_alpha(
    lo: i32,
    hi: i32,
    d: u32,
    m: usize,
    n: usize,
    overlapping: bool,
    modified: bool,
) -> (i32, f64) {
    let lo = lo.max(alpha_floor(d));
    let hi = hi.clamp(lo, 2);
    let mut best = (hi, f64::INFINITY);
    for alpha in lo..=hi {
        let e = edf_greenhall(alpha, d, m, n, overlapping, modified);
        if e.is_finite() && e > 0.0 && e < best.1 {
            best = (alpha, e);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The EDF of a variance of difference order `d` at averaging factor `m` over `n` independent
    /// unit-variance phase samples (white phase noise), by brute force: the terms' covariance
    /// matrix C, EDF = (tr C)^2 / tr(C^2).
    fn brute_white_phase_edf(d: u32, m: usize, n: usize, overlapping: bool) -> f64 {
        let step = if overlapping { 1 } else { m };
        let starts: Vec<usize> = (0..)
            .map(|i| i * step)
            .take_while(|&s| s + d as usize * m < n)
            .collect();
        let weights: Vec<f64> = (0..=d)
            .map(|k| binom(d, k) * if k % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let term = |s: usize| {
            let mut z = vec![0.0; n];
            for (k, w) in weights.iter().enumerate() {
                z[s + k * m] += w;
            }
            z
        };
        let terms: Vec<Vec<f64>> = starts.iter().map(|&s| term(s)).collect();
        let (mut tr, mut tr2) = (0.0, 0.0);
        for a in &terms {
            tr += a.iter().map(|v| v * v).sum::<f64>();
            for b in &terms {
                let c: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
                tr2 += c * c;
            }
        }
        tr * tr / tr2
    }

    #[test]
    fn white_phase_edf_is_exact_at_every_tau() {
        // Greenhall's case 4 (M > d S) and the exact sum beyond it, where allantools raises.
        for d in [2, 3] {
            for overlapping in [true, false] {
                let n = 41;
                for m in 1..=(n - 1) / d as usize {
                    let want = brute_white_phase_edf(d, m, n, overlapping);
                    let got = edf_greenhall(2, d, m, n, overlapping, false);
                    assert!(
                        ((got - want) / want).abs() < 1e-12,
                        "d {d} m {m} ov {overlapping}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn white_phase_sum_equals_case_4_where_both_apply() {
        for d in [1, 2, 3] {
            let a0 = binom(4 * d, 2 * d) / binom(2 * d, d).powi(2);
            let a1 = f64::from(d) / 2.0;
            for (big_m, s) in [(7.0, 1.0), (100.0, 3.0), (1e6, 4096.0), (31.0, 10.0)] {
                let r: f64 = big_m / s;
                assert!(r > f64::from(d), "case 4 needs M > d S");
                let case4 = (a0 - a1 / r) / big_m;
                let exact = white_phase_inv_edf(d, big_m, s);
                assert!(
                    ((exact - case4) / case4).abs() < 1e-12,
                    "d {d} M {big_m} S {s}: {exact} vs {case4}"
                );
            }
        }
    }

    #[test]
    fn bounds_and_spans() {
        assert_eq!(edf_bounds(1000), (1.0, 1000.0));
        assert_eq!(edf_bounds(0), (1.0, 1.0));
        assert_eq!(tau_spans(101, 10), 10);
        assert_eq!(tau_spans(100, 10), 9);
        assert_eq!(tau_spans(0, 10), 0);
        assert_eq!(tau_spans(10, 0), 9);
        // The exact white-phase EDF never exceeds the number of terms, however short the record.
        for m in 1..20 {
            let n = 41;
            let terms = n - 2 * m;
            let e = edf_greenhall(2, 2, m, n, true, false);
            let (lo, hi) = edf_bounds(terms);
            assert!(e >= lo && e <= hi, "m {m}: {e} outside [{lo}, {hi}]");
        }
    }

    #[test]
    fn widest_alpha_takes_the_fewest_degrees_of_freedom() {
        for (d, ov, md) in [
            (2, true, false),
            (2, false, false),
            (2, true, true),
            (3, true, false),
        ] {
            for (m, n) in [
                (64, 10_001),
                (2048, 10_001),
                (131_072, 540_001),
                (262_144, 540_001),
            ] {
                let needed = if md { 3 * m } else { d as usize * m + 1 };
                if needed > n {
                    continue; // no term at this m
                }
                let lo = alpha_floor(d);
                let (alpha, e) = widest_alpha(lo, 2, d, m, n, ov, md);
                assert!((lo..=2).contains(&alpha));
                for other in lo..=2 {
                    let e2 = edf_greenhall(other, d, m, n, ov, md);
                    assert!(
                        e <= e2,
                        "d {d} ov {ov} m {m}: alpha {alpha} {e} > {other} {e2}"
                    );
                }
                // A narrower range can only give as many or more degrees of freedom.
                let (_, e_narrow) = widest_alpha(lo + 1, 0, d, m, n, ov, md);
                assert!(e <= e_narrow);
            }
        }
        // At the long-tau end random-walk rate is the widest for the overlapped variances, the
        // bluest type for the non-overlapped ADEV (its EDF mostly rises as the noise reddens).
        assert_eq!(widest_alpha(-2, 2, 2, 131_072, 540_001, true, false).0, -2);
        assert_eq!(widest_alpha(-2, 2, 2, 131_072, 540_001, true, true).0, -2);
        assert_eq!(widest_alpha(-4, 2, 3, 131_072, 540_001, true, false).0, -4);
        assert_eq!(widest_alpha(-2, 2, 2, 2048, 10_001, false, false).0, 2);
        // Where no type has a finite positive EDF, an infinite one: add_intervals then takes 1.
        assert!(widest_alpha(-2, 2, 2, 262_144, 540_001, true, true)
            .1
            .is_infinite());
        // An empty or reversed range collapses to its lower end.
        let (a, e) = widest_alpha(0, -1, 2, 100, 10_001, true, false);
        assert_eq!(a, 0);
        assert_eq!(e, edf_greenhall(0, 2, 100, 10_001, true, false));
    }

    #[test]
    fn slope_to_alpha() {
        assert_eq!(alpha_from_slope(-2.0, 2), 2);
        assert_eq!(alpha_from_slope(-1.0, 2), 0);
        assert_eq!(alpha_from_slope(0.0, 2), -1);
        assert_eq!(alpha_from_slope(1.0, 2), -2);
        assert_eq!(alpha_from_slope(3.0, 2), -2);
        assert_eq!(alpha_from_slope(3.0, 3), -4);
        assert_eq!(alpha_floor(2), -2);
        assert_eq!(alpha_floor(3), -4);
    }
}
