//! Where saved backgrounds live. The stage asks a [`BackgroundStore`] once, on the first frame,
//! and hands it the background when it finishes; the file I/O is the store's, so the stage stays
//! a pure function of its inputs. [`DirStore`] is the store of `background_dir`
//! (`<dir>/<serial>.unitac-bg`); a runtime or node may inject its own.

use crate::background::{Background, BackgroundFileError};
use std::path::PathBuf;

pub trait BackgroundStore: Send + std::fmt::Debug {
    /// The saved background of `sensor_id` for `width` x `height` frames detected at `stride`;
    /// `Ok(None)` when none was saved.
    fn load(
        &mut self,
        sensor_id: &str,
        width: u32,
        height: u32,
        stride: u32,
    ) -> Result<Option<Background>, BackgroundFileError>;
    /// Keep `bg` for the next run of `sensor_id`.
    fn save(&mut self, sensor_id: &str, bg: &Background) -> Result<(), BackgroundFileError>;
}

/// Backgrounds as files in one directory, one per sensor serial.
#[derive(Debug, Clone)]
pub struct DirStore {
    dir: PathBuf,
}

impl DirStore {
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: dir.into() }
    }
}

impl BackgroundStore for DirStore {
    fn load(
        &mut self,
        sensor_id: &str,
        width: u32,
        height: u32,
        stride: u32,
    ) -> Result<Option<Background>, BackgroundFileError> {
        let path = Background::path_for(&self.dir, sensor_id);
        if !path.exists() {
            return Ok(None);
        }
        Background::load(&path, width, height, stride).map(Some)
    }

    fn save(&mut self, sensor_id: &str, bg: &Background) -> Result<(), BackgroundFileError> {
        bg.save(&Background::path_for(&self.dir, sensor_id))
    }
}
