//! The outputs `mimic replay`'s flags ask for, added to the frame loop: the frames (`--out`,
//! `--format`: OBJ, `frames.bin` or one GLB or VRM), `--metrics`, `--controls` and `--weights`. Each
//! output lives beside its format (mimic_assets, mimic_gltf, mimic_trackers); this table only
//! picks them.

use super::{Args, OutFormat, WeightsFormat};
use anyhow::Context;
use mimic_assets::{BinSink, ControlsCsv, MetricsCsv, ObjSink};
use mimic_gltf::{
    GlbKeys, GlbSink, Interpolation, control_morphs, rig_metres_per_unit, take_path, target_morphs,
};
use mimic_retarget::FrameLoop;
use mimic_trackers::weights_csv::{WeightsCsv, WeightsLayout};
use mimic_types::{MorphTarget, Rig};

/// Adds the outputs `args` asks for to `frames`, a loop onto `rig` whose GLB targets are the
/// rig's morph `targets` (blend-shape mode, a take) or, when there are none, the basis columns;
/// each OBJ's comment starts with `header`.
pub(super) fn add(
    args: &Args,
    rig: &Rig,
    targets: &[MorphTarget],
    header: &str,
    frames: &mut FrameLoop,
) -> anyhow::Result<()> {
    let rig_path = args.rig.rig_path();
    let every = args.every.max(1);
    match (&args.out, args.format) {
        (None, _) => {}
        (Some(out), OutFormat::Glb | OutFormat::Vrm) => {
            let scale = rig_metres_per_unit(rig)?;
            let morphs = if targets.is_empty() {
                let r = frames
                    .retargeter()
                    .context("free-form GLB without a retargeter")?;
                control_morphs(r.basis(), rig)
            } else {
                target_morphs(targets, scale)
            };
            let keys = GlbKeys {
                interpolation: if args.step_keys {
                    Interpolation::Step
                } else {
                    Interpolation::Linear
                },
                pose: !args.no_pose,
            };
            let glb = GlbSink::create(
                &take_path(out, args.format == OutFormat::Vrm),
                &rig_path,
                rig,
                morphs,
                mimic_render::SKIN_ALBEDO,
                keys,
            )?;
            frames.add_output(Box::new(glb), every);
        }
        (Some(dir), OutFormat::Obj) => {
            frames.add_output(
                Box::new(ObjSink::create(dir, &rig_path, rig, header)?),
                every,
            );
        }
        (Some(dir), OutFormat::Bin) => {
            frames.add_output(Box::new(BinSink::create(dir, &rig.mesh)?), every);
        }
    }
    if let Some(p) = &args.metrics {
        frames.add_output(Box::new(MetricsCsv::create(p, rig)?), 1);
    }
    if let Some(p) = &args.controls {
        frames.add_output(Box::new(ControlsCsv::create(p, rig)?), 1);
    }
    if let Some(p) = &args.blend.weights {
        let names = frames
            .fitter()
            .map(|f| f.names().to_vec())
            .unwrap_or_default();
        let layout = match args.weights_format {
            WeightsFormat::Mimic => WeightsLayout::Mimic,
            WeightsFormat::Livelink => WeightsLayout::LiveLink,
        };
        let csv = WeightsCsv::create(p, layout, &names, &args.namemap_path())?;
        if let Some(line) = csv.lacking_line(p) {
            // With --json, stdout holds only the summary.
            if args.json {
                eprintln!("{line}");
            } else {
                println!("{line}");
            }
        }
        frames.add_output(Box::new(csv), 1);
    }
    Ok(())
}
