//! `mimic replay TAKE.csv`: a Live Link Face CSV take onto a rig's morph targets. The take's
//! tracked rows (`mimic_trackers::take`), at their `Timecode` times, go through the name map
//! onto the rig's `[[morph_targets]]` (`mimic_retarget::WeightMap`); head yaw, pitch and roll
//! become the head rotation. Written as a blendshape-mode GLB (the rig's own morph targets, one
//! key per row), OBJ frames or `frames.bin` of the blend `P0 + sum w dP`, and `--weights` as in
//! blendshape mode.

use super::weights_out::WeightsOut;
use super::{Args, OutFormat};
use crate::cmd::setup::obj_frame_path;
use anyhow::{Context, bail};
use glam::Vec3;
use mimic_assets::{FramesWriter, ObjFrames, load_morph_targets, load_rig};
use mimic_gltf::{Interpolation, Take, target_morphs};
use mimic_retarget::{BlendshapeFitter, WeightMap};
use mimic_trackers::livelink::{HEAD_YAW, head_quat};
use mimic_trackers::namemap::NameMap;
use mimic_trackers::take::{read_take, take_weights};
use mimic_types::HeadPose;
use serde_json::json;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::time::{Duration, Instant};

/// Where the take's frames go.
enum Out {
    None,
    Obj(ObjFrames),
    Bin(FramesWriter<BufWriter<File>>),
    Glb(Box<Take>),
}

