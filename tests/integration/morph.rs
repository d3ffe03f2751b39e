//! Morph targets on the shipped ICT rig: weights recovered from control displacements, the morph
//! data file round trip, and `mimic replay --mode blendshapes` on a real recording.

use crate::{mimic, repo, text};
use glam::Vec3;
use mimic_assets::{load_morph_targets, load_rig};
use mimic_retarget::{BlendshapeFitter, BlendshapeSettings};
use mimic_types::{MorphTarget, Rig};

fn ict() -> (Rig, Vec<MorphTarget>) {
    let path = repo().join("configs/rigs/ict-face.toml");
    let rig = load_rig(&path).unwrap();
    let targets = load_morph_targets(&path, &rig).unwrap();
    (rig, targets)
}

/// The ICT mesh with `weights` of the targets applied, as a modelling tool would (truth).
fn blend(rig: &Rig, targets: &[MorphTarget], weights: &[(&str, f32)]) -> Vec<Vec3> {
    let mut p = rig.mesh.positions.clone();
    for (name, w) in weights {
        let t = targets.iter().find(|t| t.name == *name).unwrap();
        for (p, d) in p.iter_mut().zip(&t.position_deltas) {
            *p += *w * *d;
        }
    }
    p
}

#[test]
fn known_ict_combination_is_recovered_from_the_control_displacements() {
    let (rig, targets) = ict();
    assert_eq!(targets.len(), 8);
    let truth = [("jawOpen", 0.6f32), ("mouthSmileLeft", 0.3)];
    let shape = blend(&rig, &targets, &truth);
    let d: Vec<Vec3> = rig
        .controls
        .iter()
        .map(|c| shape[c.vertex as usize] - rig.mesh.positions[c.vertex as usize])
        .collect();
    let want = |name: &str| {
        truth
            .iter()
            .find(|(n, _)| *n == name)
            .map_or(0.0, |(_, w)| *w)
    };
    for (ridge, tol) in [
        // No ridge: exact data, 114 equations for 8 unknowns of full rank; the error is f32
        // rounding of the deltas amplified by the conditioning (measured 2e-7), below 1e-4.
        (0.0, 1e-4),
        // The ridge alone, 0.01 |D_k|^2 per target: a lone weight shrinks by 1 %; correlated targets
        // (jawOpen and mouthSmileLeft share the lip controls) by a few % (measured 0.594 and
        // 0.292); 0.02 bounds that.
        (mimic_retarget::BlendshapeFit::RIDGE_ONLY.ridge, 0.02),
    ] {
        let mut fitter = BlendshapeFitter::new(
            &rig,
            &targets,
            &BlendshapeSettings {
                ridge,
                l1: 0.0,
                temporal: 0.0,
                symmetry: 0.0,
                smoothing: None,
            },
        )
        .unwrap();
        let w = fitter.fit(&d, 0).to_vec();
        eprintln!(
            "ridge {ridge}: {:?}",
            fitter.names().iter().zip(&w).collect::<Vec<_>>()
        );
        for (name, got) in fitter.names().iter().zip(&w) {
            assert!(
                (got - want(name)).abs() <= tol,
                "ridge {ridge}: {name} = {got}, want {}",
                want(name)
            );
        }
        // The blended mesh then matches the truth up to the weight error times the deltas.
        let mut p = vec![Vec3::ZERO; rig.mesh.vertex_count()];
        fitter.evaluate(&w, &mut p, &mut []);
        let max_err = p
            .iter()
            .zip(&shape)
            .map(|(a, b)| a.distance(*b))
            .fold(0f32, f32::max);
        let max_delta = targets
            .iter()
            .flat_map(|t| t.position_deltas.iter())
            .map(|v| v.length())
            .fold(0f32, f32::max);
        eprintln!("ridge {ridge}: max vertex error {max_err:.5} cm");
        // |sum (w_k - w*_k) dP_k| <= 8 targets * tol * max |dP|.
        assert!(max_err <= 8.0 * tol * max_delta, "{max_err}");
    }
}

