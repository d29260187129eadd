//! What every stage file needs to read its own `[[stage]]` table: positioned errors, typed
//! keys with their ranges and defaults, and the pipeline-wide values a stage may depend on.
//!
//! A stage kind declares its keys as [`Key`]s (name, type and range, default, meaning); the
//! same declarations check the table ([`StageTable`]'s readers), reject keys of other kinds,
//! and are listed by `driftless validate --kinds`, so the documentation cannot drift from the
//! checks. Arrows point one way: stage files use this module; it knows no stage file.

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Deserialize;
use toml::de::DeValue;
use toml::Spanned;

use crate::io::InputError;

/// Input units of the raw rates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Units {
    /// Degrees per second.
    DegPerSec,
    /// Radians per second.
    RadPerSec,
}

impl Units {
    /// Factor converting these units to rad/s.
    pub fn to_rad_per_sec(self) -> f64 {
        match self {
            Units::DegPerSec => std::f64::consts::PI / 180.0,
            Units::RadPerSec => 1.0,
        }
    }

    /// The name used in pipeline and model files.
    pub fn name(self) -> &'static str {
        match self {
            Units::DegPerSec => "deg/s",
            Units::RadPerSec => "rad/s",
        }
    }
}

/// The pipeline-wide values a stage is validated and built against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Context {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Number of axes (1..=3).
    pub axes: usize,
    /// Units of the raw input.
    pub units: Units,
}

/// Positions errors in one source text.
pub struct Src<'a> {
    /// The file the text was read from (errors name it; relative paths resolve against it).
    pub path: &'a Path,
    /// The text.
    pub text: &'a str,
}

impl Src<'_> {
    /// An error at a byte offset, as file:line:column.
    pub fn at(&self, offset: usize, message: impl Into<String>) -> InputError {
        let offset = offset.min(self.text.len());
        let before = &self.text[..floor_char_boundary(self.text, offset)];
        let line = before.matches('\n').count() as u64 + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = before[line_start..].chars().count() as u64 + 1;
        InputError::At {
            path: self.path.display().to_string(),
            line,
            column,
            message: message.into(),
        }
    }

    /// An error at a spanned value.
    pub fn span<T>(&self, s: &Spanned<T>, message: impl Into<String>) -> InputError {
        self.at(s.span().start, message)
    }

    /// A toml error at its own span (or at `fallback`).
    pub fn toml(&self, e: toml::de::Error, fallback: usize) -> InputError {
        let offset = e.span().map_or(fallback, |r| r.start);
        self.at(offset, e.message().trim_end().to_string())
    }

    /// Deserialize a spanned toml value, errors positioned.
    pub fn de<'i, T: Deserialize<'i>>(&self, value: Spanned<DeValue<'i>>) -> Result<T, InputError> {
        let start = value.span().start;
        T::deserialize(serde::de::IntoDeserializer::into_deserializer(value))
            .map_err(|e| self.toml(e, start))
    }

    /// An integer in `lo..=hi`.
    pub fn int_in(
        &self,
        v: &Spanned<i64>,
        what: &str,
        lo: i64,
        hi: i64,
    ) -> Result<usize, InputError> {
        let x = *v.get_ref();
        if x < lo || x > hi {
            return Err(self.span(v, format!("{what} must be in {lo}..={hi}, got {x}")));
        }
        Ok(x as usize)
    }

    /// A finite float in `(0, max]`.
    pub fn positive(&self, v: &Spanned<f64>, what: &str, max: f64) -> Result<f64, InputError> {
        let x = *v.get_ref();
        if !(x.is_finite() && x > 0.0 && x <= max) {
            return Err(self.span(
                v,
                format!("{what} must be > 0 and <= {}, got {}", num(max), num(x)),
            ));
        }
        Ok(x)
    }

    /// A finite float in `[lo, hi]`.
    pub fn float_in(
        &self,
        v: &Spanned<f64>,
        what: &str,
        lo: f64,
        hi: f64,
    ) -> Result<f64, InputError> {
        let x = *v.get_ref();
        if !(x.is_finite() && (lo..=hi).contains(&x)) {
            return Err(self.span(
                v,
                format!(
                    "{what} must be in [{}, {}], got {}",
                    num(lo),
                    num(hi),
                    num(x)
                ),
            ));
        }
        Ok(x)
    }

    /// A valid iceoryx2 service name.
    pub fn service(&self, v: &Spanned<String>) -> Result<String, InputError> {
        crate::transport::check_service_name(v.get_ref())
            .map_err(|e| self.span(v, format!("invalid service name {:?}: {e}", v.get_ref())))?;
        Ok(v.get_ref().clone())
    }

    /// A path written in the pipeline file, relative to the file's folder.
    pub fn resolve(&self, rel: &str) -> PathBuf {
        let rel = Path::new(rel);
        if rel.is_absolute() {
            rel.to_path_buf()
        } else {
            self.path
                .parent()
                .map_or_else(|| rel.to_path_buf(), |d| d.join(rel))
        }
    }
}

