//! The thin-shell basis: `min ks u'Lu + u'L M^-1 L u` with the controls as hard constraints.
//!
//! `L` is the cotangent stiffness matrix and `M` the lumped mass of [`crate::cotangent`]; the
//! energy is a membrane term (weight `ks`, rig units^-2) plus the discrete bending energy
//! `sum_k (Lu)_k^2 / M_k` (Botsch & Sorkine 2008, "On Linear Variational Surface Deformation
//! Methods"). Each coordinate of `u` is solved alone with the same scalar system, so x, y and z
//! share one column per control, as in the other solvers.
//!
//! - **Controls are hard constraints, eliminated**: with `Q = ks L + L M^-1 L`, free vertices F
//!   and control vertices C, `u_F = -Q_FF^-1 Q_FC d`, `u_C = d`. So every control is reproduced
//!   exactly (like the RBF), there is no constraint weight to tune, and `Q_FF` keeps the
//!   conditioning of the energy (a stiff soft constraint `w^2` would add entries far above it).
//!   Two controls on one vertex share it: that vertex follows their mean.
//! - Frozen vertices are fixed at `u = 0` (eliminated); their rows of `L` stay in the bending sum,
//!   so the free surface meets the frozen border without a kink (a clamped border).
//! - Parts of the mesh that no control and no frozen vertex reaches are held still (the energy does
//!   not see their translation), with a `tracing::warn`, as the Laplacian does.
//! - One sparse Cholesky factorisation of `Q_FF` (faer, supernodal), one solve with one
//!   right-hand side per distinct control vertex; nothing dense is n x n.
//! - Sockets ([`ShellSettings::sockets`], [`SocketMode`]): the bending energy carries a
//!   lip's or lid's motion round the rim and deep into the mouth or eye socket behind it. `Free`
//!   keeps them in the solve; `Frozen` holds them still; `Decay` leaves them out of the face's
//!   solve (their triangles removed, so the lips and lids have free borders there) and fills them
//!   afterwards by a screened membrane solve `(L + M / l^2) u_S = -L_SR u_R` on the sockets (R:
//!   the vertices next to them, with the face's solution; `l` per socket), a second, small SPD
//!   factorisation; the rim's motion then fades over about `l` into the socket.

#![allow(
    clippy::needless_range_loop,
    reason = "index loops mirror the matrix formulas (rows i, columns j) and touch several arrays at once"
)]

use crate::SolveError;
use crate::cotangent::{SymRows, cotangent_laplacian, lumped_mass};
use faer::Side;
use faer::prelude::*;
use faer::sparse::{SparseColMat, Triplet};
use glam::Vec3;
use mimic_types::{ShellSettings, SocketMode};

/// What the thin-shell solve needs from a rig.
#[derive(Clone, Copy, Debug)]
pub struct ShellInputs<'a> {
    /// Rest positions.
    pub positions: &'a [Vec3],
    /// Triangles.
    pub triangles: &'a [[u32; 3]],
    /// Per-vertex frozen flags.
    pub frozen: &'a [bool],
    /// Vertex of each control (one output column each).
    pub controls: &'a [usize],
    /// Stiffness and socket handling.
    pub settings: &'a ShellSettings,
    /// Name of the system, for errors.
    pub system: &'a str,
}

