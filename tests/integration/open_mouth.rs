//! Issue 41's open-mouth Done-when, as a user meets it: a closed-lip scan as it comes (the
//! fixture of crates/mimic_rig/tests/lipcut.rs: an ICT identity, skin only, the lips zipped into
//! one surface and re-meshed, mm, z up facing -y) made into a rig by `mimic rig new`, driven by a
//! recording of the same face opening its jaw (the identity's 68 iBUG landmarks moved by ICT's
//! own `jawOpen`, the tracker's truth), rendered by `mimic render`. The pixels of the mouth are
//! looked at: the open frame shows the added interior (dark socket, red gums and tongue, pale
//! teeth) where the lips part, and neither background (a hole through the head) nor only skin
//! (lips folded shut, as before the cut).

#[path = "../../crates/mimic_rig/tests/fixtures/closed_lips.rs"]
mod closed_lips;

use crate::{mimic, repo, text};
use mimic_assets::load_shape_pack;
use mimic_render::Image;
use mimic_rig::TemplateHead;
use std::path::Path;

/// The rendered frames: rest (inside the calibration) and the jaw held wide open.
const REST: usize = 10;
const OPEN: usize = 58;

/// A recording (metres, ICT's frame) of identity `identity`'s iBUG landmarks: at rest for 30
/// frames (the calibration), then `jawOpen` ramped in over 20 frames (a tracker's pace: no jump
/// for the gate to hold), held to frame 60.
fn jaw_recording(identity: usize) -> String {
    let configs = repo().join("configs");
    let template = TemplateHead::ict(&configs).unwrap();
    let head = closed_lips::identity_head(&configs, &template, identity);
    let pack = load_shape_pack(&configs.join("meshes/ict-facekit/expressions.shapes")).unwrap();
    let jaw = &pack.get("jawOpen").unwrap().deltas;
    let mut out = String::from(
        r#"{"format":"mimic-recording","version":1,"layout":"ibug68","units":"m","source":"ICT identity, jawOpen ramp","rate_hz":30.0,"point_count":68}"#,
    );
    out.push('\n');
    for k in 0..=60usize {
        let w = ((k as f32 - 30.0) / 20.0).clamp(0.0, 1.0);
        let points: Vec<String> = (0..68)
            .map(|i| {
                let v = template.landmarks.get(i).unwrap() as usize;
                let p = (head[v] + jaw[v] * w) / 100.0;
                format!("[{},{},{}]", p.x, p.y, p.z)
            })
            .collect();
        let t_us = k as i64 * 1_000_000 / 30;
        out.push_str(&format!(
            r#"{{"t_us":{t_us},"points":[{}]}}"#,
            points.join(",")
        ));
        out.push('\n');
    }
    out
}

/// What a pixel shows, by colour: the renderer's clear colour, and the materials' albedos under
/// white light (`mimic_rig::mouth_interior::MATERIALS`, `mimic_render::SKIN_ALBEDO`).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Seen {
    /// The clear colour (the image's corner): nothing drawn there, a hole through the head.
    Background,
    /// The socket, gums and tongue: red well over green and blue (skin's red is 1.2 x its green).
    Flesh,
    /// Teeth: pale, red within 8 % of green (albedo 1.04 x; skin 1.21 x).
    Teeth,
    /// Anything else: skin.
    Skin,
}

fn seen(im: &Image, i: usize, clear: [u8; 3]) -> Seen {
    let [r, g, b] = [0, 1, 2].map(|c| im.rgba[4 * i + c]);
    let (rf, gf, bf) = (f32::from(r), f32::from(g), f32::from(b));
    if [r, g, b].iter().zip(clear).all(|(v, c)| v.abs_diff(c) <= 3) {
        Seen::Background
    } else if rf >= 1.5 * gf && rf >= 1.5 * bf {
        Seen::Flesh
    } else if gf >= 100.0 && rf <= 1.08 * gf {
        Seen::Teeth
    } else {
        Seen::Skin
    }
}

/// What the mouth shows in one render: over the pixels that change between REST and OPEN,
/// `[background, flesh, teeth, skin]` at rest and open; and the holes: background pixels of
/// the open frame inside the box around its flesh (the mouth's opening).
struct MouthPixels {
    rest: [usize; 4],
    open: [usize; 4],
    holes: usize,
}

