//! `rig new`'s step for closed lips ([`crate::lipcut`]): a mesh whose lips are one surface is cut
//! along its lip line and written beside the rig (`x.toml` -> `x.cut.obj`), which the rig then
//! names as its mesh; the landmarks and the registration follow the cut.

use super::{NewRig, write_file};
use crate::head_template::Registration;
use crate::landmarks::Landmarks;
use crate::lipcut::{Mouth, cut_closed_mouth, mouth_closed};
use crate::mouth_interior::{MATERIALS, mouth_interior};
use crate::nearest::Surface;
use crate::{RigNewError, new::landmark_frame};
use mimic_types::Mesh;
use std::path::{Path, PathBuf};

/// The cut mesh beside rig `rig`: `x.toml` -> `x.cut.obj`.
pub fn cut_mesh_path(rig: &Path) -> PathBuf {
    let stem = rig
        .file_stem()
        .map_or_else(|| "rig".into(), |s| s.to_string_lossy().into_owned());
    rig.with_file_name(format!("{stem}.cut.obj"))
}

/// What [`cut_lips`] made: the cut mesh's file, and where the added inside of the mouth starts.
#[derive(Debug)]
pub(super) struct CutLips {
    /// The cut mesh written beside the rig.
    pub file: PathBuf,
    /// Vertices and triangles of the cut skin; the mouth's inside follows.
    pub skin: (usize, usize),
    /// ICT's vertex of each added vertex of the mouth's inside.
    pub inside: Vec<u32>,
}

impl CutLips {
    /// `mesh` (the rig's working mesh) without the mouth's inside: the skin the shapes are made for.
    pub fn skin_of(&self, mesh: &Mesh) -> Mesh {
        let (v, t) = self.skin;
        let cut = |n: usize, k: usize| n.min(k);
        Mesh {
            positions: mesh.positions[..cut(mesh.positions.len(), v)].to_vec(),
            triangles: mesh.triangles[..cut(mesh.triangles.len(), t)].to_vec(),
            uvs: mesh.uvs.clone(),
            uv_triangles: mesh.uv_triangles[..cut(mesh.uv_triangles.len(), t)].to_vec(),
        }
    }
}

/// Cuts closed lips open (unless `job.cut` is off) and, with a registration, adds ICT's mouth
/// socket, gums, tongue and teeth ([`crate::mouth_interior`]): `mesh`, `marks` and `reg` are
/// changed to the cut mesh's, which is written beside the rig with its materials; `None` when
/// nothing was cut.
pub(super) fn cut_lips(
    job: &NewRig<'_>,
    mesh: &mut Mesh,
    marks: &mut Landmarks,
    reg: &mut Option<Registration>,
    note: &mut dyn FnMut(String),
) -> Result<Option<CutLips>, RigNewError> {
    // Without a face frame `make_rig` says what is missing.
    let Ok(frame) = landmark_frame(mesh, marks) else {
        return Ok(None);
    };
    if !job.cut {
        if mouth_closed(mesh, marks, &frame) == Mouth::Closed {
            note(
                "the lips are one surface and --no-cut keeps them so: the mouth cannot open".into(),
            );
        }
        return Ok(None);
    }
    let cut = match cut_closed_mouth(mesh, marks, &frame) {
        Ok(Some(cut)) => cut,
        Ok(None) => {
            note("the lips are separate surfaces: no cut".into());
            return Ok(None);
        }
        Err(why) => {
            note(format!(
                "warning: the lips are not cut ({why}): the mouth may not open"
            ));
            return Ok(None);
        }
    };
    let n = mesh.vertex_count();
    if let Some(r) = reg.as_mut() {
        let mut local = r.local.positions.clone();
        let mut allowed = r.allowed.clone();
        for (i, v) in cut.lower.iter().enumerate() {
            if *v as usize >= n {
                let o = cut.path[i] as usize;
                local.push(local[o]);
                allowed.push(allowed[o]);
            }
        }
        r.local = Surface::new(local, &cut.mesh.triangles, |v| allowed[v]);
        r.allowed = allowed;
    }
    note(format!(
        "the lips are one surface: cut the mesh along the lip line from corner to corner (iBUG 60 to 64, {} vertices split over {:.2} IOD; the lower lip gets the copies; --no-cut keeps the mesh as it is)",
        cut.split, cut.length,
    ));
    let skin = (cut.mesh.vertex_count(), cut.mesh.triangles.len());
    let mut whole = cut.mesh;
    // The skin keeps the source's own materials (the cut keeps every triangle in its place);
    // the inside's come after them.
    let source = source_materials(job)?;
    let own = source.materials.len();
    let mut material = if source.triangle_material.len() == whole.triangles.len() {
        source.triangle_material
    } else {
        vec![None; whole.triangles.len()]
    };
    let inside = match reg.as_ref() {
        Some(r) => {
            let template = crate::TemplateHead::ict(job.configs)
                .map_err(super::context("loading the ICT template head"))?;
            let inside = mouth_interior(&template, r);
            let base = whole.positions.len() as u32;
            whole.positions.extend(&inside.positions);
            whole
                .triangles
                .extend(inside.triangles.iter().map(|t| t.map(|v| v + base)));
            material.extend(inside.material.iter().map(|m| Some(own + *m)));
            if !whole.uvs.is_empty() {
                // The inside has no texture: its corners at one point of the map.
                let at = whole.uvs.len() as u32;
                whole.uvs.push(glam::Vec2::ZERO);
                whole.uv_triangles.resize(whole.triangles.len(), [at; 3]);
            }
            let [s, g, t] = inside.counts;
            note(format!(
                "added the inside of the mouth from ICT-FaceKit, placed by the registration: the mouth socket ({s} vertices), gums and tongue ({g}) and teeth ({t}), vertices {} on",
                base
            ));
            inside.template_vertex
        }
        None => {
            note("the mouth gets no inside (it comes from the template registration, which given landmarks skip)".into());
            Vec::new()
        }
    };
    let file = cut_mesh_path(job.output);
    write_cut_mesh(job, &file, &whole, &material, &source.materials, n)?;
    note(format!("wrote {}, the rig's mesh", file.display()));
    *mesh = whole;
    *marks = cut.landmarks;
    Ok(Some(CutLips { file, skin, inside }))
}

