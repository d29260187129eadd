//! Issue 14: the intervals at the longest taus. `driftless simulate --profile adxrs450 --duration
//! 3h --seed 3` then `driftless allan --rate 50` reported white phase noise, EDF 188,669 and
//! +-0.16% at tau = 2621.44 s, with 4 tau-spans in the record: the slope that picked the noise
//! type leaned on the last point (2 spans, EDF about 1). Points without enough tau-spans to
//! identify the noise must be flagged and keep a conservative interval, on any seed and profile.

use driftless::allan::deviation::local_variance_slope;
use driftless::allan::edf::{self, edf_greenhall, MIN_SPANS};
use driftless::allan::{allan, chi2::ONE_SIGMA, AllanPoint, Kind, NoiseId, TauGrid};
use driftless::sim::{SimConfig, Simulator};

/// `seconds` of every axis of a profile with a seed, as `driftless simulate` writes them.
fn record(profile: &str, seed: u64, seconds: f64) -> (Vec<Vec<f64>>, f64) {
    let mut cfg = SimConfig::profile(profile).expect("known profile");
    cfg.seed = seed;
    let mut sim = Simulator::new(&cfg).expect("valid profile");
    let n = (seconds * cfg.rate_hz).round() as usize;
    let mut axes = vec![Vec::with_capacity(n); cfg.axes];
    for _ in 0..n {
        let s = sim.next_sample();
        for (a, col) in axes.iter_mut().enumerate() {
            col.push(s.measured[a]);
        }
    }
    (axes, cfg.rate_hz)
}

/// What the slope rule before issue 14 chose at point `j`: (alpha, EDF).
fn old_rule(kind: Kind, points: &[AllanPoint], j: usize, phase_len: usize) -> (i32, f64) {
    let curve: Vec<(f64, f64)> = points.iter().map(|p| (p.tau, p.dev)).collect();
    let mu = local_variance_slope(&curve, j).map_or(-1.0, |s| s.0);
    let alpha = edf::alpha_from_slope(mu, kind.order());
    let e = edf_greenhall(
        alpha,
        kind.order(),
        points[j].m,
        phase_len,
        kind != Kind::Adev,
        kind == Kind::Mdev,
    );
    (alpha, e)
}

/// The checks every curve must pass; returns the number of points flagged as not identified.
fn check_curve(label: &str, kind: Kind, y: &[f64], rate: f64) -> usize {
    let points = allan(y, rate, kind, &TauGrid::Octave, ONE_SIGMA).expect("long enough");
    let phase_len = y.len() + 1;
    let mut flagged = 0;
    let mut last_identified = None;
    for p in &points {
        let spans = edf::tau_spans(phase_len, p.m);
        let (min_edf, max_edf) = edf::edf_bounds(p.n);
        assert!(
            p.edf >= min_edf && p.edf <= max_edf,
            "{label} tau {}: EDF {} outside [{min_edf}, {max_edf}]",
            p.tau,
            p.edf
        );
        assert!(p.lo < p.dev && p.dev < p.hi, "{label} tau {}", p.tau);
        match p.noise_id {
            NoiseId::Slope => {
                assert_eq!(
                    flagged, 0,
                    "{label} tau {}: identified after a flagged point",
                    p.tau
                );
                assert!(spans >= MIN_SPANS, "{label} tau {}: {spans} spans", p.tau);
                last_identified = Some(p.alpha);
            }
            NoiseId::Widest { lo, hi } => {
                flagged += 1;
                assert!(lo <= p.alpha && p.alpha <= hi, "{label} tau {}", p.tau);
                // The plausible types run from the floor up to the last one identified.
                assert_eq!(lo, edf::alpha_floor(kind.order()), "{label} tau {}", p.tau);
                assert_eq!(hi, last_identified.unwrap_or(2), "{label} tau {}", p.tau);
                // The record holds `spans` independent averages of this length: no noise redder
                // than white rate gives an Allan-type variance more than about 1.5 EDF per span.
                assert!(
                    p.edf <= 2.0 * spans as f64,
                    "{label} tau {}: EDF {} from {spans} spans",
                    p.tau,
                    p.edf
                );
                // Conservative: no narrower than the white-rate (or any plausible) interval.
                for alpha in lo..=hi {
                    let e = edf_greenhall(
                        alpha,
                        kind.order(),
                        p.m,
                        phase_len,
                        kind != Kind::Adev,
                        kind == Kind::Mdev,
                    );
                    assert!(
                        !(e.is_finite() && e > 0.0) || p.edf <= e.max(min_edf),
                        "{label} tau {}: EDF {} above alpha {alpha}'s {e}",
                        p.tau,
                        p.edf
                    );
                }
            }
        }
    }
    let last = points.last().expect("points");
    assert!(
        matches!(last.noise_id, NoiseId::Widest { .. }),
        "{label}: the last point (tau {}) claims an identified noise",
        last.tau
    );
    for (j, p) in points.iter().enumerate().rev().take(3) {
        let (a, e) = old_rule(kind, &points, j, phase_len);
        println!(
            "{label} tau {:>9.2}: alpha {} EDF {:.1} (+{:.1}%), before: alpha {a} EDF {e:.1}",
            p.tau,
            p.alpha,
            p.edf,
            100.0 * (p.hi / p.dev - 1.0)
        );
    }
    flagged
}

