//! Threshold functions (placeholder).
