//! What a step is timed and counted by: its stages ([`Stage`], [`StageTimes`]) and the
//! retargeter's counters over its life ([`Stats`]).

/// Stages of a step, in order, for per-stage timing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Control points from landmarks.
    Select,
    /// Rigid head motion removed.
    Stabilise,
    /// Displacement against the neutral, scaled to the target, filtered.
    Displace,
    /// `u = B d`.
    Deform,
    /// Vertex normals.
    Normals,
}

impl Stage {
    /// All stages in pipeline order.
    pub const ALL: [Stage; 5] = [
        Stage::Select,
        Stage::Stabilise,
        Stage::Displace,
        Stage::Deform,
        Stage::Normals,
    ];

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Select => "select",
            Stage::Stabilise => "stabilise",
            Stage::Displace => "displace",
            Stage::Deform => "deform",
            Stage::Normals => "normals",
        }
    }
}

/// Nanoseconds spent in each [`Stage`] of the last step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StageTimes(pub [u32; 5]);

impl StageTimes {
    /// Nanoseconds of one stage.
    pub fn get(&self, s: Stage) -> u32 {
        self.0[s as usize]
    }
}

/// Counters over a retargeter's life.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Stats {
    /// Frames given to `step`.
    pub frames: u64,
    /// Frames spent building the neutral, showing the rest face.
    pub calibrating: u64,
    /// Frames retargeted.
    pub tracked: u64,
    /// Frames with lost tracking or too few stable points.
    pub lost: u64,
    /// Tracked frames rejected for a wrong point count (lost frames are never rejected).
    pub rejected: u64,
    /// Controls filled (held) because none of their points was valid, summed over frames.
    pub filled_controls: u64,
    /// Tracked frames the plausibility gate held (counted in `tracked` too; `docs/gate.md`).
    pub gated: u64,
    /// Tracked frames in which the gate clamped some control's speed.
    pub clamped: u64,
    /// Tracked frames whose output moved some control more than `gate.jump_report` (IOD)
    /// since the previous frame.
    pub jumps: u64,
    /// Tracked frames retargeted against the layout's canonical neutral while the performer's
    /// was being calibrated (counted in `tracked` too; docs/replay.md, "Short clips").
    #[serde(default)]
    pub provisional: u64,
    /// Tracked frames whose mouth and chin the repair pulled toward the plausible subspace
    /// (`GateSettings::max_mouth_residual`, docs/gate.md "Tears").
    #[serde(default)]
    pub repaired: u64,
}
