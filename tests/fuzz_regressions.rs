//! Every input of the fuzzers' seed corpora (`fuzz/corpus/TARGET`) and every crash they ever
//! found (`fuzz/regressions/TARGET`) through the same checks the fuzz targets run
//! (`fuzz/checks.rs`), so CI keeps them fixed. Fuzzing itself: `fuzz/run.sh TARGET SECONDS`.

#![allow(dead_code)] // not every check has inputs in every build

include!("../fuzz/checks.rs");

fn inputs(target: &str) -> Vec<(std::path::PathBuf, Vec<u8>)> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut out = Vec::new();
    for dir in ["corpus", "regressions"] {
        let Ok(entries) = std::fs::read_dir(root.join(dir).join(target)) else {
            continue;
        };
        for e in entries.flatten() {
            let path = e.path();
            out.push((path.clone(), std::fs::read(&path).expect("readable input")));
        }
    }
    out.sort();
    out
}

fn run_all(target: &str, check: fn(&[u8])) {
    let inputs = inputs(target);
    assert!(!inputs.is_empty(), "no inputs for {target}");
    for (path, data) in &inputs {
        if std::panic::catch_unwind(|| check(data)).is_err() {
            panic!("{} fails its fuzz check", path.display());
        }
    }
}

#[test]
fn pipeline_files_of_the_corpus_and_past_crashes() {
    run_all("pipeline_toml", check_pipeline_toml);
}

#[test]
fn model_files_of_the_corpus_and_past_crashes() {
    run_all("model_json", check_model_json);
}

#[test]
fn csv_logs_of_the_corpus_and_past_crashes() {
    run_all("csv", check_csv);
}

#[test]
fn recordings_of_the_corpus_and_past_crashes() {
    run_all("recording", check_recording);
}

#[test]
fn gzip_csv_logs_of_the_corpus_and_past_crashes() {
    run_all("csv_gz", check_csv_gz);
}
