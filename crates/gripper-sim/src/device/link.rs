//! The symlink a simulated device keeps at a path of the caller's choosing (a stand-in for a
//! /dev/serial/by-id name), placed so that nothing else at that path is ever touched.
//!
//! The rule:
//! - nothing at the path: the link is created there (`symlink(2)`, which never replaces
//!   anything: if something appears in between, the start fails);
//! - a stale simulator link there, i.e. a symlink whose target is under /dev/pts/ and does not
//!   exist (what a killed simulator leaves behind): it is removed and the link created in its
//!   place;
//! - anything else (a file, a directory, a device node, a FIFO, a symlink to anything that
//!   exists, another simulator's live link included, or to a path outside /dev/pts/): refused
//!   with [`io::ErrorKind::AlreadyExists`], and left as it was.
//!
//! No temporary file is written. The device removes its link when it stops or is unplugged, and
//! only while the path is still a symlink to the pty it placed there.

use std::io;
use std::path::Path;

/// Where the pseudo-terminals' slave ends live.
const PTS: &str = "/dev/pts/";

/// Whether `path` is a stale simulator link: a symlink to a /dev/pts/ path that is gone.
/// Reads only.
pub fn is_stale(path: &Path) -> bool {
    let Ok(meta) = std::fs::symlink_metadata(path) else {
        return false;
    };
    if !meta.file_type().is_symlink() {
        return false;
    }
    let Ok(target) = std::fs::read_link(path) else {
        return false;
    };
    target.starts_with(PTS)
        && matches!(
            std::fs::symlink_metadata(&target),
            Err(e) if e.kind() == io::ErrorKind::NotFound
        )
}

/// Why `path` cannot take the link: it holds something that is not a stale simulator link.
fn occupied(path: &Path) -> io::Error {
    let what = match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => match std::fs::read_link(path) {
            Ok(t) => format!("a symlink to {} (not a stale simulator link)", t.display()),
            Err(_) => "a symlink".to_string(),
        },
        Ok(m) if m.is_dir() => "a directory".to_string(),
        Ok(m) if m.is_file() => "a file".to_string(),
        Ok(_) => "a device node or other special file".to_string(),
        Err(_) => "something".to_string(),
    };
    io::Error::new(
        io::ErrorKind::AlreadyExists,
        format!(
            "{} exists and is {what}: the simulator only replaces a stale link of its own (a \
             symlink to a /dev/pts/ path that is gone); remove it or choose another path",
            path.display()
        ),
    )
}

/// Create a symlink at `path` to `pty` under the rule above.
pub fn place(path: &Path, pty: &Path) -> io::Result<()> {
    match std::os::unix::fs::symlink(pty, path) {
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
        r => return r,
    }
    if !is_stale(path) {
        return Err(occupied(path));
    }
    std::fs::remove_file(path)?;
    match std::os::unix::fs::symlink(pty, path) {
        // Something else took the path in between: it is not ours.
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => Err(occupied(path)),
        r => r,
    }
}

/// Remove the link at `path` if it is still a symlink to `pty`; anything else there stays.
/// Whether it was removed.
pub fn remove(path: &Path, pty: &Path) -> bool {
    let ours = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink())
        && std::fs::read_link(path).is_ok_and(|t| t == pty);
    ours && std::fs::remove_file(path).is_ok()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;
    use std::path::PathBuf;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("unitac-sim-link-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn device_nodes_and_links_to_them_are_never_stale() {
        // Reads only: nothing here is written or removed.
        assert!(!is_stale(Path::new("/dev/null")));
        assert!(!is_stale(Path::new("/dev/pts/ptmx")));
        let d = scratch("dev");
        let l = d.join("l");
        std::os::unix::fs::symlink("/dev/null", &l).unwrap();
        assert!(!is_stale(&l));
        let e = place(&l, Path::new("/dev/pts/4000001")).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::AlreadyExists);
        assert!(e.to_string().contains("a symlink to /dev/null"), "{e}");
        assert_eq!(std::fs::read_link(&l).unwrap(), Path::new("/dev/null"));
        // A dangling link outside /dev/pts/ is someone else's too.
        let m = d.join("m");
        std::os::unix::fs::symlink(d.join("gone"), &m).unwrap();
        assert!(!is_stale(&m));
        assert!(place(&m, Path::new("/dev/pts/4000001")).is_err());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_stale_pts_link_is_replaced_and_only_its_own_link_is_removed() {
        let d = scratch("stale");
        let l = d.join("tty");
        std::os::unix::fs::symlink("/dev/pts/4000002", &l).unwrap();
        assert!(is_stale(&l));
        place(&l, Path::new("/dev/pts/4000003")).unwrap();
        assert_eq!(
            std::fs::read_link(&l).unwrap(),
            Path::new("/dev/pts/4000003")
        );
        assert!(!remove(&l, Path::new("/dev/pts/4000002")));
        assert!(l.symlink_metadata().is_ok());
        assert!(remove(&l, Path::new("/dev/pts/4000003")));
        assert!(l.symlink_metadata().is_err());
        // A file at the path is never removed, whatever is asked.
        std::fs::write(&l, "x").unwrap();
        assert!(!remove(&l, Path::new("/dev/pts/4000003")));
        assert!(place(&l, Path::new("/dev/pts/4000003")).is_err());
        assert_eq!(std::fs::read_to_string(&l).unwrap(), "x");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
