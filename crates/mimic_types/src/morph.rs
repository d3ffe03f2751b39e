//! Morph targets (blendshapes): per-vertex position and normal deltas on a rig mesh's topology.

use crate::RigControl;
use glam::Vec3;

/// One morph target: `P = P0 + w dP`, `N = N0 + w dN` for weight `w` in [0, 1].
#[derive(Clone, Debug, PartialEq)]
pub struct MorphTarget {
    /// Name, e.g. the ARKit `jawOpen`.
    pub name: String,
    /// Per-vertex position delta (target - neutral), in rig units.
    pub position_deltas: Vec<Vec3>,
    /// Per-vertex normal delta (target's area-weighted unit normal - neutral's).
    pub normal_deltas: Vec<Vec3>,
}

impl MorphTarget {
    /// Number of vertices the target covers.
    pub fn vertex_count(&self) -> usize {
        self.position_deltas.len()
    }

    /// Position deltas at the rig's control vertices, in control order (`None` if a vertex is out of range).
    pub fn control_deltas(&self, controls: &[RigControl]) -> Option<Vec<Vec3>> {
        controls
            .iter()
            .map(|c| self.position_deltas.get(c.vertex as usize).copied())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Region;

    #[test]
    fn control_deltas_pick_the_control_vertices() {
        let t = MorphTarget {
            name: "t".into(),
            position_deltas: vec![Vec3::X, Vec3::Y, Vec3::Z],
            normal_deltas: vec![Vec3::ZERO; 3],
        };
        let c = |v| RigControl {
            fdp: "8.3".parse().unwrap(),
            vertex: v,
            region: Region::Bottom,
        };
        assert_eq!(
            t.control_deltas(&[c(2), c(0)]),
            Some(vec![Vec3::Z, Vec3::X])
        );
        assert_eq!(t.control_deltas(&[c(3)]), None);
    }
}
