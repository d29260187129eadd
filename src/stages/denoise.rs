//! `denoise.wavelet` (the streaming wavelet denoiser, one per axis) and `denoise.none`.

use crate::pipeline::config::WaveletParams;
use crate::pipeline::stage::Stage;
use crate::transport::{GyroSample, FLAG_FLUSHED, FLAG_WARMING_UP};
use crate::wavelet::stream::{Sigma, StreamConfig, StreamingDenoiser};
use crate::wavelet::threshold::ThresholdFn;

/// The streaming denoiser's settings for validated parameters.
pub fn stream_config(p: &WaveletParams) -> Result<StreamConfig, String> {
    let mut threshold: ThresholdFn = p.threshold.parse().map_err(|e| format!("{e}"))?;
    match &mut threshold {
        ThresholdFn::Firm { ratio } => {
            if let Some(r) = p.ratio {
                *ratio = r;
            }
        }
        ThresholdFn::Improved { a, beta, kappa } => {
            if let Some(v) = p.a {
                *a = v;
            }
            if let Some(v) = p.beta {
                *beta = v;
            }
            if let Some(v) = p.kappa {
                *kappa = v;
            }
        }
        _ => {}
    }
    Ok(StreamConfig {
        wavelet: p.wavelet.clone(),
        level: p.level,
        threshold,
        window: p.window,
        lag: p.lag,
        sigma: p.sigma.map_or(Sigma::Mad, Sigma::Fixed),
    })
}

/// Check that the denoiser accepts these parameters (used by validation).
pub fn check_wavelet(p: &WaveletParams) -> Result<(), String> {
    let cfg = stream_config(p)?;
    StreamingDenoiser::new(&cfg)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// `denoise.wavelet`: one [`StreamingDenoiser`] per axis. With lag L, the output for sample
/// `t` leaves when sample `t + L` arrives; the metadata of the held samples waits in a ring.
pub struct Wavelet {
    axes: usize,
    denoisers: Vec<StreamingDenoiser>,
    held: Vec<GyroSample>,
    head: usize,
    count: usize,
    last_ingest_ns: u64,
}

impl Wavelet {
    /// Build from validated parameters.
    pub fn new(p: &WaveletParams, axes: usize) -> Result<Self, String> {
        let cfg = stream_config(p)?;
        let axes = axes.clamp(1, 3);
        let mut denoisers = Vec::with_capacity(axes);
        for _ in 0..axes {
            denoisers.push(StreamingDenoiser::new(&cfg).map_err(|e| e.to_string())?);
        }
        Ok(Wavelet {
            axes,
            denoisers,
            held: vec![GyroSample::default(); p.lag + 1],
            head: 0,
            count: 0,
            last_ingest_ns: 0,
        })
    }

    fn emit(&mut self, values: [f64; 3], flushed: bool) -> GyroSample {
        let oldest = (self.head + self.held.len() - self.count) % self.held.len();
        let mut out = self.held[oldest];
        self.count -= 1;
        out.denoised = values;
        out.rate = values;
        out.drift = [0.0; 3];
        out.ingest_ns = self.last_ingest_ns;
        if self.denoisers[0].warming_up() {
            out.flags |= FLAG_WARMING_UP;
        }
        if flushed {
            out.flags |= FLAG_FLUSHED;
        }
        out
    }
}

impl Stage for Wavelet {
    fn process(&mut self, input: &GyroSample) -> Option<GyroSample> {
        self.held[self.head] = *input;
        self.head = (self.head + 1) % self.held.len();
        self.count += 1;
        self.last_ingest_ns = input.ingest_ns;
        let mut values = [0.0; 3];
        let mut ready = false;
        for (axis, d) in self.denoisers.iter_mut().enumerate() {
            if let Some(v) = d.push(input.denoised[axis]) {
                values[axis] = v;
                ready = true;
            }
        }
        ready.then(|| self.emit(values, false))
    }

    fn flush(&mut self) -> Option<GyroSample> {
        if self.count == 0 {
            return None;
        }
        let mut values = [0.0; 3];
        for (axis, d) in self.denoisers.iter_mut().enumerate().take(self.axes) {
            values[axis] = d.flush()?;
        }
        Some(self.emit(values, true))
    }

    fn lag(&self) -> usize {
        self.denoisers.first().map_or(0, StreamingDenoiser::lag)
    }
}

/// `denoise.none`: the rate passes unchanged (denoised = input).
pub struct PassThrough;

impl Stage for PassThrough {
    fn process(&mut self, input: &GyroSample) -> Option<GyroSample> {
        Some(*input)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(lag: usize) -> WaveletParams {
        WaveletParams {
            wavelet: "db4".into(),
            level: 3,
            threshold: "soft".into(),
            ratio: None,
            a: None,
            beta: None,
            kappa: None,
            window: 64,
            lag,
            sigma: None,
        }
    }

    #[test]
    fn every_sample_comes_out_once_in_order_with_its_metadata() {
        let mut st = Wavelet::new(&params(5), 3).unwrap();
        let mut seqs = Vec::new();
        for i in 0..100u64 {
            let s = GyroSample {
                seq: i,
                t_ns: i * 10,
                denoised: [(i as f64).sin(), 0.0, 1.0],
                ..GyroSample::default()
            };
            if let Some(o) = st.process(&s) {
                assert_eq!(o.t_ns, o.seq * 10);
                seqs.push(o.seq);
            }
        }
        while let Some(o) = st.flush() {
            assert!(o.flags & FLAG_FLUSHED != 0);
            seqs.push(o.seq);
        }
        assert_eq!(seqs, (0..100).collect::<Vec<_>>());
    }

    #[test]
    fn matches_the_library_denoiser() {
        let p = params(7);
        let mut st = Wavelet::new(&p, 1).unwrap();
        let mut lib = StreamingDenoiser::new(&stream_config(&p).unwrap()).unwrap();
        for i in 0..200u64 {
            let x = (i as f64 * 0.1).sin() + if i % 7 == 0 { 0.5 } else { 0.0 };
            let s = GyroSample {
                seq: i,
                denoised: [x, 0.0, 0.0],
                ..GyroSample::default()
            };
            let a = st.process(&s).map(|o| o.rate[0]);
            let b = lib.push(x);
            assert_eq!(a, b);
        }
    }
}
