//! `ingest.csv`: replay a CSV file (loaded at validation) at its own rate or as fast as possible,
//! optionally looping. Sequence numbers count from 0 across loops; timestamps keep increasing.

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use crate::pipeline::config::{CsvParams, Pace};
use crate::pipeline::stage::{Poll, Source};
use crate::transport::{monotonic_ns, RawSample};

/// A CSV replay.
pub struct CsvReplay {
    params: CsvParams,
    next: usize,
    seq: u64,
    loop_offset_ns: u64,
    period_ns: u64,
    start: Option<(Instant, u64)>,
}

impl CsvReplay {
    /// A replay of validated parameters at `rate_hz` (used for the loop seam).
    pub fn new(params: CsvParams, rate_hz: f64) -> Self {
        CsvReplay {
            params,
            next: 0,
            seq: 0,
            loop_offset_ns: 0,
            period_ns: (1e9 / rate_hz).round() as u64,
            start: None,
        }
    }
}

impl Source for CsvReplay {
    fn poll(&mut self, stop: &AtomicBool) -> Poll {
        if self.next == self.params.rates.len() {
            if !self.params.looped {
                return Poll::End;
            }
            let first = self.params.t_ns[0];
            let last = self.params.t_ns[self.params.t_ns.len() - 1];
            self.loop_offset_ns += last.saturating_sub(first) + self.period_ns;
            self.next = 0;
        }
        let t_ns = self.params.t_ns[self.next] + self.loop_offset_ns;
        if self.params.pace == Pace::Realtime {
            let (t0, first_t) = *self.start.get_or_insert((Instant::now(), t_ns));
            let due = t0 + Duration::from_nanos(t_ns.saturating_sub(first_t));
            if !crate::stages::sleep_until(due, stop) {
                return Poll::Idle;
            }
        }
        let sample = RawSample {
            t_ns,
            seq: self.seq,
            rate: self.params.rates[self.next],
            flags: 0,
            reserved: 0,
        };
        self.next += 1;
        self.seq += 1;
        Poll::Sample(sample, monotonic_ns())
    }
}
