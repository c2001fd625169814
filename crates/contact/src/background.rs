//! The background model: what the gel looks like without contact.
//!
//! Learned as the mean of the first frames (with the sensor noise measured from frame-to-frame
//! differences), then followed slowly by an EMA while there is no contact. It is kept on the
//! detection grid (for detection) and at full resolution (the non-contact frame, which the
//! inference stage encodes as the sensor prior Z_sen). Saved per sensor serial in a small binary
//! file whose every size is checked on load.

use crate::grid::{BlockScratch, Geometry, block_means};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use unitac_core::{Frame, Stamp};

const MAGIC: &[u8; 8] = b"UNITACBG";
const VERSION: u32 = 1;

#[derive(Debug, Clone, PartialEq)]
pub struct Background {
    pub geo: Geometry,
    /// Block means, RGB, \[DN].
    pub grid: Vec<f32>,
    /// Full-resolution mean, RGB, \[DN].
    pub full: Vec<f32>,
    /// Noise sigma per channel of one grid cell \[DN].
    pub cell_sigma: f32,
    pub captured_at: Stamp,
}

/// Accumulates the first frames into a [`Background`].
#[derive(Debug)]
pub struct Learner {
    geo: Geometry,
    n: u32,
    sum_grid: Vec<f64>,
    sum_full: Vec<u32>,
    prev: Vec<f32>,
    cur: Vec<f32>,
    scratch: BlockScratch,
    abs_diff: f64,
    diff_n: u64,
}

impl Learner {
    pub fn new(geo: Geometry) -> Self {
        Self {
            geo,
            n: 0,
            sum_grid: vec![0.0; geo.cells() * 3],
            sum_full: vec![0; geo.width as usize * geo.height as usize * 3],
            prev: Vec::new(),
            cur: Vec::new(),
            scratch: BlockScratch::default(),
            abs_diff: 0.0,
            diff_n: 0,
        }
    }

    pub fn frames(&self) -> u32 {
        self.n
    }

    pub fn add(&mut self, f: &Frame) {
        block_means(f, &self.geo, &mut self.cur, &mut self.scratch);
        if !self.prev.is_empty() {
            self.abs_diff += self
                .cur
                .iter()
                .zip(&self.prev)
                .map(|(a, b)| f64::from((a - b).abs()))
                .sum::<f64>();
            self.diff_n += self.cur.len() as u64;
        }
        for (s, v) in self.sum_grid.iter_mut().zip(&self.cur) {
            *s += f64::from(*v);
        }
        for (s, &v) in self.sum_full.iter_mut().zip(f.data()) {
            *s += u32::from(v);
        }
        std::mem::swap(&mut self.prev, &mut self.cur);
        self.n += 1;
    }

