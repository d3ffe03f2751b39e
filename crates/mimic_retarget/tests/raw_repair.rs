//! Tears on raw Kinect imports (issue 45 item 2, docs/gate.md "Tears"): the mouth and chin
//! repair (`GateSettings::max_mouth_residual`, `max_chin_residual`) on a raw import of a shipped
//! GFE capture cuts the frames whose chin is sheared back past anything ICT's own shapes do, and
//! leaves a clean (fitted) take bit for bit. `cargo test -p mimic_retarget --test raw_repair --
//! --include-ignored --nocapture` prints the figures docs/gate.md quotes (`BOUNDS=0,0.15 CHIN=0.1`).
#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

mod common;

use common::{ict, layout, recording, root};
use glam::Vec3;
use mimic_retarget::{FrameStatus, RetargetSettings, Retargeter};
use mimic_solve::Basis;
use mimic_solve::morph_fit::{MorphFit, MorphScratch};
use mimic_types::{LandmarkFrame, Layout, Region, Rig};
/// A shipped GFE capture imported as `mimic import gfe` does without `--fit` (depths repaired).
fn gfe(name: &str) -> (Layout, Vec<LandmarkFrame>) {
    let path = root().join(format!(
        "tests/data/kinect-gfe-libras/{name}_datapoints.txt"
    ));
    let imp = mimic_trackers::importer::importer("gfe").unwrap();
    let o = mimic_trackers::importer::ImportOptions::gfe(None, None, false);
    let i = imp.import(&path, &o).unwrap();
    let frames = i.imported.frames.into_iter().map(|f| f.frame).collect();
    (layout(imp.layout()), frames)
}
struct Probe {
    lower_teeth_front: f32,
    lip: usize,
    tris: Vec<[usize; 3]>,
    bottom: Vec<usize>,
    shapes: Vec<(String, Vec<Vec3>)>,
    fit: MorphFit,
    iod: f32,
    edges: Vec<(usize, usize, f32)>,
    chin: usize,
    /// The upper lip's controls (8.1, 8.5, 8.6) and the front of the upper teeth at rest
    /// beside each (within 0.5 cm across).
    upper_lip: Vec<(usize, f32)>,
}

fn ctl(rig: &Rig, fdp: &str) -> usize {
    rig.controls
        .iter()
        .position(|c| c.fdp.to_string() == fdp)
        .unwrap()
}

fn normal(p: &[Vec3], t: &[usize; 3]) -> Vec3 {
    (p[t[1]] - p[t[0]])
        .cross(p[t[2]] - p[t[0]])
        .normalize_or_zero()
}

impl Probe {
    fn new(rig: &Rig) -> Self {
        let rest = &rig.mesh.positions;
        let jaw = rig.parts.jaw.as_ref().unwrap();
        let lower_teeth_front = jaw
            .vertices
            .iter()
            .flat_map(|[a, b]| *a as usize..=*b as usize)
            .map(|v| rest[v].z)
            .fold(f32::MIN, f32::max);
        let skin: Vec<bool> = (0..rest.len())
            .map(|i| i <= 9408 && !rig.frozen[i] && rest[i].y < -1.1)
            .collect();
        let tris: Vec<[usize; 3]> = rig
            .mesh
            .triangles
            .iter()
            .map(|t| [t[0] as usize, t[1] as usize, t[2] as usize])
            .filter(|t| t.iter().all(|v| skin[*v]))
            .collect();
        let rest_normals: Vec<Vec3> = tris.iter().map(|t| normal(rest, t)).collect();
        let mut vn = vec![Vec3::ZERO; rest.len()];
        for (t, n) in tris.iter().zip(&rest_normals) {
            for v in t {
                vn[*v] += *n;
            }
        }
        let front = |v: usize| vn[v].normalize_or_zero().z > 0.2;
        let mut edges: Vec<(usize, usize, f32)> = tris
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .filter(|(a, b)| front(*a) && front(*b))
            .map(|(a, b)| (a.min(b), a.max(b), rest[a].distance(rest[b])))
            .collect();
        edges.sort_by_key(|e| (e.0, e.1));
        edges.dedup_by_key(|e| (e.0, e.1));
        let bottom: Vec<usize> = (0..rig.controls.len())
            .filter(|j| rig.controls[*j].region == Region::Bottom)
            .collect();
        let pack = mimic_assets::load_shape_pack(
            &root().join("configs/meshes/ict-facekit/expressions.shapes"),
        )
        .unwrap();
        let shapes: Vec<(String, Vec<Vec3>)> = pack
            .shapes
            .iter()
            .map(|s| {
                (
                    s.name.clone(),
                    rig.controls
                        .iter()
                        .map(|c| s.deltas[c.vertex as usize])
                        .collect::<Vec<_>>(),
                )
            })
            .filter(|(_, d)| bottom.iter().any(|j| d[*j].length() > 0.01))
            .collect();
        let at_bottom: Vec<Vec<Vec3>> = shapes
            .iter()
            .map(|(_, d)| bottom.iter().map(|j| d[*j]).collect())
            .collect();
        let fit = MorphFit::new(&at_bottom, 1e-4).unwrap();
        let names: Vec<_> = rig.controls.iter().map(|c| c.fdp).collect();
        let iod = mimic_retarget::face_size(&names, &rig.control_positions()).unwrap();
        Self {
            lower_teeth_front,
            lip: rig.controls[ctl(rig, "8.2")].vertex as usize,
            tris,
            bottom,
            shapes,
            fit,
            iod,
            edges,
            chin: rig.controls[ctl(rig, "2.1")].vertex as usize,
            upper_lip: ["8.1", "8.5", "8.6"]
                .iter()
                .map(|f| {
                    let v = rig.controls[ctl(rig, f)].vertex as usize;
                    // ICT's upper teeth (configs/meshes/ict-facekit/SOURCE.md).
                    let front = (17039..=19246)
                        .filter(|t| (rest[*t].x - rest[v].x).abs() < 0.5)
                        .map(|t| rest[t].z)
                        .fold(f32::MIN, f32::max);
                    (v, front)
                })
                .collect(),
        }
    }

