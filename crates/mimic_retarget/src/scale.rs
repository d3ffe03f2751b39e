//! The map from the performer's face (source units and axes) to the target's: `d = S e`.

use glam::{Mat3, Quat, Vec3};
use mimic_solve::kabsch::fit_similarity;

/// Linear map taking a source displacement to a target displacement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SourceToTarget {
    /// `S = diag(axis) * scale * rotation * mirror`.
    pub linear: Mat3,
    /// Uniform scale from the similarity fit (target units per source unit).
    pub scale: f32,
    /// Rotation from source axes to target axes.
    pub rotation: Quat,
    /// Whether the source was mirrored in x before the fit.
    pub mirrored: bool,
    /// Per-axis extent ratios applied after the similarity (all 1 when off).
    pub axis: Vec3,
    /// RMS distance between mapped source controls and target controls after the fit (target units).
    pub rms_residual: f32,
}

const MIRROR_X: Mat3 = Mat3::from_cols(Vec3::NEG_X, Vec3::Y, Vec3::Z);

fn rms(a: &[Vec3], b: &[Vec3]) -> f32 {
    let sum: f32 = a.iter().zip(b).map(|(p, q)| p.distance_squared(*q)).sum();
    (sum / a.len().max(1) as f32).sqrt()
}

fn spread(points: impl Iterator<Item = Vec3> + Clone) -> Vec3 {
    let n = points.clone().count().max(1) as f32;
    let mean = points.clone().fold(Vec3::ZERO, |a, p| a + p) / n;
    (points.fold(Vec3::ZERO, |a, p| a + (p - mean) * (p - mean)) / n).map(f32::sqrt)
}

impl SourceToTarget {
    /// Fits the map from the neutral source controls to the rest target controls (same order).
    ///
    /// `None` if fewer than 3 pairs or the points are degenerate (all on one line).
    pub fn fit(
        source: &[Vec3],
        target: &[Vec3],
        allow_mirror: bool,
        per_axis: bool,
    ) -> Option<Self> {
        let direct = fit_similarity(source, target, true)?;
        let mapped = |pose: &mimic_types::HeadPose,
                      pts: &mut dyn Iterator<Item = Vec3>|
         -> Vec<Vec3> { pts.map(|p| pose.apply(p)).collect() };
        let direct_rms = rms(&mapped(&direct, &mut source.iter().copied()), target);
        let mut best = (direct, direct_rms, false);
        if allow_mirror {
            let flipped: Vec<Vec3> = source.iter().map(|p| MIRROR_X * *p).collect();
            if let Some(m) = fit_similarity(&flipped, target, true) {
                let m_rms = rms(&mapped(&m, &mut flipped.iter().copied()), target);
                // Prefer the unmirrored fit unless the mirrored one is clearly better.
                if m_rms < 0.8 * direct_rms {
                    best = (m, m_rms, true);
                }
            }
        }
        let (pose, rms_residual, mirrored) = best;
        let similarity = Mat3::from_quat(pose.rotation)
            * pose.scale
            * if mirrored { MIRROR_X } else { Mat3::IDENTITY };
        let axis = if per_axis {
            let s_src = spread(source.iter().map(|p| similarity * *p));
            let s_tgt = spread(target.iter().copied());
            Vec3::select(s_src.cmpgt(Vec3::splat(1e-12)), s_tgt / s_src, Vec3::ONE)
        } else {
            Vec3::ONE
        };
        Some(Self {
            linear: Mat3::from_diagonal(axis) * similarity,
            scale: pose.scale,
            rotation: pose.rotation,
            mirrored,
            axis,
            rms_residual,
        })
    }

    /// Maps a source displacement to the target.
    pub fn apply(&self, e: Vec3) -> Vec3 {
        self.linear * e
    }

    /// Expresses a source-space head rotation in target axes.
    pub fn rotation_in_target(&self, r: Quat) -> Quat {
        let basis = Mat3::from_quat(self.rotation)
            * if self.mirrored {
                MIRROR_X
            } else {
                Mat3::IDENTITY
            };
        let m = basis * Mat3::from_quat(r) * basis.inverse();
        Quat::from_mat3(&m).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn face() -> Vec<Vec3> {
        vec![
            Vec3::new(-3.0, 2.0, 0.5),
            Vec3::new(3.0, 2.0, 0.5),
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(-2.0, -2.5, 0.8),
            Vec3::new(2.0, -2.5, 0.8),
            Vec3::new(0.0, -4.0, 0.6),
            Vec3::new(1.0, 3.0, 0.0),
        ]
    }

    #[test]
    fn recovers_scale_and_rotation() {
        let target = face();
        let r = Quat::from_rotation_y(0.4) * Quat::from_rotation_x(-0.2);
        // source = R^-1 (target / 10) + t, so S = 10 R.
        let source: Vec<Vec3> = target
            .iter()
            .map(|p| r.inverse() * (*p / 10.0) + Vec3::new(0.1, 0.2, -0.7))
            .collect();
        let s = SourceToTarget::fit(&source, &target, true, false).unwrap();
        assert!(!s.mirrored);
        assert!((s.scale - 10.0).abs() < 1e-3, "{}", s.scale);
        // Tolerance: f32 rounding of the fit, ~1e-5 relative of |e| = 1.
        let e = Vec3::new(0.01, -0.02, 0.03);
        assert!((s.apply(e) - r * (e * 10.0)).length() < 1e-4);
        assert!(s.rms_residual < 1e-4);
    }

    #[test]
    fn detects_a_mirrored_source() {
        let target = face();
        let source: Vec<Vec3> = target.iter().map(|p| MIRROR_X * *p * 0.01).collect();
        let s = SourceToTarget::fit(&source, &target, true, false).unwrap();
        assert!(s.mirrored);
        let e = Vec3::new(0.001, 0.0, 0.0);
        // Mirrored: +x in the source is -x in the target, times the scale of 100.
        assert!((s.apply(e) - Vec3::new(-0.1, 0.0, 0.0)).length() < 1e-4);
        let no = SourceToTarget::fit(&source, &target, false, false).unwrap();
        assert!(!no.mirrored && no.rms_residual > 0.5);
    }

    #[test]
    fn per_axis_matches_extents() {
        let target = face();
        let source: Vec<Vec3> = target
            .iter()
            .map(|p| Vec3::new(p.x * 2.0, p.y, p.z))
            .collect();
        let s = SourceToTarget::fit(&source, &target, false, true).unwrap();
        // Spreads of S*source equal the target's spreads per axis, up to f32 rounding.
        let mapped: Vec<Vec3> = source.iter().map(|p| s.linear * *p).collect();
        let a = spread(mapped.iter().copied());
        let b = spread(target.iter().copied());
        assert!((a - b).abs().max_element() < 1e-4, "{a} vs {b}");
    }
}
