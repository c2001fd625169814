//! Every place the product writes, renames or deletes a path (crates/*/src outside their test
//! modules, both binaries' among them: crates/cli/src and crates/lab/src; the Python tools in
//! python/unitac_tools) is in the allow-list below with the reason its path is one the user
//! handed in (an --out, a --port for the simulator), or a temporary the code made itself. A new
//! write site fails this test until it is listed here with its reason, so it gets looked at: the
//! rule is that no command touches a path it was not given (crates/cli/README.md, "Paths it
//! writes").

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The calls that create, overwrite, move or delete a path.
const RUST_CALLS: &[&str] = &[
    "fs::write(",
    "File::create(",
    "File::create_new(",
    "OpenOptions",
    "rename(",
    "remove_file(",
    "remove_dir(",
    "remove_dir_all(",
    "symlink(",
    "create_dir(",
    "create_dir_all(",
    "fs::copy(",
    "hard_link(",
];
const PYTHON_CALLS: &[&str] = &[
    "os.rename(",
    "os.replace(",
    "os.remove(",
    "os.unlink(",
    "os.rmdir(",
    "shutil.rmtree(",
    "shutil.move(",
    "shutil.copy",
    "os.makedirs(",
    "os.mkdir(",
    "mkdtemp(",
    "onnx.save(",
    "np.save",
    "write_table(",
    // open(path, mode) as f
    "\"w\") as",
    "\"wb\") as",
    "\"a\") as",
];