/// Basis columns of the thin-shell solve: `n x k` values (k = controls), row-major. Rows of
/// frozen vertices, and of parts no control or frozen vertex reaches, are zero.
pub fn shell_columns(inp: &ShellInputs<'_>) -> Result<Vec<f64>, SolveError> {
    inp.settings
        .validate()
        .map_err(|e| SolveError::InvalidSetting(e.to_string()))?;
    let n = inp.positions.len();
    let k = inp.controls.len();
    if let Some(&c) = inp.controls.iter().find(|&&c| c >= n) {
        return Err(SolveError::InvalidSetting(format!(
            "{}: control vertex {c} outside the {n} vertices",
            inp.system
        )));
    }
    let frozen = |i: usize| inp.frozen.get(i).copied().unwrap_or(false);
    let mut is_control = vec![false; n];
    for &c in inp.controls {
        is_control[c] = true;
    }
    let mode = inp.settings.socket_mode;
    let socket: Vec<bool> = (0..n)
        .map(|i| {
            mode != SocketMode::Free
                && inp.settings.sockets.decay_of(i as u32).is_some()
                && !frozen(i)
                && !is_control[i]
        })
        .collect();
    // Fixed at zero in the face's solve: frozen, and frozen sockets.
    let mut fixed: Vec<bool> = (0..n)
        .map(|i| frozen(i) || (mode == SocketMode::Frozen && socket[i]))
        .collect();
    let decay = mode == SocketMode::Decay && socket.iter().any(|s| *s);
    // The face's mesh: without the socket triangles when they get their own solve.
    let face_triangles: Vec<[u32; 3]> = if decay {
        inp.triangles
            .iter()
            .filter(|t| t.iter().all(|&v| (v as usize) < n && !socket[v as usize]))
            .copied()
            .collect()
    } else {
        inp.triangles.to_vec()
    };
    let l = cotangent_laplacian(inp.positions, &face_triangles);
    let mass = lumped_mass(inp.positions, &face_triangles);
    let left_out = |i: usize| decay && socket[i];
    hold_floating(&l, &mut fixed, &is_control, &left_out, inp.system);

    // Distinct control vertices (one right-hand side each) and the share of each control.
    let mut slot = vec![usize::MAX; n];
    let mut vertices: Vec<usize> = Vec::new();
    let mut count: Vec<usize> = Vec::new();
    for &c in inp.controls {
        if slot[c] == usize::MAX {
            slot[c] = vertices.len();
            vertices.push(c);
            count.push(0);
        }
        count[slot[c]] += 1;
    }
    let mut free_index = vec![usize::MAX; n];
    let mut nf = 0;
    for i in 0..n {
        if !fixed[i] && !is_control[i] && !left_out(i) {
            free_index[i] = nf;
            nf += 1;
        }
    }
    // Per distinct control vertex: its column over all n vertices (1 at itself).
    let mut unit = vec![0f64; n * vertices.len()];
    let nv = vertices.len();
    for (s, &c) in vertices.iter().enumerate() {
        unit[c * nv + s] = 1.0;
    }
    if nf > 0 && nv > 0 {
        let solved = solve_face(&l, &mass, inp, &free_index, nf, &vertices)?;
        for i in 0..n {
            let f = free_index[i];
            if f != usize::MAX {
                for s in 0..nv {
                    unit[i * nv + s] = solved[(f, s)];
                }
            }
        }
    }
    if decay && nv > 0 {
        fill_sockets(inp, &socket, &mut unit, nv)?;
    }
    let mut cols = vec![0f64; n * k];
    for i in 0..n {
        if frozen(i) {
            continue;
        }
        for (j, &c) in inp.controls.iter().enumerate() {
            let s = slot[c];
            cols[i * k + j] = unit[i * nv + s] / count[s] as f64;
        }
    }
    if cols.iter().any(|v| !v.is_finite()) {
        return Err(SolveError::Singular {
            system: inp.system.to_string(),
            detail: "non-finite solution".into(),
        });
    }
    Ok(cols)
}

/// Marks as fixed every vertex of a connected part (by `l`'s pattern) that holds no control and no
/// fixed vertex, except the `left_out` ones, and warns if there were any.
fn hold_floating(
    l: &SymRows,
    fixed: &mut [bool],
    is_control: &[bool],
    left_out: &dyn Fn(usize) -> bool,
    system: &str,
) {
    let n = l.len();
    let mut part = vec![usize::MAX; n];
    let mut stack = Vec::new();
    let mut floating = 0usize;
    for start in 0..n {
        if part[start] != usize::MAX || left_out(start) {
            continue;
        }
        part[start] = start;
        stack.push(start);
        let mut members = Vec::new();
        let mut anchored = false;
        while let Some(i) = stack.pop() {
            members.push(i);
            anchored |= fixed[i] || is_control[i];
            for (j, _) in l.row(i) {
                if part[j] == usize::MAX && !left_out(j) {
                    part[j] = start;
                    stack.push(j);
                }
            }
        }
        if !anchored {
            for i in members {
                if !fixed[i] {
                    fixed[i] = true;
                    floating += 1;
                }
            }
        }
    }
    if floating > 0 {
        tracing::warn!(
            system,
            vertices = floating,
            "mesh parts reached by no control and no frozen vertex are held still"
        );
    }
}

