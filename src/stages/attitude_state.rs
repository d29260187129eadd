//! `attitude.6d`'s warm start: what the magnetometer's filter learnt online (the hard iron with
//! its uncertainty, the reference field's norm and dip) saved to the file its `state_file` key
//! names, at shutdown and every `state_every_s`, and read back at the next start as its start
//! value ([`crate::attitude::MagHeading::resume`]).
//!
//! Written, refused and moved aside as `predict.bias`'s state is ([`super::state_file`]). Tied to
//! its owner: the pipeline and stage names, and the calibration the stage was given
//! (`mag_hard_iron_ut`, `mag_soft_iron`): an offset learnt under another calibration is not
//! this one's (re-running `driftless mag-cal` starts the hard iron from its new result). A hard
//! iron does not fade with time: any age is used. The values are in uT, of readings after the
//! soft iron (`W m`), and the dip in degrees.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::attitude::hard_iron::Mat3;
use crate::attitude::MagLearnt;
use crate::stages::state_file::{self, Unusable};

/// The file format's version.
const FORMAT: u32 = 1;
/// Tesla (what the samples carry) to uT (the file's unit).
const UT: f64 = 1e6;

/// Who a state belongs to: a state of another owner is refused.
#[derive(Debug, Clone, PartialEq)]
pub struct Owner {
    /// The pipeline's name.
    pub pipeline: String,
    /// The stage's name.
    pub stage: String,
    /// The calibration's hard iron given, uT (`mag_hard_iron_ut`; zero without).
    pub hard_iron_ut: [f64; 3],
    /// The calibration's soft iron given (`mag_soft_iron`; the identity without).
    pub soft_iron: Mat3,
}

/// A state read back.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Saved {
    /// What the filter learnt, in the readings' units (tesla).
    pub learnt: MagLearnt,
    /// Wall-clock time of the save, ns since the Unix epoch.
    pub saved_unix_ns: u64,
}

/// What a `state_file` held.
pub type Loaded = state_file::Loaded<Saved>;

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    format: u32,
    pipeline: String,
    stage: String,
    calibration_hard_iron_ut: [f64; 3],
    calibration_soft_iron: Mat3,
    saved_unix_ns: u64,
    hard_iron_ut: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    hard_iron_sd_ut: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    field_ut: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    dip_deg: Option<f64>,
}

/// The state in `path` for `owner`: missing, saved, or unusable and why.
pub fn load(path: &Path, owner: &Owner) -> Loaded {
    Loaded::from(read(path, owner))
}

fn read(path: &Path, owner: &Owner) -> Result<Option<Saved>, Unusable> {
    let shown = path.display();
    let not_ours = "not a magnetometer state driftless wrote";
    let Some(f) = state_file::read_toml::<File>(path, not_ours)? else {
        return Ok(None);
    };
    let same = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .all(|(x, y)| (x - y).abs() <= 1e-9 * x.abs().max(y.abs()).max(1.0))
    };
    let why = if f.format != FORMAT {
        Some(format!(
            "format {} (this driftless reads {FORMAT})",
            f.format
        ))
    } else if f.pipeline != owner.pipeline || f.stage != owner.stage {
        Some(format!(
            "it is pipeline {:?} stage {:?}'s, not {:?} {:?}'s",
            f.pipeline, f.stage, owner.pipeline, owner.stage
        ))
    } else if !same(&f.calibration_hard_iron_ut, &owner.hard_iron_ut)
        || !same(
            f.calibration_soft_iron.as_flattened(),
            owner.soft_iron.as_flattened(),
        )
    {
        Some(
            "it was saved under another calibration (mag_hard_iron_ut, mag_soft_iron): the \
             hard iron starts from the new one"
                .into(),
        )
    } else {
        let values = f
            .hard_iron_ut
            .iter()
            .chain(&f.hard_iron_sd_ut)
            .chain(&f.field_ut)
            .chain(&f.dip_deg);
        let usable = values.clone().all(|v| v.is_finite())
            && f.hard_iron_sd_ut.is_none_or(|s| s >= 0.0)
            && f.field_ut.is_none_or(|n| n > 0.0)
            && f.dip_deg.is_none_or(|d| d.abs() <= 90.0);
        (!usable).then(|| "its values are not a usable estimate".into())
    };
    if let Some(why) = why {
        return Err(Unusable::movable(format!("state_file {shown}: {why}")));
    }
    Ok(Some(Saved {
        learnt: MagLearnt {
            hard_iron: f.hard_iron_ut.map(|v| v / UT),
            hard_iron_sd: f.hard_iron_sd_ut.map(|v| v / UT),
            reference: f
                .field_ut
                .zip(f.dip_deg)
                .map(|(n, d)| (n / UT, d.to_radians())),
        },
        saved_unix_ns: f.saved_unix_ns,
    }))
}

