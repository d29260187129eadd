//! `driftless validate PIPELINE...`: every check `run` makes, nothing started (for several
//! pipelines, also that they can share one daemon).
//! `driftless validate --kinds`: every stage kind with its keys, from the schema the stage files
//! own (`--markdown`: the table `docs/daemon.md` holds).

use std::path::PathBuf;

use crate::cli::CliError;
use crate::pipeline::config::{self, Pipeline};
use crate::pipeline::runtime;
use crate::pipeline::stage::{Kind, Role};

/// Arguments of `driftless validate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Pipeline file (TOML). Several: each, and that they can share one daemon (`driftless run`
    /// with the same files).
    #[arg(value_name = "PIPELINE", required_unless_present = "kinds")]
    pub pipelines: Vec<PathBuf>,
    /// List every stage kind with its keys, types, ranges and defaults instead.
    #[arg(long, conflicts_with = "pipelines")]
    pub kinds: bool,
    /// With --kinds: as the Markdown table of docs/daemon.md.
    #[arg(long, requires = "kinds")]
    pub markdown: bool,
}

/// Validate the pipelines and describe them on stdout, or list the stage kinds.
pub fn run(args: Args) -> Result<(), CliError> {
    if args.pipelines.is_empty() {
        print!("{}", kinds(args.markdown));
        return Ok(());
    }
    let mut all = Vec::new();
    for path in &args.pipelines {
        let p = config::load(path)?;
        describe(&p);
        all.push(p);
    }
    if all.len() > 1 {
        // Under their own prefixes, as `run` without --prefix or DRIFTLESS_IOX2_PREFIX.
        let members: Vec<_> = all.iter().map(|p| (p, p.iceoryx2.prefix.clone())).collect();
        runtime::check_group(&members).map_err(|e| CliError::input(e.to_string()))?;
        println!("the {} pipelines can share one daemon", all.len());
    }
    Ok(())
}

/// What `validate` says of one valid pipeline.
fn describe(p: &Pipeline) {
    let path = &p.path;
    println!(
        "{}: pipeline {:?} is valid: {} Hz, deadline {} us, {} axis/axes, prefix {:?}",
        path.display(),
        p.name,
        p.rate_hz,
        p.deadline.as_micros(),
        p.axes,
        p.iceoryx2.prefix
    );
    for s in &p.stages {
        println!(
            "  {:<12} {:<16} {} -> {}",
            s.name,
            s.kind.name,
            s.input.as_deref().unwrap_or("-"),
            s.output
        );
        for line in s.params.describe(s.input.as_deref(), &s.output) {
            println!("    {line}");
        }
    }
    println!("  stats on {}", p.iceoryx2.stats_service);
}

fn role(kind: &Kind) -> &'static str {
    match kind.role {
        Role::Ingest { has_input: false } => "ingest, no input",
        Role::Ingest { has_input: true } => "ingest, input from another process",
        Role::Process => "processing stage",
        Role::External => "run by another process",
        Role::Publish => "ends the chain",
    }
}

/// The stage kinds and their keys, as text or as Markdown.
pub fn kinds(markdown: bool) -> String {
    let mut out = String::new();
    let common = "`name` (unique), `kind`, `output` (a service name), and `input` where noted";
    if markdown {
        out.push_str(&format!("Every `[[stage]]` has {common}.\n"));
    } else {
        out.push_str(&format!(
            "Every [[stage]] has {}.\n",
            common.replace('`', "")
        ));
    }
    for kind in crate::stages::KINDS {
        if markdown {
            out.push_str(&format!(
                "\n**`{}`** ({}): {}.\n",
                kind.name,
                role(kind),
                kind.summary
            ));
            if kind.keys.is_empty() {
                out.push_str("\nNo keys of its own.\n");
                continue;
            }
            out.push_str("\n| key | type | default | meaning |\n|---|---|---|---|\n");
            for k in kind.keys {
                out.push_str(&format!(
                    "| `{}` | {} | {} | {} |\n",
                    k.name,
                    k.ty.describe().replace('|', "\\|"),
                    k.default,
                    k.doc
                ));
            }
        } else {
            out.push_str(&format!(
                "\n{} [{}]\n  {}\n",
                kind.name,
                role(kind),
                kind.summary
            ));
            for k in kind.keys {
                out.push_str(&format!(
                    "  {:<16} {}; default {}\n  {:<16} {}\n",
                    k.name,
                    k.ty.describe(),
                    k.default,
                    "",
                    k.doc
                ));
            }
        }
    }
    out
}
