//! The docs book's CLI reference (docs/src/reference/cli.md) is generated from the clap definitions:
//! the help of `tissuefit` and of every subcommand, as `--help` prints it. An option added, removed
//! or re-documented without regenerating the file fails here. `TISSUEFIT_BLESS=1` regenerates it.

use crate::support::generated;

use clap::CommandFactory;
use std::fmt::Write;

/// The Markdown CLI reference: a heading and what `--help` prints for `tissuefit` and every
/// subcommand, depth first in the order `tissuefit --help` lists them. The text comes from the binary
/// itself (clap decides there between its short and long layout); the library's command tree only
/// says which commands exist.
fn cli_reference() -> String {
    let mut out = String::from(
        "# CLI reference\n\n\
         Generated from the command-line definitions (clap) by `tests/integration/cli_reference.rs`: the output of\n\
         `tissuefit --help` and of `tissuefit COMMAND --help` for every command. A test fails while this\n\
         file differs from the code; regenerate it with\n\
         `TISSUEFIT_BLESS=1 cargo test --release --test integration cli_reference::`. The guide explains the commands\n\
         stage by stage; [Commands at a glance](commands.md) lists them on one page.\n\n\
         Exit codes of every command: 0 success; 1 completed but a check failed (an invalid cell, an\n\
         unconverged relaxation or fit, a missed `[demo]` truth, a failed sweep run); 2 error (unreadable\n\
         file, bad config, …) with a message naming the file and the problem; 130 interrupted after\n\
         saving a checkpoint.\n\n",
    );
    write_command(&mut out, &tissuefit::cli::Cli::command(), &[]);
    out
}

fn write_command(out: &mut String, command: &clap::Command, path: &[&str]) {
    let help = std::process::Command::new(env!("CARGO_BIN_EXE_tissuefit"))
        .args(path)
        .arg("--help")
        .env_remove("RUST_LOG")
        .output()
        .expect("running the tissuefit binary");
    let name = std::iter::once("tissuefit").chain(path.iter().copied()).collect::<Vec<_>>().join(" ");
    assert!(help.status.success(), "`{name} --help` failed: {}", String::from_utf8_lossy(&help.stderr));
    let text = String::from_utf8(help.stdout).expect("help is UTF-8");
    let _ = writeln!(out, "## `{name}`\n\n```text\n{}\n```\n", text.trim_end());
    for sub in command.get_subcommands().filter(|s| s.get_name() != "help") {
        let sub_path: Vec<&str> = path.iter().copied().chain(std::iter::once(sub.get_name())).collect();
        write_command(out, sub, &sub_path);
    }
}

#[test]
fn the_committed_cli_reference_is_the_generated_one() {
    generated::check_generated_file("docs/src/reference/cli.md", &cli_reference(), "cli_reference");
}

#[test]
fn the_cli_reference_covers_every_subcommand_with_its_options() {
    let reference = cli_reference();
    let cli = tissuefit::cli::Cli::command();
    for sub in cli.get_subcommands().filter(|s| s.get_name() != "help") {
        let heading = format!("## `tissuefit {}`", sub.get_name());
        assert!(reference.contains(&heading), "no section {heading}");
        for arg in sub.get_arguments().filter_map(|a| a.get_long()) {
            assert!(reference.contains(&format!("--{arg}")), "tissuefit {}: option --{arg} missing", sub.get_name());
        }
    }
    // The global options reach the subcommands' help, as the binary prints it.
    let simulate = reference.split("## `tissuefit simulate`").nth(1).expect("simulate section");
    assert!(simulate.contains("--threads"), "global --threads missing from `tissuefit simulate --help`");
    assert!(simulate.contains("Usage: tissuefit simulate"), "usage line of simulate lacks the full command name");
}
