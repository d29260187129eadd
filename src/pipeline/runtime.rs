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
//! The hot loop does not allocate: timings go to the reporting thread in fixed-size records over
//! a bounded crossbeam channel (`try_send`; a full channel is counted, never waited on).
//!
//! # Shutdown
//! A stop flag (set by SIGINT/SIGTERM, `--duration`, or the end of a finite source) ends the
//! ingest; the lagged stages are then flushed through the rest of the chain, the reporter
//! writes its final report, all ports and the node are dropped, and the prefix's leftover files
//! are removed when no other node of the prefix is alive.

use std::io::Write as _;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crossbeam_channel::{bounded, Sender};

use crate::metrics::{Batch, Counters, Layout, Record, Report, Reporter, BATCH, MAX_STAGES};
use crate::pipeline::config::{Pipeline, StageKind};
use crate::pipeline::guard::Guard;
use crate::pipeline::stage::{Poll, Source, Stage};
use crate::stages;
use crate::transport::{
    monotonic_ns, remove_prefix_leftovers, GyroSample, Input, Output, Qos, RawSample,
    StatsSnapshot, Transport, TransportError, FLAG_FLUSHED, FLAG_OUTPUT_REPAIRED,
};

/// Capacity of the metrics channel (batches of [`BATCH`] records): 2 minutes at 1 kHz.
const METRICS_CAPACITY: usize = 1 << 12;

/// How a run is started.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// iceoryx2 prefix (the pipeline's, unless overridden).
    pub prefix: String,
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
    #[error("pipeline {pipeline:?} is already running (prefix {prefix:?}); stop it first")]
    AlreadyRunning {
        /// Pipeline name.
        pipeline: String,
        /// iceoryx2 prefix.
        prefix: String,
    },
    /// iceoryx2 set-up or I/O.
    #[error("{0}")]
    Transport(#[from] TransportError),
    /// A stage could not be built.
    #[error("stage {stage:?}: {message}")]
    Stage {
        /// Stage name.
        stage: String,
        /// What is wrong.
        message: String,
    },
}

/// The node name of a pipeline's daemon (one per pipeline and prefix).
pub fn node_name(pipeline: &str) -> String {
    format!("driftless-{pipeline}")
}

/// Counts kept by the hot thread, stored into the shared [`Counters`] at each batch.
#[derive(Debug, Default)]
struct Local {
    stage_in: [u64; MAX_STAGES],
    stage_out: [u64; MAX_STAGES],
    misses: u64,
    repaired: u64,
    metric_drops: u64,
}

/// The hops and stages, owned by the hot thread (iceoryx2 ports are not `Send`).
struct Chain {
    raw_out: Output<RawSample>,
    raw_in: Input<RawSample>,
    guard: Guard,
    stages: Vec<Box<dyn Stage>>,
    outs: Vec<Output<GyroSample>>,
    ins: Vec<Input<GyroSample>>,
    counters: Arc<Counters>,
    local: Local,
    batch: Batch,
    batch_started_ns: u64,
    tx: Sender<Batch>,
    deadline_ns: u64,
}

/// Longest a partial batch waits before it is sent (so slow pipelines report promptly).
const BATCH_MAX_AGE_NS: u64 = 50_000_000;

impl Chain {
    /// The ingest hop, the guard, and the chain after it, for one raw sample.
    fn ingest(&mut self, raw: &RawSample, ingest_ns: u64) -> Result<(), TransportError> {
        self.local.stage_in[0] += 1;
        let mut rec = Record::default();
        self.raw_out.send(raw)?;
        self.local.stage_out[0] += 1;
        let Some(raw) = self.raw_in.receive()? else {
            return Ok(());
        };
        let s = self.guard.admit(&raw, ingest_ns);
        let t0 = monotonic_ns();
        rec.stage_ns[0] = (t0.saturating_sub(ingest_ns)).min(u64::from(u32::MAX)) as u32;
        rec.stages_run = 1;
        let end = self.process_from(0, s, &mut rec, t0)?;
        self.record(rec, end);
        Ok(())
    }

