//! What every stage file needs to read its own `[[stage]]` table: positioned errors, typed
//! keys with their ranges and defaults, and the pipeline-wide values a stage may depend on.
//!
//! A stage kind declares its keys as [`Key`]s (name, type and range, default, meaning); the
//! same declarations check the table ([`Table`]'s readers), reject keys of other kinds,
//! and are listed by `driftless validate --kinds`, so the documentation cannot drift from the
//! checks. A key's default is typed ([`DefaultValue`]): the `*_or_default` readers apply it
//! and the reference prints it, so a stage file never writes a default value itself; a
//! default that follows from other values says so in words, and the stage computes it.
//! Arrows point one way: stage files use this module; it knows no stage file.

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Deserialize;
use toml::de::{DeTable, DeValue};
use toml::Spanned;

use crate::io::InputError;
use crate::units::{AccelUnit, RateUnit};

/// The pipeline-wide values a stage is validated and built against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Context {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Number of axes (1..=3).
    pub axes: usize,
    /// Units of the raw input.
    pub units: RateUnit,
    /// Units of the raw accelerometer readings.
    pub accel_units: AccelUnit,
    /// The gyro's white rate noise N (deg/sqrt(s)) that a stage of the chain assumes
    /// (`predict.bias`'s terms), for the stages that build after it; None while the pipeline
    /// is read, and in a chain without one.
    pub white_noise: Option<f64>,
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
    /// A finite float `>= 0`.
    NonNegative,
    /// A finite float `> lo`.
    Greater(f64),
    /// A finite float in `[lo, hi]`.
    FloatIn(f64, f64),
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
    /// Finite floats in an array (its shape described: a vector, a matrix's rows).
    Floats(&'static str),
}

impl Type {
    /// How `validate --kinds` shows it.
    pub fn describe(&self) -> String {
        match self {
            Type::Int(lo, i64::MAX) => format!("int >= {lo}"),
            Type::Int(lo, hi) => format!("int {lo}..={hi}"),
            Type::IntDepends(d) => format!("int {d}"),
            Type::Positive(max) => positive(*max),
            Type::NonNegative => "float >= 0".into(),
            Type::Greater(lo) => format!("float > {}", num(*lo)),
            Type::FloatIn(lo, hi) => format!("float {}..={}", num(*lo), num(*hi)),
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
            Type::Floats(d) => format!("floats ({d})"),
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

/// What a key is when the file does not give it: one declaration, which the readers apply and
/// the reference prints (`Display`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DefaultValue {
    /// None: the file must give it (`required`).
    Required,
    /// None, but the file must give it or the named other key (`required, or `other``).
    Either(&'static str),
    /// An integer.
    Int(i64),
    /// A float (shown as [`num`] writes it).
    Float(f64),
    /// true or false.
    Bool(bool),
    /// A word (shown quoted).
    Word(&'static str),
    /// A list of words (shown as a TOML array).
    Words(&'static [&'static str]),
    /// A typed value and how the stage applies it, shown after it: a unit (`1 deg/s`), a cut or
    /// a cap by other values (`33 (at most the full lag)`). The note starts with its separator
    /// (a space, a colon).
    Noted(&'static DefaultValue, &'static str),
    /// No value: the key is absent and nothing replaces it. The text, shown as written, says
    /// what absence means (`none: every start is cold`).
    Absent(&'static str),
    /// A value that follows from other keys, the profile or the model, computed by the stage.
    /// The text, shown as written, says how (`the model's`).
    Derived(&'static str),
}

impl DefaultValue {
    /// The typed value a reader applies (a [`Noted`](DefaultValue::Noted) one's value), or
    /// None when there is none to apply (required, absent, derived).
    pub const fn value(&self) -> Option<&DefaultValue> {
        match self {
            DefaultValue::Int(_)
            | DefaultValue::Float(_)
            | DefaultValue::Bool(_)
            | DefaultValue::Word(_)
            | DefaultValue::Words(_) => Some(self),
            DefaultValue::Noted(v, _) => v.value(),
            _ => None,
        }
    }

    /// Its integer; a key declared otherwise is a programming error.
    pub fn int(&self) -> i64 {
        match self.value() {
            Some(DefaultValue::Int(v)) => *v,
            _ => unreachable!("the default {self:?} is not an integer"),
        }
    }

    /// Its float (an integer's value too); a key declared otherwise is a programming error.
    pub fn float(&self) -> f64 {
        match self.value() {
            Some(DefaultValue::Float(v)) => *v,
            Some(DefaultValue::Int(v)) => *v as f64,
            _ => unreachable!("the default {self:?} is not a number"),
        }
    }

    /// Its truth value; a key declared otherwise is a programming error.
    pub fn bool(&self) -> bool {
        match self.value() {
            Some(DefaultValue::Bool(v)) => *v,
            _ => unreachable!("the default {self:?} is not a bool"),
        }
    }

    /// Its word; a key declared otherwise is a programming error.
    pub fn word(&self) -> &'static str {
        match self.value() {
            Some(DefaultValue::Word(v)) => v,
            _ => unreachable!("the default {self:?} is not a word"),
        }
    }

    /// Its words; a key declared otherwise is a programming error.
    pub fn words(&self) -> &'static [&'static str] {
        match self.value() {
            Some(DefaultValue::Words(v)) => v,
            _ => unreachable!("the default {self:?} is not a list of words"),
        }
    }
}

impl std::fmt::Display for DefaultValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DefaultValue::Required => f.write_str("required"),
            DefaultValue::Either(other) => write!(f, "required, or `{other}`"),
            DefaultValue::Int(v) => write!(f, "{v}"),
            DefaultValue::Float(v) => f.write_str(&num(*v)),
            DefaultValue::Bool(v) => write!(f, "{v}"),
            DefaultValue::Word(w) => write!(f, "{w:?}"),
            DefaultValue::Words(w) => write!(f, "[{}]", quoted(w).join(", ")),
            DefaultValue::Noted(v, note) => write!(f, "{v}{note}"),
            DefaultValue::Absent(text) | DefaultValue::Derived(text) => f.write_str(text),
        }
    }
}

