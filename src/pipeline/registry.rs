//! The registry of stage kinds as the pipeline file's reader uses it: a kind by name, and one
//! `[[stage]]` table read by its kind: the keys every stage has here, the kind's own keys by the
//! kind's parse function ([`crate::stages`] lists the kinds). A key the kind does not take is
//! an error that names the kind it belongs to, if any: operators swap a stage by editing its
//! `kind` and leave the old kind's keys behind.

use std::sync::Arc;

use toml::de::DeValue;
use toml::Spanned;

use crate::io::InputError;
use crate::stages::contract::{Kind, Params, StageSpec};
use crate::stages::schema::{sort_entries, Context, Src, Table};
pub use crate::stages::KINDS;

/// The kind called `name` in pipeline files.
pub fn kind(name: &str) -> Option<&'static Kind> {
    KINDS.iter().copied().find(|k| k.name == name)
}

/// The kinds' names, in the order listed in messages.
pub(crate) fn kind_names() -> String {
    KINDS.iter().map(|k| k.name).collect::<Vec<_>>().join(", ")
}

/// A parsed stage with the positions the chain check reports.
pub(crate) struct Entry {
    pub spec: StageSpec,
    pub name_at: usize,
    pub input_at: usize,
    pub output_at: usize,
}

/// Keys every `[[stage]]` table has, whatever its kind (`input` only where the kind reads one).
const COMMON: [&str; 4] = ["name", "kind", "input", "output"];

/// The keys a kind's table may hold, in the order error messages list them.
fn accepted(kind: &Kind) -> Vec<&'static str> {
    COMMON
        .into_iter()
        .filter(|k| *k != "input" || kind.has_input())
        .chain(kind.keys.iter().map(|k| k.name))
        .collect()
}

/// What to say of a key `kind` does not take: when another kind takes it (a stage swapped by
/// editing its `kind`), name that kind and what to do; otherwise list the valid keys.
fn stray_key(kind: &Kind, key: &str, others: &[String]) -> String {
    let valid = accepted(kind);
    let listed = valid
        .iter()
        .map(|k| format!("`{k}`"))
        .collect::<Vec<_>>()
        .join(", ");
    let owners: Vec<&str> = KINDS
        .iter()
        .filter(|k| k.name != kind.name && accepted(k).contains(&key))
        .map(|k| k.name)
        .collect();
    if owners.is_empty() {
        return format!("unknown field `{key}`, expected one of {listed}");
    }
    let owners = if owners.len() > 3 {
        "other kinds".to_string()
    } else {
        owners.join(" and ")
    };
    let also = if others.is_empty() {
        String::new()
    } else {
        format!(
            " (also {})",
            others
                .iter()
                .map(|k| format!("`{k}`"))
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    format!(
        "`{key}` belongs to {owners}, not to {}: remove it{also}. {} takes {listed}; `driftless validate --kinds` lists every kind's keys with their defaults",
        kind.name, kind.name
    )
}

/// Read one `[[stage]]` table: its kind from the registry, the keys every stage has, then the
/// kind's own keys through the kind's parse function.
pub(crate) fn stage(
    src: &Src<'_>,
    value: Spanned<DeValue<'_>>,
    cx: Context,
    pipeline: &str,
) -> Result<Entry, InputError> {
    let start = value.span().start;
    let DeValue::Table(table) = value.into_inner() else {
        return Err(src.at(start, "each [[stage]] must be a table"));
    };
    let kind_value = table
        .iter()
        .find(|(k, _)| k.get_ref() == "kind")
        .map(|(_, v)| (v.span().start, v.get_ref().as_str().map(str::to_string)));
    let (kind_at, kind_name) = match kind_value {
        None => {
            return Err(src.at(
                start,
                format!("stage without `kind` (valid: {})", kind_names()),
            ))
        }
        Some((at, None)) => return Err(src.at(at, "`kind` must be a string")),
        Some((at, Some(k))) => (at, k),
    };
    let Some(kind) = kind(&kind_name) else {
        return Err(src.at(
            kind_at,
            format!("unknown kind {kind_name:?} (valid: {})", kind_names()),
        ));
    };
    // Sort the keys: the common ones, the kind's own, and strays (an error, at the first).
    let (declared, strays) = sort_entries(table, &accepted(kind));
    let (mut common, own): (Vec<_>, Vec<_>) =
        declared.into_iter().partition(|(n, _)| COMMON.contains(n));
    if let Some(((first, at), rest)) = strays.split_first() {
        let others: Vec<String> = rest.iter().map(|(k, _)| k.clone()).collect();
        return Err(src.at(*at, stray_key(kind, first, &others)));
    }
    let mut take = |key: &str| -> Result<Option<Spanned<String>>, InputError> {
        match common.iter().position(|(k, _)| *k == key) {
            Some(i) => src.de(common.swap_remove(i).1).map(Some),
            None => Ok(None),
        }
    };
    let missing = |key: &str| src.at(start, format!("missing field `{key}`"));
    let name = take("name")?.ok_or_else(|| missing("name"))?;
    let input = if kind.has_input() {
        Some(take("input")?.ok_or_else(|| missing("input"))?)
    } else {
        None
    };
    let output = take("output")?.ok_or_else(|| missing("output"))?;
    let mut t = Table::new(
        src,
        cx,
        start,
        kind_at,
        input.as_ref().map(|i| i.get_ref().as_str()),
        (pipeline, name.get_ref().as_str()),
        own,
    );
    let params: Arc<dyn Params> = Arc::from((kind.parse)(&mut t)?);
    if name.get_ref().is_empty() {
        return Err(src.span(&name, "stage name must not be empty"));
    }
    Ok(Entry {
        spec: StageSpec {
            name: name.get_ref().clone(),
            input: input.as_ref().map(|i| src.service(i)).transpose()?,
            output: src.service(&output)?,
            kind,
            params,
        },
        name_at: name.span().start,
        input_at: input.as_ref().map_or(start, |i| i.span().start),
        output_at: output.span().start,
    })
}
