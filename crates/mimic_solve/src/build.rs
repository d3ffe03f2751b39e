//! [`build_basis`]: the basis `B` of a rig, from RBF, Laplacian or thin-shell solves per region part.

use crate::{Basis, SolveError, border, geodesic, laplacian, rbf, regions, shell};
use mimic_types::{RbfDistance, Rig, SolverKind, SolverSettings};

/// [`SolverSettings::shell_blend`] drops the shell's entries below this share of their row's
/// largest: the shell reaches every control from everywhere, mostly by tiny weights that would
/// cost the per-frame deform its zero blocks (ICT, bottom blend: 55 % of the block-columns kept
/// instead of 34 %; with the cutoff 38 %), while the ratios of docs/quality.md move by at most
/// 0.001.
const SHELL_BLEND_CUTOFF: f32 = 0.01;

/// The Laplacian and the thin shell blend their regions over this many times the rig's `regions.band`.
const LAPLACIAN_BAND_SCALE: f32 = 2.0;

/// Builds the deformation basis of `rig` with `settings` (the rig's own `rig.solver` is not read).
///
/// Without regions, one solve over all controls. With regions, `B = sum_r diag(alpha_r) B_r`
/// blended by the rig's [`mimic_types::RegionBands`], where `B_r` has non-zero columns only for
/// region r's controls: for RBF, `B_r` is an RBF through region r's controls alone; for the
/// Laplacian and the thin shell ([`crate::shell`]), `B_r` is region r's columns of the one solve
/// constrained by every control (one
/// factorisation; measured better than per-region solves on real expressions, see
/// docs/quality.md, but it no longer reproduces a uniform translation). A region without controls
/// contributes nothing (its vertices stay still); the Laplacian and the shell blend over
/// twice the rig's band (`LAPLACIAN_BAND_SCALE`). Rows of frozen vertices are zero; the RBF's
/// rows fade to zero toward them ([`crate::border`], over twice its kernel radius, no control faded).
/// RBF reproduces each control displacement exactly when regions are off (with regions, a control
/// inside a blend band is only weighted by its own region's share). With
/// [`SolverSettings::top_split`] (RBF only) the top region is two solves (controls above / below
/// the split height), blended within the top region's weight (see [`regions::Part`]), each with
/// its own kernel if the split names one.
///
/// A rig with rigid parts ([`mimic_types::RigParts`]: jaw, eyeballs) gets four more columns per
/// part after the controls' ([`crate::rigid`]).
pub fn build_basis(rig: &Rig, settings: &SolverSettings) -> Result<Basis, SolveError> {
    let controls = control_basis(rig, settings)?;
    crate::rigid::with_parts(controls, rig)
}

