//! What an installed `driftless` brings to a shell: completions (clap_complete) that complete,
//! and manual pages (clap_mangen) that name every command.

mod common;

use common::{bin, driftless, subcommands, Dir};

#[test]
fn bash_completion_completes_commands_and_options() {
    let commands = subcommands();
    assert!(commands.len() >= 13, "{commands:?}");
    let complete = |words: &str| -> Vec<String> {
        let script = format!(
            "source <({} completions bash) && COMP_WORDS=({words}) && \
             COMP_CWORD=$((${{#COMP_WORDS[@]}} - 1)) && _driftless driftless \
             \"${{COMP_WORDS[-1]}}\" \"${{COMP_WORDS[-2]}}\" && printf '%s\\n' \"${{COMPREPLY[@]}}\"",
            bin()
        );
        let o = std::process::Command::new("bash")
            .args(["-c", &script])
            .output()
            .expect("bash");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8(o.stdout)
            .unwrap()
            .lines()
            .map(String::from)
            .collect()
    };
    assert_eq!(complete("driftless ta"), ["tap"]);
    let all = complete("driftless ''");
    for c in &commands {
        assert!(all.contains(c), "{c} not offered: {all:?}");
    }
    let tap_options = complete("driftless tap --for");
    assert_eq!(tap_options, ["--format"]);
    for shell in ["zsh", "fish", "elvish", "powershell"] {
        let o = driftless(&["completions", shell]);
        assert!(o.status.success() && !o.stdout.is_empty(), "{shell}");
    }
    assert_eq!(driftless(&["completions", "tcsh"]).status.code(), Some(2));
}

#[test]
fn man_pages_name_every_command() {
    let o = driftless(&["man"]);
    assert!(o.status.success());
    let page = String::from_utf8(o.stdout).unwrap();
    assert!(page.contains(".TH driftless 1"), "{page}");
    for c in subcommands() {
        assert!(page.contains(&c.replace('-', "\\-")), "{c} not in the page");
    }
    let dir = Dir::new();
    let o = driftless(&["man", "--dir", dir.dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for c in subcommands() {
        let file = dir.path(&format!("driftless-{c}.1"));
        let text = std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{file:?}: {e}"));
        assert!(text.contains(".SH SYNOPSIS"), "{file:?}");
    }
    let missing = driftless(&["man", "--dir", "/nonexistent/driftless-man"]);
    assert_eq!(missing.status.code(), Some(2));
}
