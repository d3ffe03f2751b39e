//! Connected pieces of a mesh and the frozen mask derived from them.

use glam::Vec3;
use mimic_types::Mesh;

/// Connected pieces (by shared triangle corners): `piece[v]` for each vertex, `None` for a
/// vertex in no triangle; pieces are numbered by their lowest vertex.
pub fn pieces(mesh: &Mesh) -> Vec<Option<u32>> {
    let n = mesh.vertex_count();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn root(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            let up = parent[parent[v as usize] as usize];
            parent[v as usize] = up;
            v = up;
        }
        v
    }
    let mut used = vec![false; n];
    for t in &mesh.triangles {
        for &v in t {
            if let Some(u) = used.get_mut(v as usize) {
                *u = true;
            }
        }
        for k in 1..3 {
            if t[0] as usize >= n || t[k] as usize >= n {
                continue;
            }
            let (a, b) = (root(&mut parent, t[0]), root(&mut parent, t[k]));
            if a != b {
                let (lo, hi) = (a.min(b), a.max(b));
                parent[hi as usize] = lo;
            }
        }
    }
    (0..n as u32)
        .map(|v| used[v as usize].then(|| root(&mut parent, v)))
        .collect()
}

/// Why a vertex is frozen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrozenCounts {
    /// Vertices in no triangle.
    pub unused: usize,
    /// Vertices of pieces that carry no control (eyeballs, teeth, lashes, ...).
    pub uncontrolled: usize,
    /// Number of such pieces.
    pub uncontrolled_pieces: usize,
    /// Vertices of controlled pieces farther than the back-of-head distance from every landmark.
    pub far: usize,
}

/// The frozen mask: vertices in no triangle, pieces with no control, and vertices of the
/// controlled pieces farther than `far` (face units) from every anchor (face coordinates).
/// Control vertices are never frozen.
pub fn frozen_mask(
    face: &[Vec3],
    piece: &[Option<u32>],
    controls: &[u32],
    anchors: &[Vec3],
    far: f32,
) -> (Vec<bool>, FrozenCounts) {
    let n = face.len();
    let mut controlled_piece = std::collections::BTreeSet::new();
    for &c in controls {
        if let Some(Some(p)) = piece.get(c as usize) {
            controlled_piece.insert(*p);
        }
    }
    let mut counts = FrozenCounts::default();
    let mut all_pieces = std::collections::BTreeSet::new();
    let mut frozen = vec![false; n];
    for v in 0..n {
        match piece[v] {
            None => {
                frozen[v] = true;
                counts.unused += 1;
            }
            Some(p) if !controlled_piece.contains(&p) => {
                frozen[v] = true;
                counts.uncontrolled += 1;
                all_pieces.insert(p);
            }
            Some(_) => {
                let near = anchors
                    .iter()
                    .any(|a| a.distance_squared(face[v]) <= far * far);
                if !near {
                    frozen[v] = true;
                    counts.far += 1;
                }
            }
        }
    }
    for &c in controls {
        if let Some(f) = frozen.get_mut(c as usize)
            && *f
        {
            *f = false;
            counts.far = counts.far.saturating_sub(1);
        }
    }
    counts.uncontrolled_pieces = all_pieces.len();
    (frozen, counts)
}

/// The mask as inclusive index ranges.
pub fn ranges(mask: &[bool]) -> Vec<[u32; 2]> {
    let mut out: Vec<[u32; 2]> = Vec::new();
    for (i, &f) in mask.iter().enumerate() {
        if !f {
            continue;
        }
        let i = i as u32;
        match out.last_mut() {
            Some(r) if r[1] + 1 == i => r[1] = i,
            _ => out.push([i, i]),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pieces_and_frozen_parts() {
        // Two triangles sharing an edge (0-3), a lone triangle (4-6), an unused vertex 7.
        let mesh = Mesh {
            positions: vec![Vec3::ZERO; 8],
            triangles: vec![[0, 1, 2], [2, 1, 3], [4, 5, 6]],
            ..Mesh::default()
        };
        let p = pieces(&mesh);
        assert_eq!(
            p,
            vec![
                Some(0),
                Some(0),
                Some(0),
                Some(0),
                Some(4),
                Some(4),
                Some(4),
                None
            ]
        );
        let face: Vec<Vec3> = (0..8).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        // Control on vertex 1, anchor at x = 0, reach 2: vertex 3 (x = 3) is too far.
        let (mask, counts) = frozen_mask(&face, &p, &[1], &[Vec3::ZERO], 2.0);
        assert_eq!(
            mask,
            vec![false, false, false, true, true, true, true, true]
        );
        assert_eq!(
            counts,
            FrozenCounts {
                unused: 1,
                uncontrolled: 3,
                uncontrolled_pieces: 1,
                far: 1
            }
        );
        // A control is never frozen, however far.
        let (mask, _) = frozen_mask(&face, &p, &[3], &[Vec3::ZERO], 2.0);
        assert!(!mask[3]);
        assert_eq!(ranges(&mask), vec![[4, 7]]);
        assert_eq!(ranges(&[true, false, true, true]), vec![[0, 0], [2, 3]]);
    }
}
