// The property each fuzz target checks, one function per parser a user feeds. Included by the
// fuzz targets (fuzz_targets/*.rs) and by tests/fuzz_regressions.rs, which runs every input of
// the seed corpora and every crash ever found through the same checks in CI.

/// A pipeline file: parsing and validation never panic; a file that validates builds its
/// stages and passes 64 samples offline, each exactly once.
pub fn check_pipeline_toml(data: &[u8]) {
    use driftless::pipeline::config::parse;
    use driftless::pipeline::offline::Offline;
    use driftless::transport::RawSample;
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
            flags: 0,
            epoch: 0,
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
