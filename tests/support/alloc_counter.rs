//! A counting global allocator for "allocates nothing" tests. Include it with
//! `#[path = "support/alloc_counter.rs"] mod alloc_counter;` (a global allocator is per test
//! binary). Counts are kept per thread, so the test harness's other threads cannot disturb
//! them, and for the whole process, for code that runs threads of its own.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

static PROCESS: AtomicU64 = AtomicU64::new(0);

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

struct Counting;

fn count() {
    ALLOCATIONS.with(|c| c.set(c.get() + 1));
    PROCESS.fetch_add(1, Ordering::Relaxed);
}

// SAFETY: forwards to the system allocator; only counts calls on the current thread.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made on this thread while `f` runs. Checks first that the counter counts, so a
/// zero proves something.
pub fn allocations_during<T>(f: impl FnOnce() -> T) -> (usize, T) {
    let before = ALLOCATIONS.with(Cell::get);
    drop(std::hint::black_box(vec![1u8; 16]));
    let start = ALLOCATIONS.with(Cell::get);
    assert!(start > before, "the counting allocator does not count");
    let out = f();
    (ALLOCATIONS.with(Cell::get) - start, out)
}

/// Allocations made so far on this thread.
#[allow(dead_code)] // not every including test needs it
pub fn this_thread() -> u64 {
    ALLOCATIONS.with(Cell::get) as u64
}

/// Allocations made so far by every thread of the process.
#[allow(dead_code)]
pub fn process() -> u64 {
    PROCESS.load(Ordering::Relaxed)
}

/// Allocations of one iceoryx2 send (+ receive) on a bare service under `prefix`: iceoryx2 0.10's
/// `Publisher::loan_uninit` allocates a small state per loaned sample, a cost the daemon's
/// allocation tests allow per hop.
#[allow(dead_code)]
pub fn iceoryx2_allocations_per_send(prefix: &str) -> u64 {
    use driftless::transport::{Qos, Transport};
    use driftless::wire::GyroSample;
    let t = Transport::new(prefix, "cal", Qos::default()).expect("node");
    let out = t.output::<GyroSample>("cal/x", false).expect("publisher");
    let input = t.input::<GyroSample>("cal/x").expect("subscriber");
    let s = GyroSample::default();
    out.send(&s).expect("send");
    input.receive().expect("receive");
    const N: u64 = 1000;
    let (allocations, ()) = allocations_during(|| {
        for _ in 0..N {
            out.send(&s).expect("send");
            input.receive().expect("receive");
        }
    });
    let per = allocations as u64 / N;
    assert!(
        per <= 1,
        "iceoryx2 allocates {per} times per send: more than measured before"
    );
    per
}

/// The pipeline test's verdict: `long` = (allocations, samples) of a long run and `short` of a
/// short run of the same pipeline; the difference may be no more than iceoryx2's own
/// `per_send` allocations on each of `hops` hops per extra sample, plus `slack` for what
/// set-up and clean-up allocate differently from one run to the next.
#[allow(dead_code)]
pub fn assert_only_iceoryx2_allocates_per_sample(
    hops: u64,
    per_send: u64,
    short: (u64, u64),
    long: (u64, u64),
    slack: u64,
) {
    let extra_samples = long.1 - short.1;
    let extra_allocs = long.0.saturating_sub(short.0);
    eprintln!(
        "allocations: {} for {} samples, {} for {}; iceoryx2: {per_send} per send",
        short.0, short.1, long.0, long.1
    );
    let iceoryx2 = per_send * hops * extra_samples;
    assert!(
        extra_allocs <= iceoryx2 + slack,
        "{extra_allocs} more allocations for {extra_samples} more samples \
         (iceoryx2's own loans account for {iceoryx2})"
    );
}
