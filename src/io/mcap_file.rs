//! MCAP files as every reader of them here starts (recordings, `io::recording`; ROS 2 bags,
//! `transport::ros2`): the file mapped and its summary read, and its messages read in file order
//! with a record length limit.

use std::collections::BTreeMap;
use std::path::Path;

use mcap::records::{MessageHeader, Record};
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

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
fn limited_reader() -> LinearReader {
    LinearReader::new_with_options(
        LinearReaderOptions::default().with_record_length_limit(MAX_CHUNK_BYTES as usize),
    )
}

/// Why [`ChannelMessages::next_with`] could not read on; each reader words the first two for
/// its own files. Shown, the mcap error alone or the sentence on the channel.
#[derive(Debug)]
pub enum McapReadError {
    /// A record that does not parse.
    Record(mcap::McapError),
    /// The records do not read: a corrupt or truncated chunk, or the file truncated.
    Chunk(mcap::McapError),
    /// A message of a channel that the summary does not list.
    UnknownChannel(u16),
}

impl std::fmt::Display for McapReadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            McapReadError::Record(e) | McapReadError::Chunk(e) => write!(f, "{e}"),
            McapReadError::UnknownChannel(id) => {
                write!(
                    f,
                    "a message of channel {id} that the summary does not list"
                )
            }
        }
    }
}

/// The messages of some channels of a mapped MCAP file, in file order: the one read loop of
/// recordings (`io::recording`) and ROS 2 bags (`transport::ros2::bag`).
pub struct ChannelMessages<'a> {
    reader: LinearReader,
    /// What the reader has not been given yet.
    rest: &'a [u8],
    /// Every channel of the summary: whether its messages are wanted.
    channels: BTreeMap<u16, bool>,
    /// An error ended the reading.
    failed: bool,
}

impl<'a> ChannelMessages<'a> {
    /// Read `file`, the whole file's bytes, for the messages of the channels `channels` maps to
    /// true; those of a channel it maps to false are passed over, one of a channel it does not
    /// list is an error ([`McapReadError::UnknownChannel`]).
    pub fn new(file: &'a [u8], channels: BTreeMap<u16, bool>) -> Self {
        ChannelMessages {
            reader: limited_reader(),
            rest: file,
            channels,
            failed: false,
        }
    }

    /// Read `file` for the messages of `topic`, on whichever of `summary`'s channels it stands.
    pub fn of_topic(file: &'a [u8], summary: &mcap::Summary, topic: &str) -> Self {
        let channels = summary
            .channels
            .iter()
            .map(|(id, c)| (*id, c.topic == topic))
            .collect();
        ChannelMessages::new(file, channels)
    }

    /// The next wanted message, given to `decode` with its header, and what `decode` made of
    /// it; None at the file's end. A function, not an iterator: the message's bytes are the
    /// reader's, only lent until it reads on. After an error, None: the file reads no further.
    pub fn next_with<R>(
        &mut self,
        decode: impl FnOnce(MessageHeader, &[u8]) -> R,
    ) -> Option<Result<R, McapReadError>> {
        if self.failed {
            return None;
        }
        let read = self.read(decode);
        self.failed = matches!(read, Some(Err(_)));
        read
    }

    fn read<R>(
        &mut self,
        decode: impl FnOnce(MessageHeader, &[u8]) -> R,
    ) -> Option<Result<R, McapReadError>> {
        while let Some(event) = self.reader.next_event() {
            match event {
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    let len = need.min(self.rest.len());
                    self.reader.insert(len).copy_from_slice(&self.rest[..len]);
                    self.reader.notify_read(len);
                    self.rest = &self.rest[len..];
                }
                Ok(LinearReadEvent::Record { opcode, data }) => {
                    let record = match mcap::parse_record(opcode, data) {
                        Ok(r) => r,
                        Err(e) => return Some(Err(McapReadError::Record(e))),
                    };
                    let Record::Message { header, data } = record else {
                        continue;
                    };
                    match self.channels.get(&header.channel_id) {
                        Some(true) => return Some(Ok(decode(header, &data))),
                        Some(false) => continue,
                        None => return Some(Err(McapReadError::UnknownChannel(header.channel_id))),
                    }
                }
                Err(e) => return Some(Err(McapReadError::Chunk(e))),
            }
        }
        None
    }
}
