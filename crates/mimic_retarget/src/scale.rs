//! The map from the performer's face (source units and axes) to the target's: `d = S e`.

use glam::{Mat3, Quat, Vec3};
use mimic_solve::kabsch::fit_similarity;

/// Linear map taking a source displacement to a target displacement.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
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
    /// Controls left out of the fit as outliers.
    pub outliers: usize,
}

const MIRROR_X: Mat3 = Mat3::from_cols(Vec3::NEG_X, Vec3::Y, Vec3::Z);

fn rms(residuals: &[f32]) -> f32 {
    (residuals.iter().map(|r| r * r).sum::<f32>() / residuals.len().max(1) as f32).sqrt()
}

fn spread(points: impl Iterator<Item = Vec3> + Clone) -> Vec3 {
    let n = points.clone().count().max(1) as f32;
    let mean = points.clone().fold(Vec3::ZERO, |a, p| a + p) / n;
    (points.fold(Vec3::ZERO, |a, p| a + (p - mean) * (p - mean)) / n).map(f32::sqrt)
}

impl SourceToTarget {
    /// Fits the map from the neutral source controls to the rest target controls (same order).
    ///
    /// Robust to a few bad pairs (e.g. a source point whose depth hit the background): every
    /// triple of pairs (or an evenly spread subset of 20,000 triples) proposes a similarity, the
    /// one with the most pairs within 15 % of the target's RMS radius wins, and the map is refitted
    /// on those inliers. With `allow_mirror`, the x-mirrored source competes too and wins only
    /// with more inliers, or as many and a clearly (20 %) smaller residual.
    /// `None` if fewer than 3 pairs or the points are degenerate (all on one line).
    pub fn fit(
        source: &[Vec3],
        target: &[Vec3],
        allow_mirror: bool,
        per_axis: bool,
    ) -> Option<Self> {
        let m = source.len().min(target.len());
        if m < 3 {
            return None;
        }
        let (source, target) = (&source[..m], &target[..m]);
        let centre = target.iter().fold(Vec3::ZERO, |a, p| a + *p) / m as f32;
        let radius = (target
            .iter()
            .map(|p| p.distance_squared(centre))
            .sum::<f32>()
            / m as f32)
            .sqrt();
        let tolerance = 0.15 * radius;
        let direct = Self::consensus(source, target, Mat3::IDENTITY, tolerance, per_axis)?;
        let mut best = direct;
        if allow_mirror
            && let Some(mirrored) = Self::consensus(source, target, MIRROR_X, tolerance, per_axis)
        {
            let more = mirrored.outliers < best.outliers;
            let as_many_and_tighter = mirrored.outliers == best.outliers
                && mirrored.rms_residual < 0.8 * best.rms_residual;
            if more || as_many_and_tighter {
                best = mirrored;
            }
        }
        Some(best)
    }

    /// The consensus fit of `mirror * source` onto `target` (see [`SourceToTarget::fit`]).
    fn consensus(
        source: &[Vec3],
        target: &[Vec3],
        mirror: Mat3,
        tolerance: f32,
        per_axis: bool,
    ) -> Option<Self> {
        let m = source.len();
        let src: Vec<Vec3> = source.iter().map(|p| mirror * *p).collect();
        let triples = m * (m - 1) * (m - 2) / 6;
        let stride = triples.div_ceil(20_000).max(1);
        let mut best: Option<(usize, f32, mimic_types::HeadPose)> = None;
        let mut index = 0usize;
        for i in 0..m {
            for j in i + 1..m {
                for k in j + 1..m {
                    index += 1;
                    if !index.is_multiple_of(stride) {
                        continue;
                    }
                    let Some(pose) = fit_similarity(
                        &[src[i], src[j], src[k]],
                        &[target[i], target[j], target[k]],
                        true,
                    ) else {
                        continue;
                    };
                    let (count, sum) =
                        src.iter()
                            .zip(target)
                            .fold((0usize, 0f32), |(c, s), (p, t)| {
                                let r = pose.apply(*p).distance(*t);
                                if r < tolerance {
                                    (c + 1, s + r)
                                } else {
                                    (c, s)
                                }
                            });
                    if best.is_none_or(|(c, s, _)| count > c || (count == c && sum < s)) {
                        best = Some((count, sum, pose));
                    }
                }
            }
        }
        let (_, _, pose) = best?;
        let inliers: Vec<usize> = (0..m)
            .filter(|&k| pose.apply(src[k]).distance(target[k]) < tolerance)
            .collect();
        let (s_in, t_in): (Vec<Vec3>, Vec<Vec3>) = if inliers.len() >= 3 {
            inliers.iter().map(|&k| (src[k], target[k])).unzip()
        } else {
            (src.clone(), target.to_vec())
        };
        let pose = fit_similarity(&s_in, &t_in, true)?;
        let residual: Vec<f32> = s_in
            .iter()
            .zip(&t_in)
            .map(|(p, t)| pose.apply(*p).distance(*t))
            .collect();
        let similarity = Mat3::from_quat(pose.rotation) * pose.scale * mirror;
        let axis = if per_axis {
            let s_src = spread(
                s_in.iter()
                    .map(|p| Mat3::from_quat(pose.rotation) * pose.scale * *p),
            );
            let s_tgt = spread(t_in.iter().copied());
            Vec3::select(s_src.cmpgt(Vec3::splat(1e-12)), s_tgt / s_src, Vec3::ONE)
        } else {
            Vec3::ONE
        };
        Some(Self {
            linear: Mat3::from_diagonal(axis) * similarity,
            scale: pose.scale,
            rotation: pose.rotation,
            mirrored: mirror != Mat3::IDENTITY,
            axis,
            rms_residual: rms(&residual),
            outliers: m - s_in.len(),
        })
    }

