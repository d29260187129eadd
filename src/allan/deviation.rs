//! Allan-type deviations of a rate record, allantools 2024.06's conventions for rate
//! ("frequency") data, on a tau grid, each point with its number of terms and a chi-squared
//! confidence interval.
//!
//! Rates y (any unit U, sampled at `rate` Hz) become phase x = [0, cumsum(y - mean(y)) / rate]
//! (U*s, N+1 values; allantools' `frequency2phase`). With tau = m / rate:
//!
//! ```text
//! OADEV^2(tau) = sum_{i=0}^{n-1} (x[i+2m] - 2 x[i+m] + x[i])^2 / (2 n tau^2),  n = N+1-2m  (oadev)
//! ADEV: the same over i = 0, m, 2m, ...                                                    (adev)
//! MDEV^2(tau)  = sum_{j=0}^{n-1} (sum_{i=j}^{j+m-1} x[i+2m] - 2 x[i+m] + x[i])^2
//!                / (2 m^2 tau^2 n),  n = N+2-3m                                           (mdev)
//! HDEV^2(tau)  = sum_{i=0}^{n-1} (x[i+3m] - 3 x[i+2m] + 3 x[i+m] - x[i])^2 / (6 n tau^2),
//!                n = N+1-3m  (overlapping Hadamard)                                       (ohdev)
//! ```
//!
//! Points with n <= 1 are dropped (allantools `remove_small_ns`). The interval is
//! [`chi2::confidence_interval`] with Greenhall's EDF ([`edf::edf_greenhall`]) for the noise type
//! read from the local slope of the variance curve ([`edf::alpha_from_slope`]) where every point
//! the slope uses has at least [`edf::MIN_SPANS`] tau-spans; past that (the long-tau end) the noise
//! cannot be identified and the point takes the plausible type with the widest interval
//! ([`edf::widest_alpha`], [`NoiseId::Widest`]). The EDF is kept within its hard bounds
//! [`edf::edf_bounds`] (1 to the number of terms).

use super::{chi2, edf};
use std::fmt;
use std::str::FromStr;

/// Which deviation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Overlapping Allan deviation (allantools `oadev`): the default, best confidence.
    Oadev,
    /// Non-overlapping Allan deviation (allantools `adev`).
    Adev,
    /// Modified Allan deviation (allantools `mdev`): separates white from flicker phase noise.
    Mdev,
    /// Overlapping Hadamard deviation (allantools `ohdev`): insensitive to a rate ramp.
    Hdev,
}

impl Kind {
    /// Difference order of the variance (2 for Allan-type, 3 for Hadamard).
    pub fn order(self) -> u32 {
        if self == Kind::Hdev {
            3
        } else {
            2
        }
    }
}

impl FromStr for Kind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "oadev" => Ok(Kind::Oadev),
            "adev" => Ok(Kind::Adev),
            "mdev" => Ok(Kind::Mdev),
            "hdev" => Ok(Kind::Hdev),
            _ => Err(format!("unknown deviation '{s}' (oadev, adev, mdev, hdev)")),
        }
    }
}

impl fmt::Display for Kind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Kind::Oadev => "oadev",
            Kind::Adev => "adev",
            Kind::Mdev => "mdev",
            Kind::Hdev => "hdev",
        })
    }
}

/// The averaging times at which to evaluate, as averaging factors m (tau = m / rate).
#[derive(Debug, Clone, PartialEq)]
pub enum TauGrid {
    /// m = 1, 2, 4, 8, ... (allantools "octave").
    Octave,
    /// m = 1, 2, 4, 10, 20, 40, 100, ... (allantools "decade").
    Decade,
    /// P points per decade: m = round(10^(j/P)), j = 0, 1, ..., duplicates removed.
    Log(u32),
    /// Every m (allantools "all").
    All,
    /// Explicit taus in seconds, rounded to m = round(tau * rate) as allantools does.
    List(Vec<f64>),
}