/// (file, call, how many, why the path is the user's or the code's own temporary).
const ALLOWED: &[(&str, &str, usize, &str)] = &[
    // Bags: `--out OUT_BAG` of `unitac replay` / `unitac run`.
    (
        "crates/bag/src/write.rs",
        "create_dir_all(",
        1,
        "the output bag directory the user named (--out)",
    ),
    (
        "crates/bag/src/write.rs",
        "File::create_new(",
        1,
        "the bag's .mcap inside it, create_new: never over an existing file",
    ),
    (
        "crates/bag/src/write.rs",
        "fs::write(",
        1,
        "metadata.yaml.tmp inside the bag directory it created",
    ),
    (
        "crates/bag/src/write.rs",
        "rename(",
        1,
        "metadata.yaml.tmp -> metadata.yaml inside that directory",
    ),
    // Library writers: the caller passes the path (the CLI passes an --out).
    (
        "crates/contact/src/depth/model.rs",
        "fs::write(",
        1,
        "DepthCalibration::save(path): `unitac calibrate depth --out`",
    ),
    (
        "crates/contact/src/background.rs",
        "File::create_new(",
        1,
        "Background::save(path): <path>.<pid>.unitac-bg.tmp beside the caller's path, new (never an existing file)",
    ),
    (
        "crates/contact/src/background.rs",
        "rename(",
        1,
        "that temporary -> the caller's path",
    ),
    (
        "crates/contact/src/background.rs",
        "remove_file(",
        1,
        "that temporary, which this call created, when the write failed",
    ),
    (
        "crates/plot/src/figure.rs",
        "fs::write(",
        1,
        "Figure::save(path): a PNG at the caller's path (--out / --plot DIR)",
    ),
    // The simulated gripper's link at --port.
    (
        "crates/gripper-sim/src/device/link.rs",
        "symlink(",
        2,
        "--port of `gripper simulate`: only where nothing is, or over a stale simulator link (symlink(2) never replaces)",
    ),
    (
        "crates/gripper-sim/src/device/link.rs",
        "remove_file(",
        2,
        "a stale simulator link at --port (a symlink to a /dev/pts/ path that is gone), or its own link",
    ),
    // unitac and unitac-lab commands: each under the directory or file the user named.
    (
        "crates/cli/src/main.rs",
        "create_dir_all(",
        1,
        "--overlay DIR of `contact`",
    ),
    (
        "crates/lab/src/report_sim.rs",
        "create_dir_all(",
        1,
        "--out DIR of `report sim`",
    ),
    (
        "crates/lab/src/touch_dataset.rs",
        "create_dir_all(",
        1,
        "--out DIR of `dataset touch`",
    ),
    (
        "crates/lab/src/touch_dataset.rs",
        "fs::write(",
        1,
        "a split's file inside --out",
    ),
    (
        "crates/lab/src/sampler.rs",
        "create_dir_all(",
        1,
        "--out DIR of `report sampler`",
    ),
    (
        "crates/lab/src/trials.rs",
        "create_dir_all(",
        1,
        "--plot DIR of `trials`",
    ),
    (
        "crates/cli/src/depth.rs",
        "create_dir_all(",
        2,
        "--review DIR of `calibrate depth`, --out DIR of `calibrate mock-presses`",
    ),
    (
        "crates/cli/src/depth.rs",
        "fs::write(",
        2,
        "files inside those directories",
    ),
    (
        "crates/lab/src/depth.rs",
        "create_dir_all(",
        1,
        "--out DIR of `eval depth`",
    ),
    (
        "crates/lab/src/dataset.rs",
        "create_dir_all(",
        1,
        "--out DIR of `dataset`",
    ),
    (
        "crates/lab/src/dataset.rs",
        "File::create(",
        3,
        "clips.f32, backgrounds.f32, labels.jsonl inside --out",
    ),
    (
        "crates/lab/src/dataset.rs",
        "fs::write(",
        1,
        "meta.json inside --out",
    ),
    (
        "crates/lab/src/demos.rs",
        "create_dir_all(",
        1,
        "--out DIR of `demos`",
    ),
    (
        "crates/lab/src/demos.rs",
        "fs::write(",
        1,
        "a file inside --out",
    ),
    // Benchmarks: new scratch directories under the temporary directory (scratch.rs).
    (
        "crates/lab/src/scratch.rs",
        "create_dir(",
        1,
        "a new directory unitac-<tag>-<pid>-<n> in the temp dir (never an existing one)",
    ),
    (
        "crates/lab/src/bench.rs",
        "fs::write(",
        3,
        "frames.raw, bg.raw and the contact baseline's slope.json inside a scratch directory this run made",
    ),
    (
        "crates/lab/src/bench.rs",
        "remove_dir_all(",
        2,
        "that scratch directory when done",
    ),
    (
        "crates/lab/src/decode_bench.rs",
        "fs::write(",
        2,
        "frames inside a scratch directory this run made",
    ),
    (
        "crates/lab/src/decode_bench.rs",
        "remove_dir_all(",
        1,
        "that scratch directory when done",
    ),
    (
        "crates/lab/src/depth.rs",
        "remove_dir_all(",
        1,
        "the bench's scratch directory (bench::raw_frames_dir) when done",
    ),
    (
        "crates/lab/src/policy_bench.rs",
        "remove_dir_all(",
        1,
        "the scratch directory of a generated policy when done (only that one)",
    ),
    // The Python tools (python/unitac_tools), run by setup and by a user.
    (
        "python/unitac_tools/annotate_presses.py",
        "\"w\") as",
        1,
        "annotations.json inside SET_DIR, the real-frame set the user names",
    ),
    (
        "python/unitac_tools/generate_reference.py",
        "os.makedirs(",
        1,
        "the OUT_DIR argument",
    ),
    (
        "python/unitac_tools/generate_reference.py",
        "onnx.save(",
        1,
        "save(): each model file inside OUT_DIR (or the path a test hands it)",
    ),
    (
        "python/unitac_tools/generate_reference.py",
        "\"w\") as",
        1,
        "manifest.json inside OUT_DIR",
    ),
    (
        "python/unitac_tools/schema.py",
        "\"w\") as",
        1,
        "write_policy_manifest: manifest.json inside the out_dir its caller was handed",
    ),
    (
        "python/unitac_tools/train_policy.py",
        "os.makedirs(",
        1,
        "each policy's directory inside --out",
    ),
    (
        "python/unitac_tools/train_policy.py",
        "np.save",
        1,
        "weights.npz inside each policy's directory in --out",
    ),
    (
        "python/unitac_tools/train_policy.py",
        "\"w\") as",
        1,
        "train.json inside --out",
    ),
    (
        "python/unitac_tools/train_projector.py",
        "os.makedirs(",
        2,
        "--out, and the stiffness readout's directory inside it",
    ),
    (
        "python/unitac_tools/train_projector.py",
        "onnx.save(",
        2,
        "velocity.onnx and the readout's policy.onnx inside --out",
    ),
    (
        "python/unitac_tools/train_projector.py",
        "shutil.copy",
        1,
        "the reference encoder copied into --out",
    ),
    (
        "python/unitac_tools/train_projector.py",
        "\"w\") as",
        4,
        "check.json, manifest.json, eval.json and the readout's latents.json inside --out",
    ),
    (
        "python/unitac_tools/fit_reference_policy.py",
        "os.makedirs(",
        1,
        "the --out directory",
    ),
    (
        "python/unitac_tools/fit_reference_policy.py",
        "onnx.save(",
        1,
        "policy.onnx inside --out",
    ),
    (
        "python/unitac_tools/fit_reference_policy.py",
        "\"w\") as",
        1,
        "fit.json inside --out (its manifest.json, in the same --out, is written by python/unitac_tools/schema.py's write_policy_manifest)",
    ),
    (
        "python/unitac_tools/lerobot_dataset.py",
        "os.makedirs(",
        2,
        "the --out's parent; directories inside its own mkdtemp",
    ),
    (
        "python/unitac_tools/lerobot_dataset.py",
        "write_table(",
        1,
        "a parquet file inside its own mkdtemp",
    ),
    (
        "python/unitac_tools/lerobot_dataset.py",
        "\"w\") as",
        1,
        "a JSON file inside its own mkdtemp",
    ),
    (
        "python/unitac_tools/lerobot_dataset.py",
        "mkdtemp(",
        2,
        "unique temporaries beside --out",
    ),
    (
        "python/unitac_tools/lerobot_dataset.py",
        "os.rename(",
        3,
        "--out (only an empty directory or a dataset) into its own mkdtemp and back, the temporary to --out",
    ),
    (
        "python/unitac_tools/lerobot_dataset.py",
        "shutil.rmtree(",
        2,
        "its own mkdtemp temporaries",
    ),
];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn files(dir: &Path, ext: &str, out: &mut Vec<PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<PathBuf> = rd.map(|e| e.unwrap().path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            files(&p, ext, out);
        } else if p.extension().is_some_and(|e| e == ext) {
            out.push(p);
        }
    }
}

