//! Streaming wavelet-threshold denoiser: one sample in, one denoised sample out from `lag`
//! samples ago, in constant time and without allocation.
//!
//! # Algorithm, and why
//! A causal **stationary** (undecimated, à trous) wavelet transform, run one sample at a time:
//! level j's details are `d_j = G_j * x`, where `G_j` is the level's equivalent analysis filter
//! (length `(2^j - 1)(F - 1) + 1`: 342 taps for db6 at level 5). Each new detail is thresholded
//! as it arrives, and the output is the input minus the synthesis of what the threshold removed:
//!
//! `x_hat[t] = x[t] - sum_j 2^-j sum_k G_j[k] e_j[t + k]`,  `e_j = d_j - T(d_j, lambda)`.
//!
//! By linearity this is exactly the inverse stationary transform of the thresholded details when
//! every `e_j[t + k]` is known, that is with `lag >= 2^J (F - 1) - F + 1` (341 samples for db6 /
//! 5 levels): translation-invariant denoising (Coifman & Donoho's cycle spinning), which is at
//! least as good as the decimated batch transform and has no block edges. With a smaller lag the
//! inner sum is truncated at `k <= lag`: less noise is removed, never more, and the low band (the
//! approximation, where drift and slow motion live) passes through untouched at every lag.
//!
//! Alternatives we did not take: re-running a windowed DWT per sample costs O(window x F) per
//! sample (tens of microseconds for db6 on 1024 samples); hopping it every H samples makes the
//! delay vary from sample to sample and leaves seams at block edges.
//!
//! Cost per sample: `2 J F` multiply-adds for the analysis cascade plus at most `sum_j |G_j|`
//! for the synthesis (about 750 for db6 / 5 levels at full lag), a thresholding per level, and
//! the noise tracker's O(window) `memmove`.
//!
//! # Noise and threshold
//! Sigma is median(|d_1|) / 0.6745 over the last `window` finest details (exact zeros excluded,
//! as the batch estimator), or fixed. The threshold is universal over that window:
//! `lambda = sigma sqrt(2 ln window)`, applied to every level.

use super::threshold::ThresholdFn;
use super::{Wavelet, WaveletError};

/// Deepest level the streaming denoiser takes (db6 at level 12 spans 45,046 samples).
pub const MAX_LEVEL: usize = 12;

/// The noise sigma of the streaming denoiser.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sigma {
    /// Tracked online: median absolute finest detail over the window / 0.6745.
    Mad,
    /// Known in advance, in the signal's units.
    Fixed(f64),
}

/// Settings of a [`StreamingDenoiser`].
#[derive(Debug, Clone, PartialEq)]
pub struct StreamConfig {
    /// Wavelet name (`db6`, `sym8`, ...).
    pub wavelet: String,
    /// Number of levels J.
    pub level: usize,
    /// Threshold function.
    pub threshold: ThresholdFn,
    /// Samples over which sigma is tracked; also the N of the universal threshold.
    pub window: usize,
    /// Algorithmic delay in samples: output `t` leaves when sample `t + lag` arrives.
    pub lag: usize,
    /// Noise sigma.
    pub sigma: Sigma,
}

impl StreamConfig {
    /// Default window: 1024 samples (20 s at 50 Hz, 1 s at 1 kHz).
    pub const DEFAULT_WINDOW: usize = 1024;
    /// Default lag: 33 samples, the span of db6's two finest levels, which hold three quarters of
    /// white noise's power (0.66 s at 50 Hz, 33 ms at 1 kHz; docs/denoise.md tabulates the rest).
    pub const DEFAULT_LAG: usize = 33;

    /// The lag at which the output equals the full stationary-transform denoising:
    /// `(2^level - 1)(F - 1)`, F the filter length.
    pub fn full_lag(filter_len: usize, level: usize) -> usize {
        ((1usize << level) - 1) * (filter_len - 1)
    }
}

impl Default for StreamConfig {
    /// db6, 5 levels, the improved threshold, window 1024, lag 33, sigma tracked online.
    fn default() -> Self {
        StreamConfig {
            wavelet: "db6".into(),
            level: 5,
            threshold: ThresholdFn::improved_default(),
            window: Self::DEFAULT_WINDOW,
            lag: Self::DEFAULT_LAG,
            sigma: Sigma::Mad,
        }
    }
}

