//! Gel depth from one image: a per-sensor photometric calibration from ball presses, the
//! gradients it gives per pixel, and their integration into depth by a DCT Poisson solve; the
//! penetration and a contact region in mm^2 from the depth.
//!
//! - `prep`: the frame's difference to the background, smoothed, less the smooth shading;
//! - [`model`]: colour and position -> gradient, the calibration file ([`DepthCalibration`]);
//! - [`calib`]: the contact circle of a ball press ([`find_circle`]) and the least-squares fit
//!   ([`Fit`]);
//! - [`poisson`]: gradients -> height ([`PoissonSolver`]: DCT rows through rustfft, tridiagonal columns);
//! - [`estimate`]: one frame -> depth map, penetration, contact region ([`DepthEstimator`]);
//! - [`selfcal`]: a linear model fitted on a press itself, up to scale (a gel with no model).

pub mod calib;
pub mod estimate;
pub mod model;
pub mod poisson;
mod prep;
pub mod selfcal;

pub use calib::{Circle, Fit, Terms, find_circle, prepare};
pub use estimate::{DepthEstimator, DepthParams, DepthSummary};
pub use model::{CalibrationInvalid, DepthCalibration, DepthError, GradientModel};
pub use poisson::PoissonSolver;
pub use prep::{Prep, Shading};
