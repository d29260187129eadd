//! The pipeline file (TOML): the only place its schema lives.
//!
//! ```toml
//! name = "demo"              # pipeline name: node name, default stats service "demo/stats"
//! rate_hz = 1000.0           # sample rate of the ingest
//! deadline_us = 1000.0       # end-to-end deadline (default: one sample period, at the
//!                            # ingest's pace: a tenth of it at pace = 10.0)
//! axes = 3                   # 1..=3
//! input_units = "deg/s"      # "deg/s" or "rad/s"; published rates are always rad/s
//! accel_units = "m/s^2"      # "m/s^2" or "g"; published accelerometer readings are m/s²
//! report_interval_s = 2.0    # stderr summary and stats service period
//! realtime_priority = 50     # optional: SCHED_FIFO priority of the hot thread (1..=99)
//! cpu = 1                    # optional: pin the hot thread to this CPU
//! prewarm_us = 100.0         # optional: wake this long before each paced sample is due to
//!                            # bring the stages' state back into the cache (default 0: off)
//!
//! [iceoryx2]
//! prefix = "driftless_"      # file prefix in /dev/shm (env DRIFTLESS_IOX2_PREFIX overrides)
//! root_path = "/run/driftless/iceoryx2"  # iceoryx2's node and service files (default
//!                            # /tmp/iceoryx2; env DRIFTLESS_IOX2_ROOT overrides)
//! buffer_size = 256          # samples a subscriber may hold before it loses new ones
//! max_subscribers = 8        # per service
//! stats_service = "demo/stats"
//!
//! [[stage]]
//! name = "sensor"
//! kind = "ingest.csv"
//! output = "demo/raw"
//! file = "data/replay.csv"
//! ```
//!
//! Every error names the file, line and column (from toml's spans); unknown keys are errors;
//! the stages must form one chain from an ingest to a publish, without cycles or dangling inputs.
//! An `external` stage (run by another process) is a link of the chain like any other; it may
//! not directly follow the ingest, end the chain, or follow another external stage.

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use toml::de::{DeTable, DeValue};
use toml::Spanned;

use crate::io::InputError;
use crate::pipeline::registry::{self, Entry};
use crate::sides::{Chain, SideSpec, SIDES};
use crate::stages::contract::Role;
pub use crate::stages::contract::StageSpec;
pub use crate::stages::schema::Context;
use crate::stages::schema::{sort_entries, DefaultValue, Entries, Key, Src, Table, Type};
use crate::units::{AccelUnit, RateUnit};

use super::iceoryx2_table::{self, ICEORYX2_TABLE};
pub use super::iceoryx2_table::{Iceoryx2Settings, ICEORYX2_KEYS};

/// A validated pipeline, stages in chain order (the ingest first, the publish last).
#[derive(Debug, Clone)]
pub struct Pipeline {
    /// The file it was read from.
    pub path: PathBuf,
    /// Pipeline name.
    pub name: String,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// End-to-end deadline.
    pub deadline: Duration,
    /// Number of axes (1..=3); unused axes are 0.
    pub axes: usize,
    /// Units of the raw input.
    pub input_units: RateUnit,
    /// Units of the raw accelerometer readings.
    pub accel_units: AccelUnit,
    /// Period of the stderr summary and stats snapshot.
    pub report_interval: Duration,
    /// SCHED_FIFO priority of the hot thread (None: the default scheduler).
    pub realtime_priority: Option<i32>,
    /// CPU the hot thread is pinned to (None: not pinned).
    pub cpu: Option<usize>,
    /// How long before a paced sample is due the hot thread wakes to bring the stages' state
    /// into the cache ([`Stage::prewarm`](crate::stages::contract::Stage::prewarm)); zero: it does not.
    pub prewarm: Duration,
    /// iceoryx2 settings.
    pub iceoryx2: Iceoryx2Settings,
    /// What runs beside the chain (`[ros2]`...), in the order of the file.
    pub sides: Vec<SideSpec>,
    /// Lines worth a warning that do not stop the pipeline (`validate` and `run` print them).
    pub warnings: Vec<String>,
    /// The stages, in chain order.
    pub stages: Vec<StageSpec>,
}

