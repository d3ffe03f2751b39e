//! Morph targets: loading a rig's `[[morph_targets]]` (an OBJ each, or a shape of a shape pack)
//! as deltas, and the morph data file.
//!
//! The morph data file (`docs/morph-format.md`) is the GPU morph-target method's text format: XYZ
//! rows, the position delta and the normal delta of a vertex alternating, vertex by vertex, target
//! after target, with a counts line and one `# target <name>` line before each target.

use crate::AssetError;
use crate::span::{line_of, toml_error};
use glam::Vec3;
use mimic_solve::vertex_normals;
use mimic_types::{Mesh, MorphTarget, Rig, limits};
use serde::Deserialize;
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

/// Decimals printed per coordinate in the morph data file.
pub const MORPH_FILE_DECIMALS: usize = 6;

/// One `[[morph_targets]]` entry of a rig file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MorphTargetEntry {
    /// Target name (ARKit names where they apply, e.g. `jawOpen`).
    pub name: String,
    /// OBJ on the neutral's topology, relative to the rig file (or `shapes`).
    #[serde(default)]
    pub obj: Option<PathBuf>,
    /// A shape pack (`*.shapes`, relative to the rig file) holding the target under its name,
    /// on the rig mesh's vertices (`mimic rig new --blendshapes arkit` writes one).
    #[serde(default)]
    pub shapes: Option<PathBuf>,
}

/// The deltas of `target` against `neutral`; `path` names the target in errors.
///
/// Fails unless both meshes have the same vertex count and the same triangles.
pub fn morph_target(
    name: &str,
    neutral: &Mesh,
    target: &Mesh,
    path: &Path,
) -> Result<MorphTarget, AssetError> {
    let topology = |message: String| AssetError::MorphTopology {
        path: path.to_path_buf(),
        message,
    };
    let n = neutral.vertex_count();
    if target.vertex_count() != n {
        return Err(topology(format!(
            "{} vertices, the neutral has {n}",
            target.vertex_count()
        )));
    }
    if target.triangles.len() != neutral.triangles.len() {
        return Err(topology(format!(
            "{} triangles, the neutral has {}",
            target.triangles.len(),
            neutral.triangles.len()
        )));
    }
    if let Some(t) =
        (0..target.triangles.len()).find(|&t| target.triangles[t] != neutral.triangles[t])
    {
        return Err(topology(format!(
            "triangle {t} is {:?}, the neutral's is {:?}",
            target.triangles[t], neutral.triangles[t]
        )));
    }
    let deltas = target
        .positions
        .iter()
        .zip(&neutral.positions)
        .map(|(t, p)| *t - *p)
        .collect();
    Ok(with_normals(name, neutral, &target.positions, deltas))
}

/// The target `name` moving `neutral`'s vertices to `moved` by `deltas`, with the normal deltas
/// that makes (the moved mesh's vertex normals minus the neutral's, on the neutral's triangles).
fn with_normals(name: &str, neutral: &Mesh, moved: &[Vec3], deltas: Vec<Vec3>) -> MorphTarget {
    let n = neutral.vertex_count();
    let mut n0 = vec![Vec3::ZERO; n];
    let mut n1 = vec![Vec3::ZERO; n];
    vertex_normals(&neutral.positions, &neutral.triangles, &mut n0);
    vertex_normals(moved, &neutral.triangles, &mut n1);
    MorphTarget {
        name: name.to_string(),
        position_deltas: deltas,
        normal_deltas: n1.iter().zip(&n0).map(|(a, b)| *a - *b).collect(),
    }
}

