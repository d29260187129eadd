//! What a file holds, told by its first bytes: the one sniffer every reader of a user's input
//! file asks before it chooses how to read it (rate logs, `ingest.csv` and `ingest.mcap`
//! files, truth files, model files, pipeline files, `predict.bias`'s state).
//!
//! The content decides; the name (its extension) is a hint. A file named for one format that
//! holds another a reader takes is read by what it holds, and [`Sniffed::note`] gives the one
//! line that says so. A file that holds nothing the reader takes is refused by
//! [`Sniffed::refuse`]: what the name claimed and what it is not, what it holds instead.
//!
//! The magic bytes: MCAP `\x89MCAP0\r\n`, gzip `1f 8b` (the start of its stream is inflated to
//! say what it packs), zstd `28 b5 2f fd`, xz, bzip2, zip and SQLite (a rosbag2 `.db3`);
//! UTF-16 by its byte-order mark. Text is what is left without a NUL byte and with almost no
//! control characters (any 8-bit encoding: a Latin-1 header is still text).

use std::io::Read;
use std::path::{Path, PathBuf};

use super::error::InputError;

/// How much of a file's start is read to tell what it holds.
const HEAD_BYTES: usize = 4096;

/// How much of a gzip stream is inflated to tell what it packs.
const INNER_BYTES: usize = 512;

/// What a file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Content {
    /// A directory (a rosbag2 bag, for the readers of bags).
    Directory,
    /// No bytes at all.
    Empty,
    /// An MCAP file (a `driftless record` recording, or a ROS 2 bag).
    Mcap,
    /// A gzip stream, and what the start of it packs.
    Gzip(Packed),
    /// A zstd stream.
    Zstd,
    /// An xz stream.
    Xz,
    /// A bzip2 stream.
    Bzip2,
    /// A zip archive.
    Zip,
    /// An SQLite database (rosbag2's older storage, `.db3`).
    Sqlite,
    /// UTF-16 text (a byte-order mark).
    Utf16,
    /// Text: no NUL byte, almost no control characters.
    Text,
    /// Anything else.
    Binary,
    /// A pipe or a device: not read ahead (its first bytes would be gone), so read as its
    /// name says.
    Stream,
}

/// What the start of a gzip stream packs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Packed {
    /// Text (a `.csv.gz`).
    Text,
    /// An MCAP file.
    Mcap,
    /// Something else.
    Other,
    /// Its start does not inflate.
    Damaged,
}

impl Content {
    /// What it is, for a line: "an MCAP file", "a gzip stream of text", "binary data".
    pub fn what(self) -> &'static str {
        match self {
            Content::Directory => "a directory",
            Content::Empty => "nothing (an empty file)",
            Content::Mcap => "an MCAP file",
            Content::Gzip(Packed::Text) => "a gzip stream of text",
            Content::Gzip(Packed::Mcap) => "a gzip stream of an MCAP file",
            Content::Gzip(Packed::Other) => "a gzip stream of binary data",
            Content::Gzip(Packed::Damaged) => "a damaged gzip stream",
            Content::Zstd => "a zstd stream",
            Content::Xz => "an xz stream",
            Content::Bzip2 => "a bzip2 stream",
            Content::Zip => "a zip archive",
            Content::Sqlite => "an SQLite database",
            Content::Utf16 => "UTF-16 text",
            Content::Text => "text",
            Content::Binary => "binary data",
            Content::Stream => "a stream (a pipe or a device)",
        }
    }

    /// What a text reader takes: text, plain or gzip-compressed; an empty file (the reader
    /// says it is empty); a stream (not read ahead: the reader finds out).
    pub fn is_text(self) -> bool {
        matches!(
            self,
            Content::Text | Content::Empty | Content::Gzip(Packed::Text) | Content::Stream
        )
    }

    /// What to do about it, where there is something to do.
    fn hint(self) -> Option<&'static str> {
        Some(match self {
            Content::Gzip(Packed::Mcap) | Content::Zstd | Content::Xz | Content::Bzip2 => {
                "decompress it first"
            }
            Content::Zip => "unpack it first",
            Content::Sqlite => {
                "a rosbag2 .db3 bag? convert it to MCAP with `ros2 bag convert` first"
            }
            Content::Utf16 => "save it as UTF-8 first",
            _ => return None,
        })
    }
}

/// What a file's name claims it holds, by its extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Claim {
    Mcap,
    Gzip,
    Zstd,
    Text,
    Sqlite,
}

