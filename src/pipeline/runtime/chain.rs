//! One chain's stages run in-thread: the hop from stage to stage, the batches of timings for
//! the reporter, and the segments a chain splits into at an external stage (each on its own
//! thread, sleeping on the external stage's output).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crossbeam_channel::Sender;

use super::run::RunError;
use crate::clock::thread_cpu_ns;
use crate::metrics::{
    miss_explained, Batch, Counters, HeadingTracker, Outputs, Record, BATCH, MAX_STAGES,
};
use crate::pipeline::config::Pipeline;
use crate::pipeline::guard::Guard;
use crate::stages::contract::{Role, SideInput, SideValue, Source, Stage};
use crate::stages::WarmStart;
use crate::transport::{monotonic_ns, Input, Losses, Output, Qos, Transport, TransportError};
use crate::wire::{
    GyroSample, RawSample, StopSignal, FLAG_FLUSHED, FLAG_GAP_BEFORE, FLAG_OUTPUT_REPAIRED,
};

/// A side input's subscriber ([`crate::stages::Params::side_inputs`]).
pub(super) enum SidePort {
    Stop(Input<StopSignal>),
}

impl SidePort {
    fn open(transport: &Transport, name: &str, kind: SideInput) -> Result<Self, TransportError> {
        Ok(match kind {
            SideInput::Stop { .. } => SidePort::Stop(transport.input::<StopSignal>(name)?),
        })
    }

    /// The newest value waiting, if any (the older ones are read and dropped: a side input
    /// is a state, not a stream).
    fn newest(&self) -> Result<Option<SideValue>, TransportError> {
        match self {
            SidePort::Stop(input) => {
                let mut newest = None;
                while let Some(v) = input.receive()? {
                    newest = Some(v);
                }
                Ok(newest.map(SideValue::Stop))
            }
        }
    }
}

/// Counts kept by a segment's thread, stored into the shared [`Counters`] at each batch.
#[derive(Debug, Default)]
pub(super) struct Local {
    pub(super) stage_in: [u64; MAX_STAGES],
    pub(super) stage_out: [u64; MAX_STAGES],
    pub(super) misses: u64,
    /// Misses the kernel explains ([`Record::off_cpu_ns`]).
    pub(super) misses_explained: u64,
    pub(super) repaired: u64,
    /// Published outputs carrying each of [`Outputs::FLAGS`].
    pub(super) outputs: [u64; 4],
    pub(super) metric_drops: u64,
    pub(super) metric_drops_stored: u64,
}

/// The hops and stages of one segment, owned by its thread (iceoryx2 ports are not `Send`).
///
/// Segment 1 (`head` set) starts at the ingest; a later segment starts at the stage after an
/// `external` stage. A segment ends at the publish stage (`is_final`) or at the stage feeding
/// an `external` stage.
pub(super) struct Chain {
    /// The ingest hop (segment 1 only).
    pub(super) head: Option<Output<RawSample>>,
    /// Where the source's logged motion goes ([`crate::stages::Params::motion_output`]).
    pub(super) motion_out: Option<Output<StopSignal>>,
    pub(super) guard: Guard,
    /// Chain position of `stages[0]`.
    pub(super) first: usize,
    pub(super) stages: Vec<Box<dyn Stage>>,
    /// Per stage, its side inputs' subscribers, by slot.
    pub(super) sides: Vec<Vec<SidePort>>,
    pub(super) outs: Vec<Output<GyroSample>>,
    pub(super) is_final: bool,
    /// Chain positions whose `stage_in` / `stage_out` counts this segment owns.
    pub(super) owns_in: std::ops::Range<usize>,
    pub(super) owns_out: std::ops::Range<usize>,
    pub(super) counters: Arc<Counters>,
    pub(super) local: Local,
    pub(super) batch: Batch,
    pub(super) batch_started_ns: u64,
    pub(super) tx: Sender<Batch>,
    pub(super) deadline_ns: u64,
    /// Heading error against the truth (a simulated ingest): raw in segment 1, published
    /// rates in the final segment.
    pub(super) heading: Option<HeadingTracker>,
}

