//! What the file replays (`ingest.csv`, `ingest.mcap`) share: a reader thread turns the file
//! into blocks of raw samples, four blocks ahead on a bounded channel; the hot thread takes a
//! block when the last is spent and hands the spent one back for reuse, so neither allocates per
//! sample and memory stays bounded whatever the file's length; the hot thread paces the samples
//! by their timestamps (`realtime`), a factor faster (`pace = 10.0`), or not at all (`asap`).
//! The pace changes when a sample is taken, never what it is: every pace publishes the same
//! samples, bit for bit. A block also carries the motion logged beside its rows (a CSV's yaw
//! rate column), each message handed out after the sample of its row
//! ([`Source::logged_motion`]).

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use crossbeam_channel::{bounded, Receiver, RecvTimeoutError, Sender, TryRecvError};

use crate::clock::{Pace, PaceClock};
use crate::io::InputError;
use crate::stages::contract::{Poll, Source};
use crate::stages::schema::{DefaultValue, Key, Table, Type, WordOr};
use crate::wire::{RawSample, StopSignal};

/// Samples per block the reader thread hands to the hot thread.
const BLOCK_ROWS: usize = 4096;
/// Blocks read ahead: 16k samples (16 ms at 1 kHz flat out, 16 s at 1 kHz real time).
const BLOCKS_AHEAD: usize = 4;

/// The most a `pace` factor may speed a source up: a 1 kHz log at 1 MHz, about as fast as
/// `"asap"` goes here; more is a typing error.
pub const MAX_PACE: f64 = 1000.0;

/// The type of a paced source's `pace` key: a word, or how many times real time.
pub const PACE_TYPE: Type = Type::WordOrPositive(&["realtime", "asap"], MAX_PACE);

/// The `pace` key of a replay.
pub const PACE: Key = Key {
    name: "pace",
    ty: PACE_TYPE,
    default: DefaultValue::Word("realtime"),
    doc: "at the file's rate, this many times faster (10.0: ten seconds of the log in one; 1.0 is \"realtime\"), or as fast as possible; the same samples at every pace",
};

/// A `pace` key of [`PACE_TYPE`] (a replay's or the simulator's), else its default.
pub fn read_pace(t: &mut Table<'_, '_>, key: &Key) -> Result<Pace, InputError> {
    Ok(match t.word_or_positive_or_default(key)? {
        WordOr::Word("asap") => Pace::Asap,
        WordOr::Number(f) => Pace::Times(f),
        _ => Pace::REALTIME,
    })
}

/// The `loop` key of a replay.
pub const LOOP: Key = Key {
    name: "loop",
    ty: Type::Bool,
    default: DefaultValue::Bool(false),
    doc: "replay again from the start at the end of the file",
};

/// The `start_delay_s` key of a replay.
pub const START_DELAY_S: Key = Key {
    name: "start_delay_s",
    ty: Type::Positive(3600.0),
    default: DefaultValue::Absent("none: the first sample at once"),
    doc: "seconds to wait after the pipeline is up before the first sample: time for a recorder or a navigator to subscribe and miss nothing",
};

/// How a file is replayed: the keys every replay stage takes ([`PACE`], [`LOOP`],
/// [`START_DELAY_S`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Replay {
    /// Pacing.
    pub pace: Pace,
    /// Replay again from the start at the end of the file.
    pub looped: bool,
    /// Held before the first sample.
    pub start_delay: Duration,
}

impl Replay {
    /// The replay keys of a stage table, checked.
    pub fn parse(t: &mut Table<'_, '_>) -> Result<Replay, InputError> {
        let pace = read_pace(t, &PACE)?;
        let looped = t.bool_or_default(&LOOP)?;
        let start_delay = t
            .float(&START_DELAY_S)?
            .map_or(Duration::ZERO, Duration::from_secs_f64);
        Ok(Replay {
            pace,
            looped,
            start_delay,
        })
    }
}

/// A block of samples and the motion logged beside them: each message with the index of the
/// sample of its row.
#[derive(Default)]
struct Block {
    samples: Vec<RawSample>,
    motion: Vec<(usize, StopSignal)>,
}

impl Block {
    fn with_capacity() -> Block {
        Block {
            samples: Vec::with_capacity(BLOCK_ROWS),
            motion: Vec::new(),
        }
    }
}

/// The reader thread's end of a replay: samples go in, full blocks go to the hot thread.
pub struct BlockSink {
    tx: Sender<Block>,
    spare: Receiver<Block>,
    block: Block,
}

impl BlockSink {
    /// Queue one sample; false when the replay is gone (stop reading).
    pub fn push(&mut self, sample: RawSample) -> bool {
        self.block.samples.push(sample);
        self.block.samples.len() < BLOCK_ROWS || self.send()
    }

    /// Queue a motion message logged on the row of the next sample pushed: the hot thread hands
    /// it out once it has taken that sample.
    pub fn push_motion(&mut self, signal: StopSignal) {
        let row = self.block.samples.len();
        self.block.motion.push((row, signal));
    }