#[test]
fn issue_14_reproduction_adxrs450_3h_seed_3() {
    let (axes, rate) = record("adxrs450", 3, 3.0 * 3600.0);
    let y = &axes[0];
    assert_eq!(rate, 50.0);
    check_curve("adxrs450 seed 3", Kind::Oadev, y, rate);

    let points = allan(y, rate, Kind::Oadev, &TauGrid::Octave, ONE_SIGMA).unwrap();
    let j = points
        .iter()
        .position(|p| (p.tau - 2621.44).abs() < 1e-9)
        .expect("tau 2621.44 s");
    let p = points[j];
    // The record still triggers the old failure: the slope rule picks white phase there.
    let (old_alpha, old_edf) = old_rule(Kind::Oadev, &points, j, y.len() + 1);
    assert_eq!(old_alpha, 2, "the reproduction no longer reproduces");
    assert!(old_edf > 1e5, "old EDF {old_edf}");
    // Now: flagged, EDF at most the 4 spans' worth, an interval tens of percent wide.
    assert!(
        matches!(p.noise_id, NoiseId::Widest { .. }),
        "{:?}",
        p.noise_id
    );
    assert_eq!(edf::tau_spans(y.len() + 1, p.m), 4);
    assert!(p.edf <= 4.0, "EDF {}", p.edf);
    assert!(
        p.hi / p.dev - 1.0 > 0.5,
        "upper end +{}",
        p.hi / p.dev - 1.0
    );
    assert!(
        1.0 - p.lo / p.dev > 0.15,
        "lower end -{}",
        1.0 - p.lo / p.dev
    );
}

#[test]
fn long_taus_are_conservative_on_other_seeds_profiles_and_kinds() {
    for seed in [0, 1, 2, 4, 5, 7] {
        let (axes, rate) = record("adxrs450", seed, 3.0 * 3600.0);
        let flagged = check_curve(
            &format!("adxrs450 seed {seed}"),
            Kind::Oadev,
            &axes[0],
            rate,
        );
        // 3 h: the far neighbour has 30 spans up to tau 180 s, so the octaves from 327.68 s on.
        assert_eq!(flagged, 5, "adxrs450 seed {seed}");
    }
    for seed in [0, 3] {
        let (axes, rate) = record("adis16405", seed, 3.0 * 3600.0);
        for (a, y) in axes.iter().enumerate() {
            check_curve(
                &format!("adis16405 seed {seed} axis {a}"),
                Kind::Oadev,
                y,
                rate,
            );
        }
    }
    let (axes, rate) = record("adxrs450", 3, 3600.0);
    for kind in [Kind::Adev, Kind::Mdev, Kind::Hdev] {
        check_curve(&format!("adxrs450 1 h {kind}"), kind, &axes[0], rate);
    }
}
