//! `mimic rig new`: a rig from a mesh and its iBUG landmarks.

use crate::RigNewError;
use crate::eyes::{EyeOpening, eye_opening};
use crate::frame::{FaceFrame, FramePoints};
use crate::landmarks::Landmarks;
use crate::parts::{FrozenCounts, frozen_mask, pieces};
use crate::place::{CONTROLS, Placed, Surface, fdp_of, rule_needs};
use glam::Vec3;
use mimic_types::{
    LaplacianWeights, Mesh, RbfDistance, RbfKernel, Region, RegionBands, SolverKind,
    SolverSettings, TopSplit,
};

/// A typical adult's distance between the eye centres, metres (what `--units` is checked
/// against, and what picks the unit when none is given).
pub const TYPICAL_IOD_M: f64 = 0.063;

/// The lengths of a generated rig, in face units (inter-ocular distances); chosen by
/// leave-one-out over the ICT expressions (docs/rigging.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Defaults {
    /// Width of the blend across each region border.
    pub band: f32,
    /// Radius of the exponential kernel of the middle and bottom regions (geodesic).
    pub radius: f32,
    /// Matern 3/2 radius of the brow half of the top region.
    pub upper_radius: f32,
    /// Matern 3/2 radius of the lid half of the top region.
    pub lower_radius: f32,
    /// Width of the blend across the top split.
    pub split_band: f32,
    /// Vertices of the controlled pieces farther than this from every landmark are frozen
    /// (the back of the head, the neck).
    pub back_of_head: f32,
    /// Membrane weight `ks` of the thin shell, in IOD^-2 (`ks IOD^2`), for masks whose eyes are
    /// closed skin ([`crate::eyes`]); chosen by leave-one-out over a morphable model's
    /// expressions (docs/rigging.md, "Which solver").
    pub shell_stiffness: f32,
    /// The solver to write; `None` picks it from the eyes (closed skin: the thin shell, open
    /// lids or unknown: the RBF).
    pub solver: Option<SolverKind>,
}

impl Default for Defaults {
    fn default() -> Self {
        Self {
            band: 0.22,
            radius: 0.40,
            upper_radius: 0.32,
            lower_radius: 0.16,
            split_band: 0.16,
            back_of_head: 1.0,
            shell_stiffness: 20.0,
            solver: None,
        }
    }
}

/// A rig made by [`make_rig`], ready to be written with [`crate::write_rig_toml`].
#[derive(Clone, Debug)]
pub struct GeneratedRig {
    /// Rig name.
    pub name: String,
    /// Length unit (one of `mimic_types::rig::RIG_UNITS`).
    pub units: String,
    /// The face frame the rules ran in.
    pub frame: FaceFrame,
    /// The controls, in [`CONTROLS`] order (missing ones left out).
    pub controls: Vec<Placed>,
    /// Frozen mask per vertex.
    pub frozen: Vec<bool>,
    /// Why vertices are frozen.
    pub frozen_counts: FrozenCounts,
    /// Region borders (mesh heights).
    pub regions: RegionBands,
    /// Solver settings (lengths in mesh units).
    pub solver: SolverSettings,
    /// The face-unit lengths the settings came from.
    pub defaults: Defaults,
    /// Across the eyes: open holes (RBF with the lid / brow split) or closed skin (thin shell);
    /// `None` when the lid landmarks are missing (then open is assumed).
    pub eyes: Option<EyeOpening>,
    /// Things the user should know (missing controls, a tilted head, ...).
    pub warnings: Vec<String>,
    /// The rigid parts found (jaw, eyeballs; [`crate::rigid_parts`]).
    pub parts: mimic_types::RigParts,
    /// What [`crate::rigid_parts::find_parts`] found, in words.
    pub parts_note: String,
    /// The turn of the mesh file into the rig's frame (`[orientation]`; [`crate::orient`]);
    /// the identity writes nothing.
    pub orientation: mimic_assets::Orientation,
}

