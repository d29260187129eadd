//! `driftless list`: what runs under a prefix (like `ros2 topic list`, `iox2 service list`,
//! `dora list`): the pipelines with their rate, the other nodes, and every service with its
//! payload type, publishers and subscribers. `--clean` removes what dead nodes left.
//!
//! The listing itself is iceoryx2's ([`Transport::list`]); this file groups and formats it. A
//! pipeline is a process holding the daemon's node (`driftless-NAME`) and its reporter's
//! (`driftless-NAME-stats`, which publishes the stats snapshots whose rate is shown).

use std::collections::BTreeSet;
use std::time::Duration;

use serde_json::{json, Value};

use crate::cli::CliError;
use crate::pipeline::runtime::{node_name, stats_node_name};
use crate::transport::ros2;
use crate::transport::{
    self, display_name, ListedNode, ListedService, Listing, NodeLife, ServiceKind, Transport,
    WireType,
};
use crate::wire::StatsSnapshot;

/// Arguments of `driftless list`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Where the pipeline's iceoryx2 files are.
    #[command(flatten)]
    pub iceoryx2: crate::cli::iceoryx2::Iceoryx2Args,
    /// Print one JSON document instead of the tables.
    #[arg(long)]
    pub json: bool,
    /// First remove what dead nodes (processes killed without cleaning up) left behind.
    #[arg(long)]
    pub clean: bool,
    /// How long to wait for each live pipeline's next stats snapshot, for its rate.
    #[arg(
        long,
        default_value = "2.5s",
        value_parser = crate::cli::duration::parse_duration,
        allow_hyphen_values = true
    )]
    pub stats_wait: Duration,
}

/// A pipeline found in the node list.
struct Pipeline<'a> {
    name: String,
    daemon: &'a ListedNode,
    /// Every node of the daemon's process that belongs to it (daemon, reporter, segments).
    nodes: Vec<&'a ListedNode>,
    stats_service: Option<String>,
    stats: Option<StatsSnapshot>,
    ros2: Option<Ros2Side>,
}

/// A pipeline's ROS 2 side, as its bridge announced it (`transport::ros2`'s attributes).
struct Ros2Side {
    /// The node's full name.
    node: String,
    domain: String,
    /// Each topic: direction (`in`, `out`, `stop`), topic, ROS 2 type, service; or a `+N more`
    /// line as the topic with the rest empty.
    topics: Vec<[String; 4]>,
}

impl Ros2Side {
    /// The side a service announces, if it is one.
    fn of(s: &ListedService) -> Option<Ros2Side> {
        let value = |key: &'static str| {
            s.attributes
                .iter()
                .filter(move |(k, _)| k == key)
                .map(|(_, v)| v)
        };
        let node = value(ros2::NODE_KEY).next()?.clone();
        let domain = value(ros2::DOMAIN_KEY).next().cloned().unwrap_or_default();
        let topics = value(ros2::TOPIC_KEY)
            .map(|t| {
                let mut w = t.splitn(4, ' ').map(str::to_string);
                match (w.next(), w.next(), w.next(), w.next()) {
                    (Some(d), Some(topic), Some(ty), Some(service)) => [d, topic, ty, service],
                    _ => [String::new(), t.clone(), String::new(), String::new()],
                }
            })
            .collect();
        Some(Ros2Side {
            node,
            domain,
            topics,
        })
    }
}

fn pid(n: &ListedNode) -> Option<i32> {
    n.holder.as_ref().map(|h| h.pid)
}

