//! Discrete wavelet transform with PyWavelets' conventions (coefficient lengths, values, modes).
//!
//! Checked against PyWavelets 1.9.0 fixtures in `tests/pywavelets.rs` (1e-12 relative).
//!
//! How it works: each level first writes the mode-extended signal once into scratch, split into
//! its even and odd samples (polyphase), so the filters become straight, branch-free dot products
//! that vectorise. Short signals are extended the way PyWavelets' C code does it (mirrors and
//! periods repeated as often as the filter needs). [`Plan`] owns that scratch, so repeated
//! transforms of equal-length windows allocate nothing; the free functions use the same kernels
//! and give bit-identical results.

use super::{Wavelet, WaveletError};
use crate::bigbuf::Scratch;
use std::ops::Range;

/// Defines `fn` so that its body runs compiled for the widest vector unit the CPU has (AVX-512,
/// AVX2, else the build's baseline), chosen at run time: the kernels' lane-wise loops then take
/// 8 or 4 outputs per instruction instead of 2. Rust never contracts `a * b + c` into a fused
/// multiply-add, so every variant computes the same operations in the same order: the same bits
/// (tested: `every_vector_unit_gives_the_same_bits`). The variants sit in a module of the same
/// name. No crate needed for these few lines (`multiversion` does the same with a proc macro).
macro_rules! widest_vectors {
    ($(#[$attr:meta])* fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $body:block) => {
        $(#[$attr])*
        fn $name($($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            {
                if std::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU has the feature the variant was compiled for.
                    return unsafe { $name::avx512($($arg),*) };
                }
                if std::is_x86_feature_detected!("avx2") {
                    // SAFETY: as above.
                    return unsafe { $name::avx2($($arg),*) };
                }
            }
            $name::portable($($arg),*)
        }

        mod $name {
            #[allow(unused_imports)]
            use super::*;

            #[inline(always)]
            pub(super) fn portable($($arg: $ty),*) $body

            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx512f")]
            pub(super) fn avx512($($arg: $ty),*) {
                portable($($arg),*)
            }

            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2")]
            pub(super) fn avx2($($arg: $ty),*) {
                portable($($arg),*)
            }
        }
    };
}
pub(crate) use widest_vectors;

/// Signal extension at the edges, as PyWavelets names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum Mode {
    /// Zero padding.
    Zero,
    /// Edge value repeated.
    Constant,
    /// Mirrored with the edge sample repeated (PyWavelets' default).
    #[default]
    Symmetric,
    /// Mirrored about the edge sample.
    Reflect,
    /// Periodic continuation (coefficients longer than N/2).
    Periodic,
    /// First-derivative extrapolation.
    Smooth,
    /// Periodic, with exactly ceil(N/2) coefficients per level.
    Periodization,
}

impl Mode {
    /// Every mode.
    pub const ALL: [Mode; 7] = [
        Mode::Zero,
        Mode::Constant,
        Mode::Symmetric,
        Mode::Reflect,
        Mode::Periodic,
        Mode::Smooth,
        Mode::Periodization,
    ];

    /// PyWavelets' name for the mode.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Zero => "zero",
            Mode::Constant => "constant",
            Mode::Symmetric => "symmetric",
            Mode::Reflect => "reflect",
            Mode::Periodic => "periodic",
            Mode::Smooth => "smooth",
            Mode::Periodization => "periodization",
        }
    }
}

impl std::str::FromStr for Mode {
    type Err = WaveletError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Mode::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| WaveletError::UnknownMode(s.to_string()))
    }
}

impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Length of each single-level output for an input of length `n`: floor((n + F - 1) / 2), or
/// ceil(n / 2) for [`Mode::Periodization`]. Zero for an empty input, as in PyWavelets.
pub fn dwt_coeff_len(n: usize, filter_len: usize, mode: Mode) -> usize {
    if n == 0 || filter_len == 0 {
        return 0;
    }
    match mode {
        Mode::Periodization => n.div_ceil(2),
        _ => (n + filter_len - 1) / 2,
    }
}

/// Deepest useful level: floor(log2(n / (F - 1))), 0 when n < F - 1.
pub fn dwt_max_level(n: usize, filter_len: usize) -> usize {
    if filter_len < 2 || n < filter_len - 1 {
        return 0;
    }
    // floor(log2(floor(q))) == floor(log2(q)) for q >= 1, so integer division is exact here.
    (n / (filter_len - 1)).ilog2() as usize
}

/// Smallest signal length whose [`dwt_max_level`] reaches `level`: (F - 1) * 2^level
/// (saturating at `usize::MAX`).
pub fn min_len_for_level(filter_len: usize, level: usize) -> usize {
    if level >= usize::BITS as usize {
        return usize::MAX;
    }
    let base = filter_len.saturating_sub(1).max(1);
    base.saturating_mul(1usize << level)
}

