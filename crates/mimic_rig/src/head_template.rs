//! `mimic rig new` without `--landmarks`: the 68 iBUG landmark vertices of a face mesh found by
//! registering a template head whose landmarks are known (the ICT head) onto it
//! (docs/rigging.md, "Without --landmarks").
//!
//! Steps: (1) the template's face area in its face frame (IOD units), thinned to nodes about
//! `spacing` apart (every landmark vertex kept), joined by a k-nearest-neighbour graph; (2) the
//! target's orientation: a probe for each of the 24 axis-aligned turns ([`Orientation::all`]):
//! facing that way, its nose tip is its frontmost vertex, its scale its width at the nose tip's
//! height against the template's, and a short similarity ICP of every `probe_stride`-th node
//! from there is scored by its coverage (then RMS); the best turn is kept (`probe_orientations`);
//! (3) coarse starts for a few turns about that up axis (and those of probes nearly as good)
//! and scales, each refined by trimmed
//! point-to-plane similarity ICP, the start covering most of the template kept ([`crate::icp`]);
//! (4) non-rigid ICP
//! of the nodes with stiffness steps ([`crate::nonrigid`]); (5) each template landmark goes to
//! the nearest target vertex facing its way ([`crate::register::nearest_allowed`]).

use crate::RigNewError;
use crate::frame::FaceFrame;
use crate::icp::{IcpSettings, RigidFit, similarity_icp};
use crate::landmarks::{IBUG_POINTS, Landmarks, Numbering, load_landmarks};
use crate::nearest::Surface;
use crate::new::landmark_frame;
use crate::nonrigid::{NonRigidSettings, knn_graph, nonrigid_icp};
use crate::register::{nearest_allowed, vertex_normals};
use glam::{Quat, Vec3};
use mimic_assets::Orientation;
use mimic_types::{HeadPose, Mesh};
use std::path::Path;

/// The ICT head's neutral mesh, relative to `configs/`.
pub const ICT_MESH: &str = "meshes/ict-facekit/generic_neutral_mesh.obj";

/// The ICT head's 68 iBUG landmark vertices (ICT-FaceKit's `idx_to_landmark_verts`), relative
/// to `configs/`.
pub const ICT_LANDMARKS: &str = "rigs/ict-face.landmarks.json";

/// The ICT head's face area: vertices 0-9408 (`configs/rigs/ict-face.toml`): the face without
/// the back of the head, scalp, ears and neck (9409-11247), the mouth and eye sockets
/// (11248-14061) and the inner parts (teeth, eyeballs, lashes: 14062-26718).
pub const ICT_FACE_AREA: std::ops::Range<usize> = 0..9409;

/// A template head: a mesh, its iBUG landmark vertices and the vertices that take part in the
/// registration (its face area).
#[derive(Clone, Debug)]
pub struct TemplateHead {
    /// The mesh.
    pub mesh: Mesh,
    /// Its landmark vertices (all inside `face_area`).
    pub landmarks: Landmarks,
    /// Vertices registered onto the target.
    pub face_area: Vec<bool>,
}

impl TemplateHead {
    /// The ICT head ([`ICT_MESH`], [`ICT_LANDMARKS`], [`ICT_FACE_AREA`]) from `configs`.
    pub fn ict(configs: &Path) -> Result<Self, RigNewError> {
        let mesh = mimic_assets::load_obj(&configs.join(ICT_MESH))?;
        let landmarks = load_landmarks(&configs.join(ICT_LANDMARKS), Numbering::default())?;
        let face_area = (0..mesh.vertex_count())
            .map(|v| ICT_FACE_AREA.contains(&v))
            .collect();
        Ok(Self {
            mesh,
            landmarks,
            face_area,
        })
    }
}

