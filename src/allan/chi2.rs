//! Chi-squared quantiles and the chi-squared confidence interval of a deviation.
//!
//! Self-contained (no statistics crate): the regularised incomplete gamma function by its series
//! and continued fraction (with a Stirling-based prefix that stays accurate for millions of degrees
//! of freedom), inverted by safeguarded Newton steps. Checked against scipy's `chi2.ppf` through
//! allantools' `confidence_interval` in the fixtures.

use std::f64::consts::PI;

/// The two-sided confidence level of a one-sigma interval, erf(1/sqrt 2) (allantools' default).
pub const ONE_SIGMA: f64 = 0.682_689_492_137_085_9;

/// Stirling's correction lnGamma(a+1) - (a ln a - a + ln(2 pi a)/2), for a >= 10.
fn stirling_correction(a: f64) -> f64 {
    let r = 1.0 / a;
    let r2 = r * r;
    r * (1.0 / 12.0 - r2 * (1.0 / 360.0 - r2 * (1.0 / 1260.0 - r2 * (1.0 / 1680.0))))
}

/// Natural log of the gamma function for a > 0.
pub fn ln_gamma(a: f64) -> f64 {
    // Shift up to a >= 10 with the recurrence, then Stirling (error below 1e-15 there).
    let mut shift = 0.0;
    let mut z = a;
    while z < 10.0 {
        shift += z.ln();
        z += 1.0;
    }
    // ln Gamma(z) = ln Gamma(z+1) - ln z
    (z - 0.5) * z.ln() - z + 0.5 * (2.0 * PI).ln() + stirling_correction(z) - shift
}

/// x^a e^-x / Gamma(a+1), computed stably for large a.
fn gamma_prefix(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if a >= 10.0 {
        let t = (x - a) / a;
        let log1pmx = if t.abs() < 0.5 {
            // ln(1+t) - t by its series: no cancellation for small t.
            let mut term = -t * t / 2.0;
            let mut sum = term;
            let mut k = 2.0;
            loop {
                term *= -t * k / (k + 1.0);
                sum += term;
                k += 1.0;
                if term.abs() <= 1e-17 * sum.abs() || k > 200.0 {
                    break;
                }
            }
            sum
        } else {
            t.ln_1p() - t
        };
        (a * log1pmx - 0.5 * (2.0 * PI * a).ln() - stirling_correction(a)).exp()
    } else {
        (a * x.ln() - x - ln_gamma(a + 1.0)).exp()
    }
}

/// Regularised incomplete gamma functions (P(a, x), Q(a, x)) = (lower, upper).
pub fn gamma_pq(a: f64, x: f64) -> (f64, f64) {
    if x <= 0.0 {
        return (0.0, 1.0);
    }
    let prefix = gamma_prefix(a, x);
    if x < a + 1.0 {
        // P = prefix * sum_n x^n / ((a+1)...(a+n))
        let mut term = 1.0;
        let mut sum = 1.0;
        let mut n = 1.0;
        while n < 1e7 {
            term *= x / (a + n);
            sum += term;
            if term < sum * 1e-17 {
                break;
            }
            n += 1.0;
        }
        let p = prefix * sum;
        (p, 1.0 - p)
    } else {
        // Q = prefix * a / x * CF, modified Lentz on the continued fraction for Gamma(a, x).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        let mut i = 1.0;
        while i < 1e7 {
            let an = -i * (i - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
            i += 1.0;
        }
        // Gamma(a,x)/Gamma(a) = x^a e^-x / Gamma(a) * h = prefix * a * h
        let q = prefix * a * h;
        (1.0 - q, q)
    }
}

/// Standard normal quantile (Acklam's rational approximation, ~1e-9): a starting point only.
fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let plow = 0.02425;
    if p < plow {
        let q = (-2.0 * p.ln()).sqrt();
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    } else if p <= 1.0 - plow {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        -normal_quantile(1.0 - p)
    }
}

