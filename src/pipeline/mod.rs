//! Pipelines: a pipeline file read into a chain of stages, and run.
//!
//! The file's schema ([`config`]: top-level keys, `[iceoryx2]`, the chain), the stage kinds by
//! name ([`registry`], over [`crate::stages::KINDS`]), the input guard every raw sample passes
//! ([`guard`]), the executor ([`runtime`]: the hot thread, its clock, shutdown) and the same
//! chain run offline on a log ([`offline`]). What a stage is, and every kind, is in
//! [`crate::stages`]: this module uses it and it never uses this one.

pub mod config;
pub mod guard;
pub mod iceoryx2_table;
pub mod offline;
pub mod registry;
pub mod runtime;

pub use config::{Pipeline, StageSpec};