#[test]
fn morph_data_file_round_trips_through_the_cli() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("ict.morph.txt");
    let f = file.to_str().unwrap();
    let out = mimic(&["morph", "export", "--rig", "ict-face", "-o", f]);
    assert!(out.status.success(), "{}", text(&out).1);
    let out = mimic(&["morph", "import", f, "--rig", "ict-face", "--json"]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(report["round_trip_ok"], true);
    assert_eq!(report["targets_in_file"], 8);
    assert_eq!(report["vertices"], 26719);
    for t in report["targets"].as_array().unwrap() {
        // 6 decimals: half a unit of the last digit plus f32 rounding of values below 8.
        assert!(t["max_position_difference"].as_f64().unwrap() <= 0.5e-6 + 8.0 * 1.2e-7);
    }
    // A damaged row is an error naming the file and line.
    let body = std::fs::read_to_string(&file).unwrap();
    let mut lines: Vec<&str> = body.lines().collect();
    lines[9] = "0.1 0.2";
    std::fs::write(&file, lines.join("\n")).unwrap();
    let out = mimic(&["morph", "import", f, "--rig", "ict-face"]);
    let (_, stderr) = text(&out);
    assert!(!out.status.success());
    assert!(
        stderr.contains("ict.morph.txt:10: expected 3 numbers (x y z), found 2"),
        "{stderr}"
    );
}

/// Median of a weights-CSV column over tracked frames with the given label.
fn median_weight(csv: &str, column: &str, label: &str) -> f64 {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let at = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (col, st, lb) = (at(column), at("status"), at("label"));
    let mut v: Vec<f64> = lines
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|f| f[st] == "1" && f[lb] == label)
        .map(|f| f[col].parse().unwrap())
        .collect();
    assert!(!v.is_empty());
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn blendshape_replay_of_a_real_question_opens_the_jaw_in_the_expressive_segments() {
    // In the GFE yes/no question the mouth opens and the chin drops while the expression is
    // labelled (control 2.1 moves about -1.2 cm, against -0.2 cm in the neutral frames); the fitted
    // jawOpen weight must follow: its median over expressive frames clearly above the neutral one.
    let dir = tempfile::tempdir().unwrap();
    let weights = dir.path().join("w.csv");
    let summary = crate::replay::replay_json(&[
        "recordings/a_yn_question.jsonl",
        "--rig",
        "ict-face",
        "--mode",
        "blendshapes",
        "--weights",
        weights.to_str().unwrap(),
    ]);
    assert_eq!(summary["frames_with_non_finite_vertices"], 0);
    let csv = std::fs::read_to_string(&weights).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(
        header.starts_with("frame,t_us,status,label,jawOpen,"),
        "{header}"
    );
    let mut rows = 0;
    for line in csv.lines().skip(1) {
        rows += 1;
        for w in line.split(',').skip(4) {
            let w: f64 = w.parse().unwrap();
            assert!((0.0..=1.0).contains(&w), "{line}");
        }
    }
    assert_eq!(rows as u64, summary["frames_in"].as_u64().unwrap());
    let expressive = median_weight(&csv, "jawOpen", "1");
    let neutral = median_weight(&csv, "jawOpen", "0");
    eprintln!("a_yn_question jawOpen median: expressive {expressive:.3}, neutral {neutral:.3}");
    assert!(
        expressive > neutral + 0.1,
        "jawOpen {expressive:.3} vs {neutral:.3}"
    );
}

