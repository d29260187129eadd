//! `driftless train` and `driftless eval` on real files: determinism, the model file's round trip
//! and every way loading it can fail, bad input (exit code 2, one line, no panic), and the
//! baselines reported honestly.

mod common;

use common::text;

use driftless::drift::model::DriftModel;
use driftless::io::model_file::read_model;
use driftless::io::write_table;
use driftless::sim::{SimConfig, Simulator};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_driftless"))
}

fn sim_log(dir: &Path, name: &str, n: usize, seed: u64) -> PathBuf {
    let mut cfg = SimConfig::profile("adxrs450").unwrap();
    cfg.seed = seed;
    let mut sim = Simulator::new(&cfg).unwrap();
    let rate: Vec<f64> = (0..n).map(|_| sim.next_sample().measured[0]).collect();
    let path = dir.join(name);
    write_table(&path, &["rate_degps".into()], &[&rate]).unwrap();
    path
}

/// `driftless train` at 50 Hz on 12,000 + 2,000 samples unless `extra` sets --rate or --train.
fn train(input: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut c = bin();
    c.arg("train").arg(input).arg("-o").arg(out).args(extra);
    if !extra.contains(&"--rate") {
        c.args(["--rate", "50"]);
    }
    if !extra.contains(&"--train") {
        c.args(["--train", "12000", "--test", "2000"]);
    }
    c.output().unwrap()
}

/// A failed run: exit code 2, one line on stderr containing `want`, no panic.
fn assert_input_error(o: &Output, want: &str) {
    let (_, err) = text(o);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    assert!(err.contains(want), "expected '{want}' in: {err}");
}

#[test]
fn training_is_deterministic_for_a_seed_and_the_file_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let log = sim_log(dir.path(), "log.csv", 15_000, 3);

    let (a, b, c) = (
        dir.path().join("a.json"),
        dir.path().join("b.json"),
        dir.path().join("c.json"),
    );
    for (out, seed) in [(&a, "7"), (&b, "7"), (&c, "8")] {
        let o = train(&log, out, &["--seed", seed]);
        assert!(o.status.success(), "{:?}", text(&o));
    }
    let (ta, tb) = (
        std::fs::read_to_string(&a).unwrap(),
        std::fs::read_to_string(&b).unwrap(),
    );
    assert_eq!(ta, tb, "same seed, different model");
    let (ma, mc) = (read_model(&a).unwrap(), read_model(&c).unwrap());
    assert_ne!(
        ma.network.centres, mc.network.centres,
        "the seed changes nothing"
    );
    // Round trip: load, write, load gives the same model and the same text.
    let again = DriftModel::from_json(&ma.to_json()).unwrap();
    assert_eq!(again, ma);
    assert_eq!(format!("{}\n", again.to_json()), ta);
    // Provenance: the input's hash, the sample range and the seed.
    assert_eq!(ma.provenance.sha256.len(), 64);
    assert_eq!(
        (
            ma.provenance.train_len,
            ma.provenance.test_len,
            ma.provenance.seed
        ),
        (12_000, 2_000, 7)
    );
    assert_eq!(
        (ma.rate_hz, ma.units.name(), ma.axis.as_str()),
        (50.0, "deg/s", "rate_degps")
    );
}

