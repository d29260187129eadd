//! Output files that appear whole or not at all: written to a temporary file beside the target,
//! then renamed over it. A failed or interrupted command leaves no partial output behind.

use std::fs::{File, Permissions};
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};

/// A file being written for `path`; invisible there until [`AtomicFile::commit`].
pub struct AtomicFile {
    tmp: tempfile::NamedTempFile,
    path: PathBuf,
}

impl AtomicFile {
    /// Start writing a file for `path` (the temporary file goes in the same directory, so the
    /// final rename cannot cross file systems).
    pub fn create(path: &Path) -> std::io::Result<AtomicFile> {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        Ok(AtomicFile {
            tmp: tempfile::NamedTempFile::new_in(dir)?,
            path: path.to_path_buf(),
        })
    }

    /// The open file to write to.
    pub fn file(&self) -> &File {
        self.tmp.as_file()
    }

    /// Make the file appear at its path. Temporary files are private (0600); an output file gets
    /// the usual 0644.
    pub fn commit(self) -> std::io::Result<()> {
        self.tmp
            .as_file()
            .set_permissions(Permissions::from_mode(0o644))?;
        self.tmp.persist(&self.path).map_err(|e| e.error)?;
        Ok(())
    }
}

/// Write `bytes` to `path` atomically.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let file = AtomicFile::create(path)?;
    std::io::Write::write_all(&mut file.file(), bytes)?;
    file.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn appears_whole_with_ordinary_permissions_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.txt");
        let f = AtomicFile::create(&p).unwrap();
        std::io::Write::write_all(&mut f.file(), b"half").unwrap();
        assert!(!p.exists(), "visible before commit");
        drop(f);
        assert!(!p.exists(), "left behind without commit");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        write_atomically(&p, b"whole").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"whole");
        let mode = std::fs::metadata(&p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o644);
    }
}
