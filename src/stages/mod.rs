//! The stage kinds, one file each, and the factory that builds them from validated specs.
//!
//! | kind | file | role |
//! |---|---|---|
//! | `ingest.sim` | [`ingest_sim`] | simulated sensor, paced in real time |
//! | `ingest.csv` | [`ingest_csv`] | CSV replay, real time or as fast as possible |
//! | `ingest.iceoryx2` | [`ingest_iceoryx2`] | raw samples from a driver in another process |
//! | `denoise.wavelet`, `denoise.none` | [`denoise`] | streaming wavelet denoiser / pass-through |
//! | `predict.none`, `predict.rbf` | [`predict`] | drift estimate 0 / the RBF drift model, gated by stillness |
//! | `external` | [`external`] | a stage run by another process (the daemon only links to it) |
//! | `publish` | [`publish`] | the final guard before the public service |

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::pipeline::config::{Pipeline, StageKind, StageSpec};
use crate::pipeline::stage::Stage;

pub mod denoise;
pub mod external;
pub mod ingest_csv;
pub mod ingest_iceoryx2;
pub mod ingest_sim;
pub mod predict;
pub mod publish;

/// Build the processing stage for `spec` (not an ingest). Errors are parameter errors that
/// validation should already have caught.
pub fn build(spec: &StageSpec, pipeline: &Pipeline) -> Result<Box<dyn Stage>, String> {
    match &spec.kind {
        StageKind::DenoiseWavelet(p) => Ok(Box::new(denoise::Wavelet::new(p, pipeline.axes)?)),
        StageKind::DenoiseNone => Ok(Box::new(denoise::PassThrough)),
        StageKind::PredictNone => Ok(Box::new(predict::NoDrift)),
        StageKind::PredictRbf(p) => Ok(Box::new(predict::RbfDrift::new(p, pipeline)?)),
        StageKind::Publish { .. } => Ok(Box::new(publish::Publish)),
        StageKind::External { .. } => Err("an external stage runs in another process".into()),
        other => Err(format!(
            "{} is an ingest, not a processing stage",
            other.name()
        )),
    }
}

/// Sleep until `due` (a monotonic instant), in slices short enough to notice `stop`.
/// Returns false when stopped first.
pub(crate) fn sleep_until(due: Instant, stop: &AtomicBool) -> bool {
    const SLICE: Duration = Duration::from_millis(20);
    loop {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        let now = Instant::now();
        if now >= due {
            return true;
        }
        std::thread::sleep((due - now).min(SLICE));
    }
}