    /// Maps a source displacement to the target.
    pub fn apply(&self, e: Vec3) -> Vec3 {
        self.linear * e
    }

    /// Expresses a source-space head rotation in target axes: `A R(r) A^-1` for the source's
    /// axes `A = R(rotation) M` (`M` the x mirror when mirrored), as a quaternion product. A
    /// mirror turns a rotation about `(x, y, z)` into one about `(-x, y, z)` by the opposite
    /// angle, quaternion `(x, -y, -z, w)`; so `q r' q^-1`, two products and no matrix.
    pub fn rotation_in_target(&self, r: Quat) -> Quat {
        let r = if self.mirrored {
            Quat::from_xyzw(r.x, -r.y, -r.z, r.w)
        } else {
            r
        };
        let q = self.rotation.normalize();
        (q * r * q.conjugate()).normalize()
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
    fn rotation_in_target_is_the_rotation_seen_in_target_axes() {
        // Independent truth: the matrix `A R A^-1` in f64, `A = R(rotation) M`.
        let mut seed = 11u64;
        let mut unit = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        };
        for k in 0..200 {
            let mut random_quat =
                || Quat::from_xyzw(unit(), unit(), unit(), unit() + 1e-3).normalize();
            let map = SourceToTarget {
                rotation: random_quat(),
                mirrored: k % 2 == 1,
                linear: Mat3::IDENTITY,
                scale: 1.0,
                axis: Vec3::ONE,
                rms_residual: 0.0,
                outliers: 0,
            };
            let r = random_quat();
            let a = glam::DMat3::from_quat(map.rotation.as_dquat())
                * if map.mirrored {
                    MIRROR_X.as_dmat3()
                } else {
                    glam::DMat3::IDENTITY
                };
            let want = a * glam::DMat3::from_quat(r.as_dquat()) * a.inverse();
            let got = glam::DMat3::from_quat(map.rotation_in_target(r).as_dquat());
            // Two quaternion products and two normalisations in f32, then the matrix: a few
            // eps per entry of a rotation matrix (entries at most 1).
            let err = (got - want).to_cols_array().map(f64::abs);
            let err = err.iter().cloned().fold(0.0, f64::max);
            assert!(err <= 16.0 * f32::EPSILON as f64, "case {k}: error {err:e}");
        }
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
        assert!(!no.mirrored && no.rms_residual > 10.0 * s.rms_residual.max(1e-3));
    }

    #[test]
    fn an_outlier_pair_does_not_bend_the_fit() {
        let target = face();
        let mut source: Vec<Vec3> = target.iter().map(|p| *p * 0.01).collect();
        source[2].z -= 0.5; // a depth sample that hit the background, 50 face-units away
        let s = SourceToTarget::fit(&source, &target, false, false).unwrap();
        assert_eq!(s.outliers, 1);
        // Without the outlier the fit is exact: scale 100 up to f32 rounding.
        assert!((s.scale - 100.0).abs() < 0.01, "{}", s.scale);
    }

    #[test]
    fn per_axis_matches_extents() {
        let target = face();
        let source: Vec<Vec3> = target
            .iter()
            .map(|p| Vec3::new(p.x * 1.1, p.y, p.z * 0.9))
            .collect();
        let s = SourceToTarget::fit(&source, &target, false, true).unwrap();
        // Spreads of S*source equal the target's spreads per axis, up to f32 rounding.
        let mapped: Vec<Vec3> = source.iter().map(|p| s.linear * *p).collect();
        let a = spread(mapped.iter().copied());
        let b = spread(target.iter().copied());
        assert!((a - b).abs().max_element() < 1e-4, "{a} vs {b}");
    }
}