    /// The background, with the noise measured if there were at least two frames, else
    /// `default_cell_sigma`.
    pub fn finish(&self, stamp: Stamp, default_cell_sigma: f32) -> Background {
        let n = f64::from(self.n.max(1));
        // E|a - b| = 2 sigma / sqrt(pi) for independent a, b with the same sigma.
        let cell_sigma = if self.diff_n > 0 {
            (self.abs_diff / self.diff_n as f64 * std::f64::consts::PI.sqrt() / 2.0) as f32
        } else {
            default_cell_sigma
        };
        Background {
            geo: self.geo,
            grid: self.sum_grid.iter().map(|s| (s / n) as f32).collect(),
            full: self
                .sum_full
                .iter()
                .map(|&s| (f64::from(s) / n) as f32)
                .collect(),
            cell_sigma,
            captured_at: stamp,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum BackgroundFileError {
    #[error("{0}: {1}")]
    Io(PathBuf, std::io::Error),
    #[error("{0}: not a background file of this version")]
    Format(PathBuf),
    #[error("{path}: background is {got}, the sensor gives {want}")]
    Mismatch {
        path: PathBuf,
        got: String,
        want: String,
    },
}

impl Background {
    /// The non-contact frame (full resolution, RGB8): the sensor prior for inference.
    pub fn frame(&self, sensor_id: &str) -> Option<Frame> {
        let data = self
            .full
            .iter()
            .map(|v| v.round().clamp(0.0, 255.0) as u8)
            .collect();
        Frame::new(
            sensor_id,
            0,
            self.captured_at,
            self.geo.width,
            self.geo.height,
            data,
        )
        .ok()
    }

    /// `<dir>/<serial>.unitac-bg`, with the serial reduced to [A-Za-z0-9_-].
    pub fn path_for(dir: &Path, serial: &str) -> PathBuf {
        let safe: String = serial
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        dir.join(format!("{safe}.unitac-bg"))
    }

    pub fn save(&self, path: &Path) -> Result<(), BackgroundFileError> {
        let io = |e| BackgroundFileError::Io(path.to_path_buf(), e);
        let mut b = Vec::with_capacity(40 + (self.grid.len() + self.full.len()) * 4);
        b.extend_from_slice(MAGIC);
        for v in [VERSION, self.geo.width, self.geo.height, self.geo.stride] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&self.cell_sigma.to_le_bytes());
        b.extend_from_slice(&self.captured_at.0.to_le_bytes());
        for v in self.grid.iter().chain(&self.full) {
            b.extend_from_slice(&v.to_le_bytes());
        }
        // Write then rename, so a crash never leaves a half-written background behind. The
        // temporary is new (`create_new`: an existing file of that name, the user's or another
        // writer's, is never overwritten) and removed again if the write fails.
        let mut name = path.file_name().unwrap_or_default().to_os_string();
        name.push(format!(".{}.unitac-bg.tmp", std::process::id()));
        let tmp = path.with_file_name(name);
        let mut f = std::fs::File::create_new(&tmp).map_err(io)?;
        let written = f
            .write_all(&b)
            .and_then(|()| f.sync_all())
            .and_then(|()| std::fs::rename(&tmp, path));
        if let Err(e) = written {
            let _ = std::fs::remove_file(&tmp);
            return Err(io(e));
        }
        Ok(())
    }

    /// Load a background saved for a sensor that gives `width` x `height` frames, detected at
    /// `stride`. Every size in the file is checked before anything is allocated.
    pub fn load(
        path: &Path,
        width: u32,
        height: u32,
        stride: u32,
    ) -> Result<Background, BackgroundFileError> {
        let io = |e| BackgroundFileError::Io(path.to_path_buf(), e);
        let fmt = || BackgroundFileError::Format(path.to_path_buf());
        let geo = Geometry::new(width, height, stride);
        let expected = 36 + (geo.cells() * 3 + width as usize * height as usize * 3) * 4;
        let mut f = std::fs::File::open(path).map_err(io)?;
        let len = f.metadata().map_err(io)?.len();
        let mut head = [0u8; 36];
        f.read_exact(&mut head).map_err(|_| fmt())?;
        let u = |i: usize| u32::from_le_bytes([head[i], head[i + 1], head[i + 2], head[i + 3]]);
        if &head[..8] != MAGIC || u(8) != VERSION {
            return Err(fmt());
        }
        let (w, h, s) = (u(12), u(16), u(20));
        if (w, h, s) != (width, height, geo.stride) {
            return Err(BackgroundFileError::Mismatch {
                path: path.to_path_buf(),
                got: format!("{w}x{h} stride {s}"),
                want: format!("{width}x{height} stride {}", geo.stride),
            });
        }
        if len != expected as u64 {
            return Err(fmt());
        }
        let cell_sigma = f32::from_le_bytes([head[24], head[25], head[26], head[27]]);
        let mut t = [0u8; 8];
        t.copy_from_slice(&head[28..36]);
        let captured_at = Stamp(i64::from_le_bytes(t));
        let mut rest = Vec::with_capacity(expected - 36);
        f.read_to_end(&mut rest).map_err(io)?;
        let vals: Vec<f32> = rest
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        if !cell_sigma.is_finite() || cell_sigma < 0.0 || vals.iter().any(|v| !v.is_finite()) {
            return Err(fmt());
        }
        let (grid, full) = vals.split_at(geo.cells() * 3);
        Ok(Background {
            geo,
            grid: grid.to_vec(),
            full: full.to_vec(),
            cell_sigma,
            captured_at,
        })
    }
}
