//! The executor: one hot thread runs the whole chain; a reporting thread owns the histograms.
//!
//! # Execution model
//! On a 2-core machine a thread per stage costs a sleep/wake-up per hop (~25 us each here, with
//! millisecond tails); one thread running the chain costs a fraction of a microsecond per hop.
//! So the hot thread waits once per input sample (the ingest's pacing clock, or the event
//! service of an external raw service), then runs every stage in turn. Every hop is still a
//! real iceoryx2 `ipc` service: the stage's output is published (zero-copy, never blocking) and
//! the next stage takes it from its own subscriber on that service, so any process can
//! subscribe to any hop. The publish stage also notifies an event service of the same name so
//! that external readers can sleep until data arrives.
//!
//! # External stages
//! An `external` stage runs in another process. The chain splits into segments there: segment 1
//! (the ingest up to the stage feeding the first external stage) runs on the hot thread; each
//! later segment runs on its own thread (ports created in it), sleeping on the event service of
//! the external stage's output with a timeout, then running its stages in-thread. Crossing the
//! process boundary costs wake-ups (~25 us each on 2 cores): inherent, and documented.
//!
//! # Several pipelines
//! [`run_group`] runs several pipelines (a vehicle's IMUs) on the one hot thread: their paced
//! sources share one clock, so samples of the same rate fall due together and one wake-up
//! serves them all; those due are run in the order given. One reporting thread serves them
//! all too. [`run`] is a group of one.
//!
//! The hot loop does not allocate: timings go to the reporting thread in fixed-size records over
//! a bounded crossbeam channel (`try_send`; a full channel is counted, never waited on).
//!
//! # Shutdown
//! A stop flag (set by SIGINT/SIGTERM or `--duration`) ends every ingest; the end of a finite
//! source or a failure ends its own pipeline's. The lagged stages are then flushed through the
//! rest of the chain, the reporter writes its final report, all ports and the node are dropped,
//! and the prefix's leftover files are removed when no other node of the prefix is alive. A
//! later segment keeps reading until the segment before it has finished and its input has been
//! quiet for [`EXTERNAL_GRACE`], then flushes its own lagged stages.

use std::io::Write as _;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crossbeam_channel::{bounded, Sender};

use crate::metrics::{
    run_all, Batch, Counters, HeadingTracker, Layout, Outputs, Publish, Record, Report, Reporter,
    BATCH, MAX_STAGES,
};
use crate::pipeline::config::Pipeline;
use crate::pipeline::guard::Guard;
use crate::pipeline::stage::Role;
use crate::pipeline::stage::{Poll, Source, Stage};
use crate::transport::{
    monotonic_ns, remove_prefix_leftovers, GyroSample, Input, NodeHolder, Output, Qos, RawSample,
    StatsSnapshot, Transport, TransportError, WakeSet, Waker, FLAG_FLUSHED, FLAG_GAP_BEFORE,
    FLAG_OUTPUT_REPAIRED,
};

/// Capacity of the metrics channel (batches of [`BATCH`] records): 2 minutes at 1 kHz.
const METRICS_CAPACITY: usize = 1 << 12;

/// How a run is started.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Stop by itself after this long.
    pub duration: Option<Duration>,
    /// Set to stop (signal handlers set it).
    pub stop: Arc<AtomicBool>,
    /// Print the periodic summary on stderr.
    pub print_summary: bool,
}

/// Why a run could not start or had to stop.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A daemon for this pipeline is already running under this prefix.
    #[error(
        "pipeline {pipeline:?} is already running (prefix {prefix:?}), held by {}",
        describe_holders(.holders)
    )]
    AlreadyRunning {
        /// Pipeline name.
        pipeline: String,
        /// iceoryx2 prefix.
        prefix: String,
        /// Who holds it, as iceoryx2's node list tells (at least one).
        holders: Vec<NodeHolder>,
    },
    /// iceoryx2 set-up or I/O.
    #[error("{0}")]
    Transport(#[from] TransportError),
    /// The pipelines given cannot share one daemon.
    #[error("{0}")]
    Group(String),
    /// A stage could not be built.
    #[error("stage {stage:?}: {message}")]
    Stage {
        /// Stage name.
        stage: String,
        /// What is wrong.
        message: String,
    },
}

fn describe_holders(holders: &[NodeHolder]) -> String {
    holders
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(" and ")
}

/// The node name of a pipeline's daemon (one per pipeline and prefix).
pub fn node_name(pipeline: &str) -> String {
    format!("driftless-{pipeline}")
}

/// The node of a daemon's reporting thread, which publishes the stats snapshots: the daemon's
/// node name (see [`node_name`]) with `-stats`. `driftless list` knows a pipeline by the pair.
pub fn stats_node_name(daemon_node: &str) -> String {
    format!("{daemon_node}-stats")
}

/// Counts kept by a segment's thread, stored into the shared [`Counters`] at each batch.
#[derive(Debug, Default)]
struct Local {
    stage_in: [u64; MAX_STAGES],
    stage_out: [u64; MAX_STAGES],
    misses: u64,
    repaired: u64,
    /// Published outputs carrying each of [`Outputs::FLAGS`].
    outputs: [u64; 4],
    metric_drops: u64,
    metric_drops_stored: u64,
}

