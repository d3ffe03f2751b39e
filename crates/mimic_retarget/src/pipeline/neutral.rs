//! The neutral calibration: the first frames averaged, each aligned to the first by its stable
//! points, then the neutral controls and the source-to-target map derived from them.

use super::{FrameOutput, FrameStatus, Retargeter};
use crate::SourceToTarget;
use glam::Vec3;
use mimic_solve::kabsch::fit_similarity;
use mimic_types::layout::mean_of_valid;
use mimic_types::{HeadPose, LandmarkFrame};

/// Neutral being accumulated from the first frames.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Accumulator {
    pub(crate) wanted: usize,
    pub(crate) frames: usize,
    pub(crate) first: Vec<Vec3>,
    pub(crate) first_valid: Vec<bool>,
    pub(crate) sum: Vec<Vec3>,
    pub(crate) count: Vec<u32>,
}

impl Retargeter {
    /// A frame of the neutral calibration: aligned to the first by the stable points and added
    /// in; once enough frames are in, the neutral is fixed ([`Retargeter::finish_neutral`]).
    pub(super) fn calibrate(
        &mut self,
        frame: &LandmarkFrame,
        out: &mut FrameOutput,
    ) -> FrameStatus {
        self.stats.calibrating += 1;
        out.status = FrameStatus::Calibrating;
        out.displacements.iter_mut().for_each(|d| *d = Vec3::ZERO);
        let Some(acc) = self.accumulator.as_mut() else {
            return out.status;
        };
        let p = frame.points.len();
        // Align this frame to the first one by the stable points, then add it in.
        let pose = if acc.frames == 0 {
            for i in 0..p {
                acc.first_valid[i] = frame.is_valid(i);
                acc.first[i] = frame.points[i];
            }
            Some(HeadPose::IDENTITY)
        } else {
            super::pose::gather_stable(
                &self.layout.stable,
                frame,
                (&acc.first, &acc.first_valid),
                (&mut self.stable_src, &mut self.stable_dst),
            );
            fit_similarity(&self.stable_src, &self.stable_dst, false)
        };
        if let Some(pose) = pose {
            for i in 0..p {
                if frame.is_valid(i) {
                    acc.sum[i] += pose.inverse_apply(frame.points[i]);
                    acc.count[i] += 1;
                }
            }
            acc.frames += 1;
        }
        if acc.frames >= acc.wanted {
            for i in 0..p {
                self.neutral_valid[i] = acc.count[i] > 0;
                self.neutral_points[i] = if acc.count[i] > 0 {
                    acc.sum[i] / acc.count[i] as f32
                } else {
                    Vec3::ZERO
                };
            }
            if self.finish_neutral() {
                self.accumulator = None;
                self.last_time_us = Some(frame.timestamp_us);
                self.accepted_time_us = Some(frame.timestamp_us);
            } else if let Some(acc) = self.accumulator.as_mut() {
                // Some control never had a valid point: keep accumulating.
                acc.wanted += 1;
            }
        }
        out.pose = HeadPose::IDENTITY;
        self.deform(out);
        out.status
    }

    /// Derives the neutral controls and the source-to-target map; false if the neutral is unusable.
    pub(super) fn finish_neutral(&mut self) -> bool {
        let neutral = LandmarkFrame {
            timestamp_us: 0,
            points: self.neutral_points.clone(),
            valid: self.neutral_valid.clone(),
            tracked: true,
        };
        for (j, points) in self.source_points.iter().enumerate() {
            match mean_of_valid(points, &neutral) {
                Some(p) => self.neutral_controls[j] = p,
                None => return false,
            }
        }
        let stable_ok = self
            .layout
            .stable
            .iter()
            .filter(|&&i| self.neutral_valid[i])
            .count()
            >= 3;
        self.to_target = SourceToTarget::fit(
            &self.neutral_controls,
            &self.target_controls,
            self.settings.allow_mirror,
            self.settings.per_axis_scale,
        );
        if let Some(s) = &self.to_target {
            tracing::info!(
                scale = s.scale,
                mirrored = s.mirrored,
                rms_residual = s.rms_residual,
                "neutral fixed; source-to-target map fitted"
            );
        }
        // Outliers are judged in target units against the rig's (clean) control spread.
        let m = self.target_controls.len().max(1) as f32;
        let centre = self.target_controls.iter().fold(Vec3::ZERO, |a, p| a + *p) / m;
        let rms_radius = (self
            .target_controls
            .iter()
            .map(|p| p.distance_squared(centre))
            .sum::<f32>()
            / m)
            .sqrt();
        self.outlier_limit = self.settings.outlier_fraction * rms_radius;
        if let Some(g) = self.gaze.as_mut() {
            g.set_neutral(&self.neutral_points, &self.neutral_valid);
        }
        stable_ok && self.to_target.is_some()
    }
}