#[test]
fn blendshape_replay_meshes_are_the_neutral_plus_the_weighted_targets() {
    // The OBJ frames of --mode blendshapes must be P0 + sum w_k dP_k with the weights of the CSV.
    let dir = tempfile::tempdir().unwrap();
    let weights = dir.path().join("w.csv");
    let out = dir.path().join("obj");
    crate::replay::replay_json(&[
        "recordings/a_yn_question.jsonl",
        "--rig",
        "ict-face",
        "--mode",
        "blendshapes",
        "--weights",
        weights.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--every",
        "150",
        "--max-frames",
        "451",
    ]);
    let (rig, targets) = ict();
    let csv = std::fs::read_to_string(&weights).unwrap();
    let max_delta = targets
        .iter()
        .flat_map(|t| t.position_deltas.iter())
        .map(|v| v.length())
        .fold(0f32, f32::max);
    let mut checked = 0;
    for frame in [150usize, 300, 450] {
        let row: Vec<&str> = csv.lines().nth(frame + 1).unwrap().split(',').collect();
        assert_eq!(row[0], frame.to_string());
        let w: Vec<(&str, f32)> = targets
            .iter()
            .zip(&row[4..])
            .map(|(t, x)| (t.name.as_str(), x.parse().unwrap()))
            .collect();
        let want = blend(&rig, &targets, &w);
        let mesh = mimic_assets::load_obj(&out.join(format!("frame_{frame:06}.obj"))).unwrap();
        let err = mesh
            .positions
            .iter()
            .zip(&want)
            .map(|(a, b)| a.distance(*b))
            .fold(0f32, f32::max);
        // The CSV rounds each weight to 4 decimals: 8 targets x 0.5e-4 x max |dP|, plus f32 sums.
        let tol = 8.0 * 0.5e-4 * max_delta + 1e-4;
        assert!(err <= tol, "frame {frame}: {err} > {tol}");
        if w.iter().any(|(_, x)| *x > 0.05) {
            checked += 1;
        }
    }
    assert!(checked >= 1, "no frame with a visible expression checked");
}

#[test]
fn morph_apply_turns_named_arkit_weights_into_meshes() {
    // A capture app's CSV (Live Link Face style: capitalised ARKit names, extra columns). ARKit's
    // single BrowInnerUp drives both ICT halves; CheekPuff names no target and is ignored.
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("arkit.csv");
    std::fs::write(
        &csv,
        "Timecode,BlendShapeCount,JawOpen,MouthSmileLeft,BrowInnerUp,CheekPuff\n\
         00:00:00:00.000,61,0,0,0,0\n\
         00:00:00:01.000,61,0.6,0.3,0.2,0.9\n",
    )
    .unwrap();
    let out = dir.path().join("obj");
    let o = mimic(&[
        "morph",
        "apply",
        csv.to_str().unwrap(),
        "--rig",
        "ict-face",
        "--out",
        out.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stdout.contains("2 frames, 2 written")
            && stdout.contains("ignored: Timecode BlendShapeCount CheekPuff"),
        "{stdout}"
    );
    let (rig, targets) = ict();
    let want = blend(
        &rig,
        &targets,
        &[
            ("jawOpen", 0.6),
            ("mouthSmileLeft", 0.3),
            ("browInnerUp_L", 0.2),
            ("browInnerUp_R", 0.2),
        ],
    );
    let got = mimic_assets::load_obj(&out.join("frame_000001.obj")).unwrap();
    // Same sums in f32 in another order; OBJ values print exactly: |error| < 1e-5 cm.
    let err = got
        .positions
        .iter()
        .zip(&want)
        .map(|(a, b)| a.distance(*b))
        .fold(0f32, f32::max);
    assert!(err < 1e-5, "{err}");
    let rest = mimic_assets::load_obj(&out.join("frame_000000.obj")).unwrap();
    assert_eq!(rest.positions, rig.mesh.positions);
    // A bad number names file, line and column.
    std::fs::write(&csv, "JawOpen\n0.5\nx\n").unwrap();
    let o = mimic(&[
        "morph",
        "apply",
        csv.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let (_, stderr) = text(&o);
    assert!(
        stderr.contains("arkit.csv:3: column `JawOpen`: `x` is not a number"),
        "{stderr}"
    );
}
