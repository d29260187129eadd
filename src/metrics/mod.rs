//! Latency histograms (hdrhistogram) per stage and end to end, deadline accounting, the
//! periodic one-line summary, the stats snapshot, the final table and the JSON report.
//!
//! The hot loop never touches a histogram: it collects one small [`Record`] per sample into a
//! [`Batch`] and sends full batches (or every 50 ms) on a bounded crossbeam channel with
//! `try_send` (never blocking; records of a batch that does not fit are counted in
//! `metric_drops`); it keeps its counters locally and stores them into relaxed atomics
//! ([`Counters`]) at each batch. The reporting thread
//! ([`Reporter`]) owns the histograms.

use std::io::Write as _;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, TryRecvError};
use hdrhistogram::Histogram;
use serde::Serialize;

use crate::transport::Losses;
use crate::wire::{
    OdometryStats, Percentiles, StageStats, StatsSnapshot, MAX_STATS_STAGES, OFF_CPU_NOT_MEASURED,
};

/// Most stages of a pipeline.
pub const MAX_STAGES: usize = MAX_STATS_STAGES;

/// Timing of one ingested sample through the chain.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Record {
    /// Time of each stage that ran for this sample, its compute and the publish of its output,
    /// ns (saturated at u32::MAX).
    pub stage_ns: [u32; MAX_STAGES],
    /// Chain position of the first stage this record times (0, or the first stage after an
    /// `external` stage for records of a later segment).
    pub first: u8,
    /// Chain position + 1 of the last stage that ran (stages `first..stages_run` are timed).
    pub stages_run: u8,
    /// Ingest of this sample to publish of the output it completed, ns; 0 if none was published.
    pub e2e_ns: u64,
    /// How long after it was due a paced source's sample was taken, ns (saturated at
    /// u32::MAX); None for a source that is not paced.
    pub late_ns: Option<u32>,
    /// For an output over the deadline: how long of its end-to-end time the hot thread was off
    /// a CPU (runnable but not run, or preempted), ns; None where not measured (a sample that
    /// crossed an external stage). A replay as fast as possible gives a lower bound.
    pub off_cpu_ns: Option<u32>,
}

/// How often the reporter drains the channel: 20 wake-ups a second, a small share of a 1 kHz
/// daemon's CPU (10 ms cost it 100). The channel holds far more than this much at any rate.
const POLL: Duration = Duration::from_millis(50);

/// Records per channel message: the hot loop batches them so the channel costs little.
pub const BATCH: usize = 32;

/// A batch of records (the first `len` are valid).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Batch {
    /// Valid records.
    pub len: usize,
    /// The records.
    pub records: [Record; BATCH],
    /// The heading errors against the truth so far, when the ingest knows the truth.
    pub heading: Option<HeadingSummary>,
    /// What the odometry did for a stage of the segment so far ([`crate::stages::Stage::odometry`]).
    pub odometry: Option<OdometryStats>,
}

impl Default for Batch {
    fn default() -> Self {
        Batch {
            len: 0,
            records: [Record::default(); BATCH],
            heading: None,
            odometry: None,
        }
    }
}

/// Heading error of one signal on one axis against the truth: the integral of (signal - true
/// rate) over time, as a navigator integrating the signal would see it. Degrees.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct HeadingError {
    /// At the last sample.
    pub final_deg: f64,
    /// RMS over time (the final value alone is a lottery of cancellations).
    pub rms_deg: f64,
    /// Largest |error|.
    pub max_deg: f64,
    #[serde(skip)]
    sum_sq: f64,
    #[serde(skip)]
    n: u64,
}

impl HeadingError {
    /// Add one sample's rate error (rad/s) held for `dt` seconds.
    pub fn add(&mut self, error_rad_s: f64, dt: f64) {
        self.final_deg += error_rad_s.to_degrees() * dt;
        self.sum_sq += self.final_deg * self.final_deg;
        self.n += 1;
        self.rms_deg = (self.sum_sq / self.n as f64).sqrt();
        self.max_deg = self.max_deg.max(self.final_deg.abs());
    }
}

/// Heading errors of the raw, denoised and corrected rates, per axis (unused axes 0). A part a
/// segment does not see (the raw rate after an external stage) is None.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct HeadingSummary {
    /// The raw rate (as the guard admitted it).
    pub raw: Option<[HeadingError; 3]>,
    /// The denoised rate, as published.
    pub denoised: Option<[HeadingError; 3]>,
    /// The corrected (published) rate.
    pub corrected: Option<[HeadingError; 3]>,
}

