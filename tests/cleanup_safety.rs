//! The clean-up deletes only what is ours, on a machine shared with other users and programs
//! (issue 38): another user's files, another prefix's live daemon, symlinks planted in
//! `/dev/shm` (to a root-only directory, in a loop, at the names a daemon's segments get:
//! issue 59), a full `/dev/shm`, and a stop at any moment of the start.
//!
//! Each scenario runs in a private mount namespace with its own tmpfs on `/dev/shm` and on
//! iceoryx2's root directory, never on the host's: the test re-runs itself (this test binary,
//! `--exact` the same test) under `unshare -m`, and the child does the work. Making the
//! namespace needs root (CI runs as root); without it a scenario says so in one line and skips.

mod common;

use std::os::unix::fs::{symlink, MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{bin, finish, run_within, Prefix};

/// iceoryx2's root directory in the namespace (its own tmpfs).
const ROOT: &str = common::ICEORYX2_ROOT;

/// A uid that is not ours (nobody).
const OTHER_UID: u32 = 65_534;

/// A SHA-1 as iceoryx2 writes them, and a node or port id.
const H: &str = "0354a209029e7d094a819e2d4030ea331e6caaf0";
const D: &str = "158456425824514663799274340511";

fn in_namespace(test: &str, shm_size: &str) -> bool {
    common::in_private_shm(test, shm_size)
}

/// The demo for a short while under `prefix`: its exit code and stderr.
fn demo(prefix: &str, secs: &str) -> (Option<i32>, String) {
    let demo = concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/demo.toml");
    run_within(
        &["run", demo, "--prefix", prefix, "--duration", secs, "-q"],
        Duration::from_secs(60),
    )
}

/// Every file (not directory) under `dir`, without following links.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return out;
    };
    for e in entries.flatten() {
        let p = e.path();
        match e.file_type() {
            Ok(t) if t.is_dir() => out.extend(files(&p)),
            _ => out.push(p),
        }
    }
    out.sort();
    out
}

fn names(dir: &Path) -> Vec<String> {
    files(dir)
        .iter()
        .map(|p| p.strip_prefix(dir).unwrap().display().to_string())
        .collect()
}

/// Create `path` with `text`, owned by `uid`.
fn plant(path: &Path, text: &str, uid: u32) {
    std::fs::write(path, text).expect("plant");
    std::os::unix::fs::lchown(path, Some(uid), Some(uid)).expect("chown");
}

#[test]
fn another_users_files_and_other_programs_files_survive_our_clean_up() {
    if !in_namespace(
        "another_users_files_and_other_programs_files_survive_our_clean_up",
        "64m",
    ) {
        return;
    }
    let shm = Path::new("/dev/shm");
    // Another user's files under our prefix, one named exactly as iceoryx2 names a segment;
    // a program's file that a bare starts_with("p") matched; one of ours that iceoryx2 never
    // names.
    let theirs = [
        format!("driftless_{H}_{D}.data"),
        format!("driftless_{H}_node.0_10_0.global_mgmt"),
        "driftless_notes".to_string(),
        "pulse-shm-12345".to_string(),
    ];
    for n in &theirs {
        plant(&shm.join(n), "theirs", OTHER_UID);
    }
    plant(&shm.join("driftless_keep.conf"), "ours, not iceoryx2's", 0);
    let mut root_theirs = vec![];
    std::fs::create_dir_all(Path::new(ROOT).join("services")).unwrap();
    let service = Path::new(ROOT).join(format!("services/driftless_{H}.service"));
    plant(&service, "theirs", OTHER_UID);
    root_theirs.push(service);

    let (code, err) = demo("driftless_", "0.3s");
    assert_eq!(code, Some(0), "{err}");
    // A prefix that a bare starts_with would have taken for pulse-shm's is refused, with the fix.
    let (code, err) = demo("p", "0.3s");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("try \"p_\""), "{err}");
    let (code, err) = run_within(&["list", "--clean"], Duration::from_secs(30));
    assert_eq!(code, Some(0), "{err}");

    let mut want: Vec<String> = theirs.to_vec();
    want.push("driftless_keep.conf".into());
    want.sort();
    assert_eq!(
        names(shm),
        want,
        "only others' files and ours that iceoryx2 never names"
    );
    for p in &root_theirs {
        assert!(p.exists(), "{} survives", p.display());
    }
    assert_eq!(
        std::fs::read_to_string(shm.join("pulse-shm-12345")).unwrap(),
        "theirs"
    );
}

