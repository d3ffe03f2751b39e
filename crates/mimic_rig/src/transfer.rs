//! Deformation transfer (Sumner and Popovic, "Deformation Transfer for Triangle Meshes",
//! SIGGRAPH 2004): a template's blend shapes (ICT's expressions) made for any head the template
//! was registered onto ([`crate::head_template::register_template`]).
//!
//! (1) [`correspond`]: the template's skin deformed by the registration's nodes (each vertex
//! moved as its nearest nodes moved, inverse-distance weighted), then each target triangle's
//! source triangle is the deformed template triangle nearest its centroid that faces its way.
//! (2) Per source triangle and shape the deformation gradient `Q = V' V^-1` (`V`: two edges and
//! the normal scaled by one over the root of its length, before and after), turned from the
//! template's axes into the target's by the registration's rotation. (3) [`transfer_shapes`]:
//! the target's displacements `d` minimise `sum_j area_j |grad_j d - (Q_c(j) - I) P_j|^2` over
//! its triangles (`grad_j` the gradient of the linear interpolant on triangle `j`, `P_j` the
//! projection onto its plane: the Poisson form of the paper's least squares, Botsch et al.
//! 2006), target triangles without a source, or whose source never moves, asking for no
//! change; vertices none of whose triangles has a moving source are held (the back of the
//! head, the neck, parts the template lacks) and the rest blend into them smoothly. The
//! normal matrix is the same for every shape and coordinate: one sparse Cholesky factorisation
//! (faer) per head, every shape's three coordinates as right-hand sides.

use crate::RigNewError;
use crate::head_template::Registration;
use crate::nearest::PointIndex;
use faer::Side;
use faer::prelude::*;
use faer::sparse::{SparseColMat, Triplet};
use glam::{DMat3, DVec3, Mat3, Vec3};
use mimic_types::Mesh;

/// Knobs of [`correspond`] and [`transfer_shapes`].
#[derive(Clone, Debug, PartialEq)]
pub struct TransferSettings {
    /// Template vertices that take part (ICT: the face, head and neck, 0-11247).
    pub skin: std::ops::Range<usize>,
    /// Nodes whose moves each template vertex follows.
    pub nodes_per_vertex: usize,
    /// A target triangle takes no source farther than this from its centroid, face units.
    pub max_distance: f32,
    /// ... nor one whose normal makes a dot product below this with its own.
    pub min_dot: f32,
    /// A source vertex moving less than this (template units) in every shape counts as still.
    pub still: f32,
    /// Length (face units) below which the gradients rule and above which each vertex keeps
    /// near its correspondence's displacement: the anchor weight is `1 / (length x IOD)^2`
    /// per unit area, so errors in the gradients do not add up across the face.
    pub anchor_length: f32,
}

impl Default for TransferSettings {
    fn default() -> Self {
        Self {
            skin: 0..11248,
            nodes_per_vertex: 8,
            max_distance: 0.1,
            min_dot: 0.3,
            still: 1e-3,
            anchor_length: 0.08,
        }
    }
}

/// Which template triangle each target triangle follows, and how template directions turn
/// into the target's.
#[derive(Clone, Debug, PartialEq)]
pub struct Correspondence {
    /// Per target triangle: its source triangle (an index into the template's triangles).
    pub source: Vec<Option<u32>>,
    /// Per target vertex: the deformed template triangle nearest it and the barycentric
    /// coordinates of its nearest point there.
    pub vertex_source: Vec<Option<(u32, Vec3)>>,
    /// Rotation taking template directions to target directions.
    pub rotation: Mat3,
    /// Scale taking template lengths to target lengths.
    pub scale: f32,
    /// One face unit (the target's IOD as the registration sees it) in target lengths.
    pub face_unit: f32,
    /// The template's skin where the registration put it, in its face frame.
    pub deformed: Vec<Vec3>,
}

/// The template's vertices in `s.skin` moved as the registration's nodes moved, in the
/// template's face frame (others stay where they are).
pub fn deform_template(template: &Mesh, reg: &Registration, s: &TransferSettings) -> Vec<Vec3> {
    let index = PointIndex::new(&reg.node_at, |_| true);
    let h2 = 0.05f32 * 0.05;
    (0..template.vertex_count())
        .map(|v| {
            let f = reg.frame.to_face(template.positions[v]);
            if !s.skin.contains(&v) {
                return f;
            }
            let (mut sum, mut total) = (Vec3::ZERO, 0.0f32);
            for (k, d) in index.nearest_k(f, s.nodes_per_vertex) {
                let w = 1.0 / (d * d + h2);
                let k = k as usize;
                sum += w * (reg.deformed[k] - reg.node_at[k]);
                total += w;
            }
            if total > 0.0 { f + sum / total } else { f }
        })
        .collect()
}