impl HeadingSummary {
    /// Take the parts `other` has.
    pub fn merge(&mut self, other: &HeadingSummary) {
        self.raw = other.raw.or(self.raw);
        self.denoised = other.denoised.or(self.denoised);
        self.corrected = other.corrected.or(self.corrected);
    }

    /// The worst axis's RMS heading error of each part, degrees.
    pub fn worst_rms(&self) -> [Option<f64>; 3] {
        let worst = |p: &Option<[HeadingError; 3]>| {
            p.map(|a| a.iter().map(|e| e.rms_deg).fold(0.0, f64::max))
        };
        [
            worst(&self.raw),
            worst(&self.denoised),
            worst(&self.corrected),
        ]
    }
}

/// Integrates the heading error of a segment's samples against the truth, in the hot thread:
/// a few additions and the truth's evaluation per sample, no allocation.
pub struct HeadingTracker {
    truth: crate::sim::TrueRate,
    /// rad/s per input unit (the truth's units).
    scale: f64,
    dt: f64,
    axes: usize,
    summary: HeadingSummary,
}

impl HeadingTracker {
    /// A tracker for samples at `rate_hz` of `axes` axes, the truth in input units scaled to
    /// rad/s by `scale`.
    pub fn new(truth: crate::sim::TrueRate, scale: f64, rate_hz: f64, axes: usize) -> Self {
        HeadingTracker {
            truth,
            scale,
            dt: 1.0 / rate_hz,
            axes: axes.clamp(1, 3),
            summary: HeadingSummary::default(),
        }
    }

    /// The true rate at `t_ns`, rad/s.
    fn truth_at(&self, t_ns: u64) -> [f64; 3] {
        let t = (self.truth)(t_ns as f64 * 1e-9);
        t.map(|v| v * self.scale)
    }

    fn add(&self, part: &mut Option<[HeadingError; 3]>, values: &[f64; 3], truth: &[f64; 3]) {
        let part = part.get_or_insert_with(Default::default);
        for axis in 0..self.axes {
            part[axis].add(values[axis] - truth[axis], self.dt);
        }
    }

    /// A raw sample as the guard admitted it (rad/s).
    pub fn raw(&mut self, s: &crate::wire::GyroSample) {
        let truth = self.truth_at(s.t_ns);
        let mut part = self.summary.raw;
        self.add(&mut part, &s.rate, &truth);
        self.summary.raw = part;
    }

    /// A published sample: its denoised and corrected rates (rad/s).
    pub fn published(&mut self, s: &crate::wire::GyroSample) {
        let truth = self.truth_at(s.t_ns);
        let (mut den, mut cor) = (self.summary.denoised, self.summary.corrected);
        self.add(&mut den, &s.denoised, &truth);
        self.add(&mut cor, &s.rate, &truth);
        (self.summary.denoised, self.summary.corrected) = (den, cor);
    }

    /// What was integrated so far.
    pub fn summary(&self) -> HeadingSummary {
        self.summary
    }
}

/// Counters the hot loop publishes (relaxed atomics) and the reporter reads.
#[derive(Debug, Default)]
pub struct Counters {
    /// Samples in, per stage.
    pub stage_in: [AtomicU64; MAX_STAGES],
    /// Samples out, per stage.
    pub stage_out: [AtomicU64; MAX_STAGES],
    /// End-to-end latencies above the deadline.
    pub deadline_misses: AtomicU64,
    /// Of them, those the kernel explains: without the time it kept the hot thread off a CPU,
    /// the output would have made the deadline ([`Record::off_cpu_ns`]).
    pub misses_explained: AtomicU64,
    /// Records the reporter could not take.
    pub metric_drops: AtomicU64,
    /// Non-finite or driver-invalid input samples.
    pub invalid: AtomicU64,
    /// Sequence gaps.
    pub gaps: AtomicU64,
    /// Sequence numbers missing.
    pub missing: AtomicU64,
    /// Stamps not believed ([`crate::clock::StampCheck`]).
    pub stamp_faults: AtomicU64,
    /// Samples whose accelerometer or magnetometer reading was not finite (held, flagged).
    pub sensors_invalid: AtomicU64,
    /// Outputs repaired by the publish guard.
    pub repaired: AtomicU64,
    /// The stream's first epoch (set once before the segments start).
    pub epoch: AtomicU64,
    /// New epochs: source restarts, and sequence numbers that repeated or stepped back.
    pub restarts: AtomicU64,
    /// Published outputs carrying each of [`Outputs::FLAGS`].
    pub outputs: [AtomicU64; 4],
}