/// Pipelines: a node `driftless-NAME` whose process also holds `driftless-NAME-stats`.
fn pipelines<'a>(listing: &'a Listing) -> Vec<Pipeline<'a>> {
    let mut out = Vec::new();
    for daemon in &listing.nodes {
        let Some(name) = daemon.name.strip_prefix(&node_name("")) else {
            continue;
        };
        let stats_node = stats_node_name(&daemon.name);
        let same_process = |n: &&ListedNode| pid(n).is_some() && pid(n) == pid(daemon);
        let Some(reporter) = listing
            .nodes
            .iter()
            .filter(same_process)
            .find(|n| n.name == stats_node)
        else {
            continue;
        };
        let own = format!("{}-", daemon.name);
        let nodes: Vec<&ListedNode> = listing
            .nodes
            .iter()
            .filter(same_process)
            .filter(|n| n.name == daemon.name || n.name.starts_with(&own))
            .collect();
        let stats_service = listing
            .services
            .iter()
            .find(|s| {
                matches!(
                    s.kind,
                    ServiceKind::PubSub {
                        wire: Some(WireType::Stats),
                        ..
                    }
                ) && s.senders.as_ref().is_some_and(|p| p.contains(&reporter.id))
            })
            .map(|s| s.name.clone());
        // The ROS 2 side its bridge announced (a service one of its nodes holds).
        let ros2 = listing
            .services
            .iter()
            .filter(|s| s.nodes.iter().any(|id| nodes.iter().any(|n| n.id == *id)))
            .find_map(Ros2Side::of);
        out.push(Pipeline {
            name: name.to_string(),
            daemon,
            nodes,
            stats_service,
            stats: None,
            ros2,
        });
    }
    out.sort_by(|a, b| a.name.cmp(&b.name));
    out
}

