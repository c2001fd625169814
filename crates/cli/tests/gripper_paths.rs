//! `unitac gripper ... simulate` places its link at `--port` only where nothing of anyone else's
//! is: an existing file, a special file, a link to something that exists (another simulator's
//! live pty included) is refused and left as it was; a stale simulator link (to a /dev/pts/N
//! that is gone) is replaced; the link goes when the simulator ends, and nothing else is written
//! next to it.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::unitac_gripper as unitac;

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A fresh, empty directory of this test's own.
fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "unitac-gripper-paths-{name}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

fn simulate(port: &Path, seconds: &str) -> Output {
    unitac(&[
        "--port",
        port.to_str().unwrap(),
        "--model",
        "robotiq_2f85",
        "--seconds",
        seconds,
        "simulate",
    ])
}

fn spawn_simulator(port: &Path) -> Child {
    let child = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(["gripper", "--port", port.to_str().unwrap()])
        .args(["--model", "robotiq_2f85", "--seconds", "30", "simulate"])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while !port.exists() {
        assert!(t0.elapsed() < Duration::from_secs(10), "no simulator link");
        std::thread::sleep(Duration::from_millis(20));
    }
    child
}

fn refused(o: &Output, port: &Path) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.starts_with("unitac: "), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains(&port.display().to_string()), "{err}");
    assert!(err.contains("exists"), "{err}");
}

#[test]
fn simulate_refuses_a_users_file_and_leaves_its_tmp_sibling_alone() {
    let d = scratch("file");
    let port = d.join("v.txt");
    std::fs::write(&port, "A\n").unwrap();
    std::fs::write(d.join("v.tmp"), "B\n").unwrap();
    let o = simulate(&port, "1");
    refused(&o, &port);
    assert_eq!(names(&d), ["v.tmp", "v.txt"]);
    assert_eq!(std::fs::read_to_string(&port).unwrap(), "A\n");
    assert_eq!(std::fs::read_to_string(d.join("v.tmp")).unwrap(), "B\n");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn simulate_refuses_special_files_directories_and_links_to_live_things() {
    let d = scratch("special");
    // A FIFO stands in for a device node (the same rule: not a link, so never replaced).
    let fifo = d.join("fifo");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    refused(&simulate(&fifo, "1"), &fifo);
    let dir = d.join("dir");
    std::fs::create_dir(&dir).unwrap();
    refused(&simulate(&dir, "1"), &dir);
    // A link to a user's file, and a link to a character device.
    std::fs::write(d.join("data"), "C\n").unwrap();
    let to_file = d.join("to-file");
    std::os::unix::fs::symlink(d.join("data"), &to_file).unwrap();
    refused(&simulate(&to_file, "1"), &to_file);
    let to_dev = d.join("to-dev");
    std::os::unix::fs::symlink("/dev/null", &to_dev).unwrap();
    refused(&simulate(&to_dev, "1"), &to_dev);
    assert_eq!(std::fs::read_link(&to_dev).unwrap(), Path::new("/dev/null"));
    assert_eq!(std::fs::read_link(&to_file).unwrap(), d.join("data"));
    assert_eq!(std::fs::read_to_string(d.join("data")).unwrap(), "C\n");
    assert!(Path::new("/dev/null").exists());
    assert_eq!(names(&d), ["data", "dir", "fifo", "to-dev", "to-file"]);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_second_simulator_does_not_take_a_live_simulators_link() {
    let d = scratch("live");
    let port = d.join("ttyGRIPPER");
    let mut first = spawn_simulator(&port);
    let pty = std::fs::read_link(&port).unwrap();
    refused(&simulate(&port, "1"), &port);
    assert_eq!(std::fs::read_link(&port).unwrap(), pty);
    assert_eq!(names(&d), ["ttyGRIPPER"]);
    // The first simulator is still reachable through it.
    let o = unitac(&[
        "--port",
        port.to_str().unwrap(),
        "--model",
        "robotiq_2f85",
        "--seconds",
        "5",
        "status",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    first.kill().unwrap();
    let _ = first.wait();
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_stale_simulator_link_is_replaced_and_the_link_goes_at_the_end() {
    let d = scratch("stale");
    let port = d.join("ttyGRIPPER");
    // What a killed simulator leaves: a link to a pty that is gone.
    std::os::unix::fs::symlink("/dev/pts/4000000", &port).unwrap();
    let o = simulate(&port, "1");
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("-> /dev/pts/"), "{out}");
    assert!(!out.contains("4000000"), "{out}");
    // Its own link removed on exit, nothing else left behind.
    assert_eq!(names(&d), Vec::<String>::new());
    // And into an empty directory: the same.
    let o = simulate(&port, "1");
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(names(&d), Vec::<String>::new());
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_failed_start_leaves_nothing_behind() {
    let d = scratch("failed");
    // The link's directory does not exist: the port named is the problem (exit 2, one line
    // naming it), and nothing is written anywhere.
    let port = d.join("missing").join("ttyGRIPPER");
    let o = simulate(&port, "1");
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).starts_with("unitac: --port ") && stderr(&o).trim_end().lines().count() == 1,
        "{}",
        stderr(&o)
    );
    assert_eq!(names(&d), Vec::<String>::new());
    std::fs::remove_dir_all(&d).unwrap();
}
