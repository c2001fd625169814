//! The layering rule of every crate, as its README states it, against the dependency graph the
//! crate has when built on its own (`cargo tree -p <crate>`; the members from `cargo metadata`).
//!
//! Each crate README has exactly one line of the form
//!
//! ```text
//! Must not depend on (checked by crates/cli/tests/layering.rs): r2r, ort, unitac-contact.
//! ```
//!
//! naming workspace crates and external crates. A crate breaks its rule when one of them is among
//! its normal or build dependencies, directly or through other crates (dev-dependencies do not
//! count: tests may use the mock sensor). Adding a crate or changing a rule is an edit of that
//! README line only.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const PREFIX: &str = "Must not depend on (checked by crates/cli/tests/layering.rs):";

/// A crate's forbidden dependencies, by package name.
type Rules = BTreeMap<String, BTreeSet<String>>;
/// Normal and build dependencies of each package, by name (one version per name is enough here).
type Graph = BTreeMap<String, BTreeSet<String>>;

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// This machine's target triple: the members are listed for it only (other platforms' crates
/// are not downloaded, and the test runs without network).
fn host() -> String {
    let out = std::process::Command::new("rustc")
        .arg("-vV")
        .output()
        .expect("rustc -vV runs");
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .find_map(|l| l.strip_prefix("host: "))
        .expect("rustc -vV names the host")
        .to_string()
}