fn get(a: &AtomicU64) -> u64 {
    a.load(Ordering::Relaxed)
}

/// Static description of the pipeline for the reports.
#[derive(Debug, Clone)]
pub struct Layout {
    /// Pipeline name.
    pub pipeline: String,
    /// Stage names and kinds, chain order.
    pub stages: Vec<(String, String)>,
    /// Deadline.
    pub deadline: Duration,
    /// Algorithmic delay (sum of lags / rate).
    pub algorithmic_delay: Duration,
    /// Summary period.
    pub interval: Duration,
    /// Print the summary line on stderr.
    pub print: bool,
    /// How the stages that keep state across runs started, one line each after the stage's
    /// name (`predict: cold: ...`), for the report.
    pub warm_start: Vec<String>,
    /// The worst of their outcomes, for the stats ([`crate::wire::WARM_START_NONE`] and
    /// its siblings).
    pub warm_start_outcome: u64,
}

mod report;
pub use report::*;

/// Where a reporter hands its periodic snapshots (the stats service).
pub type Publish<'a> = Box<dyn FnMut(&StatsSnapshot) + 'a>;

/// One reporting thread for several pipelines (a daemon running them all on one hot thread):
/// each reporter consumes its own channel until its senders are gone, then publishes its
/// final snapshot. Returns the final reports in the order given. It polls rather than
/// blocks: a blocked receiver would make every `try_send` of the hot loop a futex wake-up (a
/// system call and a context switch on the other core); one thread polling for all keeps the
/// wake-ups at one per `POLL` (50 ms) whatever the number of pipelines.
pub fn run_all(mut reporters: Vec<(Reporter, Receiver<Batch>, Publish<'_>)>) -> Vec<Report> {
    let mut done: Vec<Option<Report>> = reporters.iter().map(|_| None).collect();
    while done.iter().any(Option::is_none) {
        let next = reporters
            .iter()
            .zip(&done)
            .filter(|(_, d)| d.is_none())
            .map(|((r, _, _), _)| r.next)
            .min()
            .unwrap_or_else(Instant::now);
        std::thread::sleep(POLL.min(next.saturating_duration_since(Instant::now())));
        for ((r, rx, publish), done) in reporters.iter_mut().zip(&mut done) {
            if done.is_some() {
                continue;
            }
            if r.drain(rx) {
                r.tick(Instant::now(), publish);
            } else {
                let report = r.report();
                publish(&r.snapshot(report.rate_hz));
                *done = Some(report);
            }
        }
    }
    done.into_iter().flatten().collect()
}

/// The reporting thread's state: histograms, counters, the periodic summary.
pub struct Reporter {
    layout: Layout,
    counters: Arc<Counters>,
    lost: Vec<Arc<Losses>>,
    stage_hist: Vec<Histogram<u64>>,
    e2e: Histogram<u64>,
    heading: Option<HeadingSummary>,
    /// The odometry's, from the newest batch that had it.
    odometry: OdometryStats,
    misses: Vec<Miss>,
    /// The latest miss, however many came before it (for the stats service): when (s), end
    /// to end and off a CPU (ns). No stage times, so that keeping it allocates nothing.
    last_miss: Option<(f64, u64, Option<u64>)>,
    late: Histogram<u64>,
    late_over: u64,
    due: Histogram<u64>,
    due_over: u64,
    started: Instant,
    /// When the next summary is due, and the input count and time of the last one.
    next: Instant,
    last_in: u64,
    last_t: Instant,
}

fn histogram() -> Histogram<u64> {
    // 1 ns .. 100 s at 3 significant digits; values above are clamped.
    Histogram::new_with_bounds(1, 100_000_000_000, 3).expect("constant bounds are valid")
}

impl Reporter {
    /// A reporter for `layout`, reading `counters` and the services' loss counters `lost`.
    pub fn new(layout: Layout, counters: Arc<Counters>, lost: Vec<Arc<Losses>>) -> Self {
        let n = layout.stages.len();
        let interval = layout.interval;
        Reporter {
            layout,
            counters,
            lost,
            stage_hist: (0..n).map(|_| histogram()).collect(),
            e2e: histogram(),
            heading: None,
            odometry: OdometryStats::default(),
            misses: Vec::new(),
            last_miss: None,
            late: histogram(),
            late_over: 0,
            due: histogram(),
            due_over: 0,
            started: Instant::now(),
            next: Instant::now() + interval,
            last_in: 0,
            last_t: Instant::now(),
        }
    }

    fn record_batch(&mut self, b: &Batch) {
        for r in &b.records[..b.len.min(BATCH)] {
            self.record(r);
        }
        if let Some(h) = &b.heading {
            self.heading.get_or_insert_with(Default::default).merge(h);
        }
        if let Some(o) = b.odometry {
            self.odometry = o;
        }
    }

    fn record(&mut self, r: &Record) {
        if let Some(late) = r.late_ns.map(u64::from) {
            self.late.saturating_record(late.max(1));
            self.late_over += u64::from(late > self.layout.deadline.as_nanos() as u64);
        }
        let n = (r.stages_run as usize).min(self.stage_hist.len());
        let first = (r.first as usize).min(n);
        for (h, &ns) in self.stage_hist[first..n]
            .iter_mut()
            .zip(&r.stage_ns[first..n])
        {
            h.saturating_record(u64::from(ns.max(1)));
        }
        if let (Some(late), true) = (r.late_ns, r.e2e_ns > 0) {
            let due = u64::from(late) + r.e2e_ns;
            self.due.saturating_record(due);
            self.due_over += u64::from(due > self.layout.deadline.as_nanos() as u64);
        }
        if r.e2e_ns > 0 {
            self.e2e.saturating_record(r.e2e_ns);
            // The hot loop's own test, so the list agrees with its count.
            if r.e2e_ns > self.layout.deadline.as_nanos() as u64 {
                let at_s = self.started.elapsed().as_secs_f64();
                let off_cpu_ns = r.off_cpu_ns.map(u64::from);
                self.last_miss = Some((at_s, r.e2e_ns, off_cpu_ns));
                if self.misses.len() < MISSES_KEPT {
                    let mut stage_ns = vec![0; self.stage_hist.len()];
                    for (d, &ns) in stage_ns[first..n].iter_mut().zip(&r.stage_ns[first..n]) {
                        *d = u64::from(ns);
                    }
                    self.misses.push(Miss {
                        at_s,
                        e2e_ns: r.e2e_ns,
                        stage_ns,
                        off_cpu_ns,
                    });
                }
            }
        }
    }

    /// Take every batch waiting in `rx`; false once the senders are gone and it is drained.
    fn drain(&mut self, rx: &Receiver<Batch>) -> bool {
        loop {
            match rx.try_recv() {
                Ok(b) => self.record_batch(&b),
                Err(TryRecvError::Empty) => return true,
                Err(TryRecvError::Disconnected) => return false,
            }
        }
    }

    /// At `now`, once the interval has passed: print the summary (if enabled) and publish a
    /// snapshot.
    fn tick(&mut self, now: Instant, publish: &mut Publish<'_>) {
        if now < self.next {
            return;
        }
        let samples_in = get(&self.counters.stage_in[0]);
        let rate = (samples_in - self.last_in) as f64 / (now - self.last_t).as_secs_f64().max(1e-9);
        self.last_in = samples_in;
        self.last_t = now;
        let snap = self.snapshot(rate);
        if self.layout.print {
            // A closed stderr must not stop the reporter (the daemon keeps serving).
            let _ = writeln!(std::io::stderr(), "{}", self.summary_line(&snap));
        }
        publish(&snap);
        self.next = now + self.layout.interval;
    }

    fn summary_line(&self, s: &StatsSnapshot) -> String {
        let us = |ns: u64| ns as f64 / 1e3;
        let heading = self.heading.map_or(String::new(), |h| {
            let [raw, den, cor] = h
                .worst_rms()
                .map(|v| v.map_or("-".into(), |d| format!("{d:.2}")));
            format!(", heading rms vs truth raw {raw} denoised {den} corrected {cor} deg")
        });
        let line = format!(
            "{}: {:.0} Hz, e2e p50 {:.1} us p99 {:.1} us p99.9 {:.1} us max {:.1} us, misses {}, lost {}, flagged {}{}, drops {}",
            self.layout.pipeline,
            s.rate_hz,
            us(s.end_to_end.p50),
            us(s.end_to_end.p99),
            us(s.end_to_end.p999),
            us(s.end_to_end.max),
            misses_text(s),
            s.lost,
            s.flagged,
            stamp_faults_text(s.stamp_faults),
            s.metric_drops
        );
        let shm = crate::transport::shared_memory_trouble();
        let shm = if shm == Default::default() {
            String::new()
        } else {
            format!(
                ", shared memory FULL ({} writes unbacked, {} bytes unreserved)",
                shm.unbacked_writes, shm.unreserved_bytes
            )
        };
        line + &heading + &shm
    }

    /// Losses in every service plus the samples missing from the source.
    fn lost_total(&self) -> u64 {
        self.lost.iter().map(|l| get(&l.lost)).sum::<u64>() + get(&self.counters.missing)
    }

    fn flagged(&self) -> Flagged {
        let c = &self.counters;
        Flagged {
            invalid: get(&c.invalid),
            gaps: get(&c.gaps),
            missing: get(&c.missing),
            stamp_faults: get(&c.stamp_faults),
            sensors_invalid: get(&c.sensors_invalid),
            repaired_outputs: get(&c.repaired),
        }
    }

    /// The current snapshot (cumulative histograms, `rate_hz` over the last interval).
    pub fn snapshot(&self, rate_hz: f64) -> StatsSnapshot {
        let c = &self.counters;
        let f = self.flagged();
        let mut stages = [StageStats::default(); MAX_STATS_STAGES];
        for (i, ((name, _), h)) in self.layout.stages.iter().zip(&self.stage_hist).enumerate() {
            let st = &mut stages[i];
            let bytes = name.as_bytes();
            let n = bytes.len().min(st.name.len());
            st.name[..n].copy_from_slice(&bytes[..n]);
            st.samples_in = get(&c.stage_in[i]);
            st.samples_out = get(&c.stage_out[i]);
            st.lost = self.lost.get(i).map_or(0, |l| get(&l.lost));
            st.compute = Pct::of(h).wire();
        }
        let last = self.layout.stages.len().saturating_sub(1);
        StatsSnapshot {
            uptime_ns: self.started.elapsed().as_nanos() as u64,
            samples_in: get(&c.stage_in[0]),
            samples_out: get(&c.stage_out[last]),
            rate_hz,
            deadline_misses: get(&c.deadline_misses),
            lost: self.lost_total(),
            flagged: f.invalid + f.gaps + f.stamp_faults + f.sensors_invalid + f.repaired_outputs,
            gap_samples: f.missing,
            metric_drops: get(&c.metric_drops),
            deadline_ns: self.layout.deadline.as_nanos() as u64,
            algorithmic_delay_ns: self.layout.algorithmic_delay.as_nanos() as u64,
            end_to_end: Pct::of(&self.e2e).wire(),
            stage_count: self.layout.stages.len() as u64,
            stages,
            deadline_misses_explained: get(&c.misses_explained),
            last_miss_uptime_ns: self
                .last_miss
                .map_or(0, |(at_s, _, _)| ((at_s * 1e9) as u64).max(1)),
            last_miss_e2e_ns: self.last_miss.map_or(0, |(_, e2e, _)| e2e),
            last_miss_off_cpu_ns: self
                .last_miss
                .and_then(|(_, _, off)| off)
                .unwrap_or(OFF_CPU_NOT_MEASURED),
            stamp_faults: f.stamp_faults,
            warm_start: self.layout.warm_start_outcome,
            odometry: self.odometry,
        }
    }

    /// The final report.
    pub fn report(&self) -> Report {
        let c = &self.counters;
        let duration = self.started.elapsed().as_secs_f64();
        let samples_in = get(&c.stage_in[0]);
        let last = self.layout.stages.len().saturating_sub(1);
        Report {
            pipeline: self.layout.pipeline.clone(),
            duration_s: duration,
            samples_in,
            samples_out: get(&c.stage_out[last]),
            rate_hz: samples_in as f64 / duration.max(1e-9),
            deadline_ns: self.layout.deadline.as_nanos() as u64,
            algorithmic_delay_ns: self.layout.algorithmic_delay.as_nanos() as u64,
            deadline_misses: get(&c.deadline_misses),
            deadline_misses_explained: get(&c.misses_explained),
            misses: self.misses.clone(),
            metric_drops: get(&c.metric_drops),
            lost: self.lost_total(),
            left_unread: self.lost.iter().map(|l| get(&l.left_unread)).sum(),
            epoch: get(&c.epoch) as u32,
            source_restarts: get(&c.restarts),
            flagged: self.flagged(),
            warm_start_outcome: self.layout.warm_start_outcome,
            outputs: Outputs::from_counts(c.outputs.each_ref().map(get)),
            end_to_end_ns: Pct::of(&self.e2e),
            woken_late_ns: (!self.late.is_empty()).then(|| Pct::of(&self.late)),
            woken_late_over_deadline: self.late_over,
            due_to_published_ns: (!self.due.is_empty()).then(|| Pct::of(&self.due)),
            due_to_published_over_deadline: self.due_over,
            shared_memory: crate::transport::shared_memory_trouble(),
            stages: self
                .layout
                .stages
                .iter()
                .enumerate()
                .map(|(i, (name, kind))| StageReport {
                    name: name.clone(),
                    kind: kind.clone(),
                    samples_in: get(&c.stage_in[i]),
                    samples_out: get(&c.stage_out[i]),
                    lost: self.lost.get(i).map_or(0, |l| get(&l.lost)),
                    compute_ns: Pct::of(&self.stage_hist[i]),
                })
                .collect(),
            heading: self.heading,
            warm_start: self.layout.warm_start.clone(),
            learnt: Vec::new(),
        }
    }
}

/// `, 3 stamp faults` when there were any (they are in `flagged`, never in `lost`).
fn stamp_faults_text(n: u64) -> String {
    match n {
        0 => String::new(),
        1 => " (1 stamp fault)".into(),
        n => format!(" ({n} stamp faults)"),
    }
}

/// A snapshot's misses, and whose they were: `0`, `3 (2 the kernel's, 1 UNEXPLAINED)`.
fn misses_text(s: &StatsSnapshot) -> String {
    let explained = s.deadline_misses_explained.min(s.deadline_misses);
    match (s.deadline_misses, s.deadline_misses - explained) {
        (0, _) => "0".into(),
        (n, 0) => format!("{n} (all the kernel's)"),
        (n, u) if u == n => format!("{n} (all UNEXPLAINED)"),
        (n, u) => format!("{n} ({explained} the kernel's, {u} UNEXPLAINED)"),
    }
}

/// Format a snapshot for `driftless stats`.
pub fn format_snapshot(name: &str, s: &StatsSnapshot) -> String {
    // Fits an 80-column terminal: four summary lines, the last miss and a 76-column table.
    let us = |ns: u64| format!("{:.1}", ns as f64 / 1e3);
    let mut out = format!(
        "{name}: up {:.1} s, {:.0} Hz; deadline {} us\n\
         misses: {}\n\
         samples: {} in, {} out, {} lost ({} missing from the source)\n\
         flagged {}{}; metric drops {}\n",
        s.uptime_ns as f64 / 1e9,
        s.rate_hz,
        us(s.deadline_ns),
        misses_text(s),
        s.samples_in,
        s.samples_out,
        s.lost,
        s.gap_samples,
        s.flagged,
        stamp_faults_text(s.stamp_faults),
        s.metric_drops
    );
    if s.warm_start != crate::wire::WARM_START_NONE {
        out.push_str(&format!(
            "warm start: {}\n",
            crate::wire::warm_start_name(s.warm_start)
        ));
    }
    let o = &s.odometry;
    if o.up != 0 {
        out.push_str(&format!(
            "odometry: up {} ({}); {} used, {} rejected, {} slips\n\
             odometry: scale {:+.2} % +- {:.2} %; bias learnt in motion {:+.4} deg/s\n",
            o.up_name(),
            o.mounting_name(),
            o.learnt,
            o.spans_rejected,
            o.slips,
            o.scale * 100.0,
            o.scale_sd * 100.0,
            o.bias_learnt_rad_s.to_degrees()
        ));
    }
    if let Some(explained) = s.last_miss_explained() {
        let off = s
            .last_miss_off_cpu()
            .map_or("off a CPU: not measured".into(), |ns| {
                format!("{} us off a CPU", us(ns))
            });
        out.push_str(&format!(
            "last miss at {:.1} s: {} us, {off}: {}\n",
            s.last_miss_uptime_ns as f64 / 1e9,
            us(s.last_miss_e2e_ns),
            if explained {
                "the kernel's"
            } else {
                "UNEXPLAINED"
            }
        ));
    }
    let row = |out: &mut String, cells: [&str; 8]| {
        let [name, a, b, c, d, e, f, g] = cells;
        out.push_str(&format!(
            "{name:<12} {a:>9} {b:>9} {c:>7} {d:>8} {e:>8} {f:>8} {g:>8}\n"
        ));
    };
    row(
        &mut out,
        [
            "stage", "in", "out", "lost", "p50 us", "p99 us", "p99.9 us", "max us",
        ],
    );
    let n = (s.stage_count as usize).min(MAX_STATS_STAGES);
    for st in &s.stages[..n] {
        let c = &st.compute;
        row(
            &mut out,
            [
                &st.name_text(),
                &st.samples_in.to_string(),
                &st.samples_out.to_string(),
                &st.lost.to_string(),
                &us(c.p50),
                &us(c.p99),
                &us(c.p999),
                &us(c.max),
            ],
        );
    }
    let e = &s.end_to_end;
    row(
        &mut out,
        [
            "end-to-end",
            &e.count.to_string(),
            "",
            "",
            &us(e.p50),
            &us(e.p99),
            &us(e.p999),
            &us(e.max),
        ],
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_snapshot_fits_80_columns_even_with_large_counts() {
        let mut s = StatsSnapshot {
            uptime_ns: 86_400_000_000_000,
            samples_in: 86_400_000,
            samples_out: 86_399_936,
            rate_hz: 1000.0,
            deadline_ns: 1_000_000,
            deadline_misses: 12_345,
            deadline_misses_explained: 12_000,
            last_miss_uptime_ns: 86_399_000_000_000,
            last_miss_e2e_ns: 99_999_900,
            last_miss_off_cpu_ns: 99_999_000,
            lost: 123_456,
            flagged: 1_000,
            gap_samples: 500,
            metric_drops: 7,
            stage_count: 4,
            ..StatsSnapshot::default()
        };
        for (i, name) in ["sensor", "denoise", "predict", "publish"]
            .iter()
            .enumerate()
        {
            let st = &mut s.stages[i];
            st.name[..name.len()].copy_from_slice(name.as_bytes());
            st.samples_in = 86_400_000;
            st.samples_out = 86_400_000;
            st.lost = 99_999;
            st.compute.p50 = 12_300;
            st.compute.max = 99_999_900;
        }
        s.end_to_end.count = 86_400_000;
        s.end_to_end.max = 99_999_900;
        let text = format_snapshot("demo", &s);
        assert_eq!(text.lines().count(), 4 + 1 + 1 + 4 + 1, "{text}");
        for line in text.lines() {
            assert!(line.len() <= 80, "{} columns: {line:?}", line.len());
        }
        assert!(text.contains("denoise"), "{text}");
        assert!(
            !text.contains("warm start"),
            "no state-keeping stage: {text}"
        );
        s.warm_start = crate::wire::WARM_START_UNUSABLE;
        s.stamp_faults = 3;
        let text = format_snapshot("demo", &s);
        assert!(
            text.contains("\nwarm start: cold, the saved state unusable (moved aside)\n"),
            "{text}"
        );
        assert!(text.contains("flagged 1000 (3 stamp faults);"), "{text}");
        assert!(!text.contains("odometry"), "no odometry: {text}");
        s.odometry = crate::wire::OdometryStats {
            up: 6,
            mounting: crate::wire::MOUNTING_WRONG_SIGN,
            spans_accepted: 99_999,
            spans_rejected: 99_999,
            slips: 99_999,
            learnt: 99_999,
            scale: -0.1234,
            scale_sd: 0.0456,
            bias_learnt_rad_s: -0.5f64.to_radians(),
        };
        let text = format_snapshot("demo", &s);
        assert!(
            text.contains(
                "\nodometry: up -z (refused: wrong sign); 99999 used, 99999 rejected, 99999 \
                 slips\nodometry: scale -12.34 % +- 4.56 %; bias learnt in motion -0.5000 \
                 deg/s\n"
            ),
            "{text}"
        );
        for line in text.lines() {
            assert!(line.len() <= 80, "{} columns: {line:?}", line.len());
        }
        assert!(
            text.contains("\nmisses: 12345 (12000 the kernel's, 345 UNEXPLAINED)\n"),
            "{text}"
        );
        assert!(
            text.contains(
                "last miss at 86399.0 s: 99999.9 us, 99999.0 us off a CPU: the kernel's\n"
            ),
            "{text}"
        );
    }

    #[test]
    fn the_stats_service_carries_the_latest_miss_and_whose_it_was() {
        let mut r = reporter(1000);
        assert_eq!(r.snapshot(0.0).last_miss_explained(), None);
        // 1.8 ms end to end, 0.9 ms of it off a CPU: the kernel's. Then one on a CPU: ours.
        for (e2e, off) in [(1_800_000, Some(900_000)), (1_500_000, Some(1_000))] {
            r.record(&Record {
                e2e_ns: e2e,
                stages_run: 2,
                off_cpu_ns: off,
                ..Record::default()
            });
            let s = r.snapshot(0.0);
            assert_eq!(s.last_miss_e2e_ns, e2e);
            assert_eq!(Some(s.last_miss_off_cpu_ns), off.map(u64::from));
            assert_eq!(s.last_miss_explained(), Some(off == Some(900_000)));
            assert!(s.last_miss_uptime_ns > 0);
        }
        // A sample that crossed an external stage: not measured, so not explained.
        r.record(&Record {
            e2e_ns: 2_000_000,
            stages_run: 2,
            ..Record::default()
        });
        let s = r.snapshot(0.0);
        assert_eq!(s.last_miss_off_cpu_ns, OFF_CPU_NOT_MEASURED);
        assert_eq!(s.last_miss_explained(), Some(false));
        let json = crate::io::recording::StatsMessage::json(&s);
        assert_eq!(json["last_miss"]["off_cpu_ns"], serde_json::Value::Null);
        assert_eq!(json["last_miss"]["explained"], false);
    }

    fn reporter(deadline_us: u64) -> Reporter {
        let layout = Layout {
            pipeline: "p".into(),
            stages: vec![
                ("sensor".into(), "ingest.sim".into()),
                ("publish".into(), "publish".into()),
            ],
            deadline: Duration::from_micros(deadline_us),
            algorithmic_delay: Duration::ZERO,
            interval: Duration::from_secs(60),
            print: false,
            warm_start: Vec::new(),
            warm_start_outcome: crate::wire::WARM_START_NONE,
        };
        Reporter::new(layout, Arc::default(), Vec::new())
    }

    fn miss(e2e_us: u64, off_us: Option<u64>) -> Record {
        Record {
            stages_run: 2,
            e2e_ns: e2e_us * 1000,
            off_cpu_ns: off_us.map(|us| (us * 1000) as u32),
            ..Record::default()
        }
    }

    /// A miss is the kernel's only if, without the time off a CPU, the output made the
    /// deadline; one not measured is never excused.
    #[test]
    fn a_miss_is_the_kernels_only_when_its_time_off_a_cpu_covers_the_overshoot() {
        assert!(miss_explained(1_800_000, Some(900_000), 1_000_000));
        assert!(miss_explained(1_800_000, Some(800_000), 1_000_000));
        assert!(!miss_explained(1_800_000, Some(799_999), 1_000_000));
        assert!(!miss_explained(1_800_000, None, 1_000_000));
        assert!(miss_explained(1_800_000, Some(u64::MAX), 1_000_000));

        let mut r = reporter(1000);
        let mut batch = Batch::default();
        for (i, rec) in [
            miss(1800, Some(1750)),
            miss(1500, Some(20)),
            miss(1200, None),
        ]
        .into_iter()
        .enumerate()
        {
            batch.records[i] = rec;
        }
        batch.len = 3;
        r.record_batch(&batch);
        r.counters.deadline_misses.store(3, Ordering::Relaxed);
        r.counters.misses_explained.store(1, Ordering::Relaxed);
        let report = r.report();
        let text = report.table();
        assert!(
            report
                .verdict()
                .contains("deadline MISSED: 3 of 3 outputs over 1000.0 us (max")
                && report
                    .verdict()
                    .contains("; 1 the kernel's, 2 UNEXPLAINED)"),
            "{}",
            report.verdict()
        );
        assert!(
            text.contains(
                "1800.0 us end to end; stages 0.0 / 0.0 us; off the CPU 1750.0 us: the kernel's"
            ),
            "{text}"
        );
        assert!(
            text.contains("off the CPU 20.0 us: UNEXPLAINED, ours"),
            "{text}"
        );
        assert!(text.contains("off-CPU time not measured"), "{text}");
        r.counters.misses_explained.store(3, Ordering::Relaxed);
        assert!(r.report().verdict().contains("all the kernel's"));
    }
}
