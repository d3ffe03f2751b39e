//! Numeric core of mimic: builds the n x m deformation basis `B` once per rig, applies it per frame.
//!
//! Entry points: [`build_basis`] (RBF or Laplacian, optionally per face region, folded into one
//! [`Basis`]), [`Basis::apply`] (`u = B d`, allocation-free), [`vertex_normals`],
//! [`kabsch::fit_similarity`] (head pose) and [`morph_fit::MorphFit`] (blendshape weights).
//! Setup allocates and may fail with [`SolveError`]; the per-frame steps take `&self`, inputs and
//! `&mut` outputs and allocate nothing. No I/O, no tokio, no wgpu.

pub mod basis;
pub mod error;
pub mod kabsch;
pub mod laplacian;
pub mod morph_fit;
pub mod normals;
pub mod rbf;
pub mod regions;
#[cfg(test)]
mod test_meshes;

pub use basis::Basis;
pub use error::SolveError;
pub use normals::vertex_normals;

use mimic_types::{Rig, SolverKind, SolverSettings};

/// Builds the deformation basis of `rig` with `settings` (the rig's own `rig.solver` is not read).
///
/// Without regions, one solve over all controls. With regions, one solve per region from that
/// region's controls only, blended by the rig's [`mimic_types::RegionBands`]; a region without
/// controls contributes nothing (its vertices stay still). Rows of frozen vertices are zero.
/// RBF reproduces each control displacement exactly when regions are off (with regions, a control
/// inside a blend band is only weighted by its own region's share).
pub fn build_basis(rig: &Rig, settings: &SolverSettings) -> Result<Basis, SolveError> {
    rig.validate()?;
    let m = rig.controls.len();
    if m == 0 {
        return Err(SolveError::NoControls);
    }
    if settings.kind == SolverKind::Rbf {
        rbf::check_kernel(settings.kernel, settings.affine)?;
    }
    let positions = &rig.mesh.positions;
    let n = positions.len();
    let groups: Vec<(Option<mimic_types::Region>, Vec<usize>)> = if settings.regions {
        let by_region = regions::controls_by_region(&rig.controls);
        mimic_types::Region::ALL
            .into_iter()
            .zip(by_region)
            .map(|(r, c)| (Some(r), c))
            .collect()
    } else {
        vec![(None, (0..m).collect())]
    };
    let weights = regions::vertex_region_weights(&rig.regions, positions);
    let lap_rows = (settings.kind == SolverKind::Laplacian)
        .then(|| laplacian::laplacian_rows(positions, &rig.mesh.triangles, settings.weights));
    let mut b = vec![0f64; n * m];
    for (region, subset) in &groups {
        if subset.is_empty() {
            continue;
        }
        let system = match region {
            Some(r) => format!("{:?} solve of region {r}", settings.kind),
            None => format!("{:?} solve", settings.kind),
        };
        let cols = match &lap_rows {
            None => {
                let centres: Vec<_> = subset
                    .iter()
                    .map(|&j| positions[rig.controls[j].vertex as usize])
                    .collect();
                let fdps: Vec<_> = subset.iter().map(|&j| rig.controls[j].fdp).collect();
                rbf::rbf_columns(
                    positions,
                    &rig.frozen,
                    &centres,
                    &fdps,
                    settings.kernel,
                    settings.affine,
                    &system,
                )?
            }
            Some(rows) => {
                let vertices: Vec<usize> = subset
                    .iter()
                    .map(|&j| rig.controls[j].vertex as usize)
                    .collect();
                laplacian::laplacian_columns(
                    rows,
                    &rig.frozen,
                    &vertices,
                    settings.constraint_weight,
                    &system,
                )?
            }
        };
        regions::blend_into(&mut b, m, &cols, subset, *region, &weights);
    }
    for (row, &frozen) in b.chunks_exact_mut(m).zip(&rig.frozen) {
        if frozen {
            row.fill(0.0);
        }
    }
    let data = b.into_iter().map(|v| v as f32).collect();
    Basis::from_row_major(n, m, data).ok_or(SolveError::NoControls)
}