impl FromStr for TauGrid {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "octave" => return Ok(TauGrid::Octave),
            "decade" => return Ok(TauGrid::Decade),
            "all" => return Ok(TauGrid::All),
            _ => {}
        }
        if let Some(p) = s.strip_prefix("log:") {
            return match p.parse::<u32>() {
                Ok(p) if (1..=1000).contains(&p) => Ok(TauGrid::Log(p)),
                _ => Err(format!(
                    "'{s}': log:P needs 1 <= P <= 1000 points per decade"
                )),
            };
        }
        let taus: Result<Vec<f64>, String> = s
            .split(',')
            .map(|t| match t.trim().parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
                _ => Err(format!(
                    "'{t}' is not a tau (octave, decade, log:P, all, or a list of seconds like 0.1,1,10)"
                )),
            })
            .collect();
        Ok(TauGrid::List(taus?))
    }
}

/// How the noise type of a point was chosen for its EDF.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseId {
    /// From the local slope of the variance ([`edf::alpha_from_slope`]): every point the slope uses
    /// has at least [`edf::MIN_SPANS`] tau-spans.
    Slope,
    /// Too few tau-spans to identify the noise: of the plausible alphas `lo..=hi` (the variance's
    /// floor up to the last alpha identified at a shorter tau), the one with the widest interval
    /// ([`edf::widest_alpha`]).
    Widest {
        /// The reddest alpha considered.
        lo: i32,
        /// The bluest alpha considered.
        hi: i32,
    },
}

/// One point of a deviation curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AllanPoint {
    /// Averaging time (s), m / rate.
    pub tau: f64,
    /// Averaging factor.
    pub m: usize,
    /// The deviation, in the input's rate unit.
    pub dev: f64,
    /// Number of terms in the sum (allantools' `ns`).
    pub n: usize,
    /// Noise exponent alpha used for the EDF (see [`NoiseId`]).
    pub alpha: i32,
    /// How alpha was chosen.
    pub noise_id: NoiseId,
    /// Equivalent degrees of freedom (Greenhall).
    pub edf: f64,
    /// Lower end of the confidence interval.
    pub lo: f64,
    /// Upper end of the confidence interval.
    pub hi: f64,
}

impl AllanPoint {
    /// A point from its averaging factor, deviation and term count, before intervals are added
    /// (see [`add_intervals`]).
    pub fn bare(m: usize, rate: f64, dev: f64, n: usize) -> Self {
        AllanPoint {
            tau: m as f64 / rate,
            m,
            dev,
            n,
            alpha: 0,
            noise_id: NoiseId::Slope,
            edf: 0.0,
            lo: 0.0,
            hi: 0.0,
        }
    }
}

/// Why a deviation could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AllanError {
    /// The sample rate is not a positive finite number.
    #[error("the sample rate must be a positive number of Hz, not {0}")]
    BadRate(f64),
    /// A sample is NaN or infinite.
    #[error("sample {0} is not finite")]
    NonFinite(usize),
    /// No averaging time of the grid fits in the record.
    #[error("a record of {samples} samples is too short for any tau of this grid ({kind} needs at least {needed} samples)")]
    TooShort {
        /// Samples in the record.
        samples: usize,
        /// The deviation asked for.
        kind: Kind,
        /// The fewest samples that give one point with m = 1.
        needed: usize,
    },
}

/// numpy's pairwise summation (`np.sum` on a contiguous float64 array), so the mean removed before
/// integration is bit-identical to allantools'.
pub fn pairwise_sum(a: &[f64]) -> f64 {
    let n = a.len();
    if n < 8 {
        let mut s = 0.0;
        for &v in a {
            s += v;
        }
        s
    } else if n <= 128 {
        let mut r = [0.0; 8];
        r.copy_from_slice(&a[..8]);
        let mut i = 8;
        while i + 8 <= n {
            for k in 0..8 {
                r[k] += a[i + k];
            }
            i += 8;
        }
        let mut s = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        while i < n {
            s += a[i];
            i += 1;
        }
        s
    } else {
        let mut n2 = n / 2;
        n2 -= n2 % 8;
        pairwise_sum(&a[..n2]) + pairwise_sum(&a[n2..])
    }
}