/// The hops and stages of one segment, owned by its thread (iceoryx2 ports are not `Send`).
///
/// Segment 1 (`head` set) starts at the ingest; a later segment starts at the stage after an
/// `external` stage. A segment ends at the publish stage (`is_final`) or at the stage feeding
/// an `external` stage.
struct Chain {
    /// The ingest hop (segment 1 only).
    head: Option<(Output<RawSample>, Input<RawSample>)>,
    guard: Guard,
    /// Chain position of `stages[0]`.
    first: usize,
    stages: Vec<Box<dyn Stage>>,
    outs: Vec<Output<GyroSample>>,
    ins: Vec<Input<GyroSample>>,
    is_final: bool,
    /// Chain positions whose `stage_in` / `stage_out` counts this segment owns.
    owns_in: std::ops::Range<usize>,
    owns_out: std::ops::Range<usize>,
    counters: Arc<Counters>,
    local: Local,
    batch: Batch,
    batch_started_ns: u64,
    tx: Sender<Batch>,
    deadline_ns: u64,
    /// Heading error against the truth (a simulated ingest): raw in segment 1, published
    /// rates in the final segment.
    heading: Option<HeadingTracker>,
}

/// Longest a partial batch waits before it is sent (so slow pipelines report promptly).
const BATCH_MAX_AGE_NS: u64 = 50_000_000;

/// How long a later segment keeps reading its input once the segment before it has finished
/// and the input has gone quiet (the external process relays what was drained upstream).
pub const EXTERNAL_GRACE: Duration = Duration::from_millis(200);

impl Chain {
    /// The ingest hop, the guard, and the chain after it, for one raw sample.
    fn ingest(
        &mut self,
        raw: &RawSample,
        ingest_ns: u64,
        late_ns: Option<u64>,
    ) -> Result<(), TransportError> {
        let Some((raw_out, raw_in)) = &self.head else {
            return Ok(());
        };
        let mut rec = Record {
            late_ns: late_ns.map(|ns| ns.min(u64::from(u32::MAX)) as u32),
            ..Record::default()
        };
        raw_out.send(&self.guard.stamp(raw))?;
        let received = raw_in.receive()?;
        self.local.stage_in[0] += 1;
        self.local.stage_out[0] += 1;
        let Some(raw) = received else {
            return Ok(());
        };
        let s = self.guard.admit(&raw, ingest_ns);
        let t0 = monotonic_ns();
        rec.stage_ns[0] = (t0.saturating_sub(ingest_ns)).min(u64::from(u32::MAX)) as u32;
        rec.stages_run = 1;
        let end = self.process_from(0, s, &mut rec, t0)?;
        // Diagnostics against the truth wait until the sample has left.
        if let Some(h) = &mut self.heading {
            h.raw(&s);
        }
        self.record(rec, end);
        Ok(())
    }

    /// A later segment: one sample from the external stage before it.
    fn after_external(&mut self, s: GyroSample) -> Result<(), TransportError> {
        let t0 = monotonic_ns();
        let mut rec = Record {
            first: self.first as u8,
            stages_run: self.first as u8,
            ..Record::default()
        };
        let end = self.process_from(0, s, &mut rec, t0)?;
        self.record(rec, end);
        Ok(())
    }

    /// Run stage `k` (index into `stages`, chain position `first + k`) and everything after it
    /// in this segment; `now` is a fresh timestamp. Returns the last timestamp taken.
    fn process_from(
        &mut self,
        mut k: usize,
        mut input: GyroSample,
        rec: &mut Record,
        mut now: u64,
    ) -> Result<u64, TransportError> {
        while k < self.stages.len() {
            let pos = self.first + k;
            self.local.stage_in[pos] += 1;
            let out = self.stages[k].process(&input);
            let t1 = monotonic_ns();
            rec.stage_ns[pos] = (t1.saturating_sub(now)).min(u64::from(u32::MAX)) as u32;
            rec.stages_run = (pos + 1) as u8;
            now = t1;
            let Some(out) = out else {
                return Ok(now);
            };
            match self.publish(k, &out, rec)? {
                Some(next) => input = next,
                None => return Ok(now),
            }
            // The hop is not stage compute time.
            now = monotonic_ns();
            k += 1;
        }
        Ok(now)
    }

    /// Publish stage `k`'s output; returns what the next stage receives (None after the
    /// segment's last stage).
    fn publish(
        &mut self,
        k: usize,
        out: &GyroSample,
        rec: &mut Record,
    ) -> Result<Option<GyroSample>, TransportError> {
        let pos = self.first + k;
        self.local.stage_out[pos] += 1;
        self.outs[k].send(out)?;
        if k + 1 == self.stages.len() {
            if self.is_final {
                // Published: the end-to-end clock stops before readers are woken.
                if out.flags & FLAG_FLUSHED == 0 {
                    let e2e = monotonic_ns().saturating_sub(out.ingest_ns).max(1);
                    rec.e2e_ns = e2e;
                    if e2e > self.deadline_ns {
                        self.local.misses += 1;
                    }
                }
                if out.flags & FLAG_OUTPUT_REPAIRED != 0 {
                    self.local.repaired += 1;
                }
                for (n, flag) in self.local.outputs.iter_mut().zip(Outputs::FLAGS) {
                    *n += u64::from(out.flags & flag != 0);
                }
            } else {
                // Offered to the external stage (its "in" as seen from the service).
                self.local.stage_in[pos + 1] += 1;
            }
            self.outs[k].notify();
            // After the readers are woken: the truth is for the report, not on their path.
            if let Some(h) = self.heading.as_mut().filter(|_| self.is_final) {
                h.published(out);
            }
            return Ok(None);
        }
        self.ins[k].receive()
    }

    /// Add a record to the batch; send the batch when full or old.
    fn record(&mut self, rec: Record, now: u64) {
        if self.batch.len == 0 {
            self.batch_started_ns = now;
        }
        self.batch.records[self.batch.len] = rec;
        self.batch.len += 1;
        if self.batch.len == BATCH || now.saturating_sub(self.batch_started_ns) > BATCH_MAX_AGE_NS {
            self.send_batch();
        }
    }