/// The last `cap` values of a stream, stored twice so that any run of them is one contiguous
/// slice (oldest first): dot products over it vectorise.
#[derive(Debug, Clone)]
struct History<T> {
    buf: Vec<T>,
    cap: usize,
    pos: usize,
}

impl<T: Copy> History<T> {
    /// `cap` values, all `zero` (the stream's start overwrites them).
    fn new(cap: usize, zero: T) -> Self {
        History {
            buf: vec![zero; 2 * cap],
            cap,
            pos: 0,
        }
    }

    fn fill(&mut self, v: T) {
        self.buf.fill(v);
    }

    #[inline]
    fn push(&mut self, v: T) {
        self.buf[self.pos] = v;
        self.buf[self.pos + self.cap] = v;
        self.pos = if self.pos + 1 == self.cap {
            0
        } else {
            self.pos + 1
        };
    }

    /// The value pushed `k` pushes ago (0 = newest), `k < cap`.
    #[inline]
    fn ago(&self, k: usize) -> T {
        self.buf[self.pos + self.cap - 1 - k]
    }

    /// `len` values in time order, the first of them pushed `k` pushes ago.
    #[inline]
    fn run_from(&self, k: usize, len: usize) -> &[T] {
        let start = self.pos + self.cap - 1 - k;
        &self.buf[start..start + len]
    }
}

/// Median of the nonzero |values| among the last `window` pushed: a sorted copy of the window,
/// updated in place (O(log window) to find, about window / 3 values moved per update).
///
/// The sorted copy holds the values' bit patterns: for values without a sign (|v|, NaN
/// included) integer order is `f64::total_cmp`'s order, and an integer compare is cheaper.
#[derive(Debug, Clone)]
struct MedianTracker {
    recent: History<f64>,
    count: usize,
    sorted: Vec<u64>,
}

impl MedianTracker {
    fn new(window: usize) -> Self {
        MedianTracker {
            recent: History::new(window, 0.0),
            count: 0,
            sorted: Vec::with_capacity(window),
        }
    }

    fn push(&mut self, v: f64) {
        let v = v.abs();
        let old = if self.count == self.recent.cap {
            self.recent.ago(self.recent.cap - 1)
        } else {
            self.count += 1;
            0.0
        };
        self.recent.push(v);
        // Exact zeros are not in `sorted` (they are excluded from the median).
        let rank = |sorted: &[u64], x: f64| {
            let x = x.to_bits();
            sorted.partition_point(|p| *p < x)
        };
        match (old != 0.0, v != 0.0) {
            (true, true) => {
                // Replace in place: only the values ranked between old and new move, about a
                // third of the window on average instead of a removal and an insertion's worth.
                let i = rank(&self.sorted, old);
                let j = rank(&self.sorted, v);
                if j > i {
                    self.sorted.copy_within(i + 1..j, i);
                    self.sorted[j - 1] = v.to_bits();
                } else {
                    self.sorted.copy_within(j..i, j + 1);
                    self.sorted[j] = v.to_bits();
                }
            }
            (true, false) => {
                let i = rank(&self.sorted, old);
                self.sorted.remove(i);
            }
            (false, true) => {
                let j = rank(&self.sorted, v);
                self.sorted.insert(j, v.to_bits());
            }
            (false, false) => {}
        }
    }

    fn median(&self) -> f64 {
        let n = self.sorted.len();
        let at = |i: usize| f64::from_bits(self.sorted[i]);
        match n {
            0 => 0.0,
            _ if n % 2 == 1 => at(n / 2),
            _ => 0.5 * (at(n / 2 - 1) + at(n / 2)),
        }
    }
}

/// One level of the causal analysis cascade, for `N` streams in lock step.
#[derive(Debug, Clone)]
struct Level<const N: usize> {
    /// Past approximations of the level above (`a_{j-1}`), enough for the dilated filter.
    input: History<[f64; N]>,
    /// Filter dilation `2^(j-1)`.
    stride: usize,
    /// What thresholding removed from this level's details, the last `lag + 1` of them, one
    /// history per lane: the synthesis is then a contiguous dot product per lane.
    removed: [History<f64>; N],
    /// `2^-j G_j[0..K_j]`: the truncated synthesis filter of this level.
    synthesis: Vec<f64>,
}

