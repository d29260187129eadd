//! Clean-up of the files iceoryx2 leaves in `/dev/shm` and its root directory: a prefix's
//! leftovers after the last node, a dead node's files, segments a killed process never sized,
//! and the permissions of the one segment iceoryx2 opens to every user.
//!
//! Every path here deletes only what is provably ours, on a machine shared with other users and
//! programs (some of them hostile):
//! - a name that iceoryx2 0.10 makes for this prefix in that directory ([`super::names`]), never
//!   a bare `starts_with`;
//! - a regular file (in the root directory, iceoryx2's event socket), never a link or a
//!   directory, owned by our effective uid;
//! - reached only through directories opened without following a link (`O_NOFOLLOW`), and only
//!   `/dev/shm`, the root, its `services` and `nodes`, and the node directories in `nodes`;
//!   deleted relative to that directory (`unlinkat`), so a link swapped in meanwhile is never
//!   followed;
//! - no recursion, at most [`MAX_ENTRIES`] entries read per directory: no walk can loop or
//!   hang.
//!
//! A leaf: it takes a prefix, reads the root in force and deletes; whether a node is left is for
//! its caller to count (`discovery.rs`), so nothing here sets up or lists nodes.

use std::ffi::OsStr;
use std::os::fd::{AsFd, OwnedFd};
use std::os::unix::ffi::OsStrExt;
use std::time::Duration;

use rustix::fs::{AtFlags, FileType, Mode, OFlags, Stat};

use super::config::root;
use super::names::{is_node_dir, is_ours, Place};

/// Entries read from one directory at most (a walk never reads more, whatever is planted).
pub(super) const MAX_ENTRIES: usize = 100_000;

/// Where POSIX shared memory lives on Linux.
pub(super) const SHM_DIR: &str = "/dev/shm";

/// A directory opened without following a link, to read and delete relative to.
pub(super) struct SafeDir(OwnedFd);

impl AsFd for SafeDir {
    fn as_fd(&self) -> std::os::fd::BorrowedFd<'_> {
        self.0.as_fd()
    }
}

impl SafeDir {
    /// Open `path`; `None` if it is missing, not a directory, or its last component a link.
    pub(super) fn open(path: &std::path::Path) -> Option<Self> {
        Self::open_at(rustix::fs::CWD, path.as_os_str().as_bytes())
    }

    /// Open the directory `name` inside this one, on the same terms.
    fn sub(&self, name: &[u8]) -> Option<Self> {
        Self::open_at(self.0.as_fd(), name)
    }

    fn open_at(dir: impl AsFd, name: &[u8]) -> Option<Self> {
        Self::open_with(dir, name, OFlags::RDONLY | OFlags::NOFOLLOW).ok()
    }

    /// Open the directory `name` in `dir` with `flags` (a directory, closed on exec, whatever
    /// else they say; `O_PATH` gives one only to go through and to [`SafeDir::stat_self`]).
    pub(super) fn open_with(
        dir: impl AsFd,
        name: &[u8],
        flags: OFlags,
    ) -> rustix::io::Result<Self> {
        let flags = flags | OFlags::DIRECTORY | OFlags::CLOEXEC;
        rustix::fs::openat(dir, OsStr::from_bytes(name), flags, Mode::empty()).map(SafeDir)
    }

    /// What this directory is (`fstat` of the directory opened, not of a path).
    pub(super) fn stat_self(&self) -> Option<Stat> {
        rustix::fs::fstat(&self.0).ok()
    }

    /// The names in this directory (at most [`MAX_ENTRIES`]; `.` and `..` left out).
    pub(super) fn names(&self) -> Vec<Vec<u8>> {
        let Ok(dir) = rustix::fs::Dir::read_from(&self.0) else {
            return Vec::new();
        };
        dir.take(MAX_ENTRIES)
            .filter_map(Result::ok)
            .map(|e| e.file_name().to_bytes().to_vec())
            .filter(|n| n != b"." && n != b"..")
            .collect()
    }

