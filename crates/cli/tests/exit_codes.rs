//! The exit-code table of crates/cli/README.md for every subcommand: each command `unitac --help`
//! lists (and each of theirs, recursively, and each value of a target positional such as
//! `bench contact|replay|...`) is run with a bad value (an out-of-range number, NaN, a missing
//! file), and must end at once with exit 2 and one line on stderr starting `unitac:`, no panic.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;

/// How long a bad value may take to be refused (it is refused before any work).
const LIMIT: Duration = Duration::from_secs(60);

/// One bad value per command: the command (its subcommand path and target, as the walk names
/// it) and the arguments after `unitac`. `{tmp}` is a fresh directory.
const CASES: &[(&str, &[&str])] = &[
    (
        "run",
        &["run", "--scene", "cup_deformation_vla", "--max-frames", "0"],
    ),
    (
        "contact",
        &[
            "contact",
            "--sensor",
            "gelsight-mini",
            "--background",
            "{tmp}/missing.png",
            "{tmp}/f.png",
        ],
    ),
    ("replay", &["replay", "{tmp}/missing_bag", "--rate", "NaN"]),
    (
        "bag repair",
        &["bag", "repair", "{tmp}/missing_bag", "{tmp}/out_bag"],
    ),
    (
        "calibrate depth",
        &[
            "calibrate",
            "depth",
            "--sensor",
            "gelsight-mini",
            "--ball-radius-m",
            "NaN",
            "--background",
            "{tmp}/bg.png",
            "--out",
            "{tmp}/cal.json",
            "{tmp}/p.png",
        ],
    ),
    (
        "calibrate mock-presses",
        &[
            "calibrate",
            "mock-presses",
            "--noise-dn",
            "NaN",
            "--out",
            "{tmp}/mock",
        ],
    ),
    (
        "eval contact",
        &["eval", "contact", "--idle-minutes", "1e12"],
    ),
    ("eval slip", &["eval", "slip", "--idle-minutes", "NaN"]),
    ("eval depth", &["eval", "depth", "--out", "/dev/null/depth"]),
    ("bench contact", &["bench", "contact", "--frames", "0"]),
    ("bench replay", &["bench", "replay", "--repeat", "0"]),
    ("bench sampler", &["bench", "sampler", "--repeat", "NaN"]),
    ("bench render", &["bench", "render", "--repeat", "1001"]),
    ("bench decode", &["bench", "decode", "--frames", "-3"]),
    ("bench policy", &["bench", "policy", "--repeat", "0"]),
    (
        "bench policy",
        &[
            "bench",
            "policy",
            "--no-python",
            "--policy",
            "{tmp}/missing_policy",
        ],
    ),
    ("bench depth", &["bench", "depth", "--frames", "1e9"]),
    ("report sampler", &["report", "sampler", "--repeat", "0"]),
    (
        "report sim",
        &["report", "sim", "--out", "/dev/null/report"],
    ),
    (
        "dataset fabrics",
        &[
            "dataset", "fabrics", "--train", "0", "--test", "0", "--out", "{tmp}/ds",
        ],
    ),
    (
        "dataset touch",
        &["dataset", "touch", "--trials", "0", "--out", "{tmp}/ds"],
    ),
    (
        "demos",
        &[
            "demos",
            "--scene",
            "cup_deformation_vla",
            "--trials",
            "NaN",
            "--out",
            "{tmp}/demos",
        ],
    ),
    ("devices", &["devices", "--json=maybe"]),
    (
        "gripper activate",
        &[
            "gripper",
            "--port",
            "{tmp}/missing_tty",
            "--model",
            "robotiq_2f85",
            "activate",
        ],
    ),
    (
        "gripper open",
        &[
            "gripper",
            "--port",
            "sim",
            "--model",
            "robotiq_2f85",
            "--seconds",
            "NaN",
            "open",
        ],
    ),
    (
        "gripper close",
        &[
            "gripper",
            "--port",
            "sim",
            "--model",
            "robotiq_2f85",
            "--force",
            "-1",
            "close",
        ],
    ),
    (
        "gripper status",
        &[
            "gripper",
            "--port",
            "{tmp}/missing_tty",
            "--model",
            "robotiq_2f85",
            "status",
        ],
    ),
    (
        "gripper bench",
        &[
            "gripper",
            "--port",
            "sim",
            "--model",
            "robotiq_2f85",
            "--seconds",
            "1e12",
            "bench",
        ],
    ),
    (
        "gripper simulate",
        &[
            "gripper",
            "--port",
            "{tmp}/missing_dir/tty",
            "--model",
            "robotiq_2f85",
            "--seconds",
            "1",
            "simulate",
        ],
    ),
    (
        "trials",
        &["trials", "--scene", "cup_deformation", "--trials", "0"],
    ),
    ("scenes", &["scenes", "--scene-dir", "{tmp}/missing_dir"]),
];

fn unitac(args: &[String]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .env("RUST_LOG", "warn")
        .env_remove("UNITAC_SYSFS_ROOT")
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

/// The values of a target positional (`[possible values: a, b]` in the short help).
fn targets(short_help: &str) -> Vec<String> {
    common::help_section(short_help, "Arguments")
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

fn help(path: &[String], flag: &str) -> String {
    let mut args = path.to_vec();
    args.push(flag.into());
    let o = unitac(&args);
    assert_eq!(o.status.code(), Some(0), "{args:?}");
    String::from_utf8(o.stdout).unwrap()
}

/// Every command the help pages list, down to the leaves, each leaf with its targets.
fn walk(path: Vec<String>, out: &mut BTreeSet<String>) {
    let subs = common::help_commands(&help(&path, "--help"));
    if subs.is_empty() {
        let t = targets(&help(&path, "-h"));
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
        walk(p, out);
    }
}

/// Run `args`, killed after [`LIMIT`]: (exit code, stderr, how long it took).
fn run_limited(args: &[String]) -> (Option<i32>, String, Duration) {
    let t0 = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .env("RUST_LOG", "warn")
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

fn tmp() -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-exit-codes-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn every_subcommand_refuses_a_bad_value_with_exit_2_and_one_line() {
    let mut found = BTreeSet::new();
    walk(Vec::new(), &mut found);
    assert!(found.len() > 20, "{found:?}");
    let covered: BTreeSet<String> = CASES.iter().map(|(n, _)| n.to_string()).collect();
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

    let d = tmp();
    let mut failures = Vec::new();
    for (_, case) in CASES {
        let args: Vec<String> = case
            .iter()
            .map(|a| a.replace("{tmp}", d.to_str().unwrap()))
            .collect();
        let (code, err, took) = run_limited(&args);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert_ne!(code, Some(101), "{args:?}: {err}");
        let lines: Vec<&str> = err.trim_end().lines().collect();
        let ok = code == Some(2)
            && lines.len() == 1
            && lines[0].starts_with("unitac: ")
            && !lines[0].starts_with("unitac: warning:");
        if !ok {
            failures.push(format!("{args:?}: exit {code:?} in {took:?}: {err}"));
        }
    }
    std::fs::remove_dir_all(&d).ok();
    assert!(failures.is_empty(), "{failures:#?}");
}
