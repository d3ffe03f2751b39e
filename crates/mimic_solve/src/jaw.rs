//! The jaw read from the chin (docs/parts.md): its turn about the rig's hinge and its slide, from
//! the chin controls' displacements ([`JawReader`], what the per-frame path does), and the same
//! carried into morph targets that leave the jaw's passengers (lower teeth, gums, tongue) behind
//! ([`carry_jaw`]), so that a blend of targets, here or in any glTF viewer, opens the teeth with
//! the chin.

use crate::normals::vertex_normals;
use glam::{Mat3, Vec3};
use mimic_types::{Fdp, MorphTarget, Rig};

/// The jaw opens at most this far (radians, 40 degrees) and never closes past its rest (the
/// teeth meet there: a chin pushed up or forward by the skin alone, a chin raiser or a tracker's
/// stray chin point, would drive the lower teeth through the upper ones and the lip).
pub const JAW_OPEN: f32 = 0.70;
/// How far past its rest a jaw may close (radians).
pub const JAW_CLOSE: f32 = 0.0;
/// The slide (the chin's sideways motion, along the hinge axis, that the turn does not explain) is
/// at most this share of the chin's distance from the hinge (1.5 cm on ICT). Only sideways: the
/// chin's skin moves forward and back on its own (a pout, a chin raiser, a raw tracker's stray
/// chin point pushed the chin 1.7 cm forward on `a_yn_question`), far more than the bone
/// protrudes, and a slide forward drove the lower teeth through the lip.
pub const MAX_SLIDE: f32 = 0.1;
/// A target "leaves the jaw's passengers behind" when none of the vertices the jaw carries whole
/// moves by more than this share of its largest chin motion ([`carry_jaw`]).
pub const LEFT_BEHIND: f32 = 0.05;
/// A target whose chin moves less than this share of the chin's distance from the hinge (1 mm on
/// ICT; a turn under 0.6 degrees) does not move the jaw: a blink's or a brow's stray chin motion
/// ([`carry_jaw`]).
pub const MIN_CHIN: f32 = 0.01;

/// One chin control: its index among the rig's controls and its rest offset from the hinge.
#[derive(Clone, Copy, Debug)]
struct Chin {
    control: usize,
    from_hinge: Vec3,
}

/// The jaw's hinge and the chin controls it is read from.
#[derive(Clone, Debug)]
pub struct JawReader {
    hinge_axis: Vec3,
    chins: Vec<Chin>,
}

impl JawReader {
    /// The reader of `rig`'s jaw, whose controls stand for `fdps` (`None`: no FDP): the chin
    /// (FDP 2.1, and 2.10 the chin boss), or the lower lip's middle (2.3, 8.2) when the rig
    /// drives no chin. `None` when the rig has no jaw or none of those controls.
    pub fn new(rig: &Rig, fdps: &[Option<Fdp>]) -> Option<Self> {
        let jaw = rig.parts.jaw.as_ref()?;
        let pick = |names: &[&str]| -> Vec<Chin> {
            rig.controls
                .iter()
                .enumerate()
                .filter(|(j, _)| {
                    fdps.get(*j)
                        .copied()
                        .flatten()
                        .is_some_and(|f| names.iter().any(|n| f.to_string() == *n))
                })
                .filter_map(|(control, c)| {
                    let p = rig.mesh.positions.get(c.vertex as usize)?;
                    Some(Chin {
                        control,
                        from_hinge: *p - jaw.hinge,
                    })
                })
                .collect()
        };
        let mut chins = pick(&["2.1", "2.10"]);
        if chins.is_empty() {
            chins = pick(&["2.3", "8.2"]);
        }
        (!chins.is_empty()).then(|| JawReader {
            hinge_axis: jaw.unit_axis(),
            chins,
        })
    }

