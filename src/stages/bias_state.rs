//! `predict.bias`'s warm start: the bias filter's state saved to the file its `state_file` key
//! names, at shutdown and every `state_every_s`, and read back at the next start.
//!
//! - **Written atomically** by a thread of its own (never the hot thread): a temporary file in
//!   the same directory, synced, renamed over the old one, the directory synced. A crash
//!   leaves the old state or the new one, never half of one.
//! - **Tied to its owner**: the pipeline and stage names, the axis count, the rate and the
//!   noise terms. A state of another owner (another pipeline's, another sensor's terms, terms
//!   since re-measured), a file that does not parse (with its line and column), garbage, or a
//!   file that cannot be read is [`Loaded::Unusable`]. A cache must never cost the
//!   navigation: by default the stage starts cold, says why in one line, and moves the file
//!   aside to `<name>.unusable-<UTC time>` ([`move_aside`]) so that nothing is lost and the
//!   next save lands where the last one was; `state_required = true` refuses it (exit 2).
//! - **Grown by the time that passed**: at start each axis's filter resumes from its saved
//!   estimate and covariance, predicted through the wall-clock time since the save
//!   ([`crate::drift::bias::BiasFilter::resume`]). Older than the prior is worth, or saved in
//!   the future (a clock set back), it is not used: the stage starts cold and says why. Such a
//!   file is ours and whole: it stays, and the next save replaces it.
//!
//! How a start went is a [`WarmStart`], which the built stage gives the runtime
//! ([`crate::stages::Stage::warm_start`]) for `run`'s report.
//!
//! The file is TOML, one table per axis; `bias_deg_s` and `sd_deg_s` are there for a reader
//! and are not read back. An axis that takes the odometry's yaw rate keeps its learnt scale
//! too (`odometry_scale`, `odometry_scale_sd`), resumed with its walk over the gap.

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::drift::bias::{BiasTerms, FilterSnapshot, LearnerSnapshot, GRID, MAX_STATES};
use crate::stages::state_file;
pub use crate::stages::state_file::{move_aside, Unusable, WarmStart};

/// The file format's version.
const FORMAT: u32 = 1;

/// Axis names in files and lines.
const AXES: [&str; 3] = ["x", "y", "z"];

/// Who a state belongs to: a state of another owner is refused.
#[derive(Debug, Clone, PartialEq)]
pub struct Owner {
    /// The pipeline's name.
    pub pipeline: String,
    /// The stage's name.
    pub stage: String,
    /// Axes.
    pub axes: usize,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// The stage's noise terms (the sensor's, as far as the stage knows it).
    pub terms: BiasTerms,
}

impl Owner {
    fn terms(&self) -> [f64; 5] {
        let t = &self.terms;
        [t.n, t.b, t.k, t.q, t.lsb]
    }
}

/// A state read back: one filter snapshot per axis and when it was saved.
#[derive(Debug, Clone, PartialEq)]
pub struct Saved {
    /// Per axis.
    pub filters: Vec<FilterSnapshot>,
    /// Wall-clock time of the save, ns since the Unix epoch.
    pub saved_unix_ns: u64,
}

