//! Hostile input at the lab's command line: closed and full stdout, numbers out of range. The
//! same rules as `unitac`'s (crates/cli/tests/hostile.rs): exit 1 or 2, one line on stderr
//! starting `unitac-lab:`, never a panic, nothing written.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::process::{Command, Output, Stdio};

mod common;
use common::unitac_lab;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-lab-hostile-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Exit `code`, exactly one line on stderr starting `unitac-lab: ` and containing `needle`, no
/// panic.
fn assert_one_line(o: &Output, code: i32, needle: &str) {
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(code), "stderr: {e}");
    assert_eq!(e.trim_end().lines().count(), 1, "one line: {e}");
    assert!(e.starts_with("unitac-lab: "), "{e}");
    assert!(e.contains(needle), "expected '{needle}' in: {e}");
    assert!(!e.contains("panicked"), "{e}");
}

/// One cup trial of the VLA mode (no model to load): a few lines on stdout.
const TRIAL: [&str; 7] = [
    "trials",
    "--scene",
    "cup_deformation",
    "--modes",
    "vla",
    "--trials",
    "1",
];

#[test]
fn closed_or_full_stdout_is_exit_1_one_line() {
    // The reader is gone before the first write (its end of the pipe closed before the child
    // starts).
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = Command::new(common::EXE)
        .args(TRIAL)
        .env("RUST_LOG", "warn")
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert_one_line(&o, 1, "writing to stdout");
    let o = Command::new(common::EXE)
        .args(TRIAL)
        .arg("--json")
        .env("RUST_LOG", "warn")
        .stdout(std::fs::File::create("/dev/full").unwrap())
        .output()
        .unwrap();
    assert_one_line(&o, 1, "No space left on device");
}

/// Numbers out of range are refused (exit 2, one line naming the flag and its inclusive
/// range), never clamped or replaced by a default; bad values of `dataset fabrics` are exit 2
/// like everywhere else, before anything is written.
#[test]
fn numbers_out_of_range_are_refused_not_clamped() {
    for (args, needle) in [
        (
            &["eval", "contact", "--idle-minutes", "NaN"][..],
            "--idle-minutes <IDLE_MINUTES>': NaN is outside 0 to 600 (inclusive)",
        ),
        (
            &["eval", "contact", "--idle-minutes", "1e12"],
            "1000000000000 is outside 0 to 600 (inclusive)",
        ),
        (
            &["bench", "contact", "--frames", "0"],
            "--frames <FRAMES>': 0 is outside 1 to 10000 (inclusive)",
        ),
        (
            &["bench", "contact", "--repeat", "0"],
            "--repeat <REPEAT>': 0 is outside 1 to 1000 (inclusive)",
        ),
        (
            &["report", "sampler", "--repeat", "0"],
            "0 is outside 1 to 1000",
        ),
    ] {
        assert_one_line(&unitac_lab(args), 2, needle);
    }
    let d = tmpdir("bad-values");
    let ds = d.join("ds");
    assert_one_line(
        &unitac_lab(&[
            "dataset",
            "fabrics",
            "--train",
            "0",
            "--test",
            "0",
            "--out",
            ds.to_str().unwrap(),
        ]),
        2,
        "--train 0 + --test 0 is 0; 1 to 100000 (inclusive)",
    );
    assert!(!ds.exists(), "nothing written");
    std::fs::remove_dir_all(&d).ok();
}
