//! iceoryx2's root directory, checked before iceoryx2 uses it: a root that another user
//! controls is refused ([`TransportError::Untrusted`]); before a node, `/dev/shm` and the one
//! name in it a node opens that is known beforehand, too (below). Nodes and listings take
//! their iceoryx2 `Config` from here ([`node_config`], [`listing_config`]), so none is had
//! unchecked.
//!
//! iceoryx2 0.10 never opens its directories without following links: it names its files by
//! path (`<root>/nodes/<id>/...`, `<root>/services/...`), `stat`s and `mkdir`s each missing
//! directory by path, and has no setting that changes that. Only the last component is safe:
//! it creates its files with `O_CREAT | O_EXCL` and binds its sockets, both of which refuse a
//! link there. So whoever can put a link on the way (a `/tmp/iceoryx2` made first by anyone,
//! with `nodes` a link into a root-only directory) chooses where a root daemon writes.
//!
//! The rule, for every directory from `/` down to the root, then `nodes` and `services` in it
//! (the directories iceoryx2 makes there for us; `services/<id>` is for flatbuffer payloads
//! only, and `nodes/<id>` it makes in a `nodes` only we can write):
//! - it belongs to our effective user or to root;
//! - the root, `nodes` and `services` are not links (one above the root may be: it is followed,
//!   and where it leads is checked);
//! - nobody else may write into it: not group- or world-writable, unless sticky (as `/tmp`),
//!   and never for `nodes` and `services`, where iceoryx2 follows a directory planted beside
//!   its own (a node's directory named by its id).
//!
//! Each directory is opened relative to the one above it (`O_PATH`, the last three with
//! `O_NOFOLLOW`) and judged by `fstat` of what was opened. A node's creation makes what is
//! missing, with `mkdirat` (which never follows a link) and the mode iceoryx2 gives (0750), so
//! iceoryx2 finds them made; a listing makes nothing.
//!
//! What it guarantees: once checked, no other user can rename, replace or add any of these
//! directories, because only we and root may write into the ones that hold them, or the
//! holder is sticky and they are ours or root's. So iceoryx2, which resolves the path again on
//! every use, finds what was checked. What it does not: root and our own user can still change
//! them (nothing can stop either); a link above the root is checked where it leads and where it
//! is, not at every directory it passes through on the way; a listing with `nodes` missing in a
//! sticky root others can write into may read through a link planted after the check (it
//! writes nothing there). The check runs again at every node and every listing.
//!
//! `/dev/shm` is outside iceoryx2's root, and needs less: glibc's `shm_open` adds `O_NOFOLLOW`
//! (a link there is never followed, whoever made it: tested in this module and in
//! tests/cleanup_safety.rs) and iceoryx2 names no directory in it. What another user can still
//! do there is put something at the one name a node opens that is known beforehand, the
//! prefix's global management segment ([`GLOBAL_SEGMENT`]): iceoryx2 then fails with
//! `UnableToGenerateUniqueNodeId`, naming nothing, and after an empty file or a fifo the
//! process hung. So before a node, `/dev/shm` is judged as the root is (ours or root's; written by
//! others only if sticky, or they could replace our segments) and that name must be missing or
//! a regular file of ours or root's (root's, for another user: iceoryx2's own refusal of its
//! permissions then says whose). Every other segment's name holds an id drawn when it is made,
//! with `O_EXCL`. What it does not: something put there between the check and iceoryx2's open
//! (still never followed; only the message is then iceoryx2's).

use std::ffi::OsStr;
use std::os::fd::AsFd;
use std::os::unix::ffi::OsStrExt;
use std::path::{Component, Path, PathBuf};

use rustix::fs::{FileType, Mode, OFlags, Stat};
use rustix::io::Errno;

use iceoryx2::config::Config;

use super::cleanup::{is_own, SafeDir, SHM_DIR};
use super::config::{explicit_config, root, PREFIX_ENV, ROOT_ENV};
use super::error::TransportError;
use super::names::GLOBAL_SEGMENT;
use super::permissions::{owner_and_mode, who};

