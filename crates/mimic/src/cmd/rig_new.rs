//! `mimic rig new`: a rig from a face mesh and its iBUG landmarks (the work is
//! `mimic_rig::make_rig_file`).

use mimic_rig::{Defaults, LandmarkBase, NewRig, Numbering, make_rig_file};
use mimic_types::SolverKind;
use std::path::PathBuf;
use std::str::FromStr;

/// Arguments of `mimic rig new`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The face mesh (OBJ), or an avatar (glTF, GLB, VRM) the rig names as it is: its face
    /// mesh drives, its other meshes are classified (docs/avatars.md); y up, facing +z.
    pub mesh: PathBuf,
    /// For an avatar: the face mesh's name, or `#K` for mesh K (default: the largest mesh named
    /// like a face or head, else the largest).
    #[arg(long)]
    pub face: Option<String>,
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
    #[arg(long, value_parser = LandmarkBase::from_str)]
    pub landmark_base: Option<LandmarkBase>,
    /// Where the vertex indices V of an `N = V` landmark file count from (eos's files for the
    /// Surrey and Basel models: 0; OBJ numbering: 1).
    #[arg(long, default_value = "0", value_parser = LandmarkBase::from_str)]
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
    /// Also make ARKit's 52 blend shapes for the head as the rig's morph targets (ICT-FaceKit's
    /// expressions transferred through the registration; docs/rigging.md, "ARKit shapes").
    #[arg(long, value_parser = ["arkit"])]
    pub blendshapes: Option<String>,
    /// Keep closed lips as they are (by default a mesh whose lips are one surface is cut along
    /// its lip line so the mouth opens; docs/rigging.md, "Closed lips").
    #[arg(long)]
    pub no_cut: bool,
}

/// Runs `mimic rig new`: the options are checked and the output folder made before the work.
pub fn run(args: Args) -> anyhow::Result<()> {
    let configs = mimic_assets::ConfigDirs::locate(None).root;
    let job = NewRig {
        mesh: &args.mesh,
        face: args.face.as_deref(),
        output: &args.output,
        landmarks: args.landmarks.as_deref().map(|p| {
            let numbering = Numbering {
                point: args.landmark_base,
                vertex: args.vertex_base,
            };
            (p, numbering)
        }),
        keep_missing: args.keep_missing,
        landmarks_out: args.landmarks_out.as_deref(),
        units: args.units.as_deref(),
        name: args.name.clone(),
        controls: &args.controls,
        overrides: &args.overrides,
        defaults: Defaults {
            back_of_head: args.frozen_beyond,
            // `auto` names no solver: picked from the eyes.
            solver: SolverKind::ALL
                .into_iter()
                .find(|k| k.name() == args.solver),
            ..Defaults::default()
        },
        configs: &configs,
        // Empty: the rig's header gets `job.repeat_command()`.
        command_line: String::new(),
        blendshapes: args.blendshapes.as_deref(),
        cut: !args.no_cut,
    };
    let made = make_rig_file(&job, &mut |line| eprintln!("{line}"))?;
    println!("{}", made.summary(&args.output));
    for w in made.warnings() {
        eprintln!("warning: {w}");
    }
    Ok(())
}
