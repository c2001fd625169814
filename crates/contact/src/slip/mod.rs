//! Marker-based shear and slip: the dots of a marker gel (GelSight Mini) tracked from the gel at
//! rest, their motion fitted by least squares, slip scored from how far the rim disagrees with
//! the rigid motion of the stuck centre, the way marker-based slip detection is done on real
//! GelSight sensors (never a ground-truth flag).
//!
//! - [`markers`]: dark dots and their sub-pixel centroids;
//! - [`track`]: identities across frames, bounded search, ambiguous matches rejected;
//! - [`field`]: the reference markers and where each was last seen, followed frame by frame;
//! - [`fit`]: rigid and affine least-squares fits (nalgebra), typed errors for degenerate input;
//! - [`SlipStage`]: the stage (after `contact`), one `SlipState` per frame in contact.

pub mod field;
pub mod fit;
pub mod markers;
mod params;
mod stage;
pub mod track;

pub use field::{FieldError, MarkerField};
pub use params::SlipParams;
pub use stage::SlipStage;
