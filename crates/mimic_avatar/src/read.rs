//! Reading an avatar file: container, document, checks, buffers, then every part (the module
//! docs of [`crate::avatar`] say what is kept).

use super::accessor::{MAX_ACCESSOR_ELEMENTS, Reader};
use super::error::pointer_of_path;
use super::files::{read_buffers, read_images};
use super::*;
use crate::gltf_check;
use gltf::json;
use mimic_types::FileKind;
use std::collections::HashMap;
use std::path::Path;

/// Size cap of avatar files and of the buffers they name.
pub const AVATAR_FILE: FileKind = FileKind {
    what: "avatar files",
    max_bytes: 256 << 20,
};

/// Required extensions whose meshes mimic cannot read (their accessors have no plain data).
const COMPRESSED: &[&str] = &["KHR_draco_mesh_compression", "EXT_meshopt_compression"];

/// Reads the avatar file at `path` (`.glb`, `.vrm`, or `.gltf` with the buffers and images it
/// names beside it).
pub fn load_avatar(path: &Path) -> Result<Avatar, AvatarError> {
    let bytes = mimic_types::limits::read_bytes_capped(path, &AVATAR_FILE)
        .map_err(|e| AvatarError::at(path, "", e.to_string()))?;
    parse_avatar(path, &bytes, Some(path.parent().unwrap_or(Path::new("."))))
}

/// Reads an avatar from its bytes; files it names (buffers, images) are read from the folder
/// `files`, or refused when `files` is `None`. Errors name `path`.
pub fn parse_avatar(
    path: &Path,
    bytes: &[u8],
    files: Option<&Path>,
) -> Result<Avatar, AvatarError> {
    let at = |pointer: &str, message: String| AvatarError::at(path, pointer, message);
    let chunks = super::container::split(bytes).map_err(|m| at("", m))?;
    let document: serde_json::Value =
        serde_json::from_slice(chunks.json).map_err(|e| at("", format!("not glTF JSON: {e}")))?;
    let mut root: json::Root = serde_json::from_slice(chunks.json)
        .map_err(|e| at("", format!("not a glTF document: {e}")))?;
    gltf_check::check(&root).map_err(|f| at(&f.pointer, f.message))?;
    for (k, ext) in root.extensions_required.iter().enumerate() {
        if COMPRESSED.contains(&ext.as_str()) {
            return Err(at(
                &format!("/extensionsRequired/{k}"),
                format!("{ext}: compressed meshes are not read (export uncompressed)"),
            ));
        }
    }
    // Other required extensions (texture transforms, unlit, quantized attributes ...) do not
    // change what is read here; they stay in `document`, so the crate's validation does not
    // refuse the file for them.
    root.extensions_required.clear();
    let doc = gltf::Document::from_json(root).map_err(|e| match e {
        gltf::Error::Validation(list) => match list.first() {
            Some((p, v)) => at(&pointer_of_path(p.as_str()), v.to_string()),
            None => at("", "invalid glTF".into()),
        },
        other => at("", other.to_string()),
    })?;
    let buffers = read_buffers(path, &doc, chunks.bin, files)?;
    let reader = Reader {
        path,
        buffers: &buffers,
    };
    let images = read_images(path, &doc, &buffers, files)?;
    let textures = doc
        .textures()
        .map(|t| {
            let s = t.sampler();
            Texture {
                name: t.name().map(str::to_string),
                image: t.source().index(),
                sampler: Sampler {
                    mag_filter: s.mag_filter().map(|f| f.as_gl_enum()),
                    min_filter: s.min_filter().map(|f| f.as_gl_enum()),
                    wrap_s: s.wrap_s().as_gl_enum(),
                    wrap_t: s.wrap_t().as_gl_enum(),
                },
            }
        })
        .collect();
    let materials = doc.materials().map(material).collect();
    let nodes = read_nodes(&doc);
    let scene_roots = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().map(|n| n.index()).collect(),
        None => (0..nodes.len())
            .filter(|&n| nodes[n].parent.is_none())
            .collect(),
    };
    let mut avatar = Avatar {
        path: path.to_path_buf(),
        document,
        buffers: Vec::new(),
        scene_roots,
        nodes,
        meshes: Vec::new(),
        vertex_arrays: Vec::new(),
        morph_targets: Vec::new(),
        skins: Vec::new(),
        materials,
        textures,
        images,
        vrm: None,
        animations: Vec::new(),
    };
    read_meshes(&reader, &doc, &mut avatar)?;
    avatar.skins = read_skins(&reader, &doc)?;
    avatar.animations = crate::animation::read_animations(&reader, &doc)?;
    avatar.vrm = vrm::read(path, &avatar.document, &avatar.nodes, &avatar.meshes)?;
    avatar.buffers = buffers;
    Ok(avatar)
}