/// Knobs of [`find_landmarks`]; lengths in the template's face units (IOD).
#[derive(Clone, Debug, PartialEq)]
pub struct FindSettings {
    /// Spacing of the template nodes.
    pub spacing: f32,
    /// Neighbours of each node in the stiffness graph.
    pub neighbours: usize,
    /// Probe the 24 axis-aligned orientations first (else the target is taken as y up, +z
    /// forward).
    pub any_orientation: bool,
    /// ICP rounds of each orientation probe.
    pub probe_rounds: usize,
    /// Each probe fits every this many template nodes.
    pub probe_stride: usize,
    /// The coarse starts also run in each orientation whose probe covers at least this
    /// fraction of the best probe's coverage (at most 2 orientations in all).
    pub close_probe: f32,
    /// Coarse starts: turns about the target's up axis, degrees.
    pub yaws: Vec<f32>,
    /// Coarse starts: factors on the scale from the widths at nose height.
    pub scales: Vec<f32>,
    /// Target pieces (connected by triangles) with at least this fraction of the largest
    /// piece's vertices are matched; smaller ones (eyeballs, teeth, lashes) are not.
    pub min_piece: f32,
    /// The similarity ICP.
    pub icp: IcpSettings,
    /// The non-rigid ICP.
    pub nonrigid: NonRigidSettings,
    /// The final nearest-vertex rule's normal agreement (as [`crate::register`]'s).
    pub min_normal_dot: f32,
}

impl Default for FindSettings {
    fn default() -> Self {
        Self {
            spacing: 0.05,
            neighbours: 6,
            any_orientation: true,
            probe_rounds: 8,
            probe_stride: 3,
            close_probe: 0.8,
            yaws: vec![-30.0, 0.0, 30.0],
            scales: vec![0.75, 0.9, 1.05],
            min_piece: 0.25,
            icp: IcpSettings::default(),
            nonrigid: NonRigidSettings::default(),
            min_normal_dot: 0.3,
        }
    }
}

/// Landmarks found by [`find_landmarks`], with how well the template fitted.
#[derive(Clone, Debug, PartialEq)]
pub struct FoundLandmarks {
    /// The landmark vertices on the target.
    pub landmarks: Landmarks,
    /// The best similarity (template face units to target coordinates; its scale is the
    /// target's IOD in its units, as far as the similarity sees it).
    pub rigid: RigidFit,
    /// Coarse starts tried.
    pub starts: usize,
    /// The target's orientation the starts were made in.
    pub orientation: Orientation,
    /// Template nodes.
    pub nodes: usize,
    /// Fraction of the nodes matched after the non-rigid fit.
    pub coverage: f32,
    /// RMS point-to-plane distance of the matched nodes after the non-rigid fit, IOD.
    pub residual: f32,
    /// Per iBUG point: distance from its registered place to its vertex, IOD (NaN: none).
    pub landmark_distance: [f32; IBUG_POINTS],
}

impl FoundLandmarks {
    /// Why the fit probably failed, if it looks so: the similarity covered less than 30% of
    /// the template, the non-rigid fit matched less than 35% of it or left more than 0.03 IOD
    /// RMS, or a landmark is more than 0.25 IOD from its vertex (MediaPipe's face mask, fitted
    /// well, gives 42%, 45%, 0.015 and 0.18: the mask is smaller than ICT's face area and
    /// coarse).
    pub fn doubt(&self) -> Option<String> {
        let worst = self
            .landmark_distance
            .iter()
            .copied()
            .filter(|d| d.is_finite())
            .fold(0.0, f32::max);
        let mut why = Vec::new();
        if self.rigid.coverage < 0.3 {
            why.push(format!(
                "the similarity covers {:.0}% of the template's face",
                100.0 * self.rigid.coverage
            ));
        }
        if self.coverage < 0.35 {
            why.push(format!(
                "the non-rigid fit matches {:.0}% of it",
                100.0 * self.coverage
            ));
        }
        if self.residual > 0.03 {
            why.push(format!("its residual is {:.3} IOD", self.residual));
        }
        if worst > 0.25 {
            why.push(format!("a landmark lies {worst:.3} IOD from its vertex"));
        }
        (!why.is_empty()).then(|| why.join(", "))
    }
}

/// The template's nodes in its face frame: vertex numbers, positions, normals, and the node of
/// each landmark.
struct Nodes {
    vertex: Vec<u32>,
    at: Vec<Vec3>,
    normal: Vec<Vec3>,
    landmark: [Option<usize>; IBUG_POINTS],
}