/// A key of a stage kind's table: its one declaration, used to read, to check and to list it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Key {
    /// The key as written in the file.
    pub name: &'static str,
    /// Its type and range.
    pub ty: Type,
    /// Its default: applied by the `*_or_default` readers, listed as written by its `Display`.
    pub default: DefaultValue,
    /// What it means.
    pub doc: &'static str,
}

impl Key {
    /// Whether its typed default is a value of its own type, within its range or among its
    /// choices (an `IntDepends` or described `Float` range is not checked; a note must start
    /// with its separator; absent text says "none").
    pub fn check_default(&self) -> Result<(), String> {
        let bad = |why: String| Err(format!("{}: default {}: {why}", self.name, self.default));
        if let DefaultValue::Noted(_, note) = self.default {
            if !note.starts_with([' ', ':']) {
                return bad("a note starts with a space or a colon".into());
            }
        }
        if let DefaultValue::Absent(text) = self.default {
            if !text.starts_with("none") {
                return bad("absent text starts with \"none\"".into());
            }
        }
        let Some(value) = self.default.value() else {
            return Ok(());
        };
        let finite = |x: f64, ok: bool| x.is_finite() && ok;
        let fits = match (self.ty, *value) {
            (Type::Int(lo, hi), DefaultValue::Int(v)) => (lo..=hi).contains(&v),
            (Type::IntDepends(_), DefaultValue::Int(v)) => v >= 0,
            (Type::Positive(max), DefaultValue::Float(x)) => finite(x, x > 0.0 && x <= max),
            (Type::NonNegative, DefaultValue::Float(x)) => finite(x, x >= 0.0),
            (Type::Greater(lo), DefaultValue::Float(x)) => finite(x, x > lo),
            (Type::FloatIn(lo, hi), DefaultValue::Float(x)) => finite(x, (lo..=hi).contains(&x)),
            (Type::Float(_), DefaultValue::Float(x)) => x.is_finite(),
            (Type::Choice(c), DefaultValue::Word(w)) => c.contains(&w),
            (Type::Str(_), DefaultValue::Word(_)) => true,
            (Type::StrList(_), DefaultValue::Words(_)) => true,
            (Type::Bool, DefaultValue::Bool(_)) => true,
            (Type::WordOrPositive(words, _), DefaultValue::Word(w)) => words.contains(&w),
            (Type::WordOrPositive(_, max), DefaultValue::Float(x)) => {
                finite(x, x > 0.0 && x <= max)
            }
            _ => return bad(format!("not a value of type {}", self.ty.describe())),
        };
        if fits {
            Ok(())
        } else {
            bad(format!("outside {}", self.ty.describe()))
        }
    }
}

/// How a reader takes a key, against how the key's default is declared: a required key by a
/// required reader, a typed default by an `*_or_default` reader (the stage never writes it
/// again), the rest by an optional reader. Anything else is a programming error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reading {
    Required,
    Optional,
    OrDefault,
}

