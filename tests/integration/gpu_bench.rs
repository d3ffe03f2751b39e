//! `mimic bench --gpu`: many sessions morphed in one wgpu dispatch, on lavapipe (or any Vulkan
//! adapter); and the same command with no adapter at all, which says so and exits 0.
//! With no adapter the first test fails, unless MIMIC_SKIP_GPU_TESTS is set.

use crate::{mimic, repo, text};
use std::process::Command;

#[test]
fn bench_gpu_reports_dispatch_time_and_sessions_at_60fps() {
    if std::env::var_os("MIMIC_SKIP_GPU_TESTS").is_some() {
        eprintln!("MIMIC_SKIP_GPU_TESTS is set: skipping a GPU test");
        return;
    }
    let o = mimic(&[
        "bench",
        "--gpu",
        "--rigs",
        "ict-face-3k",
        "--sessions",
        "3",
        "--gpu-dispatches",
        "3",
        "--json",
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        !out.contains("no GPU to time"),
        "no adapter (set MIMIC_SKIP_GPU_TESTS=1 to skip GPU tests): {out}"
    );
    let report: serde_json::Value = serde_json::from_str(&out).unwrap();
    let rig = &report["gpu"][0];
    assert_eq!(rig["rig"], "ict-face-3k");
    assert!(!rig["adapter"].as_str().unwrap().is_empty());
    let runs = rig["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2, "{rig}");
    for (run, sessions) in runs.iter().zip([1u64, 3]) {
        assert_eq!(run["sessions"].as_u64(), Some(sessions));
        assert_eq!(
            run["moving_rows"].as_u64(),
            Some(3000),
            "every vertex moves"
        );
        let per = run["per_dispatch_us"].as_f64().unwrap();
        assert!(per > 0.0 && per.is_finite(), "{run}");
        // sessions x 16 667 us / the per-dispatch time.
        let at60 = run["sessions_per_frame_at_60fps"].as_f64().unwrap();
        let want = sessions as f64 * 1e6 / 60.0 / per;
        assert!((at60 - want).abs() <= 1e-9 * want, "{run}");
        let by = run["timed_by"].as_str().unwrap();
        assert_eq!(
            by == "gpu timestamps",
            run["gpu_morph_us"].is_number(),
            "{run}"
        );
    }
}

#[test]
fn bench_gpu_without_an_adapter_says_so_and_exits_0() {
    // No Vulkan driver to load: the loader finds no ICD, wgpu no adapter.
    let o = Command::new(env!("CARGO_BIN_EXE_mimic"))
        .args(["bench", "--gpu", "--rigs", "ict-face-3k", "--sessions", "2"])
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .output()
        .unwrap();
    let (out, err) = text(&o);
    assert!(o.status.success(), "{out}\n{err}");
    assert!(
        out.contains("no GPU adapter") && out.contains("nothing measured"),
        "{out}\n{err}"
    );
}