    /// Send the pending batch (never blocking) and store the counters this segment owns.
    fn send_batch(&mut self) {
        self.batch.heading = self.heading.as_ref().map(HeadingTracker::summary);
        if self.batch.len > 0 {
            if self.tx.try_send(self.batch).is_err() {
                self.local.metric_drops += self.batch.len as u64;
            }
            self.batch.len = 0;
        }
        let c = &self.counters;
        let l = &mut self.local;
        for i in self.owns_in.clone() {
            c.stage_in[i].store(l.stage_in[i], Ordering::Relaxed);
        }
        for i in self.owns_out.clone() {
            c.stage_out[i].store(l.stage_out[i], Ordering::Relaxed);
        }
        if self.is_final {
            c.deadline_misses.store(l.misses, Ordering::Relaxed);
            c.repaired.store(l.repaired, Ordering::Relaxed);
            for (c, l) in c.outputs.iter().zip(l.outputs) {
                c.store(l, Ordering::Relaxed);
            }
        }
        // Every segment may drop records: add, do not overwrite.
        c.metric_drops
            .fetch_add(l.metric_drops - l.metric_drops_stored, Ordering::Relaxed);
        l.metric_drops_stored = l.metric_drops;
        if self.head.is_some() {
            let g = &self.guard.counts;
            c.invalid.store(g.invalid, Ordering::Relaxed);
            c.gaps.store(g.gaps, Ordering::Relaxed);
            c.missing.store(g.missing, Ordering::Relaxed);
            c.backwards.store(g.backwards, Ordering::Relaxed);
            c.restarts.store(g.restarts, Ordering::Relaxed);
        }
    }

    /// Connect every output of the segment to its subscribers now rather than at its first
    /// sample (which comes only after the denoiser's lag, when all pipelines of a daemon pay it
    /// in the same round).
    fn connect(&self) -> Result<(), TransportError> {
        if let Some((raw_out, _)) = &self.head {
            raw_out.connect()?;
        }
        self.outs.iter().try_for_each(Output::connect)
    }

    /// [`Stage::prewarm`] of every stage, and the metrics slot the sample will fill.
    fn prewarm(&self) {
        for stage in &self.stages {
            stage.prewarm();
        }
        // A copy is a read: a reference alone would not touch the memory.
        std::hint::black_box(self.batch.records.get(self.batch.len).copied());
    }

    /// When the source is idle: do not let a partial batch wait.
    fn idle(&mut self) {
        if self.batch.len > 0
            && monotonic_ns().saturating_sub(self.batch_started_ns) > BATCH_MAX_AGE_NS
        {
            self.send_batch();
        }
    }

    /// Drain the lagged stages, oldest first, through the rest of the segment.
    fn drain(&mut self) -> Result<(), TransportError> {
        for k in 0..self.stages.len() {
            while let Some(out) = self.stages[k].flush() {
                let mut rec = Record::default();
                if let Some(next) = self.publish(k, &out, &mut rec)? {
                    self.process_from(k + 1, next, &mut rec, monotonic_ns())?;
                }
            }
        }
        self.send_batch();
        Ok(())
    }
}

/// The start line: the services this daemon publishes, with their types, and how to watch them.
pub fn services_line(p: &Pipeline, prefix: &str) -> String {
    // Every stage's output after the ingest, but an external stage's (another process's).
    let gyro: Vec<&str> = p.stages[1..]
        .iter()
        .filter(|s| s.kind.role != Role::External)
        .map(|s| s.output.as_str())
        .collect();
    let last = &p.stages[p.stages.len() - 1].output;
    format!(
        "pipeline {} running under prefix {prefix:?}: publishes {} (RawSample), {} (GyroSample), \
         {} (StatsSnapshot); watch with `driftless tap {last}` or `driftless stats {}`",
        p.name,
        p.stages[0].output,
        gyro.join(", "),
        p.iceoryx2.stats_service,
        p.path.display()
    )
}

fn build_source(p: &Pipeline, transport: &Transport) -> Result<Box<dyn Source>, RunError> {
    let spec = &p.stages[0];
    let err = |message: String| RunError::Stage {
        stage: spec.name.clone(),
        message,
    };
    spec.params
        .source(&p.context(), transport, spec.input.as_deref())
        .map_err(err)
}

/// Run a validated pipeline under `prefix` until stopped; returns the final report.
pub fn run(p: &Pipeline, prefix: &str, opts: &RunOptions) -> Result<Report, RunError> {
    let mut reports = run_group(&[(p, prefix.to_string())], opts)?;
    // One member gives one result.
    reports
        .pop()
        .unwrap_or_else(|| Err(RunError::Group("the pipeline gave no result".into())))
}

