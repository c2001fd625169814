//! Contact detection by background subtraction, as a pure [`Stage`].
//!
//! Per frame, on a grid of block means (stride 2 by default):
//! 1. compensate global illumination changes: per-channel gain = median of frame / background over
//!    a sample of cells (robust to a contact covering less than half the gel), so LED warm-up and
//!    exposure steps do not fire contacts;
//! 2. residual = sum over channels of |frame - gain * background|, thresholded at `noise_k` times the
//!    noise measured while learning the background (never below `min_threshold`);
//! 3. marker dots masked (GelSight Mini), opening then closing, connected components below
//!    `min_component_px` dropped;
//! 4. area (px and mm^2), centroid and bounding box in the INPUT image's pixels, strength score;
//! 5. hysteresis (enter / exit area) and debounce (k frames) into contact episodes, with a bounded
//!    clip of the episode's frames for the encoder;
//! 6. the background follows slow changes by an EMA only while there is no contact, and only in
//!    cells outside the current mask: a held contact is never absorbed.
//!
//! Saturated or dark frames, and frames whose gain is implausible, are rejected with an error and
//! leave the detector's state as it was.

pub mod background;
mod detector;
mod episodes;
pub mod grid;
mod params;
mod stage;
mod store;

pub use background::{Background, BackgroundFileError, Learner};
pub use detector::{ContactDetector, Measurement};
pub use params::{ContactParams, MAX_CLIP_FRAMES, ParamsError};
pub use stage::ContactStage;
pub use store::{BackgroundStore, DirStore};
