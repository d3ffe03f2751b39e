//! A mouth that opens on closed lips (`mimic rig new`, docs/rigging.md "Closed lips"): a scanned
//! head whose lips are one surface is cut along its lip line so the lower lip can leave the upper.
//!
//! (1) [`mouth_closed`]: the mouth is closed when the upper inner lip (iBUG 62) reaches the lower
//! one (iBUG 66) over the mesh's edges without leaving the lips' front: a ball of
//! [`DETECT_RADIUS`] around the inner-lip landmarks' mean, no deeper than [`DETECT_DEPTH`] behind
//! it (lips that are separate meet only around the corners, or through a mouth socket, both
//! outside). (2) [`lip_line`]: the cut's edge path from one inner mouth corner (iBUG 60) to the
//! other (64), the shortest over edges weighted by how far they stray from the registered
//! inner-lip contour (the corners and the midpoints of the facing inner-lip landmarks 61/67,
//! 62/66, 63/65) and made cheaper along a crease (where closed lips meet). (3) [`cut_mesh`]: each vertex of the path between the corners is duplicated;
//! the triangles around it above the path keep the vertex, those below get the copy (copies appended after the mesh's vertices, so every other index holds;
//! UVs are per triangle corner and stay). (4) [`cut_closed_mouth`] does it all and puts the
//! inner-lip landmarks on the cut: 61-63 on its upper side, 65-67 on the copies.

use crate::frame::FaceFrame;
use crate::landmarks::Landmarks;
use glam::Vec3;
use mimic_types::Mesh;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Radius (IOD) around the inner lip's middle inside which separate lips do not meet.
pub const DETECT_RADIUS: f32 = 0.25;

/// Depth (IOD) behind the inner lip's middle that the detection looks (a mouth socket lies deeper).
pub const DETECT_DEPTH: f32 = 0.1;

/// How far (IOD) the cut's path may stray from the inner-lip contour before its edges cost
/// twice their length.
const PATH_SIGMA: f32 = 0.05;

/// An edge along a crease of depth `k` (its neighbours' mean `k` edge lengths in front of it)
/// costs `1 / (1 + CREASE k)` of its length.
const CREASE: f32 = 6.0;

/// The search for the cut stays within this many IOD of the inner lip's middle ...
const PATH_RADIUS: f32 = 0.8;

/// ... and no deeper than this behind it (the mouth corners lie about 0.15 IOD deeper).
const PATH_DEPTH: f32 = 0.3;

/// What was found at the mouth.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Mouth {
    /// The lips are separate surfaces: nothing to cut.
    Open,
    /// The lips are one surface.
    Closed,
    /// It could not be told (the reason).
    Unknown(String),
}

/// A closed mouth cut open ([`cut_closed_mouth`]).
#[derive(Clone, Debug)]
pub struct LipCut {
    /// The mesh with the cut (the copies after the original vertices).
    pub mesh: Mesh,
    /// The landmarks on it (inner-lip points on the cut's sides).
    pub landmarks: Landmarks,
    /// The cut's path, corner to corner (original vertices).
    pub path: Vec<u32>,
    /// Per vertex of the path: the lower lip's vertex there (the copy; the corners are shared).
    pub lower: Vec<u32>,
    /// Vertices split (the path's, less the corners and any on the edge of a gap already there).
    pub split: usize,
    /// Length of the cut along the path, IOD.
    pub length: f32,
}

/// Each vertex's neighbours over the triangles' edges.
fn neighbours(n: usize, triangles: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let mut out = vec![Vec::new(); n];
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            if a < n && b < n {
                if !out[a].contains(&t[(k + 1) % 3]) {
                    out[a].push(t[(k + 1) % 3]);
                }
                if !out[b].contains(&t[k]) {
                    out[b].push(t[k]);
                }
            }
        }
    }
    out
}

/// Face-frame position of landmark `k`.
fn mark(face: &[Vec3], marks: &Landmarks, k: usize) -> Option<Vec3> {
    marks.get(k).and_then(|v| face.get(v as usize).copied())
}

