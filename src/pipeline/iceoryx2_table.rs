//! The pipeline file's `[iceoryx2]` table: the transport settings every service of the
//! pipeline, and of its sides, is built with. Its keys are declared here like a stage kind's;
//! the pipeline reader ([`super::config`]) hands this table over and keeps the result.

use std::path::PathBuf;

use crate::io::InputError;
use crate::stages::schema::{DefaultValue, Key, Src, Table, Type};

/// The iceoryx2 settings of a pipeline.
#[derive(Debug, Clone, PartialEq)]
pub struct Iceoryx2Settings {
    /// Prefix of the iceoryx2 files (the env variable `DRIFTLESS_IOX2_PREFIX` overrides it).
    pub prefix: String,
    /// iceoryx2's root directory (`None`: its default, `/tmp/iceoryx2`); the env variable
    /// `DRIFTLESS_IOX2_ROOT` overrides it.
    pub root_path: Option<PathBuf>,
    /// Subscriber buffer size of every service.
    pub buffer_size: usize,
    /// Subscribers per service.
    pub max_subscribers: usize,
    /// The statistics service.
    pub stats_service: String,
}

impl Iceoryx2Settings {
    /// The one `Qos` every service of the pipeline, and of its sides, is built from.
    pub fn qos(&self) -> crate::transport::Qos {
        crate::transport::Qos {
            buffer_size: self.buffer_size,
            max_subscribers: self.max_subscribers,
        }
    }
}

const PREFIX: Key = Key {
    name: "prefix",
    ty: Type::Str("letters, digits, `-`, `.`, ending in its only `_`"),
    default: DefaultValue::Word(crate::transport::DEFAULT_PREFIX),
    doc: "prefix of the iceoryx2 files (docs/operations.md); `--prefix` or \
          `DRIFTLESS_IOX2_PREFIX` override it",
};
const ROOT_PATH: Key = Key {
    name: "root_path",
    ty: Type::Str("an absolute path"),
    default: DefaultValue::Absent("none: iceoryx2's, `/tmp/iceoryx2`"),
    doc: "iceoryx2's directory of node and service files; `--root-path` or \
          `DRIFTLESS_IOX2_ROOT` override it",
};
const BUFFER_SIZE: Key = Key {
    name: "buffer_size",
    ty: Type::Int(1, 65_536),
    default: DefaultValue::Int(256),
    doc: "samples a subscriber may hold unread before it loses new ones",
};
const MAX_SUBSCRIBERS: Key = Key {
    name: "max_subscribers",
    ty: Type::Int(1, 64),
    default: DefaultValue::Int(8),
    doc: "subscribers per service (all for other processes: the daemon reads none of its own)",
};
const STATS_SERVICE: Key = Key {
    name: "stats_service",
    ty: Type::Str("a service name"),
    default: DefaultValue::Derived("`<name>/stats`"),
    doc: "where the statistics snapshot is published",
};

/// The `[iceoryx2]` table's keys, in the order listed.
pub const ICEORYX2_KEYS: &[Key] = &[
    PREFIX,
    ROOT_PATH,
    BUFFER_SIZE,
    MAX_SUBSCRIBERS,
    STATS_SERVICE,
];

/// The one top-level table that is the pipeline's own (the sides' tables and `[[stage]]` aside).
pub(super) const ICEORYX2_TABLE: &str = "iceoryx2";

/// Read the `[iceoryx2]` table of pipeline `name` (its entries already checked against
/// [`ICEORYX2_KEYS`]); the stats service defaults to `<name>/stats`.
pub(super) fn read(
    t: &mut Table<'_, '_>,
    src: &Src<'_>,
    name: &str,
) -> Result<Iceoryx2Settings, InputError> {
    let prefix = t.str_or_default(&PREFIX, |p| {
        crate::transport::check_prefix(p).map_err(|e| format!("invalid prefix: {e}"))
    })?;
    let root_path = match t.get::<String>(&ROOT_PATH)? {
        Some(r) => {
            let path = PathBuf::from(r.get_ref());
            crate::transport::check_root(&path)
                .map_err(|e| src.span(&r, format!("invalid root_path: {e}")))?;
            Some(path)
        }
        None => None,
    };
    let buffer_size = t.int_or_default(&BUFFER_SIZE)?;
    let max_subscribers = t.int_or_default(&MAX_SUBSCRIBERS)?;
    let stats_service = match t.get::<String>(&STATS_SERVICE)? {
        Some(s) => src.service(&s)?,
        None => format!("{name}/stats"),
    };
    Ok(Iceoryx2Settings {
        prefix,
        root_path,
        buffer_size,
        max_subscribers,
        stats_service,
    })
}
