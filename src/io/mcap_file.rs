//! MCAP files as every reader of them here starts (recordings, `io::recording`; ROS 2 bags,
//! `transport::ros2`): the file mapped and its summary read, and a record reader with a length limit.

use std::path::Path;

use super::content::{classify, Content};

/// The largest chunk, uncompressed, an MCAP file we read may have (the recorder writes chunks of
/// about a megabyte; MCAP writers' and rosbag2's defaults are 1-4 MiB); a larger record length
/// is taken for corruption, not allocated.
pub const MAX_CHUNK_BYTES: u64 = 64 << 20;

/// Why [`map_mcap`] could not open a file; each reader words it for its own files.
#[derive(Debug)]
pub enum McapOpenError {
    /// Opening or mapping the file failed.
    Io(std::io::Error),
    /// No MCAP magic at its start: what it holds instead.
    NotMcap(Content),
    /// No summary section, or one that does not read (truncated, still being written).
    Incomplete(String),
}

/// Map `path` and read its summary: what every reader of MCAP files here (recordings, ROS 2
/// bags) starts from.
pub fn map_mcap(path: &Path) -> Result<(memmap2::Mmap, mcap::Summary), McapOpenError> {
    let file = std::fs::File::open(path).map_err(McapOpenError::Io)?;
    // SAFETY: the map is only read. Like any reader of a file it sees what another process
    // writes into it meanwhile; truncating it under us would fault (SIGBUS): recordings and
    // bags are read once their writer has closed them (`driftless record` renames a file only
    // once whole).
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(McapOpenError::Io)?;
    if !map.starts_with(mcap::MAGIC) {
        let head = &map[..map.len().min(4096)];
        return Err(McapOpenError::NotMcap(classify(head)));
    }
    match mcap::Summary::read(&map) {
        Ok(Some(s)) => Ok((map, s)),
        Ok(None) => Err(McapOpenError::Incomplete("no summary section".into())),
        Err(e) => Err(McapOpenError::Incomplete(e.to_string())),
    }
}

/// A reader of an MCAP file's records in order. Not mcap's MessageStream: it sets no record
/// length limit, and a corrupt length inside a chunk made it allocate what the length claimed
/// (found by fuzzing: an abort on a 216 PB allocation). The same sans-io reader with
/// [`MAX_CHUNK_BYTES`] as its limit refuses such a record.
pub fn limited_reader() -> mcap::sans_io::linear_reader::LinearReader {
    mcap::sans_io::linear_reader::LinearReader::new_with_options(
        mcap::sans_io::linear_reader::LinearReaderOptions::default()
            .with_record_length_limit(MAX_CHUNK_BYTES as usize),
    )
}