/// `N` streams (the axes of one gyro) denoised in lock step: the same filters and settings,
/// each stream (lane) with its own noise window and threshold. Each lane's arithmetic is exactly
/// a one-stream denoiser's, the same operations in the same order, so its results are bit for
/// bit those of a [`StreamingDenoiser`] fed that stream alone; the lanes share each pass over the
/// filter taps, whose sums are chains of dependent additions: `N` of them run side by side at
/// about the cost of one.
#[derive(Debug, Clone)]
pub struct LaneDenoiser<const N: usize> {
    lo: Vec<f64>,
    hi: Vec<f64>,
    levels: Vec<Level<N>>,
    input: History<[f64; N]>,
    threshold: ThresholdFn,
    sigma: Sigma,
    noise: [MedianTracker; N],
    universal: f64,
    lambda: [f64; N],
    lag: usize,
    full_lag: usize,
    pushed: u64,
    flushed: usize,
}

/// A constant-time, allocation-free streaming wavelet-threshold denoiser of one stream (see the
/// module docs): a [`LaneDenoiser`] of one lane.
#[derive(Debug, Clone)]
pub struct StreamingDenoiser(LaneDenoiser<1>);

/// Full convolution of `a` and `b`.
fn convolve(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (k, y) in b.iter().enumerate() {
            out[i + k] += x * y;
        }
    }
    out
}

/// `f` with `stride - 1` zeros between taps.
fn dilate(f: &[f64], stride: usize) -> Vec<f64> {
    let mut out = vec![0.0; (f.len() - 1) * stride + 1];
    for (k, v) in f.iter().enumerate() {
        out[k * stride] = *v;
    }
    out
}

impl<const N: usize> LaneDenoiser<N> {
    /// Build a denoiser of `N` streams; fails on an unknown wavelet or an out-of-range setting.
    pub fn new(cfg: &StreamConfig) -> Result<Self, WaveletError> {
        let wavelet = Wavelet::by_name(&cfg.wavelet)?;
        if !(1..=MAX_LEVEL).contains(&cfg.level) {
            return Err(WaveletError::BadParameter(format!(
                "level must be 1 to {MAX_LEVEL}, got {}",
                cfg.level
            )));
        }
        if cfg.window < 2 {
            return Err(WaveletError::BadParameter(format!(
                "window must be at least 2 samples, got {}",
                cfg.window
            )));
        }
        if let Sigma::Fixed(s) = cfg.sigma {
            if !(s >= 0.0 && s.is_finite()) {
                return Err(WaveletError::BadParameter(format!(
                    "a fixed sigma must be finite and >= 0, got {s}"
                )));
            }
        }
        cfg.threshold.validate()?;
        let f = wavelet.filter_len();
        let full_lag = StreamConfig::full_lag(f, cfg.level);
        if cfg.lag > full_lag {
            return Err(WaveletError::BadParameter(format!(
                "lag {} is beyond the filter span: {} with {} at level {} already gives the full \
                 stationary-transform result",
                cfg.lag,
                full_lag,
                wavelet.name(),
                cfg.level
            )));
        }
        let (lo, hi) = (wavelet.dec_lo().to_vec(), wavelet.dec_hi().to_vec());
        let mut lowpass = vec![1.0];
        let mut levels = Vec::with_capacity(cfg.level);
        for j in 1..=cfg.level {
            let stride = 1usize << (j - 1);
            let equivalent = convolve(&lowpass, &dilate(&hi, stride));
            lowpass = convolve(&lowpass, &dilate(&lo, stride));
            let taps = equivalent.len().min(cfg.lag + 1);
            let scale = 0.5f64.powi(j as i32);
            levels.push(Level {
                input: History::new((f - 1) * stride + 1, [0.0; N]),
                stride,
                removed: std::array::from_fn(|_| History::new(cfg.lag + 1, 0.0)),
                synthesis: equivalent[..taps].iter().map(|g| g * scale).collect(),
            });
        }
        Ok(LaneDenoiser {
            lo,
            hi,
            levels,
            input: History::new(cfg.lag + 1, [0.0; N]),
            threshold: cfg.threshold,
            sigma: cfg.sigma,
            noise: std::array::from_fn(|_| MedianTracker::new(cfg.window)),
            universal: (2.0 * (cfg.window as f64).ln()).sqrt(),
            lambda: [0.0; N],
            lag: cfg.lag,
            full_lag,
            pushed: 0,
            flushed: 0,
        })
    }

