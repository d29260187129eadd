//! [`TransportError`]: what failed, on which name, and for a refusal on permissions, whose files
//! (found by `permissions.rs`, which builds that variant).

/// A transport failure, with what was being done.
#[derive(Debug, thiserror::Error)]
pub enum TransportError {
    /// A service, port or node name is not acceptable to iceoryx2.
    #[error("invalid name {name:?}: {reason}")]
    Name {
        /// The name.
        name: String,
        /// Why.
        reason: String,
    },
    /// Setting up a node, service or port failed.
    #[error("{what} {name:?}: {reason}")]
    Setup {
        /// What was being set up.
        what: &'static str,
        /// Its name.
        name: String,
        /// iceoryx2's error.
        reason: String,
    },
    /// An existing input service, created by another process, would lose samples silently.
    #[error(
        "service {name:?} was created by another process with a subscriber buffer of {buffer} \
         and safe overflow {overflow}: it would lose samples silently. driftless needs a buffer \
         of at least {need} (the pipeline's buffer_size) and safe overflow off: start the daemon \
         first (it creates the service), or create it with subscriber_max_buffer_size >= {need} \
         and enable_safe_overflow(false)",
        overflow = if *safe_overflow { "on" } else { "off" }
    )]
    Qos {
        /// The service.
        name: String,
        /// Its creator's subscriber buffer limit.
        buffer: usize,
        /// Whether its creator enabled safe overflow (new samples overwrite unread ones).
        safe_overflow: bool,
        /// The buffer the pipeline asks for.
        need: usize,
    },
    /// iceoryx2's files belong to another user: what, whose, and how to fix it.
    #[error("{what} {name:?}: {problem}")]
    Permission {
        /// What was being set up.
        what: &'static str,
        /// Its name.
        name: String,
        /// Which file or directory, its owner and mode, and the ways out.
        problem: String,
    },
    /// iceoryx2's root directory, a directory above it, or its `nodes` or `services`, is
    /// another user's, a link, or open to others' writes: refused before iceoryx2 touches it
    /// (iceoryx2 follows links there, so that user would choose where this process writes).
    /// Also `/dev/shm` another user controls, or anything but a regular file of ours or root's
    /// at the name of the prefix's global management segment.
    #[error("{message}")]
    Untrusted {
        /// The directory or file refused.
        path: std::path::PathBuf,
        /// The whole sentence: which directory, whose it is, and the ways out.
        message: String,
    },
    /// The service carries another layout version of one of our types (a driftless of another
    /// release publishes it): the whole sentence, from [`crate::wire::wire_version_mismatch`].
    #[error("{0}")]
    Version(String),
    /// `/dev/shm` cannot hold the segments just created (a full or too small tmpfs).
    #[error(
        "not enough shared memory in {dir} ({needed} bytes needed, {free} free): free some, or \
         enlarge it (e.g. `mount -o remount,size=64M {dir}`)"
    )]
    SharedMemoryFull {
        /// Where the segments are.
        dir: &'static str,
        /// Bytes the segments of this process need.
        needed: u64,
        /// Bytes the file system had free before this process created them.
        free: u64,
    },
    /// Sending or receiving failed at run time.
    #[error("{what}: {reason}")]
    Io {
        /// What failed.
        what: &'static str,
        /// iceoryx2's error.
        reason: String,
    },
}

impl TransportError {
    /// Whether the user's configuration is at fault (the CLI's exit code 2), not the run.
    pub fn is_configuration(&self) -> bool {
        matches!(self, TransportError::Untrusted { .. })
    }
}
