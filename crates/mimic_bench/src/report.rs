//! [`RigReport`]: what [`crate::bench_rig`] measured, as JSON (serde), as a plain summary for
//! people, and as the developer detail (`mimic bench --detail`).

use crate::baseline::{Baseline, Floor};
use crate::kernels::{KernelsInStep, Turns};
use crate::sessions::SessionsComparison;
use mimic_retarget::StagePercentiles;
use serde::Serialize;
use std::fmt::Write;

/// The whole step's figures.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct StepFigures {
    /// Median, microseconds.
    pub median_us: f64,
    /// 99th percentile, microseconds.
    pub p99_us: f64,
    /// Frames per second at the median.
    pub frames_per_second: f64,
}

/// The 1-minute load average at the start and the end of a rig's run (`None`: not on Linux).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LoadAverage {
    /// At the start.
    pub start: Option<f64>,
    /// At the end.
    pub end: Option<f64>,
}

/// One rig's benchmark.
#[derive(Clone, Debug, Serialize)]
pub struct RigReport {
    /// Rig name.
    pub rig: String,
    /// Mesh vertices.
    pub vertices: usize,
    /// Vertices the basis moves.
    pub moving_vertices: usize,
    /// Controls (columns of the basis).
    pub controls: usize,
    /// The solver that built the basis.
    pub solver: serde_json::Value,
    /// Time spent building the basis, milliseconds.
    pub basis_setup_ms: f64,
    /// The recording stepped.
    pub recording: String,
    /// Tracked steps timed.
    pub steps: usize,
    /// Median and p99 of each stage.
    pub stages: StagePercentiles,
    /// The whole step.
    pub step: StepFigures,
    /// Baselines in the same process.
    pub baseline: Baseline,
    /// One read of the deform's bytes.
    pub floor: Floor,
    /// numpy's product over the same rows (`--numpy`).
    pub numpy: Option<serde_json::Value>,
    /// The step with each kernel variant, taking turns with the default.
    pub vector_kernels_in_step: KernelsInStep,
    /// 1 session against many (`--sessions`).
    pub sessions: Option<SessionsComparison>,
    /// Many sessions recording in each record mode against none (`--sessions N --record-cost DIR`).
    pub record_cost: Option<crate::record_cost::RecordCost>,
    /// The load average around the run.
    pub load_average: LoadAverage,
}

/// `x` to one decimal, or what stands for a figure not measured.
fn us(x: Option<f64>) -> String {
    match x {
        Some(x) if x.is_finite() => format!("{x:.1} us"),
        _ => "not available on this CPU".into(),
    }
}

