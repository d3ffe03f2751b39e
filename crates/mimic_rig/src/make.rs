//! The whole of `mimic rig new` as one call ([`make_rig_file`]): the output folder checked
//! before the work, landmarks given or found by template registration, the rig made, written
//! (with an OBJ copy of a glTF mesh), overrides merged, read back, a dense control set registered,
//! and with `--blendshapes arkit` the ARKit shapes made through the registration ([`crate::arkit`]).

use crate::landmarks::{IBUG_POINTS, Landmarks, Numbering, landmarks_json, load_landmarks};
use crate::{
    Defaults, FindSettings, GeneratedRig, Registration, RigNewError, TemplateHead, make_rig,
    register_template, relative_path, write_rig_toml,
};
use mimic_types::{Mesh, Rig};
use std::path::{Path, PathBuf};

mod avatar;
mod lips;

pub use lips::cut_mesh_path;

/// What `mimic rig new` was asked for.
#[derive(Clone, Debug)]
pub struct NewRig<'a> {
    /// The face mesh (OBJ), or an avatar (glTF, GLB, VRM) whose face mesh the rig drives.
    pub mesh: &'a Path,
    /// For an avatar: its face mesh by name or `#K` (`None`: the largest mesh named like a face
    /// or head, else the largest).
    pub face: Option<&'a str>,
    /// The rig TOML to write.
    pub output: &'a Path,
    /// The landmark file and its numbering; `None` finds them by registering the ICT head.
    pub landmarks: Option<(&'a Path, Numbering)>,
    /// With given landmarks: leave the points they lack out instead of registering for them.
    pub keep_missing: bool,
    /// Where to write the landmarks the rig was made from, if anywhere.
    pub landmarks_out: Option<&'a Path>,
    /// Length unit of the mesh (`None`: guessed).
    pub units: Option<&'a str>,
    /// Rig name (`None`: the output file's stem, less `.generated`).
    pub name: Option<String>,
    /// The control set: `mpeg4` or a layout's name (`crate::register`).
    pub controls: &'a str,
    /// Override files merged in order.
    pub overrides: &'a [PathBuf],
    /// The generated lengths and the solver.
    pub defaults: Defaults,
    /// The `configs/` directory (the ICT template head, layouts' templates).
    pub configs: &'a Path,
    /// The command line that makes the rig again, written into its header (empty:
    /// [`NewRig::repeat_command`]'s).
    pub command_line: String,
    /// Blend shapes made for the head as the rig's morph targets: `arkit` (ARKit's 52 from
    /// ICT-FaceKit's expressions, [`crate::arkit`]) or none.
    pub blendshapes: Option<&'a str>,
    /// Cut closed lips open along the lip line ([`crate::lipcut`]; `--no-cut`: false).
    pub cut: bool,
}

/// What [`make_rig_file`] made.
#[derive(Debug)]
pub struct MadeRig {
    /// The rig as generated (frame, frozen counts, warnings).
    pub generated: GeneratedRig,
    /// The written rig read back as every command reads it.
    pub loaded: Rig,
}

impl NewRig<'_> {
    /// The `mimic rig new` command line that makes this rig again (the options that differ from
    /// the defaults), as written into the rig's header.
    pub fn repeat_command(&self) -> String {
        let mut words = vec![
            "mimic rig new".to_string(),
            self.mesh.display().to_string(),
            format!("-o {}", self.output.display()),
        ];
        if let Some(f) = self.face {
            words.push(format!("--face {f}"));
        }
        if let Some((l, numbering)) = &self.landmarks {
            words.push(format!("--landmarks {}", l.display()));
            if let Some(b) = numbering.point {
                words.push(format!("--landmark-base {}", b.offset()));
            }
            if numbering.vertex == crate::LandmarkBase::One {
                words.push("--vertex-base 1".into());
            }
            if self.keep_missing {
                words.push("--keep-missing".into());
            }
        }
        if let Some(u) = self.units {
            words.push(format!("--units {u}"));
        }
        if let Some(n) = &self.name {
            words.push(format!("--name {n}"));
        }
        if self.controls != "mpeg4" {
            words.push(format!("--controls {}", self.controls));
        }
        if self.defaults.back_of_head != Defaults::default().back_of_head {
            words.push(format!("--frozen-beyond {}", self.defaults.back_of_head));
        }
        if let Some(k) = self.defaults.solver {
            words.push(format!("--solver {}", k.name()));
        }
        for o in self.overrides {
            words.push(format!("--overrides {}", o.display()));
        }
        if let Some(b) = self.blendshapes {
            words.push(format!("--blendshapes {b}"));
        }
        if !self.cut {
            words.push("--no-cut".into());
        }
        words.join(" ")
    }
}

