//! The plausibility gate: a tracked frame whose head pose or control displacements no face can
//! make (a fit failure, a tracker that latched onto the background) is held and eased like a
//! lost frame instead of being passed through. Bounds are in units of the face's own size, the
//! target's inter-ocular distance (`docs/gate.md`).

use glam::{Quat, Vec3};
use mimic_types::{Fdp, Region};
use serde::{Deserialize, Serialize};

/// Bounds of the plausibility gate; lengths in inter-ocular distances (IOD) of the target face
/// (6.30 cm on the ICT head, 0.60 on CANDIDE-3), angles in degrees, speeds per second. Serde
/// defaults, so a config that predates the gate still loads. Defaults and the figures behind
/// them: `docs/gate.md`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GateSettings {
    /// Off: every tracked frame passes unchanged (the pipeline as it was before the gate).
    pub enabled: bool,
    /// Largest displacement from the neutral of a chin or inner-lip control (FDP group 2), IOD;
    /// a frame with a control beyond its bound is held.
    pub max_jaw: f32,
    /// ... of an eye or eyelid control (group 3), IOD.
    pub max_eye: f32,
    /// ... of a brow control (group 4), IOD.
    pub max_brow: f32,
    /// ... of a cheek control (group 5), IOD.
    pub max_cheek: f32,
    /// ... of an outer-lip control (group 8), IOD.
    pub max_lip: f32,
    /// ... of any other control (nose, group 9, and the rest), IOD.
    pub max_other: f32,
    /// A frame whose head is turned further than this from the neutral's is held, degrees.
    pub max_rotation_deg: f32,
    /// A frame whose head turned faster than this since the last accepted frame is held, and so
    /// are the frames after it until the head is back within one frame's turn of that pose (or
    /// `max_hold_secs` have passed), degrees per second.
    pub max_turn_speed_dps: f32,
    /// The head may always turn this far between two frames, degrees.
    pub turn_floor_deg: f32,
    /// A run of frames held for their turn ends after this long even if the head did not come
    /// back (the new pose is taken as real), seconds.
    pub max_hold_secs: f32,
    /// No output control moves faster than this: faster steps are clamped, IOD per second.
    pub max_control_speed: f32,
    /// An output control may always move this far between two frames, IOD.
    pub step_floor: f32,
    /// A frame counts as a jump in [`Stats::jumps`](crate::Stats) when some output control moves
    /// more than this between two frames, IOD (0.159 IOD is 1 cm on the ICT head).
    pub jump_report: f32,
    /// A stable point is trimmed from the head-pose fit (as an outlier, beyond `stable_trim`
    /// times the median residual) only if its residual is also above this, IOD: with clean
    /// points the median is sensor noise, and trimming on noise swaps the point set, and the
    /// pose, from frame to frame. 0 (the default) keeps the pipeline's trim as it was;
    /// `docs/gate.md` has what 0.2 does on depth-repaired Kinect captures.
    pub pose_trim_floor: f32,
    /// The mouth and chin repair (docs/gate.md, "Tears"): an accepted frame whose bottom-region
    /// controls the bounded fit onto ICT's expression shapes leaves more than this far from
    /// the fit at a lip control (IOD) has that control's leftover shrunk to this bound; 0 turns
    /// the repair off.
    pub max_mouth_residual: f32,
    /// ... the same bound for the chin's controls (FDPs 2.1 and 2.10-2.14), IOD; 0: as
    /// `max_mouth_residual`.
    pub max_chin_residual: f32,
}

/// The default of [`GateSettings::max_mouth_residual`], IOD (docs/gate.md, "Tears").
pub const MOUTH_RESIDUAL: f32 = 0.0;
/// The default of [`GateSettings::max_chin_residual`], IOD (docs/gate.md, "Tears").
pub const CHIN_RESIDUAL: f32 = 0.0;

impl Default for GateSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            max_jaw: 0.65,
            max_eye: 0.4,
            max_brow: 0.65,
            max_cheek: 0.65,
            max_lip: 0.65,
            max_other: 0.5,
            max_rotation_deg: 60.0,
            max_turn_speed_dps: 500.0,
            turn_floor_deg: 2.0,
            max_hold_secs: 0.75,
            max_control_speed: 1.8,
            step_floor: 0.005,
            jump_report: 1.0 / 6.303,
            pose_trim_floor: 0.0,
            max_mouth_residual: MOUTH_RESIDUAL,
            max_chin_residual: CHIN_RESIDUAL,
        }
    }
}

impl GateSettings {
    /// The displacement bound (IOD) of a control.
    pub fn bound(&self, fdp: Fdp) -> f32 {
        match fdp.group {
            2 => self.max_jaw,
            3 => self.max_eye,
            4 => self.max_brow,
            5 => self.max_cheek,
            8 => self.max_lip,
            _ => self.max_other,
        }
    }