impl Pipeline {
    /// The pipeline-wide values stages are validated and built against.
    pub fn context(&self) -> Context {
        Context {
            rate_hz: self.rate_hz,
            axes: self.axes,
            units: self.input_units,
            accel_units: self.accel_units,
            white_noise: self.stages.iter().find_map(|s| s.params.white_noise()),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The pipeline's own keys, declared like a stage kind's: the same declarations check the file,
// and `validate --kinds` and the generated reference list them.

const NAME: Key = Key {
    name: "name",
    ty: Type::Str("`[A-Za-z0-9_-]+`"),
    default: DefaultValue::Required,
    doc: "pipeline name; the daemon's node is `driftless-<name>`",
};
const RATE_HZ: Key = Key {
    name: "rate_hz",
    ty: Type::Positive(1e6),
    default: DefaultValue::Required,
    doc: "sample rate of the ingest",
};
const DEADLINE_US: Key = Key {
    name: "deadline_us",
    ty: Type::Positive(1e9),
    default: DefaultValue::Derived("one period (at the ingest's `pace`)"),
    doc: "end-to-end deadline counted in `deadline_misses`",
};
const AXES: Key = Key {
    name: "axes",
    ty: Type::Int(1, 3),
    default: DefaultValue::Int(3),
    doc: "axes processed; unused axes are 0",
};
const INPUT_UNITS: Key = Key {
    name: "input_units",
    ty: Type::Choice(&RateUnit::NAMES),
    default: DefaultValue::Word(RateUnit::DegPerS.name()),
    doc: "units of the raw rates; published rates are rad/s",
};
const ACCEL_UNITS: Key = Key {
    name: "accel_units",
    ty: Type::Choice(&AccelUnit::NAMES),
    default: DefaultValue::Word(AccelUnit::MPerS2.name()),
    doc: "units of the raw accelerometer readings (`g`: 9.80665 m/s²); published readings are \
          m/s²",
};
const REPORT_INTERVAL_S: Key = Key {
    name: "report_interval_s",
    ty: Type::FloatIn(0.01, 3600.0),
    default: DefaultValue::Float(2.0),
    doc: "period of the stderr line and of the stats service",
};
const REALTIME_PRIORITY: Key = Key {
    name: "realtime_priority",
    ty: Type::Int(1, 99),
    default: DefaultValue::Absent("none"),
    doc: "SCHED_FIFO priority of the hot thread (docs/pipelines.md, Scheduling)",
};
const CPU: Key = Key {
    name: "cpu",
    ty: Type::Int(0, 1023),
    default: DefaultValue::Absent("none"),
    doc: "pin the hot thread to this CPU",
};
const PREWARM_US: Key = Key {
    name: "prewarm_us",
    ty: Type::Float("0..=half a period"),
    default: DefaultValue::Noted(&DefaultValue::Float(0.0), " (off)"),
    doc: "wake this long before each paced sample to warm the cache (docs/pipelines.md, \
          Scheduling)",
};

/// The pipeline file's top-level keys, in the order listed.
pub const PIPELINE_KEYS: &[Key] = &[
    NAME,
    RATE_HZ,
    DEADLINE_US,
    AXES,
    INPUT_UNITS,
    ACCEL_UNITS,
    REPORT_INTERVAL_S,
    REALTIME_PRIORITY,
    CPU,
    PREWARM_US,
];

/// Split a table's entries by the keys declared for it: an undeclared key is an error at its
/// position that lists the valid ones.
fn split<'i>(
    src: &Src<'_>,
    table: DeTable<'i>,
    valid: &[&'static str],
) -> Result<Entries<'i>, InputError> {
    let (declared, strays) = sort_entries(table, valid);
    match strays.first() {
        Some((key, at)) => {
            let listed: Vec<String> = valid.iter().map(|k| format!("`{k}`")).collect();
            Err(src.at(
                *at,
                format!(
                    "unknown field `{key}`, expected one of {}",
                    listed.join(", ")
                ),
            ))
        }
        None => Ok(declared),
    }
}

/// A table value as its entries, or an error at it.
fn table<'i>(
    src: &Src<'_>,
    key: &str,
    value: Spanned<DeValue<'i>>,
) -> Result<(usize, DeTable<'i>), InputError> {
    let at = value.span().start;
    match value.into_inner() {
        DeValue::Table(t) => Ok((at, t)),
        _ => Err(src.at(at, format!("`{key}` must be a table ([{key}])"))),
    }
}

/// Read and validate a pipeline file: everything `run` needs is checked here, nothing started.
pub fn load(path: &Path) -> Result<Pipeline, InputError> {
    let text = std::fs::read_to_string(path).map_err(|source| {
        // Not UTF-8: say what it holds instead.
        let sniffed = crate::io::content::sniff(path);
        match sniffed {
            Ok(s) if source.kind() == std::io::ErrorKind::InvalidData && !s.content.is_text() => {
                s.refuse("a pipeline file is TOML text")
            }
            _ => InputError::Io {
                path: path.display().to_string(),
                source,
            },
        }
    })?;
    parse(path, &text)
}

/// Validate pipeline text as if read from `path` (relative files resolve against its folder).
pub fn parse(path: &Path, text: &str) -> Result<Pipeline, InputError> {
    let src = Src { path, text };
    let doc = DeTable::parse(text).map_err(|e| src.toml(e, 0))?;
    let doc_span = doc.span();
    let mut top = DeTable::new();
    let mut stage_values: Option<Spanned<DeValue<'_>>> = None;
    let mut iox = DeTable::new();
    let mut iox_at = doc_span.start;
    let mut side_tables = Vec::new();
    for (k, v) in doc.into_inner() {
        let key = k.get_ref().as_ref();
        if key == "stage" {
            stage_values = Some(v);
        } else if key == ICEORYX2_TABLE {
            (iox_at, iox) = table(&src, key, v)?;
        } else if let Some(kind) = SIDES.iter().find(|s| s.table == key) {
            side_tables.push((*kind, table(&src, key, v)?));
        } else {
            top.insert(k, v);
        }
    }
    let valid: Vec<&'static str> = PIPELINE_KEYS
        .iter()
        .map(|k| k.name)
        .chain([ICEORYX2_TABLE])
        .chain(SIDES.iter().map(|s| s.table))
        .collect();
    // Until the chain is read, the context is unknown: the pipeline's own readers need none.
    let unknown = Context {
        rate_hz: f64::NAN,
        axes: 0,
        units: RateUnit::DegPerS,
        accel_units: AccelUnit::MPerS2,
        white_noise: None,
    };
    let top = split(&src, top, &valid)?;
    let mut t = Table::new(
        &src,
        unknown,
        doc_span.start,
        doc_span.start,
        None,
        ("", ""),
        top,
    );
    let name = t.required_str(&NAME)?;
    let rate_hz = t.required_float(&RATE_HZ)?;
    valid_name(&src, &name)?;
    let name = name.into_inner();
    let deadline_us = t.float(&DEADLINE_US)?;
    let axes = t.int_or_default(&AXES)?;
    let (input_units, accel_units) = units(&mut t)?;
    let report_interval = Duration::from_secs_f64(t.float_or_default(&REPORT_INTERVAL_S)?);
    let realtime_priority = t.int(&REALTIME_PRIORITY)?.map(|p| p as i32);
    let cpu = t.int(&CPU)?;
    let prewarm_us = match t.get::<f64>(&PREWARM_US)? {
        // Waking a whole period early would be waking for the sample before.
        Some(w) => src.float_in(&w, PREWARM_US.name, 0.0, 0.5e6 / rate_hz)?,
        None => PREWARM_US.default.float(),
    };
    let prewarm = Duration::from_secs_f64(prewarm_us * 1e-6);
    let valid: Vec<&'static str> = ICEORYX2_KEYS.iter().map(|k| k.name).collect();
    let iox = split(&src, iox, &valid)?;
    let mut t = Table::new(&src, unknown, iox_at, iox_at, None, (&name, ""), iox);
    let iceoryx2 = iceoryx2_table::read(&mut t, &src, &name)?;

    let Some(stage_values) = stage_values else {
        return Err(src.at(
            doc_span.end,
            "no [[stage]] entries: a pipeline needs at least an ingest and a publish",
        ));
    };
    let stage_span = stage_values.span();
    let DeValue::Array(array) = stage_values.into_inner() else {
        return Err(src.at(
            stage_span.start,
            "`stage` must be an array of tables ([[stage]])",
        ));
    };
    let cx = Context {
        rate_hz,
        axes,
        units: input_units,
        accel_units,
        white_noise: None,
    };
    let mut entries = Vec::new();
    for value in array {
        entries.push(registry::stage(&src, value, cx, &name)?);
    }
    let stages = chain(&src, entries, stage_span.start)?;
    let deadline = deadline(deadline_us, &stages, rate_hz);
    let warnings = warnings(&stages, input_units);
    let chain = Chain {
        pipeline: &name,
        cx,
        stages: &stages,
        stats_service: &iceoryx2.stats_service,
    };
    let sides = sides(&src, side_tables, &name, &chain)?;
    Ok(Pipeline {
        path: path.to_path_buf(),
        name,
        rate_hz,
        deadline,
        axes,
        input_units,
        accel_units,
        report_interval,
        realtime_priority,
        cpu,
        prewarm,
        iceoryx2,
        sides,
        warnings,
        stages,
    })
}

/// A pipeline's name: non-empty ASCII letters, digits, '-' or '_'.
fn valid_name(src: &Src<'_>, name: &Spanned<String>) -> Result<(), InputError> {
    if name.get_ref().is_empty()
        || !name
            .get_ref()
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
    {
        return Err(src.span(
            name,
            "name must be non-empty ASCII letters, digits, '-' or '_'",
        ));
    }
    Ok(())
}

/// The rate units and the accelerometer's (`input_units`, `accel_units`).
fn units(t: &mut Table<'_, '_>) -> Result<(RateUnit, AccelUnit), InputError> {
    // Choice keys: the table read only their names, which parse.
    let input_units: RateUnit = t
        .choice_or_default(&INPUT_UNITS, "input_units", true)?
        .parse()
        .unwrap_or_default();
    let accel_units: AccelUnit = t
        .choice_or_default(&ACCEL_UNITS, "accel_units", true)?
        .parse()
        .unwrap_or_default();
    Ok((input_units, accel_units))
}

/// The deadline: `deadline_us`, or one period of the samples as they fall due.
fn deadline(deadline_us: Option<f64>, stages: &[StageSpec], rate_hz: f64) -> Duration {
    match deadline_us {
        Some(us) => Duration::from_secs_f64(us * 1e-6),
        // One period of the samples as they fall due: a replay at pace 10 takes one every
        // tenth of a period, and a chain slower than that falls behind.
        None => {
            let speed = stages
                .first()
                .and_then(|s| s.params.pace())
                .and_then(crate::clock::Pace::factor)
                .unwrap_or(1.0);
            Duration::from_secs_f64(1.0 / (rate_hz * speed))
        }
    }
}

/// The pipeline's warnings: the step a stage assumes against the data's, then each stage's own.
fn warnings(stages: &[StageSpec], input_units: RateUnit) -> Vec<String> {
    step_warning(stages, input_units)
        .into_iter()
        .chain(stages.iter().flat_map(|s| {
            let name = &s.name;
            s.params
                .warnings()
                .into_iter()
                .map(move |w| format!("stage {name:?}: {w}"))
        }))
        .collect()
}

/// The side tables read against the chain, in the file's order.
fn sides<'i>(
    src: &Src<'_>,
    side_tables: Vec<(&'static crate::sides::Kind, (usize, DeTable<'i>))>,
    name: &str,
    chain: &Chain<'_>,
) -> Result<Vec<SideSpec>, InputError> {
    let mut sides = Vec::new();
    for (kind, (at, table)) in side_tables {
        let valid: Vec<&'static str> = kind.keys.iter().map(|k| k.name).collect();
        let own = split(src, table, &valid)?;
        let mut t = Table::new(src, chain.cx, at, at, None, (name, kind.table), own);
        let side = (kind.read)(&mut t, chain)?;
        sides.push(SideSpec {
            kind,
            side: Arc::from(side),
        });
    }
    Ok(sides)
}