    /// Read the state the next [`push`](Self::push) touches (one value per cache line), so
    /// that a push after a long idle time finds it in the cache; changes nothing. A daemon
    /// pacing samples calls it shortly before each is due.
    pub fn prewarm(&self) {
        let step = (8 / N).max(1);
        let lines = |v: &[[f64; N]]| v.iter().step_by(step).map(|l| l[0]).sum::<f64>();
        let mut s = lines(&self.input.buf);
        for noise in &self.noise {
            let recent = &noise.recent;
            s += noise
                .sorted
                .iter()
                .step_by(8)
                .map(|b| f64::from_bits(*b))
                .sum::<f64>()
                + recent.buf[recent.pos]
                + recent.buf[recent.pos + recent.cap]
                + recent.ago(recent.cap - 1);
        }
        for level in &self.levels {
            s += lines(&level.input.buf) + level.synthesis.iter().step_by(8).sum::<f64>();
            for removed in &level.removed {
                s += removed.buf.iter().step_by(8).sum::<f64>();
            }
        }
        std::hint::black_box(s);
    }

    /// The algorithmic delay in samples.
    pub fn lag(&self) -> usize {
        self.lag
    }

    /// The threshold lambda of each stream in force after the latest sample.
    pub fn lambda(&self) -> [f64; N] {
        self.lambda
    }

    /// The noise sigma of each stream in force after the latest sample.
    pub fn sigma(&self) -> [f64; N] {
        std::array::from_fn(|n| match self.sigma {
            Sigma::Fixed(s) => s,
            Sigma::Mad => self.noise[n].median() / super::denoise::MAD_TO_SIGMA,
        })
    }

    /// Samples pushed since the start (or the last [`reset`](Self::reset)).
    pub fn pushed(&self) -> u64 {
        self.pushed
    }

    /// Whether the latest output still depends on the start-up extension (its analysis reached
    /// back before the first sample), or the noise window is not yet full (the same for every
    /// stream: each window counts every push).
    pub fn warming_up(&self) -> bool {
        let window_full = self.noise.iter().all(|n| n.count == n.recent.cap);
        // The latest output t = pushed - 1 - lag is clean once t >= full_lag.
        self.pushed < (self.full_lag + self.lag + 1) as u64
            || (matches!(self.sigma, Sigma::Mad) && !window_full)
    }

    /// Forget everything: the next push starts a new stream.
    pub fn reset(&mut self) {
        self.pushed = 0;
        self.flushed = 0;
        for noise in &mut self.noise {
            *noise = MedianTracker::new(noise.recent.cap);
        }
        self.lambda = [0.0; N];
    }

