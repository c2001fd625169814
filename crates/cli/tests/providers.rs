//! A scene may ask for GPU execution providers first: `providers: [cuda, cpu]` on this
//! project's CPU-only ONNX Runtime runs the models on the CPU, says so in one line on stderr, and
//! gives the same outputs as `providers: [cpu]`. `providers: cuda` alone is a one-line error
//! (crates/cli/tests/hostile.rs).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn run(scene: &std::path::Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args([
            "run",
            "--scene",
            scene.to_str().unwrap(),
            "--fast",
            "--events",
        ])
        .env("RUST_LOG", "warn")
        .output()
        .unwrap()
}

#[test]
fn cuda_before_cpu_runs_on_the_cpu_with_one_line() {
    let dir = std::env::temp_dir().join(format!("unitac-providers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(root().join("launch/scenes/fabric_selection.yaml")).unwrap();
    assert!(text.contains("providers: [cpu]"));
    let cpu = dir.join("cpu.yaml");
    let gpu = dir.join("gpu.yaml");
    std::fs::write(&cpu, &text).unwrap();
    std::fs::write(
        &gpu,
        text.replace("providers: [cpu]", "providers: [cuda, cpu]"),
    )
    .unwrap();
    let (a, b) = (run(&cpu), run(&gpu));
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    assert!(b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));
    let notices = |o: &Output| {
        String::from_utf8_lossy(&o.stderr)
            .lines()
            .filter(|l| l.contains("execution provider"))
            .map(str::to_string)
            .collect::<Vec<_>>()
    };
    assert!(notices(&a).is_empty(), "{:?}", notices(&a));
    let n = notices(&b);
    assert_eq!(n.len(), 1, "{n:?}");
    assert!(
        n[0].contains("execution provider cuda is not in this ONNX Runtime library")
            && n[0].ends_with("run on cpu"),
        "{}",
        n[0]
    );
    // The events (JSON lines; the summary after them holds wall times).
    let events = |o: &Output| {
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .filter(|l| l.starts_with('{'))
            .map(str::to_string)
            .collect::<Vec<_>>()
    };
    assert!(events(&a).len() > 100, "{}", events(&a).len());
    assert!(events(&a) == events(&b), "the same events on the CPU");
    std::fs::remove_dir_all(&dir).ok();
}
