//! The live compensator (and so the `predict.rbf` stage) allocates nothing per sample: a
//! counting global allocator watches `push` after construction, through warming up, still and
//! moving stretches.

use driftless::drift::compensator::{Compensator, Mode};
use driftless::drift::stillness::StillnessConfig;
use driftless::drift::training::{train, TrainConfig};
use driftless::drift::LowBand;
#[path = "support/alloc_counter.rs"]
mod alloc_counter;

#[test]
fn push_allocates_nothing_in_any_mode() {
    let drift: Vec<f64> = (0..5000).map(|i| 0.1 * (i as f64 / 700.0).sin()).collect();
    let model = train(&drift, &TrainConfig::default(), &mut |_| {}).unwrap();
    let still = StillnessConfig {
        window: 20,
        var_enter: 0.02,
        var_exit: 0.01,
        mean_enter: 0.2,
        mean_exit: 0.1,
        settle: 50,
    };
    let mut c = Compensator::new(model, LowBand::new("db6", 5).unwrap(), still, 1e-3).unwrap();
    let (allocations, modes) = alloc_counter::allocations_during(|| {
        let mut modes = [0usize; 3];
        for t in 0..3000 {
            let x = 0.3 + if (1000..2000).contains(&t) { 5.0 } else { 0.0 };
            let s = c.push(x);
            modes[match s.mode {
                Mode::Warming => 0,
                Mode::Still => 1,
                Mode::Moving => 2,
            }] += 1;
        }
        modes
    });
    assert!(
        modes.iter().all(|&m| m > 0),
        "every mode exercised: {modes:?}"
    );
    assert_eq!(allocations, 0, "allocations during push");
}

/// The `predict.rbf` stage as the daemon builds it from a pipeline file, with the network or the
/// model's AR(p) in its place: `process` allocates nothing per sample either.
#[test]
fn the_predict_rbf_stage_allocates_nothing_per_sample() {
    use driftless::pipeline::config;
    use driftless::wire::GyroSample;
    use std::process::Command;
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("log.csv");
    let model = dir.path().join("m.json");
    let bin = env!("CARGO_BIN_EXE_driftless");
    let ok = |c: &mut Command| assert!(c.output().unwrap().status.success(), "{c:?}");
    ok(Command::new(bin)
        .args([
            "simulate",
            "--profile",
            "adxrs450",
            "--duration",
            "400s",
            "-o",
        ])
        .arg(&log));
    ok(Command::new(bin)
        .arg("train")
        .arg(&log)
        .args(["--rate", "50", "--train", "15000", "--test", "2000", "-o"])
        .arg(&model));
    let text = r#"
name = "a"
rate_hz = 50.0
axes = 1
[[stage]]
name = "sensor"
kind = "ingest.csv"
output = "a/raw"
file = "log.csv"
columns = ["gyro_x_degps"]
[[stage]]
name = "predict"
kind = "predict.rbf"
model = "m.json"
input = "a/raw"
output = "a/predicted"
[[stage]]
name = "publish"
kind = "publish"
input = "a/predicted"
output = "a/corrected"
"#;
    // The network and the model's AR baseline in its place.
    for predictor in ["rbf", "ar"] {
        let text = text.replace(
            "model = \"m.json\"",
            &format!("model = \"m.json\"\npredictor = \"{predictor}\""),
        );
        let file = dir.path().join("p.toml");
        std::fs::write(&file, &text).unwrap();
        let p = config::load(&file).expect("valid pipeline");
        let spec = p.stages.iter().find(|s| s.name == "predict").unwrap();
        let mut stage = spec.params.stage(&p.context()).expect("stage");
        let (allocations, n) = alloc_counter::allocations_during(|| {
            let mut n = 0;
            for t in 0..5000u64 {
                let mut s = GyroSample {
                    seq: t,
                    ..GyroSample::default()
                };
                s.denoised[0] = 0.01 + if (2000..3000).contains(&t) { 0.2 } else { 0.0 };
                if stage.process(&s).is_some() {
                    n += 1;
                }
            }
            n
        });
        assert_eq!(n, 5000);
        assert_eq!(
            allocations, 0,
            "allocations in predict.rbf process, predictor {predictor}"
        );
    }
}
