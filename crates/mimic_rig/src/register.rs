//! Template registration: every point of a layout's template (CANDIDE-3's mesh for `kinect121`,
//! MediaPipe's canonical face for `mediapipe478`, the rig's own iBUG landmark vertices for
//! `ibug68`) mapped onto a rig's mesh, which gives a dense control set (docs/rigging.md).
//!
//! Steps: (1) a similarity (Umeyama) from the landmarks template and rig share (the rig's FDP
//! controls, which the layout maps to template points); (2) a smooth non-rigid warp of the
//! similarity's residuals at those landmarks: a 3D thin-plate (biharmonic, `phi(r) = r`) spline
//! with an affine part and a small smoothing term; (3) each warped template point goes to the
//! **nearest vertex** of the rig (the solvers take vertices, so no barycentric weights are kept)
//! among the allowed ones (not frozen, and facing the same way as the template's surface
//! there); points farther than `max_distance` face units from every allowed vertex are off the
//! face and rejected, and of two points on one vertex the nearer keeps it.

use crate::RigNewError;
use crate::landmarks::Landmarks;
use glam::{DVec3, Vec3};
use mimic_types::{ControlName, Layout, Mesh, Rig, RigControl};
use std::path::Path;

/// The control sets `--controls` takes besides `mpeg4` (the 38 FDPs of the rig itself).
pub const DENSE_SETS: [&str; 3] = ["kinect121", "ibug68", "mediapipe478"];

/// Where a layout's template comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TemplateSource {
    /// Vertices `0..points` of a mesh (path relative to the `configs/` directory) are the
    /// layout's points `0..points`.
    Mesh {
        /// The mesh file, relative to `configs/`.
        file: &'static str,
        /// How many of its vertices are layout points (the rest are not skin: MediaPipe's irises).
        points: usize,
    },
    /// Point `i` is the rig's iBUG landmark vertex `i` (needs the rig's landmarks).
    RigLandmarks,
}

/// The template of a layout that has one (see [`DENSE_SETS`]).
pub fn template_source(layout: &str) -> Option<TemplateSource> {
    match layout {
        // Kinect's points 0-112 are CANDIDE-3's vertices in its numbering (113-120: unknown).
        "kinect121" => Some(TemplateSource::Mesh {
            file: "meshes/candide3/candide3.obj",
            points: 113,
        }),
        // MediaPipe's 468 mesh points are the canonical model's vertices; 468-477 are irises.
        "mediapipe478" => Some(TemplateSource::Mesh {
            file: "models/mediapipe/face_model_with_iris.obj",
            points: 468,
        }),
        "ibug68" => Some(TemplateSource::RigLandmarks),
        _ => None,
    }
}

/// Knobs of [`register`]; lengths in face units (inter-ocular distances of the rig).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegisterSettings {
    /// Smoothing of the thin-plate warp (added to its kernel's diagonal), face units; 0
    /// interpolates the landmarks exactly.
    pub smoothing: f64,
    /// A warped point farther than this from every allowed vertex is off the face.
    pub max_distance: f32,
    /// A vertex is a candidate only if its normal and the template's normal at the point have
    /// at least this dot product (keeps lip points out of the mouth socket); ignored without
    /// template normals.
    pub min_normal_dot: f32,
}

impl Default for RegisterSettings {
    fn default() -> Self {
        Self {
            smoothing: 0.01,
            max_distance: 0.1,
            min_normal_dot: 0.3,
        }
    }
}

/// A template: points (and, for a mesh, their vertex normals) with its landmark pairs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Template {
    /// The template's points, by layout point index.
    pub points: Vec<Vec3>,
    /// Unit normals of the points, or empty (then no facing test).
    pub normals: Vec<Vec3>,
}

impl Template {
    /// The first `count` vertices of `mesh`, with area-weighted normals over all its triangles.
    pub fn from_mesh(mesh: &Mesh, count: usize) -> Self {
        let normals = vertex_normals(&mesh.positions, &mesh.triangles);
        let count = count.min(mesh.vertex_count());
        Self {
            points: mesh.positions[..count].to_vec(),
            normals: normals[..count].to_vec(),
        }
    }
}

/// One template point placed on the rig.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// The template (layout) point.
    pub point: usize,
    /// The rig vertex it lands on.
    pub vertex: u32,
    /// Distance from the warped point to that vertex, face units.
    pub residual: f32,
}

