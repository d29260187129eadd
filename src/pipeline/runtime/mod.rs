//! The executor: one hot thread runs the whole chain; a reporting thread owns the histograms.
//!
//! # Execution model
//! On a 2-core machine a thread per stage costs a sleep/wake-up per hop (~25 us each here, with
//! millisecond tails); one thread running the chain costs a fraction of a microsecond per hop.
//! So the hot thread waits once per input sample (the ingest's pacing clock, or the event
//! service of an external raw service), then runs every stage in turn. Every hop is still a
//! real iceoryx2 `ipc` service: the stage's output is published (zero-copy, never blocking; not
//! loaned at all while nobody subscribes), so any process can subscribe to any hop, and the
//! next stage takes the same value directly (a receive of what this thread just published
//! would only cost time: a third of the hot path in a profile of the flat-out replay). The
//! publish stage also notifies an event service of the same name so that external readers can
//! sleep until data arrives.
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
//!
//! Files: this one starts and stops pipelines ([`run`], [`run_group`]); `chain.rs` is one
//! chain's stages run in-thread (segments, their threads when a stage is external, flushing);
//! `group.rs` is the hot thread that serves every pipeline of the daemon (waking, pacing,
//! failing alone) and the checks that let pipelines share it; `sides.rs` starts and stops
//! what runs beside the pipelines (`[ros2]`...), each on a thread of its own; `run.rs`, below
//! them all, is what they share (options, errors, node names).

mod chain;
mod group;
mod run;
mod sides;

pub use chain::EXTERNAL_GRACE;
pub use group::check_group;
pub use run::{node_name, stats_node_name, RunError, RunOptions};
pub use sides::announcement_service;

use group::{hot_settings, schedule_hot_thread, serve, spawn_reporter, Notified, Running};

use std::io::Write as _;
use std::time::Duration;

use crate::metrics::Report;
use crate::pipeline::config::Pipeline;
use crate::stages::contract::Role;
use crate::transport::{remove_prefix_leftovers, Transport};

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
    // Every segment whole now, or a clear error: never a SIGBUS later.
    if let Some(e) = group
        .iter()
        .find_map(|r| r.transport.reserve_shared_memory().err())
    {
        return abandon(group, e.into());
    }
    // The sides on threads of their own, once the services they feed and read exist.
    let sides = match sides::Sides::start(members) {
        Ok(sides) => sides,
        Err(e) => return abandon(group, e),
    };
    let stats = group.iter_mut().filter_map(|r| r.stats.take()).collect();
    let reporter = match spawn_reporter(stats) {
        Ok(h) => h,
        Err(e) => {
            sides.finish(false);
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
    serve(&mut group, opts, prewarm_of(members), notified);
    sides.finish(true);
    let finished: Vec<Result<Vec<String>, RunError>> =
        group.into_iter().map(Running::finish).collect();
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
        .map(|(f, mut report)| {
            f.map(|learnt| {
                report.learnt = learnt;
                report
            })
        })
        .collect())
}

/// The longest prewarm of the group's pipelines.
fn prewarm_of(members: &[(&Pipeline, String)]) -> Duration {
    members
        .iter()
        .map(|(p, _)| p.prewarm)
        .max()
        .unwrap_or_default()
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
