//! `mimic import … --fit candide3` and the fitted `kinect121` recordings in recordings/.

use crate::replay::replay_json;
use crate::{mimic, repo, text};
use serde_json::Value;

const GFE: [&str; 3] = ["a_affirmative", "a_doubt_question", "a_yn_question"];

/// Header and frames of a recording, as JSON.
fn read(path: &std::path::Path) -> (Value, Vec<Value>) {
    let t = std::fs::read_to_string(path).unwrap();
    let mut lines = t.lines().map(|l| serde_json::from_str::<Value>(l).unwrap());
    let header = lines.next().unwrap();
    (header, lines.collect())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn gfe_fit_writes_kinect121_with_a_bounded_reprojection_residual() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fit.jsonl");
    let data = repo().join("tests/data/kinect-gfe-libras");
    assert!(
        data.is_dir(),
        "{} missing: the repository ships it",
        data.display()
    );
    let o = mimic(&[
        "import",
        "gfe",
        data.join("a_affirmative_datapoints.txt").to_str().unwrap(),
        "--targets",
        data.join("a_affirmative_targets.txt").to_str().unwrap(),
        "--fit",
        "candide3",
        "-o",
        out.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stdout.contains("1062 frames fitted with CANDIDE-3"),
        "{stdout}"
    );
    let (header, frames) = read(&out);
    assert_eq!(header["layout"], "kinect121");
    assert_eq!(header["point_count"], 121);
    assert_eq!(header["fit"]["au_names"].as_array().unwrap().len(), 11);
    assert_eq!(frames.len(), 1062);
    // The same command wrote the shipped recording: same fit, frame by frame (to the written digits).
    let (_, shipped) = read(&repo().join("recordings/a_affirmative.kinect121.jsonl"));
    for (a, b) in frames.iter().zip(&shipped) {
        assert_eq!(a["fit"]["au"], b["fit"]["au"], "t_us {}", a["t_us"]);
    }
    for f in &frames {
        let points = f["points"].as_array().unwrap();
        assert_eq!(points.len(), 121);
        // 0-112: fitted CANDIDE-3 vertices, all present; 113-120: never modelled, always invalid.
        assert!(points[..113].iter().all(|p| p.is_array()));
        assert!(points[113..].iter().all(|p| p.is_null()));
        let invalid: Vec<u64> = f["invalid"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect();
        assert_eq!(invalid, (113..121).collect::<Vec<u64>>());
    }
}

#[test]
fn shipped_fits_have_a_small_median_residual_and_no_lost_frames() {
    for n in GFE {
        let (header, frames) = read(&repo().join(format!("recordings/{n}.kinect121.jsonl")));
        assert_eq!(header["layout"], "kinect121", "{n}");
        let tracked: Vec<&Value> = frames.iter().filter(|f| f["tracked"] == true).collect();
        // Every GFE row has all 100 points tracked in the image: no frame may be lost.
        assert_eq!(tracked.len(), frames.len(), "{n}");
        let res: Vec<f64> = tracked
            .iter()
            .map(|f| f["fit"]["residual_px"].as_f64().unwrap())
            .collect();
        let m = median(res);
        // Bound: the tracker's own jitter (~0.5-1 px on a ~45 px wide face) combined with where the
        // correspondences sit between CANDIDE-3 vertices (~0.03 model units ~ 1.3 px at ~44 px per
        // unit): sqrt(1^2 + 1.3^2) ~ 1.6 px; 2.5 px leaves room for the performer's face not being
        // CANDIDE-3's. Measured 1.39-1.55 px (1.44-1.65 symmetric).
        assert!(m < 2.5, "{n}: median residual {m} px");
    }
}

#[test]
fn jaw_and_lip_aus_rise_in_expressive_segments() {
    // Jaw and lip AUVs in file order: 0 upper lip raiser, 1 jaw drop, 2 lip stretcher, 4 lip corner depressor.
    let mouth = [0usize, 1, 2, 4];
    for n in GFE {
        let (_, frames) = read(&repo().join(format!("recordings/{n}.kinect121.jsonl")));
        let rows: Vec<(i64, Vec<f64>)> = frames
            .iter()
            .filter(|f| f["tracked"] == true)
            .map(|f| {
                let au = f["fit"]["au"].as_array().unwrap();
                (
                    f["label"].as_i64().unwrap(),
                    mouth.iter().map(|&k| au[k].as_f64().unwrap()).collect(),
                )
            })
            .collect();
        // Activity: summed distance of the mouth AUs from their median over neutral (label 0) frames.
        let baseline: Vec<f64> = (0..mouth.len())
            .map(|k| median(rows.iter().filter(|r| r.0 == 0).map(|r| r.1[k]).collect()))
            .collect();
        let activity = |label: i64| {
            let v: Vec<f64> = rows
                .iter()
                .filter(|r| r.0 == label)
                .map(|r| r.1.iter().zip(&baseline).map(|(a, b)| (a - b).abs()).sum())
                .collect();
            v.iter().sum::<f64>() / v.len() as f64
        };
        let ratio = activity(1) / activity(0);
        eprintln!("{n}: mouth AU activity expressive / neutral = {ratio:.2}");
        // AUs unrelated to the targets would give a ratio near 1 (both means estimate the same spread);
        // 1.3 asks for a clear rise. Measured 1.7-2.9.
        assert!(ratio > 1.3, "{n}: ratio {ratio}");
    }
}

#[test]
fn fitted_recordings_replay_with_the_kinect121_layout() {
    for n in GFE {
        let rec = format!("recordings/{n}.kinect121.jsonl");
        let v = replay_json(&[&rec]);
        assert_eq!(v["layout"], "kinect121");
        assert_eq!(v["rejected"], 0, "{rec}: {v}");
        assert_eq!(v["frames_with_non_finite_vertices"], 0, "{rec}: {v}");
        assert!(v["tracked"].as_u64().unwrap() > 1000, "{rec}: {v}");
        // CANDIDE-3 is fitted with x = the subject's left, as kinect121 is: no mirroring.
        assert_eq!(v["source_to_target"]["mirrored"], false, "{rec}: {v}");
    }
}

#[test]
fn openface_capture_fits_through_the_ibug68_correspondences() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("of.csv");
    let src = repo().join("tests/data/openface-68pt-3d-sequence/OpenFace_Test.csv");
    assert!(
        src.is_file(),
        "{} missing: the repository ships it",
        src.display()
    );
    std::fs::copy(&src, &csv).unwrap();
    let out = dir.path().join("of.jsonl");
    let o = mimic(&[
        "import",
        "openface",
        csv.to_str().unwrap(),
        "--fit",
        "candide3",
        "-o",
        out.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    assert!(stdout.contains("100 frames fitted"), "{stdout}");
    let (header, _) = read(&out);
    assert_eq!(header["fit"]["from_layout"], "ibug68");
}

/// A GFE capture of a still face (one real neutral row of user A repeated at 15 Hz) whose
/// subject's-left mouth corner alone (GFE points 54, outer, and 64, inner) moves `(6, -3) px`
/// (outwards and up) over frames 40-69 and then holds until frame 99; depths kept. Returns the
/// datapoints file.
fn one_sided_smile_capture(dir: &std::path::Path) -> std::path::PathBuf {
    let src = std::fs::read_to_string(
        repo().join("tests/data/kinect-gfe-libras/a_affirmative_datapoints.txt"),
    )
    .unwrap();
    let mut lines = src.lines();
    let mut out = String::new();
    out.push_str(lines.next().unwrap());
    out.push('\n');
    let row: Vec<f64> = lines
        .nth(10)
        .unwrap()
        .split_whitespace()
        .skip(1)
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(row.len(), 300);
    for k in 0..100usize {
        let smile = ((k as f64 - 40.0) / 30.0).clamp(0.0, 1.0);
        // Seconds and whole milliseconds, as the GFE files write them.
        let ms = 1000 + k * 66;
        out.push_str(&format!("{}.{}", 1_390_385_000 + ms / 1000, ms % 1000));
        for (p, xyz) in row.chunks(3).enumerate() {
            let (mut x, mut y) = (xyz[0], xyz[1]);
            if p == 54 || p == 64 {
                // Subject's left is image right (+x); up is -y in the image.
                x += 6.0 * smile;
                y -= 3.0 * smile;
            }
            out.push_str(&format!(" {x} {y} {}", xyz[2]));
        }
        out.push('\n');
    }
    let path = dir.join("smile_datapoints.txt");
    std::fs::write(&path, out).unwrap();
    path
}

/// Imports `datapoints` with `--fit candide3` (and `extra` flags) and replays the result onto
/// ict-face; returns the last frame's displacement (cm) of the left (8.3) and right (8.4) mouth
/// corner controls.
fn corners_on_ict(datapoints: &std::path::Path, extra: &[&str]) -> (f64, f64) {
    let dir = datapoints.parent().unwrap();
    let fitted = dir.join(format!("fit{}.jsonl", extra.len()));
    let mut args = vec![
        "import",
        "gfe",
        datapoints.to_str().unwrap(),
        "--fit",
        "candide3",
        "-o",
        fitted.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = mimic(&args);
    assert!(o.status.success(), "{}", text(&o).1);
    let controls = dir.join(format!("controls{}.csv", extra.len()));
    let v = replay_json(&[
        fitted.to_str().unwrap(),
        "--rig",
        "ict-face",
        "--controls",
        controls.to_str().unwrap(),
    ]);
    assert_eq!(v["gated"], 0, "{v}");
    let csv = std::fs::read_to_string(&controls).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let last: Vec<f64> = lines
        .last()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    let moved = |fdp: &str| -> f64 {
        let i = header
            .iter()
            .position(|h| *h == format!("{fdp}_x"))
            .unwrap();
        (last[i].powi(2) + last[i + 1].powi(2) + last[i + 2].powi(2)).sqrt()
    };
    (moved("8.3"), moved("8.4"))
}

#[test]
fn a_one_sided_mouth_corner_stays_one_sided_on_the_target() {
    let dir = tempfile::tempdir().unwrap();
    let capture = one_sided_smile_capture(dir.path());
    let (left, right) = corners_on_ict(&capture, &[]);
    let (sym_left, sym_right) = corners_on_ict(&capture, &["--symmetric"]);
    eprintln!(
        "one-sided mouth corner on ict-face: left / right corner {left:.3} / {right:.3} cm, --symmetric {sym_left:.3} / {sym_right:.3} cm"
    );
    // The tracked corner moved 6.7 px on a face ~45 px wide (one IOD ~ 6.3 cm on ICT, ~25 px in
    // these frames): ~1.7 cm on the target if followed in full. The fit follows part of it (the
    // CANDIDE-3 units move the corner sideways and down, the neighbours that did not move hold it
    // back), so at least 0.2 cm. The right corner did not move; on the target it still moves a
    // little (measured 0.45 vs 0.10 cm; the fitted units' odd parts also move the shared lip
    // vertices near the midline): at most a third of the left, where the symmetric fit moves both
    // alike.
    assert!(left > 0.2, "left corner {left} cm");
    assert!(
        right < left / 3.0,
        "right corner {right} cm vs left {left} cm"
    );
    // `--symmetric`, the fit before: both corners move alike (mirror-symmetric units).
    assert!(
        sym_right > 0.5 * sym_left,
        "--symmetric: {sym_left} vs {sym_right} cm"
    );
}

#[test]
fn symmetric_import_keeps_the_pose_and_aus_and_adds_no_odd_parts() {
    // The odd parts are fitted after the pose with everything else held: a default import and a
    // `--symmetric` one have the same pose and AUs frame by frame, and only the default has
    // `au_odd` (and lists the odd parts in `au_fitted`).
    let dir = tempfile::tempdir().unwrap();
    let data = repo().join("tests/data/kinect-gfe-libras");
    let mut outs = Vec::new();
    for extra in [&[][..], &["--symmetric"][..]] {
        let out = dir.path().join(format!("fit{}.jsonl", extra.len()));
        let mut args = vec![
            "import",
            "gfe",
            data.join("a_doubt_question_datapoints.txt")
                .to_str()
                .unwrap(),
            "--targets",
            data.join("a_doubt_question_targets.txt").to_str().unwrap(),
            "--fit",
            "candide3",
            "-o",
            out.to_str().unwrap(),
        ]
        .into_iter()
        .map(str::to_string)
        .collect::<Vec<_>>();
        args.extend(extra.iter().map(|s| s.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = mimic(&args);
        assert!(o.status.success(), "{}", text(&o).1);
        outs.push(read(&out));
    }
    let ((h_odd, f_odd), (h_sym, f_sym)) = (&outs[0], &outs[1]);
    assert_eq!(h_odd["fit"]["odd"], "after_pose");
    assert!(h_sym["fit"].get("odd").is_none());
    let fitted = |h: &Value| -> Vec<u64> {
        h["fit"]["au_fitted"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect()
    };
    assert_eq!(fitted(h_sym), vec![0, 1, 2, 3, 4, 5, 6]);
    assert!(fitted(h_odd).starts_with(&[0, 1, 2, 3, 4, 5, 6]) && fitted(h_odd).len() > 7);
    assert_eq!(f_odd.len(), f_sym.len());
    let mut one_sided = 0;
    for (a, b) in f_odd.iter().zip(f_sym) {
        for key in ["rotation", "translation", "scale", "au"] {
            assert_eq!(a["fit"][key], b["fit"][key], "{key}, t_us {}", a["t_us"]);
        }
        assert!(b["fit"].get("au_odd").is_none());
        let odd = a["fit"]["au_odd"].as_array().unwrap();
        assert_eq!(odd.len(), 11);
        if odd.iter().any(|v| v.as_f64().unwrap().abs() > 0.05) {
            one_sided += 1;
        }
    }
    eprintln!(
        "a_doubt_question: {one_sided} of {} frames with an odd part over 0.05",
        f_odd.len()
    );
    assert!(one_sided > 0, "no odd part fitted");
}
