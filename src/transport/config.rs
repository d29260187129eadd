//! Where iceoryx2's files live and what may be named: the prefix and root directory, the
//! explicit iceoryx2 `Config` every node is built from (handed out by `trust.rs` once the root
//! is checked), name checks, and the one [`Qos`].

use iceoryx2::prelude::*;

use super::error::TransportError;

/// Default iceoryx2 prefix of the daemon's files in `/dev/shm` and `/tmp/iceoryx2`.
pub const DEFAULT_PREFIX: &str = "driftless_";

/// Environment variable that overrides the iceoryx2 prefix (tests give each run its own).
pub const PREFIX_ENV: &str = "DRIFTLESS_IOX2_PREFIX";

/// iceoryx2's own root directory (its node and service files) on Linux, used unless
/// [`set_root`] says otherwise. The shared memory itself is in `/dev/shm` either way.
pub const DEFAULT_ROOT: &str = "/tmp/iceoryx2";

/// Environment variable that sets iceoryx2's root directory (overrides the pipeline's
/// `[iceoryx2] root_path`; `--root-path` overrides it).
pub const ROOT_ENV: &str = "DRIFTLESS_IOX2_ROOT";

/// The root directory every node of this process uses (`None`: [`DEFAULT_ROOT`]).
static ROOT: std::sync::RwLock<Option<std::path::PathBuf>> = std::sync::RwLock::new(None);

/// The iceoryx2 service flavour used everywhere: inter-process, even inside one process
/// (`local` lost wake-ups at high rates on our machines).
pub(super) type Svc = iceoryx2::prelude::ipc::Service;

/// A publish-subscribe service of ours with payload `T`, as a port is made from it.
pub(super) type PubSubFactory<T> =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, T, ()>;

/// Quality of service of every service the daemon creates (one definition, see module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    /// Samples a subscriber can hold before it loses new ones.
    pub buffer_size: usize,
    /// Subscribers per service (the daemon's own hop takes one).
    pub max_subscribers: usize,
}

impl Default for Qos {
    fn default() -> Self {
        Qos {
            buffer_size: 256,
            max_subscribers: 8,
        }
    }
}

/// Check that `name` is a valid iceoryx2 service name.
pub fn check_service_name(name: &str) -> Result<(), String> {
    ServiceName::new(name)
        .map(|_| ())
        .map_err(|e| format!("{e:?}"))
}

pub(super) fn service_name(name: &str) -> Result<ServiceName, TransportError> {
    ServiceName::new(name).map_err(|e| TransportError::Name {
        name: name.to_string(),
        reason: format!("{e:?}"),
    })
}

/// Check that `root` can be iceoryx2's root directory: an absolute path iceoryx2 accepts.
pub fn check_root(root: &std::path::Path) -> Result<(), String> {
    iox_root(root).map(|_| ())
}

pub(super) fn iox_root(root: &std::path::Path) -> Result<Path, String> {
    use std::os::unix::ffi::OsStrExt;
    if !root.is_absolute() {
        return Err("must be an absolute path".into());
    }
    // iceoryx2 joins its directory names to the root as to a string.
    let mut bytes = root.as_os_str().as_bytes().to_vec();
    if !bytes.ends_with(b"/") {
        bytes.push(b'/');
    }
    Path::new(&bytes).map_err(|e| format!("not a path iceoryx2 accepts: {e:?}"))
}

/// Set iceoryx2's root directory for every node this process creates from now on (`None`:
/// [`DEFAULT_ROOT`]). Process-wide, as iceoryx2's own global configuration: a daemon and every
/// process that talks to it must use the same root directory and prefix.
pub fn set_root(root: Option<std::path::PathBuf>) -> Result<(), String> {
    if let Some(r) = &root {
        check_root(r)?;
    }
    *ROOT.write().unwrap_or_else(|e| e.into_inner()) = root;
    Ok(())
}

/// iceoryx2's root directory in force in this process.
pub fn root() -> std::path::PathBuf {
    ROOT.read()
        .unwrap_or_else(|e| e.into_inner())
        .clone()
        .unwrap_or_else(|| DEFAULT_ROOT.into())
}

/// The explicit iceoryx2 configuration for `prefix` and the root in force (never the silently
/// discovered `config/iceoryx2.toml`), unchecked: nodes and listings take it from
/// [`super::trust`], which checks the root directory first.
pub(super) fn explicit_config(prefix: &str) -> Result<Config, TransportError> {
    let mut cfg = Config::default();
    cfg.global.prefix = FileName::new(prefix.as_bytes()).map_err(|e| TransportError::Name {
        name: prefix.to_string(),
        reason: format!("{e:?}"),
    })?;
    if let Some(r) = ROOT.read().unwrap_or_else(|e| e.into_inner()).as_deref() {
        let path = iox_root(r).map_err(|reason| TransportError::Name {
            name: r.display().to_string(),
            reason,
        })?;
        cfg.global.set_root_path(&path);
    }
    Ok(cfg)
}

/// Quiet iceoryx2's own logging unless `IOX2_LOG_LEVEL` asks for it.
pub fn quiet_logging() {
    set_log_level_from_env_or(LogLevel::Fatal);
}
