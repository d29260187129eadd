//! Input files are read by what they hold, their names only a hint (docs/commands.md,
//! "Files"): a CSV named `.mcap`, an MCAP named `.csv`, gzip named `.csv` and plain text named
//! `.csv.gz` are read by their content with one warning line saying so, and give what the
//! rightly named file gives; garbage is exit 2 naming the file and what it is not. The same for
//! a pipeline's `ingest.csv` and `ingest.mcap` files, and a model file. Real binary, real files.

mod common;

use std::path::{Path, PathBuf};

use common::{driftless, finish, run_command, text, Dir, Prefix};

/// A still gyro at 100 Hz, three axes, 3,000 rows.
fn csv() -> String {
    let mut s = String::from("t,x,y,z\n");
    for i in 0..3000 {
        let v = 0.1 * (i as f64 * 0.37).sin() + 0.01 * ((i * 7919) % 13) as f64;
        s.push_str(&format!("{:.2},{v:.6},{:.6},0.5\n", i as f64 / 100.0, -v));
    }
    s
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    std::io::Write::write_all(&mut enc, bytes).unwrap();
    enc.finish().unwrap()
}

fn put(dir: &Dir, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.path(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn bag_fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/ros2/imu.mcap")
}

/// `driftless allan FILE ARGS...`: exit code, stdout, stderr.
fn allan(file: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let mut all = vec!["allan", file.to_str().unwrap()];
    all.extend(args);
    let o = driftless(&all);
    let (out, err) = text(&o);
    (o.status.code(), out, err)
}

/// Exit 2, one `driftless: error:` line holding every needle, never a panic.
fn assert_refused(code: Option<i32>, err: &str, needles: &[&str]) {
    assert_eq!(code, Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(err.starts_with("driftless: error: "), "{err}");
    for n in needles {
        assert!(err.contains(n), "{n:?} not in: {err}");
    }
}

#[test]
fn garbage_named_mcap_is_exit_2_saying_it_is_not_an_mcap_file() {
    let dir = Dir::new();
    let x = put(&dir, "x.mcap", &common::garbage());
    let (code, out, err) = allan(&x, &["--rate", "100"]);
    assert!(out.is_empty(), "{out}");
    assert_refused(
        code,
        &err,
        &[
            &format!(
                "{}: not an MCAP file (no MCAP magic at its start)",
                x.display()
            ),
            "it holds binary data",
        ],
    );
    // Named for CSV, or for nothing: what it is not is what the name claimed.
    let (code, _, err) = allan(&put(&dir, "x.csv", &common::garbage()), &["--rate", "100"]);
    assert_refused(code, &err, &["x.csv: not CSV text: it holds binary data"]);
    let (code, _, err) = allan(&put(&dir, "x.log", &common::garbage()), &["--rate", "100"]);
    assert_refused(
        code,
        &err,
        &["x.log: it holds binary data; a rate log is CSV text"],
    );
    // A format we do not read: what to do.
    let mut zstd = vec![0x28, 0xb5, 0x2f, 0xfd];
    zstd.extend(common::garbage());
    let (code, _, err) = allan(&put(&dir, "z.csv", &zstd), &["--rate", "100"]);
    assert_refused(
        code,
        &err,
        &["it holds a zstd stream (decompress it first)"],
    );
}

#[test]
fn a_file_named_for_another_format_is_read_by_what_it_holds_with_one_line() {
    let dir = Dir::new();
    let plain = put(&dir, "log.csv", csv().as_bytes());
    let (code, want, err) = allan(&plain, &["--rate", "100"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.is_empty(), "a rightly named file says nothing: {err}");
    for (name, bytes, line) in [
        (
            "log.mcap",
            csv().into_bytes(),
            "log.mcap: named .mcap but holds text: read as CSV",
        ),
        (
            "packed.csv",
            gzip(csv().as_bytes()),
            "packed.csv: named .csv but holds a gzip stream of text: read decompressed, as CSV",
        ),
        (
            "plain.csv.gz",
            csv().into_bytes(),
            "plain.csv.gz: named .gz but holds text: read as CSV",
        ),
    ] {
        let f = put(&dir, name, &bytes);
        let (code, out, err) = allan(&f, &["--rate", "100"]);
        assert_eq!(code, Some(0), "{name}: {err}");
        assert_eq!(
            err.trim_end(),
            format!("driftless: warning: {}/{line}", dir.dir.path().display()),
            "{name}: one line"
        );
        // The same samples: the same deviations, to the last digit (the header names the
        // column, not the file).
        assert_eq!(out, want, "{name}");
    }

    // An MCAP named .csv: read as the bag it is.
    let bag = bag_fixture();
    let (code, want, err) = allan(&bag, &["--topic", "/imu/data"]);
    assert_eq!(code, Some(0), "{err}");
    let named_csv = put(&dir, "imu.csv", &std::fs::read(&bag).unwrap());
    let (code, out, err) = allan(&named_csv, &["--topic", "/imu/data"]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(
        err.trim_end(),
        format!(
            "driftless: warning: {}: named .csv but holds an MCAP file: read as a ROS 2 bag",
            named_csv.display()
        )
    );
    assert_eq!(out, want);
}

/// A pipeline replaying `file` with `kind` to publish; 100 Hz in rad/s (a bag's units).
fn pipeline(dir: &Dir, name: &str, kind: &str, file: &str) -> PathBuf {
    let extra = if kind == "ingest.csv" {
        "time_column = \"t\"\n"
    } else {
        "topic = \"/imu/data\"\n"
    };
    dir.write(
        &format!("{name}.toml"),
        &format!(
            r#"name = "{name}"
rate_hz = 100.0
input_units = "rad/s"

[iceoryx2]
buffer_size = 4096

[[stage]]
name = "sensor"
kind = "{kind}"
output = "{name}/raw"
file = "{file}"
pace = "asap"
{extra}
[[stage]]
name = "publish"
kind = "publish"
input = "{name}/raw"
output = "{name}/corrected"
"#
        ),
    )
}

fn validate(p: &Path) -> (Option<i32>, String, String) {
    let o = driftless(&["validate", p.to_str().unwrap()]);
    let (out, err) = text(&o);
    (o.status.code(), out, err)
}

#[test]
fn a_pipelines_ingest_file_is_read_by_what_it_holds_and_refused_for_the_other_kind() {
    let dir = Dir::new();
    put(&dir, "log.mcap", csv().as_bytes());
    std::fs::copy(bag_fixture(), dir.path("bag.csv")).unwrap();
    put(&dir, "junk.csv", &common::garbage());

    // A CSV named .mcap, replayed by ingest.csv: valid, one line.
    let p = pipeline(&dir, "csvmcap", "ingest.csv", "log.mcap");
    let (code, out, err) = validate(&p);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("is valid"), "{out}");
    assert_eq!(
        err.trim_end(),
        format!(
            "driftless: warning: {}: stage \"sensor\": {}: named .mcap but holds text: read as \
             CSV",
            p.display(),
            dir.path("log.mcap").display()
        )
    );
    // An MCAP named .csv, replayed by ingest.mcap: valid, one line.
    let p = pipeline(&dir, "mcapcsv", "ingest.mcap", "bag.csv");
    let (code, out, err) = validate(&p);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("replays 1800 messages of /imu/data"), "{out}");
    assert_eq!(
        err.trim_end(),
        format!(
            "driftless: warning: {}: stage \"sensor\": {}: named .csv but holds an MCAP file: \
             read as MCAP",
            p.display(),
            dir.path("bag.csv").display()
        )
    );
    // The kind claims more than the name: the other format is refused, naming the kind to use,
    // at the file key's line and column.
    for (kind, file, needles) in [
        (
            "ingest.mcap",
            "log.mcap",
            [
                "log.mcap: not an MCAP file (no MCAP magic at its start): it holds text",
                "a CSV log is replayed by kind = \"ingest.csv\"",
            ],
        ),
        (
            "ingest.csv",
            "bag.csv",
            [
                "bag.csv: not CSV text: it holds an MCAP file",
                "is replayed by kind = \"ingest.mcap\"",
            ],
        ),
        (
            "ingest.csv",
            "junk.csv",
            [
                "junk.csv: not CSV text: it holds binary data",
                "ingest.csv replays",
            ],
        ),
        (
            "ingest.mcap",
            "junk.csv",
            [
                "junk.csv: not CSV text: it holds binary data",
                "ingest.mcap replays",
            ],
        ),
    ] {
        let p = pipeline(&dir, "other", kind, file);
        let (code, _, err) = validate(&p);
        let at = format!("{}:12:8: ", p.display());
        assert_refused(code, &err, &[&at, needles[0], needles[1]]);
    }
}

#[test]
fn run_replays_a_csv_named_mcap_whole_and_says_so_once() {
    let dir = Dir::new();
    put(&dir, "log.mcap", csv().as_bytes());
    let p = pipeline(&dir, "runcsv", "ingest.csv", "log.mcap");
    let prefix = Prefix::new("fmtrun");
    let out = run_command(&p, &prefix)
        .args(["--quiet", "--report"])
        .arg(dir.path("report.json"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn driftless");
    let (code, err) = finish(out, std::time::Duration::from_secs(60));
    assert_eq!(code, Some(0), "{err}");
    let note = "log.mcap: named .mcap but holds text: read as CSV";
    assert_eq!(
        err.matches(note).count(),
        1,
        "said once, not per pass: {err}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path("report.json")).unwrap()).unwrap();
    assert_eq!(report["samples_out"], 3000, "every row: {report}");
}

#[test]
fn a_model_file_that_is_not_json_text_says_what_it_holds() {
    let dir = Dir::new();
    let log = put(&dir, "log.csv", csv().as_bytes());
    for (name, bytes, needle) in [
        (
            "m.json",
            common::garbage(),
            "m.json: not JSON text: it holds binary data",
        ),
        (
            "g.json",
            gzip(b"{\"a\": 1}"),
            "g.json: not JSON text: it holds a gzip stream of text",
        ),
    ] {
        let model = put(&dir, name, &bytes);
        let o = driftless(&[
            "eval",
            log.to_str().unwrap(),
            "--model",
            model.to_str().unwrap(),
        ]);
        let (_, err) = text(&o);
        assert_refused(
            o.status.code(),
            &err,
            &[needle, "a model file is JSON text"],
        );
    }
}