/// The morph targets listed in the rig file at `rig_path`, as deltas against `rig`'s mesh.
///
/// `rig` is the rig loaded from the same file ([`crate::load_rig`]); a rig without
/// `[[morph_targets]]` gives an empty list. An entry names an OBJ (`obj`) or a shape pack
/// (`shapes`, each pack read once). Errors name the rig file, the entry's line and the OBJ or pack.
pub fn load_morph_targets(rig_path: &Path, rig: &Rig) -> Result<Vec<MorphTarget>, AssetError> {
    let text = crate::read::read_text(rig_path, &limits::RIG_FILE)?;
    let file: crate::RigFile = toml::from_str(&text).map_err(|e| toml_error(rig_path, &text, e))?;
    let dir = rig_path.parent().unwrap_or(Path::new("."));
    let mut seen = std::collections::HashSet::new();
    let mut packs: std::collections::HashMap<PathBuf, crate::ShapePack> = Default::default();
    let mut targets = Vec::with_capacity(file.morph_targets.len().min(limits::MAX_MORPH_TARGETS));
    for (k, entry) in file.morph_targets.iter().enumerate() {
        let line = line_of(&text, entry.span().start);
        if k == limits::MAX_MORPH_TARGETS {
            return Err(AssetError::Toml {
                path: rig_path.to_path_buf(),
                line,
                message: format!(
                    "more than {} morph targets, the most a rig may have",
                    limits::MAX_MORPH_TARGETS
                ),
            });
        }
        let e = entry.get_ref();
        let wrap = |source: AssetError| AssetError::MorphTarget {
            path: rig_path.to_path_buf(),
            line,
            name: e.name.clone(),
            cause: Box::new(source),
        };
        if e.name.is_empty() || e.name.chars().any(char::is_whitespace) {
            return Err(AssetError::Toml {
                path: rig_path.to_path_buf(),
                line,
                message: format!("morph target name `{}` is empty or has spaces", e.name),
            });
        }
        if !seen.insert(e.name.clone()) {
            return Err(AssetError::Toml {
                path: rig_path.to_path_buf(),
                line,
                message: format!("morph target `{}` appears twice", e.name),
            });
        }
        let target = match (&e.obj, &e.shapes) {
            (Some(obj), None) => {
                let obj = dir.join(obj);
                let turn = file.turn(&text).unwrap_or_default();
                let mesh = crate::rig::turn_mesh(crate::load_obj(&obj).map_err(wrap)?, turn);
                morph_target(&e.name, &rig.mesh, &mesh, &obj).map_err(wrap)?
            }
            (None, Some(pack)) => {
                let pack = dir.join(pack);
                if !packs.contains_key(&pack) {
                    let loaded = crate::load_shape_pack(&pack).map_err(wrap)?;
                    packs.insert(pack.clone(), loaded);
                }
                packed_target(&e.name, &rig.mesh, &packs[&pack], &pack).map_err(wrap)?
            }
            _ => {
                return Err(AssetError::Toml {
                    path: rig_path.to_path_buf(),
                    line,
                    message: format!(
                        "morph target `{}` needs one of `obj` (an OBJ) and `shapes` (a shape pack)",
                        e.name
                    ),
                });
            }
        };
        targets.push(target);
    }
    // Shapes that open the chin but leave the lower teeth behind carry them (docs/parts.md).
    mimic_solve::jaw::carry_jaw(rig, &mut targets);
    Ok(targets)
}

/// The target named `name` of shape pack `pack` (read from `path`) on `neutral`: its position
/// deltas and the normal deltas they make.
pub fn packed_target(
    name: &str,
    neutral: &Mesh,
    pack: &crate::ShapePack,
    path: &Path,
) -> Result<MorphTarget, AssetError> {
    let topology = |message: String| AssetError::MorphTopology {
        path: path.to_path_buf(),
        message,
    };
    let n = neutral.vertex_count();
    if pack.vertex_count != n {
        return Err(topology(format!(
            "{} vertices, the neutral has {n}",
            pack.vertex_count
        )));
    }
    let shape = pack
        .get(name)
        .ok_or_else(|| topology(format!("no shape `{name}` in the pack")))?;
    let moved: Vec<Vec3> = neutral
        .positions
        .iter()
        .zip(&shape.deltas)
        .map(|(p, d)| *p + *d)
        .collect();
    Ok(with_normals(name, neutral, &moved, shape.deltas.clone()))
}

