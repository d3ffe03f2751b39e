//! OBJ meshes in (through tobj, keeping the file's vertex order) and out.
//!
//! tobj re-indexes the vertices of every object, group or material in order of first use, so
//! the vertex numbers a rig file writes (OBJ `v` line k is vertex k-1) would not survive.
//! [`load_obj`] therefore first checks every line itself (errors name the line), then hands tobj
//! one model whose first faces visit every vertex in file order, and drops those faces again.

use crate::AssetError;
use glam::{Vec2, Vec3};
use mimic_types::Mesh;
use mimic_types::limits::{MAX_MESH_TRIANGLES, MAX_MESH_VERTICES};
use std::io::Write;
use std::path::Path;

/// Shape of a face corner: which of `v/vt/vn` it carries.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Corner {
    V,
    VVt,
    VVtVn,
    VVn,
}

impl Corner {
    fn of(token: &str) -> Corner {
        let parts: Vec<&str> = token.split('/').collect();
        match parts.as_slice() {
            [_] => Corner::V,
            [_, _] => Corner::VVt,
            [_, "", _] => Corner::VVn,
            _ => Corner::VVtVn,
        }
    }

    fn write(self, out: &mut String, v: usize) {
        use std::fmt::Write as _;
        let _ = match self {
            Corner::V => write!(out, " {v}"),
            Corner::VVt => write!(out, " {v}/1"),
            Corner::VVtVn => write!(out, " {v}/1/1"),
            Corner::VVn => write!(out, " {v}//1"),
        };
    }
}

/// Loads an OBJ mesh: positions in file order, polygons triangulated, texture coordinates if any.
pub fn load_obj(path: &Path) -> Result<Mesh, AssetError> {
    let text = crate::read::read_text(path, &mimic_types::limits::OBJ_FILE)?;
    parse_obj(path, &text)
}

fn obj_err(path: &Path, line: usize, message: impl Into<String>) -> AssetError {
    AssetError::Obj {
        path: path.to_path_buf(),
        line,
        message: message.into(),
    }
}