/// The product's lines of a Rust file: comments, and the test module a file ends with
/// (`#[cfg(test)]` then `mod`), left out.
fn product_lines(text: &str) -> Vec<&str> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        let t = l.trim_start();
        if t.starts_with("#[cfg(test)]")
            && lines[i + 1..]
                .iter()
                .find(|n| !n.trim().is_empty())
                .is_some_and(|n| n.trim_start().starts_with("mod "))
        {
            break;
        }
        if t.starts_with("//") {
            continue;
        }
        out.push(*l);
    }
    out
}

/// (file, call) -> count over the product's sources.
fn write_sites() -> BTreeMap<(String, String), usize> {
    let root = root();
    let mut found = BTreeMap::new();
    let mut rust = Vec::new();
    for c in std::fs::read_dir(root.join("crates")).unwrap() {
        files(&c.unwrap().path().join("src"), "rs", &mut rust);
    }
    let mut py = Vec::new();
    for e in std::fs::read_dir(root.join("python/unitac_tools")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|e| e == "py") {
            py.push(p);
        }
    }
    let scan = |path: &Path, calls: &[&str], rust: bool, found: &mut BTreeMap<_, _>| {
        let text = std::fs::read_to_string(path).unwrap();
        let lines: Vec<&str> = if rust {
            product_lines(&text)
        } else {
            text.lines()
                .filter(|l| !l.trim_start().starts_with('#'))
                .collect()
        };
        let rel = path
            .strip_prefix(&root)
            .unwrap()
            .to_string_lossy()
            .into_owned();
        for call in calls {
            let n: usize = lines.iter().map(|l| count_call(l, call)).sum();
            if n > 0 {
                found.insert((rel.clone(), call.to_string()), n);
            }
        }
    };
    for p in &rust {
        scan(p, RUST_CALLS, true, &mut found);
    }
    for p in &py {
        scan(p, PYTHON_CALLS, false, &mut found);
    }
    found
}