    /// (the lower lip's middle behind the lower teeth at rest, edge strain p99 of the front
    /// skin, chin shear (IOD), the upper lip (8.1, 8.5, 8.6) behind the upper teeth beside it:
    /// bared teeth).
    fn mesh(&self, p: &[Vec3], rest: &[Vec3]) -> (bool, f32, f32, bool) {
        let behind = p[self.lip].z <= self.lower_teeth_front;
        let bared = self.upper_lip.iter().any(|(v, front)| p[*v].z <= *front);
        let mut strain: Vec<f32> = self
            .edges
            .iter()
            .map(|(a, b, l)| (p[*a].distance(p[*b]) / l - 1.0).abs())
            .collect();
        let st = pct(&mut strain, 0.99);
        let d = p[self.chin] - rest[self.chin];
        let shear = (-d.z - 1.03 * (-d.y).max(0.0)) / self.iod;
        (behind, st, shear, bared)
    }

    /// Per bottom control, the residual of the fit (IOD).
    fn residual(&self, d: &[Vec3], scratch: &mut MorphScratch) -> Vec<f32> {
        let db: Vec<Vec3> = self.bottom.iter().map(|j| d[*j]).collect();
        let mut w = vec![0.0; self.shapes.len()];
        scratch.reset();
        self.fit.fit(&db, scratch, &mut w);
        self.bottom
            .iter()
            .enumerate()
            .map(|(k, j)| {
                let f: Vec3 = self
                    .shapes
                    .iter()
                    .zip(&w)
                    .map(|((_, s), w)| s[*j] * *w)
                    .sum();
                (db[k] - f).length() / self.iod
            })
            .collect()
    }
}

const STRAIN: f32 = 0.5;
const SHEAR: f32 = 0.1;

fn pct(v: &mut [f32], q: f32) -> f32 {
    v.sort_by(f32::total_cmp);
    if v.is_empty() {
        return f32::NAN;
    }
    v[((v.len() - 1) as f32 * q).round() as usize]
}

fn apply_basis(basis: &Basis, rest: &[Vec3], d: &[Vec3]) -> Vec<Vec3> {
    let m = basis.control_count();
    let mut full = vec![Vec3::ZERO; m];
    full[..d.len()].copy_from_slice(d);
    rest.iter()
        .enumerate()
        .map(|(i, r)| {
            *r + basis
                .row(i)
                .iter()
                .zip(&full)
                .map(|(b, x)| *x * *b)
                .sum::<Vec3>()
        })
        .collect()
}

