//! CANDIDE-3 model fitting: turns tracked landmarks (2D pixels, with depth where the sensor had it)
//! into the 113 posed CANDIDE-3 vertices a Kinect v1 face tracker reports, plus pose and
//! animation-unit coefficients. See `docs/fitter.md`.
//!
//! Entry types: [`Candide3`] (the model, parsed from its `.wfm` file), [`Fitter`] (per-frame
//! Levenberg-Marquardt with warm start), [`Camera`], [`capture::fit_capture`] (a whole capture in
//! memory -> `kinect121` frames and per-frame fits). Numeric only: no I/O beyond what the caller
//! hands in, no async.

pub mod camera;
pub mod candide;
pub mod capture;
mod cholesky;
pub mod fitter;

pub use camera::Camera;
pub use candide::{AUV_COUNT, Candide3, ModelError, Unit};
pub use fitter::{FitError, FitResult, FitSettings, Fitter, OddParts, PointObservation, Pose};
