//! The README (and .gitignore) against the code: what it tells a new user to run must exist, and the numbers
//! and commands it states must be the code's.

use crate::common;

use std::path::Path;

use common::hort;

/// The README with every run of whitespace (line breaks included) as one space, so that a
/// phrase is found wherever the text wraps.
fn readme() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../README.md");
    let text = std::fs::read_to_string(&path).expect("README.md");
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The command that installs `hort` names the folder of a package whose binary is `hort`.
#[test]
fn the_readme_says_how_to_install_hort() {
    let readme = readme();
    let command = "cargo install --locked --path ";
    let at = readme
        .find(command)
        .unwrap_or_else(|| panic!("README.md never says `{command}...`"));
    let folder = readme[at + command.len()..]
        .split([' ', '`'])
        .next()
        .unwrap();
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(folder)
        .join("Cargo.toml");
    let toml = std::fs::read_to_string(&manifest).unwrap_or_else(|e| {
        panic!(
            "README.md installs from {folder}: {}: {e}",
            manifest.display()
        )
    });
    assert!(
        toml.contains("[[bin]]\nname = \"hort\"\n"),
        "{} builds no binary named hort",
        manifest.display()
    );
    // Every later example calls the binary by that name.
    assert!(readme.contains("```sh hort "), "examples call `hort`");
}

/// `hort bench --help`'s subcommands, each named in the README as `hort bench NAME`.
#[test]
fn every_bench_subcommand_is_in_the_readme() {
    let o = hort(&["bench", "--help"]);
    assert!(o.status.success(), "{o:?}");
    let help = String::from_utf8(o.stdout).unwrap();
    let commands: Vec<&str> = help
        .split_once("Commands:\n")
        .expect("a Commands section")
        .1
        .lines()
        .take_while(|line| line.starts_with("  "))
        .filter_map(|line| line.split_whitespace().next())
        .filter(|name| *name != "help")
        .collect();
    assert!(
        commands.len() >= 6 && commands.contains(&"faults"),
        "subcommands read from the help: {commands:?}"
    );
    let readme = readme();
    let missing: Vec<&&str> = commands
        .iter()
        .filter(|name| !readme.contains(&format!("`hort bench {name}")))
        .collect();
    assert!(missing.is_empty(), "not in README.md: {missing:?}");
}

/// `--task-timeout`'s default range, in `hort render --help` and the README, is the plan's.
#[test]
fn task_timeout_help_and_readme_give_the_plans_bounds() {
    use hort_core::predict::{MAX_TIMEOUT_SECONDS, MIN_TIMEOUT_SECONDS, TIMEOUT_MULTIPLE};
    let bounds = format!("{MIN_TIMEOUT_SECONDS} to {MAX_TIMEOUT_SECONDS} s");
    let o = hort(&["render", "--help"]);
    assert!(o.status.success(), "{o:?}");
    let help = String::from_utf8(o.stdout).unwrap();
    let line = help
        .lines()
        .skip_while(|line| !line.contains("--task-timeout <"))
        .nth(1)
        .expect("--task-timeout in hort render --help");
    assert!(
        line.contains(&format!(
            "(default: {TIMEOUT_MULTIPLE} times each task's predicted time, {bounds};"
        )),
        "{line}"
    );
    let readme = readme();
    let row = readme
        .split("| `--task-timeout SECONDS` |")
        .nth(1)
        .and_then(|rest| rest.split(" |").next())
        .expect("the --task-timeout row of README.md");
    assert!(
        row.contains(&format!(
            "default: {TIMEOUT_MULTIPLE} times each task's predicted time, {bounds};"
        )),
        "{row}"
    );
}

/// What builds write is ignored by git: cargo's `target/` and `sam build`'s `.aws-sam/` (which
/// `infra/build-lambdas.sh` leaves wherever `sam` runs).
#[test]
fn the_gitignore_ignores_what_builds_write() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../.gitignore");
    let text = std::fs::read_to_string(&path).expect(".gitignore");
    let lines: Vec<&str> = text.lines().map(str::trim).collect();
    for pattern in ["/target", ".aws-sam/"] {
        assert!(
            lines.contains(&pattern),
            ".gitignore has no line {pattern:?}: {lines:?}"
        );
    }
}
