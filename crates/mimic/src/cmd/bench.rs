//! `mimic bench`: per-stage timing of the retarget pipeline on a rig, with an in-process baseline.

use crate::cmd::setup::{PipelineArgs, RigArgs, fit_candide3, prepare};
use anyhow::Context;
use glam::Vec3;
use mimic_assets::ConfigDirs;
use mimic_fit::capture::{CaptureFrame, FitSummary};
use mimic_retarget::{
    FrameStatus, Retargeter, Stage, StageSamples, elapsed_ns, median_p99_us, throughput,
};
use mimic_solve::VectorKernel;
use serde_json::json;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

mod gpu;

/// Arguments of `mimic bench`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Recording whose frames drive the benchmark (looped).
    #[arg(long, default_value = "recordings/a_affirmative.jsonl")]
    pub recording: PathBuf,
    /// Number of timed steps.
    #[arg(long, default_value_t = 3000)]
    pub steps: usize,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// Rigs to run, one after the other (default: `ict-face-3k`, the source method's scale, then
    /// `--rig`).
    #[arg(long, value_delimiter = ',')]
    pub rigs: Vec<String>,
    /// Also step 1 and then N independent sessions at once (one named thread each, one basis
    /// shared; at least 20 000 steps each) and report frames/s and frames/s per core; with `--gpu`,
    /// the sessions in one GPU dispatch (default 100).
    #[arg(long)]
    pub sessions: Option<usize>,
    /// Also time numpy's `B @ D` (float32) over the same rows: runs `python3 tools/bench_numpy.py`.
    #[arg(long)]
    pub numpy: bool,
    /// Time the GPU pass instead: `--sessions` sessions (default 100) morphed in one wgpu compute
    /// dispatch (one basis, sessions x controls x 3 weights), positions and normals; reports the
    /// time per dispatch and sessions per frame at 60 fps. Without an adapter it says so and exits 0.
    #[arg(long)]
    pub gpu: bool,
    /// Dispatches timed by `--gpu`.
    #[arg(long, default_value_t = 50)]
    pub gpu_dispatches: usize,
}

/// Runs `mimic bench`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let rigs = if args.rigs.is_empty() {
        let mut r = vec!["ict-face-3k".to_string()];
        if args.rig.rig != "ict-face-3k" {
            r.push(args.rig.rig.clone());
        }
        r
    } else {
        args.rigs.clone()
    };
    if args.gpu {
        return gpu::bench_gpu(&args, &rigs);
    }
    let mut reports = Vec::new();
    for name in &rigs {
        let mut rig_args = args.rig.clone();
        rig_args.rig = name.clone();
        reports.push(bench_rig(&args, &rig_args)?);
    }
    let recording = mimic_capture::read_recording(&args.recording, None)?;
    let fit = fit_throughput(&recording)?;
    if args.json {
        let report = json!({
            "rigs": reports,
            "fit": fit.as_ref().map(|f| json!({"model": "candide3", "frames": f.frames, "lost": f.lost, "frames_per_second": f.frames_per_s, "median_residual_px": f.median_residual_px})),
            "build": if cfg!(debug_assertions) { "debug (not representative)" } else { "release" },
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&report).context("report")?
        );
    } else if let Some(f) = &fit {
        println!(
            "fit CANDIDE-3 to the recording: {:.0} frames/s ({} frames, median residual {:.2} px)",
            f.frames_per_s, f.frames, f.median_residual_px
        );
    }
    Ok(())
}

/// The 1-minute load average (Linux), for the record next to each figure.
fn load_average() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    text.split_whitespace().next()?.parse().ok()
}

/// Sum of `v` in 16 independent partial sums (vectorised): one read of every value, the
/// bandwidth floor of a kernel that reads the same bytes.
fn read_all(v: &[f32]) -> f32 {
    let mut acc = [0f32; 16];
    let mut chunks = v.chunks_exact(16);
    for c in &mut chunks {
        for (a, x) in acc.iter_mut().zip(c) {
            *a += *x;
        }
    }
    acc.iter().sum::<f32>() + chunks.remainder().iter().sum::<f32>()
}

