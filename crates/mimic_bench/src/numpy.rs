//! numpy's `B @ D` over the moving rows, through `tools/bench_numpy.py` (`mimic bench --numpy`):
//! an outside reference for the deform's product.

use crate::BenchError;
use mimic_solve::Basis;

/// Runs `python3 tools/bench_numpy.py` (from the working directory) on `rows` of `basis`
/// written as float32; returns the script's JSON (`matmul_median_us`, `matmul_out_median_us`).
pub fn reference(basis: &Basis, rows: &[u32]) -> Result<serde_json::Value, BenchError> {
    let m = basis.control_count();
    let mut bytes = Vec::with_capacity(rows.len() * m * 4);
    for &i in rows {
        bytes.extend(basis.row(i as usize).iter().flat_map(|w| w.to_le_bytes()));
    }
    let path = std::env::temp_dir().join(format!("mimic-bench-{}.f32", std::process::id()));
    std::fs::write(&path, &bytes)
        .map_err(|e| BenchError::Numpy(format!("writing {}: {e}", path.display())))?;
    let out = std::process::Command::new("python3")
        .arg("tools/bench_numpy.py")
        .arg(&path)
        .arg(rows.len().to_string())
        .arg(m.to_string())
        .output();
    // The rows file is scratch: a failed removal leaves a file in the temp directory, no more.
    let _ = std::fs::remove_file(&path);
    let out =
        out.map_err(|e| BenchError::Numpy(format!("running python3 tools/bench_numpy.py: {e}")))?;
    if !out.status.success() {
        return Err(BenchError::Numpy(format!(
            "tools/bench_numpy.py failed: {}",
            String::from_utf8_lossy(&out.stderr)
        )));
    }
    serde_json::from_slice(&out.stdout)
        .map_err(|e| BenchError::Numpy(format!("tools/bench_numpy.py output: {e}")))
}
