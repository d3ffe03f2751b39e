//! `mimic rig new`: a rig from a face mesh and its iBUG landmarks (logic in `mimic_rig`).

use anyhow::Context;
use mimic_rig::{
    Defaults, FindSettings, LandmarkBase, Landmarks, Numbering, TemplateHead, find_landmarks,
    landmarks_json, load_landmarks, make_rig, relative_path, write_rig_toml,
};
use mimic_types::SolverKind;
use std::path::Path;
use std::path::PathBuf;

/// Arguments of `mimic rig new`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The face mesh (OBJ, or glTF / GLB: then an OBJ copy is written beside the rig as
    /// `<rig>.mesh.obj`, which the rig names), y up, facing +z.
    pub mesh: PathBuf,
    /// Where to write the rig TOML.
    #[arg(short = 'o', long)]
    pub output: PathBuf,
    /// Which vertex carries each iBUG-68 point: a JSON object {"0": V, ...}, a JSON list of 68
    /// vertices, or `N = V` lines. Without it they are found by registering the ICT head onto
    /// the mesh (docs/rigging.md, "Without --landmarks").
    #[arg(long)]
    pub landmarks: Option<PathBuf>,
    /// Write the landmarks the rig was made from (given or found) to this file, as the JSON
    /// object `--landmarks` reads, to inspect and fix them.
    #[arg(long)]
    pub landmarks_out: Option<PathBuf>,
    /// Where the iBUG numbers N of an `N = V` landmark file count from (default: seen from the
    /// file, a point 68 and no point 0 meaning 1).
    #[arg(long, value_parser = parse_base)]
    pub landmark_base: Option<LandmarkBase>,
    /// Where the vertex indices V of an `N = V` landmark file count from (eos's files for the
    /// Surrey and Basel models: 0; OBJ numbering: 1).
    #[arg(long, default_value = "0", value_parser = parse_base)]
    pub vertex_base: LandmarkBase,
    /// Length unit of the mesh (default: guessed from the distance between the eyes).
    #[arg(long, value_parser = ["m", "cm", "mm", "in", "model"])]
    pub units: Option<String>,
    /// Rig name (default: the output file's stem).
    #[arg(long)]
    pub name: Option<String>,
    /// Which controls the rig gets: `mpeg4` (the 38 FDPs placed by rules) or a layout's own
    /// points registered from its template: `kinect121`, `ibug68`, `mediapipe478`
    /// (docs/rigging.md, "Dense control sets"; the FDPs are placed first, as the landmarks the
    /// registration aligns by).
    #[arg(long, default_value = "mpeg4")]
    pub controls: String,
    /// Hand values kept over the generated ones: a TOML file whose tables merge into the rig's
    /// key by key, whose other values (arrays included) replace the rig's, and whose
    /// `[[controls]]` entries change the control their `fdp` names (docs/rigging.md,
    /// "Overrides"). Repeatable; applied in order, each checked by loading the merged rig.
    #[arg(long = "overrides", value_name = "FILE")]
    pub overrides: Vec<PathBuf>,
    /// Freeze the vertices of the controlled pieces farther than this many inter-ocular
    /// distances from every landmark (the back of the head, the neck).
    #[arg(long, value_name = "IOD", default_value_t = Defaults::default().back_of_head)]
    pub frozen_beyond: f32,
    /// The rig's solver: `auto` measures the eyes (open lids: `rbf` with the lid / brow split;
    /// closed skin, as in morphable face models: `shell`; docs/rigging.md, "Which solver").
    #[arg(long, default_value = "auto", value_parser = ["auto", "rbf", "shell", "laplacian"])]
    pub solver: String,
    /// With `--landmarks`: leave the iBUG points the file lacks out, instead of taking them from
    /// a registration of the ICT head (which the given points check).
    #[arg(long)]
    pub keep_missing: bool,
}

impl Args {
    /// The command line that makes this rig again, as written into its header.
    fn command_line(&self) -> String {
        let mut words = vec![
            "mimic rig new".to_string(),
            self.mesh.display().to_string(),
            format!("-o {}", self.output.display()),
        ];
        if let Some(l) = &self.landmarks {
            words.push(format!("--landmarks {}", l.display()));
            if let Some(b) = self.landmark_base {
                words.push(format!("--landmark-base {}", b.offset()));
            }
            if self.vertex_base == LandmarkBase::One {
                words.push("--vertex-base 1".into());
            }
            if self.keep_missing {
                words.push("--keep-missing".into());
            }
        }
        if let Some(u) = &self.units {
            words.push(format!("--units {u}"));
        }
        if let Some(n) = &self.name {
            words.push(format!("--name {n}"));
        }
        if self.controls != "mpeg4" {
            words.push(format!("--controls {}", self.controls));
        }
        if self.frozen_beyond != Defaults::default().back_of_head {
            words.push(format!("--frozen-beyond {}", self.frozen_beyond));
        }
        if self.solver != "auto" {
            words.push(format!("--solver {}", self.solver));
        }
        for o in &self.overrides {
            words.push(format!("--overrides {}", o.display()));
        }
        words.join(" ")
    }
}