/// The chi-squared quantile with `dof` degrees of freedom (any real dof > 0) at lower-tail
/// probability `p` in (0, 1): the x with P(chi2_dof <= x) = p. Relative accuracy ~1e-12.
pub fn chi2_quantile(p: f64, dof: f64) -> f64 {
    chi2_quantile_tail(p, 1.0 - p, dof)
}

/// As [`chi2_quantile`], with both tails given so that upper quantiles keep full precision.
fn chi2_quantile_tail(p: f64, q: f64, dof: f64) -> f64 {
    if !(p > 0.0 && q > 0.0 && dof > 0.0) {
        return f64::NAN;
    }
    let a = dof / 2.0;
    let upper = p > 0.5;
    // Wilson-Hilferty start, in units of x = chi2 / 2.
    let z = if upper {
        -normal_quantile(q)
    } else {
        normal_quantile(p)
    };
    let h = 1.0 / (9.0 * a);
    let wh = a * (1.0 - h + z * h.sqrt()).powi(3);
    let mut x = if wh > 0.0 && a > 0.5 {
        wh
    } else {
        // Small a: P(a, x) ~ x^a / Gamma(a+1) near zero.
        (p * (ln_gamma(a + 1.0)).exp()).powf(1.0 / a).max(1e-300)
    };
    let (mut lo, mut hi) = (0.0_f64, f64::INFINITY);
    for _ in 0..200 {
        let (pp, qq) = gamma_pq(a, x);
        // f increases with x in both forms.
        let f = if upper { q - qq } else { pp - p };
        if f > 0.0 {
            hi = hi.min(x);
        } else {
            lo = lo.max(x);
        }
        let dens = gamma_prefix(a, x) * a / x; // x^(a-1) e^-x / Gamma(a)
        let mut next = if dens > 0.0 { x - f / dens } else { f64::NAN };
        if !(next > lo && next < hi) {
            next = if hi.is_finite() {
                0.5 * (lo + hi)
            } else {
                2.0 * x.max(1e-300)
            };
        }
        let done = (next - x).abs() <= 1e-15 * x;
        x = next;
        if done {
            break;
        }
    }
    2.0 * x
}

/// allantools' `confidence_interval(dev, edf, ci)`: the deviation's two-sided chi-squared interval
/// at confidence `ci` (NIST SP1065 eqn 45): `(dev sqrt(edf / chi2_hi), dev sqrt(edf / chi2_lo))`.
pub fn confidence_interval(dev: f64, edf: f64, ci: f64) -> (f64, f64) {
    let tail = ci.abs().min((ci - 1.0).abs()) / 2.0;
    let chi2_lo = chi2_quantile_tail(tail, 1.0 - tail, edf);
    let chi2_hi = chi2_quantile_tail(1.0 - tail, tail, edf);
    (dev * (edf / chi2_hi).sqrt(), dev * (edf / chi2_lo).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_quantiles() {
        // scipy.stats.chi2.ppf
        let cases = [
            (0.5, 1.0, 0.454_936_423_119_572),
            (0.95, 1.0, 3.841_458_820_694_124),
            (0.05, 10.0, 3.940_299_136_119_060_5),
            (0.975, 2.5, 8.392_295_266_912_964),
        ];
        for (p, k, want) in cases {
            let got = chi2_quantile(p, k);
            assert!(
                ((got - want) / want).abs() < 1e-10,
                "{p} {k}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn quantile_inverts_the_cdf() {
        for &k in &[0.3, 1.0, 3.7, 50.0, 1e3, 1e5, 3e6] {
            for &p in &[1e-6, 0.01, 0.158, 0.5, 0.841, 0.99, 1.0 - 1e-6] {
                let x = chi2_quantile(p, k);
                let (pp, _) = gamma_pq(k / 2.0, x / 2.0);
                assert!((pp - p).abs() < 1e-11 * p.max(1e-3), "k={k} p={p}: P={pp}");
            }
        }
    }
}