#[test]
fn a_live_daemon_under_another_prefix_survives_a_shorter_prefixs_clean_up() {
    if !in_namespace(
        "a_live_daemon_under_another_prefix_survives_a_shorter_prefixs_clean_up",
        "64m",
    ) {
        return;
    }
    // driftless_b, the prefix that lost its files before, is refused with the one that works.
    let (code, err) = demo("driftless_b", "0.3s");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("try \"driftless-b_\""), "{err}");

    let demo_file = concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/demo.toml");
    let live = Command::new(bin())
        .args([
            "run",
            demo_file,
            "--prefix",
            "driftless-b_",
            "--duration",
            "60s",
            "-q",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let shm = Path::new("/dev/shm");
    let end = Instant::now() + Duration::from_secs(60);
    let tap_b = |count: &str| {
        run_within(
            &[
                "tap",
                "demo/corrected",
                "--prefix",
                "driftless-b_",
                "--count",
                count,
            ],
            Duration::from_secs(30),
        )
    };
    while tap_b("1").0 != Some(0) {
        assert!(
            Instant::now() < end,
            "the daemon under driftless-b_ never served"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let before = (names(shm), names(Path::new(ROOT)));
    assert!(!before.0.is_empty());

    // Everything of the shorter prefix that cleans up on exit: a tap, a daemon, list --clean.
    let (code, _) = run_within(
        &[
            "tap",
            "demo/corrected",
            "--prefix",
            "driftless_",
            "--duration",
            "0.5s",
        ],
        Duration::from_secs(30),
    );
    assert!(code.is_some());
    let (code, err) = demo("driftless_", "0.3s");
    assert_eq!(code, Some(0), "{err}");
    let (code, err) = run_within(
        &["list", "--clean", "--prefix", "driftless_"],
        Duration::from_secs(30),
    );
    assert_eq!(code, Some(0), "{err}");

    // The live daemon's files are all there (its own may have come and gone: taps), and its
    // next subscriber is served.
    let after = names(shm);
    for f in before.0.iter().filter(|f| f.contains("global_mgmt")) {
        assert!(after.contains(f), "{f} survives");
    }
    assert!(
        after.iter().all(|f| f.starts_with("driftless-b_")),
        "{after:?}"
    );
    let (code, err) = tap_b("5");
    assert_eq!(code, Some(0), "a new subscriber is served: {err}");
    common::signal(&live, libc::SIGTERM);
    let (code, err) = finish(live, Duration::from_secs(30));
    assert_eq!(code, Some(0), "{err}");
    assert!(names(shm).is_empty(), "{:?}", names(shm));
}

/// A node that is being created has its details written before the monitor that makes it
/// listed: a command ending meanwhile (here `list`, its clean-up finding no node) must not
/// take them (a listing then showed the daemon's node without its name). Planted as iceoryx2
/// leaves them in that instant; a second later, with still no monitor, they are a dead
/// start's and go.
#[test]
fn a_node_being_created_keeps_its_details_through_another_commands_clean_up() {
    if !in_namespace(
        "a_node_being_created_keeps_its_details_through_another_commands_clean_up",
        "64m",
    ) {
        return;
    }
    let node_dir = Path::new(ROOT).join("nodes").join(D);
    std::fs::create_dir_all(&node_dir).unwrap();
    let details = node_dir.join("settle_node.details");
    // SAFETY: geteuid cannot fail.
    plant(&details, "name = \"starting\"", unsafe { libc::geteuid() });
    let planted = Instant::now();
    let list = || run_within(&["list", "--prefix", "settle_"], Duration::from_secs(30));
    let (code, err) = list();
    assert_eq!(code, Some(0), "{err}");
    assert!(
        planted.elapsed() < Duration::from_millis(900),
        "the machine was too slow to tell: {:?}",
        planted.elapsed()
    );
    assert!(details.exists(), "a starting node's details were removed");
    std::thread::sleep(Duration::from_millis(1100).saturating_sub(planted.elapsed()));
    let (code, err) = list();
    assert_eq!(code, Some(0), "{err}");
    assert!(!details.exists(), "a dead start's details were left");
    assert!(!node_dir.exists(), "its node directory was left");
}

#[test]
fn a_symlink_to_a_root_only_directory_is_never_followed() {
    if !in_namespace(
        "a_symlink_to_a_root_only_directory_is_never_followed",
        "64m",
    ) {
        return;
    }
    let secret = tempfile::tempdir().unwrap();
    std::fs::set_permissions(secret.path(), std::fs::Permissions::from_mode(0o700)).unwrap();
    let kept = [
        "driftless_keep.conf".to_string(),
        format!("driftless_{H}_{D}.data"),
        format!("driftless_{H}.service"),
        "driftless_node.details".to_string(),
    ];
    for n in &kept {
        plant(&secret.path().join(n), "secret", 0);
    }
    // An unprivileged user's links: to the directory, under a name iceoryx2 would give a
    // segment, and in iceoryx2's nodes directory as a node's directory and monitor.
    let shm = Path::new("/dev/shm");
    let nodes = Path::new(ROOT).join("nodes");
    std::fs::create_dir_all(&nodes).unwrap();
    std::fs::set_permissions(&nodes, std::fs::Permissions::from_mode(0o750)).unwrap();
    let links = [
        (shm.join("innocent"), secret.path().to_path_buf()),
        (
            shm.join(format!("driftless_{H}_1.data")),
            secret.path().join(&kept[1]),
        ),
        (nodes.join(D), secret.path().to_path_buf()),
        (
            nodes.join(format!("driftless_{D}.node_monitor")),
            secret.path().join(&kept[0]),
        ),
    ];
    for (link, target) in &links {
        symlink(target, link).unwrap();
        std::os::unix::fs::lchown(link, Some(OTHER_UID), Some(OTHER_UID)).unwrap();
    }
    let (code, err) = demo("driftless_", "0.3s");
    assert_eq!(code, Some(0), "{err}");
    let (code, err) = run_within(&["list", "--clean"], Duration::from_secs(30));
    eprintln!("list --clean: {code:?} {err}");
    let mut want = kept.to_vec();
    want.sort();
    assert_eq!(names(secret.path()), want, "the directory is untouched");
    for n in &kept {
        let m = std::fs::metadata(secret.path().join(n)).unwrap();
        assert_eq!(m.mode() & 0o777, 0o644 & !umask(), "{n}: mode unchanged");
    }
    for (link, _) in &links {
        assert!(
            link.symlink_metadata().is_ok(),
            "{}: left alone",
            link.display()
        );
    }
}

/// A file's content and what says whether it was written, truncated, replaced or re-moded.
fn fingerprint(path: &Path) -> (Vec<u8>, u64, u32, u32, i64, i64, u64) {
    let m = std::fs::symlink_metadata(path).expect("the target is still there");
    let text = std::fs::read(path).expect("read");
    (
        text,
        m.len(),
        m.mode(),
        m.uid(),
        m.mtime(),
        m.mtime_nsec(),
        m.ino(),
    )
}

/// `args` run by another user (nobody) with setpriv(1), as that user would from a shell.
fn as_other(args: &[&str]) {
    let id = OTHER_UID.to_string();
    let out = Command::new("setpriv")
        .args(["--reuid", &id, "--regid", &id, "--clear-groups", "--"])
        .args(args)
        .output()
        .expect("setpriv runs");
    assert!(out.status.success(), "{args:?} as nobody: {out:?}");
}

/// Issue 59: `/dev/shm` is outside the root's trust check, on the belief that iceoryx2's
/// `shm_open` never follows a link (glibc adds `O_NOFOLLOW`) and that the sticky `/dev/shm`
/// lets no one replace our files. Another user links the exact names iceoryx2 gave a daemon's
/// segments (found by running one) to root-only files outside `/dev/shm`. A root daemon never
/// follows them: at the global management segment's name, the one a node opens by a name known
/// beforehand, it is refused with exit 2 and a line naming the link, its maker and the fix (it
/// failed with `UnableToGenerateUniqueNodeId` before, naming nothing); at the other names (ids
/// drawn anew at each start) it runs and never touches them. The clean-up neither follows nor
/// removes any of them. Another user's empty file at that name (a hang before) and a
/// `/dev/shm` without its sticky bit are refused as well.
#[test]
fn links_at_our_segments_names_are_never_followed_and_the_global_ones_is_refused_by_name() {
    if !in_namespace(
        "links_at_our_segments_names_are_never_followed_and_the_global_ones_is_refused_by_name",
        "64m",
    ) {
        return;
    }
    let shm = Path::new("/dev/shm");
    eprintln!(
        "fs.protected_symlinks = {:?}",
        std::fs::read_to_string("/proc/sys/fs/protected_symlinks").map(|s| s.trim().to_string())
    );
    // The names a daemon's segments get: read while one runs.
    let demo_file = concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/demo.toml");
    let live = Command::new(bin())
        .args([
            "run",
            demo_file,
            "--prefix",
            "driftless_",
            "--duration",
            "60s",
            "-q",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let end = Instant::now() + Duration::from_secs(30);
    let find = |seen: &[String], suffix: &str| seen.iter().find(|n| n.ends_with(suffix)).cloned();
    let (global, data, dynamic) = loop {
        let seen = names(shm);
        if let (Some(g), Some(d), Some(y)) = (
            find(&seen, ".global_mgmt"),
            find(&seen, ".data"),
            find(&seen, ".dynamic"),
        ) {
            break (g, d, y);
        }
        assert!(Instant::now() < end, "no segments seen: {seen:?}");
        std::thread::sleep(Duration::from_millis(50));
    };
    common::signal(&live, libc::SIGTERM);
    let (code, err) = finish(live, Duration::from_secs(30));
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(names(shm), Vec::<String>::new(), "the daemon cleaned up");

    // Root-only files outside /dev/shm, one per name.
    let secret = tempfile::tempdir().unwrap();
    std::fs::set_permissions(secret.path(), std::fs::Permissions::from_mode(0o700)).unwrap();
    let mut links = Vec::new();
    for name in [&global, &data, &dynamic] {
        let target = secret
            .path()
            .join(format!("{}.secret", &name[name.len() - 12..]));
        std::fs::write(&target, format!("root's own, for {name}\n")).unwrap();
        std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o600)).unwrap();
        let link = shm.join(name);
        as_other(&["ln", "-s", target.to_str().unwrap(), link.to_str().unwrap()]);
        links.push((link, target));
    }
    let targets = || -> Vec<_> { links.iter().map(|(_, t)| fingerprint(t)).collect() };
    let before = (targets(), names(secret.path()));
    let untouched = |when: &str, links: &[(PathBuf, PathBuf)]| {
        assert_eq!(
            (targets(), names(secret.path())),
            before,
            "{when}: targets unchanged"
        );
        for (link, target) in links {
            let m = link
                .symlink_metadata()
                .unwrap_or_else(|e| panic!("{when}: {e}"));
            assert!(m.file_type().is_symlink() && m.uid() == OTHER_UID, "{when}");
            assert_eq!(std::fs::read_link(link).unwrap(), *target, "{when}");
        }
    };

    // The global segment's name: refused by name, before anything is made.
    let planted = names(shm);
    let (code, err) = demo("driftless_", "1s");
    assert_eq!(code, Some(2), "{err}");
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    for want in [
        format!(
            "{}, the name of this prefix's global management segment",
            links[0].0.display()
        ),
        format!(
            "is a symbolic link (to {}, made by nobody (uid 65534))",
            links[0].1.display()
        ),
        "Remove it".into(),
        "--prefix".into(),
    ] {
        assert!(err.contains(&want), "no {want:?} in: {err}");
    }
    untouched("a refused daemon", &links);
    assert_eq!(names(shm), planted, "the refused daemon made nothing");
    // The clean-up: `list --clean` is refused the same way (it makes a node); `list` looks.
    let (code, err) = run_within(&["list", "--clean"], Duration::from_secs(30));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("is a symbolic link (to "), "{err}");
    let (code, err) = run_within(&["list"], Duration::from_secs(30));
    assert_eq!(code, Some(0), "{err}");
    untouched("list --clean and list", &links);
    assert_eq!(names(shm), planted);

    // Removed (as the message says), the other two stay: names a new start never draws. The
    // daemon serves, its clean-up at exit and list --clean leave them and their targets.
    std::fs::remove_file(&links[0].0).unwrap();
    let (code, err) = demo("driftless_", "1s");
    assert_eq!(code, Some(0), "{err}");
    let (code, err) = run_within(&["list", "--clean"], Duration::from_secs(30));
    assert_eq!(code, Some(0), "{err}");
    untouched(
        "a daemon beside the other links, and list --clean",
        &links[1..],
    );
    let mut left = vec![data.clone(), dynamic.clone()];
    left.sort();
    assert_eq!(names(shm), left, "only the links are left");

    // Another user's empty file there held a node's start forever: refused, at once.
    let empty = shm.join(&global);
    as_other(&["sh", "-c", &format!(": > '{}'", empty.display())]);
    let (code, err) = demo("driftless_", "1s");
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("belongs to nobody (uid 65534), mode "),
        "{err}"
    );
    std::fs::remove_file(&empty).unwrap();

    // A /dev/shm others could write into without the sticky bit: refused, named.
    std::fs::set_permissions(shm, std::fs::Permissions::from_mode(0o777)).unwrap();
    let (code, err) = demo("driftless_", "1s");
    std::fs::set_permissions(shm, std::fs::Permissions::from_mode(0o1777)).unwrap();
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("the shared memory directory /dev/shm can be written by other users"),
        "{err}"
    );
    untouched("the end", &links[1..]);
}