    /// Hand the filled block to the hot thread and take an empty one; false when the replay is
    /// gone.
    fn send(&mut self) -> bool {
        if self.block.samples.is_empty() {
            return true;
        }
        let mut next = self
            .spare
            .try_recv()
            .unwrap_or_else(|_| Block::with_capacity());
        next.samples.clear();
        next.motion.clear();
        self.tx
            .send(std::mem::replace(&mut self.block, next))
            .is_ok()
    }
}

impl Drop for BlockSink {
    /// The last, partial block reaches the hot thread when the reader ends.
    fn drop(&mut self) {
        let _ = self.send();
    }
}

/// The hot thread's end of a replay: a [`Source`] over the reader thread's blocks.
pub struct BlockReplay {
    blocks: Receiver<Block>,
    spent: Sender<Block>,
    block: Block,
    next: usize,
    /// The block's next motion message to hand out.
    next_motion: usize,
    pace: Pace,
    start: Option<(PaceClock, u64)>,
    /// The clock to start from at the first sample (a shared hot thread's), or none: now.
    shared: Option<PaceClock>,
    /// `start_delay_s`: the whole schedule starts this much later.
    start_delay: Duration,
    /// The delay still to wait, and from the first poll, when it ends.
    delay: Duration,
    not_before: Option<std::time::Instant>,
}

impl BlockReplay {
    /// Start the reader thread `name` running `read` (it pushes samples into its sink and
    /// returns at the end of the file or when a push returns false), paced and delayed as
    /// `replay` says.
    pub fn spawn(
        name: &str,
        replay: Replay,
        read: impl FnOnce(&mut BlockSink) + Send + 'static,
    ) -> Result<Self, String> {
        let (tx, blocks) = bounded(BLOCKS_AHEAD);
        // Room for every block there is: handing one back never blocks the hot thread.
        let (spent, spare) = bounded(BLOCKS_AHEAD + 2);
        std::thread::Builder::new()
            .name(name.into())
            .spawn(move || {
                let mut sink = BlockSink {
                    tx,
                    spare,
                    block: Block::with_capacity(),
                };
                read(&mut sink);
            })
            .map_err(|e| format!("cannot start the {name} reader thread: {e}"))?;
        Ok(BlockReplay {
            blocks,
            spent,
            block: Block::default(),
            next: 0,
            next_motion: 0,
            pace: replay.pace,
            start: None,
            shared: None,
            start_delay: replay.start_delay,
            delay: replay.start_delay,
            not_before: None,
        })
    }
}

impl Source for BlockReplay {
    fn poll(&mut self, stop: &AtomicBool) -> Poll {
        if !self.delay.is_zero() {
            let now = std::time::Instant::now();
            let end = *self.not_before.get_or_insert(now + self.delay);
            if now < end {
                // In short sleeps: a stop is seen within 20 ms.
                std::thread::sleep((end - now).min(Duration::from_millis(20)));
                return Poll::Idle;
            }
            self.delay = Duration::ZERO;
        }
        if self.next == self.block.samples.len() {
            let spent = std::mem::take(&mut self.block);
            if spent.samples.capacity() > 0 {
                let _ = self.spent.try_send(spent);
            }
            (self.next, self.next_motion) = (0, 0);
            // Normally a block is waiting; flat out the reader may be behind for a moment.
            self.block = match self.blocks.try_recv() {
                Ok(b) => b,
                Err(TryRecvError::Disconnected) => return Poll::End,
                Err(TryRecvError::Empty) => {
                    match self.blocks.recv_timeout(Duration::from_millis(20)) {
                        Ok(b) => b,
                        Err(RecvTimeoutError::Timeout) => return Poll::Idle,
                        Err(RecvTimeoutError::Disconnected) => return Poll::End,
                    }
                }
            };
            if self.block.samples.is_empty() {
                return Poll::Idle;
            }
        }
        let sample = self.block.samples[self.next];
        let first_t = self.start.map_or(sample.t_ns, |(_, t)| t);
        let due_ns = match self.pace.due_after(sample.t_ns.saturating_sub(first_t)) {
            None => None,
            Some(offset) => {
                // A shared clock started with the daemon: the delay (wall time at any pace)
                // shifts the whole schedule, so the samples due while it lasted are not late.
                let delay = self.start_delay;
                let (clock, _) = *self.start.get_or_insert_with(|| {
                    let clock = self.shared.map_or_else(PaceClock::now, |c| c.later(delay));
                    (clock, sample.t_ns)
                });
                match clock.wait(offset, stop) {
                    Some(due) => Some(due),
                    None => return Poll::Idle,
                }
            }
        };
        self.next += 1;
        let ingest_ns = crate::clock::ingest_now(due_ns.is_some());
        Poll::Sample(
            sample,
            ingest_ns,
            due_ns.map(|d| ingest_ns.saturating_sub(d)),
        )
    }