/// Run several validated pipelines, each under its prefix, on one hot thread (a vehicle's
/// IMUs: one wake-up serves every pipeline whose sample is due, where separate daemons would
/// each pay their own). Pipelines due together run in the order given. Starting is all or
/// nothing: an error starting any pipeline stops those already started. Once running, a
/// pipeline that fails stops alone (its error is printed at once) and the others go on; its
/// result says why.
pub fn run_group(
    members: &[(&Pipeline, String)],
    opts: &RunOptions,
) -> Result<Vec<Result<Report, RunError>>, RunError> {
    crate::transport::quiet_logging();
    check_group(members)?;
    for (p, prefix) in members {
        let holders = Transport::holders_of(prefix, &node_name(&p.name))?;
        if !holders.is_empty() {
            return Err(RunError::AlreadyRunning {
                pipeline: p.name.clone(),
                prefix: prefix.clone(),
                holders,
            });
        }
    }
    // Starting is all or nothing: stop what did start, then say why.
    let abandon = |group: Vec<Running<'_>>, e: RunError| {
        for r in group {
            let _ = r.finish();
        }
        remove_leftovers(members);
        Err(e)
    };
    let mut group: Vec<Running<'_>> = Vec::with_capacity(members.len());
    for (p, prefix) in members {
        match Running::start(p, prefix, opts.print_summary) {
            Ok(r) => group.push(r),
            Err(e) => return abandon(group, e),
        }
    }
    let notified = match Notified::of(&group) {
        Ok(n) => n,
        Err(e) => return abandon(group, e.into()),
    };
    let stats = group.iter_mut().filter_map(|r| r.stats.take()).collect();
    let reporter = match spawn_reporter(stats) {
        Ok(h) => h,
        Err(e) => {
            let e = RunError::Stage {
                stage: "reporter".into(),
                message: e.to_string(),
            };
            return abandon(group, e);
        }
    };
    // After the reporting thread is spawned, so only the hot thread gets these settings.
    schedule_hot_thread(hot_settings(members));
    if opts.print_summary {
        for r in &group {
            let _ = writeln!(std::io::stderr(), "{}", services_line(r.p, &r.prefix));
        }
    }
    let prewarm = members
        .iter()
        .map(|(p, _)| p.prewarm)
        .max()
        .unwrap_or_default();
    serve(&mut group, opts, prewarm, notified);
    let finished: Vec<Result<(), RunError>> = group.into_iter().map(Running::finish).collect();
    // Every sender is gone now: the reporting thread ends with the final reports.
    let reports = reporter.join();
    remove_leftovers(members);
    let reports = reports.map_err(|_| RunError::Stage {
        stage: "reporter".into(),
        message: "the reporting thread panicked".into(),
    })?;
    Ok(finished
        .into_iter()
        .zip(reports)
        .map(|(f, report)| f.map(|()| report))
        .collect())
}

/// Remove the leftover files of each prefix of the group (when no other node of it is alive).
fn remove_leftovers(members: &[(&Pipeline, String)]) {
    let mut prefixes: Vec<&str> = members.iter().map(|(_, prefix)| prefix.as_str()).collect();
    prefixes.sort_unstable();
    prefixes.dedup();
    for prefix in prefixes {
        remove_prefix_leftovers(prefix);
    }
}

/// What stops a set of pipelines from sharing one daemon: the same pipeline or service twice
/// under one prefix, or different settings for the one hot thread.
pub fn check_group(members: &[(&Pipeline, String)]) -> Result<(), RunError> {
    if members.len() < 2 {
        return Ok(());
    }
    let file = |p: &Pipeline| p.path.display().to_string();
    let names = members
        .iter()
        .map(|(p, prefix)| ((prefix.as_str(), p.name.as_str()), *p));
    if let Some(((prefix, name), a, b)) = clash(names) {
        return Err(RunError::Group(format!(
            "{} and {} are both pipeline {name:?} under prefix {prefix:?}: a pipeline runs once \
             per prefix; rename one (its `name`) or run it under another prefix",
            file(a),
            file(b)
        )));
    }
    let services = members.iter().flat_map(|(p, prefix)| {
        let outputs = p.stages.iter().map(|s| s.output.as_str());
        outputs
            .chain([p.iceoryx2.stats_service.as_str()])
            .map(move |service| ((prefix.as_str(), service), *p))
    });
    if let Some(((prefix, service), a, b)) = clash(services) {
        return Err(RunError::Group(format!(
            "{} and {} both publish {service:?} under prefix {prefix:?}: a service has one \
             publisher; rename it in one file or run one under another prefix",
            file(a),
            file(b)
        )));
    }
    let cpus: Vec<(i64, &Pipeline)> = members
        .iter()
        .filter_map(|(p, _)| Some((p.cpu? as i64, *p)))
        .collect();
    let priorities = members
        .iter()
        .filter_map(|(p, _)| Some((i64::from(p.realtime_priority?), *p)))
        .collect();
    for (what, set) in [("cpu", cpus), ("realtime_priority", priorities)] {
        let Some(&(va, a)) = set.first() else {
            continue;
        };
        if let Some(&(vb, b)) = set.iter().find(|(v, _)| *v != va) {
            return Err(RunError::Group(format!(
                "{} sets {what} = {va} and {} sets {what} = {vb}: one hot thread serves the \
                 group; give the same value, or set it in one file only",
                file(a),
                file(b)
            )));
        }
    }
    Ok(())
}

/// The first key two pipelines share, with both (in the order given).
fn clash<'a, K: PartialEq>(
    keyed: impl IntoIterator<Item = (K, &'a Pipeline)>,
) -> Option<(K, &'a Pipeline, &'a Pipeline)> {
    let mut seen: Vec<(K, &Pipeline)> = Vec::new();
    for (key, p) in keyed {
        if let Some((_, first)) = seen.iter().find(|(k, _)| *k == key) {
            return Some((key, first, p));
        }
        seen.push((key, p));
    }
    None
}

/// The hot thread's CPU and SCHED_FIFO priority: whichever pipeline of the group sets them
/// ([`check_group`] refused different values).
fn hot_settings(members: &[(&Pipeline, String)]) -> (Option<usize>, Option<i32>) {
    (
        members.iter().find_map(|(p, _)| p.cpu),
        members.iter().find_map(|(p, _)| p.realtime_priority),
    )
}