/// Why a template point got no vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rejection {
    /// No allowed vertex within `max_distance` (face units: the nearest's distance).
    OffFace(f32),
    /// Its vertex went to a nearer point (that point's index).
    Duplicate(usize),
}

/// The result of [`register`].
#[derive(Clone, Debug, PartialEq)]
pub struct Registration {
    /// Points that landed on a vertex, by point index.
    pub placed: Vec<Placement>,
    /// Points that did not, with why.
    pub rejected: Vec<(usize, Rejection)>,
    /// RMS distance of the landmarks after the similarity alone, face units.
    pub similarity_rms: f32,
    /// RMS distance of the landmarks after the warp, face units (0 without smoothing).
    pub warp_rms: f32,
    /// Every template point after similarity and warp, in rig coordinates.
    pub warped: Vec<Vec3>,
}

/// Maps every template point onto `mesh`: similarity and thin-plate warp fitted on `pairs`
/// (template position, rig position), then the nearest allowed vertex (`allowed[v]`; vertex
/// normals of `mesh` are compared with the template's). `iod` is the rig's face unit.
pub fn register(
    template: &Template,
    pairs: &[(Vec3, Vec3)],
    mesh: &Mesh,
    allowed: &[bool],
    iod: f32,
    settings: &RegisterSettings,
) -> Result<Registration, RigNewError> {
    if pairs.len() < 4 {
        return Err(RigNewError::Frame(format!(
            "registration needs at least 4 landmarks shared by template and rig, got {}",
            pairs.len()
        )));
    }
    let (src, dst): (Vec<Vec3>, Vec<Vec3>) = pairs.iter().copied().unzip();
    let sim = mimic_solve::kabsch::fit_similarity(&src, &dst, true).ok_or_else(|| {
        RigNewError::Frame("the shared landmarks are degenerate (on one line)".into())
    })?;
    let moved: Vec<Vec3> = src.iter().map(|p| sim.apply(*p)).collect();
    let rms = |a: &[Vec3]| {
        (a.iter()
            .zip(&dst)
            .map(|(p, q)| f64::from(p.distance_squared(*q)))
            .sum::<f64>()
            / a.len() as f64)
            .sqrt() as f32
            / iod
    };
    let similarity_rms = rms(&moved);
    let warp = ThinPlate::fit(&moved, &dst, settings.smoothing * f64::from(iod))?;
    let warp_rms = rms(&moved.iter().map(|p| warp.apply(*p)).collect::<Vec<_>>());
    let warped: Vec<Vec3> = template
        .points
        .iter()
        .map(|p| warp.apply(sim.apply(*p)))
        .collect();
    let normals = vertex_normals(&mesh.positions, &mesh.triangles);
    let mut best: Vec<(usize, Option<(u32, f32)>)> = Vec::with_capacity(warped.len());
    for (i, w) in warped.iter().enumerate() {
        let facing = template.normals.get(i).map(|n| sim.rotation * *n);
        let near = nearest_allowed(
            *w,
            facing,
            &mesh.positions,
            &normals,
            allowed,
            settings.min_normal_dot,
        );
        best.push((i, near.map(|(v, d)| (v, d / iod))));
    }
    let mut rejected = Vec::new();
    let mut owner: std::collections::HashMap<u32, (usize, f32)> = Default::default();
    for &(i, near) in &best {
        match near {
            Some((v, d)) if d <= settings.max_distance => match owner.get(&v) {
                Some(&(j, dj)) if dj <= d => rejected.push((i, Rejection::Duplicate(j))),
                Some(&(j, _)) => {
                    rejected.push((j, Rejection::Duplicate(i)));
                    owner.insert(v, (i, d));
                }
                None => {
                    owner.insert(v, (i, d));
                }
            },
            Some((_, d)) => rejected.push((i, Rejection::OffFace(d))),
            None => rejected.push((i, Rejection::OffFace(f32::INFINITY))),
        }
    }
    let mut placed: Vec<Placement> = owner
        .into_iter()
        .map(|(vertex, (point, residual))| Placement {
            point,
            vertex,
            residual,
        })
        .collect();
    placed.sort_by_key(|p| p.point);
    rejected.sort_by_key(|r| r.0);
    Ok(Registration {
        placed,
        rejected,
        similarity_rms,
        warp_rms,
        warped,
    })
}