/// The step the data shows against the step a stage assumes (a profile's `lsb`): one line when
/// they differ by more than a quarter (a profile of another sensor, or `lsb` in other units).
fn step_warning(stages: &[StageSpec], units: RateUnit) -> Option<String> {
    let deg_per_unit = units.to_rad_per_s().to_degrees();
    let seen = stages.iter().find_map(|s| s.params.data_step())? * deg_per_unit;
    let (stage, assumed) = stages
        .iter()
        .find_map(|s| Some((&s.name, s.params.assumed_step()?)))?;
    if assumed > 0.0 && (seen < 0.75 * assumed || seen > 1.25 * assumed) {
        return Some(format!(
            "stage {stage:?} assumes the raw rate steps by {assumed} deg/s (its lsb), but the data's \
             smallest step is {seen:.3e} deg/s: another sensor's profile? Set lsb to the data's \
             step (0 if it is not quantised)"
        ));
    }
    None
}

/// Order the stages into one chain ingest -> ... -> publish, or say where it breaks.
fn chain(src: &Src<'_>, entries: Vec<Entry>, at: usize) -> Result<Vec<StageSpec>, InputError> {
    if entries.len() > crate::metrics::MAX_STAGES {
        return Err(src.at(
            at,
            format!(
                "{} stages: a pipeline has at most {}",
                entries.len(),
                crate::metrics::MAX_STAGES
            ),
        ));
    }
    unique_names(src, &entries)?;
    let ingests: Vec<&Entry> = entries.iter().filter(|e| e.spec.kind.is_ingest()).collect();
    let Some(ingest) = ingests.first() else {
        let ingests: Vec<&str> = registry::KINDS
            .iter()
            .filter(|k| k.is_ingest())
            .map(|k| k.name)
            .collect();
        return Err(src.at(
            at,
            format!("no ingest stage (kinds {})", ingests.join(", ")),
        ));
    };
    if let Some(second) = ingests.get(1) {
        return Err(src.at(
            second.name_at,
            format!(
                "a second ingest stage {:?}: a pipeline has exactly one (the first is {:?})",
                second.spec.name, ingest.spec.name
            ),
        ));
    }
    // Every non-ingest input must be some stage's output.
    for e in entries.iter().filter(|e| !e.spec.kind.is_ingest()) {
        let input = e.spec.input.as_deref().unwrap_or("");
        if !entries.iter().any(|p| p.spec.output == input) {
            return Err(src.at(
                e.input_at,
                format!(
                    "dangling input {input:?}: no stage of this pipeline publishes it (a service of another process is read by ingest.iceoryx2 at the head of the chain, or declared by an `external` stage)"
                ),
            ));
        }
        if e.spec.output == input {
            return Err(src.at(
                e.output_at,
                format!("cycle: stage {:?} reads its own output", e.spec.name),
            ));
        }
    }
    let order = walk(src, &entries, &ingest.spec.name)?;
    externals_placed(src, &entries, &order)?;
    let last = &entries[*order.last().unwrap_or(&0)];
    if last.spec.kind.role != Role::Publish {
        return Err(src.at(
            last.output_at,
            format!(
                "the chain ends at stage {:?} ({}), not at a publish stage",
                last.spec.name, last.spec.kind.name
            ),
        ));
    }
    for &i in &order[1..order.len() - 1] {
        if entries[i].spec.kind.role == Role::Publish {
            return Err(src.at(
                entries[i].name_at,
                "a publish stage must be the last of the chain",
            ));
        }
    }
    if order.len() < 2 {
        return Err(src.at(at, "a pipeline needs an ingest and a publish stage"));
    }
    let mut slots: Vec<Option<Entry>> = entries.into_iter().map(Some).collect();
    Ok(order
        .into_iter()
        .filter_map(|i| slots[i].take().map(|e| e.spec))
        .collect())
}

