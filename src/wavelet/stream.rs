//! Streaming denoiser (placeholder).
