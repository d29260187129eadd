//! Synthetic benchmark signals (placeholder).
