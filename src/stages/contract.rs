//! The stage contract: what a stage kind provides ([`Kind`], [`Params`]) and what a built
//! stage does ([`Stage`], [`Source`]).
//!
//! A stage is built from its validated TOML table ([`crate::pipeline::StageSpec`]), then called
//! once per sample with [`Stage::process`], which must not allocate; at shutdown the runtime
//! calls [`Stage::flush`] until it returns `None` to drain what a lagged stage still holds.
//! The runtime, not the stage, owns services, clocks, histograms and shutdown.
//!
//! An ingest is a [`Source`]: the runtime asks it for the next raw sample; a real-time source
//! sleeps until that sample is due.

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use crate::io::InputError;
use crate::stages::schema::{Context, Key, Table};
use crate::wire::{GyroSample, RawSample, StopSignal};

/// What a side input carries: a service a stage reads beside its chain input
/// ([`Params::side_inputs`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SideInput {
    /// [`StopSignal`]: whether the vehicle stands; `by_speed` when the stage judges it by the
    /// signal's speed (it has a `stop_speed`), so a signal that says only a speed can feed it.
    Stop {
        /// The stage judges by speed.
        by_speed: bool,
    },
}

/// The newest value of a side input ([`Stage::side`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SideValue {
    /// A [`StopSignal`].
    Stop(StopSignal),
}

/// A processing stage: one sample in, at most one sample out.
pub trait Stage {
    /// Process one sample. `None`: nothing to emit yet (a lagged stage filling up).
    /// Must not allocate.
    fn process(&mut self, input: &GyroSample) -> Option<GyroSample>;

    /// At shutdown: the next held sample, oldest first; `None` once drained.
    fn flush(&mut self) -> Option<GyroSample> {
        None
    }

    /// Algorithmic delay in samples (output `t` leaves when sample `t + lag` arrives).
    fn lag(&self) -> usize {
        0
    }

    /// Bring what the next [`process`](Self::process) touches back into the cache, changing
    /// no output: after the hot thread's sleep between paced samples a stage's state (and its
    /// code) has left it. Called `prewarm_us` before a sample is due. Default: nothing.
    fn prewarm(&mut self) {}

    /// What the stage learnt while running, one line each, for `run`'s report (called once,
    /// after the last sample; may allocate). Default: nothing.
    fn learnt(&self) -> Vec<String> {
        Vec::new()
    }

    /// How a stage that keeps state across runs started (`predict.bias`: warm, or cold and
    /// why); called once, after it is built. None for a stage that keeps no state. Default:
    /// None.
    fn warm_start(&self) -> Option<crate::stages::state_file::WarmStart> {
        None
    }

    /// What the vehicle's odometry has done for the stage so far (`predict.bias` fed a yaw
    /// rate), for the stats service; called once per batch of samples. Must not allocate.
    /// Default: None.
    fn odometry(&self) -> Option<crate::wire::OdometryStats> {
        None
    }

    /// The newest value of side input `slot` (the index in [`Params::side_inputs`]), handed
    /// over before the sample it precedes whenever a new one arrived; never waited for. Must
    /// not allocate. Default: ignored.
    fn side(&mut self, _slot: usize, _value: &SideValue) {}
}

/// What a source has for the runtime.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Poll {
    /// A raw sample, ingested at `ingest_ns` ([`crate::transport::monotonic_ns`]), and for a
    /// paced source how long after it was due it was taken (ns; the hot thread's wake-up
    /// lateness, which the end-to-end latency from `ingest_ns` does not include).
    Sample(RawSample, u64, Option<u64>),
    /// Nothing now (a timeout passed): check for shutdown and ask again.
    Idle,
    /// The source is exhausted: drain and stop.
    End,
}

/// An ingest stage.
pub trait Source {
    /// The next raw sample; may sleep until it is due (unless it has a [`waker`](Self::waker)),
    /// but returns `Idle` within a few milliseconds when `stop` is set. Must not allocate.
    fn poll(&mut self, stop: &AtomicBool) -> Poll;

    /// When the sample the next [`poll`](Self::poll) returns is due, where the source paces
    /// itself and knows it (for `prewarm_us`). Default: unknown.
    fn next_due(&self) -> Option<std::time::Instant> {
        None
    }

    /// Pace from `clock` from now on: the sample taken first is due at its start (the next
    /// one a sample period later at the source's [`Pace`](crate::clock::Pace), and so on). The
    /// runtime gives every source of a daemon the same clock after their first samples, so
    /// that samples of pipelines sharing the hot thread (at one rate and pace) fall due
    /// together and one wake-up serves them all, and so that the first samples' cold cost
    /// makes no later one late. Default: nothing (a source that does not pace itself).
    fn share_clock(&mut self, _clock: crate::clock::PaceClock) {}

    /// For a source that another process tells of new samples: what the runtime sleeps on
    /// for it, and for how long at most before asking anyway (a driver that does not notify).
    /// Such a source's `poll` never sleeps: the runtime sleeps on every waker of the daemon at
    /// once, with the paced sources' due times, and drains a waker it reports before asking
    /// its source. Default: none.
    fn waker(&self) -> Option<(&crate::transport::Waker, std::time::Duration)> {
        None
    }

    /// The vehicle's motion logged beside the samples (a bag's odometry), one message at a
    /// time, due by the sample [`poll`](Self::poll) returned last: the runtime publishes each
    /// on the stage's [`Params::motion_output`] before that sample runs through the chain, so a
    /// stage reading it there has it first. Stamped on the samples' clock
    /// ([`crate::wire::STOP_CLOCK_SAMPLES`]). Must not allocate. Default: none.
    fn logged_motion(&mut self) -> Option<crate::wire::StopSignal> {
        None
    }
}