#[test]
fn the_rbf_is_reported_beside_persistence_and_ar_honestly() {
    let dir = tempfile::tempdir().unwrap();
    let log = sim_log(dir.path(), "log.csv", 15_000, 4);
    let model = dir.path().join("m.json");
    let o = train(&log, &model, &[]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let rmse = |name: &str| -> f64 {
        let line = out
            .lines()
            .map(str::trim_start)
            .find(|l| l.starts_with(name))
            .unwrap_or_else(|| panic!("no {name} row: {out}"));
        let cols: Vec<&str> = line[name.len()..].split_whitespace().collect();
        cols[0].parse().unwrap()
    };
    // Data on stdout, messages on stderr.
    assert!(!out.contains("wrote"), "{out}");
    assert!(err.contains(&format!("wrote {}", model.display())), "{err}");
    let (p, ar, rbf) = (rmse("persistence"), rmse("AR(4)"), rmse("RBF(40 centres)"));
    let verdict = out.lines().find(|l| l.starts_with("model skill")).unwrap();
    // The verdict line says what the numbers say, whichever way they go.
    assert_eq!(
        verdict.contains("NOT better"),
        rbf >= ar,
        "{verdict} ({rbf} vs AR {ar})"
    );
    let skill: f64 = verdict
        .split_whitespace()
        .nth(4)
        .unwrap()
        .trim_end_matches(';')
        .parse()
        .unwrap();
    assert!(
        (skill - (1.0 - (rbf / p).powi(2))).abs() < 1e-3,
        "{skill} vs {rbf}/{p}"
    );
    // The saved scores are the printed ones.
    let m = read_model(&model).unwrap();
    let names: Vec<&str> = m.scores.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["persistence", "mean", "AR(4)", "RBF(40 centres)"]);

    // eval prints Table 3 with the three compensations and the paper's ratios; JSON parses.
    let table_svg = dir.path().join("t.svg");
    let o = bin()
        .arg("eval")
        .arg(&log)
        .arg("--model")
        .arg(&model)
        .arg("--plot")
        .arg(&table_svg)
        .output()
        .unwrap();
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(!out.contains("wrote"), "{out}");
    assert!(
        err.contains(&format!("wrote {}", table_svg.display())),
        "{err}"
    );
    for want in [
        "Table 3",
        " RBF ",
        " AR ",
        " persistence ",
        "deg/sqrt(h)",
        "0.46",
        "0.69",
        "0.61",
    ] {
        assert!(out.contains(want), "no '{want}' in {out}");
    }
    assert!(out.contains("samples 12000..15000 (held out"), "{out}");
    // Table 3's terms in data-sheet units, as `allan` prints them; per second on request.
    let n_raw = |out: &str| -> f64 {
        let row = out
            .lines()
            .map(str::trim_start)
            .find(|l| l.starts_with("N "))
            .unwrap_or_else(|| panic!("no N row: {out}"));
        row.split_whitespace()
            .nth(2)
            .unwrap()
            .trim_end_matches('*')
            .parse()
            .unwrap()
    };
    let o = bin()
        .arg("eval")
        .arg(&log)
        .arg("--model")
        .arg(&model)
        .args(["--term-units", "seconds"])
        .output()
        .unwrap();
    let per_second = text(&o).0;
    assert!(per_second.contains("deg/sqrt(s)"), "{per_second}");
    let ratio = n_raw(&out) / n_raw(&per_second);
    assert!((ratio - 60.0).abs() < 0.05, "N: {ratio}");
    let svg = dir.path().join("f.svg");
    let o = bin()
        .arg("eval")
        .arg(&log)
        .arg("--model")
        .arg(&model)
        .arg("--json")
        .arg("--plot")
        .arg(&svg)
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["table"].as_array().unwrap().len(), 5);
    assert!(std::fs::read_to_string(&svg).unwrap().contains("Figure 11"));
}

