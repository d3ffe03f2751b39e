//! Solver quality against real expression meshes, as `mimic eval` measures it (docs/quality.md).
//!
//! For an expression shape on the rig's topology, the rig's controls are driven with the shape's
//! own displacements at the control vertices ([`control_displacements`]), the neutral is deformed
//! (`u = B d`, or by morph-target weights with [`MorphEval`]), and [`measure`] compares `u` with the
//! true displacement at the measured vertices, overall and per region (by
//! `RegionBands::region_at` of the rest height). `ratio = mean_error / mean_displacement`: 0 is
//! perfect, 1 is no better than leaving the neutral unchanged.

pub mod crease;
mod report;

pub use report::{JitterReport, RigUnder, ShapesReport, file_name};

use crate::{BlendshapeError, BlendshapeFitter, BlendshapeSettings};
use glam::Vec3;
use mimic_solve::Basis;
use mimic_types::{Mesh, MorphTarget, Rig};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// An expression mesh whose vertices or triangles are not the rig mesh's.
#[derive(Debug, thiserror::Error)]
#[error(
    "{}: not the rig mesh's topology ({} vertices, {} triangles; the rig mesh has {} and {})",
    path.display(), shape.0, shape.1, rig.0, rig.1
)]
pub struct TopologyMismatch {
    /// The expression mesh's file.
    pub path: PathBuf,
    /// Its vertices and triangles.
    pub shape: (usize, usize),
    /// The rig mesh's vertices and triangles.
    pub rig: (usize, usize),
}

/// Checks that `mesh` (read from `path`) has `rig`'s vertices and triangles.
pub fn check_topology(path: &Path, mesh: &Mesh, rig: &Rig) -> Result<(), TopologyMismatch> {
    if mesh.vertex_count() == rig.mesh.vertex_count() && mesh.triangles == rig.mesh.triangles {
        return Ok(());
    }
    Err(TopologyMismatch {
        path: path.to_path_buf(),
        shape: (mesh.vertex_count(), mesh.triangles.len()),
        rig: (rig.mesh.vertex_count(), rig.mesh.triangles.len()),
    })
}

/// Error statistics over a set of vertices (rig units).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Vertices measured.
    pub vertices: usize,
    /// Mean distance between deformed and true position.
    pub mean_error: f64,
    /// Nearest-rank 95th percentile of the error.
    pub p95_error: f64,
    /// Largest error.
    pub max_error: f64,
    /// Mean length of the true displacement.
    pub mean_displacement: f64,
    /// `mean_error / mean_displacement` (NaN when nothing moves).
    pub ratio: f64,
}

impl ErrorStats {
    /// Statistics of per-vertex `errors` (sorted here) and true `displacements`.
    pub fn of(errors: &mut [f64], displacements: &[f64]) -> Self {
        let n = errors.len();
        if n == 0 {
            return Self::default();
        }
        let mean_error = errors.iter().sum::<f64>() / n as f64;
        let mean_displacement = displacements.iter().sum::<f64>() / n as f64;
        errors.sort_by(f64::total_cmp);
        let p95_error = errors[((n as f64 * 0.95).ceil() as usize).clamp(1, n) - 1];
        Self {
            vertices: n,
            mean_error,
            p95_error,
            max_error: errors[n - 1],
            mean_displacement,
            ratio: if mean_displacement > 0.0 {
                mean_error / mean_displacement
            } else {
                f64::NAN
            },
        }
    }
}

/// The error of one deformed shape: over all measured vertices and per [`Region`](mimic_types::Region).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShapeError {
    /// All measured vertices.
    pub all: ErrorStats,
    /// Per region, in [`Region::ALL`](mimic_types::Region::ALL) order.
    pub regions: [ErrorStats; 3],
}

/// The control displacements that make the rig's controls follow `shape` (positions on the rig's
/// topology): `shape - rest` at each control vertex, in control order.
pub fn control_displacements(rig: &Rig, shape: &[Vec3]) -> Vec<Vec3> {
    let rest = &rig.mesh.positions;
    rig.controls
        .iter()
        .map(|c| shape[c.vertex as usize] - rest[c.vertex as usize])
        .collect()
}