/// Solves `Q_FF X = -Q_FC` for the distinct control vertices (`nf x nv`), `Q = ks L + L M^-1 L`.
fn solve_face(
    l: &SymRows,
    mass: &[f64],
    inp: &ShellInputs<'_>,
    free_index: &[usize],
    nf: usize,
    vertices: &[usize],
) -> Result<Mat<f64>, SolveError> {
    let n = l.len();
    let ks = inp.settings.stiffness;
    let mut triplets: Vec<Triplet<usize, usize, f64>> = Vec::new();
    // Membrane: ks L over the free vertices (lower triangle).
    if ks > 0.0 {
        for i in 0..n {
            let p = free_index[i];
            if p == usize::MAX {
                continue;
            }
            triplets.push(Triplet::new(p, p, ks * l.diag[i]));
            for (j, v) in l.row(i) {
                let q = free_index[j];
                if q != usize::MAX && p > q {
                    triplets.push(Triplet::new(p, q, ks * v));
                }
            }
        }
    }
    // Bending: every row k of L (fixed ones too), restricted to free columns, outer product / M_k.
    let mut row: Vec<(usize, f64)> = Vec::new();
    for kk in 0..n {
        row.clear();
        let entries = std::iter::once((kk, l.diag[kk])).chain(l.row(kk));
        row.extend(entries.filter_map(|(j, v)| {
            let q = free_index[j];
            (q != usize::MAX && v != 0.0).then_some((q, v))
        }));
        let inv = 1.0 / mass[kk];
        for &(p, vp) in &row {
            for &(q, vq) in &row {
                if p >= q {
                    triplets.push(Triplet::new(p, q, vp * vq * inv));
                }
            }
        }
    }
    let singular = |detail: String| SolveError::Singular {
        system: inp.system.to_string(),
        detail,
    };
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(nf, nf, &triplets)
        .map_err(|e| singular(format!("assembly failed: {e:?}")))?;
    drop(triplets);
    let llt = a
        .sp_cholesky(Side::Lower)
        .map_err(|e| singular(format!("{e:?}")))?;
    // Right-hand sides: -Q[F, c] = -(ks L e_c + L M^-1 L e_c) on the free rows.
    let mut rhs = Mat::<f64>::zeros(nf, vertices.len());
    for (s, &c) in vertices.iter().enumerate() {
        let mut add = |i: usize, v: f64| {
            let p = free_index[i];
            if p != usize::MAX {
                rhs[(p, s)] -= v;
            }
        };
        // L e_c: column c of the symmetric L is row c.
        let lc = std::iter::once((c, l.diag[c])).chain(l.row(c));
        for (kk, lkc) in lc {
            if ks > 0.0 {
                add(kk, ks * lkc);
            }
            let a = lkc / mass[kk];
            add(kk, l.diag[kk] * a);
            for (i, lik) in l.row(kk) {
                add(i, lik * a);
            }
        }
    }
    llt.solve_in_place(rhs.as_mut());
    Ok(rhs)
}