fn expect(key: &Key, reading: Reading) {
    let typed = key.default.value().is_some();
    let ok = match reading {
        Reading::Required => key.default == DefaultValue::Required,
        Reading::OrDefault => typed,
        // A noted default is a value the stage applies as its note says: it reads the key's
        // presence, and the value from the key.
        Reading::Optional => {
            key.default != DefaultValue::Required
                && (!typed || matches!(key.default, DefaultValue::Noted(..)))
        }
    };
    assert!(
        ok,
        "{}: default {:?} read as {reading:?}",
        key.name, key.default
    );
}

/// A table's declared entries: each key by its declaration's name, with its value.
pub(crate) type Entries<'i> = Vec<(&'static str, Spanned<DeValue<'i>>)>;

/// A table's entries sorted by the keys declared for it: the declared ones (named by their
/// declaration), and the strays (key, offset) in the file's order, for the caller to refuse.
pub(crate) fn sort_entries<'i>(
    table: DeTable<'i>,
    valid: &[&'static str],
) -> (Entries<'i>, Vec<(String, usize)>) {
    let mut declared = Vec::new();
    let mut strays: Vec<(String, usize)> = Vec::new();
    for (k, v) in table {
        match valid.iter().find(|n| **n == k.get_ref().as_ref()) {
            Some(&n) => declared.push((n, v)),
            None => strays.push((k.get_ref().to_string(), k.span().start)),
        }
    }
    strays.sort_by_key(|(_, at)| *at);
    (declared, strays)
}

/// One table of the pipeline file, its keys already sorted against their declarations: a stage
/// kind's own `[[stage]]` table (without `name`, `kind`, `input`, `output`), a side's table, or
/// the pipeline's own keys. Its reader takes the keys through the readers below, which check
/// types and ranges against the [`Key`] declarations, apply typed defaults and position every
/// error. `kind_at` and `input` are a stage's; `cx` is the pipeline's once its own keys are read.
pub struct Table<'a, 'i> {
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

impl<'a, 'i> Table<'a, 'i> {
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
        Table {
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

    /// The value of `key` deserialized as `T`, spanned; None when absent: for a key without
    /// a typed default (or with a noted one, whose value the stage takes from the key), or
    /// whose value the kind checks itself.
    pub fn get<T: Deserialize<'i>>(&mut self, key: &Key) -> Result<Option<Spanned<T>>, InputError> {
        expect(key, Reading::Optional);
        self.take(key)
    }

    fn take<T: Deserialize<'i>>(&mut self, key: &Key) -> Result<Option<Spanned<T>>, InputError> {
        match self.entries.iter().position(|(k, _)| *k == key.name) {
            Some(i) => {
                let (_, v) = self.entries.swap_remove(i);
                self.src.de(v).map(Some)
            }
            None => Ok(None),
        }
    }

    /// Whether the table gives `key` (it is left to be read).
    pub fn has(&self, key: &Key) -> bool {
        self.entries.iter().any(|(k, _)| *k == key.name)
    }

    /// A required string.
    pub fn required_str(&mut self, key: &Key) -> Result<Spanned<String>, InputError> {
        expect(key, Reading::Required);
        self.take(key)?
            .ok_or_else(|| self.error(format!("missing field `{}`", key.name)))
    }

    /// A required float, checked as [`Table::float`] checks it.
    pub fn required_float(&mut self, key: &Key) -> Result<f64, InputError> {
        expect(key, Reading::Required);
        self.take_float(key)?
            .ok_or_else(|| self.error(format!("missing field `{}`", key.name)))
    }

    /// A string of a [`Type::Str`] key, `check`ed when given (its error positioned at the
    /// value), else its default word.
    pub fn str_or_default(
        &mut self,
        key: &Key,
        check: impl FnOnce(&str) -> Result<(), String>,
    ) -> Result<String, InputError> {
        let Type::Str(_) = key.ty else {
            unreachable!("{} is not declared Type::Str", key.name)
        };
        expect(key, Reading::OrDefault);
        match self.take::<String>(key)? {
            Some(v) => {
                check(v.get_ref()).map_err(|e| self.src.span(&v, e))?;
                Ok(v.into_inner())
            }
            None => Ok(key.default.word().to_string()),
        }
    }

    /// An integer of a [`Type::Int`] key, range-checked; None when absent.
    pub fn int(&mut self, key: &Key) -> Result<Option<usize>, InputError> {
        expect(key, Reading::Optional);
        self.take_int(key)
    }

