//! Shared helpers of the inference integration tests.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The reference bundle made by `scripts/setup.sh run`. Its absence is a failure, not a skip.
pub fn reference() -> PathBuf {
    let models = std::env::var_os("UNITAC_MODELS")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join(".build/models"));
    let dir = models.join("reference");
    assert!(
        dir.join("manifest.json").is_file(),
        "{} is missing: `bash scripts/setup.sh run` makes it (~6 min on first use)",
        dir.display()
    );
    dir
}

/// The touch projector bundle made by `scripts/setup.sh touch`. Its absence is a failure.
pub fn touch() -> PathBuf {
    let dir = reference().parent().unwrap().join("touch");
    assert!(
        dir.join("manifest.json").is_file(),
        "{} is missing: `bash scripts/setup.sh touch` makes it (~5 min on first use)",
        dir.display()
    );
    dir
}

pub fn python() -> PathBuf {
    std::env::var_os("UNITAC_VENV")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join(".venv"))
        .join("bin/python")
}

pub fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-infer-{}-{name}", std::process::id()));
    std::fs::remove_dir_all(&d).ok();
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Copy the reference bundle so a test can break it.
pub fn copy_reference(name: &str) -> PathBuf {
    let d = tmpdir(name);
    for e in std::fs::read_dir(reference()).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, d.join(p.file_name().unwrap())).unwrap();
    }
    d
}

pub fn write_f32(path: &Path, v: &[f32]) {
    std::fs::write(
        path,
        v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>(),
    )
    .unwrap();
}

pub fn read_f32(path: &Path) -> Vec<f32> {
    std::fs::read(path)
        .unwrap()
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}
