//! Landmark layouts from `configs/layouts/<name>.toml`, and where config files are found.

use crate::AssetError;
use crate::span::{line_of, line_of_nth, toml_error};
use mimic_types::{EyePoints, GazeLayout, Layout, LayoutControl, LayoutError, ModelCorrespondence};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// The on-disk form of a layout: [`Layout`] with source positions kept for error messages.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LayoutFile {
    name: String,
    #[serde(default)]
    description: String,
    point_count: Spanned<usize>,
    controls: Vec<Spanned<LayoutControl>>,
    stable: Spanned<Vec<usize>>,
    #[serde(default)]
    undocumented: Option<Spanned<Vec<usize>>>,
    #[serde(default)]
    point_names: Option<Spanned<Vec<String>>>,
    #[serde(default)]
    candide_correspondences: Vec<Spanned<ModelCorrespondence>>,
    #[serde(default)]
    gaze: Option<GazeFile>,
    /// An OBJ whose vertex i is point i of the tracker's neutral face, relative to the layout file.
    #[serde(default)]
    canonical_neutral: Option<Spanned<PathBuf>>,
}

/// The on-disk `[gaze]` table, each eye with its position.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GazeFile {
    left: Spanned<EyePoints>,
    right: Spanned<EyePoints>,
}

/// Loads and validates a layout file; errors name the file and the offending line.
pub fn load_layout(path: &Path) -> Result<Layout, AssetError> {
    let text = crate::read::read_text(path, &mimic_types::limits::LAYOUT_FILE)?;
    parse_layout(path, &text)
}

/// Parses and validates layout TOML text; `path` names the file in errors and anchors a
/// relative `canonical_neutral` (an OBJ, read from there).
pub fn parse_layout(path: &Path, text: &str) -> Result<Layout, AssetError> {
    let file: LayoutFile = toml::from_str(text).map_err(|e| toml_error(path, text, e))?;
    let control_line = |fdp, nth: usize| line_of_nth(text, &file.controls, |c| c.fdp == fdp, nth);
    let stable_line = line_of(text, file.stable.span().start);
    let line_of_opt = |start: Option<usize>| start.map_or(1, |s| line_of(text, s));
    let layout = Layout {
        name: file.name.clone(),
        description: file.description.clone(),
        point_count: *file.point_count.get_ref(),
        controls: file.controls.iter().map(|c| c.get_ref().clone()).collect(),
        stable: file.stable.get_ref().clone(),
        undocumented: file
            .undocumented
            .as_ref()
            .map(|u| u.get_ref().clone())
            .unwrap_or_default(),
        point_names: file
            .point_names
            .as_ref()
            .map(|n| n.get_ref().clone())
            .unwrap_or_default(),
        candide_correspondences: file
            .candide_correspondences
            .iter()
            .map(|c| c.get_ref().clone())
            .collect(),
        gaze: file.gaze.as_ref().map(|g| GazeLayout {
            left: g.left.get_ref().clone(),
            right: g.right.get_ref().clone(),
        }),
        canonical_neutral: match &file.canonical_neutral {
            Some(obj) => {
                let at = path.parent().unwrap_or(Path::new("")).join(obj.get_ref());
                Some(crate::obj::load_obj(&at)?.positions)
            }
            None => None,
        },
    };
    if let Err(source) = layout.validate() {
        let line = match &source {
            LayoutError::ControlPointOutOfRange { fdp, .. }
            | LayoutError::ControlWithoutPoints { fdp, .. } => control_line(*fdp, 0),
            LayoutError::DuplicateControl { fdp, .. } => control_line(*fdp, 1),
            LayoutError::StablePointOutOfRange { .. } | LayoutError::TooFewStablePoints { .. } => {
                stable_line
            }
            LayoutError::TooManyPoints { .. } => line_of(text, file.point_count.span().start),
            LayoutError::UndocumentedPointOutOfRange { .. } => {
                line_of_opt(file.undocumented.as_ref().map(|u| u.span().start))
            }
            LayoutError::TooManyPointNames { .. } => {
                line_of_opt(file.point_names.as_ref().map(|n| n.span().start))
            }
            LayoutError::BadCorrespondence { index, .. } => file
                .candide_correspondences
                .get(*index)
                .map_or(1, |c| line_of(text, c.span().start)),
            LayoutError::BadGaze { eye, .. } => line_of_opt(file.gaze.as_ref().map(|g| {
                let e = if *eye == "left" { &g.left } else { &g.right };
                e.span().start
            })),
            LayoutError::BadCanonicalNeutral { .. } => {
                line_of_opt(file.canonical_neutral.as_ref().map(|c| c.span().start))
            }
        };
        return Err(AssetError::Layout {
            path: path.to_path_buf(),
            line,
            cause: source,
        });
    }
    Ok(layout)
}

/// Where mimic finds its config files (`layouts/`, `rigs/`, meshes).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConfigDirs {
    /// The `configs/` directory.
    pub root: PathBuf,
}

