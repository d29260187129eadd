//! Time: the one clock every timestamp of ours is read on, and the pacing of sources that
//! follow a sensor's clock (the simulator, a replay), in real time or a factor faster, and
//! whether a sensor's stamp can be believed ([`StampCheck`]).
//!
//! [`monotonic_ns`] is `CLOCK_MONOTONIC`: the `ingest_ns` stamps on the wire, every latency the
//! daemon measures and every subscriber's "now" are on it, so they compare between processes on
//! one host. A [`PaceClock`] is when a paced source's first sample was due; the runtime shares
//! one between the pipelines of a daemon, so that their samples fall due together.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

mod stamps;
pub use stamps::{StampCheck, StampFault, MAX_STAMP_STEP_NS, RESYNC};

/// CLOCK_MONOTONIC in nanoseconds: comparable between processes on one host.
pub fn monotonic_ns() -> u64 {
    clock_ns(libc::CLOCK_MONOTONIC)
}

/// `clock` in nanoseconds; `clock` must be one Linux always has.
fn clock_ns(clock: libc::clockid_t) -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; the callers pass clocks Linux always has.
    unsafe {
        libc::clock_gettime(clock, &mut ts);
    }
    (ts.tv_sec as u64)
        .wrapping_mul(1_000_000_000)
        .wrapping_add(ts.tv_nsec as u64)
}

/// The ingest stamp of a source's sample: [`monotonic_ns`]. This thread's CPU time is read
/// just before it ([`cpu_at_ingest`]), so that a deadline miss can say how long of its
/// end-to-end time the hot thread was off a CPU. The read (about 0.3-0.5 us, a system call) is
/// outside the end-to-end window. Every sample of a source that keeps time (`every_sample`:
/// paced, or a driver's) reads it; a replay as fast as possible reads it at every
/// [`CPU_READ_EVERY`]th sample only (at each it would cost a third of the throughput), so that
/// its misses are judged on the CPU time since an earlier sample: more than ran since the
/// ingest, so the time off a CPU it leaves is a lower bound, never more than the truth.
pub fn ingest_now(every_sample: bool) -> u64 {
    CPU_AT_INGEST.with(|c| {
        let (cpu, since) = c.get();
        c.set(match cpu {
            Some(_) if !every_sample && since + 1 < CPU_READ_EVERY => (cpu, since + 1),
            _ => (Some(thread_cpu_ns()), 0),
        });
    });
    monotonic_ns()
}

/// Whether a miss is the kernel's: the output, `e2e_ns` after its ingest, would have made
/// `deadline_ns` without the `off_cpu_ns` the hot thread spent off a CPU meanwhile (None: not
/// measured, so not excused).
pub fn miss_explained(e2e_ns: u64, off_cpu_ns: Option<u64>, deadline_ns: u64) -> bool {
    off_cpu_ns.is_some_and(|off| e2e_ns.saturating_sub(off) <= deadline_ns)
}

/// How often a replay as fast as possible reads its CPU clock ([`ingest_now`]): 64 samples,
/// about 45 us of its work here.
pub const CPU_READ_EVERY: u32 = 64;

/// This thread's CPU time at its last [`ingest_now`] that read it, ns (None before one).
pub fn cpu_at_ingest() -> Option<u64> {
    CPU_AT_INGEST.with(|c| c.get().0)
}

thread_local! {
    /// The CPU time last read at an ingest, and the ingests since.
    static CPU_AT_INGEST: std::cell::Cell<(Option<u64>, u32)> =
        const { std::cell::Cell::new((None, 0)) };
}

/// CPU time this thread has run, ns (`CLOCK_THREAD_CPUTIME_ID`): against the wall clock over
/// the same span, what is left is time the thread spent off a CPU (preempted and waiting to
/// run again, stopped, or blocked; the hot path never blocks by design).
pub fn thread_cpu_ns() -> u64 {
    clock_ns(libc::CLOCK_THREAD_CPUTIME_ID)
}

/// How fast a source goes through its samples' own time (the `pace` key of a replay or the
/// simulator): when each sample falls due after the first ([`PaceClock`]), or never.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pace {
    /// At the samples' times, this many times faster than they were taken (finite, > 0): 1 is
    /// real time, 10 goes through ten seconds of a log in one.
    Times(f64),
    /// As fast as possible: no sample waits.
    Asap,
}

impl Pace {
    /// At the samples' own rate.
    pub const REALTIME: Pace = Pace::Times(1.0);

    /// When a sample `sensor_ns` of sensor time after the first falls due, after the first's
    /// due time: `sensor_ns / factor`, to the nanosecond (None as fast as possible). Never
    /// earlier for a later sample.
    pub fn due_after(self, sensor_ns: u64) -> Option<Duration> {
        match self {
            Pace::Asap => None,
            // Exact, however long the log (an f64 holds ns exactly only up to 104 days).
            Pace::Times(1.0) => Some(Duration::from_nanos(sensor_ns)),
            Pace::Times(f) => Some(Duration::from_nanos((sensor_ns as f64 / f).round() as u64)),
        }
    }

