//! The rigid parts `rig new` finds (docs/parts.md): among the mesh's pieces that are not the skin,
//! round ones on an eye are eyeballs, small ones in the mouth below the lip line ride on the jaw
//! (lower teeth), and a piece in the mouth that spans the lip line (gums and tongue in one) rides
//! on it below the line, ramped across it; the upper teeth stay with the skull. The hinge is the
//! template's (ICT-FaceKit's, fitted to its `jawOpen`), carried in the face frame.

use crate::frame::FaceFrame;
use crate::landmarks::Landmarks;
use glam::Vec3;
use mimic_types::{EyePart, JawPart, RigParts};
use std::collections::BTreeMap;

/// The jaw's hinge in face coordinates (IOD units; x the subject's left, y up, z out of the
/// face, origin between the inner eye corners): the centre of the rotation that best carries
/// ICT-FaceKit's chin (its vertices that `jawOpen` moves at least 85 % of the most) from the
/// neutral to `jawOpen`, in ICT's face frame (`the_hinge_is_icts_jaw_open_centre` checks it).
pub const HINGE_FACE: Vec3 = Vec3::new(0.0, -0.30, -1.67);

/// A piece smaller than this (IOD) is a tooth: whole with the jaw or whole with the skull.
const SMALL: f32 = 0.6;

/// The ramp across the lip line of a piece that spans it, in IOD.
const RAMP_BAND: f32 = 0.05;

/// What one piece looks like in the face frame.
struct Piece {
    /// Inclusive vertex ranges.
    ranges: Vec<[u32; 2]>,
    /// Bounding box, face coordinates.
    lo: Vec3,
    hi: Vec3,
}

impl Piece {
    fn centre(&self) -> Vec3 {
        (self.lo + self.hi) * 0.5
    }
    fn extent(&self) -> Vec3 {
        self.hi - self.lo
    }
}