/// The landmarks template and rig share: each FDP control of the rig that `layout` maps,
/// as (mean of its template points, the rig vertex's position). Template points outside
/// `template` are skipped.
pub fn fdp_pairs(rig: &Rig, layout: &Layout, template: &Template) -> Vec<(Vec3, Vec3)> {
    rig.controls
        .iter()
        .filter_map(|c| {
            let f = c.fdp.as_fdp()?;
            let points = &layout.controls.iter().find(|l| l.fdp == f)?.points;
            let at: Option<Vec<Vec3>> = points
                .iter()
                .map(|&p| template.points.get(p).copied())
                .collect();
            let at = at?;
            let mean = at.iter().fold(Vec3::ZERO, |a, p| a + *p) / at.len().max(1) as f32;
            Some((mean, *rig.mesh.positions.get(c.vertex as usize)?))
        })
        .collect()
}

/// The rig's face unit: the distance between its eye centres (FDPs 3.7 + 3.11, 3.8 + 3.12).
pub fn rig_iod(rig: &Rig) -> Option<f32> {
    crate::check::rig_frame(rig).map(|f| f.iod)
}

/// A dense control set for `rig` (an FDP rig, whose controls give the shared landmarks) from
/// `layout`'s template ([`template_source`]; mesh templates are read from `configs`): the
/// controls `layout:i` at the registered vertices, each in the region of its height, and the
/// registration (for its residuals and rejections). `landmarks` are needed for `ibug68`.
pub fn dense_controls(
    rig: &Rig,
    layout: &Layout,
    configs: &Path,
    landmarks: Option<&Landmarks>,
    settings: &RegisterSettings,
) -> Result<(Vec<RigControl>, Registration), RigNewError> {
    let source = template_source(&layout.name).ok_or_else(|| {
        RigNewError::Frame(format!(
            "layout `{}` has no template to register (dense sets: {})",
            layout.name,
            DENSE_SETS.join(", ")
        ))
    })?;
    let iod = rig_iod(rig).ok_or_else(|| {
        RigNewError::Frame(format!(
            "rig `{}` lacks the eye-corner FDPs (3.7, 3.8, 3.11, 3.12) or mouth corners (8.3, 8.4) that place a template",
            rig.name
        ))
    })?;
    let allowed: Vec<bool> = rig.frozen.iter().map(|f| !f).collect();
    let registration = match source {
        TemplateSource::Mesh { file, points } => {
            let mesh = mimic_assets::load_obj(&configs.join(file))?;
            let template = Template::from_mesh(&mesh, points);
            let pairs = fdp_pairs(rig, layout, &template);
            register(&template, &pairs, &rig.mesh, &allowed, iod, settings)?
        }
        TemplateSource::RigLandmarks => {
            let marks = landmarks.ok_or_else(|| {
                RigNewError::Frame(format!(
                    "the `{}` set is the rig's own iBUG landmark vertices: give --landmarks",
                    layout.name
                ))
            })?;
            landmark_registration(rig, marks, &allowed)
        }
    };
    let controls = registration
        .placed
        .iter()
        .filter_map(|p| {
            let name = ControlName::point(&layout.name, p.point)?;
            let y = rig.mesh.positions.get(p.vertex as usize)?.y;
            Some(RigControl {
                fdp: name,
                vertex: p.vertex,
                region: rig.regions.region_at(y),
            })
        })
        .collect();
    Ok((controls, registration))
}

/// The landmarks control set `set` registers from, for the rig file `rig_path`: read only for
/// `ibug68`, from `landmarks` or else `<rig>.landmarks.json` beside the rig file when it exists.
pub fn control_landmarks(
    rig_path: &Path,
    set: &str,
    landmarks: Option<&Path>,
) -> Result<Option<Landmarks>, RigNewError> {
    let beside = rig_path.with_extension("landmarks.json");
    let path = landmarks.or_else(|| beside.is_file().then_some(beside.as_path()));
    match (path, set) {
        (Some(p), "ibug68") => Ok(Some(crate::load_landmarks(p, Default::default())?)),
        _ => Ok(None),
    }
}

