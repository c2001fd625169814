//! Shared helpers of the bag integration tests.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::Command;
use unitac_bag::replay::{ImageResult, OutputBag, ReplayReport, replay};
use unitac_bag::{BagSource, ReplayOptions};
use unitac_contact::{ContactParams, ContactStage};
use unitac_core::{Frame, Msg, SensorKind, Source, Stage};
use unitac_sim::{MockConfig, MockSensor, Scenario};

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

pub fn python() -> PathBuf {
    let venv = std::env::var_os("UNITAC_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join(".venv"));
    venv.join("bin/python")
}

/// Run a helper under tests/bag with the project venv; panics with its stderr on failure.
pub fn run_py(script: &str, args: &[&std::ffi::OsStr]) -> String {
    let o = Command::new(python())
        .arg(root().join("tests/bag").join(script))
        .args(args)
        .output()
        .expect("run python from .venv (scripts/setup.sh creates it)");
    assert!(
        o.status.success(),
        "{script} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).unwrap()
}

pub fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-bag-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The first `n` frames of the mock GelSight Mini in the fabric scene (learning, then contacts).
pub fn mock_frames(n: usize) -> Vec<Frame> {
    let mut s = MockSensor::new(
        MockConfig::new(SensorKind::GELSIGHT_MINI, 3),
        Scenario::fabric_selection(),
    );
    let mut out = Vec::new();
    while out.len() < n {
        match s.next_frame().unwrap() {
            Some(f) => out.push(f),
            None => break,
        }
    }
    out
}

pub fn contact_stage() -> Vec<Box<dyn Stage>> {
    vec![Box::new(
        ContactStage::new(ContactParams::default(), SensorKind::GELSIGHT_MINI.spec()).unwrap(),
    )]
}

/// (stamp, events, error) of one image message.
pub type Line = (i64, Vec<Msg>, Option<String>);

/// Replay a bag through the contact stage: per-image results and the report.
pub fn replay_contact(
    bag: &Path,
    opts: ReplayOptions,
    out: Option<&Path>,
) -> (Vec<Line>, ReplayReport) {
    let mut src = BagSource::open(bag, opts).unwrap();
    let mut chain = unitac_core::Chain::new(contact_stage());
    let mut out = out.map(|p| {
        OutputBag::new(
            unitac_bag::BagWriter::create(p, unitac_bag::WriteOptions::default()).unwrap(),
        )
    });
    let mut lines = Vec::new();
    let stop = std::sync::atomic::AtomicBool::new(false);
    let report = replay(
        &mut src,
        &mut chain,
        out.as_mut(),
        &mut unitac_core::Pacer::fast(),
        &stop,
        |r: &ImageResult| lines.push((r.stamp, r.events.clone(), r.error.clone())),
        |_| {},
    )
    .unwrap();
    if let Some(o) = out {
        o.finish().unwrap();
    }
    (lines, report)
}

/// The contact states the stage gives for frames fed directly.
pub fn direct_contact(frames: &[Frame]) -> Vec<Vec<Msg>> {
    let mut stages = contact_stage();
    let clock = unitac_core::ManualClock::default();
    frames
        .iter()
        .map(|f| {
            clock.set(f.stamp);
            stages[0].process(&Msg::Frame(f.clone()), &clock).unwrap()
        })
        .collect()
}
