//! A rig whose mesh is an avatar file (`mesh = "head.glb"`, `.gltf` or `.vrm`): the `[avatar]`
//! section of the rig file says which of its meshes is the face and what the other meshes are;
//! the face mesh and the parts drawn with it ([`DRAWN_PARTS`], after the face's vertices), read
//! from the file itself, are the rig's working mesh (no copy is made).

use crate::AssetError;
use mimic_avatar::{Avatar, FaceMesh};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The `[avatar]` section of a rig file.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AvatarSection {
    /// The face mesh: its glTF name, or `#K` for mesh K (default: the largest mesh named like a
    /// face or head, else the largest).
    #[serde(default)]
    pub face: Option<String>,
    /// What each other mesh is, by mesh name: `eyeballs`, `upper_teeth`, `lower_teeth`, `teeth`,
    /// `tongue`, `lashes`, `hair`, `body`, `head` (follows the head).
    #[serde(default)]
    pub parts: BTreeMap<String, String>,
}

/// Every kind of part a rig's `[avatar.parts]` may name.
pub const PART_KINDS: [&str; 9] = [
    "eyeballs",
    "upper_teeth",
    "lower_teeth",
    "teeth",
    "tongue",
    "lashes",
    "hair",
    "body",
    "head",
];

/// The kinds of part drawn with the face in the working mesh (frozen unless something drives
/// them): the first six of [`PART_KINDS`]; hair, body and the rest are written back but not drawn
/// by mimic.
pub const DRAWN_PARTS: &[&str] = PART_KINDS.as_slice().split_at(6).0;

/// A rig's avatar: the file read whole and its face mesh.
#[derive(Clone, Debug)]
pub struct RigAvatar {
    /// The avatar file.
    pub path: PathBuf,
    /// The file, read whole.
    pub avatar: Avatar,
    /// The face mesh, as the rig's working mesh.
    pub face: FaceMesh,
    /// The rig's `[avatar]` section.
    pub section: AvatarSection,
}

/// Reads the avatar at `path` and the face mesh `section` names ([`avatar_face`]).
pub fn read_avatar_face(path: &Path, section: &AvatarSection) -> Result<RigAvatar, AssetError> {
    avatar_face(mimic_avatar::load_avatar(path)?, section)
}

/// The face mesh `section` names (and its drawn parts) of `avatar`, already read.
pub fn avatar_face(avatar: Avatar, section: &AvatarSection) -> Result<RigAvatar, AssetError> {
    let path = avatar.path.clone();
    let path = path.as_path();
    let face = match &section.face {
        Some(name) => mimic_avatar::find_mesh(&avatar, name).ok_or_else(|| {
            let names: Vec<String> = avatar
                .meshes
                .iter()
                .enumerate()
                .map(|(k, m)| m.name.clone().unwrap_or_else(|| format!("#{k}")))
                .collect();
            mimic_avatar::AvatarError::at(
                path,
                "/meshes",
                format!(
                    "no mesh `{name}` for the rig's [avatar] face; the file has {}",
                    names.join(", ")
                ),
            )
        })?,
        None => mimic_avatar::largest_mesh(&avatar).ok_or_else(|| {
            mimic_avatar::AvatarError::at(path, "/meshes", "no mesh with triangles is shown")
        })?,
    };
    if let Some((name, kind)) = section
        .parts
        .iter()
        .find(|(_, kind)| !PART_KINDS.contains(&kind.as_str()))
    {
        return Err(mimic_avatar::AvatarError::at(
            path,
            "/meshes",
            format!(
                "the rig's [avatar.parts] calls `{name}` `{kind}`, which is not one of {}",
                PART_KINDS.join(", ")
            ),
        )
        .into());
    }
    let mut meshes = vec![face];
    let mut parts: Vec<usize> = section
        .parts
        .iter()
        .filter(|(_, kind)| DRAWN_PARTS.contains(&kind.as_str()))
        .map(|(name, _)| {
            mimic_avatar::find_mesh(&avatar, name).ok_or_else(|| {
                mimic_avatar::AvatarError::at(
                    path,
                    "/meshes",
                    format!("no mesh `{name}` for the rig's [avatar.parts]"),
                )
            })
        })
        .collect::<Result<_, _>>()?;
    parts.sort_unstable();
    parts.dedup();
    meshes.extend(parts.into_iter().filter(|m| *m != face));
    let face = FaceMesh::of_meshes(&avatar, &meshes)?;
    Ok(RigAvatar {
        path: path.to_path_buf(),
        avatar,
        face,
        section: section.clone(),
    })
}

/// The avatar of the rig at `rig_path`, None when its mesh is an OBJ.
pub fn load_rig_avatar(rig_path: &Path) -> Result<Option<RigAvatar>, AssetError> {
    let file = crate::look::read_rig_file(rig_path)?;
    let mesh = rig_path
        .parent()
        .unwrap_or(Path::new("."))
        .join(file.mesh.get_ref());
    if !mimic_avatar::is_avatar_path(&mesh) {
        return Ok(None);
    }
    read_avatar_face(&mesh, &file.avatar.unwrap_or_default()).map(Some)
}

/// The face mesh's materials as a rig's: each glTF material's name (`material_K` when it has
/// none), base colour and whether it is see-through (alpha mode BLEND or MASK, or a base alpha
/// below 1); per triangle, its primitive's material.
pub fn avatar_materials(a: &RigAvatar) -> crate::MeshMaterials {
    let materials = a
        .avatar
        .materials
        .iter()
        .enumerate()
        .map(|(k, m)| crate::Material {
            name: m.name.clone().unwrap_or_else(|| format!("material_{k}")),
            diffuse: m.base_color.truncate().to_array(),
            transparent: m.alpha_mode != mimic_avatar::AlphaMode::Opaque || m.base_color.w < 1.0,
            texture: None,
        })
        .collect();
    crate::MeshMaterials {
        materials,
        triangle_material: a.face.triangle_material.clone(),
    }
}
