//! Tests of [`crate::build_basis`] on generated meshes and rigs.

use crate::test_meshes::{control_lattice, grid, random_d, rig};
use crate::{Basis, SolveError, build_basis};
use glam::Vec3;
use mimic_types::{
    LaplacianWeights, RbfDistance, RbfKernel, Rig, RigError, SolverKind, SolverSettings,
};

fn settings(kind: SolverKind, regions: bool) -> SolverSettings {
    SolverSettings {
        kind,
        kernel: RbfKernel::Exponential { radius: 0.3 },
        affine: false,
        distance: mimic_types::RbfDistance::Euclidean,
        weights: LaplacianWeights::MeanValue,
        constraint_weight: 10.0,
        regions,
        top_split: None,
        shell: mimic_types::ShellSettings {
            regions,
            ..mimic_types::ShellSettings::default()
        },
        rbf_ridge: 0.0,
        shell_blend: [0.0; 3],
    }
}

fn test_rig(band: f32) -> Rig {
    rig(
        grid(20, 20, 0.3, 0.3, 5),
        &control_lattice(20, 20, 6, 6),
        band,
    )
}

fn apply(b: &Basis, d: &[Vec3]) -> Vec<Vec3> {
    let mut out = vec![Vec3::NAN; b.vertex_count()];
    b.apply(d, &mut out);
    out
}

#[test]
fn rbf_hits_every_control_exactly() {
    let r = test_rig(0.1);
    let b = build_basis(&r, &settings(SolverKind::Rbf, false)).unwrap();
    let mut seed = 1;
    let d = random_d(&mut seed, r.controls.len(), 0.05);
    let u = apply(&b, &d);
    let dmax = d.iter().fold(0f32, |a, v| a.max(v.abs().max_element()));
    for (c, dj) in r.controls.iter().zip(&d) {
        // f32 basis and f32 sums: 1e-4 * max|d| as the brief states.
        assert!(
            (u[c.vertex as usize] - *dj).abs().max_element() <= 1e-4 * dmax,
            "{}",
            c.fdp
        );
    }
}

#[test]
fn zero_and_linearity_and_frozen_rows_for_both_solvers() {
    let mut r = test_rig(0.1);
    for (i, f) in r.frozen.iter_mut().enumerate() {
        *f = i < 20; // bottom row of the grid (no controls there)
    }
    let mut seed = 2;
    for kind in [SolverKind::Rbf, SolverKind::Laplacian, SolverKind::Shell] {
        for regions in [false, true] {
            let b = build_basis(&r, &settings(kind, regions)).unwrap();
            let m = r.controls.len();
            assert!(
                apply(&b, &vec![Vec3::ZERO; m])
                    .iter()
                    .all(|v| *v == Vec3::ZERO)
            );
            let d1 = random_d(&mut seed, m, 0.05);
            let d2 = random_d(&mut seed, m, 0.05);
            let (a, c) = (0.7f32, -1.3f32);
            let mix: Vec<Vec3> = d1.iter().zip(&d2).map(|(x, y)| *x * a + *y * c).collect();
            let (u1, u2, um) = (apply(&b, &d1), apply(&b, &d2), apply(&b, &mix));
            for i in 0..b.vertex_count() {
                // f32 sums of m terms |B_ij d_j| <= 0.05 * max|B|: 1e-5 covers m eps (|B| <= ~3).
                assert!(
                    (um[i] - (u1[i] * a + u2[i] * c)).length() < 1e-5,
                    "{kind:?} {regions}"
                );
                if r.frozen[i] {
                    assert!(b.row(i).iter().all(|w| *w == 0.0));
                }
            }
        }
    }
}

#[test]
fn laplacian_translation_moves_every_vertex() {
    // L 1 = 0: with nothing frozen the exact minimiser for a uniform translation t is u = t.
    let r = test_rig(0.1);
    let b = build_basis(&r, &settings(SolverKind::Laplacian, false)).unwrap();
    let t = Vec3::new(0.01, -0.02, 0.03);
    for u in apply(&b, &vec![t; r.controls.len()]) {
        // Solver residual ~1e-12 plus f32 rounding of B and 36-term sums: 1e-5 |t|.
        assert!((u - t).length() <= 1e-5 * t.length(), "{u}");
    }
}