impl Saved {
    /// How long ago it was saved; None if in the future by more than a second (a clock set
    /// back: the time between is unknown).
    pub fn age(&self) -> Option<Duration> {
        state_file::age(self.saved_unix_ns)
    }
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    format: u32,
    pipeline: String,
    stage: String,
    axes: usize,
    rate_hz: f64,
    /// N, B, K, Q, lsb in the filter's base units (deg/s based).
    terms: [f64; 5],
    saved_unix_ns: u64,
    axis: Vec<AxisFile>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct AxisFile {
    name: String,
    bias_deg_s: f64,
    sd_deg_s: f64,
    x: Vec<f64>,
    p: Vec<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    walk: Option<WalkFile>,
    /// The odometry's scale correction and its sd (`OdometryAid`), where the stage takes a
    /// yaw rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    odometry_scale: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    odometry_scale_sd: Option<f64>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct WalkFile {
    walk: f64,
    stops: u64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    end_var: Option<f64>,
    ll: Vec<f64>,
}

/// What a `state_file` held when the pipeline was read.
pub type Loaded = state_file::Loaded<Saved>;

/// The state in `path` for `owner`: missing, saved, or unusable and why.
pub fn load(path: &Path, owner: &Owner) -> Loaded {
    Loaded::from(read(path, owner))
}

fn read(path: &Path, owner: &Owner) -> Result<Option<Saved>, Unusable> {
    let shown = path.display();
    let unusable = Unusable::movable;
    let Some(file) = state_file::read_toml::<File>(path, "not a bias state driftless wrote")?
    else {
        return Ok(None);
    };
    if file.format != FORMAT {
        return Err(unusable(format!(
            "state_file {shown}: format {} (this driftless reads {FORMAT})",
            file.format
        )));
    }
    let same_terms = file
        .terms
        .iter()
        .zip(owner.terms())
        .all(|(a, b)| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()));
    let mismatch = if file.pipeline != owner.pipeline || file.stage != owner.stage {
        Some(format!(
            "it is pipeline {:?} stage {:?}'s, not {:?} {:?}'s",
            file.pipeline, file.stage, owner.pipeline, owner.stage
        ))
    } else if file.axes != owner.axes || file.axis.len() != owner.axes {
        Some(format!(
            "it holds {} axes, this pipeline has {}",
            file.axis.len(),
            owner.axes
        ))
    } else if (file.rate_hz - owner.rate_hz).abs() > 1e-9 * owner.rate_hz {
        Some(format!(
            "it was saved at {} Hz, this pipeline runs at {} Hz",
            file.rate_hz, owner.rate_hz
        ))
    } else if !same_terms {
        Some(
            "it was saved with other noise terms (another sensor's, or terms since changed)"
                .to_string(),
        )
    } else {
        None
    };
    if let Some(why) = mismatch {
        return Err(unusable(format!("state_file {shown}: {why}")));
    }
    let mut filters = Vec::with_capacity(file.axis.len());
    for (k, a) in file.axis.iter().enumerate() {
        let n = a.x.len();
        let bad = |what: &str| unusable(format!("state_file {shown}: axis {}: {what}", AXES[k]));
        if n == 0 || n > MAX_STATES || a.p.len() != n || a.p.iter().any(|r| r.len() != n) {
            return Err(bad(
                "its x and p do not hold one state vector and its covariance",
            ));
        }
        let mut snap = FilterSnapshot {
            states: n,
            x: [0.0; MAX_STATES],
            p: [[0.0; MAX_STATES]; MAX_STATES],
            learner: None,
            scale: match (a.odometry_scale, a.odometry_scale_sd) {
                (Some(s), Some(sd)) if s.is_finite() && sd.is_finite() && sd >= 0.0 => {
                    Some((s, sd * sd))
                }
                (None, None) => None,
                _ => return Err(bad("its odometry scale is not a value with its sd")),
            },
        };
        snap.x[..n].copy_from_slice(&a.x);
        for (row, saved) in snap.p.iter_mut().zip(&a.p) {
            row[..n].copy_from_slice(saved);
        }
        if let Some(w) = &a.walk {
            if w.ll.len() != GRID {
                return Err(bad("its walk's likelihoods are not the learner's grid"));
            }
            let mut ll = [0.0; GRID];
            ll.copy_from_slice(&w.ll);
            snap.learner = Some(LearnerSnapshot {
                ll,
                walk: w.walk,
                stops: w.stops,
                end_var: w.end_var,
            });
        }
        let finite = snap
            .x
            .iter()
            .chain(snap.p.iter().flatten())
            .all(|v| v.is_finite());
        if !finite || snap.variance() <= 0.0 {
            return Err(bad("its values are not a usable estimate"));
        }
        filters.push(snap);
    }
    Ok(Some(Saved {
        filters,
        saved_unix_ns: file.saved_unix_ns,
    }))
}

/// The state as text, saved now.
fn render(owner: &Owner, filters: &[FilterSnapshot], saved_unix_ns: u64) -> String {
    let axis = filters
        .iter()
        .zip(AXES)
        .map(|(f, name)| {
            let n = f.states;
            AxisFile {
                name: name.to_string(),
                bias_deg_s: f.estimate(),
                sd_deg_s: f.variance().sqrt(),
                x: f.x[..n].to_vec(),
                p: f.p[..n].iter().map(|r| r[..n].to_vec()).collect(),
                walk: f.learner.map(|l| WalkFile {
                    walk: l.walk,
                    stops: l.stops,
                    end_var: l.end_var,
                    ll: l.ll.to_vec(),
                }),
                odometry_scale: f.scale.map(|(s, _)| s),
                odometry_scale_sd: f.scale.map(|(_, var)| var.max(0.0).sqrt()),
            }
        })
        .collect();
    let file = File {
        format: FORMAT,
        pipeline: owner.pipeline.clone(),
        stage: owner.stage.clone(),
        axes: owner.axes,
        rate_hz: owner.rate_hz,
        terms: owner.terms(),
        saved_unix_ns,
        axis,
    };
    let body = toml::to_string(&file).expect("a state of plain values");
    format!("# The bias filter's state, written by driftless's predict.bias (state_file).\n{body}")
}