impl MadeRig {
    /// The warnings `rig new` prints after its summary: the generation's, then `rig check`'s on
    /// the rig as written.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = self.generated.warnings.clone();
        out.extend(
            crate::check_rig(&self.loaded)
                .iter()
                .map(ToString::to_string),
        );
        out
    }

    /// The line `mimic rig new` prints: controls, frozen vertices and why, units, IOD, and the
    /// rigid parts found.
    pub fn summary(&self, output: &Path) -> String {
        let (c, loaded) = (self.generated.frozen_counts, &self.loaded);
        format!(
            "wrote {}: {} controls, {} of {} vertices frozen ({} unused, {} in {} pieces with no control, {} far from the face), units {}, IOD {:.4}; {}",
            output.display(),
            loaded.controls.len(),
            loaded.frozen.iter().filter(|f| **f).count(),
            loaded.mesh.vertex_count(),
            c.unused,
            c.uncontrolled,
            c.uncontrolled_pieces,
            c.far,
            loaded.units,
            self.generated.frame.iod,
            self.generated.parts_note
        )
    }
}

/// A context line in front of an error of the rig code.
pub(crate) fn context(what: impl Into<String>) -> impl FnOnce(RigNewError) -> RigNewError {
    let context = what.into();
    move |cause| RigNewError::Context {
        context,
        cause: Box::new(cause),
    }
}

/// Writes `text` to `path`.
pub(crate) fn write(path: &Path, text: &str) -> Result<(), RigNewError> {
    write_file(path, text.as_bytes())
}

/// Writes `bytes` to `path`.
pub(crate) fn write_file(path: &Path, bytes: &[u8]) -> Result<(), RigNewError> {
    std::fs::write(path, bytes).map_err(|cause| RigNewError::Write {
        path: path.to_path_buf(),
        cause,
    })
}