/// Region `region`'s own field, computed independently of the region code: RBF through that
/// region's controls alone (a rig holding only them); Laplacian: the all-controls solve
/// (regions off) driven by that region's displacements only.
fn region_field(r: &Rig, kind: SolverKind, region: mimic_types::Region, d: &[Vec3]) -> Vec<Vec3> {
    let keep: Vec<usize> = (0..r.controls.len())
        .filter(|&j| r.controls[j].region == region)
        .collect();
    match kind {
        SolverKind::Rbf => {
            let mut sub = r.clone();
            sub.controls = keep.iter().map(|&j| r.controls[j].clone()).collect();
            let dr: Vec<Vec3> = keep.iter().map(|&j| d[j]).collect();
            apply(&build_basis(&sub, &settings(kind, false)).unwrap(), &dr)
        }
        SolverKind::Laplacian | SolverKind::Shell => {
            let dr: Vec<Vec3> = (0..d.len())
                .map(|j| if keep.contains(&j) { d[j] } else { Vec3::ZERO })
                .collect();
            apply(&build_basis(r, &settings(kind, false)).unwrap(), &dr)
        }
    }
}

#[test]
fn regions_fold_into_blended_independent_solves() {
    // Independent truth: each region's own field (see region_field), blended by
    // RegionBands::weights (the Laplacian's over twice the rig's band, build.rs); the folded
    // basis must give the same field.
    let r = test_rig(0.15);
    let mut seed = 3;
    let d = random_d(&mut seed, r.controls.len(), 0.05);
    for kind in [SolverKind::Rbf, SolverKind::Laplacian, SolverKind::Shell] {
        let folded = apply(&build_basis(&r, &settings(kind, true)).unwrap(), &d);
        let mut blended = vec![Vec3::ZERO; r.mesh.vertex_count()];
        let mut bands = r.regions;
        if kind != SolverKind::Rbf {
            bands.band *= 2.0;
        }
        for region in mimic_types::Region::ALL {
            let u = region_field(&r, kind, region, &d);
            for (i, (acc, ui)) in blended.iter_mut().zip(&u).enumerate() {
                *acc += *ui * bands.weights(r.mesh.positions[i].y)[region.index()];
            }
        }
        for (a, b) in folded.iter().zip(&blended) {
            // Same arithmetic up to f32 rounding order: 1e-6 on displacements ~0.05.
            assert!((*a - *b).length() < 1e-6, "{kind:?}");
        }
    }
}

#[test]
fn top_split_folds_into_two_top_solves() {
    // Independent truth: RBFs through the top controls above / below the split alone (rigs
    // holding only them; the lower one with its own radius), weighted by the top region's
    // weight times the split's linear ramp, plus the middle and bottom regions' own fields.
    let r = test_rig(0.15);
    let split = mimic_types::TopSplit {
        at: 0.9,
        band: 0.1,
        upper_kernel: None,
        lower_kernel: Some(RbfKernel::Exponential { radius: 0.2 }),
    };
    let s = SolverSettings {
        top_split: Some(split),
        ..settings(SolverKind::Rbf, true)
    };
    let mut seed = 5;
    let d = random_d(&mut seed, r.controls.len(), 0.05);
    let folded = apply(&build_basis(&r, &s).unwrap(), &d);
    let half = |upper: bool, radius: f64| {
        let keep: Vec<usize> = (0..r.controls.len())
            .filter(|&j| {
                let c = &r.controls[j];
                c.region == mimic_types::Region::Top
                    && (r.mesh.positions[c.vertex as usize].y >= 0.9) == upper
            })
            .collect();
        assert!(!keep.is_empty());
        let mut sub = r.clone();
        sub.controls = keep.iter().map(|&j| r.controls[j].clone()).collect();
        let dr: Vec<Vec3> = keep.iter().map(|&j| d[j]).collect();
        let flat = SolverSettings {
            kernel: RbfKernel::Exponential { radius },
            ..settings(SolverKind::Rbf, false)
        };
        apply(&build_basis(&sub, &flat).unwrap(), &dr)
    };
    let (upper, lower) = (half(true, 0.3), half(false, 0.2));
    let lower_same_radius = half(false, 0.3);
    let middle = region_field(&r, SolverKind::Rbf, mimic_types::Region::Middle, &d);
    let bottom = region_field(&r, SolverKind::Rbf, mimic_types::Region::Bottom, &d);
    let mut bites = false;
    for (i, p) in r.mesh.positions.iter().enumerate() {
        let w = r.regions.weights(p.y);
        let share = ((p.y - 0.9) / 0.1 + 0.5).clamp(0.0, 1.0);
        let top = w[0] * share * upper[i] + w[0] * (1.0 - share) * lower[i];
        let want = top + w[1] * middle[i] + w[2] * bottom[i];
        // Same arithmetic up to f32 rounding order: 1e-6 on displacements ~0.05.
        assert!((folded[i] - want).length() < 1e-6, "vertex {i}");
        bites |= (w[0] * (1.0 - share) * (lower[i] - lower_same_radius[i])).length() > 1e-3;
    }
    assert!(
        bites,
        "the lower radius changes nothing: the test would not catch ignoring it"
    );
}