impl Claim {
    fn of(path: &Path) -> Option<(Claim, String)> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        let claim = match ext.as_str() {
            "mcap" => Claim::Mcap,
            "gz" | "gzip" => Claim::Gzip,
            "zst" | "zstd" => Claim::Zstd,
            "csv" | "tsv" | "txt" | "json" | "toml" => Claim::Text,
            "db3" => Claim::Sqlite,
            _ => return None,
        };
        Some((claim, ext))
    }

    fn holds(self, c: Content) -> bool {
        match self {
            Claim::Mcap => c == Content::Mcap,
            Claim::Gzip => matches!(c, Content::Gzip(_)),
            Claim::Zstd => c == Content::Zstd,
            Claim::Text => matches!(c, Content::Text | Content::Empty | Content::Utf16),
            Claim::Sqlite => c == Content::Sqlite,
        }
    }

    /// "not an MCAP file (no MCAP magic at its start)".
    fn denied(self, ext: &str) -> String {
        match self {
            Claim::Mcap => "not an MCAP file (no MCAP magic at its start)".into(),
            Claim::Gzip => "not gzip-compressed (no gzip magic at its start)".into(),
            Claim::Zstd => "not zstd-compressed (no zstd magic at its start)".into(),
            Claim::Text if ext == "txt" => "not text".into(),
            Claim::Text => format!("not {} text", ext.to_ascii_uppercase()),
            Claim::Sqlite => "not an SQLite database".into(),
        }
    }
}

/// A file and what it holds ([`sniff`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Sniffed {
    /// The file.
    pub path: PathBuf,
    /// What its first bytes say it holds.
    pub content: Content,
}

impl Sniffed {
    /// Whether a text reader reads it through a gzip decoder: by its content, or for a stream
    /// (not read ahead) by its name (`.gz`).
    pub fn is_gzip(&self) -> bool {
        match self.content {
            Content::Gzip(_) => true,
            Content::Stream => super::atomic::is_gzip(&self.path),
            _ => false,
        }
    }

    /// One line when the name claims another format than the file holds, ending with how it
    /// is read (`read_as`, e.g. "read as CSV"): "x.mcap: named .mcap but holds text: read as
    /// CSV". None when the name says nothing or says what it holds.
    pub fn note(&self, read_as: &str) -> Option<String> {
        let (claim, ext) = Claim::of(&self.path)?;
        let unknown = self.content == Content::Stream;
        (!unknown && !claim.holds(self.content)).then(|| {
            format!(
                "{}: named .{ext} but holds {}: {read_as}",
                self.path.display(),
                self.content.what()
            )
        })
    }

    /// [`Sniffed::note`] for a file read as CSV: "read as CSV", or "read decompressed, as
    /// CSV".
    pub fn csv_note(&self) -> Option<String> {
        self.note(if self.is_gzip() {
            "read decompressed, as CSV"
        } else {
            "read as CSV"
        })
    }

    /// The error for a file that holds nothing the reader takes: what its name claimed and
    /// what it is not, what it holds, what to do where there is something, and `takes` (what
    /// the reader reads): "x.mcap: not an MCAP file (no MCAP magic at its start): it holds
    /// binary data; a rate log is ...".
    pub fn refuse(&self, takes: &str) -> InputError {
        let denied = match Claim::of(&self.path) {
            Some((claim, ext)) if !claim.holds(self.content) => {
                format!("{}: ", claim.denied(&ext))
            }
            _ => String::new(),
        };
        let hint = self
            .content
            .hint()
            .map_or(String::new(), |h| format!(" ({h})"));
        let holds = match self.content {
            Content::Directory => "it is a directory".to_string(),
            c => format!("it holds {}", c.what()),
        };
        InputError::file(&self.path, format!("{denied}{holds}{hint}; {takes}"))
    }
}

/// `path` sniffed for a reader of text (`takes` says what it reads, for the refusal): text,
/// plain or gzip-compressed, or a stream; anything else refused, saying what it holds.
pub fn text_file(path: &Path, takes: &str) -> Result<Sniffed, InputError> {
    let s = sniff(path)?;
    if s.content.is_text() {
        Ok(s)
    } else {
        Err(s.refuse(takes))
    }
}

