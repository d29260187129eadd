//! Large zeroed `f64` buffers that ask Linux for transparent huge pages.
//!
//! A fresh buffer costs a page fault per 4 KiB page at its first write, and on the 2-vCPU VMs we
//! measure on a fault costs about 2 us: a one-shot denoise of 10^6 samples spent a third of its
//! time in the kernel faulting and zeroing pages. With transparent huge pages in `madvise` mode
//! (the default on many distributions), `MADV_HUGEPAGE` on a buffer before its first write turns
//! 512 faults into one. numpy does the same for its large arrays, which is why the
//! peers we compare with do not pay this. No crate offers it for a plain `Vec`, hence these few
//! lines. Elsewhere (or with THP off) the advice is a no-op: the buffer is the same, only slower.
//!
//! [`zeroed`] gives a `Vec` (for results handed to the caller): the pages of its unaligned head and
//! tail still fault one by one. [`Scratch`] maps whole huge pages itself, for work buffers, and
//! keeps them when dropped (up to [`POOL_BYTES`]) for the next work buffer, as `malloc` keeps
//! freed memory: a second denoise of a long signal neither faults nor has the kernel zero its
//! pages again (those two were a fifth of a one-shot denoise of 10^6 samples, `perf`).

use std::ops::{Deref, DerefMut};
use std::sync::Mutex;

/// The size of a transparent huge page on x86_64 and most aarch64 kernels.
const HUGE_PAGE: usize = 2 << 20;

/// Buffers smaller than one huge page are left alone (numpy waits for 4 MiB; our level-1
/// scratch of a 10^6-sample transform is just under that).
const MIN_BYTES: usize = 2 << 20;

/// A zeroed vector of `n` values, advised to use huge pages when it is large.
///
/// `vec![0.0; n]` comes from `calloc`, which hands out untouched pages for a large fresh
/// allocation, so the advice lands before the first write.
pub fn zeroed(n: usize) -> Vec<f64> {
    let v = vec![0.0; n];
    advise_huge_pages(&v);
    v
}

/// Most bytes of dropped [`Scratch`] mappings kept for reuse (a 10^6-sample denoise needs about
/// 20 MiB of work buffers); a mapping that would exceed it goes back to the kernel.
pub const POOL_BYTES: usize = 256 << 20;

/// Dropped mappings, for the next [`Scratch`] that fits in one.
static POOL: Mutex<Pool> = Mutex::new(Pool(Vec::new()));

/// Mappings kept for reuse, at most [`POOL_BYTES`] in all.
struct Pool(Vec<memmap2::MmapMut>);

impl Pool {
    /// The smallest kept mapping of at least `len` bytes, if any.
    fn take(&mut self, len: usize) -> Option<memmap2::MmapMut> {
        let (i, _) = (self.0.iter().enumerate())
            .filter(|(_, m)| m.len() >= len)
            .min_by_key(|(_, m)| m.len())?;
        Some(self.0.swap_remove(i))
    }

    /// Keep `map` if it fits under [`POOL_BYTES`] (otherwise it is unmapped).
    fn put(&mut self, map: memmap2::MmapMut) {
        if self.0.iter().map(|m| m.len()).sum::<usize>() + map.len() <= POOL_BYTES {
            self.0.push(map);
        }
    }
}

fn pool() -> std::sync::MutexGuard<'static, Pool> {
    POOL.lock().unwrap_or_else(|e| e.into_inner())
}

/// A `[f64]` work buffer: an anonymous mapping of whole huge pages when it is large (no fault
/// per 4 KiB page, reused from the pool after the first call), a `Vec` otherwise.
pub struct Scratch {
    repr: Repr,
}

enum Repr {
    Heap(Vec<f64>),
    Mapped(memmap2::MmapMut, usize),
}

impl Scratch {
    /// `n` zeros.
    pub fn zeroed(n: usize) -> Scratch {
        let mut s = Scratch::for_overwrite(n);
        if matches!(s.repr, Repr::Mapped(..)) {
            s.fill(0.0);
        }
        s
    }

