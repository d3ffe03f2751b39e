//! The part of the rig that can move: rows of `B` that are not all zero, and the normals they touch.
//!
//! On a head rig most vertices (back of the head, teeth, eyeballs) are frozen, so their rows of `B`
//! are zero. Applying only the moving rows, and renormalising only the normals those rows can
//! change, keeps a frame's cost proportional to the face, not to the whole head.

use glam::Vec3;
use mimic_solve::Basis;
use mimic_solve::deform::MovingDeform;
use mimic_solve::{VectorKernel, normals::VertexFans};

/// Moving rows of a basis and the neighbourhood whose normals follow them.
#[derive(Clone, Debug)]
pub(crate) struct MovingPatch {
    /// `rest + B d` over the moving rows, in one pass (rows in its own order).
    deform: MovingDeform,
    /// Fans around the vertices whose normal can change, over a local numbering of the vertices
    /// the normal pass reads (first the moving rows, in the order of `deform.rows()`, then the
    /// other vertices whose normal can change, corners of triangles with a moving vertex, then
    /// the other corners of their triangles); each fan's normal is named by its mesh vertex.
    fans: VertexFans,
    /// Positions by local index, packed 3 floats a vertex (and 1 of padding after the last, for
    /// the fan pass's 16-byte loads): the moving rows are rewritten by every
    /// [`MovingPatch::deform`], the others never move and keep their rest position.
    local_positions: Vec<f32>,
    /// The deform's kernel ([`VectorKernel::best_for_deform`] unless set).
    deform_kernel: VectorKernel,
    /// The fan pass's kernel ([`VectorKernel::best_for_normals`] unless set).
    normals_kernel: VectorKernel,
}

impl MovingPatch {
    /// Finds the moving rows of `basis` and the triangles around them; `rest` holds the rest
    /// positions of every vertex of the mesh (`basis.vertex_count()` of them).
    pub(crate) fn new(basis: &Basis, triangles: &[[u32; 3]], rest: &[Vec3]) -> Self {
        let n = basis.vertex_count().min(rest.len());
        let deform = MovingDeform::new(basis, &rest[..n]);
        let rows = deform.rows().to_vec();
        let mut moving = vec![false; n];
        rows.iter().for_each(|&i| moving[i as usize] = true);
        let mut in_normal_set = vec![false; n];
        let in_range = |t: &[u32; 3]| t.iter().all(|&v| (v as usize) < n);
        for t in triangles.iter().filter(|t| in_range(t)) {
            if t.iter().any(|&v| moving[v as usize]) {
                t.iter().for_each(|&v| in_normal_set[v as usize] = true);
            }
        }
        let incident: Vec<[u32; 3]> = triangles
            .iter()
            .filter(|t| in_range(t) && t.iter().any(|&v| in_normal_set[v as usize]))
            .copied()
            .collect();
        // Local numbering: the moving rows, the rest of the normal set, then the remaining corners
        // of incident triangles. Every moving vertex is in the normal set or in no triangle at
        // all (its normal is then zero, as `vertex_normals` gives it).
        let mut local_of = vec![u32::MAX; n];
        let mut local_vertices: Vec<u32> = rows.clone();
        local_vertices
            .extend((0..n as u32).filter(|&v| in_normal_set[v as usize] && !moving[v as usize]));
        let normal_count = local_vertices.len();
        for (k, &v) in local_vertices.iter().enumerate() {
            local_of[v as usize] = k as u32;
        }
        for t in &incident {
            for &v in t {
                if local_of[v as usize] == u32::MAX {
                    local_of[v as usize] = local_vertices.len() as u32;
                    local_vertices.push(v);
                }
            }
        }
        let local_triangles: Vec<[u32; 3]> = incident
            .iter()
            .map(|t| t.map(|v| local_of[v as usize]))
            .collect();
        // Each fan's normal is reported under its mesh vertex.
        let fans = VertexFans::new(normal_count, local_vertices.len(), &local_triangles)
            .with_names(&local_vertices);
        Self {
            deform,
            local_positions: local_vertices
                .iter()
                .flat_map(|&v| rest[v as usize].to_array())
                .chain([0.0])
                .collect(),
            fans,
            deform_kernel: VectorKernel::best_for_deform(),
            normals_kernel: VectorKernel::best_for_normals(),
        }
    }

    /// The same patch with its deform and its normals computed by the given kernels (the widest
    /// narrower one the CPU has where it lacks one).
    pub(crate) fn with_kernels(mut self, deform: VectorKernel, normals: VectorKernel) -> Self {
        self.deform_kernel = deform.available();
        self.normals_kernel = normals.available();
        self
    }

    /// Number of moving vertices.
    pub(crate) fn moving_count(&self) -> usize {
        self.deform.rows().len()
    }

    /// `positions[i] = rest[i] + (B d)_i` for every moving vertex (`rest` as given to
    /// [`MovingPatch::new`]); others are left as they are. The new positions are also kept for
    /// [`MovingPatch::normals`].
    pub(crate) fn deform(&mut self, d: &[Vec3], positions: &mut [Vec3]) {
        self.deform
            .deform_packed_by(self.deform_kernel, d, &mut self.local_positions, positions);
    }