/// Each target triangle's source triangle on the registered template.
pub fn correspond(
    target: &Mesh,
    template: &Mesh,
    reg: &Registration,
    s: &TransferSettings,
) -> Correspondence {
    let deformed = deform_template(template, reg, s);
    let in_skin = |t: &[u32; 3]| t.iter().all(|v| s.skin.contains(&(*v as usize)));
    let mut around: Vec<Vec<u32>> = vec![Vec::new(); template.vertex_count()];
    for (i, t) in template.triangles.iter().enumerate() {
        if in_skin(t) {
            for v in t {
                around[*v as usize].push(i as u32);
            }
        }
    }
    let index = PointIndex::new(&deformed, |v| !around[v].is_empty());
    let local = &reg.local.positions;
    // The nearest deformed template triangle to `at` facing along `normal`, and the point.
    let nearest = |at: Vec3, normal: Vec3| {
        let mut best: Option<(u32, f32, Vec3)> = None;
        for (v, _) in index.nearest_k(at, 6) {
            for &i in &around[v as usize] {
                let [p, q, r] = template.triangles[i as usize].map(|v| deformed[v as usize]);
                let Some(n) = (q - p).cross(r - p).try_normalize() else {
                    continue;
                };
                if n.dot(normal) < s.min_dot {
                    continue;
                }
                let on = closest_on_triangle(at, p, q, r);
                let d = at.distance(on);
                if d <= s.max_distance && best.is_none_or(|(_, e, _)| d < e) {
                    best = Some((i, d, barycentric(on, p, q, r)));
                }
            }
        }
        best
    };
    let source = target
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| local[v as usize]);
            let normal = (b - a).cross(c - a).try_normalize()?;
            nearest((a + b + c) / 3.0, normal).map(|(i, _, _)| i)
        })
        .collect();
    let normals = crate::register::vertex_normals(local, &target.triangles);
    let vertex_source = local
        .iter()
        .zip(&normals)
        .map(|(p, n)| {
            if *n == Vec3::ZERO {
                return None;
            }
            nearest(*p, *n).map(|(i, _, b)| (i, b))
        })
        .collect();
    let axes = Mat3::from_cols(reg.frame.axes[0], reg.frame.axes[1], reg.frame.axes[2]);
    Correspondence {
        source,
        vertex_source,
        rotation: Mat3::from_quat(reg.rigid.pose.rotation) * axes.transpose(),
        scale: reg.rigid.pose.scale / reg.frame.iod,
        face_unit: reg.rigid.pose.scale,
        deformed,
    }
}

/// Barycentric coordinates of `p` (on the triangle's plane) in triangle `a b c`.
fn barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (v0, v1, v2) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (v0.dot(v0), v0.dot(v1), v1.dot(v1));
    let (d20, d21) = (v2.dot(v0), v2.dot(v1));
    let denom = d00 * d11 - d01 * d01;
    if denom.abs() <= f32::MIN_POSITIVE {
        return Vec3::new(1.0, 0.0, 0.0);
    }
    let v = (d11 * d20 - d01 * d21) / denom;
    let w = (d00 * d21 - d01 * d20) / denom;
    Vec3::new(1.0 - v - w, v, w)
}

/// The point of triangle `a b c` nearest to `p` (Ericson, "Real-Time Collision Detection" 5.1.5).
pub fn closest_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Sumner's frame of a triangle: two edges and the normal scaled by one over the root of its
/// length.
fn frame_of(a: DVec3, b: DVec3, c: DVec3) -> DMat3 {
    let (e1, e2) = (b - a, c - a);
    let n = e1.cross(e2);
    DMat3::from_cols(e1, e2, n / n.length().sqrt().max(1e-300))
}

/// The deformation gradient `Q = V' V^-1` of source triangle `t` under `delta`, or `None` when
/// the triangle is degenerate.
fn gradient(neutral: &[Vec3], delta: &[Vec3], t: [u32; 3]) -> Option<DMat3> {
    let p = t.map(|v| neutral[v as usize].as_dvec3());
    let q = t.map(|v| (neutral[v as usize] + delta[v as usize]).as_dvec3());
    let v = frame_of(p[0], p[1], p[2]);
    (v.determinant().abs() > 1e-300).then(|| frame_of(q[0], q[1], q[2]) * v.inverse())
}

/// Made shapes: per shape, a position delta per target vertex.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferredShapes {
    /// Per shape (in the order given), the target's deltas.
    pub deltas: Vec<Vec<Vec3>>,
    /// Target vertices solved for (the rest held).
    pub free: usize,
    /// Target triangles that follow a moving source triangle.
    pub following: usize,
}

