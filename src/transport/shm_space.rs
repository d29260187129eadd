//! Room in `/dev/shm`: each segment this process creates is reserved whole, so that a full or
//! tiny tmpfs is a clear error at start ([`TransportError::SharedMemoryFull`]) and never a
//! SIGBUS later; and a guard for the page a full tmpfs cannot back after all.
//!
//! A tmpfs gives a page only when it is first written. iceoryx2 0.10 sizes a segment with
//! `ftruncate` and writes into it at once, so on a full `/dev/shm` the process dies of SIGBUS
//! inside iceoryx2, with no message and its files left behind. It offers no reservation, so:
//! - after set-up, every new segment of ours is reserved with `fallocate` (on tmpfs it takes
//!   the pages, or fails with ENOSPC and takes none). The running daemon does the same each
//!   report period for segments created since (a new subscriber's connection).
//! - a SIGBUS on a write to an iceoryx2 segment in `/dev/shm` (found in `/proc/self/maps` from
//!   the handler, with `open`/`read` only) maps a private zero page over the one that could not
//!   be backed and counts it: the write lands in this process only, which the set-up check and
//!   the verdict report. Any other SIGBUS keeps its default action.

use std::collections::HashSet;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::Mutex;

use rustix::fs::{FallocateFlags, OFlags};

use super::cleanup::{own_segments, SHM_DIR};
use super::error::TransportError;
use super::names::is_segment;

/// Writes to a segment that `/dev/shm` could not back (each redirected to a private page).
static FAULTS: AtomicU64 = AtomicU64::new(0);

/// Bytes of segments that could not be reserved after set-up (so far).
static UNRESERVED: AtomicU64 = AtomicU64::new(0);

static PAGE_SIZE: AtomicUsize = AtomicUsize::new(4096);

/// Per prefix: the segments this process has seen (those other processes had before its first
/// node, and those it reserved) and the space free at that first look.
static KNOWN: Mutex<Vec<(String, Known)>> = Mutex::new(Vec::new());

struct Known {
    names: HashSet<Vec<u8>>,
    free: u64,
}

/// What went wrong with shared memory in this process so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ShmTrouble {
    /// Writes to a segment that `/dev/shm` could not back: each reached this process only.
    pub unbacked_writes: u64,
    /// Bytes of segments created while running that could not be reserved.
    pub unreserved_bytes: u64,
}

/// What went wrong with shared memory in this process so far (all zero on a healthy machine).
pub fn shared_memory_trouble() -> ShmTrouble {
    ShmTrouble {
        unbacked_writes: FAULTS.load(Ordering::Relaxed),
        unreserved_bytes: UNRESERVED.load(Ordering::Relaxed),
    }
}

/// Remember what `prefix` has in `/dev/shm` before this process's first node of it, so that
/// [`reserve_new`] reserves only what comes after. Later calls for the same prefix do nothing.
pub(super) fn note_existing(prefix: &str) {
    let mut known = KNOWN.lock().unwrap_or_else(|e| e.into_inner());
    if known.iter().any(|(p, _)| p == prefix) {
        return;
    }
    let names = own_segments(prefix)
        .map(|(_, found)| found.into_iter().map(|s| s.name).collect())
        .unwrap_or_default();
    let free = rustix::fs::statvfs(SHM_DIR)
        .map(|v| v.f_bavail.saturating_mul(v.f_frsize))
        .unwrap_or(0);
    known.push((prefix.to_string(), Known { names, free }));
}

/// Reserve every segment of `prefix` created since [`note_existing`]: all its bytes, now.
/// Fails if one cannot be reserved or a write could not be backed since start (the segments
/// stay as they are: dropping the ports and the node removes them).
pub(super) fn reserve_new(prefix: &str) -> Result<(), TransportError> {
    let Some((free, tried)) = reserve_unseen(prefix, false) else {
        return Ok(());
    };
    // A fault at any time since start means a page went private: the segments are not whole.
    if tried.iter().any(|&(_, reserved)| !reserved) || FAULTS.load(Ordering::Relaxed) > 0 {
        return Err(TransportError::SharedMemoryFull {
            dir: SHM_DIR,
            needed: tried.iter().map(|&(size, _)| size).sum(),
            free,
        });
    }
    Ok(())
}

