//! What each mesh of an avatar is, besides the face: by its name first (`Eye_L`, `Teeth`,
//! `EyeLashes`, `Hair`, `Body`), else by where it sits in the face's frame (the landmarks):
//! small meshes centred on an eye are eyeballs, small meshes behind the lips are teeth (split
//! upper and lower by the lip line), thin ones along the lids are lashes, large ones above the
//! brows hair and below the chin body. Whatever is left follows the head. `rig new` writes the
//! result into the rig's `[avatar.parts]`, where a user can change it.

use crate::Landmarks;
use glam::Vec3;
use mimic_avatar::{Avatar, FaceMesh, Mode};
use std::collections::BTreeMap;

/// The kinds of part, as the rig file names them.
pub use mimic_assets::PART_KINDS;

/// The kind a mesh's name says, if it says one.
pub fn kind_by_name(name: &str) -> Option<&'static str> {
    let n = name.to_ascii_lowercase();
    let has = |words: &[&str]| words.iter().any(|w| n.contains(w));
    if has(&["lash", "brow"]) {
        Some("lashes")
    } else if has(&["tongue"]) {
        Some("tongue")
    } else if has(&["teeth", "tooth", "gum"]) {
        if has(&["lower", "bottom", "_dn", "down"]) {
            Some("lower_teeth")
        } else if has(&["upper", "top", "_up"]) {
            Some("upper_teeth")
        } else {
            Some("teeth")
        }
    } else if has(&["eyeball", "eye", "iris", "cornea", "pupil"]) {
        Some("eyeballs")
    } else if has(&["hair", "bang", "ponytail"]) {
        Some("hair")
    } else if has(&["body", "cloth", "shirt", "torso", "skin_body"]) {
        Some("body")
    } else {
        None
    }
}

/// The rest-pose world positions of mesh `mesh`'s vertices (each vertex array once).
fn mesh_points(avatar: &Avatar, mesh: usize) -> Vec<Vec3> {
    FaceMesh::of(avatar, mesh).map_or_else(|_| Vec::new(), |f| f.mesh_data.positions)
}

/// The kind of each mesh other than the face, keyed by mesh name (`#K` for an unnamed mesh K):
/// by name, else by place (module docs). `marks` are the face's landmarks on `face`.
pub fn classify_parts(
    avatar: &Avatar,
    face: &FaceMesh,
    marks: &Landmarks,
) -> BTreeMap<String, String> {
    let p = &face.mesh_data.positions;
    let at = |k: usize| marks.get(k).and_then(|v| p.get(v as usize)).copied();
    let mean = |ks: std::ops::RangeInclusive<usize>| {
        let pts: Vec<Vec3> = ks.filter_map(at).collect();
        (!pts.is_empty()).then(|| pts.iter().copied().sum::<Vec3>() / pts.len() as f32)
    };
    let (eye_r, eye_l, mouth, brow, chin) = (
        mean(36..=41),
        mean(42..=47),
        mean(60..=67),
        mean(17..=26),
        at(8),
    );
    let iod = match (eye_r, eye_l) {
        (Some(a), Some(b)) => a.distance(b).max(f32::MIN_POSITIVE),
        _ => 1.0,
    };
    let mut out = BTreeMap::new();
    for (k, m) in avatar.meshes.iter().enumerate() {
        let shown = avatar.nodes_of_mesh(k).next().is_some();
        let has_triangles = m.primitives.iter().any(|p| p.mode == Mode::Triangles);
        if k == face.mesh || !shown || !has_triangles {
            continue;
        }
        let name = m.name.clone().unwrap_or_else(|| format!("#{k}"));
        let kind = kind_by_name(&name).map(str::to_string).unwrap_or_else(|| {
            let pts = mesh_points(avatar, k);
            by_place(&pts, eye_r, eye_l, mouth, brow, chin, iod).to_string()
        });
        out.insert(name, kind);
    }
    out
}

