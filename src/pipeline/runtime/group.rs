//! The hot thread: every pipeline of the daemon served on one thread (waking on paced due
//! times and drivers' notifications, a failure stopping its own pipeline), and the checks that
//! let a set of pipelines share it.

use std::io::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crossbeam_channel::bounded;

use super::chain::build_source;
use super::chain::{build_segment, run_segment, segments, Chain, Ready, SetOnDrop};
use super::run::{node_name, stats_node_name, RunError, RunOptions};
use crate::metrics::{run_all, Batch, Counters, Layout, Publish, Report, Reporter};
use crate::pipeline::config::Pipeline;
use crate::stages::contract::{Poll, Source};
use crate::stages::WarmStart;
use crate::transport::{monotonic_ns, Losses, Qos, Transport, TransportError, WakeSet, Waker};
use crate::wire::{RawSample, StatsSnapshot, StopSignal};

/// Capacity of the metrics channel (batches of [`BATCH`] records): 2 minutes at 1 kHz.
const METRICS_CAPACITY: usize = 1 << 12;

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
pub(super) fn clash<'a, K: PartialEq>(
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
pub(super) fn hot_settings(members: &[(&Pipeline, String)]) -> (Option<usize>, Option<i32>) {
    (
        members.iter().find_map(|(p, _)| p.cpu),
        members.iter().find_map(|(p, _)| p.realtime_priority),
    )
}

/// Apply the pipeline's scheduling settings to the calling (hot) thread; failures (no
/// permission, no such CPU) are warnings: the pipeline still runs.
pub(super) fn schedule_hot_thread((cpu, priority): (Option<usize>, Option<i32>)) {
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
                 of at least {priority} (LimitRTPRIO=, or rtprio in limits.conf); see \
                 docs/operations.md, \"Real-time scheduling without root\"",
                std::io::Error::last_os_error()
            );
        }
    }
}

/// later segments and its reporter have threads of their own.
pub(super) struct Running<'a> {
    pub(super) p: &'a Pipeline,
    pub(super) prefix: String,
    /// The source and segment 1, until the ingest ends.
    pub(super) hot: Option<(Box<dyn Source>, Chain)>,
    /// Set by a later segment that failed: this pipeline stops.
    pub(super) stop: Arc<AtomicBool>,
    /// Per segment: it has finished (segment 1's is set when the ingest ends).
    pub(super) done: Vec<Arc<AtomicBool>>,
    pub(super) segment_threads: Vec<std::thread::JoinHandle<Result<Vec<String>, RunError>>>,
    /// What the stages learnt ([`crate::stages::Stage::learnt`]), once their segments ended.
    pub(super) learnt: Vec<String>,
    /// How the stages that keep state across runs started, by stage name, in chain order
    /// ([`crate::stages::Stage::warm_start`]; `predict.bias` with or without a
    /// `state_file`): known once every segment is built, before the first sample.
    pub(super) warm_starts: Vec<(String, WarmStart)>,
    /// Until the daemon's reporting thread takes it.
    pub(super) stats: Option<Stats>,
    pub(super) failure: Option<RunError>,
    pub(super) transport: Transport,
    /// The source's last answer was a sample (a notified source is asked again at once).
    pub(super) more: bool,
}

/// What the daemon's reporting thread takes of each pipeline: its reporter, the channel its
/// segments send timings on, and where its stats go (a node of its own per pipeline, by which
/// `driftless list` knows it).
pub(super) struct Stats {
    pub(super) reporter: Reporter,
    pub(super) rx: crossbeam_channel::Receiver<Batch>,
    pub(super) prefix: String,
    pub(super) node: String,
    pub(super) service: String,
    pub(super) qos: Qos,
}

