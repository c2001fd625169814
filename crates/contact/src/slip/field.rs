//! The marker field of one contact: the reference markers (found on the background, the gel at
//! rest) and where each was last seen, followed frame by frame ([`track`]). The slip stage
//! measures shear and slip from it; the contact stage's overlay draws each marker's displacement
//! from rest as an arrow.

use super::markers::{DotError, find_dots};
use super::params::SlipParams;
use super::track::{Reference, track};
use unitac_core::Frame;

/// Why a background gives no marker reference, or a frame cannot be followed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FieldError {
    #[error("the background shows {found} marker dots, {needed} are needed")]
    TooFewMarkers { found: usize, needed: u32 },
    #[error("frame {got_w}x{got_h}, the marker reference is {want_w}x{want_h}")]
    WrongSize {
        got_w: u32,
        got_h: u32,
        want_w: u32,
        want_h: u32,
    },
    #[error(transparent)]
    Dots(#[from] DotError),
}

/// The reference markers and each one's latest position.
#[derive(Debug, Clone, Default)]
pub struct MarkerField {
    reference: Option<Reference>,
    /// Each reference marker's position in the previous frame followed (None: not seen there).
    last: Vec<Option<[f64; 2]>>,
}

impl MarkerField {
    /// The reference markers, if a background gave them.
    pub fn reference(&self) -> Option<&Reference> {
        self.reference.as_ref()
    }

    /// Take the markers of `bg` (the gel at rest) as the reference; with too few, there is no
    /// reference (every later frame follows nothing) and the error says why.
    pub fn learn(&mut self, bg: &Frame, p: &SlipParams) -> Result<(), FieldError> {
        self.reference = None;
        self.reset();
        let dots = find_dots(bg, &p.dots())?;
        if dots.len() < p.min_reference_markers as usize {
            return Err(FieldError::TooFewMarkers {
                found: dots.len(),
                needed: p.min_reference_markers,
            });
        }
        self.reference = Some(Reference::new(&dots, bg.width, bg.height));
        Ok(())
    }

    /// Forget the last positions (out of contact): the next frame looks for each marker at rest.
    pub fn reset(&mut self) {
        self.last.clear();
    }

    /// Each reference marker's position in `f` (None: not found or ambiguous), looked for where
    /// it was last seen, else at rest; None without a reference. A frame of another size is an
    /// error and leaves the field as it was.
    pub fn follow(
        &mut self,
        f: &Frame,
        p: &SlipParams,
    ) -> Result<Option<&[Option<[f64; 2]>]>, FieldError> {
        let Some(reference) = &self.reference else {
            return Ok(None);
        };
        if (f.width, f.height) != (reference.width, reference.height) {
            return Err(FieldError::WrongSize {
                got_w: f.width,
                got_h: f.height,
                want_w: reference.width,
                want_h: reference.height,
            });
        }
        let dots = find_dots(f, &p.dots())?;
        let predicted: Vec<[f64; 2]> = reference
            .points
            .iter()
            .enumerate()
            .map(|(i, &r)| self.last.get(i).copied().flatten().unwrap_or(r))
            .collect();
        self.last = track(reference, &predicted, &dots, &p.tracking());
        Ok(Some(&self.last))
    }

    /// (rest, now) in pixels for each marker seen in the last frame followed.
    pub fn displacements(&self) -> Vec<([f32; 2], [f32; 2])> {
        let Some(reference) = &self.reference else {
            return Vec::new();
        };
        reference
            .points
            .iter()
            .zip(&self.last)
            .filter_map(|(r, now)| {
                let n = (*now)?;
                Some(([r[0] as f32, r[1] as f32], [n[0] as f32, n[1] as f32]))
            })
            .collect()
    }
}
