//! Several still records of one sensor (one per power-up, one per day) pooled into one deviation
//! curve, never joined end to end: the step in bias between two power-ups would read as bias
//! instability (138 deg/h joined against 1.1 deg/h pooled on a real dataset).
//!
//! Every Allan-type estimator of [`super::deviation`] is a mean of squared differences over its n
//! terms (allantools' `ns`: overlapping or not, second or third differences, modified or not), so
//! the records' variances at an averaging factor m pool as the mean over all their terms:
//!
//! ```text
//! AVAR_pooled(m) = sum_i n_i(m) AVAR_i(m) / sum_i n_i(m)   over the records i that reach m
//! ```
//!
//! No term straddles two records, so no step between them enters. A tau is in the pooled curve if
//! at least one record reaches it (the longest record alone gives the longest taus).
//!
//! The interval comes from the pooled degrees of freedom, the sum of each record's Greenhall EDF at
//! that m ([`super::edf::edf_greenhall`] with the record's own length), each within its bounds
//! [`super::edf::edf_bounds`]. The sum is exact where each record's EDF is proportional to its
//! weight n_i (records of one length) and a slight overstatement otherwise (Satterthwaite's
//! (sum n_i)^2 / sum (n_i^2 / edf_i) is its lower bound). The noise type behind the EDF is read
//! from the pooled curve's slope, as [`super::deviation::add_intervals`] reads one record's,
//! where the records together hold [`super::edf::MIN_SPANS`] tau-spans; past that, of the
//! plausible types, the one whose summed EDF is fewest. For one record every step is the one
//! record's own, so pooling one record gives that record's curve bit for bit.

use super::deviation::{local_variance_slope, AllanPoint, Kind, NoiseId};
use super::{chi2, edf};
use std::collections::BTreeMap;

/// One record's curve, as [`pool`] takes it.
#[derive(Debug, Clone, Copy)]
pub struct LogCurve<'a> {
    /// Its points, tau ascending, each with its number of terms `n` (the deviations of
    /// [`super::deviation::deviations`], or a whole curve: intervals are recomputed).
    pub points: &'a [AllanPoint],
    /// Its phase points: samples + 1.
    pub phase_len: usize,
}

/// A pooled curve.
#[derive(Debug, Clone, PartialEq)]
pub struct Pooled {
    /// The pooled points, tau ascending: `n` the terms of every record summed, `edf` their EDFs
    /// summed, the interval from that EDF.
    pub points: Vec<AllanPoint>,
    /// Per point, how many records reached its tau.
    pub logs: Vec<usize>,
}

/// One record's share of a pooled point: its term count, deviation and phase length.
#[derive(Debug, Clone, Copy)]
struct Share {
    n: usize,
    dev: f64,
    phase_len: usize,
}

