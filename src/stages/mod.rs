//! The stage kinds, one file each: every file owns its kind's keys (with types, ranges and
//! defaults), their validation, how the stage is built, and the line that documents it.
//!
//! | kind | file | role |
//! |---|---|---|
//! | `ingest.sim` | [`ingest_sim`] | simulated sensor, paced in real time or a factor faster |
//! | `ingest.csv` | [`ingest_csv`] | CSV replay, real time, a factor faster or as fast as possible |
//! | `ingest.mcap` | [`ingest_mcap`] | replay of a `driftless record` recording (MCAP), real time, a factor faster or as fast as possible |
//! | `ingest.iceoryx2` | [`ingest_iceoryx2`] | raw samples from a driver in another process |
//! | `denoise.wavelet`, `denoise.none` | [`denoise`] | streaming wavelet denoiser / pass-through |
//! | `predict.none`, `predict.rbf` | [`predict`] | drift estimate 0 / the RBF drift model, gated by stillness |
//! | `predict.bias` | [`predict_bias`] | the bias as a Kalman state from the gyro's Allan terms (no training) |
//! | `attitude.6d` | [`attitude_6d`] | the orientation from the corrected gyro and the accelerometer |
//! | `external` | [`external`] | a stage run by another process (the daemon only links to it) |
//! | `publish` | [`publish`] | the final guard before the public service |
//!
//! [`accel_terms`] holds the accelerometer's noise keys (`accel_vrw`, `accel_bias_instability`)
//! a stage reads beside the gyro's, as [`stop_rule`] holds the vehicle's stop keys.
//! [`replay`] is what the file replays (`ingest.csv`, `ingest.mcap`) share: the reader thread,
//! its blocks of samples and the pacing. [`bias_state`] is `predict.bias`'s saved state (its
//! warm start): the file and its checks; [`attitude_state`] is `attitude.6d`'s (the
//! magnetometer's learnt hard iron); [`state_file`] is what both share: the file read, moved
//! aside and written atomically by a thread of its own.
//!
//! # Adding a stage kind
//! 1. Write `src/stages/<kind>.rs` with: its keys as [`Key`](crate::stages::schema::Key)
//!    constants, each with its typed default
//!    ([`DefaultValue`](crate::stages::schema::DefaultValue)); a parse function reading them
//!    from the [`Table`](crate::stages::schema::Table) with the reader the default
//!    asks for (`required_str` for a required key, an `*_or_default` reader for a typed
//!    default, an optional one for the rest; it checks types, ranges and anything else `run`
//!    needs, positioning every error) and returning its parameters; a parameters
//!    type implementing [`Params`] (how the stage or source is
//!    built, what `validate` says of it); and a `pub const KIND: Kind` tying them together with
//!    its name, [`Role`] and one-line summary.
//! 2. Add `pub mod <kind>;` below and its `KIND` to [`KINDS`].
//!
//! Nothing else changes: the pipeline file's reader finds the kind in [`KINDS`], rejects keys
//! the kind does not declare (naming the kind a stray key belongs to), and `driftless validate
//! --kinds` and `docs/reference/pipeline-file.md` (generated from it) list the new keys.

pub mod accel_terms;
pub mod bag_motion;
pub mod bias_odometry;
pub mod bias_state;
pub mod contract;
pub mod schema;
pub mod state_file;

pub mod attitude_6d;
pub mod attitude_state;
pub mod denoise;
pub mod external;
pub mod ingest_csv;
pub mod ingest_iceoryx2;
pub mod ingest_mcap;
pub mod ingest_sim;
pub mod predict;
pub mod predict_bias;
pub mod publish;
pub mod replay;
pub mod stop_rule;

pub use contract::{Kind, Params, Poll, Role, SideInput, SideValue, Source, Stage};
pub use state_file::WarmStart;

/// Every stage kind, in the order listed in messages and documentation.
pub const KINDS: &[&Kind] = &[
    &ingest_sim::KIND,
    &ingest_csv::KIND,
    &ingest_mcap::KIND,
    &ingest_iceoryx2::KIND,
    &denoise::WAVELET_KIND,
    &denoise::NONE_KIND,
    &predict::NONE_KIND,
    &predict::RBF_KIND,
    &predict_bias::KIND,
    &attitude_6d::KIND,
    &external::KIND,
    &publish::KIND,
];

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::io::InputError;
    use crate::stages::schema::{test_table, DefaultValue, Src, Type};

    /// Every kind's keys: a typed default is a value of the key's own type and range, and an
    /// `Either` names another key of the same kind.
    #[test]
    fn every_default_fits_its_key() {
        for kind in KINDS {
            for key in kind.keys {
                key.check_default()
                    .unwrap_or_else(|e| panic!("{}: {e}", kind.name));
                if let DefaultValue::Either(other) = key.default {
                    assert!(
                        kind.keys
                            .iter()
                            .any(|k| k.name == other && k.name != key.name),
                        "{}: {} names {other}, not a key of the kind",
                        kind.name,
                        key.name
                    );
                }
            }
        }
    }

    /// The kind's own table read from `text` (keys of the kind only), under a pipeline at
    /// 100 Hz, 3 axes, deg/s, whose file sits in a folder that does not exist.
    fn parse(kind: &Kind, text: &str) -> Result<Box<dyn Params>, InputError> {
        let src = Src {
            path: Path::new("/nonexistent/driftless-keys-test/pipeline.toml"),
            text,
        };
        let mut t = test_table(&src, 3, Some("in/raw"), ("keys", "s"), |k| {
            let key = kind.keys.iter().find(|key| key.name == k);
            key.expect("a key of the kind").name
        });
        (kind.parse)(&mut t)
    }

    /// Every kind reads each key with the reader its default asks for (a reader given another
    /// key panics: a required key by a required reader, a typed default by a defaulting one,
    /// the rest by an optional one), and a required key missing is said by name. Each kind is
    /// read from an empty table, then with its required keys and its string keys without a
    /// default given (a file or service that does not exist: those errors are the file's).
    #[test]
    fn every_kind_reads_its_keys_as_their_defaults_say() {
        for kind in KINDS {
            let required: Vec<&str> = kind
                .keys
                .iter()
                .filter(|k| k.default == DefaultValue::Required)
                .map(|k| k.name)
                .collect();
            match (parse(kind, ""), required.first()) {
                (Err(e), Some(first)) => assert!(
                    e.to_string().contains(&format!("missing field `{first}`")),
                    "{}: {e}",
                    kind.name
                ),
                (Ok(_), Some(first)) => panic!("{} without {first} read", kind.name),
                (_, None) => {}
            }
            let given: String = kind
                .keys
                .iter()
                .filter(|k| {
                    matches!(k.ty, Type::Str(_))
                        && matches!(k.default, DefaultValue::Required | DefaultValue::Absent(_))
                })
                .map(|k| format!("{} = \"keys-test/{}\"\n", k.name, k.name))
                .collect();
            if let Err(e) = parse(kind, &given) {
                assert!(
                    !e.to_string().contains("missing field"),
                    "{}: {e}",
                    kind.name
                );
            }
        }
    }
}