    /// Run stage `k` (index into `stages`, chain position k + 1) and everything after it;
    /// `now` is a fresh timestamp. Returns the last timestamp taken.
    fn process_from(
        &mut self,
        mut k: usize,
        mut input: GyroSample,
        rec: &mut Record,
        mut now: u64,
    ) -> Result<u64, TransportError> {
        while k < self.stages.len() {
            let pos = k + 1;
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

    /// Publish stage `k`'s output; returns what the next stage receives (None after the last).
    fn publish(
        &mut self,
        k: usize,
        out: &GyroSample,
        rec: &mut Record,
    ) -> Result<Option<GyroSample>, TransportError> {
        self.local.stage_out[k + 1] += 1;
        self.outs[k].send(out)?;
        if k + 1 == self.stages.len() {
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
            self.outs[k].notify();
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

    /// Send the pending batch (never blocking) and store the counters.
    fn send_batch(&mut self) {
        if self.batch.len > 0 {
            if self.tx.try_send(self.batch).is_err() {
                self.local.metric_drops += self.batch.len as u64;
            }
            self.batch.len = 0;
        }
        let c = &self.counters;
        let l = &self.local;
        for i in 0..MAX_STAGES {
            c.stage_in[i].store(l.stage_in[i], Ordering::Relaxed);
            c.stage_out[i].store(l.stage_out[i], Ordering::Relaxed);
        }
        c.deadline_misses.store(l.misses, Ordering::Relaxed);
        c.repaired.store(l.repaired, Ordering::Relaxed);
        c.metric_drops.store(l.metric_drops, Ordering::Relaxed);
        let g = &self.guard.counts;
        c.invalid.store(g.invalid, Ordering::Relaxed);
        c.gaps.store(g.gaps, Ordering::Relaxed);
        c.missing.store(g.missing, Ordering::Relaxed);
        c.backwards.store(g.backwards, Ordering::Relaxed);
    }

    /// When the source is idle: do not let a partial batch wait.
    fn idle(&mut self) {
        if self.batch.len > 0
            && monotonic_ns().saturating_sub(self.batch_started_ns) > BATCH_MAX_AGE_NS
        {
            self.send_batch();
        }
    }

    /// Drain the lagged stages, oldest first, through the rest of the chain.
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

fn build_source(p: &Pipeline, transport: &Transport) -> Result<Box<dyn Source>, RunError> {
    let spec = &p.stages[0];
    let err = |message: String| RunError::Stage {
        stage: spec.name.clone(),
        message,
    };
    match &spec.kind {
        StageKind::IngestCsv(csv) => Ok(Box::new(stages::ingest_csv::CsvReplay::new(
            csv.clone(),
            p.rate_hz,
        ))),
        StageKind::IngestIceoryx2 { poll_timeout } => {
            let input = spec
                .input
                .as_deref()
                .ok_or_else(|| err("ingest.iceoryx2 needs an input service".into()))?;
            Ok(Box::new(stages::ingest_iceoryx2::ExternalRaw::new(
                transport,
                input,
                *poll_timeout,
            )?))
        }
        StageKind::IngestSim(sim) => Ok(Box::new(
            stages::ingest_sim::SimSource::new(sim, p.rate_hz, p.axes).map_err(err)?,
        )),
        other => Err(err(format!("{} cannot start a chain", other.name()))),
    }
}

/// Run a validated pipeline until stopped; returns the final report.
pub fn run(p: &Pipeline, opts: &RunOptions) -> Result<Report, RunError> {
    crate::transport::quiet_logging();
    let name = node_name(&p.name);
    if Transport::live_nodes_named(&opts.prefix, &name)? > 0 {
        return Err(RunError::AlreadyRunning {
            pipeline: p.name.clone(),
            prefix: opts.prefix.clone(),
        });
    }
    let result = run_inner(p, opts, &name);
    remove_prefix_leftovers(&opts.prefix);
    result
}

/// Apply the pipeline's scheduling settings to the calling (hot) thread; failures (no
/// permission, no such CPU) are warnings: the pipeline still runs.
fn schedule_hot_thread(p: &Pipeline) {
    if let Some(cpu) = p.cpu {
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
    if let Some(priority) = p.realtime_priority {
        let param = libc::sched_param {
            sched_priority: priority,
        };
        // SAFETY: `param` is a valid sched_param; 0 means the calling thread.
        let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
        if rc != 0 {
            let _ = writeln!(
                std::io::stderr(),
                "driftless: warning: cannot set SCHED_FIFO priority {priority}: {} (needs CAP_SYS_NICE or an rtprio limit)",
                std::io::Error::last_os_error()
            );
        }
    }
}

fn run_inner(p: &Pipeline, opts: &RunOptions, name: &str) -> Result<Report, RunError> {
    let qos = Qos {
        buffer_size: p.iceoryx2.buffer_size,
        max_subscribers: p.iceoryx2.max_subscribers,
    };
    let transport = Transport::new(&opts.prefix, name, qos)?;
    let mut source = build_source(p, &transport)?;
    let raw_service = &p.stages[0].output;
    let raw_out = transport.output::<RawSample>(raw_service, false)?;
    let raw_in = transport.input::<RawSample>(raw_service)?;
    let mut stage_objs = Vec::new();
    let mut outs = Vec::new();
    let mut ins = Vec::new();
    let mut lag_total = 0usize;
    let last = p.stages.len() - 1;
    for (i, spec) in p.stages.iter().enumerate().skip(1) {
        let stage = stages::build(spec, p).map_err(|message| RunError::Stage {
            stage: spec.name.clone(),
            message,
        })?;
        lag_total += stage.lag();
        stage_objs.push(stage);
        let notify = matches!(spec.kind, StageKind::Publish { notify: true });
        outs.push(transport.output::<GyroSample>(&spec.output, notify)?);
        if i != last {
            ins.push(transport.input::<GyroSample>(&spec.output)?);
        }
    }
    let mut lost: Vec<Arc<AtomicU64>> = vec![raw_out.lost_counter()];
    lost.extend(outs.iter().map(Output::lost_counter));

    let counters = Arc::new(Counters::default());
    let (tx, rx) = bounded::<Batch>(METRICS_CAPACITY);
    let layout = Layout {
        pipeline: p.name.clone(),
        stages: p
            .stages
            .iter()
            .map(|s| (s.name.clone(), s.kind.name().to_string()))
            .collect(),
        deadline: p.deadline,
        algorithmic_delay: Duration::from_secs_f64(lag_total as f64 / p.rate_hz),
        interval: p.report_interval,
        print: opts.print_summary,
    };
    let reporter = Reporter::new(layout, Arc::clone(&counters), lost);
    let stats_prefix = opts.prefix.clone();
    let stats_node = format!("{name}-stats");
    let stats_service = p.iceoryx2.stats_service.clone();
    let reporter_thread = std::thread::Builder::new()
        .name("driftless-report".into())
        .spawn(move || {
            // The reporter's own node: ports are not Send. Stats are best effort.
            let stats = Transport::new(&stats_prefix, &stats_node, qos).and_then(|t| {
                t.output::<StatsSnapshot>(&stats_service, true)
                    .map(|o| (t, o))
            });
            if let Err(e) = &stats {
                let _ = writeln!(
                    std::io::stderr(),
                    "driftless: warning: no stats service: {e}"
                );
            }
            let report = reporter.run(rx, |snap| {
                if let Ok((t, out)) = &stats {
                    let _ = out.send(snap);
                    // Subscribers that died keep their buffers until someone cleans up.
                    t.cleanup_dead_nodes();
                }
            });
            drop(stats);
            report
        })
        .map_err(|e| RunError::Stage {
            stage: "reporter".into(),
            message: e.to_string(),
        })?;

    let mut chain = Chain {
        raw_out,
        raw_in,
        guard: Guard::new(p.input_units, p.axes),
        stages: stage_objs,
        outs,
        ins,
        counters,
        local: Local::default(),
        batch: Batch::default(),
        batch_started_ns: 0,
        tx,
        deadline_ns: p.deadline.as_nanos() as u64,
    };
    // After the reporter thread is spawned, so only the hot thread gets these settings.
    schedule_hot_thread(p);
    let stop = &opts.stop;
    // The end of --duration on the clock the ingest stamps samples with (no extra clock read
    // per sample); a sample already taken from the source is always processed.
    let end_ns = opts.duration.map_or(u64::MAX, |d| {
        monotonic_ns().saturating_add(d.as_nanos() as u64)
    });
    let mut failure = None;
    while !stop.load(Ordering::Relaxed) {
        match source.poll(stop) {
            Poll::Sample(raw, ingest_ns) => {
                if let Err(e) = chain.ingest(&raw, ingest_ns) {
                    failure = Some(e);
                    break;
                }
                if ingest_ns >= end_ns {
                    break;
                }
            }
            Poll::Idle => {
                chain.idle();
                if monotonic_ns() >= end_ns {
                    break;
                }
            }
            Poll::End => break,
        }
    }
    if failure.is_none() {
        if let Err(e) = chain.drain() {
            failure = Some(e);
        }
    }
    chain.send_batch();
    drop(source);
    drop(chain);
    let report = reporter_thread.join().map_err(|_| RunError::Stage {
        stage: "reporter".into(),
        message: "the reporting thread panicked".into(),
    })?;
    drop(transport);
    match failure {
        Some(e) => Err(e.into()),
        None => Ok(report),
    }
}