/// Single-level transform: (cA, cD).
///
/// Works for every `x.len() >= 1` exactly as PyWavelets does (signals shorter than the filter
/// are extended repeatedly). One deliberate difference: PyWavelets refuses [`Mode::Reflect`] on a
/// single sample; here its reflection is the sample itself (a constant extension). An empty input
/// gives empty outputs.
pub fn dwt(x: &[f64], w: &Wavelet, mode: Mode) -> (Vec<f64>, Vec<f64>) {
    let nc = dwt_coeff_len(x.len(), w.filter_len(), mode);
    let mut ca = vec![0.0; nc];
    let mut cd = vec![0.0; nc];
    dwt_into(x, w, mode, &mut ca, &mut cd);
    (ca, cd)
}

/// Single-level transform into caller buffers of length [`dwt_coeff_len`].
///
/// # Panics
/// If `ca` or `cd` does not have length `dwt_coeff_len(x.len(), F, mode)`.
pub fn dwt_into(x: &[f64], w: &Wavelet, mode: Mode, ca: &mut [f64], cd: &mut [f64]) {
    let taps = Taps::new(w);
    let nc = dwt_coeff_len(x.len(), taps.f, mode);
    assert!(
        ca.len() == nc && cd.len() == nc,
        "dwt_into: outputs must have length {nc}, got {} and {}",
        ca.len(),
        cd.len()
    );
    let half = ext_half_len(nc, taps.f);
    let mut ev = vec![0.0; half];
    let mut od = vec![0.0; half];
    extend(x, mode, taps.f, &mut ev, &mut od);
    dwt_filter(&taps, &ev, &od, ca, cd);
}

/// Length of [`idwt`]'s output from coefficients of length `coeff_len`: 2 * len - F + 2, or
/// 2 * len for [`Mode::Periodization`]. Zero when `coeff_len < F / 2` outside periodization
/// (PyWavelets raises an error there; no output sample is fully determined).
pub fn idwt_len(coeff_len: usize, filter_len: usize, mode: Mode) -> usize {
    match mode {
        Mode::Periodization => 2 * coeff_len,
        _ if coeff_len == 0 => 0,
        _ => (2 * coeff_len + 2).saturating_sub(filter_len),
    }
}

/// Single-level inverse transform of equal-length (cA, cD).
///
/// # Panics
/// If `ca` and `cd` differ in length.
pub fn idwt(ca: &[f64], cd: &[f64], w: &Wavelet, mode: Mode) -> Vec<f64> {
    let mut out = vec![0.0; idwt_len(ca.len(), w.filter_len(), mode)];
    idwt_into(ca, cd, w, mode, &mut out);
    out
}

/// Single-level inverse into a caller buffer of length [`idwt_len`].
///
/// # Panics
/// If `ca` and `cd` differ in length, or `out` does not have length [`idwt_len`].
pub fn idwt_into(ca: &[f64], cd: &[f64], w: &Wavelet, mode: Mode, out: &mut [f64]) {
    assert_eq!(
        ca.len(),
        cd.len(),
        "idwt: cA and cD must have equal lengths"
    );
    let taps = Taps::new(w);
    let want = idwt_len(ca.len(), taps.f, mode);
    assert_eq!(out.len(), want, "idwt_into: output must have length {want}");
    let len = coeff_ext_len(ca.len(), taps.h, mode);
    let mut ea = vec![0.0; len];
    let mut ed = vec![0.0; len];
    coeff_extend(ca, taps.h, mode, &mut ea);
    coeff_extend(cd, taps.h, mode, &mut ed);
    idwt_filter(&taps, mode, &ea, &ed, out);
}

/// Multilevel decomposition, PyWavelets' order: `[cA_level, cD_level, ..., cD_1]`.
///
/// Unlike PyWavelets (which only warns), a `level` above [`dwt_max_level`] is refused with
/// [`WaveletError::TooShort`], saying how many samples that level needs; level 0 is a
/// [`WaveletError::BadParameter`].
pub fn wavedec(
    x: &[f64],
    w: &Wavelet,
    mode: Mode,
    level: usize,
) -> Result<Vec<Vec<f64>>, WaveletError> {
    // One code path with the plan, so both give bit-identical coefficients.
    let mut plan = Plan::new(w, mode, x.len(), level)?;
    let mut flat = vec![0.0; plan.coeffs_len()];
    plan.wavedec(x, &mut flat);
    Ok(plan
        .ranges()
        .iter()
        .map(|r| flat[r.clone()].to_vec())
        .collect())
}