/// Start the daemon's one reporting thread for every pipeline of the group; it returns their
/// final reports, in order, once every pipeline's senders are gone.
pub(super) fn spawn_reporter(
    stats: Vec<Stats>,
) -> std::io::Result<std::thread::JoinHandle<Vec<Report>>> {
    std::thread::Builder::new()
        .name("driftless-report".into())
        .spawn(move || {
            // The reporters' own nodes: ports are not Send. Stats are best effort.
            let ports: Vec<_> = stats
                .iter()
                .map(|s| {
                    let port = Transport::new(&s.prefix, &s.node, s.qos)
                        .and_then(|t| t.output::<StatsSnapshot>(&s.service, true).map(|o| (t, o)));
                    match &port {
                        // Whole now, as the pipelines' were at start (or counted).
                        Ok((t, _)) => t.reserve_shared_memory_or_count(),
                        Err(e) => {
                            let _ = writeln!(
                                std::io::stderr(),
                                "driftless: warning: no stats service {:?}: {e}",
                                s.service
                            );
                        }
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
                            // New subscribers' connections, whole or counted.
                            t.reserve_shared_memory_or_count();
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
    pub(super) fn start(
        p: &'a Pipeline,
        prefix: &str,
        print_summary: bool,
    ) -> Result<Self, RunError> {
        let name = node_name(&p.name);
        let qos = p.iceoryx2.qos();
        let transport = Transport::new(prefix, &name, qos)?;
        let source = build_source(p, &transport)?;
        let raw_service = &p.stages[0].output;
        let raw_out = transport.output::<RawSample>(raw_service, false)?;
        let spans = segments(p);
        let counters = Arc::new(Counters::default());
        // A fresh epoch per start, so a subscriber that outlives a restart can tell the runs apart.
        counters
            .epoch
            .store(u64::from(rand::random::<u32>().max(1)), Ordering::Relaxed);
        let (tx, rx) = bounded::<Batch>(METRICS_CAPACITY);
        let (mut chain, head_lost, mut lag_total) =
            build_segment(p, &transport, spans[0], Arc::clone(&counters), tx.clone())?;
        let warm_starts = chain.warm_starts(p);
        let mut lost: Vec<Arc<Losses>> = vec![raw_out.losses()];
        lost.extend(head_lost);
        chain.head = Some(raw_out);
        chain.motion_out = match p.stages[0].params.motion_output() {
            Some(service) => Some(transport.output::<StopSignal>(service, false)?),
            None => None,
        };
        chain.connect()?;
        let mut r = Running {
            p,
            prefix: prefix.to_string(),
            hot: Some((source, chain)),
            stop: Arc::default(),
            done: spans.iter().map(|_| Arc::default()).collect(),
            segment_threads: Vec::new(),
            learnt: Vec::new(),
            warm_starts,
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
            let external_lost = Arc::<Losses>::default();
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
                Ok((seg_lost, lag, warm)) => {
                    lost.push(external_lost);
                    lost.extend(seg_lost);
                    lag_total += lag;
                    r.warm_starts.extend(warm);
                }
                Err(e) => {
                    drop(tx);
                    let _ = r.finish();
                    return Err(e);
                }
            }
        }
        drop(tx);

        let layout = layout(p, &r.warm_starts, lag_total, print_summary);
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
    pub(super) fn next_due(&self) -> Option<Option<std::time::Instant>> {
        self.hot.as_ref().map(|(source, _)| source.next_due())
    }

    /// What the source is notified on, while the ingest runs ([`Source::waker`]).
    pub(super) fn waker(&self) -> Option<(&Waker, Duration)> {
        self.hot.as_ref().and_then(|(source, _)| source.waker())
    }

    /// Ask the source once and run what it gives through the chain; returns when a sample was
    /// due (a paced source's, on its clock) or else taken, in monotonic ns.
    pub(super) fn step(&mut self, stop: &AtomicBool) -> Option<u64> {
        let (source, chain) = self.hot.as_mut()?;
        let poll = source.poll(stop);
        self.more = matches!(poll, Poll::Sample(..));
        match poll {
            Poll::Sample(raw, ingest_ns, late_ns) => match logged_motion(source.as_mut(), chain)
                .and_then(|()| chain.ingest(&raw, ingest_ns, late_ns))
            {
                Ok(()) => Some(ingest_ns.saturating_sub(late_ns.unwrap_or(0))),
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
    pub(super) fn fail(&mut self, e: RunError) {
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
    pub(super) fn end_ingest(&mut self) {
        let Some((source, mut chain)) = self.hot.take() else {
            return;
        };
        if self.failure.is_none() {
            if let Err(e) = chain.drain() {
                self.failure = Some(e.into());
            }
        }
        chain.send_batch();
        self.learnt.extend(chain.learnt(self.p));
        drop(source);
        drop(chain);
        // The later segments drain what the external stages still relay, then flush.
        self.done[0].store(true, Ordering::Release);
    }

    /// End the ingest if it still runs and wait for the later segments; what the stages
    /// learnt, or the first failure.
    pub(super) fn finish(mut self) -> Result<Vec<String>, RunError> {
        self.end_ingest();
        let mut failure = self.failure.take();
        for h in std::mem::take(&mut self.segment_threads) {
            let result = h.join().unwrap_or_else(|_| {
                Err(RunError::Stage {
                    stage: "segment".into(),
                    message: "a segment thread panicked".into(),
                })
            });
            match (result, &failure) {
                (Ok(learnt), _) => self.learnt.extend(learnt),
                (Err(e), None) => failure = Some(e),
                (Err(_), Some(_)) => {}
            }
        }
        drop(self.stats.take());
        drop(self.transport);
        failure.map_or(Ok(self.learnt), Err)
    }
}

/// The sleep of a group whose sources include some that other processes notify
/// ([`Source::waker`]): one set over all their wakers, and the shortest of their timeouts.
pub(super) struct Notified {
    pub(super) set: WakeSet,
    pub(super) timeout: Duration,
}

impl Notified {
    /// `None` when no source of the group is notified (the paced sleep alone serves it).
    pub(super) fn of(group: &[Running<'_>]) -> Result<Option<Self>, TransportError> {
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
pub(super) fn serve(
    group: &mut [Running<'_>],
    opts: &RunOptions,
    prewarm: Duration,
    mut notified: Option<Notified>,
) {
    let stop = &*opts.stop;
    // The end of --duration on the clock the ingest stamps samples with (no extra clock read
    // per sample). Once the paced sources share a clock it counts from that clock's start and
    // is judged on when a sample was due, not when it was taken: a paced run is then the same
    // samples however late a busy machine wakes the thread (issue 59).
    let until = |start_ns: u64| {
        opts.duration
            .map_or(u64::MAX, |d| start_ns.saturating_add(d.as_nanos() as u64))
    };
    let mut end_ns = until(monotonic_ns());
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
                if crate::clock::sleep_until(early, stop) {
                    for r in group.iter_mut() {
                        let next = r.next_due();
                        if let (Some(Some(d)), Some((_, chain))) = (next, &mut r.hot) {
                            if d <= due {
                                chain.prewarm();
                            }
                        }
                    }
                }
            }
            if !crate::clock::sleep_until(due, stop) {
                break;
            }
        }
        let now = std::time::Instant::now();
        let mut ended = false;
        for r in group.iter_mut() {
            if matches!(r.next_due(), Some(Some(d)) if d > now) {
                continue;
            }
            ended |= r.step(stop).is_some_and(|due_ns| due_ns >= end_ns);
        }
        // Sources that do not pace themselves may give nothing for a long time.
        if ended || ((ask_now || notified.is_some()) && monotonic_ns() >= end_ns) {
            break;
        }
        if first_round {
            // The first samples met everything cold (code, stage state, shared memory): the
            // clock starts once they are through, so that their cost makes no later sample late.
            first_round = false;
            let clock = crate::clock::PaceClock::now();
            end_ns = until(clock.start_ns());
            for r in group.iter_mut() {
                if let Some((source, _)) = &mut r.hot {
                    source.share_clock(clock);
                }
            }
        }
    }
}

/// What the reporter shows of the pipeline: its stages, deadline and delay, and how each
/// stage with a state file started.
fn layout(
    p: &Pipeline,
    warm_starts: &[(String, WarmStart)],
    lag_total: usize,
    print_summary: bool,
) -> Layout {
    Layout {
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
        // Only stages with a state file: a line for each start of the others says nothing.
        warm_start: warm_starts
            .iter()
            .filter(|(_, w)| *w != WarmStart::NotConfigured)
            .map(|(stage, w)| format!("{stage}: {w}"))
            .collect(),
        // The stats carry one outcome: the worst of the stages' (a second state-keeping
        // stage is rare; its line is in the report).
        warm_start_outcome: warm_starts
            .iter()
            .map(|(_, w)| w.code())
            .max()
            .unwrap_or(crate::wire::WARM_START_NONE),
    }
}

/// Publish what the source logged beside the sample it just gave, before that sample runs.
fn logged_motion(source: &mut dyn Source, chain: &Chain) -> Result<(), TransportError> {
    while let Some(m) = source.logged_motion() {
        chain.logged_motion(&m)?;
    }
    Ok(())
}