/// Rates to phase as allantools does: x = [0, cumsum(y - mean(y)) * (1 / rate)].
pub fn frequency_to_phase(y: &[f64], rate: f64) -> Vec<f64> {
    let mut x = crate::bigbuf::zeroed(y.len() + 1);
    phase_into(y, pairwise_sum(y), rate, &mut x);
    x
}

/// [`frequency_to_phase`] into `x` (`y.len() + 1` values), `sum` being `pairwise_sum(y)`.
fn phase_into(y: &[f64], sum: f64, rate: f64, x: &mut [f64]) {
    let dt = 1.0 / rate;
    let mean = sum / y.len().max(1) as f64;
    x[0] = 0.0;
    let mut s = 0.0;
    for (xi, &v) in x[1..].iter_mut().zip(y) {
        s += v - mean;
        *xi = s * dt;
    }
}

/// Averaging factors of `grid` for `phase_len` phase samples, as allantools' `tau_generator`:
/// m = round(tau * rate), 0 < m < phase_len, sorted, duplicates removed. Points whose number of
/// terms would be <= 1 are removed later.
pub fn averaging_factors(grid: &TauGrid, phase_len: usize, rate: f64) -> Vec<usize> {
    let len = phase_len as f64;
    let mut ms: Vec<usize> = match grid {
        TauGrid::Octave => {
            let maxn = len.log2().floor() as u32;
            (0..=maxn).map(|k| 1usize << k.min(62)).collect()
        }
        TauGrid::Decade => {
            let maxn = len.log10().floor() as i32;
            (0..=maxn)
                .flat_map(|k| {
                    let p = 10f64.powi(k);
                    [p, 2.0 * p, 4.0 * p]
                })
                .map(|m| m.round() as usize)
                .collect()
        }
        TauGrid::Log(p) => {
            let mut v = Vec::new();
            let mut j = 0u32;
            loop {
                let m = 10f64.powf(f64::from(j) / f64::from(*p)).round();
                if m >= len {
                    break;
                }
                v.push(m as usize);
                j += 1;
            }
            v
        }
        TauGrid::All => (1..phase_len).collect(),
        TauGrid::List(taus) => taus
            .iter()
            .map(|t| (t * rate).round())
            .filter(|m| *m > 0.0 && *m < len)
            .map(|m| m as usize)
            .collect(),
    };
    ms.retain(|&m| m > 0 && m < phase_len);
    ms.sort_unstable();
    ms.dedup();
    ms
}

/// Number of terms of `kind` at averaging factor `m` for `phase_len` phase samples.
pub fn terms(kind: Kind, phase_len: usize, m: usize) -> usize {
    let l = phase_len;
    match kind {
        Kind::Oadev => l.saturating_sub(2 * m),
        Kind::Adev => {
            if l > 2 * m {
                (l - 1 - 2 * m) / m + 1
            } else {
                0
            }
        }
        Kind::Mdev => {
            if l >= 3 * m {
                l - 3 * m + 1
            } else {
                0
            }
        }
        Kind::Hdev => l.saturating_sub(3 * m),
    }
}

/// Lanes of one m's partial sums in the OADEV kernel: term i adds to lane i % LANES, in every
/// build (portable or AVX2) and however the terms are blocked or grouped, so a sum depends only
/// on x and m, not on the CPU, the other m computed with it or the number of threads.
const LANES: usize = 8;

/// Averaging factors the kernel takes at once: they share the loads of x[i], which were a third
/// of the kernel's loads with one m at a time (22 % faster on the m whose streams are cached).
const GROUP: usize = 4;

/// Block length (phase samples, a multiple of [`LANES`]) of the cache-blocked OADEV pass: a
/// block of x[i] is loaded once for every m while it is in cache.
const BLOCK: usize = 1 << 14;