/// The directories iceoryx2 0.10 makes in its root for the services and nodes we create.
const SUBDIRS: [&str; 2] = ["nodes", "services"];

/// The mode iceoryx2 0.10 gives a directory it makes (without its `dev_permissions` feature).
const DIR_MODE: rustix::fs::RawMode = 0o750;

/// What to do with a directory that does not exist yet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Missing {
    /// Make it (before a node is created: iceoryx2 would make it, following links).
    Make,
    /// Stop there (a listing: iceoryx2 makes nothing then).
    Leave,
}

/// Which directory on the way to iceoryx2's files, for the rule and the message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Place {
    /// A directory above the root (a link there is followed).
    Above,
    /// The root itself.
    Root,
    /// `nodes` or `services` in the root.
    Sub,
    /// `/dev/shm`, where the segments are.
    Shm,
}

impl Place {
    fn label(self) -> &'static str {
        match self {
            Place::Above => "the directory above iceoryx2's root,",
            Place::Root => "iceoryx2's root directory",
            Place::Sub => "iceoryx2's directory",
            Place::Shm => "the shared memory directory",
        }
    }
}

/// The explicit iceoryx2 configuration for a node of `prefix` (never the silently discovered
/// `config/iceoryx2.toml`): the root directory in force checked first, and what is missing of
/// it made.
pub(super) fn node_config(prefix: &str) -> Result<Config, TransportError> {
    check_root_dirs(&root(), Missing::Make)?;
    check_shm(Path::new(SHM_DIR), prefix)?;
    explicit_config(prefix)
}

/// [`node_config`] for a listing: the root directory checked, nothing made.
pub(super) fn listing_config(prefix: &str) -> Result<Config, TransportError> {
    check_root_dirs(&root(), Missing::Leave)?;
    explicit_config(prefix)
}

/// Refuse `root` as iceoryx2's root if another user controls it, a directory above it, or its
/// `nodes` or `services` (module docs); `missing` says whether to make what does not exist.
/// Where this process may not look further (no search permission), nor may iceoryx2 write:
/// that is left to iceoryx2's own error, which says whose the directory is.
fn check_root_dirs(root: &Path, missing: Missing) -> Result<(), TransportError> {
    // All of it first, so that a refusal comes before anything is made (a missing `nodes`
    // beside a linked `services`).
    walk(root, Missing::Leave)?;
    if missing == Missing::Make {
        walk(root, Missing::Make)?;
    }
    Ok(())
}

fn walk(root: &Path, missing: Missing) -> Result<(), TransportError> {
    let steps = steps(root);
    let Some(mut dir) = open_dir(rustix::fs::CWD, b"/", false).ok() else {
        return Ok(());
    };
    let mut here = PathBuf::from("/");
    let slash = if steps.is_empty() {
        Place::Root
    } else {
        Place::Above
    };
    judge(&here, &dir.stat_self(), slash)?;
    for (i, name) in steps.iter().enumerate() {
        here.push(OsStr::from_bytes(name));
        let place = if i + 1 == steps.len() {
            Place::Root
        } else {
            Place::Above
        };
        match step(&dir, name, &here, place, missing)? {
            Some(next) => dir = next,
            None => return Ok(()),
        }
    }
    for sub in SUBDIRS {
        step(&dir, sub.as_bytes(), &root.join(sub), Place::Sub, missing)?;
    }
    Ok(())
}

/// The names to open one after the other from `/` to reach `root` (`..` kept: the kernel
/// resolves it where it stands, as for iceoryx2's path).
fn steps(root: &Path) -> Vec<Vec<u8>> {
    root.components()
        .filter_map(|c| match c {
            Component::Normal(n) => Some(n.as_bytes().to_vec()),
            Component::ParentDir => Some(b"..".to_vec()),
            _ => None,
        })
        .collect()
}