/// Unique stage names and outputs: each service has one publisher.
fn unique_names(src: &Src<'_>, entries: &[Entry]) -> Result<(), InputError> {
    // Unique names and outputs.
    for (i, e) in entries.iter().enumerate() {
        if let Some(prev) = entries[..i].iter().find(|p| p.spec.name == e.spec.name) {
            let pos = src.at(prev.name_at, "");
            return Err(src.at(
                e.name_at,
                format!(
                    "duplicate stage name {:?} (first used at {})",
                    e.spec.name,
                    position(&pos)
                ),
            ));
        }
        if let Some(prev) = entries[..i].iter().find(|p| p.spec.output == e.spec.output) {
            return Err(src.at(
                e.output_at,
                format!(
                    "service {:?} is already the output of stage {:?}: each service has one publisher",
                    e.spec.output, prev.spec.name
                ),
            ));
        }
    }
    Ok(())
}

/// The chain's order, walked from the ingest (`entries`' first ingest stage, named `ingest`):
/// each output read by at most one stage, no cycle, every stage reached.
fn walk(src: &Src<'_>, entries: &[Entry], ingest: &str) -> Result<Vec<usize>, InputError> {
    // Walk from the ingest.
    let mut order: Vec<usize> = Vec::with_capacity(entries.len());
    let mut current = entries
        .iter()
        .position(|e| e.spec.kind.is_ingest())
        .unwrap_or(0);
    order.push(current);
    loop {
        let out = &entries[current].spec.output;
        let readers: Vec<usize> = entries
            .iter()
            .enumerate()
            .filter(|(_, e)| !e.spec.kind.is_ingest() && e.spec.input.as_deref() == Some(out))
            .map(|(i, _)| i)
            .collect();
        match readers.as_slice() {
            [] => break,
            [next] => {
                if order.contains(next) {
                    return Err(src.at(entries[*next].input_at, "cycle in the stage chain"));
                }
                order.push(*next);
                current = *next;
            }
            [_, second, ..] => {
                return Err(src.at(
                    entries[*second].input_at,
                    format!("service {out:?} is read by more than one stage: the stages must form one chain"),
                ))
            }
        }
    }
    if let Some(stray) = (0..entries.len()).find(|i| !order.contains(i)) {
        return Err(src.at(
            entries[stray].input_at,
            format!(
                "cycle: stage {:?} is not reachable from the ingest {:?}",
                entries[stray].spec.name, ingest
            ),
        ));
    }
    Ok(order)
}