/// The kind of a mesh by where its points sit (module docs).
fn by_place(
    pts: &[Vec3],
    eye_r: Option<Vec3>,
    eye_l: Option<Vec3>,
    mouth: Option<Vec3>,
    brow: Option<Vec3>,
    chin: Option<Vec3>,
    iod: f32,
) -> &'static str {
    if pts.is_empty() {
        return "head";
    }
    let c = pts.iter().copied().sum::<Vec3>() / pts.len() as f32;
    let (lo, hi) = pts
        .iter()
        .fold((Vec3::MAX, Vec3::MIN), |(l, h), q| (l.min(*q), h.max(*q)));
    let size = (hi - lo).max_element() / iod;
    let near = |q: Option<Vec3>, r: f32| q.is_some_and(|q| q.distance(c) < r * iod);
    let one_eye = size < 0.8 && (near(eye_r, 0.45) || near(eye_l, 0.45));
    let both_eyes = (0.8..1.6).contains(&size)
        && eye_r
            .zip(eye_l)
            .is_some_and(|(r, l)| c.distance((r + l) / 2.0) < 0.3 * iod);
    if one_eye || both_eyes {
        // Centred on an eye (or between both, for one mesh holding both eyes): thin along z
        // are lashes, round are eyeballs.
        let depth = (hi.z - lo.z) / iod;
        return if depth < 0.08 { "lashes" } else { "eyeballs" };
    }
    if size < 1.5 && near(mouth, 0.7) {
        return match mouth {
            Some(m) if hi.y < m.y => "lower_teeth",
            Some(m) if lo.y > m.y => "upper_teeth",
            _ => "teeth",
        };
    }
    if size > 1.5 && brow.is_some_and(|b| c.y > b.y) {
        return "hair";
    }
    if size > 1.5 && chin.is_some_and(|b| c.y < b.y) {
        return "body";
    }
    "head"
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_say_the_kind() {
        assert_eq!(kind_by_name("EyeLashes"), Some("lashes"));
        assert_eq!(kind_by_name("Eye_L"), Some("eyeballs"));
        assert_eq!(kind_by_name("LowerTeeth"), Some("lower_teeth"));
        assert_eq!(kind_by_name("Teeth"), Some("teeth"));
        assert_eq!(kind_by_name("J_Hair_Front"), Some("hair"));
        assert_eq!(kind_by_name("Body"), Some("body"));
        assert_eq!(kind_by_name("Mesh.003"), None);
        assert!(PART_KINDS.contains(&"tongue"));
    }

    #[test]
    fn places_say_the_kind_without_names() {
        let (eye_r, eye_l) = (Vec3::new(-0.5, 0.0, 0.0), Vec3::new(0.5, 0.0, 0.0));
        let (mouth, brow, chin) = (
            Vec3::new(0.0, -1.0, 0.1),
            Vec3::new(0.0, 0.3, 0.1),
            Vec3::new(0.0, -1.6, 0.0),
        );
        let ball = |c: Vec3, r: f32| -> Vec<Vec3> {
            (0..64)
                .map(|k| {
                    let (a, b) = (k as f32 * 0.7, k as f32 * 1.3);
                    c + r * Vec3::new(a.cos() * b.sin(), a.sin() * b.sin(), b.cos())
                })
                .collect()
        };
        let place = |pts: &[Vec3]| {
            by_place(
                pts,
                Some(eye_r),
                Some(eye_l),
                Some(mouth),
                Some(brow),
                Some(chin),
                1.0,
            )
        };
        assert_eq!(place(&ball(eye_r, 0.24)), "eyeballs");
        let lower: Vec<Vec3> = ball(mouth - Vec3::Y * 0.15, 0.1);
        assert_eq!(place(&lower), "lower_teeth");
        assert_eq!(place(&ball(Vec3::new(0.0, 1.5, -0.5), 1.2)), "hair");
        assert_eq!(place(&ball(Vec3::new(0.0, -4.0, -0.5), 2.0)), "body");
        assert_eq!(place(&ball(Vec3::new(1.4, -0.5, -0.6), 0.2)), "head");
    }
}