impl ConfigDirs {
    /// Uses `explicit` if given, else `$MIMIC_CONFIGS`, else `./configs`, else `configs/` beside an
    /// ancestor of the running executable (so `target/debug/mimic` finds the repo's configs).
    pub fn locate(explicit: Option<&Path>) -> ConfigDirs {
        if let Some(p) = explicit {
            return ConfigDirs {
                root: p.to_path_buf(),
            };
        }
        if let Some(p) = std::env::var_os("MIMIC_CONFIGS") {
            return ConfigDirs {
                root: PathBuf::from(p),
            };
        }
        let local = PathBuf::from("configs");
        if local.is_dir() {
            return ConfigDirs { root: local };
        }
        if let Ok(exe) = std::env::current_exe() {
            for dir in exe.ancestors().skip(1) {
                let c = dir.join("configs");
                if c.join("layouts").is_dir() {
                    return ConfigDirs { root: c };
                }
            }
        }
        ConfigDirs { root: local }
    }

    /// Path of the layout file for `name`.
    pub fn layout_path(&self, name: &str) -> PathBuf {
        self.root.join("layouts").join(format!("{name}.toml"))
    }

    /// Loads the layout called `name` (as recordings name it).
    pub fn load_layout_named(&self, name: &str) -> Result<Layout, AssetError> {
        let path = self.layout_path(name);
        if !path.is_file() {
            return Err(AssetError::LayoutNotFound {
                name: name.to_string(),
                tried: vec![path],
            });
        }
        load_layout(&path)
    }

    /// Names of the layouts in `layouts/` (each `*.toml`'s stem), sorted.
    pub fn layout_names(&self) -> Result<Vec<String>, AssetError> {
        let dir = self.root.join("layouts");
        let io = |cause| AssetError::Io {
            path: dir.clone(),
            cause,
        };
        let mut names = Vec::new();
        for e in std::fs::read_dir(&dir).map_err(io)? {
            let path = e.map_err(io)?.path();
            if path.extension().is_some_and(|x| x == "toml")
                && let Some(stem) = path.file_stem()
            {
                names.push(stem.to_string_lossy().into_owned());
            }
        }
        names.sort();
        Ok(names)
    }