    /// Feed one sample of each stream; returns the denoised samples from `lag` samples ago once
    /// that many have arrived. A non-finite sample is replaced by the stream's previous one (the
    /// caller flags it), so the output never turns NaN. Pushing after [`flush`](Self::flush)
    /// starts new streams.
    pub fn push(&mut self, x: [f64; N]) -> Option<[f64; N]> {
        if self.flushed > 0 {
            self.reset();
        }
        let previous = if self.pushed > 0 {
            self.input.ago(0)
        } else {
            [0.0; N]
        };
        let x: [f64; N] =
            std::array::from_fn(|n| if x[n].is_finite() { x[n] } else { previous[n] });
        if self.pushed == 0 {
            self.start(x);
        }
        self.pushed += 1;
        self.input.push(x);
        let mut a = x;
        let mut details = [[0.0; N]; MAX_LEVEL];
        for (level, detail) in self.levels.iter_mut().zip(&mut details) {
            level.input.push(a);
            // Both sums in locals: accumulated in `details` itself, each addition waited on a
            // store and a reload.
            let (mut next, mut d) = ([0.0; N], [0.0; N]);
            // In tap order, one sum per lane: a detail that is zero in exact arithmetic comes
            // out as the same exact zero or not as before, and exact zeros are left out of the
            // noise median (a reassociated sum moved the median of quantised input).
            for (k, (h, g)) in self.lo.iter().zip(&self.hi).enumerate() {
                let v = level.input.ago(k * level.stride);
                for n in 0..N {
                    next[n] += h * v[n];
                    d[n] += g * v[n];
                }
            }
            *detail = d;
            a = next;
        }
        for (n, noise) in self.noise.iter_mut().enumerate() {
            self.lambda[n] = match self.sigma {
                Sigma::Fixed(s) => s * self.universal,
                Sigma::Mad => {
                    noise.push(details[0][n]);
                    noise.median() / super::denoise::MAD_TO_SIGMA * self.universal
                }
            };
        }
        for (level, d) in self.levels.iter_mut().zip(&details) {
            for (n, removed) in level.removed.iter_mut().enumerate() {
                removed.push(d[n] - self.threshold.apply(d[n], self.lambda[n]));
            }
        }
        (self.pushed > self.lag as u64).then(|| self.output(self.lag))
    }

    /// Drain the samples still held at the end of the streams, one per call, oldest first;
    /// `None` once all are out. Their sums are truncated at the newest sample, as with a
    /// smaller lag.
    pub fn flush(&mut self) -> Option<[f64; N]> {
        let held = self.pushed.min(self.lag as u64) as usize;
        if self.flushed >= held {
            return None;
        }
        let ago = held - 1 - self.flushed;
        self.flushed += 1;
        Some(self.output(ago))
    }

    /// Prime every history with the constant extension of the first samples.
    fn start(&mut self, x: [f64; N]) {
        self.input.fill(x);
        // A constant c has approximation c * (sum lo)^j = c * sqrt(2)^j and zero details.
        let gain: f64 = self.lo.iter().sum();
        let mut a = x;
        for level in &mut self.levels {
            level.input.fill(a);
            for removed in &mut level.removed {
                removed.fill(0.0);
            }
            a = a.map(|v| v * gain);
        }
    }

    /// The denoised samples pushed `ago` pushes ago, from the removed parts known so far.
    #[inline]
    fn output(&self, ago: usize) -> [f64; N] {
        let mut removed = [0.0; N];
        for level in &self.levels {
            let taps = level.synthesis.len().min(ago + 1);
            let c = &level.synthesis[..taps];
            for (n, e) in level.removed.iter().enumerate() {
                removed[n] += dot4(c, e.run_from(ago, taps));
            }
        }
        let x = self.input.ago(ago);
        std::array::from_fn(|n| x[n] - removed[n])
    }
}

/// `c . e` in four partial sums (tap k into sum k mod 4, in increasing k), added as
/// `(s0 + s1) + (s2 + s3)`: one chain of hundreds of dependent additions would wait on each
/// one's latency, and four side by side are one vector operation.
#[inline]
fn dot4(c: &[f64], e: &[f64]) -> f64 {
    let mut sum = [0.0; 4];
    let whole = c.len() - c.len() % 4;
    for (c4, e4) in c[..whole].chunks_exact(4).zip(e[..whole].chunks_exact(4)) {
        for q in 0..4 {
            sum[q] += c4[q] * e4[q];
        }
    }
    for (c, v) in c[whole..].iter().zip(&e[whole..]) {
        sum[0] += c * v;
    }
    (sum[0] + sum[1]) + (sum[2] + sum[3])
}

impl StreamingDenoiser {
    /// Build a denoiser; fails on an unknown wavelet or an out-of-range setting.
    pub fn new(cfg: &StreamConfig) -> Result<Self, WaveletError> {
        LaneDenoiser::new(cfg).map(StreamingDenoiser)
    }

    /// See [`LaneDenoiser::prewarm`].
    pub fn prewarm(&self) {
        self.0.prewarm();
    }

    /// The algorithmic delay in samples.
    pub fn lag(&self) -> usize {
        self.0.lag()
    }

