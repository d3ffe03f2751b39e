//! `rig new --blendshapes arkit` on a 50k-vertex head (issue 41: at most 30 s on 2 cores): ICT's
//! skin and mouth socket (vertices 0-14061) subdivided once at the edge midpoints (56 k vertices),
//! in mm, turned z-up and facing -y as scans come, written as an OBJ; then the whole job
//! (`make_rig_file`: orientation probes, registration, landmarks, controls, parts, the 51 ARKit
//! shapes by deformation transfer, the rig written and loaded back), timed end to end.
//! `cargo bench -p mimic_rig --bench rig_new` prints each run and the median (3 runs;
//! `MIMIC_BENCH_RUNS` for more). Under `cargo test` (no `--bench`) it only says so: a run takes
//! minutes in a debug build.

#![allow(
    clippy::unwrap_used,
    reason = "a bench: a failed unwrap is the failure report"
)]

use glam::{Quat, Vec3};
use mimic_rig::{Defaults, NewRig, make_rig_file};
use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

/// The head: ICT's vertices below `keep`, every triangle among them cut in four.
fn subdivided_head(repo: &std::path::Path, keep: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let ict = repo.join("configs/meshes/ict-facekit/generic_neutral_mesh.obj");
    let mesh = mimic_assets::load_obj(&ict).unwrap();
    let mut positions: Vec<Vec3> = mesh.positions[..keep as usize].to_vec();
    let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
    let mut triangles = Vec::new();
    for t in mesh
        .triangles
        .iter()
        .filter(|t| t.iter().all(|&v| v < keep))
    {
        let mut m = [0u32; 3];
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            m[k] = *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                positions.push((positions[a as usize] + positions[b as usize]) * 0.5);
                (positions.len() - 1) as u32
            });
        }
        triangles.extend([
            [t[0], m[0], m[2]],
            [t[1], m[1], m[0]],
            [t[2], m[2], m[1]],
            m,
        ]);
    }
    // cm -> mm, then y up / +z forward -> z up / -y forward (a turn of +90 degrees about x).
    let turn = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
    for p in &mut positions {
        *p = turn * (*p * 10.0);
    }
    (positions, triangles)
}

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        println!("rig_new: run with `cargo bench -p mimic_rig --bench rig_new` (minutes in debug)");
        return;
    }
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let configs = repo.join("configs");
    let tmp = tempfile::tempdir().unwrap();
    let (positions, triangles) = subdivided_head(&repo, 14062);
    let obj = tmp.path().join("head50k.obj");
    let mut w = std::io::BufWriter::new(std::fs::File::create(&obj).unwrap());
    mimic_assets::write_obj(&mut w, "bench head", &positions, None, &triangles).unwrap();
    drop(w);
    let runs: usize = std::env::var("MIMIC_BENCH_RUNS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    println!(
        "rig_new: {} vertices, {} triangles (mm, z up, facing -y), --blendshapes arkit, {runs} runs",
        positions.len(),
        triangles.len()
    );
    let mut seconds = Vec::new();
    for run in 0..runs {
        let output = tmp.path().join(format!("run{run}/head.toml"));
        let job = NewRig {
            mesh: &obj,
            face: None,
            output: &output,
            landmarks: None,
            keep_missing: false,
            landmarks_out: None,
            units: None,
            name: None,
            controls: "mpeg4",
            overrides: &[],
            defaults: Defaults::default(),
            configs: &configs,
            command_line: String::new(),
            blendshapes: Some("arkit"),
            cut: true,
        };
        let t = Instant::now();
        let made = make_rig_file(&job, &mut |_| {}).unwrap();
        let s = t.elapsed().as_secs_f64();
        assert_eq!(made.loaded.mesh.vertex_count(), positions.len());
        println!("  run {run}: {s:.2} s");
        seconds.push(s);
    }
    seconds.sort_by(f64::total_cmp);
    let median = seconds[seconds.len() / 2];
    println!(
        "rig_new median {median:.2} s ({:.2} of the 30 s goal)",
        median / 30.0
    );
}
