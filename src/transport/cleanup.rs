//! Clean-up of the files iceoryx2 leaves in `/dev/shm` and its root directory: a prefix's
//! leftovers after the last node, segments a killed process never sized, and the permissions
//! of the one segment iceoryx2 opens to every user.

use std::time::Duration;

use super::config::root;
use super::node::Transport;

/// Remove this prefix's shared memory segments of size 0 older than a second: what a process
/// killed between creating a segment and sizing it leaves (creator and size are microseconds
/// apart). iceoryx2 0.10 waits for such a segment to be sized without a timeout
/// (`MappingSizeIsZero` in its `open_impl`), so the next node's clean-up of dead nodes, or a
/// listing, would hang forever (found by the `list --clean` test killing daemons mid-start).
pub(super) fn remove_unsized_segments(prefix: &str) {
    const SETTLE: Duration = Duration::from_secs(1);
    let unsized_segments = || -> Vec<(std::path::PathBuf, Duration)> {
        own_segments(prefix)
            .into_iter()
            .filter(|(_, m)| m.is_file() && m.len() == 0)
            .filter_map(|(path, m)| Some((path, m.modified().ok()?.elapsed().unwrap_or_default())))
            .collect()
    };
    let found = unsized_segments();
    // A segment younger than a second may be one a live process is sizing right now: wait
    // until it is a second old (rare: only after a kill at that instant), then look again.
    if let Some(youngest) = found.iter().map(|(_, age)| *age).min() {
        if youngest < SETTLE {
            std::thread::sleep(SETTLE - youngest);
        }
        for (path, age) in unsized_segments() {
            if age >= SETTLE {
                let _ = std::fs::remove_file(path);
            }
        }
    }
}

/// iceoryx2 0.10 makes each prefix's global management segment (a node counter in `/dev/shm`)
/// readable and writable by every user, the one resource it opens to all: make ours the
/// owner's alone, as everything else it creates is (a process of another user is then refused,
/// as by the rest).
pub(super) fn restrict_global_segment(prefix: &str) {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    for (path, m) in own_segments(prefix) {
        let global = path.to_string_lossy().ends_with(".global_mgmt");
        if global && m.mode() & 0o077 != 0 {
            let _ = std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600));
        }
    }
}

/// This prefix's shared memory segments in `/dev/shm` that belong to this process's user, with
/// their metadata.
fn own_segments(prefix: &str) -> Vec<(std::path::PathBuf, std::fs::Metadata)> {
    use std::os::unix::fs::MetadataExt;
    // SAFETY: geteuid cannot fail.
    let me = unsafe { libc::geteuid() };
    let Ok(entries) = std::fs::read_dir("/dev/shm") else {
        return Vec::new();
    };
    entries
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with(prefix))
        .filter_map(|e| Some((e.path(), e.metadata().ok()?)))
        .filter(|(_, m)| m.uid() == me)
        .collect()
}

/// Remove the files iceoryx2 leaves for `prefix` once no node of it is left (the per-prefix
/// management file in `/dev/shm`). Does nothing while a node of the prefix is alive.
pub fn remove_prefix_leftovers(prefix: &str) {
    if Transport::node_count(prefix).map_or(true, |n| n > 0) {
        return;
    }
    for dir in [std::path::PathBuf::from("/dev/shm"), root()] {
        remove_files_with_prefix(&dir, prefix);
    }
}

pub(super) fn remove_files_with_prefix(dir: &std::path::Path, prefix: &str) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name();
        if !name.to_string_lossy().starts_with(prefix) {
            if path.is_dir() {
                remove_files_with_prefix(&path, prefix);
            }
            continue;
        }
        if path.is_dir() {
            let _ = std::fs::remove_dir_all(&path);
        } else {
            let _ = std::fs::remove_file(&path);
        }
    }
}