/// A rig's controls by set name: `mpeg4` keeps the rig's own (FDP) controls and returns
/// `None`; a layout name of [`DENSE_SETS`] replaces them with that layout's registered points
/// ([`dense_controls`]; the layout is read from `configs/layouts/`) and returns the registration.
pub fn apply_control_set(
    rig: &mut Rig,
    set: &str,
    configs: &Path,
    landmarks: Option<&Landmarks>,
    settings: &RegisterSettings,
) -> Result<Option<Registration>, RigNewError> {
    if set == "mpeg4" {
        return Ok(None);
    }
    // `SET@N`: N of the set's controls, spread by farthest-point sampling.
    let (set, keep) = match set.split_once('@') {
        Some((s, n)) => (
            s,
            Some(n.parse::<usize>().ok().filter(|n| *n >= 4).ok_or_else(|| {
                RigNewError::Frame(format!("control set `{set}`: `@N` needs a count N >= 4"))
            })?),
        ),
        None => (set, None),
    };
    if !DENSE_SETS.contains(&set) {
        return Err(RigNewError::Frame(format!(
            "control set `{set}`: use mpeg4 (the rig's 38 FDPs) or one of {}",
            DENSE_SETS.join(", ")
        )));
    }
    let layout = mimic_assets::load_layout(&configs.join("layouts").join(format!("{set}.toml")))?;
    let (mut controls, registration) = dense_controls(rig, &layout, configs, landmarks, settings)?;
    if let Some(n) = keep {
        let at: Vec<Vec3> = controls
            .iter()
            .map(|c| rig.mesh.positions[c.vertex as usize])
            .collect();
        let mut picked = farthest_points(&at, n);
        picked.sort_unstable();
        controls = picked.into_iter().map(|i| controls[i].clone()).collect();
    }
    rig.controls = controls;
    Ok(Some(registration))
}

/// `n` of `points` (all if fewer) by farthest-point sampling from the first: each next one is
/// the point farthest from those picked so far (ties: the lowest index). Indices into `points`.
pub fn farthest_points(points: &[Vec3], n: usize) -> Vec<usize> {
    if points.is_empty() {
        return Vec::new();
    }
    let mut picked = vec![0usize];
    let mut gap: Vec<f32> = points
        .iter()
        .map(|p| p.distance_squared(points[0]))
        .collect();
    while picked.len() < n.min(points.len()) {
        let mut best = 0;
        for (i, g) in gap.iter().enumerate() {
            if *g > gap[best] {
                best = i;
            }
        }
        picked.push(best);
        for (g, p) in gap.iter_mut().zip(points) {
            *g = g.min(p.distance_squared(points[best]));
        }
    }
    picked
}

/// `text` (a rig file) with its `[[controls]]` tables replaced by `controls`, written as
/// `control = "layout:i"` (no per-control note, so a 464-point set stays a small file), after a
/// comment with the registration's residuals (face units). Everything else (comments, settings,
/// `[look]`, morph targets, relative paths) is kept.
pub fn replace_controls_toml(
    text: &str,
    controls: &[RigControl],
    registration: &Registration,
) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let mut in_controls = false;
    // Comment and blank lines inside the controls: dropped with them, unless a table other
    // than a control follows, whose comment they are.
    let mut held = String::new();
    for line in text.lines() {
        let head = line.trim_start();
        if head.starts_with('[') {
            in_controls = head.starts_with("[[controls]]");
            if !in_controls {
                let gap = out.is_empty() || out.ends_with("\n\n");
                out.push_str(if gap {
                    held.trim_start_matches('\n')
                } else {
                    &held
                });
            }
            held.clear();
        }
        if !in_controls {
            out.push_str(line);
            out.push('\n');
        } else if head.is_empty() || head.starts_with('#') {
            held.push_str(line);
            held.push('\n');
        } else {
            held.clear();
        }
    }
    while out.ends_with("\n\n") {
        out.pop();
    }
    let mut residuals: Vec<f32> = registration.placed.iter().map(|p| p.residual).collect();
    residuals.sort_by(f32::total_cmp);
    let median = residuals.get(residuals.len() / 2).copied().unwrap_or(0.0);
    let max = residuals.last().copied().unwrap_or(0.0);
    let _ = writeln!(
        out,
        "\n# {} controls registered from the layout's template (docs/rigging.md, \"Dense control sets\"): each the\n# nearest allowed vertex to its warped template point, {median:.3} IOD away at the median, {max:.3} at most;\n# {} template points rejected (off the face, or sharing a vertex with a nearer point).",
        controls.len(),
        registration.rejected.len()
    );
    for c in controls {
        let _ = write!(
            out,
            "\n[[controls]]\ncontrol = \"{}\"\nvertex = {}\nregion = \"{}\"\n",
            c.fdp,
            c.vertex,
            c.region.name(),
        );
    }
    out
}

