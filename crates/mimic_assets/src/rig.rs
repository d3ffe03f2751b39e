//! Target rigs from `configs/rigs/<name>.toml`: mesh, control vertices, regions, frozen vertices, solver.

use crate::AssetError;
use crate::span::{line_of, line_of_nth, toml_error};
use mimic_types::{RegionBands, Rig, RigControl, RigError, SolverSettings};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// The on-disk form of a rig, as written in `configs/rigs/*.toml`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigFile {
    /// Short name.
    pub name: String,
    /// What the rig is and where its mesh comes from.
    #[serde(default)]
    pub description: String,
    /// Length unit of the mesh.
    pub units: String,
    /// OBJ file, or a glTF / GLB / VRM avatar, relative to the rig file.
    pub mesh: Spanned<PathBuf>,
    /// For an avatar mesh: its face mesh and parts ([`crate::AvatarSection`]).
    #[serde(default)]
    pub avatar: Option<crate::AvatarSection>,
    /// Inclusive vertex index ranges that never move.
    #[serde(default)]
    pub frozen: Vec<Spanned<[u32; 2]>>,
    /// Region borders and blend band.
    pub regions: RegionBands,
    /// Default solver settings.
    #[serde(default)]
    pub solver: SolverSettings,
    /// Control vertices.
    pub controls: Vec<Spanned<RigControl>>,
    /// Morph targets (blendshapes) on the mesh's topology; loaded by [`crate::load_morph_targets`].
    #[serde(default)]
    pub morph_targets: Vec<Spanned<crate::MorphTargetEntry>>,
    /// How the rig is drawn; loaded by [`crate::load_rig_look`].
    #[serde(default)]
    pub look: mimic_types::RigLook,
    /// Rigid parts: the jaw's passengers and the eyeballs (docs/parts.md).
    #[serde(default)]
    pub parts: Option<Spanned<mimic_types::RigParts>>,
    /// The terms of the fit of the morph targets' weights to the controls
    /// ([`mimic_types::BlendshapeFit`]; its defaults when absent); loaded by
    /// [`load_blendshape_fit`].
    #[serde(default)]
    pub blendshape_fit: Option<Spanned<mimic_types::BlendshapeFit>>,
    /// The mesh file's up and forward axes: the mesh is turned to y up, +z forward as it loads
    /// ([`crate::Orientation`]); every other number of the rig is in that turned frame.
    #[serde(default)]
    pub orientation: Option<Spanned<crate::OrientationTable>>,
}

impl RigFile {
    /// The turn of the mesh (the identity without `[orientation]`), or the line and why the
    /// table is bad.
    pub fn turn(&self, text: &str) -> Result<crate::Orientation, (usize, String)> {
        match &self.orientation {
            None => Ok(crate::Orientation::default()),
            Some(t) => t
                .get_ref()
                .orientation()
                .map_err(|e| (line_of(text, t.span().start), e)),
        }
    }
}

/// `mesh` turned into the rig's frame by `turn` (positions only; nothing when it is the
/// identity).
pub(crate) fn turn_mesh(
    mut mesh: mimic_types::Mesh,
    turn: crate::Orientation,
) -> mimic_types::Mesh {
    if !turn.is_identity() {
        for p in &mut mesh.positions {
            *p = turn.to_rig(*p);
        }
    }
    mesh
}

/// Where a rig's numeric settings sit in its text: a second, lenient read (unknown keys
/// ignored) that only keeps source positions, for the lines of range errors.
#[derive(Default, Deserialize)]
struct SettingLines {
    #[serde(default)]
    regions: Option<Spanned<RegionLines>>,
    #[serde(default)]
    solver: Option<Spanned<SolverLines>>,
}

/// Positions of the `[regions]` keys.
#[derive(Deserialize)]
struct RegionLines {
    top_from: Option<Spanned<toml::Value>>,
    bottom_below: Option<Spanned<toml::Value>>,
    band: Option<Spanned<toml::Value>>,
}