/// The controls' columns of [`build_basis`] (`n x m`, no rigid part).
fn control_basis(rig: &Rig, settings: &SolverSettings) -> Result<Basis, SolveError> {
    rig.validate()?;
    let m = rig.controls.len();
    if m == 0 {
        return Err(SolveError::NoControls);
    }
    if let Err(e) = settings.validate_shell_blend() {
        return Err(SolveError::InvalidSetting(e.to_string()));
    }
    if settings.kind == SolverKind::Rbf {
        rbf::check_kernel(settings.kernel, settings.affine)?;
        let ridge = settings.rbf_ridge;
        if !SolverSettings::valid_rbf_ridge(ridge) {
            return Err(SolveError::InvalidSetting(format!(
                "RBF ridge {ridge}: must be finite, >= 0 and <= 1"
            )));
        }
        if let Some(split) = settings.top_split {
            if !(split.at.is_finite() && split.band.is_finite() && split.band >= 0.0) {
                return Err(SolveError::InvalidSetting(format!(
                    "top split at {} with band {}: both must be finite, the band >= 0",
                    split.at, split.band
                )));
            }
            for k in [split.upper_kernel, split.lower_kernel]
                .into_iter()
                .flatten()
            {
                rbf::check_kernel(k, settings.affine)?;
            }
        }
    }
    let positions = &rig.mesh.positions;
    let n = positions.len();
    // The top split is an RBF setting (its lower radius is a kernel radius); measured worse for
    // the Laplacian (median 0.681 vs 0.653 on the ICT expressions), which keeps three regions.
    let split = settings
        .top_split
        .filter(|_| settings.kind == SolverKind::Rbf);
    let use_regions = if settings.kind == SolverKind::Shell {
        settings.shell.regions
    } else {
        settings.regions
    };
    let parts = regions::Part::all(use_regions, split);
    let groups: Vec<(regions::Part, Vec<usize>)> = parts
        .into_iter()
        .map(|p| {
            let subset = (0..m)
                .filter(|&j| {
                    let c = &rig.controls[j];
                    p.owns(c, positions[c.vertex as usize].y)
                })
                .collect();
            (p, subset)
        })
        .collect();
    // The Laplacian's region r keeps region r's columns of one global solve, whose fields reach
    // well past a band: cut over the rig's band they shear into a seam across the cheeks on a
    // jaw opening; over twice the band they bend no more than the regions (docs/quality.md).
    let mut bands = rig.regions;
    if matches!(settings.kind, SolverKind::Laplacian | SolverKind::Shell) {
        bands.band *= LAPLACIAN_BAND_SCALE;
    }
    let weights = regions::vertex_region_weights(&bands, positions);
    let lap_rows = (settings.kind == SolverKind::Laplacian)
        .then(|| laplacian::laplacian_rows(positions, &rig.mesh.triangles, settings.weights));
    // The RBF's edge graph: its geodesic distances and its fade toward the frozen vertices.
    let graph = (settings.kind == SolverKind::Rbf)
        .then(|| geodesic::EdgeGraph::new(positions, &rig.mesh.triangles));
    // Geodesic RBF: one Dijkstra per control, shared by every region.
    let geodesic = graph
        .as_ref()
        .filter(|_| settings.distance == RbfDistance::Geodesic)
        .map(|graph| {
            rig.controls
                .iter()
                .map(|c| graph.distances_from(c.vertex as usize))
                .collect::<Vec<_>>()
        });
    // Laplacian: one solve constrained by every control; with regions, region r keeps its own
    // controls' columns of it (measured better than per-region solves, docs/quality.md).
    // The thin shell likewise: one solve with every control, columns kept per region.
    let all: Vec<usize> = rig.controls.iter().map(|c| c.vertex as usize).collect();
    let system = format!("{:?} solve", settings.kind);
    let lap_all = match &lap_rows {
        Some(rows) => Some(laplacian::laplacian_columns(
            rows,
            &rig.frozen,
            &all,
            settings.constraint_weight,
            &system,
        )?),
        None if settings.kind == SolverKind::Shell => {
            Some(shell::shell_columns(&shell::ShellInputs {
                positions,
                triangles: &rig.mesh.triangles,
                frozen: &rig.frozen,
                controls: &all,
                settings: &settings.shell,
                system: &system,
            })?)
        }
        None => None,
    };
    let mut b = vec![0f64; n * m];
    for (part, subset) in &groups {
        if subset.is_empty() {
            continue;
        }
        let system = match part {
            regions::Part::All => format!("{:?} solve", settings.kind),
            regions::Part::Region(r) => format!("{:?} solve of region {r}", settings.kind),
            regions::Part::TopHalf { upper, .. } => format!(
                "{:?} solve of the {} part of region top",
                settings.kind,
                if *upper { "upper" } else { "lower" }
            ),
        };
        let kernel = match part {
            regions::Part::TopHalf { split, upper } => {
                let own = if *upper {
                    split.upper_kernel
                } else {
                    split.lower_kernel
                };
                own.unwrap_or(settings.kernel)
            }
            _ => settings.kernel,
        };
        let cols = match &lap_all {
            None => {
                let centres: Vec<_> = subset
                    .iter()
                    .map(|&j| positions[rig.controls[j].vertex as usize])
                    .collect();
                let fdps: Vec<_> = subset.iter().map(|&j| rig.controls[j].fdp).collect();
                let table: Vec<Vec<f64>>;
                let vertices: Vec<usize>;
                let metric = match &geodesic {
                    None => rbf::Metric::Euclidean,
                    Some(all) => {
                        table = subset.iter().map(|&j| all[j].clone()).collect();
                        vertices = subset
                            .iter()
                            .map(|&j| rig.controls[j].vertex as usize)
                            .collect();
                        rbf::Metric::Table {
                            to_vertex: &table,
                            centre_vertices: &vertices,
                        }
                    }
                };
                rbf::rbf_columns(&rbf::RbfInputs {
                    positions,
                    frozen: &rig.frozen,
                    centres: &centres,
                    fdps: &fdps,
                    kernel,
                    affine: settings.affine,
                    metric,
                    ridge: settings.rbf_ridge,
                    system: &system,
                })?
            }
            Some(all) => {
                let k = subset.len();
                (0..n * k)
                    .map(|x| all[(x / k) * m + subset[x % k]])
                    .collect()
            }
        };
        regions::blend_into(&mut b, m, &cols, subset, *part, positions, &weights);
    }
    // The thin shell blended into the RBF's rows by region (before the fade below, which the
    // shell's part needs too: its field meets the frozen neck at a steeper slope than the fade).
    if settings.kind == SolverKind::Rbf && settings.shell_blend.iter().any(|&s| s > 0.0) {
        blend_shell(rig, settings, &weights, &mut b)?;
    }
    // The RBF knows nothing of the frozen vertices: fade its rows to zero toward them
    // (`border`), so the face meets a frozen neck without a step; controls keep their rows.
    if let Some(fade) = graph
        .as_ref()
        .and_then(|graph| border::BorderFade::new(graph, &rig.frozen, &all, settings.kernel))
    {
        fade.apply(&mut b, m);
    }
    for (row, &frozen) in b.chunks_exact_mut(m).zip(&rig.frozen) {
        if frozen {
            row.fill(0.0);
        }
    }
    let data = b.into_iter().map(|v| v as f32).collect();
    Basis::from_row_major(n, m, data).ok_or(SolveError::NoControls)
}