/// Apply the pipeline's scheduling settings to the calling (hot) thread; failures (no
/// permission, no such CPU) are warnings: the pipeline still runs.
fn schedule_hot_thread((cpu, priority): (Option<usize>, Option<i32>)) {
    if let Some(cpu) = cpu {
        // SAFETY: a zeroed cpu_set_t is valid; CPU_SET stays in bounds (cpu < 1024 = CPU_SETSIZE).
        let rc = unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            libc::CPU_SET(cpu, &mut set);
            libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set)
        };
        if rc != 0 {
            let _ = writeln!(
                std::io::stderr(),
                "driftless: warning: cannot pin the hot thread to CPU {cpu}: {}",
                std::io::Error::last_os_error()
            );
        }
    }
    if let Some(priority) = priority {
        let param = libc::sched_param {
            sched_priority: priority,
        };
        // SAFETY: `param` is a valid sched_param; 0 means the calling thread.
        let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
        if rc != 0 {
            let _ = writeln!(
                std::io::stderr(),
                "driftless: warning: cannot set SCHED_FIFO priority {priority}: {}; running with \
                 default scheduling. It needs CAP_SYS_NICE (`setcap cap_sys_nice+ep` on the \
                 driftless binary, or AmbientCapabilities= in a systemd unit) or an rtprio limit \
                 of at least {priority} (LimitRTPRIO=, or rtprio in limits.conf); see README, \
                 \"Users and permissions\"",
                std::io::Error::last_os_error()
            );
        }
    }
}

/// The positions of one segment's stages (`lo..hi`, after the ingest) and what follows it.
#[derive(Debug, Clone, Copy)]
struct SegmentSpan {
    lo: usize,
    hi: usize,
    /// Ends at the publish stage (otherwise it feeds the external stage at `hi`).
    is_final: bool,
}

/// Split the chain at its `external` stages: segment 1 starts after the ingest, each later one
/// after an external stage.
fn segments(p: &Pipeline) -> Vec<SegmentSpan> {
    let mut out = Vec::new();
    let mut lo = 1;
    for (i, spec) in p.stages.iter().enumerate().skip(1) {
        if spec.kind.role == Role::External {
            out.push(SegmentSpan {
                lo,
                hi: i,
                is_final: false,
            });
            lo = i + 1;
        }
    }
    out.push(SegmentSpan {
        lo,
        hi: p.stages.len(),
        is_final: true,
    });
    out
}

/// Build a segment's stages and ports (in the thread that runs it). Returns the chain without
/// its head, the loss counters of its outputs and the sum of its stages' lags.
fn build_segment(
    p: &Pipeline,
    transport: &Transport,
    span: SegmentSpan,
    counters: Arc<Counters>,
    tx: Sender<Batch>,
) -> Result<(Chain, Vec<Arc<AtomicU64>>, usize), RunError> {
    let mut stage_objs = Vec::new();
    let mut outs = Vec::new();
    let mut ins = Vec::new();
    let mut lag = 0usize;
    for i in span.lo..span.hi {
        let spec = &p.stages[i];
        let stage = spec
            .params
            .stage(&p.context())
            .map_err(|message| RunError::Stage {
                stage: spec.name.clone(),
                message,
            })?;
        lag += stage.lag();
        stage_objs.push(stage);
        let feeds_external = !span.is_final && i + 1 == span.hi;
        if feeds_external {
            // The external process may have created the service first.
            outs.push(transport.external_output::<GyroSample>(&spec.output, true)?);
        } else {
            let notify = spec.params.notifies();
            outs.push(transport.output::<GyroSample>(&spec.output, notify)?);
        }
        if i + 1 != span.hi {
            ins.push(transport.input::<GyroSample>(&spec.output)?);
        }
    }
    let lost = outs.iter().map(Output::lost_counter).collect();
    let (first_in, first_out) = if span.lo == 1 {
        (0, 0)
    } else {
        // The external stage before: its "out" is what this segment receives.
        (span.lo, span.lo - 1)
    };
    let end_in = if span.is_final { span.hi } else { span.hi + 1 };
    let chain = Chain {
        head: None,
        guard: Guard::new(
            p.input_units,
            p.axes,
            counters.epoch.load(Ordering::Relaxed) as u32,
        ),
        first: span.lo,
        stages: stage_objs,
        outs,
        ins,
        is_final: span.is_final,
        owns_in: first_in..end_in,
        owns_out: first_out..span.hi,
        counters,
        local: Local::default(),
        batch: Batch::default(),
        batch_started_ns: 0,
        tx,
        deadline_ns: p.deadline.as_nanos() as u64,
        heading: (span.lo == 1 || span.is_final)
            .then(|| p.stages[0].params.truth(&p.context()))
            .flatten()
            .map(|t| HeadingTracker::new(t, p.input_units.to_rad_per_sec(), p.rate_hz, p.axes)),
    };
    Ok((chain, lost, lag))
}

/// Sets a flag when dropped: a segment is finished on every way out of its thread.
struct SetOnDrop(Arc<AtomicBool>);

impl Drop for SetOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

/// What a later segment's thread reports once its ports exist.
type Ready = Result<(Vec<Arc<AtomicU64>>, usize), RunError>;

