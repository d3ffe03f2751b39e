//! Issue 44's last point (with issue 45's jaw and eyes): a performance replayed onto the
//! multi-mesh avatar fixture moves its lower teeth with the jaw and turns its eyes, in mimic's own
//! frames and in the avatar written back (the parts' meshes gain their targets and keyed weights).

use crate::avatar::{run, s};
use crate::repo;
use mimic_gltf::avatar::{ChannelPath, load_avatar};

fn vertices(ranges: &[[u32; 2]]) -> Vec<usize> {
    ranges
        .iter()
        .flat_map(|[a, b]| *a as usize..=*b as usize)
        .collect()
}

#[test]
fn a_performance_on_the_avatar_fixture_moves_its_lower_teeth_with_the_jaw_and_turns_its_eyes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rig_path = d.join("fixture.toml");
    let fixture = repo().join("tests/data/avatar/ict_multimesh.glb");
    let (out, _) = run(&["rig", "new", s(&fixture), "-o", s(&rig_path)]);
    assert!(out.contains("rigid parts: jaw found"), "{out}");
    let rig = mimic_assets::load_rig(&rig_path).unwrap();
    let jaw = rig
        .parts
        .jaw
        .as_ref()
        .expect("the fixture's lower teeth ride on the jaw");
    let eyes = rig.parts.eyes.as_ref().expect("the fixture's eyeballs");
    let lower = vertices(&jaw.vertices);
    let balls: Vec<usize> = eyes.iter().flat_map(|e| vertices(&e.vertices)).collect();
    let chin = rig
        .controls
        .iter()
        .find(|c| c.fdp.to_string() == "2.1")
        .unwrap()
        .vertex as usize;
    // MediaPipe's take: its irises give the gaze.
    let rec = "recordings/megamind_mediapipe.jsonl";
    let frames = d.join("frames");
    run(&[
        "replay",
        rec,
        "--rig",
        s(&rig_path),
        "--format",
        "bin",
        "--out",
        s(&frames),
    ]);
    let file = std::fs::File::open(frames.join("frames.bin")).unwrap();
    let mut reader = mimic_assets::FramesReader::new(std::io::BufReader::new(file)).unwrap();
    let rest = &rig.mesh.positions;
    let edges: Vec<(usize, usize)> = rig
        .mesh
        .triangles
        .iter()
        .filter(|t| t.iter().all(|v| balls.contains(&(*v as usize))))
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2])])
        .map(|(a, b)| (a as usize, b as usize))
        .collect();
    let (mut widest, mut eye_move, mut stretch) = ((0.0f32, 0.0f32), 0.0f32, 0.0f32);
    while let Some(f) = reader.next_frame().unwrap() {
        let p = &f.positions;
        let drop = rest[chin].y - p[chin].y;
        if drop > widest.0 {
            let teeth = lower.iter().map(|&v| rest[v].y - p[v].y).sum::<f32>() / lower.len() as f32;
            widest = (drop, teeth);
        }
        for &v in &balls {
            eye_move = eye_move.max(p[v].distance(rest[v]));
        }
        for &(a, b) in &edges {
            let r = rest[a].distance(rest[b]);
            stretch = stretch.max((p[a].distance(p[b]) - r).abs() / r);
        }
    }
    let iod = 0.063; // the fixture is ICT in metres
    println!(
        "fixture: chin drops {:.2} mm, lower teeth {:.2} mm; eyeballs move up to {:.2} mm, edges within {stretch:.1e}",
        widest.0 * 1e3,
        widest.1 * 1e3,
        eye_move * 1e3
    );
    assert!(
        widest.0 > 0.05 * iod,
        "the take opens the mouth: {widest:?}"
    );
    assert!(
        widest.1 >= 0.5 * widest.0,
        "lower teeth follow the jaw: {widest:?}"
    );
    // A 2 degree turn moves the front of a 1.5 cm eyeball 0.5 mm; rigid within 1 %.
    assert!(eye_move > 0.0005, "eyeballs turn: {eye_move} m");
    assert!(stretch < 0.01, "{stretch}");

    // The avatar written back: the eyes' and teeth's meshes carry the parts' targets, and the take
    // keys their weights.
    let glb = d.join("take.glb");
    run(&[
        "replay",
        rec,
        "--rig",
        s(&rig_path),
        "--format",
        "glb",
        "--out",
        s(&glb),
    ]);
    let a = load_avatar(&glb).unwrap();
    let take = a.animations.last().unwrap();
    for (mesh_name, prefix) in [("Eyes", "eye_"), ("Teeth", "jaw.")] {
        let mesh = a.mesh_named(mesh_name).unwrap();
        let names = &a.meshes[mesh].target_names;
        let first = names.iter().position(|n| n.starts_with(prefix)).unwrap();
        let channel = take
            .channels
            .iter()
            .find(|c| c.path == ChannelPath::Weights && a.nodes[c.node].mesh == Some(mesh))
            .unwrap_or_else(|| panic!("no weights keyed on {mesh_name}"));
        let width = names.len();
        let moved = channel
            .values
            .chunks_exact(width)
            .any(|key| key[first..].iter().any(|w| w.abs() > 1e-3));
        assert!(moved, "{mesh_name}: its part's weights never move");
    }
}