/// Multilevel reconstruction from [`wavedec`]'s output (may be one sample longer than the
/// original for odd lengths, as in PyWavelets).
///
/// As PyWavelets, an approximation one longer than the next detail band is trimmed; other length
/// mismatches, and (outside periodization) bands shorter than F / 2, are
/// [`WaveletError::BadParameter`]. A single band is returned as is.
pub fn waverec(coeffs: &[Vec<f64>], w: &Wavelet, mode: Mode) -> Result<Vec<f64>, WaveletError> {
    let (first, details) = coeffs
        .split_first()
        .ok_or_else(|| WaveletError::BadParameter("waverec: no coefficients".into()))?;
    let taps = Taps::new(w);
    let mut a = first.clone();
    for (k, d) in details.iter().enumerate() {
        if a.len() == d.len() + 1 {
            a.truncate(d.len());
        } else if a.len() != d.len() {
            return Err(WaveletError::BadParameter(format!(
                "waverec: approximation of length {} does not fit detail band {} of length {}",
                a.len(),
                k + 1,
                d.len()
            )));
        }
        if mode != Mode::Periodization && d.len() < taps.h {
            return Err(WaveletError::BadParameter(format!(
                "waverec: band {} has {} coefficients, {} needs at least {} in mode {mode}",
                k + 1,
                d.len(),
                w.name(),
                taps.h
            )));
        }
        let len = coeff_ext_len(d.len(), taps.h, mode);
        let mut ea = vec![0.0; len];
        let mut ed = vec![0.0; len];
        coeff_extend(&a, taps.h, mode, &mut ea);
        coeff_extend(d, taps.h, mode, &mut ed);
        a = vec![0.0; idwt_len(d.len(), taps.f, mode)];
        idwt_filter(&taps, mode, &ea, &ed, &mut a);
    }
    Ok(a)
}

/// A multilevel transform planned for one signal length, working in caller-owned buffers so that
/// repeated calls on equal-length windows allocate nothing. Levels of [`SPLIT_MIN`] coefficients
/// or more are shared out over rayon's thread pool (same bits; the pool may allocate), shorter
/// ones run on the calling thread alone.
///
/// Results are bit-identical to [`wavedec`] and to the first [`Plan::signal_len`] samples of
/// [`waverec`].
#[derive(Debug, Clone)]
pub struct Plan {
    taps: Taps,
    mode: Mode,
    level: usize,
    /// Signal length entering each level: `lens[0] = n`, `lens[k]` = length of cA_k.
    lens: Vec<usize>,
    ranges: Vec<Range<usize>>,
    /// Polyphase halves of the extended signal (dwt) or extended cA / cD (idwt).
    ev: Scratch,
    od: Scratch,
    /// Intermediate approximation between levels.
    approx: Scratch,
}

impl Plan {
    /// Plan `level` levels of `w` in `mode` for signals of length `n`.
    ///
    /// Errors: level 0 is [`WaveletError::BadParameter`]; a level above
    /// [`dwt_max_level`]`(n, F)` is [`WaveletError::TooShort`].
    pub fn new(w: &Wavelet, mode: Mode, n: usize, level: usize) -> Result<Plan, WaveletError> {
        let f = w.filter_len();
        if level == 0 {
            return Err(WaveletError::BadParameter(
                "decomposition level must be at least 1".into(),
            ));
        }
        if level > dwt_max_level(n, f) {
            return Err(WaveletError::TooShort {
                level,
                wavelet: w.name().to_string(),
                needed: min_len_for_level(f, level),
                got: n,
            });
        }
        let taps = Taps::new(w);
        let mut lens = vec![n];
        for k in 0..level {
            lens.push(dwt_coeff_len(lens[k], f, mode));
        }
        // PyWavelets' order: cA_L, cD_L, cD_{L-1}, ..., cD_1.
        let mut ranges = Vec::with_capacity(level + 1);
        let mut start = 0;
        for k in std::iter::once(level).chain((1..=level).rev()) {
            ranges.push(start..start + lens[k]);
            start += lens[k];
        }
        // Scratch sized for the largest level (level 1 for both directions).
        let half = ext_half_len(lens[1], f).max(coeff_ext_len(lens[1], taps.h, mode));
        Ok(Plan {
            taps,
            mode,
            level,
            ev: Scratch::for_overwrite(half),
            od: Scratch::for_overwrite(half),
            approx: Scratch::for_overwrite(lens[1]),
            lens,
            ranges,
        })
    }

    /// Signal length this plan takes.
    pub fn signal_len(&self) -> usize {
        self.lens[0]
    }

    /// Number of levels.
    pub fn level(&self) -> usize {
        self.level
    }

