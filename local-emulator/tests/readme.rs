//! The README against the code: what it tells a new user to run must exist, and the numbers
//! and commands it states must be the code's.

mod common;

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

/// `--task-timeout`'s default range, in `hort render --help` and the README, is the plan's.
#[test]
fn task_timeout_help_and_readme_give_the_plans_bounds() {
    use hort_core::pipeline::{MAX_TIMEOUT_SECONDS, MIN_TIMEOUT_SECONDS, TIMEOUT_MULTIPLE};
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