pub use crate::sim::TrueRate;

/// Where a kind sits in the chain.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// Starts the chain (a [`Source`]); `input` only when it reads another process's service.
    Ingest {
        /// Whether the table has an `input` (a service of another process).
        has_input: bool,
    },
    /// A processing stage the daemon runs (a [`Stage`]).
    Process,
    /// A stage another process runs: the daemon only links to it.
    External,
    /// The final, public service: ends the chain.
    Publish,
}

/// A stage's validated parameters, as its kind's parse function made them: what the runtime
/// builds the stage from, and what `validate` tells about it.
pub trait Params: std::fmt::Debug + Send + Sync {
    /// Build the processing stage (kinds with [`Role::Process`] or [`Role::Publish`]).
    fn stage(&self, _cx: &Context) -> Result<Box<dyn Stage>, String> {
        Err("this kind is not a processing stage".into())
    }

    /// Build the source (kinds with [`Role::Ingest`]); `input` is the stage's input service.
    /// Default: [`Params::local_source`], for a kind that reads no other process.
    fn source(
        &self,
        cx: &Context,
        _transport: &crate::transport::Transport,
        _input: Option<&str>,
    ) -> Result<Box<dyn Source>, String> {
        self.local_source(cx)
    }

    /// Build the source of an ingest kind that reads no other process's service
    /// (`Role::Ingest { has_input: false }`: a file, the simulator): all it needs is the
    /// pipeline's context.
    fn local_source(&self, _cx: &Context) -> Result<Box<dyn Source>, String> {
        Err("this kind cannot start a chain".into())
    }

    /// Whether the daemon notifies the event service named like this stage's output after
    /// each sample (so other processes can sleep until data arrives).
    fn notifies(&self) -> bool {
        false
    }

    /// How long the daemon's wait on this stage's output sleeps before checking for shutdown
    /// (stages whose output another process publishes).
    fn poll_timeout(&self) -> Duration {
        Duration::from_millis(1)
    }

    /// The true rate of the sensor, when the ingest knows it (a simulator): the daemon then
    /// reports the heading error of what it publishes against the truth.
    fn truth(&self, _cx: &Context) -> Option<TrueRate> {
        None
    }

    /// The services this stage reads beside its input, and what each carries: the runtime
    /// subscribes to them and hands the stage the newest value ([`Stage::side`]). Another
    /// process publishes them (a vehicle's stop signal). Default: none.
    fn side_inputs(&self) -> Vec<(String, SideInput)> {
        Vec::new()
    }

    /// The service an ingest publishes the motion logged beside its samples on
    /// ([`Source::logged_motion`]; `ingest.mcap`'s `motion_output`). Default: none.
    fn motion_output(&self) -> Option<&str> {
        None
    }

    /// The gyro's white rate noise this stage assumes, N in deg/sqrt(s) (`predict.bias`: its
    /// terms' N); a `[ros2]` table without `rate_noise` publishes the covariance from it.
    fn white_noise(&self) -> Option<f64> {
        None
    }

    /// The output step (LSB) this stage assumes of the raw rate, deg/s (`predict.bias`: its
    /// terms' lsb, 0 for none); compared with the step an ingest sees in its data.
    fn assumed_step(&self) -> Option<f64> {
        None
    }

    /// The step of the raw rate an ingest sees in the data it checked (the smallest difference
    /// between two values on one axis), in input units; None where it read none.
    fn data_step(&self) -> Option<f64> {
        None
    }

    /// How fast the source's samples fall due, where it paces them itself (a replay, the
    /// simulator): the pipeline's deadline is by default one period of them. Default: none.
    fn pace(&self) -> Option<crate::clock::Pace> {
        None
    }

    /// Extra lines for `driftless validate` (indented by the caller).
    fn describe(&self, _input: Option<&str>, _output: &str) -> Vec<String> {
        Vec::new()
    }

    /// Lines worth a warning found when the table was read, that do not stop the pipeline
    /// (`validate` and `run` print them once): e.g. a file read by what it holds, not by what
    /// its name says. Default: none.
    fn warnings(&self) -> Vec<String> {
        Vec::new()
    }
}

/// A stage kind: its name in pipeline files, its place in the chain, its keys and its parse
/// function. Each stage file declares one or more; [`crate::stages::KINDS`] lists them all.
pub struct Kind {
    /// The name written as `kind = "..."`.
    pub name: &'static str,
    /// Where it sits in the chain.
    pub role: Role,
    /// One line on what it does (`docs/reference/pipeline-file.md` is generated from it).
    pub summary: &'static str,
    /// Its own keys, beyond `name`, `kind`, `input` and `output`, in the order listed.
    pub keys: &'static [Key],
    /// Read and check its table; everything the stage needs is validated here.
    pub parse: fn(&mut Table<'_, '_>) -> Result<Box<dyn Params>, InputError>,
}

impl Kind {
    /// Whether this kind starts a chain.
    pub fn is_ingest(&self) -> bool {
        matches!(self.role, Role::Ingest { .. })
    }

    /// Whether its table has an `input` key.
    pub fn has_input(&self) -> bool {
        !matches!(self.role, Role::Ingest { has_input: false })
    }
}

impl std::fmt::Debug for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name)
    }
}

/// One stage of a pipeline, as its table was read and checked: what the runtime builds it from.
#[derive(Debug, Clone)]
pub struct StageSpec {
    /// Unique name in the pipeline.
    pub name: String,
    /// Input service (None for the simulator and CSV ingest).
    pub input: Option<String>,
    /// Output service.
    pub output: String,
    /// The kind ([`crate::stages::KINDS`]).
    pub kind: &'static Kind,
    /// Its validated parameters, as the kind's parse function made them.
    pub params: std::sync::Arc<dyn Params>,
}