    /// Length of the flat coefficient buffer.
    pub fn coeffs_len(&self) -> usize {
        self.ranges.last().map_or(0, |r| r.end)
    }

    /// Where each band sits in the flat buffer, PyWavelets' order: `[cA_n, cD_n, ..., cD_1]`.
    pub fn ranges(&self) -> &[Range<usize>] {
        &self.ranges
    }

    /// The plan's own work buffer, free between calls (nothing in it is kept): room for at least
    /// the largest band, so that a caller needs no buffer of its own for a copy of one.
    pub(crate) fn spare(&mut self) -> &mut [f64] {
        &mut self.ev
    }

    /// Decompose `x` (length [`Plan::signal_len`]) into `coeffs` (length [`Plan::coeffs_len`]).
    ///
    /// # Panics
    /// If a buffer has the wrong length.
    pub fn wavedec(&mut self, x: &[f64], coeffs: &mut [f64]) {
        assert_eq!(x.len(), self.signal_len(), "Plan::wavedec: signal length");
        assert_eq!(
            coeffs.len(),
            self.coeffs_len(),
            "Plan::wavedec: coeffs length"
        );
        let f = self.taps.f;
        let last = self.level;
        // cA_L sits first in `coeffs`; the detail bands follow it.
        let (ca_last, details) = coeffs.split_at_mut(self.lens[last]);
        for k in 1..=last {
            let (n_in, nc) = (self.lens[k - 1], self.lens[k]);
            let half = ext_half_len(nc, f);
            let (ev, od) = (&mut self.ev[..half], &mut self.od[..half]);
            let input = if k == 1 { x } else { &self.approx[..n_in] };
            extend(input, self.mode, f, ev, od);
            let r = &self.ranges[last - k + 1];
            let cd = &mut details[r.start - ca_last.len()..r.end - ca_last.len()];
            let ca = if k == last {
                &mut *ca_last
            } else {
                &mut self.approx[..nc]
            };
            dwt_filter(&self.taps, ev, od, ca, cd);
        }
    }

    /// Reconstruct the first [`Plan::signal_len`] samples from `coeffs` into `out`.
    ///
    /// # Panics
    /// If a buffer has the wrong length.
    pub fn waverec(&mut self, coeffs: &[f64], out: &mut [f64]) {
        assert_eq!(
            coeffs.len(),
            self.coeffs_len(),
            "Plan::waverec: coeffs length"
        );
        assert_eq!(out.len(), self.signal_len(), "Plan::waverec: output length");
        let (h, mode) = (self.taps.h, self.mode);
        let last = self.level;
        if mode != Mode::Periodization {
            // No extension to write (coeff_ext_len is the band's length): the filters read the
            // bands in place, and the approximations alternate between two buffers (a level's
            // output may not overwrite its input). The same values as the copying path below.
            let mut bufs = [&mut self.approx, &mut self.ev];
            for k in (1..=last).rev() {
                let [cur, next] = &mut bufs;
                let a = if k == last {
                    &coeffs[self.ranges[0].clone()]
                } else {
                    &cur[..self.lens[k]]
                };
                let d = &coeffs[self.ranges[last - k + 1].clone()];
                let dst = if k == 1 {
                    &mut *out
                } else {
                    &mut next[..self.lens[k - 1]]
                };
                idwt_filter(&self.taps, mode, a, d, dst);
                bufs.swap(0, 1);
            }
            return;
        }
        for k in (1..=last).rev() {
            let nc = self.lens[k];
            let len = coeff_ext_len(nc, h, mode);
            let (ea, ed) = (&mut self.ev[..len], &mut self.od[..len]);
            let a = if k == last {
                &coeffs[self.ranges[0].clone()]
            } else {
                &self.approx[..nc]
            };
            coeff_extend(a, h, mode, ea);
            coeff_extend(&coeffs[self.ranges[last - k + 1].clone()], h, mode, ed);
            // PyWavelets trims a one-too-long approximation; computing fewer samples is the same.
            let dst = if k == 1 {
                &mut *out
            } else {
                &mut self.approx[..self.lens[k - 1]]
            };
            idwt_filter(&self.taps, mode, ea, ed, dst);
        }
    }
}

/// The filters split into even and odd taps (polyphase), in the order the kernels consume them.
#[derive(Debug, Clone)]
struct Taps {
    /// Filter length F (even for every supported wavelet) and F / 2.
    f: usize,
    h: usize,
    /// Analysis: cA[o] = sum_s lo_e[s] * e[2o + 2s] + lo_o[s] * e[2o + 2s + 1] (F reversed).
    lo_e: Vec<f64>,
    lo_o: Vec<f64>,
    hi_e: Vec<f64>,
    hi_o: Vec<f64>,
    /// Synthesis, by parity q of the filter taps: g[q][t] = rec[2(h - 1 - t) + q].
    rlo: [Vec<f64>; 2],
    rhi: [Vec<f64>; 2],
}