/// The inner lip's middle (mean of iBUG 60-67 that exist), face units.
fn lip_centre(face: &[Vec3], marks: &Landmarks) -> Option<Vec3> {
    let pts: Vec<Vec3> = (60..=67).filter_map(|k| mark(face, marks, k)).collect();
    (!pts.is_empty()).then(|| pts.iter().copied().sum::<Vec3>() / pts.len() as f32)
}

/// Whether the lips of `mesh` are one surface (see the module's (1)); `frame` is the face frame.
pub fn mouth_closed(mesh: &Mesh, marks: &Landmarks, frame: &FaceFrame) -> Mouth {
    let face: Vec<Vec3> = mesh.positions.iter().map(|p| frame.to_face(*p)).collect();
    let (Some(up), Some(down), Some(c)) = (marks.get(62), marks.get(66), lip_centre(&face, marks))
    else {
        return Mouth::Unknown("the inner-lip landmarks (iBUG 60-67) are missing".into());
    };
    if up as usize >= face.len() || down as usize >= face.len() {
        return Mouth::Unknown("an inner-lip landmark is not a vertex of the mesh".into());
    }
    if up == down {
        return Mouth::Closed;
    }
    let inside = |v: usize| face[v].distance(c) < DETECT_RADIUS && face[v].z > c.z - DETECT_DEPTH;
    let near = neighbours(face.len(), &mesh.triangles);
    let mut seen = vec![false; face.len()];
    let mut stack = vec![up];
    seen[up as usize] = true;
    while let Some(v) = stack.pop() {
        if v == down {
            return Mouth::Closed;
        }
        for &w in &near[v as usize] {
            if !seen[w as usize] && inside(w as usize) {
                seen[w as usize] = true;
                stack.push(w);
            }
        }
    }
    Mouth::Open
}

