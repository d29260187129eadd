//! iceoryx2 0.10's names for its files, and the prefixes we allow: which file, in which
//! directory, belongs to which prefix. The clean-up deletes only names that match here.
//!
//! A prefix is letters, digits, `-` and `.`, ending in one `_` and holding no other `_`
//! ([`check_prefix`]). So the prefix of any file is its name up to its first `_`, and no
//! prefix's files can be taken for another's: `driftless_` never matches `driftless-b_...`
//! (a bare `starts_with("p")` matched `pulse-shm-12345`). After the prefix, iceoryx2 0.10
//! writes (`H`: a 40-digit lowercase hex SHA-1, `D`: a decimal `u128`):
//!
//! | directory | names after the prefix |
//! |---|---|
//! | `/dev/shm` | `H_D.data`, `H_D__D.data`, `H_D__mgmt.data`, `H_D.dynamic`, `H_D.event_mgmt`, `H_D_D.connection`, `H_D.blackboard_mgmt`, `H_D.blackboard_data`, `H_node.D_D_D.global_mgmt` |
//! | root | `D.event` (a Unix socket) |
//! | root`/services` | `H.service` |
//! | root`/nodes` | `D.node_monitor`, `D.node_monitor_context`, `D.node_monitor_owner_lock` |
//! | root`/nodes/D` (no prefix on the directory) | `node.details`, `D.port_tag`, `H.service_tag` |
//!
//! The functions here are pure byte checks that never allocate: the SIGBUS guard
//! (`shm_space`) calls [`is_segment`] inside a signal handler.

/// Longest prefix we accept: iceoryx2 adds up to about 130 bytes to it, and a file name holds
/// 255.
const MAX_PREFIX_LEN: usize = 64;

/// The name of a prefix's global management segment in `/dev/shm` after the prefix: the one
/// segment every node of the prefix opens by a name known beforehand (its node counter; every
/// other segment's name holds an id drawn when it is made). iceoryx2 0.10 names it by the
/// SHA-1 of the type it holds, `iceoryx2::node::global_management_segment::State`, then
/// `_node.` and its own version (tests/cleanup_safety.rs finds this name in a daemon's run).
pub(super) const GLOBAL_SEGMENT: &[u8] =
    b"9204dd183d1c4d8e1ff592a30766ffa6765aa8b5_node.0_10_0.global_mgmt";

/// The directories iceoryx2 keeps its files in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Place {
    /// `/dev/shm`: the shared memory segments.
    Shm,
    /// The root directory itself: the event sockets.
    Root,
    /// `<root>/services`: the static service configurations.
    Services,
    /// `<root>/nodes`: the node monitors.
    Nodes,
    /// `<root>/nodes/<node id>`: one node's details and tags.
    NodeDir,
}

/// Is `name` a file that iceoryx2 0.10 makes for `prefix` in `place`?
pub(super) fn is_ours(place: Place, prefix: &[u8], name: &[u8]) -> bool {
    let Some(rest) = name.strip_prefix(prefix) else {
        return false;
    };
    let any = |suffixes: &[&[u8]], body: fn(&[u8]) -> bool| {
        suffixes
            .iter()
            .any(|s| rest.strip_suffix(*s).is_some_and(body))
    };
    match place {
        Place::Shm => is_segment_body(rest),
        Place::Root => any(&[b".event"], decimal),
        Place::Services => any(&[b".service"], hash),
        Place::Nodes => any(
            &[
                b".node_monitor",
                b".node_monitor_context",
                b".node_monitor_owner_lock",
            ],
            decimal,
        ),
        Place::NodeDir => {
            rest == b"node.details"
                || any(&[b".port_tag"], decimal)
                || any(&[b".service_tag"], hash)
        }
    }
}

/// Is `name` (a file name in `/dev/shm`) a segment iceoryx2 0.10 made under a prefix of ours,
/// whatever the prefix? Safe to call in a signal handler.
pub(super) fn is_segment(name: &[u8]) -> bool {
    let Some(end) = name.iter().position(|&b| b == b'_') else {
        return false;
    };
    let (prefix, rest) = name.split_at(end + 1);
    prefix_is_valid(prefix) && is_segment_body(rest)
}