/// Like [`reserve_new`] for a running daemon: what cannot be reserved is counted in
/// [`shared_memory_trouble`] (once per segment), and the daemon goes on.
pub(super) fn reserve_new_or_count(prefix: &str) {
    if let Some((_, tried)) = reserve_unseen(prefix, true) {
        let short: u64 = tried.iter().filter(|t| !t.1).map(|t| t.0).sum();
        UNRESERVED.fetch_add(short, Ordering::Relaxed);
    }
}

/// Reserve each sized segment of `prefix` not seen yet, and remember it once reserved (or
/// tried, with `remember_failed`). The space free at the first look, and (size, reserved) for
/// each segment tried.
fn reserve_unseen(prefix: &str, remember_failed: bool) -> Option<(u64, Vec<(u64, bool)>)> {
    let mut known = KNOWN.lock().unwrap_or_else(|e| e.into_inner());
    let (_, k) = known.iter_mut().find(|(p, _)| p == prefix)?;
    let (shm, found) = own_segments(prefix)?;
    let mut tried = Vec::new();
    for s in found {
        let size = u64::try_from(s.stat.st_size).unwrap_or(0);
        // Not sized yet: its creator is at it, and the next look sees it.
        if size == 0 || k.names.contains(&s.name) {
            continue;
        }
        let reserved = shm
            .open_own_file(&s.name, OFlags::RDWR)
            .is_some_and(|(fd, _)| {
                rustix::fs::fallocate(&fd, FallocateFlags::empty(), 0, size).is_ok()
            });
        if reserved || remember_failed {
            k.names.insert(s.name);
        }
        tried.push((size, reserved));
    }
    Some((k.free, tried))
}

/// The SIGBUS action in force before the guard (Rust's own stack-overflow handler, usually):
/// a fault that is not ours goes back to it.
/// (A leaked `libc::sigaction`, so the handler reads it without a lock; 0 before the guard.)
static PREVIOUS: AtomicUsize = AtomicUsize::new(0);

/// Install the SIGBUS guard for this process (idempotent; [`super::Transport::new`] calls
/// it). A SIGBUS that is not a write to one of our segments goes to the handler that was there
/// before, or to the default action.
pub fn install_sigbus_guard() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // SAFETY: sysconf, and sigaction with a handler that only makes async-signal-safe calls.
        unsafe {
            if let Ok(page) = usize::try_from(libc::sysconf(libc::_SC_PAGESIZE)) {
                PAGE_SIZE.store(page, Ordering::Relaxed);
            }
            let mut act: libc::sigaction = std::mem::zeroed();
            act.sa_sigaction = on_sigbus as *const () as usize;
            act.sa_flags = libc::SA_SIGINFO;
            libc::sigemptyset(&mut act.sa_mask);
            let mut old: libc::sigaction = std::mem::zeroed();
            if libc::sigaction(libc::SIGBUS, &act, &mut old) == 0 {
                let kept: &'static libc::sigaction = Box::leak(Box::new(old));
                PREVIOUS.store(kept as *const _ as usize, Ordering::Release);
            }
        }
    });
}

extern "C" fn on_sigbus(_sig: libc::c_int, info: *mut libc::siginfo_t, _ctx: *mut libc::c_void) {
    // SAFETY: the kernel hands a valid siginfo to an SA_SIGINFO handler; every call below is
    // async-signal-safe (open, read, close, mmap, sigaction, raise).
    unsafe {
        let (code, addr) = ((*info).si_code, (*info).si_addr() as usize);
        if code == libc::BUS_ADRERR && in_iceoryx2_segment(addr) {
            let page = PAGE_SIZE.load(Ordering::Relaxed);
            let start = addr & !(page - 1);
            let mapped = libc::mmap(
                start as *mut libc::c_void,
                page,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_FIXED,
                -1,
                0,
            );
            if mapped != libc::MAP_FAILED {
                FAULTS.fetch_add(1, Ordering::Relaxed);
                return;
            }
        }
        // Not ours to mend: back to the action that was there before the guard. A fault runs
        // the access again, now under that action; a sent signal is raised again for it.
        let previous = PREVIOUS.load(Ordering::Acquire) as *const libc::sigaction;
        let mut dfl: libc::sigaction = std::mem::zeroed();
        dfl.sa_sigaction = libc::SIG_DFL;
        let restore = if previous.is_null() { &dfl } else { &*previous };
        libc::sigaction(libc::SIGBUS, restore, std::ptr::null_mut());
        if code <= 0 {
            libc::raise(libc::SIGBUS);
        }
    }
}