/// External stages in the chain `order`: neither first after the ingest nor last, nor two in
/// a row.
fn externals_placed(src: &Src<'_>, entries: &[Entry], order: &[usize]) -> Result<(), InputError> {
    let is_external = |i: usize| entries[i].spec.kind.role == Role::External;
    for (pos, &i) in order.iter().enumerate() {
        if !is_external(i) {
            continue;
        }
        if pos == 1 {
            return Err(src.at(
                entries[i].input_at,
                format!(
                    "external stage {:?} cannot be the first stage after the ingest: it would read the raw service {:?}; put a daemon stage (e.g. denoise.none) before it",
                    entries[i].spec.name,
                    entries[i].spec.input.as_deref().unwrap_or("")
                ),
            ));
        }
        if pos == order.len() - 1 {
            return Err(src.at(
                entries[i].output_at,
                format!(
                    "external stage {:?} cannot be the last stage: the chain ends at a publish stage the daemon runs",
                    entries[i].spec.name
                ),
            ));
        }
        if is_external(order[pos - 1]) {
            return Err(src.at(
                entries[i].input_at,
                format!(
                    "external stage {:?} follows external stage {:?}: merge them into one external process or put a daemon stage between",
                    entries[i].spec.name,
                    entries[order[pos - 1]].spec.name
                ),
            ));
        }
    }
    Ok(())
}