    /// What `name` is, without following it if it is a link.
    pub(super) fn stat(&self, name: &[u8]) -> Option<Stat> {
        rustix::fs::statat(&self.0, OsStr::from_bytes(name), AtFlags::SYMLINK_NOFOLLOW).ok()
    }

    /// Open the file `name` for `flags` if it is a regular file of ours (never through a link).
    pub(super) fn open_own_file(&self, name: &[u8], flags: OFlags) -> Option<(OwnedFd, Stat)> {
        let flags = flags | OFlags::NOFOLLOW | OFlags::NONBLOCK | OFlags::CLOEXEC;
        let fd = rustix::fs::openat(&self.0, OsStr::from_bytes(name), flags, Mode::empty()).ok()?;
        let st = rustix::fs::fstat(&fd).ok()?;
        (is_own(&st) && FileType::from_raw_mode(st.st_mode) == FileType::RegularFile)
            .then_some((fd, st))
    }

    /// Delete `name` if it is a regular file (or, with `socket`, a Unix socket) of ours.
    pub(super) fn remove_own(&self, name: &[u8], socket: bool) -> bool {
        let Some(st) = self.stat(name) else {
            return false;
        };
        let kind = FileType::from_raw_mode(st.st_mode);
        let removable = kind == FileType::RegularFile || (socket && kind == FileType::Socket);
        removable
            && is_own(&st)
            && rustix::fs::unlinkat(&self.0, OsStr::from_bytes(name), AtFlags::empty()).is_ok()
    }

    /// Delete every file of `prefix` in this directory that is `place`'s and passes `also`.
    fn remove_prefix_files(&self, place: Place, prefix: &str, also: impl Fn(&[u8]) -> bool) {
        for name in self.names() {
            if is_ours(place, prefix.as_bytes(), &name) && also(&name) {
                self.remove_own(&name, place == Place::Root);
            }
        }
    }
}

/// Is this file our effective user's?
pub(super) fn is_own(st: &Stat) -> bool {
    st.st_uid == rustix::process::geteuid().as_raw()
}

/// iceoryx2's `nodes` directory under the root in force.
fn nodes_dir() -> Option<SafeDir> {
    SafeDir::open(&root())?.sub(b"nodes")
}

/// One clean-up of the files of `prefix` that iceoryx2 leaves once no node of it is left (the
/// per-prefix management segment in `/dev/shm`, and whatever a killed process left): does
/// nothing while a node of the prefix is alive, or if the nodes cannot be listed
/// (`node_count`: the prefix's nodes, alive or dead; None if they cannot be listed). Returns
/// how long until the youngest node details it left are settled, if it left any.
///
/// Another process may be creating a node meanwhile: iceoryx2 writes a node's details before
/// the monitor that makes it listed. So the files are taken stock of before the nodes are
/// counted, and only those are deleted, each only if it is still the same file (a file made
/// after the stock is never touched). A node's details made less than [`NODE_SETTLE`] before
/// the count are left as well: they may be a node that is not listed yet (a listing would
/// show it without its name).
pub(super) fn remove_leftovers_once(
    prefix: &str,
    node_count: impl FnOnce() -> Option<usize>,
) -> Option<Duration> {
    let stock = Leftovers::take(prefix)?;
    let counted = std::time::SystemTime::now();
    if node_count().is_none_or(|n| n > 0) {
        return None;
    }
    stock.remove(counted)
}

/// How long before the nodes are counted a node's details file may be one that is still
/// being created (its monitor follows within microseconds; a second covers a loaded machine).
const NODE_SETTLE: Duration = Duration::from_secs(1);

/// One file to delete: where it is, its name, and which file it was (device and inode).
struct Found {
    place: Place,
    /// Index into [`Leftovers::dirs`].
    dir: usize,
    name: Vec<u8>,
    stat: Stat,
}

/// The files of a prefix that [`remove_leftovers_once`] deletes, taken stock of beforehand,
/// with the directories (opened without following links) they are in.
struct Leftovers {
    dirs: Vec<SafeDir>,
    found: Vec<Found>,
    /// Node directories (their names in `nodes`) to remove once empty.
    node_dirs: Vec<Vec<u8>>,
    /// Index into `dirs` of the `nodes` directory.
    nodes: Option<usize>,
}

