//! `denoise.wavelet` (the streaming wavelet denoiser, one per axis) and `denoise.none`.
//!
//! ```toml
//! [[stage]]
//! name = "denoise"
//! kind = "denoise.wavelet"
//! input = "demo/raw"
//! output = "demo/denoised"
//! wavelet = "db6"
//! level = 5
//! threshold = "improved"     # hard, soft, garrote, firm, improved
//! window = 1024              # samples of the noise-sigma window
//! lag = 64                   # output delay, samples (0..=full lag)
//! ```

use crate::io::InputError;
use crate::stages::contract::{Kind, Params, Role, Stage};
use crate::stages::schema::{Context, DefaultValue, Key, Table, Type, WordOr};
use crate::wavelet::stream::{LaneDenoiser, Sigma, StreamConfig, StreamingDenoiser};
use crate::wavelet::threshold::ThresholdFn;
use crate::wire::{
    GyroSample, DRIFT_STD_NOT_PROVIDED, FLAG_FLUSHED, FLAG_WARMING_UP, SENSOR_ACCEL,
};

const WAVELET: Key = Key {
    name: "wavelet",
    ty: Type::Str("haar, db1..db20, sym2..sym20, coif1..coif17"),
    default: DefaultValue::Word("db6"),
    doc: "the wavelet",
};
const LEVEL: Key = Key {
    name: "level",
    ty: Type::Int(1, 12),
    default: DefaultValue::Int(5),
    doc: "decomposition level",
};
const THRESHOLD: Key = Key {
    name: "threshold",
    ty: Type::Choice(&["hard", "soft", "garrote", "firm", "improved"]),
    default: DefaultValue::Word("improved"),
    doc: "threshold function",
};
const RATIO: Key = Key {
    name: "ratio",
    ty: Type::Greater(1.0),
    default: DefaultValue::Float(ThresholdFn::FIRM_RATIO),
    doc: "firm threshold: upper / lower threshold",
};
const A: Key = Key {
    name: "a",
    ty: Type::NonNegative,
    default: DefaultValue::Float(ThresholdFn::IMPROVED_A),
    doc: "improved threshold: shrinkage below the threshold",
};
const BETA: Key = Key {
    name: "beta",
    ty: Type::Positive(1e9),
    default: DefaultValue::Float(ThresholdFn::IMPROVED_BETA),
    doc: "improved threshold: how fast it tends to hard above the threshold",
};
const KAPPA: Key = Key {
    name: "kappa",
    ty: Type::Positive(1e9),
    default: DefaultValue::Float(ThresholdFn::IMPROVED_KAPPA),
    doc: "improved threshold: how fast small coefficients vanish",
};
const WINDOW: Key = Key {
    name: "window",
    ty: Type::Int(2, 1 << 20),
    default: DefaultValue::Int(StreamConfig::DEFAULT_WINDOW as i64),
    doc: "samples of the sliding noise-sigma window",
};
const LAG: Key = Key {
    name: "lag",
    ty: Type::IntDepends("0..=full lag ((2^level - 1)(filter length - 1))"),
    default: DefaultValue::Noted(
        &DefaultValue::Int(StreamConfig::DEFAULT_LAG as i64),
        " (at most the full lag)",
    ),
    doc: "output delay in samples: more lag, closer to offline denoising",
};
const SIGMA: Key = Key {
    name: "sigma",
    ty: Type::WordOrPositive(&["mad"], f64::MAX),
    default: DefaultValue::Word("mad"),
    doc: "noise sigma: estimated (median absolute deviation) or fixed, in input units",
};

const DENOISE_ACCEL: Key = Key {
    name: "denoise_accel",
    ty: Type::Bool,
    default: DefaultValue::Bool(false),
    doc: "denoise the accelerometer too, with the same wavelet, threshold, window and lag (its \
          noise sigma always estimated: `sigma` is in rate units); off, it passes as received, \
          each reading with its own sample",
};

