//! `mimic rig new` on the ICT head from its own landmark list: as good as the hand rig on the
//! expressions, and the same per-shape ratios on the head scaled to mm, turned and moved.
//! `mimic rig check`: each warning on a rig made to show it.

use crate::{mimic, repo, text};
use glam::{Quat, Vec3};
use std::path::{Path, PathBuf};

const SHAPES: [&str; 8] = [
    "jawOpen",
    "mouthSmile_L",
    "mouthSmile_R",
    "browInnerUp_L",
    "browInnerUp_R",
    "eyeBlink_L",
    "eyeBlink_R",
    "mouthFunnel",
];

fn ict_dir() -> PathBuf {
    repo().join("configs/meshes/ict-facekit")
}

/// Copies an OBJ with every `v` (and `vn`) line moved by `f` (`g` for normals).
fn transform_obj(from: &Path, to: &Path, f: &dyn Fn(Vec3) -> Vec3, g: &dyn Fn(Vec3) -> Vec3) {
    let text = std::fs::read_to_string(from).unwrap();
    let mut out = String::with_capacity(text.len() + text.len() / 4);
    for line in text.lines() {
        let mut it = line.split_whitespace();
        let tag = it.next();
        if matches!(tag, Some("v") | Some("vn")) {
            let c: Vec<f32> = it.take(3).map(|s| s.parse().unwrap()).collect();
            let p = Vec3::new(c[0], c[1], c[2]);
            let q = if tag == Some("v") { f(p) } else { g(p) };
            out.push_str(&format!(
                "{} {:.7} {:.7} {:.7}\n",
                tag.unwrap(),
                q.x,
                q.y,
                q.z
            ));
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    std::fs::write(to, out).unwrap();
}

/// `mimic rig new MESH -o OUT --landmarks MARKS EXTRA...`.
fn rig_new_from(mesh: &Path, out: &Path, marks: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "rig",
        "new",
        mesh.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--landmarks",
        marks.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    mimic(&args)
}

fn rig_new(mesh: &Path, out: &Path, units: &str) {
    let marks = repo().join("configs/rigs/ict-face.landmarks.json");
    let o = rig_new_from(mesh, out, &marks, &["--units", units]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}\n{stderr}");
    assert!(stdout.contains("38 controls"), "{stdout}");
}

/// Per-shape ratios and the median from `mimic eval --json`.
fn eval(rig: &Path, shapes: &[PathBuf]) -> (Vec<f64>, f64) {
    let mut args = vec![
        "eval".to_string(),
        "--rig".into(),
        rig.display().to_string(),
        "--json".into(),
        "--shapes".into(),
    ];
    args.extend(shapes.iter().map(|s| s.display().to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = mimic(&args);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let ratios = v["shapes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["all"]["ratio"].as_f64().unwrap())
        .collect();
    (ratios, v["median_ratio"].as_f64().unwrap())
}

#[test]
fn generated_ict_rig_matches_the_hand_rig_and_ignores_a_similarity() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ict = ict_dir();
    let shapes: Vec<PathBuf> = SHAPES
        .iter()
        .map(|s| ict.join(format!("{s}.obj")))
        .collect();

    // The ICT head as shipped (cm), from its own landmark list.
    let plain = d.join("plain.toml");
    rig_new(&ict.join("generic_neutral_mesh.obj"), &plain, "cm");
    let (ratios, median) = eval(&plain, &shapes);
    let (_, hand) = eval(&repo().join("configs/rigs/ict-face.toml"), &shapes);
    assert!(
        median <= hand * 1.05,
        "generated rig median {median} vs the hand rig's {hand} (allowed 5% more)"
    );

    // Scaled to mm, turned 20 degrees about the vertical axis and moved.
    let rot = Quat::from_rotation_y(20f32.to_radians());
    let f = |p: Vec3| rot * (p * 10.0) + Vec3::new(123.0, -456.0, 78.0);
    let g = |n: Vec3| rot * n;
    let moved_dir = d.join("moved");
    std::fs::create_dir_all(&moved_dir).unwrap();
    transform_obj(
        &ict.join("generic_neutral_mesh.obj"),
        &moved_dir.join("neutral.obj"),
        &f,
        &g,
    );
    let moved_shapes: Vec<PathBuf> = SHAPES
        .iter()
        .map(|s| {
            let to = moved_dir.join(format!("{s}.obj"));
            transform_obj(&ict.join(format!("{s}.obj")), &to, &f, &g);
            to
        })
        .collect();
    let moved = d.join("moved.toml");
    rig_new(&moved_dir.join("neutral.obj"), &moved, "mm");
    let (moved_ratios, _) = eval(&moved, &moved_shapes);
    assert_eq!(
        (ratios.len(), moved_ratios.len()),
        (SHAPES.len(), SHAPES.len())
    );
    for ((shape, a), b) in SHAPES.iter().zip(&ratios).zip(&moved_ratios) {
        assert!(
            (a - b).abs() <= 0.01 * a,
            "{shape}: ratio {a} on the shipped head, {b} scaled, turned and moved"
        );
    }

    // The same moved head without `--landmarks`: the ICT template registered onto it finds
    // the landmarks (written by --landmarks-out), and the rig scores as the one from the list.
    let found = d.join("found.toml");
    let found_marks = d.join("found.landmarks.json");
    let o = mimic(&[
        "rig",
        "new",
        moved_dir.join("neutral.obj").to_str().unwrap(),
        "-o",
        found.to_str().unwrap(),
        "--units",
        "mm",
        "--landmarks-out",
        found_marks.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}\n{stderr}");
    assert!(stderr.contains("68 of 68 landmarks found"), "{stderr}");
    assert!(!stderr.contains("probably failed"), "{stderr}");
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let (given, got) = (
        read(&repo().join("configs/rigs/ict-face.landmarks.json")),
        read(&found_marks),
    );
    // The list is the 68 vertices in iBUG order; the found file an object keyed by number.
    let same = (0..68)
        .filter(|&k| given[k].as_u64().is_some() && given[k] == got[k.to_string().as_str()])
        .count();
    assert!(same >= 60, "{same} of 68 landmarks on the listed vertex");
    let (found_ratios, _) = eval(&found, &moved_shapes);
    for ((shape, a), b) in SHAPES.iter().zip(&ratios).zip(&found_ratios) {
        assert!(
            (a - b).abs() <= 0.01 * a,
            "{shape}: ratio {a} from the landmark list, {b} from the found landmarks"
        );
    }
}

/// Writes a rig on the ICT mesh built from `controls` (`fdp`, `vertex`, `region`) with `units`.
fn ict_rig_with(dir: &Path, units: &str, controls: &[(&str, u32, &str)]) -> PathBuf {
    let mesh = ict_dir().join("generic_neutral_mesh.obj");
    let mut t = format!(
        "name = \"t\"\nunits = \"{units}\"\nmesh = \"{}\"\nfrozen = [[14062, 26718]]\n\n[regions]\ntop_from = 2.3\nbottom_below = -1.8\nband = 1.4\n",
        mesh.display()
    );
    for (fdp, v, region) in controls {
        t.push_str(&format!(
            "\n[[controls]]\nfdp = \"{fdp}\"\nvertex = {v}\nregion = \"{region}\"\n"
        ));
    }
    let path = dir.join(format!("t-{}.toml", controls.len()));
    std::fs::write(&path, t).unwrap();
    path
}

/// A control as (fdp, vertex, region).
type Control = (String, u32, String);

/// The shipped ICT rig's controls.
fn ict_controls() -> Vec<Control> {
    let rig = mimic_assets::load_rig(&repo().join("configs/rigs/ict-face.toml")).unwrap();
    rig.controls
        .iter()
        .map(|c| (c.fdp.to_string(), c.vertex, c.region.name().to_string()))
        .collect()
}

fn check_kinds(rig: &Path) -> Vec<(String, Vec<String>)> {
    let o = mimic(&["rig", "check", rig.to_str().unwrap(), "--json"]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    v["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| {
            (
                w["kind"].as_str().unwrap().to_string(),
                w["fdps"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|f| f.as_str().unwrap().to_string())
                    .collect(),
            )
        })
        .collect()
}

#[test]
fn rig_check_reports_each_kind_of_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let base = ict_controls();
    let with = |edit: &dyn Fn(&mut Vec<Control>), units: &str| {
        let mut c = base.clone();
        edit(&mut c);
        let c: Vec<(&str, u32, &str)> = c
            .iter()
            .map(|(f, v, r)| (f.as_str(), *v, r.as_str()))
            .collect();
        ict_rig_with(d, units, &c)
    };
    let kinds = |p: &Path| check_kinds(p);
    let has = |w: &[(String, Vec<String>)], kind: &str, fdps: &[&str]| {
        w.iter()
            .any(|(k, f)| k == kind && fdps.iter().all(|x| f.iter().any(|g| g == x)))
    };
    // The shipped controls: only the cheeks, which sit below the middle region (known).
    let clean = kinds(&with(&|_| {}, "cm"));
    assert!(
        clean.iter().all(|(k, f)| k == "outside_region"
            && (f == &["5.1".to_string()] || f == &["5.2".to_string()])),
        "{clean:?}"
    );
    // A missing FDP (a rig with 37 controls).
    let w = kinds(&with(&|c| c.retain(|x| x.0 != "8.7"), "cm"));
    assert!(has(&w, "missing_fdp", &["8.7"]), "{w:?}");
    // Two FDPs on one vertex.
    let w = kinds(&with(
        &|c| {
            let v = c.iter().find(|x| x.0 == "2.2").unwrap().1;
            c.iter_mut().find(|x| x.0 == "2.3").unwrap().1 = v;
        },
        "cm",
    ));
    assert!(has(&w, "shared_vertex", &["2.2", "2.3"]), "{w:?}");
    // A brow control said to drive the bottom region.
    let w = kinds(&with(
        &|c| c.iter_mut().find(|x| x.0 == "4.3").unwrap().2 = "bottom".into(),
        "cm",
    ));
    assert!(has(&w, "outside_region", &["4.3"]), "{w:?}");
    // The left lip midpoint moved onto the left mouth corner: no longer 8.6's mirror image.
    let w = kinds(&with(
        &|c| {
            let v = c.iter().find(|x| x.0 == "8.3").unwrap().1;
            c.iter_mut().find(|x| x.0 == "8.5").unwrap().1 = v;
        },
        "cm",
    ));
    assert!(has(&w, "not_mirrored", &["8.5", "8.6"]), "{w:?}");
    // The nose tip moved onto the right nostril: off the midline.
    let w = kinds(&with(
        &|c| {
            let v = c.iter().find(|x| x.0 == "9.4").unwrap().1;
            c.iter_mut().find(|x| x.0 == "9.3").unwrap().1 = v;
        },
        "cm",
    ));
    assert!(has(&w, "off_midline", &["9.3"]), "{w:?}");
    // A cm head labelled metres.
    let w = kinds(&with(&|_| {}, "m"));
    assert!(has(&w, "units", &[]), "{w:?}");
    let w = kinds(&with(&|_| {}, "mm"));
    assert!(has(&w, "units", &[]), "{w:?}");
    // Without eye corners there is no face frame.
    let w = kinds(&with(&|c| c.retain(|x| x.0 != "3.7"), "cm"));
    assert!(has(&w, "no_face_frame", &[]), "{w:?}");
    // Text output: one line per warning.
    let o = mimic(&["rig", "check", with(&|_| {}, "m").to_str().unwrap()]);
    let (stdout, _) = text(&o);
    assert!(stdout.contains("warning: units: units = \"m\""), "{stdout}");
}

#[test]
fn rig_check_draws_the_neutral_with_regions_and_labels() {
    if std::env::var_os("MIMIC_SKIP_GPU_TESTS").is_some() {
        eprintln!("MIMIC_SKIP_GPU_TESTS is set: skipping a GPU test");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("check.png");
    let o = mimic(&[
        "rig",
        "check",
        "ict-face",
        "-o",
        png.to_str().unwrap(),
        "--size",
        "320x320",
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}\n{stderr}");
    let image = mimic_render::Image::load_png(&png).unwrap();
    assert_eq!((image.width, image.height), (320, 320));
    let px = |x: u32, y: u32| {
        let at = ((y * image.width + x) * 4) as usize;
        [image.rgba[at], image.rgba[at + 1], image.rgba[at + 2]]
    };
    // The legend's first swatch (scale 1 at 320 px: x 4..10, y 4..9) is the top region's colour.
    let top = mimic_rig::picture::srgb8(mimic_rig::picture::REGION_COLORS[0]);
    assert_eq!(px(6, 6), [top[0], top[1], top[2]]);
    // The face fills the middle of the picture: not the background there.
    let background = px(1, image.height - 2);
    let face = px(image.width / 2, image.height / 3);
    assert_ne!(face, background);
}

#[test]
fn a_glb_head_gives_the_same_rig_as_its_obj() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let obj = ict_dir().join("generic_neutral_mesh.obj");
    let mesh = mimic_assets::load_obj(&obj).unwrap();
    let glb = d.join("head.glb");
    std::fs::write(
        &glb,
        mimic_rig::gltf_mesh::write_glb(&mesh.positions, &mesh.triangles, Vec3::ZERO),
    )
    .unwrap();
    let (from_obj, from_glb) = (d.join("obj.toml"), d.join("glb.toml"));
    rig_new(&obj, &from_obj, "cm");
    rig_new(&glb, &from_glb, "cm");
    // The GLB's rig names the GLB itself: no OBJ copy.
    assert!(!d.join("glb.mesh.obj").exists());
    assert!(
        std::fs::read_to_string(&from_glb)
            .unwrap()
            .contains("mesh = \"head.glb\""),
    );
    let a = mimic_assets::load_rig(&from_obj).unwrap();
    let b = mimic_assets::load_rig(&from_glb).unwrap();
    // The GLB's vertices at exactly one place are welded (seam copies); the OBJ's are not: the
    // same surface, the same controls at the same places, the same triangles.
    let mut places: Vec<[u32; 3]> = mesh
        .positions
        .iter()
        .map(|p| p.to_array().map(f32::to_bits))
        .collect();
    places.sort_unstable();
    places.dedup();
    assert_eq!(b.mesh.vertex_count(), places.len());
    assert_eq!(a.mesh.triangles.len(), b.mesh.triangles.len());
    let at = |r: &mimic_types::Rig| -> Vec<_> {
        r.controls
            .iter()
            .map(|c| (c.fdp, r.mesh.positions[c.vertex as usize], c.region))
            .collect()
    };
    assert_eq!(at(&a), at(&b));
    let frozen = |r: &mimic_types::Rig| r.frozen.iter().filter(|f| **f).count();
    // Welding joins pieces that touched at shared places: no more frozen than the OBJ's rig.
    assert!(frozen(&b) <= frozen(&a), "{} vs {}", frozen(&b), frozen(&a));
}

/// A landmark file as eos ships them (TOML, `[landmark_mappings]`, iBUG numbers from 1, vertices
/// from 0, a `[contour_landmarks]` table after it) that lacks the jaw contour and the inner mouth
/// corners, as eos's Surrey Face Model mapping does: the base is seen from the file, the 18
/// missing points come from the ICT registration, and on the ICT head the rig is the one made
/// from the whole landmark list. Open eyes: the RBF.
#[test]
fn an_eos_mapping_without_the_jaw_contour_gives_the_whole_lists_rig() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let obj = ict_dir().join("generic_neutral_mesh.obj");
    let list: Vec<u32> = serde_json::from_str(
        &std::fs::read_to_string(repo().join("configs/rigs/ict-face.landmarks.json")).unwrap(),
    )
    .unwrap();
    // eos leaves out iBUG 1-8 and 10-17 (the contour) and 61, 65 (inner mouth corners), 1-based.
    let lacking = |k: usize| (1..=8).contains(&k) || (10..=17).contains(&k) || k == 61 || k == 65;
    let mut toml = String::from(
        "# Mappings from input landmarks (ibug, lhs) to output landmarks (mesh, rhs):\n[landmark_mappings]\n",
    );
    for (i, v) in list.iter().enumerate() {
        let k = i + 1;
        if lacking(k) {
            toml.push_str(&format!("            # {k} not defined\n"));
        } else {
            toml.push_str(&format!("{k:2} = {v:5}  # point {k}\n"));
        }
    }
    toml.push_str("\n[contour_landmarks]\nright = [ 1,\n  2 ]\nleft = [ 10,\n 11 ]\n");
    let eos = d.join("ibug_to_ict.txt");
    std::fs::write(&eos, toml).unwrap();
    let out = d.join("eos.toml");
    let o = rig_new_from(&obj, &out, &eos, &["--units", "cm"]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}\n{stderr}");
    assert!(
        stderr.contains(
            "filled iBUG [0, 1, 2, 3, 4, 5, 6, 7, 9, 10, 11, 12, 13, 14, 15, 16, 60, 64]"
        ),
        "{stderr}"
    );
    let whole = d.join("whole.toml");
    rig_new(&obj, &whole, "cm");
    let (a, b) = (
        mimic_assets::load_rig(&out).unwrap(),
        mimic_assets::load_rig(&whole).unwrap(),
    );
    assert_eq!(a.controls, b.controls);
    assert_eq!(a.frozen, b.frozen);
    assert_eq!(a.solver.kind, mimic_types::SolverKind::Rbf);
    let written = std::fs::read_to_string(&out).unwrap();
    assert!(
        written.contains("kind = \"rbf\"  # rbf, because the eyes are open"),
        "{written}"
    );
    // --keep-missing leaves the four controls that need the missing points out.
    let kept = d.join("kept.toml");
    let o = rig_new_from(&obj, &kept, &eos, &["--keep-missing"]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}\n{stderr}");
    assert!(stdout.contains("34 controls"), "{stdout}");
    // --solver shell is written as asked.
    let shell = d.join("shell.toml");
    let marks = repo().join("configs/rigs/ict-face.landmarks.json");
    let o = rig_new_from(&obj, &shell, &marks, &["--solver", "shell"]);
    assert!(o.status.success(), "{:?}", text(&o));
    let r = mimic_assets::load_rig(&shell).unwrap();
    assert_eq!(r.solver.kind, mimic_types::SolverKind::Shell);
    // 20 / IOD^2 with the ICT head's IOD of 6.3029 cm (docs/rigging.md).
    let ks = 20.0 / (6.3029f64 * 6.3029);
    assert!(
        (r.solver.shell.stiffness - ks).abs() < 1e-3 * ks,
        "{}",
        r.solver.shell.stiffness
    );
}

#[test]
fn rig_new_makes_its_output_folder_and_refuses_an_unwritable_one_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = ict_dir().join("generic_neutral_mesh.obj");
    let marks = repo().join("configs/rigs/ict-face.landmarks.json");
    // A folder that does not exist yet, two levels deep: made.
    let nested = dir.path().join("new/dir/x.toml");
    let o = rig_new_from(&mesh, &nested, &marks, &["--units", "cm"]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}\n{stderr}");
    assert!(mimic_assets::load_rig(&nested).is_ok());
    // A folder under a regular file cannot be made: one clear line, and no registration ran
    // (without --landmarks the ICT head would be registered first, which takes seconds).
    let file = dir.path().join("plain");
    std::fs::write(&file, "not a folder").unwrap();
    let under = file.join("sub/x.toml");
    let o = mimic(&[
        "rig",
        "new",
        mesh.to_str().unwrap(),
        "-o",
        under.to_str().unwrap(),
    ]);
    let (_, stderr) = text(&o);
    assert!(!o.status.success(), "{stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("x.toml: cannot create the folder") && !stderr.contains("registered"),
        "{stderr}"
    );
}