/// `ibug68`: point i is landmark vertex i itself (frozen or missing ones rejected).
fn landmark_registration(rig: &Rig, marks: &Landmarks, allowed: &[bool]) -> Registration {
    let mut placed = Vec::new();
    let mut rejected = Vec::new();
    let mut warped = Vec::new();
    let mut seen: std::collections::HashMap<u32, usize> = Default::default();
    for (i, v) in marks.vertex.iter().enumerate() {
        let at = v.and_then(|v| rig.mesh.positions.get(v as usize).map(|p| (v, *p)));
        warped.push(at.map_or(Vec3::NAN, |(_, p)| p));
        match at {
            Some((v, _)) if allowed.get(v as usize).copied().unwrap_or(false) => {
                if let Some(&j) = seen.get(&v) {
                    rejected.push((i, Rejection::Duplicate(j)));
                } else {
                    seen.insert(v, i);
                    placed.push(Placement {
                        point: i,
                        vertex: v,
                        residual: 0.0,
                    });
                }
            }
            _ => rejected.push((i, Rejection::OffFace(f32::INFINITY))),
        }
    }
    Registration {
        placed,
        rejected,
        similarity_rms: 0.0,
        warp_rms: 0.0,
        warped,
    }
}

/// The nearest vertex to `w` among the `allowed` ones whose normal has a dot product of at
/// least `min_dot` with `facing` (any normal without `facing`), and its distance: how a
/// registered template point becomes a vertex (the normal test keeps lip points out of the
/// mouth socket behind them).
pub fn nearest_allowed(
    w: Vec3,
    facing: Option<Vec3>,
    positions: &[Vec3],
    normals: &[Vec3],
    allowed: &[bool],
    min_dot: f32,
) -> Option<(u32, f32)> {
    let mut near: Option<(u32, f32)> = None;
    for (v, p) in positions.iter().enumerate() {
        if !allowed.get(v).copied().unwrap_or(false) {
            continue;
        }
        if let Some(f) = facing
            && f.dot(normals.get(v).copied().unwrap_or(Vec3::ZERO)) < min_dot
        {
            continue;
        }
        let d = p.distance_squared(w);
        if near.is_none_or(|(_, b)| d < b) {
            near = Some((v as u32, d));
        }
    }
    near.map(|(v, d)| (v, d.sqrt()))
}

/// Area-weighted unit vertex normals (zero for vertices in no triangle).
pub fn vertex_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|v| v as usize);
        let (Some(pa), Some(pb), Some(pc)) = (positions.get(a), positions.get(b), positions.get(c))
        else {
            continue;
        };
        let face = (*pb - *pa).cross(*pc - *pa);
        for v in [a, b, c] {
            n[v] += face;
        }
    }
    n.iter().map(|v| v.normalize_or_zero()).collect()
}

/// A 3D thin-plate warp `x + sum_i w_i |x - c_i| + A [1, x]`, fitted to move `c_i` to `y_i`.
struct ThinPlate {
    centres: Vec<DVec3>,
    weights: Vec<DVec3>,
    affine: [DVec3; 4],
}