/// Transfers `shapes` (position deltas on `source`, the template mesh) onto `target` through
/// `corr`: one factorisation, every shape one solve.
pub fn transfer_shapes(
    target: &Mesh,
    source: &Mesh,
    shapes: &[&[Vec3]],
    corr: &Correspondence,
    s: &TransferSettings,
) -> Result<TransferredShapes, RigNewError> {
    let n = target.vertex_count();
    // Source triangles that move in some shape.
    let moves: Vec<bool> = (0..source.vertex_count())
        .map(|v| {
            shapes
                .iter()
                .any(|d| d.get(v).is_some_and(|d| d.length() > s.still))
        })
        .collect();
    let moving = |t: u32| {
        source
            .triangles
            .get(t as usize)
            .is_some_and(|t| t.iter().any(|v| moves[*v as usize]))
    };
    let follows: Vec<Option<u32>> = corr
        .source
        .iter()
        .map(|c| c.filter(|t| moving(*t)))
        .collect();
    let mut free = vec![u32::MAX; n];
    let mut unknowns = 0u32;
    for (t, f) in target.triangles.iter().zip(&follows) {
        if f.is_some() {
            for v in t {
                let slot = &mut free[*v as usize];
                if *slot == u32::MAX {
                    *slot = unknowns;
                    unknowns += 1;
                }
            }
        }
    }
    let m = unknowns as usize;
    let r = corr.rotation.as_dmat3();
    // Per target triangle: area and the gradients of its three hat functions.
    let mut grads: Vec<Option<(f64, [DVec3; 3])>> = Vec::with_capacity(target.triangles.len());
    let mut triplets: Vec<Triplet<usize, usize, f64>> = Vec::new();
    let mut diagonal = 0.0f64;
    for t in &target.triangles {
        let p = t.map(|v| target.positions[v as usize].as_dvec3());
        let cross = (p[1] - p[0]).cross(p[2] - p[0]);
        let twice = cross.length();
        let idx = t.map(|v| free[v as usize]);
        if twice <= 1e-300 || idx.iter().all(|i| *i == u32::MAX) {
            grads.push(None);
            continue;
        }
        let u = cross / twice;
        let g = [
            u.cross(p[2] - p[1]) / twice,
            u.cross(p[0] - p[2]) / twice,
            u.cross(p[1] - p[0]) / twice,
        ];
        let area = 0.5 * twice;
        for a in 0..3 {
            for b in 0..3 {
                let (ia, ib) = (idx[a], idx[b]);
                if ia == u32::MAX || ib == u32::MAX || ia < ib {
                    continue;
                }
                let w = area * g[a].dot(g[b]);
                if ia == ib {
                    diagonal += w;
                }
                triplets.push(Triplet::new(ia as usize, ib as usize, w));
            }
        }
        grads.push(Some((area, g)));
    }
    // A tiny pull to zero keeps pieces with no held vertex solvable.
    let eps = 1e-9 * diagonal / m.max(1) as f64;
    for i in 0..m {
        triplets.push(Triplet::new(i, i, eps));
    }
    // The anchors: each free vertex pulled towards its correspondence's displacement with
    // weight `lambda` x its area (a third of its triangles').
    let mut vertex_area = vec![0f64; m];
    for (t, g) in target.triangles.iter().zip(&grads) {
        if let Some((area, _)) = g {
            for v in t {
                if let Some(a) = vertex_area.get_mut(free[*v as usize] as usize) {
                    *a += area / 3.0;
                }
            }
        }
    }
    let length = f64::from(s.anchor_length) * f64::from(corr.face_unit);
    let lambda = if length > 0.0 {
        1.0 / (length * length)
    } else {
        0.0
    };
    for (i, a) in vertex_area.iter().enumerate() {
        triplets.push(Triplet::new(i, i, lambda * a));
    }
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(m, m, &triplets)
        .map_err(|e| RigNewError::Frame(format!("deformation transfer: assembly failed: {e:?}")))?;
    let llt = a.sp_cholesky(Side::Lower).map_err(|e| {
        RigNewError::Frame(format!(
            "deformation transfer: the system is singular: {e:?}"
        ))
    })?;
    let mut rhs = Mat::<f64>::zeros(m, 3 * shapes.len());
    let to_target = r * f64::from(corr.scale);
    for (k, delta) in shapes.iter().enumerate() {
        for (v, vs) in corr.vertex_source.iter().enumerate() {
            let (i, Some((src, b))) = (free[v], vs) else {
                continue;
            };
            let Some(st) = source.triangles.get(*src as usize) else {
                continue;
            };
            if i == u32::MAX {
                continue;
            }
            let i = i as usize;
            let u: Vec3 = st
                .iter()
                .zip(b.to_array())
                .map(|(sv, w)| delta.get(*sv as usize).copied().unwrap_or(Vec3::ZERO) * w)
                .sum();
            let u = to_target * u.as_dvec3() * (lambda * vertex_area[i]);
            for c in 0..3 {
                rhs[(i, 3 * k + c)] += u[c];
            }
        }
        // Each source triangle's gradient, in target axes, minus the identity.
        let mut cache: std::collections::HashMap<u32, DMat3> = Default::default();
        for ((t, f), g) in target.triangles.iter().zip(&follows).zip(&grads) {
            let (Some(src), Some((area, g))) = (f, g) else {
                continue;
            };
            let q = *cache.entry(*src).or_insert_with(|| {
                source
                    .triangles
                    .get(*src as usize)
                    .and_then(|st| gradient(&source.positions, delta, *st))
                    .map_or(DMat3::ZERO, |q| r * (q - DMat3::IDENTITY) * r.transpose())
            });
            for (v, ga) in t.iter().zip(g) {
                let i = free[*v as usize];
                if i == u32::MAX {
                    continue;
                }
                let b = q * *ga * *area;
                for c in 0..3 {
                    rhs[(i as usize, 3 * k + c)] += b[c];
                }
            }
        }
    }
    llt.solve_in_place(rhs.as_mut());
    let deltas = (0..shapes.len())
        .map(|k| {
            free.iter()
                .map(|&i| {
                    if i == u32::MAX {
                        Vec3::ZERO
                    } else {
                        let i = i as usize;
                        DVec3::new(rhs[(i, 3 * k)], rhs[(i, 3 * k + 1)], rhs[(i, 3 * k + 2)])
                            .as_vec3()
                    }
                })
                .collect()
        })
        .collect();
    Ok(TransferredShapes {
        deltas,
        free: m,
        following: follows.iter().filter(|f| f.is_some()).count(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_closest_point_is_a_corner_an_edge_point_or_inside() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        assert_eq!(closest_on_triangle(Vec3::new(-1.0, -1.0, 2.0), a, b, c), a);
        assert_eq!(
            closest_on_triangle(Vec3::new(0.5, -1.0, 0.0), a, b, c),
            Vec3::new(0.5, 0.0, 0.0)
        );
        assert_eq!(
            closest_on_triangle(Vec3::new(0.2, 0.3, 5.0), a, b, c),
            Vec3::new(0.2, 0.3, 0.0)
        );
        let bary = barycentric(Vec3::new(0.2, 0.3, 0.0), a, b, c);
        assert!((bary - Vec3::new(0.5, 0.2, 0.3)).length() < 1e-6, "{bary}");
    }

    #[test]
    fn a_sheet_onto_itself_turned_and_scaled_gets_its_own_shape_back() {
        // A 21 x 21 sheet; the shape bulges a disc in the middle. The target is the same sheet
        // turned and scaled by 10, each triangle and vertex corresponding to its own.
        let side = 21u32;
        let mut source = Mesh::default();
        for j in 0..side {
            for i in 0..side {
                source
                    .positions
                    .push(Vec3::new(i as f32, j as f32, 0.0) / (side - 1) as f32);
            }
        }
        for j in 0..side - 1 {
            for i in 0..side - 1 {
                let a = j * side + i;
                source.triangles.push([a, a + 1, a + side + 1]);
                source.triangles.push([a, a + side + 1, a + side]);
            }
        }
        let bump: Vec<Vec3> = source
            .positions
            .iter()
            .map(|p| {
                let r2 = (*p - Vec3::new(0.5, 0.5, 0.0)).length_squared();
                Vec3::new(0.0, 0.0, 0.1 * (1.0 - r2 / 0.09).max(0.0).powi(2))
            })
            .collect();
        let rotation = Mat3::from_rotation_y(0.4);
        let target = Mesh {
            positions: source
                .positions
                .iter()
                .map(|p| rotation * (*p * 10.0))
                .collect(),
            triangles: source.triangles.clone(),
            ..Mesh::default()
        };
        let corr = Correspondence {
            source: (0..source.triangles.len() as u32).map(Some).collect(),
            vertex_source: (0..source.vertex_count())
                .map(|v| {
                    let t = source.triangles.iter().position(|t| t[0] == v as u32);
                    t.map(|t| (t as u32, Vec3::X))
                })
                .collect(),
            rotation,
            scale: 10.0,
            face_unit: 10.0,
            deformed: source.positions.clone(),
        };
        let s = TransferSettings::default();
        let made = transfer_shapes(&target, &source, &[&bump], &corr, &s).unwrap();
        let want: Vec<Vec3> = bump.iter().map(|d| rotation * (*d * 10.0)).collect();
        let error: f32 = made.deltas[0]
            .iter()
            .zip(&want)
            .map(|(a, b)| a.distance(*b))
            .sum();
        let size: f32 = want.iter().map(|d| d.length()).sum();
        // Gradients and anchors agree with the truth, so only the held border differs.
        assert!(error <= 0.02 * size, "{error} vs {size}");
    }
}