impl RigReport {
    /// The plain summary: what was measured, the step's median, and each ratio against its
    /// baseline in the same run.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let step = &self.step;
        let _ = writeln!(
            s,
            "{}: {} vertices ({} move), {} controls; basis built in {:.0} ms",
            self.rig, self.vertices, self.moving_vertices, self.controls, self.basis_setup_ms
        );
        let _ = writeln!(
            s,
            "  one frame through the whole pipeline: median {:.1} us, p99 {:.1} us ({:.0} frames/s), {} frames of {}",
            step.median_us, step.p99_us, step.frames_per_second, self.steps, self.recording
        );
        let stages: Vec<String> = mimic_retarget::Stage::ALL
            .iter()
            .map(|&st| format!("{} {:.1}", st.name(), self.stages.get(st).median_us))
            .collect();
        let _ = writeln!(s, "  its stages, median us: {}", stages.join(", "));
        let b = &self.baseline;
        let _ = writeln!(
            s,
            "  deform {:.1}x as fast as the dense product over every vertex ({:.1} us); normals {:.1}x as fast as face-by-face normals over every vertex ({:.1} us); same run",
            crate::baseline::ratio(
                b.apply_row_pairs_median_us,
                self.stages.get(mimic_retarget::Stage::Deform).median_us
            ),
            b.apply_row_pairs_median_us,
            b.normals_speedup,
            b.normals_median_us
        );
        let _ = writeln!(
            s,
            "  kernels: deform {}, normals {}; {}",
            b.deform_kernel,
            b.normals_kernel,
            variants_line(&self.vector_kernels_in_step.cold)
        );
        if let Some(c) = &self.sessions {
            let _ = writeln!(
                s,
                "  sessions: 1 at {:.0} frames/s, {} at once at {:.0} frames/s ({:.2}x; {:.0} frames/s per core)",
                c.one_frames_per_second,
                c.sessions,
                c.many_frames_per_second,
                c.speedup,
                c.per_core_frames_per_second
            );
        }
        if let Some(c) = &self.record_cost {
            let modes: Vec<String> = c
                .modes
                .iter()
                .map(|m| {
                    let name = m
                        .mode
                        .map_or("none".to_string(), |w| format!("{w:?}").to_lowercase());
                    format!(
                        "{name} {:.0} ({:.2}x)",
                        m.median_frames_per_second, m.ratio_to_none
                    )
                })
                .collect();
            let _ = writeln!(
                s,
                "  recording, {} sessions, frames/s (medians of 3 rounds): {}",
                c.sessions,
                modes.join(", ")
            );
        }
        s
    }

    /// The developer detail: every stage's p99, every baseline and kernel variant, the floor,
    /// numpy's figure and the load average.
    pub fn detail(&self) -> String {
        let mut s = format!("{}", self.stages);
        let b = &self.baseline;
        let _ = writeln!(
            s,
            "  baselines over every vertex, same run: Basis::apply {:.1} us, dense row-pair product {:.1} us ({:.2}x); normals by fans {:.1} us, face by face {:.1} us ({:.2}x)",
            b.apply_median_us,
            b.apply_row_pairs_median_us,
            b.apply_kernel_speedup,
            b.normals_fans_median_us,
            b.normals_median_us,
            b.normals_kernel_speedup
        );
        let f = &self.floor;
        let _ = writeln!(
            s,
            "  deform over the moving rows: previous (blocked product, then add and scatter) {:.1} us, the kernel alone {:.1} us; one read of its {} kB {:.1} us ({:.0} % of the block-columns kept)",
            b.previous_deform_median_us,
            b.deform_kernel_median_us,
            f.bytes / 1000,
            f.read_median_us,
            100.0 * f.kept_block_columns
        );
        for (what, t) in [
            ("warm", &self.vector_kernels_in_step.warm),
            ("cold", &self.vector_kernels_in_step.cold),
        ] {
            let _ = writeln!(
                s,
                "  in the step, turns of {} frame(s) ({what}):",
                t.turn_frames
            );
            for (name, v) in &t.variants {
                let _ = writeln!(
                    s,
                    "    {name:<16} deform {:>7.1} us  normals {:>7.1} us  step {:>7.1} us ({:.3}x): {}",
                    v.deform_median_us, v.normals_median_us, v.step_median_us, v.step_ratio, v.what
                );
            }
        }
        if let Some(np) = self.numpy.as_ref().and_then(|v| v.as_object()) {
            let _ = writeln!(
                s,
                "  numpy B @ D (float32, same rows): {} (into a kept buffer {})",
                us(np.get("matmul_median_us").and_then(|v| v.as_f64())),
                us(np.get("matmul_out_median_us").and_then(|v| v.as_f64()))
            );
        }
        let load = |l: Option<f64>| l.map_or("unknown".into(), |l| format!("{l:.2}"));
        let _ = writeln!(
            s,
            "  load average {} at the start, {} at the end",
            load(self.load_average.start),
            load(self.load_average.end)
        );
        s
    }
}

/// How much longer the step takes with each variant than with the default (turns of 1 frame).
fn variants_line(t: &Turns) -> String {
    let parts: Vec<String> = t
        .variants
        .iter()
        .filter(|(name, _)| name.as_str() != "Default")
        .map(|(_, v)| {
            format!(
                "with {} the step takes {:.2}x as long",
                v.what, v.step_ratio
            )
        })
        .collect();
    parts.join(", ")
}
