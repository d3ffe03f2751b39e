//! Where `mimic replay` writes deformed frames: nothing, OBJ frames, one `frames.bin`, or the
//! keys of one GLB; set up from the flags ([`Sink::open`]) and written frame by frame.

use super::{Args, OutFormat, status_code};
use crate::cmd::setup::obj_frame_path;
use anyhow::Context;
use glam::Vec3;
use mimic_assets::{FramesWriter, ObjFrames};
use mimic_gltf::{Interpolation, Take};
use mimic_retarget::FrameOutput;
use mimic_types::{Mesh, Rig};
use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;

/// Where deformed frames go.
pub(super) enum Sink {
    None,
    Obj {
        dir: PathBuf,
        frames: ObjFrames,
    },
    Bin {
        writer: FramesWriter<BufWriter<File>>,
        path: PathBuf,
        written: usize,
    },
    Glb(Box<GlbSink>),
}

/// The keys of a GLB being collected.
pub(super) struct GlbSink {
    pub(super) path: PathBuf,
    pub(super) take: Take,
    /// Metres per rig unit.
    pub(super) scale: f32,
    /// This frame's weights.
    pub(super) weights: Vec<f32>,
    /// The head's last translation (metres), held over frames without one.
    pub(super) translation: Vec3,
}

impl Sink {
    /// Frames (or GLB keys) written so far.
    pub(super) fn written(&self) -> usize {
        match self {
            Sink::None => 0,
            Sink::Obj { frames, .. } => frames.written(),
            Sink::Bin { written, .. } => *written,
            Sink::Glb(g) => g.take.len(),
        }
    }
}

impl Sink {
    /// The sink `--out` and `--format` ask for, on `rig`; a GLB gets `blend_targets` weights a
    /// key in blendshape mode, else three per control.
    pub(super) fn open(
        args: &Args,
        rig: &Rig,
        blend_targets: Option<usize>,
    ) -> anyhow::Result<Self> {
        let sink = match (&args.out, args.format) {
            (None, _) => Sink::None,
            (Some(out), OutFormat::Glb) => {
                let path = if out
                    .extension()
                    .is_some_and(|e| e.eq_ignore_ascii_case("glb"))
                {
                    out.clone()
                } else {
                    out.join("take.glb")
                };
                if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                    std::fs::create_dir_all(dir)
                        .with_context(|| format!("creating {}", dir.display()))?;
                }
                let scale = mimic_gltf::metres_per_unit(&rig.units).with_context(|| {
                    format!(
                        "rig `{}`: units `{}` have no length in metres for glTF",
                        rig.name, rig.units
                    )
                })?;
                let targets = blend_targets.unwrap_or(3 * rig.controls.len());
                let interpolation = if args.step_keys {
                    Interpolation::Step
                } else {
                    Interpolation::Linear
                };
                Sink::Glb(Box::new(GlbSink {
                    path,
                    take: Take::new(targets, interpolation, !args.no_pose),
                    scale,
                    weights: vec![0.0; targets],
                    translation: Vec3::ZERO,
                }))
            }
            (Some(dir), format) => {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("creating {}", dir.display()))?;
                match format {
                    OutFormat::Obj => Sink::Obj {
                        dir: dir.clone(),
                        frames: ObjFrames::new(
                            dir,
                            &args.rig.rig_path(),
                            &rig.name,
                            rig.mesh.triangles.len(),
                        )?,
                    },
                    OutFormat::Glb => unreachable!("matched above"),
                    OutFormat::Bin => {
                        let path = dir.join("frames.bin");
                        let file =
                            File::create(&path).with_context(|| path.display().to_string())?;
                        let writer = FramesWriter::new(
                            BufWriter::new(file),
                            rig.mesh.vertex_count(),
                            &rig.mesh.triangles,
                            true,
                        )?;
                        Sink::Bin {
                            writer,
                            path,
                            written: 0,
                        }
                    }
                }
            }
        };
        Ok(sink)
    }
}

/// Writes one deformed frame to an OBJ or binary sink (a GLB collects keys instead).
pub(super) fn write_frame(
    sink: &mut Sink,
    index: usize,
    out: &FrameOutput,
    mesh: &Mesh,
    rig: &str,
) -> anyhow::Result<()> {
    match sink {
        Sink::None | Sink::Glb(_) => {}
        Sink::Obj { dir, frames } => {
            let header = format!(
                "mimic replay onto rig {rig}: frame {index}, t = {} us",
                out.timestamp_us
            );
            let path = obj_frame_path(dir, index);
            frames.write(&path, &header, &out.positions, &out.normals, mesh)?;
        }
        Sink::Bin {
            writer,
            path,
            written,
        } => {
            writer
                .write_frame(
                    out.timestamp_us,
                    status_code(out.status),
                    &out.pose,
                    &out.positions,
                    &out.normals,
                )
                .with_context(|| path.display().to_string())?;
            *written += 1;
        }
    }
    Ok(())
}
