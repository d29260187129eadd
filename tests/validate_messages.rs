//! `driftless validate` prints exactly the recorded message for every shipped pipeline and for
//! one bad file per check of the pipeline schema (file:line:col, text, exit code).
//!
//! The cases are written by `tests/fixtures/validate/make_cases.py`; the expected outputs were
//! recorded by `tests/fixtures/validate/record.sh` from the binary before the schema moved into
//! the stage files, and re-recorded since only where a message changed on purpose.

use std::path::Path;
use std::process::Command;

const FIXTURES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/validate");

/// What `driftless validate FILE` prints, run in `dir`, in the format of `record.sh`.
fn shown(dir: &Path, file: &str) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .current_dir(dir)
        .arg("validate")
        .arg(file)
        .output()
        .expect("run driftless validate");
    format!(
        "exit: {}\nstdout:\n{}stderr:\n{}",
        out.status.code().map_or("signal".into(), |c| c.to_string()),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

#[test]
fn every_recorded_case_prints_its_recorded_message() {
    let fixtures = Path::new(FIXTURES);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut expected: Vec<_> = std::fs::read_dir(fixtures.join("expected"))
        .expect("expected outputs")
        .map(|e| e.expect("entry").path())
        .collect();
    expected.sort();
    let mut failures = Vec::new();
    let mut shipped = 0;
    for path in &expected {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        let want = std::fs::read_to_string(path).expect("read expected output");
        let got = match name.strip_prefix("shipped-") {
            Some(p) => {
                shipped += 1;
                shown(root, &format!("pipelines/{p}.toml"))
            }
            None => shown(fixtures, &format!("cases/{name}.toml")),
        };
        if got != want {
            failures.push(format!("--- {name}: expected\n{want}--- got\n{got}"));
        }
    }
    // Every shipped pipeline and every case has its recorded output.
    let pipelines = std::fs::read_dir(root.join("pipelines"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "toml")
        })
        .count();
    assert_eq!(shipped, pipelines, "a shipped pipeline without a recording");
    let cases = std::fs::read_dir(fixtures.join("cases"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "toml")
        })
        .count();
    assert_eq!(expected.len(), cases + pipelines, "a case without a recording");
    assert!(cases >= 90, "only {cases} cases");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