impl Leftovers {
    fn take(prefix: &str) -> Option<Self> {
        let mut l = Leftovers {
            dirs: Vec::new(),
            found: Vec::new(),
            node_dirs: Vec::new(),
            nodes: None,
        };
        if let Some(shm) = SafeDir::open(SHM_DIR.as_ref()) {
            l.add(shm, Place::Shm, prefix);
        }
        let root = SafeDir::open(&root())?;
        let services = root.sub(b"services");
        let nodes = root.sub(b"nodes");
        l.add(root, Place::Root, prefix);
        if let Some(services) = services {
            l.add(services, Place::Services, prefix);
        }
        if let Some(nodes) = nodes {
            let ids: Vec<Vec<u8>> = nodes
                .names()
                .into_iter()
                .filter(|n| is_node_dir(n))
                .collect();
            let subs: Vec<(Vec<u8>, SafeDir)> = ids
                .into_iter()
                .filter(|id| is_own_dir(&nodes, id))
                .filter_map(|id| nodes.sub(&id).map(|d| (id, d)))
                .collect();
            l.nodes = Some(l.add(nodes, Place::Nodes, prefix));
            for (id, dir) in subs {
                l.add(dir, Place::NodeDir, prefix);
                l.node_dirs.push(id);
            }
        }
        Some(l)
    }

    /// Take stock of `dir`'s files of `prefix` in `place`; the index of `dir`.
    fn add(&mut self, dir: SafeDir, place: Place, prefix: &str) -> usize {
        let at = self.dirs.len();
        for name in dir.names() {
            if is_ours(place, prefix.as_bytes(), &name) {
                if let Some(stat) = dir.stat(&name) {
                    self.found.push(Found {
                        place,
                        dir: at,
                        name,
                        stat,
                    });
                }
            }
        }
        self.dirs.push(dir);
        at
    }

    /// Delete every file taken stock of that is still the same file (a node's details only if
    /// made [`NODE_SETTLE`] before `counted`), then the node directories left empty. Returns
    /// how long until the youngest details it left are settled, if it left any.
    fn remove(self, counted: std::time::SystemTime) -> Option<Duration> {
        let mut settle: Option<Duration> = None;
        for f in &self.found {
            let dir = &self.dirs[f.dir];
            let Some(now) = dir.stat(&f.name) else {
                continue;
            };
            if (now.st_dev, now.st_ino) != (f.stat.st_dev, f.stat.st_ino) {
                continue;
            }
            if f.place == Place::NodeDir {
                let made = std::time::UNIX_EPOCH
                    + Duration::new(now.st_ctime.max(0) as u64, now.st_ctime_nsec as u32);
                if made + NODE_SETTLE > counted {
                    let wait = (made + NODE_SETTLE)
                        .duration_since(counted)
                        .unwrap_or_default()
                        .min(NODE_SETTLE);
                    settle = Some(settle.map_or(wait, |s| s.max(wait)));
                    continue;
                }
            }
            dir.remove_own(&f.name, f.place == Place::Root);
        }
        if let Some(nodes) = self.nodes.map(|i| &self.dirs[i]) {
            for id in &self.node_dirs {
                let _ = rustix::fs::unlinkat(&nodes.0, OsStr::from_bytes(id), AtFlags::REMOVEDIR);
            }
        }
        settle
    }
}

/// Remove what is left of the dead node `id` of `prefix`: its files in the directory iceoryx2
/// names by the node id (and the directory once empty), then its monitor files.
pub(super) fn remove_node_files(prefix: &str, id: u128) {
    let Some(nodes) = nodes_dir() else {
        return;
    };
    let id = id.to_string();
    remove_node_dir(&nodes, prefix, id.as_bytes());
    let monitor = format!("{prefix}{id}.");
    nodes.remove_prefix_files(Place::Nodes, prefix, |n| n.starts_with(monitor.as_bytes()));
}