/// Compares the displacement `u` with the true one (`shape - rest`) at the vertices where
/// `measured` is true.
pub fn measure(rig: &Rig, u: &[Vec3], shape: &[Vec3], measured: &[bool]) -> ShapeError {
    let rest = &rig.mesh.positions;
    let mut errors: [Vec<f64>; 4] = Default::default();
    let mut moves: [Vec<f64>; 4] = Default::default();
    for (i, p) in rest.iter().enumerate() {
        if !measured.get(i).copied().unwrap_or(false) {
            continue;
        }
        let truth = shape[i] - *p;
        let e = (u[i] - truth).length() as f64;
        let t = truth.length() as f64;
        let r = 1 + rig.regions.region_at(p.y).index();
        for slot in [0, r] {
            errors[slot].push(e);
            moves[slot].push(t);
        }
    }
    let [mut e0, mut e1, mut e2, mut e3] = errors;
    ShapeError {
        all: ErrorStats::of(&mut e0, &moves[0]),
        regions: [
            ErrorStats::of(&mut e1, &moves[1]),
            ErrorStats::of(&mut e2, &moves[2]),
            ErrorStats::of(&mut e3, &moves[3]),
        ],
    }
}

/// The per-vertex errors of [`measure`] as CSV text (`vertex,x,y,z,error,displacement`, rest
/// position and true displacement length), for plotting where the error is.
pub fn error_csv(rig: &Rig, u: &[Vec3], shape: &[Vec3], measured: &[bool]) -> String {
    use std::fmt::Write as _;
    let mut csv = String::from("vertex,x,y,z,error,displacement\n");
    for (i, p) in rig.mesh.positions.iter().enumerate() {
        if !measured.get(i).copied().unwrap_or(false) {
            continue;
        }
        let truth = shape[i] - *p;
        let _ = writeln!(
            csv,
            "{i},{},{},{},{},{}",
            p.x,
            p.y,
            p.z,
            (u[i] - truth).length(),
            truth.length()
        );
    }
    csv
}

/// The basis' noise gain: the largest row sum of `|B|` over its first `controls` columns (the
/// controls'; a rigid part's columns after them carry lengths, not control weights), i.e. how
/// much a per-control error (tracking noise, inconsistent neighbouring controls) can be amplified
/// at one vertex (1 for a partition of unity).
pub fn noise_gain(basis: &Basis, controls: usize) -> f64 {
    (0..basis.vertex_count())
        .map(|i| {
            let row = basis.row(i);
            row[..controls.min(row.len())]
                .iter()
                .map(|w| w.abs() as f64)
                .sum::<f64>()
        })
        .fold(0f64, f64::max)
}

pub use mimic_solve::stats::median;

/// Morph targets as the "solver" of an evaluation: weights fitted to a shape's control
/// displacements (no smoothing) deform the neutral, `u = sum w_k dP_k`.
#[derive(Clone, Debug)]
pub struct MorphEval {
    targets: Vec<MorphTarget>,
    leave_one_out: bool,
    ridge: f64,
}

impl MorphEval {
    /// Evaluates with `targets`; with `leave_one_out`, a target identical to the measured shape is
    /// left out of that shape's fit (so a shape cannot be matched by itself).
    pub fn new(targets: Vec<MorphTarget>, leave_one_out: bool, ridge: f64) -> Self {
        Self {
            targets,
            leave_one_out,
            ridge,
        }
    }