/// Occurrences of `call` in `line`, where `rename(` is not the tail of a longer name and
/// `File::create(` is not `File::create_new(`.
fn count_call(line: &str, call: &str) -> usize {
    line.match_indices(call)
        .filter(|(i, _)| {
            let before = line[..*i].chars().next_back();
            let starts_name = call.chars().next().is_some_and(|c| c.is_alphabetic());
            !(starts_name && before.is_some_and(|c| c.is_alphanumeric() || c == '_'))
        })
        .count()
}

#[test]
fn every_write_site_is_listed_with_its_reason() {
    let found = write_sites();
    let allowed: BTreeMap<(String, String), (usize, &str)> = ALLOWED
        .iter()
        .map(|(f, c, n, why)| ((f.to_string(), c.to_string()), (*n, *why)))
        .collect();
    assert_eq!(allowed.len(), ALLOWED.len(), "duplicate allow-list entries");
    let mut problems = Vec::new();
    for ((file, call), n) in &found {
        match allowed.get(&(file.clone(), call.clone())) {
            Some((m, _)) if m == n => {}
            Some((m, _)) => problems.push(format!(
                "{file}: {n} `{call}` site(s), the allow-list has {m}: check the new one's path \
                 and update the entry"
            )),
            None => problems.push(format!(
                "{file}: {n} `{call}` site(s), not in the allow-list: add (\"{file}\", \
                 \"{call}\", {n}, \"<why the path is the user's or the code's own temporary>\")"
            )),
        }
    }
    for ((file, call), (m, _)) in &allowed {
        if !found.contains_key(&(file.clone(), call.clone())) {
            problems.push(format!(
                "{file}: allow-list entry for `{call}` ({m}) but no such site: remove it"
            ));
        }
    }
    assert!(problems.is_empty(), "\n{}", problems.join("\n"));
}

#[test]
fn the_scan_finds_what_it_looks_for() {
    // The scan must see a write site, and must not take a test module's or a comment's for one.
    let text = "fn a() { std::fs::write(p, b)?; }\n// std::fs::remove_file(x)\n\
                fn rename_it() {}\n#[cfg(test)]\nmod tests { fn t() { std::fs::remove_file(y); } }\n";
    let lines = product_lines(text);
    assert_eq!(lines.len(), 2, "{lines:?}");
    let n = |call| lines.iter().map(|l| count_call(l, call)).sum::<usize>();
    assert_eq!(n("fs::write("), 1);
    assert_eq!(n("remove_file("), 0);
    assert_eq!(n("rename("), 0);
    assert_eq!(count_call("File::create_new(&p)", "File::create("), 0);
    assert_eq!(count_call("std::fs::rename(&a, &b)", "rename("), 1);
    assert_eq!(count_call("os.rename(a, b)", "os.rename("), 1);
    let found = write_sites();
    for (file, call) in [
        ("crates/gripper-sim/src/device/link.rs", "symlink("),
        ("crates/lab/src/scratch.rs", "create_dir("),
    ] {
        assert!(
            found.contains_key(&(file.to_string(), call.to_string())),
            "{file} {call}: {found:?}"
        );
    }
}
