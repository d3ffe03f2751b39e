//! Errors of the solver setup (the per-frame steps cannot fail).

use mimic_types::RigError;

/// Why a deformation basis or a morph fit could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// The rig does not hold together (bad indices, frozen controls, broken mesh).
    #[error("invalid rig: {0}")]
    InvalidRig(#[from] RigError),
    /// The rig has no control points, so nothing can drive it.
    #[error("the rig has no control points")]
    NoControls,
    /// A setting is out of range (e.g. a non-positive kernel radius).
    #[error("invalid solver setting: {0}")]
    InvalidSetting(String),
    /// A linear system turned out singular or not positive definite.
    #[error("{system} is singular or not positive definite: {detail}")]
    Singular {
        /// Which system, e.g. `RBF kernel matrix of region top`.
        system: String,
        /// What the factorisation reported.
        detail: String,
    },
    /// Morph targets do not match the control count.
    #[error("morph target {target} has {got} control deltas, expected {expected}")]
    MorphTargetLength {
        /// Offending target.
        target: usize,
        /// Deltas given.
        got: usize,
        /// Deltas expected (those of target 0).
        expected: usize,
    },
    /// A morph target delta is NaN or infinite.
    #[error("morph target {target} has a non-finite delta at control {control}")]
    MorphTargetNonFinite {
        /// Offending target.
        target: usize,
        /// Offending control.
        control: usize,
    },
}
