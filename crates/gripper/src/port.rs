//! Opening the serial port: by its stable /dev/serial/by-id name when there is one (so a USB
//! adapter that comes back as another ttyUSBn is found again), with errors that say what to do.

use std::io;
use std::path::{Path, PathBuf};
use std::time::Duration;
use thiserror::Error;

/// Where udev puts the stable names of USB serial adapters.
pub const BY_ID: &str = "/dev/serial/by-id";

#[derive(Debug, Error)]
pub enum PortError {
    #[error("{path}: no such serial device{}", candidates_text(.candidates))]
    NotFound {
        path: PathBuf,
        candidates: Vec<PathBuf>,
    },
    #[error(
        "{path}: permission denied; add yourself to the group that owns it (usually `dialout`: \
         sudo usermod -aG dialout $USER, then log in again)"
    )]
    Permission { path: PathBuf },
    #[error("{path}: not a serial port")]
    NotSerial { path: PathBuf },
    #[error("{path}: device busy (another program has it open?)")]
    Busy { path: PathBuf },
    #[error("{path}: {what}")]
    Other { path: PathBuf, what: String },
}

fn candidates_text(c: &[PathBuf]) -> String {
    if c.is_empty() {
        format!("; nothing under {BY_ID} either (adapter unplugged?)")
    } else {
        let names: Vec<_> = c.iter().map(|p| p.display().to_string()).collect();
        format!("; serial devices present: {}", names.join(", "))
    }
}

/// The entries of `dir` (a by-id directory), sorted.
pub fn list_by_id(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    v.sort();
    v
}

/// The stable name of `path`: itself when it is already a link in `by_id`, else the link in
/// `by_id` that points at the same device, else `path` unchanged.
pub fn stable_path(path: &Path, by_id: &Path) -> PathBuf {
    if path.parent() == Some(by_id) {
        return path.to_path_buf();
    }
    let Ok(target) = path.canonicalize() else {
        return path.to_path_buf();
    };
    list_by_id(by_id)
        .into_iter()
        .find(|l| l.canonicalize().ok().as_deref() == Some(target.as_path()))
        .unwrap_or_else(|| path.to_path_buf())
}

/// Open `path` at `baud`, 8N1, no flow control.
pub fn open(path: &Path, baud: u32) -> Result<Box<dyn serialport::SerialPort>, PortError> {
    let name = path.to_string_lossy().into_owned();
    serialport::new(name, baud)
        .data_bits(serialport::DataBits::Eight)
        .parity(serialport::Parity::None)
        .stop_bits(serialport::StopBits::One)
        .flow_control(serialport::FlowControl::None)
        .timeout(Duration::from_millis(10))
        .open()
        .map_err(|e| classify(path, e))
}

fn classify(path: &Path, e: serialport::Error) -> PortError {
    let path = path.to_path_buf();
    let io_kind = match e.kind {
        serialport::ErrorKind::Io(k) => Some(k),
        _ => None,
    };
    let exists = path.exists();
    match (io_kind, e.kind) {
        (Some(io::ErrorKind::PermissionDenied), _) => PortError::Permission { path },
        (Some(io::ErrorKind::NotFound), _) | (_, serialport::ErrorKind::NoDevice) if !exists => {
            PortError::NotFound {
                path,
                candidates: list_by_id(Path::new(BY_ID)),
            }
        }
        (Some(io::ErrorKind::ResourceBusy), _) => PortError::Busy { path },
        _ if e.description.contains("ermission") => PortError::Permission { path },
        _ if e.description.contains("Not a typewriter")
            || e.description.contains("Inappropriate ioctl") =>
        {
            PortError::NotSerial { path }
        }
        _ if e.description.contains("busy") => PortError::Busy { path },
        _ => PortError::Other {
            path,
            what: e.description,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_port_names_what_is_there() {
        let e = open(Path::new("/dev/does-not-exist-gripper"), 115_200).err();
        let Some(PortError::NotFound { path, .. }) = e else {
            panic!("expected NotFound, got {e:?}");
        };
        assert_eq!(path, Path::new("/dev/does-not-exist-gripper"));
    }

    #[test]
    fn errors_say_what_to_do() {
        let io = |k| serialport::Error::new(serialport::ErrorKind::Io(k), "x");
        let p = Path::new("/dev/ttyUSB0");
        let e = classify(p, io(io::ErrorKind::PermissionDenied));
        assert!(matches!(e, PortError::Permission { .. }));
        assert!(e.to_string().contains("dialout"), "{e}");
        let e = classify(p, io(io::ErrorKind::ResourceBusy));
        assert!(matches!(e, PortError::Busy { .. }));
        let e = classify(
            Path::new("/dev/null"),
            serialport::Error::new(serialport::ErrorKind::Unknown, "Not a typewriter"),
        );
        assert_eq!(e.to_string(), "/dev/null: not a serial port");
        let e = open(Path::new("/dev/null"), 115_200).err();
        assert!(matches!(e, Some(PortError::NotSerial { .. })), "{e:?}");
    }

    #[test]
    fn stable_path_finds_the_link() {
        let dir = std::env::temp_dir().join(format!("unitac-by-id-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let dev = dir.join("ttyFAKE0");
        std::fs::write(&dev, b"").unwrap();
        let by_id = dir.join("by-id");
        std::fs::create_dir_all(&by_id).unwrap();
        let link = by_id.join("usb-FTDI_FT232R_USB_UART_A10KXYZ-if00-port0");
        std::os::unix::fs::symlink(&dev, &link).unwrap();
        assert_eq!(stable_path(&dev, &by_id), link);
        assert_eq!(stable_path(&link, &by_id), link);
        let other = dir.join("ttyFAKE1");
        assert_eq!(stable_path(&other, &by_id), other);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
