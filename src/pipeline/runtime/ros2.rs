//! The ROS 2 side of the pipelines that have a `[ros2]` table (feature `ros2`): one thread
//! each, started once the pipelines run and stopped after them
//! ([`crate::transport::ros2::run_bridge`]: why a thread, and what it does).

use std::io::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crossbeam_channel::bounded;

use super::RunError;
use crate::pipeline::config::Pipeline;
use crate::transport::ros2::{run_bridge, BridgeCounts};
use crate::transport::{Qos, TransportError};

/// The event service on which pipeline `pipeline`'s ROS 2 side says what it does (its node,
/// domain and topics, as attributes), for `driftless list`.
pub fn announcement_service(pipeline: &str) -> String {
    format!("driftless/{pipeline}/ros2")
}

/// The running ROS 2 sides of a group.
pub(super) struct Ros2Sides {
    stop: Arc<AtomicBool>,
    threads: Vec<(
        String,
        std::thread::JoinHandle<Result<BridgeCounts, TransportError>>,
    )>,
}

/// How long a bridge may take to set up (DDS sockets, iceoryx2 ports) before the run fails.
const SETUP_LIMIT: Duration = Duration::from_secs(20);

impl Ros2Sides {
    /// Start the ROS 2 side of each pipeline that has one; all or nothing.
    pub(super) fn start(members: &[(&Pipeline, String)]) -> Result<Ros2Sides, RunError> {
        let mut sides = Ros2Sides {
            stop: Arc::default(),
            threads: Vec::new(),
        };
        for (p, prefix) in members {
            let Some(settings) = p.ros2.clone() else {
                continue;
            };
            let (tx, rx) = bounded::<Result<(), String>>(1);
            let (prefix, stop, rate_hz) = (prefix.clone(), Arc::clone(&sides.stop), p.rate_hz);
            let node = format!("{}-ros2", super::node_name(&p.name));
            let announce_as = announcement_service(&p.name);
            let qos = Qos {
                buffer_size: p.iceoryx2.buffer_size,
                max_subscribers: p.iceoryx2.max_subscribers,
            };
            let spawned = std::thread::Builder::new()
                .name("driftless-ros2".into())
                .spawn(move || {
                    run_bridge(
                        &settings,
                        &prefix,
                        &node,
                        &announce_as,
                        qos,
                        rate_hz,
                        &stop,
                        |r| {
                            let _ = tx.send(r);
                        },
                    )
                });
            let failure = match spawned {
                Ok(handle) => {
                    sides.threads.push((p.name.clone(), handle));
                    match rx.recv_timeout(SETUP_LIMIT) {
                        Ok(Ok(())) => None,
                        Ok(Err(e)) => Some(e),
                        Err(_) => Some(format!("not set up after {} s", SETUP_LIMIT.as_secs())),
                    }
                }
                Err(e) => Some(e.to_string()),
            };
            if let Some(message) = failure {
                sides.finish(false);
                return Err(RunError::Stage {
                    stage: "ros2".into(),
                    message,
                });
            }
        }
        Ok(sides)
    }

    /// Stop every side; with `report`, one line each on stderr of what it carried (beside the
    /// final table, which `--quiet` keeps too).
    pub(super) fn finish(self, report: bool) {
        self.stop.store(true, Ordering::Relaxed);
        for (pipeline, handle) in self.threads {
            let line = match handle.join() {
                Ok(Ok(counts)) => format!("pipeline {pipeline}: ros2: {counts}"),
                Ok(Err(e)) => format!("pipeline {pipeline}: ros2 failed: {e}"),
                Err(_) => format!("pipeline {pipeline}: ros2: its thread panicked"),
            };
            if report {
                let _ = writeln!(std::io::stderr(), "{line}");
            }
        }
    }
}