/// Positions of the numeric `[solver]` keys.
#[derive(Deserialize)]
struct SolverLines {
    kernel: Option<Spanned<toml::Value>>,
    constraint_weight: Option<Spanned<toml::Value>>,
    rbf_ridge: Option<Spanned<toml::Value>>,
    shell_blend: Option<Spanned<toml::Value>>,
    top_split: Option<Spanned<SplitLines>>,
}

/// Positions of the `top_split` keys.
#[derive(Deserialize)]
struct SplitLines {
    at: Option<Spanned<toml::Value>>,
    band: Option<Spanned<toml::Value>>,
    upper_kernel: Option<Spanned<toml::Value>>,
    lower_kernel: Option<Spanned<toml::Value>>,
}

impl SettingLines {
    /// Byte offset of the setting `key` (a [`mimic_types::SettingError`] key), else of its
    /// section, else 0.
    fn offset(&self, key: &str) -> usize {
        fn at<T>(s: &Option<Spanned<T>>) -> Option<usize> {
            s.as_ref().map(|s| s.span().start)
        }
        let regions = self.regions.as_ref();
        let solver = self.solver.as_ref();
        let split = solver.and_then(|s| s.get_ref().top_split.as_ref());
        let exact = match key {
            "regions.top_from" => regions.and_then(|r| at(&r.get_ref().top_from)),
            "regions.bottom_below" => regions.and_then(|r| at(&r.get_ref().bottom_below)),
            "regions.band" => regions.and_then(|r| at(&r.get_ref().band)),
            "solver.kernel" => solver.and_then(|s| at(&s.get_ref().kernel)),
            "solver.constraint_weight" => solver.and_then(|s| at(&s.get_ref().constraint_weight)),
            "solver.rbf_ridge" => solver.and_then(|s| at(&s.get_ref().rbf_ridge)),
            "solver.shell_blend" => solver.and_then(|s| at(&s.get_ref().shell_blend)),
            "solver.top_split.at" => split.and_then(|t| at(&t.get_ref().at)),
            "solver.top_split.band" => split.and_then(|t| at(&t.get_ref().band)),
            "solver.top_split.upper_kernel" => split.and_then(|t| at(&t.get_ref().upper_kernel)),
            "solver.top_split.lower_kernel" => split.and_then(|t| at(&t.get_ref().lower_kernel)),
            _ => None,
        };
        let section = if key.starts_with("regions.") {
            regions.map(|r| r.span().start)
        } else {
            solver.map(|s| s.span().start)
        };
        exact.or(section).unwrap_or(0)
    }
}

/// Loads a rig file and its mesh, and validates them; errors name the file and line.
pub fn load_rig(path: &Path) -> Result<Rig, AssetError> {
    let text = crate::read::read_text(path, &mimic_types::limits::RIG_FILE)?;
    parse_rig(path, &text)
}