/// The unit whose typical inter-ocular distance is nearest (by ratio) to `iod` mesh units;
/// `model` when none is within a factor of 3.
pub fn guess_units(iod: f32) -> &'static str {
    let mut best = ("model", 3.0f64.ln());
    for (name, metres) in mimic_types::rig::RIG_UNITS {
        let Some(m) = metres else { continue };
        let off = (f64::from(iod) * m / TYPICAL_IOD_M).ln().abs();
        if off < best.1 {
            best = (name, off);
        }
    }
    best.0
}

/// The face frame of a mesh from its landmarks (iBUG 36, 39, 42, 45 for the eyes, 8 and 27 for
/// the profile line are needed).
pub fn landmark_frame(mesh: &Mesh, marks: &Landmarks) -> Result<FaceFrame, RigNewError> {
    let n = mesh.vertex_count();
    for (k, v) in marks.vertex.iter().enumerate() {
        if let Some(v) = v
            && *v as usize >= n
        {
            return Err(RigNewError::Frame(format!(
                "iBUG {k} is vertex {v}, but the mesh has {n} vertices"
            )));
        }
    }
    let need = [8, 27, 36, 39, 42, 45];
    let missing: Vec<usize> = need
        .iter()
        .copied()
        .filter(|&n| marks.get(n).is_none())
        .collect();
    if !missing.is_empty() {
        return Err(RigNewError::Frame(format!(
            "the face frame needs the eye corners (iBUG 36, 39, 42, 45), the menton (8) and the nasion (27); missing {missing:?}"
        )));
    }
    let at = |k: usize| {
        marks
            .get(k)
            .map_or(Vec3::ZERO, |v| mesh.positions[v as usize])
    };
    FaceFrame::new(&FramePoints {
        right_outer: at(36),
        right_inner: at(39),
        left_inner: at(42),
        left_outer: at(45),
        low: at(8),
        high: at(27),
    })
    .ok_or_else(|| {
        RigNewError::Frame("the eye corners, menton and nasion are degenerate (on one line)".into())
    })
}