/// Makes the folder of `path` (a file to write later) and checks that a file can be written
/// there, so a long job fails before it starts.
pub fn prepare_output(path: &Path) -> Result<(), RigNewError> {
    let bad = |message: String| RigNewError::Output {
        path: path.to_path_buf(),
        message,
    };
    if path.is_dir() {
        return Err(bad("is a folder; give a file name".into()));
    }
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)
        .map_err(|e| bad(format!("cannot create the folder {}: {e}", dir.display())))?;
    let name = path
        .file_name()
        .map_or_else(|| "rig".into(), |n| n.to_string_lossy().into_owned());
    let probe = dir.join(format!(".{name}.{}.probe", std::process::id()));
    std::fs::write(&probe, b"")
        .map_err(|e| bad(format!("cannot write in {}: {e}", dir.display())))?;
    // The probe is empty and ours; a failed removal leaves only it behind.
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Runs `mimic rig new`: `note` receives the progress lines and warnings (`warning: ...`) as
/// they come. The output folders are checked first ([`prepare_output`]).
pub fn make_rig_file(
    job: &NewRig<'_>,
    note: &mut dyn FnMut(String),
) -> Result<MadeRig, RigNewError> {
    if !(job.defaults.back_of_head.is_finite() && job.defaults.back_of_head > 0.0) {
        return Err(RigNewError::Frame(format!(
            "--frozen-beyond {}: a distance in inter-ocular distances above 0",
            job.defaults.back_of_head
        )));
    }
    if let Some(b) = job.blendshapes.filter(|b| *b != "arkit") {
        return Err(RigNewError::Frame(format!(
            "--blendshapes {b}: the one set made is `arkit`"
        )));
    }
    prepare_output(job.output)?;
    if let Some(out) = job.landmarks_out {
        prepare_output(out)?;
    }
    let overrides = job
        .overrides
        .iter()
        .map(|p| {
            mimic_types::limits::read_capped(p, &mimic_types::limits::RIG_FILE)
                .map(|t| (p.as_path(), t))
                .map_err(|cause| RigNewError::Read {
                    path: p.to_path_buf(),
                    cause,
                })
                .map_err(context("--overrides"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let avatar = avatar::avatar_of(job, note)?;
    let mesh = match &avatar {
        Some(a) => a.face.mesh_data.clone(),
        None => crate::load_mesh(job.mesh)?,
    };
    let (mut marks, marks_from, mut registration) = landmarks_of(job, &mesh, note)?;
    let mut mesh = mesh;
    // An avatar's face keeps its mesh (its file is written back whole).
    let cut = match &avatar {
        None => lips::cut_lips(job, &mut mesh, &mut marks, &mut registration, note)?,
        Some(_) => None,
    };
    let turn = crate::orient::head_orientation(&mesh, &marks).unwrap_or_default();
    let turn = if turn.is_identity() || avatar.is_none() {
        turn
    } else {
        note(format!(
            "warning: the avatar's face {}; it is not turned (glTF is y up, +z forward by its specification)",
            turn.describe()
        ));
        mimic_assets::Orientation::default()
    };
    if !turn.is_identity() {
        crate::orient::turn_mesh(&mut mesh, turn);
        if let Some(reg) = &mut registration {
            crate::orient::turn_registration(reg, turn);
        }
        note(crate::orient::turn_note(turn));
    }
    // The ARKit shapes are made for the skin; a cut mouth's added inside follows its template.
    let face = cut
        .as_ref()
        .map_or_else(|| mesh.clone(), |c| c.skin_of(&mesh));
    // An avatar's parts drawn with the face join the working mesh after the face's vertices
    // (the landmarks keep their numbers).
    let (avatar, mesh) = match avatar {
        Some(a) => {
            let whole = avatar::with_parts(a, &marks, note)?;
            let mesh = whole.face.mesh_data.clone();
            (Some(whole), mesh)
        }
        None => (None, mesh),
    };
    if let Some(out) = job.landmarks_out {
        write(out, &landmarks_json(&marks))?;
        note(format!(
            "wrote {} ({} landmarks)",
            out.display(),
            marks.count()
        ));
    }
    let name = job.name.clone().unwrap_or_else(|| {
        job.output
            .file_stem()
            .map_or_else(|| "rig".into(), |s| s.to_string_lossy().into_owned())
            .trim_end_matches(".generated")
            .to_string()
    });
    let mut generated = make_rig(&mesh, &marks, &name, job.units, job.defaults)
        .map_err(context(format!("{}: {marks_from}", job.mesh.display())))?;
    generated.orientation = turn;
    let file = cut.as_ref().map_or(job.mesh, |c| c.file.as_path());
    let text = rig_text(job, file, &mesh, &generated)?;
    let text = match &avatar {
        Some(a) => format!(
            "{text}{}{}",
            avatar::avatar_toml(&a.avatar, a.face.mesh, &a.section.parts),
            avatar::see_through_look(a)
        ),
        None => text,
    };
    let merged: Vec<(&Path, &str)> = overrides.iter().map(|(p, t)| (*p, t.as_str())).collect();
    let text = crate::apply_overrides(&text, &merged, job.output)?;
    write(job.output, &text)?;
    let loaded = read_back(job, &text, &marks)?;
    if job.blendshapes.is_some() {
        let inside = cut.as_ref().map(|c| (c.skin.0, &c.inside[..]));
        crate::arkit::add_arkit(job, &face, &loaded, registration, inside, note)?;
    }
    Ok(MadeRig { generated, loaded })
}

/// The generated rig's TOML (the command line as its second line); `file` (the mesh or avatar
/// file, or the cut mesh) is named as the rig's mesh, relative to the rig.
fn rig_text(
    job: &NewRig<'_>,
    file: &Path,
    mesh: &Mesh,
    rig: &GeneratedRig,
) -> Result<String, RigNewError> {
    let out_dir = job
        .output
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map_or_else(|| PathBuf::from("."), PathBuf::from);
    let mesh_rel = relative_path(&out_dir, file);
    let text = write_rig_toml(rig, &mesh_rel, mesh.vertex_count());
    let (first, rest) = text.split_once('\n').unwrap_or((&text, ""));
    Ok(format!(
        "{first}\n# Regenerate: {}\n{rest}",
        if job.command_line.is_empty() {
            job.repeat_command()
        } else {
            job.command_line.clone()
        }
    ))
}

/// Reads the written rig back as every other command will (its look and morph targets too when
/// overrides wrote them), and registers a dense control set into it if one was asked for.
fn read_back(job: &NewRig<'_>, text: &str, marks: &Landmarks) -> Result<Rig, RigNewError> {
    let written = || {
        context(format!(
            "{}: the written rig does not load",
            job.output.display()
        ))
    };
    let mut loaded = mimic_assets::load_rig(job.output)
        .map_err(RigNewError::from)
        .map_err(written())?;
    if !job.overrides.is_empty() {
        // The parts of a rig only an override writes: its look and morph targets.
        mimic_assets::load_rig_look(job.output)
            .and_then(|_| mimic_assets::load_morph_targets(job.output, &loaded))
            .map_err(RigNewError::from)
            .map_err(context(format!(
                "{}: the look or morph targets from the overrides do not load",
                job.output.display()
            )))?;
    }
    let registration = crate::register::apply_control_set(
        &mut loaded,
        job.controls,
        job.configs,
        Some(marks),
        &crate::register::RegisterSettings::default(),
    )
    .map_err(context(format!("--controls {}", job.controls)))?;
    if let Some(reg) = registration {
        let dense = crate::register::replace_controls_toml(text, &loaded.controls, &reg);
        write(job.output, &dense)?;
        loaded = mimic_assets::load_rig(job.output)
            .map_err(RigNewError::from)
            .map_err(written())?;
    }
    Ok(loaded)
}

/// Writes the rig file at `rig_path` with `rig`'s controls (a control set `registration` placed)
/// to `out`, which must be in the same folder (the mesh path in it is relative), and checks that
/// it loads (`mimic eval --write-rig`).
pub fn write_rig_with_controls(
    rig_path: &Path,
    out: &Path,
    rig: &Rig,
    registration: &crate::register::Registration,
) -> Result<(), RigNewError> {
    let folder = |p: &Path| p.parent().map(Path::to_path_buf).unwrap_or_default();
    if folder(out) != folder(rig_path) {
        return Err(RigNewError::Output {
            path: out.to_path_buf(),
            message: format!(
                "write it beside {} (its mesh path is relative)",
                rig_path.display()
            ),
        });
    }
    let text = mimic_types::limits::read_capped(rig_path, &mimic_types::limits::RIG_FILE).map_err(
        |cause| RigNewError::Read {
            path: rig_path.to_path_buf(),
            cause,
        },
    )?;
    write(
        out,
        &crate::register::replace_controls_toml(&text, &rig.controls, registration),
    )?;
    mimic_assets::load_rig(out)
        .map_err(RigNewError::from)
        .map_err(context(format!(
            "{}: the written rig does not load",
            out.display()
        )))?;
    Ok(())
}

/// The landmarks the rig is made from (given, filled in, or found) and where they came from.
fn landmarks_of(
    job: &NewRig<'_>,
    mesh: &Mesh,
    note: &mut dyn FnMut(String),
) -> Result<(Landmarks, String, Option<Registration>), RigNewError> {
    let Some((path, numbering)) = job.landmarks else {
        let (found, reg) = found_landmarks(job.mesh, mesh, job.configs, note)?;
        let from = "landmarks found by template registration".to_string();
        return Ok((found, from, Some(reg)));
    };
    let given = load_landmarks(path, numbering)?;
    let marks = if given.count() < IBUG_POINTS && !job.keep_missing {
        fill_missing(job.mesh, mesh, job.configs, given, note)
    } else {
        given
    };
    Ok((marks, path.display().to_string(), None))
}

/// `[0, 1, 2]`: a list of iBUG point numbers as the messages print it.
fn point_list(points: &[usize]) -> String {
    let items: Vec<String> = points.iter().map(usize::to_string).collect();
    format!("[{}]", items.join(", "))
}

/// The given landmarks with the points they lack taken from the template registration; the given
/// ones are kept as they are. A registration that fails (or lands far from the given points)
/// leaves the set as given, with a warning.
fn fill_missing(
    path: &Path,
    mesh: &Mesh,
    configs: &Path,
    mut given: Landmarks,
    note: &mut dyn FnMut(String),
) -> Landmarks {
    let missing: Vec<usize> = (0..IBUG_POINTS)
        .filter(|&k| given.get(k).is_none())
        .collect();
    note(format!(
        "the landmarks lack iBUG {}: taking them from a registration of the ICT head (--keep-missing leaves them out)",
        point_list(&missing)
    ));
    let found = match found_landmarks(path, mesh, configs, note) {
        Ok((f, _)) => f,
        Err(e) => {
            note(format!(
                "warning: no registration, the missing landmarks stay missing: {e}"
            ));
            return given;
        }
    };
    // The given points check the registration: how far its landmarks are from them.
    let at = |marks: &Landmarks, k: usize| {
        marks
            .get(k)
            .and_then(|v| mesh.positions.get(v as usize).copied())
    };
    let mut off: Vec<f32> = (0..IBUG_POINTS)
        .filter_map(|k| Some(at(&given, k)?.distance(at(&found, k)?)))
        .collect();
    off.sort_by(f32::total_cmp);
    let median = off.get(off.len() / 2).copied().unwrap_or(f32::INFINITY);
    let eyes = at(&given, 36)
        .zip(at(&given, 45))
        .map_or(f32::NAN, |(p, q)| p.distance(q));
    // The outer eye corners are about 1.4 IOD apart; a registration whose landmarks sit a fifth
    // of that from the given ones on the median has not found this face.
    let close = median <= 0.2 * eyes;
    if !close {
        note(format!(
            "warning: the registration's landmarks are {median:.4} from the given ones on the median (the outer eye corners are {eyes:.4} apart): the missing landmarks stay missing"
        ));
        return given;
    }
    let mut filled = Vec::new();
    for k in missing {
        if let Some(v) = found.get(k) {
            given.vertex[k] = Some(v);
            filled.push(k);
        }
    }
    note(format!(
        "filled iBUG {} from the registration (its landmarks are {median:.4} from the given ones on the median)",
        point_list(&filled)
    ));
    given
}

/// The landmarks of `mesh` found by registering the ICT head onto it, with the fit as a note,
/// and the registration.
fn found_landmarks(
    path: &Path,
    mesh: &Mesh,
    configs: &Path,
    note: &mut dyn FnMut(String),
) -> Result<(Landmarks, Registration), RigNewError> {
    let template = TemplateHead::ict(configs).map_err(context("loading the ICT template head"))?;
    let settings = FindSettings::default();
    let reg = register_template(mesh, &template, &settings).map_err(context(format!(
        "{}: registering the ICT template head",
        path.display()
    )))?;
    let found = crate::landmarks_of_registration(&reg, &settings);
    let worst = found
        .landmark_distance
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .fold(0.0, f32::max);
    note(format!(
        "registered the ICT head onto {} ({} nodes, best of {} starts: similarity covers {:.0}% at {:.3} IOD RMS; non-rigid fit covers {:.0}%, residual {:.3} IOD RMS; landmarks at most {worst:.3} IOD from their vertices); {} of 68 landmarks found (--landmarks-out writes them)",
        path.display(),
        found.nodes,
        found.starts,
        100.0 * found.rigid.coverage,
        found.rigid.rms,
        100.0 * found.coverage,
        found.residual,
        found.landmarks.count()
    ));
    if let Some(why) = found.doubt() {
        note(format!(
            "warning: the template registration probably failed ({why}): check the rig with `mimic rig check`, and give --landmarks (docs/rigging.md)"
        ));
    }
    Ok((found.landmarks, reg))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_folder_is_made_and_a_file_under_a_file_is_refused() {
        let dir = tempfile::tempdir().expect("tempdir");
        let nested = dir.path().join("a/b/rig.toml");
        prepare_output(&nested).expect("nested folder made");
        assert!(dir.path().join("a/b").is_dir());
        assert_eq!(
            std::fs::read_dir(dir.path().join("a/b"))
                .map(|d| d.count())
                .ok(),
            Some(0)
        );
        let file = dir.path().join("plain");
        std::fs::write(&file, "x").expect("write");
        let err = prepare_output(&file.join("sub/rig.toml")).expect_err("under a file");
        assert!(
            err.to_string().contains("cannot create the folder"),
            "{err}"
        );
        assert_eq!(point_list(&[0, 1, 60]), "[0, 1, 60]");
    }
}
