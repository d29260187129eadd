//! The drift series of a rate record, measured exactly as the live pipeline measures it: the
//! streaming denoiser (the daemon's `denoise.wavelet` stage), then the causal low band of its
//! output. Causal end to end, except for the denoiser's own `lag` of look-ahead: the denoised
//! sample t depends on raw samples up to t + lag, so a training range that ends at sample E
//! may only use drift up to E - lag ([`train_end`]) for no test sample to leak into training.

use super::lowband::LowBand;
use super::model::{DenoiseSettings, LowbandSettings};
use crate::wavelet::stream::{Sigma, StreamConfig, StreamingDenoiser};
use crate::wavelet::threshold::ThresholdFn;

/// A record split into its denoised rate and the drift (low band of the denoised rate).
#[derive(Debug, Clone, PartialEq)]
pub struct Separated {
    /// Denoised rate, aligned with the input (sample t is the denoised sample t).
    pub denoised: Vec<f64>,
    /// Drift: the causal low band of `denoised`.
    pub drift: Vec<f64>,
    /// Samples at the start whose values are still start-up transients.
    pub warm_up: usize,
}

/// The streaming denoiser for these settings.
pub fn stream_config(d: &DenoiseSettings) -> Result<StreamConfig, String> {
    let threshold: ThresholdFn = d.threshold.parse().map_err(|e| format!("{e}"))?;
    Ok(StreamConfig {
        wavelet: d.wavelet.clone(),
        level: d.level,
        threshold,
        window: d.window,
        lag: d.lag,
        sigma: Sigma::Mad,
    })
}

/// Denoise `x` with the streaming denoiser and take the causal low band.
pub fn separate_causal(
    x: &[f64],
    d: &DenoiseSettings,
    l: &LowbandSettings,
) -> Result<Separated, String> {
    let mut den = StreamingDenoiser::new(&stream_config(d)?).map_err(|e| e.to_string())?;
    let mut lb = LowBand::new(&l.wavelet, l.level).map_err(|e| e.to_string())?;
    let mut denoised = Vec::with_capacity(x.len());
    for &v in x {
        if let Some(y) = den.push(v) {
            denoised.push(y);
        }
    }
    while let Some(y) = den.flush() {
        denoised.push(y);
    }
    let drift = lb.run(&denoised);
    let full = StreamConfig::full_lag(
        crate::wavelet::Wavelet::by_name(&d.wavelet)
            .map_err(|e| e.to_string())?
            .filter_len(),
        d.level,
    );
    Ok(Separated {
        denoised,
        drift,
        warm_up: lb.span().max(d.window).max(full),
    })
}

/// The last drift sample (exclusive) a training range ending at raw sample `end` may use.
pub fn train_end(end: usize, d: &DenoiseSettings) -> usize {
    end.saturating_sub(d.lag)
}
