//! glTF vertices from an OBJ-style mesh, whose texture coordinates are per triangle corner.

use crate::GltfError;
use glam::Vec2;
use std::collections::HashMap;

/// A mesh's vertices as glTF needs them: one texture coordinate per vertex.
///
/// The first `n` glTF vertices are the rig's vertices in their order (each with the UV of its
/// first corner); a vertex used with other UVs too (a UV seam) gets one more glTF vertex per
/// other UV, appended after them. So glTF vertex `i < n` is rig vertex `i`.
#[derive(Clone, Debug, PartialEq)]
pub struct SplitVertices {
    /// Rig vertex of each glTF vertex (`source[i] == i` for `i < n`).
    pub source: Vec<u32>,
    /// Texture coordinate of each glTF vertex, glTF convention (`v` down: `1 - v` of the OBJ);
    /// empty when the mesh has no UVs.
    pub uvs: Vec<Vec2>,
    /// Triangles in glTF vertex indices.
    pub triangles: Vec<[u32; 3]>,
}

/// Splits the vertices of a mesh of `vertex_count` vertices at its UV seams (see
/// [`SplitVertices`]); without UVs (`uv_triangles` empty) the vertices stay as they are.
pub fn split_vertices(
    vertex_count: usize,
    triangles: &[[u32; 3]],
    uvs: &[Vec2],
    uv_triangles: &[[u32; 3]],
) -> Result<SplitVertices, GltfError> {
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&v) = tri.iter().find(|v| **v as usize >= vertex_count) {
            return Err(GltfError::VertexIndex {
                triangle: t,
                vertex: v,
                vertex_count,
            });
        }
    }
    let mut source: Vec<u32> = (0..vertex_count as u32).collect();
    if uv_triangles.is_empty() || uv_triangles.len() != triangles.len() {
        return Ok(SplitVertices {
            source,
            uvs: Vec::new(),
            triangles: triangles.to_vec(),
        });
    }
    let mut first: Vec<Option<u32>> = vec![None; vertex_count];
    let mut extra: HashMap<(u32, u32), u32> = HashMap::new();
    let mut out = Vec::with_capacity(triangles.len());
    for (t, (tri, uvt)) in triangles.iter().zip(uv_triangles).enumerate() {
        let mut g = [0u32; 3];
        for k in 0..3 {
            let (v, uv) = (tri[k], uvt[k]);
            if uv as usize >= uvs.len() {
                return Err(GltfError::UvIndex {
                    triangle: t,
                    uv,
                    uv_count: uvs.len(),
                });
            }
            g[k] = match first[v as usize] {
                None => {
                    first[v as usize] = Some(uv);
                    v
                }
                Some(f) if f == uv => v,
                Some(_) => *extra.entry((v, uv)).or_insert_with(|| {
                    source.push(v);
                    (source.len() - 1) as u32
                }),
            };
        }
        out.push(g);
    }
    let flip = |uv: Vec2| Vec2::new(uv.x, 1.0 - uv.y);
    let mut gl_uvs: Vec<Vec2> = first
        .iter()
        .map(|f| f.map_or(Vec2::ZERO, |k| flip(uvs[k as usize])))
        .collect();
    let mut extras: Vec<(u32, u32)> = extra.into_iter().map(|(k, g)| (g, k.1)).collect();
    extras.sort_unstable();
    gl_uvs.extend(extras.iter().map(|(_, uv)| flip(uvs[*uv as usize])));
    Ok(SplitVertices {
        source,
        uvs: gl_uvs,
        triangles: out,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_seam_vertex_is_duplicated_after_the_rig_vertices() {
        // Two triangles sharing vertices 1 and 2; vertex 2 has another UV in the second.
        let tris = [[0, 1, 2], [2, 1, 3]];
        let uvs = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.5, 0.5),
        ];
        let uvt = [[0, 1, 2], [4, 1, 3]];
        let s = split_vertices(4, &tris, &uvs, &uvt).unwrap();
        assert_eq!(s.source, vec![0, 1, 2, 3, 2]);
        assert_eq!(s.triangles, vec![[0, 1, 2], [4, 1, 3]]);
        assert_eq!(s.uvs[4], Vec2::new(0.5, 0.5));
        assert_eq!(s.uvs[2], Vec2::new(0.0, 0.0));
        assert_eq!(s.uvs[3], Vec2::new(1.0, 0.0));
        // Every corner's glTF UV is the mesh's UV of that corner (flipped).
        for (g, u) in s.triangles.iter().zip(&uvt) {
            for k in 0..3 {
                let want = uvs[u[k] as usize];
                assert_eq!(s.uvs[g[k] as usize], Vec2::new(want.x, 1.0 - want.y));
            }
        }
        let e = split_vertices(4, &tris, &uvs, &[[0, 1, 9], [4, 1, 3]]).unwrap_err();
        assert!(e.to_string().contains("triangle 0"), "{e}");
    }
}
