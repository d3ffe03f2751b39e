//! The mouth from speech on any rig (`mimic replay REC --audio SPEECH.wav`): the lip sync's ARKit
//! mouth weights ([`mimic_audio::lip_sync`]) drive the rig's mouth controls through ICT's
//! expression set ([`crate::arkit::arkit_from_ict`]) read at the template's controls and scaled
//! by the two faces' inter-ocular distances ([`mouth_shapes`]); the tracker keeps the rest
//! ([`mimic_retarget::mouth::MouthDrive`]).

use crate::RigNewError;
use crate::arkit::{ICT_EXPRESSIONS, arkit_from_ict};
use glam::Vec3;
use mimic_audio::{AudioError, LipSync, visemes::VisemeTable};
use mimic_retarget::face_size;
use mimic_retarget::mouth::{MouthDrive, MouthError};
use mimic_types::{ControlName, Region, Rig};
use std::path::Path;

/// The template rig whose controls read ICT's shapes, relative to `configs/`.
pub const TEMPLATE_RIG: &str = "rigs/ict-face.toml";

/// One shape's displacement at every control of a rig, if the template has the shape.
pub type ShapeAtControls = Option<Vec<Vec3>>;

/// Why the mouth cannot be driven from speech.
#[derive(Debug, thiserror::Error)]
pub enum SpeechMouthError {
    /// The template or its shapes could not be read.
    #[error(transparent)]
    Rig(#[from] RigNewError),
    /// The speech could not be read or recognised.
    #[error(transparent)]
    Audio(#[from] AudioError),
    /// The drive does not fit the rig.
    #[error(transparent)]
    Mouth(#[from] MouthError),
}

/// Per name, the displacement ARKit shape `name` implies at each of `rig`'s controls (target
/// units; `None` where ICT lacks the shape); and per control, how much of it the mouth drives
/// (1 for the bottom region's controls the template can read, else 0). A control is read at
/// its own vertex when the rig's mesh is the template's, else at the template's control of the
/// same MPEG-4 feature point.
pub fn mouth_shapes(
    configs: &Path,
    rig: &Rig,
    names: &[&str],
) -> Result<(Vec<ShapeAtControls>, Vec<f32>), RigNewError> {
    let template = mimic_assets::load_rig(&configs.join(TEMPLATE_RIG))?;
    let pack = mimic_assets::load_shape_pack(&configs.join(ICT_EXPRESSIONS))?;
    let (shapes, _) = arkit_from_ict(&pack);
    let scale_of = |r: &Rig| {
        let names: Vec<ControlName> = r.controls.iter().map(|c| c.fdp).collect();
        face_size(&names, &r.control_positions())
    };
    let scale = match (scale_of(rig), scale_of(&template)) {
        (Some(a), Some(b)) => a / b,
        _ => {
            return Err(RigNewError::Frame(
                "speech: a face too degenerate to measure".into(),
            ));
        }
    };
    let same_mesh = rig.mesh.vertex_count() == template.mesh.vertex_count()
        && rig
            .mesh
            .positions
            .iter()
            .zip(&template.mesh.positions)
            .all(|(a, b)| a.distance(*b) <= 1e-4 * (1.0 + b.length()));
    let read_at: Vec<Option<usize>> = rig
        .controls
        .iter()
        .map(|c| {
            if same_mesh {
                return Some(c.vertex as usize);
            }
            template
                .controls
                .iter()
                .find(|t| matches!(c.fdp, ControlName::Fdp(_)) && t.fdp == c.fdp)
                .map(|t| t.vertex as usize)
        })
        .collect();
    let mix = rig
        .controls
        .iter()
        .zip(&read_at)
        .map(|(c, at)| f32::from(u8::from(c.region == Region::Bottom && at.is_some())))
        .collect();
    let per_name = names
        .iter()
        .map(|name| {
            let shape = shapes.iter().find(|s| s.name == *name)?;
            Some(
                read_at
                    .iter()
                    .map(|at| at.map_or(Vec3::ZERO, |v| shape.deltas[v] * scale))
                    .collect(),
            )
        })
        .collect();
    Ok((per_name, mix))
}

/// The mouth drive of `rig` from the speech in `wav` (phones recognised, or laid along the
/// words of `transcript`: text, or a file of it), starting `offset_s` after the first frame; and
/// one line saying what drives the mouth ([`speech_line`]).
pub fn speech_drive(
    configs: &Path,
    rig: &Rig,
    wav: &Path,
    transcript: Option<&str>,
    offset_s: f64,
) -> Result<(MouthDrive, String), SpeechMouthError> {
    let words = transcript.map(mimic_audio::transcript_words).transpose()?;
    let sync = mimic_audio::lip_sync(wav, words.as_deref(), &VisemeTable::shipped()?)?;
    let (shapes, mix) = mouth_shapes(configs, rig, &sync.names)?;
    let drive = MouthDrive::new(
        mix,
        &sync.names,
        &shapes,
        &sync.frames,
        mimic_audio::coart::FPS,
        offset_s,
    )?;
    let line = speech_line(wav, &sync, &drive, rig.controls.len());
    Ok((drive, line))
}

/// One line saying what drives the mouth: the speech's figures and the controls it drives.
pub fn speech_line(wav: &Path, sync: &LipSync, drive: &MouthDrive, controls: usize) -> String {
    let mut line = format!(
        "mouth from {} ({} of {controls} controls)",
        sync.said(wav),
        drive.driven_controls()
    );
    if !drive.lacking().is_empty() {
        line.push_str(&format!(
            "; shapes the template lacks, left out: {}",
            drive.lacking().join(", ")
        ));
    }
    line
}