/// Longest a partial batch waits before it is sent (so slow pipelines report promptly).
pub(super) const BATCH_MAX_AGE_NS: u64 = 50_000_000;

/// How long a later segment keeps reading its input once the segment before it has finished
/// and the input has gone quiet (the external process relays what was drained upstream).
pub const EXTERNAL_GRACE: Duration = Duration::from_millis(200);

impl Chain {
    /// The ingest hop, the guard, and the chain after it, for one raw sample.
    pub(super) fn ingest(
        &mut self,
        raw: &RawSample,
        ingest_ns: u64,
        late_ns: Option<u64>,
    ) -> Result<(), TransportError> {
        let Some(raw_out) = &self.head else {
            return Ok(());
        };
        let mut rec = Record {
            late_ns: late_ns.map(|ns| ns.min(u64::from(u32::MAX)) as u32),
            ..Record::default()
        };
        let raw = self.guard.stamp(raw);
        raw_out.send(&raw)?;
        self.local.stage_in[0] += 1;
        self.local.stage_out[0] += 1;
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

    /// Publish a motion message the source logged beside its next sample.
    pub(super) fn logged_motion(&self, m: &StopSignal) -> Result<(), TransportError> {
        if let Some(out) = &self.motion_out {
            out.send(m)?;
        }
        Ok(())
    }

    /// A later segment: one sample from the external stage before it.
    pub(super) fn after_external(&mut self, s: GyroSample) -> Result<(), TransportError> {
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
    pub(super) fn process_from(
        &mut self,
        mut k: usize,
        mut input: GyroSample,
        rec: &mut Record,
        mut now: u64,
    ) -> Result<u64, TransportError> {
        while k < self.stages.len() {
            let pos = self.first + k;
            self.local.stage_in[pos] += 1;
            for (slot, port) in self.sides[k].iter().enumerate() {
                if let Some(v) = port.newest()? {
                    self.stages[k].side(slot, &v);
                }
            }
            // A stage's time is its compute and the publish of its output (as the ingest's is):
            // one clock read per stage, the one taken when its output has left.
            let (next, t1) = match self.stages[k].process(&input) {
                Some(out) => self.publish(k, &out, rec)?,
                None => (None, monotonic_ns()),
            };
            rec.stage_ns[pos] = (t1.saturating_sub(now)).min(u64::from(u32::MAX)) as u32;
            rec.stages_run = (pos + 1) as u8;
            now = t1;
            match next {
                Some(next) => input = next,
                None => return Ok(now),
            }
            k += 1;
        }
        Ok(now)
    }

    /// Publish stage `k`'s output; returns what the next stage takes (None after the
    /// segment's last stage) and the time it was sent.
    pub(super) fn publish(
        &mut self,
        k: usize,
        out: &GyroSample,
        rec: &mut Record,
    ) -> Result<(Option<GyroSample>, u64), TransportError> {
        let pos = self.first + k;
        self.local.stage_out[pos] += 1;
        self.outs[k].send(out)?;
        let sent = monotonic_ns();
        if k + 1 == self.stages.len() {
            if self.is_final {
                // Published: the end-to-end clock stops before readers are woken.
                if out.flags & FLAG_FLUSHED == 0 {
                    let e2e = sent.saturating_sub(out.ingest_ns).max(1);
                    rec.e2e_ns = e2e;
                    if e2e > self.deadline_ns {
                        self.local.misses += 1;
                        // Off the CPU: the wall time since ingest less what this thread ran
                        // since the source last read its CPU clock (at this ingest, or a few
                        // samples before it: then a lower bound), on this thread.
                        // A later segment's sample crossed other threads: not measured.
                        let off = self
                            .head
                            .is_some()
                            .then(crate::clock::cpu_at_ingest)
                            .flatten()
                            .map(|cpu| e2e.saturating_sub(thread_cpu_ns().saturating_sub(cpu)));
                        rec.off_cpu_ns = off.map(|ns| ns.min(u64::from(u32::MAX)) as u32);
                        if miss_explained(e2e, off, self.deadline_ns) {
                            self.local.misses_explained += 1;
                        }
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
            return Ok((None, sent));
        }
        // The next stage takes the value just published, not a copy back out of shared
        // memory: the same bits, without a receive on the hot path.
        Ok((Some(*out), sent))
    }

    /// Add a record to the batch; send the batch when full or old.
    pub(super) fn record(&mut self, rec: Record, now: u64) {
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
    pub(super) fn send_batch(&mut self) {
        self.batch.heading = self.heading.as_ref().map(HeadingTracker::summary);
        self.batch.odometry = self.stages.iter().find_map(|s| s.odometry());
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
            c.misses_explained
                .store(l.misses_explained, Ordering::Relaxed);
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
            c.stamp_faults.store(g.stamp_faults, Ordering::Relaxed);
            c.sensors_invalid
                .store(g.sensors_invalid, Ordering::Relaxed);
            c.restarts.store(g.restarts, Ordering::Relaxed);
        }
    }

    /// Connect every output of the segment to its subscribers now rather than at its first
    /// sample (which comes only after the denoiser's lag, when all pipelines of a daemon pay it
    /// in the same round).
    pub(super) fn connect(&self) -> Result<(), TransportError> {
        if let Some(raw_out) = &self.head {
            raw_out.connect()?;
        }
        self.outs.iter().try_for_each(Output::connect)
    }

    /// [`Stage::prewarm`] of every stage, and the metrics slot the sample will fill.
    pub(super) fn prewarm(&mut self) {
        for stage in &mut self.stages {
            stage.prewarm();
        }
        // A copy is a read: a reference alone would not touch the memory.
        std::hint::black_box(self.batch.records.get(self.batch.len).copied());
    }

    /// When the source is idle: do not let a partial batch wait.
    pub(super) fn idle(&mut self) {
        if self.batch.len > 0
            && monotonic_ns().saturating_sub(self.batch_started_ns) > BATCH_MAX_AGE_NS
        {
            self.send_batch();
        }
    }

    /// How the stages that keep state across runs started ([`Stage::warm_start`]), by stage
    /// name.
    pub(super) fn warm_starts(&self, p: &crate::pipeline::Pipeline) -> Vec<(String, WarmStart)> {
        let name = |k: usize| p.stages[self.first + k].name.clone();
        self.stages
            .iter()
            .enumerate()
            .filter_map(|(k, stage)| Some((name(k), stage.warm_start()?)))
            .collect()
    }

    /// What the stages learnt ([`Stage::learnt`]), each line after its stage's name.
    pub(super) fn learnt(&self, p: &crate::pipeline::Pipeline) -> Vec<String> {
        let mut out = Vec::new();
        for (k, stage) in self.stages.iter().enumerate() {
            let name = &p.stages[self.first + k].name;
            out.extend(stage.learnt().into_iter().map(|l| format!("{name}: {l}")));
        }
        out
    }

    /// Drain the lagged stages, oldest first, through the rest of the segment.
    pub(super) fn drain(&mut self) -> Result<(), TransportError> {
        for k in 0..self.stages.len() {
            while let Some(out) = self.stages[k].flush() {
                let mut rec = Record::default();
                if let (Some(next), sent) = self.publish(k, &out, &mut rec)? {
                    self.process_from(k + 1, next, &mut rec, sent)?;
                }
            }
        }
        self.send_batch();
        Ok(())
    }
}

/// The positions of one segment's stages (`lo..hi`, after the ingest) and what follows it.
#[derive(Debug, Clone, Copy)]
pub(super) struct SegmentSpan {
    pub(super) lo: usize,
    pub(super) hi: usize,
    /// Ends at the publish stage (otherwise it feeds the external stage at `hi`).
    pub(super) is_final: bool,
}

/// Split the chain at its `external` stages: segment 1 starts after the ingest, each later one
/// after an external stage.
pub(super) fn segments(p: &Pipeline) -> Vec<SegmentSpan> {
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
pub(super) fn build_segment(
    p: &Pipeline,
    transport: &Transport,
    span: SegmentSpan,
    counters: Arc<Counters>,
    tx: Sender<Batch>,
) -> Result<(Chain, Vec<Arc<Losses>>, usize), RunError> {
    let mut stage_objs = Vec::new();
    let mut sides = Vec::new();
    let mut outs = Vec::new();
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
        sides.push(
            spec.params
                .side_inputs()
                .iter()
                .map(|(name, kind)| SidePort::open(transport, name, *kind))
                .collect::<Result<Vec<_>, _>>()?,
        );
        let feeds_external = !span.is_final && i + 1 == span.hi;
        if feeds_external {
            // The external process may have created the service first.
            outs.push(transport.external_output::<GyroSample>(&spec.output, true)?);
        } else {
            let notify = spec.params.notifies();
            outs.push(transport.output::<GyroSample>(&spec.output, notify)?);
        }
    }
    let lost = outs.iter().map(Output::losses).collect();
    let (first_in, first_out) = if span.lo == 1 {
        (0, 0)
    } else {
        // The external stage before: its "out" is what this segment receives.
        (span.lo, span.lo - 1)
    };
    let end_in = if span.is_final { span.hi } else { span.hi + 1 };
    let chain = Chain {
        head: None,
        motion_out: None,
        guard: Guard::new(
            p.input_units,
            p.accel_units,
            p.axes,
            counters.epoch.load(Ordering::Relaxed) as u32,
        ),
        first: span.lo,
        stages: stage_objs,
        sides,
        outs,
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
            .map(|t| HeadingTracker::new(t, p.input_units.to_rad_per_s(), p.rate_hz, p.axes)),
    };
    Ok((chain, lost, lag))
}

/// Sets a flag when dropped: a segment is finished on every way out of its thread.
pub(super) struct SetOnDrop(pub(super) Arc<AtomicBool>);

impl Drop for SetOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

/// What a later segment's thread reports once its ports exist: its outputs' loss counters,
/// its stages' lags and how its stages started ([`Chain::warm_starts`]).
pub(super) type Ready = Result<(Vec<Arc<Losses>>, usize, Vec<(String, WarmStart)>), RunError>;

/// A later segment's thread: it wakes on the event service of the external stage's output,
/// runs its stages on each sample, and after `upstream_done` keeps reading until its input has
/// been quiet for [`EXTERNAL_GRACE`]; then it flushes its own lagged stages.
#[allow(clippy::too_many_arguments)]
pub(super) fn run_segment(
    p: &Pipeline,
    prefix: &str,
    node: &str,
    qos: Qos,
    span: SegmentSpan,
    counters: Arc<Counters>,
    tx: Sender<Batch>,
    external_lost: Arc<Losses>,
    upstream_done: &AtomicBool,
    stop: &AtomicBool,
    ready: crossbeam_channel::Sender<Ready>,
) -> Result<Vec<String>, RunError> {
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
            return Ok(Vec::new());
        }
    };
    let _ = ready.send(Ok((lost, lag, chain.warm_starts(p))));
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
                            external_lost
                                .lost
                                .fetch_add(s.seq - expected, Ordering::Relaxed);
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
    let learnt = chain.learnt(p);
    drop(chain);
    drop((input, waker));
    drop(transport);
    match failure {
        Some(e) => {
            // Stop the whole pipeline: the segments before this one end and drain.
            stop.store(true, Ordering::Relaxed);
            Err(e.into())
        }
        None => Ok(learnt),
    }
}

/// The pipeline's ingest, built as a [`Source`] on the hot thread's `transport`.
pub(super) fn build_source(
    p: &Pipeline,
    transport: &Transport,
) -> Result<Box<dyn Source>, RunError> {
    let spec = &p.stages[0];
    let err = |message: String| RunError::Stage {
        stage: spec.name.clone(),
        message,
    };
    spec.params
        .source(&p.context(), transport, spec.input.as_deref())
        .map_err(err)
}