/// Parses and validates rig TOML text as if read from `path`; its mesh is loaded relative to `path`.
pub fn parse_rig(path: &Path, text: &str) -> Result<Rig, AssetError> {
    let file: RigFile = toml::from_str(text).map_err(|e| toml_error(path, text, e))?;
    if !mimic_types::rig::is_rig_unit(&file.units) {
        let names: Vec<&str> = mimic_types::rig::RIG_UNITS.iter().map(|u| u.0).collect();
        return Err(AssetError::Toml {
            path: path.to_path_buf(),
            line: units_line(text),
            message: format!(
                "units = {:?} is not a length unit mimic knows; use one of {} (`model`: no physical unit)",
                file.units,
                names.join(", ")
            ),
        });
    }
    let mesh_path = path
        .parent()
        .unwrap_or(Path::new("."))
        .join(file.mesh.get_ref());
    // A FIFO, a device or an oversized file is refused at the `mesh` line, before a byte of it is
    // read; other errors (a missing file) come from the mesh loader as before.
    let avatar = mimic_avatar::is_avatar_path(&mesh_path);
    let kind = if avatar {
        &mimic_avatar::AVATAR_FILE
    } else {
        &mimic_types::limits::OBJ_FILE
    };
    if let Err(cause) = mimic_types::limits::check_file(&mesh_path, kind)
        && cause.is_refusal()
    {
        return Err(AssetError::Refused {
            path: path.to_path_buf(),
            line: line_of(text, file.mesh.span().start),
            file: mesh_path,
            cause,
        });
    }
    let mesh = if avatar {
        let section = file.avatar.clone().unwrap_or_default();
        crate::read_avatar_face(&mesh_path, &section).map(|a| a.face.mesh_data)
    } else {
        crate::load_obj(&mesh_path)
    };
    let mesh = mesh.map_err(|e| AssetError::RigMesh {
        path: path.to_path_buf(),
        cause: Box::new(e),
    })?;
    let turn = file
        .turn(text)
        .map_err(|(line, message)| AssetError::Toml {
            path: path.to_path_buf(),
            line,
            message,
        })?;
    if avatar && !turn.is_identity() {
        return Err(AssetError::Toml {
            path: path.to_path_buf(),
            line: line_of(text, file.orientation.as_ref().map_or(0, |o| o.span().start)),
            message: "orientation: an avatar's mesh is not turned (glTF is y up, +z forward by its specification)".into(),
        });
    }
    let mesh = turn_mesh(mesh, turn);
    let n = mesh.vertex_count();
    let rig_err = |line: usize, cause: RigError| AssetError::Rig {
        path: path.to_path_buf(),
        line,
        cause,
    };

    let mut frozen = vec![false; n];
    for range in &file.frozen {
        let [a, b] = *range.get_ref();
        let line = line_of(text, range.span().start);
        if a > b || b as usize >= n {
            return Err(AssetError::Toml {
                path: path.to_path_buf(),
                line,
                message: format!("frozen range [{a}, {b}] is not inside the mesh's {n} vertices"),
            });
        }
        frozen[a as usize..=b as usize]
            .iter_mut()
            .for_each(|f| *f = true);
    }

    let rig = Rig {
        name: file.name.clone(),
        units: file.units.clone(),
        mesh,
        controls: file.controls.iter().map(|c| c.get_ref().clone()).collect(),
        regions: file.regions,
        frozen,
        solver: file.solver,
        parts: file
            .parts
            .as_ref()
            .map(|p| p.get_ref().clone())
            .unwrap_or_default(),
    };
    if let Some(parts) = &file.parts
        && let Err(e) = parts.get_ref().validate(rig.mesh.vertex_count())
    {
        return Err(AssetError::Toml {
            path: path.to_path_buf(),
            line: line_of(text, parts.span().start),
            message: e.to_string(),
        });
    }
    if let Err(source) = rig.validate() {
        let control_line =
            |fdp, nth: usize| line_of_nth(text, &file.controls, |c| c.fdp == fdp, nth);
        let line = match &source {
            RigError::ControlVertexOutOfRange { fdp, .. } | RigError::FrozenControl { fdp, .. } => {
                control_line(*fdp, 0)
            }
            RigError::DuplicateControl(fdp) => control_line(*fdp, 1),
            RigError::Mesh(_) | RigError::FrozenMaskLength { .. } => {
                line_of(text, file.mesh.span().start)
            }
        };
        return Err(rig_err(line, source));
    }
    if let Err(cause) = rig.validate_settings() {
        let lines: SettingLines = toml::from_str(text).unwrap_or_default();
        return Err(AssetError::Setting {
            path: path.to_path_buf(),
            line: line_of(text, lines.offset(cause.key)),
            cause,
        });
    }
    blendshape_fit(path, text, &file)?;
    Ok(rig)
}

/// The rig file's `[blendshape_fit]`, range-checked (the error at the table's line), or the
/// defaults when it has none.
fn blendshape_fit(
    path: &Path,
    text: &str,
    file: &RigFile,
) -> Result<mimic_types::BlendshapeFit, AssetError> {
    let Some(fit) = &file.blendshape_fit else {
        return Ok(mimic_types::BlendshapeFit::default());
    };
    fit.get_ref()
        .validate()
        .map_err(|cause| AssetError::Setting {
            path: path.to_path_buf(),
            line: line_of(text, fit.span().start),
            cause,
        })?;
    Ok(*fit.get_ref())
}

