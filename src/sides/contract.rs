//! The side contract: what runs beside a pipeline's chain ([`Kind`], [`Side`]).
//!
//! A side is a table of the pipeline file (`[ros2]`) that starts something beside the chain: a
//! bridge to another middleware, a diagnostics publisher. It reaches the chain only through
//! the chain's iceoryx2 services, like any other process, and runs on a thread of its own,
//! never on the hot thread. Its kind declares its keys with the stages' [`Key`] schema (so
//! `validate --kinds` and the generated reference list them) and checks its table against the
//! chain it runs beside ([`Chain`]): a service it feeds must be an input the chain reads, a
//! service it reads must be one the chain writes.

use std::fmt::Debug;

use crate::io::InputError;
use crate::stages::contract::{SideInput, StageSpec};
use crate::stages::schema::{Context, Key, Table};

/// A side kind: its table in the pipeline file, its keys, and how its table is read.
pub struct Kind {
    /// The table's name (`ros2` for `[ros2]`).
    pub table: &'static str,
    /// One line on what it does (the reference is generated from it).
    pub summary: &'static str,
    /// Its keys, in the order listed.
    pub keys: &'static [Key],
    /// Read its table and check it against the chain; everything `run` needs is checked here.
    pub read: Read,
}

/// How a side kind reads its table against the chain.
pub type Read = fn(&mut Table<'_, '_>, &Chain<'_>) -> Result<Box<dyn Side>, InputError>;

impl Debug for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "[{}]", self.table)
    }
}

/// The chain a side runs beside, as read from the pipeline file.
pub struct Chain<'a> {
    /// The pipeline's name.
    pub pipeline: &'a str,
    /// Its rate, axes and input units.
    pub cx: Context,
    /// Its stages, in chain order.
    pub stages: &'a [StageSpec],
    /// The service its stats snapshots go to (`StatsSnapshot`, the reporting thread's).
    pub stats_service: &'a str,
}

impl Chain<'_> {
    /// The stage that publishes `service`, if one does.
    pub fn writer(&self, service: &str) -> Option<&StageSpec> {
        self.stages.iter().find(|s| s.output == service)
    }

    /// The stage whose chain input is `service` (an ingest fed by another process), if one is.
    pub fn reader(&self, service: &str) -> Option<&StageSpec> {
        self.stages
            .iter()
            .find(|s| s.input.as_deref() == Some(service))
    }

    /// The stages that read `service` beside their chain input, with what they read it as.
    pub fn side_readers(&self, service: &str) -> Vec<(&StageSpec, SideInput)> {
        self.stages
            .iter()
            .flat_map(|s| {
                s.params
                    .side_inputs()
                    .into_iter()
                    .filter(move |(name, _)| name == service)
                    .map(move |(_, kind)| (s, kind))
            })
            .collect()
    }

    /// Whether a stage of `kind` runs at or before the stage that publishes `service`.
    pub fn upstream_of(&self, service: &str, kind: &str) -> bool {
        let Some(at) = self.stages.iter().position(|s| s.output == service) else {
            return false;
        };
        self.stages[..=at].iter().any(|s| s.kind.name == kind)
    }

    /// The white rate noise a stage assumes (`predict.bias`'s N, deg/s/sqrt(Hz)), if one does.
    pub fn white_noise(&self) -> Option<f64> {
        self.stages.iter().find_map(|s| s.params.white_noise())
    }
}

/// What the runtime hands a side when its pipeline starts. Defined in `transport`, below the
/// sides, so that a side whose work is done there (the ROS 2 bridge) takes it whole.
pub use crate::transport::SideStart as Start;

/// Said once by a side when it is set up (`Ok`) or cannot be (`Err`, why).
pub type Ready<'a> = Box<dyn FnOnce(Result<(), String>) + Send + 'a>;

/// A side, read and checked: what the runtime starts beside the chain.
pub trait Side: Debug + Send + Sync {
    /// What `validate` says of it, a line each.
    fn describe(&self) -> Vec<String>;

    /// What it needs of its environment (`ROS_DOMAIN_ID`...), checked before any pipeline
    /// starts: an error is bad configuration. Default: nothing.
    fn check_environment(&self) -> Result<(), String> {
        Ok(())
    }

    /// Run on the thread the runtime gave it until `start.stop`: set up its own iceoryx2 node
    /// (`start.node`), announce what it does on `start.announce_as` (attributes `driftless
    /// list` shows), say [`Ready`] once set up (the pipeline does not run without it), then
    /// serve. Returns one line of what it carried, or why it failed.
    fn run(&self, start: &Start<'_>, ready: Ready<'_>) -> Result<String, String>;
}

/// One side of a pipeline, as its table was read and checked.
#[derive(Debug, Clone)]
pub struct SideSpec {
    /// Its kind ([`crate::sides::SIDES`]).
    pub kind: &'static Kind,
    /// The side, ready to run.
    pub side: std::sync::Arc<dyn Side>,
}
