//! `docs/cli.md`, the command-line reference, generated from the clap definitions (the same text
//! as `hort ... --help`), so that no document repeats a flag table by hand. A unit test keeps the
//! committed file equal to what this module generates; `HORT_WRITE_CLI_DOC=1 cargo test -p hort
//! --bin hort cli_reference` rewrites it.

use clap::{Arg, ArgAction, Command, CommandFactory};

/// The reference of every command and flag `hort` has (hidden ones left out), as markdown.
pub fn markdown() -> String {
    let mut out = String::from(
        "# Command-line reference\n\n\
         Generated from the command's own definitions (`local-emulator/src/cli.rs` and the \
         modules it names) by `local-emulator/src/cli_reference.rs`: the text of `hort ... \
         --help`. A test keeps this file current; `docs/ARCHITECTURE.md` section 13 has the \
         rules the flags follow.\n",
    );
    let cli = crate::cli::Cli::command();
    for sub in cli.get_subcommands().filter(|c| !c.is_hide_set()) {
        command(&mut out, "hort", sub);
    }
    out
}

/// Appends `cmd` (named `parent cmd`) and its subcommands.
fn command(out: &mut String, parent: &str, cmd: &Command) {
    let name = format!("{parent} {}", cmd.get_name());
    let subcommands: Vec<&Command> = cmd.get_subcommands().filter(|c| !c.is_hide_set()).collect();
    out.push_str(&format!("\n## `{name}`\n\n"));
    if let Some(about) = cmd.get_long_about().or(cmd.get_about()) {
        out.push_str(&format!("{}\n", one_paragraph(&about.to_string())));
    }
    let args: Vec<&Arg> = cmd
        .get_arguments()
        .filter(|a| !a.is_hide_set() && !matches!(a.get_id().as_str(), "help" | "version"))
        .collect();
    if !args.is_empty() {
        out.push_str("\n| argument | default | meaning |\n|---|---|---|\n");
        for arg in args {
            out.push_str(&format!(
                "| {} | {} | {} |\n",
                cell(&shown(arg)),
                cell(&default(arg)),
                cell(&one_paragraph(
                    &arg.get_long_help()
                        .or(arg.get_help())
                        .map(|h| h.to_string())
                        .unwrap_or_default()
                ))
            ));
        }
    }
    for sub in subcommands {
        command(out, &name, sub);
    }
}

/// How the argument is written: `SCENE`, `--width <WIDTH>`, `--monolithic`.
fn shown(arg: &Arg) -> String {
    let values = || -> String {
        match arg.get_value_names() {
            Some(names) => names
                .iter()
                .map(|n| format!("<{n}>"))
                .collect::<Vec<_>>()
                .join(" "),
            None => format!("<{}>", arg.get_id().as_str().to_uppercase()),
        }
    };
    let takes_value = !matches!(
        arg.get_action(),
        ArgAction::SetTrue | ArgAction::SetFalse | ArgAction::Count
    );
    match (arg.get_long(), arg.get_short()) {
        (None, None) => format!("`{}`", values().trim_matches(|c| c == '<' || c == '>')),
        (long, short) => {
            let flag = long
                .map(|l| format!("--{l}"))
                .or(short.map(|s| format!("-{s}")))
                .unwrap_or_default();
            if takes_value {
                format!("`{flag} {}`", values())
            } else {
                format!("`{flag}`")
            }
        }
    }
}

/// The default, the environment variable and the choices, as `--help` shows them.
fn default(arg: &Arg) -> String {
    let mut parts = Vec::new();
    let defaults: Vec<String> = arg
        .get_default_values()
        .iter()
        .map(|v| v.to_string_lossy().into_owned())
        .collect();
    if !defaults.is_empty() {
        parts.push(format!("`{}`", defaults.join(",")));
    }
    if let Some(env) = arg.get_env() {
        parts.push(format!("env `{}`", env.to_string_lossy()));
    }
    let choices: Vec<String> = arg
        .get_possible_values()
        .iter()
        .filter(|v| !v.is_hide_set())
        .map(|v| v.get_name().to_string())
        .collect();
    if !choices.is_empty() && !matches!(arg.get_action(), ArgAction::SetTrue) {
        parts.push(format!("one of {}", choices.join(", ")));
    }
    parts.join("; ")
}

/// Help text as one line: lines joined with spaces, paragraphs kept apart by a space too.
fn one_paragraph(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Text safe inside a table cell.
fn cell(text: &str) -> String {
    text.replace('|', "\\|")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `docs/cli.md` is exactly what the definitions generate.
    #[test]
    fn docs_cli_md_is_the_generated_reference() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/cli.md");
        let generated = markdown();
        if std::env::var_os("HORT_WRITE_CLI_DOC").is_some() {
            std::fs::write(&path, &generated).unwrap();
        }
        let committed = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            committed == generated,
            "docs/cli.md is not what the command's definitions generate: run \
             `HORT_WRITE_CLI_DOC=1 cargo test -p hort --bin hort cli_reference` and commit it"
        );
    }

    /// Every visible subcommand and a few flags appear, written as users type them.
    #[test]
    fn the_reference_names_every_command_and_flag() {
        let text = markdown();
        for heading in [
            "## `hort render`",
            "## `hort plan`",
            "## `hort bench faults`",
            "## `hort jobs clean`",
            "## `hort serve`",
            "## `hort scene generate`",
        ] {
            assert!(text.contains(heading), "{heading}");
        }
        for flag in ["| `--width <WIDTH>` |", "| `--monolithic` |", "| `SCENE` |"] {
            assert!(text.contains(flag), "{flag}");
        }
        assert!(
            text.contains(
                "| `--missing-textures <MISSING_TEXTURES>` | `error`; one of error, flat |"
            )
        );
    }
}