/// Distance from `p` to the polyline `line`.
fn to_polyline(p: Vec3, line: &[Vec3]) -> f32 {
    line.windows(2)
        .map(|s| {
            let (a, b) = (s[0], s[1]);
            let ab = b - a;
            let t = ((p - a).dot(ab) / ab.length_squared().max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
            p.distance(a + ab * t)
        })
        .fold(f32::INFINITY, f32::min)
}

/// The cut's edge path from iBUG 60 to 64 (see the module's (2)), and the inner-lip contour it
/// followed (face units); `None` when the landmarks lack the corners or no path joins them.
pub fn lip_line(mesh: &Mesh, marks: &Landmarks, frame: &FaceFrame) -> Option<Vec<u32>> {
    let face: Vec<Vec3> = mesh.positions.iter().map(|p| frame.to_face(*p)).collect();
    let c = lip_centre(&face, marks)?;
    let (from, to) = (marks.get(60)?, marks.get(64)?);
    if from as usize >= face.len() || to as usize >= face.len() || from == to {
        return None;
    }
    let mid = |a: usize, b: usize| match (mark(&face, marks, a), mark(&face, marks, b)) {
        (Some(p), Some(q)) => Some((p + q) * 0.5),
        (p, q) => p.or(q),
    };
    let mut line = vec![face[from as usize]];
    line.extend(
        [(61, 67), (62, 66), (63, 65)]
            .iter()
            .filter_map(|(a, b)| mid(*a, *b)),
    );
    line.push(face[to as usize]);
    let inside = |v: usize| face[v].distance(c) < PATH_RADIUS && face[v].z > c.z - PATH_DEPTH;
    let near = neighbours(face.len(), &mesh.triangles);
    // How far each vertex lies in a crease: its neighbours' mean in front of it along its
    // (outward) normal, in mean edge lengths; the lips' line is the crease between them.
    let normals = crate::register::vertex_normals(&mesh.positions, &mesh.triangles);
    let crease: Vec<f32> = (0..face.len())
        .map(|v| {
            let ns = &near[v];
            if ns.is_empty() || !inside(v) {
                return 0.0;
            }
            let p = mesh.positions[v];
            let mean =
                ns.iter().map(|w| mesh.positions[*w as usize]).sum::<Vec3>() / ns.len() as f32;
            let edge = ns
                .iter()
                .map(|w| mesh.positions[*w as usize].distance(p))
                .sum::<f32>()
                / ns.len() as f32;
            ((mean - p).dot(normals[v]) / edge.max(f32::MIN_POSITIVE)).max(0.0)
        })
        .collect();
    // Dijkstra on integer-scaled costs (f32 is not Ord): costs in micro-IOD.
    let mut best = vec![u64::MAX; face.len()];
    let mut back = vec![u32::MAX; face.len()];
    let mut heap = BinaryHeap::new();
    best[from as usize] = 0;
    heap.push(Reverse((0u64, from)));
    while let Some(Reverse((d, v))) = heap.pop() {
        if v == to {
            break;
        }
        if d > best[v as usize] {
            continue;
        }
        for &w in &near[v as usize] {
            if !inside(w as usize) {
                continue;
            }
            let (p, q) = (face[v as usize], face[w as usize]);
            let off = to_polyline((p + q) * 0.5, &line) / PATH_SIGMA;
            let deep = 0.5 * (crease[v as usize] + crease[w as usize]);
            let cost = (p.distance(q) * (1.0 + off * off) / (1.0 + CREASE * deep) * 1e6) as u64;
            let e = d.saturating_add(cost.max(1));
            if e < best[w as usize] {
                best[w as usize] = e;
                back[w as usize] = v;
                heap.push(Reverse((e, w)));
            }
        }
    }
    if best[to as usize] == u64::MAX {
        return None;
    }
    let mut path = vec![to];
    while let Some(&v) = path.last() {
        if v == from {
            break;
        }
        path.push(*back.get(v as usize)?);
    }
    path.reverse();
    Some(path)
}

/// Cuts `mesh` along `path` (see the module's (3)); `up` is the face's up direction. Returns the
/// cut mesh and per path vertex its lower-lip vertex.
///
/// Each triangle around a vertex of the path between the corners lies above or below the path
/// by its centroid, measured along `up` made perpendicular to the path there; so a scan's
/// messy lip line (a fin, a vertex where more than two fans meet) still splits in two; a vertex
/// with triangles on one side only (on the edge of a gap between the lips) is not split.
pub fn cut_mesh(mesh: &Mesh, path: &[u32], up: Vec3) -> Result<(Mesh, Vec<u32>), String> {
    let n = mesh.vertex_count();
    if let Some(v) = path.iter().find(|v| **v as usize >= n) {
        return Err(format!("the lip line's vertex {v} is not in the mesh"));
    }
    let mut around: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, t) in mesh.triangles.iter().enumerate() {
        for v in t {
            if let Some(a) = around.get_mut(*v as usize) {
                a.push(i);
            }
        }
    }
    let mut out = mesh.clone();
    let mut lower: Vec<u32> = path.to_vec();
    let last = path.len().saturating_sub(1);
    let at = |v: u32| mesh.positions[v as usize];
    for k in 1..last {
        let v = path[k];
        let along = (at(path[k + 1]) - at(path[k - 1])).normalize_or_zero();
        let Some(side) = (up - along * along.dot(up)).try_normalize() else {
            return Err(format!("the lip line runs up and down at vertex {v}"));
        };
        let p = at(v);
        let below: Vec<usize> = around[v as usize]
            .iter()
            .copied()
            .filter(|t| {
                let m = mesh.triangles[*t].iter().map(|w| at(*w)).sum::<Vec3>() / 3.0;
                (m - p).dot(side) < 0.0
            })
            .collect();
        if below.is_empty() || below.len() == around[v as usize].len() {
            // On the edge of a gap the lips already have: one side only, nothing to split.
            continue;
        }
        let copy = out.positions.len() as u32;
        out.positions.push(p);
        lower[k] = copy;
        for t in below {
            for w in out.triangles[t].iter_mut() {
                if *w == v {
                    *w = copy;
                }
            }
        }
    }
    Ok((out, lower))
}