/// Refuse `shm` (`/dev/shm`) if another user controls it, or what stands at the name of
/// `prefix`'s global management segment in it if it is not a regular file of ours or root's
/// (module docs). Missing, or not ours to look into: left to iceoryx2's own error.
fn check_shm(shm: &Path, prefix: &str) -> Result<(), TransportError> {
    // Followed if a link (as shm_open's path is): judged where it leads.
    let Ok(dir) = open_dir(rustix::fs::CWD, shm.as_os_str().as_bytes(), false) else {
        return Ok(());
    };
    judge(shm, &dir.stat_self(), Place::Shm)?;
    let name = [prefix.as_bytes(), GLOBAL_SEGMENT].concat();
    let Some(st) = dir.stat(&name) else {
        return Ok(());
    };
    let (uid, kind) = (st.st_uid, FileType::from_raw_mode(st.st_mode));
    let problem = if kind == FileType::Symlink {
        let target = rustix::fs::readlinkat(dir.as_fd(), OsStr::from_bytes(&name), Vec::new())
            .map(|t| String::from_utf8_lossy(t.as_bytes()).into_owned())
            .unwrap_or_else(|_| "?".into());
        format!(
            "is a symbolic link (to {target}, made by {}): iceoryx2 does not follow it \
             (O_NOFOLLOW), but cannot start a node with it there",
            who(uid)
        )
    } else if kind != FileType::RegularFile {
        format!(
            "is not a regular file (it belongs to {}): iceoryx2 would fail or wait on it \
             forever",
            who(uid)
        )
    } else if !is_own(&st) && uid != 0 {
        format!(
            "{}, {}: that user decides what every node of this prefix reads at its start (an \
             empty file holds it forever)",
            owner_and_mode(uid, st.st_mode),
            not_ours()
        )
    } else {
        return Ok(());
    };
    let path = shm.join(OsStr::from_bytes(&name));
    Err(TransportError::Untrusted {
        message: format!(
            "{}, the name of this prefix's global management segment (every node of the prefix \
             opens it), {problem}. Remove it (its owner or root can), or give driftless another \
             prefix: --prefix or {PREFIX_ENV}=..., the same for the daemon and its subscribers",
            path.display()
        ),
        path,
    })
}

/// Open `name` in `dir` as the next directory on the way, judged by what was opened; make it if
/// missing and asked to. `None`: nothing to check beyond (missing, or no permission to look).
fn step(
    dir: &SafeDir,
    name: &[u8],
    path: &Path,
    place: Place,
    missing: Missing,
) -> Result<Option<SafeDir>, TransportError> {
    let no_follow = place != Place::Above;
    let (mut tried, mut made) = (false, false);
    let opened = loop {
        match open_dir(dir, name, no_follow) {
            Err(Errno::NOENT) if missing == Missing::Make && !tried => {
                tried = true;
                match rustix::fs::mkdirat(dir.as_fd(), OsStr::from_bytes(name), mode(DIR_MODE)) {
                    Ok(()) => made = true,
                    // Made by another process meanwhile: judged as found.
                    Err(Errno::EXIST) => {}
                    Err(_) => return Ok(None),
                }
            }
            other => break other,
        }
    };
    match opened {
        Ok(next) => {
            judge(path, &next.stat_self(), place)?;
            if made {
                set_mode(dir, name);
            }
            Ok(Some(next))
        }
        Err(Errno::LOOP | Errno::NOTDIR) => Err(not_a_directory(dir, name, path, place)),
        // Missing, or not ours to look into (nor iceoryx2's to write into): nothing beyond.
        Err(_) => Ok(None),
    }
}

/// Open the directory `name` in `dir` only to go through it and to `fstat` it (`O_PATH`: no
/// read permission needed, as iceoryx2's own path lookups need none).
fn open_dir(dir: impl AsFd, name: &[u8], no_follow: bool) -> rustix::io::Result<SafeDir> {
    let flags = if no_follow {
        OFlags::PATH | OFlags::NOFOLLOW
    } else {
        OFlags::PATH
    };
    SafeDir::open_with(dir, name, flags)
}

/// Give a directory we just made the mode iceoryx2 gives its own (its `mkdir` applies the
/// umask, and so does ours): through a descriptor of the directory itself, never a link.
fn set_mode(dir: &SafeDir, name: &[u8]) {
    if let Ok(d) = SafeDir::open_with(dir, name, OFlags::RDONLY | OFlags::NOFOLLOW) {
        if d.stat_self().is_some_and(|st| is_own(&st)) {
            let _ = rustix::fs::fchmod(d.as_fd(), mode(DIR_MODE));
        }
    }
}