/// Builds a rig for `mesh` from its landmarks: controls by the rules of [`CONTROLS`], frozen
/// parts, regions, top split and kernels from `defaults` (face units) in mesh units.
pub fn make_rig(
    mesh: &Mesh,
    marks: &Landmarks,
    name: &str,
    units: Option<&str>,
    defaults: Defaults,
) -> Result<GeneratedRig, RigNewError> {
    if let Some(u) = units
        && !mimic_types::rig::is_rig_unit(u)
    {
        return Err(RigNewError::Units(u.to_string()));
    }
    let frame = landmark_frame(mesh, marks)?;
    let units = units.map_or_else(|| guess_units(frame.iod).to_string(), str::to_string);
    let mut warnings = Vec::new();
    if let Some(m) = mimic_types::rig::unit_in_metres(&units) {
        let ratio = f64::from(frame.iod) * m / TYPICAL_IOD_M;
        if !(1.0 / 3.0..=3.0).contains(&ratio) {
            warnings.push(format!(
                "the eye centres are {:.3} {units} apart, {ratio:.2} times a typical head's {:.1} cm: is `--units {units}` right?",
                frame.iod,
                TYPICAL_IOD_M * 100.0
            ));
        }
    }
    let tilt = frame.tilt_degrees();
    if tilt > 15.0 {
        warnings.push(format!(
            "the face's up axis is {tilt:.0} degrees from the mesh's +y; rig regions are mesh heights, so stand the head up (y up) for them to follow the face"
        ));
    }
    let face: Vec<Vec3> = mesh.positions.iter().map(|p| frame.to_face(*p)).collect();
    let piece = pieces(mesh);
    // The skin: the piece that holds the most landmarks.
    let mut votes = std::collections::BTreeMap::<u32, usize>::new();
    for v in marks.vertex.iter().flatten() {
        if let Some(Some(p)) = piece.get(*v as usize) {
            *votes.entry(*p).or_default() += 1;
        }
    }
    let skin_piece = votes
        .iter()
        .max_by_key(|(p, n)| (**n, std::cmp::Reverse(**p)))
        .map(|(p, _)| *p)
        .ok_or_else(|| RigNewError::Frame("no landmark lies on a triangle of the mesh".into()))?;
    let skin: Vec<bool> = piece.iter().map(|p| *p == Some(skin_piece)).collect();
    let (parts, parts_note) =
        crate::rigid_parts::find_parts(&face, &piece, skin_piece, &frame, marks);
    let surface = Surface {
        face: &face,
        skin: &skin,
        landmarks: marks,
    };
    let mut controls = Vec::new();
    for (id, region, rule) in CONTROLS {
        let fdp = fdp_of(id);
        let missing: Vec<usize> = rule_needs(rule)
            .into_iter()
            .filter(|&n| marks.get(n).is_none())
            .collect();
        if !missing.is_empty() {
            warnings.push(format!(
                "{fdp} left out: its rule needs iBUG {missing:?}, which the landmarks lack"
            ));
            continue;
        }
        match surface.place(rule) {
            Some((vertex, note)) => controls.push(Placed {
                fdp,
                vertex,
                region,
                note,
            }),
            None => warnings.push(format!("{fdp} left out: its rule found no skin vertex")),
        }
    }
    let control_vertices: Vec<u32> = controls.iter().map(|c| c.vertex).collect();
    let anchors: Vec<Vec3> = marks
        .vertex
        .iter()
        .flatten()
        .map(|v| face[*v as usize])
        .collect();
    let (frozen, frozen_counts) = frozen_mask(
        &face,
        &piece,
        &control_vertices,
        &anchors,
        defaults.back_of_head,
    );
    let (regions, top_split) = region_settings(mesh, &controls, frame.iod, defaults)?;
    let iod = f64::from(frame.iod);
    // Eyes of closed skin (a morphable model's mask): the thin shell; open lids: the RBF with its
    // lid / brow split (docs/rigging.md, "Which solver").
    let eyes = eye_opening(&mesh.positions, &mesh.triangles, marks);
    let by_eyes = if eyes.is_some_and(|e| !e.open()) {
        SolverKind::Shell
    } else {
        SolverKind::Rbf
    };
    let solver = SolverSettings {
        kind: defaults.solver.unwrap_or(by_eyes),
        kernel: RbfKernel::Exponential {
            radius: f64::from(defaults.radius) * iod,
        },
        affine: false,
        distance: RbfDistance::Geodesic,
        weights: LaplacianWeights::MeanValue,
        constraint_weight: 10.0,
        regions: true,
        top_split,
        shell: mimic_types::ShellSettings {
            stiffness: f64::from(defaults.shell_stiffness) / (iod * iod),
            ..mimic_types::ShellSettings::default()
        },
        rbf_ridge: 0.0,
        shell_blend: [0.0; 3],
    };
    Ok(GeneratedRig {
        name: name.to_string(),
        units,
        frame,
        controls,
        frozen,
        frozen_counts,
        regions,
        solver,
        defaults,
        eyes,
        warnings,
        parts,
        parts_note,
        orientation: mimic_assets::Orientation::default(),
    })
}

