//! Pipelines: the pipeline file ([`config`]: top-level keys, `[iceoryx2]`, the chain), the kinds
//! by name ([`registry`]), the helpers every stage kind reads its own table with ([`schema`]),
//! the stage contract
//! ([`stage`]), the input guard ([`guard`]) and the executor ([`runtime`]).

pub mod config;
pub mod guard;
pub mod offline;
pub mod registry;
pub mod runtime;
pub mod schema;
pub mod stage;

pub use config::{Pipeline, StageSpec};
