//! The accelerometer of the real ADIS16405 6-axis static log (../shared/data, never copied into
//! the repository; its path from `DRIFTLESS_ADIS16405_6AXIS`): each axis's OADEV at every octave
//! tau against allantools 2024.6 (`tests/fixtures/allantools/accel_6axis.json`, from
//! `scripts/gen_allantools_accel_fixture.py`), the intervals where both identify the same noise,
//! and the terms `driftless allan --accel-column` reports (docs/allan.md's table).

use driftless::allan::analysis::analyse;
use driftless::allan::{AccelUnit, Kind, NoiseId, SampleUnit, Sensor, TauGrid, Term};
use driftless::drift::bias::{own_accel_terms, ColumnFit, MG_PER_M_S2, VRW_PER_HOUR};
use driftless::io::read_table;
use serde_json::Value;
use std::path::PathBuf;

const VAR: &str = "DRIFTLESS_ADIS16405_6AXIS";

fn log_path() -> Option<PathBuf> {
    match std::env::var_os(VAR) {
        Some(p) => Some(PathBuf::from(p)),
        None => {
            println!(
                "SKIP: {VAR} is not set (path of adis16405-imu1-static-100hz-6axis.csv.gz, e.g. {VAR}=../shared/data/adis16405-imu1-static-100hz-6axis.csv.gz)"
            );
            None
        }
    }
}

fn rel(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

/// What docs/allan.md prints for each axis: N m/s/sqrt(h), B mg (fitted, 68.3% intervals).
const DOCUMENTED: [(&str, f64, f64); 3] = [
    ("accel_x_g", 0.28030, 0.40809),
    ("accel_y_g", 0.21404, 0.33120),
    ("accel_z_g", 0.27512, 0.30231),
];

#[test]
fn accelerometer_oadev_matches_allantools_and_its_terms_are_the_documented_ones() {
    let Some(path) = log_path() else { return };
    let fx: Value = serde_json::from_str(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/fixtures/allantools/accel_6axis.json"
        ))
        .unwrap(),
    )
    .unwrap();
    let names: Vec<String> = DOCUMENTED.iter().map(|(n, _, _)| n.to_string()).collect();
    let table = read_table(&path, &names).unwrap_or_else(|e| panic!("{VAR}: {e}"));
    let unit = SampleUnit::Accel(AccelUnit::G);
    let mut analyses = Vec::new();
    for ((axis, y), want) in names
        .iter()
        .zip(&table.columns)
        .zip(fx["axes"].as_array().unwrap())
    {
        assert_eq!(want["column"].as_str(), Some(axis.as_str()));
        assert_eq!(y.len() as u64, want["samples"].as_u64().unwrap());
        let mean = y.iter().sum::<f64>() / y.len() as f64;
        assert!(
            rel(mean, want["mean"].as_f64().unwrap()) < 1e-9,
            "{axis}: mean"
        );
        let a = analyse(
            y,
            100.0,
            Kind::Oadev,
            &TauGrid::Octave,
            unit.to_base(),
            &mut |_| {},
        )
        .unwrap();
        let points = want["points"].as_array().unwrap();
        assert_eq!(a.points.len(), points.len(), "{axis}: number of taus");
        let (mut worst, mut same_noise, mut identified) = (0.0f64, 0, 0);
        for (p, w) in a.points.iter().zip(points) {
            let label = format!("{axis} m {}", p.m);
            assert_eq!(p.m as u64, w["m"].as_u64().unwrap(), "{label}");
            assert_eq!(p.n as u64, w["n"].as_u64().unwrap(), "{label}: n");
            let r = rel(p.dev, w["dev"].as_f64().unwrap());
            assert!(r < 1e-9, "{label}: dev {} vs {} ({r:e})", p.dev, w["dev"]);
            worst = worst.max(r);
            // The octave curve the fit uses is the same one, in m/s^2.
            let o = a.octave.iter().find(|o| o.m == p.m).unwrap();
            assert!(rel(o.dev, p.dev * 9.80665) < 1e-12, "{label}: in m/s^2");
            let Some(alpha) = w["alpha"].as_i64() else {
                // allantools refuses to identify the noise: so do we.
                assert!(matches!(p.noise_id, NoiseId::Widest { .. }), "{label}");
                continue;
            };
            identified += 1;
            // Where both identify the same noise, the interval is allantools' to 1e-9.
            if matches!(p.noise_id, NoiseId::Slope) && i64::from(p.alpha) == alpha {
                same_noise += 1;
                for (ours, key) in [(p.edf, "edf"), (p.lo, "lo"), (p.hi, "hi")] {
                    let theirs = w[key].as_f64().unwrap();
                    assert!(
                        rel(ours, theirs) < 1e-9,
                        "{label}: {key} {ours} vs {theirs}"
                    );
                }
            }
        }
        println!(
            "{axis}: {} taus, worst relative OADEV difference {worst:.1e}; the same noise type as allantools' lag-1 autocorrelation at {same_noise} of the {identified} taus it identifies",
            points.len()
        );
        // Real noise lies between the five types; still, most short taus agree.
        assert!(same_noise >= 6, "{axis}: {same_noise} of {identified}");
        analyses.push(a);
    }
    // The terms, per axis as `allan` prints them and combined as `allan --stage` writes them.
    let fits: Vec<ColumnFit> = analyses
        .iter()
        .zip(&names)
        .map(|(a, name)| ColumnFit {
            name,
            fit: a.fit.as_ref().unwrap(),
            points: &a.octave,
        })
        .collect();
    let sensor = Sensor::Accel;
    for ((f, (axis, n_doc, b_doc)), a) in fits.iter().zip(DOCUMENTED).zip(&analyses) {
        let n = f.fit.get(Term::N).estimate.expect("N identified");
        let b = f.fit.get(Term::B).estimate.expect("B identified");
        let (n_unit, n_f) = sensor.display(Term::N);
        let (b_unit, b_f) = sensor.display(Term::B);
        println!(
            "{axis}: N {:.5} {n_unit} [{:.5}, {:.5}], B {:.5} {b_unit} [{:.5}, {:.5}], K {}",
            n.value * n_f,
            n.lo * n_f,
            n.hi * n_f,
            b.value * b_f,
            b.lo * b_f,
            b.hi * b_f,
            f.fit.get(Term::K).reason.as_deref().unwrap_or("identified")
        );
        assert!(rel(n.value * n_f, n_doc) < 1e-4, "{axis}: N as documented");
        assert!(rel(b.value * b_f, b_doc) < 1e-4, "{axis}: B as documented");
        assert!(a.fit.is_ok());
    }
    let own = own_accel_terms(&fits).unwrap();
    let vrw = own.terms.vrw * VRW_PER_HOUR;
    let b_mg = own.terms.b * MG_PER_M_S2;
    assert!(rel(vrw, 0.28030) < 1e-4, "accel_vrw {vrw}");
    assert!(rel(b_mg, 0.33120) < 1e-4, "accel_bias_instability {b_mg}");
    println!(
        "allan --stage: accel_vrw = {vrw:.5} m/s/sqrt(h), accel_bias_instability = {b_mg:.5} mg; white noise per sample at 100 Hz {:.5} m/s^2",
        own.terms.white_std(100.0)
    );
}