fn template_nodes(
    template: &TemplateHead,
    frame: &FaceFrame,
    spacing: f32,
) -> Result<Nodes, RigNewError> {
    let normals = vertex_normals(&template.mesh.positions, &template.mesh.triangles);
    let face = |v: usize| frame.to_face(template.mesh.positions[v]);
    let usable =
        |v: usize| template.face_area.get(v).copied().unwrap_or(false) && normals[v] != Vec3::ZERO;
    // One vertex per cell of a `spacing` grid: the one nearest the cell's centre.
    let mut cells: std::collections::HashMap<[i32; 3], (u32, f32)> = Default::default();
    for v in (0..template.mesh.vertex_count()).filter(|&v| usable(v)) {
        let q = face(v) / spacing;
        let key = [q.x.floor() as i32, q.y.floor() as i32, q.z.floor() as i32];
        let centre = Vec3::new(key[0] as f32, key[1] as f32, key[2] as f32) + 0.5;
        let d = q.distance_squared(centre);
        let e = cells.entry(key).or_insert((v as u32, d));
        if d < e.1 {
            *e = (v as u32, d);
        }
    }
    let mut vertex: Vec<u32> = cells.values().map(|(v, _)| *v).collect();
    for v in template.landmarks.vertex.iter().flatten() {
        if usable(*v as usize) {
            vertex.push(*v);
        }
    }
    vertex.sort_unstable();
    vertex.dedup();
    let mut landmark = [None; IBUG_POINTS];
    for (k, v) in template.landmarks.vertex.iter().enumerate() {
        landmark[k] = v.and_then(|v| vertex.binary_search(&v).ok());
    }
    let axes = frame.axes;
    Ok(Nodes {
        at: vertex.iter().map(|&v| face(v as usize)).collect(),
        normal: vertex
            .iter()
            .map(|&v| {
                let n = normals[v as usize];
                Vec3::new(axes[0].dot(n), axes[1].dot(n), axes[2].dot(n))
            })
            .collect(),
        vertex,
        landmark,
    })
}

/// Target vertices in pieces with at least `min_piece` of the largest piece's vertices.
fn big_pieces(target: &Mesh, min_piece: f32) -> Vec<bool> {
    let piece = crate::parts::pieces(target);
    let mut size = std::collections::HashMap::<u32, usize>::new();
    for p in piece.iter().flatten() {
        *size.entry(*p).or_default() += 1;
    }
    let largest = size.values().copied().max().unwrap_or(0) as f32;
    piece
        .iter()
        .map(|p| {
            p.is_some_and(|p| size.get(&p).copied().unwrap_or(0) as f32 >= min_piece * largest)
        })
        .collect()
}

/// Extent of `points` along `axis` among those within `band` of `at` along `up`.
fn width_at(points: impl Iterator<Item = Vec3>, at: Vec3, up: Vec3, axis: Vec3, band: f32) -> f32 {
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for p in points {
        if up.dot(p - at).abs() <= band {
            let x = axis.dot(p);
            lo = lo.min(x);
            hi = hi.max(x);
        }
    }
    (hi - lo).max(0.0)
}

/// One orientation probe (a short similarity ICP from one axis-aligned turn).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Probe {
    /// The target's orientation tried.
    pub orientation: Orientation,
    /// Fraction of the probe's nodes covered after its short ICP.
    pub coverage: f32,
    /// Their RMS distance, face units.
    pub rms: f32,
}

/// What a coarse start needs: the template's nodes, nose tip and width at nose height, the
/// target's surface, its height band and its kept vertices.
struct Coarse<'a, K: Fn() -> I, I: Iterator<Item = Vec3>> {
    nodes: &'a Nodes,
    nose: Vec3,
    template_width: f32,
    surface: &'a Surface,
    band: f32,
    kept: &'a K,
}

impl<K: Fn() -> I, I: Iterator<Item = Vec3>> Coarse<'_, K, I> {
    /// The start with the template turned by `rotation` (its face frame to the target's), its
    /// nose tip on the target's frontmost vertex that way, scaled by `factor` times the widths'
    /// ratio at nose height; `None` when the target has no width there.
    fn start(&self, rotation: Quat, factor: f32) -> Option<HeadPose> {
        let (side, up, front) = (rotation * Vec3::X, rotation * Vec3::Y, rotation * Vec3::Z);
        let tip = (self.kept)().max_by(|a, b| front.dot(*a).total_cmp(&front.dot(*b)))?;
        let width = width_at((self.kept)(), tip, up, side, self.band);
        if !(width > 0.0 && self.template_width > 0.0) {
            return None;
        }
        let scale = factor * width / self.template_width;
        Some(HeadPose {
            rotation,
            scale,
            translation: tip - rotation * (self.nose * scale),
        })
    }
}