impl Taps {
    fn new(w: &Wavelet) -> Taps {
        let f = w.filter_len();
        let h = f / 2;
        let rev =
            |v: &[f64], q: usize| -> Vec<f64> { (0..h).map(|s| v[f - 1 - 2 * s - q]).collect() };
        let syn =
            |v: &[f64], q: usize| -> Vec<f64> { (0..h).map(|t| v[2 * (h - 1 - t) + q]).collect() };
        Taps {
            f,
            h,
            lo_e: rev(w.dec_lo(), 0),
            lo_o: rev(w.dec_lo(), 1),
            hi_e: rev(w.dec_hi(), 0),
            hi_o: rev(w.dec_hi(), 1),
            rlo: [syn(w.rec_lo(), 0), syn(w.rec_lo(), 1)],
            rhi: [syn(w.rec_hi(), 0), syn(w.rec_hi(), 1)],
        }
    }
}

/// Length of each polyphase half of the extended signal that yields `nc` coefficients:
/// the extension covers 2 (nc - 1) + F samples (an even count, F being even).
fn ext_half_len(nc: usize, f: usize) -> usize {
    if nc == 0 {
        0
    } else {
        nc - 1 + f / 2
    }
}

/// Left padding of the extended signal: output o reads samples 2o + 2 - F ..= 2o + 1 (PyWavelets
/// starts at input index 1), or, in periodization, F / 2 + 2o - F + 1 ..= F / 2 + 2o.
fn left_pad(f: usize, mode: Mode) -> usize {
    match mode {
        Mode::Periodization => f / 2 - 1,
        _ => f - 2,
    }
}

/// Sample `m` (outside `0..n`) of `x` extended as PyWavelets' C code does, which for short
/// signals means repeating the mirror / period as often as the filter needs.
fn ext_value(x: &[f64], mode: Mode, m: isize) -> f64 {
    let n = x.len() as isize;
    let at = |i: isize| x[i as usize];
    let constant = || if m < 0 { at(0) } else { at(n - 1) };
    match mode {
        Mode::Zero => 0.0,
        Mode::Constant => constant(),
        Mode::Symmetric => {
            let r = m.rem_euclid(2 * n);
            if r < n {
                at(r)
            } else {
                at(2 * n - 1 - r)
            }
        }
        Mode::Reflect if n >= 2 => {
            let p = 2 * n - 2;
            let r = m.rem_euclid(p);
            if r < n {
                at(r)
            } else {
                at(p - r)
            }
        }
        // A lone sample reflects onto itself (PyWavelets refuses this case).
        Mode::Reflect => constant(),
        Mode::Periodic => at(m.rem_euclid(n)),
        // Same expression and operation order as PyWavelets, so bit-identical extrapolation.
        Mode::Smooth if n >= 2 => {
            if m < 0 {
                at(0) + (-m) as f64 * (at(0) - at(1))
            } else {
                at(n - 1) + (m - n + 1) as f64 * (at(n - 1) - at(n - 2))
            }
        }
        // PyWavelets falls back to constant for a single sample.
        Mode::Smooth => constant(),
        // Odd lengths are first padded with their last sample, then made periodic.
        Mode::Periodization => at(m.rem_euclid(n + n % 2).min(n - 1)),
    }
}

widest_vectors! {
/// Writes the extended signal e[k] = ext(k - left_pad) for k in 0..2 * ev.len() split into its
/// even (`ev`) and odd (`od`) samples. The mode is handled here, once per level, so the filter
/// loops are plain dot products.
fn extend(x: &[f64], mode: Mode, f: usize, ev: &mut [f64], od: &mut [f64]) {
    let n = x.len();
    let total = ev.len() + od.len();
    if n == 0 || total == 0 {
        return;
    }
    let left = left_pad(f, mode);
    let mut put = |k: usize, v: f64| {
        if k % 2 == 0 {
            ev[k / 2] = v;
        } else {
            od[k / 2] = v;
        }
    };
    for k in (0..left.min(total)).chain((left + n).min(total)..total) {
        put(k, ext_value(x, mode, k as isize - left as isize));
    }
    // The body is a de-interleaving copy: x[i] lands at k = left + i.
    let (a, b) = if left % 2 == 0 {
        (&mut *ev, &mut *od)
    } else {
        (&mut *od, &mut *ev)
    };
    let (a, b) = (&mut a[left / 2..], &mut b[left.div_ceil(2)..]);
    let pairs = x.chunks_exact(2);
    if let Some(&v) = pairs.remainder().first() {
        if let Some(dst) = a.get_mut(n / 2) {
            *dst = v;
        }
    }
    for ((pair, da), db) in pairs.zip(a.iter_mut()).zip(b.iter_mut()) {
        *da = pair[0];
        *db = pair[1];
    }
}
}