/// One m's running OADEV sum: [`LANES`] partial sums over whole chunks of `LANES` terms, and
/// the sum of the terms after the last whole chunk.
#[derive(Debug, Clone, Copy, Default)]
struct Partial {
    lanes: [f64; LANES],
    tail: f64,
}

impl Partial {
    /// The lanes added pairwise (a fixed tree), then the tail.
    fn total(&self) -> f64 {
        let mut q = self.lanes;
        let mut w = LANES / 2;
        while w > 0 {
            for k in 0..w {
                q[k] += q[k + w];
            }
            w /= 2;
        }
        q[0] + self.tail
    }
}

/// Adds the terms i in [from, to) of each m in `ms` to its partial, portable build. `from` and
/// `to` are multiples of [`LANES`] and `to + 2 m <= x.len()` for every m.
fn chunks_portable<const K: usize>(
    x: &[f64],
    ms: [usize; K],
    from: usize,
    to: usize,
    p: &mut [Partial],
) {
    for i in (from..to).step_by(LANES) {
        let a = &x[i..i + LANES];
        for (t, &m) in ms.iter().enumerate() {
            let (b, c) = (&x[i + m..i + m + LANES], &x[i + 2 * m..i + 2 * m + LANES]);
            for k in 0..LANES {
                let v = c[k] - 2.0 * b[k] + a[k];
                p[t].lanes[k] += v * v;
            }
        }
    }
}

/// [`chunks_portable`] with AVX2: two 4-lane accumulators per m, the same partial sums and
/// operation order. `c - 2 b` is one fused multiply-add: 2 b is exact, so its single rounding is
/// the portable build's (the same bits, one operation fewer). The sum of squares stays unfused.
///
/// # Safety
/// The CPU must support AVX2 and FMA; `from <= to`, both multiples of [`LANES`], and
/// `to + 2 m <= x.len()` for every m in `ms`; `p` has at least `K` partials.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn chunks_avx2<const K: usize>(
    x: &[f64],
    ms: [usize; K],
    from: usize,
    to: usize,
    p: &mut [Partial],
) {
    use std::arch::x86_64::*;
    let px = x.as_ptr();
    let two = _mm256_set1_pd(2.0);
    let mut acc = [[_mm256_setzero_pd(); 2]; K];
    for (a, q) in acc.iter_mut().zip(p.iter()) {
        // SAFETY: `lanes` holds 8 values, two loads of 4.
        unsafe {
            a[0] = _mm256_loadu_pd(q.lanes.as_ptr());
            a[1] = _mm256_loadu_pd(q.lanes.as_ptr().add(4));
        }
    }
    let mut i = from;
    while i < to {
        for h in 0..2 {
            let o = i + 4 * h;
            // SAFETY: o + 4 <= to <= x.len() - 2 m for every m (the caller's contract), so
            // x[o..o + 4], x[o + m..][..4] and x[o + 2 m..][..4] are in bounds.
            unsafe {
                let va = _mm256_loadu_pd(px.add(o));
                for (a, &m) in acc.iter_mut().zip(ms.iter()) {
                    let vb = _mm256_loadu_pd(px.add(o + m));
                    let vc = _mm256_loadu_pd(px.add(o + 2 * m));
                    let v = _mm256_add_pd(_mm256_fnmadd_pd(two, vb, vc), va);
                    a[h] = _mm256_add_pd(a[h], _mm256_mul_pd(v, v));
                }
            }
        }
        i += LANES;
    }
    for (a, q) in acc.iter().zip(p.iter_mut()) {
        // SAFETY: as for the loads above.
        unsafe {
            _mm256_storeu_pd(q.lanes.as_mut_ptr(), a[0]);
            _mm256_storeu_pd(q.lanes.as_mut_ptr().add(4), a[1]);
        }
    }
}