#[test]
#[ignore = "exploration: prints figures"]
fn explore() {
    let (rig, basis) = ict();
    let probe = Probe::new(rig);
    let rest = &rig.mesh.positions;
    println!(
        "iod {} ; {} shapes, {} tris, teeth front {}",
        probe.iod,
        probe.shapes.len(),
        probe.tris.len(),
        probe.lower_teeth_front
    );
    let pack = mimic_assets::load_shape_pack(
        &root().join("configs/meshes/ict-facekit/expressions.shapes"),
    )
    .unwrap();
    // ICT truth: every shape, as the true mesh and through the basis; and leave-one-out residual.
    for s in &pack.shapes {
        let truth: Vec<Vec3> = rest.iter().zip(&s.deltas).map(|(a, b)| *a + *b).collect();
        let d: Vec<Vec3> = rig
            .controls
            .iter()
            .map(|c| s.deltas[c.vertex as usize])
            .collect();
        let via = apply_basis(basis, rest, &d);
        let t = probe.mesh(&truth, rest);
        let v = probe.mesh(&via, rest);
        // leave-one-out: fit without this shape.
        let keep: Vec<&(String, Vec<Vec3>)> =
            probe.shapes.iter().filter(|(n, _)| *n != s.name).collect();
        let at: Vec<Vec<Vec3>> = keep
            .iter()
            .map(|(_, d)| probe.bottom.iter().map(|j| d[*j]).collect())
            .collect();
        let f = MorphFit::new(&at, 1e-4).unwrap();
        let mut sc = f.scratch();
        let db: Vec<Vec3> = probe.bottom.iter().map(|j| d[*j]).collect();
        let mut w = vec![0.0; keep.len()];
        f.fit(&db, &mut sc, &mut w);
        let mut mx = 0f32;
        for (k, _) in probe.bottom.iter().enumerate() {
            let fv: Vec3 = at.iter().zip(&w).map(|(a, w)| a[k] * *w).sum();
            mx = mx.max((db[k] - fv).length());
        }
        let dmax = db.iter().map(|v| v.length()).fold(0.0, f32::max);
        println!(
            "ICT {:24} truth behind {} strain {:5.3} shear {:6.3} bared {} | basis behind {} strain {:5.3} shear {:6.3} bared {} | dmax {:.3} IOD loo resid {:.3} IOD",
            s.name,
            t.0,
            t.1,
            t.2,
            t.3,
            v.0,
            v.1,
            v.2,
            v.3,
            dmax / probe.iod,
            mx / probe.iod
        );
    }
    let takes: Vec<(String, Layout, Vec<LandmarkFrame>)> = vec![
        (
            "a_affirmative (repaired)".into(),
            gfe("a_affirmative").0,
            gfe("a_affirmative").1,
        ),
        (
            "a_doubt_question (repaired)".into(),
            gfe("a_doubt_question").0,
            gfe("a_doubt_question").1,
        ),
        (
            "a_yn_question (repaired)".into(),
            gfe("a_yn_question").0,
            gfe("a_yn_question").1,
        ),
    ]
    .into_iter()
    .chain(
        [
            "a_affirmative.jsonl",
            "a_doubt_question.jsonl",
            "a_yn_question.jsonl",
            "a_affirmative.kinect121.jsonl",
            "a_doubt_question.kinect121.jsonl",
            "a_yn_question.kinect121.jsonl",
            "megamind_mediapipe.jsonl",
        ]
        .iter()
        .map(|n| {
            let (l, f) = recording(n);
            (n.to_string(), l, f)
        }),
    )
    .collect();
    let bounds: Vec<f32> = std::env::var("BOUNDS")
        .unwrap_or_else(|_| "1000,0.2,0.15,0.1".into())
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    for (name, l, frames) in &takes {
        for &bound in &bounds {
            run_take(&probe, name, l, frames, bound);
        }
    }
}

