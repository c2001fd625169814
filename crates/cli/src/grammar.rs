//! Checks of a command line's grammar (from [`crate::command`]) that each binary's tests run
//! on its own: every page of `--help` describes what it lists, each command whose target is a
//! positional (`bench contact|replay|...`) names every target in its summary, and the texts
//! are plain (no markdown escapes printed literally). Each check returns what breaks it, empty
//! when nothing does.

/// Every command below `cmd` (itself first), with its path of subcommand names.
fn commands<'a>(
    cmd: &'a clap::Command,
    path: Vec<&'a str>,
    out: &mut Vec<(Vec<&'a str>, &'a clap::Command)>,
) {
    out.push((path.clone(), cmd));
    for sub in cmd.get_subcommands() {
        let mut p = path.clone();
        p.push(sub.get_name());
        commands(sub, p, out);
    }
}

/// `<program> a b` for `path` ["a", "b"].
fn name(grammar: &clap::Command, path: &[&str]) -> String {
    std::iter::once(grammar.get_name())
        .chain(path.iter().copied())
        .collect::<Vec<_>>()
        .join(" ")
}

/// How many commands the grammar has (itself and every subcommand, recursively).
pub fn count(grammar: &clap::Command) -> usize {
    let mut all = Vec::new();
    commands(grammar, Vec::new(), &mut all);
    all.len()
}

/// Subcommands, options and positionals without a description, and values of a subcommand's
/// target (`eval contact|slip|depth`, ...) without one.
pub fn undescribed(grammar: &clap::Command) -> Vec<String> {
    let mut all = Vec::new();
    commands(grammar, Vec::new(), &mut all);
    let mut missing = Vec::new();
    for (path, cmd) in &all {
        if cmd.get_about().is_none() {
            missing.push(name(grammar, path));
        }
        for a in cmd.get_arguments() {
            let id = a.get_id().as_str();
            if id == "help" || id == "version" {
                continue;
            }
            let shown = match a.get_long() {
                Some(l) => format!("--{l}"),
                None => format!("<{}>", id.to_uppercase()),
            };
            if a.get_help().is_none() && a.get_long_help().is_none() {
                missing.push(format!("{} {shown}", name(grammar, path)));
            }
            if a.is_positional() && id == "what" {
                for v in a.get_possible_values() {
                    if v.get_help().is_none() {
                        missing.push(format!("{} {}", name(grammar, path), v.get_name()));
                    }
                }
            }
        }
    }
    missing
}

/// `<command> <target>` for each target of a command (a positional `what`) that its summary
/// does not name.
pub fn targets_not_in_summaries(grammar: &clap::Command) -> Vec<String> {
    let mut all = Vec::new();
    commands(grammar, Vec::new(), &mut all);
    let mut missing = Vec::new();
    for (path, cmd) in &all {
        let about = cmd.get_about().map(|s| s.to_string()).unwrap_or_default();
        let Some(last) = path.last() else { continue };
        for a in cmd
            .get_arguments()
            .filter(|a| a.is_positional() && a.get_id() == "what")
        {
            for v in a.get_possible_values() {
                let want = format!("{last} {}", v.get_name());
                if !about.contains(&want) {
                    missing.push(want);
                }
            }
        }
    }
    missing
}

/// Help texts with a backslash (a markdown escape such as `\[mm]` that clap prints literally),
/// each as `<command>: <text>`.
pub fn escaped_texts(grammar: &clap::Command) -> Vec<String> {
    let mut all = Vec::new();
    commands(grammar, Vec::new(), &mut all);
    let mut found = Vec::new();
    for (path, cmd) in &all {
        let mut texts: Vec<String> = cmd.get_about().iter().map(|s| s.to_string()).collect();
        texts.extend(cmd.get_long_about().map(|s| s.to_string()));
        for a in cmd.get_arguments() {
            texts.extend(a.get_help().map(|s| s.to_string()));
            texts.extend(a.get_long_help().map(|s| s.to_string()));
        }
        for t in texts {
            if t.contains('\\') {
                found.push(format!("{}: {t}", name(grammar, path)));
            }
        }
    }
    found
}