    /// The fitter for `shape` (positions on the rig's topology).
    pub fn fitter(&self, rig: &Rig, shape: &[Vec3]) -> Result<BlendshapeFitter, BlendshapeError> {
        let is_shape = |t: &MorphTarget| {
            t.position_deltas
                .iter()
                .zip(shape.iter().zip(&rig.mesh.positions))
                .all(|(d, (s, p))| (*s - *p - *d).abs().max_element() <= 1e-6)
        };
        let used: Vec<MorphTarget> = self
            .targets
            .iter()
            .filter(|t| !(self.leave_one_out && is_shape(t)))
            .cloned()
            .collect();
        // A still shape: no previous frame, and the ridge alone (the figures of docs/quality.md).
        let settings = BlendshapeSettings {
            ridge: self.ridge,
            l1: 0.0,
            temporal: 0.0,
            symmetry: 0.0,
            smoothing: None,
        };
        BlendshapeFitter::new(rig, &used, &settings)
    }

    /// `u = sum w_k dP_k` for the weights `fitter` fits to `d`; returns the weights by name.
    pub fn deform(fitter: &mut BlendshapeFitter, d: &[Vec3], u: &mut [Vec3]) -> Vec<(String, f32)> {
        let w = fitter.fit(d, 0).to_vec();
        fitter.displacements(&w, u);
        fitter.names().iter().cloned().zip(w).collect()
    }
}

/// One shape evaluated by [`evaluate`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Evaluated {
    /// The deformation `u` the solver made (per rig vertex).
    pub displacements: Vec<Vec3>,
    /// Its error against the shape.
    pub error: ShapeError,
    /// With morph targets: the fitted weights by target name.
    pub weights: Option<Vec<(String, f32)>>,
}

/// Drives the rig's controls with `shape`'s own control displacements, deforms the neutral with
/// `basis` (`u = B d`) or, given `blend`, with fitted morph-target weights, and measures the
/// result at the `measured` vertices.
pub fn evaluate(
    rig: &Rig,
    basis: &Basis,
    blend: Option<&MorphEval>,
    shape: &[Vec3],
    measured: &[bool],
) -> Result<Evaluated, BlendshapeError> {
    let mut d = control_displacements(rig, shape);
    // The rigid parts' columns (after the controls') at rest: the shapes measure the skin.
    d.resize(basis.control_count().max(d.len()), Vec3::ZERO);
    let mut u = vec![Vec3::ZERO; rig.mesh.vertex_count()];
    let weights = match blend {
        Some(b) => {
            let mut fitter = b.fitter(rig, shape)?;
            Some(MorphEval::deform(&mut fitter, &d, &mut u))
        }
        None => {
            basis.apply(&d, &mut u);
            None
        }
    };
    let error = measure(rig, &u, shape, measured);
    Ok(Evaluated {
        displacements: u,
        error,
        weights,
    })
}

/// The median and the largest of the shapes' overall ratios (NaN for none).
pub fn median_and_max(errors: &[ShapeError]) -> (f64, f64) {
    let mut ratios: Vec<f64> = errors.iter().map(|e| e.all.ratio).collect();
    let median = median(&mut ratios);
    (median, ratios.last().copied().unwrap_or(f64::NAN))
}

/// The evaluation in words for people: a line per shape (ratio and errors in `units`), then the
/// median and worst ratio and the noise gain, each explained.
pub fn summary_text(shapes: &[(String, ShapeError)], units: &str, noise_gain: f64) -> String {
    use std::fmt::Write as _;
    let mut t = String::new();
    let measured = shapes.first().map_or(0, |(_, e)| e.all.vertices);
    let _ = writeln!(
        t,
        "Error: the distance from the true expression at each of the {measured} measured vertices, {units}.\n\
         Ratio: mean error / mean true movement (0 is perfect, 1 is no better than leaving the face at rest)."
    );
    let width = shapes
        .iter()
        .map(|(n, _)| n.len())
        .max()
        .unwrap_or(5)
        .max(5);
    let _ = writeln!(
        t,
        "{:<width$}  {:>6}  {:>10}  {:>10}  {:>10}",
        "shape", "ratio", "mean error", "95% within", "worst"
    );
    for (name, e) in shapes {
        let a = &e.all;
        let _ = writeln!(
            t,
            "{name:<width$}  {:>6.3}  {:>10.4}  {:>10.4}  {:>10.4}",
            a.ratio, a.mean_error, a.p95_error, a.max_error
        );
    }
    let errors: Vec<ShapeError> = shapes.iter().map(|(_, e)| *e).collect();
    let (median, max) = median_and_max(&errors);
    let worst = shapes
        .iter()
        .max_by(|a, b| a.1.all.ratio.total_cmp(&b.1.all.ratio))
        .map_or("", |(n, _)| n.as_str());
    let above = shapes
        .iter()
        .filter(|(_, e)| e.all.ratio >= 1.0 || e.all.ratio.is_nan())
        .count();
    let verdict = if above == 0 {
        "every shape is better than leaving the face at rest".to_string()
    } else {
        format!(
            "{above} of {} shapes are no better than leaving the face at rest",
            shapes.len()
        )
    };
    let _ = writeln!(
        t,
        "Median ratio {median:.3}, worst {max:.3} ({worst}): {verdict}."
    );
    let _ = writeln!(
        t,
        "Noise gain {noise_gain:.2}: tracking noise at one control can show up to {noise_gain:.2} times as large at a vertex."
    );
    t
}

