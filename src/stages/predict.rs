//! `predict.none`: no drift model; the corrected rate is the denoised rate.
//! (`predict.rbf`, the RBF drift model, comes with the drift-model issue.)

use crate::pipeline::stage::Stage;
use crate::transport::GyroSample;

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
