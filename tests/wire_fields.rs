//! The wire types' tables (`src/wire/fields.rs`) against what is written elsewhere of the same
//! fields:
//!
//! - the Python `struct` formats in docs/ and the examples are the ones computed from the
//!   tables (offsets, sizes, padding);
//! - the layout tables of docs/wire-types.md and of the types' doc comments, and the ctypes
//!   structures of examples/python/, hold the tables' fields at their offsets, with their types;
//! - every bit of the sensors word is named in the Python examples, docs/wire-types.md and
//!   the recording's schema;
//! - a recording's JSON forms hold each field under the table's key, and nothing else (the
//!   Raw and Gyro forms' keys, which field fills each, when it may be absent; the statistics'
//!   keys and schema).
//!
//! The tables themselves are checked against the Rust layouts (`offset_of!`) by their unit
//! tests, and the ROS 2 mapping by `transport::ros2::imu`'s.

use std::collections::BTreeSet;
use std::path::Path;

use driftless::io::recording::{
    gyro_schema, raw_schema, stats_schema, GyroMessage, RawMessage, StatsMessage,
};
use driftless::wire::{
    Field, FieldKind, FieldTable, GyroSample, OdometryStats, RawSample, StageStats, StatsSnapshot,
    WireBytes, GYRO_FIELDS, GYRO_TYPE_NAME, RAW_FIELDS, RAW_TYPE_NAME, SENSOR_NAMES, STATS_FIELDS,
    STOP_FIELDS,
};
use serde_json::Value;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn read(rel: &str) -> String {
    std::fs::read_to_string(Path::new(ROOT).join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

// ---------------------------------------------------------------------------------------------
// Python's struct formats

/// The letters of a table's layout, one per element, nested structs flattened, padding as `x`.
fn letters(table: &FieldTable, out: &mut Vec<(char, usize)>) {
    let mut at = 0;
    for f in table.fields {
        if f.offset > at {
            out.push(('x', f.offset - at));
        }
        for _ in 0..f.len {
            match f.kind {
                FieldKind::U64 => out.push(('Q', 1)),
                FieldKind::U32 => out.push(('I', 1)),
                FieldKind::F64 => out.push(('d', 1)),
                FieldKind::U8 => out.push(('s', 1)),
                FieldKind::Struct(t) => letters(t, out),
            }
        }
        at = f.offset + f.size();
    }
    if table.size > at {
        out.push(('x', table.size - at));
    }
}

/// The little-endian `struct` format of a table as our docs write it: runs of doubles, padding
/// and bytes counted (`3d`, a lone `d`), integers one letter each (`QQ`, `II`).
fn python_format(table: &FieldTable) -> String {
    let mut flat = Vec::new();
    letters(table, &mut flat);
    let mut runs: Vec<(char, usize)> = Vec::new();
    for (c, n) in flat {
        match runs.last_mut() {
            Some((last, count)) if *last == c && "dxs".contains(c) => *count += n,
            _ => runs.push((c, n)),
        }
    }
    let mut out = String::from("<");
    for (c, n) in runs {
        if n > 1 && "dxs".contains(c) {
            out += &n.to_string();
        }
        out.push(c);
    }
    out
}

/// Every quoted `struct` format in `text`: a `"<` then digits and format letters.
fn struct_formats(text: &str) -> Vec<String> {
    let mut found = Vec::new();
    for (at, _) in text.match_indices("\"<") {
        let rest = &text[at + 1..];
        let end = rest[1..].find('"').map(|e| e + 1);
        if let Some(body) = end.map(|e| &rest[..e]) {
            if body.len() > 1 && body[1..].chars().all(|c| c.is_ascii_alphanumeric()) {
                found.push(body.to_string());
            }
        }
    }
    found
}

#[test]
fn python_struct_formats_are_the_tables() {
    let raw = python_format(&RAW_FIELDS);
    let gyro = python_format(&GYRO_FIELDS);
    let stop = python_format(&STOP_FIELDS);
    // The formats as they stand: a change here is a change of the wire (and of its version).
    assert_eq!(
        [raw.as_str(), gyro.as_str(), stop.as_str()],
        ["<QQ3dII6d", "<QQQ9dII12dII7d", "<QdII3dQ"]
    );
    let wanted: &[(&str, &[&str])] = &[
        ("docs/wire-types.md", &[&raw, &gyro, &stop]),
        ("docs/bridge.md", &[&gyro, &raw]),
        ("examples/zenoh_subscriber.py", &[&gyro]),
    ];
    for (file, formats) in wanted {
        let found = struct_formats(&read(file));
        for want in *formats {
            assert!(found.contains(&want.to_string()), "{file}: no \"{want}\"");
        }
    }
    // No other format of ours anywhere in the docs or the Python examples.
    let ours = [raw, gyro, stop];
    let mut files = Vec::new();
    walk(&Path::new(ROOT).join("docs"), "md", &mut files);
    walk(&Path::new(ROOT).join("examples"), "py", &mut files);
    for path in files {
        let text = std::fs::read_to_string(&path).unwrap();
        for f in struct_formats(&text) {
            assert!(
                ours.contains(&f),
                "{}: \"{f}\" is none of {ours:?}",
                path.display()
            );
        }
    }
}

fn walk(dir: &Path, ext: &str, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            walk(&path, ext, out);
        } else if path.extension().is_some_and(|e| e == ext) {
            out.push(path);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Layout tables in Markdown and doc comments; ctypes structures

/// A field's type as docs/wire-types.md writes it (`u64`, `f64[3]`).
fn doc_type(f: &Field) -> String {
    let scalar = match f.kind {
        FieldKind::U64 => "u64",
        FieldKind::U32 => "u32",
        FieldKind::F64 => "f64",
        FieldKind::U8 => "u8",
        FieldKind::Struct(t) => t.name,
    };
    match f.len {
        1 => scalar.to_string(),
        n => format!("{scalar}[{n}]"),
    }
}

/// The rows `| offset | [type |] field |` of the first table after the line that contains
/// `after`, as (offset, type, the field's first `code` word); the type is normalised to
/// `f64[3]` (a doc comment writes `` `[f64; 3]` ``). Without a type column, the type is empty.
fn layout_rows(text: &str, after: &str, prefix: &str) -> Vec<(usize, String, String)> {
    let start = text.find(after).unwrap_or_else(|| panic!("no {after:?}"));
    let lines = text[start..]
        .lines()
        .map(|l| l.trim_start().trim_start_matches(prefix).trim());
    let table = lines
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'));
    let mut rows = Vec::new();
    for line in table {
        let cells: Vec<&str> = line.trim_matches('|').split('|').map(str::trim).collect();
        let Ok(offset) = cells[0].parse::<usize>() else {
            continue; // the header and its rule
        };
        let ty = if cells.len() > 2 {
            let t = cells[1].trim_matches('`');
            match t.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
                Some(inner) => inner.replace("; ", "[") + "]",
                None => t.to_string(),
            }
        } else {
            String::new()
        };
        let field = cells[cells.len() - 1]
            .split('`')
            .nth(1)
            .unwrap_or("")
            .to_string();
        rows.push((offset, ty, field));
    }
    rows
}

fn table_rows(table: &FieldTable, typed: bool) -> Vec<(usize, String, String)> {
    let ty = |f: &Field| if typed { doc_type(f) } else { String::new() };
    table
        .fields
        .iter()
        .map(|f| (f.offset, ty(f), f.name.to_string()))
        .collect()
}

#[test]
fn the_documented_layouts_are_the_tables() {
    let docs = read("docs/wire-types.md");
    for (after, table, typed) in [
        ("`driftless::RawSample.v2`, 96 bytes", &RAW_FIELDS, true),
        ("`driftless::GyroSample.v4`, 264 bytes", &GYRO_FIELDS, true),
        ("`driftless::StopSignal.v2`, 56 bytes", &STOP_FIELDS, true),
        (
            "`driftless::StatsSnapshot.v4`, 1024 bytes",
            &STATS_FIELDS,
            false,
        ),
    ] {
        let rows = layout_rows(&docs, after, "");
        assert_eq!(
            rows,
            table_rows(table, typed),
            "docs/wire-types.md, {after}"
        );
    }
    let source = read("src/wire/samples.rs");
    for (after, table) in [
        (
            "/// Whether the vehicle stands, and how it moves",
            &STOP_FIELDS,
        ),
        (
            "/// A raw IMU sample as a sensor driver publishes it",
            &RAW_FIELDS,
        ),
        ("/// A processed IMU sample", &GYRO_FIELDS),
    ] {
        let rows = layout_rows(&source, after, "///");
        assert_eq!(
            rows,
            table_rows(table, true),
            "src/wire/samples.rs, {after}"
        );
    }
}

/// A ctypes structure's `_fields_` as (name, C type, count), and the `# N:` offsets of its
/// comments, in order.
fn ctypes_fields(text: &str, class: &str) -> (Vec<(String, String, usize)>, Vec<usize>) {
    let start = text.find(&format!("class {class}(")).expect(class);
    let body = &text[start..];
    let block = &body[body.find("_fields_ = [").unwrap()..];
    let block = &block[..block.find("\n    ]").unwrap()];
    let (mut fields, mut offsets) = (Vec::new(), Vec::new());
    for line in block.lines().skip(1) {
        let (code, comment) = line.split_once('#').unwrap_or((line, ""));
        if let Some(n) = comment
            .trim()
            .split(':')
            .next()
            .and_then(|n| n.parse().ok())
        {
            offsets.push(n);
        }
        let code = code
            .trim()
            .trim_start_matches('(')
            .trim_end_matches([',', ')']);
        if let Some((name, ty)) = code.split_once(',') {
            let (ty, count) = match ty.split_once('*') {
                Some((t, n)) => (t.trim(), n.trim().parse().unwrap()),
                None => (ty.trim(), 1),
            };
            fields.push((name.trim_matches('"').into(), ty.into(), count));
        }
    }
    (fields, offsets)
}

#[test]
fn the_python_examples_ctypes_are_the_tables() {
    let text = read("examples/python/driftless_iox2.py");
    for (table, type_name) in [(&RAW_FIELDS, RAW_TYPE_NAME), (&GYRO_FIELDS, GYRO_TYPE_NAME)] {
        let (fields, offsets) = ctypes_fields(&text, table.name);
        let want: Vec<(String, String, usize)> = table
            .fields
            .iter()
            .map(|f| {
                let c = match f.kind {
                    FieldKind::U64 => "ctypes.c_uint64",
                    FieldKind::U32 => "ctypes.c_uint32",
                    FieldKind::F64 => "ctypes.c_double",
                    _ => unreachable!("no sample has one"),
                };
                (f.name.to_string(), c.to_string(), f.len)
            })
            .collect();
        assert_eq!(fields, want, "{}", table.name);
        let all: Vec<usize> = table.fields.iter().map(|f| f.offset).collect();
        assert_eq!(offsets, all, "{}: the offsets in the comments", table.name);
        assert!(
            text.contains(&format!("return \"{type_name}\"")),
            "{type_name}"
        );
        // The file's own check of its offsets.
        let check = format!("({}, {}, {{", table.name, table.size);
        let at = text.find(&check).unwrap_or_else(|| panic!("no {check}"));
        let dict = &text[at + check.len()..];
        let dict = &dict[..dict.find('}').unwrap()];
        for pair in dict.split(',').filter(|p| p.contains(':')) {
            let (name, offset) = pair.split_once(':').unwrap();
            let name = name.trim().trim_matches('"');
            let f = table.field(name).unwrap_or_else(|| panic!("{name}"));
            assert_eq!(offset.trim().parse::<usize>().unwrap(), f.offset, "{name}");
        }
    }
}

/// The value of a Python constant `NAME = 1 << n` (or `= n`) in `text`.
fn python_bit(text: &str, name: &str) -> Option<u32> {
    let line = text
        .lines()
        .find_map(|l| l.strip_prefix(&format!("{name} = ")))?;
    match line.trim().split_once("<<") {
        Some((one, n)) => Some(one.trim().parse::<u32>().ok()? << n.trim().parse::<u32>().ok()?),
        None => line.trim().parse().ok(),
    }
}

/// Every bit of the sensors word (`SENSOR_NAMES`, which `tap` prints) is known by name to the
/// Python examples (`SENSOR_<NAME> = 1 << n`) and in docs/wire-types.md's sensors table
/// (`` | `0x80` | `heading_absolute` | ``), and the recording's schema says it.
#[test]
fn every_sensors_bit_is_named_in_python_and_the_docs() {
    let python = read("examples/python/driftless_iox2.py");
    let docs = read("docs/wire-types.md");
    let about = GYRO_FIELDS.field("sensors").unwrap().about;
    for (bit, name) in SENSOR_NAMES {
        let constant = format!("SENSOR_{}", name.to_uppercase());
        assert_eq!(python_bit(&python, &constant), Some(bit), "{constant}");
        let row = format!("| `{bit:#x}` | `{name}` |");
        assert!(docs.contains(&row), "docs/wire-types.md: no {row}");
        assert!(
            about.contains(&format!("{bit:#x} ")),
            "{name} ({bit:#x}): {about}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// A recording's JSON forms

/// The keys of `v` whose values differ in `w`, and those only one of them has.
fn moved(v: &Value, w: &Value) -> BTreeSet<String> {
    let (v, w) = (v.as_object().unwrap(), w.as_object().unwrap());
    v.keys()
        .chain(w.keys())
        .filter(|k| v.get(*k) != w.get(*k))
        .cloned()
        .collect()
}

/// Each field of the table is recorded under its key and no other (`t_ns` also as `t_s`); a
/// field without a key changes nothing; a field present by a bit is absent without it; the
/// form's keys are the schema's properties, and the schema requires exactly the keys the form
/// cannot be read without; each value is of its field's kind.
fn the_form_is_the_table<T: WireBytes, M>(table: &FieldTable, sample: &T, schema: &str)
where
    M: for<'a> From<&'a T> + serde::Serialize + serde::de::DeserializeOwned,
{
    let json = |b: &[u8]| serde_json::to_value(M::from(&T::decode(b).unwrap())).unwrap();
    let mut bytes = Vec::new();
    sample.encode(&mut bytes);
    let base = json(&bytes);
    for f in table.fields {
        let mut want: BTreeSet<String> = f.json.into_iter().map(String::from).collect();
        if f.name == "t_ns" {
            want.insert("t_s".into());
        }
        assert_eq!(
            moved(&base, &json(&f.changed_in(&bytes))),
            want,
            "{}",
            f.name
        );
        if f.presence.is_some() {
            let gone = json(&table.without(f, &bytes));
            assert!(
                gone.get(f.json.unwrap()).is_none(),
                "{}: recorded while absent",
                f.name
            );
        }
    }
    let schema: Value = serde_json::from_str(schema).unwrap();
    let properties: BTreeSet<&String> = schema["properties"].as_object().unwrap().keys().collect();
    let keys: BTreeSet<&String> = base.as_object().unwrap().keys().collect();
    assert_eq!(keys, properties, "{}", table.name);
    let required: Vec<&str> = schema["required"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_str().unwrap())
        .collect();
    // The required keys alone read; without any one of them, the form does not.
    let only = |keys: &[&str]| {
        let o: serde_json::Map<String, Value> = keys
            .iter()
            .map(|k| (k.to_string(), base[*k].clone()))
            .collect();
        serde_json::from_value::<M>(Value::Object(o)).is_ok()
    };
    assert!(only(&required), "{}: {required:?}", table.name);
    for k in &required {
        let fewer: Vec<&str> = required.iter().copied().filter(|r| r != k).collect();
        assert!(!only(&fewer), "{}: reads without {k}", table.name);
    }
    for (key, value) in base.as_object().unwrap() {
        let f = table.fields.iter().find(|f| f.json == Some(key.as_str()));
        let Some(f) = f else {
            assert_eq!(key, "t_s", "{}: {key} is no field's", table.name);
            continue;
        };
        let ok = match (f.kind, f.len) {
            (FieldKind::U64 | FieldKind::U32, 1) => value.is_u64(),
            (FieldKind::F64, n) => {
                let axes = &["x", "y", "z", "w"][..n];
                let o = value.as_object().unwrap();
                o.len() == n && axes.iter().all(|a| o[*a].is_f64())
            }
            _ => false,
        };
        assert!(
            ok,
            "{}.{key}: {value} is not a {:?} x {}",
            table.name, f.kind, f.len
        );
    }
}

#[test]
fn the_recorded_samples_are_the_tables() {
    use driftless::wire::{RAW_ACCEL, RAW_MAG, SENSOR_ACCEL, SENSOR_MAG, SENSOR_ORIENTATION};
    // Every reading present; the rest as it may be.
    let gyro = GyroSample {
        sensors: SENSOR_ACCEL | SENSOR_MAG | SENSOR_ORIENTATION,
        ..GyroSample::default()
    };
    the_form_is_the_table::<_, GyroMessage>(&GYRO_FIELDS, &gyro, &gyro_schema());
    let raw = RawSample {
        flags: RAW_ACCEL | RAW_MAG,
        ..RawSample::default()
    };
    the_form_is_the_table::<_, RawMessage>(&RAW_FIELDS, &raw, &raw_schema());
}

/// The dotted JSON paths of a table's fields (`a.b`: `b` in the object `a`; a struct's own
/// paths below its key; an array of structs, below its key too).
fn table_paths(table: &FieldTable, under: &str, out: &mut BTreeSet<String>) {
    for f in table.fields {
        let Some(key) = f.json else {
            continue;
        };
        let path = format!("{under}{key}");
        if let FieldKind::Struct(t) = f.kind {
            table_paths(t, &format!("{path}."), out);
        }
        out.insert(path);
    }
}

/// The dotted paths of a JSON value's keys (an array's by its first element); the parents
/// of a dotted key (`last_miss` of `last_miss.uptime_ns`) are paths too.
fn json_paths(v: &Value, under: &str, out: &mut BTreeSet<String>) {
    match v {
        Value::Object(o) => {
            for (k, v) in o {
                let path = format!("{under}{k}");
                json_paths(v, &format!("{path}."), out);
                out.insert(path);
            }
        }
        Value::Array(a) => {
            if let Some(first) = a.first() {
                json_paths(first, under, out);
            }
        }
        _ => {}
    }
}

/// The statistics' JSON form holds each field of the table under its key, and the schema has
/// each: nothing recorded is missing from the table, nothing of the table from the record.
#[test]
fn the_recorded_statistics_are_the_table() {
    let mut s = StatsSnapshot {
        stage_count: 1,
        last_miss_uptime_ns: 5,
        odometry: OdometryStats {
            up: 5,
            ..OdometryStats::default()
        },
        ..StatsSnapshot::default()
    };
    s.stages[0] = StageStats {
        name: *b"denoise\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0",
        ..StageStats::default()
    };
    let mut want = BTreeSet::new();
    table_paths(&STATS_FIELDS, "", &mut want);
    // Of the table, but derived: the object of the latest miss, and whether it is explained.
    for derived in ["last_miss", "last_miss.explained"] {
        want.insert(derived.into());
    }
    let mut got = BTreeSet::new();
    json_paths(&StatsMessage::json(&s), "", &mut got);
    assert_eq!(got, want);
    // Every path is a property of the schema.
    let schema: Value = serde_json::from_str(&stats_schema()).unwrap();
    for path in &want {
        let mut node = &schema;
        for key in path.split('.') {
            let props = match node.get("items") {
                Some(items) => &items["properties"],
                None => &node["properties"],
            };
            node = props
                .get(key)
                .unwrap_or_else(|| panic!("{path}: not in the schema"));
        }
    }
}
