//! `mimic bench --gpu`: per rig, the many-sessions GPU morph ([`BatchMorph`]) timed for one
//! session and for many in one dispatch, each session driven by its own frame of the recording's
//! displacements.

use crate::batch::{BatchError, BatchMorph, BatchTiming};
use crate::{BenchError, Recorded, Subject, load_average};
use glam::Vec3;
use mimic_render::RenderError;
use mimic_retarget::FrameStatus;
use serde::Serialize;
use std::fmt::Write;

/// One timed dispatch size.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GpuRun {
    /// Sessions in each dispatch.
    pub sessions: usize,
    /// Dispatches timed.
    pub dispatches: usize,
    /// Rows of the basis the morph pass computes.
    pub moving_rows: usize,
    /// Vertices whose normals the normals pass recomputes.
    pub normal_vertices: usize,
    /// "gpu timestamps" or the wall clock.
    pub timed_by: &'static str,
    /// The time a dispatch is counted at, microseconds (GPU time where timestamps exist).
    pub per_dispatch_us: f64,
    /// Median wall time of a dispatch: upload, submit and wait, microseconds.
    pub wall_us: f64,
    /// The morph pass by GPU timestamps, microseconds.
    pub gpu_morph_us: Option<f64>,
    /// The normals pass by GPU timestamps, microseconds.
    pub gpu_normals_us: Option<f64>,
    /// Sessions whose morph fits one 60 fps frame at this cost per session.
    pub sessions_per_frame_at_60fps: f64,
}

/// One rig on the GPU.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GpuRigReport {
    /// Rig name.
    pub rig: String,
    /// Mesh vertices.
    pub vertices: usize,
    /// Controls.
    pub controls: usize,
    /// The adapter, its type and backend.
    pub adapter: String,
    /// 1 session, then the sessions asked for.
    pub runs: Vec<GpuRun>,
    /// The 1-minute load average at the end.
    pub load_average: Option<f64>,
}

/// What [`bench_rig`] found.
#[derive(Clone, Debug, PartialEq)]
pub enum GpuOutcome {
    /// The rig was timed.
    Measured(GpuRigReport),
    /// No adapter or device: why (nothing was measured).
    NoGpu(String),
}

/// Times the rig's morph on the GPU for 1 and for `sessions` sessions, `dispatches` dispatches
/// each; session `s` replays the displacements of tracked frame `s` (up to 200 of them).
pub fn bench_rig(
    subject: &mut Subject<'_>,
    recorded: &Recorded,
    sessions: usize,
    dispatches: usize,
) -> Result<GpuOutcome, BenchError> {
    let mut out = subject.retargeter.new_output();
    let mut ds: Vec<Vec<Vec3>> = Vec::new();
    for f in recorded.frames.iter().take(2000) {
        if subject.retargeter.step(f, &mut out) == FrameStatus::Tracked {
            ds.push(out.displacements.clone());
            if ds.len() == 200 {
                break;
            }
        }
    }
    if ds.is_empty() {
        return Err(BenchError::TooFewTracked(recorded.name.clone()));
    }
    let weights =
        |count: usize| -> Vec<Vec3> { (0..count).flat_map(|s| ds[s % ds.len()].clone()).collect() };
    let (rig, basis) = (subject.rig, subject.retargeter.basis());
    let mut runs = Vec::new();
    let mut adapter = String::new();
    for count in [1, sessions] {
        let mut batch =
            match BatchMorph::new(basis, &rig.mesh.positions, &rig.mesh.triangles, count) {
                Ok(b) => b,
                Err(BatchError::Render(
                    e @ (RenderError::NoAdapter(_) | RenderError::NoDevice(_)),
                )) => return Ok(GpuOutcome::NoGpu(e.to_string())),
                Err(e) => return Err(e.into()),
            };
        adapter = batch.adapter().to_string();
        let t = batch.time(&weights(count), dispatches)?;
        runs.push(run(&batch, &t));
    }
    Ok(GpuOutcome::Measured(GpuRigReport {
        rig: rig.name.clone(),
        vertices: rig.mesh.vertex_count(),
        controls: basis.control_count(),
        adapter,
        runs,
        load_average: load_average(),
    }))
}

/// The report of one timed batch.
fn run(batch: &BatchMorph, t: &BatchTiming) -> GpuRun {
    GpuRun {
        sessions: t.sessions,
        dispatches: t.iterations,
        moving_rows: batch.moving_count(),
        normal_vertices: batch.normal_count(),
        timed_by: if batch.has_timestamps() {
            "gpu timestamps"
        } else {
            "wall clock around upload, submit and wait"
        },
        per_dispatch_us: t.per_dispatch_us(),
        wall_us: t.wall_us,
        gpu_morph_us: t.gpu.map(|g| g.morph_us),
        gpu_normals_us: t.gpu.map(|g| g.normals_us),
        sessions_per_frame_at_60fps: t.sessions_at_60fps(),
    }
}

impl GpuRigReport {
    /// The plain summary: per dispatch size, its time and the sessions it fits at 60 fps.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "{} ({} vertices, {} controls) on {}\n",
            self.rig, self.vertices, self.controls, self.adapter
        );
        for r in &self.runs {
            let parts = match (r.gpu_morph_us, r.gpu_normals_us) {
                (Some(m), Some(n)) => format!(" (morph {m:.1} us, normals {n:.1} us)"),
                _ => String::new(),
            };
            let by = if r.timed_by == "gpu timestamps" {
                "GPU timestamps"
            } else {
                "wall clock"
            };
            let _ = writeln!(
                s,
                "  {} session(s), {} moving rows, {} normals: {:.1} us a dispatch{parts}, by {by}; wall {:.1} us; {:.1} sessions per frame at 60 fps",
                r.sessions,
                r.moving_rows,
                r.normal_vertices,
                r.per_dispatch_us,
                r.wall_us,
                r.sessions_per_frame_at_60fps
            );
        }
        let load = self.load_average;
        let _ = writeln!(
            s,
            "  load average {}",
            load.map_or("unknown".into(), |l| format!("{l:.2}"))
        );
        s
    }
}
