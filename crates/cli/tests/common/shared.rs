//! What the tests of both command-line binaries do, on a binary given by its path: `unitac`'s
//! (crates/cli/tests) and `unitac-lab`'s (crates/lab/tests, which include this file): a run
//! killed after a time limit, the help pages and the commands they list, the exit-code contract
//! of crates/cli/README.md for a bad value per command, and a shipped scene copied under a new
//! name.
#![allow(dead_code)]

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The workspace root (both binaries' crates are two levels below it).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `exe args` with the environment variables `env` set, killed after `limit` (a hang is a
/// failure, not a stuck test).
pub fn run_within(exe: &str, args: &[&str], env: &[(&str, &str)], limit: Duration) -> Output {
    let mut child = Command::new(exe)
        .args(args)
        .envs(env.iter().copied())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            let o = child.wait_with_output().unwrap();
            panic!(
                "{exe} {args:?} still ran after {limit:?}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

/// The lines of a help page's section (`Commands`, `Arguments`, ...), up to the blank line that
/// ends it; none where the page has no such section.
pub fn help_section<'a>(help: &'a str, title: &str) -> impl Iterator<Item = &'a str> {
    help.split_once(&format!("{title}:\n"))
        .map(|(_, rest)| rest.lines().take_while(|l| !l.trim().is_empty()))
        .into_iter()
        .flatten()
}

/// The subcommands a help page lists under `Commands:` (without `help`).
pub fn help_commands(help: &str) -> Vec<String> {
    help_section(help, "Commands")
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(String::from)
        .collect()
}

/// `exe <path> <flag>` (`--help` or `-h`): the page, which must come with exit 0.
pub fn help(exe: &str, path: &[String], flag: &str) -> String {
    let o = Command::new(exe)
        .args(path)
        .arg(flag)
        .env("RUST_LOG", "warn")
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{exe} {path:?} {flag}");
    String::from_utf8(o.stdout).unwrap()
}

/// Every `--help` page of `exe` below `path`, with its path; each in plain text (no markdown
/// escapes such as `\[mm]` printed literally).
pub fn help_pages(exe: &str, path: Vec<String>, out: &mut Vec<(Vec<String>, String)>) {
    let text = help(exe, &path, "--help");
    assert!(!text.contains("\\["), "{exe} {path:?} --help: {text}");
    assert!(!text.contains("\\]"), "{exe} {path:?} --help: {text}");
    let subs = help_commands(&text);
    out.push((path.clone(), text));
    for s in subs {
        let mut p = path.clone();
        p.push(s);
        help_pages(exe, p, out);
    }
}

/// The values of a target positional (`[possible values: a, b]` in the short help).
fn targets(short_help: &str) -> Vec<String> {
    help_section(short_help, "Arguments")
        .filter_map(|l| l.split_once("[possible values: "))
        .flat_map(|(_, v)| {
            v.trim_end()
                .trim_end_matches(']')
                .split(", ")
                .map(String::from)
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Every command the help pages of `exe` list, down to the leaves, each leaf with its targets
/// (`bench contact`, ...).
pub fn commands(exe: &str, path: Vec<String>, out: &mut BTreeSet<String>) {
    let subs = help_commands(&help(exe, &path, "--help"));
    if subs.is_empty() {
        let t = targets(&help(exe, &path, "-h"));
        if t.is_empty() {
            out.insert(path.join(" "));
        }
        for v in t {
            out.insert(format!("{} {v}", path.join(" ")));
        }
    }
    for s in subs {
        let mut p = path.clone();
        p.push(s);
        commands(exe, p, out);
    }
}

/// How long a bad value may take to be refused (it is refused before any work).
const LIMIT: Duration = Duration::from_secs(60);

/// Run `exe args`, killed after [`LIMIT`]: (exit code, stderr, how long it took).
fn run_limited(exe: &str, args: &[String]) -> (Option<i32>, String, Duration) {
    let t0 = Instant::now();
    let mut child = Command::new(exe)
        .args(args)
        .env("RUST_LOG", "warn")
        .env_remove("UNITAC_SYSFS_ROOT")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let code = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s.code();
        }
        if t0.elapsed() > LIMIT {
            child.kill().unwrap();
            child.wait().unwrap();
            panic!("{args:?}: still running after {LIMIT:?} (a bad value is refused at once)");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    (code, err, t0.elapsed())
}

/// The exit-code table of crates/cli/README.md for every command of `exe` (named `program`):
/// `cases` has one bad value per command the help pages list (the command as [`commands`] names
/// it, and the arguments after the program; `{tmp}` is a fresh directory), and each must end at
/// once with exit 2 and one line on stderr starting `<program>: `, no panic.
pub fn every_command_refuses_a_bad_value(exe: &str, program: &str, cases: &[(&str, &[&str])]) {
    let mut found = BTreeSet::new();
    commands(exe, Vec::new(), &mut found);
    assert!(found.len() > 5, "{found:?}");
    let covered: BTreeSet<String> = cases.iter().map(|(n, _)| n.to_string()).collect();
    let untested: Vec<_> = found.difference(&covered).collect();
    assert!(
        untested.is_empty(),
        "commands without a bad-value case: {untested:?}"
    );
    let stale: Vec<_> = covered.difference(&found).collect();
    assert!(
        stale.is_empty(),
        "cases of commands the help does not list: {stale:?}"
    );

    let d = std::env::temp_dir().join(format!("{program}-exit-codes-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let mut failures = Vec::new();
    for (_, case) in cases {
        let args: Vec<String> = case
            .iter()
            .map(|a| a.replace("{tmp}", d.to_str().unwrap()))
            .collect();
        let (code, err, took) = run_limited(exe, &args);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert_ne!(code, Some(101), "{args:?}: {err}");
        let lines: Vec<&str> = err.trim_end().lines().collect();
        let ok = code == Some(2)
            && lines.len() == 1
            && lines[0].starts_with(&format!("{program}: "))
            && !lines[0].starts_with(&format!("{program}: warning:"));
        if !ok {
            failures.push(format!("{args:?}: exit {code:?} in {took:?}: {err}"));
        }
    }
    std::fs::remove_dir_all(&d).ok();
    assert!(failures.is_empty(), "{failures:#?}");
}

/// `launch/scenes/<from>.yaml` as `<dir>/<to>.yaml`, its `scene:` renamed.
pub fn copy_scene(dir: &Path, from: &str, to: &str) {
    let text = std::fs::read_to_string(root().join(format!("launch/scenes/{from}.yaml"))).unwrap();
    let renamed = text.replace(&format!("scene: {from}\n"), &format!("scene: {to}\n"));
    assert_ne!(renamed, text, "{from}");
    std::fs::write(dir.join(format!("{to}.yaml")), renamed).unwrap();
}
