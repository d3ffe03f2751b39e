//! `mimic bench --gpu`: the many-sessions GPU morph, timed per rig.

use super::{Args, load_average};
use crate::cmd::setup::prepare;
use anyhow::Context;
use glam::Vec3;
use mimic_retarget::FrameStatus;
use serde_json::json;

/// `mimic bench --gpu`: per rig, the many-sessions GPU morph of `mimic_render::compute`, timed for
/// one session and for `--sessions` (default 100) in one dispatch, each session driven by its own
/// frame of the recording's displacements.
pub(super) fn bench_gpu(args: &Args, rigs: &[String]) -> anyhow::Result<()> {
    use mimic_render::{RenderError, compute::BatchError, compute::BatchMorph};
    let sessions = args.sessions.unwrap_or(100);
    let recording = mimic_capture::read_recording(&args.recording, None)?;
    let frames: Vec<_> = recording.frames.iter().map(|f| f.frame.clone()).collect();
    let mut reports = Vec::new();
    for name in rigs {
        let mut rig_args = args.rig.clone();
        rig_args.rig = name.clone();
        let mut p = prepare(&rig_args, &args.pipeline, &recording.header.layout)?;
        // Up to 200 tracked frames' displacements; session s replays frame s (mod their count).
        let mut out = p.retargeter.new_output();
        let mut ds: Vec<Vec<Vec3>> = Vec::new();
        for f in frames.iter().take(2000) {
            if p.retargeter.step(f, &mut out) == FrameStatus::Tracked {
                ds.push(out.displacements.clone());
                if ds.len() == 200 {
                    break;
                }
            }
        }
        anyhow::ensure!(
            !ds.is_empty(),
            "{}: no tracked frames",
            args.recording.display()
        );
        let weights = |count: usize| -> Vec<Vec3> {
            (0..count).flat_map(|s| ds[s % ds.len()].clone()).collect()
        };
        let basis = p.retargeter.basis();
        let mut runs = Vec::new();
        let mut adapter = String::new();
        for count in [1, sessions] {
            let mut batch =
                match BatchMorph::new(basis, &p.rig.mesh.positions, &p.rig.mesh.triangles, count) {
                    Ok(b) => b,
                    Err(BatchError::Render(
                        e @ (RenderError::NoAdapter(_) | RenderError::NoDevice(_)),
                    )) => {
                        println!("mimic bench --gpu: {e}; no GPU to time, nothing measured");
                        return Ok(());
                    }
                    Err(e) => return Err(e.into()),
                };
            adapter = batch.adapter().to_string();
            let t = batch.time(&weights(count), args.gpu_dispatches)?;
            runs.push((
                batch.moving_count(),
                batch.normal_count(),
                batch.has_timestamps(),
                t,
            ));
        }
        let load = load_average();
        let report = json!({
            "rig": p.rig.name,
            "vertices": p.rig.mesh.vertex_count(),
            "controls": basis.control_count(),
            "adapter": adapter,
            "runs": runs.iter().map(|(moving, normal, stamps, t)| json!({
                "sessions": t.sessions,
                "dispatches": t.iterations,
                "moving_rows": moving,
                "normal_vertices": normal,
                "timed_by": if *stamps { "gpu timestamps" } else { "wall clock around upload, submit and wait" },
                "per_dispatch_us": t.per_dispatch_us(),
                "wall_us": t.wall_us,
                "gpu_morph_us": t.gpu.map(|g| g.morph_us),
                "gpu_normals_us": t.gpu.map(|g| g.normals_us),
                "sessions_per_frame_at_60fps": t.sessions_at_60fps(),
            })).collect::<Vec<_>>(),
            "load_average": load,
        });
        if !args.json {
            println!(
                "rig {} ({} vertices, {} controls) on {adapter}",
                p.rig.name,
                p.rig.mesh.vertex_count(),
                basis.control_count()
            );
            for (moving, normal, stamps, t) in &runs {
                let parts = t.gpu.map_or(String::new(), |g| {
                    format!(
                        " (morph {:.1} us, normals {:.1} us)",
                        g.morph_us, g.normals_us
                    )
                });
                println!(
                    "  {} session(s), {moving} moving rows, {normal} normals: {:.1} us a dispatch{parts}, by {}; wall {:.1} us; {:.1} sessions per frame at 60 fps",
                    t.sessions,
                    t.per_dispatch_us(),
                    if *stamps {
                        "GPU timestamps"
                    } else {
                        "wall clock"
                    },
                    t.wall_us,
                    t.sessions_at_60fps()
                );
            }
            println!(
                "  load average {}",
                load.map_or("?".into(), |l| format!("{l:.2}"))
            );
        }
        reports.push(report);
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({ "gpu": reports })).context("report")?
        );
    }
    Ok(())
}
