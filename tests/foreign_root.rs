//! A root daemon never writes through another user's iceoryx2 root (issue 47, item 1).
//! `/tmp` is everyone's: an unprivileged user who makes `/tmp/iceoryx2` first, or links its
//! `nodes` and `services` into a root-only directory, chose where a root `driftless run` wrote
//! its node and service files (iceoryx2 follows links there). Now every command that would
//! create a node refuses such a root with exit 2 before it creates anything, and says whose it
//! is and what to do.
//!
//! Each scenario runs as root in a private mount namespace with its own tmpfs on `/tmp` and
//! `/dev/shm` (`common::in_private_tmp`); without root it says so in one line and skips.

mod common;

use std::os::unix::fs::{lchown, symlink, MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// iceoryx2's default root, in the namespace's own `/tmp`.
const ROOT: &str = common::ICEORYX2_ROOT;

/// Another user (nobody), who made the root or its links.
const OTHER_UID: u32 = 65_534;

/// The root-only directory the links lead into.
const SECRET: &str = "/tmp/secret";

fn demo() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/demo.toml").to_string()
}

/// `driftless ARGS` to its end (a minute at most): exit code and stderr.
fn driftless(args: &[&str]) -> (Option<i32>, String) {
    common::run_within(args, Duration::from_secs(60))
}

/// Every path under `dir` (directories too), without following links, with owner and mode.
fn tree(dir: &Path) -> Vec<(PathBuf, u32, u32)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = e.path();
        let m = p.symlink_metadata().expect("metadata");
        out.push((p.clone(), m.uid(), m.mode()));
        if m.is_dir() {
            out.extend(tree(&p));
        }
    }
    out.sort();
    out
}

/// What the commands could write into: the links' target, the root, `/dev/shm`.
fn written() -> Vec<(PathBuf, u32, u32)> {
    [SECRET, ROOT, "/dev/shm"]
        .iter()
        .flat_map(|d| tree(Path::new(d)))
        .collect()
}

/// A root-only directory with `nodes` and `services` in it, as a root daemon's own would be.
fn make_secret() {
    for d in ["", "/nodes", "/services"] {
        let p = format!("{SECRET}{d}");
        std::fs::create_dir(&p).unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o700)).unwrap();
    }
}

fn link_as_other(target: &str, link: &Path) {
    symlink(target, link).unwrap();
    lchown(link, Some(OTHER_UID), Some(OTHER_UID)).unwrap();
}

/// The daemon and the clients that create a node (all but `bridge`, which needs the `zenoh`
/// feature and goes the same way), each refused with exit 2, naming `path` and `owner`, with
/// the fix, and nothing written anywhere.
fn every_command_is_refused(path: &str, owner: &str) {
    let before = written();
    let demo = demo();
    let recording = "/tmp/refused.mcap";
    let commands: [&[&str]; 7] = [
        &["run", &demo, "--duration", "2s", "-q"],
        &["stats", &demo, "--once"],
        &["tap", "demo/corrected", "--count", "1"],
        &["record", "demo/corrected", "-o", recording],
        &["list"],
        &["list", "--clean"],
        &[
            "relay",
            "--input",
            "demo/corrected",
            "--output",
            "demo/relayed",
        ],
    ];
    for args in commands {
        let (code, err) = driftless(args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: one line: {err}");
        for want in [
            path,
            owner,
            "Remove it",
            "root_path",
            "DRIFTLESS_IOX2_ROOT",
            "--root-path",
        ] {
            assert!(err.contains(want), "{args:?}: no {want:?} in: {err}");
        }
        assert_eq!(written(), before, "{args:?} wrote nothing: {err}");
    }
    assert!(!Path::new(recording).exists() && !Path::new("/tmp/refused.mcap.part").exists());
}

#[test]
fn another_users_root_is_refused_before_anything_is_created() {
    let name = "another_users_root_is_refused_before_anything_is_created";
    if !common::in_private_tmp(name) {
        return;
    }
    for d in ["", "/nodes", "/services"] {
        let p = format!("{ROOT}{d}");
        std::fs::create_dir(&p).unwrap();
        std::os::unix::fs::chown(&p, Some(OTHER_UID), Some(OTHER_UID)).unwrap();
    }
    every_command_is_refused(
        &format!("iceoryx2's root directory {ROOT} belongs to"),
        "(uid 65534)",
    );
}

#[test]
fn nodes_and_services_linked_into_a_root_only_directory_are_refused() {
    let name = "nodes_and_services_linked_into_a_root_only_directory_are_refused";
    if !common::in_private_tmp(name) {
        return;
    }
    make_secret();
    std::fs::create_dir(ROOT).unwrap();
    link_as_other(&format!("{SECRET}/nodes"), &Path::new(ROOT).join("nodes"));
    link_as_other(
        &format!("{SECRET}/services"),
        &Path::new(ROOT).join("services"),
    );
    every_command_is_refused(
        &format!("iceoryx2's directory {ROOT}/nodes is a symbolic link (to {SECRET}/nodes"),
        "(uid 65534)",
    );
}

#[test]
fn a_root_that_is_a_link_is_refused() {
    if !common::in_private_tmp("a_root_that_is_a_link_is_refused") {
        return;
    }
    make_secret();
    link_as_other(SECRET, Path::new(ROOT));
    every_command_is_refused(
        &format!("iceoryx2's root directory {ROOT} is a symbolic link (to {SECRET}"),
        "(uid 65534)",
    );
}

#[test]
fn a_root_of_our_own_serves_made_by_us_or_found() {
    if !common::in_private_tmp("a_root_of_our_own_serves_made_by_us_or_found") {
        return;
    }
    let demo = demo();
    let run = ["run", demo.as_str(), "--duration", "0.3s", "-q"];
    // Missing: made by the daemon, as iceoryx2 would make it.
    let (code, err) = driftless(&run);
    assert_eq!(code, Some(0), "{err}");
    for d in ["", "/nodes", "/services"] {
        let m = std::fs::symlink_metadata(format!("{ROOT}{d}")).unwrap();
        assert!(m.is_dir(), "{ROOT}{d}");
        assert_eq!((m.uid(), m.mode() & 0o7777), (0, 0o750), "{ROOT}{d}");
    }
    let (code, err) = driftless(&["list"]);
    assert_eq!(code, Some(0), "{err}");
    // Found, and others may write into it with the sticky bit (a tmpfs of its own, as the other
    // tests mount it): served.
    std::fs::remove_dir_all(ROOT).unwrap();
    std::fs::create_dir(ROOT).unwrap();
    std::fs::set_permissions(ROOT, std::fs::Permissions::from_mode(0o1777)).unwrap();
    let (code, err) = driftless(&run);
    assert_eq!(code, Some(0), "{err}");
    // Without the sticky bit, the same directory is refused, and says why.
    std::fs::set_permissions(ROOT, std::fs::Permissions::from_mode(0o777)).unwrap();
    let (code, err) = driftless(&run);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains(
            "can be written by other users (it belongs to root (uid 0), mode 0777, no sticky bit)"
        ),
        "{err}"
    );
}
