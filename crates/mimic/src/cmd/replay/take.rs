//! `mimic replay TAKE.csv`: a Live Link Face CSV take onto a rig's morph targets. The take's
//! tracked rows (`mimic_trackers::take`), at their `Timecode` times, go through the name map
//! onto the rig's `[[morph_targets]]` (`mimic_retarget::WeightMap`); head yaw, pitch and roll
//! become the head rotation. Written as a blendshape-mode GLB (the rig's own morph targets, one
//! key per row), OBJ frames or `frames.bin` of the blend `P0 + sum w dP`, and `--weights` as in
//! blendshape mode.

use super::{Args, outputs};
use anyhow::{Context, bail};
use mimic_assets::{load_morph_targets, load_rig};
use mimic_retarget::{BlendshapeFitter, FrameLoop};
use mimic_trackers::namemap::NameMap;
use mimic_trackers::take::{read_take, take_weights};
use mimic_trackers::take_rig::TakeOntoRig;
use mimic_trackers::take_summary::TakeSummary;
use std::time::{Duration, Instant};

/// Replays the take `args.recording`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let path = &args.recording;
    if args.metrics.is_some() || args.controls.is_some() || args.audio.is_some() {
        bail!(
            "{}: a Live Link take drives morph targets: --metrics, --controls and --audio are for landmark recordings",
            path.display()
        );
    }
    let take = read_take(path)?;
    let rig_path = args.rig.rig_path();
    let rig = load_rig(&rig_path)?;
    let (fitter, targets) = morph_fitter(args, &rig_path, &rig)?;
    let names = fitter.names().to_vec();
    let namemap_path = args.namemap_path();
    let map = NameMap::load(&namemap_path)?;
    let tw = take_weights(&take, &map);
    let mut onto = TakeOntoRig::new(&take, &tw, &names);
    let lacking = onto.lacking();
    if let Some(line) = onto
        .lacking_line(&rig.name, &lacking)
        .filter(|_| !args.json)
    {
        println!("{line}");
    }
    let header = format!("mimic replay of a Live Link take onto rig {}", rig.name);
    let mut frames = FrameLoop::weights(&rig.mesh.positions, fitter);
    outputs::add(args, &rig, &targets, &header, &mut frames)?;
    let started = Instant::now();
    for k in 0..onto.len() {
        if args.max_frames.is_some_and(|m| frames.frames() >= m) {
            break;
        }
        let Some((t_us, w, head)) = onto.frame(k) else {
            break;
        };
        if args.realtime {
            let due = t_us as f64 / 1e6 / args.speed.max(1e-3);
            let now = started.elapsed().as_secs_f64();
            if due > now {
                std::thread::sleep(Duration::from_secs_f64(due - now));
            }
        }
        frames.push_weights(t_us, w, head)?;
    }
    let paced_s = started.elapsed().as_secs_f64();
    let count = frames.frames();
    let report = frames.finish()?;
    let summary = TakeSummary {
        path,
        rig: &rig.name,
        take: &take,
        weights: &tw,
        targets: &names,
        lacking: &lacking,
        wall_s: paced_s,
        frames: count,
        outputs: &report.outputs,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary.json())?);
    } else {
        print!("{}", summary.text());
    }
    Ok(())
}

/// The rig's morph targets and their blend (a take drives nothing else).
fn morph_fitter(
    args: &Args,
    rig_path: &std::path::Path,
    rig: &mimic_types::Rig,
) -> anyhow::Result<(BlendshapeFitter, Vec<mimic_types::MorphTarget>)> {
    let targets = load_morph_targets(rig_path, rig)?;
    if targets.is_empty() {
        bail!(
            "rig `{}` has no [[morph_targets]]: a Live Link take drives morph targets",
            rig.name
        );
    }
    let fitter = BlendshapeFitter::new(rig, &targets, &args.blend.settings(rig_path)?)
        .with_context(|| format!("morph targets of rig `{}`", rig.name))?;
    Ok((fitter, targets))
}