    /// How many times real time the samples fall due (None as fast as possible).
    pub fn factor(self) -> Option<f64> {
        match self {
            Pace::Times(f) => Some(f),
            Pace::Asap => None,
        }
    }
}

/// The clock of a paced source: when its first sample is due, as an instant to sleep until and
/// as [`monotonic_ns`] to measure lateness on. The pipelines of one daemon share one.
#[derive(Debug, Clone, Copy)]
pub struct PaceClock {
    start: Instant,
    start_ns: u64,
}

impl PaceClock {
    /// A clock starting now.
    pub fn now() -> Self {
        PaceClock {
            start: Instant::now(),
            start_ns: monotonic_ns(),
        }
    }

    /// The same clock started `by` later (a source that waits before its first sample).
    pub fn later(&self, by: Duration) -> PaceClock {
        PaceClock {
            start: self.start + by,
            start_ns: self.start_ns.saturating_add(by.as_nanos() as u64),
        }
    }

    /// When it started, in monotonic ns ([`monotonic_ns`]).
    pub fn start_ns(&self) -> u64 {
        self.start_ns
    }

    /// The instant `offset` after the start.
    pub fn at(&self, offset: Duration) -> Instant {
        self.start + offset
    }

    /// Sleep until `offset` after the start (noticing `stop`); returns when that was due, in
    /// monotonic ns, or None when stopped first.
    pub fn wait(&self, offset: Duration, stop: &AtomicBool) -> Option<u64> {
        sleep_until(self.at(offset), stop)
            .then(|| self.start_ns.saturating_add(offset.as_nanos() as u64))
    }
}

/// Sleep until `due` (a monotonic instant), in slices short enough to notice `stop`.
/// Returns false when stopped first.
pub fn sleep_until(due: Instant, stop: &AtomicBool) -> bool {
    const SLICE: Duration = Duration::from_millis(20);
    loop {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        let now = Instant::now();
        if now >= due {
            return true;
        }
        std::thread::sleep((due - now).min(SLICE));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn at_factor_f_a_sample_falls_due_its_sensor_time_over_f_after_the_first() {
        let s = 1_000_000_000u64;
        assert_eq!(Pace::REALTIME.due_after(s), Some(Duration::from_secs(1)));
        assert_eq!(
            Pace::Times(10.0).due_after(s),
            Some(Duration::from_millis(100))
        );
        assert_eq!(Pace::Times(0.5).due_after(s), Some(Duration::from_secs(2)));
        // 1 kHz at 3x: to the nearest ns, and the 1,000th sample 1/3 s after the first.
        assert_eq!(
            Pace::Times(3.0).due_after(1_000_000),
            Some(Duration::from_nanos(333_333))
        );
        assert_eq!(
            Pace::Times(3.0).due_after(1000 * 1_000_000),
            Some(Duration::from_nanos(333_333_333))
        );
        assert_eq!(Pace::Asap.due_after(s), None);
        // Real time stays exact past where an f64 holds every ns (2^53 ns, 104 days).
        let late = (1u64 << 53) + 1;
        assert_eq!(
            Pace::REALTIME.due_after(late),
            Some(Duration::from_nanos(late))
        );
        // A later sample is never due earlier, at any factor.
        for f in [1.0, 1.5, 7.0, 10.0, 999.9] {
            let pace = Pace::Times(f);
            let mut last = Duration::ZERO;
            for k in 0..10_000u64 {
                let due = pace.due_after(k * 1_000_003).unwrap();
                assert!(due >= last, "{f}: sample {k}");
                last = due;
            }
        }
    }

    #[test]
    fn a_replay_as_fast_as_possible_reads_its_cpu_clock_every_64th_sample() {
        // A thread of its own: the clock's state is per thread.
        std::thread::spawn(|| {
            assert_eq!(cpu_at_ingest(), None);
            ingest_now(false);
            let first = cpu_at_ingest().expect("read at the first sample");
            let spin = |ns| {
                let t = thread_cpu_ns();
                while thread_cpu_ns() < t + ns {}
            };
            for _ in 1..CPU_READ_EVERY {
                spin(10_000);
                ingest_now(false);
                assert_eq!(cpu_at_ingest(), Some(first), "kept between reads");
            }
            spin(10_000);
            ingest_now(false);
            let second = cpu_at_ingest().unwrap();
            assert!(second > first, "read again at sample {CPU_READ_EVERY}");
            // A source that keeps time reads it at every sample.
            spin(10_000);
            ingest_now(true);
            assert!(cpu_at_ingest().unwrap() > second);
        })
        .join()
        .unwrap();
    }
}