/// `denoise.wavelet`.
pub const WAVELET_KIND: Kind = Kind {
    name: "denoise.wavelet",
    role: Role::Process,
    summary: "the streaming wavelet-threshold denoiser, one per axis",
    keys: &[
        WAVELET,
        LEVEL,
        THRESHOLD,
        RATIO,
        A,
        BETA,
        KAPPA,
        WINDOW,
        LAG,
        SIGMA,
        DENOISE_ACCEL,
    ],
    parse: parse_wavelet,
};

/// `denoise.none`.
pub const NONE_KIND: Kind = Kind {
    name: "denoise.none",
    role: Role::Process,
    summary: "no denoising: the rate passes through",
    keys: &[],
    parse: |_| Ok(Box::new(NoDenoise)),
};

/// Parameters of `denoise.wavelet` (validated; passed to the streaming denoiser).
#[derive(Debug, Clone, PartialEq)]
pub struct WaveletParams {
    /// Wavelet name, e.g. "db6".
    pub wavelet: String,
    /// Decomposition level.
    pub level: usize,
    /// Threshold function name.
    pub threshold: String,
    /// Firm threshold ratio (used by `firm` only).
    pub ratio: f64,
    /// Improved threshold `a` (used by `improved` only).
    pub a: f64,
    /// Improved threshold `beta` (used by `improved` only).
    pub beta: f64,
    /// Improved threshold `kappa` (used by `improved` only).
    pub kappa: f64,
    /// Sliding window length, samples.
    pub window: usize,
    /// Output lag, samples.
    pub lag: usize,
    /// Noise sigma: None for MAD, Some(fixed).
    pub sigma: Option<f64>,
    /// Whether the accelerometer is denoised too.
    pub denoise_accel: bool,
}

fn parse_wavelet(t: &mut Table<'_, '_>) -> Result<Box<dyn Params>, InputError> {
    let wavelet = t.str_or_default(&WAVELET, |w| {
        crate::wavelet::Wavelet::by_name(w)
            .map(|_| ())
            .map_err(|e| e.to_string())
    })?;
    let level = t.int_or_default(&LEVEL)?;
    let threshold = t.choice_or_default(&THRESHOLD, "threshold function", false)?;
    let ratio = t.float_or_default(&RATIO)?;
    let a = t.float_or_default(&A)?;
    let beta = t.float_or_default(&BETA)?;
    let kappa = t.float_or_default(&KAPPA)?;
    let window = t.int_or_default(&WINDOW)?;
    let filter_len = crate::wavelet::Wavelet::by_name(&wavelet)
        .map(|w| w.filter_len())
        .unwrap_or(2);
    let full_lag = StreamConfig::full_lag(filter_len, level);
    let lag = t.int_in_or_default(&LAG, 0, full_lag as i64)?;
    let sigma = match t.word_or_positive_or_default(&SIGMA)? {
        WordOr::Number(x) => Some(x),
        WordOr::Word(_) => None,
    };
    let denoise_accel = t.bool_or_default(&DENOISE_ACCEL)?;
    let params = WaveletParams {
        wavelet,
        level,
        threshold,
        ratio,
        a,
        beta,
        kappa,
        window,
        lag,
        sigma,
        denoise_accel,
    };
    StreamingDenoiser::new(
        &stream_config(&params).map_err(|e| t.error(format!("denoise.wavelet: {e}")))?,
    )
    .map_err(|e| t.error(format!("denoise.wavelet: {e}")))?;
    Ok(Box::new(params))
}

impl Params for WaveletParams {
    fn stage(&self, cx: &Context) -> Result<Box<dyn Stage>, String> {
        Ok(Box::new(Wavelet::new(self, cx.axes)?))
    }
}

/// `denoise.none` parameters (it has none).
#[derive(Debug, Clone, Copy)]
struct NoDenoise;

impl Params for NoDenoise {
    fn stage(&self, _cx: &Context) -> Result<Box<dyn Stage>, String> {
        Ok(Box::new(PassThrough))
    }
}