    /// An integer of a [`Type::Int`] key, range-checked, else its default.
    pub fn int_or_default(&mut self, key: &Key) -> Result<usize, InputError> {
        expect(key, Reading::OrDefault);
        Ok(self.take_int(key)?.unwrap_or(key.default.int() as usize))
    }

    fn take_int(&mut self, key: &Key) -> Result<Option<usize>, InputError> {
        let Type::Int(lo, hi) = key.ty else {
            unreachable!("{} is not declared Type::Int", key.name)
        };
        self.take::<i64>(key)?
            .map(|v| self.src.int_in(&v, key.name, lo, hi))
            .transpose()
    }

    /// An integer of a [`Type::IntDepends`] key in `lo..=hi` (the range the other keys
    /// give), else its default brought into that range.
    pub fn int_in_or_default(&mut self, key: &Key, lo: i64, hi: i64) -> Result<usize, InputError> {
        let Type::IntDepends(_) = key.ty else {
            unreachable!("{} is not declared Type::IntDepends", key.name)
        };
        expect(key, Reading::OrDefault);
        Ok(match self.take::<i64>(key)? {
            Some(v) => self.src.int_in(&v, key.name, lo, hi)?,
            None => key.default.int().clamp(lo, hi) as usize,
        })
    }

    /// A float of a [`Type::Positive`], [`Type::NonNegative`], [`Type::Greater`] or
    /// [`Type::FloatIn`] key, checked (named by the key in the message); None when absent.
    pub fn float(&mut self, key: &Key) -> Result<Option<f64>, InputError> {
        expect(key, Reading::Optional);
        self.take_float(key)
    }

    /// A float as [`Table::float`] reads it, else its default.
    pub fn float_or_default(&mut self, key: &Key) -> Result<f64, InputError> {
        expect(key, Reading::OrDefault);
        Ok(self.take_float(key)?.unwrap_or(key.default.float()))
    }

    fn take_float(&mut self, key: &Key) -> Result<Option<f64>, InputError> {
        let Some(v) = self.take::<f64>(key)? else {
            return Ok(None);
        };
        let (x, name) = (*v.get_ref(), key.name);
        match key.ty {
            Type::Positive(max) => self.src.positive(&v, name, max).map(Some),
            Type::FloatIn(lo, hi) => self.src.float_in(&v, name, lo, hi).map(Some),
            Type::NonNegative if !(x.is_finite() && x >= 0.0) => Err(self
                .src
                .span(&v, format!("{name} must be finite and >= 0, got {x}"))),
            Type::Greater(lo) if !(x.is_finite() && x > lo) => Err(self
                .src
                .span(&v, format!("{name} must be > {}, got {x}", num(lo)))),
            Type::NonNegative | Type::Greater(_) => Ok(Some(x)),
            _ => unreachable!("{name} is not declared a checked float"),
        }
    }

    /// true or false, of a [`Type::Bool`] key, else its default.
    pub fn bool_or_default(&mut self, key: &Key) -> Result<bool, InputError> {
        let Type::Bool = key.ty else {
            unreachable!("{} is not declared Type::Bool", key.name)
        };
        expect(key, Reading::OrDefault);
        Ok(self
            .take::<bool>(key)?
            .map_or(key.default.bool(), Spanned::into_inner))
    }

    /// A string of a [`Type::Choice`] key, checked against its choices: "unknown {what} "x"
    /// (valid: ...)", the choices quoted when `quote` is set; None when absent.
    pub fn choice(
        &mut self,
        key: &Key,
        what: &str,
        quote: bool,
    ) -> Result<Option<String>, InputError> {
        expect(key, Reading::Optional);
        self.take_choice(key, what, quote)
    }

    /// A choice as [`Table::choice`] reads it, else its default word.
    pub fn choice_or_default(
        &mut self,
        key: &Key,
        what: &str,
        quote: bool,
    ) -> Result<String, InputError> {
        expect(key, Reading::OrDefault);
        Ok(self
            .take_choice(key, what, quote)?
            .unwrap_or_else(|| key.default.word().to_string()))
    }