/// A later segment's thread: it wakes on the event service of the external stage's output,
/// runs its stages on each sample, and after `upstream_done` keeps reading until its input has
/// been quiet for [`EXTERNAL_GRACE`]; then it flushes its own lagged stages.
#[allow(clippy::too_many_arguments)]
fn run_segment(
    p: &Pipeline,
    prefix: &str,
    node: &str,
    qos: Qos,
    span: SegmentSpan,
    counters: Arc<Counters>,
    tx: Sender<Batch>,
    external_lost: Arc<AtomicU64>,
    upstream_done: &AtomicBool,
    stop: &AtomicBool,
    ready: crossbeam_channel::Sender<Ready>,
) -> Result<(), RunError> {
    let ext = &p.stages[span.lo - 1];
    let poll_timeout = ext.params.poll_timeout();
    if ext.kind.role != Role::External {
        return Err(RunError::Stage {
            stage: ext.name.clone(),
            message: "a later segment must follow an external stage".into(),
        });
    };
    let set_up = (|| {
        let transport = Transport::new(prefix, node, qos)?;
        let input = transport.external_input::<GyroSample>(&ext.output)?;
        let waker = transport.waker(&ext.output)?;
        let (chain, lost, lag) = build_segment(p, &transport, span, counters, tx)?;
        chain.connect()?;
        Ok::<_, RunError>((transport, input, waker, chain, lost, lag))
    })();
    let (transport, input, waker, mut chain, lost, lag) = match set_up {
        Ok(v) => v,
        Err(e) => {
            let _ = ready.send(Err(RunError::Stage {
                stage: ext.name.clone(),
                message: e.to_string(),
            }));
            return Ok(());
        }
    };
    let _ = ready.send(Ok((lost, lag)));
    let grace = EXTERNAL_GRACE.as_nanos() as u64;
    let mut next_seq: Option<u64> = None;
    let mut last_rx = monotonic_ns();
    let mut upstream_done_at: Option<u64> = None;
    let mut failure = None;
    'run: loop {
        loop {
            match input.receive() {
                Ok(Some(s)) => {
                    chain.local.stage_out[span.lo - 1] += 1;
                    if let Some(expected) = next_seq {
                        // A sensor's own gap is flagged (and counted as lost) at the ingest.
                        if s.seq > expected && s.flags & FLAG_GAP_BEFORE == 0 {
                            external_lost.fetch_add(s.seq - expected, Ordering::Relaxed);
                        }
                    }
                    next_seq = Some(s.seq.wrapping_add(1));
                    if let Err(e) = chain.after_external(s) {
                        failure = Some(e);
                        break 'run;
                    }
                    last_rx = monotonic_ns();
                }
                Ok(None) => break,
                Err(e) => {
                    failure = Some(e);
                    break 'run;
                }
            }
        }
        let now = monotonic_ns();
        if upstream_done_at.is_none() && upstream_done.load(Ordering::Acquire) {
            upstream_done_at = Some(now);
        }
        if let Some(done) = upstream_done_at {
            if now.saturating_sub(done.max(last_rx)) >= grace {
                break;
            }
        }
        chain.idle();
        // An error here is a signal interrupting the wait (SIGTERM may land on this thread):
        // the flags above decide when to stop, the next round reads the input again.
        let _ = waker.wait(poll_timeout);
    }
    if failure.is_none() {
        if let Err(e) = chain.drain() {
            failure = Some(e);
        }
    }
    chain.send_batch();
    drop(chain);
    drop((input, waker));
    drop(transport);
    match failure {
        Some(e) => {
            // Stop the whole pipeline: the segments before this one end and drain.
            stop.store(true, Ordering::Relaxed);
            Err(e.into())
        }
        None => Ok(()),
    }
}

/// One pipeline of a daemon, started: the hot thread runs its source and first segment; its
/// later segments and its reporter have threads of their own.
struct Running<'a> {
    p: &'a Pipeline,
    prefix: String,
    /// The source and segment 1, until the ingest ends.
    hot: Option<(Box<dyn Source>, Chain)>,
    /// Set by a later segment that failed: this pipeline stops.
    stop: Arc<AtomicBool>,
    /// Per segment: it has finished (segment 1's is set when the ingest ends).
    done: Vec<Arc<AtomicBool>>,
    segment_threads: Vec<std::thread::JoinHandle<Result<(), RunError>>>,
    /// Until the daemon's reporting thread takes it.
    stats: Option<Stats>,
    failure: Option<RunError>,
    transport: Transport,
    /// The source's last answer was a sample (a notified source is asked again at once).
    more: bool,
}

/// What the daemon's reporting thread takes of each pipeline: its reporter, the channel its
/// segments send timings on, and where its stats go (a node of its own per pipeline, by which
/// `driftless list` knows it).
struct Stats {
    reporter: Reporter,
    rx: crossbeam_channel::Receiver<Batch>,
    prefix: String,
    node: String,
    service: String,
    qos: Qos,
}

/// Start the daemon's one reporting thread for every pipeline of the group; it returns their
/// final reports, in order, once every pipeline's senders are gone.
fn spawn_reporter(stats: Vec<Stats>) -> std::io::Result<std::thread::JoinHandle<Vec<Report>>> {
    std::thread::Builder::new()
        .name("driftless-report".into())
        .spawn(move || {
            // The reporters' own nodes: ports are not Send. Stats are best effort.
            let ports: Vec<_> = stats
                .iter()
                .map(|s| {
                    let port = Transport::new(&s.prefix, &s.node, s.qos)
                        .and_then(|t| t.output::<StatsSnapshot>(&s.service, true).map(|o| (t, o)));
                    if let Err(e) = &port {
                        let _ = writeln!(
                            std::io::stderr(),
                            "driftless: warning: no stats service {:?}: {e}",
                            s.service
                        );
                    }
                    port.ok()
                })
                .collect();
            let reporters = stats
                .into_iter()
                .zip(&ports)
                .map(|(s, port)| {
                    let publish: Publish<'_> = Box::new(move |snap| {
                        if let Some((t, out)) = port {
                            let _ = out.send(snap);
                            // Subscribers that died keep their buffers until someone cleans up.
                            t.cleanup_dead_nodes();
                        }
                    });
                    (s.reporter, s.rx, publish)
                })
                .collect();
            let reports = run_all(reporters);
            drop(ports);
            reports
        })
}

