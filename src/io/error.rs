//! The errors of a bad input file, shared by every reader of a user's file: [`InputError`] (a
//! CSV table, a truth file, a pipeline file, any file as a whole) and [`BagError`] (a ROS 2
//! bag, which an [`InputError`] carries when a rate log is one). Below every reader, so that
//! the sniffer (`content.rs`), the CSV reader and the bag reader can all name them.

use std::path::Path;

/// A bad input file, with the position of the fault where there is one.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The file could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// A fault at a place in the file (1-based line and column).
    #[error("{path}:{line}:{column}: {message}")]
    At {
        /// The file.
        path: String,
        /// 1-based line.
        line: u64,
        /// 1-based column (characters from the start of the line).
        column: u64,
        /// What is wrong there.
        message: String,
    },
    /// A fault of a ROS 2 bag (its message names the file, and the message where there is one).
    #[error(transparent)]
    Bag(#[from] BagError),
    /// A fault of the file as a whole.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: String,
        /// What is wrong with it.
        message: String,
    },
}

impl InputError {
    /// A whole-file error.
    pub fn file(path: &Path, message: impl Into<String>) -> Self {
        InputError::File {
            path: path.display().to_string(),
            message: message.into(),
        }
    }
}

/// What went wrong with a bag, for a caller that acts on the kind (the message says it all).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BagErrorKind {
    /// The file or directory cannot be read (or written).
    Io,
    /// Not an MCAP file, or a rosbag2 bag of another storage.
    NotMcap,
    /// No summary: truncated, or still being written.
    Incomplete,
    /// No Imu topic in the bag.
    NoImuTopic,
    /// Several Imu topics and none chosen.
    SeveralImuTopics,
    /// The chosen topic is not in the bag.
    NoSuchTopic,
    /// The chosen topic is of another type (not Imu; for a motion topic, not a motion type).
    NotImu,
    /// A corrupt record or chunk.
    Corrupt,
    /// A message that does not decode.
    Cdr,
    /// A stamp that does not rise (the reader of a log checks it).
    Stamp,
    /// A value a log cannot hold (a non-finite rate).
    Value,
    /// A message that cannot be written (a stamp before 1970, a bad topic name).
    Write,
}

/// An error reading or writing a bag: one line naming the file and, for a message, the topic,
/// the message's number on it and its log time.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct BagError {
    /// What went wrong.
    pub kind: BagErrorKind,
    /// The line to show.
    pub message: String,
}

impl From<BagError> for String {
    fn from(e: BagError) -> String {
        e.message
    }
}
