//! The rigid parts' entries of `d` (after the controls'): the jaw turned about its hinge by the
//! chin's swing, and the eyeballs turned by the gaze (docs/parts.md). Allocation-free per frame.

use crate::gaze::EyeGaze;
use glam::{Mat3, Vec3};
use mimic_solve::rigid::part_coefficients;
use mimic_types::{Fdp, Rig, parts::PART_COLUMNS};

/// The jaw opens at most this far (radians, 40 degrees) and never closes past its rest (the
/// teeth meet there: a chin pushed up or forward by the skin alone, a chin raiser or a tracker's
/// stray chin point, would drive the lower teeth through the upper ones and the lip).
const JAW_OPEN: f32 = 0.70;
/// How far past its rest a jaw may close (radians).
const JAW_CLOSE: f32 = 0.0;
/// The slide (the chin's sideways motion, along the hinge axis, that the turn does not explain) is
/// at most this share of the chin's distance from the hinge (1.5 cm on ICT). Only sideways: the
/// chin's skin moves forward and back on its own (a pout, a chin raiser, a raw tracker's stray
/// chin point pushed the chin 1.7 cm forward on `a_yn_question`), far more than the bone
/// protrudes, and a slide forward drove the lower teeth through the lip.
const MAX_SLIDE: f32 = 0.1;

/// One chin control: its index among the rig's controls and its rest offset from the hinge.
#[derive(Clone, Copy, Debug)]
struct Chin {
    control: usize,
    from_hinge: Vec3,
}

/// The jaw's hinge and the chin controls it is read from.
#[derive(Clone, Debug)]
struct Jaw {
    hinge_axis: Vec3,
    chins: Vec<Chin>,
}

/// What moves each rigid part per frame.
#[derive(Clone, Debug)]
pub(crate) struct PartMotion {
    /// Index in `d` of the first part column (the rig's control count).
    first: usize,
    /// The jaw, when the rig has one and some chin control to read it from.
    jaw: Option<Jaw>,
    /// Whether the jaw's four columns are present (a jaw with no chin control stays still).
    has_jaw: bool,
    /// Whether the rig has eyeballs.
    has_eyes: bool,
}

impl PartMotion {
    /// The part motion of `rig`, whose controls stand for `fdps` (`None`: no FDP). The jaw is
    /// read from the chin (FDP 2.1, and 2.10 the chin boss), or the lower lip's middle (2.3,
    /// 8.2) when the rig drives no chin.
    pub(crate) fn new(rig: &Rig, fdps: &[Option<Fdp>]) -> Self {
        let first = rig.controls.len();
        let jaw = rig.parts.jaw.as_ref().and_then(|jaw| {
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
                    .map(|(control, c)| Chin {
                        control,
                        from_hinge: rig.mesh.positions[c.vertex as usize] - jaw.hinge,
                    })
                    .collect()
            };
            let mut chins = pick(&["2.1", "2.10"]);
            if chins.is_empty() {
                chins = pick(&["2.3", "8.2"]);
            }
            (!chins.is_empty()).then(|| Jaw {
                hinge_axis: jaw.unit_axis(),
                chins,
            })
        });
        PartMotion {
            first,
            jaw,
            has_jaw: rig.parts.jaw.is_some(),
            has_eyes: rig.parts.eyes.is_some(),
        }
    }

    /// Writes the parts' entries of `d` from the controls' entries (the jaw) and `eyes` (the
    /// left and right eye's turn; `None`: looking ahead).
    pub(crate) fn fill(&self, d: &mut [Vec3], eyes: Option<[EyeGaze; 2]>) {
        let mut col = self.first;
        if self.has_jaw {
            let (turn, slide) = self
                .jaw
                .as_ref()
                .map_or((Mat3::IDENTITY, Vec3::ZERO), |j| j.motion(&d[..self.first]));
            write(d, col, part_coefficients(turn, slide));
            col += PART_COLUMNS;
        }
        if self.has_eyes {
            for e in eyes.unwrap_or_default() {
                write(
                    d,
                    col,
                    part_coefficients(eye_rotation(e.yaw, e.pitch), Vec3::ZERO),
                );
                col += PART_COLUMNS;
            }
        }
    }
}

fn write(d: &mut [Vec3], col: usize, values: [Vec3; PART_COLUMNS]) {
    if let Some(slot) = d.get_mut(col..col + PART_COLUMNS) {
        slot.copy_from_slice(&values);
    }
}

/// The eye's rotation in the rig's frame (x the subject's left, y up, z out of the face): turned
/// by `yaw` about y, then raised by `pitch` (about -x, so that the front goes up).
pub(crate) fn eye_rotation(yaw: f32, pitch: f32) -> Mat3 {
    Mat3::from_rotation_y(yaw) * Mat3::from_rotation_x(-pitch)
}

impl Jaw {
    /// The jaw's turn about the hinge and its slide, from the chin controls' displacements `d`:
    /// the mean angle each chin swings about the hinge axis (in the plane across the axis),
    /// clamped to `[-JAW_CLOSE, JAW_OPEN]`, then the mean of what the turn leaves unexplained
    /// along the axis (sideways), at most [`MAX_SLIDE`] of the chin's reach.
    fn motion(&self, d: &[Vec3]) -> (Mat3, Vec3) {
        let a = self.hinge_axis;
        let across = |v: Vec3| v - a * a.dot(v);
        let mut angle = 0.0;
        let mut reach = 0.0;
        for c in &self.chins {
            let r0 = across(c.from_hinge);
            let r1 = across(c.from_hinge + d[c.control]);
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
            slide += c.from_hinge + d[c.control] - turn * c.from_hinge;
        }
        let limit = MAX_SLIDE * reach;
        let slide = a * (a.dot(slide) / count).clamp(-limit, limit);
        (turn, slide)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    fn jaw() -> Jaw {
        Jaw {
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

    #[test]
    fn eyes_turn_left_and_up_as_named() {
        let front = Vec3::Z;
        let left = eye_rotation(0.3, 0.0) * front;
        assert!(left.x > 0.0 && left.y.abs() < 1e-6);
        let up = eye_rotation(0.0, 0.3) * front;
        assert!(up.y > 0.0 && up.x.abs() < 1e-6);
    }
}
