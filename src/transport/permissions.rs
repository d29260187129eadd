//! Who owns iceoryx2's files and processes: the diagnostics behind a permission refusal
//! ([`setup`]: iceoryx2's error as a [`TransportError`] that says whose files) and behind "who
//! holds this pipeline".

use std::fmt::Debug;

use super::config::{root, ROOT_ENV};
use super::error::TransportError;

/// iceoryx2's error setting up `what` (`name`) as a [`TransportError`]: a
/// [`TransportError::Permission`] that says whose files are in the way where permissions are
/// the cause, [`TransportError::Setup`] otherwise.
pub(super) fn setup(what: &'static str, name: &str, e: impl Debug) -> TransportError {
    let reason = format!("{e:?}");
    // iceoryx2 says only `InsufficientPermissions`, or even `InternalError`: say whose files.
    let culprit = foreign_directory();
    if culprit.is_some() || reason.contains("Permission") {
        return TransportError::Permission {
            what,
            name: name.to_string(),
            problem: access_problem(culprit, &reason),
        };
    }
    TransportError::Setup {
        what,
        name: name.to_string(),
        reason,
    }
}

/// A user's name and id, as `name (uid N)`, or `uid N` when it has no name.
pub(super) fn who(uid: u32) -> String {
    match user_name(uid) {
        Some(n) => format!("{n} (uid {uid})"),
        None => format!("uid {uid}"),
    }
}

/// `belongs to NAME (uid N), mode 0750`, of a file whose owner is `uid` and mode `mode`.
pub(super) fn owner_and_mode(uid: u32, mode: u32) -> String {
    format!("belongs to {}, mode {:04o}", who(uid), mode & 0o7777)
}

/// The first of iceoryx2's directories (root, nodes, services) that belongs to another user
/// without granting this process access, or that it cannot create: with owner and mode.
pub(super) fn foreign_directory() -> Option<String> {
    use std::os::unix::fs::MetadataExt;
    // SAFETY: geteuid cannot fail.
    let me = unsafe { libc::geteuid() };
    if me == 0 {
        return None;
    }
    let root = root();
    for dir in [root.clone(), root.join("nodes"), root.join("services")] {
        match std::fs::metadata(&dir) {
            Ok(m) if m.uid() != me && m.mode() & 0o002 == 0 => {
                return Some(format!(
                    "iceoryx2's directory {} {}",
                    dir.display(),
                    owner_and_mode(m.uid(), m.mode())
                ));
            }
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                let parent = dir.parent().unwrap_or(&dir);
                let m = std::fs::metadata(parent).ok()?;
                return (m.uid() != me && m.mode() & 0o002 == 0).then(|| {
                    format!(
                        "iceoryx2 cannot create {}: {} {}",
                        dir.display(),
                        parent.display(),
                        owner_and_mode(m.uid(), m.mode())
                    )
                });
            }
            Err(e) => return Some(format!("{}: {e}", dir.display())),
        }
    }
    None
}

/// The refusal in full: whose files (or iceoryx2's own words), who we are, the ways out.
pub(super) fn access_problem(culprit: Option<String>, reason: &str) -> String {
    // SAFETY: geteuid cannot fail.
    let me = unsafe { libc::geteuid() };
    let root = root();
    let culprit =
        culprit.unwrap_or_else(|| format!("iceoryx2 says {reason} (under {})", root.display()));
    format!(
        "{culprit}; this process runs as {}. iceoryx2's files are for one user: run the daemon \
         and every process that talks to it as the same user (docs/operations.md, \"Users \
         and permissions\"), or give your own pipelines their own directory: `root_path = \"...\"` \
         under [iceoryx2] in the pipeline file, or {ROOT_ENV}=..., or --root-path, the same for \
         the daemon and its subscribers",
        who(me)
    )
}

/// The user owning process `pid` (the owner of `/proc/PID`), by name where it has one.
pub(super) fn process_owner(pid: i32) -> Option<String> {
    use std::os::unix::fs::MetadataExt as _;
    let uid = std::fs::metadata(format!("/proc/{pid}")).ok()?.uid();
    Some(user_name(uid).unwrap_or_else(|| format!("uid {uid}")))
}

/// The name of user `uid` from the password database.
pub fn user_name(uid: u32) -> Option<String> {
    // SAFETY: a zeroed passwd is a valid out-parameter for getpwuid_r.
    let mut pwd: libc::passwd = unsafe { std::mem::zeroed() };
    let mut buf: Vec<libc::c_char> = vec![0; 16 * 1024];
    let mut found: *mut libc::passwd = std::ptr::null_mut();
    // SAFETY: every pointer is valid for the call; the strings it sets point into `buf`.
    let rc = unsafe { libc::getpwuid_r(uid, &mut pwd, buf.as_mut_ptr(), buf.len(), &mut found) };
    if rc != 0 || found.is_null() || pwd.pw_name.is_null() {
        return None;
    }
    // SAFETY: pw_name is a NUL-terminated string inside `buf`, alive here.
    let name = unsafe { std::ffi::CStr::from_ptr(pwd.pw_name) };
    Some(name.to_string_lossy().into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn user_names_come_from_the_password_database() {
        assert_eq!(user_name(0).as_deref(), Some("root"));
    }
}