impl ThinPlate {
    /// Fits the warp taking `from[i]` near `to[i]` (exactly with `smoothing` 0).
    fn fit(from: &[Vec3], to: &[Vec3], smoothing: f64) -> Result<Self, RigNewError> {
        let k = from.len();
        let n = k + 4;
        let centres: Vec<DVec3> = from.iter().map(|p| p.as_dvec3()).collect();
        let mut a = vec![0f64; n * n];
        let mut rhs = vec![DVec3::ZERO; n];
        for i in 0..k {
            for j in 0..k {
                a[i * n + j] = centres[i].distance(centres[j]);
            }
            a[i * n + i] += smoothing;
            let row = [1.0, centres[i].x, centres[i].y, centres[i].z];
            for (c, v) in row.iter().enumerate() {
                a[i * n + k + c] = *v;
                a[(k + c) * n + i] = *v;
            }
            rhs[i] = to[i].as_dvec3() - centres[i];
        }
        let x = solve_dense(&mut a, &mut rhs, n).ok_or_else(|| {
            RigNewError::Frame(
                "the warp's landmark system is singular (landmarks coincide or lie on a plane)"
                    .into(),
            )
        })?;
        Ok(Self {
            centres,
            weights: x[..k].to_vec(),
            affine: [x[k], x[k + 1], x[k + 2], x[k + 3]],
        })
    }

    fn apply(&self, p: Vec3) -> Vec3 {
        let q = p.as_dvec3();
        let mut u =
            self.affine[0] + self.affine[1] * q.x + self.affine[2] * q.y + self.affine[3] * q.z;
        for (c, w) in self.centres.iter().zip(&self.weights) {
            u += *w * c.distance(q);
        }
        (q + u).as_vec3()
    }
}