    /// The displacement bound (IOD) of a control that stands for `fdp` (its group's bound, as
    /// [`Self::bound`]), or of a point control that is no FDP: the loosest bound of its region's
    /// groups (top: eyes and brows; middle: cheeks and nose; bottom: jaw and lips), so a dense
    /// set holds no frame that the FDPs around it would pass.
    pub fn bound_of(&self, fdp: Option<Fdp>, region: Region) -> f32 {
        match (fdp, region) {
            (Some(f), _) => self.bound(f),
            (None, Region::Top) => self.max_eye.max(self.max_brow),
            (None, Region::Middle) => self.max_cheek.max(self.max_other),
            (None, Region::Bottom) => self.max_jaw.max(self.max_lip),
        }
    }
}

/// Why the gate held a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GateReason {
    /// A control moved further from the neutral than its bound.
    Displacement,
    /// The head turned further from the neutral than `max_rotation_deg`.
    Rotation,
    /// The head turned faster than `max_turn_speed_dps` (or has not come back since it did).
    Turn,
}

/// What the gate measured on the last tracked frame (before deciding).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct GateReading {
    /// Largest control displacement over its bound (1 = at the bound).
    pub displacement: f32,
    /// Head rotation from the neutral, degrees.
    pub rotation_deg: f32,
    /// Head rotation since the last accepted frame, degrees.
    pub turn_deg: f32,
    /// Seconds since the last accepted frame.
    pub since_accepted_s: f32,
    /// Seconds since the previous frame.
    pub frame_dt_s: f32,
    /// Seconds since the gate started holding frames; `None` when the previous frame passed.
    pub holding_s: Option<f32>,
    /// Why the frame was held; `None`: it passed.
    pub reason: Option<GateReason>,
}

impl GateReading {
    /// The verdict of `settings` on these readings.
    pub fn judge(&self, settings: &GateSettings) -> Option<GateReason> {
        // While holding after a turn, the head must come back within one frame's turn of the
        // last accepted pose; a free frame may turn as far as the time since then allows.
        let turn_time = match self.holding_s {
            Some(h) if h < settings.max_hold_secs => self.frame_dt_s,
            Some(_) => f32::INFINITY,
            None => self.since_accepted_s,
        };
        // `passes` is false for a NaN reading, so a NaN fails the gate.
        let passes = |x: f32, limit: f32| x <= limit;
        if !passes(self.displacement, 1.0) {
            Some(GateReason::Displacement)
        } else if !passes(self.rotation_deg, settings.max_rotation_deg) {
            Some(GateReason::Rotation)
        } else if !passes(
            self.turn_deg,
            settings.turn_floor_deg + settings.max_turn_speed_dps * turn_time,
        ) {
            Some(GateReason::Turn)
        } else {
            None
        }
    }
}

/// Inter-ocular distance of a face: the distance between the eye centres, each the midpoint of
/// the eye's outer and inner corners (FDPs 3.7 + 3.11 and 3.8 + 3.12). Without those controls,
/// 1.25 times the RMS distance of the controls from their centroid (the ratio on the ICT head is
/// 1.23, on CANDIDE-3 1.32). `None` if that is not positive and finite. `fdps` names each
/// position's FDP (`Fdp`, `Option<Fdp>` for controls that may be none, or rig control names).
pub fn face_size<F: Copy + Into<Option<Fdp>>>(fdps: &[F], positions: &[Vec3]) -> Option<f32> {
    let find = |g: u8, i: u8| {
        fdps.iter()
            .zip(positions)
            .find(|(f, _)| {
                let f: Option<Fdp> = (**f).into();
                f.is_some_and(|f| f.group == g && f.index == i)
            })
            .map(|(_, p)| *p)
    };
    let iod = match (find(3, 7), find(3, 11), find(3, 8), find(3, 12)) {
        (Some(a), Some(b), Some(c), Some(d)) => ((a + b) * 0.5).distance((c + d) * 0.5),
        _ => {
            let m = positions.len().max(1) as f32;
            let centre = positions.iter().fold(Vec3::ZERO, |a, p| a + *p) / m;
            let rms = (positions
                .iter()
                .map(|p| p.distance_squared(centre))
                .sum::<f32>()
                / m)
                .sqrt();
            1.25 * rms
        }
    };
    (iod.is_finite() && iod > 0.0).then_some(iod)
}

/// Angle of a rotation, degrees in [0, 180].
pub(crate) fn angle_deg(q: Quat) -> f32 {
    let w = q.w.abs().min(1.0);
    (2.0 * w.acos()).to_degrees()
}