/// Scores the 24 axis-aligned orientations of the target, best first: for each, the middle
/// scale's start ([`Coarse::start`], no yaw) refined by `probe_rounds` rounds of the similarity
/// ICP on every `probe_stride`-th node, scored by coverage then RMS ([`crate::icp::score`]). At
/// the defaults (8 rounds, a third of the nodes) the 24 probes cost about as much as 64 rounds
/// of one full start, where each of the 9 coarse starts runs up to 60.
fn probe_orientations<K: Fn() -> I, I: Iterator<Item = Vec3>>(
    coarse: &Coarse<'_, K, I>,
    s: &FindSettings,
) -> Vec<Probe> {
    let stride = s.probe_stride.max(1);
    let at: Vec<Vec3> = coarse.nodes.at.iter().step_by(stride).copied().collect();
    let normal: Vec<Vec3> = coarse
        .nodes
        .normal
        .iter()
        .step_by(stride)
        .copied()
        .collect();
    let settings = IcpSettings {
        rounds: s.probe_rounds.max(1),
        ..s.icp
    };
    let middle = s.scales.get(s.scales.len() / 2).copied().unwrap_or(1.0);
    let mut probes: Vec<Probe> = Orientation::all()
        .into_iter()
        .filter_map(|orientation| {
            let rotation = if orientation.is_identity() {
                Quat::IDENTITY
            } else {
                Quat::from_mat3(&orientation.rig_to_file())
            };
            let start = coarse.start(rotation, middle)?;
            let fit = similarity_icp(&at, &normal, coarse.surface, start, &settings)?;
            Some(Probe {
                orientation,
                coverage: fit.coverage,
                rms: fit.rms,
            })
        })
        .collect();
    // Best first; a stable sort keeps the identity (first in `Orientation::all`) ahead on a tie.
    probes.sort_by(|a, b| {
        (b.coverage, -b.rms)
            .partial_cmp(&(a.coverage, -a.rms))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    probes
}

/// The template registered onto a target ([`register_template`]): the similarity, then where
/// each template node went, in the template's face frame.
pub struct Registration {
    /// The best similarity (template face units to target coordinates).
    pub rigid: RigidFit,
    /// The template's face frame (its mesh coordinates to face units).
    pub frame: FaceFrame,
    /// Template vertex of each node.
    pub node_vertex: Vec<u32>,
    /// Each node in the template's face frame.
    pub node_at: Vec<Vec3>,
    /// Where each node went: the target, in the template's face frame
    /// (`rigid.pose.inverse_apply` of target coordinates).
    pub deformed: Vec<Vec3>,
    /// The target's vertices in the template's face frame.
    pub local: Surface,
    /// Target vertices in pieces large enough to match.
    pub allowed: Vec<bool>,
    /// Coarse starts tried.
    pub starts: usize,
    /// The orientation probes, best first (empty when not probed).
    pub probes: Vec<Probe>,
    /// The target's orientation: that of the start whose similarity fit best.
    pub orientation: Orientation,
    /// Nodes matched after the non-rigid fit.
    pub matched: usize,
    /// RMS point-to-plane distance of the matched nodes, face units.
    pub residual: f32,
    node_normal: Vec<Vec3>,
    node_landmark: [Option<usize>; IBUG_POINTS],
}

/// Registers `template` onto `target`: coarse starts, similarity ICP, non-rigid ICP of the
/// template's nodes.
pub fn register_template(
    target: &Mesh,
    template: &TemplateHead,
    s: &FindSettings,
) -> Result<Registration, RigNewError> {
    let frame = landmark_frame(&template.mesh, &template.landmarks)?;
    let nodes = template_nodes(template, &frame, s.spacing)?;
    let nose = nodes.landmark[30]
        .map(|i| nodes.at[i])
        .ok_or_else(|| RigNewError::Frame("the template lacks its nose tip (iBUG 30)".into()))?;
    let allowed = big_pieces(target, s.min_piece);
    let surface = Surface::new(target.positions.clone(), &target.triangles, |v| allowed[v]);
    if surface.index.len() < 10 {
        return Err(RigNewError::Frame(format!(
            "the mesh has {} vertices on triangles to register a template onto",
            surface.index.len()
        )));
    }
    let kept = || {
        target
            .positions
            .iter()
            .zip(&allowed)
            .filter(|(_, a)| **a)
            .map(|(p, _)| *p)
    };
    let (lo, hi) = kept().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
        (lo.min(p), hi.max(p))
    });
    let band = 0.015 * lo.distance(hi);
    let template_width = width_at(nodes.at.iter().copied(), nose, Vec3::Y, Vec3::X, 0.1);
    let coarse = Coarse {
        nodes: &nodes,
        nose,
        template_width,
        surface: &surface,
        band,
        kept: &kept,
    };
    let probes = if s.any_orientation {
        probe_orientations(&coarse, s)
    } else {
        Vec::new()
    };
    // The coarse starts run in the best probe's orientation, and in any other whose probe
    // covers at least `close_probe` of the best's (at most 2 in all): a small face mask
    // (MediaPipe's) covers 19.2% upright and 18.4% upside down in its probes.
    let mut tried: Vec<Orientation> = probes
        .iter()
        .take_while(|p| {
            probes
                .first()
                .is_some_and(|b| p.coverage >= s.close_probe * b.coverage)
        })
        .take(2)
        .map(|p| p.orientation)
        .collect();
    if tried.is_empty() {
        tried.push(Orientation::default());
    }
    let mut best: Option<(RigidFit, Orientation)> = None;
    let mut starts = 0;
    for orientation in tried {
        let base =
            (!orientation.is_identity()).then(|| Quat::from_mat3(&orientation.rig_to_file()));
        for yaw in &s.yaws {
            let turn = Quat::from_rotation_y(yaw.to_radians());
            let rotation = base.map_or(turn, |b| b * turn);
            for f in &s.scales {
                let Some(start) = coarse.start(rotation, *f) else {
                    continue;
                };
                starts += 1;
                let Some(fit) = similarity_icp(&nodes.at, &nodes.normal, &surface, start, &s.icp)
                else {
                    continue;
                };
                let better =
                    best.is_none_or(|(b, _)| (fit.coverage, -fit.rms) > (b.coverage, -b.rms));
                if better {
                    best = Some((fit, orientation));
                }
            }
        }
    }
    let orientation = best.map_or_else(Orientation::default, |b| b.1);
    let best = best.map(|b| b.0);
    let rigid = best.ok_or_else(|| {
        RigNewError::Frame(
            "no start of the template registration matched the mesh (is it a face?)".into(),
        )
    })?;
    // The target in the template's face units, then the non-rigid fit there.
    let local: Vec<Vec3> = target
        .positions
        .iter()
        .map(|p| rigid.pose.inverse_apply(*p))
        .collect();
    let local = Surface::new(local, &target.triangles, |v| allowed[v]);
    let edges = knn_graph(&nodes.at, s.neighbours);
    let fit = nonrigid_icp(&nodes.at, &nodes.normal, &edges, &local, &s.nonrigid)?;
    Ok(Registration {
        rigid,
        frame,
        node_vertex: nodes.vertex,
        node_at: nodes.at,
        deformed: fit.deformed,
        local,
        allowed,
        starts,
        probes,
        orientation,
        matched: fit.matched,
        residual: fit.rms,
        node_normal: nodes.normal,
        node_landmark: nodes.landmark,
    })
}

