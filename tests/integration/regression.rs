//! Regression tests on recorded sequences: every shipped recording onto every shipped rig with
//! both solvers, checked for NaN and lost frames, and compared with golden per-frame metrics in
//! `tests/golden/`.
//!
//! After an intended change, re-bless with
//! `MIMIC_BLESS=1 cargo test -p mimic --test integration regression` and review the diff.

use crate::replay::{replay_json, shipped_recordings};
use crate::repo;
use serde_json::{Value, json};

/// Per-frame metrics may drift by this much (rig units) before a test fails: well above float
/// reordering noise (~1e-5) and well below any visible change (0.1 mm on a cm rig).
const ABS_TOL: f64 = 1e-2;
/// ... plus this fraction of the golden value.
const REL_TOL: f64 = 1e-2;

fn metrics_table(csv: &str) -> Value {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let cols = ["status", "top", "middle", "bottom", "max_vertex"];
    let idx: Vec<usize> = cols
        .iter()
        .map(|c| header.iter().position(|h| h == c).unwrap())
        .collect();
    let rows: Vec<Value> = lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let status: u64 = f[idx[0]].parse().unwrap();
            let vals: Vec<f64> = idx[1..]
                .iter()
                .map(|&i| (f[i].parse::<f64>().unwrap() * 1e4).round() / 1e4)
                .collect();
            json!([status, vals[0], vals[1], vals[2], vals[3]])
        })
        .collect();
    json!({"columns": cols, "frames": rows})
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= ABS_TOL + REL_TOL * b.abs()
}

#[test]
fn regression_against_golden_metrics() {
    let bless = std::env::var_os("MIMIC_BLESS").is_some();
    let dir = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    for rec in shipped_recordings() {
        for rig in ["ict-face", "candide3"] {
            for solver in ["rbf", "laplacian"] {
                let stem = std::path::Path::new(&rec)
                    .file_stem()
                    .unwrap()
                    .to_string_lossy()
                    .into_owned();
                let name = format!("{stem}__{rig}__{solver}.json");
                let metrics = dir.path().join(&name);
                let s = replay_json(&[
                    &rec,
                    "--rig",
                    rig,
                    "--solver",
                    solver,
                    "--metrics",
                    metrics.to_str().unwrap(),
                ]);
                // Sanity before comparison: no NaN anywhere, every accepted frame accounted for,
                // and nearly all of them tracked.
                let frames_in = s["frames_in"].as_u64().unwrap();
                assert!(frames_in >= 100, "{name}: {frames_in} frames");
                assert_eq!(s["frames_with_non_finite_vertices"], 0, "{name}");
                let tracked = s["tracked"].as_u64().unwrap();
                let sum =
                    tracked + s["lost"].as_u64().unwrap() + s["calibrating"].as_u64().unwrap();
                assert_eq!(sum, frames_in, "{name}");
                assert!(
                    tracked * 10 >= frames_in * 9,
                    "{name}: only {tracked} of {frames_in} tracked"
                );
                let now = json!({
                    "recording": rec, "rig": rig, "solver": solver,
                    "counts": {
                        "frames_in": s["frames_in"], "rejected": s["rejected"], "tracked": s["tracked"],
                        "lost": s["lost"], "calibrating": s["calibrating"], "filled_controls": s["filled_controls"],
                    },
                    "metrics": metrics_table(&std::fs::read_to_string(&metrics).unwrap()),
                });
                let golden_path = repo().join("tests/golden").join(&name);
                if bless {
                    std::fs::write(&golden_path, serde_json::to_string(&now).unwrap() + "\n")
                        .unwrap();
                    continue;
                }
                let Ok(text) = std::fs::read_to_string(&golden_path) else {
                    failures.push(format!("{name}: no golden file (bless with MIMIC_BLESS=1)"));
                    continue;
                };
                let golden: Value = serde_json::from_str(&text).unwrap();
                if golden["counts"] != now["counts"] {
                    failures.push(format!(
                        "{name}: counts {} != golden {}",
                        now["counts"], golden["counts"]
                    ));
                    continue;
                }
                let (g, n) = (
                    golden["metrics"]["frames"].as_array().unwrap(),
                    now["metrics"]["frames"].as_array().unwrap(),
                );
                if g.len() != n.len() {
                    failures.push(format!("{name}: {} frames != golden {}", n.len(), g.len()));
                    continue;
                }
                let mut bad = 0;
                let mut first = None;
                for (k, (gr, nr)) in g.iter().zip(n).enumerate() {
                    let same_status = gr[0] == nr[0];
                    let ok = same_status
                        && (1..5).all(|c| close(nr[c].as_f64().unwrap(), gr[c].as_f64().unwrap()));
                    if !ok {
                        bad += 1;
                        first.get_or_insert(format!("frame {k}: {nr} vs golden {gr}"));
                    }
                }
                if bad > 0 {
                    failures.push(format!(
                        "{name}: {bad} frames differ, first {}",
                        first.unwrap_or_default()
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "regressions:\n{}", failures.join("\n"));
}