/// Fills the socket rows of `unit` (`n x nv`) by the screened membrane solve from their rim.
fn fill_sockets(
    inp: &ShellInputs<'_>,
    socket: &[bool],
    unit: &mut [f64],
    nv: usize,
) -> Result<(), SolveError> {
    let n = inp.positions.len();
    let l = cotangent_laplacian(inp.positions, inp.triangles);
    let mass = lumped_mass(inp.positions, inp.triangles);
    let mut index = vec![usize::MAX; n];
    let mut ns = 0;
    for i in 0..n {
        if socket[i] {
            index[i] = ns;
            ns += 1;
        }
    }
    let mut triplets = Vec::new();
    let mut rhs = Mat::<f64>::zeros(ns, nv);
    for i in 0..n {
        let p = index[i];
        if p == usize::MAX {
            continue;
        }
        let decay = inp.settings.sockets.decay_of(i as u32).unwrap_or(1.0);
        triplets.push(Triplet::new(p, p, l.diag[i] + mass[i] / (decay * decay)));
        for (j, v) in l.row(i) {
            let q = index[j];
            if q == usize::MAX {
                // A rim neighbour with the face's solution (0 when frozen).
                for s in 0..nv {
                    rhs[(p, s)] -= v * unit[j * nv + s];
                }
            } else if p > q {
                triplets.push(Triplet::new(p, q, v));
            }
        }
    }
    let singular = |detail: String| SolveError::Singular {
        system: format!("{} (sockets)", inp.system),
        detail,
    };
    let a = SparseColMat::<usize, f64>::try_new_from_triplets(ns, ns, &triplets)
        .map_err(|e| singular(format!("assembly failed: {e:?}")))?;
    let llt = a
        .sp_cholesky(Side::Lower)
        .map_err(|e| singular(format!("{e:?}")))?;
    llt.solve_in_place(rhs.as_mut());
    for i in 0..n {
        let p = index[i];
        if p != usize::MAX {
            for s in 0..nv {
                unit[i * nv + s] = rhs[(p, s)];
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::{grid, tri_lattice};

    fn settings(ks: f64) -> ShellSettings {
        ShellSettings {
            stiffness: ks,
            ..ShellSettings::default()
        }
    }

    fn columns(
        mesh: &mimic_types::Mesh,
        frozen: &[bool],
        controls: &[usize],
        s: &ShellSettings,
    ) -> Vec<f64> {
        shell_columns(&ShellInputs {
            positions: &mesh.positions,
            triangles: &mesh.triangles,
            frozen,
            controls,
            settings: s,
            system: "test",
        })
        .unwrap()
    }

    /// Vertices of an `nx x ny` lattice within `rings` of its border.
    fn border(nx: usize, ny: usize, rings: usize) -> Vec<usize> {
        (0..nx * ny)
            .filter(|v| {
                let (i, j) = (v % nx, v / nx);
                i < rings || j < rings || i + rings >= nx || j + rings >= ny
            })
            .collect()
    }

    /// `u = B d` for one scalar field `d` over the controls.
    fn field(cols: &[f64], d: &[f64]) -> Vec<f64> {
        cols.chunks_exact(d.len())
            .map(|row| row.iter().zip(d).map(|(b, x)| b * x).sum())
            .collect()
    }

    #[test]
    fn controls_are_hard_and_frozen_rows_zero() {
        let mesh = grid(9, 9, 0.2, 0.3, 2);
        let n = mesh.vertex_count();
        let frozen: Vec<bool> = (0..n).map(|i| i < 9).collect();
        let controls = [30usize, 40, 58, 66, 40];
        let cols = columns(&mesh, &frozen, &controls, &settings(0.5));
        let k = controls.len();
        for (j, &c) in controls.iter().enumerate() {
            // Eliminated: exact by construction; vertex 40 carries two controls, each at 1/2.
            let share = if c == 40 { 0.5 } else { 1.0 };
            for (jj, &cc) in controls.iter().enumerate() {
                let expect = if cc == c { share } else { 0.0 };
                assert_eq!(cols[c * k + jj], expect, "control {j} column {jj}");
            }
        }
        assert!(cols[..9 * k].iter().all(|v| *v == 0.0));
        assert!(cols.iter().any(|v| v.abs() > 0.1 && v.abs() < 0.9));
    }

    #[test]
    fn linear_fields_are_reproduced_for_any_stiffness() {
        // Controls on the two outer rings with a linear field's values: the free interior's
        // optimality rows (Q u)_i only read rows of L at least one ring inside, where L f = 0
        // for linear f (cotangent linear precision), so u = f is the unique minimiser.
        let (nx, ny) = (12, 11);
        let mesh = tri_lattice(nx, ny, 0.12, 4);
        let controls = border(nx, ny, 2);
        let f = |v: usize| {
            let p = mesh.positions[v].as_dvec3();
            0.2 - 0.7 * p.x + 1.3 * p.y
        };
        let d: Vec<f64> = controls.iter().map(|&c| f(c)).collect();
        for ks in [0.0, 0.3, 10.0] {
            let u = field(&columns(&mesh, &[], &controls, &settings(ks)), &d);
            for (v, uv) in u.iter().enumerate() {
                // |f| <= 15, solve round-off ~1e-12 times the condition: 1e-7 relative.
                assert!(
                    (uv - f(v)).abs() < 1e-7 * 15.0,
                    "ks {ks} vertex {v}: {uv} vs {}",
                    f(v)
                );
            }
        }
    }

    #[test]
    fn pure_bending_reproduces_a_biharmonic_quadratic() {
        // On the exact equilateral lattice, M^-1 L f = -4 at interior vertices for f = x^2 + y^2
        // (6 spokes of length 1 at weight 1/sqrt(3), mass sqrt(3)/2), a constant that the next L
        // maps to 0: f is discretely biharmonic, not harmonic. With ks = 0 and two rings of
        // controls the solve returns f; with ks > 0 it must not (the membrane sees L f != 0).
        let (nx, ny) = (12, 12);
        let mesh = tri_lattice(nx, ny, 0.0, 0);
        let controls = border(nx, ny, 2);
        let f = |v: usize| {
            let p = mesh.positions[v].as_dvec3() - glam::DVec3::new(5.0, 4.0, 0.0);
            p.x * p.x + p.y * p.y + 0.5 * p.x
        };
        let d: Vec<f64> = controls.iter().map(|&c| f(c)).collect();
        let fmax = (0..nx * ny).map(f).fold(0f64, f64::max);
        let u = field(&columns(&mesh, &[], &controls, &settings(0.0)), &d);
        // f32 lattice positions (relative error 6e-8) perturb L and M: 1e-5 of max |f|.
        let worst = (0..nx * ny)
            .map(|v| (u[v] - f(v)).abs())
            .fold(0f64, f64::max);
        assert!(worst < 1e-5 * fmax, "bending: {worst} vs max {fmax}");
        let stiff = field(&columns(&mesh, &[], &controls, &settings(1.0)), &d);
        let off = (0..nx * ny)
            .map(|v| (stiff[v] - f(v)).abs())
            .fold(0f64, f64::max);
        assert!(
            off > 1e-2,
            "with a membrane term the quadratic is not the minimiser: {off}"
        );
    }

    #[test]
    fn sparse_assembly_matches_a_dense_reference() {
        // Dense Q = ks L + L M^-1 L from the same L and M, eliminated and solved by dense LU.
        let mesh = grid(8, 7, 0.3, 0.3, 6);
        let n = mesh.vertex_count();
        let frozen: Vec<bool> = (0..n).map(|i| i % 8 == 0).collect();
        let controls = [10usize, 20, 29, 37, 45, 52];
        let ks = 0.7;
        let cols = columns(&mesh, &frozen, &controls, &settings(ks));
        let l = cotangent_laplacian(&mesh.positions, &mesh.triangles);
        let m = lumped_mass(&mesh.positions, &mesh.triangles);
        let mut ld = Mat::<f64>::zeros(n, n);
        for i in 0..n {
            ld[(i, i)] = l.diag[i];
            for (j, v) in l.row(i) {
                ld[(i, j)] = v;
            }
        }
        let minv = Mat::<f64>::from_fn(n, n, |i, j| if i == j { 1.0 / m[i] } else { 0.0 });
        let q = &ld * &minv * &ld + &ld * ks;
        let free: Vec<usize> = (0..n)
            .filter(|i| !frozen[*i] && !controls.contains(i))
            .collect();
        let qff = Mat::<f64>::from_fn(free.len(), free.len(), |a, b| q[(free[a], free[b])]);
        let rhs = Mat::<f64>::from_fn(free.len(), controls.len(), |a, c| {
            -q[(free[a], controls[c])]
        });
        let x = qff.partial_piv_lu().solve(&rhs);
        let scale = cols.iter().fold(0f64, |a, v| a.max(v.abs()));
        for (a, &i) in free.iter().enumerate() {
            for c in 0..controls.len() {
                let s = cols[i * controls.len() + c];
                // Two backward-stable solves of one system (condition ~1e5 here): 1e-9 max |B|.
                assert!(
                    (s - x[(a, c)]).abs() <= 1e-9 * scale,
                    "{i} {c}: {s} vs {}",
                    x[(a, c)]
                );
            }
        }
    }

    #[test]
    fn translation_is_exact_and_floating_parts_stay_still() {
        // Constants have zero energy: equal control displacements move every vertex equally
        // (rows sum to 1), and a piece with no control and no frozen vertex is held at 0.
        let mut mesh = grid(7, 7, 0.2, 0.2, 1);
        let base = mesh.positions.len() as u32;
        mesh.positions.extend([
            Vec3::new(5.0, 0.0, 0.0),
            Vec3::new(6.0, 0.0, 0.0),
            Vec3::new(5.0, 1.0, 0.0),
        ]);
        mesh.triangles.push([base, base + 1, base + 2]);
        let controls = [8usize, 12, 36, 40, 24];
        let cols = columns(&mesh, &[], &controls, &settings(0.2));
        for (i, row) in cols.chunks_exact(controls.len()).enumerate() {
            let sum: f64 = row.iter().sum();
            if i < base as usize {
                assert!((sum - 1.0).abs() < 1e-9, "row {i}: {sum}");
            } else {
                assert!(row.iter().all(|v| *v == 0.0));
            }
        }
    }

    #[test]
    fn decayed_sockets_follow_the_screened_profile() {
        // A strip of right triangles, x in [0, 1]; the socket is x > 0.5. Controls on the left
        // column all move by 1, so the face (x <= 0.5) moves by exactly 1 (zero energy) and the
        // socket solves (L + M / l^2) u = 0 from the rim at x = 0.5 with a free end at x = 1. On
        // this grid the diagonals have weight cot 90 = 0 and L is the 3-point stencil along x, so
        // the continuous solution cosh((1 - x) / l) / cosh(0.5 / l) is met to O((h / l)^2)
        // relative (the stencil's truncation and the lumped half mass at the free end): 2 (h/l)^2.
        let (nx, ny) = (61, 3);
        let mesh = grid(nx, ny, 0.0, 0.0, 0);
        let h = 1.0 / (nx - 1) as f64;
        let l = 0.15;
        let first = (nx / 2 + 1) as u32;
        let mut s = settings(0.0);
        s.socket_mode = SocketMode::Decay;
        let rows: Vec<mimic_types::Socket> = (0..ny as u32)
            .map(|j| mimic_types::Socket {
                vertices: [j * nx as u32 + first, j * nx as u32 + nx as u32 - 1],
                decay: l,
            })
            .collect();
        s.sockets = mimic_types::Sockets::try_from(rows).unwrap();
        let controls: Vec<usize> = (0..ny).map(|j| j * nx).collect();
        let u = field(&columns(&mesh, &[], &controls, &s), &vec![1.0; ny]);
        for v in 0..nx * ny {
            let x = f64::from(mesh.positions[v].x);
            let expect = if x <= 0.5 + 1e-6 {
                1.0
            } else {
                ((1.0 - x) / l).cosh() / (0.5 / l).cosh()
            };
            assert!(
                (u[v] - expect).abs() <= 2.0 * (h / l).powi(2) * expect,
                "x {x}: {} vs {expect}",
                u[v]
            );
        }
        // Free sockets: the same strip moves rigidly by 1 everywhere; frozen ones not at all.
        for (mode, inside) in [(SocketMode::Free, 1.0), (SocketMode::Frozen, 0.0)] {
            s.socket_mode = mode;
            let u = field(&columns(&mesh, &[], &controls, &s), &vec![1.0; ny]);
            assert!((u[nx - 1] - inside).abs() < 1e-9, "{mode:?}: {}", u[nx - 1]);
        }
    }
}