    fn next_due(&self) -> Option<std::time::Instant> {
        // Unknown at a block's end: the next block may not have come yet.
        let (clock, first_t) = self.start?;
        let t_ns = self.block.samples.get(self.next)?.t_ns;
        Some(clock.at(self.pace.due_after(t_ns.saturating_sub(first_t))?))
    }

    fn share_clock(&mut self, clock: PaceClock) {
        match &mut self.start {
            Some((start, _)) => *start = clock,
            None => self.shared = Some(clock),
        }
    }

    fn logged_motion(&mut self) -> Option<StopSignal> {
        // Its row's sample was taken: the poll that took it advanced `next` past it.
        let &(row, signal) = self.block.motion.get(self.next_motion)?;
        (row < self.next).then(|| {
            self.next_motion += 1;
            signal
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A replay of `n` samples 1 ms apart at `pace`.
    fn replay(n: u64, pace: Pace) -> BlockReplay {
        let replay = Replay {
            pace,
            looped: false,
            start_delay: Duration::ZERO,
        };
        BlockReplay::spawn("replay-test", replay, move |sink| {
            for k in 0..n {
                let s = RawSample {
                    t_ns: 5_000_000_000 + k * 1_000_000,
                    seq: k,
                    rate: [k as f64; 3],
                    ..RawSample::default()
                };
                if !sink.push(s) {
                    return;
                }
            }
        })
        .unwrap()
    }

    /// Every sample of `r`, with its ingest time and lateness.
    fn drain(r: &mut BlockReplay) -> Vec<(RawSample, u64, Option<u64>)> {
        let stop = AtomicBool::new(false);
        let mut got = Vec::new();
        loop {
            match r.poll(&stop) {
                Poll::Sample(s, ingest, late) => got.push((s, ingest, late)),
                Poll::Idle => {}
                Poll::End => return got,
            }
        }
    }

    #[test]
    fn at_pace_10_a_replay_takes_each_sample_a_tenth_of_its_interval_after_the_first() {
        let stop = AtomicBool::new(false);
        let mut r = replay(40, Pace::Times(10.0));
        let Poll::Sample(first, ..) = r.poll(&stop) else {
            panic!("the first sample at once")
        };
        assert_eq!(first.seq, 0);
        // As the hot thread does after its first round: the schedule restarts from a shared
        // clock, the first sample's time kept.
        let clock = PaceClock::now();
        r.share_clock(clock);
        assert_eq!(
            r.next_due(),
            Some(clock.at(Duration::from_micros(100))),
            "1 ms of the log later, at 10x"
        );
        let rest = drain(&mut r);
        assert_eq!(rest.len(), 39);
        let start_ns = rest[0].1 - rest[0].2.unwrap();
        for (s, ingest, late) in &rest {
            let due = start_ns + s.seq * 100_000 - 100_000;
            // Its lateness measured from its due time (and never taken before it: the lateness
            // saturates at 0, which would not add up).
            assert_eq!(ingest - late.expect("paced"), due, "{}", s.seq);
            assert_eq!(s.rate, [s.seq as f64; 3], "the sample as read");
        }
        // As fast as possible nothing is due, nothing late.
        let mut r = replay(40, Pace::Asap);
        assert!(drain(&mut r).iter().all(|(_, _, late)| late.is_none()));
        assert_eq!(r.next_due(), None);
    }

    #[test]
    fn logged_motion_follows_its_rows_sample_across_blocks() {
        let replay = Replay {
            pace: Pace::Asap,
            looped: false,
            start_delay: Duration::ZERO,
        };
        // Three blocks and a part; a message before every third sample, two on the last row
        // of the first block.
        let n = 3 * BLOCK_ROWS as u64 + 7;
        let mut r = BlockReplay::spawn("replay-test", replay, move |sink| {
            for k in 0..n {
                let extra = u64::from(k == BLOCK_ROWS as u64 - 1);
                for m in 0..=extra {
                    if k % 3 == 0 || extra == 1 {
                        sink.push_motion(StopSignal::new(k, m as f64, 0));
                    }
                }
                if !sink.push(RawSample {
                    t_ns: k,
                    seq: k,
                    ..RawSample::default()
                }) {
                    return;
                }
            }
        })
        .unwrap();
        let stop = AtomicBool::new(false);
        let (mut taken, mut handed) = (Vec::new(), Vec::new());
        assert_eq!(r.logged_motion(), None, "nothing before the first sample");
        loop {
            match r.poll(&stop) {
                Poll::Sample(s, ..) => {
                    taken.push(s.seq);
                    while let Some(m) = r.logged_motion() {
                        handed.push((s.seq, m.t_ns, m.speed_m_s));
                    }
                }
                Poll::Idle => {}
                Poll::End => break,
            }
        }
        assert_eq!(taken, (0..n).collect::<Vec<_>>());
        let mut want = Vec::new();
        for k in 0..n {
            if k % 3 == 0 || k == BLOCK_ROWS as u64 - 1 {
                want.push((k, k, 0.0));
            }
            if k == BLOCK_ROWS as u64 - 1 {
                want.push((k, k, 1.0));
            }
        }
        assert_eq!(handed, want);
    }
}
