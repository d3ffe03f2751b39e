//! The rigid parts' entries of `d` (after the controls'): the jaw turned about its hinge by the
//! chin's swing, and the eyeballs turned by the gaze (docs/parts.md). Allocation-free per frame.

use crate::gaze::EyeGaze;
use glam::{Mat3, Vec3};
use mimic_solve::jaw::JawReader;
use mimic_solve::rigid::part_coefficients;
use mimic_types::{Fdp, Rig, parts::PART_COLUMNS};

/// What moves each rigid part per frame.
#[derive(Clone, Debug)]
pub(crate) struct PartMotion {
    /// Index in `d` of the first part column (the rig's control count).
    first: usize,
    /// The jaw, when the rig has one and some chin control to read it from.
    jaw: Option<JawReader>,
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
        let jaw = JawReader::new(rig, fdps);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eyes_turn_left_and_up_as_named() {
        let front = Vec3::Z;
        let left = eye_rotation(0.3, 0.0) * front;
        assert!(left.x > 0.0 && left.y.abs() < 1e-6);
        let up = eye_rotation(0.0, 0.3) * front;
        assert!(up.y > 0.0 && up.x.abs() < 1e-6);
    }
}