/// Writes targets as a morph data file; `comment` lines go into the header.
///
/// # Panics
/// If the targets do not all have the same vertex count in positions and normals.
pub fn write_morph_file<W: Write>(
    mut w: W,
    comment: &str,
    targets: &[MorphTarget],
) -> std::io::Result<()> {
    let n = targets.first().map_or(0, MorphTarget::vertex_count);
    assert!(
        targets
            .iter()
            .all(|t| t.position_deltas.len() == n && t.normal_deltas.len() == n),
        "write_morph_file: targets of different vertex counts"
    );
    writeln!(
        w,
        "# mimic morph data: XYZ rows, position delta and normal delta alternating, vertex by vertex, target after target"
    )?;
    for line in comment.lines() {
        writeln!(w, "# {line}")?;
    }
    writeln!(w, "{} {n}", targets.len())?;
    let d = MORPH_FILE_DECIMALS;
    for t in targets {
        writeln!(w, "# target {}", t.name)?;
        for (p, q) in t.position_deltas.iter().zip(&t.normal_deltas) {
            writeln!(w, "{:.d$} {:.d$} {:.d$}", p.x, p.y, p.z)?;
            writeln!(w, "{:.d$} {:.d$} {:.d$}", q.x, q.y, q.z)?;
        }
    }
    w.flush()
}

/// Reads a morph data file; `path` names it in errors, which carry the 1-based line.
pub fn read_morph_file<R: BufRead>(r: R, path: &Path) -> Result<Vec<MorphTarget>, AssetError> {
    let err = |line: usize, message: String| AssetError::MorphFile {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut lines = r.lines();
    let mut no = 0usize;
    // The next line and its number; at the end of the file, an error saying what was expected.
    let mut next = |what: &dyn Fn() -> String| -> Result<(usize, String), AssetError> {
        no += 1;
        match lines.next() {
            Some(Ok(l)) => Ok((no, l)),
            Some(Err(e)) => Err(AssetError::io(path, e)),
            None => Err(err(no, format!("the file ends before {}", what()))),
        }
    };
    let counts_what = || "the counts line `<targets> <vertices>`".to_string();
    let (counts_no, counts) = loop {
        let (no, l) = next(&counts_what)?;
        if !l.trim_start().starts_with('#') {
            break (no, l);
        }
    };
    let parsed: Vec<usize> = counts
        .split_whitespace()
        .map_while(|f| f.parse().ok())
        .collect();
    let [k, n] = parsed[..] else {
        return Err(err(
            counts_no,
            format!("expected the counts `<targets> <vertices>`, found `{counts}`"),
        ));
    };
    if counts.split_whitespace().count() != 2 {
        return Err(err(
            counts_no,
            format!("expected the counts `<targets> <vertices>`, found `{counts}`"),
        ));
    }
    if k > limits::MAX_MORPH_TARGETS || n > limits::MAX_MESH_VERTICES {
        return Err(err(
            counts_no,
            format!(
                "counts `{k} {n}` over the maximum of {} targets of {} vertices",
                limits::MAX_MORPH_TARGETS,
                limits::MAX_MESH_VERTICES
            ),
        ));
    }
    let mut targets = Vec::with_capacity(k);
    for t in 0..k {
        let (no, l) = next(&|| format!("target {} of {k}", t + 1))?;
        let name = l
            .strip_prefix("# target ")
            .map(str::trim)
            .filter(|s| !s.is_empty() && !s.contains(char::is_whitespace))
            .ok_or_else(|| {
                err(
                    no,
                    format!(
                        "expected `# target <name>` to start target {} of {k}",
                        t + 1
                    ),
                )
            })?
            .to_string();
        let mut position_deltas = Vec::with_capacity(n.min(1 << 24));
        let mut normal_deltas = Vec::with_capacity(n.min(1 << 24));
        for v in 0..2 * n {
            let what = || {
                format!(
                    "row {} of target `{name}` (2 x {n} rows: position and normal per vertex)",
                    v + 1
                )
            };
            let (no, l) = next(&what)?;
            let p = parse_row(&l).map_err(|m| err(no, format!("{m} in {}", what())))?;
            if v % 2 == 0 {
                position_deltas.push(p);
            } else {
                normal_deltas.push(p);
            }
        }
        targets.push(MorphTarget {
            name,
            position_deltas,
            normal_deltas,
        });
    }
    loop {
        match next(&String::new) {
            Ok((_, l)) if l.trim().is_empty() => {}
            Ok((no, _)) => {
                return Err(err(
                    no,
                    format!("more rows than the counts line's {k} targets x {n} vertices announce"),
                ));
            }
            Err(AssetError::MorphFile { .. }) => return Ok(targets),
            Err(e) => return Err(e),
        }
    }
}

/// One `x y z` row.
fn parse_row(l: &str) -> Result<Vec3, String> {
    let mut it = l.split_whitespace();
    let mut v = [0f32; 3];
    for (i, slot) in v.iter_mut().enumerate() {
        let s = it
            .next()
            .ok_or_else(|| format!("expected 3 numbers (x y z), found {i}"))?;
        *slot = s
            .parse::<f32>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("`{s}` is not a finite number"))?;
    }
    if it.next().is_some() {
        return Err(format!(
            "expected 3 numbers (x y z), found {}",
            l.split_whitespace().count()
        ));
    }
    Ok(Vec3::from_array(v))
}

