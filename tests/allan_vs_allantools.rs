//! driftless's Allan deviations, EDF and intervals against allantools 2024.6
//! (fixtures from scripts/gen_allantools_fixtures.py; the data sets are regenerated here bit for bit).

use driftless::allan::chi2::{confidence_interval, ONE_SIGMA};
use driftless::allan::edf::edf_greenhall;
use driftless::allan::{allan, Kind, NoiseId, TauGrid};
use serde_json::Value;

fn fixture(name: &str) -> Value {
    let path = format!(
        "{}/tests/fixtures/allantools/{name}",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let v: Value = serde_json::from_str(&text).expect("fixture is JSON");
    assert_eq!(v["generator"]["allantools"], "2024.6");
    v
}

fn nbs14_1000() -> Vec<f64> {
    let mut n = vec![1_234_567_890u64];
    for _ in 0..999 {
        let last = n[n.len() - 1];
        n.push((16807 * last) % 2_147_483_647);
    }
    assert_eq!(&n[1..4], &[395_529_916, 1_209_410_747, 633_705_974]);
    n.iter().map(|&v| v as f64 / 2_147_483_647.0).collect()
}

fn dataset(name: &str) -> Vec<f64> {
    match name {
        "nbs14" => vec![
            892.0, 809.0, 823.0, 798.0, 671.0, 644.0, 883.0, 903.0, 677.0,
        ],
        "nbs14_1000" => nbs14_1000(),
        "white_4096" => {
            let mut g = driftless::synthetic::SplitMix64(1);
            (0..4096)
                .map(|_| g.next().expect("endless") - 0.5)
                .collect()
        }
        "random_walk_3000" => {
            let mut g = driftless::synthetic::SplitMix64(2);
            let mut s = 0.0;
            (0..3000)
                .map(|_| {
                    s += g.next().expect("endless") - 0.5;
                    s
                })
                .collect()
        }
        "gyro_like_20000" => {
            let mut g = driftless::synthetic::SplitMix64(3);
            let mut rw = 0.0;
            (0..20000)
                .map(|k| {
                    let a = g.next().expect("endless");
                    let b = g.next().expect("endless");
                    rw += b - 0.5;
                    ((a - 0.5) * 2.0 + rw * 0.01) + (1e-4 * k as f64 + 3.0)
                })
                .collect()
        }
        "white_32768" => {
            let mut g = driftless::synthetic::SplitMix64(11);
            (0..32768)
                .map(|_| g.next().expect("endless") - 0.5)
                .collect()
        }
        "random_walk_32768" => {
            let mut g = driftless::synthetic::SplitMix64(12);
            let mut s = 0.0;
            (0..32768)
                .map(|_| {
                    s += g.next().expect("endless") - 0.5;
                    s
                })
                .collect()
        }
        other => panic!("unknown data set {other}"),
    }
}

fn rel(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        ((a - b) / b).abs()
    }
}