#[test]
fn every_bad_model_file_is_refused_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let log = sim_log(dir.path(), "log.csv", 15_000, 5);
    let good = dir.path().join("m.json");
    assert!(train(&log, &good, &["--centres", "8"]).status.success());
    let text_good = std::fs::read_to_string(&good).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text_good).unwrap();
    let edit = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut v = v.clone();
        f(&mut v);
        serde_json::to_string(&v).unwrap()
    };
    let cases: Vec<(String, &str)> = vec![
        (
            text_good[..text_good.len() / 2].to_string(),
            "not a valid driftless model",
        ),
        ("hello".into(), "not a valid driftless model"),
        (
            edit(&|v| v["format"] = "something-else".into()),
            "not a driftless drift model",
        ),
        (
            edit(&|v| v["version"] = 2.into()),
            "version 2 is not supported",
        ),
        (
            edit(&|v| {
                v["network"]["centres"].as_array_mut().unwrap().pop();
            }),
            "centres has",
        ),
        (
            edit(&|v| v["network"]["widths"][0] = (-1.0).into()),
            "width is not positive",
        ),
        (
            edit(&|v| v["network"]["widths"][0] = serde_json::Value::Null),
            "not a valid driftless model",
        ),
        (
            edit(&|v| v["network"]["lags"] = 5.into()),
            "feature_mean has",
        ),
        (
            edit(&|v| v["units"] = "furlongs/s".into()),
            "units 'furlongs/s'",
        ),
        (edit(&|v| v["rate_hz"] = 0.into()), "rate_hz must be > 0"),
        (
            edit(&|v| v["stillness"]["window"] = 1.into()),
            "stillness window",
        ),
        (
            edit(&|v| {
                v["baselines"]["ar"]["coef"].as_array_mut().unwrap().pop();
            }),
            "baselines.ar has 3",
        ),
        (
            edit(&|v| v["separation"]["lowband"]["wavelet"] = "db99".into()),
            "unknown wavelet",
        ),
    ];
    for (i, (body, want)) in cases.iter().enumerate() {
        let bad = dir.path().join(format!("bad{i}.json"));
        std::fs::write(&bad, body).unwrap();
        let o = bin()
            .arg("eval")
            .arg(&log)
            .arg("--model")
            .arg(&bad)
            .output()
            .unwrap();
        assert_input_error(&o, want);
    }
    let o = bin()
        .arg("eval")
        .arg(&log)
        .arg("--model")
        .arg(dir.path().join("missing.json"))
        .output()
        .unwrap();
    assert_input_error(&o, "No such file");
}

#[test]
fn bad_input_is_refused_with_exit_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let log = sim_log(dir.path(), "log.csv", 15_000, 6);
    let model = dir.path().join("m.json");
    assert!(train(&log, &model, &["--centres", "8"]).status.success());
    let eval = |extra: &[&str]| {
        bin()
            .arg("eval")
            .arg(&log)
            .arg("--model")
            .arg(&model)
            .args(extra)
            .output()
            .unwrap()
    };
    assert_input_error(&eval(&["--rate", "100"]), "at 100 Hz but model");
    assert_input_error(&eval(&["--units", "rad/s"]), "in rad/s but model");
    assert_input_error(&eval(&["--column", "nope"]), "no column named 'nope'");
    assert_input_error(&eval(&["--from", "14995"]), "too few to evaluate");
    // Training: too little data for the lags and centres, too short a file, NaN, bad settings.
    let out = dir.path().join("x.json");
    assert_input_error(
        &train(&log, &out, &["--centres", "4000"]),
        "too little data",
    );
    assert_input_error(
        &train(&log, &out, &["--train", "20000"]),
        "has 15000 samples",
    );
    assert_input_error(
        &train(&log, &out, &["--method", "magic"]),
        "unknown centre method",
    );
    for (args, want) in [
        (&["--lags", "0"][..], "lags must be 1 to 32"),
        (&["--centres", "0"], "centres must be at least 1"),
        (&["--rate", "0"], "--rate must be a positive"),
        (
            &["--still-window", "1e9"],
            "more than the 12000 training samples",
        ),
        (
            &["--horizon=-1"],
            "for '--horizon <HORIZON>': \"-1\" is not a positive duration",
        ),
        (
            &["--still-window", "0ms"],
            "\"0ms\" is not a positive duration",
        ),
        (&["--drift-level", "30"], "low-band level must be 1 to 12"),
        (&["--lag", "100000"], "lag"),
        (&["--units", "furlongs/s"], "--units 'furlongs/s'"),
    ] {
        assert_input_error(&train(&log, &out, args), want);
    }
    assert_input_error(
        &train(&log, &out, &["--inputs", "relative", "--target", "next"]),
        "relative inputs need",
    );
    let mut rows = std::fs::read_to_string(&log)
        .unwrap()
        .lines()
        .map(String::from)
        .collect::<Vec<_>>();
    rows[5001] = "NaN".into();
    let nan = dir.path().join("nan.csv");
    std::fs::write(&nan, rows.join("\n")).unwrap();
    assert_input_error(
        &train(&nan, &out, &[]),
        "nan.csv:5002:1: column 'rate_degps': NaN is not a finite sample",
    );
    assert!(!out.exists(), "a model was written for bad input");
    // A model trained at 50 Hz does not go into a 100 Hz daemon either: see tests/daemon.rs.
}