/// numpy's `B @ D` over `rows` (the moving rows of `basis`), through `tools/bench_numpy.py`.
fn numpy_reference(basis: &mimic_solve::Basis, rows: &[u32]) -> anyhow::Result<serde_json::Value> {
    let m = basis.control_count();
    let mut bytes = Vec::with_capacity(rows.len() * m * 4);
    for &i in rows {
        bytes.extend(basis.row(i as usize).iter().flat_map(|w| w.to_le_bytes()));
    }
    let path = std::env::temp_dir().join(format!("mimic-bench-{}.f32", std::process::id()));
    std::fs::write(&path, &bytes).with_context(|| format!("writing {}", path.display()))?;
    let out = std::process::Command::new("python3")
        .arg("tools/bench_numpy.py")
        .arg(&path)
        .arg(rows.len().to_string())
        .arg(m.to_string())
        .output()
        .context("running python3 tools/bench_numpy.py");
    let _ = std::fs::remove_file(&path);
    let out = out?;
    anyhow::ensure!(
        out.status.success(),
        "tools/bench_numpy.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).context("tools/bench_numpy.py output")
}

/// Benchmarks one rig; prints its text report unless `--json`, returns its JSON report.
fn bench_rig(args: &Args, rig_args: &RigArgs) -> anyhow::Result<serde_json::Value> {
    let load_start = load_average();
    let recording = mimic_capture::read_recording(&args.recording, None)?;
    let layout_name = recording.header.layout.clone();
    let frames: Vec<_> = recording.frames.iter().map(|f| f.frame.clone()).collect();
    anyhow::ensure!(
        !frames.is_empty(),
        "{}: no usable frames",
        args.recording.display()
    );
    let span_us =
        frames.last().map(|f| f.timestamp_us).unwrap_or(0) - frames[0].timestamp_us + 33_333;
    let mut p = prepare(rig_args, &args.pipeline, &layout_name)?;
    let mut out = p.retargeter.new_output();
    let mut samples = StageSamples::with_capacity(args.steps);
    let mut k = 0usize;
    let mut guard = 0usize;
    while samples.steps() < args.steps {
        let src = &frames[k % frames.len()];
        let mut f = src.clone();
        f.timestamp_us += (k / frames.len()) as i64 * span_us;
        let t = Instant::now();
        let status = p.retargeter.step(&f, &mut out);
        let ns = elapsed_ns(t);
        if status == FrameStatus::Tracked {
            samples.push(ns, &out.times);
        }
        k += 1;
        guard += 1;
        anyhow::ensure!(
            guard < 100 * args.steps.max(100),
            "too few tracked frames in {}",
            args.recording.display()
        );
    }

    // Baselines in the same process, interleaved so that each variant runs in the same VM speed
    // state: the dense product over every vertex of the rig and full-mesh normals, as a pipeline
    // without the moving-part restriction would do, each with the current kernel and with the
    // previous one (row-pair product, face-by-face scatter normals); the previous deform (the
    // blocked product over the moving rows in index order, then a pass adding the rest positions
    // and scattering); the current deform kernel alone; and one plain read of the bytes it reads.
    let n = p.rig.mesh.vertex_count();
    let basis = p.retargeter.basis();
    let d = out.displacements.clone();
    let mut u = vec![Vec3::ZERO; n];
    let mut normals = vec![Vec3::ZERO; n];
    let fans = mimic_solve::normals::VertexFans::new(n, n, &p.rig.mesh.triangles);
    let mut u_a = vec![glam::Vec3A::ZERO; n];
    let moving = basis.moving_rows(n);
    let rest_rows: Vec<glam::Vec3A> = moving
        .rows
        .iter()
        .map(|&i| p.rig.mesh.positions[i as usize].into())
        .collect();
    let mut u_rows = vec![Vec3::ZERO; moving.rows.len()];
    let mut local = vec![glam::Vec3A::ZERO; moving.rows.len()];
    let mut positions = p.rig.mesh.positions.clone();
    let deform = mimic_solve::deform::MovingDeform::new(basis, &p.rig.mesh.positions);
    let floor_buf = vec![1f32; deform.bytes_read() / 4];
    let baseline_steps = (args.steps / 4).max(50);
    let mut base: [Vec<u32>; 14] = Default::default();
    let mut u_packed = vec![0f32; 3 * n + 1];
    let mut local_packed = vec![0f32; 3 * moving.rows.len()];
    let ns = elapsed_ns;
    for _ in 0..baseline_steps {
        let t = Instant::now();
        basis.apply(&d, &mut u);
        base[0].push(ns(t));
        let t = Instant::now();
        basis.apply_row_pairs(&d, &mut u);
        base[1].push(ns(t));
        let t = Instant::now();
        mimic_solve::vertex_normals(&u, &p.rig.mesh.triangles, &mut normals);
        base[2].push(ns(t));
        u_a.iter_mut().zip(&u).for_each(|(a, b)| *a = (*b).into());
        let t = Instant::now();
        fans.normals(&u_a, |v, nv| normals[v] = nv);
        base[3].push(ns(t));
        let t = Instant::now();
        fans.normals_gather(&u_a, |v, nv| normals[v] = nv);
        base[7].push(ns(t));
        u_packed
            .chunks_exact_mut(3)
            .zip(&u)
            .for_each(|(a, b)| a.copy_from_slice(&b.to_array()));
        let t = Instant::now();
        fans.normals_packed(&u_packed, |v, nv| normals[v] = nv);
        base[8].push(ns(t));
        // Each fan kernel the CPU has (one it lacks runs the best it has: same figure twice).
        let t = Instant::now();
        fans.normals_packed_by(VectorKernel::Avx2, &u_packed, |v, nv| normals[v] = nv);
        base[10].push(ns(t));
        let t = Instant::now();
        fans.normals_packed_by(VectorKernel::Avx512, &u_packed, |v, nv| normals[v] = nv);
        base[11].push(ns(t));
        let t = Instant::now();
        moving.basis.apply(&d, &mut u_rows);
        let moved = moving.rows.iter().zip(&u_rows).zip(&rest_rows);
        for (((&i, u), rest), l) in moved.zip(&mut local) {
            let q = *rest + glam::Vec3A::from(*u);
            *l = q;
            positions[i as usize] = Vec3::from(q);
        }
        base[4].push(ns(t));
        let t = Instant::now();
        deform.deform(&d, &mut local, &mut positions);
        base[5].push(ns(t));
        let t = Instant::now();
        deform.deform_packed(&d, &mut local_packed, &mut positions);
        base[9].push(ns(t));
        // Each deform kernel the CPU has (as the fan kernels above).
        let t = Instant::now();
        deform.deform_packed_by(VectorKernel::Avx2, &d, &mut local_packed, &mut positions);
        base[12].push(ns(t));
        let t = Instant::now();
        deform.deform_packed_by(VectorKernel::Avx512, &d, &mut local_packed, &mut positions);
        base[13].push(ns(t));
        let t = Instant::now();
        std::hint::black_box(read_all(std::hint::black_box(&floor_buf)));
        base[6].push(ns(t));
    }
    std::hint::black_box((&normals, &positions));
    let [
        ba,
        ba_pairs,
        bn,
        bn_fans,
        prev_deform,
        deform_alone,
        floor,
        bn_gather,
        bn_packed,
        deform_packed,
        bn_avx2,
        bn_avx512,
        deform_avx2,
        deform_avx512,
    ] = base.map(|mut v| median_p99_us(&mut v).0);
    let numpy = if args.numpy {
        Some(numpy_reference(basis, &moving.rows)?)
    } else {
        None
    };
    let vector_kernels = bench_vector_kernels(args, &p, &frames, span_us)?;
    let sessions = match args.sessions {
        Some(k) if k > 0 => {
            let basis = Arc::new(basis.clone());
            let make =
                || Retargeter::new(&p.rig, &p.layout, basis.clone(), args.pipeline.settings());
            // Long enough (about 0.2-2 s a run) that thread start and timer noise do not count.
            let steps = args.steps.max(20_000);
            let report = throughput::compare_sessions(make, &frames, span_us, steps, k)?;
            Some(serde_json::to_value(report)?)
        }
        _ => None,
    };

    let steps = samples.steps();
    let (stages, step) = samples.summary();
    let (step_m, step_p99) = (step.median_us, step.p99_us);
    let deform_m = stages.get(Stage::Deform).median_us;
    let normals_m = stages.get(Stage::Normals).median_us;
    let report = json!({
        "rig": p.rig.name,
        "vertices": n,
        "moving_vertices": p.retargeter.moving_vertex_count(),
        "controls": basis.control_count(),
        "solver": serde_json::to_value(p.solver)?,
        "basis_setup_ms": p.basis_time.as_secs_f64() * 1e3,
        "recording": args.recording.display().to_string(),
        "steps": steps,
        "stages": stages,
        "step": {"median_us": step_m, "p99_us": step_p99, "frames_per_second": step.per_second()},
        "baseline": {
            "what": "dense B d over every vertex plus full-mesh normals, same process; apply and normals_fans with the current kernels, apply_row_pairs and normals with the previous ones",
            "apply_median_us": ba,
            "apply_row_pairs_median_us": ba_pairs,
            "normals_median_us": bn,
            "normals_fans_median_us": bn_fans,
            "apply_kernel_speedup": if ba > 0.0 { ba_pairs / ba } else { 0.0 },
            "normals_kernel_speedup": if bn_fans > 0.0 { bn / bn_fans } else { 0.0 },
            "deform_speedup": if deform_m > 0.0 { ba / deform_m } else { 0.0 },
            "normals_speedup": if normals_m > 0.0 { bn / normals_m } else { 0.0 },
            "normals_fans_gather_median_us": bn_gather,
            "normals_fans_packed_median_us": bn_packed,
            "deform_kernel": format!("{:?}", VectorKernel::best_for_deform()),
            "normals_kernel": format!("{:?}", VectorKernel::best_for_normals()),
            "normals_fans_avx2_median_us": bn_avx2,
            "normals_fans_avx512_median_us": bn_avx512,
            "vector_kernel_avx512_supported": VectorKernel::Avx512.supported(),
            "deform_packed_avx2_median_us": deform_avx2,
            "deform_packed_avx512_median_us": deform_avx512,
            "deform_packed_kernel_median_us": deform_packed,
            "previous_deform_median_us": prev_deform,
            "deform_kernel_median_us": deform_alone,
        },
        "floor": {
            "what": "one vectorised read of the bytes the deform kernel reads (kept weights and rest positions), same process",
            "bytes": deform.bytes_read(),
            "kept_block_columns": deform.kept_fraction(),
            "read_median_us": floor,
        },
        "numpy": numpy,
        "vector_kernels_in_step": vector_kernels,
        "sessions": sessions,
        "load_average": {"start": load_start, "end": load_average()},
    });
    if !args.json {
        println!(
            "rig {} ({} vertices, {} moving, {} controls), basis {:.0} ms, {} steps",
            p.rig.name,
            n,
            p.retargeter.moving_vertex_count(),
            basis.control_count(),
            p.basis_time.as_secs_f64() * 1e3,
            steps
        );
        print!("{stages}");
        println!(
            "  {:<10} median {step_m:>8.1} us  p99 {step_p99:>8.1} us  ({:.0} frames/s)",
            "step",
            1e6 / step_m.max(1e-9)
        );
        println!(
            "  baseline, every vertex: apply {ba:.1} us (previous row-pair kernel {ba_pairs:.1} us), normals by fans {bn_fans:.1} us (by gathers {bn_gather:.1} us; face scatter {bn:.1} us)"
        );
        println!(
            "  A/B: normals by fans on packed 12-byte positions {bn_packed:.1} us (16-byte {bn_fans:.1} us); deform kernel with a packed copy {deform_packed:.1} us (16-byte copy: below)"
        );
        println!(
            "  fan kernels on packed positions: AVX2 {bn_avx2:.1} us, AVX-512 {bn_avx512:.1} us{}; the step uses {:?}",
            if VectorKernel::Avx512.supported() {
                ""
            } else {
                " (no AVX-512 here: the best kernel the CPU has)"
            },
            VectorKernel::best_for_normals()
        );
        println!(
            "  deform kernels on packed rows: AVX2 {deform_avx2:.1} us, AVX-512 {deform_avx512:.1} us; the step uses {:?}",
            VectorKernel::best_for_deform()
        );
        if let Some(fk) = report["vector_kernels_in_step"].as_object() {
            for (mode, what) in [
                ("warm", "turns of 200 frames"),
                ("cold", "turns of 1 frame"),
            ] {
                let at = |k: &str, f: &str| fk[mode][k][f].as_f64().unwrap_or(f64::NAN);
                println!(
                    "  in the step, {what}: deform AVX2 {:.1} us (f16 weights {:.1}), AVX-512 {:.1} us; normals AVX2 {:.1} us, AVX-512 {:.1} us; whole step AVX2 {:.1} (f16 {:.1}), AVX-512 {:.1}, defaults {:.1} us",
                    at("Avx2", "deform_median_us"),
                    at("Avx2F16", "deform_median_us"),
                    at("Avx512", "deform_median_us"),
                    at("Avx2", "normals_median_us"),
                    at("Avx512", "normals_median_us"),
                    at("Avx2", "step_median_us"),
                    at("Avx2F16", "step_median_us"),
                    at("Avx512", "step_median_us"),
                    at("Default", "step_median_us"),
                );
            }
        }
        println!(
            "  deform: previous (blocked product in index order, then add and scatter) {prev_deform:.1} us, current kernel alone {deform_alone:.1} us; floor (one read of its {} kB) {floor:.1} us",
            deform.bytes_read() / 1000
        );
        if let Some(np) = &report["numpy"].as_object() {
            println!(
                "  numpy B @ D (float32, same rows): {:.1} us (into a kept buffer {:.1} us)",
                np["matmul_median_us"].as_f64().unwrap_or(0.0),
                np["matmul_out_median_us"].as_f64().unwrap_or(0.0)
            );
        }
        if let Some(s) = &report["sessions"].as_object() {
            println!(
                "  sessions: 1 at {:.0} frames/s, {} at {:.0} frames/s ({:.2}x; {:.0} frames/s per core)",
                s["one_frames_per_second"].as_f64().unwrap_or(0.0),
                s["sessions"],
                s["many_frames_per_second"].as_f64().unwrap_or(0.0),
                s["speedup"].as_f64().unwrap_or(0.0),
                s["per_core_frames_per_second"].as_f64().unwrap_or(0.0)
            );
        }
        println!(
            "  load average {} at the start, {} at the end",
            load_start.map_or("?".into(), |l| format!("{l:.2}")),
            load_average().map_or("?".into(), |l| format!("{l:.2}"))
        );
    }
    Ok(report)
}

/// The step with each vector kernel (deform and normals) the CPU has, and with the deform's
/// weights as binary16: one retargeter per variant, taking turns on the same frames
/// ([`throughput::step_alternately`]) of 200 frames each (`warm`: each runs as one session does,
/// its data in cache) and of 1 frame (`cold`: each step finds the others' data in cache, as with
/// many sessions on a core); `None` where the CPU has no AVX2 (nothing to compare). Reports the
/// median deform and normals stages and the whole step of each (keys `Default`, each pass's own
/// default kernel; `Avx2` and `Avx512`, both passes by that kernel, the latter where the CPU has
/// it; `Avx2F16`, with binary16 weights).
fn bench_vector_kernels(
    args: &Args,
    p: &crate::cmd::setup::Prepared,
    frames: &[mimic_types::LandmarkFrame],
    span_us: i64,
) -> anyhow::Result<Option<serde_json::Value>> {
    if !VectorKernel::Avx2.supported() {
        return Ok(None);
    }
    // (name, both passes' kernel (`None`: each pass's default), binary16 weights)
    let mut variants = vec![
        ("Default", None, false),
        ("Avx2", Some(VectorKernel::Avx2), false),
        ("Avx2F16", Some(VectorKernel::Avx2), true),
    ];
    if VectorKernel::Avx512.supported() {
        variants.push(("Avx512", Some(VectorKernel::Avx512), false));
    }
    let basis = Arc::new(p.retargeter.basis().clone());
    let mut report = serde_json::Map::new();
    for (mode, turn) in [("warm", 200), ("cold", 1)] {
        let mut retargeters = variants
            .iter()
            .map(|&(_, k, f16)| {
                let mut settings = args.pipeline.settings();
                settings.deform_kernel = k;
                settings.normals_kernel = k;
                settings.f16_weights = f16;
                Retargeter::new(&p.rig, &p.layout, basis.clone(), settings)
            })
            .collect::<Result<Vec<_>, _>>()
            .context("vector kernel retargeter")?;
        let steps = args.steps.max(100);
        let samples = throughput::step_alternately(&mut retargeters, frames, span_us, steps, turn)?;
        let mut by_variant = serde_json::Map::new();
        for (&(name, _, _), mut samples) in variants.iter().zip(samples) {
            let (stages, step) = samples.summary();
            by_variant.insert(
                name.into(),
                json!({
                    "deform_median_us": stages.get(Stage::Deform).median_us,
                    "normals_median_us": stages.get(Stage::Normals).median_us,
                    "step_median_us": step.median_us,
                }),
            );
        }
        by_variant.insert("turn_frames".into(), json!(turn));
        report.insert(mode.into(), serde_json::Value::Object(by_variant));
    }
    Ok(Some(serde_json::Value::Object(report)))
}

/// CANDIDE-3 fitting speed on a recording whose layout lists correspondences (`None` otherwise):
/// its valid 3D points only (a recording keeps no pixels of depth-less points).
fn fit_throughput(recording: &mimic_capture::Recording) -> anyhow::Result<Option<FitSummary>> {
    let configs = ConfigDirs::locate(None);
    let has_correspondences = configs
        .load_layout_named(&recording.header.layout)
        .is_ok_and(|l| !l.candide_correspondences.is_empty());
    if !has_correspondences {
        return Ok(None);
    }
    let frames: Vec<CaptureFrame> = recording
        .frames
        .iter()
        .map(|f| CaptureFrame {
            landmarks: &f.frame,
            label: f.label,
            pixels: None,
        })
        .collect();
    let fit = fit_candide3(
        &configs,
        &recording.header.layout,
        &frames,
        mimic_fit::OddParts::default(),
    )?;
    Ok(Some(fit.summary))
}