/// Parses OBJ text; `path` only names the file in errors.
pub fn parse_obj(path: &Path, text: &str) -> Result<Mesh, AssetError> {
    let mut vertex_lines = String::new();
    let mut face_lines = String::new();
    let (mut nv, mut nvt, mut nvn) = (0usize, 0usize, 0usize);
    let mut triangle_count = 0usize;
    let mut corner: Option<Corner> = None;
    for (k, raw) in text.lines().enumerate() {
        let line_no = k + 1;
        let line = raw.trim();
        let mut tokens = line.split_whitespace();
        match tokens.next() {
            Some("v") => {
                let coords: Vec<&str> = tokens.collect();
                if coords.len() < 3 {
                    return Err(obj_err(
                        path,
                        line_no,
                        format!("vertex has {} coordinates, needs 3", coords.len()),
                    ));
                }
                for c in &coords[..3] {
                    match c.parse::<f32>() {
                        Ok(x) if x.is_finite() => {}
                        _ => {
                            return Err(obj_err(
                                path,
                                line_no,
                                format!("vertex coordinate `{c}` is not a finite number"),
                            ));
                        }
                    }
                }
                nv += 1;
                if nv > MAX_MESH_VERTICES {
                    return Err(obj_err(
                        path,
                        line_no,
                        format!("more than {MAX_MESH_VERTICES} vertices, the most a mesh may have"),
                    ));
                }
                vertex_lines.push_str(line);
                vertex_lines.push('\n');
            }
            Some("vt") => {
                nvt += 1;
                vertex_lines.push_str(line);
                vertex_lines.push('\n');
            }
            Some("vn") => {
                nvn += 1;
                vertex_lines.push_str(line);
                vertex_lines.push('\n');
            }
            Some("f") => {
                let corners: Vec<&str> = tokens.collect();
                if corners.len() < 3 {
                    return Err(obj_err(
                        path,
                        line_no,
                        format!("face has {} corners, needs at least 3", corners.len()),
                    ));
                }
                for c in &corners {
                    let shape = Corner::of(c);
                    if *corner.get_or_insert(shape) != shape {
                        return Err(obj_err(
                            path,
                            line_no,
                            format!("face corner `{c}` mixes v/vt/vn forms with earlier faces"),
                        ));
                    }
                    for (part, count, what) in c
                        .split('/')
                        .zip([nv, nvt, nvn])
                        .zip(["vertex", "texture coordinate", "normal"])
                        .map(|((p, n), w)| (p, n, w))
                    {
                        if part.is_empty() {
                            continue;
                        }
                        match part.parse::<i64>() {
                            Ok(i) if i >= 1 && (i as usize) <= count => {}
                            Ok(i) if i < 0 => {
                                return Err(obj_err(
                                    path,
                                    line_no,
                                    format!(
                                        "relative (negative) {what} index {i} is not supported"
                                    ),
                                ));
                            }
                            Ok(i) => {
                                return Err(obj_err(
                                    path,
                                    line_no,
                                    format!(
                                        "{what} index {i} is out of range: {count} defined so far"
                                    ),
                                ));
                            }
                            Err(_) => {
                                return Err(obj_err(
                                    path,
                                    line_no,
                                    format!("{what} index `{part}` is not an integer"),
                                ));
                            }
                        }
                    }
                }
                triangle_count += corners.len() - 2;
                if triangle_count > MAX_MESH_TRIANGLES {
                    return Err(obj_err(
                        path,
                        line_no,
                        format!(
                            "more than {MAX_MESH_TRIANGLES} triangles, the most a mesh may have"
                        ),
                    ));
                }
                face_lines.push_str(line);
                face_lines.push('\n');
            }
            // Objects, groups, materials and smoothing groups would split tobj's output into
            // separately re-indexed models; points and lines are not surfaces.
            _ => {}
        }
    }
    if nv == 0 {
        return Err(obj_err(path, 0, "no vertices"));
    }
    let shape = corner.unwrap_or(Corner::V);
    // Dummy triangles visiting vertices 1..=nv in order fix tobj's first-use numbering to file order.
    let mut buf = vertex_lines;
    let dummy_count = nv.div_ceil(3);
    for t in 0..dummy_count {
        buf.push('f');
        for k in 0..3 {
            shape.write(&mut buf, (3 * t + k + 1).min(nv));
        }
        buf.push('\n');
    }
    buf.push_str(&face_lines);

    let options = tobj::LoadOptions {
        single_index: false,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _materials) = tobj::load_obj_buf(&mut buf.as_bytes(), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| obj_err(path, 0, format!("tobj: {e}")))?;
    let [model] = models.as_slice() else {
        return Err(obj_err(
            path,
            0,
            format!(
                "expected one model after flattening, tobj gave {}",
                models.len()
            ),
        ));
    };
    let m = &model.mesh;
    if m.positions.len() != 3 * nv {
        return Err(obj_err(
            path,
            0,
            format!("tobj kept {} of {nv} vertices", m.positions.len() / 3),
        ));
    }
    let positions: Vec<Vec3> = m
        .positions
        .chunks_exact(3)
        .map(|p| Vec3::new(p[0], p[1], p[2]))
        .collect();
    let skip = 3 * dummy_count;
    let triangles: Vec<[u32; 3]> = m.indices[skip..]
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    let (uvs, uv_triangles) =
        if !m.texcoords.is_empty() && m.texcoord_indices.len() == m.indices.len() {
            (
                m.texcoords
                    .chunks_exact(2)
                    .map(|t| Vec2::new(t[0], t[1]))
                    .collect(),
                m.texcoord_indices[skip..]
                    .chunks_exact(3)
                    .map(|t| [t[0], t[1], t[2]])
                    .collect(),
            )
        } else {
            (Vec::new(), Vec::new())
        };
    let mesh = Mesh {
        positions,
        triangles,
        uvs,
        uv_triangles,
    };
    mesh.validate()
        .map_err(|e| obj_err(path, 0, e.to_string()))?;
    Ok(mesh)
}

