//! A rig's rigid parts: the mouth's insides that ride on the jaw and the eyeballs, each moved
//! per frame as one body (docs/parts.md).
//!
//! A part moves its vertices by `p' = p + w (R - I)(p - pivot) + w t`: a rotation `R` about its
//! pivot and a slide `t`, scaled by a per-vertex weight `w` (1 for a tooth, ramped across the
//! lip line for a piece that holds both the upper and lower gums). That is linear in the four
//! vectors `(R - I) e_x`, `(R - I) e_y`, `(R - I) e_z` and `t`, so each part is four more columns
//! of the rig's basis `B` (rows `w (p - pivot)_x`, `w (p - pivot)_y`, `w (p - pivot)_z`, `w`), and
//! a frame is still `u = B d`: the CPU step, the GPU morph, the viewers and the GLB's morph
//! targets carry the jaw and the eyes with no code of their own.

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Basis columns each rigid part adds.
pub const PART_COLUMNS: usize = 4;

/// The rigid parts of a rig (`[parts]` in a rig file); empty for a rig without any.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RigParts {
    /// The lower jaw's passengers: lower teeth, lower gums and tongue, turned about the hinge.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jaw: Option<JawPart>,
    /// The eyeballs, turned about their centres by the gaze: the subject's left eye first.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eyes: Option<[EyePart; 2]>,
}

/// The vertices the jaw carries and the hinge it turns about (mesh units).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JawPart {
    /// Inclusive vertex ranges that follow the jaw whole (the lower teeth).
    #[serde(default)]
    pub vertices: Vec<[u32; 2]>,
    /// Inclusive vertex ranges cut by the lip line (gums and tongue in one piece): a vertex
    /// follows by `smoothstep` of its height below `cut` over `band` (see [`JawPart::weight`]).
    #[serde(default)]
    pub ramped: Vec<[u32; 2]>,
    /// Height (mesh y) of the cut between what the skull keeps and what the jaw carries.
    #[serde(default)]
    pub cut: f32,
    /// Width of the cut's ramp (mesh units); 0 is a hard cut.
    #[serde(default)]
    pub band: f32,
    /// A point on the hinge axis (between the jaw joints).
    pub hinge: Vec3,
    /// The hinge axis, toward the subject's left (normalised when used).
    #[serde(default = "lateral")]
    pub axis: Vec3,
}

/// One eyeball: its vertices and centre (mesh units).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EyePart {
    /// Inclusive vertex ranges of the eyeball (iris, pupil, sclera).
    pub vertices: Vec<[u32; 2]>,
    /// The centre it turns about.
    pub centre: Vec3,
}

fn lateral() -> Vec3 {
    Vec3::X
}

/// A part that does not fit its rig.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PartError {
    /// A vertex range is reversed or past the mesh.
    #[error("parts.{part}: vertex range [{first}, {last}] is not within 0..{vertex_count}")]
    Range {
        /// `jaw` or `eyes`.
        part: &'static str,
        /// First vertex of the range.
        first: u32,
        /// Last vertex of the range.
        last: u32,
        /// Vertices in the mesh.
        vertex_count: usize,
    },
    /// A pivot, axis, cut or band is not a finite number, the axis zero, or the band negative.
    #[error(
        "parts.{0}: hinge, axis, centre, cut and band must be finite, the axis non-zero, the band >= 0"
    )]
    Number(&'static str),
}

impl JawPart {
    /// The share of the jaw's motion vertex `p` (rest position) takes when it is in `ramped`:
    /// 1 below `cut - band / 2`, 0 above `cut + band / 2`, `smoothstep` between.
    pub fn weight(&self, p: Vec3) -> f32 {
        if self.band <= 0.0 {
            return if p.y < self.cut { 1.0 } else { 0.0 };
        }
        let t = ((self.cut + 0.5 * self.band - p.y) / self.band).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    }

    /// The unit hinge axis ([`Vec3::X`] for a zero axis).
    pub fn unit_axis(&self) -> Vec3 {
        self.axis.try_normalize().unwrap_or(Vec3::X)
    }
}

impl RigParts {
    /// True when the rig has no rigid part.
    pub fn is_empty(&self) -> bool {
        self.jaw.is_none() && self.eyes.is_none()
    }

    /// Basis columns the parts add: four per part (jaw, left eye, right eye).
    pub fn column_count(&self) -> usize {
        PART_COLUMNS * (usize::from(self.jaw.is_some()) + 2 * usize::from(self.eyes.is_some()))
    }

    /// Names of the parts' basis columns, in order: `jaw.turn_x`, `jaw.turn_y`, `jaw.turn_z`,
    /// `jaw.slide`, then `eye_left.*` and `eye_right.*` (a turn column's weights are the
    /// column of `R - I`, the slide's the slide).
    pub fn column_names(&self) -> Vec<String> {
        let mut parts = Vec::new();
        if self.jaw.is_some() {
            parts.push("jaw");
        }
        if self.eyes.is_some() {
            parts.extend(["eye_left", "eye_right"]);
        }
        parts
            .into_iter()
            .flat_map(|p| ["turn_x", "turn_y", "turn_z", "slide"].map(move |c| format!("{p}.{c}")))
            .collect()
    }