    /// The threshold lambda in force after the latest sample.
    pub fn lambda(&self) -> f64 {
        self.0.lambda()[0]
    }

    /// The noise sigma in force after the latest sample.
    pub fn sigma(&self) -> f64 {
        self.0.sigma()[0]
    }

    /// Samples pushed since the start (or the last [`reset`](Self::reset)).
    pub fn pushed(&self) -> u64 {
        self.0.pushed()
    }

    /// Whether the latest output still depends on the start-up extension (its analysis reached
    /// back before the first sample), or the noise window is not yet full.
    pub fn warming_up(&self) -> bool {
        self.0.warming_up()
    }

    /// Forget everything: the next push starts a new stream.
    pub fn reset(&mut self) {
        self.0.reset();
    }

    /// Feed one sample; returns the denoised sample from `lag` samples ago once that many have
    /// arrived. A non-finite sample is replaced by the previous one (the caller flags it), so the
    /// output never turns NaN. Pushing after [`flush`](Self::flush) starts a new stream.
    pub fn push(&mut self, x: f64) -> Option<f64> {
        self.0.push([x]).map(|[v]| v)
    }

    /// Drain the samples still held at the end of a stream, one per call, oldest first; `None`
    /// once all are out. Their sums are truncated at the newest sample, as with a smaller lag.
    pub fn flush(&mut self) -> Option<f64> {
        self.0.flush().map(|[v]| v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(lag: usize, threshold: ThresholdFn, sigma: Sigma) -> StreamConfig {
        StreamConfig {
            lag,
            threshold,
            sigma,
            ..StreamConfig::default()
        }
    }

    fn run(d: &mut StreamingDenoiser, x: &[f64]) -> Vec<f64> {
        let mut out: Vec<f64> = x.iter().filter_map(|v| d.push(*v)).collect();
        while let Some(v) = d.flush() {
            out.push(v);
        }
        out
    }

    fn signal(n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| {
                let t = i as f64 * 0.02;
                (1.3 * t).sin()
                    + 0.5 * (7.0 * t).cos()
                    + 0.3 * ((i * 7919 % 1013) as f64 / 1013.0 - 0.5)
            })
            .collect()
    }

    /// Equivalent filters written out independently of the streaming code.
    fn equivalent_filters(w: &Wavelet, levels: usize) -> (Vec<Vec<f64>>, Vec<f64>) {
        let mut low = vec![1.0];
        let mut details = Vec::new();
        for j in 1..=levels {
            let s = 1 << (j - 1);
            details.push(convolve(&low, &dilate(w.dec_hi(), s)));
            low = convolve(&low, &dilate(w.dec_lo(), s));
        }
        (details, low)
    }

    /// Causal convolution of `x` (extended before its start by x[0]) with `f`.
    fn causal(x: &[f64], f: &[f64]) -> Vec<f64> {
        (0..x.len())
            .map(|t| {
                // Before the start, the first sample repeats (the denoiser's start-up extension).
                f.iter()
                    .enumerate()
                    .map(|(k, c)| c * x[t.saturating_sub(k)])
                    .sum()
            })
            .collect()
    }

    #[test]
    fn equals_direct_stationary_transform_at_every_lag() {
        let x = signal(1500);
        let w = Wavelet::by_name("db6").unwrap();
        let (g, _) = equivalent_filters(&w, 5);
        let sigma = 0.1;
        let f = ThresholdFn::Soft;
        for lag in [0, 1, 11, 40, 200, 341] {
            let mut d = StreamingDenoiser::new(&cfg(lag, f, Sigma::Fixed(sigma))).unwrap();
            let lambda = sigma * (2.0 * (StreamConfig::DEFAULT_WINDOW as f64).ln()).sqrt();
            let got = run(&mut d, &x);
            assert_eq!(got.len(), x.len());
            let removed: Vec<Vec<f64>> = g
                .iter()
                .map(|gj| {
                    causal(&x, gj)
                        .iter()
                        .map(|v| v - f.apply(*v, lambda))
                        .collect()
                })
                .collect();
            for t in 0..x.len() {
                let mut want = x[t];
                for (j, (gj, e)) in g.iter().zip(&removed).enumerate() {
                    for (k, c) in gj.iter().enumerate() {
                        if k <= lag && t + k < x.len() {
                            want -= c * 0.5f64.powi(j as i32 + 1) * e[t + k];
                        }
                    }
                }
                assert!(
                    (got[t] - want).abs() < 1e-12,
                    "lag {lag} t {t}: {} vs {want}",
                    got[t]
                );
            }
        }
    }

    #[test]
    fn killing_every_detail_leaves_the_stationary_low_band() {
        // Perfect reconstruction: x = low band + sum of detail syntheses, so removing all details
        // must leave 2^-J sum_k H_J[k] a_J[t + k] with a_J = H_J * x.
        let x = signal(2000);
        let w = Wavelet::by_name("db6").unwrap();
        let (_, h) = equivalent_filters(&w, 5);
        let mut d =
            StreamingDenoiser::new(&cfg(341, ThresholdFn::Hard, Sigma::Fixed(1e9))).unwrap();
        let got = run(&mut d, &x);
        let a = causal(&x, &h);
        for t in 400..x.len() - 400 {
            let low: f64 = h.iter().enumerate().map(|(k, c)| c * a[t + k]).sum::<f64>() / 32.0;
            assert!((got[t] - low).abs() < 1e-11, "t {t}: {} vs {low}", got[t]);
        }
    }

    #[test]
    fn polynomials_pass_unchanged() {
        // db6 has six vanishing moments: a quintic has no details at any level.
        let x: Vec<f64> = (0..3000)
            .map(|i| {
                let t = i as f64 / 3000.0;
                1.0 + 2.0 * t - 3.0 * t * t + 0.5 * t.powi(5)
            })
            .collect();
        let mut d = StreamingDenoiser::new(&cfg(64, ThresholdFn::Hard, Sigma::Fixed(1e9))).unwrap();
        let got = run(&mut d, &x);
        for t in 400..2900 {
            assert!(
                (got[t] - x[t]).abs() < 1e-9,
                "t {t}: {} vs {}",
                got[t],
                x[t]
            );
        }
    }

    #[test]
    fn lag_zero_answers_at_once_and_counts_match() {
        let mut d = StreamingDenoiser::new(&cfg(0, ThresholdFn::Soft, Sigma::Mad)).unwrap();
        assert!(d.push(1.0).is_some());
        assert!(d.flush().is_none());
        let mut d = StreamingDenoiser::new(&cfg(100, ThresholdFn::Soft, Sigma::Mad)).unwrap();
        assert_eq!((0..50).filter_map(|i| d.push(i as f64)).count(), 0);
        assert_eq!(std::iter::from_fn(|| d.flush()).count(), 50);
        // Pushing after a flush starts over.
        assert_eq!(d.pushed(), 50);
        assert!(d.push(1.0).is_none());
        assert_eq!(d.pushed(), 1);
    }

    #[test]
    fn non_finite_input_never_reaches_the_output() {
        let mut d = StreamingDenoiser::new(&StreamConfig::default()).unwrap();
        let mut x = signal(3000);
        x[1000] = f64::NAN;
        x[2000] = f64::INFINITY;
        let out = run(&mut d, &x);
        assert_eq!(out.len(), x.len());
        assert!(out.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn lanes_equal_one_stream_denoisers_bit_for_bit() {
        let x = signal(4000);
        let y: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(i, v)| match i % 401 {
                3 => f64::NAN,
                5 => 0.0,
                _ => -2.0 * v,
            })
            .collect();
        for cfg in [
            cfg(33, ThresholdFn::improved_default(), Sigma::Mad),
            cfg(0, ThresholdFn::Soft, Sigma::Fixed(0.2)),
        ] {
            let mut lanes = LaneDenoiser::<2>::new(&cfg).unwrap();
            let mut one = [0, 1].map(|_| StreamingDenoiser::new(&cfg).unwrap());
            // Two streams, flushed halfway (the next push starts new streams).
            for (i, (a, b)) in x.iter().zip(&y).enumerate() {
                let got = lanes.push([*a, *b]).map(|v| v.map(f64::to_bits));
                let want = one[0].push(*a).zip(one[1].push(*b));
                assert_eq!(got, want.map(|(p, q)| [p.to_bits(), q.to_bits()]), "{i}");
                if i == 2000 {
                    while let Some(v) = lanes.flush() {
                        let w = [one[0].flush().unwrap(), one[1].flush().unwrap()];
                        assert_eq!(v.map(f64::to_bits), w.map(f64::to_bits));
                    }
                    assert!(one[0].flush().is_none());
                }
            }
            assert_eq!(lanes.lambda()[1].to_bits(), one[1].lambda().to_bits());
            assert_eq!(lanes.warming_up(), one[0].warming_up());
        }
    }

    /// Values as detail coefficients have them (repeats, exact zeros, sign changes), random and
    /// quantised values, and runs: rising, falling, one value only.
    fn median_inputs(n: usize) -> Vec<Vec<f64>> {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mixed: Vec<f64> = (0..n)
            .map(|i| match i % 7 {
                0 => 0.0,
                3 => -(((i * 31) % 17) as f64),
                _ => ((i * 7919) % 101) as f64 * 0.25,
            })
            .collect();
        let random: Vec<f64> = (0..n).map(|_| (next() >> 11) as f64 - 2e15).collect();
        let quantised: Vec<f64> = (0..n).map(|_| (next() % 5) as f64 * 0.5).collect();
        let rising: Vec<f64> = (0..n).map(|i| (i % 997) as f64).collect();
        let falling: Vec<f64> = (0..n).map(|i| (n - i) as f64).collect();
        let constant = vec![3.0; n];
        vec![mixed, random, quantised, rising, falling, constant]
    }

    #[test]
    fn median_tracker_equals_a_sorted_copy_of_the_window() {
        for window in [2, 3, 5, 16, 64, 100, 1024] {
            for (case, input) in median_inputs(3000).iter().enumerate() {
                let mut t = MedianTracker::new(window);
                let mut held: Vec<f64> = Vec::new();
                for (i, v) in input.iter().enumerate() {
                    t.push(*v);
                    held.push(v.abs());
                    if held.len() > window {
                        held.remove(0);
                    }
                    let mut nonzero: Vec<f64> =
                        held.iter().copied().filter(|x| *x != 0.0).collect();
                    nonzero.sort_by(f64::total_cmp);
                    let n = nonzero.len();
                    let want = match n {
                        0 => 0.0,
                        _ if n % 2 == 1 => nonzero[n / 2],
                        _ => 0.5 * (nonzero[n / 2 - 1] + nonzero[n / 2]),
                    };
                    let sorted: Vec<f64> = t.sorted.iter().map(|b| f64::from_bits(*b)).collect();
                    assert_eq!(sorted, nonzero, "window {window}, case {case}, sample {i}");
                    assert_eq!(t.median(), want, "window {window}, case {case}, sample {i}");
                }
            }
        }
    }

    #[test]
    fn tracks_sigma_of_white_noise() {
        use rand::SeedableRng;
        use rand_distr::Distribution;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let n = rand_distr::Normal::new(0.0, 0.7).unwrap();
        let mut d = StreamingDenoiser::new(&StreamConfig::default()).unwrap();
        for _ in 0..5000 {
            d.push(n.sample(&mut rng));
        }
        assert!((d.sigma() / 0.7 - 1.0).abs() < 0.08, "sigma {}", d.sigma());
        assert!(!d.warming_up());
    }

    #[test]
    fn settings_out_of_range_are_refused() {
        let bad = |c: StreamConfig| StreamingDenoiser::new(&c).unwrap_err().to_string();
        let base = StreamConfig::default;
        assert!(bad(StreamConfig { lag: 342, ..base() }).contains("341"));
        assert!(bad(StreamConfig {
            window: 1,
            ..base()
        })
        .contains("window"));
        assert!(bad(StreamConfig { level: 0, ..base() }).contains("level"));
        assert!(bad(StreamConfig {
            wavelet: "db0".into(),
            ..base()
        })
        .contains("unknown wavelet"));
        assert!(bad(StreamConfig {
            sigma: Sigma::Fixed(f64::NAN),
            ..base()
        })
        .contains("sigma"));
    }
}