/// Outputs from which one filter pass is shared out between the cores (`rayon::join`, halving
/// until the pieces are smaller): below it the hand-off costs more than it saves. Every output is
/// computed the same way wherever a split falls, so the bits do not depend on the threads.
pub const SPLIT_MIN: usize = 1 << 15;

/// Analysis filters on an extended signal already split by [`extend`].
fn dwt_filter(taps: &Taps, ev: &[f64], od: &[f64], ca: &mut [f64], cd: &mut [f64]) {
    let n = ca.len();
    if n >= SPLIT_MIN {
        let mid = n / 2;
        let (ca0, ca1) = ca.split_at_mut(mid);
        let (cd0, cd1) = cd.split_at_mut(mid);
        rayon::join(
            || dwt_filter(taps, ev, od, ca0, cd0),
            || dwt_filter(taps, &ev[mid..], &od[mid..], ca1, cd1),
        );
    } else {
        dwt_filter_serial(taps, ev, od, ca, cd);
    }
}

widest_vectors! {
fn dwt_filter_serial(taps: &Taps, ev: &[f64], od: &[f64], ca: &mut [f64], cd: &mut [f64]) {
    fir2x2(
        [&taps.lo_e, &taps.lo_o, &taps.hi_e, &taps.hi_o],
        ev,
        od,
        [ca, cd],
    );
}
}

/// Outputs per idwt block (stack buffers of this many samples per parity).
const BLOCK: usize = 256;

/// Outputs computed together in registers by [`fir2`].
const LANES: usize = 8;

/// out[o] = sum_s ta[s] * sa[o + s] + tb[s] * sb[o + s].
///
/// Outputs go in groups of [`LANES`] whose accumulators stay in registers while the taps stream
/// by: lane-wise multiply-adds that the compiler vectorises, with each output still summed in tap
/// order (no reassociation, so every path gives the same bits).
#[inline(always)]
fn fir2(ta: &[f64], tb: &[f64], sa: &[f64], sb: &[f64], out: &mut [f64]) {
    let taps = ta.len();
    let n = out.len();
    assert!(tb.len() == taps && sa.len() + 1 >= n + taps && sb.len() + 1 >= n + taps);
    let mut groups = out.chunks_exact_mut(LANES);
    for (g, y) in groups.by_ref().enumerate() {
        let o0 = g * LANES;
        let (wa, wb) = (
            &sa[o0..o0 + LANES + taps - 1],
            &sb[o0..o0 + LANES + taps - 1],
        );
        let mut acc = [0.0f64; LANES];
        for (s, (&a, &b)) in ta.iter().zip(tb).enumerate() {
            let (xa, xb) = (&wa[s..s + LANES], &wb[s..s + LANES]);
            for k in 0..LANES {
                acc[k] += a * xa[k] + b * xb[k];
            }
        }
        y.copy_from_slice(&acc);
    }
    let done = n - groups.into_remainder().len();
    for (o, y) in out.iter_mut().enumerate().skip(done) {
        let mut acc = 0.0;
        for (s, (&a, &b)) in ta.iter().zip(tb).enumerate() {
            acc += a * sa[o + s] + b * sb[o + s];
        }
        *y = acc;
    }
}

/// Outputs per group in [`fir2x2`] (two accumulator sets: fewer lanes keep them in registers).
const PAIR_LANES: usize = 4;

/// Two [`fir2`]s over the same sources at once (sharing every load):
/// `outs[0]` from taps 0 and 1, `outs[1]` from taps 2 and 3. Same bits as two [`fir2`] calls.
#[inline(always)]
fn fir2x2(t: [&[f64]; 4], sa: &[f64], sb: &[f64], outs: [&mut [f64]; 2]) {
    let taps = t[0].len();
    let [out0, out1] = outs;
    let n = out0.len();
    assert!(t.iter().all(|v| v.len() == taps) && out1.len() == n);
    assert!(sa.len() + 1 >= n + taps && sb.len() + 1 >= n + taps);
    let done = n / PAIR_LANES * PAIR_LANES;
    for o0 in (0..done).step_by(PAIR_LANES) {
        let (wa, wb) = (
            &sa[o0..o0 + PAIR_LANES + taps - 1],
            &sb[o0..o0 + PAIR_LANES + taps - 1],
        );
        let mut acc0 = [0.0f64; PAIR_LANES];
        let mut acc1 = [0.0f64; PAIR_LANES];
        for s in 0..taps {
            let (a0, b0, a1, b1) = (t[0][s], t[1][s], t[2][s], t[3][s]);
            let (xa, xb) = (&wa[s..s + PAIR_LANES], &wb[s..s + PAIR_LANES]);
            for k in 0..PAIR_LANES {
                acc0[k] += a0 * xa[k] + b0 * xb[k];
                acc1[k] += a1 * xa[k] + b1 * xb[k];
            }
        }
        out0[o0..o0 + PAIR_LANES].copy_from_slice(&acc0);
        out1[o0..o0 + PAIR_LANES].copy_from_slice(&acc1);
    }
    fir2(t[0], t[1], &sa[done..], &sb[done..], &mut out0[done..]);
    fir2(t[2], t[3], &sa[done..], &sb[done..], &mut out1[done..]);
}