    /// Each part's pivot and weighted vertices, in column order (jaw, then the left and right
    /// eye): `(pivot, [(vertex, weight)])`. A vertex named twice in one part counts once.
    pub fn bodies(&self, positions: &[Vec3]) -> Vec<(Vec3, Vec<(u32, f32)>)> {
        let mut out = Vec::new();
        if let Some(jaw) = &self.jaw {
            let mut vs: Vec<(u32, f32)> = Vec::new();
            for &[a, b] in &jaw.vertices {
                vs.extend((a..=b).map(|v| (v, 1.0)));
            }
            for &[a, b] in &jaw.ramped {
                for v in a..=b {
                    if let Some(p) = positions.get(v as usize) {
                        vs.push((v, jaw.weight(*p)));
                    }
                }
            }
            out.push((jaw.hinge, dedup(vs)));
        }
        for eye in self.eyes.iter().flatten() {
            let mut vs: Vec<(u32, f32)> = Vec::new();
            for &[a, b] in &eye.vertices {
                vs.extend((a..=b).map(|v| (v, 1.0)));
            }
            out.push((eye.centre, dedup(vs)));
        }
        out
    }

    /// Checks every range against `vertex_count` and every number.
    pub fn validate(&self, vertex_count: usize) -> Result<(), PartError> {
        let ranges = |part: &'static str, rs: &[[u32; 2]]| {
            rs.iter().try_for_each(|&[first, last]| {
                if first > last || last as usize >= vertex_count {
                    Err(PartError::Range {
                        part,
                        first,
                        last,
                        vertex_count,
                    })
                } else {
                    Ok(())
                }
            })
        };
        if let Some(j) = &self.jaw {
            ranges("jaw", &j.vertices)?;
            ranges("jaw", &j.ramped)?;
            let finite = j.hinge.is_finite() && j.axis.is_finite() && j.cut.is_finite();
            if !finite || j.axis == Vec3::ZERO || !(j.band >= 0.0 && j.band.is_finite()) {
                return Err(PartError::Number("jaw"));
            }
        }
        for e in self.eyes.iter().flatten() {
            ranges("eyes", &e.vertices)?;
            if !e.centre.is_finite() {
                return Err(PartError::Number("eyes"));
            }
        }
        Ok(())
    }
}

/// Sorted by vertex, the first weight of a vertex kept.
fn dedup(mut vs: Vec<(u32, f32)>) -> Vec<(u32, f32)> {
    vs.sort_by_key(|(v, _)| *v);
    vs.dedup_by_key(|(v, _)| *v);
    vs
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jaw() -> JawPart {
        JawPart {
            vertices: vec![[0, 1]],
            ramped: vec![[2, 4]],
            cut: 0.0,
            band: 2.0,
            hinge: Vec3::new(0.0, 1.0, -1.0),
            axis: Vec3::X,
        }
    }

    #[test]
    fn the_ramp_is_a_smoothstep_across_the_cut() {
        let j = jaw();
        assert_eq!(j.weight(Vec3::new(0.0, -1.0, 0.0)), 1.0);
        assert_eq!(j.weight(Vec3::new(0.0, 1.0, 0.0)), 0.0);
        assert!((j.weight(Vec3::ZERO) - 0.5).abs() < 1e-6);
        let hard = JawPart { band: 0.0, ..j };
        assert_eq!(hard.weight(Vec3::new(0.0, -1e-3, 0.0)), 1.0);
        assert_eq!(hard.weight(Vec3::new(0.0, 1e-3, 0.0)), 0.0);
    }

    #[test]
    fn bodies_are_in_column_order_with_their_weights() {
        let eye = |x: f32, v: u32| EyePart {
            vertices: vec![[v, v]],
            centre: Vec3::new(x, 0.0, 0.0),
        };
        let parts = RigParts {
            jaw: Some(jaw()),
            eyes: Some([eye(1.0, 5), eye(-1.0, 6)]),
        };
        assert_eq!(parts.column_count(), 12);
        let names = parts.column_names();
        assert_eq!(names.len(), 12);
        assert_eq!(
            (names[0].as_str(), names[11].as_str()),
            ("jaw.turn_x", "eye_right.slide")
        );
        let pos: Vec<Vec3> = (0..7)
            .map(|k| Vec3::new(0.0, 1.0 - k as f32 * 0.5, 0.0))
            .collect();
        let b = parts.bodies(&pos);
        assert_eq!(b.len(), 3);
        // Vertices 2, 3, 4 sit at y = 0, -0.5, -1: halfway, more, all.
        let w: Vec<f32> = b[0].1.iter().map(|(_, w)| *w).collect();
        assert_eq!(w[..2], [1.0, 1.0]);
        assert!((w[2] - 0.5).abs() < 1e-6 && w[3] > 0.5 && w[4] == 1.0);
        assert_eq!(b[1], (Vec3::X, vec![(5, 1.0)]));
        assert!(parts.validate(7).is_ok());
        assert!(matches!(
            parts.validate(6),
            Err(PartError::Range { part: "eyes", .. })
        ));
        assert_eq!(RigParts::default().column_count(), 0);
    }
}