/// Delete `prefix`'s files in `nodes/<id>`, then the directory if it is ours and now empty
/// (another prefix's node of the same id keeps it).
fn remove_node_dir(nodes: &SafeDir, prefix: &str, id: &[u8]) {
    if !is_own_dir(nodes, id) {
        return;
    }
    if let Some(dir) = nodes.sub(id) {
        dir.remove_prefix_files(Place::NodeDir, prefix, |_| true);
    }
    let _ = rustix::fs::unlinkat(&nodes.0, OsStr::from_bytes(id), AtFlags::REMOVEDIR);
}

/// Is `id` in `dir` a directory of ours (not a link to one)?
fn is_own_dir(dir: &SafeDir, id: &[u8]) -> bool {
    dir.stat(id)
        .is_some_and(|st| FileType::from_raw_mode(st.st_mode) == FileType::Directory && is_own(&st))
}

/// A shared memory segment of ours in `/dev/shm`: its name and what it is.
pub(super) struct Segment {
    pub name: Vec<u8>,
    pub stat: Stat,
}

/// This prefix's shared memory segments in `/dev/shm` that are regular files of ours, and the
/// directory to act on them through.
pub(super) fn own_segments(prefix: &str) -> Option<(SafeDir, Vec<Segment>)> {
    let shm = SafeDir::open(SHM_DIR.as_ref())?;
    let found = shm
        .names()
        .into_iter()
        .filter(|n| is_ours(Place::Shm, prefix.as_bytes(), n))
        .filter_map(|name| {
            let stat = shm.stat(&name)?;
            (FileType::from_raw_mode(stat.st_mode) == FileType::RegularFile && is_own(&stat))
                .then_some(Segment { name, stat })
        })
        .collect();
    Some((shm, found))
}

/// Remove this prefix's shared memory segments of size 0 older than a second: what a process
/// killed between creating a segment and sizing it leaves (creator and size are microseconds
/// apart). iceoryx2 0.10 waits for such a segment to be sized without a timeout
/// (`MappingSizeIsZero` in its `open_impl`), so the next node's clean-up of dead nodes, or a
/// listing, would hang forever (found by the `list --clean` test killing daemons mid-start).
pub(super) fn remove_unsized_segments(prefix: &str) {
    const SETTLE: Duration = Duration::from_secs(1);
    let age = |st: &Stat| {
        let modified = std::time::UNIX_EPOCH
            + Duration::new(st.st_mtime.max(0) as u64, st.st_mtime_nsec as u32);
        std::time::SystemTime::now()
            .duration_since(modified)
            .unwrap_or_default()
    };
    let unsized_ages = || {
        own_segments(prefix).map(|(shm, found)| {
            let ages: Vec<(Vec<u8>, Duration)> = found
                .into_iter()
                .filter(|s| s.stat.st_size == 0)
                .map(|s| (s.name, age(&s.stat)))
                .collect();
            (shm, ages)
        })
    };
    let Some((_, found)) = unsized_ages() else {
        return;
    };
    // A segment younger than a second may be one a live process is sizing right now: wait
    // until it is a second old (rare: only after a kill at that instant), then look again.
    if let Some(youngest) = found.iter().map(|(_, age)| *age).min() {
        if youngest < SETTLE {
            std::thread::sleep(SETTLE - youngest);
        }
        let Some((shm, found)) = unsized_ages() else {
            return;
        };
        for (name, age) in found {
            if age >= SETTLE {
                shm.remove_own(&name, false);
            }
        }
    }
}

/// iceoryx2 0.10 makes each prefix's global management segment (a node counter in `/dev/shm`)
/// readable and writable by every user, the one resource it opens to all: make ours the
/// owner's alone, as everything else it creates is (a process of another user is then refused,
/// as by the rest). Changed through a descriptor of the file itself, never through a link.
pub(super) fn restrict_global_segment(prefix: &str) {
    let Some((shm, found)) = own_segments(prefix) else {
        return;
    };
    for s in found {
        if s.name.ends_with(b".global_mgmt") && s.stat.st_mode & 0o077 != 0 {
            if let Some((fd, _)) = shm.open_own_file(&s.name, OFlags::RDONLY) {
                let _ = rustix::fs::fchmod(&fd, Mode::from_raw_mode(0o600));
            }
        }
    }
}
