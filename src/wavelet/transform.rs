//! Discrete wavelet transform with PyWavelets' conventions (coefficient lengths, values, modes).
//!
//! CONTRACT (being implemented): signatures below are fixed; bodies are filled in by the
//! transform work and checked against PyWavelets fixtures in `tests/pywavelets.rs`.

use super::{Wavelet, WaveletError};
use std::ops::Range;

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
/// ceil(n / 2) for [`Mode::Periodization`].
pub fn dwt_coeff_len(n: usize, filter_len: usize, mode: Mode) -> usize {
    let _ = (n, filter_len, mode);
    todo!()
}

/// Deepest useful level: floor(log2(n / (F - 1))), 0 when n < F - 1.
pub fn dwt_max_level(n: usize, filter_len: usize) -> usize {
    let _ = (n, filter_len);
    todo!()
}

/// Single-level transform: (cA, cD).
pub fn dwt(x: &[f64], w: &Wavelet, mode: Mode) -> (Vec<f64>, Vec<f64>) {
    let _ = (x, w, mode);
    todo!()
}

/// Single-level transform into caller buffers of length [`dwt_coeff_len`].
pub fn dwt_into(x: &[f64], w: &Wavelet, mode: Mode, ca: &mut [f64], cd: &mut [f64]) {
    let _ = (x, w, mode, ca, cd);
    todo!()
}

/// Length of [`idwt`]'s output from coefficients of length `coeff_len`: 2 * len - F + 2, or
/// 2 * len for [`Mode::Periodization`].
pub fn idwt_len(coeff_len: usize, filter_len: usize, mode: Mode) -> usize {
    let _ = (coeff_len, filter_len, mode);
    todo!()
}

/// Single-level inverse transform of equal-length (cA, cD).
pub fn idwt(ca: &[f64], cd: &[f64], w: &Wavelet, mode: Mode) -> Vec<f64> {
    let _ = (ca, cd, w, mode);
    todo!()
}

/// Single-level inverse into a caller buffer of length [`idwt_len`].
pub fn idwt_into(ca: &[f64], cd: &[f64], w: &Wavelet, mode: Mode, out: &mut [f64]) {
    let _ = (ca, cd, w, mode, out);
    todo!()
}

/// Multilevel decomposition, PyWavelets' order: `[cA_level, cD_level, ..., cD_1]`.
pub fn wavedec(
    x: &[f64],
    w: &Wavelet,
    mode: Mode,
    level: usize,
) -> Result<Vec<Vec<f64>>, WaveletError> {
    let _ = (x, w, mode, level);
    todo!()
}

/// Multilevel reconstruction from [`wavedec`]'s output (may be one sample longer than the
/// original for odd lengths, as in PyWavelets).
pub fn waverec(coeffs: &[Vec<f64>], w: &Wavelet, mode: Mode) -> Result<Vec<f64>, WaveletError> {
    let _ = (coeffs, w, mode);
    todo!()
}

/// A multilevel transform planned for one signal length, working in caller-owned buffers so that
/// repeated calls on equal-length windows allocate nothing.
#[derive(Debug, Clone)]
pub struct Plan {
    _private: (),
}

impl Plan {
    /// Plan `level` levels of `w` in `mode` for signals of length `n`.
    pub fn new(w: &Wavelet, mode: Mode, n: usize, level: usize) -> Result<Plan, WaveletError> {
        let _ = (w, mode, n, level);
        todo!()
    }

    /// Signal length this plan takes.
    pub fn signal_len(&self) -> usize {
        todo!()
    }

    /// Number of levels.
    pub fn level(&self) -> usize {
        todo!()
    }

    /// Length of the flat coefficient buffer.
    pub fn coeffs_len(&self) -> usize {
        todo!()
    }

    /// Where each band sits in the flat buffer, PyWavelets' order: `[cA_n, cD_n, ..., cD_1]`.
    pub fn ranges(&self) -> &[Range<usize>] {
        todo!()
    }

    /// Decompose `x` (length [`Plan::signal_len`]) into `coeffs` (length [`Plan::coeffs_len`]).
    pub fn wavedec(&mut self, x: &[f64], coeffs: &mut [f64]) {
        let _ = (x, coeffs);
        todo!()
    }

    /// Reconstruct the first [`Plan::signal_len`] samples from `coeffs` into `out`.
    pub fn waverec(&mut self, coeffs: &[f64], out: &mut [f64]) {
        let _ = (coeffs, out);
        todo!()
    }
}
