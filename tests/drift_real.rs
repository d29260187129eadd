//! The drift model on the real ADIS16405 static log (path from `DRIFTLESS_ADIS16405`; CI sets
//! it, locally `/work/shared/data/adis16405-imu1-static-100hz.csv.gz`).

use std::path::PathBuf;
use std::process::Command;

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

#[test]
fn real_log_train_and_table3() {
    let Some(log) = log() else { return };
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("adis.json");
    let o = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .arg("train")
        .arg(&log)
        .args(["--rate", "100", "--column", "gyro_x_degps", "-o"])
        .arg(&model)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    println!("{out}{}", String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success());
    let m = driftless::io::model_file::read_model(&model).unwrap();
    let s = |name: &str| {
        m.scores
            .iter()
            .find(|s| s.name.starts_with(name))
            .unwrap()
            .clone()
    };
    let (p, rbf) = (s("persistence"), s("RBF"));
    // One step ahead the low band is smooth: any model with momentum beats persistence.
    assert!(rbf.skill > 0.9, "one-step skill {}", rbf.skill);
    // Free-running for 1 s it must still beat persistence.
    assert!(
        rbf.free_rmse < p.free_rmse,
        "{} vs {}",
        rbf.free_rmse,
        p.free_rmse
    );

    let o = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .arg("eval")
        .arg(&log)
        .arg("--model")
        .arg(&model)
        .args(["--to", "400000", "--json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        v["from"], 99_000,
        "the scored range starts where training ends"
    );
    let dev_at = |row: usize, tau: f64| -> f64 {
        v["table"][row]["oadev"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| (p[0].as_f64().unwrap(), p[1].as_f64().unwrap()))
            .min_by(|a, b| (a.0 / tau).ln().abs().total_cmp(&(b.0 / tau).ln().abs()))
            .unwrap()
            .1
    };
    let (raw, comp) = (dev_at(0, 80.0), dev_at(2, 80.0));
    println!("OADEV near 80 s: raw {raw:.3e}, compensated (RBF) {comp:.3e}");
    // The drift band is what compensation removes: the long-tau deviation must drop.
    assert!(comp < 0.5 * raw);
}