/// Replays the take `args.recording`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let path = &args.recording;
    if args.metrics.is_some() || args.controls.is_some() {
        bail!(
            "{}: a Live Link take drives morph targets: --metrics and --controls are for landmark recordings",
            path.display()
        );
    }
    let take = read_take(path)?;
    let rig_path = args.rig.rig_path();
    let rig = load_rig(&rig_path)?;
    let targets = load_morph_targets(&rig_path, &rig)?;
    if targets.is_empty() {
        bail!(
            "rig `{}` has no [[morph_targets]]: a Live Link take drives morph targets",
            rig.name
        );
    }
    let fitter = BlendshapeFitter::new(&rig, &targets, &args.blend.settings())
        .with_context(|| format!("morph targets of rig `{}`", rig.name))?;
    let names = fitter.names().to_vec();
    let namemap_path = args.namemap_path();
    let map = NameMap::load(&namemap_path)?;
    let tw = take_weights(&take, &map);
    let rig_map = WeightMap::new(&names);
    let mut probe = vec![0.0f32; names.len()];
    let lacking: Vec<&str> = tw
        .targets
        .iter()
        .filter(|t| rig_map.apply([(t.as_str(), 1.0)], &mut probe) > 0)
        .map(String::as_str)
        .collect();
    if !lacking.is_empty() && !args.json {
        println!(
            "rig `{}` has no morph target for {} of the take's {} names (ignored): {}",
            rig.name,
            lacking.len(),
            tw.targets.len(),
            lacking.join(", ")
        );
    }
    let mut weights_out = match &args.blend.weights {
        Some(p) => Some(WeightsOut::create(
            p,
            args.weights_format,
            &names,
            &namemap_path,
        )?),
        None => None,
    };
    let scale = mimic_gltf::metres_per_unit(&rig.units).with_context(|| {
        format!(
            "rig `{}`: units `{}` have no length in metres",
            rig.name, rig.units
        )
    })?;
    let glb_path = args.out.as_ref().map(|out| {
        if out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("glb"))
        {
            out.clone()
        } else {
            out.join("take.glb")
        }
    });
    let mut out = match (&args.out, args.format) {
        (None, _) => Out::None,
        (Some(_), OutFormat::Glb) => {
            if let Some(dir) = glb_path
                .as_ref()
                .and_then(|p| p.parent())
                .filter(|d| !d.as_os_str().is_empty())
            {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("creating {}", dir.display()))?;
            }
            let interpolation = if args.step_keys {
                Interpolation::Step
            } else {
                Interpolation::Linear
            };
            Out::Glb(Box::new(Take::new(
                names.len(),
                interpolation,
                !args.no_pose,
            )))
        }
        (Some(dir), format) => {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
            let tris = &rig.mesh.triangles;
            if format == OutFormat::Obj {
                Out::Obj(ObjFrames::new(dir, &rig_path, &rig.name, tris.len())?)
            } else {
                let p = dir.join("frames.bin");
                let file = File::create(&p).with_context(|| p.display().to_string())?;
                let n = rig.mesh.vertex_count();
                Out::Bin(FramesWriter::new(BufWriter::new(file), n, tris, true)?)
            }
        }
    };
    let mut w = vec![0.0f32; names.len()];
    let mut positions = rig.mesh.positions.clone();
    let mut normals = vec![Vec3::ZERO; positions.len()];
    let mut pairs: Vec<(&str, f32)> = Vec::with_capacity(tw.targets.len());
    let rows = take.rows.iter().filter(|r| r.tracked);
    let started = Instant::now();
    let mut frames = 0usize;
    for (row, (_, t_us, mapped)) in rows.zip(&tw.frames) {
        if args.max_frames.is_some_and(|m| frames >= m) {
            break;
        }
        if args.realtime {
            let due = *t_us as f64 / 1e6 / args.speed.max(1e-3);
            let now = started.elapsed().as_secs_f64();
            if due > now {
                std::thread::sleep(Duration::from_secs_f64(due - now));
            }
        }
        pairs.clear();
        pairs.extend(
            tw.targets
                .iter()
                .map(String::as_str)
                .zip(mapped.iter().copied()),
        );
        rig_map.apply(pairs.iter().copied(), &mut w);
        let mut head = [0.0f32; 3];
        head.copy_from_slice(&row.curves[HEAD_YAW..HEAD_YAW + 3]);
        let rotation = head_quat(head);
        if let Some(csv) = weights_out.as_mut() {
            csv.row(frames, *t_us, 1, None, &w, rotation)?;
        }
        if frames.is_multiple_of(args.every.max(1)) {
            match &mut out {
                Out::None => {}
                Out::Glb(keys) => {
                    keys.push(*t_us, &w, (rotation, Vec3::ZERO));
                }
                Out::Obj(objs) => {
                    fitter.evaluate(&w, &mut positions, &mut normals);
                    let dir = args.out.as_deref().unwrap_or(std::path::Path::new("."));
                    let header = format!(
                        "mimic replay of a Live Link take onto rig {}: frame {frames}, t = {t_us} us",
                        rig.name
                    );
                    let p = obj_frame_path(dir, frames);
                    objs.write(&p, &header, &positions, &normals, &rig.mesh)?;
                }
                Out::Bin(bin) => {
                    fitter.evaluate(&w, &mut positions, &mut normals);
                    let pose = HeadPose {
                        rotation,
                        ..HeadPose::default()
                    };
                    bin.write_frame(*t_us, 1, &pose, &positions, &normals)?;
                }
            }
        }
        frames += 1;
    }
    let paced_s = started.elapsed().as_secs_f64();
    if let Some(csv) = weights_out {
        csv.finish()?;
    }
    let mut wrote = json!(null);
    match out {
        Out::None => {}
        Out::Obj(objs) => {
            wrote = json!({"frames": objs.written(), "bytes": objs.bytes()});
        }
        Out::Bin(bin) => {
            let file = bin.finish()?;
            drop(file);
            wrote = json!({"frames": frames.div_ceil(args.every.max(1))});
        }
        Out::Glb(keys) => {
            let p = glb_path.context("no --out")?;
            let t = Instant::now();
            let morphs = target_morphs(&targets, scale);
            let file = File::create(&p).with_context(|| p.display().to_string())?;
            let mut bw = BufWriter::new(file);
            let written = mimic_gltf::write_rig_glb(
                &rig_path,
                &rig,
                &morphs,
                Some(&keys),
                mimic_render::SKIN_ALBEDO,
                &mut bw,
            )
            .with_context(|| p.display().to_string())?;
            bw.flush().with_context(|| p.display().to_string())?;
            wrote = json!({"path": p.display().to_string(), "summary": written,
                "skipped_frames": keys.skipped(), "write_s": t.elapsed().as_secs_f64()});
        }
    }
    let summary = json!({
        "take": path.display().to_string(),
        "rig": rig.name,
        "rows": take.rows.len(),
        "untracked_rows": tw.untracked,
        "frames": frames,
        "duration_s": take.duration_s(),
        "timecode_rate": take.timecode_rate,
        "targets": names,
        "names_lacking": lacking,
        "wall_s": paced_s,
        "out": wrote,
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!(
            "take {}: {} rows ({} with no face), {:.3} s at {} fps timecode; {frames} frames onto rig {} ({} morph targets) in {paced_s:.3} s",
            path.display(),
            take.rows.len(),
            tw.untracked,
            take.duration_s(),
            take.timecode_rate,
            rig.name,
            names.len()
        );
        if !wrote.is_null() {
            println!("  wrote {wrote}");
        }
    }
    Ok(())
}
