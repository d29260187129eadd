//! Equivalent degrees of freedom (EDF) of Allan-type variances: Greenhall & Riley's algorithm
//! ("Uncertainty of stability variances based on finite differences", PTTI 2003; C. Greenhall,
//! W. Riley 2004), exactly as allantools 2024.06 implements it in `ci.edf_greenhall`.
//!
//! It needs the power-law noise type alpha (S_y(f) ~ f^alpha) at each averaging factor; the
//! deviation module identifies it from the local slope of the deviation curve.

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
/// when ceil(M/S) <= d (only at the very last taus); this returns the large-r formula there.
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
    } else {
        let a0 = binom(4 * d, 2 * d) / binom(2 * d, d).powi(2);
        let a1 = df / 2.0;
        (a0 - a1 / r) / big_m
    };
    1.0 / inv
}
