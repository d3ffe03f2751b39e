//! Frames not taken as they come: lost frames and frames the plausibility gate refuses, held
//! and eased to neutral; the gate's reading of a frame and the control speed clamp.

use super::{FrameOutput, FrameStatus, Retargeter};
use crate::gate::{GateReading, GateReason, angle_deg};
use crate::{OneEuro, SourceToTarget};
use mimic_types::HeadPose;

impl Retargeter {
    pub(super) fn lost(&mut self, t_us: i64, out: &mut FrameOutput) -> FrameStatus {
        self.stats.lost += 1;
        let since = *self.lost_since_us.get_or_insert(t_us);
        self.gated_since_us = None;
        self.hold_and_ease(since, t_us, out);
        for f in &mut self.filters {
            f.iter_mut().for_each(OneEuro::reset);
        }
        out.pose = self.last_pose;
        out.status = FrameStatus::Lost;
        self.deform(out);
        out.status
    }

    /// `out.displacements`: the last accepted `d`, held `lost_hold_secs` after `since`, then eased
    /// to neutral over `lost_ease_secs`; the gaze likewise.
    pub(super) fn hold_and_ease(&mut self, since: i64, t_us: i64, out: &mut FrameOutput) {
        let elapsed = t_us.saturating_sub(since) as f32 * 1e-6;
        let ease = self.settings.lost_ease_secs.max(1e-6);
        let k = 1.0 - ((elapsed - self.settings.lost_hold_secs) / ease).clamp(0.0, 1.0);
        for (o, d) in out.displacements.iter_mut().zip(&self.last_d) {
            *o = *d * k;
        }
        if let Some(g) = self.gaze.as_mut().filter(|g| g.has_neutral()) {
            self.eye_turn = Some(g.hold(k));
        }
    }

    /// Judges the raw `d` of this frame (in `raw_d`) and its head pose; `Some` holds the frame.
    pub(super) fn gate(&mut self, pose: &HeadPose, t_us: i64) -> Option<GateReason> {
        let g = self.settings.gate;
        let secs = |t: Option<i64>| {
            t.map(|t| (t_us.saturating_sub(t) as f32 * 1e-6).max(0.0))
                .unwrap_or(0.0)
        };
        let mut r = GateReading {
            since_accepted_s: secs(self.accepted_time_us),
            frame_dt_s: secs(self.previous_time_us),
            holding_s: self.gated_since_us.map(|t| secs(Some(t))),
            rotation_deg: angle_deg(pose.rotation),
            turn_deg: angle_deg(pose.rotation * self.accepted_rotation.inverse()),
            ..GateReading::default()
        };
        // The largest ratio squared (a multiply per control by `1 / bound^2`), one square root.
        let mut ratio2 = 0.0f32;
        for (d, inv2) in self.raw_d.iter().zip(&self.gate_inverse_bounds2) {
            ratio2 = ratio2.max(ratio_squared(d.length_squared(), *inv2));
        }
        r.displacement = ratio2.sqrt();
        r.reason = if g.enabled { r.judge(&g) } else { None };
        self.gate_reading = r;
        r.reason
    }

    /// Limits each control's step from the previous output to `gate.max_control_speed` over
    /// the typical frame time; true if some control was clamped.
    pub(super) fn clamp_speed(&self, t_us: i64, out: &mut FrameOutput) -> bool {
        let g = &self.settings.gate;
        // The first frame of a session retargeted against the canonical neutral has no output
        // before it to stay near (a single frame's expression is not a jump from rest).
        if !g.enabled || (self.previous_time_us.is_none() && self.canonical_in_use()) {
            return false;
        }
        let dt = if let Some(typical) = self.typical_interval() {
            typical
        } else {
            self.previous_time_us
                .map(|t| (t_us.saturating_sub(t) as f32 * 1e-6).clamp(0.0, 1.0))
                .unwrap_or(0.0)
        };
        let limit = (g.step_floor + g.max_control_speed * dt) * self.face_size;
        let limit2 = limit * limit;
        let mut clamped = false;
        for (d, p) in out.displacements.iter_mut().zip(&self.previous_out) {
            let step = *d - *p;
            // Compared squared: a square root only for a control that is clamped.
            let len2 = step.length_squared();
            if len2 > limit2 {
                *d = *p + step * (limit / len2.sqrt());
                clamped = true;
            }
        }
        clamped
    }

    /// Median of the intervals seen so far (of the last [`INTERVALS`](super::INTERVALS)), seconds.
    pub(super) fn typical_interval(&self) -> Option<f32> {
        let mut sorted = self.intervals;
        let seen = sorted.iter().filter(|t| **t > 0.0).count();
        if seen == 0 {
            return None;
        }
        sorted.sort_unstable_by(|a, b| b.total_cmp(a));
        Some(sorted[seen / 2])
    }

    /// A tracked frame the gate refused: counted, last expression held then eased, pose held.
    pub(super) fn hold_gated(
        &mut self,
        t_us: i64,
        filled: u32,
        to_target: &SourceToTarget,
        out: &mut FrameOutput,
    ) -> FrameStatus {
        self.stats.tracked += 1;
        self.stats.gated += 1;
        self.stats.filled_controls += u64::from(filled);
        let since = *self.gated_since_us.get_or_insert(t_us);
        self.hold_and_ease(since, t_us, out);
        self.lost_since_us = None;
        out.filled = filled;
        out.pose = self.last_pose;
        out.target_rotation = to_target.rotation_in_target(self.last_pose.rotation);
        out.status = FrameStatus::Tracked;
        self.deform(out);
        out.status
    }
}

/// `x2 / limit^2` from `inverse2 = 1 / limit^2`: 0 when `x2` is 0, infinite past a zero limit
/// (infinite `inverse2`); NaN stays NaN.
fn ratio_squared(x2: f32, inverse2: f32) -> f32 {
    if x2 == 0.0 { 0.0 } else { x2 * inverse2 }
}
