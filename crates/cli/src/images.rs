//! Reading image files into frames, with every size bounded before anything is decoded.

use anyhow::Context;
use std::path::Path;
use unitac_core::{Frame, Stamp};
use unitac_driver::still::{self, StillFormat};

/// Largest image file read \[bytes].
const MAX_FILE_BYTES: u64 = 64 << 20;

/// PNG or JPEG (8- or 16-bit, gray, RGB or RGBA) -> RGB8 frame. Errors name the file.
/// The header's dimensions are checked against the image size limit
/// ([`unitac_core::frame::check_image_size`]) and, with `expect`, against the size the frame
/// must have (the background's), before the image is decoded. A cut JPEG (no EOI marker, or data
/// that ends before the last MCU) is an error, as a cut PNG is (`unitac_driver::still`).
pub fn read_frame(
    path: &Path,
    sensor_id: &str,
    seq: u64,
    expect: Option<(u32, u32)>,
) -> anyhow::Result<Frame> {
    let meta = std::fs::metadata(path).with_context(|| format!("{}", path.display()))?;
    if meta.len() == 0 {
        anyhow::bail!("{}: empty file", path.display());
    }
    if meta.len() > MAX_FILE_BYTES {
        anyhow::bail!(
            "{}: {} bytes, more than {MAX_FILE_BYTES}",
            path.display(),
            meta.len()
        );
    }
    let data = std::fs::read(path).with_context(|| format!("{}", path.display()))?;
    let format = StillFormat::sniff(&data)
        .with_context(|| format!("{}: not a PNG or JPEG image", path.display()))?;
    let (w, h) = still::dimensions(&data, format).with_context(|| format!("{}", path.display()))?;
    if let Some((ew, eh)) = expect {
        if (w, h) != (ew, eh) {
            anyhow::bail!(
                "{}: frame is {w}x{h}, the background is {ew}x{eh}",
                path.display()
            );
        }
    }
    let rgb = still::decode(&data, format).with_context(|| format!("{}", path.display()))?;
    Frame::new(sensor_id, seq, Stamp::ZERO, rgb.width, rgb.height, rgb.data)
        .with_context(|| format!("{}", path.display()))
}

/// A name for each of the image files given on the command line, distinct among distinct
/// files: its file name, with as many of its parent folders as tell it apart from the other
/// files of that name (a calibration set laid out as `N/gelsight.png` gives `0/gelsight.png`,
/// `1/gelsight.png`, ...). A file given twice gets one name.
pub fn distinct_names(paths: &[std::path::PathBuf]) -> Vec<String> {
    use std::collections::{BTreeSet, HashMap};
    // Each path's last `k` components, from the file name up.
    let tail = |p: &Path, k: usize| -> String {
        let parts: Vec<String> = p
            .components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect();
        parts[parts.len().saturating_sub(k)..].join("/")
    };
    let depth = |p: &Path| p.components().count().max(1);
    let distinct: BTreeSet<&Path> = paths.iter().map(|p| p.as_path()).collect();
    let mut k: HashMap<&Path, usize> = distinct.iter().map(|p| (*p, 1)).collect();
    // Lengthen the names that collide until none does (a path's whole length at most).
    loop {
        let mut by_name: HashMap<String, Vec<&Path>> = HashMap::new();
        for p in &distinct {
            by_name.entry(tail(p, k[p])).or_default().push(p);
        }
        let mut grew = false;
        for group in by_name.values().filter(|g| g.len() > 1) {
            for p in group {
                if k[p] < depth(p) {
                    *k.get_mut(p).unwrap_or(&mut 0) += 1;
                    grew = true;
                }
            }
        }
        if !grew {
            break;
        }
    }
    paths.iter().map(|p| tail(p, k[p.as_path()])).collect()
}

/// The file that output `suffix` (e.g. `overlay.png`) of an input named `name` (one of
/// [`distinct_names`]) gets in an output directory: the name without its extension, its
/// folders joined with `_` (`..` and `.` left out), then `.suffix`: `0/gelsight.png` ->
/// `0_gelsight.overlay.png`.
pub fn output_file(name: &str, suffix: &str) -> String {
    let path = Path::new(name);
    let parts: Vec<String> = path
        .with_extension("")
        .components()
        .filter_map(|c| match c {
            std::path::Component::Normal(s) => Some(s.to_string_lossy().into_owned()),
            _ => None,
        })
        .collect();
    let stem = if parts.is_empty() {
        "frame".to_string()
    } else {
        parts.join("_")
    };
    format!("{stem}.{suffix}")
}

/// [`output_file`] of each name, refused when two distinct names would write one file
/// (`a_b/c.png` and `a/b_c.png`).
pub fn output_files(names: &[String], suffix: &str) -> anyhow::Result<Vec<String>> {
    let mut by_file: std::collections::HashMap<String, &String> = Default::default();
    let mut files = Vec::with_capacity(names.len());
    for n in names {
        let f = output_file(n, suffix);
        match by_file.get(&f) {
            Some(other) if *other != n => {
                anyhow::bail!("{other} and {n} would both write {f}: rename one");
            }
            _ => {
                by_file.insert(f.clone(), n);
            }
        }
        files.push(f);
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use std::path::PathBuf;

    #[test]
    fn files_of_one_name_in_several_folders_are_told_apart_by_their_folders() {
        let given: Vec<PathBuf> = [
            "/d/cal/0/gelsight.png",
            "/d/cal/1/gelsight.png",
            "bg/p07.png",
            "x/a/f.png",
            "y/a/f.png",
            "bg/p07.png",
        ]
        .iter()
        .map(PathBuf::from)
        .collect();
        let names = distinct_names(&given);
        assert_eq!(
            names,
            [
                "0/gelsight.png",
                "1/gelsight.png",
                "p07.png",
                "x/a/f.png",
                "y/a/f.png",
                "p07.png"
            ]
        );
        let files = output_files(&names, "overlay.png").unwrap();
        assert_eq!(
            files,
            [
                "0_gelsight.overlay.png",
                "1_gelsight.overlay.png",
                "p07.overlay.png",
                "x_a_f.overlay.png",
                "y_a_f.overlay.png",
                "p07.overlay.png"
            ]
        );
        assert_eq!(
            output_file("../up/./a.b.png", "review.png"),
            "up_a.b.review.png"
        );
        let clash = ["a_b/c.png".to_string(), "a/b_c.png".to_string()];
        assert!(output_files(&clash, "overlay.png").is_err());
    }
}