/// The `[blendshape_fit]` of the rig file at `path` ([`mimic_types::BlendshapeFit`]: the terms
/// of the fit of its morph targets' weights to its controls), its defaults when it has none.
pub fn load_blendshape_fit(path: &Path) -> Result<mimic_types::BlendshapeFit, AssetError> {
    let text = crate::read::read_text(path, &mimic_types::limits::RIG_FILE)?;
    let file: RigFile = toml::from_str(&text).map_err(|e| toml_error(path, &text, e))?;
    blendshape_fit(path, &text, &file)
}

/// 1-based line of the top-level `units = ...` key (1 when it is not found as a plain line).
fn units_line(text: &str) -> usize {
    text.lines()
        .position(|l| {
            l.trim_start()
                .strip_prefix("units")
                .is_some_and(|rest| rest.trim_start().starts_with('='))
        })
        .map_or(1, |i| i + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_rig(dir: &Path, controls: &str) -> PathBuf {
        std::fs::write(
            dir.join("tri.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n",
        )
        .unwrap();
        let rig = format!(
            r#"name = "tri"
units = "cm"
mesh = "tri.obj"
frozen = [[3, 3]]

[regions]
top_from = 0.7
bottom_below = 0.3
band = 0.1

[solver]
kind = "laplacian"

{controls}"#
        );
        let path = dir.join("tri.toml");
        std::fs::write(&path, rig).unwrap();
        path
    }

    #[test]
    fn loads_a_rig_with_its_mesh() {
        let dir = tempfile::tempdir().unwrap();
        let path = write_rig(
            dir.path(),
            "[[controls]]\nfdp = \"8.3\"\nvertex = 1\nregion = \"bottom\"\n",
        );
        let rig = load_rig(&path).unwrap();
        assert_eq!(rig.mesh.vertex_count(), 4);
        assert_eq!(rig.frozen, vec![false, false, false, true]);
        assert_eq!(rig.controls[0].vertex, 1);
        assert_eq!(rig.solver.kind, mimic_types::SolverKind::Laplacian);
    }

    #[test]
    fn solver_kernel_and_top_split_parse() {
        let dir = tempfile::tempdir().unwrap();
        let path = write_rig(
            dir.path(),
            "[[controls]]\nfdp = \"8.3\"\nvertex = 1\nregion = \"bottom\"\n",
        );
        let text = std::fs::read_to_string(&path).unwrap().replace(
            "kind = \"laplacian\"",
            "kernel = { kind = \"matern32\", radius = 2.0 }\ntop_split = { at = 4.6, band = 1.0, lower_kernel = { kind = \"exponential\", radius = 1.0 } }",
        );
        let rig = parse_rig(&path, &text).unwrap();
        assert_eq!(
            rig.solver.kernel,
            mimic_types::RbfKernel::Matern32 { radius: 2.0 }
        );
        assert_eq!(
            rig.solver.top_split,
            Some(mimic_types::TopSplit {
                at: 4.6,
                band: 1.0,
                upper_kernel: None,
                lower_kernel: Some(mimic_types::RbfKernel::Exponential { radius: 1.0 }),
            })
        );
        // Without the key there is no split (other rigs keep one top solve).
        assert_eq!(load_rig(&path).unwrap().solver.top_split, None);
        let bad = text.replace("band = 1.0,", "bnad = 1.0,");
        assert!(parse_rig(&path, &bad).is_err());
    }

    #[test]
    fn blendshape_fit_table_is_read_checked_and_defaulted() {
        let dir = tempfile::tempdir().unwrap();
        let controls = "[[controls]]\nfdp = \"8.3\"\nvertex = 1\nregion = \"bottom\"\n";
        let path = write_rig(dir.path(), controls);
        assert_eq!(
            load_blendshape_fit(&path).unwrap(),
            mimic_types::BlendshapeFit::default()
        );
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(
            &path,
            format!("{text}\n[blendshape_fit]\nl1 = 0.25\nsymmetry = 2\n"),
        )
        .unwrap();
        assert_eq!(
            load_blendshape_fit(&path).unwrap(),
            mimic_types::BlendshapeFit {
                l1: 0.25,
                symmetry: 2.0,
                ..mimic_types::BlendshapeFit::default()
            }
        );
        std::fs::write(&path, format!("{text}\n[blendshape_fit]\ntemporal = -1\n")).unwrap();
        let e = load_rig(&path).unwrap_err().to_string();
        assert!(
            e.contains("tri.toml:19") && e.contains("blendshape_fit.temporal"),
            "{e}"
        );
        assert!(load_blendshape_fit(&path).is_err());
    }

    #[test]
    fn control_vertex_out_of_range_names_file_and_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = write_rig(
            dir.path(),
            "[[controls]]\nfdp = \"8.3\"\nvertex = 99\nregion = \"bottom\"\n",
        );
        let e = load_rig(&path).unwrap_err().to_string();
        assert!(
            e.ends_with("tri.toml:14: control 8.3 uses vertex 99, but the mesh has 4 vertices"),
            "{e}"
        );
    }

    #[test]
    fn unknown_units_are_refused_at_their_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = write_rig(
            dir.path(),
            "[[controls]]\nfdp = \"8.3\"\nvertex = 1\nregion = \"bottom\"\n",
        );
        let good = std::fs::read_to_string(&path).unwrap();
        for unit in ["m", "cm", "mm", "in", "model"] {
            let text = good.replace("units = \"cm\"", &format!("units = \"{unit}\""));
            assert_eq!(parse_rig(&path, &text).unwrap().units, unit);
        }
        let text = good.replace("units = \"cm\"", "units = \"furlongs\"");
        let e = parse_rig(&path, &text).unwrap_err().to_string();
        assert!(
            e.contains("tri.toml:2: units = \"furlongs\" is not a length unit mimic knows; use one of m, cm, mm, in, model"),
            "{e}"
        );
    }

    #[test]
    fn missing_mesh_names_rig_and_mesh() {
        let dir = tempfile::tempdir().unwrap();
        let path = write_rig(
            dir.path(),
            "[[controls]]\nfdp = \"8.3\"\nvertex = 1\nregion = \"bottom\"\n",
        );
        std::fs::remove_file(dir.path().join("tri.obj")).unwrap();
        let e = load_rig(&path).unwrap_err().to_string();
        assert!(
            e.contains("tri.toml: mesh: ") && e.contains("tri.obj: "),
            "{e}"
        );
    }

    #[test]
    fn out_of_range_settings_name_their_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = write_rig(
            dir.path(),
            "[[controls]]\nfdp = \"8.3\"\nvertex = 1\nregion = \"bottom\"\n",
        );
        let good = std::fs::read_to_string(&path).unwrap();
        let e = |from: &str, to: &str| {
            let text = good.replacen(from, to, 1);
            assert_ne!(text, good, "{from}");
            parse_rig(&path, &text).unwrap_err().to_string()
        };
        let ends = |got: String, want: &str| assert!(got.ends_with(want), "{got}\nwant {want}");
        ends(
            e("band = 0.1", "band = nan"),
            "tri.toml:9: regions.band = NaN: must be finite and >= 0",
        );
        ends(
            e("band = 0.1", "band = -0.1"),
            "tri.toml:9: regions.band = -0.1: must be finite and >= 0",
        );
        assert!(
            e("band = 0.1", "band = 0.5")
                .contains("tri.toml:9: regions.band = 0.5: must be at most")
        );
        ends(
            e("top_from = 0.7", "top_from = inf"),
            "tri.toml:7: regions.top_from = inf: must be a finite number",
        );
        assert!(
            e("bottom_below = 0.3", "bottom_below = 0.8")
                .contains("tri.toml:7: regions.top_from = 0.7: must be above")
        );
        let kernel = |k: &str| {
            e(
                "kind = \"laplacian\"",
                &format!("kind = \"laplacian\"\n{k}"),
            )
        };
        assert!(
            kernel("kernel = { kind = \"gaussian\", radius = 0.0 }")
                .contains("tri.toml:13: solver.kernel = { radius = 0 }: the radius must be finite")
        );
        assert!(
            kernel("kernel = { kind = \"exponential\", radius = -3.0 }")
                .contains("tri.toml:13: solver.kernel")
        );
        assert!(
            kernel("kernel = { kind = \"thin_plate\" }")
                .contains("tri.toml:13: solver.kernel = thin_plate: needs affine = true")
        );
        assert!(
            kernel("constraint_weight = 0.0")
                .contains("tri.toml:13: solver.constraint_weight = 0: must be finite, > 0")
        );
        assert!(
            kernel("constraint_weight = 1e300").contains("tri.toml:13: solver.constraint_weight")
        );
        assert!(
            kernel("rbf_ridge = 2.0")
                .contains("tri.toml:13: solver.rbf_ridge = 2: must be finite, >= 0 and <= 1")
        );
        assert!(kernel("shell_blend = [0.0, 0.0, 1.5]").contains(
            "tri.toml:13: solver.shell_blend = 1.5: each share must be finite, >= 0 and <= 1"
        ));
        let split = |s: &str| kernel(&format!("top_split = {{ {s} }}"));
        assert!(split("at = nan").contains("tri.toml:13: solver.top_split.at = NaN"));
        assert!(
            split("at = 0.8, band = -1.0")
                .contains("tri.toml:13: solver.top_split.band = -1: must be finite and >= 0")
        );
        assert!(split("at = 0.8, band = 3.0").contains(
            "tri.toml:13: solver.top_split.band = 3: must be at most the mesh's height 1"
        ));
        assert!(
            split("at = 0.8, lower_kernel = { kind = \"matern32\", radius = inf }")
                .contains("tri.toml:13: solver.top_split.lower_kernel")
        );
        // Within range, the same keys load.
        let text = good.replacen(
            "kind = \"laplacian\"",
            "kind = \"laplacian\"\nconstraint_weight = 100.0\ntop_split = { at = 0.8, band = 0.2 }",
            1,
        );
        parse_rig(&path, &text).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn device_mesh_is_refused_at_its_line_before_reading() {
        let dir = tempfile::tempdir().unwrap();
        let path = write_rig(
            dir.path(),
            "[[controls]]\nfdp = \"8.3\"\nvertex = 1\nregion = \"bottom\"\n",
        );
        let text = std::fs::read_to_string(&path)
            .unwrap()
            .replace("mesh = \"tri.obj\"", "mesh = \"/dev/zero\"");
        let e = parse_rig(&path, &text).unwrap_err().to_string();
        assert!(
            e.ends_with("tri.toml:3: /dev/zero: not a regular file but a character device; OBJ meshes are read only from regular files"),
            "{e}"
        );
        // A mesh over the OBJ cap is refused by its size (a sparse file: no disk used).
        let big = std::fs::File::create(dir.path().join("big.obj")).unwrap();
        big.set_len(mimic_types::limits::OBJ_FILE.max_bytes + 1)
            .unwrap();
        let text = text.replace("/dev/zero", "big.obj");
        let e = parse_rig(&path, &text).unwrap_err().to_string();
        assert!(
            e.contains("tri.toml:3: ")
                && e.ends_with("big.obj: 67108865 bytes, over the 64 MiB cap for OBJ meshes"),
            "{e}"
        );
    }

    #[test]
    fn frozen_control_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = write_rig(
            dir.path(),
            "[[controls]]\nfdp = \"8.3\"\nvertex = 3\nregion = \"bottom\"\n",
        );
        let e = load_rig(&path).unwrap_err().to_string();
        assert!(
            e.ends_with("control 8.3 uses vertex 3, which is frozen"),
            "{e}"
        );
    }
}
