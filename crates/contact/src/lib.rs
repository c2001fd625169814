//! Contact detection by background subtraction, as a pure [`Stage`](unitac_core::Stage).
//!
//! Per frame, on a grid of block means (stride 2 at 320x240; the pixel parameters scale with the
//! frame, so 640x480 uses stride 4):
//! 1. compensate global illumination changes: per-channel gain = median of frame / background over
//!    a sample of cells (robust to a contact covering less than half the gel), so LED warm-up and
//!    exposure steps do not fire contacts;
//! 2. remove the smooth shading of the signed difference (a robust quartic fit, [`shading`]) and
//!    measure the noise from the frame itself (neighbouring-cell differences), so one background
//!    image is enough and uneven LED drift or gel stretch is not contact;
//! 3. on noisy frames average the difference over a box of cells; threshold the summed absolute
//!    difference at `noise_k` times the measured noise (never below `min_threshold`);
//! 4. marker dots masked (GelSight Mini), opening then closing, then the coherent regions only:
//!    components over `min_component_px` and not much smaller than the largest;
//! 5. area (px and mm^2), centroid and bounding box in the INPUT image's pixels, strength score,
//!    from the contact region inside that deformation mask: per component the cells at or above
//!    `area_level` (half) of its own robust peak residual, grown, closed, holes filled, and the
//!    skirt's flank outside the press's ridge peeled off (`peel_skirt`), so the gel's skirt
//!    around a press is not contact; or, by the `region` param, the gel's half-depth contour
//!    from a photometric model where the residual finds a deformation (`depth_region`);
//! 6. hysteresis (enter / exit area) and debounce (k frames) into contact episodes
//!    ([`episodes`](crate::ContactStage)), with a bounded clip of the episode's frames;
//! 7. the background follows slow changes by an EMA only while there is no contact, and only in
//!    cells outside the current mask: a held contact is never absorbed.
//!
//! Saturated or dark frames, frames whose gain is implausible and frames of another size are
//! rejected with an error and leave the detector's state as it was (a sustained new size is
//! learned again). Saved backgrounds come through a [`BackgroundStore`]; the stage does no I/O.
//!
//! The [`slip`] stage runs after it on marker gels: shear and slip from the tracked marker field.

pub mod background;
pub mod depth;
mod depth_region;
mod detector;
mod episodes;
mod flank;
pub mod grid;
pub mod overlay;
mod params;
mod region;
mod residual;
pub mod shading;
pub mod slip;
mod stage;
mod store;

pub use background::{Background, BackgroundFileError, Learner};
pub use detector::{ContactDetector, FrameRefused, Measurement};
pub use params::{ContactParams, MAX_CLIP_FRAMES, ParamsError, RegionRule};
pub use slip::{MarkerField, SlipParams, SlipStage};
pub use stage::ContactStage;
pub use store::{BackgroundStore, DirStore};