/// [`chunks_avx2`] where the CPU has AVX2 and FMA, else [`chunks_portable`] (identical results
/// either way); the bounds of [`chunks_portable`], checked here.
fn chunks_of<const K: usize>(x: &[f64], ms: [usize; K], from: usize, to: usize, p: &mut [Partial]) {
    let top = ms.iter().max().map_or(0, |&m| to + 2 * m);
    assert!(from <= to && from % LANES == 0 && to % LANES == 0 && top <= x.len() && p.len() >= K);
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA (checked just above); the bounds are asserted.
        return unsafe { chunks_avx2(x, ms, from, to, p) };
    }
    chunks_portable(x, ms, from, to, p)
}

/// Adds the terms i in [from, to) of each m in `ms` (one to [`GROUP`] of them) to its partial.
fn chunks(x: &[f64], ms: &[usize], from: usize, to: usize, p: &mut [Partial]) {
    match *ms {
        [a] => chunks_of(x, [a], from, to, p),
        [a, b] => chunks_of(x, [a, b], from, to, p),
        [a, b, c] => chunks_of(x, [a, b, c], from, to, p),
        [a, b, c, d] => chunks_of(x, [a, b, c, d], from, to, p),
        _ => unreachable!("1 to GROUP averaging factors at once, got {}", ms.len()),
    }
}

/// OADEV sums of squares sum_i (x[i+2m] - 2 x[i+m] + x[i])^2 for every m in `ms`, in one
/// cache-blocked pass over `x`, the m in groups of [`GROUP`] that share their loads of x[i].
fn oadev_sums(x: &[f64], ms: &[usize]) -> Vec<f64> {
    let l = x.len();
    let n = |m: usize| terms(Kind::Oadev, l, m);
    let whole = |m: usize| n(m) - n(m) % LANES;
    let mut parts = vec![Partial::default(); ms.len()];
    let mut start = 0;
    while start < l {
        let end = (start + BLOCK).min(l);
        for (g, p) in ms.chunks(GROUP).zip(parts.chunks_mut(GROUP)) {
            // Together while every m of the group has whole chunks left, then each m alone.
            let common = g.iter().map(|&m| whole(m)).min().unwrap_or(0).min(end);
            if start < common {
                chunks(x, g, start, common, p);
            }
            for (t, &m) in g.iter().enumerate() {
                let (from, to) = (start.max(common), whole(m).min(end));
                if from < to {
                    chunks(x, &[m], from, to, &mut p[t..=t]);
                }
            }
        }
        start = end;
    }
    for (p, &m) in parts.iter_mut().zip(ms) {
        for i in whole(m)..n(m) {
            let v = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
            p.tail += v * v;
        }
    }
    parts.iter().map(Partial::total).collect()
}

/// The deviation of `kind` at averaging factor `m` from phase `x` (allantools' formulas), and its
/// number of terms.
pub fn deviation_at(kind: Kind, x: &[f64], rate: f64, m: usize) -> (f64, usize) {
    let n = terms(kind, x.len(), m);
    if n == 0 {
        return (0.0, 0);
    }
    let mf = m as f64;
    match kind {
        Kind::Oadev => {
            let s = oadev_sums(x, &[m])[0];
            ((s / (2.0 * n as f64)).sqrt() / mf * rate, n)
        }
        Kind::Adev => {
            let mut s = 0.0;
            let mut i = 0;
            while i + 2 * m < x.len() {
                let v = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
                s += v * v;
                i += m;
            }
            ((s / (2.0 * n as f64)).sqrt() / mf * rate, n)
        }
        Kind::Mdev => {
            let tau = mf / rate;
            let mut v = 0.0;
            for i in 0..m {
                v += x[i + 2 * m] - 2.0 * x[i + m] + x[i];
            }
            let mut s = v * v;
            for j in 0..n - 1 {
                v += x[j + 3 * m] - 3.0 * x[j + 2 * m] + 3.0 * x[j + m] - x[j];
                s += v * v;
            }
            ((s / (2.0 * mf * mf * tau * tau * n as f64)).sqrt(), n)
        }
        Kind::Hdev => {
            let mut s = 0.0;
            for i in 0..n {
                let v = x[i + 3 * m] - 3.0 * x[i + 2 * m] + 3.0 * x[i + m] - x[i];
                s += v * v;
            }
            ((s / 6.0 / n as f64).sqrt() / (mf / rate), n)
        }
    }
}

