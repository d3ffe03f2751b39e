//! `mimic rig check`: what is suspicious about a rig, as warnings.

use crate::frame::{FaceFrame, FramePoints};
use crate::new::TYPICAL_IOD_M;
use crate::place::{CONTROLS, fdp_of};
use glam::Vec3;
use mimic_types::{Fdp, Rig};
use serde::Serialize;

/// Left/right control pairs (subject's left first) that should mirror each other.
pub const MIRROR_PAIRS: [((u8, u8), (u8, u8)); 15] = [
    ((4, 1), (4, 2)),
    ((4, 3), (4, 4)),
    ((4, 5), (4, 6)),
    ((3, 1), (3, 2)),
    ((3, 3), (3, 4)),
    ((3, 7), (3, 12)),
    ((3, 11), (3, 8)),
    ((9, 5), (9, 4)),
    ((5, 1), (5, 2)),
    ((5, 3), (5, 4)),
    ((8, 3), (8, 4)),
    ((8, 5), (8, 6)),
    ((8, 7), (8, 8)),
    ((2, 4), (2, 5)),
    ((2, 11), (2, 12)),
];

/// Controls on the midline (face x = 0).
pub const MIDLINE: [(u8, u8); 8] = [
    (9, 3),
    (9, 15),
    (8, 1),
    (8, 2),
    (2, 2),
    (2, 3),
    (2, 1),
    (2, 10),
];

/// How far (face units) a mirrored control may be from its partner, or a midline control from
/// the midline, before it is reported.
pub const MIRROR_TOLERANCE: f32 = 0.05;

/// One finding of [`check_rig`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Warning {
    /// Machine-readable kind: `missing_fdp`, `extra_fdp`, `shared_vertex`, `outside_region`,
    /// `not_mirrored`, `off_midline`, `units`, `no_face_frame`.
    pub kind: &'static str,
    /// The FDPs concerned.
    pub fdps: Vec<String>,
    /// One line for a person.
    pub message: String,
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.kind, self.message)
    }
}

fn warn<F: ToString>(kind: &'static str, fdps: &[F], message: String) -> Warning {
    Warning {
        kind,
        fdps: fdps.iter().map(ToString::to_string).collect(),
        message,
    }
}

/// The face frame of a rig, from its eye-corner controls, with the mouth corners' midpoint and
/// the eyes' standing in for the profile line (the mirror checks need only x; the nasion is no
/// control).
pub fn rig_frame(rig: &Rig) -> Option<FaceFrame> {
    let at = |g: u8, i: u8| {
        rig.controls
            .iter()
            .find(|c| c.fdp.as_fdp() == Some(Fdp { group: g, index: i }))
            .and_then(|c| rig.mesh.positions.get(c.vertex as usize).copied())
    };
    let (ri, li) = (at(3, 8)?, at(3, 11)?);
    FaceFrame::new(&FramePoints {
        right_outer: at(3, 12)?,
        right_inner: ri,
        left_inner: li,
        left_outer: at(3, 7)?,
        low: (at(8, 4)? + at(8, 3)?) * 0.5,
        high: (ri + li) * 0.5,
    })
}

/// The first line `mimic rig check` prints: the rig file, its controls and its warnings' count.
pub fn check_line(path: &std::path::Path, rig: &Rig, warnings: usize) -> String {
    format!(
        "{}: {} controls, {warnings} warning(s)",
        path.display(),
        rig.controls.len()
    )
}

