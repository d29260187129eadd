//! The house rules of ARCHITECTURE.md, checked on the source tree: each top-level module imports
//! only modules of a lower layer, only `transport` touches iceoryx2 (and only its `zenoh` file
//! and `cli::bridge` touch Zenoh, only its `ros2/dds.rs` ros2-client), the maths does no I/O,
//! no source file holds more than 1,000 lines of non-test code (the generated filter bank
//! excepted), and no function of a command (`src/cli/`) is over 120 lines.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The layers, from the ground up: a module may use its own layer's lower modules and the
/// layers below, never one above. Within the maths, the order is what they build on.
const LAYERS: &[(&str, u32)] = &[
    ("clock", 0),
    ("bigbuf", 0),
    ("quality", 0),
    ("synthetic", 0),
    ("sim", 1),
    ("allan", 1),
    ("wavelet", 1),
    ("drift", 2),
    ("nav", 3),
    ("transport", 4),
    ("io", 5),
    ("metrics", 6),
    ("stages", 7),
    ("pipeline", 8),
    ("nav_eval", 9),
    ("cli", 10),
];

/// The maths: pure computation, usable as a library without a daemon.
const MATHS: &[&str] = &[
    "bigbuf",
    "quality",
    "synthetic",
    "sim",
    "allan",
    "wavelet",
    "drift",
    "nav",
];

/// Words that mean I/O, processes or transport in code.
const IMPURE: &[&str] = &[
    "std::fs",
    "std::net",
    "std::process",
    "std::io::stdin",
    "std::io::stdout",
    "println!",
    "eprintln!",
    "print!(",
    "iceoryx2",
    "zenoh",
    "crate::io",
    "crate::transport",
];

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The top-level module a file belongs to (`src/drift/bias/mod.rs` -> `drift`), or None for
/// `lib.rs` and `main.rs`.
fn module_of(file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src()).unwrap();
    let first = rel
        .components()
        .next()?
        .as_os_str()
        .to_string_lossy()
        .into_owned();
    let name = first.trim_end_matches(".rs").to_string();
    (name != "lib" && name != "main").then_some(name)
}

/// The file's code: comments (`//`, doc comments included) removed, and the unit tests (from
/// the first `#[cfg(test)]` on) left out.
fn code(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        let code = match line.find("//") {
            // A `//` inside a string literal ("http://") is rare in our code; none is a path.
            Some(at) => &line[..at],
            None => line,
        };
        if !code.trim().is_empty() {
            out.push((i + 1, code.to_string()));
        }
    }
    out
}

/// Every `crate::NAME` a line uses, also inside `use crate::{a, b::c}` groups.
fn crate_refs(line: &str) -> Vec<String> {
    let mut refs = Vec::new();
    let mut rest = line;
    while let Some(at) = rest.find("crate::") {
        let after = &rest[at + "crate::".len()..];
        if let Some(group) = after.strip_prefix('{') {
            let end = group.find('}').unwrap_or(group.len());
            for part in group[..end].split(',') {
                let name: String = part
                    .trim()
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    refs.push(name);
                }
            }
        } else {
            let name: String = after
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                refs.push(name);
            }
        }
        rest = after;
    }
    refs
}

/// Whether `line` names the external crate `krate` (`iceoryx2::x`, `use iceoryx2;`), not a
/// module of ours that ends in its name (`cli::iceoryx2::`, `ingest_iceoryx2::`).
fn names_crate(line: &str, krate: &str) -> bool {
    let t = line.trim_start();
    if t.starts_with("mod ") || t.starts_with("pub mod ") {
        return false; // our own module of that name
    }
    line.match_indices(krate).any(|(at, _)| {
        let before = line[..at].chars().next_back();
        let after = &line[at + krate.len()..];
        !before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':')
            && (after.starts_with("::") || after.starts_with(';'))
    })
}

fn files() -> Vec<(PathBuf, String)> {
    let mut paths = Vec::new();
    rust_files(&src(), &mut paths);
    paths.sort();
    paths
        .into_iter()
        .map(|p| {
            let text = std::fs::read_to_string(&p).unwrap();
            (p, text)
        })
        .collect()
}

fn rel(p: &Path) -> String {
    p.strip_prefix(Path::new(env!("CARGO_MANIFEST_DIR")))
        .unwrap()
        .display()
        .to_string()
}