fn run_take(probe: &Probe, name: &str, l: &Layout, frames: &[LandmarkFrame], bound: f32) {
    let (rig, basis) = ict();
    let chin = ctl(rig, "2.1");
    let chin10 = ctl(rig, "2.10");
    let mut settings = RetargetSettings::default();
    settings.gate.max_mouth_residual = bound;
    settings.gate.max_chin_residual = std::env::var("CHIN").map_or(0.0, |c| c.parse().unwrap());
    let mut rt = Retargeter::new(rig, l, basis.clone(), settings).unwrap();
    let mut out = rt.new_output();
    let (mut behind, mut flip, mut crossed, mut tracked, mut bared) = (0, 0, 0, 0, 0);
    let (mut r_all, mut r_torn, mut r_clean) = (vec![], vec![], vec![]);
    let mut chin_d = vec![];
    let mut chin_v = vec![];
    let mut shears: Vec<f32> = vec![];
    let mut per: Vec<Vec<f32>> = vec![];
    let mut scratch = probe.fit.scratch();
    let mut worst = (0f32, 0usize);
    let mut torn_frames = vec![];
    for (i, f) in frames.iter().enumerate() {
        rt.step(f, &mut out);
        if out.status != FrameStatus::Tracked {
            continue;
        }
        tracked += 1;
        let (b, t, c, u) = probe.mesh(&out.positions, &rig.mesh.positions);
        bared += usize::from(u);
        let r = rt.repair_reading().residual;
        let torn = b || t > STRAIN || c > SHEAR;
        behind += usize::from(b);
        flip += usize::from(t > STRAIN);
        crossed += usize::from(c > SHEAR);
        chin_v.push(out.displacements[chin]);
        shears.push(c);
        if bound > 100.0 {
            per.push(probe.residual(&out.displacements[..rig.controls.len()], &mut scratch));
        }
        r_all.push(r);
        if torn {
            r_torn.push(r);
            if torn_frames.len() < 12 {
                torn_frames.push(i);
            }
        } else {
            r_clean.push(r)
        }
        if r > worst.0 {
            worst = (r, i);
        }
        chin_d.push(out.displacements[chin].length());
    }
    if !per.is_empty() {
        let line: Vec<String> = probe
            .bottom
            .iter()
            .enumerate()
            .map(|(k, j)| {
                let mut v: Vec<f32> = per.iter().map(|r| r[k]).collect();
                format!("{} {:.3}", rig.controls[*j].fdp, pct(&mut v, 0.99))
            })
            .collect();
        println!("  per-control p99: {}", line.join(", "));
    }
    let nc = rt.neutral_controls().unwrap();
    let s = rt.source_to_target().unwrap();
    let tc = rt.target_controls();
    let m = nc.len() as f32;
    let cs = nc.iter().sum::<Vec3>() / m;
    let ct = tc.iter().sum::<Vec3>() / m;
    let mapped = |j: usize| s.apply(nc[j] - cs) + ct;
    let pose = mimic_solve::kabsch::fit_similarity(nc, tc, true).unwrap();
    let comp = |k: usize, v: &mut Vec<Vec3>| {
        let mut c: Vec<f32> = v.iter().map(|x| x.to_array()[k]).collect();
        pct(&mut c, 0.5)
    };
    if std::env::var_os("VERBOSE").is_some() {
        println!(
            "   chin median d ({:.2}, {:.2}, {:.2}) cm; kabsch chin offset {:?} ; strain>{STRAIN} {flip} shear>{SHEAR} {crossed}",
            comp(0, &mut chin_v),
            comp(1, &mut chin_v),
            comp(2, &mut chin_v),
            pose.apply(nc[chin]) - tc[chin]
        );
    }
    println!(
        "{name} bound {bound}: tracked {tracked} repaired {} behind {behind} bared {bared} strain {flip} shear {crossed} (p99 {:.3} max {:.3} IOD) | resid IOD p50 {:.3} p90 {:.3} p99 {:.3} max {:.3} (frame {}) | torn p50 {:.3} clean p99 {:.3} | chin |d| p50 {:.3} cm | neutral chin off {:.2} / {:.2} cm (kabsch {:.2} / {:.2}), rms {:.2} | torn {:?}",
        rt.stats().repaired,
        pct(&mut shears, 0.99),
        pct(&mut shears, 1.0),
        pct(&mut r_all, 0.5),
        pct(&mut r_all, 0.9),
        pct(&mut r_all, 0.99),
        pct(&mut r_all, 1.0),
        worst.1,
        pct(&mut r_torn, 0.5),
        pct(&mut r_clean, 0.99),
        pct(&mut chin_d, 0.5),
        mapped(chin).distance(tc[chin]),
        mapped(chin10).distance(tc[chin10]),
        pose.apply(nc[chin]).distance(tc[chin]),
        pose.apply(nc[chin10]).distance(tc[chin10]),
        s.rms_residual,
        torn_frames,
    );
}

/// The plausible subspace's table as `repair::ICT_AT_FDPS` should hold it: ICT's expression
/// shapes at the ICT rig's feature points, in ICT's inter-ocular distances.
fn table_text() -> String {
    use std::fmt::Write;
    let (rig, _) = ict();
    let names: Vec<_> = rig.controls.iter().map(|c| c.fdp).collect();
    let iod = mimic_retarget::face_size(&names, &rig.control_positions()).unwrap();
    let pack = mimic_assets::load_shape_pack(
        &root().join("configs/meshes/ict-facekit/expressions.shapes"),
    )
    .unwrap();
    let mut t = String::from("fdps");
    for c in &rig.controls {
        write!(t, " {}", c.fdp).unwrap();
    }
    let numbers = |t: &mut String, v: &mut dyn Iterator<Item = Vec3>| {
        for p in v {
            for x in p.to_array() {
                write!(t, " {:.5}", x / iod).unwrap();
            }
        }
        t.push('\n');
    };
    t.push_str("\nrest");
    numbers(&mut t, &mut rig.control_positions().into_iter());
    for s in &pack.shapes {
        let d: Vec<Vec3> = rig
            .controls
            .iter()
            .map(|c| s.deltas[c.vertex as usize])
            .collect();
        if d.iter().all(|v| v.length() < 1e-3 * iod) {
            continue;
        }
        t.push_str(&s.name);
        numbers(&mut t, &mut d.into_iter());
    }
    t
}

