// The property each fuzz target checks, one function per parser a user feeds. Included by the
// fuzz targets (fuzz_targets/*.rs) and by tests/fuzz_regressions.rs, which runs every input of
// the seed corpora and every crash ever found through the same checks in CI.

/// `data` written to `name` in this thread's own scratch folder (made once per thread, so
/// parallel test threads never share a file).
pub fn scratch_file(name: &str, data: &[u8]) -> std::path::PathBuf {
    thread_local! {
        static DIR: std::path::PathBuf = {
            let d = std::env::temp_dir().join(format!(
                "driftless-fuzz-{}-{:?}",
                std::process::id(),
                std::thread::current().id()
            ));
            std::fs::create_dir_all(&d).expect("temporary folder");
            d
        };
    }
    let path = DIR.with(|d| d.join(name));
    std::fs::write(&path, data).expect("temporary file");
    path
}

/// A pipeline file: parsing and validation never panic; a file that validates builds its
/// stages and passes 64 samples offline, each exactly once.
pub fn check_pipeline_toml(data: &[u8]) {
    use driftless::pipeline::config::parse;
    use driftless::pipeline::offline::Offline;
    use driftless::wire::RawSample;
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    // Relative paths in the file (CSV logs, models) resolve against the working directory.
    let Ok(p) = parse(std::path::Path::new("fuzz.toml"), text) else {
        return;
    };
    let Ok(mut offline) = Offline::new(&p) else {
        return;
    };
    let mut out = 0usize;
    for seq in 0..64u64 {
        let raw = RawSample {
            t_ns: seq * 1_000_000,
            seq,
            rate: [0.01, -0.02, 0.03],
            flags: driftless::wire::RAW_ACCEL,
            accel: [0.1, -0.2, 9.8],
            ..RawSample::default()
        };
        offline.push(&raw, &mut |_| out += 1);
    }
    offline.finish(&mut |_| out += 1);
    assert_eq!(out, 64, "every sample comes out once");
}

/// A drift model file: refused with an error or loaded; a loaded model writes back to a
/// document that loads to the same model.
pub fn check_model_json(data: &[u8]) {
    use driftless::drift::model::DriftModel;
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(model) = DriftModel::from_json(text) else {
        return;
    };
    let written = model.to_json();
    let again = DriftModel::from_json(&written).expect("a loaded model writes a loadable file");
    assert_eq!(again.to_json(), written, "load and save round-trip");
}

/// A CSV log: the fast reader (memory map, parallel chunks, fast-float) and the reference
/// reader (the csv crate and `str::parse::<f64>`) agree bit for bit, or both refuse the file
/// with the same message (which names file, line and column).
pub fn check_csv(data: &[u8]) {
    use driftless::io::csv_table::{read_table, read_table_reference};
    let path = &scratch_file("log.csv", data);
    let fast = read_table(path, &[]);
    let reference = read_table_reference(path, &[]);
    match (fast, reference) {
        (Ok(a), Ok(b)) => {
            assert_eq!(a.names, b.names, "column names");
            assert_eq!(a.has_header, b.has_header);
            assert_eq!(a.columns.len(), b.columns.len());
            for (x, y) in a.columns.iter().zip(&b.columns) {
                let bits = |c: &[f64]| c.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(x), bits(y), "values, bit for bit");
            }
        }
        (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "the same refusal"),
        (a, b) => panic!("the readers disagree: fast {a:?}, reference {b:?}"),
    }
}

/// A recording (MCAP) for `ingest.mcap`: opening, listing, metadata and decoding every message
/// never panic (an error names the file), and a pipeline replaying it validates or is refused
/// with file:line:col.
pub fn check_recording(data: &[u8]) {
    use driftless::io::recording::{RawMessage, Recording, METADATA_NAME};
    let path = scratch_file("rec.mcap", data);
    let shown = path.display().to_string();
    match Recording::open(&path) {
        Err(e) => assert!(e.starts_with(&shown), "the error names the file: {e}"),
        Ok(rec) => {
            if let Err(e) = rec.metadata(METADATA_NAME) {
                assert!(e.starts_with(&shown), "{e}");
            }
            for c in rec.channels() {
                for m in rec.messages::<RawMessage>(&c.topic).take(100_000) {
                    if let Err(e) = m {
                        assert!(e.starts_with(&shown), "{e}");
                    }
                }
            }
        }
    }
    let pipeline = "name = \"f\"\nrate_hz = 100.0\n\n[[stage]]\nname = \"sensor\"\n\
        kind = \"ingest.mcap\"\noutput = \"f/raw\"\nfile = \"rec.mcap\"\n\n[[stage]]\n\
        name = \"publish\"\nkind = \"publish\"\ninput = \"f/raw\"\noutput = \"f/corrected\"\n";
    let toml = path.with_file_name("p.toml");
    if let Err(e) = driftless::pipeline::config::parse(&toml, pipeline) {
        let e = e.to_string();
        assert!(e.starts_with(&format!("{}:8:", toml.display())), "{e}");
    }
}

/// A gzip-compressed CSV log: the fuzz input as a `.csv.gz` file (read by its content: gzip,
/// or the text it is) read by both readers as [`check_csv`] does; and the input gzipped, read
/// through the streaming path (decompression, blocks handed between threads), gives what the
/// plain file gives, value for value, or the same refusal at the same line and column. An
/// input that is gzip itself is read decompressed from the plain file too (by its content,
/// whatever its name): the first check covers it.
pub fn check_csv_gz(data: &[u8]) {
    use driftless::io::csv_table::{read_table, read_table_reference, Table};
    use std::io::Write;
    let bits = |t: &Table| -> Vec<Vec<u64>> {
        let col = |c: &Vec<f64>| c.iter().map(|v| v.to_bits()).collect();
        t.columns.iter().map(col).collect()
    };
    let raw = &scratch_file("raw.csv.gz", data);
    match (read_table(raw, &[]), read_table_reference(raw, &[])) {
        (Ok(a), Ok(b)) => assert_eq!(bits(&a), bits(&b), "the gzip file, both readers"),
        (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "the same refusal"),
        (a, b) => panic!("the readers disagree: fast {a:?}, reference {b:?}"),
    }
    if data.starts_with(&[0x1f, 0x8b]) {
        return;
    }
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(data).expect("gzip into memory");
    let packed = &scratch_file("log.csv.gz", &gz.finish().expect("gzip into memory"));
    let plain = &scratch_file("log.csv", data);
    match (read_table(packed, &[]), read_table(plain, &[])) {
        (Ok(a), Ok(b)) => {
            assert_eq!(a.names, b.names, "column names");
            assert_eq!(bits(&a), bits(&b), "values, bit for bit");
        }
        (Err(a), Err(b)) => {
            // The same message after each file's own path (a column may be named like a file).
            let (a, b) = (a.to_string(), b.to_string());
            let after = |m: &str, p: &std::path::Path| {
                let p = p.display().to_string();
                m.strip_prefix(&p).map(str::to_string)
            };
            assert_eq!(
                after(&a, packed),
                after(&b, plain),
                "the same refusal at the same place"
            );
            assert!(after(&a, packed).is_some(), "the error names the file: {a}");
        }
        (a, b) => panic!("gzip and plain disagree: gzip {a:?}, plain {b:?}"),
    }
}
