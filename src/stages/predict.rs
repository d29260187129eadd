//! `predict.none` (no drift model) and `predict.rbf` (the RBF drift model with live,
//! stillness-gated compensation: [`crate::drift::compensator`]).

use crate::drift::compensator::{Compensator, Mode};
use crate::drift::Rbf;
use crate::pipeline::config::{Pipeline, RbfParams};
use crate::pipeline::stage::Stage;
use crate::transport::{GyroSample, FLAG_MOVING, FLAG_STILL, FLAG_WARMING_UP};

/// Drift estimate 0.
pub struct NoDrift;

impl Stage for NoDrift {
    fn process(&mut self, input: &GyroSample) -> Option<GyroSample> {
        let mut out = *input;
        out.drift = [0.0; 3];
        out.rate = out.denoised;
        Some(out)
    }
}

/// `predict.rbf`: one compensator per axis. The published rate is the denoised rate minus the
/// predicted drift. Flags: [`FLAG_STILL`] when every axis is still, [`FLAG_MOVING`] when any axis
/// is moving, [`FLAG_WARMING_UP`] while an axis has never been still (nothing subtracted there).
/// The models work in the pipeline's input units; samples arrive in rad/s and are scaled.
pub struct RbfDrift {
    comps: Vec<Compensator<Rbf>>,
    /// rad/s per model unit.
    scale: f64,
}

impl RbfDrift {
    /// Build from validated parameters (the models were checked against the pipeline).
    pub fn new(p: &RbfParams, pipeline: &Pipeline) -> Result<Self, String> {
        let mut comps = Vec::with_capacity(p.models.len());
        for (m, s) in p.models.iter().zip(&p.stillness) {
            comps.push(Compensator::new(
                m.network.clone(),
                m.lowband()?,
                *s,
                m.max_step,
            )?);
        }
        Ok(RbfDrift {
            comps,
            scale: pipeline.input_units.to_rad_per_sec(),
        })
    }
}

impl Stage for RbfDrift {
    fn process(&mut self, input: &GyroSample) -> Option<GyroSample> {
        let mut out = *input;
        let (mut still, mut moving, mut warming) = (true, false, false);
        for (axis, c) in self.comps.iter_mut().enumerate() {
            let step = c.push(input.denoised[axis] / self.scale);
            out.drift[axis] = step.drift * self.scale;
            out.rate[axis] = input.denoised[axis] - out.drift[axis];
            match step.mode {
                Mode::Still => {}
                Mode::Moving => (still, moving) = (false, true),
                Mode::Warming => (still, warming) = (false, true),
            }
        }
        if moving {
            out.flags |= FLAG_MOVING;
        } else if still {
            out.flags |= FLAG_STILL;
        }
        if warming {
            out.flags |= FLAG_WARMING_UP;
        }
        Some(out)
    }
}
