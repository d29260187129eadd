//! Orthogonal discrete wavelets, matched to PyWavelets, and wavelet-threshold denoising.
//!
//! - [`families`]: the filters of haar, db1-db20, sym2-sym20 and coif1-coif17.
//! - [`transform`]: `dwt`/`idwt`, `wavedec`/`waverec` in PyWavelets' seven signal-extension modes,
//!   and a [`transform::Plan`] that reuses caller-owned buffers on equal-length windows.
//! - [`threshold`]: hard, soft, garrote, firm and the paper's improved threshold function.
//! - [`denoise`]: batch denoising (noise sigma, threshold rules) and the drift / noise split.
//! - [`stream`]: a constant-time-per-sample streaming denoiser for the daemon.
//!
//! Pure maths: nothing here does I/O.

pub mod denoise;
pub mod families;
mod filters;
pub mod stream;
pub mod threshold;
pub mod transform;

pub use families::Wavelet;
pub use transform::Mode;

/// What can go wrong when asking for a transform or a denoiser.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WaveletError {
    /// No wavelet of that name.
    #[error("unknown wavelet '{0}' (valid: haar, db1..db20, sym2..sym20, coif1..coif17)")]
    UnknownWavelet(String),
    /// No signal-extension mode of that name.
    #[error(
        "unknown mode '{0}' (valid: zero, constant, symmetric, reflect, periodic, smooth, periodization)"
    )]
    UnknownMode(String),
    /// No threshold function of that name.
    #[error("unknown threshold function '{0}' (valid: hard, soft, garrote, firm, improved)")]
    UnknownThreshold(String),
    /// No threshold rule of that name.
    #[error("unknown threshold rule '{0}' (valid: universal, level-universal, sure, bayes, or a fixed number)")]
    UnknownRule(String),
    /// The signal is too short for the requested decomposition level (`needed` saturates at
    /// `usize::MAX` for levels no record could reach).
    #[error(
        "level {level} with {wavelet} needs at least {} samples, got {got}",
        if *needed == usize::MAX { format!("2^{level}") } else { needed.to_string() }
    )]
    TooShort {
        /// Requested level.
        level: usize,
        /// Wavelet name.
        wavelet: String,
        /// Samples needed.
        needed: usize,
        /// Samples given.
        got: usize,
    },
    /// A parameter is outside its valid range.
    #[error("{0}")]
    BadParameter(String),
}
