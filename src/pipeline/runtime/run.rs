//! What every part of the runtime shares, below them all: how a run is asked for
//! ([`RunOptions`]), why one fails ([`RunError`]) and the names of a pipeline's nodes.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use crate::transport::{NodeHolder, TransportError};

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