/// The curves of several records of one rate (tau = m / rate in each) and one `kind`, pooled per
/// averaging factor, with intervals at two-sided confidence `ci` (e.g. [`chi2::ONE_SIGMA`]). The
/// order of the records does not matter.
pub fn pool(kind: Kind, curves: &[LogCurve<'_>], ci: f64) -> Pooled {
    let mut by_m: BTreeMap<usize, (f64, Vec<Share>)> = BTreeMap::new();
    for c in curves {
        for p in c.points.iter().filter(|p| p.n > 0) {
            let share = Share {
                n: p.n,
                dev: p.dev,
                phase_len: c.phase_len,
            };
            by_m.entry(p.m).or_insert((p.tau, Vec::new())).1.push(share);
        }
    }
    let shares: Vec<Vec<Share>> = by_m.values().map(|(_, s)| s.clone()).collect();
    let mut points: Vec<AllanPoint> = by_m
        .iter()
        .map(|(&m, (tau, s))| {
            let n: usize = s.iter().map(|s| s.n).sum();
            // One record's deviation is kept as it is: sqrt(n dev^2 / n) may differ in its last bit.
            let dev = match s.as_slice() {
                [one] => one.dev,
                _ => {
                    let sum: f64 = s.iter().map(|s| s.n as f64 * s.dev * s.dev).sum();
                    (sum / n as f64).sqrt()
                }
            };
            AllanPoint {
                tau: *tau,
                ..AllanPoint::bare(m, 1.0, dev, n)
            }
        })
        .collect();
    add_pooled_intervals(kind, &mut points, &shares, ci);
    Pooled {
        points,
        logs: shares.iter().map(Vec::len).collect(),
    }
}

/// [`super::deviation::add_intervals`] for pooled points: `shares[j]` are the records behind
/// point j. With one record throughout it does what `add_intervals` does, operation for operation.
fn add_pooled_intervals(kind: Kind, points: &mut [AllanPoint], shares: &[Vec<Share>], ci: f64) {
    let curve: Vec<(f64, f64)> = points.iter().map(|p| (p.tau, p.dev)).collect();
    let ms: Vec<usize> = points.iter().map(|p| p.m).collect();
    let d = kind.order();
    let overlapping = kind != Kind::Adev;
    let modified = kind == Kind::Mdev;
    let greenhall = |alpha: i32, m: usize, s: &Share| {
        edf::edf_greenhall(alpha, d, m, s.phase_len, overlapping, modified)
    };
    // Each record's EDF within its own bounds (1 where it is not finite), summed.
    let summed = |alpha: i32, m: usize, s: &[Share]| -> f64 {
        s.iter()
            .map(|s| {
                let e = greenhall(alpha, m, s);
                let (lo, hi) = edf::edf_bounds(s.n);
                if e.is_finite() {
                    e.clamp(lo, hi)
                } else {
                    lo
                }
            })
            .sum()
    };
    let mut last_identified: Option<i32> = None;
    for (j, p) in points.iter_mut().enumerate() {
        let spans = |k: usize| -> usize {
            shares[k]
                .iter()
                .map(|s| edf::tau_spans(s.phase_len, ms[k]))
                .sum()
        };
        let slope =
            local_variance_slope(&curve, j).filter(|&(_, _, hi)| spans(hi) >= edf::MIN_SPANS);
        p.alpha = match slope {
            Some((mu, _, _)) => {
                p.noise_id = NoiseId::Slope;
                let alpha = edf::alpha_from_slope(mu, d);
                last_identified = Some(alpha);
                alpha
            }
            None => {
                let (lo, hi) = (edf::alpha_floor(d), last_identified.unwrap_or(2));
                p.noise_id = NoiseId::Widest { lo, hi };
                widest(lo, hi, d, |alpha| {
                    shares[j].iter().map(|s| greenhall(alpha, p.m, s)).sum()
                })
            }
        };
        p.edf = summed(p.alpha, p.m, &shares[j]);
        let (lo, hi) = chi2::confidence_interval(p.dev, p.edf, ci);
        p.lo = lo;
        p.hi = hi;
    }
}

/// Of alphas `lo..=hi` (as [`edf::widest_alpha`] bounds them), the one whose `total` EDF is the
/// fewest finite positive one; `hi` when none is.
fn widest(lo: i32, hi: i32, d: u32, total: impl Fn(i32) -> f64) -> i32 {
    let lo = lo.max(edf::alpha_floor(d));
    let hi = hi.clamp(lo, 2);
    let mut best = (hi, f64::INFINITY);
    for alpha in lo..=hi {
        let e = total(alpha);
        if e.is_finite() && e > 0.0 && e < best.1 {
            best = (alpha, e);
        }
    }
    best.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::allan::deviation::{allan, averaging_factors, deviations, frequency_to_phase};
    use crate::allan::TauGrid;
    use proptest::prelude::*;

    const KINDS: [Kind; 4] = [Kind::Oadev, Kind::Adev, Kind::Mdev, Kind::Hdev];

    /// White rate noise plus a random walk, deterministic from `seed`.
    fn record(seed: u64, len: usize) -> Vec<f64> {
        let mut s = seed
            .wrapping_mul(2862933555777941757)
            .wrapping_add(3037000493);
        let mut walk = 0.0;
        (0..len)
            .map(|_| {
                let mut u = || {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
                };
                walk += 0.002 * u();
                u() + walk
            })
            .collect()
    }

    fn curve(y: &[f64], kind: Kind, grid: &TauGrid) -> Vec<AllanPoint> {
        allan(y, 100.0, kind, grid, chi2::ONE_SIGMA).unwrap()
    }

    fn pooled(kind: Kind, logs: &[&[f64]], grid: &TauGrid) -> Pooled {
        let curves: Vec<Vec<AllanPoint>> = logs.iter().map(|y| curve(y, kind, grid)).collect();
        let inputs: Vec<LogCurve> = curves
            .iter()
            .zip(logs)
            .map(|(c, y)| LogCurve {
                points: c,
                phase_len: y.len() + 1,
            })
            .collect();
        pool(kind, &inputs, chi2::ONE_SIGMA)
    }

    #[test]
    fn one_record_pools_to_itself_bit_for_bit() {
        let y = record(1, 30_000);
        for kind in KINDS {
            for grid in [TauGrid::Octave, TauGrid::Log(7)] {
                let p = pooled(kind, &[&y], &grid);
                assert_eq!(p.points, curve(&y, kind, &grid), "{kind} {grid:?}");
                assert!(p.logs.iter().all(|&k| k == 1));
            }
        }
    }

    /// The pooled variance is the mean over all terms: the same sums of squares as each record's
    /// deviation undone, added, over the summed count.
    #[test]
    fn the_pooled_variance_is_the_mean_over_every_records_terms() {
        let (a, b) = (record(2, 5_000), record(3, 12_000));
        for kind in KINDS {
            let p = pooled(kind, &[&a, &b], &TauGrid::Octave);
            let xa = frequency_to_phase(&a, 100.0);
            let xb = frequency_to_phase(&b, 100.0);
            for (pt, &k) in p.points.iter().zip(&p.logs) {
                let [(da, na), (db, nb)] = [&xa, &xb].map(|x| {
                    let (d, n) = deviations(kind, x, 100.0, &[pt.m])[0];
                    if n > 1 {
                        (d, n)
                    } else {
                        (0.0, 0)
                    }
                });
                assert_eq!(k, usize::from(na > 0) + usize::from(nb > 0), "m {}", pt.m);
                assert_eq!(pt.n, na + nb);
                let want = ((na as f64 * da * da + nb as f64 * db * db) / (na + nb) as f64).sqrt();
                assert!((pt.dev - want).abs() <= 1e-12 * want, "{kind} m {}", pt.m);
                assert!(pt.lo < pt.dev && pt.dev < pt.hi && pt.edf >= k as f64);
            }
            // The longer record alone reaches the longest taus.
            let longest = averaging_factors(&TauGrid::Octave, b.len() + 1, 100.0);
            assert!(p.points.last().unwrap().m <= *longest.last().unwrap());
            assert_eq!(*p.logs.last().unwrap(), 1);
            assert_eq!(p.logs[0], 2);
        }
    }

    /// The pooled EDF is each record's summed, so two equal records narrow the interval.
    #[test]
    fn two_records_sum_their_degrees_of_freedom() {
        let (a, b) = (record(4, 20_000), record(5, 20_000));
        let one = pooled(Kind::Oadev, &[&a], &TauGrid::Octave);
        let two = pooled(Kind::Oadev, &[&a, &b], &TauGrid::Octave);
        for (p1, p2) in one.points.iter().zip(&two.points) {
            if p1.alpha == p2.alpha {
                assert!(
                    p2.edf > 1.5 * p1.edf,
                    "m {}: {} vs {}",
                    p1.m,
                    p2.edf,
                    p1.edf
                );
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// Pooling does not depend on the order of the records.
        #[test]
        fn the_order_of_records_does_not_matter(
            seeds in proptest::collection::vec(0u64..1000, 2..5),
            lens in proptest::collection::vec(50usize..4000, 4),
            k in 0usize..4,
        ) {
            let kind = KINDS[k];
            let logs: Vec<Vec<f64>> =
                seeds.iter().zip(&lens).map(|(&s, &n)| record(s, n)).collect();
            let refs: Vec<&[f64]> = logs.iter().map(Vec::as_slice).collect();
            let mut reversed = refs.clone();
            reversed.reverse();
            let (p, q) = (pooled(kind, &refs, &TauGrid::Octave), pooled(kind, &reversed, &TauGrid::Octave));
            prop_assert_eq!(&p.logs, &q.logs);
            for (a, b) in p.points.iter().zip(&q.points) {
                prop_assert_eq!((a.m, a.n, a.alpha, a.noise_id), (b.m, b.n, b.alpha, b.noise_id));
                for (u, v) in [(a.dev, b.dev), (a.edf, b.edf), (a.lo, b.lo), (a.hi, b.hi)] {
                    prop_assert!((u - v).abs() <= 1e-12 * u.abs().max(1e-300), "m {}: {} vs {}", a.m, u, v);
                }
            }
        }

        /// A record cut in two halves pools to about the whole where both halves hold many
        /// terms (only the terms across the cut are missing).
        #[test]
        fn two_halves_pool_to_about_the_whole(seed in 0u64..1000, len in 4_000usize..20_000) {
            let y = record(seed, len);
            let (a, b) = y.split_at(len / 2);
            let whole = curve(&y, Kind::Oadev, &TauGrid::Octave);
            let halves = pooled(Kind::Oadev, &[a, b], &TauGrid::Octave);
            for (w, h) in whole.iter().zip(&halves.points) {
                prop_assert_eq!(w.m, h.m);
                // Each half's mean removed shifts its phase by a ramp, which the second
                // difference cancels; what differs is the ~2m terms across the cut.
                if w.m * 40 < len {
                    let rel = (h.dev - w.dev).abs() / w.dev;
                    prop_assert!(rel < 0.1 && h.lo < w.hi && w.lo < h.hi,
                        "m {}: whole {} [{}, {}] halves {} [{}, {}]", w.m, w.dev, w.lo, w.hi, h.dev, h.lo, h.hi);
                }
            }
        }
    }
}