fn mode(bits: rustix::fs::RawMode) -> Mode {
    Mode::from_raw_mode(bits)
}

/// The rule (module docs) for the directory at `path`, as `fstat` found it.
fn judge(path: &Path, st: &Option<Stat>, place: Place) -> Result<(), TransportError> {
    let Some(st) = st else {
        return Ok(());
    };
    let (uid, mode) = (st.st_uid, st.st_mode);
    if !is_own(st) && uid != 0 {
        let could = match place {
            Place::Shm => "replace this process's shared memory segments",
            _ => "choose where iceoryx2 writes this process's files",
        };
        return Err(untrusted(
            path,
            place,
            format!(
                "{}, {}: that user could {could}",
                owner_and_mode(uid, mode),
                not_ours()
            ),
        ));
    }
    let sticky_ok = place != Place::Sub;
    if mode & 0o022 != 0 && !(sticky_ok && mode & 0o1000 != 0) {
        let sticky = if sticky_ok { ", no sticky bit" } else { "" };
        let could = match place {
            Place::Shm => "remove or replace this process's segments",
            _ => "put a link in it, and iceoryx2 would follow it",
        };
        return Err(untrusted(
            path,
            place,
            format!(
                "can be written by other users (it {}{sticky}): any of them could {could}",
                owner_and_mode(uid, mode)
            ),
        ));
    }
    Ok(())
}

/// `not to NAME, who runs this process[, nor to root]`.
fn not_ours() -> String {
    let me = rustix::process::geteuid().as_raw();
    if me == 0 {
        "not to root, who runs this process".to_string()
    } else {
        format!("not to {}, who runs this process, nor to root", who(me))
    }
}

/// The refusal of `name` in `dir`, found not to be a directory (a link, or something else).
fn not_a_directory(dir: &SafeDir, name: &[u8], path: &Path, place: Place) -> TransportError {
    let Some(st) = dir.stat(name) else {
        return untrusted(path, place, "is not a directory".into());
    };
    let link = FileType::from_raw_mode(st.st_mode) == FileType::Symlink;
    // Above the root a link is followed: there, only where it leads is wrong.
    let problem = if link && place != Place::Above {
        let target = rustix::fs::readlinkat(dir.as_fd(), OsStr::from_bytes(name), Vec::new())
            .map(|t| String::from_utf8_lossy(t.as_bytes()).into_owned())
            .unwrap_or_else(|_| "?".into());
        format!(
            "is a symbolic link (to {target}, made by {}): iceoryx2 would write wherever it \
             leads",
            who(st.st_uid)
        )
    } else {
        format!(
            "does not lead to a directory (it belongs to {})",
            who(st.st_uid)
        )
    };
    untrusted(path, place, problem)
}