#[test]
fn every_module_imports_only_from_below() {
    let rank: BTreeMap<&str, u32> = LAYERS.iter().copied().collect();
    let mut wrong = Vec::new();
    for (path, text) in files() {
        let Some(module) = module_of(&path) else {
            continue;
        };
        let Some(&own) = rank.get(module.as_str()) else {
            wrong.push(format!(
                "{}: module `{module}` has no layer in tests/layers.rs (and ARCHITECTURE.md)",
                rel(&path)
            ));
            continue;
        };
        for (n, line) in code(&text) {
            for used in crate_refs(&line) {
                if used == module {
                    continue;
                }
                match rank.get(used.as_str()) {
                    Some(&r) if r < own => {}
                    Some(&r) => wrong.push(format!(
                        "{}:{n}: `{module}` (layer {own}) uses `{used}` (layer {r}): {}",
                        rel(&path),
                        line.trim()
                    )),
                    None => {}
                }
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "imports against the layers:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn only_transport_touches_iceoryx2_and_only_the_bridge_zenoh_and_only_dds_ros2_client() {
    let mut wrong = Vec::new();
    for (path, text) in files() {
        let r = rel(&path);
        let transport = r.starts_with("src/transport/");
        let zenoh_ok = r == "src/transport/zenoh.rs" || r == "src/cli/bridge.rs";
        let dds_ok = r == "src/transport/ros2/dds.rs";
        for (n, line) in code(&text) {
            if names_crate(&line, "iceoryx2") && !transport {
                wrong.push(format!(
                    "{r}:{n}: iceoryx2 outside transport: {}",
                    line.trim()
                ));
            }
            if names_crate(&line, "ros2_client") && !dds_ok {
                wrong.push(format!(
                    "{r}:{n}: ros2_client outside transport/ros2/dds.rs: {}",
                    line.trim()
                ));
            }
            if names_crate(&line, "zenoh") && !zenoh_ok {
                wrong.push(format!(
                    "{r}:{n}: zenoh outside the bridge: {}",
                    line.trim()
                ));
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn the_maths_does_no_io() {
    let mut wrong = Vec::new();
    for (path, text) in files() {
        let Some(module) = module_of(&path) else {
            continue;
        };
        if !MATHS.contains(&module.as_str()) {
            continue;
        }
        for (n, line) in code(&text) {
            for word in IMPURE {
                if line.contains(word) {
                    wrong.push(format!(
                        "{}:{n}: `{word}` in the maths: {}",
                        rel(&path),
                        line.trim()
                    ));
                }
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn no_source_file_holds_over_1000_lines_of_code() {
    let mut wrong = Vec::new();
    for (path, text) in files() {
        let r = rel(&path);
        if r == "src/wavelet/filters.rs" {
            continue; // generated coefficient tables (scripts/gen_filters.py)
        }
        let lines = text
            .lines()
            .take_while(|l| !l.trim_start().starts_with("#[cfg(test)]"))
            .count();
        if lines > 1000 {
            wrong.push(format!(
                "{r}: {lines} lines before its tests: split it by concern"
            ));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// The longest function a command's file may hold, lines from its `fn` line to its closing
/// brace: `cli` parses, calls the library and prints; a longer function is doing the library's
/// work, or printing what wants a function of its own.
const CLI_FN_MAX_LINES: usize = 120;

/// Functions over [`CLI_FN_MAX_LINES`] until branch `wire` lands (it shortens them; then this
/// list goes).
const CLI_LONG_FNS: &[(&str, &str)] = &[
    ("src/cli/list.rs", "text"),
    ("src/cli/record.rs", "record"),
    ("src/cli/tap.rs", "tap"),
];

/// Each function with a body before the unit tests: its name, its first line (1-based) and its
/// length in lines, from the `fn` line to the closing brace at the `fn` line's indentation (as
/// rustfmt writes it).
fn functions(text: &str) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = text
        .lines()
        .take_while(|l| !l.trim_start().starts_with("#[cfg(test)]"))
        .collect();
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let t = line.trim_start();
        let indent = &line[..line.len() - t.len()];
        let mut words = t.split_whitespace().peekable();
        while words
            .peek()
            .is_some_and(|w| w.starts_with("pub") || ["const", "async", "unsafe"].contains(w))
        {
            words.next();
        }
        if words.next() != Some("fn") {
            continue;
        }
        let Some(name) = words.next().map(|w| {
            w.chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect::<String>()
        }) else {
            continue;
        };
        // The signature ends at its body's `{`, or at a `;` (no body: a trait's declaration).
        let Some(open) = (i..lines.len())
            .find(|&j| lines[j].contains('{') || lines[j].trim_end().ends_with(';'))
        else {
            continue;
        };
        if !lines[open].contains('{') {
            continue;
        }
        let closing = format!("{indent}}}");
        let one_line = lines[open].matches('{').count() == lines[open].matches('}').count();
        let end = if one_line {
            Some(open)
        } else {
            (open + 1..lines.len()).find(|&j| lines[j] == closing)
        };
        if let Some(end) = end {
            out.push((name, i + 1, end - i + 1));
        }
    }
    out
}

#[test]
fn no_function_of_a_command_is_over_120_lines() {
    let mut wrong = Vec::new();
    for (path, text) in files() {
        let r = rel(&path);
        if !r.starts_with("src/cli/") {
            continue;
        }
        for (name, line, len) in functions(&text) {
            let allowed = CLI_LONG_FNS.contains(&(r.as_str(), name.as_str()));
            if len > CLI_FN_MAX_LINES && !allowed {
                wrong.push(format!(
                    "{r}:{line}: fn {name} is {len} lines (at most {CLI_FN_MAX_LINES}): move its computation below cli, or split it"
                ));
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn the_checks_see_what_they_check() {
    assert_eq!(
        crate_refs("use crate::{io, nav::MotionTrace}; x = crate::sim::f();"),
        ["io", "nav", "sim"]
    );
    assert_eq!(
        code("let a = 1; // crate::cli\n#[cfg(test)]\nuse crate::cli;").len(),
        1
    );
    assert_eq!(
        module_of(&src().join("drift/bias/mod.rs")).as_deref(),
        Some("drift")
    );
    assert_eq!(module_of(&src().join("lib.rs")), None);
    assert!(names_crate("use iceoryx2::prelude::*;", "iceoryx2"));
    assert!(!names_crate(
        "pub a: crate::cli::iceoryx2::Args,",
        "iceoryx2"
    ));
    assert!(!names_crate("&ingest_iceoryx2::KIND,", "iceoryx2"));
    assert!(!names_crate("pub mod zenoh;", "zenoh"));
    let text = "pub fn a(\n    x: u8,\n) -> u8 {\n    x\n}\nfn b() {}\ntrait T {\n    fn c();\n    fn d(&self) {\n        let _ = 1;\n    }\n}\n#[cfg(test)]\nfn e() {\n}\n";
    assert_eq!(
        functions(text),
        [
            ("a".to_string(), 1, 5),
            ("b".to_string(), 6, 1),
            ("d".to_string(), 9, 3)
        ]
    );
}
