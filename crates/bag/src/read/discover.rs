//! Finding the storage files of a bag: by extension, and in rosbag2's split-file order.

use crate::BagError;
use std::io::Read;
use std::path::{Path, PathBuf};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    Mcap,
    Sqlite,
}

pub(super) fn storage_kind(p: &Path) -> Option<Kind> {
    match p.extension()?.to_str()? {
        "mcap" => Some(Kind::Mcap),
        "db3" => Some(Kind::Sqlite),
        _ => None,
    }
}

pub(super) fn storage_files_in(dir: &Path) -> Result<Vec<PathBuf>, BagError> {
    let io = |e| BagError::Io {
        path: dir.to_path_buf(),
        error: e,
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(io)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && storage_kind(p).is_some())
        .collect();
    // rosbag2 names split files <bag>_0, <bag>_1, ...: order by that index, then by name.
    files.sort_by_key(|p| {
        let stem = p
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default()
            .to_string();
        let idx = stem
            .rsplit_once('_')
            .and_then(|(_, n)| n.parse::<u64>().ok())
            .unwrap_or(0);
        (idx, stem)
    });
    Ok(files)
}

pub(super) fn read_bounded(p: &Path, max: usize) -> Result<String, BagError> {
    let io = |e| BagError::Io {
        path: p.to_path_buf(),
        error: e,
    };
    let f = std::fs::File::open(p).map_err(io)?;
    let mut s = String::new();
    f.take(max as u64 + 1).read_to_string(&mut s).map_err(io)?;
    Ok(s)
}
