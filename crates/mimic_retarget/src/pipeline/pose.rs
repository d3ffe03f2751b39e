//! The head pose of a tracked frame: a similarity fit on the layout's stable points, refitted
//! without the points it does not explain.

use super::Retargeter;
use glam::{Affine3A, Vec3};
use mimic_solve::kabsch::fit_similarity;
use mimic_types::{HeadPose, LandmarkFrame};

impl Retargeter {
    /// Head pose from the stable pairs in `stable_src`/`stable_dst`, refitted once without pairs whose
    /// residual exceeds `stable_trim` times the median residual (if at least 3 remain).
    pub(super) fn robust_pose(&mut self) -> Option<HeadPose> {
        let pose = fit_similarity(&self.stable_src, &self.stable_dst, false)?;
        self.stable_residual.clear();
        // The pose as one affine map: a matrix product per point, not a quaternion product.
        let forward = Affine3A::from_scale_rotation_translation(
            Vec3::splat(pose.scale),
            pose.rotation,
            pose.translation,
        );
        for (s, d) in self.stable_src.iter().zip(&self.stable_dst) {
            self.stable_residual
                .push(forward.transform_point3(*s).distance(*d));
        }
        let k = self.stable_residual.len();
        self.stable_sorted.clear();
        self.stable_sorted.extend_from_slice(&self.stable_residual);
        // The median (the upper one for even k) by selection, not a full sort.
        let (_, median, _) = self
            .stable_sorted
            .select_nth_unstable_by(k / 2, f32::total_cmp);
        let mut limit = self.settings.stable_trim * *median;
        let floor = self.pose_trim_floor();
        if floor > 0.0 {
            limit = limit.max(floor);
        }
        let keep = self.stable_residual.iter().filter(|r| **r <= limit).count();
        if keep == k || keep < 3 {
            return Some(pose);
        }
        let mut w = 0;
        for r in 0..k {
            if self.stable_residual[r] <= limit {
                self.stable_src[w] = self.stable_src[r];
                self.stable_dst[w] = self.stable_dst[r];
                w += 1;
            }
        }
        self.stable_src.truncate(w);
        self.stable_dst.truncate(w);
        fit_similarity(&self.stable_src, &self.stable_dst, false).or(Some(pose))
    }

    /// Residual (source units) below which a stable point is never trimmed from the head pose:
    /// `gate.pose_trim_floor` IODs of the face, 0 with the gate off (`docs/gate.md`).
    pub(super) fn pose_trim_floor(&self) -> f32 {
        let g = &self.settings.gate;
        match self.to_target {
            Some(t) if g.enabled && t.scale > 0.0 && self.face_size.is_finite() => {
                g.pose_trim_floor * self.face_size / t.scale
            }
            _ => 0.0,
        }
    }
}

/// Fills `src` / `dst` with the stable points valid both in `frame` and in `reference` (points,
/// validity): the pairs a head pose is fitted to.
pub(super) fn gather_stable(
    stable: &[usize],
    frame: &LandmarkFrame,
    (points, valid): (&[Vec3], &[bool]),
    (src, dst): (&mut Vec<Vec3>, &mut Vec<Vec3>),
) {
    src.clear();
    dst.clear();
    for &i in stable {
        if frame.is_valid(i) && valid[i] {
            src.push(points[i]);
            dst.push(frame.points[i]);
        }
    }
}