    /// The jaw's turn about the hinge and its slide, from the controls' displacements `d`: the
    /// mean angle each chin swings about the hinge axis (in the plane across the axis), clamped
    /// to `[-JAW_CLOSE, JAW_OPEN]`, then the mean of what the turn leaves unexplained along the
    /// axis (sideways), at most [`MAX_SLIDE`] of the chin's reach. Allocation-free.
    pub fn motion(&self, d: &[Vec3]) -> (Mat3, Vec3) {
        let a = self.hinge_axis;
        let across = |v: Vec3| v - a * a.dot(v);
        let mut angle = 0.0;
        let mut reach = 0.0;
        let at = |c: &Chin| d.get(c.control).copied().unwrap_or(Vec3::ZERO);
        for c in &self.chins {
            let r0 = across(c.from_hinge);
            let r1 = across(c.from_hinge + at(c));
            angle += a.dot(r0.cross(r1)).atan2(r0.dot(r1));
            reach += c.from_hinge.length();
        }
        let count = self.chins.len() as f32;
        let angle = (angle / count).clamp(-JAW_CLOSE, JAW_OPEN);
        let reach = reach / count;
        // Opening moves the chin down and back: a turn about +x (the subject's left) by a
        // positive angle for a chin in front of and below the hinge.
        let turn = Mat3::from_axis_angle(a, angle);
        let mut slide = Vec3::ZERO;
        for c in &self.chins {
            slide += c.from_hinge + at(c) - turn * c.from_hinge;
        }
        let limit = MAX_SLIDE * reach;
        let slide = a * (a.dot(slide) / count).clamp(-limit, limit);
        (turn, slide)
    }

    /// The chin controls' mean distance from the hinge.
    fn reach(&self) -> f32 {
        self.chins
            .iter()
            .map(|c| c.from_hinge.length())
            .sum::<f32>()
            / self.chins.len() as f32
    }

    /// How far the jaw's motion `(turn, slide)` moves the farthest-moved chin control.
    fn carried_chin(&self, turn: Mat3, slide: Vec3) -> f32 {
        self.chins
            .iter()
            .map(|c| (turn * c.from_hinge - c.from_hinge + slide).length())
            .fold(0.0, f32::max)
    }

    /// The largest displacement among the chin controls of `d`.
    fn chin_motion(&self, d: &[Vec3]) -> f32 {
        self.chins
            .iter()
            .filter_map(|c| d.get(c.control))
            .map(|v| v.length())
            .fold(0.0, f32::max)
    }
}