/// The refusal in full: which directory, what is wrong, and the ways out (a directory above
/// the root is not iceoryx2's to remove).
fn untrusted(path: &Path, place: Place, problem: String) -> TransportError {
    let give = match place {
        Place::Above => "Give",
        Place::Root | Place::Sub => "Remove it (its owner or root can), or give",
        Place::Shm => {
            return TransportError::Untrusted {
                path: path.to_path_buf(),
                message: format!(
                    "{} {} {problem}. Mount it as the system does: root's, mode 1777",
                    place.label(),
                    path.display()
                ),
            }
        }
    };
    TransportError::Untrusted {
        path: path.to_path_buf(),
        message: format!(
            "{} {} {problem}. {give} driftless a root directory of its own: `root_path = \
             \"...\"` under [iceoryx2] in the pipeline file, or {ROOT_ENV}=..., or --root-path, \
             the same for the daemon and its subscribers",
            place.label(),
            path.display()
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::{symlink, MetadataExt, PermissionsExt};

    fn chmod(p: &Path, mode: u32) {
        std::fs::set_permissions(p, std::fs::Permissions::from_mode(mode)).unwrap();
    }

    fn message(r: Result<(), TransportError>) -> String {
        match r {
            Err(e @ TransportError::Untrusted { .. }) => e.to_string(),
            other => panic!("not refused: {other:?}"),
        }
    }

    #[test]
    fn a_root_of_ours_is_made_with_iceoryx2s_mode_and_a_listing_makes_nothing() {
        let t = tempfile::tempdir().unwrap();
        let root = t.path().join("a/iox");
        check_root_dirs(&root, Missing::Leave).unwrap();
        assert!(!t.path().join("a").exists(), "a listing made nothing");
        check_root_dirs(&root, Missing::Make).unwrap();
        for d in ["a", "a/iox", "a/iox/nodes", "a/iox/services"] {
            let m = std::fs::symlink_metadata(t.path().join(d)).unwrap();
            assert!(m.is_dir(), "{d}");
            assert_eq!(m.mode() & 0o7777, DIR_MODE, "{d}");
        }
        check_root_dirs(&root, Missing::Leave).unwrap();
    }

    #[test]
    fn links_at_the_root_nodes_or_services_are_refused_and_nothing_is_made_through_them() {
        let t = tempfile::tempdir().unwrap();
        let target = t.path().join("target");
        std::fs::create_dir(&target).unwrap();
        let root = t.path().join("iox");
        symlink(&target, &root).unwrap();
        let m = message(check_root_dirs(&root, Missing::Make));
        assert!(
            m.contains(&format!("iceoryx2's root directory {}", root.display())),
            "{m}"
        );
        assert!(m.contains("is a symbolic link (to "), "{m}");

        std::fs::remove_file(&root).unwrap();
        std::fs::create_dir(&root).unwrap();
        symlink(&target, root.join("services")).unwrap();
        let m = message(check_root_dirs(&root, Missing::Make));
        assert!(m.contains("iox/services is a symbolic link"), "{m}");
        assert_eq!(std::fs::read_dir(&target).unwrap().count(), 0);
        assert!(
            !root.join("nodes").exists(),
            "refused before anything is made"
        );
    }

    #[test]
    fn others_may_write_into_the_root_only_with_the_sticky_bit_and_never_into_nodes() {
        let t = tempfile::tempdir().unwrap();
        let root = t.path().join("iox");
        check_root_dirs(&root, Missing::Make).unwrap();
        chmod(&root, 0o777);
        let m = message(check_root_dirs(&root, Missing::Leave));
        assert!(m.contains("mode 0777, no sticky bit"), "{m}");
        chmod(&root, 0o1777);
        check_root_dirs(&root, Missing::Leave).unwrap();
        chmod(&root.join("nodes"), 0o1770);
        let m = message(check_root_dirs(&root, Missing::Leave));
        assert!(
            m.contains("iox/nodes can be written by other users (it belongs to"),
            "{m}"
        );
        assert!(m.contains("mode 1770): any of them"), "{m}");
        // Above the root, as at the root: /tmp is fine, a world-writable parent is not.
        chmod(&root.join("nodes"), 0o750);
        chmod(t.path(), 0o777);
        let m = message(check_root_dirs(&root, Missing::Leave));
        assert!(m.starts_with("the directory above iceoryx2's root,"), "{m}");
        assert!(!m.contains("Remove it"), "{m}");
    }

    #[test]
    fn another_users_root_is_refused_by_name_and_uid() {
        if !rustix::process::geteuid().is_root() {
            eprintln!("skipped: giving a directory to another user needs root");
            return;
        }
        let t = tempfile::tempdir().unwrap();
        let root = t.path().join("iox");
        std::fs::create_dir(&root).unwrap();
        std::os::unix::fs::chown(&root, Some(65_534), None).unwrap();
        let m = message(check_root_dirs(&root, Missing::Make));
        assert!(
            m.contains("(uid 65534), mode 0755, not to root, who runs"),
            "{m}"
        );
        assert!(m.contains("DRIFTLESS_IOX2_ROOT"), "{m}");
        assert!(!root.join("nodes").exists(), "nothing made in it");
    }

    /// The name of `prefix`'s global management segment in `/dev/shm`.
    fn global_segment(prefix: &str) -> PathBuf {
        Path::new(SHM_DIR).join(OsStr::from_bytes(
            &[prefix.as_bytes(), GLOBAL_SEGMENT].concat(),
        ))
    }

    /// A link at the global management segment's name, the one iceoryx2 opens by a name known
    /// beforehand: iceoryx2 itself (asked directly, past our check) fails and never follows it;
    /// our check refuses it by name first. The link is this process's own, so the kernel's
    /// `protected_symlinks` (which stops following another user's link in a sticky directory)
    /// plays no part: only `O_NOFOLLOW` keeps the target whole.
    #[test]
    fn a_link_at_the_global_segments_name_is_never_followed_and_refused_by_name() {
        use iceoryx2::prelude::{NodeBuilder, SignalHandlingMode};
        let prefix = format!("dltrust{}_", std::process::id());
        let t = tempfile::tempdir().unwrap();
        let target = t.path().join("secret");
        std::fs::write(&target, "secret").unwrap();
        chmod(&target, 0o600);
        let before = std::fs::metadata(&target).unwrap();
        let link = global_segment(&prefix);
        symlink(&target, &link).unwrap();
        let mut cfg = explicit_config(&prefix).unwrap();
        let iox_root = super::super::config::iox_root(&t.path().join("iox")).unwrap();
        cfg.global.set_root_path(&iox_root);
        let node = || {
            NodeBuilder::new()
                .config(&cfg)
                .signal_handling_mode(SignalHandlingMode::Disabled)
                .create::<super::super::config::Svc>()
        };
        let through_the_link = node().map(drop);
        let refused = check_shm(Path::new(SHM_DIR), &prefix);
        let still_a_link = link.symlink_metadata().map(|m| m.file_type().is_symlink());
        std::fs::remove_file(&link).unwrap();
        // Without the link the same node is made (so the link was why it was not).
        let without = node().map(drop);
        let _ = std::fs::remove_file(&link);
        assert!(without.is_ok(), "{without:?}");
        assert!(
            through_the_link.is_err(),
            "iceoryx2 made a node through the link"
        );
        let after = std::fs::metadata(&target).unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"secret");
        assert_eq!(
            (
                after.len(),
                after.mode(),
                after.mtime(),
                after.mtime_nsec(),
                after.ino()
            ),
            (
                before.len(),
                before.mode(),
                before.mtime(),
                before.mtime_nsec(),
                before.ino()
            )
        );
        assert!(matches!(still_a_link, Ok(true)), "the link left as it was");
        let m = message(refused);
        assert!(
            m.starts_with(&format!("{}, the name of", link.display())),
            "{m}"
        );
        assert!(
            m.contains(&format!(
                "is a symbolic link (to {}, made by",
                target.display()
            )),
            "{m}"
        );
        assert!(m.contains("--prefix"), "{m}");
    }

    #[test]
    fn dev_shm_is_judged_as_the_root_and_a_file_of_ours_at_the_name_passes() {
        let t = tempfile::tempdir().unwrap();
        let shm = t.path().join("shm");
        std::fs::create_dir(&shm).unwrap();
        chmod(&shm, 0o1777);
        let seg = shm.join(OsStr::from_bytes(&[b"p_", GLOBAL_SEGMENT].concat()));
        std::fs::write(&seg, [0u8; 64]).unwrap();
        check_shm(&shm, "p_").unwrap();
        // Another prefix's name is not looked at.
        std::fs::remove_file(&seg).unwrap();
        std::fs::create_dir(&seg).unwrap();
        check_shm(&shm, "q_").unwrap();
        let m = message(check_shm(&shm, "p_"));
        assert!(m.contains("is not a regular file (it belongs to"), "{m}");
        std::fs::remove_dir(&seg).unwrap();
        chmod(&shm, 0o777);
        let m = message(check_shm(&shm, "p_"));
        assert!(
            m.starts_with(&format!(
                "the shared memory directory {} can be written",
                shm.display()
            )),
            "{m}"
        );
        assert!(m.contains("mode 0777, no sticky bit"), "{m}");
        assert!(m.ends_with("root's, mode 1777"), "{m}");
    }
}