/// `cargo ARGS --offline --locked` in the workspace root: its stdout (a failure fails the test).
fn cargo(args: &[&str]) -> Vec<u8> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let out = std::process::Command::new(cargo)
        .args(args)
        .args(["--offline", "--locked"])
        .current_dir(workspace_root())
        .output()
        .expect("cargo runs");
    assert!(
        out.status.success(),
        "cargo {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

fn metadata() -> Value {
    let out = cargo(&[
        "metadata",
        "--format-version",
        "1",
        "--filter-platform",
        &host(),
    ]);
    serde_json::from_slice(&out).expect("cargo metadata prints JSON")
}

/// Package names of the workspace members, with their manifest directories.
fn members(meta: &Value) -> BTreeMap<String, PathBuf> {
    let ids: BTreeSet<&str> = meta["workspace_members"]
        .as_array()
        .expect("workspace_members")
        .iter()
        .filter_map(Value::as_str)
        .collect();
    meta["packages"]
        .as_array()
        .expect("packages")
        .iter()
        .filter(|p| p["id"].as_str().is_some_and(|id| ids.contains(id)))
        .map(|p| {
            let manifest = PathBuf::from(p["manifest_path"].as_str().expect("manifest_path"));
            let dir = manifest.parent().expect("manifest dir").to_path_buf();
            (p["name"].as_str().expect("name").to_string(), dir)
        })
        .collect()
}

/// The dependency graph of `krate` built on its own (features resolved as `cargo build -p
/// krate` resolves them, for this machine), by package name, without dev-dependency edges: a
/// feature another workspace crate turns on (the pipeline's `v4l` for the binaries) does not
/// count against a crate that leaves it off.
fn graph(krate: &str) -> Graph {
    let out = cargo(&[
        "tree",
        "-p",
        krate,
        "-e",
        "normal,build",
        "--prefix",
        "depth",
        "-f",
        "{p}",
    ]);
    parse_tree(&String::from_utf8_lossy(&out))
}

/// `cargo tree --prefix depth -f {p}` lines (`<depth><name> v<version> ...`) as a graph.
fn parse_tree(text: &str) -> Graph {
    let mut g = Graph::new();
    let mut stack: Vec<String> = Vec::new();
    for line in text.lines() {
        let digits = line.chars().take_while(char::is_ascii_digit).count();
        let Ok(depth) = line[..digits].parse::<usize>() else {
            continue;
        };
        let Some(name) = line[digits..].split_whitespace().next() else {
            continue;
        };
        stack.truncate(depth);
        if let Some(parent) = stack.last() {
            g.entry(parent.clone())
                .or_default()
                .insert(name.to_string());
        }
        g.entry(name.to_string()).or_default();
        stack.push(name.to_string());
    }
    g
}

/// The names listed on the README's rule line; an error unless there is exactly one such line.
fn parse_rule(readme: &str) -> Result<BTreeSet<String>, String> {
    let lines: Vec<&str> = readme
        .lines()
        .filter_map(|l| l.trim().strip_prefix(PREFIX))
        .collect();
    let [line] = lines[..] else {
        return Err(format!(
            "{} lines start with '{PREFIX}' (want exactly one)",
            lines.len()
        ));
    };
    let names: BTreeSet<String> = line
        .trim()
        .trim_end_matches('.')
        .split(',')
        .map(|n| n.trim().trim_matches('`').to_string())
        .filter(|n| !n.is_empty())
        .collect();
    if names.is_empty() {
        return Err("the rule line lists nothing".into());
    }
    Ok(names)
}

/// Every (crate, forbidden dependency, path to it) where a crate breaks its rule.
fn violations(g: &Graph, rules: &Rules) -> Vec<String> {
    let mut out = Vec::new();
    for (krate, forbidden) in rules {
        // Breadth-first over normal/build edges, remembering how each crate was reached.
        let mut via: BTreeMap<&str, &str> = BTreeMap::new();
        let mut queue = vec![krate.as_str()];
        while let Some(c) = queue.pop() {
            for d in g.get(c).into_iter().flatten() {
                if d != krate && !via.contains_key(d.as_str()) {
                    via.insert(d, c);
                    queue.push(d);
                }
            }
        }
        for f in forbidden {
            if via.contains_key(f.as_str()) {
                let mut path = vec![f.as_str()];
                while let Some(&p) = via.get(path[path.len() - 1]) {
                    path.push(p);
                    if p == krate {
                        break;
                    }
                }
                path.reverse();
                out.push(format!("{krate} depends on {f}: {}", path.join(" -> ")));
            }
        }
    }
    out
}

#[test]
fn every_crate_keeps_the_dependency_rule_of_its_readme() {
    let meta = metadata();
    let members = members(&meta);
    let mut rules = Rules::new();
    let mut problems = Vec::new();
    for (name, dir) in &members {
        let readme = dir.join("README.md");
        let text = std::fs::read_to_string(&readme)
            .unwrap_or_else(|e| panic!("{name}: no README ({}): {e}", readme.display()));
        match parse_rule(&text) {
            Ok(r) => {
                for n in &r {
                    if n.starts_with("unitac-") && !members.contains_key(n) {
                        problems.push(format!("{name}: README names {n}, not a workspace crate"));
                    }
                    if n == name {
                        problems.push(format!("{name}: README forbids the crate itself"));
                    }
                }
                rules.insert(name.clone(), r);
            }
            Err(e) => problems.push(format!("{}: {e}", readme.display())),
        }
    }
    for (krate, forbidden) in &rules {
        let one = Rules::from([(krate.clone(), forbidden.clone())]);
        problems.extend(violations(&graph(krate), &one));
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    // The rules were read: every workspace crate has one.
    assert_eq!(rules.len(), members.len());
}

#[test]
fn a_forbidden_dependency_through_another_crate_is_found() {
    let mut g = Graph::new();
    g.insert("a".into(), ["b".to_string()].into());
    g.insert("b".into(), ["c".to_string()].into());
    g.insert("c".into(), BTreeSet::new());
    let mut rules = Rules::new();
    rules.insert("a".into(), ["c".to_string()].into());
    rules.insert("b".into(), ["a".to_string()].into());
    assert_eq!(violations(&g, &rules), ["a depends on c: a -> b -> c"]);
}

#[test]
fn a_cargo_tree_listing_becomes_the_graph_it_draws() {
    let g = parse_tree("0a v0.1.0 (/x)\n1b v1.0.0\n2c v1.0.0\n1d v2.0.0\n2c v1.0.0 (*)\n");
    assert_eq!(g["a"], ["b", "d"].map(String::from).into());
    assert_eq!(g["b"], ["c"].map(String::from).into());
    assert_eq!(g["d"], ["c"].map(String::from).into());
    assert!(g["c"].is_empty());
}

#[test]
fn the_rule_line_is_parsed_and_must_be_unique() {
    let one = format!("# x\n\n{PREFIX} r2r, `ort`, unitac-contact.\n");
    assert_eq!(
        parse_rule(&one).unwrap(),
        ["ort", "r2r", "unitac-contact"]
            .map(String::from)
            .into_iter()
            .collect::<BTreeSet<_>>()
    );
    assert!(parse_rule("# x\nMust not depend on ROS.\n").is_err());
    assert!(parse_rule(&format!("{one}{one}")).is_err());
    assert!(parse_rule(&format!("{PREFIX} .\n")).is_err());
}