fn material(m: gltf::Material<'_>) -> Material {
    let pbr = m.pbr_metallic_roughness();
    let tex = |t: Option<gltf::texture::Info<'_>>| {
        t.map(|i| TextureRef {
            texture: i.texture().index(),
            tex_coord: i.tex_coord(),
        })
    };
    Material {
        name: m.name().map(str::to_string),
        base_color: Vec4::from_array(pbr.base_color_factor()),
        base_color_texture: tex(pbr.base_color_texture()),
        metallic: pbr.metallic_factor(),
        roughness: pbr.roughness_factor(),
        normal_texture: m.normal_texture().map(|n| TextureRef {
            texture: n.texture().index(),
            tex_coord: n.tex_coord(),
        }),
        emissive: Vec3::from_array(m.emissive_factor()),
        alpha_mode: match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Mask => AlphaMode::Mask {
                cutoff: m.alpha_cutoff().unwrap_or(0.5),
            },
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
        },
        double_sided: m.double_sided(),
    }
}

/// Every node with its parent and world transform (the graph is a checked forest: each root's
/// tree walked with a stack, parents before children).
fn read_nodes(doc: &gltf::Document) -> Vec<Node> {
    let mut nodes: Vec<Node> = doc
        .nodes()
        .map(|n| {
            let (local, (scale, rotation, translation)) = match n.transform() {
                gltf::scene::Transform::Matrix { matrix } => {
                    let m = Mat4::from_cols_array_2d(&matrix);
                    (m, m.to_scale_rotation_translation())
                }
                gltf::scene::Transform::Decomposed {
                    translation,
                    rotation,
                    scale,
                } => {
                    let (t, r, s) = (
                        Vec3::from_array(translation),
                        Quat::from_array(rotation),
                        Vec3::from_array(scale),
                    );
                    (Mat4::from_scale_rotation_translation(s, r, t), (s, r, t))
                }
            };
            Node {
                name: n.name().map(str::to_string),
                parent: None,
                children: n.children().map(|c| c.index()).collect(),
                translation,
                rotation,
                scale,
                local,
                world: local,
                mesh: n.mesh().map(|m| m.index()),
                skin: n.skin().map(|s| s.index()),
            }
        })
        .collect();
    for p in 0..nodes.len() {
        for k in 0..nodes[p].children.len() {
            let c = nodes[p].children[k];
            nodes[c].parent = Some(p);
        }
    }
    let mut stack: Vec<usize> = (0..nodes.len())
        .filter(|&n| nodes[n].parent.is_none())
        .collect();
    while let Some(p) = stack.pop() {
        let world = nodes[p].world;
        for k in 0..nodes[p].children.len() {
            let c = nodes[p].children[k];
            nodes[c].world = world * nodes[c].local;
            stack.push(c);
        }
    }
    nodes
}

fn mode(m: gltf::mesh::Mode) -> Mode {
    use gltf::mesh::Mode as M;
    match m {
        M::Points => Mode::Points,
        M::Lines => Mode::Lines,
        M::LineLoop => Mode::LineLoop,
        M::LineStrip => Mode::LineStrip,
        M::Triangles => Mode::Triangles,
        M::TriangleStrip => Mode::TriangleStrip,
        M::TriangleFan => Mode::TriangleFan,
    }
}

fn vec3s(f: Vec<f32>) -> Vec<Vec3> {
    f.chunks_exact(3).map(Vec3::from_slice).collect()
}