    /// Recomputes the area-weighted normals of the vertices the moving rows can affect, from the
    /// positions of the last [`MovingPatch::deform`] (rest positions before the first).
    ///
    /// Gathers vertex by vertex over precomputed fans ([`VertexFans`]) on the compact copy of the
    /// neighbourhood, packed 3 floats a vertex (a quarter less to load than 16-byte vectors, and
    /// the deform stores it from the registers it stores the mesh positions from): each normal is
    /// summed in registers, normalised and written once.
    pub(crate) fn normals(&mut self, normals: &mut [Vec3]) {
        self.fans
            .normals_packed_by(self.normals_kernel, &self.local_positions, |v, n| {
                normals[v] = n
            });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use mimic_testkit::lcg;

    #[test]
    fn patch_on_the_ict_head_equals_full_apply_and_reference_normals() {
        // The real mesh (26 719 vertices, open boundaries, eye and mouth holes, separate shells),
        // a synthetic basis moving the front of the face with 5 controls (rows behind z = 2 cm
        // frozen), a random frame.
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../configs/meshes/ict-facekit/generic_neutral_mesh.obj");
        let mesh = mimic_assets::load_obj(&path).expect("ICT neutral mesh");
        let (n, m) = (mesh.positions.len(), 5usize);
        let mut seed = 17u64;
        let data: Vec<f32> = mesh
            .positions
            .iter()
            .flat_map(|p| {
                let front = p.z > 2.0;
                (0..m)
                    .map(|_| {
                        if front {
                            0.5 + 0.5 * lcg(&mut seed)
                        } else {
                            0.0
                        }
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        let basis = Basis::from_row_major(n, m, data).unwrap();
        let mut patch = MovingPatch::new(&basis, &mesh.triangles, &mesh.positions);
        assert!(patch.moving_count() > 1000 && patch.moving_count() < n);
        let d: Vec<Vec3> = (0..m)
            .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)) * 0.5)
            .collect();
        let mut u = vec![Vec3::ZERO; n];
        basis.apply(&d, &mut u);
        let full: Vec<Vec3> = mesh
            .positions
            .iter()
            .zip(&u)
            .map(|(p, u)| *p + *u)
            .collect();
        let mut full_n = vec![Vec3::ZERO; n];
        mimic_solve::vertex_normals(&full, &mesh.triangles, &mut full_n);
        let mut pos = mesh.positions.clone();
        let mut nrm = vec![Vec3::ZERO; n];
        mimic_solve::vertex_normals(&pos, &mesh.triangles, &mut nrm);
        patch.deform(&d, &mut pos);
        patch.normals(&mut nrm);
        assert_eq!(pos, full);
        // Tolerance per vertex: both are f32 area-weighted sums of the same k cross products,
        // taken at different corners; each is within (6 + k) eps sum_t L_t^2 of the exact sum (L_t
        // the triangle's longest edge), so after normalising the two differ by at most
        // 4 (6 + k) eps sum_t L_t^2 / |N| + 16 eps (|N| the exact sum's length, here in f64).
        let mut sum = vec![glam::DVec3::ZERO; n];
        let mut scale = vec![0f64; n];
        let mut k = vec![0usize; n];
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|v| full[v as usize].as_dvec3());
            let l2 = (b - a)
                .length_squared()
                .max((c - a).length_squared())
                .max((c - b).length_squared());
            for &v in t {
                sum[v as usize] += (b - a).cross(c - a);
                scale[v as usize] += l2;
                k[v as usize] += 1;
            }
        }
        let eps = f32::EPSILON as f64;
        let mut compared = 0;
        for v in 0..n {
            let len = sum[v].length();
            let tol = 4.0 * (6 + k[v]) as f64 * eps * scale[v] / len + 16.0 * eps;
            if len > 0.0 && tol < 0.1 {
                let err = (nrm[v].as_dvec3() - full_n[v].as_dvec3()).length();
                assert!(
                    err <= tol,
                    "v={v}: {} vs {}, {err:e} > {tol:e}",
                    nrm[v],
                    full_n[v]
                );
                compared += 1;
            }
        }
        assert!(
            compared > n * 9 / 10,
            "{compared} of {n} vertices well conditioned"
        );
    }

    #[test]
    fn patch_equals_full_apply_and_full_normals() {
        // A 6 x 6 grid, 2 controls, rows of the left half zero (frozen).
        let g = 6usize;
        let positions: Vec<Vec3> = (0..g * g)
            .map(|k| Vec3::new((k % g) as f32, (k / g) as f32, 0.0))
            .collect();
        let mut triangles = Vec::new();
        for y in 0..g - 1 {
            for x in 0..g - 1 {
                let i = (y * g + x) as u32;
                triangles.push([i, i + 1, i + g as u32 + 1]);
                triangles.push([i, i + g as u32 + 1, i + g as u32]);
            }
        }
        let data: Vec<f32> = (0..g * g)
            .flat_map(|k| {
                if k % g < 3 {
                    [0.0, 0.0]
                } else {
                    [0.1 * (k % g) as f32, 0.05 * (k / g) as f32]
                }
            })
            .collect();
        let basis = Basis::from_row_major(g * g, 2, data).unwrap();
        let mut patch = MovingPatch::new(&basis, &triangles, &positions);
        assert_eq!(patch.moving_count(), g * 3);
        let d = [Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.3, -0.2, 0.5)];
        // Reference: full apply and full normals.
        let mut u = vec![Vec3::ZERO; g * g];
        basis.apply(&d, &mut u);
        let full: Vec<Vec3> = positions.iter().zip(&u).map(|(p, u)| *p + *u).collect();
        let mut full_n = vec![Vec3::ZERO; g * g];
        mimic_solve::vertex_normals(&full, &triangles, &mut full_n);
        // Patch: start from rest positions and rest normals, update only what moves.
        let mut pos = positions.clone();
        let mut nrm = vec![Vec3::ZERO; g * g];
        mimic_solve::vertex_normals(&pos, &triangles, &mut nrm);
        patch.deform(&d, &mut pos);
        patch.normals(&mut nrm);
        assert_eq!(pos, full);
        for (a, b) in nrm.iter().zip(&full_n) {
            // Same sums in a different order: f32 rounding, ~1e-6.
            assert!((*a - *b).length() < 1e-5, "{a} vs {b}");
        }
    }
}
