//! The 52 ARKit blend shapes made for any head (`mimic rig new --blendshapes arkit`): ICT's
//! expression set, combined into ARKit's shapes on the template ([`arkit_from_ict`]: `_L` is
//! `...Left`, ICT's split `browInnerUp` and `cheekPuff` halves summed), transferred onto the
//! registered head ([`crate::transfer`]) and written beside the rig as one shape pack that the
//! rig's `[[morph_targets]]` entries name ([`write_arkit_targets`]); [`add_arkit`] is the step of
//! `rig new`.

use crate::head_template::{Registration, TemplateHead};
use crate::make::{context, write};
use crate::transfer::{TransferSettings, correspond, transfer_shapes};
use crate::{FindSettings, NewRig, RigNewError, register_template};
use glam::Vec3;
use mimic_assets::{PackedShape, ShapePack};
use mimic_types::{Mesh, Rig};
use std::path::{Path, PathBuf};

/// ICT's expression set, relative to `configs/`.
pub const ICT_EXPRESSIONS: &str = "meshes/ict-facekit/expressions.shapes";

pub use mimic_types::arkit::ARKIT_NAMES;

/// ICT's spellings of ARKit shape `arkit`, tried in order: the name itself (`jawLeft`,
/// `jawOpen`), the `_L` / `_R` form (`eyeBlinkLeft` -> `eyeBlink_L`), and for a shape without a
/// side its two halves, to be summed (ICT splits `browInnerUp` and `cheekPuff`).
pub fn ict_spellings(arkit: &str) -> Vec<Vec<String>> {
    let mut out = vec![vec![arkit.to_string()]];
    for (long, short) in [("Left", "_L"), ("Right", "_R")] {
        if let Some(base) = arkit.strip_suffix(long) {
            out.push(vec![format!("{base}{short}")]);
            return out;
        }
    }
    out.push(vec![format!("{arkit}_L"), format!("{arkit}_R")]);
    out
}

/// ICT's shapes as ARKit's: per ARKit name ICT has, its deltas on the template (the halves
/// summed); and the ARKit names ICT lacks. ICT's shapes that are not ARKit's (`cheekRaiser`,
/// `PupilDilate`) are left out.
pub fn arkit_from_ict(ict: &ShapePack) -> (Vec<PackedShape>, Vec<&'static str>) {
    let (mut made, mut missing) = (Vec::new(), Vec::new());
    for name in ARKIT_NAMES {
        // The first spelling ICT has all parts of.
        let parts = ict_spellings(name).into_iter().find_map(|names| {
            names
                .iter()
                .map(|n| ict.get(n))
                .collect::<Option<Vec<&PackedShape>>>()
        });
        let Some(parts) = parts else {
            missing.push(name);
            continue;
        };
        let mut deltas = vec![Vec3::ZERO; ict.vertex_count];
        for p in parts {
            deltas.iter_mut().zip(&p.deltas).for_each(|(d, e)| *d += *e);
        }
        made.push(PackedShape {
            name: name.to_string(),
            deltas,
        });
    }
    (made, missing)
}

/// The ARKit shapes made for a head.
#[derive(Clone, Debug)]
pub struct ArkitShapes {
    /// The shapes, ARKit-named, in ARKit's order, a delta per vertex of the working mesh.
    pub shapes: Vec<PackedShape>,
    /// ARKit names the template lacks (ICT: `tongueOut`).
    pub missing: Vec<&'static str>,
    /// Vertices solved for (the rest held still).
    pub free: usize,
}