/// Reads one vertex array (every attribute as long as `POSITION`).
fn read_vertex_array(
    r: &Reader<'_>,
    prim: &gltf::Primitive<'_>,
    keys: AttributeAccessors,
    at: &str,
) -> Result<VertexArray, AvatarError> {
    use gltf::Semantic as S;
    let get = |s: &S| prim.get(s);
    let mut v = VertexArray {
        accessors: keys,
        ..Default::default()
    };
    let position = get(&S::Positions)
        .ok_or_else(|| AvatarError::at(r.path, format!("{at}/attributes"), "no POSITION"))?;
    v.positions = vec3s(r.floats(&position, &[3])?);
    let n = v.positions.len();
    let check = |name: &str, len: usize| {
        if len == n {
            Ok(())
        } else {
            Err(AvatarError::at(
                r.path,
                format!("{at}/attributes/{name}"),
                format!("{len} elements, POSITION has {n}"),
            ))
        }
    };
    if let Some(a) = get(&S::Normals) {
        v.normals = vec3s(r.floats(&a, &[3])?);
        check("NORMAL", v.normals.len())?;
    }
    if let Some(a) = get(&S::TexCoords(0)) {
        v.tex_coords = r
            .floats(&a, &[2])?
            .chunks_exact(2)
            .map(Vec2::from_slice)
            .collect();
        check("TEXCOORD_0", v.tex_coords.len())?;
    }
    if let Some(a) = get(&S::Colors(0)) {
        let d = super::accessor::dims(a.dimensions());
        v.colors = r
            .floats(&a, &[3, 4])?
            .chunks_exact(d)
            .map(|c| match c {
                [r, g, b] => Vec4::new(*r, *g, *b, 1.0),
                c => Vec4::from_slice(c),
            })
            .collect();
        check("COLOR_0", v.colors.len())?;
    }
    if let Some(a) = get(&S::Joints(0)) {
        let raw = r.unsigned(&a, &[4])?;
        let mut joints = Vec::with_capacity(raw.len() / 4);
        for j in raw.chunks_exact(4) {
            let mut out = [0u16; 4];
            for (o, &x) in out.iter_mut().zip(j) {
                *o = u16::try_from(x).map_err(|_| {
                    AvatarError::at(
                        r.path,
                        format!("{at}/attributes/JOINTS_0"),
                        "joint index over 65535",
                    )
                })?;
            }
            joints.push(out);
        }
        v.joints = joints;
        check("JOINTS_0", v.joints.len())?;
    }
    if let Some(a) = get(&S::Weights(0)) {
        v.weights = r
            .floats(&a, &[4])?
            .chunks_exact(4)
            .map(Vec4::from_slice)
            .collect();
        check("WEIGHTS_0", v.weights.len())?;
    }
    Ok(v)
}

fn read_meshes(
    r: &Reader<'_>,
    doc: &gltf::Document,
    avatar: &mut Avatar,
) -> Result<(), AvatarError> {
    use gltf::Semantic as S;
    let mut arrays: HashMap<AttributeAccessors, usize> = HashMap::new();
    let mut targets: HashMap<(Option<usize>, Option<usize>), usize> = HashMap::new();
    let mut total = 0usize;
    for mesh in doc.meshes() {
        let m = mesh.index();
        let mut primitives = Vec::new();
        let mut target_count = None;
        for prim in mesh.primitives() {
            let at = format!("/meshes/{m}/primitives/{}", prim.index());
            let idx = |s: &S| prim.get(s).map(|a| a.index());
            let keys = AttributeAccessors {
                position: idx(&S::Positions).ok_or_else(|| {
                    AvatarError::at(r.path, format!("{at}/attributes"), "no POSITION")
                })?,
                normal: idx(&S::Normals),
                tex_coord: idx(&S::TexCoords(0)),
                color: idx(&S::Colors(0)),
                joints: idx(&S::Joints(0)),
                weights: idx(&S::Weights(0)),
            };
            let vertices = match arrays.get(&keys) {
                Some(&k) => k,
                None => {
                    let v = read_vertex_array(r, &prim, keys, &at)?;
                    total += v.positions.len();
                    if total > MAX_ACCESSOR_ELEMENTS {
                        return Err(AvatarError::at(
                            r.path,
                            format!("{at}/attributes/POSITION"),
                            format!("more than the {MAX_ACCESSOR_ELEMENTS} vertices mimic reads"),
                        ));
                    }
                    avatar.vertex_arrays.push(v);
                    arrays.insert(keys, avatar.vertex_arrays.len() - 1);
                    avatar.vertex_arrays.len() - 1
                }
            };
            let n = avatar.vertex_arrays[vertices].positions.len();
            let indices = match prim.indices() {
                Some(a) => {
                    let i = r.unsigned(&a, &[1])?;
                    if let Some(bad) = i.iter().find(|&&i| i as usize >= n) {
                        return Err(AvatarError::at(
                            r.path,
                            format!("{at}/indices"),
                            format!("index {bad} past the {n} vertices"),
                        ));
                    }
                    i
                }
                None => (0..n as u32).collect(),
            };
            let prim_targets = read_targets(r, &prim, &at, n, &mut targets, avatar)?;
            if *target_count.get_or_insert(prim_targets.len()) != prim_targets.len() {
                return Err(AvatarError::at(
                    r.path,
                    format!("{at}/targets"),
                    "another number of morph targets than the mesh's first primitive",
                ));
            }
            primitives.push(Primitive {
                vertices,
                indices,
                indices_accessor: prim.indices().map(|a| a.index()),
                material: prim.material().index(),
                mode: mode(prim.mode()),
                targets: prim_targets,
            });
        }
        let target_names = avatar
            .document
            .pointer(&format!("/meshes/{m}/extras/targetNames"))
            .and_then(|v| v.as_array())
            .map(|a| {
                a.iter()
                    .filter_map(|s| s.as_str().map(str::to_string))
                    .collect()
            })
            .unwrap_or_default();
        avatar.meshes.push(Mesh {
            name: mesh.name().map(str::to_string),
            primitives,
            target_names,
            weights: mesh.weights().map(<[f32]>::to_vec).unwrap_or_default(),
        });
    }
    Ok(())
}