/// Solves `a x = rhs` (`n x n`, row-major, three right-hand sides as `DVec3`) by Gaussian
/// elimination with partial pivoting; `None` if singular.
fn solve_dense(a: &mut [f64], rhs: &mut [DVec3], n: usize) -> Option<Vec<DVec3>> {
    let scale = a
        .iter()
        .fold(0f64, |m, v| m.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    for col in 0..n {
        let pivot =
            (col..n).max_by(|&r, &s| a[r * n + col].abs().total_cmp(&a[s * n + col].abs()))?;
        if a[pivot * n + col].abs() <= 1e-12 * scale {
            return None;
        }
        if pivot != col {
            for c in 0..n {
                a.swap(pivot * n + c, col * n + c);
            }
            rhs.swap(pivot, col);
        }
        let d = a[col * n + col];
        for r in col + 1..n {
            let f = a[r * n + col] / d;
            if f == 0.0 {
                continue;
            }
            for c in col..n {
                a[r * n + c] -= f * a[col * n + c];
            }
            let sub = rhs[col] * f;
            rhs[r] -= sub;
        }
    }
    let mut x = vec![DVec3::ZERO; n];
    for r in (0..n).rev() {
        let mut s = rhs[r];
        for c in r + 1..n {
            s -= x[c] * a[r * n + c];
        }
        x[r] = s / a[r * n + r];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaced_controls_keep_the_comment_of_the_table_after_them() {
        let text = "name = \"r\"\n\n[[controls]]\nfdp = \"2.1\"\nvertex = 1\n# inside\nregion = \"bottom\"\n\n# The expressions.\n[[morph_targets]]\nname = \"a\"\n";
        let registration = Registration {
            placed: Vec::new(),
            rejected: Vec::new(),
            similarity_rms: 0.0,
            warp_rms: 0.0,
            warped: Vec::new(),
        };
        let out = replace_controls_toml(text, &[], &registration);
        assert!(
            out.starts_with(
                "name = \"r\"\n\n# The expressions.\n[[morph_targets]]\nname = \"a\"\n"
            ),
            "{out}"
        );
        assert!(!out.contains("inside") && !out.contains("fdp"), "{out}");
    }

    /// A bumpy 21 x 21 sheet (spacing 1), facing +z.
    fn sheet() -> Mesh {
        let side = 21;
        let mut positions = Vec::new();
        for y in 0..side {
            for x in 0..side {
                let (fx, fy) = (x as f32 - 10.0, y as f32 - 10.0);
                positions.push(Vec3::new(fx, fy, 4.0 * (-(fx * fx + fy * fy) / 60.0).exp()));
            }
        }
        let mut triangles = Vec::new();
        for y in 0..side - 1 {
            for x in 0..side - 1 {
                let i = (y * side + x) as u32;
                let s = side as u32;
                triangles.push([i, i + 1, i + s + 1]);
                triangles.push([i, i + s + 1, i + s]);
            }
        }
        Mesh {
            positions,
            triangles,
            ..Default::default()
        }
    }

    #[test]
    fn a_warped_copy_registers_back_onto_its_own_vertices() {
        let target = sheet();
        // The template: the same sheet under a known smooth warp (a bend of up to 0.3 spacings,
        // a thin-plate spline can follow it) and a known similarity (scale 0.02, a turn, a shift).
        let rot = glam::Quat::from_euler(glam::EulerRot::YXZ, 0.4, -0.2, 0.1);
        let warp = |p: Vec3| {
            p + Vec3::new(
                0.3 * (p.y / 7.0).sin(),
                0.2 * (p.x / 9.0).cos(),
                0.3 * (p.x * p.y / 80.0),
            )
        };
        let shift = Vec3::new(0.5, -1.0, 2.0);
        let forward = |p: Vec3| rot * (warp(p) * 0.02) + shift;
        let template_mesh = Mesh {
            positions: target.positions.iter().map(|p| forward(*p)).collect(),
            ..target.clone()
        };
        let template = Template::from_mesh(&template_mesh, template_mesh.vertex_count());
        // 49 landmarks on a 7 x 7 lattice of the sheet.
        let pairs: Vec<(Vec3, Vec3)> = (0..7)
            .flat_map(|j| (0..7).map(move |i| (j * 3 + 1) * 21 + i * 3 + 1))
            .map(|v| (template.points[v], target.positions[v]))
            .collect();
        let allowed = vec![true; target.vertex_count()];
        let settings = RegisterSettings {
            smoothing: 0.0,
            max_distance: 1.0,
            ..RegisterSettings::default()
        };
        let r = register(&template, &pairs, &target, &allowed, 1.0, &settings).unwrap();
        // The similarity alone cannot undo the bend; the warp meets the landmarks exactly.
        assert!(r.similarity_rms > 0.05, "{}", r.similarity_rms);
        assert!(r.warp_rms < 1e-4, "{}", r.warp_rms);
        // Every point inside the landmark lattice (vertices 1..=19 in x and y) is recovered:
        // its warped position is within half a spacing of its own vertex.
        let mut inside = 0;
        for p in &r.placed {
            let (x, y) = (p.point % 21, p.point / 21);
            if (1..=19).contains(&x) && (1..=19).contains(&y) {
                inside += 1;
                assert_eq!(p.vertex as usize, p.point, "residual {}", p.residual);
                assert!(p.residual < 0.5);
            }
        }
        assert_eq!(inside, 19 * 19);
    }

    #[test]
    fn farthest_points_spread_over_a_line() {
        let line: Vec<Vec3> = (0..11).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        // From 0: the far end 10, then the middle 5.
        let picked = farthest_points(&line, 3);
        assert_eq!(picked, vec![0, 10, 5]);
        assert_eq!(farthest_points(&line, 50).len(), 11);
        assert!(farthest_points(&[], 3).is_empty());
    }

    #[test]
    fn points_off_the_allowed_surface_are_rejected_and_duplicates_resolved() {
        let target = sheet();
        let template = Template {
            points: vec![
                target.positions[220],
                target.positions[221] + Vec3::new(0.3, 0.0, 0.0),
                target.positions[220] + Vec3::new(0.1, 0.0, 0.05),
                target.positions[0] + Vec3::new(0.0, 0.0, 5.0),
            ],
            normals: vec![],
        };
        let pairs: Vec<(Vec3, Vec3)> = [0usize, 20, 420, 440, 110]
            .iter()
            .map(|&v| (target.positions[v], target.positions[v]))
            .collect();
        let mut allowed = vec![true; target.vertex_count()];
        allowed[221] = false;
        let settings = RegisterSettings {
            smoothing: 0.0,
            max_distance: 1.0,
            ..RegisterSettings::default()
        };
        let r = register(&template, &pairs, &target, &allowed, 1.0, &settings).unwrap();
        assert_eq!(r.placed.len(), 2, "{r:?}");
        assert_eq!((r.placed[0].point, r.placed[0].vertex), (0, 220));
        // 221 is not allowed: point 1 goes to the nearest allowed vertex, 222.
        assert_eq!((r.placed[1].point, r.placed[1].vertex), (1, 222));
        assert!(
            matches!(r.rejected[0], (2, Rejection::Duplicate(0))),
            "{:?}",
            r.rejected
        );
        assert!(matches!(r.rejected[1], (3, Rejection::OffFace(d)) if d > 4.0));
    }
}
