//! The neutral calibration: the first frames averaged, each aligned to the first by its stable
//! points, then the neutral controls and the source-to-target map derived from them; meanwhile
//! the provisional neutral (the layout's canonical face), and the ease from it into the calibrated
//! output (docs/replay.md, "Short clips").

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

/// The layout's canonical neutral face, which frames are retargeted against until the performer's
/// neutral is calibrated, and the ease from its output into the calibrated one.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CanonicalNeutral {
    /// The canonical points (the layout's units, e.g. cm).
    points: Vec<Vec3>,
    /// The rig controls' positions on the canonical face.
    controls: Vec<Vec3>,
    /// The canonical controls' map onto the rig's.
    map: SourceToTarget,
    /// Source units per canonical unit (the first frame's similarity fit on the stable points);
    /// 0 until a frame has set it.
    scale: f32,
    /// Whether the retargeter's neutral is the canonical one now.
    in_use: bool,
    /// The ease into the calibrated output: `None` before the switch; then the time of the first
    /// calibrated frame (`None` until it comes) and what it adds to it, eased out.
    ease: Option<Option<i64>>,
    /// The output of the last provisional frame minus the first calibrated one's, per control.
    offset: Vec<Vec3>,
}

impl CanonicalNeutral {
    /// The canonical neutral of `layout` for controls made of `source_points`, mapped onto
    /// `target_controls`; `None` when the layout has none or the map cannot be fitted.
    pub(crate) fn new(
        layout: &mimic_types::Layout,
        source_points: &[Vec<usize>],
        target_controls: &[Vec3],
        allow_mirror: bool,
        per_axis: bool,
    ) -> Option<Self> {
        let points = layout.canonical_neutral.clone()?;
        let controls: Vec<Vec3> = source_points
            .iter()
            .map(|p| p.iter().fold(Vec3::ZERO, |a, i| a + points[*i]) / p.len().max(1) as f32)
            .collect();
        let map = SourceToTarget::fit(&controls, target_controls, allow_mirror, per_axis)?;
        Some(CanonicalNeutral {
            offset: vec![Vec3::ZERO; controls.len()],
            points,
            controls,
            map,
            scale: 0.0,
            in_use: false,
            ease: None,
        })
    }
}

impl Retargeter {
    /// A frame of the neutral calibration: aligned to the first by the stable points and added
    /// in; once enough frames are in, the neutral is fixed ([`Retargeter::finish_neutral`]).
    /// Meanwhile (this frame included) the frame is retargeted against the canonical neutral when
    /// there is one (tracked, counted in `provisional`), else the rest face is shown (calibrating).
    pub(super) fn calibrate(
        &mut self,
        frame: &LandmarkFrame,
        out: &mut FrameOutput,
    ) -> FrameStatus {
        let enough = self.add_to_neutral(frame);
        let status = if self.use_canonical(frame) {
            let status = self.track(frame, out);
            if status == FrameStatus::Tracked {
                self.stats.provisional += 1;
            }
            status
        } else {
            self.stats.calibrating += 1;
            out.status = FrameStatus::Calibrating;
            out.displacements.iter_mut().for_each(|d| *d = Vec3::ZERO);
            out.pose = HeadPose::IDENTITY;
            self.deform(out);
            out.status
        };
        if enough {
            self.fix_neutral(frame.timestamp_us);
        }
        status
    }