impl<'a> Running<'a> {
    /// Build the pipeline's ports and stages, and start its later segments and its reporter.
    fn start(p: &'a Pipeline, prefix: &str, print_summary: bool) -> Result<Self, RunError> {
        let name = node_name(&p.name);
        let qos = Qos {
            buffer_size: p.iceoryx2.buffer_size,
            max_subscribers: p.iceoryx2.max_subscribers,
        };
        let transport = Transport::new(prefix, &name, qos)?;
        let source = build_source(p, &transport)?;
        let raw_service = &p.stages[0].output;
        let raw_out = transport.output::<RawSample>(raw_service, false)?;
        let raw_in = transport.input::<RawSample>(raw_service)?;
        let spans = segments(p);
        let counters = Arc::new(Counters::default());
        // A fresh epoch per start, so a subscriber that outlives a restart can tell the runs apart.
        counters
            .epoch
            .store(u64::from(rand::random::<u32>().max(1)), Ordering::Relaxed);
        let (tx, rx) = bounded::<Batch>(METRICS_CAPACITY);
        let (mut chain, head_lost, mut lag_total) =
            build_segment(p, &transport, spans[0], Arc::clone(&counters), tx.clone())?;
        let mut lost: Vec<Arc<AtomicU64>> = vec![raw_out.lost_counter()];
        lost.extend(head_lost);
        chain.head = Some((raw_out, raw_in));
        chain.connect()?;
        let mut r = Running {
            p,
            prefix: prefix.to_string(),
            hot: Some((source, chain)),
            stop: Arc::default(),
            done: spans.iter().map(|_| Arc::default()).collect(),
            segment_threads: Vec::new(),
            stats: None,
            failure: None,
            transport,
            more: false,
        };

        // Later segments: one thread each, started before the ingest so that their subscribers
        // exist before the first sample.
        let shared = Arc::new(p.clone());
        for (j, span) in spans.iter().copied().enumerate().skip(1) {
            let (ready_tx, ready_rx) = bounded::<Ready>(1);
            let external_lost = Arc::new(AtomicU64::new(0));
            let args = (
                Arc::clone(&shared),
                prefix.to_string(),
                format!("{name}-seg{}", j + 1),
                Arc::clone(&counters),
                tx.clone(),
                Arc::clone(&external_lost),
                Arc::clone(&r.done[j - 1]),
                Arc::clone(&r.done[j]),
                Arc::clone(&r.stop),
            );
            let spawned = std::thread::Builder::new()
                .name(format!("driftless-seg{}", j + 1))
                .spawn(move || {
                    let (p, prefix, node, counters, tx, ext_lost, upstream, mine, stop) = args;
                    let _finished = SetOnDrop(mine);
                    run_segment(
                        &p, &prefix, &node, qos, span, counters, tx, ext_lost, &upstream, &stop,
                        ready_tx,
                    )
                });
            let started = match spawned {
                Ok(h) => {
                    r.segment_threads.push(h);
                    ready_rx.recv().unwrap_or_else(|_| {
                        Err(RunError::Stage {
                            stage: format!("segment {}", j + 1),
                            message: "the segment thread ended before starting".into(),
                        })
                    })
                }
                Err(e) => Err(RunError::Stage {
                    stage: format!("segment {}", j + 1),
                    message: e.to_string(),
                }),
            };
            match started {
                Ok((seg_lost, lag)) => {
                    lost.push(external_lost);
                    lost.extend(seg_lost);
                    lag_total += lag;
                }
                Err(e) => {
                    drop(tx);
                    let _ = r.finish();
                    return Err(e);
                }
            }
        }
        drop(tx);

        let layout = Layout {
            pipeline: p.name.clone(),
            stages: p
                .stages
                .iter()
                .map(|s| (s.name.clone(), s.kind.name.to_string()))
                .collect(),
            deadline: p.deadline,
            algorithmic_delay: Duration::from_secs_f64(lag_total as f64 / p.rate_hz),
            interval: p.report_interval,
            print: print_summary,
        };
        r.stats = Some(Stats {
            reporter: Reporter::new(layout, counters, lost),
            rx,
            prefix: prefix.to_string(),
            node: stats_node_name(&name),
            service: p.iceoryx2.stats_service.clone(),
            qos,
        });
        Ok(r)
    }

    /// When the source's next sample is due, if it paces itself and knows (`Some(None)`: it
    /// does not know, ask it now); `None` once its ingest has ended.
    fn next_due(&self) -> Option<Option<std::time::Instant>> {
        self.hot.as_ref().map(|(source, _)| source.next_due())
    }

    /// What the source is notified on, while the ingest runs ([`Source::waker`]).
    fn waker(&self) -> Option<(&Waker, Duration)> {
        self.hot.as_ref().and_then(|(source, _)| source.waker())
    }

    /// Ask the source once and run what it gives through the chain; returns the ingest time of
    /// a sample.
    fn step(&mut self, stop: &AtomicBool) -> Option<u64> {
        let (source, chain) = self.hot.as_mut()?;
        let poll = source.poll(stop);
        self.more = matches!(poll, Poll::Sample(..));
        match poll {
            Poll::Sample(raw, ingest_ns, late_ns) => match chain.ingest(&raw, ingest_ns, late_ns) {
                Ok(()) => Some(ingest_ns),
                Err(e) => {
                    self.fail(e.into());
                    None
                }
            },
            Poll::Idle => {
                chain.idle();
                None
            }
            Poll::End => {
                self.end_ingest();
                None
            }
        }
    }

    /// A failure while running: this pipeline stops, undrained; in a group the others go on,
    /// so say it now rather than at the end.
    fn fail(&mut self, e: RunError) {
        let _ = writeln!(
            std::io::stderr(),
            "driftless: pipeline {} stopped: {e}",
            self.p.name
        );
        self.failure = Some(e);
        self.end_ingest();
    }