fn parse_base(s: &str) -> Result<LandmarkBase, String> {
    match s {
        "0" => Ok(LandmarkBase::Zero),
        "1" => Ok(LandmarkBase::One),
        _ => Err(format!("`{s}`: the landmark base is 0 or 1")),
    }
}

/// Runs `mimic rig new`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mesh = mimic_rig::load_mesh(&args.mesh)?;
    let configs = mimic_assets::ConfigDirs::locate(None).root;
    let (marks, marks_from) = match &args.landmarks {
        Some(path) => {
            let numbering = Numbering {
                point: args.landmark_base,
                vertex: args.vertex_base,
            };
            let given = load_landmarks(path, numbering)?;
            let marks = if given.count() < mimic_rig::IBUG_POINTS && !args.keep_missing {
                fill_missing(&args.mesh, &mesh, &configs, given)
            } else {
                given
            };
            (marks, path.display().to_string())
        }
        None => (
            found_landmarks(&args.mesh, &mesh, &configs)?,
            "landmarks found by template registration".to_string(),
        ),
    };
    if let Some(out) = &args.landmarks_out {
        std::fs::write(out, landmarks_json(&marks)).with_context(|| out.display().to_string())?;
        eprintln!("wrote {} ({} landmarks)", out.display(), marks.count());
    }
    let name = args.name.clone().unwrap_or_else(|| {
        args.output
            .file_stem()
            .map_or_else(|| "rig".into(), |s| s.to_string_lossy().into_owned())
            .trim_end_matches(".generated")
            .to_string()
    });
    if !(args.frozen_beyond.is_finite() && args.frozen_beyond > 0.0) {
        anyhow::bail!(
            "--frozen-beyond {}: a distance in inter-ocular distances above 0",
            args.frozen_beyond
        );
    }
    let overrides = args
        .overrides
        .iter()
        .map(|p| {
            mimic_types::limits::read_capped(p, &mimic_types::limits::RIG_FILE)
                .map(|t| (p.as_path(), t))
                .with_context(|| format!("--overrides {}", p.display()))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let defaults = Defaults {
        back_of_head: args.frozen_beyond,
        // `auto` names no solver: picked from the eyes.
        solver: SolverKind::ALL
            .into_iter()
            .find(|k| k.name() == args.solver),
        ..Defaults::default()
    };
    let rig = make_rig(&mesh, &marks, &name, args.units.as_deref(), defaults)
        .with_context(|| format!("{}: {marks_from}", args.mesh.display()))?;
    let out_dir = args
        .output
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map_or_else(|| PathBuf::from("."), PathBuf::from);
    let mesh_file = if mimic_rig::gltf_mesh::is_gltf(&args.mesh) {
        let stem = args
            .output
            .file_stem()
            .map_or_else(|| "rig".into(), |s| s.to_string_lossy().into_owned());
        // The OBJ copy keeps the glTF's UVs, materials and base colour textures (MTL map_Kd).
        let (_, look) = mimic_rig::gltf_mesh::load_gltf_look(&args.mesh)?;
        let header = format!("from {} by mimic rig new", args.mesh.display());
        mimic_rig::gltf_mesh::write_obj_copy(&out_dir, &stem, &mesh, &look, &header)
            .with_context(|| format!("writing {stem}.mesh.obj in {}", out_dir.display()))?
    } else {
        args.mesh.clone()
    };
    let mesh_rel = relative_path(&out_dir, &mesh_file);
    let text = with_command(
        &write_rig_toml(&rig, &mesh_rel, mesh.vertex_count()),
        &args.command_line(),
    );
    let merged: Vec<(&Path, &str)> = overrides.iter().map(|(p, t)| (*p, t.as_str())).collect();
    let text = mimic_rig::apply_overrides(&text, &merged, &args.output)?;
    std::fs::write(&args.output, &text).with_context(|| args.output.display().to_string())?;
    // Read it back as every other command will.
    let mut loaded = mimic_assets::load_rig(&args.output)
        .with_context(|| format!("{}: the written rig does not load", args.output.display()))?;
    if !args.overrides.is_empty() {
        // The parts of a rig only an override writes: its look and morph targets.
        mimic_assets::load_rig_look(&args.output)
            .and_then(|_| mimic_assets::load_morph_targets(&args.output, &loaded))
            .with_context(|| {
                format!(
                    "{}: the look or morph targets from the overrides do not load",
                    args.output.display()
                )
            })?;
    }
    if let Some(reg) = mimic_rig::register::apply_control_set(
        &mut loaded,
        &args.controls,
        &configs,
        Some(&marks),
        &mimic_rig::register::RegisterSettings::default(),
    )
    .with_context(|| format!("--controls {}", args.controls))?
    {
        let dense = mimic_rig::register::replace_controls_toml(&text, &loaded.controls, &reg);
        std::fs::write(&args.output, &dense).with_context(|| args.output.display().to_string())?;
        loaded = mimic_assets::load_rig(&args.output)
            .with_context(|| format!("{}: the written rig does not load", args.output.display()))?;
    }
    let c = rig.frozen_counts;
    println!(
        "wrote {}: {} controls, {} of {} vertices frozen ({} unused, {} in {} pieces with no control, {} far from the face), units {}, IOD {:.4}",
        args.output.display(),
        loaded.controls.len(),
        loaded.frozen.iter().filter(|f| **f).count(),
        loaded.mesh.vertex_count(),
        c.unused,
        c.uncontrolled,
        c.uncontrolled_pieces,
        c.far,
        loaded.units,
        rig.frame.iod
    );
    for w in &rig.warnings {
        eprintln!("warning: {w}");
    }
    for w in mimic_rig::check_rig(&loaded) {
        eprintln!("warning: {w}");
    }
    Ok(())
}

/// The rig text with the command that regenerates it as its second line.
fn with_command(text: &str, command: &str) -> String {
    let (first, rest) = text.split_once('\n').unwrap_or((text, ""));
    format!("{first}\n# Regenerate: {command}\n{rest}")
}

/// The given landmarks with the points they lack taken from the template registration; the given
/// ones are kept as they are. A registration that fails (or lands far from the given points)
/// leaves the set as given, with a warning.
fn fill_missing(
    path: &Path,
    mesh: &mimic_types::Mesh,
    configs: &Path,
    mut given: Landmarks,
) -> Landmarks {
    let missing: Vec<usize> = (0..mimic_rig::IBUG_POINTS)
        .filter(|&k| given.get(k).is_none())
        .collect();
    eprintln!(
        "the landmarks lack iBUG {missing:?}: taking them from a registration of the ICT head (--keep-missing leaves them out)"
    );
    let found = match found_landmarks(path, mesh, configs) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("warning: no registration, the missing landmarks stay missing: {e:#}");
            return given;
        }
    };
    // The given points check the registration: how far its landmarks are from them.
    let at = |marks: &Landmarks, k: usize| {
        marks
            .get(k)
            .and_then(|v| mesh.positions.get(v as usize).copied())
    };
    let mut off: Vec<f32> = (0..mimic_rig::IBUG_POINTS)
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
        eprintln!(
            "warning: the registration's landmarks are {median:.4} from the given ones on the median (the outer eye corners are {eyes:.4} apart): the missing landmarks stay missing"
        );
        return given;
    }
    let mut filled = Vec::new();
    for k in missing {
        if let Some(v) = found.get(k) {
            given.vertex[k] = Some(v);
            filled.push(k);
        }
    }
    eprintln!(
        "filled iBUG {filled:?} from the registration (its landmarks are {median:.4} from the given ones on the median)"
    );
    given
}