/// ARKit's shapes for `face` (the mesh `reg` registered `template` onto) from ICT's
/// `expressions`, padded with zero deltas to `vertices` (an avatar's frozen parts after the face).
pub fn make_arkit_shapes(
    face: &Mesh,
    vertices: usize,
    template: &TemplateHead,
    reg: &Registration,
    expressions: &ShapePack,
) -> Result<ArkitShapes, RigNewError> {
    if expressions.vertex_count != template.mesh.vertex_count() || vertices < face.vertex_count() {
        return Err(RigNewError::Frame(format!(
            "ARKit shapes: the expressions have {} vertices, the template {}; the rig {} and its face {}",
            expressions.vertex_count,
            template.mesh.vertex_count(),
            vertices,
            face.vertex_count()
        )));
    }
    let (on_template, missing) = arkit_from_ict(expressions);
    let s = TransferSettings::default();
    let corr = correspond(face, &template.mesh, reg, &s);
    let deltas: Vec<&[Vec3]> = on_template.iter().map(|p| &p.deltas[..]).collect();
    let made = transfer_shapes(face, &template.mesh, &deltas, &corr, &s)?;
    let shapes = on_template
        .into_iter()
        .zip(made.deltas)
        .map(|(p, mut d)| {
            d.resize(vertices, Vec3::ZERO);
            PackedShape {
                name: p.name,
                deltas: d,
            }
        })
        .collect();
    Ok(ArkitShapes {
        shapes,
        missing,
        free: made.free,
    })
}

/// The shape pack beside rig `rig`: `x.toml` -> `x.arkit.shapes`.
pub fn arkit_pack_path(rig: &Path) -> PathBuf {
    let stem = rig
        .file_stem()
        .map_or_else(|| "rig".into(), |s| s.to_string_lossy().into_owned());
    rig.with_file_name(format!("{stem}.arkit.shapes"))
}

/// Writes `made` beside the rig at `rig` ([`arkit_pack_path`], deltas rounded to `quantum`) and
/// returns the `[[morph_targets]]` entries naming it, to append to the rig's TOML.
pub fn write_arkit_targets(
    rig: &Path,
    made: &ArkitShapes,
    quantum: f32,
) -> Result<String, RigNewError> {
    let path = arkit_pack_path(rig);
    let pack = ShapePack {
        vertex_count: made.shapes.first().map_or(0, |s| s.deltas.len()),
        quantum,
        shapes: made.shapes.clone(),
    };
    mimic_assets::save_shape_pack(&path, &pack)?;
    let file = path
        .file_name()
        .map_or_else(String::new, |f| f.to_string_lossy().into_owned());
    // A JSON string is a TOML basic string.
    let q = serde_json::Value::String(file).to_string();
    let mut out = format!(
        "\n# The {} ARKit blend shapes, ICT-FaceKit's expressions transferred onto this head (`--blendshapes arkit`){}.\n",
        made.shapes.len(),
        if made.missing.is_empty() {
            String::new()
        } else {
            format!("; the template lacks {}", made.missing.join(", "))
        }
    );
    for s in &made.shapes {
        out.push_str(&format!(
            "[[morph_targets]]\nname = \"{}\"\nshapes = {q}\n\n",
            s.name
        ));
    }
    Ok(out)
}

/// The line `rig new` prints about the shapes.
pub fn arkit_line(made: &ArkitShapes, pack: &Path) -> String {
    format!(
        "wrote {}: {} ARKit blend shapes transferred from ICT-FaceKit ({} vertices solved for, the rest held); missing: {}; ICT's cheekRaiser and PupilDilate shapes left out",
        pack.display(),
        made.shapes.len(),
        made.free,
        if made.missing.is_empty() {
            "none".into()
        } else {
            made.missing.join(", ")
        }
    )
}