    /// `n` values for a caller that writes each before reading it: zeros, or what an earlier
    /// buffer left (always valid `f64`s, never uninitialised memory).
    pub fn for_overwrite(n: usize) -> Scratch {
        let bytes = n * std::mem::size_of::<f64>();
        if bytes >= MIN_BYTES {
            let len = bytes.next_multiple_of(HUGE_PAGE);
            if let Some(map) = pool().take(len) {
                return Scratch {
                    repr: Repr::Mapped(map, n),
                };
            }
            // A length in whole huge pages also makes Linux place the mapping on a huge-page
            // boundary; if mapping fails, the heap serves as well, only slower.
            if let Ok(map) = memmap2::MmapOptions::new().len(len).map_anon() {
                #[cfg(target_os = "linux")]
                let _ = map.advise(memmap2::Advice::HugePage);
                return Scratch {
                    repr: Repr::Mapped(map, n),
                };
            }
        }
        Scratch {
            repr: Repr::Heap(vec![0.0; n]),
        }
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if let Repr::Mapped(map, _) = std::mem::replace(&mut self.repr, Repr::Heap(Vec::new())) {
            pool().put(map);
        }
    }
}

impl Deref for Scratch {
    type Target = [f64];
    fn deref(&self) -> &[f64] {
        match &self.repr {
            Repr::Heap(v) => v,
            // SAFETY: the mapping is page-aligned, holds at least n f64s, starts zeroed (a valid
            // f64) and lives as long as `self`.
            Repr::Mapped(map, n) => unsafe { std::slice::from_raw_parts(map.as_ptr().cast(), *n) },
        }
    }
}

impl DerefMut for Scratch {
    fn deref_mut(&mut self) -> &mut [f64] {
        match &mut self.repr {
            Repr::Heap(v) => v,
            // SAFETY: as in `deref`, and `&mut self` makes the borrow unique.
            Repr::Mapped(map, n) => unsafe {
                std::slice::from_raw_parts_mut(map.as_mut_ptr().cast(), *n)
            },
        }
    }
}

impl Clone for Scratch {
    fn clone(&self) -> Scratch {
        let mut copy = Scratch::for_overwrite(self.len());
        copy.copy_from_slice(self);
        copy
    }
}

impl std::fmt::Debug for Scratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Scratch({} values)", self.len())
    }
}

#[cfg(target_os = "linux")]
fn advise_huge_pages(v: &[f64]) {
    let bytes = std::mem::size_of_val(v);
    if bytes < MIN_BYTES {
        return;
    }
    const PAGE: usize = 4096;
    let start = (v.as_ptr() as usize).next_multiple_of(PAGE);
    let end = (v.as_ptr() as usize + bytes) / PAGE * PAGE;
    if end > start {
        // SAFETY: [start, end) lies inside `v`'s allocation; MADV_HUGEPAGE changes no content,
        // only how the kernel backs the range. A failure (THP off) leaves the buffer as it was.
        unsafe { libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE) };
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge_pages(_: &[f64]) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pool_hands_out_the_smallest_fit_and_keeps_at_most_its_cap() {
        let map = |len| {
            memmap2::MmapOptions::new()
                .len(len)
                .map_anon()
                .expect("mapped")
        };
        let mut pool = Pool(Vec::new());
        pool.put(map(3 * HUGE_PAGE));
        pool.put(map(HUGE_PAGE));
        assert!(pool.take(4 * HUGE_PAGE).is_none());
        assert_eq!(pool.take(HUGE_PAGE).map(|m| m.len()), Some(HUGE_PAGE));
        assert_eq!(pool.take(HUGE_PAGE).map(|m| m.len()), Some(3 * HUGE_PAGE));
        assert!(pool.take(HUGE_PAGE).is_none());
        pool.put(map(POOL_BYTES - HUGE_PAGE));
        pool.put(map(2 * HUGE_PAGE));
        assert_eq!(pool.0.len(), 1, "over the cap: unmapped");
    }

    #[test]
    fn a_reused_mapping_comes_back_zeroed_from_zeroed() {
        let n = 5 * MIN_BYTES / 8 + 3;
        let mut a = Scratch::for_overwrite(n);
        a.fill(f64::NAN);
        drop(a);
        // Whether this takes that mapping or another (tests run side by side), it must be zeros.
        assert!(Scratch::zeroed(n).iter().all(|x| x.to_bits() == 0));
    }

    #[test]
    fn zeroed_is_zero_at_every_size() {
        for n in [0, 1, 4095, (MIN_BYTES / 8) + 3, 3 << 20] {
            let v = zeroed(n);
            assert_eq!(v.len(), n);
            assert!(v.iter().all(|x| x.to_bits() == 0));
            let mut s = Scratch::zeroed(n);
            assert_eq!(s.len(), n);
            assert!(s.iter().all(|x| x.to_bits() == 0));
            if n > 0 {
                s[n - 1] = 1.5;
                let c = s.clone();
                assert_eq!(c[n - 1], 1.5);
                assert_eq!(c.len(), n);
            }
        }
    }
}