/// Is a node directory's name (`<root>/nodes/<id>`) a node id?
pub(super) fn is_node_dir(name: &[u8]) -> bool {
    decimal(name)
}

/// `H_<name><suffix>`: a segment's name after its prefix.
fn is_segment_body(rest: &[u8]) -> bool {
    if rest.len() < 41 || !hash(&rest[..40]) || rest[40] != b'_' {
        return false;
    }
    let name = &rest[41..];
    let with = |suffix: &[u8], body: fn(&[u8]) -> bool| name.strip_suffix(suffix).is_some_and(body);
    with(b".data", |n| {
        decimal(n)
            || split_once(n, b"__").is_some_and(|(id, segment)| {
                decimal(id) && (decimal(segment) || segment == b"mgmt")
            })
    }) || with(b".dynamic", decimal)
        || with(b".event_mgmt", decimal)
        || with(b".blackboard_mgmt", decimal)
        || with(b".blackboard_data", decimal)
        || with(b".connection", |n| {
            split_once(n, b"_").is_some_and(|(a, b)| decimal(a) && decimal(b))
        })
        || with(b".global_mgmt", |n| {
            n.strip_prefix(b"node.").is_some_and(|version| {
                let mut parts = version.split(|&b| b == b'_');
                (0..3).all(|_| parts.next().is_some_and(decimal)) && parts.next().is_none()
            })
        })
}

fn split_once<'a>(s: &'a [u8], sep: &[u8]) -> Option<(&'a [u8], &'a [u8])> {
    let at = s.windows(sep.len()).position(|w| w == sep)?;
    Some((&s[..at], &s[at + sep.len()..]))
}

/// A decimal `u128` as iceoryx2 prints it: 1 to 39 digits.
fn decimal(s: &[u8]) -> bool {
    (1..=39).contains(&s.len()) && s.iter().all(u8::is_ascii_digit)
}

/// A SHA-1 as iceoryx2 prints it: 40 lowercase hex digits.
fn hash(s: &[u8]) -> bool {
    s.len() == 40 && s.iter().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

fn prefix_is_valid(p: &[u8]) -> bool {
    let Some((b'_', stem)) = p.split_last() else {
        return false;
    };
    p.len() <= MAX_PREFIX_LEN
        && stem.first().is_some_and(u8::is_ascii_alphanumeric)
        && stem
            .iter()
            .all(|&b| b.is_ascii_alphanumeric() || b == b'-' || b == b'.')
}

/// Check that `prefix` can be our iceoryx2 prefix: letters, digits, `-` and `.` (starting with
/// a letter or digit), then one `_` at the end and no other, at most 64 bytes. The error names a
/// prefix that works.
pub fn check_prefix(prefix: &str) -> Result<(), String> {
    if prefix_is_valid(prefix.as_bytes()) {
        return Ok(());
    }
    Err(format!(
        "a prefix is letters, digits, '-' or '.', then one '_' at the end and no other \
         (at most {MAX_PREFIX_LEN} bytes), so that no prefix's files can be taken for another's: \
         try {:?}",
        suggest_prefix(prefix)
    ))
}

/// A valid prefix close to `wanted`: every other character a `-`, one `_` at the end.
pub(super) fn suggest_prefix(wanted: &str) -> String {
    let stem: String = wanted
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' {
                c
            } else {
                '-'
            }
        })
        .collect();
    let stem = stem.trim_matches(|c| c == '-' || c == '.');
    let stem = if stem.is_empty() { "driftless" } else { stem };
    let cut = stem.len().min(MAX_PREFIX_LEN - 1);
    format!("{}_", stem[..cut].trim_end_matches(['-', '.']))
}

#[cfg(test)]
mod tests {
    use super::*;

    const H: &str = "0354a209029e7d094a819e2d4030ea331e6caaf0";
    const D: &str = "158456425824514663799274340511";