/// Blends the thin-shell basis into `b` (row-major, n x m) by [`SolverSettings::shell_blend`]:
/// row `i` becomes `(1 - s_i) b_i + s_i shell_i` with `s_i = sum_r shell_blend[r] alpha_r(y_i)`,
/// `alpha_r = weights[i][r]` the RBF's region weights (over the rig's own band), and `shell_i`
/// without its entries below [`SHELL_BLEND_CUTOFF`] of its largest.
/// Called before the RBF's fade toward the frozen vertices, which then fades both parts.
fn blend_shell(
    rig: &Rig,
    settings: &SolverSettings,
    weights: &[[f32; 3]],
    b: &mut [f64],
) -> Result<(), SolveError> {
    let shell = control_basis(
        rig,
        &SolverSettings {
            kind: SolverKind::Shell,
            shell_blend: [0.0; 3],
            ..*settings
        },
    )?;
    let m = shell.control_count();
    for (i, (row, w)) in b.chunks_exact_mut(m).zip(weights).enumerate() {
        let s: f64 = (0..3)
            .map(|r| settings.shell_blend[r] * f64::from(w[r]))
            .sum();
        if s > 0.0 {
            let shell_row = shell.row(i);
            let cutoff = SHELL_BLEND_CUTOFF * shell_row.iter().fold(0f32, |a, v| a.max(v.abs()));
            for (x, &y) in row.iter_mut().zip(shell_row) {
                let y = if y.abs() < cutoff { 0.0 } else { f64::from(y) };
                *x = (1.0 - s) * *x + s * y;
            }
        }
    }
    Ok(())
}