    fn take_choice(
        &mut self,
        key: &Key,
        what: &str,
        quote: bool,
    ) -> Result<Option<String>, InputError> {
        let Type::Choice(valid) = key.ty else {
            unreachable!("{} is not declared Type::Choice", key.name)
        };
        let Some(v) = self.take::<String>(key)? else {
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
    /// got ..."; None when absent.
    pub fn word_or_positive(&mut self, key: &Key) -> Result<Option<WordOr>, InputError> {
        expect(key, Reading::Optional);
        self.take_word_or_positive(key)
    }

    /// A value as [`Table::word_or_positive`] reads it, else its default.
    pub fn word_or_positive_or_default(&mut self, key: &Key) -> Result<WordOr, InputError> {
        expect(key, Reading::OrDefault);
        Ok(match self.take_word_or_positive(key)? {
            Some(v) => v,
            None => match key.default.value() {
                Some(DefaultValue::Word(w)) => WordOr::Word(w),
                _ => WordOr::Number(key.default.float()),
            },
        })
    }

    fn take_word_or_positive(&mut self, key: &Key) -> Result<Option<WordOr>, InputError> {
        let Type::WordOrPositive(words, max) = key.ty else {
            unreachable!("{} is not declared Type::WordOrPositive", key.name)
        };
        let Some(v) = self.take::<toml::Value>(key)? else {
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

    /// A `poll_timeout_us` key: how long a stage waiting on another process's service sleeps
    /// before checking for shutdown.
    pub fn poll_timeout(&mut self, key: &Key) -> Result<Duration, InputError> {
        Ok(Duration::from_micros(self.int_or_default(key)? as u64))
    }
}

/// The `poll_timeout_us` key of stages that wait on another process's service.
pub const POLL_TIMEOUT_US: Key = Key {
    name: "poll_timeout_us",
    ty: Type::Int(10, 1_000_000),
    default: DefaultValue::Int(1000),
    doc: "the longest sleep before looking again when the other process does not notify",
};

/// For tests: the stage table `src.text` (its keys only), each key named by `key_name` (the
/// kind's declaration of it), under a pipeline at 100 Hz, in deg/s and m/s^2, with `axes` axes.
#[cfg(test)]
pub(crate) fn test_table<'a>(
    src: &'a Src<'a>,
    axes: usize,
    input: Option<&'a str>,
    owner: (&'a str, &'a str),
    key_name: impl Fn(&str) -> &'static str,
) -> Table<'a, 'a> {
    let entries = DeTable::parse(src.text)
        .unwrap()
        .into_inner()
        .into_iter()
        .map(|(k, v)| (key_name(k.get_ref()), v))
        .collect();
    let cx = Context {
        rate_hz: 100.0,
        axes,
        units: RateUnit::DegPerS,
        accel_units: AccelUnit::MPerS2,
        white_noise: None,
    };
    Table::new(src, cx, 0, 0, input, owner, entries)
}

#[cfg(test)]
mod tests {
    use super::*;

    const fn key(ty: Type, default: DefaultValue) -> Key {
        Key {
            name: "k",
            ty,
            default,
            doc: "",
        }
    }

    #[test]
    fn a_typed_default_outside_its_keys_range_or_type_fails_the_check() {
        use DefaultValue as D;
        for ok in [
            key(Type::Int(1, 12), D::Int(12)),
            key(Type::Positive(100.0), D::Float(100.0)),
            key(Type::NonNegative, D::Float(0.0)),
            key(Type::Greater(1.0), D::Float(2.0)),
            key(Type::FloatIn(0.0, 60.0), D::Float(60.0)),
            key(Type::Choice(&["a", "b"]), D::Word("b")),
            key(Type::WordOrPositive(&["mad"], 1.0), D::Word("mad")),
            key(Type::Bool, D::Noted(&D::Bool(false), ": why")),
            key(Type::StrList(""), D::Words(&["x"])),
            key(Type::Int(1, 12), D::Required),
            key(Type::Str(""), D::Absent("none: nothing")),
        ] {
            assert_eq!(ok.check_default(), Ok(()), "{ok:?}");
        }
        for bad in [
            key(Type::Int(1, 12), D::Int(13)),
            key(Type::Int(1, 12), D::Float(5.0)),
            key(Type::Positive(100.0), D::Float(0.0)),
            key(Type::Positive(100.0), D::Float(f64::NAN)),
            key(Type::NonNegative, D::Float(-1.0)),
            key(Type::Greater(1.0), D::Float(1.0)),
            key(Type::FloatIn(0.0, 60.0), D::Float(61.0)),
            key(Type::Choice(&["a", "b"]), D::Word("c")),
            key(Type::WordOrPositive(&["mad"], 1.0), D::Float(2.0)),
            key(Type::Bool, D::Noted(&D::Int(0), ": why")),
            key(Type::Bool, D::Noted(&D::Bool(true), "no separator")),
            key(Type::Str(""), D::Absent("nothing")),
        ] {
            assert!(bad.check_default().is_err(), "{bad:?}");
        }
    }

    #[test]
    fn a_default_prints_as_a_pipeline_file_writes_it() {
        use DefaultValue as D;
        for (d, text) in [
            (D::Required, "required"),
            (D::Either("models"), "required, or `models`"),
            (D::Int(1024), "1024"),
            (D::Float(0.02), "0.02"),
            (D::Float(120.0), "120"),
            (D::Bool(true), "true"),
            (D::Word("db6"), "\"db6\""),
            (D::Words(&["x", "y", "z"]), "[\"x\", \"y\", \"z\"]"),
            (D::Noted(&D::Float(1.0), " deg/s"), "1 deg/s"),
            (D::Absent("none (until stopped)"), "none (until stopped)"),
            (D::Derived("the model's"), "the model's"),
        ] {
            assert_eq!(d.to_string(), text);
        }
    }

    fn read<T>(text: &str, f: impl FnOnce(&mut Table<'_, '_>) -> T) -> T {
        let src = Src {
            path: Path::new("p.toml"),
            text,
        };
        f(&mut test_table(&src, 1, None, ("p", "s"), |k| {
            assert_eq!(k, "k");
            "k"
        }))
    }

    #[test]
    fn the_readers_apply_the_typed_default_and_check_a_given_value() {
        const LEVEL: Key = key(Type::Int(1, 12), DefaultValue::Int(5));
        assert_eq!(read("", |t| t.int_or_default(&LEVEL).unwrap()), 5);
        assert_eq!(read("k = 7", |t| t.int_or_default(&LEVEL).unwrap()), 7);
        let e = read("k = 13", |t| t.int_or_default(&LEVEL).unwrap_err());
        assert!(e.to_string().contains("k must be in 1..=12, got 13"), "{e}");
        const LAG: Key = key(
            Type::IntDepends(""),
            DefaultValue::Noted(&DefaultValue::Int(33), " (at most the full lag)"),
        );
        assert_eq!(read("", |t| t.int_in_or_default(&LAG, 0, 10).unwrap()), 10);
        assert_eq!(read("", |t| t.int_in_or_default(&LAG, 0, 99).unwrap()), 33);
        const RATIO: Key = key(Type::Greater(1.0), DefaultValue::Float(2.0));
        assert_eq!(read("", |t| t.float_or_default(&RATIO).unwrap()), 2.0);
        let e = read("k = 1.0", |t| t.float_or_default(&RATIO).unwrap_err());
        assert!(e.to_string().contains("k must be > 1, got 1"), "{e}");
        const SIGMA: Key = key(
            Type::WordOrPositive(&["mad"], f64::MAX),
            DefaultValue::Word("mad"),
        );
        let sigma = |text| read(text, |t| t.word_or_positive_or_default(&SIGMA).unwrap());
        assert_eq!(sigma(""), WordOr::Word("mad"));
        assert_eq!(sigma("k = 2"), WordOr::Number(2.0));
        const NOTIFY: Key = key(Type::Bool, DefaultValue::Bool(true));
        assert!(read("", |t| t.bool_or_default(&NOTIFY).unwrap()));
        const FILE: Key = key(Type::Str(""), DefaultValue::Required);
        let e = read("", |t| t.required_str(&FILE).unwrap_err());
        assert!(e.to_string().contains("missing field `k`"), "{e}");
    }

    #[test]
    #[should_panic(expected = "read as Optional")]
    fn a_typed_default_read_by_an_optional_reader_is_a_programming_error() {
        const LEVEL: Key = key(Type::Int(1, 12), DefaultValue::Int(5));
        read("", |t| t.int(&LEVEL).unwrap());
    }

    #[test]
    #[should_panic(expected = "read as Optional")]
    fn a_required_key_read_by_an_optional_reader_is_a_programming_error() {
        const FILE: Key = key(Type::Str(""), DefaultValue::Required);
        read("", |t| t.get::<String>(&FILE).unwrap());
    }

    #[test]
    #[should_panic(expected = "read as OrDefault")]
    fn a_key_without_a_value_read_by_a_defaulting_reader_is_a_programming_error() {
        const SAMPLES: Key = key(Type::Int(1, 12), DefaultValue::Absent("none"));
        read("", |t| t.int_or_default(&SAMPLES).unwrap());
    }
}