/// A primitive's morph targets as indices into [`Avatar::morph_targets`], each accessor pair read
/// once (`targets` maps pairs to indices), their deltas as many as the `n` vertices.
fn read_targets(
    r: &Reader<'_>,
    prim: &gltf::Primitive<'_>,
    at: &str,
    n: usize,
    targets: &mut HashMap<(Option<usize>, Option<usize>), usize>,
    avatar: &mut Avatar,
) -> Result<Vec<usize>, AvatarError> {
    let mut prim_targets = Vec::new();
    for (t, target) in prim.morph_targets().enumerate() {
        let tat = format!("{at}/targets/{t}");
        let key = (
            target.positions().map(|a| a.index()),
            target.normals().map(|a| a.index()),
        );
        let k = match targets.get(&key) {
            Some(&k) => k,
            None => {
                let mut mt = MorphTarget {
                    position_accessor: key.0,
                    normal_accessor: key.1,
                    ..Default::default()
                };
                if let Some(a) = target.positions() {
                    mt.positions = vec3s(r.floats(&a, &[3])?);
                }
                if let Some(a) = target.normals() {
                    mt.normals = vec3s(r.floats(&a, &[3])?);
                }
                avatar.morph_targets.push(mt);
                targets.insert(key, avatar.morph_targets.len() - 1);
                avatar.morph_targets.len() - 1
            }
        };
        let mt = &avatar.morph_targets[k];
        for (name, len) in [
            ("POSITION", mt.positions.len()),
            ("NORMAL", mt.normals.len()),
        ] {
            if len != 0 && len != n {
                return Err(AvatarError::at(
                    r.path,
                    format!("{tat}/{name}"),
                    format!("{len} deltas for {n} vertices"),
                ));
            }
        }
        prim_targets.push(k);
    }
    Ok(prim_targets)
}

fn read_skins(r: &Reader<'_>, doc: &gltf::Document) -> Result<Vec<Skin>, AvatarError> {
    let mut skins = Vec::new();
    for skin in doc.skins() {
        let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
        let inverse_bind_matrices = match skin.inverse_bind_matrices() {
            Some(a) => {
                let m: Vec<Mat4> = r
                    .floats(&a, &[16])?
                    .chunks_exact(16)
                    .map(Mat4::from_cols_slice)
                    .collect();
                if m.len() < joints.len() {
                    return Err(AvatarError::at(
                        r.path,
                        format!("/skins/{}/inverseBindMatrices", skin.index()),
                        format!("{} matrices for {} joints", m.len(), joints.len()),
                    ));
                }
                m
            }
            None => vec![Mat4::IDENTITY; joints.len()],
        };
        skins.push(Skin {
            name: skin.name().map(str::to_string),
            joints,
            inverse_bind_matrices,
            skeleton: skin.skeleton().map(|n| n.index()),
        });
    }
    Ok(skins)
}