    /// The ingest is over (its end, a stop, a failure): drain the lagged stages unless it
    /// failed, send the last batch, and let the later segments finish.
    fn end_ingest(&mut self) {
        let Some((source, mut chain)) = self.hot.take() else {
            return;
        };
        if self.failure.is_none() {
            if let Err(e) = chain.drain() {
                self.failure = Some(e.into());
            }
        }
        chain.send_batch();
        drop(source);
        drop(chain);
        // The later segments drain what the external stages still relay, then flush.
        self.done[0].store(true, Ordering::Release);
    }

    /// End the ingest if it still runs and wait for the later segments; the first failure.
    fn finish(mut self) -> Result<(), RunError> {
        self.end_ingest();
        let mut failure = self.failure.take();
        for h in std::mem::take(&mut self.segment_threads) {
            let result = h.join().unwrap_or_else(|_| {
                Err(RunError::Stage {
                    stage: "segment".into(),
                    message: "a segment thread panicked".into(),
                })
            });
            if let (Err(e), None) = (result, &failure) {
                failure = Some(e);
            }
        }
        drop(self.stats.take());
        drop(self.transport);
        failure.map_or(Ok(()), Err)
    }
}

/// The sleep of a group whose sources include some that other processes notify
/// ([`Source::waker`]): one set over all their wakers, and the shortest of their timeouts.
struct Notified {
    set: WakeSet,
    timeout: Duration,
}

impl Notified {
    /// `None` when no source of the group is notified (the paced sleep alone serves it).
    fn of(group: &[Running<'_>]) -> Result<Option<Self>, TransportError> {
        let mut notified: Option<Notified> = None;
        for (i, r) in group.iter().enumerate() {
            let Some((waker, timeout)) = r.waker() else {
                continue;
            };
            let n = match &mut notified {
                Some(n) => n,
                None => notified.insert(Notified {
                    set: WakeSet::new()?,
                    timeout,
                }),
            };
            n.set.add(waker, i)?;
            n.timeout = n.timeout.min(timeout);
        }
        Ok(notified)
    }
}

/// The hot thread: sleep until the earliest sample of the group is due or a notified source
/// has news (asking at once any source that does not know when), then run every pipeline whose
/// sample is due or whose source is notified, in order. After the first round the paced
/// sources share one clock (one wake-up serves them all). Ends at a stop, at `--duration` (a
/// sample already taken is always processed) or when every ingest has ended.
fn serve(
    group: &mut [Running<'_>],
    opts: &RunOptions,
    prewarm: Duration,
    mut notified: Option<Notified>,
) {
    let stop = &*opts.stop;
    // The end of --duration on the clock the ingest stamps samples with (no extra clock read
    // per sample).
    let end_ns = opts.duration.map_or(u64::MAX, |d| {
        monotonic_ns().saturating_add(d.as_nanos() as u64)
    });
    let mut first_round = true;
    while !stop.load(Ordering::Relaxed) {
        let mut due: Option<std::time::Instant> = None;
        let mut ask_now = false;
        let mut live = false;
        for r in group.iter_mut() {
            if r.stop.load(Ordering::Relaxed) {
                r.end_ingest();
            }
            match r.next_due() {
                Some(Some(d)) => due = Some(due.map_or(d, |e| e.min(d))),
                // A notified source that has just given a sample may have more.
                Some(None) => ask_now |= r.more || r.waker().is_none(),
                None => continue,
            }
            live = true;
        }
        if !live {
            break;
        }
        if ask_now {
            // No sleep: a source is asked at once.
        } else if let Some(n) = &mut notified {
            let woken = n.set.wait(due, n.timeout, |i| {
                if let Some((waker, _)) = group[i].waker() {
                    // A failed drain leaves the waker readable: the next sleep is short, and
                    // the source is asked anyway.
                    let _ = waker.drain();
                }
            });
            if let Err(e) = woken {
                for r in group.iter_mut().filter(|r| r.waker().is_some()) {
                    let stage = r.p.stages[0].name.clone();
                    r.fail(RunError::Stage {
                        stage,
                        message: e.to_string(),
                    });
                }
            }
        } else if let Some(due) = due {
            // Wake `prewarm` early for the pipelines due next, then sleep to the due time.
            if let Some(early) = (!prewarm.is_zero())
                .then(|| due.checked_sub(prewarm))
                .flatten()
            {
                if crate::stages::sleep_until(early, stop) {
                    for r in group.iter() {
                        if let (Some(Some(d)), Some((_, chain))) = (r.next_due(), &r.hot) {
                            if d <= due {
                                chain.prewarm();
                            }
                        }
                    }
                }
            }
            if !crate::stages::sleep_until(due, stop) {
                break;
            }
        }
        let now = std::time::Instant::now();
        let mut ended = false;
        for r in group.iter_mut() {
            if matches!(r.next_due(), Some(Some(d)) if d > now) {
                continue;
            }
            ended |= r.step(stop).is_some_and(|ingest_ns| ingest_ns >= end_ns);
        }
        // Sources that do not pace themselves may give nothing for a long time.
        if ended || ((ask_now || notified.is_some()) && monotonic_ns() >= end_ns) {
            break;
        }
        if first_round {
            // The first samples met everything cold (code, stage state, shared memory): the
            // clock starts once they are through, so that their cost makes no later sample late.
            first_round = false;
            let clock = crate::stages::PaceClock::now();
            for r in group.iter_mut() {
                if let Some((source, _)) = &mut r.hot {
                    source.share_clock(clock);
                }
            }
        }
    }
}