fn umask() -> u32 {
    // SAFETY: umask is always safe; set it back at once.
    unsafe {
        let m = libc::umask(0o022);
        libc::umask(m);
        m
    }
}

#[test]
fn a_symlink_loop_in_dev_shm_hangs_nothing() {
    if !in_namespace("a_symlink_loop_in_dev_shm_hangs_nothing", "64m") {
        return;
    }
    let shm = Path::new("/dev/shm");
    for (name, target) in [
        ("loop1", "/dev/shm"),
        ("loop2", "/dev/shm"),
        ("driftless_x", "."),
    ] {
        symlink(target, shm.join(name)).unwrap();
        std::os::unix::fs::lchown(shm.join(name), Some(OTHER_UID), Some(OTHER_UID)).unwrap();
    }
    // Each ends in seconds; `finish` fails the test on a hang.
    let (code, err) = demo("driftless_", "0.5s");
    assert_eq!(code, Some(0), "{err}");
    let (code, _) = run_within(
        &["tap", "demo/corrected", "--duration", "0.5s"],
        Duration::from_secs(20),
    );
    assert!(code.is_some());
    let (code, err) = run_within(&["list", "--clean"], Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(names(shm), ["driftless_x", "loop1", "loop2"]);
}

/// A daemon on a `/dev/shm` of `size`: the clear error, exit 2, nothing left.
fn tiny_dev_shm(test: &str, size: &str) {
    if !in_namespace(test, size) {
        return;
    }
    let (code, err) = demo("driftless_", "2s");
    assert_eq!(code, Some(2), "exit 2: {err}");
    assert!(
        err.contains("not enough shared memory in /dev/shm (") && err.contains(" free)"),
        "the clear error: {err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(names(Path::new("/dev/shm")), Vec::<String>::new());
    assert_eq!(names(Path::new(ROOT)), Vec::<String>::new());
}

#[test]
fn a_64_kib_dev_shm_is_a_clear_error_exit_2_and_nothing_left() {
    tiny_dev_shm(
        "a_64_kib_dev_shm_is_a_clear_error_exit_2_and_nothing_left",
        "64k",
    );
}

#[test]
fn a_256_kib_dev_shm_is_a_clear_error_exit_2_and_nothing_left() {
    tiny_dev_shm(
        "a_256_kib_dev_shm_is_a_clear_error_exit_2_and_nothing_left",
        "256k",
    );
}

#[test]
fn a_dev_shm_that_fills_while_running_is_said_in_the_verdict_and_the_daemon_serves_on() {
    if !in_namespace(
        "a_dev_shm_that_fills_while_running_is_said_in_the_verdict_and_the_daemon_serves_on",
        "6m",
    ) {
        return;
    }
    let demo = concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/demo.toml");
    let daemon = Command::new(bin())
        .args(["run", demo, "--duration", "5s"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Once it runs (its stats service's segment exists), fill /dev/shm, then subscribe: the
    // new subscriber's connection finds no page.
    let end = Instant::now() + Duration::from_secs(20);
    while !names(Path::new("/dev/shm"))
        .iter()
        .any(|n| n.ends_with(".data"))
    {
        assert!(Instant::now() < end, "the daemon never started");
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(500));
    let mut filler = std::fs::File::create("/dev/shm/filler").unwrap();
    let block = vec![1u8; 64 * 1024];
    while std::io::Write::write_all(&mut filler, &block).is_ok() {}
    drop(filler);
    let (code, _) = run_within(
        &["tap", "demo/corrected", "--duration", "1s"],
        Duration::from_secs(30),
    );
    assert!(code.is_some());
    let (code, err) = finish(daemon, Duration::from_secs(60));
    assert_eq!(code, Some(0), "the daemon serves on: {err}");
    let verdict = err.lines().find(|l| l.starts_with("verdict:")).unwrap();
    assert!(verdict.contains("; shared memory FULL: "), "{verdict}");
    std::fs::remove_file("/dev/shm/filler").unwrap();
    assert_eq!(names(Path::new("/dev/shm")), Vec::<String>::new());
}

/// Whether `pid` has a handler for SIGTERM (its `SigCgt` mask in /proc).
fn catches_sigterm(pid: u32) -> bool {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("SigCgt:"))
        .and_then(|m| u64::from_str_radix(m.trim(), 16).ok())
        .is_some_and(|m| m & (1 << (libc::SIGTERM - 1)) != 0)
}

/// `driftless run PIPELINE` for 30 s under `prefix`, quiet, its stderr captured.
fn spawn_run(pipeline: &Path, prefix: &Prefix) -> std::process::Child {
    Command::new(bin())
        .arg("run")
        .arg(pipeline)
        .args(["--prefix", &prefix.0, "--duration", "30s", "-q"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("driftless runs")
}

/// SIGTERM at 0, 1 and 3 ms after start: a clean exit (0) with nothing left, every time. A
/// signal can only be handled from the process's first instruction: one that lands while the
/// kernel and the loader are still starting it (about a millisecond; longer on a loaded
/// machine) ends it by the default action before it has created anything. So the test
/// measures from the moment the daemon catches SIGTERM (its `SigCgt` in /proc), and checks
/// the earlier case apart: killed by the signal only if it did not catch it yet, and nothing
/// left either way. Needs no namespace: the daemon runs under a prefix of its own.
#[test]
fn sigterm_at_0_1_and_3_ms_after_start_exits_cleanly() {
    let demo_file = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/demo.toml"));
    for delay_ms in [0u64, 1, 3] {
        for run in 0..5 {
            let prefix = Prefix::new(&format!("sigterm{delay_ms}x{run}"));
            let mut child = spawn_run(demo_file, &prefix);
            let pid = child.id();
            let end = Instant::now() + Duration::from_secs(20);
            while !catches_sigterm(pid) {
                assert!(Instant::now() < end, "never caught SIGTERM");
                assert!(child.try_wait().unwrap().is_none(), "exited early");
            }
            let t = Instant::now();
            while t.elapsed() < Duration::from_millis(delay_ms) {}
            common::signal(&child, libc::SIGTERM);
            let (code, err) = finish(child, Duration::from_secs(30));
            assert_eq!(code, Some(0), "SIGTERM {delay_ms} ms after start: {err}");
            assert!(!err.contains("panicked"), "{err}");
            assert_eq!(prefix.leftovers(), Vec::<PathBuf>::new(), "{delay_ms} ms");
        }
    }
    // While it reads its pipeline file (here a FIFO nobody has written yet): it has caught
    // SIGTERM already, and once it has the file it says so and exits 0, having started nothing.
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipeline.toml");
    let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: mkfifo on a path we own.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let prefix = Prefix::new("sigtermload");
    let child = spawn_run(&fifo, &prefix);
    let end = Instant::now() + Duration::from_secs(20);
    while !catches_sigterm(child.id()) {
        assert!(Instant::now() < end, "never caught SIGTERM");
    }
    common::signal(&child, libc::SIGTERM);
    std::fs::write(&fifo, std::fs::read_to_string(demo_file).unwrap()).unwrap();
    let (code, err) = finish(child, Duration::from_secs(30));
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("stopped by SIGTERM before any pipeline started"),
        "{err}"
    );
    assert_eq!(prefix.leftovers(), Vec::<PathBuf>::new());

    // Before the first instruction: the default action, and nothing to leave.
    for run in 0..5 {
        let prefix = Prefix::new(&format!("sigtermexec{run}"));
        let mut child = spawn_run(demo_file, &prefix);
        let caught = catches_sigterm(child.id());
        common::signal(&child, libc::SIGTERM);
        let end = Instant::now() + Duration::from_secs(30);
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            assert!(Instant::now() < end, "no exit");
            std::thread::sleep(Duration::from_millis(5));
        };
        use std::os::unix::process::ExitStatusExt;
        match (status.code(), status.signal()) {
            (Some(0), _) => {}
            (None, Some(libc::SIGTERM)) => assert!(!caught, "caught SIGTERM, yet died of it"),
            other => panic!("SIGTERM at once: {other:?}"),
        }
        assert_eq!(prefix.leftovers(), Vec::<PathBuf>::new());
    }
}