#[test]
fn region_blend_has_no_seam() {
    // Across an edge (i, j): |u_i - u_j| <= max_r |u_r(i) - u_r(j)| + sum_r |alpha_r(i) - alpha_r(j)| |u_r(j)|
    // and |alpha(i) - alpha(j)| <= |y_i - y_j| / band. So the jump across any edge is bounded by
    // the regions' own variation plus (2 |dy| / band) max |u_r|: no seam larger than the band allows.
    // With band 0 the same bound fails somewhere (a hard seam), which shows the test bites.
    let mut seed = 4;
    let base = test_rig(0.0);
    let d = random_d(&mut seed, base.controls.len(), 0.05);
    for kind in [SolverKind::Rbf, SolverKind::Laplacian, SolverKind::Shell] {
        let mut per_region = Vec::new();
        for region in mimic_types::Region::ALL {
            per_region.push(region_field(&base, kind, region, &d));
        }
        let umax = per_region
            .iter()
            .flatten()
            .fold(0f32, |a, v| a.max(v.length()));
        for (band, expect_ok) in [(0.2f32, true), (0.0, false)] {
            let mut r = base.clone();
            r.regions.band = band;
            let u = apply(&build_basis(&r, &settings(kind, true)).unwrap(), &d);
            let mut ok = true;
            for (a, b) in r.mesh.edges() {
                let (a, b) = (a as usize, b as usize);
                let own = per_region
                    .iter()
                    .fold(0f32, |m, ur| m.max((ur[a] - ur[b]).length()));
                let dy = (r.mesh.positions[a].y - r.mesh.positions[b].y).abs();
                let bound =
                    own + if band > 0.0 {
                        2.0 * dy / band * umax
                    } else {
                        0.0
                    } + 1e-6;
                ok &= (u[a] - u[b]).length() <= bound;
            }
            assert_eq!(ok, expect_ok, "{kind:?} band {band}");
        }
    }
}

#[test]
fn geodesic_rbf_hits_controls_and_does_not_leak_across_a_slit() {
    // A 20 x 20 grid cut between rows 9 and 10 for columns 0..15 (like parted lips). Control
    // A below the cut moves, control B just above it stays. Along the skin the rows above the
    // cut are far from A (around the end of the cut), in space they are 1/19 away.
    let mut mesh = grid(20, 20, 0.0, 0.0, 0);
    mesh.triangles.retain(|t| {
        let rows: Vec<u32> = t.iter().map(|v| v / 20).collect();
        let cols: Vec<u32> = t.iter().map(|v| v % 20).collect();
        !(rows.contains(&9) && rows.contains(&10) && cols.iter().all(|c| *c < 15))
    });
    let (a, b) = (9 * 20 + 5, 10 * 20 + 5);
    let mut r = rig(
        mesh,
        &[a, b, 2 * 20 + 2, 17 * 20 + 17, 2 * 20 + 17, 17 * 20 + 2],
        0.1,
    );
    r.controls
        .iter_mut()
        .for_each(|c| c.region = mimic_types::Region::Middle);
    let mut d = vec![Vec3::ZERO; 6];
    d[0] = Vec3::new(0.0, 0.0, 0.1);
    let mut moved = Vec::new();
    for distance in [RbfDistance::Euclidean, RbfDistance::Geodesic] {
        let s = SolverSettings {
            distance,
            ..settings(SolverKind::Rbf, false)
        };
        let u = apply(&build_basis(&r, &s).unwrap(), &d);
        for (c, dj) in r.controls.iter().zip(&d) {
            // Interpolation is exact for either metric: f32 round-off, 1e-4 * max|d|.
            assert!(
                (u[c.vertex as usize] - *dj).length() <= 1e-5,
                "{distance:?}"
            );
        }
        moved.push(u[11 * 20 + 4].length());
    }
    // Vertex (4, 11), above the cut: Euclidean lets A's motion through, geodesic much less.
    assert!(
        moved[1] < 0.5 * moved[0],
        "euclidean {} geodesic {}",
        moved[0],
        moved[1]
    );
}