/// `predict.rbf` with `predictor = "ar"` is the model file's AR(p) baseline in the network's
/// place, in the same compensator (same low band, stillness gating, step limit): the stage's
/// drift is that compensator's, sample for sample, and not the network's. An unknown predictor is
/// refused at its place in the pipeline file.
#[test]
fn predict_rbf_with_the_ar_predictor_is_the_models_ar_in_the_same_compensator() {
    use driftless::drift::compensator::Compensator;
    use driftless::pipeline::config;
    use driftless::wire::GyroSample;
    let dir = tempfile::tempdir().unwrap();
    let log = sim_log(dir.path(), "log.csv", 15_000, 5);
    let model_path = dir.path().join("m.json");
    let o = train(&log, &model_path, &[]);
    assert!(o.status.success(), "{}", text(&o).1);
    let model = read_model(&model_path).unwrap();
    let pipeline = |predictor: &str| {
        format!(
            "name = \"a\"\nrate_hz = 50.0\naxes = 1\ninput_units = \"deg/s\"\n\
             [[stage]]\nname = \"sensor\"\nkind = \"ingest.sim\"\noutput = \"a/raw\"\n\
             [[stage]]\nname = \"predict\"\nkind = \"predict.rbf\"\nmodel = \"m.json\"\n{predictor}\n\
             input = \"a/raw\"\noutput = \"a/predicted\"\n\
             [[stage]]\nname = \"publish\"\nkind = \"publish\"\ninput = \"a/predicted\"\noutput = \"a/corrected\"\n"
        )
    };
    // Still with a bias, a 20 deg/s turn, still: every mode of the compensator.
    let input: Vec<f64> = (0..6000)
        .map(|t| {
            0.4 + 0.01 * ((t * 7919 % 11) as f64 - 5.0)
                + if (2500..3500).contains(&t) { 20.0 } else { 0.0 }
        })
        .collect();
    let drifts = |predictor: &str| -> Vec<f64> {
        let file = dir.path().join("p.toml");
        std::fs::write(&file, pipeline(predictor)).unwrap();
        let p = config::load(&file).expect("valid pipeline");
        let spec = p.stages.iter().find(|s| s.name == "predict").unwrap();
        let mut stage = spec.params.stage(&p.context()).expect("stage");
        input
            .iter()
            .enumerate()
            .map(|(t, &x)| {
                let mut s = GyroSample {
                    seq: t as u64,
                    // As if a stage before had one: predict.rbf must not pass it on.
                    drift_std: [0.5; 3],
                    ..GyroSample::default()
                };
                s.denoised[0] = x.to_radians();
                let out = stage.process(&s).unwrap();
                // The RBF model has no uncertainty of its own: not provided.
                assert_eq!(out.drift_std, [-1.0; 3]);
                out.drift[0].to_degrees()
            })
            .collect()
    };
    let ar = drifts("predictor = \"ar\"");
    let mut c = Compensator::new(
        model.baselines.ar.clone(),
        model.lowband().unwrap(),
        model.stillness,
        model.max_step,
    )
    .unwrap();
    for (t, (&x, &d)) in input.iter().zip(&ar).enumerate() {
        let want = c.push(x).drift;
        assert!(
            (d - want).abs() <= 1e-9 * want.abs().max(1e-3),
            "sample {t}: {d} vs {want}"
        );
    }
    assert!(ar[1000..].iter().any(|&d| d != 0.0), "the AR compensated");
    let rbf = drifts("");
    assert_eq!(rbf, drifts("predictor = \"rbf\""), "rbf is the default");
    assert!(
        rbf.iter().zip(&ar).any(|(a, b)| (a - b).abs() > 1e-9),
        "the network and the AR give the same drift: the key did nothing"
    );
    let file = dir.path().join("p.toml");
    std::fs::write(&file, pipeline("predictor = \"arma\"")).unwrap();
    let e = config::load(&file).unwrap_err().to_string();
    assert!(
        e.contains("p.toml:13:13: unknown predictor \"arma\" (valid: \"rbf\", \"ar\")"),
        "{e}"
    );
}