/// The rigid parts of a mesh: `face` its vertices in face coordinates, `piece` each vertex's
/// piece, `skin` the skin's piece, `frame` the face frame and `marks` the landmarks. Returns the
/// parts (mesh units) and a line on what was found.
pub fn find_parts(
    face: &[Vec3],
    piece: &[Option<u32>],
    skin: u32,
    frame: &FaceFrame,
    marks: &Landmarks,
) -> (RigParts, String) {
    let pieces = gather(face, piece, skin);
    let mean = |ks: std::ops::RangeInclusive<usize>| -> Option<Vec3> {
        let pts: Vec<Vec3> = ks
            .filter_map(|k| marks.get(k))
            .filter_map(|v| face.get(v as usize).copied())
            .collect();
        (!pts.is_empty()).then(|| pts.iter().copied().sum::<Vec3>() / pts.len() as f32)
    };
    let eye_r = mean(36..=41).unwrap_or(Vec3::new(-0.5, 0.0, 0.0));
    let eye_l = mean(42..=47).unwrap_or(Vec3::new(0.5, 0.0, 0.0));
    let mouth = mean(60..=67).or_else(|| mean(48..=59));
    let mut eyes: [Vec<&Piece>; 2] = [Vec::new(), Vec::new()];
    let (mut whole, mut ramped) = (Vec::new(), Vec::new());
    for p in pieces.values() {
        let (c, e) = (p.centre(), p.extent());
        let round = e.min_element() > 0.7 * e.max_element();
        let on = |eye: Vec3| {
            (c.truncate() - eye.truncate()).length() < 0.35 && (c.z - eye.z).abs() < 0.6
        };
        if round && (0.15..0.8).contains(&e.max_element()) {
            if on(eye_l) {
                eyes[0].push(p);
                continue;
            }
            if on(eye_r) {
                eyes[1].push(p);
                continue;
            }
        }
        let Some(m) = mouth else { continue };
        if c.distance(m) > 1.2 {
            continue;
        }
        // A tooth, or a row of teeth: with the jaw when it sits below the lip line (its middle
        // below, and small or wholly below); the upper ones stay with the skull.
        let small = e.max_element() < SMALL;
        if c.y < m.y && (small || p.hi.y < m.y + 0.1) && e.max_element() < 1.2 {
            whole.extend(p.ranges.iter().copied());
        } else if !small && e.max_element() < 2.0 && p.lo.y < m.y && m.y < p.hi.y {
            // Gums and tongue in one piece: the part below the line rides on the jaw.
            ramped.extend(p.ranges.iter().copied());
        }
    }
    let eye_parts = (!eyes[0].is_empty() && !eyes[1].is_empty()).then(|| {
        eyes.map(|ps| {
            let lo = ps.iter().fold(Vec3::MAX, |a, p| a.min(p.lo));
            let hi = ps.iter().fold(Vec3::MIN, |a, p| a.max(p.hi));
            // The ball's centre: the middle across and up, its radius in front of its back (the
            // cornea bulges past the ball, so the box's middle in depth would sit too far out).
            let radius = 0.25 * ((hi.x - lo.x) + (hi.y - lo.y));
            let middle = (lo + hi) * 0.5;
            EyePart {
                vertices: merged(ps.iter().flat_map(|p| p.ranges.iter().copied()).collect()),
                centre: frame.to_mesh(Vec3::new(middle.x, middle.y, lo.z + radius)),
            }
        })
    });
    let jaw = (mouth.is_some() && !(whole.is_empty() && ramped.is_empty())).then(|| {
        let m = mouth.unwrap_or(Vec3::ZERO);
        JawPart {
            vertices: merged(whole.clone()),
            ramped: merged(ramped.clone()),
            cut: frame.to_mesh(m).y,
            band: RAMP_BAND * frame.iod,
            hinge: frame.to_mesh(HINGE_FACE),
            axis: frame.axes[0],
        }
    });
    let count = |rs: &[[u32; 2]]| rs.iter().map(|[a, b]| (b - a + 1) as usize).sum::<usize>();
    let note = format!(
        "rigid parts: jaw {} ({} vertices whole, {} ramped across the lip line), eyeballs {}",
        if jaw.is_some() { "found" } else { "none" },
        count(&whole),
        count(&ramped),
        match &eye_parts {
            Some([l, r]) => format!("{} + {} vertices", count(&l.vertices), count(&r.vertices)),
            None => "none".to_string(),
        }
    );
    (
        RigParts {
            jaw,
            eyes: eye_parts,
        },
        note,
    )
}

/// `ranges` sorted, touching ones joined.
fn merged(mut ranges: Vec<[u32; 2]>) -> Vec<[u32; 2]> {
    ranges.sort_unstable();
    let mut out: Vec<[u32; 2]> = Vec::with_capacity(ranges.len());
    for r in ranges {
        match out.last_mut() {
            Some(last) if r[0] <= last[1].saturating_add(1) => last[1] = last[1].max(r[1]),
            _ => out.push(r),
        }
    }
    out
}

/// The pieces other than the skin, with their vertex ranges and face-frame boxes.
fn gather(face: &[Vec3], piece: &[Option<u32>], skin: u32) -> BTreeMap<u32, Piece> {
    let mut out: BTreeMap<u32, Piece> = BTreeMap::new();
    for (v, (p, q)) in piece.iter().zip(face).enumerate() {
        let Some(p) = *p else { continue };
        if p == skin {
            continue;
        }
        let v = v as u32;
        let e = out.entry(p).or_insert(Piece {
            ranges: Vec::new(),
            lo: Vec3::MAX,
            hi: Vec3::MIN,
        });
        e.lo = e.lo.min(*q);
        e.hi = e.hi.max(*q);
        match e.ranges.last_mut() {
            Some(r) if r[1] + 1 == v => r[1] = v,
            _ => e.ranges.push([v, v]),
        }
    }
    out
}
