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
    /// OBJ file, relative to the rig file.
    pub mesh: Spanned<PathBuf>,
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
}

/// Loads a rig file and its mesh, and validates them; errors name the file and line.
pub fn load_rig(path: &Path) -> Result<Rig, AssetError> {
    let text = std::fs::read_to_string(path).map_err(|e| AssetError::io(path, e))?;
    parse_rig(path, &text)
}

/// Parses and validates rig TOML text as if read from `path`; its mesh is loaded relative to `path`.
pub fn parse_rig(path: &Path, text: &str) -> Result<Rig, AssetError> {
    let file: RigFile = toml::from_str(text).map_err(|e| toml_error(path, text, e))?;
    let mesh_path = path
        .parent()
        .unwrap_or(Path::new("."))
        .join(file.mesh.get_ref());
    let mesh = crate::load_obj(&mesh_path).map_err(|e| AssetError::RigMesh {
        path: path.to_path_buf(),
        cause: Box::new(e),
    })?;
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
    };
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
    Ok(rig)
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