/// Writes a morph data file to `path`.
pub fn save_morph_file(
    path: &Path,
    comment: &str,
    targets: &[MorphTarget],
) -> Result<(), AssetError> {
    let file = std::fs::File::create(path).map_err(|e| AssetError::io(path, e))?;
    write_morph_file(std::io::BufWriter::new(file), comment, targets)
        .map_err(|e| AssetError::io(path, e))
}

/// Reads the morph data file at `path`.
pub fn load_morph_file(path: &Path) -> Result<Vec<MorphTarget>, AssetError> {
    let file = crate::read::open_capped(path, &limits::MORPH_FILE)?;
    read_morph_file(std::io::BufReader::new(file), path)
}

/// Largest difference a value may show after printing with [`MORPH_FILE_DECIMALS`] decimals and
/// parsing back to f32: half the last printed digit plus half an f32 ulp of the value.
pub fn round_trip_tolerance(v: f32) -> f32 {
    0.5 * 10f32.powi(-(MORPH_FILE_DECIMALS as i32)) + v.abs() * f32::EPSILON
}

/// Largest component difference between two delta lists (`a` the original), and whether every
/// component is within [`round_trip_tolerance`] of the original's.
pub fn compare_deltas(a: &[glam::Vec3], b: &[glam::Vec3]) -> (f32, bool) {
    let mut max = 0f32;
    let mut ok = true;
    for (p, q) in a.iter().zip(b) {
        for (x, y) in p.to_array().into_iter().zip(q.to_array()) {
            let e = (x - y).abs();
            max = max.max(e);
            ok &= e <= round_trip_tolerance(x);
        }
    }
    (max, ok)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(z: f32) -> Mesh {
        Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, z), Vec3::Y],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            ..Mesh::default()
        }
    }

    fn target(name: &str, scale: f32) -> MorphTarget {
        MorphTarget {
            name: name.into(),
            position_deltas: (0..3)
                .map(|i| Vec3::new(0.1234567 * scale, -(i as f32) * 1.75, 3.0e-7))
                .collect(),
            normal_deltas: (0..3)
                .map(|i| Vec3::new(-0.5, 0.25 * i as f32, 1.0 / 3.0))
                .collect(),
        }
    }

    fn text_of(targets: &[MorphTarget]) -> String {
        let mut buf = Vec::new();
        write_morph_file(&mut buf, "rig test\nunits cm", targets).unwrap();
        String::from_utf8(buf).unwrap()
    }

    fn read(text: &str) -> Result<Vec<MorphTarget>, AssetError> {
        read_morph_file(text.as_bytes(), Path::new("m.txt"))
    }

    #[test]
    fn deltas_are_target_minus_neutral_with_normal_change() {
        let t = morph_target("lift", &quad(0.0), &quad(1.0), Path::new("lift.obj")).unwrap();
        assert_eq!(t.position_deltas[2], Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(t.position_deltas[0], Vec3::ZERO);
        // Flat neutral: every normal is +z. Lifting corner 2 by 1 tilts triangle [0,1,2] to
        // normal (0,-1,1)/sqrt2 (area sqrt2/2) and [0,2,3] to (-1,0,1)/sqrt2; vertex 1 only sees
        // the first, so its normal delta is (0,-1,1)/sqrt2 - (0,0,1).
        let s = std::f32::consts::FRAC_1_SQRT_2;
        assert!((t.normal_deltas[1] - Vec3::new(0.0, -s, s - 1.0)).length() < 1e-6);
        assert!((t.normal_deltas[3] - Vec3::new(-s, 0.0, s - 1.0)).length() < 1e-6);
    }

    #[test]
    fn topology_mismatch_names_the_file() {
        let mut short = quad(0.0);
        short.positions.pop();
        short.triangles.pop();
        let e = morph_target("x", &quad(0.0), &short, Path::new("jawOpen.obj"))
            .unwrap_err()
            .to_string();
        assert_eq!(e, "jawOpen.obj: 3 vertices, the neutral has 4");
        let mut flipped = quad(0.0);
        flipped.triangles[1] = [0, 3, 2];
        let e = morph_target("x", &quad(0.0), &flipped, Path::new("a.obj"))
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "a.obj: triangle 1 is [0, 3, 2], the neutral's is [0, 2, 3]"
        );
    }

    #[test]
    fn round_trip_is_exact_to_the_printed_precision() {
        let targets = [target("jawOpen", 1.0), target("mouthSmile_L", -2.0)];
        let text = text_of(&targets);
        let back = read(&text).unwrap();
        assert_eq!(back.len(), 2);
        for (a, b) in targets.iter().zip(&back) {
            assert_eq!(a.name, b.name);
            // Printed to 6 decimals: |printed - value| <= 0.5e-6; parsing back to f32 adds at
            // most half an ulp of values below 4 (2^-22 / 2 ~ 1.2e-7).
            let tol = 0.5e-6 + 1.2e-7;
            for (p, q) in a
                .position_deltas
                .iter()
                .chain(&a.normal_deltas)
                .zip(b.position_deltas.iter().chain(&b.normal_deltas))
            {
                assert!((*p - *q).abs().max_element() <= tol, "{p} {q}");
            }
        }
        // And the printed text itself survives a second trip unchanged.
        assert_eq!(text_of(&back), text);
        assert!(text.contains("\n2 3\n# target jawOpen\n0.123457 -0.000000 0.000000\n"));
    }

    #[test]
    fn malformed_files_give_line_numbers() {
        let good = text_of(&[target("a", 1.0)]);
        let lines: Vec<&str> = good.lines().collect();
        // Header: 1 format line + 2 comment lines, counts on line 4, `# target a` on 5, rows 6..=11.
        assert_eq!(lines[3], "1 3");
        let with = |i: usize, s: &str| {
            let mut l = lines.clone();
            l[i] = s;
            l.join("\n")
        };
        let e = |t: String| read(&t).unwrap_err().to_string();
        assert!(
            e(with(7, "1 2")).starts_with("m.txt:8: expected 3 numbers (x y z), found 2"),
            "{}",
            e(with(7, "1 2"))
        );
        assert!(e(with(8, "1 2 x")).starts_with("m.txt:9: `x` is not a finite number"));
        assert!(e(with(8, "1 2 3 4")).starts_with("m.txt:9: expected 3 numbers (x y z), found 4"));
        assert!(e(with(8, "1 nan 3")).starts_with("m.txt:9: `nan` is not a finite number"));
        assert!(e(with(3, "1")).starts_with("m.txt:4: expected the counts"));
        assert!(e(with(4, "target a")).starts_with("m.txt:5: expected `# target <name>`"));
        assert_eq!(
            e(with(3, "2 3")),
            "m.txt:12: the file ends before target 2 of 2"
        );
        assert_eq!(
            e(with(3, "1 4")),
            "m.txt:12: the file ends before row 7 of target `a` (2 x 4 rows: position and normal per vertex)"
        );
        assert_eq!(
            e(format!("{good}0 0 0\n")),
            "m.txt:12: more rows than the counts line's 1 targets x 3 vertices announce"
        );
    }

    #[test]
    fn counts_over_the_maxima_are_refused_at_the_counts_line() {
        let e = |t: &str| read(t).unwrap_err().to_string();
        assert_eq!(
            e("# h\n1 1048577\n"),
            "m.txt:2: counts `1 1048577` over the maximum of 1024 targets of 1048576 vertices"
        );
        assert!(e("# h\n1025 3\n").starts_with("m.txt:2: counts `1025 3` over the maximum"));
        // At the maxima, a short file is an ordinary early end (nothing was allocated for it).
        assert_eq!(
            e("# h\n1024 1048576\n"),
            "m.txt:3: the file ends before target 1 of 1024"
        );
    }

    #[test]
    fn morph_file_loader_refuses_devices_and_oversized_files() {
        let dir = tempfile::tempdir().unwrap();
        let big = dir.path().join("big.txt");
        let f = std::fs::File::create(&big).unwrap();
        f.set_len(limits::MORPH_FILE.max_bytes + 1).unwrap();
        let e = load_morph_file(&big).unwrap_err().to_string();
        assert!(
            e.ends_with("big.txt: 268435457 bytes, over the 256 MiB cap for morph data files"),
            "{e}"
        );
        #[cfg(unix)]
        {
            let e = load_morph_file(Path::new("/dev/zero"))
                .unwrap_err()
                .to_string();
            assert!(
                e.starts_with("/dev/zero: not a regular file but a character device"),
                "{e}"
            );
        }
    }

    #[test]
    fn rig_targets_load_and_bad_topology_names_rig_line_and_obj() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let quad_obj = |z: f32| format!("v 0 0 0\nv 1 0 0\nv 1 1 {z}\nv 0 1 0\nf 1 2 3\nf 1 3 4\n");
        std::fs::write(d.join("n.obj"), quad_obj(0.0)).unwrap();
        std::fs::write(d.join("up.obj"), quad_obj(2.0)).unwrap();
        std::fs::write(d.join("tri.obj"), "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n").unwrap();
        let rig_text = |second: &str| {
            format!(
                "name = \"q\"\nunits = \"cm\"\nmesh = \"n.obj\"\n[regions]\ntop_from = 0.7\nbottom_below = 0.3\nband = 0.1\n\n[[controls]]\nfdp = \"8.3\"\nvertex = 2\nregion = \"bottom\"\n\n[[morph_targets]]\nname = \"up\"\nobj = \"up.obj\"\n\n[[morph_targets]]\nname = \"other\"\nobj = \"{second}\"\n"
            )
        };
        let path = d.join("q.toml");
        std::fs::write(&path, rig_text("up.obj")).unwrap();
        let rig = crate::load_rig(&path).unwrap();
        let t = load_morph_targets(&path, &rig).unwrap();
        assert_eq!(t.len(), 2);
        assert_eq!(t[0].name, "up");
        assert_eq!(t[0].position_deltas[2], Vec3::new(0.0, 0.0, 2.0));
        std::fs::write(&path, rig_text("tri.obj")).unwrap();
        let e = load_morph_targets(&path, &rig).unwrap_err().to_string();
        assert!(
            e.contains("q.toml:18: morph target `other`: ")
                && e.ends_with("tri.obj: 3 vertices, the neutral has 4"),
            "{e}"
        );
    }

    #[test]
    fn rig_targets_load_from_a_shape_pack_and_an_entry_names_one_source() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let quad_obj = |z: f32| format!("v 0 0 0\nv 1 0 0\nv 1 1 {z}\nv 0 1 0\nf 1 2 3\nf 1 3 4\n");
        std::fs::write(d.join("n.obj"), quad_obj(0.0)).unwrap();
        std::fs::write(d.join("up.obj"), quad_obj(2.0)).unwrap();
        let shape = |name: &str, z: f32| crate::PackedShape {
            name: name.into(),
            deltas: vec![Vec3::ZERO, Vec3::ZERO, Vec3::new(0.0, 0.0, z), Vec3::ZERO],
        };
        let pack = crate::ShapePack {
            vertex_count: 4,
            quantum: 1e-3,
            shapes: vec![shape("jawOpen", 2.0), shape("eyeBlinkLeft", -1.0)],
        };
        crate::save_shape_pack(&d.join("q.arkit.shapes"), &pack).unwrap();
        let head = "name = \"q\"\nunits = \"cm\"\nmesh = \"n.obj\"\n[regions]\ntop_from = 0.7\nbottom_below = 0.3\nband = 0.1\n\n[[controls]]\nfdp = \"8.3\"\nvertex = 2\nregion = \"bottom\"\n";
        let path = d.join("q.toml");
        let entries = "[[morph_targets]]\nname = \"up\"\nobj = \"up.obj\"\n\n[[morph_targets]]\nname = \"eyeBlinkLeft\"\nshapes = \"q.arkit.shapes\"\n\n[[morph_targets]]\nname = \"jawOpen\"\nshapes = \"q.arkit.shapes\"\n";
        std::fs::write(&path, format!("{head}\n{entries}")).unwrap();
        let rig = crate::load_rig(&path).unwrap();
        let t = load_morph_targets(&path, &rig).unwrap();
        let names: Vec<&str> = t.iter().map(|t| t.name.as_str()).collect();
        assert_eq!(names, ["up", "eyeBlinkLeft", "jawOpen"]);
        assert_eq!(t[2].position_deltas, t[0].position_deltas);
        assert_eq!(t[2].normal_deltas, t[0].normal_deltas);
        assert_eq!(t[1].position_deltas[2], Vec3::new(0.0, 0.0, -1.0));
        // A name the pack lacks, and an entry naming both sources or neither.
        let bad = "[[morph_targets]]\nname = \"tongueOut\"\nshapes = \"q.arkit.shapes\"\n";
        std::fs::write(&path, format!("{head}\n{bad}")).unwrap();
        let e = load_morph_targets(&path, &rig).unwrap_err().to_string();
        assert!(
            e.contains("q.toml:14: morph target `tongueOut`: ")
                && e.ends_with("q.arkit.shapes: no shape `tongueOut` in the pack"),
            "{e}"
        );
        let both = "[[morph_targets]]\nname = \"jawOpen\"\nobj = \"up.obj\"\nshapes = \"q.arkit.shapes\"\n";
        std::fs::write(&path, format!("{head}\n{both}")).unwrap();
        let e = load_morph_targets(&path, &rig).unwrap_err().to_string();
        assert!(e.contains("needs one of `obj`"), "{e}");
    }

    #[test]
    fn deltas_compare_within_the_printed_precision() {
        use glam::Vec3;
        let a = [Vec3::new(1.0, -2.0, 0.5)];
        // Half a printed digit (5e-7) off is within; 2e-6 is not.
        let (d, ok) = compare_deltas(&a, &[Vec3::new(1.0, -2.0, 0.500_000_4)]);
        assert!(ok && d > 0.0 && d < 5e-7, "{d}");
        let (d, ok) = compare_deltas(&a, &[Vec3::new(1.0, -2.000_002, 0.5)]);
        assert!(!ok && (d - 2e-6).abs() < 1e-6, "{d}");
    }
}
