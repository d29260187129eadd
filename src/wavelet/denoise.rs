//! Batch denoising (placeholder).