    /// Path of the rig file for `name`, or `name` itself when it is a path to a file.
    pub fn rig_path(&self, name: &str) -> PathBuf {
        let as_path = PathBuf::from(name);
        if as_path.is_file() {
            return as_path;
        }
        self.root.join("rigs").join(format!("{name}.toml"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn layout_names_are_the_toml_stems_sorted_and_a_missing_folder_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let layouts = dir.path().join("layouts");
        std::fs::create_dir(&layouts).unwrap();
        for f in [
            "mediapipe478.toml",
            "ibug68.toml",
            "notes.md",
            "kinect121.toml",
        ] {
            std::fs::write(layouts.join(f), "").unwrap();
        }
        let dirs = ConfigDirs::locate(Some(dir.path()));
        assert_eq!(
            dirs.layout_names().unwrap(),
            ["ibug68", "kinect121", "mediapipe478"]
        );
        let empty = tempfile::tempdir().unwrap();
        let e = ConfigDirs::locate(Some(empty.path()))
            .layout_names()
            .unwrap_err();
        assert!(e.to_string().contains("layouts"), "{e}");
    }

    const GOOD: &str = r#"
name = "tiny"
point_count = 4
stable = [0, 1, 3]

[[controls]]
fdp = "8.3"
points = [1, 2]
region = "bottom"

[[controls]]
fdp = "4.1"
points = [0]
region = "top"
"#;

    #[test]
    fn parses_a_layout() {
        let l = parse_layout(Path::new("tiny.toml"), GOOD).unwrap();
        assert_eq!(l.controls.len(), 2);
        assert_eq!(l.controls[0].points, vec![1, 2]);
        assert_eq!(l.controls[1].fdp.to_string(), "4.1");
    }

    #[test]
    fn out_of_range_control_names_file_line_and_control() {
        let bad = GOOD.replace("points = [0]", "points = [9]");
        let e = parse_layout(Path::new("tiny.toml"), &bad)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "tiny.toml:11: control 4.1 maps to point 9, but layout `tiny` has 4 points"
        );
    }

    #[test]
    fn bad_fdp_and_syntax_name_the_line() {
        let bad = GOOD.replace("\"4.1\"", "\"4.9\"");
        let e = parse_layout(Path::new("tiny.toml"), &bad)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("tiny.toml:12:") && e.contains("4.9"), "{e}");
        let e = parse_layout(Path::new("tiny.toml"), "name = \n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("tiny.toml:1:"), "{e}");
    }

    #[test]
    fn counts_and_correspondences_name_their_line() {
        let e = |t: &str| {
            parse_layout(Path::new("tiny.toml"), t)
                .unwrap_err()
                .to_string()
        };
        let huge = GOOD.replace("point_count = 4", "point_count = 1000000000000");
        assert_eq!(
            e(&huge),
            "tiny.toml:3: layout `tiny` has point_count 1000000000000, over the maximum of 4096 points"
        );
        let names = GOOD.replace(
            "stable = [0, 1, 3]",
            "stable = [0, 1, 3]\nundocumented = [2]\npoint_names = [\"a\", \"b\", \"c\", \"d\", \"e\"]",
        );
        assert!(e(&names).starts_with("tiny.toml:6: layout `tiny` names 5 points"));
        let undoc = GOOD.replace(
            "stable = [0, 1, 3]",
            "stable = [0, 1, 3]\nundocumented = [4]",
        );
        assert!(e(&undoc).starts_with("tiny.toml:5: undocumented point 4 is out of range"));
        let text = GOOD.replace(
            "stable = [0, 1, 3]",
            "stable = [0, 1, 3]\ncandide_correspondences = [\n  { point = 0, vertex = 3 },\n  { point = 1, vertices = [1, 2], t = 0.5, weight = -1.0 },\n]",
        );
        assert_eq!(
            e(&text),
            "tiny.toml:7: candide_correspondences entry 2 (point 1) of layout `tiny`: weight -1 must be finite and > 0"
        );
        parse_layout(
            Path::new("tiny.toml"),
            &text.replace("weight = -1.0", "weight = 2.0"),
        )
        .unwrap();
    }

    #[test]
    fn gaze_table_parses_and_its_errors_name_the_line() {
        let text = format!(
            "{GOOD}\n[gaze]\nleft = {{ pupil = [0], outer = 1, inner = 2, upper = [3], lower = [3] }}\nright = {{ pupil = [3], outer = 2, inner = 1, upper = [0], lower = [0] }}\n"
        );
        let l = parse_layout(Path::new("tiny.toml"), &text).unwrap();
        let g = l.gaze.unwrap();
        assert_eq!((g.left.pupil, g.left.outer, g.right.inner), (vec![0], 1, 1));
        assert!(
            parse_layout(Path::new("tiny.toml"), GOOD)
                .unwrap()
                .gaze
                .is_none()
        );
        let e = parse_layout(
            Path::new("tiny.toml"),
            &text.replace("outer = 2", "outer = 7"),
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            e,
            "tiny.toml:18: gaze: the right eye of layout `tiny` names point 7, but the layout has 4 points"
        );
        let e = parse_layout(
            Path::new("tiny.toml"),
            &text.replace("pupil = [0]", "pupil = []"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("left eye") && e.contains("pupil"), "{e}");
        let e = parse_layout(
            Path::new("tiny.toml"),
            &text.replace("lower = [3] }", "lower = [3], iris = 1 }"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("iris"), "{e}");
    }

    #[test]
    fn a_canonical_neutral_is_read_beside_the_layout_and_must_fit_it() {
        let dir = tempfile::tempdir().unwrap();
        let toml = dir.path().join("tiny.toml");
        let text = GOOD.replace(
            "stable = [0, 1, 3]",
            "stable = [0, 1, 3]\ncanonical_neutral = \"models/face.obj\"",
        );
        std::fs::create_dir(dir.path().join("models")).unwrap();
        let obj = dir.path().join("models/face.obj");
        std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n").unwrap();
        std::fs::write(&toml, &text).unwrap();
        let l = load_layout(&toml).unwrap();
        let c = l.canonical_neutral.unwrap();
        assert_eq!(c, [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z]);
        std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        let e = load_layout(&toml).unwrap_err().to_string();
        assert!(
            e.ends_with("tiny.toml:5: the canonical neutral of layout `tiny` has 3 points (3 finite); the layout has 4"),
            "{e}"
        );
        std::fs::remove_file(&obj).unwrap();
        let e = load_layout(&toml).unwrap_err().to_string();
        assert!(e.contains("face.obj"), "{e}");
        assert!(
            parse_layout(&toml, GOOD)
                .unwrap()
                .canonical_neutral
                .is_none()
        );
    }

    #[test]
    fn the_mediapipe_layout_ships_its_canonical_face() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/layouts");
        let l = load_layout(&root.join("mediapipe478.toml")).unwrap();
        let c = l.canonical_neutral.unwrap();
        assert_eq!(c.len(), 478);
        // Landmark 4, the nose tip, is the canonical face's most anterior point (cm).
        assert_eq!(c[4], Vec3::new(0.0, -0.46317, 7.58658));
        for other in ["kinect121", "ibug68", "openseeface68", "kinect-gfe100"] {
            let path = root.join(format!("{other}.toml"));
            assert!(load_layout(&path).unwrap().canonical_neutral.is_none());
        }
    }

    #[test]
    fn duplicate_control_points_at_second_entry() {
        let bad = GOOD.replace("\"4.1\"", "\"8.3\"");
        let e = parse_layout(Path::new("tiny.toml"), &bad)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "tiny.toml:11: control 8.3 appears twice in layout `tiny`"
        );
    }
}