/// Finds the 68 iBUG landmark vertices of `target` by registering `template` onto it.
pub fn find_landmarks(
    target: &Mesh,
    template: &TemplateHead,
    s: &FindSettings,
) -> Result<FoundLandmarks, RigNewError> {
    let r = register_template(target, template, s)?;
    Ok(landmarks_of_registration(&r, s))
}

/// The 68 iBUG landmark vertices a registration ([`register_template`]) puts on its target.
pub fn landmarks_of_registration(r: &Registration, s: &FindSettings) -> FoundLandmarks {
    let mut landmarks = Landmarks {
        vertex: [None; IBUG_POINTS],
    };
    let mut landmark_distance = [f32::NAN; IBUG_POINTS];
    for (k, node) in r.node_landmark.iter().enumerate() {
        let Some(i) = *node else { continue };
        if let Some((v, d)) = nearest_allowed(
            r.deformed[i],
            Some(r.node_normal[i]),
            &r.local.positions,
            &r.local.normals,
            &r.allowed,
            s.min_normal_dot,
        ) {
            landmarks.vertex[k] = Some(v);
            landmark_distance[k] = d;
        }
    }
    FoundLandmarks {
        landmarks,
        rigid: r.rigid,
        starts: r.starts,
        orientation: r.orientation,
        nodes: r.node_vertex.len(),
        coverage: r.matched as f32 / r.node_vertex.len().max(1) as f32,
        residual: r.residual,
        landmark_distance,
    }
}
