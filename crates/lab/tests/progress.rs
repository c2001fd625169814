//! Long commands show progress on a terminal and print nothing extra when piped.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::process::Command;

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-progress-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

const ARGS: [&str; 6] = ["dataset", "fabrics", "--train", "3", "--test", "1"];

#[test]
fn dataset_is_quiet_when_piped() {
    let dir = out_dir("piped");
    let out = Command::new(env!("CARGO_BIN_EXE_unitac-lab"))
        .args(ARGS)
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    assert_eq!(String::from_utf8_lossy(&out.stderr), "");
    assert_eq!(String::from_utf8_lossy(&out.stdout), "");
    let labels = std::fs::read_to_string(dir.join("labels.jsonl")).unwrap();
    assert_eq!(labels.lines().count(), 4);
    std::fs::remove_dir_all(&dir).ok();
}

/// Under a pseudo-terminal (util-linux `script`) the same command draws its bar.
#[test]
fn dataset_shows_a_bar_on_a_terminal() {
    let dir = out_dir("tty");
    let cmd = format!(
        "'{}' {} --out '{}'",
        env!("CARGO_BIN_EXE_unitac-lab"),
        ARGS.join(" "),
        dir.display()
    );
    let out = Command::new("script")
        .args(["-qec", &cmd, "/dev/null"])
        .env("TERM", "xterm")
        .output()
        .expect("util-linux `script` is installed");
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("fabrics [") && text.contains("4/4"),
        "{text:?}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