/// Carries the jaw into `targets` (deltas on `rig`'s mesh): a target that moves the chin, and
/// whose jaw motion read from it moves the chin, by at least [`MIN_CHIN`] of its reach, but
/// leaves the vertices the jaw carries whole still (within [`LEFT_BEHIND`] of the chin's motion;
/// ICT-FaceKit's own expression shapes do) gets, on every vertex of the rig's jaw part, the
/// jaw's motion read from the target's chin ([`JawReader::motion`]) in the share the part gives
/// it (1 for the lower teeth, the ramp's weight for gums and tongue): `delta <- (1 - w) delta +
/// w ((R - I)(p - hinge) + slide)`, normals turned alike. Targets that move the passengers
/// themselves are kept as they are. Controls stand for their own FDPs. Returns the names of the
/// targets changed.
pub fn carry_jaw(rig: &Rig, targets: &mut [MorphTarget]) -> Vec<String> {
    let Some(jaw) = rig.parts.jaw.as_ref() else {
        return Vec::new();
    };
    let fdps: Vec<Option<Fdp>> = rig.controls.iter().map(|c| c.fdp.as_fdp()).collect();
    let Some(reader) = JawReader::new(rig, &fdps) else {
        return Vec::new();
    };
    let n = rig.mesh.vertex_count();
    let bodies = rig.parts.bodies(&rig.mesh.positions);
    let Some((hinge, carried)) = bodies.first() else {
        return Vec::new();
    };
    let mut normals = vec![Vec3::ZERO; n];
    vertex_normals(&rig.mesh.positions, &rig.mesh.triangles, &mut normals);
    let whole: Vec<usize> = jaw
        .vertices
        .iter()
        .flat_map(|&[a, b]| a as usize..=b as usize)
        .filter(|v| *v < n)
        .collect();
    let mut changed = Vec::new();
    let mut d = vec![Vec3::ZERO; rig.controls.len()];
    for t in targets.iter_mut() {
        if t.position_deltas.len() != n || t.normal_deltas.len() != n {
            continue;
        }
        for (slot, c) in d.iter_mut().zip(&rig.controls) {
            *slot = t
                .position_deltas
                .get(c.vertex as usize)
                .copied()
                .unwrap_or(Vec3::ZERO);
        }
        let chin = reader.chin_motion(&d);
        let passengers = whole
            .iter()
            .map(|v| t.position_deltas[*v].length())
            .fold(0.0, f32::max);
        if chin < MIN_CHIN * reader.reach() || passengers > LEFT_BEHIND * chin {
            continue;
        }
        let (turn, slide) = reader.motion(&d);
        // The jaw itself must move the chin as far too (a chin pushed up or forward by the skin
        // is clamped to no turn, and a sliver of slide is not a jaw's).
        if reader.carried_chin(turn, slide) < MIN_CHIN * reader.reach() {
            continue;
        }
        let r = turn - Mat3::IDENTITY;
        for &(v, w) in carried {
            let v = v as usize;
            if v >= n || w <= 0.0 {
                continue;
            }
            let rigid = r * (rig.mesh.positions[v] - *hinge) + slide;
            t.position_deltas[v] = t.position_deltas[v] * (1.0 - w) + rigid * w;
            t.normal_deltas[v] = t.normal_deltas[v] * (1.0 - w) + (r * normals[v]) * w;
        }
        changed.push(t.name.clone());
    }
    changed
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    fn jaw() -> JawReader {
        JawReader {
            hinge_axis: Vec3::X,
            chins: vec![
                Chin {
                    control: 0,
                    from_hinge: Vec3::new(0.0, -9.0, 12.0),
                },
                Chin {
                    control: 1,
                    from_hinge: Vec3::new(0.0, -6.0, 12.5),
                },
            ],
        }
    }

    #[test]
    fn a_chin_turned_about_the_hinge_reads_as_that_turn() {
        let j = jaw();
        for deg in [0.0f32, 5.0, 15.0, 30.0] {
            let q = Quat::from_rotation_x(deg.to_radians());
            let d: Vec<Vec3> = j
                .chins
                .iter()
                .map(|c| q * c.from_hinge - c.from_hinge)
                .collect();
            let (turn, slide) = j.motion(&d);
            let (axis, angle) = Quat::from_mat3(&turn).to_axis_angle();
            // f32 atan2 of products of ~10-unit vectors: a few ulps of a radian.
            assert!(
                (angle * axis.x.signum() - deg.to_radians()).abs() < 1e-5,
                "{deg}"
            );
            assert!(slide.length() < 1e-4, "{deg}: {slide}");
        }
        // Opening (the chin goes down and back) is a positive turn.
        let open = Quat::from_rotation_x(0.2);
        let d: Vec<Vec3> = j
            .chins
            .iter()
            .map(|c| open * c.from_hinge - c.from_hinge)
            .collect();
        assert!(d[0].y < 0.0 && d[0].z < 0.0);
    }

    #[test]
    fn a_chin_pushed_aside_slides_and_a_wild_one_is_clamped() {
        let j = jaw();
        // A push sideways and down: a little turn (the chin moves across the radius), the
        // sideways part slides; a push forward does not.
        let push = Vec3::new(0.4, -0.2, 0.0);
        let (turn, slide) = j.motion(&[push, push]);
        assert!(
            (slide - Vec3::new(0.4, 0.0, 0.0)).length() < 1e-5,
            "{slide}"
        );
        // The turn carries the chins down by about the push (each chin's drop off by less than
        // half of it: the two chins lie at different angles and reaches from the hinge).
        for c in &j.chins {
            let miss = turn * c.from_hinge + slide - (c.from_hinge + push);
            assert!(
                miss.x.abs() < 1e-5 && miss.y.abs() < 0.5 * push.y.abs(),
                "{miss}"
            );
        }
        let (_, slide) = j.motion(&[Vec3::Z, Vec3::Z]);
        assert_eq!(slide, Vec3::ZERO);
        let wild = Vec3::new(0.0, -40.0, -30.0);
        let (turn, slide) = j.motion(&[wild, wild]);
        let (_, angle) = Quat::from_mat3(&turn).to_axis_angle();
        assert!(angle <= JAW_OPEN + 1e-6);
        assert!(slide.length() <= MAX_SLIDE * 15.0 + 1e-3);
        // A chin pushed up does not close the jaw past its rest.
        let (turn, _) = j.motion(&[Vec3::new(0.0, 0.5, 0.3), Vec3::new(0.0, 0.5, 0.3)]);
        assert_eq!(turn, Mat3::IDENTITY);
    }

    /// A grid rig (control 0 is the chin, FDP 2.1) whose second-last vertex is a tooth the jaw
    /// carries whole and whose last is ramped at half weight.
    fn jawed_rig() -> Rig {
        let mesh = crate::test_meshes::grid(4, 4, 0.0, 0.0, 1);
        let mut rig = crate::test_meshes::rig(mesh, &[0, 5, 10], 0.5);
        let n = rig.mesh.vertex_count() as u32;
        let cut = rig.mesh.positions[n as usize - 1].y;
        rig.parts.jaw = Some(mimic_types::JawPart {
            vertices: vec![[n - 2, n - 2]],
            ramped: vec![[n - 1, n - 1]],
            cut,
            band: 1.0,
            hinge: Vec3::new(0.0, 2.0, -1.0),
            axis: Vec3::X,
        });
        rig
    }

    fn target(name: &str, n: usize) -> MorphTarget {
        MorphTarget {
            name: name.into(),
            position_deltas: vec![Vec3::ZERO; n],
            normal_deltas: vec![Vec3::ZERO; n],
        }
    }

    #[test]
    fn a_target_that_leaves_the_teeth_behind_carries_them_with_its_chin() {
        let rig = jawed_rig();
        let n = rig.mesh.vertex_count();
        let hinge = rig.parts.jaw.as_ref().unwrap().hinge;
        let q = Quat::from_rotation_x(0.25);
        let swing = |p: Vec3| q * (p - hinge) - (p - hinge);
        let chin = rig.controls[0].vertex as usize;
        let mut open = target("jawOpen", n);
        open.position_deltas[chin] = swing(rig.mesh.positions[chin]);
        // A target that moves the teeth itself, and one that does not move the chin.
        let mut own = open.clone();
        own.name = "own".into();
        own.position_deltas[n - 2] = Vec3::new(0.0, -0.3, 0.0);
        let mut still = target("browInnerUp", n);
        still.position_deltas[rig.controls[2].vertex as usize] = Vec3::Y;
        // A blink's stray chin motion: under MIN_CHIN of the chin's reach from the hinge.
        let mut blink = target("eyeBlinkLeft", n);
        let reach = rig.mesh.positions[chin].distance(hinge);
        blink.position_deltas[chin] = Vec3::new(0.0, -0.5 * MIN_CHIN * reach, 0.0);
        let mut targets = vec![open, own.clone(), still.clone(), blink.clone()];
        let changed = carry_jaw(&rig, &mut targets);
        assert_eq!(changed, vec!["jawOpen".to_string()]);
        assert_eq!(targets[1], own);
        assert_eq!(targets[2], still);
        assert_eq!(targets[3], blink);
        // The tooth turns with the chin about the hinge (truth: the quaternion's own turn), the
        // ramped vertex by half of it (smoothstep at the cut).
        let scale = rig.mesh.positions[n - 2].distance(hinge);
        let tol = 8.0 * f32::EPSILON * scale;
        let tooth = targets[0].position_deltas[n - 2];
        assert!(
            (tooth - swing(rig.mesh.positions[n - 2])).length() <= tol,
            "{tooth}"
        );
        let half = targets[0].position_deltas[n - 1];
        assert!(
            (half - 0.5 * swing(rig.mesh.positions[n - 1])).length() <= tol,
            "{half}"
        );
        let mut normals = vec![Vec3::ZERO; n];
        vertex_normals(&rig.mesh.positions, &rig.mesh.triangles, &mut normals);
        let turned = q * normals[n - 2] - normals[n - 2];
        assert!((targets[0].normal_deltas[n - 2] - turned).length() <= 8.0 * f32::EPSILON);
        // The skin is the target's own.
        assert_eq!(
            targets[0].position_deltas[chin],
            swing(rig.mesh.positions[chin])
        );
        assert_eq!(targets[0].position_deltas[1], Vec3::ZERO);
    }
}