/// The state as text, saved at `saved_unix_ns`.
fn render(owner: &Owner, learnt: &MagLearnt, saved_unix_ns: u64) -> String {
    let file = File {
        format: FORMAT,
        pipeline: owner.pipeline.clone(),
        stage: owner.stage.clone(),
        calibration_hard_iron_ut: owner.hard_iron_ut,
        calibration_soft_iron: owner.soft_iron,
        saved_unix_ns,
        hard_iron_ut: learnt.hard_iron.map(|v| v * UT),
        hard_iron_sd_ut: learnt.hard_iron_sd.map(|v| v * UT),
        field_ut: learnt.reference.map(|(n, _)| n * UT),
        dip_deg: learnt.reference.map(|(_, d)| d.to_degrees()),
    };
    let body = toml::to_string(&file).expect("a state of plain values");
    format!(
        "# The magnetometer's learnt hard iron (uT, of readings after the soft iron) and \
         reference field,\n# written by driftless's attitude.6d (state_file).\n{body}"
    )
}

/// The thread that writes the state: the hot thread hands it snapshots, never waiting.
pub type StateWriter = state_file::StateWriter<MagLearnt>;

/// Start the writer of `path` for `owner`.
pub fn start_writer(path: PathBuf, owner: Owner) -> Result<StateWriter, String> {
    state_file::StateWriter::start(
        path,
        move |learnt: &MagLearnt, now: u64| render(&owner, learnt, now),
        || MagLearnt {
            hard_iron: [0.0; 3],
            hard_iron_sd: None,
            reference: None,
        },
    )
}

/// A state for a line: `hard iron (x, y, z) +- sd uT, field n uT at dip d deg`.
pub fn describe(l: &MagLearnt) -> String {
    let [x, y, z] = l.hard_iron.map(|v| v * UT);
    let sd = l
        .hard_iron_sd
        .map_or(String::new(), |s| format!(" +- {:.2}", s * UT));
    let field = l.reference.map_or(String::new(), |(n, d)| {
        format!(", field {:.1} uT at dip {:.1} deg", n * UT, d.to_degrees())
    });
    format!("hard iron ({x:.2}, {y:.2}, {z:.2}){sd} uT{field}")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn owner() -> Owner {
        Owner {
            pipeline: "p".into(),
            stage: "attitude".into(),
            hard_iron_ut: [1.0, 2.0, 3.0],
            soft_iron: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        }
    }

    #[test]
    fn a_state_round_trips_and_another_owners_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mag.toml");
        let learnt = MagLearnt {
            hard_iron: [3e-6, -7e-6, 12e-6],
            hard_iron_sd: Some(2e-7),
            reference: Some((48e-6, 1.1)),
        };
        state_file::write_atomically(&path, &render(&owner(), &learnt, 1_700_000_000_000_000_000))
            .unwrap();
        let Loaded::Saved(saved) = load(&path, &owner()) else {
            panic!("its own state")
        };
        let back = saved.learnt;
        for i in 0..3 {
            assert!(
                (back.hard_iron[i] - learnt.hard_iron[i]).abs() < 1e-15,
                "{back:?}"
            );
        }
        let (n, d) = back.reference.unwrap();
        assert!(
            (n - 48e-6).abs() < 1e-15 && (d - 1.1).abs() < 1e-12,
            "{back:?}"
        );
        assert_eq!(saved.saved_unix_ns, 1_700_000_000_000_000_000);
        // Why the state is refused to `other`, which must be able to move it aside.
        let refused = |other: &Owner| match load(&path, other) {
            Loaded::Unusable(u) if u.movable => u.why,
            got => panic!("refused: {got:?}"),
        };
        let stage = Owner {
            stage: "q".into(),
            ..owner()
        };
        assert!(refused(&stage).contains("stage \"attitude\"'s, not"));
        let recalibrated = Owner {
            hard_iron_ut: [1.0, 2.0, 4.0],
            ..owner()
        };
        assert!(refused(&recalibrated).contains("another calibration"));
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(&path, text.replace("field_ut = 48", "field_ut = -48")).unwrap();
        assert!(refused(&owner()).contains("not a usable estimate"));
        std::fs::write(&path, &text[..text.len() / 2]).unwrap();
        assert!(refused(&owner()).contains("not a magnetometer state"));
    }
}