/// `rig new --blendshapes arkit`: makes the ARKit shapes for `face` (the registered mesh; `rig`'s
/// working mesh is it and then an avatar's frozen parts, or a cut mouth's inside: `inside`, its
/// first vertex and ICT's vertex of each, which take ICT's own deltas), writes them beside the
/// rig and appends their entries to the rig file, which is then read back with its morph targets.
pub fn add_arkit(
    job: &NewRig<'_>,
    face: &Mesh,
    rig: &Rig,
    registration: Option<Registration>,
    inside: Option<(usize, &[u32])>,
    note: &mut dyn FnMut(String),
) -> Result<(), RigNewError> {
    let template =
        TemplateHead::ict(job.configs).map_err(context("loading the ICT template head"))?;
    let reg = match registration {
        Some(r) => r,
        None => register_template(face, &template, &FindSettings::default()).map_err(context(
            format!(
                "{}: registering the ICT template head for the ARKit shapes",
                job.mesh.display()
            ),
        ))?,
    };
    let expressions = mimic_assets::load_shape_pack(&job.configs.join(ICT_EXPRESSIONS))?;
    let mut made = make_arkit_shapes(face, rig.mesh.vertex_count(), &template, &reg, &expressions)
        .map_err(context("--blendshapes arkit"))?;
    if let Some((start, template_vertex)) = inside {
        let (on_template, _) = arkit_from_ict(&expressions);
        crate::mouth_interior::carry_shapes(
            &mut made.shapes,
            start,
            template_vertex,
            &on_template,
            &reg,
        );
    }
    // Deltas kept to 2e-5 of the eye distance (ICT's own pack: 1e-4 cm, about 1.6e-5 IOD).
    let entries = write_arkit_targets(job.output, &made, 2e-5 * reg.rigid.pose.scale)?;
    let text = mimic_types::limits::read_capped(job.output, &mimic_types::limits::RIG_FILE)
        .map_err(|cause| RigNewError::Read {
            path: job.output.to_path_buf(),
            cause,
        })?;
    write(job.output, &format!("{}\n{entries}", text.trim_end()))?;
    mimic_assets::load_morph_targets(job.output, rig)
        .map_err(RigNewError::from)
        .map_err(context(format!(
            "{}: the ARKit shapes do not load",
            job.output.display()
        )))?;
    note(arkit_line(&made, &arkit_pack_path(job.output)));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arkit_names_map_onto_icts_and_split_halves_are_summed() {
        assert_eq!(
            ict_spellings("eyeBlinkLeft"),
            [vec!["eyeBlinkLeft"], vec!["eyeBlink_L"]]
        );
        assert_eq!(
            ict_spellings("browInnerUp"),
            [vec!["browInnerUp"], vec!["browInnerUp_L", "browInnerUp_R"]]
        );
        let distinct: std::collections::HashSet<&str> = ARKIT_NAMES.into_iter().collect();
        assert_eq!(distinct.len(), 52);
        let shape = |name: &str, v: f32| PackedShape {
            name: name.into(),
            deltas: vec![Vec3::splat(v), Vec3::ZERO],
        };
        let ict = ShapePack {
            vertex_count: 2,
            quantum: 1e-4,
            shapes: vec![
                shape("eyeBlink_L", 1.0),
                shape("browInnerUp_L", 2.0),
                shape("browInnerUp_R", 3.0),
                shape("jawOpen", 4.0),
                shape("jawLeft", 6.0),
                shape("cheekRaiser_L", 5.0),
            ],
        };
        let (made, missing) = arkit_from_ict(&ict);
        let names: Vec<&str> = made.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["eyeBlinkLeft", "jawLeft", "jawOpen", "browInnerUp"]);
        assert_eq!(made[3].deltas, [Vec3::splat(5.0), Vec3::ZERO]);
        assert_eq!(missing.len(), 48);
        assert!(missing.contains(&"tongueOut") && !missing.contains(&"browInnerUp"));
    }

    #[test]
    fn icts_shipped_set_lacks_only_tongue_out() {
        let configs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs");
        let ict = mimic_assets::load_shape_pack(&configs.join(ICT_EXPRESSIONS))
            .expect("the shipped expression set");
        let (made, missing) = arkit_from_ict(&ict);
        assert_eq!(missing, ["tongueOut"]);
        assert_eq!(made.len(), 51);
        let cheek = made
            .iter()
            .find(|s| s.name == "cheekPuff")
            .expect("cheekPuff");
        let (l, r) = (
            ict.get("cheekPuff_L").expect("L"),
            ict.get("cheekPuff_R").expect("R"),
        );
        for v in [0, 100, 5000] {
            assert_eq!(cheek.deltas[v], l.deltas[v] + r.deltas[v]);
        }
        assert_eq!(
            arkit_pack_path(Path::new("out/face.toml")),
            Path::new("out/face.arkit.shapes")
        );
    }
}