/// Who a node is in the listing: its pipeline's name, or its own name.
fn who(id: u128, listing: &Listing, pipes: &[Pipeline<'_>]) -> String {
    if let Some(p) = pipes.iter().find(|p| p.nodes.iter().any(|n| n.id == id)) {
        return p.name.clone();
    }
    match listing.nodes.iter().find(|n| n.id == id) {
        Some(n) => display_name(n),
        None => format!("node {id:x}"),
    }
}

fn life_of(id: u128, listing: &Listing) -> Option<NodeLife> {
    listing.nodes.iter().find(|n| n.id == id).map(|n| n.life)
}

/// The publishers of a service, by pipeline or node name (dead ones marked), once each.
fn published_by(s: &ListedService, listing: &Listing, pipes: &[Pipeline<'_>]) -> Vec<String> {
    let names: BTreeSet<String> = s
        .senders
        .iter()
        .flatten()
        .map(|&id| match life_of(id, listing) {
            Some(NodeLife::Alive) => who(id, listing, pipes),
            Some(life) => format!("{} ({})", who(id, listing, pipes), life.as_str()),
            None => format!("{} (gone)", who(id, listing, pipes)),
        })
        .collect();
    names.into_iter().collect()
}

/// `12s`, `5m 3s`, `2h 7m`, `3d 4h`: the two largest units of an age.
fn age(d: Duration) -> String {
    let s = d.as_secs();
    match s {
        0..60 => format!("{s}s"),
        60..3600 => format!("{}m {}s", s / 60, s % 60),
        3600..86_400 => format!("{}h {}m", s / 3600, s % 3600 / 60),
        _ => format!("{}d {}h", s / 86_400, s % 86_400 / 3600),
    }
}

fn started(n: &ListedNode) -> String {
    n.holder
        .as_ref()
        .and_then(|h| h.since)
        .map_or("-".into(), |(_, a)| format!("{} ago", age(a)))
}

fn user(n: &ListedNode) -> String {
    n.holder
        .as_ref()
        .and_then(|h| h.user.clone())
        .unwrap_or_else(|| "-".into())
}

fn pid_text(n: &ListedNode) -> String {
    pid(n).map_or("-".into(), |p| p.to_string())
}

fn type_text(kind: &ServiceKind) -> String {
    match kind {
        ServiceKind::PubSub { wire: Some(w), .. } => w.short_name().into(),
        // Ours, in another layout version (an older or newer driftless's daemon).
        ServiceKind::PubSub {
            wire: None,
            type_name,
        } => crate::wire::other_layout_of(type_name)
            .map_or_else(|| "foreign".into(), |t| format!("{t} (other version)")),
        ServiceKind::Event => "event".into(),
        ServiceKind::Other(pattern) => pattern.to_string(),
    }
}

fn count_text(ports: &Option<Vec<u128>>) -> String {
    ports.as_ref().map_or("?".into(), |p| p.len().to_string())
}

/// Left-aligned columns (right-aligned where `right` says), each as wide as its widest cell,
/// two spaces apart: typical names fit 80 columns, a long one widens only its column.
fn table(header: &[&str], right: &[bool], rows: &[Vec<String>]) -> String {
    let mut widths: Vec<usize> = header.iter().map(|h| h.len()).collect();
    for row in rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |cells: Vec<&str>| {
        let text: Vec<String> = cells
            .iter()
            .zip(&widths)
            .zip(right)
            .map(|((c, &w), &r)| {
                if r {
                    format!("{c:>w$}")
                } else {
                    format!("{c:<w$}")
                }
            })
            .collect();
        text.join("  ").trim_end().to_string() + "\n"
    };
    let mut out = line(header.to_vec());
    for row in rows {
        out.push_str(&line(row.iter().map(String::as_str).collect()));
    }
    out
}

fn text(prefix: &str, listing: &Listing, pipes: &[Pipeline<'_>]) -> String {
    let dead = listing
        .nodes
        .iter()
        .filter(|n| n.life == NodeLife::Dead)
        .count();
    let plural = |n: usize, one: &str| format!("{n} {one}{}", if n == 1 { "" } else { "s" });
    if listing.nodes.is_empty() && listing.services.is_empty() {
        return format!("prefix {prefix:?}: nothing running\n");
    }
    let mut out = format!(
        "prefix {prefix:?}: {}, {}{}, {}\n",
        plural(pipes.len(), "pipeline"),
        plural(listing.nodes.len(), "node"),
        if dead > 0 {
            format!(" ({dead} dead)")
        } else {
            String::new()
        },
        plural(listing.services.len(), "service"),
    );
    for section in [
        pipelines_table(pipes),
        ros2_table(pipes),
        others_table(listing, pipes),
        services_table(listing, pipes),
    ]
    .into_iter()
    .flatten()
    {
        out.push('\n');
        out.push_str(&section);
    }
    out
}

/// The pipelines, with the rate of their latest stats snapshot.
fn pipelines_table(pipes: &[Pipeline<'_>]) -> Option<String> {
    if pipes.is_empty() {
        return None;
    }
    let rows: Vec<Vec<String>> = pipes
        .iter()
        .map(|p| {
            let rate = match (&p.stats, p.daemon.life) {
                (Some(s), _) => format!("{:.1} Hz", s.rate_hz),
                (None, NodeLife::Alive) => "?".into(),
                (None, _) => "-".into(),
            };
            vec![
                p.name.clone(),
                p.daemon.life.as_str().into(),
                pid_text(p.daemon),
                user(p.daemon),
                started(p.daemon),
                rate,
            ]
        })
        .collect();
    Some(table(
        &["PIPELINE", "STATE", "PID", "USER", "STARTED", "RATE"],
        &[false, false, true, false, false, true],
        &rows,
    ))
}

/// The topics of the pipelines' ROS 2 sides.
fn ros2_table(pipes: &[Pipeline<'_>]) -> Option<String> {
    let rows: Vec<Vec<String>> = pipes
        .iter()
        .filter_map(|p| Some((p, p.ros2.as_ref()?)))
        .flat_map(|(p, r)| {
            r.topics.iter().map(move |t| {
                let mut row = vec![p.name.clone(), r.node.clone(), r.domain.clone()];
                row.extend(t.iter().cloned());
                row
            })
        })
        .collect();
    (!rows.is_empty()).then(|| {
        table(
            &[
                "ROS 2 OF", "NODE", "DOMAIN", "DIR", "TOPIC", "TYPE", "SERVICE",
            ],
            &[false, false, true, false, false, false, false],
            &rows,
        )
    })
}

/// The nodes no pipeline holds.
fn others_table(listing: &Listing, pipes: &[Pipeline<'_>]) -> Option<String> {
    let rows: Vec<Vec<String>> = listing
        .nodes
        .iter()
        .filter(|n| !pipes.iter().any(|p| p.nodes.iter().any(|m| m.id == n.id)))
        .map(|n| {
            vec![
                display_name(n),
                n.life.as_str().into(),
                pid_text(n),
                user(n),
                started(n),
            ]
        })
        .collect();
    (!rows.is_empty()).then(|| {
        table(
            &["NODE", "STATE", "PID", "USER", "STARTED"],
            &[false, false, true, false, false],
            &rows,
        )
    })
}

/// Every service, its type, ports and publishers.
fn services_table(listing: &Listing, pipes: &[Pipeline<'_>]) -> Option<String> {
    let rows: Vec<Vec<String>> = listing
        .services
        .iter()
        .map(|s| {
            let by = published_by(s, listing, pipes);
            vec![
                s.name.clone(),
                type_text(&s.kind),
                count_text(&s.senders),
                count_text(&s.receivers),
                if s.senders.is_none() {
                    "?".into()
                } else if by.is_empty() {
                    "-".into()
                } else {
                    by.join(", ")
                },
            ]
        })
        .collect();
    (!rows.is_empty()).then(|| {
        table(
            &["SERVICE", "TYPE", "PUB", "SUB", "PUBLISHED BY"],
            &[false, false, true, true, false],
            &rows,
        )
    })
}

fn node_json(n: &ListedNode, pipeline: Option<&str>) -> Value {
    let h = n.holder.as_ref();
    json!({
        "name": n.name,
        "state": n.life.as_str(),
        "pid": h.map(|h| h.pid),
        "user": h.and_then(|h| h.user.clone()),
        "executable": h.and_then(|h| h.executable.clone()),
        "since": h.and_then(|h| h.since).map(|(t, _)| humantime::format_rfc3339_seconds(t).to_string()),
        "uptime_s": h.and_then(|h| h.since).map(|(_, a)| a.as_secs_f64()),
        "pipeline": pipeline,
    })
}

fn document(
    prefix: &str,
    listing: &Listing,
    pipes: &[Pipeline<'_>],
    removed: Option<&[ListedNode]>,
) -> Value {
    let pipeline_of = |id: u128| {
        pipes
            .iter()
            .find(|p| p.nodes.iter().any(|n| n.id == id))
            .map(|p| p.name.as_str())
    };
    let pipelines: Vec<Value> = pipes
        .iter()
        .map(|p| {
            let mut v = node_json(p.daemon, None);
            v["name"] = json!(p.name);
            v["nodes"] = json!(p.nodes.iter().map(|n| &n.name).collect::<Vec<_>>());
            v["stats_service"] = json!(p.stats_service);
            v["rate_hz"] = json!(p.stats.map(|s| s.rate_hz));
            v["samples_in"] = json!(p.stats.map(|s| s.samples_in));
            v["samples_out"] = json!(p.stats.map(|s| s.samples_out));
            v["lost"] = json!(p.stats.map(|s| s.lost));
            v["ros2"] = json!(p.ros2.as_ref().map(|r| json!({
                "node": r.node,
                "domain": r.domain.parse::<u16>().ok(),
                "topics": r.topics.iter().map(|[direction, topic, ty, service]| json!({
                    "direction": direction, "topic": topic, "type": ty, "service": service,
                })).collect::<Vec<_>>(),
            })));
            v.as_object_mut().expect("an object").remove("pipeline");
            v
        })
        .collect();
    let nodes: Vec<Value> = listing
        .nodes
        .iter()
        .map(|n| node_json(n, pipeline_of(n.id)))
        .collect();
    let services: Vec<Value> = listing
        .services
        .iter()
        .map(|s| {
            let count = |p: &Option<Vec<u128>>| p.as_ref().map(Vec::len);
            let (pattern, type_name) = match &s.kind {
                ServiceKind::PubSub { type_name, .. } => ("publish-subscribe", Some(type_name)),
                ServiceKind::Event => ("event", None),
                ServiceKind::Other(pattern) => (*pattern, None),
            };
            let mut v = json!({
                "name": s.name,
                "pattern": pattern,
                "type": type_name,
                "wire_type": match &s.kind {
                    ServiceKind::PubSub { .. } => Some(type_text(&s.kind)),
                    _ => None,
                },
                "published_by": s.senders.as_ref().map(|_| published_by(s, listing, pipes)),
                "nodes": s.nodes.iter().map(|&id| who(id, listing, pipes)).collect::<BTreeSet<_>>(),
                "attributes": s.attributes.iter().map(|(k, v)| json!([k, v])).collect::<Vec<_>>(),
            });
            let (send, receive) = if matches!(s.kind, ServiceKind::Event) {
                ("notifiers", "listeners")
            } else {
                ("publishers", "subscribers")
            };
            v[send] = json!(count(&s.senders));
            v[receive] = json!(count(&s.receivers));
            v
        })
        .collect();
    let mut doc = json!({
        "prefix": prefix,
        "pipelines": pipelines,
        "nodes": nodes,
        "services": services,
    });
    if let Some(removed) = removed {
        doc["removed_dead_nodes"] = json!(removed
            .iter()
            .map(|n| node_json(n, None))
            .collect::<Vec<_>>());
    }
    doc
}

/// List what runs under the prefix (after removing dead nodes' leftovers with `--clean`).
pub fn run(args: Args) -> Result<(), CliError> {
    transport::quiet_logging();
    let prefix = args.iceoryx2.resolve(None)?;
    let result = list(&args, &prefix);
    // The last process of a prefix removes its management file; `--clean` also waits out a
    // start killed within the last second (its files look like a start in progress).
    if args.clean {
        transport::remove_prefix_leftovers_settled(&prefix);
    } else {
        transport::remove_prefix_leftovers(&prefix);
    }
    result
}

fn list(args: &Args, prefix: &str) -> Result<(), CliError> {
    let removed = if args.clean {
        let removed = Transport::remove_dead_nodes(prefix)?;
        let names: Vec<String> = removed
            .iter()
            .map(|n| match pid(n) {
                Some(p) => format!("{} (pid {p})", display_name(n)),
                None => display_name(n),
            })
            .collect();
        eprintln!(
            "removed {} dead node{} under prefix {prefix:?}{}{}",
            removed.len(),
            if removed.len() == 1 { "" } else { "s" },
            if names.is_empty() { "" } else { ": " },
            names.join(", ")
        );
        Some(removed)
    } else {
        None
    };
    let listing = Transport::list(prefix)?;
    let mut pipes = pipelines(&listing);
    let waiting: Vec<usize> = (0..pipes.len())
        .filter(|&i| pipes[i].daemon.life == NodeLife::Alive && pipes[i].stats_service.is_some())
        .collect();
    let services: Vec<String> = waiting
        .iter()
        .filter_map(|&i| pipes[i].stats_service.clone())
        .collect();
    let snapshots = Transport::read_stats(prefix, &services, args.stats_wait)?;
    for (&i, snap) in waiting.iter().zip(snapshots) {
        pipes[i].stats = snap;
    }
    let out = if args.json {
        let doc = document(prefix, &listing, &pipes, removed.as_deref());
        serde_json::to_string_pretty(&doc).expect("JSON of plain values") + "\n"
    } else {
        text(prefix, &listing, &pipes)
    };
    // A closed stdout (`| head`) ends the command cleanly.
    let _ = std::io::Write::write_all(&mut std::io::stdout(), out.as_bytes());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ages_read_in_their_two_largest_units() {
        assert_eq!(age(Duration::from_secs(12)), "12s");
        assert_eq!(age(Duration::from_secs(303)), "5m 3s");
        assert_eq!(age(Duration::from_secs(7620)), "2h 7m");
        assert_eq!(
            age(Duration::from_secs(3 * 86_400 + 4 * 3600 + 59)),
            "3d 4h"
        );
    }

    #[test]
    fn columns_are_as_wide_as_their_widest_cell() {
        let t = table(
            &["NAME", "N"],
            &[false, true],
            &[
                vec!["a".into(), "1".into()],
                vec!["longer".into(), "100".into()],
            ],
        );
        assert_eq!(t, "NAME      N\na         1\nlonger  100\n");
    }
}