/// The streaming denoiser's settings for validated parameters.
pub fn stream_config(p: &WaveletParams) -> Result<StreamConfig, String> {
    let mut threshold: ThresholdFn = p.threshold.parse().map_err(|e| format!("{e}"))?;
    match &mut threshold {
        ThresholdFn::Firm { ratio } => *ratio = p.ratio,
        ThresholdFn::Improved { a, beta, kappa } => (*a, *beta, *kappa) = (p.a, p.beta, p.kappa),
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

/// `denoise.wavelet`: the axes denoised in lock step by one [`LaneDenoiser`] (each axis's
/// result bit for bit a [`StreamingDenoiser`]'s). With lag L, the output for sample `t` leaves
/// when sample `t + L` arrives; the metadata of the held samples waits in a ring.
pub struct Wavelet {
    axes: usize,
    denoiser: LaneDenoiser<3>,
    /// The accelerometer's denoiser, in lock step with the rates' (`denoise_accel`).
    accel: Option<LaneDenoiser<3>>,
    held: Vec<GyroSample>,
    head: usize,
    count: usize,
    last_ingest_ns: u64,
}

impl Wavelet {
    /// Build from validated parameters.
    pub fn new(p: &WaveletParams, axes: usize) -> Result<Self, String> {
        let cfg = stream_config(p)?;
        let accel = p
            .denoise_accel
            .then(|| {
                LaneDenoiser::new(&StreamConfig {
                    sigma: Sigma::Mad,
                    ..cfg.clone()
                })
            })
            .transpose()
            .map_err(|e| e.to_string())?;
        Ok(Wavelet {
            axes: axes.clamp(1, 3),
            denoiser: LaneDenoiser::new(&cfg).map_err(|e| e.to_string())?,
            accel,
            held: vec![GyroSample::default(); p.lag + 1],
            head: 0,
            count: 0,
            last_ingest_ns: 0,
        })
    }

    fn emit(&mut self, values: [f64; 3], accel: Option<[f64; 3]>, flushed: bool) -> GyroSample {
        let oldest = (self.head + self.held.len() - self.count) % self.held.len();
        let mut out = self.held[oldest];
        self.count -= 1;
        if let Some(a) = accel.filter(|_| out.sensors & SENSOR_ACCEL != 0) {
            out.accel = a;
        }
        out.denoised = values;
        out.rate = values;
        out.drift = [0.0; 3];
        // No drift removed here, so no uncertainty of one (after a predict stage too).
        out.drift_std = [DRIFT_STD_NOT_PROVIDED; 3];
        out.ingest_ns = self.last_ingest_ns;
        if self.denoiser.warming_up() {
            out.flags |= FLAG_WARMING_UP;
        }
        if flushed {
            out.flags |= FLAG_FLUSHED;
        }
        out
    }
}

/// `v` with the axes the pipeline does not use set to 0 (in and out of the lock-step denoiser).
fn used_axes(axes: usize, v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|a| if a < axes { v[a] } else { 0.0 })
}

impl Stage for Wavelet {
    fn process(&mut self, input: &GyroSample) -> Option<GyroSample> {
        self.held[self.head] = *input;
        self.head = (self.head + 1) % self.held.len();
        self.count += 1;
        self.last_ingest_ns = input.ingest_ns;
        // Both denoisers take every sample (an absent reading as its held or zero value), so
        // they stay in lock step and each output gets its own sample's accelerometer.
        let accel = self.accel.as_mut().and_then(|d| d.push(input.accel));
        let values = self.denoiser.push(used_axes(self.axes, input.denoised))?;
        Some(self.emit(used_axes(self.axes, values), accel, false))
    }

    fn flush(&mut self) -> Option<GyroSample> {
        if self.count == 0 {
            return None;
        }
        let accel = self.accel.as_mut().and_then(LaneDenoiser::flush);
        let values = self.denoiser.flush()?;
        Some(self.emit(used_axes(self.axes, values), accel, true))
    }

    fn lag(&self) -> usize {
        self.denoiser.lag()
    }

    fn prewarm(&mut self) {
        self.denoiser.prewarm();
        if let Some(d) = &self.accel {
            d.prewarm();
        }
        // A copy is a read: a reference alone would not touch the memory.
        std::hint::black_box(self.held[self.head]);
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
            ratio: ThresholdFn::FIRM_RATIO,
            a: ThresholdFn::IMPROVED_A,
            beta: ThresholdFn::IMPROVED_BETA,
            kappa: ThresholdFn::IMPROVED_KAPPA,
            window: 64,
            lag,
            sigma: None,
            denoise_accel: false,
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
    fn three_axes_match_three_library_denoisers_bit_for_bit() {
        let p = params(33);
        let mut st = Wavelet::new(&p, 3).unwrap();
        let mut lib: Vec<StreamingDenoiser> = (0..3)
            .map(|_| StreamingDenoiser::new(&stream_config(&p).unwrap()).unwrap())
            .collect();
        let mut got = Vec::new();
        let mut want = Vec::new();
        for i in 0..3000u64 {
            let t = i as f64 * 0.01;
            let x = [
                t.sin() + ((i * 7919) % 101) as f64 * 1e-3,
                if i % 500 == 7 {
                    f64::NAN
                } else {
                    (3.0 * t).cos()
                },
                if i % 3 == 0 {
                    0.0
                } else {
                    0.1 * ((i * 104_729) % 89) as f64
                },
            ];
            let s = GyroSample {
                seq: i,
                denoised: x,
                ..GyroSample::default()
            };
            if let Some(o) = st.process(&s) {
                got.push(o.rate.map(f64::to_bits));
            }
            let w: Vec<Option<f64>> = lib.iter_mut().zip(x).map(|(d, v)| d.push(v)).collect();
            if w[0].is_some() {
                want.push([0, 1, 2].map(|a| w[a].unwrap().to_bits()));
            }
        }
        while let Some(o) = st.flush() {
            got.push(o.rate.map(f64::to_bits));
        }
        while let Some(v) = lib[0].flush() {
            let (y, z) = (lib[1].flush().unwrap(), lib[2].flush().unwrap());
            want.push([v, y, z].map(f64::to_bits));
        }
        assert_eq!(got.len(), 3000);
        assert_eq!(got, want);
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

    #[test]
    fn the_accelerometer_passes_with_its_own_sample_or_is_denoised_in_lock_step() {
        let accel_of = |i: u64| [0.01 * (i % 13) as f64, -0.02 * (i % 7) as f64, -9.81];
        for denoise_accel in [false, true] {
            let p = WaveletParams {
                denoise_accel,
                ..params(9)
            };
            let mut st = Wavelet::new(&p, 3).unwrap();
            let mut lib = LaneDenoiser::<3>::new(&stream_config(&p).unwrap()).unwrap();
            let (mut got, mut want) = (Vec::new(), Vec::new());
            for i in 0..300u64 {
                let s = GyroSample {
                    seq: i,
                    denoised: [(i as f64 * 0.1).sin(), 0.0, 1.0],
                    accel: accel_of(i),
                    sensors: SENSOR_ACCEL,
                    ..GyroSample::default()
                };
                if let Some(o) = st.process(&s) {
                    got.push((o.seq, o.accel));
                }
                if let Some(a) = lib.push(accel_of(i)) {
                    want.push(a);
                }
            }
            while let Some(o) = st.flush() {
                got.push((o.seq, o.accel));
            }
            while let Some(a) = lib.flush() {
                want.push(a);
            }
            assert_eq!(got.len(), 300);
            for (k, (seq, a)) in got.iter().enumerate() {
                assert_eq!(*seq, k as u64);
                let expected = if denoise_accel {
                    want[k]
                } else {
                    accel_of(*seq)
                };
                assert_eq!(*a, expected, "sample {k}, denoise_accel {denoise_accel}");
            }
        }
    }
}