/// Per output parity p: (parity q of the synthesis taps, offset into the extended coefficients).
///
/// Outside periodization, x[2m + p] = sum_t rec[2(h-1-t) + p] * c[m + t] (PyWavelets' "valid"
/// upsampling convolution). In periodization the coefficients wrap (period n) and the output is
/// shifted by F / 2 - 1 samples, which moves odd-h filters' taps to the other parity.
fn idwt_phase(h: usize, mode: Mode) -> [(usize, usize); 2] {
    match mode {
        Mode::Periodization => {
            let q0 = (h + 1) % 2;
            let q1 = h % 2;
            // d_p = (p - q_p - 1 + h) / 2, always a non-negative integer.
            [(q0, (h - 1 - q0) / 2), (q1, (h - q1) / 2)]
        }
        _ => [(0, 0), (1, 0)],
    }
}

/// Length of the extended coefficient buffer for `n` coefficients.
fn coeff_ext_len(n: usize, h: usize, mode: Mode) -> usize {
    match mode {
        Mode::Periodization if n > 0 => {
            let [(_, d0), (_, d1)] = idwt_phase(h, mode);
            n + h - 1 + d0.max(d1)
        }
        _ => n,
    }
}

/// Copies coefficients into `dst`, wrapped periodically (left pad h - 1) in periodization.
fn coeff_extend(c: &[f64], h: usize, mode: Mode, dst: &mut [f64]) {
    let n = c.len();
    if mode != Mode::Periodization || n == 0 {
        dst[..n].copy_from_slice(c);
        return;
    }
    let left = h - 1;
    for (k, v) in dst.iter_mut().enumerate() {
        *v = c[(k + n * left - left) % n];
    }
}

/// Synthesis: `out[2m + p] = sum_t rlo[q_p][t] * ea[m + t + d_p] + rhi[q_p][t] * ed[m + t + d_p]`.
/// `out` may be shorter than the full inverse (trimming), never longer.
fn idwt_filter(taps: &Taps, mode: Mode, ea: &[f64], ed: &[f64], out: &mut [f64]) {
    if out.len() >= 2 * SPLIT_MIN {
        // Output 2m + p reads the extended coefficients from m on: the second part is the same
        // problem with both shifted by m.
        let m = out.len() / 4;
        let (first, second) = out.split_at_mut(2 * m);
        rayon::join(
            || idwt_filter(taps, mode, ea, ed, first),
            || idwt_filter(taps, mode, &ea[m..], &ed[m..], second),
        );
    } else {
        idwt_filter_serial(taps, mode, ea, ed, out);
    }
}