/// Renders frames REST and OPEN of `rec` on `rig` (face framed) and counts ([`MouthPixels`]).
fn mouth_pixels(rec: &Path, rig: &Path, out: &Path) -> MouthPixels {
    let o = mimic(&[
        "render",
        rec.to_str().unwrap(),
        "--rig",
        rig.to_str().unwrap(),
        "--frames",
        &format!("{REST},{OPEN}"),
        "--frame",
        "face",
        "--size",
        "384x384",
        "-o",
        out.to_str().unwrap(),
    ]);
    let (_, stderr) = text(&o);
    assert!(o.status.success(), "mimic render failed:\n{stderr}");
    let load = |k: usize| Image::load_png(&out.join(format!("frame_{k:06}.png"))).unwrap();
    let (rest, open) = (load(REST), load(OPEN));
    let clear = [0, 1, 2].map(|c| rest.rgba[c]);
    let w = rest.width as usize;
    let (mut counts, mut lo, mut hi) = ([[0; 4]; 2], [usize::MAX; 2], [0; 2]);
    for i in 0..(rest.width * rest.height) as usize {
        if (0..3).all(|c| rest.rgba[4 * i + c].abs_diff(open.rgba[4 * i + c]) <= 40) {
            continue;
        }
        for (k, im) in [&rest, &open].into_iter().enumerate() {
            counts[k][seen(im, i, clear) as usize] += 1;
        }
        if seen(&open, i, clear) == Seen::Flesh {
            for (a, v) in [i % w, i / w].into_iter().enumerate() {
                lo[a] = lo[a].min(v);
                hi[a] = hi[a].max(v);
            }
        }
    }
    let holes = (lo[1]..=hi[1])
        .flat_map(|y| (lo[0]..=hi[0]).map(move |x| y * w + x))
        .filter(|i| seen(&open, *i, clear) == Seen::Background)
        .count();
    MouthPixels {
        rest: counts[0],
        open: counts[1],
        holes,
    }
}

#[test]
fn a_closed_lip_scan_made_into_a_rig_opens_its_mouth_on_teeth_and_a_dark_inside() {
    if std::env::var_os("MIMIC_SKIP_GPU_TESTS").is_some() {
        eprintln!("MIMIC_SKIP_GPU_TESTS is set: skipping a GPU test");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let configs = repo().join("configs");
    let scan = closed_lips::closed_lip_scan(&configs, 7, 0.3);
    let obj = dir.path().join("scan.obj");
    let mut bytes = Vec::new();
    mimic_assets::write_obj(
        &mut bytes,
        "scan",
        &scan.mesh.positions,
        None,
        &scan.mesh.triangles,
    )
    .unwrap();
    std::fs::write(&obj, bytes).unwrap();
    let rig = dir.path().join("scan.toml");
    let o = mimic(&[
        "rig",
        "new",
        obj.to_str().unwrap(),
        "-o",
        rig.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "rig new failed:\n{stderr}");
    println!("{stdout}{stderr}");
    let rec = dir.path().join("jaw.jsonl");
    std::fs::write(&rec, jaw_recording(7)).unwrap();
    let scan = mouth_pixels(&rec, &rig, &dir.path().join("scan"));
    // The reference: ICT-FaceKit's own head (open lips, its own mouth) on the same motion.
    let ict = mouth_pixels(
        &rec,
        &configs.join("rigs/ict-face.toml"),
        &dir.path().join("ict"),
    );
    for (name, m) in [("the cut scan", &scan), ("ict-face", &ict)] {
        println!(
            "{name}: where the frames differ, [background, flesh, teeth, skin] at rest {:?}, open {:?}; background inside the open mouth {}",
            m.rest, m.open, m.holes
        );
    }
    let (flesh, teeth) = (Seen::Flesh as usize, Seen::Teeth as usize);
    // At rest the lips are shut: no inside shows.
    assert_eq!(
        scan.rest[flesh], 0,
        "the closed mouth shows its inside at rest"
    );
    // Open: the dark socket, gums and tongue, and teeth show where the lips part, at least half
    // as much of each as the template's own head shows on the same jaw (a fold or a cut with no
    // inside shows none).
    assert!(
        2 * scan.open[flesh] >= ict.open[flesh] && ict.open[flesh] > 0,
        "flesh: {} vs ict-face's {}",
        scan.open[flesh],
        ict.open[flesh]
    );
    let more_teeth = |m: &MouthPixels| m.open[teeth].saturating_sub(m.rest[teeth]);
    assert!(
        2 * more_teeth(&scan) >= more_teeth(&ict) && more_teeth(&ict) > 0,
        "teeth: {} vs ict-face's {}",
        more_teeth(&scan),
        more_teeth(&ict)
    );
    // No hole: nothing of the background shows through the opening.
    assert_eq!(scan.holes, 0, "background shows through the open mouth");
}
