//! The heading benchmark on the real static ADIS16405 log with known motion added (path from
//! `DRIFTLESS_ADIS16405`; locally `/work/shared/data/adis16405-imu1-static-100hz.csv.gz`).
//!
//! Noise terms per axis come from `allan::fit_terms` on the first 33 min (rows 0-197,999) of
//! that axis. The log is cut into 16 windows of 10 min per axis; windows 0-3 overlap the
//! characterisation and were used to choose the defaults, so this test evaluates the held-out
//! windows 4-15 of all three axes under all four motion profiles (144 windows), and checks that
//! the result does not hang on the terms: with the x axis' terms on every axis, and with the
//! built-in adis16405 profile terms.

use driftless::allan::{allan, chi2::ONE_SIGMA, fit_terms, Kind, TauGrid};
use driftless::drift::bias::{own_terms, BiasTerms, ColumnFit};
use driftless::io::csv_table::read_table;
use driftless::nav::{
    evaluate, format_table, generate, summarize_methods, HeadingMetrics, Method, Profile, Setup,
};
use std::path::PathBuf;

const RATE: f64 = 100.0;
const WINDOW: usize = 60_000;
const CHARACTERISE: usize = 198_000;
const HELD_OUT: std::ops::Range<usize> = 4..16;

fn log() -> Option<PathBuf> {
    match std::env::var_os("DRIFTLESS_ADIS16405") {
        Some(p) => Some(PathBuf::from(p)),
        None => {
            println!(
                "SKIP: DRIFTLESS_ADIS16405 is not set (path of adis16405-imu1-static-100hz.csv.gz)"
            );
            None
        }
    }
}

fn terms_of(y: &[f64]) -> BiasTerms {
    let points = allan(y, RATE, Kind::Oadev, &TauGrid::Octave, ONE_SIGMA).unwrap();
    let fit = fit_terms(&points, ONE_SIGMA).unwrap();
    let column = ColumnFit {
        name: "axis",
        fit: &fit,
        points: &points,
    };
    own_terms(&[column], 0.05).unwrap().terms
}

/// Every held-out window of every axis under `profile`, with per-axis terms from `terms`.
fn run(
    axes: &[&[f64]],
    profile: Profile,
    terms: &dyn Fn(usize) -> BiasTerms,
    methods: &[Method],
) -> Vec<Vec<HeadingMetrics>> {
    let mut out = Vec::new();
    for (a, y) in axes.iter().enumerate() {
        let setup = Setup::new(terms(a), RATE);
        for w in HELD_OUT {
            let m = generate(profile, RATE, 600.0, (w * 3 + a) as u64).unwrap();
            let measured: Vec<f64> = y[w * WINDOW..(w + 1) * WINDOW]
                .iter()
                .zip(&m.truth)
                .map(|(x, t)| x + t)
                .collect();
            out.push(evaluate(&measured, &m.truth, &m.still, &setup, methods).unwrap());
        }
    }
    out
}

#[test]
fn the_bias_filter_on_the_real_log() {
    let Some(path) = log() else { return };
    let table = read_table(&path, &[]).unwrap();
    let axes: Vec<&[f64]> = ["gyro_x_degps", "gyro_y_degps", "gyro_z_degps"]
        .iter()
        .map(|c| table.column(c).expect("column"))
        .collect();
    assert!(axes[0].len() >= 16 * WINDOW);
    let own: Vec<BiasTerms> = axes.iter().map(|y| terms_of(&y[..CHARACTERISE])).collect();
    for (a, t) in own.iter().enumerate() {
        println!(
            "axis {a}: N {:.3} deg/sqrt(h), B {:.1} deg/h, K {:.2} deg/h/sqrt(h) (first 33 min)",
            t.n * 60.0,
            t.b * 3600.0,
            t.k * 216_000.0
        );
    }
    let methods = [
        Method::Raw,
        Method::PowerOn,
        Method::ZaruOracle,
        Method::ZaruDetected,
        Method::KfDetected,
        Method::KfOracle,
        Method::KfHold,
        Method::KfDenoised,
    ];
    let mut all = Vec::new();
    for p in Profile::ALL {
        let res = run(&axes, p, &|a| own[a], &methods);
        let rows = summarize_methods(&methods, &res, Method::ZaruOracle);
        println!("{}", format_table(&format!("real {p}, held out"), &rows));
        all.extend(res);
    }
    let rows = summarize_methods(&methods, &all, Method::ZaruOracle);
    println!("{}", format_table("real, all profiles, held out", &rows));
    let kf = rows[4].rms_ratio;
    let zd = rows[3].rms_ratio;

    // Sensitivity to the terms: the x axis' terms everywhere, and the built-in profile's.
    let short = [Method::ZaruOracle, Method::KfDetected];
    let profile_terms = BiasTerms::profile("adis16405").unwrap();
    for (name, terms) in [
        (
            "x-axis terms on all axes",
            &(|_| own[0]) as &dyn Fn(usize) -> BiasTerms,
        ),
        ("built-in adis16405 terms", &|_| profile_terms),
    ] {
        let mut res = Vec::new();
        for p in Profile::ALL {
            res.extend(run(&axes, p, terms, &short));
        }
        let r = summarize_methods(&short, &res, Method::ZaruOracle)[1].rms_ratio;
        println!(
            "{name}: KF detected / ZARU oracle median {:.3}, worst {:.3}",
            r.median, r.worst
        );
        assert!(
            r.median <= kf.median * 1.1 + 0.02,
            "{name}: {r:?} vs own terms {kf:?}"
        );
    }

    // What the new estimator reaches on held-out windows (docs/navigation.md). It does NOT
    // reach the goal (0.9x oracle ZARU at the median, 1.25x worst): measured 1.06x and
    // 4.5x. What it does reach, with its own stop detection: within 15% of oracle ZARU at the
    // median, clearly better than ZARU on the same detector at the median and in the worst
    // window, and far ahead of power-on bias.
    assert!(kf.median <= 1.15, "KF detected / ZARU oracle {kf:?}");
    assert!(
        kf.median < 0.9 * zd.median,
        "{kf:?} vs ZARU detected {zd:?}"
    );
    assert!(kf.worst < zd.worst, "{kf:?} vs ZARU detected {zd:?}");
    assert!(rows[1].rms.median > 2.0 * rows[4].rms.median);
}
