//! What `mimic info` says about a rig ([`RigSummary`]) and a tracker layout
//! ([`LayoutSummary`]): counts per region, bounds, the solver, and the rig's warnings.

use mimic_types::{Layout, Region, Rig, SolverSettings};
use serde::Serialize;

/// A count per region, top to bottom.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct PerRegion {
    /// The top region (brows, lids).
    pub top: usize,
    /// The middle region (cheeks, nose).
    pub middle: usize,
    /// The bottom region (mouth, jaw).
    pub bottom: usize,
}

impl PerRegion {
    /// Counts how many of `regions` fall in each region.
    fn count(regions: impl IntoIterator<Item = Region>) -> Self {
        let mut n = Self::default();
        for r in regions {
            *match r {
                Region::Top => &mut n.top,
                Region::Middle => &mut n.middle,
                Region::Bottom => &mut n.bottom,
            } += 1;
        }
        n
    }
}

/// A tracker layout in numbers.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LayoutSummary {
    /// Always `layout`.
    pub kind: &'static str,
    /// The layout's name.
    pub name: String,
    /// Points per frame.
    pub points: usize,
    /// Controls it drives.
    pub controls: usize,
    /// Its controls per region.
    pub controls_by_region: PerRegion,
    /// Points on rigid parts of the head (for the head pose).
    pub stable_points: usize,
    /// Points the layout does not document.
    pub undocumented_points: usize,
    /// The controls' FDP names, space-separated.
    pub fdps: String,
}

impl LayoutSummary {
    /// The summary of `l`.
    pub fn of(l: &Layout) -> Self {
        Self {
            kind: "layout",
            name: l.name.clone(),
            points: l.point_count,
            controls: l.controls.len(),
            controls_by_region: PerRegion::count(l.controls.iter().map(|c| c.region)),
            stable_points: l.stable.len(),
            undocumented_points: l.undocumented.len(),
            fdps: l
                .controls
                .iter()
                .map(|c| c.fdp.to_string())
                .collect::<Vec<_>>()
                .join(" "),
        }
    }
}

/// A rig in numbers, with what looks wrong in it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RigSummary {
    /// Always `rig`.
    pub kind: &'static str,
    /// The rig's name.
    pub name: String,
    /// Its length unit.
    pub units: String,
    /// Mesh vertices.
    pub vertices: usize,
    /// Mesh triangles.
    pub triangles: usize,
    /// Whether the mesh has texture coordinates.
    pub textured: bool,
    /// Controls.
    pub controls: usize,
    /// Vertices that never move.
    pub frozen_vertices: usize,
    /// The vertices that move, per region of their rest height.
    pub movable_vertices_by_region: PerRegion,
    /// Lowest corner of the mesh's bounds.
    pub bounds_min: [f32; 3],
    /// Highest corner of the mesh's bounds.
    pub bounds_max: [f32; 3],
    /// The solver settings.
    pub solver: SolverSettings,
    /// The names of the rig's morph targets (checked against its mesh), empty when none.
    pub morph_targets: Vec<String>,
    /// Pairs of controls on one rest position, in words.
    pub warnings: Vec<String>,
}

impl RigSummary {
    /// The summary of `r`.
    pub fn of(r: &Rig) -> Self {
        let movable = r
            .mesh
            .positions
            .iter()
            .zip(&r.frozen)
            .filter(|(_, frozen)| !**frozen)
            .map(|(p, _)| r.regions.region_at(p.y));
        let (lo, hi) = r.mesh.bounds().unwrap_or_default();
        let warnings = r
            .coincident_controls()
            .into_iter()
            .map(|(a, b)| {
                format!(
                    "controls {a} and {b} share one rest position: an RBF solve merges them into one \
                     centre driven by their mean, so they cannot move apart (use --solver laplacian, or \
                     put them on different vertices)"
                )
            })
            .collect();
        Self {
            kind: "rig",
            name: r.name.clone(),
            units: r.units.clone(),
            vertices: r.mesh.vertex_count(),
            triangles: r.mesh.triangles.len(),
            textured: !r.mesh.uvs.is_empty(),
            controls: r.controls.len(),
            frozen_vertices: r.mesh.vertex_count() - r.frozen.iter().filter(|f| !**f).count(),
            movable_vertices_by_region: PerRegion::count(movable),
            bounds_min: lo.to_array(),
            bounds_max: hi.to_array(),
            solver: r.solver,
            morph_targets: Vec::new(),
            warnings,
        }
    }

    /// The summary with the names of the rig's morph targets (loaded, so checked, by the caller).
    pub fn with_morph_targets(mut self, targets: &[mimic_types::MorphTarget]) -> Self {
        self.morph_targets = targets.iter().map(|t| t.name.clone()).collect();
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_are_counted_top_to_bottom() {
        let n = PerRegion::count([Region::Top, Region::Bottom, Region::Bottom]);
        assert_eq!((n.top, n.middle, n.bottom), (1, 0, 2));
    }
}
