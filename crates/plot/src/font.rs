//! The one font of every chart: DejaVu Sans from the system's TrueType file, rasterised by
//! ab_glyph through plotters (no fontconfig or FreeType). Loaded on first use, once per process.

use crate::PlotError;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Where Debian's `fonts-dejavu-core` puts DejaVu Sans.
pub const DEFAULT_FONT: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
/// The Debian package that provides [`DEFAULT_FONT`] (installed by scripts/setup.sh).
pub const FONT_PACKAGE: &str = "fonts-dejavu-core";
/// The family name charts ask plotters for (also plotters' default for mesh labels).
pub(crate) const FAMILY: &str = "sans-serif";
/// A font file larger than this is refused (DejaVu Sans is 0.75 MB).
const MAX_FONT_BYTES: u64 = 32 << 20;

/// The font registered with plotters, if any.
static REGISTERED: Mutex<Option<PathBuf>> = Mutex::new(None);

/// Make the TrueType font at `path` the charts' font. The first font that loads stays for the
/// life of the process (plotters keeps fonts in a global table); later calls return at once.
pub fn load_font(path: &Path) -> Result<(), PlotError> {
    // A panic elsewhere while holding the lock leaves the Option intact: keep using it.
    let mut registered = REGISTERED.lock().unwrap_or_else(|e| e.into_inner());
    if registered.is_some() {
        return Ok(());
    }
    let bytes = read_font(path)?;
    // plotters wants 'static font bytes: leaked once, only after they parsed as a font.
    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
    plotters::style::register_font(FAMILY, plotters::style::FontStyle::Normal, bytes).map_err(
        |_| PlotError::FontInvalid {
            path: path.to_path_buf(),
        },
    )?;
    *registered = Some(path.to_path_buf());
    Ok(())
}

/// The font the charts use: [`DEFAULT_FONT`] unless [`load_font`] registered another first.
pub(crate) fn ensure_font() -> Result<(), PlotError> {
    load_font(Path::new(DEFAULT_FONT))
}

/// The bytes of the font file at `path`, checked to be a TrueType/OpenType font of bounded size.
fn read_font(path: &Path) -> Result<Vec<u8>, PlotError> {
    let missing = |source| PlotError::FontMissing {
        path: path.to_path_buf(),
        package: FONT_PACKAGE,
        source,
    };
    let file = std::fs::File::open(path).map_err(missing)?;
    let mut bytes = Vec::new();
    file.take(MAX_FONT_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(missing)?;
    let invalid = || PlotError::FontInvalid {
        path: path.to_path_buf(),
    };
    if bytes.len() as u64 > MAX_FONT_BYTES {
        return Err(invalid());
    }
    ab_glyph::FontRef::try_from_slice(&bytes).map_err(|_| invalid())?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_font_names_its_path_and_package() {
        let e = read_font(Path::new("/nonexistent/DejaVuSans.ttf")).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("/nonexistent/DejaVuSans.ttf"), "{msg}");
        assert!(msg.contains(FONT_PACKAGE), "{msg}");
        assert!(matches!(e, PlotError::FontMissing { .. }));
    }

    #[test]
    fn a_file_that_is_not_a_font_is_refused() {
        let path =
            std::env::temp_dir().join(format!("unitac-plot-notafont-{}", std::process::id()));
        std::fs::write(&path, b"not a font at all").unwrap();
        let e = read_font(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert!(matches!(e, PlotError::FontInvalid { .. }), "{e}");
    }
}
