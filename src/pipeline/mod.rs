//! Pipelines: the TOML schema ([`config`]), the stage contract ([`stage`]), the input guard
//! ([`guard`]) and the executor ([`runtime`]).

pub mod config;
pub mod guard;
pub mod runtime;
pub mod stage;

pub use config::{Pipeline, StageKind, StageSpec};
