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
    assert_eq!(
        expected.len(),
        cases + pipelines,
        "a case without a recording"
    );
    assert!(cases >= 90, "only {cases} cases");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The stage table of docs/daemon.md is what `validate --kinds --markdown` prints from the
/// keys the stage files declare.
#[test]
fn the_documented_stage_table_is_the_generated_one() {
    let out = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .args(["validate", "--kinds", "--markdown"])
        .output()
        .expect("run driftless validate --kinds");
    assert_eq!(out.status.code(), Some(0));
    let generated = String::from_utf8(out.stdout).unwrap();
    for kind in ["ingest.sim", "denoise.wavelet", "predict.rbf", "publish"] {
        assert!(generated.contains(&format!("**`{kind}`**")), "{generated}");
    }
    let doc =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/daemon.md")).unwrap();
    let begin = doc.find("<!-- stage-kinds:begin").expect("begin marker");
    let body = &doc[doc[begin..].find('\n').unwrap() + begin + 1..];
    let end = body.find("<!-- stage-kinds:end -->").expect("end marker");
    assert_eq!(
        &body[..end],
        generated,
        "docs/daemon.md is stale: paste `driftless validate --kinds --markdown` between its markers"
    );
}

/// `validate --kinds` lists every kind's keys, one per line with type and default.
#[test]
fn kinds_lists_every_key_with_type_and_default() {
    let out = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .args(["validate", "--kinds"])
        .output()
        .expect("run driftless validate --kinds");
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8(out.stdout).unwrap();
    for line in [
        "  lag              int 0..=full lag",
        "  level            int 1..=12; default 5",
        "  poll_timeout_us  int 10..=1000000; default 1000",
        "  notify           bool; default true",
    ] {
        assert!(text.contains(line), "{line:?} in\n{text}");
    }
    // Without a pipeline and without --kinds, it is a usage error.
    let out = Command::new(env!("CARGO_BIN_EXE_driftless"))
        .arg("validate")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}