#[test]
fn the_shipped_subspace_is_icts_shapes_at_its_feature_points() {
    let want = table_text();
    let path = root().join("crates/mimic_retarget/src/repair/ict_at_fdps.txt");
    if std::env::var_os("MIMIC_BLESS").is_some() {
        std::fs::write(&path, &want).unwrap();
    }
    assert_eq!(
        mimic_retarget::repair::ICT_AT_FDPS,
        want,
        "regenerate with MIMIC_BLESS=1 (then rebuild)"
    );
    let s = mimic_retarget::repair::Subspace::ict();
    assert_eq!(s.fdps.len(), 38);
    assert!(s.shapes.len() >= 40, "{}", s.shapes.len());
}

/// Per frame, each control's displacement; and the frames whose chin is sheared back more than
/// `SHEAR` IOD, and the largest shear.
fn run(
    l: &Layout,
    frames: &[LandmarkFrame],
    bounds: [f32; 2],
) -> (Vec<Vec<Vec3>>, usize, f32, u64) {
    let (rig, basis) = ict();
    let probe = Probe::new(rig);
    let mut settings = RetargetSettings::default();
    [
        settings.gate.max_mouth_residual,
        settings.gate.max_chin_residual,
    ] = bounds;
    let mut rt = Retargeter::new(rig, l, basis.clone(), settings).unwrap();
    let mut out = rt.new_output();
    let (mut ds, mut torn, mut worst) = (Vec::new(), 0, f32::MIN);
    for f in frames {
        rt.step(f, &mut out);
        ds.push(out.displacements.clone());
        if out.status == FrameStatus::Tracked {
            let (_, _, shear, _) = probe.mesh(&out.positions, &rig.mesh.positions);
            torn += usize::from(shear > SHEAR);
            worst = worst.max(shear);
        }
    }
    (ds, torn, worst, rt.stats().repaired)
}

#[test]
fn the_repair_cuts_a_raw_imports_chin_tears_and_leaves_a_clean_take_alone() {
    let (rig, _) = ict();
    let probe = Probe::new(rig);
    let rest = &rig.mesh.positions;
    // The tear measure's truth: no expression ICT ships shears the chin back past its drop.
    let pack = mimic_assets::load_shape_pack(
        &root().join("configs/meshes/ict-facekit/expressions.shapes"),
    )
    .unwrap();
    for s in &pack.shapes {
        let p: Vec<Vec3> = rest.iter().zip(&s.deltas).map(|(a, b)| *a + *b).collect();
        let (_, _, shear, _) = probe.mesh(&p, rest);
        assert!(shear < 0.1 * SHEAR, "{}: {shear}", s.name);
    }
    let chosen = mimic_retarget::repair::CHOSEN;
    // A raw import (`mimic import gfe`, depths repaired) of a shipped capture.
    let (l, frames) = gfe("a_doubt_question");
    let (_, before, worst_before, none) = run(&l, &frames, [0.0, 0.0]);
    let (_, after, worst_after, repaired) = run(&l, &frames, chosen);
    println!(
        "a_doubt_question, raw import: chin sheared past {SHEAR} IOD in {before} -> {after} frames, worst {worst_before:.3} -> {worst_after:.3} IOD; {repaired} of {} frames repaired",
        frames.len()
    );
    assert_eq!(none, 0);
    assert!(before > 100, "{before}");
    assert!(10 * after <= 9 * before, "{before} -> {after}");
    assert!(
        worst_after <= 0.8 * worst_before,
        "{worst_before} -> {worst_after}"
    );
    // The same capture fitted (`--fit candide3`): clean, so nothing repaired, bit for bit.
    let (l, frames) = recording("a_doubt_question.kinect121.jsonl");
    let (off, torn, _, _) = run(&l, &frames, [0.0, 0.0]);
    let (on, _, _, repaired) = run(&l, &frames, chosen);
    assert_eq!(torn, 0);
    assert_eq!(repaired, 0);
    assert!(off == on, "a clean take changed");
}
