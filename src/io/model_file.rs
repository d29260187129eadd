//! Drift model files on disk: read and check, write atomically, and hash input files for
//! provenance.

use super::content::Content;
use crate::drift::model::DriftModel;
use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::Path;

/// What a model file is, for a file that holds something else.
const MODEL_TAKES: &str = "a model file is JSON text, as `driftless train` writes it";

/// Read and check a model file; the error is one line naming the file (one that does not
/// hold text says what it holds).
pub fn read_model(path: &Path) -> Result<DriftModel, String> {
    let sniffed = super::content::sniff(path).map_err(|e| format!("model {e}"))?;
    if !matches!(sniffed.content, Content::Text | Content::Stream) {
        return Err(format!("model {}", sniffed.refuse(MODEL_TAKES)));
    }
    let text =
        std::fs::read_to_string(path).map_err(|e| format!("model {}: {e}", path.display()))?;
    DriftModel::from_json(&text).map_err(|e| format!("model {}: {e}", path.display()))
}

/// Write a model file atomically (a reader never sees half a model).
pub fn write_model(path: &Path, model: &DriftModel) -> Result<(), String> {
    let mut text = model.to_json();
    text.push('\n');
    super::atomic::write_atomically(path, text.as_bytes())
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// SHA-256 of a file's bytes (as stored, before any decompression), lower-case hex.
pub fn sha256_file(path: &Path) -> Result<String, String> {
    let mut f = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = f
            .read(&mut buf)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}