/// Writes positions (and optional normals) with triangles as an OBJ; `header` becomes a comment.
pub fn write_obj<W: Write>(
    w: &mut W,
    header: &str,
    positions: &[Vec3],
    normals: Option<&[Vec3]>,
    triangles: &[[u32; 3]],
) -> std::io::Result<()> {
    for line in header.lines() {
        writeln!(w, "# {line}")?;
    }
    for p in positions {
        writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
    }
    if let Some(ns) = normals {
        for n in ns {
            writeln!(w, "vn {} {} {}", n.x, n.y, n.z)?;
        }
        for t in triangles {
            writeln!(
                w,
                "f {a}//{a} {b}//{b} {c}//{c}",
                a = t[0] + 1,
                b = t[1] + 1,
                c = t[2] + 1
            )?;
        }
    } else {
        for t in triangles {
            writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    const GROUPED: &str = "\
# two groups whose faces use vertices out of file order
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 0 0
vt 0 0
vt 1 1
g second
usemtl b
f 5/1 2/2 3/1
g first
usemtl a
f 4/1 1/2 2/1 3/2
";

    #[test]
    fn keeps_file_vertex_order_across_groups_and_triangulates() {
        let m = parse_obj(Path::new("t.obj"), GROUPED).unwrap();
        assert_eq!(m.positions[4], Vec3::new(2.0, 0.0, 0.0));
        assert_eq!(m.positions[3], Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(m.triangles.len(), 3);
        assert_eq!(m.triangles[0], [4, 1, 2]);
        // The quad 4 1 2 3 becomes two triangles over the same four vertices.
        let mut quad: Vec<u32> = m.triangles[1..].iter().flatten().copied().collect();
        quad.sort();
        quad.dedup();
        assert_eq!(quad, vec![0, 1, 2, 3]);
        assert_eq!(m.uv_triangles.len(), 3);
        assert_eq!(m.uv_triangles[0], [0, 1, 0]);
    }

    #[test]
    fn errors_name_the_line() {
        let bad = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n";
        let e = parse_obj(Path::new("x.obj"), bad).unwrap_err().to_string();
        assert_eq!(
            e,
            "x.obj:4: vertex index 7 is out of range: 3 defined so far"
        );
        let bad = "v 0 0 0\nv 1 nan 0\n";
        let e = parse_obj(Path::new("x.obj"), bad).unwrap_err().to_string();
        assert!(e.starts_with("x.obj:2: vertex coordinate `nan`"), "{e}");
    }

    #[test]
    fn vertex_and_triangle_counts_are_capped() {
        let mut text = "v 0 0 0\n".repeat(MAX_MESH_VERTICES + 1);
        let e = parse_obj(Path::new("x.obj"), &text)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            format!(
                "x.obj:{}: more than 1048576 vertices, the most a mesh may have",
                MAX_MESH_VERTICES + 1
            )
        );
        text = "v 0 0 0\nv 1 0 0\nv 0 1 0\n".to_string();
        // One polygon of MAX + 3 corners triangulates into MAX + 1 triangles.
        text.push('f');
        for k in 0..MAX_MESH_TRIANGLES + 3 {
            text.push_str([" 1", " 2", " 3"][k % 3]);
        }
        text.push('\n');
        let e = parse_obj(Path::new("x.obj"), &text)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "x.obj:4: more than 2097152 triangles, the most a mesh may have"
        );
    }

    #[test]
    fn oversized_and_device_files_are_refused_by_the_loader() {
        let dir = tempfile::tempdir().unwrap();
        let big = dir.path().join("big.obj");
        let f = std::fs::File::create(&big).unwrap();
        f.set_len(mimic_types::limits::OBJ_FILE.max_bytes + 1)
            .unwrap();
        let e = load_obj(&big).unwrap_err().to_string();
        assert!(
            e.ends_with("big.obj: 67108865 bytes, over the 64 MiB cap for OBJ meshes"),
            "{e}"
        );
        #[cfg(unix)]
        {
            let e = load_obj(Path::new("/dev/zero")).unwrap_err().to_string();
            assert_eq!(
                e,
                "/dev/zero: not a regular file but a character device; OBJ meshes are read only from regular files"
            );
        }
    }

    #[test]
    fn missing_file_names_the_file() {
        let e = load_obj(Path::new("/no/such/head.obj"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("/no/such/head.obj: "), "{e}");
    }

    #[test]
    fn write_then_load_round_trips() {
        let m = parse_obj(Path::new("t.obj"), GROUPED).unwrap();
        let mut out = Vec::new();
        write_obj(&mut out, "round trip", &m.positions, None, &m.triangles).unwrap();
        let back = parse_obj(Path::new("rt.obj"), std::str::from_utf8(&out).unwrap()).unwrap();
        assert_eq!(back.positions, m.positions);
        assert_eq!(back.triangles, m.triangles);
    }

    #[test]
    fn loads_the_ict_head_in_file_order() {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../configs/meshes/ict-facekit/generic_neutral_mesh.obj");
        let Ok(text) = std::fs::read_to_string(&path) else {
            eprintln!("skipped: {} not present", path.display());
            return;
        };
        let m = parse_obj(&path, &text).unwrap();
        assert_eq!(m.positions.len(), 26719);
        // 25836 quads -> 2 triangles each, plus 548 triangles.
        assert_eq!(m.triangles.len(), 2 * 25836 + 548);
        // Independent truth: the first `v` line of the file is vertex 0.
        let first_v = text.lines().find(|l| l.starts_with("v ")).unwrap();
        let c: Vec<f32> = first_v
            .split_whitespace()
            .skip(1)
            .map(|x| x.parse().unwrap())
            .collect();
        assert_eq!(m.positions[0], Vec3::new(c[0], c[1], c[2]));
        let last_v = text.lines().rfind(|l| l.starts_with("v ")).unwrap();
        let c: Vec<f32> = last_v
            .split_whitespace()
            .skip(1)
            .map(|x| x.parse().unwrap())
            .collect();
        assert_eq!(m.positions[26718], Vec3::new(c[0], c[1], c[2]));
    }
}