/// Does `addr` lie in a mapping of an iceoryx2 segment in `/dev/shm`? Reads
/// `/proc/self/maps` with a fixed buffer: no allocation, signal-safe.
unsafe fn in_iceoryx2_segment(addr: usize) -> bool {
    // SAFETY: open/read/close on a buffer we own.
    let fd = unsafe {
        libc::open(
            c"/proc/self/maps".as_ptr(),
            libc::O_RDONLY | libc::O_CLOEXEC,
        )
    };
    if fd < 0 {
        return false;
    }
    let mut buf = [0u8; 4096];
    let mut line = [0u8; 512];
    let (mut len, mut overlong) = (0usize, false);
    let mut answer = false;
    'read: loop {
        // SAFETY: reading into our own buffer.
        let n = unsafe { libc::read(fd, buf.as_mut_ptr().cast(), buf.len()) };
        if n <= 0 {
            break;
        }
        for &b in &buf[..n as usize] {
            if b != b'\n' {
                if len < line.len() {
                    line[len] = b;
                    len += 1;
                } else {
                    overlong = true;
                }
                continue;
            }
            if !overlong {
                if let Some(ours) = maps_line(&line[..len], addr) {
                    answer = ours;
                    break 'read;
                }
            }
            (len, overlong) = (0, false);
        }
    }
    // SAFETY: our descriptor.
    unsafe { libc::close(fd) };
    answer
}

/// One line of `/proc/self/maps`: `None` if its range does not hold `addr`, else whether it
/// maps an iceoryx2 segment in `/dev/shm`.
fn maps_line(line: &[u8], addr: usize) -> Option<bool> {
    let mut fields = line.split(|b| *b == b' ').filter(|f| !f.is_empty());
    let range = fields.next()?;
    let dash = range.iter().position(|b| *b == b'-')?;
    let (start, end) = (hex(&range[..dash])?, hex(&range[dash + 1..])?);
    if !(start..end).contains(&addr) {
        return None;
    }
    // perms, offset, device, inode, then the path (which may hold spaces).
    for _ in 0..4 {
        fields.next()?;
    }
    let at = line.windows(9).position(|w| w == b"/dev/shm/");
    let name = at.map(|i| &line[i + 9..]).unwrap_or_default();
    let name = name.strip_suffix(b" (deleted)").unwrap_or(name);
    Some(at.is_some() && is_segment(name))
}

fn hex(s: &[u8]) -> Option<usize> {
    if s.is_empty() || s.len() > 16 {
        return None;
    }
    s.iter().try_fold(0usize, |v, &b| {
        let d = (b as char).to_digit(16)? as usize;
        Some(v << 4 | d)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SEG: &str =
        "driftless_0354a209029e7d094a819e2d4030ea331e6caaf0_158456425824514663799274340511.data";

    #[test]
    fn a_maps_line_tells_whether_it_holds_the_address_and_maps_a_segment() {
        let line = format!("7f00a000-7f00c000 rw-s 00000000 00:1a 42   /dev/shm/{SEG}");
        assert_eq!(maps_line(line.as_bytes(), 0x7f00a000), Some(true));
        assert_eq!(maps_line(line.as_bytes(), 0x7f00bfff), Some(true));
        assert_eq!(maps_line(line.as_bytes(), 0x7f00c000), None);
        let deleted = format!("{line} (deleted)");
        assert_eq!(maps_line(deleted.as_bytes(), 0x7f00a000), Some(true));
        for other in [
            "7f00a000-7f00c000 rw-s 00000000 00:1a 42   /dev/shm/pulse-shm-12345",
            "7f00a000-7f00c000 r--p 00000000 08:01 42   /home/me/log.csv",
            "7f00a000-7f00c000 rw-p 00000000 00:00 0 ",
        ] {
            assert_eq!(
                maps_line(other.as_bytes(), 0x7f00b000),
                Some(false),
                "{other}"
            );
        }
        assert_eq!(maps_line(b"garbage", 1), None);
    }

    #[test]
    fn the_guard_finds_a_real_mapping_of_this_process() {
        let v = vec![0u8; 4096];
        // SAFETY: reading /proc/self/maps only.
        assert!(!unsafe { in_iceoryx2_segment(v.as_ptr() as usize) });
    }
}