#[test]
fn bad_rigs_are_errors() {
    let mut r = test_rig(0.1);
    r.frozen[r.controls[0].vertex as usize] = true;
    assert!(matches!(
        build_basis(&r, &settings(SolverKind::Rbf, false)),
        Err(SolveError::InvalidRig(RigError::FrozenControl { .. }))
    ));
    let mut r = test_rig(0.1);
    r.controls.clear();
    assert!(matches!(
        build_basis(&r, &settings(SolverKind::Laplacian, true)),
        Err(SolveError::NoControls)
    ));
    let r = test_rig(0.1);
    let mut s = settings(SolverKind::Rbf, true);
    s.kernel = RbfKernel::ThinPlate;
    assert!(matches!(
        build_basis(&r, &s),
        Err(SolveError::InvalidSetting(_))
    ));
}

#[test]
fn shell_blend_mixes_the_two_bases_by_region_weight() {
    let r = test_rig(0.1);
    let m = r.controls.len();
    let rbf = build_basis(&r, &settings(SolverKind::Rbf, true)).unwrap();
    // The blend's shell is the rig's own (`settings.shell`, here with its region cut).
    let shell = build_basis(
        &r,
        &SolverSettings {
            kind: SolverKind::Shell,
            ..settings(SolverKind::Rbf, true)
        },
    )
    .unwrap();
    let shares = [0.0, 0.25, 0.75];
    let blended = build_basis(
        &r,
        &SolverSettings {
            shell_blend: shares,
            ..settings(SolverKind::Rbf, true)
        },
    )
    .unwrap();
    // Off, the setting builds no shell: the RBF basis bit for bit.
    let off = build_basis(
        &r,
        &SolverSettings {
            shell_blend: [0.0; 3],
            ..settings(SolverKind::Rbf, true)
        },
    )
    .unwrap();
    assert_eq!(off.as_slice(), rbf.as_slice());
    let (mut in_top, mut blended_rows) = (0, 0);
    for (i, p) in r.mesh.positions.iter().enumerate() {
        let w = r.regions.weights(p.y);
        let s: f64 = (0..3).map(|k| shares[k] * f64::from(w[k])).sum();
        let srow = shell.row(i);
        let big = srow.iter().fold(0f32, |a, v| a.max(v.abs()));
        let rrow = rbf.row(i);
        for (j, ((&sv, &rv), &got)) in srow.iter().zip(rrow).zip(blended.row(i)).enumerate() {
            // The shell's entry, unless below the cutoff of its row's largest (only where blended).
            let y = if s > 0.0 && sv.abs() < 0.01 * big {
                0.0
            } else {
                f64::from(sv)
            };
            let want = (1.0 - s) * f64::from(rv) + s * y;
            // Both built in f64 and rounded to f32 once: a few ulps of the larger input.
            let scale = f64::from(rv.abs().max(sv.abs())).max(1e-6);
            let got = f64::from(got);
            assert!(
                (got - want).abs() <= 4.0 * f64::from(f32::EPSILON) * scale,
                "row {i} column {j}: {got} vs {want}"
            );
        }
        if s == 0.0 {
            in_top += 1;
            assert_eq!(blended.row(i), rbf.row(i), "row {i}: top share 0");
        } else {
            blended_rows += 1;
        }
    }
    assert!(in_top > 0 && blended_rows > 0, "{in_top} / {blended_rows}");
    // Both bases reproduce a control where it is alone in its region (far from the bands), so the
    // blend does too.
    let mut seed = 7;
    let d = random_d(&mut seed, m, 0.05);
    let (ur, us, ub) = (apply(&rbf, &d), apply(&shell, &d), apply(&blended, &d));
    let dmax = d.iter().fold(0f32, |a, v| a.max(v.abs().max_element()));
    let mut checked = 0;
    for (c, dj) in r.controls.iter().zip(&d) {
        let v = c.vertex as usize;
        if (ur[v] - *dj).abs().max_element() <= 1e-4 * dmax
            && (us[v] - *dj).abs().max_element() <= 1e-4 * dmax
        {
            checked += 1;
            assert!(
                (ub[v] - *dj).abs().max_element() <= 2e-4 * dmax,
                "{}: {} vs {}",
                c.fdp,
                ub[v],
                dj
            );
        }
    }
    assert!(checked >= m / 2, "{checked} of {m} controls checked");
}

#[test]
fn shell_blend_out_of_range_is_an_error() {
    let r = test_rig(0.1);
    let e = build_basis(
        &r,
        &SolverSettings {
            shell_blend: [0.0, 0.0, 1.5],
            ..settings(SolverKind::Rbf, true)
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("shell_blend"), "{e}");
}