    /// Every name iceoryx2 0.10 made for prefix `probe_` in a run of the daemon with a driver
    /// and a subscriber (ids and hashes as they were).
    fn seen(place: Place) -> Vec<String> {
        match place {
            Place::Shm => vec![
                format!("probe_{H}_{D}.data"),
                format!("probe_{H}_{D}__7.data"),
                format!("probe_{H}_{D}__mgmt.data"),
                format!("probe_{H}_{D}.dynamic"),
                format!("probe_{H}_{D}.event_mgmt"),
                format!("probe_{H}_{D}_{D}.connection"),
                format!("probe_{H}_node.0_10_0.global_mgmt"),
            ],
            Place::Root => vec![format!("probe_{D}.event")],
            Place::Services => vec![format!("probe_{H}.service")],
            Place::Nodes => vec![
                format!("probe_{D}.node_monitor"),
                format!("probe_{D}.node_monitor_context"),
                format!("probe_{D}.node_monitor_owner_lock"),
            ],
            Place::NodeDir => vec![
                "probe_node.details".into(),
                format!("probe_{D}.port_tag"),
                format!("probe_{H}.service_tag"),
            ],
        }
    }

    const PLACES: [Place; 5] = [
        Place::Shm,
        Place::Root,
        Place::Services,
        Place::Nodes,
        Place::NodeDir,
    ];

    #[test]
    fn iceoryx2s_names_are_ours_in_their_own_place_only() {
        for place in PLACES {
            for name in seen(place) {
                for other in PLACES {
                    assert_eq!(
                        is_ours(other, b"probe_", name.as_bytes()),
                        other == place,
                        "{name} in {other:?}"
                    );
                }
            }
        }
        assert!(is_segment(seen(Place::Shm)[0].as_bytes()));
        let global = [b"probe_", GLOBAL_SEGMENT].concat();
        assert!(is_ours(Place::Shm, b"probe_", &global));
        assert!(!is_segment(b"pulse-shm-12345"));
        assert!(is_node_dir(D.as_bytes()));
        assert!(!is_node_dir(b"probe_1"));
    }

    #[test]
    fn other_programs_files_and_other_prefixes_are_never_ours() {
        let others = [
            "pulse-shm-12345".to_string(),
            "probe_keep.conf".into(),
            "probe_".into(),
            format!("probe_{H}_{D}.data.bak"),
            format!("probe_{}_{D}.data", H.to_uppercase()),
            format!("probe_{H}x_{D}.data"),
            format!("probe_{H}_{D}x.dynamic"),
            format!("probe_{H}_node.0_10.global_mgmt"),
            format!("probe_{H}_{}.data", "1".repeat(40)),
        ];
        for name in &others {
            for place in PLACES {
                assert!(!is_ours(place, b"probe_", name.as_bytes()), "{name}");
            }
        }
        // A longer prefix's files are never a shorter one's, whatever follows.
        for place in PLACES {
            for name in seen(place) {
                let longer = name.replacen("probe_", "probe-b_", 1);
                assert!(!is_ours(place, b"probe_", longer.as_bytes()), "{longer}");
                let digits = name.replacen("probe_", "probe1_", 1);
                assert!(!is_ours(place, b"probe_", digits.as_bytes()), "{digits}");
            }
        }
    }

    #[test]
    fn a_prefix_ends_in_its_only_underscore() {
        for good in ["driftless_", "p_", "dlt1234order_", "a.b-c_", "X9_"] {
            assert_eq!(check_prefix(good), Ok(()), "{good}");
        }
        for (bad, fix) in [
            ("p", "p_"),
            ("driftless_b", "driftless-b_"),
            ("driftless_b_", "driftless-b_"),
            ("_", "driftless_"),
            ("-x_", "x_"),
            (".x_", "x_"),
            ("a/b", "a-b_"),
            ("dlpy12_ab_", "dlpy12-ab_"),
        ] {
            let e = check_prefix(bad).unwrap_err();
            assert!(e.ends_with(&format!("try {fix:?}")), "{bad}: {e}");
            assert_eq!(check_prefix(fix), Ok(()), "{fix}");
        }
        let long = "a".repeat(80);
        let fix = suggest_prefix(&long);
        assert_eq!(fix.len(), MAX_PREFIX_LEN);
        assert_eq!(check_prefix(&fix), Ok(()));
    }
}