    /// Adds `frame` to the neutral being averaged; true when enough frames are in.
    fn add_to_neutral(&mut self, frame: &LandmarkFrame) -> bool {
        let Some(acc) = self.accumulator.as_mut() else {
            return false;
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
        acc.frames >= acc.wanted
    }

    /// Fixes the neutral from the frames averaged (the last at `t_us`), or waits for one more
    /// frame when some control never had a valid point.
    fn fix_neutral(&mut self, t_us: i64) {
        let Some(acc) = self.accumulator.as_mut() else {
            return;
        };
        for i in 0..acc.count.len() {
            self.neutral_valid[i] = acc.count[i] > 0;
            self.neutral_points[i] = if acc.count[i] > 0 {
                acc.sum[i] / acc.count[i] as f32
            } else {
                Vec3::ZERO
            };
        }
        if self.finish_neutral() {
            self.accumulator = None;
            self.last_time_us = Some(t_us);
            self.accepted_time_us = Some(t_us);
            self.leave_canonical();
            return;
        }
        if let Some(acc) = self.accumulator.as_mut() {
            // Some control never had a valid point: keep accumulating.
            acc.wanted += 1;
        }
        if let Some(c) = self.canonical.as_mut() {
            // `finish_neutral` overwrote the canonical neutral: put it back on the next frame.
            c.in_use = false;
        }
    }

    /// Makes the canonical neutral the retargeter's (scaled to the performer by `frame`'s stable
    /// points the first time); false when there is none or it cannot be scaled yet.
    fn use_canonical(&mut self, frame: &LandmarkFrame) -> bool {
        if self.canonical_in_use() {
            return true;
        }
        let limit = self.outlier_limit();
        let Some(c) = self.canonical.as_mut() else {
            return false;
        };
        if c.scale <= 0.0 {
            self.stable_src.clear();
            self.stable_dst.clear();
            for &i in &self.layout.stable {
                if frame.is_valid(i) {
                    self.stable_src.push(c.points[i]);
                    self.stable_dst.push(frame.points[i]);
                }
            }
            match fit_similarity(&self.stable_src, &self.stable_dst, true) {
                Some(p) if p.scale.is_finite() && p.scale > 0.0 => {
                    c.scale = p.scale;
                    // The gate measures turns from the first frame's head, not the canonical one's.
                    self.accepted_rotation = p.rotation;
                }
                _ => return false,
            }
        }
        let s = c.scale;
        for (n, p) in self.neutral_points.iter_mut().zip(&c.points) {
            *n = *p * s;
        }
        self.neutral_valid.iter_mut().for_each(|v| *v = true);
        for (n, p) in self.neutral_controls.iter_mut().zip(&c.controls) {
            *n = *p * s;
        }
        self.to_target = Some(SourceToTarget {
            linear: c.map.linear / s,
            scale: c.map.scale / s,
            ..c.map
        });
        self.outlier_limit = limit;
        if let Some(g) = self.gaze.as_mut() {
            g.set_neutral(&self.neutral_points, &self.neutral_valid);
        }
        c.in_use = true;
        true
    }

    /// After the calibrated neutral replaced the canonical one: the per-frame state that was
    /// relative to the canonical face is reset, and the ease into the calibrated output armed.
    fn leave_canonical(&mut self) {
        let Some(c) = self.canonical.as_mut() else {
            return;
        };
        if !std::mem::take(&mut c.in_use) {
            return;
        }
        c.ease = Some(None);
        for f in &mut self.filters {
            f.iter_mut().for_each(crate::OneEuro::reset);
        }
        self.last_e.iter_mut().for_each(|e| *e = Vec3::ZERO);
        self.accepted_rotation = glam::Quat::IDENTITY;
        self.gated_since_us = None;
        self.last_pose = HeadPose::IDENTITY;
        self.eye_turn = None;
    }

    /// Eases the calibrated output from the last provisional one: on the first calibrated frame
    /// the difference is taken, then added back fading linearly to nothing over `lost_ease_secs`.
    pub(super) fn ease_from_canonical(&mut self, t_us: i64, out: &mut FrameOutput) {
        let ease_secs = self.settings.lost_ease_secs;
        let Some(c) = self.canonical.as_mut() else {
            return;
        };
        let Some(since) = c.ease else {
            return;
        };
        let m = c.offset.len();
        let since = match since {
            Some(t) => t,
            None => {
                for ((o, p), d) in c
                    .offset
                    .iter_mut()
                    .zip(&self.previous_out)
                    .zip(&out.displacements)
                {
                    *o = *p - *d;
                }
                c.ease = Some(Some(t_us));
                t_us
            }
        };
        let k =
            1.0 - (t_us.saturating_sub(since) as f32 * 1e-6 / ease_secs.max(1e-6)).clamp(0.0, 1.0);
        if k <= 0.0 {
            c.ease = None;
            return;
        }
        for (d, o) in out.displacements[..m].iter_mut().zip(&c.offset) {
            *d += *o * k;
        }
    }

    /// Whether frames are retargeted against the canonical neutral now.
    pub(super) fn canonical_in_use(&self) -> bool {
        self.canonical.as_ref().is_some_and(|c| c.in_use)
    }

    /// Target-space displacements longer than this are outliers: a fraction of the rig controls'
    /// RMS radius.
    fn outlier_limit(&self) -> f32 {
        let m = self.target_controls.len().max(1) as f32;
        let centre = self.target_controls.iter().fold(Vec3::ZERO, |a, p| a + *p) / m;
        let rms_radius = (self
            .target_controls
            .iter()
            .map(|p| p.distance_squared(centre))
            .sum::<f32>()
            / m)
            .sqrt();
        self.settings.outlier_fraction * rms_radius
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
        self.outlier_limit = self.outlier_limit();
        if let Some(g) = self.gaze.as_mut() {
            g.set_neutral(&self.neutral_points, &self.neutral_valid);
        }
        stable_ok && self.to_target.is_some()
    }
}