/// Detects a closed mouth and cuts it ([`mouth_closed`], [`lip_line`], [`cut_mesh`]); `Ok(None)`
/// when the mouth is open, `Err` (a reason) when it is closed but cannot be cut or cannot be told.
pub fn cut_closed_mouth(
    mesh: &Mesh,
    marks: &Landmarks,
    frame: &FaceFrame,
) -> Result<Option<LipCut>, String> {
    match mouth_closed(mesh, marks, frame) {
        Mouth::Open => return Ok(None),
        Mouth::Unknown(why) => return Err(why),
        Mouth::Closed => {}
    }
    let path = lip_line(mesh, marks, frame)
        .ok_or_else(|| "no edge path joins the mouth corners (iBUG 60, 64)".to_string())?;
    if path.len() < 3 {
        return Err(format!(
            "the lip line has {} vertices: nothing between the corners to cut",
            path.len()
        ));
    }
    let (cut, lower) = cut_mesh(mesh, &path, frame.axes[1])?;
    let mut landmarks = marks.clone();
    let at = |v: u32| mesh.positions[v as usize];
    let inner = &path[1..path.len() - 1];
    let nearest = |k: usize| {
        let p = at(marks.get(k)?);
        inner
            .iter()
            .enumerate()
            .min_by(|(_, a), (_, b)| at(**a).distance(p).total_cmp(&at(**b).distance(p)))
            .map(|(i, _)| i + 1)
    };
    landmarks.vertex[60] = path.first().copied();
    landmarks.vertex[64] = path.last().copied();
    for k in [61, 62, 63] {
        if let Some(i) = nearest(k) {
            landmarks.vertex[k] = Some(path[i]);
        }
    }
    for k in [65, 66, 67] {
        if let Some(i) = nearest(k) {
            landmarks.vertex[k] = Some(lower[i]);
        }
    }
    let length = path
        .windows(2)
        .map(|w| at(w[0]).distance(at(w[1])))
        .sum::<f32>()
        / frame.iod;
    let split = cut.vertex_count() - mesh.vertex_count();
    Ok(Some(LipCut {
        split,
        mesh: cut,
        landmarks,
        path,
        lower,
        length,
    }))
}

/// What `rig check` says of a rig's mouth: whether its lips were cut open (vertex pairs at one
/// place within 0.6 IOD of the upper inner lip, 2.2: the cut's vertex and its lower copy) and
/// what rides on its jaw; `None` for a rig without 2.2 or the eyes' FDPs.
pub fn mouth_note(rig: &mimic_types::Rig) -> Option<String> {
    let iod = crate::register::rig_iod(rig)?;
    let lip = rig
        .controls
        .iter()
        .find(|c| c.fdp.to_string() == "2.2")
        .and_then(|c| rig.mesh.positions.get(c.vertex as usize))
        .copied()?;
    let mut used = vec![false; rig.mesh.vertex_count()];
    for t in &rig.mesh.triangles {
        for v in t {
            if let Some(u) = used.get_mut(*v as usize) {
                *u = true;
            }
        }
    }
    let mut near: Vec<(u32, [u32; 3])> = rig
        .mesh
        .positions
        .iter()
        .enumerate()
        .filter(|(v, p)| used[*v] && p.distance(lip) < 0.6 * iod)
        .map(|(v, p)| (v as u32, p.to_array().map(f32::to_bits)))
        .collect();
    near.sort_by_key(|(v, bits)| (*bits, *v));
    let split = near.windows(2).filter(|w| w[0].1 == w[1].1).count();
    let count = |rs: &[[u32; 2]]| rs.iter().map(|[a, b]| (b - a + 1) as usize).sum::<usize>();
    let jaw = rig.parts.jaw.as_ref().map_or_else(
        || "no jaw part".to_string(),
        |j| {
            format!(
                "the jaw carries {} vertices whole and {} ramped across the lip line",
                count(&j.vertices),
                count(&j.ramped)
            )
        },
    );
    Some(if split > 0 {
        format!(
            "mouth: the lips are cut open ({split} vertices split along the lip line, the lower lip on the copies); {jaw}"
        )
    } else {
        format!("mouth: no cut (no two vertices at one place along the lips); {jaw}")
    })
}