fn position(e: &InputError) -> Cow<'static, str> {
    match e {
        InputError::At { line, column, .. } => Cow::Owned(format!("{line}:{column}")),
        _ => Cow::Borrowed("?"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clock::Pace;

    const HEAD: &str = "name = \"t\"\nrate_hz = 500.0\n";
    const INGEST: &str =
        "[[stage]]\nname = \"in\"\nkind = \"ingest.iceoryx2\"\ninput = \"s/raw\"\noutput = \"t/raw\"\n";
    const DENOISE: &str =
        "[[stage]]\nname = \"dn\"\nkind = \"denoise.none\"\ninput = \"t/raw\"\noutput = \"t/dn\"\n";
    const PUBLISH: &str =
        "[[stage]]\nname = \"pub\"\nkind = \"publish\"\ninput = \"t/dn\"\noutput = \"t/out\"\n";

    fn parse_str(text: &str) -> Result<Pipeline, String> {
        parse(Path::new("p.toml"), text).map_err(|e| e.to_string())
    }

    #[test]
    fn stages_are_ordered_as_a_chain_whatever_the_file_order() {
        let p = parse_str(&format!("{HEAD}{PUBLISH}{DENOISE}{INGEST}")).unwrap();
        let names: Vec<&str> = p.stages.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["in", "dn", "pub"]);
        assert_eq!(
            p.deadline,
            Duration::from_millis(2),
            "default: one sample period"
        );
        assert_eq!(p.axes, 3);
        assert_eq!(p.input_units, RateUnit::DegPerS);
        assert_eq!(p.iceoryx2.stats_service, "t/stats");
    }

    #[test]
    fn a_chain_must_end_at_a_publish() {
        let e = parse_str(&format!("{HEAD}{INGEST}{DENOISE}")).unwrap_err();
        assert!(
            e.starts_with("p.toml:12:10: the chain ends at stage \"dn\""),
            "{e}"
        );
    }

    #[test]
    fn a_service_read_twice_is_not_a_chain() {
        let second = PUBLISH
            .replace("\"pub\"", "\"pub2\"")
            .replace("t/out", "t/out2");
        let e = parse_str(&format!("{HEAD}{INGEST}{DENOISE}{PUBLISH}{second}")).unwrap_err();
        assert!(e.contains("read by more than one stage"), "{e}");
    }

    #[test]
    fn an_external_stage_is_a_link_of_the_chain() {
        let ext = "[[stage]]\nname = \"ext\"\nkind = \"external\"\ninput = \"t/dn\"\noutput = \"t/ext\"\n";
        let publish = PUBLISH.replace("input = \"t/dn\"", "input = \"t/ext\"");
        let p = parse_str(&format!("{HEAD}{publish}{ext}{DENOISE}{INGEST}")).unwrap();
        let names: Vec<&str> = p.stages.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["in", "dn", "ext", "pub"]);
        assert_eq!(p.stages[2].kind.name, "external");
        assert_eq!(p.stages[2].params.poll_timeout(), Duration::from_millis(1));
        // Without the external declaration the publish stage's input dangles.
        let e = parse_str(&format!("{HEAD}{publish}{DENOISE}{INGEST}")).unwrap_err();
        assert!(e.contains("dangling input \"t/ext\""), "{e}");
    }

    #[test]
    fn errors_point_at_the_offending_value() {
        let e = parse_str(&format!(
            "name = \"t\"\nrate_hz = 500.0\naxes = 4\n{INGEST}{PUBLISH}"
        ))
        .unwrap_err();
        assert!(
            e.starts_with("p.toml:3:8: axes must be in 1..=3, got 4"),
            "{e}"
        );
    }

    #[test]
    fn a_pace_is_a_word_or_a_factor_and_the_default_deadline_one_period_at_it() {
        let with = |head: &str, pace: &str| {
            parse_str(&format!(
                "{head}[[stage]]\nname = \"in\"\nkind = \"ingest.sim\"\noutput = \"t/raw\"\n\
                 pace = {pace}\n{}",
                PUBLISH.replace("t/dn", "t/raw")
            ))
        };
        let sim = |pace: &str| with(HEAD, pace);
        let paced = |pace: &str| {
            let p = sim(pace).unwrap();
            (p.stages[0].params.pace(), p.deadline)
        };
        let period = Duration::from_millis(2);
        assert_eq!(paced("\"realtime\""), (Some(Pace::REALTIME), period));
        assert_eq!(paced("1.0"), paced("\"realtime\""), "1.0 is real time");
        assert_eq!(paced("\"asap\""), (Some(Pace::Asap), period));
        assert_eq!(paced("10.0"), (Some(Pace::Times(10.0)), period / 10));
        assert_eq!(paced("10"), paced("10.0"), "an integer too");
        assert_eq!(paced("1000"), (Some(Pace::Times(1000.0)), period / 1000));
        // An explicit deadline is the user's, at any pace.
        let own = with(&format!("{HEAD}deadline_us = 700.0\n"), "10.0").unwrap();
        assert_eq!(own.deadline, Duration::from_micros(700));
        for bad in [
            "0", "0.0", "-2.5", "nan", "inf", "1000.5", "1e9", "\"fast\"", "true",
        ] {
            let e = sim(bad).unwrap_err();
            assert!(
                e.starts_with("p.toml:7:8: pace must be \"realtime\", \"asap\" or a number > 0 and <= 1000, got "),
                "{bad}: {e}"
            );
        }
        assert!(sim("true").unwrap_err().ends_with("got a boolean"));
        assert!(sim("-2.5").unwrap_err().ends_with("got -2.5"));
    }

    /// The pipeline's own, `[iceoryx2]`'s and every side's keys: a typed default is a value
    /// of the key's own type and range.
    #[test]
    fn every_pipeline_and_side_default_fits_its_key() {
        let sides = crate::sides::SIDES.iter().flat_map(|s| s.keys);
        for key in PIPELINE_KEYS.iter().chain(ICEORYX2_KEYS).chain(sides) {
            key.check_default().unwrap_or_else(|e| panic!("{e}"));
        }
    }

    /// A file that writes out every typed default reads as the file that leaves them out: the
    /// declared default (what the reference prints) is the applied one.
    #[test]
    fn the_declared_defaults_are_the_applied_ones() {
        let written = |keys: &[Key]| -> String {
            keys.iter()
                .filter_map(|k| {
                    let value = match k.default.value()? {
                        DefaultValue::Int(v) => v.to_string(),
                        DefaultValue::Float(v) => format!("{v:?}"),
                        DefaultValue::Word(w) => format!("{w:?}"),
                        DefaultValue::Bool(b) => b.to_string(),
                        other => panic!("{}: {other:?} has no TOML form here", k.name),
                    };
                    Some(format!("{} = {value}\n", k.name))
                })
                .collect()
        };
        let (top, iox) = (written(PIPELINE_KEYS), written(ICEORYX2_KEYS));
        assert_eq!(top.lines().count(), 5, "{top}");
        assert_eq!(iox.lines().count(), 3, "{iox}");
        let chain = format!("{INGEST}{DENOISE}{PUBLISH}");
        let bare = parse_str(&format!("{HEAD}{chain}")).unwrap();
        let full = parse_str(&format!("{HEAD}{top}[iceoryx2]\n{iox}{chain}")).unwrap();
        let settings = |p: &Pipeline| {
            format!(
                "{} {:?} {} {:?} {:?} {:?} {:?} {:?}",
                p.rate_hz,
                p.deadline,
                p.axes,
                p.input_units,
                p.report_interval,
                p.prewarm,
                p.cpu,
                p.iceoryx2
            )
        };
        assert_eq!(settings(&full), settings(&bare));
    }
}