#[test]
fn deviations_match_allantools() {
    let fx = fixture("deviations.json");
    let cases = fx["cases"].as_array().expect("cases");
    assert!(cases.len() >= 40);
    let mut worst: f64 = 0.0;
    for case in cases {
        let data = dataset(case["data"].as_str().unwrap());
        let rate = case["rate"].as_f64().unwrap();
        let kind: Kind = case["kind"].as_str().unwrap().parse().unwrap();
        let grid = match case["grid"].as_str().unwrap() {
            "list" => TauGrid::List(
                case["taus_in"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_f64().unwrap())
                    .collect(),
            ),
            g => g.parse().unwrap(),
        };
        let label = format!("{} {} {} ", case["data"], kind, case["grid"]);
        let got = allan(&data, rate, kind, &grid, 0.683).unwrap();
        let tau: Vec<f64> = case["tau"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let dev: Vec<f64> = case["dev"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let n: Vec<u64> = case["n"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect();
        assert_eq!(got.len(), tau.len(), "{label}: number of points");
        for (k, p) in got.iter().enumerate() {
            assert_eq!(p.n as u64, n[k], "{label} tau {}: n", tau[k]);
            assert!(
                rel(p.tau, tau[k]) < 1e-15,
                "{label}: tau {} vs {}",
                p.tau,
                tau[k]
            );
            let e = rel(p.dev, dev[k]);
            worst = worst.max(e);
            assert!(
                e < 1e-9,
                "{label} tau {}: {} vs {} ({e:e})",
                tau[k],
                p.dev,
                dev[k]
            );
        }
    }
    println!("worst relative deviation error vs allantools: {worst:e}");
}

#[test]
fn greenhall_edf_matches_allantools() {
    let fx = fixture("edf.json");
    let mut worst: f64 = 0.0;
    for row in fx["cases"].as_array().unwrap() {
        let alpha = row["alpha"].as_i64().unwrap() as i32;
        let d = row["d"].as_u64().unwrap() as u32;
        let m = row["m"].as_u64().unwrap() as usize;
        let n = row["n"].as_u64().unwrap() as usize;
        let ov = row["overlapping"].as_bool().unwrap();
        let md = row["modified"].as_bool().unwrap();
        let want = row["edf"].as_f64().unwrap();
        let got = edf_greenhall(alpha, d, m, n, ov, md);
        let e = rel(got, want);
        worst = worst.max(e);
        assert!(
            e < 1e-9,
            "alpha {alpha} d {d} m {m} n {n} ov {ov} mod {md}: {got} vs {want}"
        );
    }
    println!("worst relative EDF error vs allantools: {worst:e}");
}

#[test]
fn chi_squared_intervals_match_allantools() {
    let fx = fixture("intervals.json");
    for row in fx["cases"].as_array().unwrap() {
        let (edf, ci, dev) = (
            row["edf"].as_f64().unwrap(),
            row["ci"].as_f64().unwrap(),
            row["dev"].as_f64().unwrap(),
        );
        let (lo, hi) = confidence_interval(dev, edf, ci);
        let (wlo, whi) = (row["lo"].as_f64().unwrap(), row["hi"].as_f64().unwrap());
        assert!(rel(lo, wlo) < 1e-9, "edf {edf} ci {ci}: lo {lo} vs {wlo}");
        assert!(rel(hi, whi) < 1e-9, "edf {edf} ci {ci}: hi {hi} vs {whi}");
    }
}

/// Issue 14: allantools' own noise identification (lag-1 autocorrelation) at every octave tau.
/// Where it identifies the noise and so does our slope, the type, EDF and interval agree; where
/// it refuses (fewer than 30 decimated points, `NotImplementedError`) we flag the point; where we
/// flag a point it still identifies (30 to 60 spans: our slope needs 30 at the far neighbour,
/// about 2 tau), our interval holds allantools'.
#[test]
fn noise_identification_and_long_taus_against_allantools() {
    let fx = fixture("noise_id.json");
    for case in fx["cases"].as_array().unwrap() {
        let name = case["data"].as_str().unwrap();
        let data = dataset(name);
        let rate = case["rate"].as_f64().unwrap();
        assert_eq!(case["phase_len"].as_u64().unwrap() as usize, data.len() + 1);
        let got = allan(&data, rate, Kind::Oadev, &TauGrid::Octave, ONE_SIGMA).unwrap();
        let want = case["points"].as_array().unwrap();
        assert_eq!(got.len(), want.len(), "{name}: number of points");
        let (mut same, mut refused, mut held) = (0, 0, 0);
        for (p, w) in got.iter().zip(want) {
            let label = format!("{name} m {}", p.m);
            assert_eq!(p.m as u64, w["m"].as_u64().unwrap(), "{label}");
            assert!(
                rel(p.dev, w["dev"].as_f64().unwrap()) < 1e-9,
                "{label}: dev"
            );
            match (p.noise_id, w["alpha"].as_i64()) {
                (NoiseId::Slope, Some(alpha)) => {
                    assert_eq!(i64::from(p.alpha), alpha, "{label}: noise type");
                    for key in ["edf", "lo", "hi"] {
                        let ours = match key {
                            "edf" => p.edf,
                            "lo" => p.lo,
                            _ => p.hi,
                        };
                        let theirs = w[key].as_f64().unwrap();
                        assert!(
                            rel(ours, theirs) < 1e-9,
                            "{label}: {key} {ours} vs {theirs}"
                        );
                    }
                    same += 1;
                }
                (NoiseId::Slope, None) => panic!("{label}: allantools refuses, we identify"),
                (NoiseId::Widest { .. }, None) => refused += 1,
                (NoiseId::Widest { .. }, Some(_)) => {
                    let (lo, hi) = (w["lo"].as_f64().unwrap(), w["hi"].as_f64().unwrap());
                    assert!(
                        p.edf <= w["edf"].as_f64().unwrap() * (1.0 + 1e-12),
                        "{label}"
                    );
                    assert!(
                        p.lo <= lo * (1.0 + 1e-12) && p.hi >= hi * (1.0 - 1e-12),
                        "{label}"
                    );
                    held += 1;
                }
            }
        }
        println!("{name}: {same} points as allantools, {held} wider, {refused} it refuses");
        assert!(
            same >= 10 && refused >= 3 && held >= 1,
            "{name}: {same} {held} {refused}"
        );
    }
}
