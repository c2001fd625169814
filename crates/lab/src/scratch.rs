//! Temporary directories the benchmarks write their inputs for a Python baseline into: always a
//! new one (`create_dir`, never an existing directory or a symlink planted at the name), so the
//! removal at the end only ever deletes what this run made.

use std::path::PathBuf;

/// Most names tried before giving up (each taken by someone else).
const TRIES: u32 = 1000;

/// A new, empty directory `<temp>/unitac-<tag>-<pid>-<n>`, made by this call.
pub(crate) fn new_dir(tag: &str) -> std::io::Result<PathBuf> {
    let base = std::env::temp_dir();
    let pid = std::process::id();
    for n in 0..TRIES {
        let dir = base.join(format!("unitac-{tag}-{pid}-{n}"));
        match std::fs::create_dir(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::new(
        std::io::ErrorKind::AlreadyExists,
        format!(
            "{}: {TRIES} names unitac-{tag}-{pid}-* taken",
            base.display()
        ),
    ))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_name_already_taken_is_left_alone_and_another_is_made() {
        let taken =
            std::env::temp_dir().join(format!("unitac-scratch-test-{}-0", std::process::id()));
        std::fs::create_dir_all(&taken).unwrap();
        std::fs::write(taken.join("theirs"), b"keep").unwrap();
        let mine = new_dir("scratch-test").unwrap();
        assert_ne!(mine, taken);
        assert_eq!(std::fs::read_dir(&mine).unwrap().count(), 0);
        assert_eq!(std::fs::read(taken.join("theirs")).unwrap(), b"keep");
        std::fs::remove_dir_all(&mine).unwrap();
        std::fs::remove_dir_all(&taken).unwrap();
    }
}
