//! `rig new` on an avatar file: its face mesh read (and said), the other meshes classified and
//! joined to the working mesh after the face, the rig's `[avatar]` section and the `[look]` that
//! hides the see-through layers.

use super::NewRig;
use crate::{Landmarks, RigNewError};

/// For an avatar file: the file read whole and its face mesh (said in a progress line).
pub(super) fn avatar_of(
    job: &NewRig<'_>,
    note: &mut dyn FnMut(String),
) -> Result<Option<mimic_assets::RigAvatar>, RigNewError> {
    if !mimic_avatar::is_avatar_path(job.mesh) {
        return Ok(None);
    }
    let section = mimic_assets::AvatarSection {
        face: job.face.map(str::to_string),
        ..Default::default()
    };
    let a = mimic_assets::read_avatar_face(job.mesh, &section)?;
    note(format!(
        "{}: face mesh `{}` ({} vertices) of {} meshes (--face picks another)",
        job.mesh.display(),
        mesh_name(&a.avatar, a.face.mesh),
        a.face.mesh_data.vertex_count(),
        a.avatar.meshes.len()
    ));
    Ok(Some(a))
}

/// Mesh `k`'s name, `#K` when it has none.
fn mesh_name(avatar: &mimic_avatar::Avatar, k: usize) -> String {
    avatar.meshes[k]
        .name
        .clone()
        .unwrap_or_else(|| format!("#{k}"))
}

/// The line saying what each other mesh of the avatar was taken for.
fn parts_line(
    avatar: &mimic_avatar::Avatar,
    face: &mimic_avatar::FaceMesh,
    parts: &std::collections::BTreeMap<String, String>,
) -> String {
    let said: Vec<String> = parts.iter().map(|(m, k)| format!("{m} = {k}")).collect();
    format!(
        "avatar parts besides the face `{}`: {} (the rig's [avatar.parts] changes them)",
        mesh_name(avatar, face.mesh),
        if said.is_empty() {
            "none".into()
        } else {
            said.join(", ")
        }
    )
}

/// The rig's `[avatar]` section: the face mesh and the other meshes' kinds.
pub(super) fn avatar_toml(
    avatar: &mimic_avatar::Avatar,
    face: usize,
    parts: &std::collections::BTreeMap<String, String>,
) -> String {
    // A JSON string is a TOML basic string.
    let q = |s: &str| serde_json::Value::String(s.to_string()).to_string();
    let mut out = format!(
        "\n# The avatar: which mesh is the face, and what the other meshes are ({}).\n[avatar]\nface = {}\n\n[avatar.parts]\n",
        crate::avatar_parts::PART_KINDS.join(", "),
        q(&mesh_name(avatar, face))
    );
    for (m, k) in parts {
        out.push_str(&format!("{} = {}\n", q(m), q(k)));
    }
    out
}

/// The `[look]` hiding the vertices drawn only by see-through materials (alpha BLEND: an eye's
/// occlusion shadow, lashes), which mimic's renderer would draw solid; empty when there are none.
pub(super) fn see_through_look(a: &mimic_assets::RigAvatar) -> String {
    let face = &a.face;
    let n = face.mesh_data.vertex_count();
    let (mut solid, mut blend) = (vec![false; n], vec![false; n]);
    for (t, m) in face.mesh_data.triangles.iter().zip(&face.triangle_material) {
        let see_through = m
            .and_then(|k| a.avatar.materials.get(k))
            .is_some_and(|m| m.alpha_mode == mimic_avatar::AlphaMode::Blend);
        let mark = if see_through { &mut blend } else { &mut solid };
        t.iter().for_each(|&v| mark[v as usize] = true);
    }
    let only: Vec<bool> = blend.iter().zip(&solid).map(|(b, s)| *b && !*s).collect();
    let ranges = crate::parts::ranges(&only);
    if ranges.is_empty() {
        return String::new();
    }
    let list: Vec<String> = ranges.iter().map(|[a, b]| format!("[{a}, {b}]")).collect();
    format!(
        "\n# Vertices drawn only by see-through (alpha BLEND) materials: mimic's renderer would draw\n# them solid, so it leaves them out (the avatar written back keeps them).\n[look]\nhidden = [{}]\n",
        list.join(", ")
    )
}

/// The avatar's other meshes classified from the face's landmarks (said in a progress line), and
/// the parts drawn with the face joined to its working mesh, from the avatar already read.
pub(super) fn with_parts(
    a: mimic_assets::RigAvatar,
    marks: &Landmarks,
    note: &mut dyn FnMut(String),
) -> Result<mimic_assets::RigAvatar, RigNewError> {
    let parts = crate::avatar_parts::classify_parts(&a.avatar, &a.face, marks);
    note(parts_line(&a.avatar, &a.face, &parts));
    let section = mimic_assets::AvatarSection {
        face: Some(mesh_name(&a.avatar, a.face.mesh)),
        parts,
    };
    Ok(mimic_assets::avatar_face(a.avatar, &section)?)
}