/// Region borders and the top split, from the control heights (mesh y):
/// - `top_from`: the blend into the top region ends at the lowest top control;
/// - `bottom_below`: halfway between the nose base (9.15) and the upper lip (8.1);
/// - top split: halfway between the highest lid control (3.x) and the lowest brow (4.x).
fn region_settings(
    mesh: &Mesh,
    controls: &[Placed],
    iod: f32,
    d: Defaults,
) -> Result<(RegionBands, Option<TopSplit>), RigNewError> {
    let y = |c: &Placed| mesh.positions[c.vertex as usize].y;
    let heights = |keep: &dyn Fn(&Placed) -> bool| -> Vec<f32> {
        controls.iter().filter(|c| keep(c)).map(y).collect()
    };
    let min = |v: &[f32]| v.iter().copied().fold(f32::INFINITY, f32::min);
    let max = |v: &[f32]| v.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let of = |g: u8, i: u8| {
        controls
            .iter()
            .find(|c| c.fdp.group == g && c.fdp.index == i)
            .map(y)
    };
    let band = d.band * iod;
    let top = heights(&|c| c.region == Region::Top);
    let (Some(nose), Some(lip)) = (of(9, 15), of(8, 1)) else {
        return Err(RigNewError::Frame(
            "the region borders need the nose base (9.15, iBUG 33) and the upper lip (8.1, iBUG 51)"
                .into(),
        ));
    };
    if top.is_empty() {
        return Err(RigNewError::Frame(
            "no top-region control was placed".into(),
        ));
    }
    let bottom_below = (nose + lip) * 0.5;
    let top_from = min(&top) - band * 0.5;
    let middle = top_from - bottom_below;
    if middle <= 0.0 {
        return Err(RigNewError::Frame(format!(
            "the lowest eye control (y = {}) is not above the nose base and upper lip (y = {nose}, {lip}): is the head upright, y up?",
            min(&top)
        )));
    }
    let regions = RegionBands {
        top_from,
        bottom_below,
        band: band.min(middle),
    };
    let lids = heights(&|c| c.fdp.group == 3);
    let brows = heights(&|c| c.fdp.group == 4);
    let split = (!lids.is_empty() && !brows.is_empty() && max(&lids) < min(&brows)).then(|| {
        let iod = f64::from(iod);
        TopSplit {
            at: (max(&lids) + min(&brows)) * 0.5,
            band: d.split_band * iod as f32,
            upper_kernel: Some(RbfKernel::Matern32 {
                radius: f64::from(d.upper_radius) * iod,
            }),
            lower_kernel: Some(RbfKernel::Matern32 {
                radius: f64::from(d.lower_radius) * iod,
            }),
        }
    });
    Ok((regions, split))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_are_guessed_from_the_eye_distance() {
        assert_eq!(guess_units(6.3), "cm");
        assert_eq!(guess_units(63.0), "mm");
        assert_eq!(guess_units(0.063), "m");
        assert_eq!(guess_units(2.5), "in");
        // CANDIDE-3's 0.60 is 10 times too small for metres and far from the rest.
        assert_eq!(guess_units(0.0063), "model");
    }

    #[test]
    fn landmark_errors_say_what_is_wrong() {
        let mesh = Mesh {
            positions: vec![Vec3::ZERO; 4],
            triangles: vec![[0, 1, 2]],
            ..Mesh::default()
        };
        let mut marks = Landmarks {
            vertex: [None; crate::IBUG_POINTS],
        };
        marks.vertex[1] = Some(99);
        let e = landmark_frame(&mesh, &marks).unwrap_err().to_string();
        assert_eq!(e, "iBUG 1 is vertex 99, but the mesh has 4 vertices");
        marks.vertex[1] = Some(3);
        let e = landmark_frame(&mesh, &marks).unwrap_err().to_string();
        assert!(e.ends_with("missing [8, 27, 36, 39, 42, 45]"), "{e}");
        for n in [8, 27, 36, 39, 42, 45] {
            marks.vertex[n] = Some(0);
        }
        let e = landmark_frame(&mesh, &marks).unwrap_err().to_string();
        assert!(e.contains("degenerate"), "{e}");
        let e = make_rig(&mesh, &marks, "t", Some("furlongs"), Defaults::default()).unwrap_err();
        assert_eq!(
            e.to_string(),
            "units `furlongs` is not one of m, cm, mm, in, model"
        );
    }
}
