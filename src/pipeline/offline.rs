//! The daemon's stage code without the daemon: the same [`Guard`] and the same stages, built
//! from the same pipeline file, in chain order, each output handed to the next stage in
//! memory instead of through an iceoryx2 hop. The daemon's in-thread hops deliver every sample
//! once and in order, so for the same raw samples this gives the same published samples as a
//! live run (a test checks it, sample for sample); offline tools (`driftless nav-eval`) judge
//! exactly what the daemon publishes.

use crate::pipeline::config::Pipeline;
use crate::pipeline::guard::Guard;
use crate::pipeline::stage::{Role, Stage};
use crate::transport::{GyroSample, RawSample};

/// The epoch of an offline run's samples (a daemon picks a random one per start).
pub const OFFLINE_EPOCH: u32 = 1;

/// A pipeline's guard and stages (everything after the ingest), run in the caller's thread.
pub struct Offline {
    guard: Guard,
    stages: Vec<Box<dyn Stage>>,
}

impl Offline {
    /// Build the stages of a validated pipeline. A pipeline with an `external` stage cannot run
    /// offline (that stage is another process).
    pub fn new(p: &Pipeline) -> Result<Self, String> {
        let cx = p.context();
        let mut stages = Vec::with_capacity(p.stages.len());
        for spec in p.stages.iter().skip(1) {
            if spec.kind.role == Role::External {
                return Err(format!(
                    "stage {:?} is external (another process): the pipeline cannot run offline",
                    spec.name
                ));
            }
            stages.push(
                spec.params
                    .stage(&cx)
                    .map_err(|e| format!("stage {:?}: {e}", spec.name))?,
            );
        }
        Ok(Offline {
            guard: Guard::new(p.input_units, p.axes, OFFLINE_EPOCH),
            stages,
        })
    }

    /// One raw sample through the guard and every stage; `out` receives what the last stage
    /// publishes (nothing while a lagged stage fills up).
    pub fn push(&mut self, raw: &RawSample, out: &mut impl FnMut(GyroSample)) {
        let raw = self.guard.stamp(raw);
        let s = self.guard.admit(&raw, 0);
        self.run_from(0, s, out);
    }

    /// At the end of the input: drain the lagged stages, oldest first, as the daemon does.
    pub fn finish(&mut self, out: &mut impl FnMut(GyroSample)) {
        for k in 0..self.stages.len() {
            while let Some(s) = self.stages[k].flush() {
                self.run_from(k + 1, s, out);
            }
        }
    }

    /// Total algorithmic delay of the stages, samples.
    pub fn lag(&self) -> usize {
        self.stages.iter().map(|s| s.lag()).sum()
    }

    fn run_from(&mut self, first: usize, mut s: GyroSample, out: &mut impl FnMut(GyroSample)) {
        for stage in &mut self.stages[first..] {
            match stage.process(&s) {
                Some(next) => s = next,
                None => return,
            }
        }
        out(s);
    }
}