/// The source OBJ's own materials and each triangle's, textures named by absolute paths (the cut
/// mesh is written elsewhere); none for another format or an OBJ without `mtllib`.
fn source_materials(job: &NewRig<'_>) -> Result<mimic_assets::MeshMaterials, RigNewError> {
    let is_obj = job
        .mesh
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    if !is_obj {
        return Ok(Default::default());
    }
    let text = mimic_types::limits::read_capped(job.mesh, &mimic_types::limits::OBJ_FILE).map_err(
        |cause| RigNewError::Read {
            path: job.mesh.to_path_buf(),
            cause,
        },
    )?;
    let mut own = mimic_assets::parse_obj_materials(job.mesh, &text)?;
    for m in &mut own.materials {
        if let Some(t) = m.texture.as_mut()
            && let Ok(full) = std::fs::canonicalize(&*t)
        {
            *t = full;
        }
    }
    Ok(own)
}

/// Writes the cut mesh (OBJ) and its materials (MTL) beside it: the source's own (`own`), then
/// the mouth's inside.
fn write_cut_mesh(
    job: &NewRig<'_>,
    file: &Path,
    mesh: &Mesh,
    material: &[Option<usize>],
    own: &[mimic_assets::Material],
    uncut: usize,
) -> Result<(), RigNewError> {
    let header = format!(
        "{} with its closed lips cut open along the lip line by `mimic rig new`:\nvertices {} on are the lower lip's copies of the cut's vertices, then the inside of the mouth.",
        job.mesh.display(),
        uncut
    );
    let mtl = file.with_extension("mtl");
    let mtl_name = mtl
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let materials: Vec<mimic_assets::Material> = own
        .iter()
        .cloned()
        .chain(MATERIALS.iter().map(|(name, kd)| mimic_assets::Material {
            name: name.to_string(),
            diffuse: *kd,
            transparent: false,
            texture: None,
        }))
        .collect();
    let names: Vec<String> = materials.iter().map(|m| m.name.clone()).collect();
    let has_inside = material.iter().any(Option::is_some);
    let mut text = Vec::new();
    let fail = |path: &Path| {
        let path = path.to_path_buf();
        move |cause| RigNewError::Write { path, cause }
    };
    mimic_assets::write_obj_with(
        &mut text,
        &header,
        &mesh.positions,
        &mesh.triangles,
        &mimic_assets::ObjExtras {
            uvs: &mesh.uvs,
            uv_triangles: &mesh.uv_triangles,
            mtllib: has_inside.then_some(mtl_name.as_str()),
            materials: &names,
            triangle_material: if has_inside { material } else { &[] },
            ..Default::default()
        },
    )
    .map_err(fail(file))?;
    write_file(file, &text)?;
    if has_inside {
        let mut text = Vec::new();
        mimic_assets::write_mtl(
            &mut text,
            &format!(
                "{} materials of {} (textures by absolute path), then the inside of the mouth added by `mimic rig new`.",
                own.len(),
                job.mesh.display()
            ),
            &materials,
        )
        .map_err(fail(&mtl))?;
        write_file(&mtl, &text)?;
    }
    Ok(())
}