/// Checks a loaded rig: missing or extra FDPs (against the 38 of docs/layouts.md), FDPs that
/// share a vertex, controls outside their region, left/right controls that are not mirror
/// images in the face frame, midline controls off it, and units that do not fit the face size.
pub fn check_rig(rig: &Rig) -> Vec<Warning> {
    let mut out = Vec::new();
    let standard: Vec<Fdp> = CONTROLS.iter().map(|c| fdp_of(c.0)).collect();
    let has = |f: &Fdp| rig.controls.iter().any(|c| c.fdp.as_fdp() == Some(*f));
    // A dense rig (layout points as controls, docs/layouts.md) needs no FDP.
    let dense = rig.controls.iter().any(|c| c.fdp.as_point().is_some());
    let missing: Vec<Fdp> = standard.iter().copied().filter(|f| !has(f)).collect();
    if !missing.is_empty() && !dense {
        let names: Vec<String> = missing.iter().map(ToString::to_string).collect();
        out.push(warn(
            "missing_fdp",
            &missing,
            format!(
                "{} of the 38 controls are missing: {} (the retargeter leaves them undriven)",
                missing.len(),
                names.join(", ")
            ),
        ));
    }
    let extra: Vec<Fdp> = rig
        .controls
        .iter()
        .filter_map(|c| c.fdp.as_fdp())
        .filter(|f| !standard.contains(f))
        .collect();
    if !extra.is_empty() {
        let names: Vec<String> = extra.iter().map(ToString::to_string).collect();
        out.push(warn(
            "extra_fdp",
            &extra,
            format!(
                "controls outside the 38 of docs/layouts.md: {} (no layout drives them)",
                names.join(", ")
            ),
        ));
    }
    for (a, b) in rig.coincident_controls() {
        let va = rig
            .controls
            .iter()
            .find(|c| c.fdp == a)
            .map_or(0, |c| c.vertex);
        let vb = rig
            .controls
            .iter()
            .find(|c| c.fdp == b)
            .map_or(0, |c| c.vertex);
        let how = if va == vb {
            format!("both on vertex {va}")
        } else {
            format!("vertices {va} and {vb} share a rest position")
        };
        out.push(warn(
            "shared_vertex",
            &[a, b],
            format!("{a} and {b}: {how}; an RBF solve can only move them together"),
        ));
    }
    for c in &rig.controls {
        let Some(p) = rig.mesh.positions.get(c.vertex as usize) else {
            continue;
        };
        let w = rig.regions.weights(p.y)[c.region.index()];
        if w < 0.5 {
            out.push(warn(
                "outside_region",
                &[c.fdp],
                format!(
                    "{} drives the {} region but sits at y = {:.4}, where that region's weight is {w:.2} (regions: top from {}, bottom below {}, band {})",
                    c.fdp,
                    c.region,
                    p.y,
                    rig.regions.top_from,
                    rig.regions.bottom_below,
                    rig.regions.band
                ),
            ));
        }
    }
    let Some(frame) = rig_frame(rig) else {
        if dense {
            // A dense rig has no eye-corner FDPs: the mirror and unit checks need them.
            return out;
        }
        out.push(warn(
            "no_face_frame",
            &[] as &[Fdp],
            "the eye corners (3.7, 3.8, 3.11, 3.12) and mouth corners (8.3, 8.4) are missing or degenerate: mirror and unit checks skipped".into(),
        ));
        return out;
    };
    let face = |g: u8, i: u8| -> Option<Vec3> {
        rig.controls
            .iter()
            .find(|c| c.fdp.as_fdp() == Some(Fdp { group: g, index: i }))
            .and_then(|c| rig.mesh.positions.get(c.vertex as usize))
            .map(|p| frame.to_face(*p))
    };
    for (l, r) in MIRROR_PAIRS {
        let (Some(pl), Some(pr)) = (face(l.0, l.1), face(r.0, r.1)) else {
            continue;
        };
        let mirrored = Vec3::new(-pr.x, pr.y, pr.z);
        let off = pl.distance(mirrored);
        if off > MIRROR_TOLERANCE {
            let (fl, fr) = (fdp_of(l), fdp_of(r));
            out.push(warn(
                "not_mirrored",
                &[fl, fr],
                format!(
                    "{fl} and {fr} are not mirror images: {fl} is {off:.3} IOD from {fr} mirrored across the face's midline (more than {MIRROR_TOLERANCE})"
                ),
            ));
        }
    }
    for m in MIDLINE {
        let Some(p) = face(m.0, m.1) else { continue };
        if p.x.abs() > MIRROR_TOLERANCE {
            let f = fdp_of(m);
            out.push(warn(
                "off_midline",
                &[f],
                format!(
                    "{f} is {:.3} IOD off the face's midline (more than {MIRROR_TOLERANCE})",
                    p.x
                ),
            ));
        }
    }
    if let Some(m) = mimic_types::rig::unit_in_metres(&rig.units) {
        let ratio = f64::from(frame.iod) * m / TYPICAL_IOD_M;
        if !(1.0 / 3.0..=3.0).contains(&ratio) {
            out.push(warn(
                "units",
                &[] as &[Fdp],
                format!(
                    "units = \"{}\" makes the eye centres {:.4} m apart, {ratio:.2} times a typical head's {TYPICAL_IOD_M} m; the mesh looks like it is in {}",
                    rig.units,
                    f64::from(frame.iod) * m,
                    crate::new::guess_units(frame.iod)
                ),
            ));
        }
    }
    out
}
