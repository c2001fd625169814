//! What the command-line binaries share: `unitac` (the robot's commands, this package's binary)
//! and `unitac-lab` (the lab's: evaluations, benchmarks, reports, datasets, demonstrations,
//! trials; crates/lab).
//!
//! - the grammar's parse ([`command`], [`parse`]) and the one stderr line of a usage error
//!   ([`clap_error_line`]);
//! - the exit codes of crates/cli/README.md ("Exit codes"): [`ConfigError`] for exit 2,
//!   [`exit_code`] for the end of a command;
//! - stdout that fails cleanly ([`emit`], [`emit_report`]);
//! - the numeric flags' ranges and the forms of the stderr lines ([`args`]);
//! - the mock gel the depth commands press balls into ([`mock`]);
//! - the checks of a grammar's descriptions that each binary's tests run ([`grammar`]).
//!
//! Every line on stderr starts with the program's name ([`program`]): `unitac: ...`,
//! `unitac-lab: ...`.

pub mod args;
pub mod grammar;
pub mod mock;

use anyhow::Context;
use std::io::Write;
use std::process::ExitCode;
use std::sync::OnceLock;

/// The running binary's name, as its grammar names it ([`parse`] sets it).
static PROGRAM: OnceLock<String> = OnceLock::new();

/// The running binary's name (`unitac`, `unitac-lab`): the start of each of its stderr lines.
/// `unitac` until [`parse`] has read a grammar.
pub fn program() -> &'static str {
    PROGRAM.get().map_or("unitac", String::as_str)
}

/// Error that maps to exit code 2 (usage / configuration).
#[derive(Debug)]
pub struct ConfigError(pub String);

impl std::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ConfigError {}

/// Log lines (`RUST_LOG`, default `warn`) on stderr, coloured only on a terminal.
pub fn init_logging() {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
}

/// The command line's grammar of `T`, with a negative number taken as the value of a flag that
/// takes one (`--ball-radius-m -1` is refused by the flag's range, not read as a flag).
pub fn command<T: clap::CommandFactory>() -> clap::Command {
    fn negatives(c: clap::Command) -> clap::Command {
        c.mut_args(|a| {
            if a.get_action().takes_values() {
                a.allow_negative_numbers(true)
            } else {
                a
            }
        })
        .mut_subcommands(negatives)
    }
    negatives(T::command())
}

/// The process's arguments read by `grammar` (from [`command`]). Help and version are printed
/// on stdout (`Err` exit 0); a usage error is one line on stderr ([`clap_error_line`], `Err`
/// exit 2). Sets [`program`] to the grammar's name.
pub fn parse<T: clap::FromArgMatches>(grammar: clap::Command) -> Result<T, ExitCode> {
    let _ = PROGRAM.set(grammar.get_name().to_string());
    let parsed = grammar
        .clone()
        .try_get_matches()
        .and_then(|mut m| T::from_arg_matches_mut(&mut m));
    match parsed {
        Ok(c) => Ok(c),
        // Help and version: on stdout, exit 0.
        Err(e) if !e.use_stderr() => {
            let _ = e.print();
            Err(ExitCode::SUCCESS)
        }
        Err(e) => {
            eprintln!("{}", clap_error_line(&grammar, &e));
            Err(ExitCode::from(2))
        }
    }
}

/// A clap error as the one stderr line of exit 2: the program's name (`unitac: `) and clap's
/// message (its paragraphs joined), without the usage and the `--help` hint; a missing
/// subcommand names the ones there are. `grammar` is the command line's (from [`command`]).
pub fn clap_error_line(grammar: &clap::Command, e: &clap::Error) -> String {
    let text = e.render().to_string();
    let program = grammar.get_name();
    // The command's path: the leading arguments that name subcommands (`unitac calibrate depth`).
    let mut cmd = program.to_string();
    let mut at = grammar.clone();
    for a in std::env::args_os().skip(1) {
        let Some(sub) = a.to_str().and_then(|a| at.find_subcommand(a)).cloned() else {
            break;
        };
        cmd = format!("{cmd} {}", sub.get_name());
        at = sub;
    }
    if e.kind() == clap::error::ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
        let commands: Vec<&str> = text
            .split("\n\n")
            .find_map(|p| p.strip_prefix("Commands:"))
            .unwrap_or("")
            .lines()
            .filter_map(|l| l.split_whitespace().next())
            .filter(|c| *c != "help")
            .collect();
        return format!(
            "{program}: {cmd} needs a subcommand: {} (see {cmd} --help)",
            commands.join(", ")
        );
    }
    let parts: Vec<String> = text
        .split("\n\n")
        .map(str::trim)
        .filter(|p| !p.is_empty() && !p.starts_with("Usage:") && !p.starts_with("For more"))
        .map(|p| {
            let p = p.strip_prefix("error: ").unwrap_or(p);
            p.split_whitespace().collect::<Vec<_>>().join(" ")
        })
        .collect();
    let what = parts.join("; ");
    let what = if what.is_empty() {
        "bad usage".into()
    } else {
        what
    };
    format!("{program}: {what} (see {cmd} --help)")
}

/// Write to stdout and flush: a closed pipe (`| head`) or a full disk is an error (exit 1, one
/// line), never a panic as `print!` would give.
pub fn emit(text: impl std::fmt::Display) -> anyhow::Result<()> {
    let mut o = std::io::stdout().lock();
    write!(o, "{text}")
        .and_then(|()| o.flush())
        .context("writing to stdout")
}

/// A report on stdout: its JSON on one line with `--json`, else its text.
pub fn emit_report<R: serde::Serialize>(
    r: anyhow::Result<R>,
    json: bool,
    text: impl FnOnce(&R) -> String,
) -> anyhow::Result<bool> {
    let r = r?;
    if json {
        emit(format_args!("{}\n", serde_json::to_string(&r)?))?;
    } else {
        emit(text(&r))?;
    }
    Ok(true)
}

/// The exit code of a command that returned `r` (Ok(false): it ran but something in it failed):
/// 0 for Ok(true), `failed` for Ok(false), 2 for a [`ConfigError`], 1 for any other error; an
/// error's reason is one line on stderr, `<program>: <reason>`.
pub fn exit_code(r: anyhow::Result<bool>, failed: u8) -> ExitCode {
    match r {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(failed),
        Err(e) if e.downcast_ref::<ConfigError>().is_some() => {
            eprintln!("{}: {e}", program());
            ExitCode::from(2)
        }
        Err(e) => {
            eprintln!("{}: {e:#}", program());
            ExitCode::from(1)
        }
    }
}
