//! Output files that appear whole or not at all: written to a temporary file beside the target,
//! then renamed over it. A failed or interrupted command leaves no partial output behind.

use std::fs::{File, Permissions};
use std::io::{BufWriter, Write};
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

/// Whether `path` names a gzip file (it ends in `.gz`): such a file is written compressed
/// ([`write_text_atomically`]). A file read is decompressed by its content, whatever its name
/// ([`crate::io::content`]).
pub fn is_gzip(path: &Path) -> bool {
    path.extension().is_some_and(|e| e == "gz")
}

/// Write a text file for `path` through `body`, atomically, gzip-compressed when the name ends
/// in `.gz` (so `simulate -o log.csv.gz` writes what `allan log.csv.gz` reads).
pub fn write_text_atomically(
    path: &Path,
    body: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let file = AtomicFile::create(path)?;
    {
        let mut w = BufWriter::with_capacity(1 << 20, file.file());
        if is_gzip(path) {
            let mut gz = flate2::write::GzEncoder::new(&mut w, flate2::Compression::default());
            body(&mut gz)?;
            gz.finish()?;
        } else {
            body(&mut w)?;
        }
        w.flush()?;
    }
    file.commit()
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

    #[test]
    fn a_gz_name_is_written_compressed_another_as_is() {
        let dir = tempfile::tempdir().unwrap();
        let gz = dir.path().join("o.csv.gz");
        write_text_atomically(&gz, |w| w.write_all(b"x\n1\n")).unwrap();
        let bytes = std::fs::read(&gz).unwrap();
        assert_eq!(&bytes[..2], &[0x1f, 0x8b], "gzip magic");
        let mut text = String::new();
        std::io::Read::read_to_string(&mut flate2::read::GzDecoder::new(&bytes[..]), &mut text)
            .unwrap();
        assert_eq!(text, "x\n1\n");
        let plain = dir.path().join("o.csv");
        write_text_atomically(&plain, |w| w.write_all(b"x\n1\n")).unwrap();
        assert_eq!(std::fs::read(&plain).unwrap(), b"x\n1\n");
        // A failed body leaves nothing behind.
        let failed = dir.path().join("f.csv.gz");
        let e = write_text_atomically(&failed, |_| Err(std::io::Error::other("no"))).unwrap_err();
        assert_eq!(e.to_string(), "no");
        assert!(!failed.exists());
    }
}