/// What `path` holds, from its first bytes (a directory: [`Content::Directory`]; a pipe or a
/// device, not read: [`Content::Stream`]). The error is the system's, naming the file (no
/// such file, no permission).
pub fn sniff(path: &Path) -> Result<Sniffed, InputError> {
    let io = |source| InputError::Io {
        path: path.display().to_string(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    let content = if meta.is_dir() {
        Content::Directory
    } else if !meta.is_file() {
        Content::Stream
    } else {
        let mut head = Vec::with_capacity(HEAD_BYTES);
        std::fs::File::open(path)
            .and_then(|f| f.take(HEAD_BYTES as u64).read_to_end(&mut head))
            .map_err(io)?;
        classify(&head)
    };
    Ok(Sniffed {
        path: path.to_path_buf(),
        content,
    })
}

/// What a file that starts with `head` holds.
pub fn classify(head: &[u8]) -> Content {
    const MAGICS: [(&[u8], Content); 7] = [
        (b"\x89MCAP0\r\n", Content::Mcap),
        (b"\x28\xb5\x2f\xfd", Content::Zstd),
        (b"\xfd7zXZ\x00", Content::Xz),
        (b"BZh", Content::Bzip2),
        (b"PK\x03\x04", Content::Zip),
        (b"SQLite format 3\x00", Content::Sqlite),
        (b"\x1f\x8b", Content::Gzip(Packed::Damaged)),
    ];
    if head.is_empty() {
        return Content::Empty;
    }
    match MAGICS.iter().find(|(m, _)| head.starts_with(m)) {
        Some((_, Content::Gzip(_))) => Content::Gzip(packed(head)),
        Some((_, c)) => *c,
        None if head.starts_with(b"\xff\xfe") || head.starts_with(b"\xfe\xff") => Content::Utf16,
        None if is_text(head) => Content::Text,
        None => Content::Binary,
    }
}

/// What the start of the gzip stream `head` packs.
fn packed(head: &[u8]) -> Packed {
    let mut inner = Vec::with_capacity(INNER_BYTES);
    // The head cuts the stream short: an end of input after some bytes is expected.
    let _ = flate2::read::MultiGzDecoder::new(head)
        .take(INNER_BYTES as u64)
        .read_to_end(&mut inner);
    if inner.is_empty() {
        return Packed::Damaged;
    }
    match classify(&inner) {
        Content::Mcap => Packed::Mcap,
        Content::Text => Packed::Text,
        _ => Packed::Other,
    }
}

/// Text: no NUL byte, and control characters (but tab, line ends, form feed and escape) at
/// most 1 in 100 bytes. Random bytes hold 11 in 100.
fn is_text(head: &[u8]) -> bool {
    let controls = head
        .iter()
        .filter(|&&b| (b < 0x20 && !matches!(b, b'\t' | b'\n' | b'\r' | 0x0c | 0x1b)) || b == 0x7f)
        .count();
    !head.contains(&0) && controls * 100 <= head.len()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gzip(bytes: &[u8]) -> Vec<u8> {
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        std::io::Write::write_all(&mut enc, bytes).unwrap();
        enc.finish().unwrap()
    }

    fn random(n: usize) -> Vec<u8> {
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 24) as u8
            })
            .collect()
    }

    #[test]
    fn each_format_is_told_by_its_first_bytes() {
        let csv = b"t,x\n0,1.5\n".to_vec();
        let latin1 = b"t,rate \xb0/s\n0,1\n".to_vec();
        let mut mcap = b"\x89MCAP0\r\n".to_vec();
        mcap.extend(random(100));
        for (bytes, want) in [
            (Vec::new(), Content::Empty),
            (csv.clone(), Content::Text),
            (latin1, Content::Text),
            (mcap.clone(), Content::Mcap),
            (gzip(&csv), Content::Gzip(Packed::Text)),
            (gzip(&mcap), Content::Gzip(Packed::Mcap)),
            (gzip(&random(5000)), Content::Gzip(Packed::Other)),
            (
                b"\x1f\x8bnot deflate".to_vec(),
                Content::Gzip(Packed::Damaged),
            ),
            (b"\x28\xb5\x2f\xfd\x00".to_vec(), Content::Zstd),
            (b"SQLite format 3\x00....".to_vec(), Content::Sqlite),
            (b"\xff\xfet\x00,\x00".to_vec(), Content::Utf16),
            (random(5000), Content::Binary),
        ] {
            assert_eq!(
                classify(&bytes),
                want,
                "{:?}",
                &bytes[..bytes.len().min(16)]
            );
        }
    }

    #[test]
    fn a_name_that_claims_another_format_gets_one_line_and_garbage_a_refusal() {
        let s = |name: &str, content| Sniffed {
            path: PathBuf::from(name),
            content,
        };
        assert_eq!(s("x.mcap", Content::Mcap).note("read as MCAP"), None);
        assert_eq!(s("x.log", Content::Mcap).note("read as MCAP"), None);
        assert_eq!(
            s("x.mcap", Content::Text).note("read as CSV").unwrap(),
            "x.mcap: named .mcap but holds text: read as CSV"
        );
        assert_eq!(
            s("x.csv", Content::Gzip(Packed::Text))
                .note("read decompressed")
                .unwrap(),
            "x.csv: named .csv but holds a gzip stream of text: read decompressed"
        );
        assert_eq!(
            s("x.csv.gz", Content::Text).note("read as CSV").unwrap(),
            "x.csv.gz: named .gz but holds text: read as CSV"
        );
        let e = s("x.mcap", Content::Binary).refuse("a log is CSV or MCAP");
        assert_eq!(
            e.to_string(),
            "x.mcap: not an MCAP file (no MCAP magic at its start): it holds binary data; a log \
             is CSV or MCAP"
        );
        let e = s("x.csv", Content::Zstd).refuse("a log is CSV");
        assert_eq!(
            e.to_string(),
            "x.csv: not CSV text: it holds a zstd stream (decompress it first); a log is CSV"
        );
        let e = s("x.bin", Content::Binary).refuse("a log is CSV");
        assert_eq!(e.to_string(), "x.bin: it holds binary data; a log is CSV");
    }
}
