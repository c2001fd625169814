//! The help pages as printed: plain text (no markdown escapes such as `\[mm]`), and each
//! command's summary names every target it takes (`bench contact`, ..., `bench depth`).
//! (That every option has a description is checked on clap's command tree, in main.rs.)
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::Command;

mod common;

fn help(path: &[String]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(path)
        .arg("--help")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{path:?}");
    String::from_utf8(o.stdout).unwrap()
}

/// Every help page below `path`, with its path.
fn pages(path: Vec<String>, out: &mut Vec<(Vec<String>, String)>) {
    let text = help(&path);
    let subs = common::help_commands(&text);
    out.push((path.clone(), text));
    for s in subs {
        let mut p = path.clone();
        p.push(s);
        pages(p, out);
    }
}

#[test]
fn help_pages_are_plain_text_and_name_every_target() {
    let mut all = Vec::new();
    pages(Vec::new(), &mut all);
    assert!(all.len() > 15, "{} pages", all.len());
    for (path, text) in &all {
        assert!(!text.contains("\\["), "unitac {path:?} --help: {text}");
        assert!(!text.contains("\\]"), "unitac {path:?} --help: {text}");
    }
    let page = |p: &str| {
        all.iter()
            .find(|(path, _)| path.join(" ") == p)
            .map(|(_, t)| t.clone())
            .unwrap()
    };
    assert!(
        page("calibrate depth")
            .contains("Radius of the ball pressed into the gel, in m (a 4 mm ball: 0.002)")
    );
    let bench = page("bench");
    let summary = bench.split("\n\n").next().unwrap();
    for target in [
        "contact", "replay", "sampler", "render", "decode", "policy", "depth",
    ] {
        assert!(summary.contains(&format!("`bench {target}`")), "{summary}");
    }
}
