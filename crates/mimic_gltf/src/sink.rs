//! A take as one GLB, behind the frame loop's seam ([`GlbSink`]): each frame becomes a key
//! (the morph weights: the rig's fitted or given weights, or `d` in metres on the basis
//! targets; the head rotation and translation), and `finish` writes the rig, its targets and
//! the animation (docs/gltf.md). A path ending in `.vrm` asks for a VRM: the rig's avatar must
//! be one, and is written back whole as a VRM (docs/avatars.md).

use crate::{Interpolation, Morph, Take, basis_weights, metres_per_unit, write_rig_glb};
use glam::Vec3;
use mimic_types::{FrameSink, Rig, SinkError, SinkFrame, SinkReport};
use serde_json::json;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The keys of a GLB being collected (module docs).
pub struct GlbSink {
    path: PathBuf,
    rig_path: PathBuf,
    rig: Rig,
    morphs: Vec<Morph>,
    skin: [f32; 3],
    take: Take,
    /// Metres per rig unit.
    scale: f32,
    /// This key's weights.
    weights: Vec<f32>,
    /// The head's last translation (metres), held over frames without one.
    translation: Vec3,
    /// The rig's avatar, written back whole with the targets and the take (docs/avatars.md).
    avatar: Option<mimic_assets::RigAvatar>,
}

/// Whether `path` names a `.vrm` file.
fn is_vrm_path(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vrm"))
}

/// The file of `replay --out OUT` for a GLB (`vrm` false) or VRM: `out` itself when it ends in
/// `.glb` (`.vrm`), else `take.glb` (`take.vrm`) in the folder `out`.
pub fn take_path(out: &Path, vrm: bool) -> PathBuf {
    let ext = if vrm { "vrm" } else { "glb" };
    if out.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext)) {
        out.to_path_buf()
    } else {
        out.join(format!("take.{ext}"))
    }
}

/// How a [`GlbSink`] keys its take.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GlbKeys {
    /// Linear or step keys.
    pub interpolation: Interpolation,
    /// Whether the head pose is animated (else the face animates in place).
    pub pose: bool,
}

impl GlbSink {
    /// A GLB at `path` (its folder created if missing) of `rig` (read from `rig_path`, for
    /// materials and look) with `morphs` (one weight each per key) and skin colour `skin`.
    pub fn create(
        path: &Path,
        rig_path: &Path,
        rig: &Rig,
        morphs: Vec<Morph>,
        skin: [f32; 3],
        keys: GlbKeys,
    ) -> Result<Self, SinkError> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| SinkError::new(dir, e))?;
        }
        let avatar =
            mimic_assets::load_rig_avatar(rig_path).map_err(|e| SinkError::new(path, e))?;
        if is_vrm_path(path) && avatar.as_ref().is_none_or(|a| a.avatar.vrm.is_none()) {
            let has = avatar.as_ref().map_or("no avatar".into(), |a| {
                format!("the avatar {}, not a VRM", a.path.display())
            });
            return Err(SinkError::new(
                path,
                format!(
                    "--format vrm writes the rig's VRM avatar back, and rig `{}` has {has}",
                    rig.name
                ),
            ));
        }
        // An avatar's face is in the file's own units: its targets' weights are `d` as it is.
        let scale = if avatar.is_some() {
            Some(1.0)
        } else {
            metres_per_unit(&rig.units)
        }
        .ok_or_else(|| {
            SinkError::new(
                path,
                format!(
                    "rig `{}`: units `{}` have no length in metres for glTF",
                    rig.name, rig.units
                ),
            )
        })?;
        let targets = morphs.len();
        Ok(Self {
            path: path.to_path_buf(),
            rig_path: rig_path.to_path_buf(),
            rig: rig.clone(),
            morphs,
            skin,
            take: Take::new(targets, keys.interpolation, keys.pose),
            scale,
            weights: vec![0.0; targets],
            translation: Vec3::ZERO,
            avatar,
        })
    }
}

impl FrameSink for GlbSink {
    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<(), SinkError> {
        match f.weights {
            Some(w) if w.len() == self.weights.len() => self.weights.copy_from_slice(w),
            Some(w) => {
                return Err(SinkError::new(
                    &self.path,
                    format!(
                        "frame {} has {} weights; the GLB has {} morph targets",
                        f.index,
                        w.len(),
                        self.weights.len()
                    ),
                ));
            }
            None if 3 * f.view.displacements.len() == self.weights.len() => {
                basis_weights(f.view.displacements, self.scale, &mut self.weights);
            }
            None => {
                return Err(SinkError::new(
                    &self.path,
                    format!(
                        "frame {} has {} controls; the GLB has {} basis targets",
                        f.index,
                        f.view.displacements.len(),
                        self.weights.len()
                    ),
                ));
            }
        }
        if let Some(t) = f.head_translation {
            self.translation = t * self.scale;
        }
        self.take.push(
            f.view.timestamp_us,
            &self.weights,
            (f.view.target_rotation, self.translation),
        );
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<SinkReport, SinkError> {
        let started = Instant::now();
        let path = &self.path;
        let file = File::create(path).map_err(|e| SinkError::new(path, e))?;
        let mut w = BufWriter::new(file);
        // The avatar written back whole, else the rig as one GLB: the summary either way.
        let (bytes, summary) = match &self.avatar {
            Some(a) => {
                let take = Some(&self.take);
                let s = crate::write_avatar_glb(&a.avatar, &a.face, &self.morphs, take, &mut w)
                    .map_err(|e| SinkError::new(path, e))?;
                (s.bytes, json!(s))
            }
            None => {
                let s = write_rig_glb(
                    &self.rig_path,
                    &self.rig,
                    &self.morphs,
                    Some(&self.take),
                    self.skin,
                    &mut w,
                )
                .map_err(|e| SinkError::new(path, e))?;
                (s.bytes, json!(s))
            }
        };
        w.flush().map_err(|e| SinkError::new(path, e))?;
        Ok(SinkReport {
            kind: "glb",
            path: self.path.clone(),
            frames: self.take.len(),
            bytes: bytes as u64,
            detail: json!({
                "summary": summary,
                "skipped_frames": self.take.skipped(),
                "write_s": started.elapsed().as_secs_f64(),
            }),
        })
    }
}
