//! The sides of a group's pipelines (`[ros2]`...): each on a thread of its own, started once
//! the pipelines' services exist and stopped after the pipelines. A side reaches its pipeline
//! only through those services ([`crate::sides`]: the contract).

use std::io::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::bounded;

use super::run::{node_name, RunError};
use crate::pipeline::config::Pipeline;
use crate::sides::Start;

/// The event service on which a side of pipeline `pipeline` says what it does (as
/// attributes), for `driftless list`.
pub fn announcement_service(pipeline: &str, table: &str) -> String {
    format!("driftless/{pipeline}/{table}")
}

/// How long a side may take to set up (sockets, iceoryx2 ports) before the run fails.
const SETUP_LIMIT: Duration = Duration::from_secs(20);

/// A side's thread: what it carried, or why it failed.
type Thread = JoinHandle<Result<String, String>>;

/// The running sides of a group.
pub(super) struct Sides {
    stop: Arc<AtomicBool>,
    /// Each side's pipeline, table and thread.
    threads: Vec<(String, &'static str, Thread)>,
}

impl Sides {
    /// Start every side of every pipeline, each once it said it is set up; all or nothing.
    pub(super) fn start(members: &[(&Pipeline, String)]) -> Result<Sides, RunError> {
        let mut sides = Sides {
            stop: Arc::default(),
            threads: Vec::new(),
        };
        // The group's one hot thread: whichever pipeline pins it.
        let cpu = members.iter().find_map(|(p, _)| p.cpu);
        for (p, prefix) in members {
            for spec in &p.sides {
                let table = spec.kind.table;
                if let Err(message) = sides.spawn(p, prefix, spec, cpu) {
                    sides.finish(false);
                    return Err(RunError::Stage {
                        stage: table.into(),
                        message,
                    });
                }
            }
        }
        Ok(sides)
    }

    /// Spawn one side and wait until it says it is set up.
    fn spawn(
        &mut self,
        p: &Pipeline,
        prefix: &str,
        spec: &crate::sides::SideSpec,
        cpu: Option<usize>,
    ) -> Result<(), String> {
        let (tx, rx) = bounded::<Result<(), String>>(1);
        let table = spec.kind.table;
        let side = Arc::clone(&spec.side);
        let stop = Arc::clone(&self.stop);
        let (pipeline, prefix, rate_hz) = (p.name.clone(), prefix.to_string(), p.rate_hz);
        let node = format!("{}-{table}", node_name(&p.name));
        let announce_as = announcement_service(&p.name, table);
        let qos = p.iceoryx2.qos();
        let handle = std::thread::Builder::new()
            .name(format!("driftless-{table}"))
            .spawn(move || {
                let start = Start {
                    pipeline: &pipeline,
                    prefix: &prefix,
                    node: &node,
                    announce_as: &announce_as,
                    qos,
                    rate_hz,
                    cpu,
                    stop: &stop,
                };
                side.run(
                    &start,
                    Box::new(|r| {
                        let _ = tx.send(r);
                    }),
                )
            })
            .map_err(|e| e.to_string())?;
        self.threads.push((p.name.clone(), table, handle));
        match rx.recv_timeout(SETUP_LIMIT) {
            Ok(ready) => ready,
            Err(_) => Err(format!("not set up after {} s", SETUP_LIMIT.as_secs())),
        }
    }

    /// Stop every side; with `report`, one line each on stderr of what it carried (beside the
    /// final table, which `--quiet` keeps too).
    pub(super) fn finish(self, report: bool) {
        self.stop.store(true, Ordering::Relaxed);
        for (pipeline, table, handle) in self.threads {
            let line = match handle.join() {
                Ok(Ok(carried)) => format!("pipeline {pipeline}: {table}: {carried}"),
                Ok(Err(e)) => format!("pipeline {pipeline}: {table} failed: {e}"),
                Err(_) => format!("pipeline {pipeline}: {table}: its thread panicked"),
            };
            if report {
                let _ = writeln!(std::io::stderr(), "{line}");
            }
        }
    }
}
