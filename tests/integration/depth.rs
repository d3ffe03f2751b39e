//! `mimic import gfe` repairs depth holes and off-face depths (docs/gate.md, "Depth holes"): on
//! each GFE capture in the shared data, the repaired import has no invalid point, fewer clamped
//! frames than the raw one and no more jumps; with the head-pose trim floor on, at most 1 % of the
//! tracked frames are clamped or jump. A capture whose chin has no depth in nine frames of ten
//! (a performer the project does not ship) keeps its chin where the full capture has it.

use crate::replay::replay_json;
use crate::{mimic, repo, text};
use mimic_capture::RecordingReader;
use mimic_retarget::{RetargetSettings, Retargeter};
use mimic_types::{LandmarkFrame, SolverKind};
use std::path::{Path, PathBuf};

const GFE: [&str; 3] = ["a_affirmative", "a_doubt_question", "a_yn_question"];

/// The GFE files: `tests/data/kinect-gfe-libras` (a copy of the shared data's, with its SOURCE.md).
fn data() -> Option<PathBuf> {
    let d = repo().join("tests/data/kinect-gfe-libras");
    assert!(
        d.is_dir(),
        "{} missing: the repository ships it",
        d.display()
    );
    Some(d)
}

/// Imports `datapoints` to `out` (extra args appended); returns stdout.
fn import(datapoints: &Path, out: &Path, extra: &[&str]) -> String {
    let mut args = vec![
        "import",
        "gfe",
        datapoints.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = mimic(&args);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    stdout
}

fn frames(path: &Path) -> Vec<LandmarkFrame> {
    let r = RecordingReader::open(path, Some(100)).unwrap();
    r.read_all().frames.into_iter().map(|f| f.frame).collect()
}

/// (tracked, clamped, jumps) of a library replay onto ict-face (RBF; the gate works before the
/// solve, so the solver does not change them) with `floor` as the head-pose trim floor.
fn library_counts(path: &Path, floor: f32) -> (u64, u64, u64) {
    let root = repo();
    let rig = mimic_assets::load_rig(&root.join("configs/rigs/ict-face.toml")).unwrap();
    let layout =
        mimic_assets::load_layout(&root.join("configs/layouts/kinect-gfe100.toml")).unwrap();
    let mut s = rig.solver;
    s.kind = SolverKind::Rbf;
    let basis = std::sync::Arc::new(mimic_solve::build_basis(&rig, &s).unwrap());
    let mut settings = RetargetSettings {
        positions: false,
        normals: false,
        ..RetargetSettings::default()
    };
    settings.gate.pose_trim_floor = floor;
    let mut rt = Retargeter::new(&rig, &layout, basis, settings).unwrap();
    let mut out = rt.new_output();
    for f in frames(path) {
        rt.step(&f, &mut out);
    }
    let st = rt.stats();
    (st.tracked, st.clamped, st.jumps)
}

#[test]
fn repaired_gfe_imports_have_no_holes_and_fewer_clamped_frames() {
    let Some(data) = data() else { return };
    let dir = tempfile::tempdir().unwrap();
    for n in GFE {
        let dp = data.join(format!("{n}_datapoints.txt"));
        let rep = dir.path().join(format!("{n}.jsonl"));
        let raw = dir.path().join(format!("{n}.raw.jsonl"));
        let said = import(&dp, &rep, &[]);
        assert!(said.contains("depth repaired: "), "{said}");
        assert!(said.contains(", 0 invalid points,"), "{said}");
        let said_raw = import(&dp, &raw, &["--raw-depth"]);
        assert!(!said_raw.contains("depth repaired"), "{said_raw}");
        assert!(!said_raw.contains(", 0 invalid points,"), "{said_raw}");
        let count = |j: &serde_json::Value, k: &str| j[k].as_u64().unwrap();
        let r = replay_json(&[raw.to_str().unwrap()]);
        for solver in ["rbf", "laplacian"] {
            let j = replay_json(&[rep.to_str().unwrap(), "--solver", solver]);
            let tracked = count(&j, "tracked");
            println!(
                "{n} {solver}: tracked {tracked}, clamped {} (raw {}), jumps {} (raw {})",
                count(&j, "clamped"),
                count(&r, "clamped"),
                count(&j, "jumps"),
                count(&r, "jumps")
            );
            assert_eq!(tracked, count(&r, "tracked"), "{n}");
            assert_eq!(count(&j, "invalid_points"), 0, "{n}");
            // Every frame of the capture is tracked: nothing is bought by losing frames.
            assert!(
                count(&j, "lost") + count(&j, "gated") <= count(&r, "gated"),
                "{n}"
            );
            assert!(count(&j, "jumps") * 100 <= tracked, "{n}: jumps");
            assert!(count(&j, "jumps") <= count(&r, "jumps"), "{n}: jumps");
            // Measured: 6 to 47 times fewer clamped frames (docs/gate.md); a third is the bound.
            assert!(
                count(&j, "clamped") * 3 <= count(&r, "clamped"),
                "{n}: clamped {} vs raw {}",
                count(&j, "clamped"),
                count(&r, "clamped")
            );
        }
        // With the trim floor, the figure: at most 1 % of tracked frames clamped or jumping.
        let (tracked, clamped, jumps) = library_counts(&rep, 0.2);
        println!("{n} floor 0.2: tracked {tracked}, clamped {clamped}, jumps {jumps}");
        assert!(
            clamped * 100 <= tracked,
            "{n}: {clamped} clamped of {tracked}"
        );
        assert!(jumps * 100 <= tracked, "{n}: {jumps} jumps of {tracked}");
    }
}

/// Chin contour points of the GFE layout (the chin controls' points 76-78 and their neighbours).
const CHIN: std::ops::RangeInclusive<usize> = 74..=80;

#[test]
fn a_chin_without_depth_in_most_frames_stays_where_the_full_capture_has_it() {
    let Some(data) = data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let n = "a_yn_question";
    let dp = data.join(format!("{n}_datapoints.txt"));
    let text = std::fs::read_to_string(&dp).unwrap();
    // Nine frames in ten lose the depth of every chin point (the pixel stays).
    let mut holed = String::new();
    for (k, line) in text.lines().enumerate() {
        if k == 0 || k % 10 == 0 {
            holed.push_str(line);
        } else {
            let mut tok: Vec<&str> = line.split_whitespace().collect();
            for p in CHIN {
                tok[3 + 3 * p] = "0";
            }
            holed.push_str(&tok.join(" "));
        }
        holed.push('\n');
    }
    let holed_dp = dir.path().join("holed_datapoints.txt");
    std::fs::write(&holed_dp, holed).unwrap();
    let full = dir.path().join("full.jsonl");
    let part = dir.path().join("part.jsonl");
    import(&dp, &full, &[]);
    let said = import(&holed_dp, &part, &[]);
    assert!(said.contains(", 0 invalid points,"), "{said}");
    let (a, b) = (frames(&full), frames(&part));
    assert_eq!(a.len(), b.len());
    // The face's inter-ocular distance in the first frame (eye corners 0, 4 and 8, 12).
    let p = &a[0].points;
    let iod = ((p[0] + p[4]) * 0.5).distance((p[8] + p[12]) * 0.5);
    let mut shifts: Vec<f32> = a
        .iter()
        .zip(&b)
        .flat_map(|(fa, fb)| CHIN.map(|q| fa.points[q].distance(fb.points[q])))
        .collect();
    shifts.sort_by(f32::total_cmp);
    let (median, p99, worst) = (
        shifts[shifts.len() / 2],
        shifts[shifts.len() * 99 / 100],
        shifts[shifts.len() - 1],
    );
    println!(
        "chin without depth in 9 of 10 frames: shift median {median} p99 {p99} max {worst} m (IOD {iod} m)"
    );
    // Same pixels, so only the depth can differ: the chin's relief from a tenth of the frames and
    // a plane fitted without the chin (its pitch is less sure). Measured: median 0.02, p99 0.08,
    // max 0.19 IOD; the issue saw 3-4 cm (0.5 IOD) in neutral frames, and the raw import has no
    // chin depth at all in these frames.
    assert!(median <= 0.03 * iod, "median {median} m vs IOD {iod} m");
    assert!(p99 <= 0.1 * iod, "p99 {p99} m vs IOD {iod} m");
    assert!(worst <= 0.25 * iod, "max {worst} m vs IOD {iod} m");
}