/// The per-region table of the shapes (developer detail): vertices, mean, p95 and largest
/// error, mean true displacement and ratio, for all measured vertices and each region.
pub fn region_table(shapes: &[(String, ShapeError)]) -> String {
    use std::fmt::Write as _;
    let mut t = format!(
        "{:<28} {:<7} {:>7} {:>9} {:>9} {:>9} {:>9} {:>6}\n",
        "shape", "region", "verts", "mean_err", "p95_err", "max_err", "mean_disp", "ratio"
    );
    for (name, e) in shapes {
        let rows = std::iter::once(("all", &e.all)).chain(
            mimic_types::Region::ALL
                .iter()
                .map(|r| r.name())
                .zip(e.regions.iter()),
        );
        for (region, s) in rows {
            let _ = writeln!(
                t,
                "{name:<28} {region:<7} {:>7} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>6.3}",
                s.vertices, s.mean_error, s.p95_error, s.max_error, s.mean_displacement, s.ratio
            );
        }
    }
    t
}

/// The jitter of replayed recordings in words for people: a line per recording (`name`, its
/// jitter, and how many tracked frames the plausibility gate held), lengths in `units`.
pub fn jitter_text(rows: &[(String, Jitter, u64)], units: &str) -> String {
    use std::fmt::Write as _;
    let mut t = format!(
        "Jitter: how much the moving vertices wobble from frame to frame (RMS second difference, {units}).\n\
         Movement: how much they move between frames (RMS first difference), for scale.\n\
         Triples: runs of three tracked frames measured. Held: tracked frames the plausibility gate held (docs/gate.md).\n"
    );
    let width = rows.iter().map(|(n, ..)| n.len()).max().unwrap_or(9).max(9);
    let _ = writeln!(
        t,
        "{:<width$}  {:>8}  {:>14}  {:>12}  {:>15}  {:>5}",
        "recording", "triples", "median jitter", "95% jitter", "median movement", "held"
    );
    for (name, j, held) in rows {
        let _ = writeln!(
            t,
            "{name:<width$}  {:>8}  {:>14.5}  {:>12.5}  {:>15.5}  {:>5}",
            j.triples,
            j.median_second_difference,
            j.p95_second_difference,
            j.median_first_difference,
            held
        );
    }
    t
}

/// Frame-to-frame jitter of a replay's deformed mesh ([`jitter`]), rig units.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Jitter {
    /// Runs of three consecutive tracked frames measured.
    pub triples: usize,
    /// Median over triples of the RMS second difference `|p(t+1) - 2 p(t) + p(t-1)|` over the
    /// measured vertices: motion that reverses from frame to frame (noise), not steady motion.
    pub median_second_difference: f64,
    /// Nearest-rank 95th percentile of the same.
    pub p95_second_difference: f64,
    /// Median over frame pairs of the RMS first difference `|p(t) - p(t-1)|` (how much the
    /// face moves at all), for scale.
    pub median_first_difference: f64,
}