/// A number as a person reads it in a message: plain decimals in a readable range, scientific
/// notation outside it (`1e300`, not 301 digits).
pub fn num(x: f64) -> String {
    let a = x.abs();
    if x == 0.0 || !x.is_finite() || (1e-4..1e9).contains(&a) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

fn floor_char_boundary(s: &str, mut i: usize) -> usize {
    while i > 0 && !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

/// The type and range of a key, as listed and as checked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Type {
    /// An integer in `lo..=hi`.
    Int(i64, i64),
    /// An integer whose range depends on other keys (described).
    IntDepends(&'static str),
    /// A finite float in `(0, max]`.
    Positive(f64),
    /// A float with a described range.
    Float(&'static str),
    /// One of these strings.
    Choice(&'static [&'static str]),
    /// A string (described: a file, a name...).
    Str(&'static str),
    /// A list of strings (described).
    StrList(&'static str),
    /// true or false.
    Bool,
    /// A table of its own (its keys described).
    Table(&'static str),
    /// A list of tables (`[[...]]`, their keys described).
    TableList(&'static str),
    /// One of these words, or a finite float in `(0, max]` (`f64::MAX`: no bound).
    WordOrPositive(&'static [&'static str], f64),
}

impl Type {
    /// How `validate --kinds` shows it.
    pub fn describe(&self) -> String {
        match self {
            Type::Int(lo, i64::MAX) => format!("int >= {lo}"),
            Type::Int(lo, hi) => format!("int {lo}..={hi}"),
            Type::IntDepends(d) => format!("int {d}"),
            Type::Positive(max) => positive(*max),
            Type::Float(d) => format!("float {d}"),
            Type::Choice(c) => quoted(c).join(" | "),
            Type::Str(d) => format!("string ({d})"),
            Type::StrList(d) => format!("list of strings ({d})"),
            Type::Bool => "bool".into(),
            Type::Table(d) => format!("table ({d})"),
            Type::TableList(d) => format!("list of tables ({d})"),
            Type::WordOrPositive(words, max) => {
                format!("{} | {}", quoted(words).join(" | "), positive(*max))
            }
        }
    }
}

/// A positive float's range as listed: `float > 0`, or `float (0, 1e3]`.
fn positive(max: f64) -> String {
    if max == f64::MAX {
        "float > 0".into()
    } else {
        format!("float (0, {max:e}]")
    }
}

/// Words as written in a pipeline file, quoted.
fn quoted(words: &[&str]) -> Vec<String> {
    words.iter().map(|w| format!("{w:?}")).collect()
}

/// A value of a [`Type::WordOrPositive`] key.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WordOr {
    /// One of the key's words.
    Word(&'static str),
    /// A number in the key's range.
    Number(f64),
}

/// A key of a stage kind's table: its one declaration, used to read, to check and to list it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Key {
    /// The key as written in the file.
    pub name: &'static str,
    /// Its type and range.
    pub ty: Type,
    /// Its default as shown to users (`"required"` when it has none).
    pub default: &'static str,
    /// What it means.
    pub doc: &'static str,
}

/// A stage kind's own `[[stage]]` table (without `name`, `kind`, `input`, `output`): the kind's
/// parse function takes its keys through the readers below, which check types and ranges
/// against the [`Key`] declarations and position every error.
pub struct StageTable<'a, 'i> {
    /// The pipeline file.
    pub src: &'a Src<'a>,
    /// The pipeline's rate, axes and units.
    pub cx: Context,
    /// Offset of the table (errors about the table as a whole point here).
    pub start: usize,
    /// Offset of the `kind` value.
    pub kind_at: usize,
    /// The stage's input service, if it has one.
    pub input: Option<&'a str>,
    /// The pipeline's name and the stage's (what a stage's saved state is tied to).
    pub owner: (&'a str, &'a str),
    entries: Vec<(&'static str, Spanned<DeValue<'i>>)>,
}

impl<'a, 'i> StageTable<'a, 'i> {
    /// A table whose keys were already checked against the kind's declarations.
    pub(crate) fn new(
        src: &'a Src<'a>,
        cx: Context,
        start: usize,
        kind_at: usize,
        input: Option<&'a str>,
        owner: (&'a str, &'a str),
        entries: Vec<(&'static str, Spanned<DeValue<'i>>)>,
    ) -> Self {
        StageTable {
            src,
            cx,
            start,
            kind_at,
            input,
            owner,
            entries,
        }
    }

    /// An error at the table's start.
    pub fn error(&self, message: impl Into<String>) -> InputError {
        self.src.at(self.start, message)
    }

    /// The value of `key` deserialized as `T`, spanned; None when absent.
    pub fn get<T: Deserialize<'i>>(&mut self, key: &Key) -> Result<Option<Spanned<T>>, InputError> {
        match self.entries.iter().position(|(k, _)| *k == key.name) {
            Some(i) => {
                let (_, v) = self.entries.swap_remove(i);
                self.src.de(v).map(Some)
            }
            None => Ok(None),
        }
    }

    /// A required string.
    pub fn required_str(&mut self, key: &Key) -> Result<Spanned<String>, InputError> {
        self.get(key)?
            .ok_or_else(|| self.error(format!("missing field `{}`", key.name)))
    }

    /// An integer of a [`Type::Int`] key, range-checked.
    pub fn int(&mut self, key: &Key) -> Result<Option<usize>, InputError> {
        let Type::Int(lo, hi) = key.ty else {
            unreachable!("{} is not declared Type::Int", key.name)
        };
        self.int_in(key, lo, hi)
    }

    /// An integer in `lo..=hi` (for keys whose range depends on others).
    pub fn int_in(&mut self, key: &Key, lo: i64, hi: i64) -> Result<Option<usize>, InputError> {
        self.get::<i64>(key)?
            .map(|v| self.src.int_in(&v, key.name, lo, hi))
            .transpose()
    }

    /// A float of a [`Type::Positive`] key, checked (named by the key in the message).
    pub fn positive(&mut self, key: &Key) -> Result<Option<f64>, InputError> {
        let Type::Positive(max) = key.ty else {
            unreachable!("{} is not declared Type::Positive", key.name)
        };
        self.get::<f64>(key)?
            .map(|v| self.src.positive(&v, key.name, max))
            .transpose()
    }

    /// A string of a [`Type::Choice`] key, checked against its choices: "unknown {what} "x"
    /// (valid: ...)", the choices quoted when `quote` is set.
    pub fn choice(
        &mut self,
        key: &Key,
        what: &str,
        quote: bool,
    ) -> Result<Option<String>, InputError> {
        let Type::Choice(valid) = key.ty else {
            unreachable!("{} is not declared Type::Choice", key.name)
        };
        let Some(v) = self.get::<String>(key)? else {
            return Ok(None);
        };
        if !valid.contains(&v.get_ref().as_str()) {
            let list: Vec<String> = valid
                .iter()
                .map(|c| {
                    if quote {
                        format!("{c:?}")
                    } else {
                        c.to_string()
                    }
                })
                .collect();
            return Err(self.src.span(
                &v,
                format!(
                    "unknown {what} {:?} (valid: {})",
                    v.get_ref(),
                    list.join(", ")
                ),
            ));
        }
        Ok(Some(v.into_inner()))
    }

    /// A value of a [`Type::WordOrPositive`] key: one of its words, or a number (an integer
    /// too) in its range; anything else is "{key} must be "a", "b" or a number > 0 and <= max,
    /// got ...".
    pub fn word_or_positive(&mut self, key: &Key) -> Result<Option<WordOr>, InputError> {
        let Type::WordOrPositive(words, max) = key.ty else {
            unreachable!("{} is not declared Type::WordOrPositive", key.name)
        };
        let Some(v) = self.get::<toml::Value>(key)? else {
            return Ok(None);
        };
        let (number, got) = match v.get_ref() {
            toml::Value::String(s) => match words.iter().find(|w| **w == s.as_str()) {
                Some(w) => return Ok(Some(WordOr::Word(w))),
                None => (None, format!("{s:?}")),
            },
            toml::Value::Float(x) => (Some(*x), num(*x)),
            toml::Value::Integer(i) => (Some(*i as f64), i.to_string()),
            other => (None, format!("a {}", other.type_str())),
        };
        match number {
            Some(x) if x.is_finite() && x > 0.0 && x <= max => Ok(Some(WordOr::Number(x))),
            _ => {
                let range = if max == f64::MAX {
                    String::new()
                } else {
                    format!(" and <= {}", num(max))
                };
                Err(self.src.span(
                    &v,
                    format!(
                        "{} must be {} or a number > 0{range}, got {got}",
                        key.name,
                        quoted(words).join(", ")
                    ),
                ))
            }
        }
    }

    /// A `poll_timeout_us` key (10 us to 1 s, default 1 ms): how long a stage waiting on
    /// another process's service sleeps before checking for shutdown.
    pub fn poll_timeout(&mut self, key: &Key) -> Result<Duration, InputError> {
        Ok(self.int(key)?.map_or(Duration::from_millis(1), |us| {
            Duration::from_micros(us as u64)
        }))
    }
}

/// The `poll_timeout_us` key of stages that wait on another process's service.
pub const POLL_TIMEOUT_US: Key = Key {
    name: "poll_timeout_us",
    ty: Type::Int(10, 1_000_000),
    default: "1000",
    doc: "the longest sleep before looking again when the other process does not notify",
};