/// One save: each axis's filter (fixed size, so that taking one never allocates).
pub struct Snapshot {
    filters: [Option<FilterSnapshot>; 3],
}

impl Snapshot {
    /// The snapshots of up to three axes, in order.
    pub fn new(mut each: impl FnMut(usize) -> Option<FilterSnapshot>) -> Snapshot {
        Snapshot {
            filters: [each(0), each(1), each(2)],
        }
    }
}

/// The thread that writes the state: the hot thread hands it snapshots, never waiting.
pub type StateWriter = state_file::StateWriter<Snapshot>;

/// Start the writer of `path` for `owner`.
pub fn start_writer(path: PathBuf, owner: Owner) -> Result<StateWriter, String> {
    let render = move |snap: &Snapshot, now: u64| {
        let filters: Vec<FilterSnapshot> = snap.filters.iter().flatten().cloned().collect();
        render(&owner, &filters, now)
    };
    state_file::StateWriter::start(path, render, || Snapshot::new(|_| None))
}

/// The axes of a state for a line: `x +0.1234 +- 0.0012 deg/s, y ...`.
pub fn describe(filters: &[FilterSnapshot]) -> String {
    filters
        .iter()
        .zip(AXES)
        .map(|(f, a)| format!("{a} {:+.4} +- {:.4}", f.estimate(), f.variance().sqrt()))
        .collect::<Vec<_>>()
        .join(", ")
        + " deg/s"
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drift::bias::{BiasTracker, TrackerConfig};

    fn owner() -> Owner {
        Owner {
            pipeline: "p".into(),
            stage: "predict".into(),
            axes: 2,
            rate_hz: 100.0,
            terms: BiasTerms::profile("adis16405").unwrap(),
        }
    }

    /// Two axes, the second carrying an odometry scale.
    fn learnt() -> Vec<FilterSnapshot> {
        let o = owner();
        (0..2)
            .map(|k| {
                let mut t =
                    BiasTracker::new(&o.terms, o.rate_hz, &TrackerConfig::default()).unwrap();
                for i in 0..3000 {
                    t.push(0.3 * (k as f64 + 1.0) + 0.01 * ((i * 7919) % 13) as f64);
                }
                let mut snap = t.snapshot();
                if k == 1 {
                    snap.scale = Some((0.0123, 0.002f64.powi(2)));
                }
                snap
            })
            .collect()
    }

    #[test]
    fn a_state_round_trips_through_its_file() {
        let dir = std::env::temp_dir().join(format!("dl-state-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s.toml");
        let filters = learnt();
        state_file::write_atomically(
            &path,
            &render(&owner(), &filters, 1_700_000_000_000_000_000),
        )
        .unwrap();
        let Loaded::Saved(saved) = load(&path, &owner()) else {
            panic!("its own state")
        };
        assert_eq!(saved.filters[0], filters[0]);
        let (s, var) = saved.filters[1].scale.unwrap();
        assert!(s == 0.0123 && (var - 4e-6).abs() < 1e-18, "{s} {var}");
        let mut rest = saved.filters[1].clone();
        rest.scale = filters[1].scale;
        assert_eq!(rest, filters[1]);
        assert_eq!(saved.saved_unix_ns, 1_700_000_000_000_000_000);
        // Another owner's: refused, naming why.
        for (other, why) in [
            (
                Owner {
                    stage: "q".into(),
                    ..owner()
                },
                "stage \"predict\"'s, not",
            ),
            (Owner { axes: 3, ..owner() }, "holds 2 axes"),
            (
                Owner {
                    rate_hz: 200.0,
                    ..owner()
                },
                "saved at 100 Hz",
            ),
            (
                Owner {
                    terms: BiasTerms::profile("adxrs450").unwrap(),
                    ..owner()
                },
                "other noise terms",
            ),
        ] {
            let Loaded::Unusable(u) = load(&path, &other) else {
                panic!("{why}: refused")
            };
            assert!(u.why.contains(why) && u.movable, "{u:?}");
        }
        // Cut short: refused with a position, never half read.
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(&path, &text[..text.len() / 2]).unwrap();
        let Loaded::Unusable(u) = load(&path, &owner()) else {
            panic!("half a state")
        };
        assert!(
            u.why.contains("s.toml:") && u.why.contains("not a bias state"),
            "{u:?}"
        );
        // Garbage: what it holds.
        std::fs::write(&path, [0x1f, 0x8b, 0, 0xff, 0x10]).unwrap();
        let Loaded::Unusable(u) = load(&path, &owner()) else {
            panic!("garbage")
        };
        assert!(
            u.why
                .ends_with("not a bias state driftless wrote: it holds a damaged gzip stream"),
            "{u:?}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(load(&path, &owner()), Loaded::Missing, "no file: cold");
    }
}
