//! Settings of the per-frame pipeline.

use crate::{GateSettings, OneEuroSettings};
use mimic_solve::VectorKernel;
use mimic_types::LandmarkFrame;

/// Where the neutral (expressionless) face comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Neutral {
    /// Average of the first `n` usable frames, each aligned to the first by its stable points.
    FirstFrames(usize),
    /// A given frame of the same layout (a marked neutral or a calibration file).
    Frame(LandmarkFrame),
}

/// What a frame is retargeted against while the neutral is still being calibrated
/// ([`Neutral::FirstFrames`]), docs/replay.md "Short clips".
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Provisional {
    /// The layout's canonical neutral face, when it names one (`canonical_neutral`), scaled to
    /// the performer by the first frame's stable points: the frame is tracked (counted in
    /// [`Stats::provisional`](crate::Stats::provisional)) and the output eases into the
    /// calibrated one over `lost_ease_secs` once the neutral is known. Without one, as `Rest`.
    #[default]
    Canonical,
    /// Nothing: the rig shows its rest face (status `Calibrating`).
    Rest,
}

/// Knobs of [`Retargeter`](crate::Retargeter).
#[derive(Clone, Debug, PartialEq)]
pub struct RetargetSettings {
    /// Source of the neutral face.
    pub neutral: Neutral,
    /// What frames are retargeted against until that neutral is known.
    pub provisional: Provisional,
    /// Jitter filter on the control displacements; `None` turns it off.
    pub filter: Option<OneEuroSettings>,
    /// Also match the face's extent per axis (width, height, depth), not only a uniform scale.
    pub per_axis_scale: bool,
    /// Accept a mirrored source (e.g. a mirrored camera image) when it fits the target better.
    pub allow_mirror: bool,
    /// After tracking is lost, hold the last expression this long (seconds) ...
    pub lost_hold_secs: f32,
    /// ... then ease to neutral over this long (seconds).
    pub lost_ease_secs: f32,
    /// Compute vertex normals of the deformed mesh.
    pub normals: bool,
    /// Compute deformed positions (`rest + B d`). Off: `step` produces only the pose and the
    /// control displacements `d` (for viewers that evaluate the morph themselves); `positions`
    /// keep the rest mesh and normals are not updated.
    pub positions: bool,
    /// The deform's kernel; `None`: [`VectorKernel::best_for_deform`]. One the CPU lacks runs
    /// the portable one. Every kernel's positions are the same bit for bit.
    pub deform_kernel: Option<VectorKernel>,
    /// The normal pass's kernel; `None`: [`VectorKernel::best_for_normals`]. One the CPU lacks
    /// runs the portable one. The kernels' normals differ by at most 9 eps per component.
    pub normals_kernel: Option<VectorKernel>,
    /// A control whose displacement, scaled to the target, exceeds this fraction of the RMS radius
    /// of the rig's controls is an outlier (e.g. a depth sample that hit the background): it is
    /// held like a missing control.
    pub outlier_fraction: f32,
    /// Stable points whose residual after the head-pose fit exceeds this many times the median
    /// residual are dropped and the pose refitted (robust to a bad stable point).
    pub stable_trim: f32,
    /// The plausibility gate: tracked frames no face can make are held and eased like lost
    /// ones (`docs/gate.md`).
    pub gate: GateSettings,
}

impl RetargetSettings {
    /// These settings computing only the control displacements `d`: no positions, no normals
    /// (for a GPU that computes `u = B d` and the normals itself).
    pub fn displacements_only(self) -> Self {
        Self {
            positions: false,
            normals: false,
            ..self
        }
    }
}

impl Default for RetargetSettings {
    fn default() -> Self {
        Self {
            neutral: Neutral::FirstFrames(5),
            provisional: Provisional::Canonical,
            filter: Some(OneEuroSettings::default()),
            per_axis_scale: false,
            allow_mirror: true,
            lost_hold_secs: 0.25,
            lost_ease_secs: 0.5,
            normals: true,
            positions: true,
            deform_kernel: None,
            normals_kernel: None,
            outlier_fraction: 0.8,
            stable_trim: 3.0,
            gate: GateSettings::default(),
        }
    }
}
