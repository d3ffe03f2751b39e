//! `mimic rig new`: a rig from a face mesh and its iBUG landmarks (logic in `mimic_rig`).

use anyhow::{Context, bail};
use mimic_rig::{Defaults, LandmarkBase, load_landmarks, make_rig, relative_path, write_rig_toml};
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
    /// vertices, or `N = V` lines.
    #[arg(long)]
    pub landmarks: Option<PathBuf>,
    /// Where the numbers of an `N = V` landmark file count from (both N and V).
    #[arg(long, default_value = "0", value_parser = parse_base)]
    pub landmark_base: LandmarkBase,
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
    let Some(marks_path) = &args.landmarks else {
        bail!(
            "--landmarks is needed: finding the landmarks by registering a template head is not implemented yet (docs/rigging.md)"
        );
    };
    let mesh = mimic_rig::load_mesh(&args.mesh)?;
    let marks = load_landmarks(marks_path, args.landmark_base)?;
    let name = args.name.clone().unwrap_or_else(|| {
        args.output
            .file_stem()
            .map_or_else(|| "rig".into(), |s| s.to_string_lossy().into_owned())
            .trim_end_matches(".generated")
            .to_string()
    });
    let rig = make_rig(
        &mesh,
        &marks,
        &name,
        args.units.as_deref(),
        Defaults::default(),
    )
    .with_context(|| format!("{}: {}", args.mesh.display(), marks_path.display()))?;
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
    let text = write_rig_toml(&rig, &mesh_rel, mesh.vertex_count());
    std::fs::write(&args.output, &text).with_context(|| args.output.display().to_string())?;
    // Read it back as every other command will.
    let mut loaded = mimic_assets::load_rig(&args.output)
        .with_context(|| format!("{}: the written rig does not load", args.output.display()))?;
    if let Some(reg) = mimic_rig::register::apply_control_set(
        &mut loaded,
        &args.controls,
        &mimic_assets::ConfigDirs::locate(None).root,
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