/// The pipeline settings a jitter measure replays with: the defaults, the One Euro filter on
/// or off as `filter` says.
pub fn jitter_settings(filter: bool) -> crate::RetargetSettings {
    let defaults = crate::RetargetSettings::default();
    crate::RetargetSettings {
        filter: if filter { defaults.filter } else { None },
        ..defaults
    }
}

/// Replays `frames` through `r` and measures the jitter of the deformed positions at the
/// `measured` vertices (rig order); only runs of tracked frames count.
pub fn jitter<'a>(
    r: &mut crate::Retargeter,
    frames: impl IntoIterator<Item = &'a mimic_types::LandmarkFrame>,
    measured: &[bool],
) -> Jitter {
    let mut out = r.new_output();
    let idx: Vec<usize> = (0..out.positions.len())
        .filter(|&i| measured.get(i).copied().unwrap_or(false))
        .collect();
    let mut history: Vec<Vec<Vec3>> = Vec::new();
    let (mut second, mut first) = (Vec::new(), Vec::new());
    for f in frames {
        let status = r.step(f, &mut out);
        if status != crate::FrameStatus::Tracked {
            history.clear();
            continue;
        }
        history.push(idx.iter().map(|&i| out.positions[i]).collect());
        if history.len() > 3 {
            history.remove(0);
        }
        let k = idx.len().max(1) as f64;
        let n = history.len();
        if n >= 2 {
            let s: f64 = history[n - 1]
                .iter()
                .zip(&history[n - 2])
                .map(|(a, b)| f64::from(a.distance_squared(*b)))
                .sum();
            first.push((s / k).sqrt());
        }
        if n == 3 {
            let s: f64 = (0..idx.len())
                .map(|v| {
                    let a = history[2][v] - 2.0 * history[1][v] + history[0][v];
                    f64::from(a.length_squared())
                })
                .sum();
            second.push((s / k).sqrt());
        }
    }
    let pick = |v: &mut Vec<f64>, q: f64| {
        if v.is_empty() {
            return 0.0;
        }
        v.sort_by(f64::total_cmp);
        let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
        v[rank - 1]
    };
    Jitter {
        triples: second.len(),
        median_second_difference: pick(&mut second.clone(), 0.5),
        p95_second_difference: pick(&mut second, 0.95),
        median_first_difference: pick(&mut first, 0.5),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_of_known_errors() {
        // Errors 1..=100 (order does not matter): mean 50.5, nearest-rank p95 = 95, max 100;
        // displacements all 101: ratio 0.5.
        let mut errors: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        let s = ErrorStats::of(&mut errors, &[101.0; 100]);
        assert_eq!(s.vertices, 100);
        assert!((s.mean_error - 50.5).abs() < 1e-12);
        assert_eq!(s.p95_error, 95.0);
        assert_eq!(s.max_error, 100.0);
        assert!((s.ratio - 0.5).abs() < 1e-12);
        let empty = ErrorStats::of(&mut [], &[]);
        assert_eq!(empty.vertices, 0);
        assert!(ErrorStats::of(&mut [1.0], &[0.0]).ratio.is_nan());
    }

    #[test]
    fn summary_names_the_worst_shape_and_says_whether_any_is_worse_than_rest() {
        let shape = |ratio: f64| ShapeError {
            all: ErrorStats {
                vertices: 10,
                ratio,
                ..ErrorStats::default()
            },
            regions: [ErrorStats::default(); 3],
        };
        let good = [("a".to_string(), shape(0.2)), ("b".to_string(), shape(0.6))];
        let text = summary_text(&good, "cm", 1.5);
        assert!(
            text.contains("worst 0.600 (b): every shape is better"),
            "{text}"
        );
        let bad = [("a".to_string(), shape(1.2)), ("b".to_string(), shape(0.6))];
        assert!(summary_text(&bad, "cm", 1.5).contains("1 of 2 shapes are no better"));
        assert_eq!(region_table(&good).lines().count(), 1 + 2 * 4);
    }
}