widest_vectors! {
fn idwt_filter_serial(taps: &Taps, mode: Mode, ea: &[f64], ed: &[f64], out: &mut [f64]) {
    let phase = idwt_phase(taps.h, mode);
    let halves = [out.len().div_ceil(2), out.len() / 2];
    let mut buf = [[0.0; BLOCK]; 2];
    let mut m0 = 0;
    while m0 < halves[0] {
        let mut nb = [0; 2];
        for p in 0..2 {
            nb[p] = halves[p].saturating_sub(m0).min(BLOCK);
            let (q, d) = phase[p];
            let start = m0 + d;
            fir2(
                &taps.rlo[q],
                &taps.rhi[q],
                &ea[start.min(ea.len())..],
                &ed[start.min(ed.len())..],
                &mut buf[p][..nb[p]],
            );
        }
        let dst = &mut out[2 * m0..];
        for (i, &v) in buf[0][..nb[0]].iter().enumerate() {
            dst[2 * i] = v;
        }
        for (i, &v) in buf[1][..nb[1]].iter().enumerate() {
            dst[2 * i + 1] = v;
        }
        m0 += BLOCK;
    }
}
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        crate::synthetic::SplitMix64(seed)
            .take(n)
            .map(|u| u - 0.5)
            .collect()
    }

    /// Each kernel's AVX-512 and AVX2 builds against its baseline build, on every length up to
    /// a few vector groups past the lane counts (remainders) and one long pass, several wavelets.
    #[test]
    #[cfg(target_arch = "x86_64")]
    fn every_vector_unit_gives_the_same_bits() {
        let units = [
            ("avx512f", std::is_x86_feature_detected!("avx512f")),
            ("avx2", std::is_x86_feature_detected!("avx2")),
        ];
        for (unit, _) in units.iter().filter(|(_, has)| !has) {
            eprintln!("this CPU has no {unit}: its kernels are not checked here");
        }
        let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
        // Outputs start as NaN, so a build that skipped one would not match the baseline.
        let nan = |n: usize| vec![f64::NAN; n];
        for name in ["db1", "db6", "sym8", "coif5"] {
            let taps = Taps::new(&Wavelet::by_name(name).expect("built in"));
            for nc in (1..40).chain([1001, 4099]) {
                let half = ext_half_len(nc, taps.f);
                let (ev, od) = (noise(half, 1), noise(half, 2));
                let x = noise(2 * nc, 5);
                for mode in Mode::ALL {
                    let len = coeff_ext_len(nc, taps.h, mode);
                    let (ea, ed) = (noise(len, 3), noise(len, 4));
                    let n_out = idwt_len(nc, taps.f, mode);
                    let mut want = [nan(nc), nan(nc), nan(half), nan(half), nan(n_out)];
                    let [wa, wd, we, wo, wr] = &mut want;
                    dwt_filter_serial::portable(&taps, &ev, &od, wa, wd);
                    extend::portable(&x, mode, taps.f, we, wo);
                    idwt_filter_serial::portable(&taps, mode, &ea, &ed, wr);
                    for (unit, has) in units {
                        if !has {
                            continue;
                        }
                        let mut got = [nan(nc), nan(nc), nan(half), nan(half), nan(n_out)];
                        let [ga, gd, ge, go, gr] = &mut got;
                        // SAFETY: the CPU has the unit (checked above).
                        unsafe {
                            if unit == "avx2" {
                                dwt_filter_serial::avx2(&taps, &ev, &od, ga, gd);
                                extend::avx2(&x, mode, taps.f, ge, go);
                                idwt_filter_serial::avx2(&taps, mode, &ea, &ed, gr);
                            } else {
                                dwt_filter_serial::avx512(&taps, &ev, &od, ga, gd);
                                extend::avx512(&x, mode, taps.f, ge, go);
                                idwt_filter_serial::avx512(&taps, mode, &ea, &ed, gr);
                            }
                        }
                        let what = format!("{name}, {nc} coefficients, {mode:?}, {unit}");
                        assert!(got.iter().flatten().all(|v| !v.is_nan()), "{what}");
                        assert!(same(&got.concat(), &want.concat()), "{what}");
                    }
                }
            }
        }
    }

    /// The passes shared between threads give the bits of one pass over the whole band, for
    /// lengths around every split.
    #[test]
    fn split_filter_passes_equal_one_pass_bit_for_bit() {
        let w = Wavelet::by_name("db6").expect("built in");
        let taps = Taps::new(&w);
        for nc in [SPLIT_MIN, 3 * SPLIT_MIN + 5, 5 * SPLIT_MIN - 1] {
            let half = ext_half_len(nc, taps.f);
            let (ev, od) = (noise(half, 1), noise(half, 2));
            let mut split = [vec![0.0; nc], vec![0.0; nc]];
            let mut whole = [vec![0.0; nc], vec![0.0; nc]];
            let [sa, sd] = &mut split;
            dwt_filter(&taps, &ev, &od, sa, sd);
            let [wa, wd] = &mut whole;
            dwt_filter_serial(&taps, &ev, &od, wa, wd);
            assert!(split
                .iter()
                .flatten()
                .zip(whole.iter().flatten())
                .all(|(a, b)| a.to_bits() == b.to_bits()));

            for mode in [Mode::Symmetric, Mode::Periodization] {
                let len = coeff_ext_len(nc, taps.h, mode);
                let (ea, ed) = (noise(len, 3), noise(len, 4));
                let n_out = 2 * nc - taps.f + 2 - 1;
                let mut split = vec![0.0; n_out];
                let mut whole = vec![0.0; n_out];
                idwt_filter(&taps, mode, &ea, &ed, &mut split);
                idwt_filter_serial(&taps, mode, &ea, &ed, &mut whole);
                assert!(
                    split
                        .iter()
                        .zip(&whole)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{mode:?}"
                );
            }
        }
    }
}