/// The landmarks of `mesh` found by registering the ICT head onto it, with the fit on stderr.
fn found_landmarks(
    path: &Path,
    mesh: &mimic_types::Mesh,
    configs: &Path,
) -> anyhow::Result<Landmarks> {
    let template = TemplateHead::ict(configs).context("loading the ICT template head")?;
    let found = find_landmarks(mesh, &template, &FindSettings::default())
        .with_context(|| format!("{}: registering the ICT template head", path.display()))?;
    let worst = found
        .landmark_distance
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .fold(0.0, f32::max);
    eprintln!(
        "registered the ICT head onto {} ({} nodes, best of {} starts: similarity covers {:.0}% at {:.3} IOD RMS; non-rigid fit covers {:.0}%, residual {:.3} IOD RMS; landmarks at most {worst:.3} IOD from their vertices); {} of 68 landmarks found (--landmarks-out writes them)",
        path.display(),
        found.nodes,
        found.starts,
        100.0 * found.rigid.coverage,
        found.rigid.rms,
        100.0 * found.coverage,
        found.residual,
        found.landmarks.count()
    );
    if let Some(why) = found.doubt() {
        eprintln!(
            "warning: the template registration probably failed ({why}): check the rig with `mimic rig check`, and give --landmarks (docs/rigging.md)"
        );
    }
    Ok(found.landmarks)
}