/// Deviations of `kind` at each m (no intervals): (dev, n) per m. OADEV runs cache-blocked and
/// spread over the available cores; the result does not depend on the number of threads.
pub fn deviations(kind: Kind, x: &[f64], rate: f64, ms: &[usize]) -> Vec<(f64, usize)> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(ms.len().max(1));
    let work = |part: &[usize]| -> Vec<(f64, usize)> {
        if kind == Kind::Oadev {
            let sums = oadev_sums(x, part);
            part.iter()
                .zip(sums)
                .map(|(&m, s)| {
                    let n = terms(kind, x.len(), m);
                    let dev = if n == 0 {
                        0.0
                    } else {
                        (s / (2.0 * n as f64)).sqrt() / m as f64 * rate
                    };
                    (dev, n)
                })
                .collect()
        } else {
            part.iter()
                .map(|&m| deviation_at(kind, x, rate, m))
                .collect()
        }
    };
    if threads <= 1 || x.len() < 100_000 {
        return work(ms);
    }
    // Deal the m values round-robin so every thread gets a similar mix of lags.
    let parts: Vec<Vec<usize>> = (0..threads)
        .map(|t| ms.iter().copied().skip(t).step_by(threads).collect())
        .collect();
    let results: Vec<Vec<(f64, usize)>> = std::thread::scope(|scope| {
        let handles: Vec<_> = parts.iter().map(|p| scope.spawn(move || work(p))).collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    let mut out = vec![(0.0, 0); ms.len()];
    for (t, r) in results.into_iter().enumerate() {
        for (k, v) in r.into_iter().enumerate() {
            out[t + k * threads] = v;
        }
    }
    out
}

/// Local log-log slope of the variance at point `j` of `(tau, dev)`, from the neighbours about a
/// factor 2 away in tau (one-sided at the ends), with the indices of the two points used. `None`
/// for a single point or a zero deviation.
pub fn local_variance_slope(points: &[(f64, f64)], j: usize) -> Option<(f64, usize, usize)> {
    let tau = points[j].0;
    let lo = points[..j]
        .iter()
        .rposition(|p| p.0 <= tau / 2.0)
        .unwrap_or(0);
    let hi = points[j..]
        .iter()
        .position(|p| p.0 >= tau * 2.0)
        .map_or(points.len() - 1, |k| j + k);
    if hi == lo || points[lo].1 <= 0.0 || points[hi].1 <= 0.0 {
        return None;
    }
    let mu = 2.0 * (points[hi].1 / points[lo].1).ln() / (points[hi].0 / points[lo].0).ln();
    Some((mu, lo, hi))
}

/// Fill in the noise type, EDF and interval (confidence `ci`, e.g. [`chi2::ONE_SIGMA`]) of
/// points whose tau, m, dev and n are set (sorted by tau), for `phase_len` phase samples.
///
/// Where every point of the local slope has at least [`edf::MIN_SPANS`] tau-spans, alpha comes
/// from the slope ([`NoiseId::Slope`]). Beyond (these points come last: the spans fall with tau),
/// the noise cannot be identified; a point there takes, of the alphas from the variance's floor up
/// to the last one identified (or 2 if none was), the one with the widest interval
/// ([`edf::widest_alpha`], [`NoiseId::Widest`]). Before this rule a 3-hour ADXRS450 record
/// reported white phase noise and EDF 188,669 (+-0.16%) at tau = 2621 s, with 4 tau-spans, because
/// the last point (2 spans, EDF about 1) happened to fall low and steepened the slope.
pub fn add_intervals(kind: Kind, points: &mut [AllanPoint], phase_len: usize, ci: f64) {
    let curve: Vec<(f64, f64)> = points.iter().map(|p| (p.tau, p.dev)).collect();
    let ms: Vec<usize> = points.iter().map(|p| p.m).collect();
    let d = kind.order();
    let overlapping = kind != Kind::Adev;
    let modified = kind == Kind::Mdev;
    let mut last_identified: Option<i32> = None;
    for (j, p) in points.iter_mut().enumerate() {
        let slope = local_variance_slope(&curve, j)
            .filter(|&(_, _, hi)| edf::tau_spans(phase_len, ms[hi]) >= edf::MIN_SPANS);
        let e = match slope {
            Some((mu, _, _)) => {
                p.alpha = edf::alpha_from_slope(mu, d);
                p.noise_id = NoiseId::Slope;
                last_identified = Some(p.alpha);
                edf::edf_greenhall(p.alpha, d, p.m, phase_len, overlapping, modified)
            }
            None => {
                let (lo, hi) = (edf::alpha_floor(d), last_identified.unwrap_or(2));
                let (alpha, e) =
                    edf::widest_alpha(lo, hi, d, p.m, phase_len, overlapping, modified);
                p.alpha = alpha;
                p.noise_id = NoiseId::Widest { lo, hi };
                e
            }
        };
        let (min_edf, max_edf) = edf::edf_bounds(p.n);
        p.edf = if e.is_finite() {
            e.clamp(min_edf, max_edf)
        } else {
            min_edf
        };
        let (lo, hi) = chi2::confidence_interval(p.dev, p.edf, ci);
        p.lo = lo;
        p.hi = hi;
    }
}

/// The deviation curve of rate samples `y` at `rate` Hz on `grid`, with confidence `ci`
/// (two-sided, e.g. [`chi2::ONE_SIGMA`]).
pub fn allan(
    y: &[f64],
    rate: f64,
    kind: Kind,
    grid: &TauGrid,
    ci: f64,
) -> Result<Vec<AllanPoint>, AllanError> {
    if !(rate.is_finite() && rate > 0.0) {
        return Err(AllanError::BadRate(rate));
    }
    // The sum behind the mean screens the input too: it is finite when every sample is (when
    // it is not, either a sample is not or the sum overflowed, and the scan tells which).
    let sum = pairwise_sum(y);
    if !sum.is_finite() {
        if let Some(i) = y.iter().position(|v| !v.is_finite()) {
            return Err(AllanError::NonFinite(i));
        }
    }
    let needed = match kind {
        Kind::Oadev | Kind::Adev => 3,
        Kind::Mdev => 3,
        Kind::Hdev => 4,
    };
    let too_short = AllanError::TooShort {
        samples: y.len(),
        kind,
        needed,
    };
    if y.len() < needed {
        return Err(too_short);
    }
    // A work buffer from the pool: a repeated call does not fault its 80 MB in again.
    let mut x = crate::bigbuf::Scratch::for_overwrite(y.len() + 1);
    phase_into(y, sum, rate, &mut x);
    let ms = averaging_factors(grid, x.len(), rate);
    let devs = deviations(kind, &x, rate, &ms);
    let mut points: Vec<AllanPoint> = ms
        .iter()
        .zip(devs)
        .filter(|(_, (_, n))| *n > 1)
        .map(|(&m, (dev, n))| AllanPoint::bare(m, rate, dev, n))
        .collect();
    if points.is_empty() {
        return Err(too_short);
    }
    add_intervals(kind, &mut points, x.len(), ci);
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairwise_sum_is_exact_on_integers() {
        let v: Vec<f64> = (0..1000).map(f64::from).collect();
        assert_eq!(pairwise_sum(&v), 499_500.0);
    }

    /// An OADEV sum depends only on x and m: not on the other m computed with it, their order,
    /// the number of threads or the CPU's build; and it is the exact sum to rounding.
    #[test]
    fn oadev_sums_do_not_depend_on_grouping_threads_or_build() {
        let y: Vec<f64> = (0..120_003).map(|i| ((i * 7919) % 1013) as f64).collect();
        let x = frequency_to_phase(&y, 10.0);
        let ms = averaging_factors(&TauGrid::Log(7), x.len(), 10.0);
        let all = deviations(Kind::Oadev, &x, 10.0, &ms);
        let reversed: Vec<usize> = ms.iter().rev().copied().collect();
        let sums = oadev_sums(&x, &ms);
        let sums_rev = oadev_sums(&x, &reversed);
        for (k, &m) in ms.iter().enumerate() {
            assert_eq!(all[k], deviation_at(Kind::Oadev, &x, 10.0, m), "m={m}");
            assert_eq!(sums[k], sums_rev[ms.len() - 1 - k], "m={m}");
            // Kahan-compensated: the reference's own rounding is negligible.
            let (mut plain, mut carry) = (0.0f64, 0.0f64);
            for i in 0..terms(Kind::Oadev, x.len(), m) {
                let v = (x[i + 2 * m] - 2.0 * x[i + m] + x[i]).powi(2) - carry;
                let t = plain + v;
                carry = (t - plain) - v;
                plain = t;
            }
            let close = sums[k] == plain || ((sums[k] - plain) / plain).abs() < 1e-12;
            assert!(close, "m={m}: {} vs {plain}", sums[k]);
        }
    }

    #[test]
    fn simd_and_portable_kernels_agree_bit_for_bit() {
        let x: Vec<f64> = (0..1000)
            .map(|i| ((i * 7919) % 1013) as f64 * 1e-3)
            .collect();
        let ms = [1, 3, 17, 100];
        let to = (x.len() - 2 * 100) / LANES * LANES;
        for k in 1..=GROUP {
            let mut fast = vec![Partial::default(); k];
            let mut portable = fast.clone();
            chunks(&x, &ms[..k], LANES, to, &mut fast);
            match k {
                1 => chunks_portable(&x, [1], LANES, to, &mut portable),
                2 => chunks_portable(&x, [1, 3], LANES, to, &mut portable),
                3 => chunks_portable(&x, [1, 3, 17], LANES, to, &mut portable),
                _ => chunks_portable(&x, ms, LANES, to, &mut portable),
            }
            for (f, p) in fast.iter().zip(&portable) {
                assert_eq!(f.lanes, p.lanes, "{k} at once");
                assert!(f.total() > 0.0);
            }
        }
    }

    #[test]
    fn grids_parse() {
        assert_eq!("log:5".parse::<TauGrid>(), Ok(TauGrid::Log(5)));
        assert_eq!(
            "0.5,2".parse::<TauGrid>(),
            Ok(TauGrid::List(vec![0.5, 2.0]))
        );
        assert!("log:0".parse::<TauGrid>().is_err());
        assert!("1,x".parse::<TauGrid>().is_err());
    }

    #[test]
    fn too_short_and_bad_rate() {
        assert!(matches!(
            allan(&[1.0, 2.0], 1.0, Kind::Oadev, &TauGrid::Octave, 0.68),
            Err(AllanError::TooShort { .. })
        ));
        assert_eq!(
            allan(&[1.0; 10], 0.0, Kind::Oadev, &TauGrid::Octave, 0.68),
            Err(AllanError::BadRate(0.0))
        );
    }

    /// The first non-finite sample is named, whatever the others are; finite samples whose sum
    /// overflows are not refused as non-finite.
    #[test]
    fn the_first_non_finite_sample_is_named() {
        let oadev = |y: &[f64]| allan(y, 1.0, Kind::Oadev, &TauGrid::Octave, 0.68);
        for (bad, at) in [
            (vec![(7, f64::NAN)], 7),
            (vec![(0, f64::INFINITY)], 0),
            (vec![(99, f64::NEG_INFINITY)], 99),
            (vec![(40, f64::INFINITY), (3, f64::NEG_INFINITY)], 3),
        ] {
            let mut y = vec![0.5; 100];
            for (i, v) in bad {
                y[i] = v;
            }
            assert_eq!(oadev(&y), Err(AllanError::NonFinite(at)));
        }
        let huge = vec![f64::MAX; 100];
        assert!(!matches!(oadev(&huge), Err(AllanError::NonFinite(_))));
    }
}
