//! Dumps what docs/crease_explore.py needs to try bases against the crease measure and the eval
//! (issue 45): the rig's rest mesh, the brows-and-forehead region, ICT's expression shapes, the
//! eval shapes' control displacements, each replayed take's per-frame displacements (controls and
//! rigid parts: `positions = rest + B d`, so a basis variant needs no replay), and the basis with
//! the shell blend shares given. Raw little-endian arrays with a JSON index.
//! `cargo run -p mimic_retarget --example crease_dump -- OUT_DIR [top,middle,bottom ...]`
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    reason = "an exploration tool: a failed unwrap is the report"
)]

use glam::Vec3;
use mimic_retarget::quality::control_displacements;
use mimic_retarget::{FrameStatus, RetargetSettings, Retargeter};
use mimic_solve::build_basis;
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn write_f32(path: &Path, v: impl IntoIterator<Item = f32>) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    for x in v {
        f.write_all(&x.to_le_bytes()).unwrap();
    }
}

fn flat(v: &[Vec3]) -> impl Iterator<Item = f32> + '_ {
    v.iter().flat_map(|p| [p.x, p.y, p.z])
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let out = PathBuf::from(args.get(1).expect("OUT_DIR"));
    std::fs::create_dir_all(&out).unwrap();
    let rig = mimic_assets::load_rig(&root().join("configs/rigs/ict-face.toml")).unwrap();
    let rest = &rig.mesh.positions;
    let n = rest.len();
    write_f32(&out.join("rest.f32"), flat(rest));
    let tris: Vec<u8> = rig
        .mesh
        .triangles
        .iter()
        .flat_map(|t| t.iter().flat_map(|v| v.to_le_bytes()))
        .collect();
    std::fs::write(out.join("tris.u32"), tris).unwrap();
    std::fs::write(
        out.join("frozen.u8"),
        rig.frozen.iter().map(|&f| u8::from(f)).collect::<Vec<_>>(),
    )
    .unwrap();
    let controls: Vec<serde_json::Value> = rig
        .controls
        .iter()
        .map(|c| json!({"fdp": c.fdp.to_string(), "vertex": c.vertex}))
        .collect();
    let pack = mimic_assets::load_shape_pack(
        &root().join("configs/meshes/ict-facekit/expressions.shapes"),
    )
    .unwrap();
    let shapes: Vec<_> = pack
        .shapes
        .iter()
        .filter(|s| !s.name.starts_with("Pupil"))
        .collect();
    write_f32(
        &out.join("ict_shapes.f32"),
        shapes
            .iter()
            .flat_map(|s| flat(&s.deltas).collect::<Vec<_>>()),
    );
    let names: Vec<&str> = shapes.iter().map(|s| s.name.as_str()).collect();
    // The eval's eight shapes: their true displacements and control displacements.
    let eval = [
        "jawOpen",
        "mouthSmile_L",
        "mouthSmile_R",
        "browInnerUp_L",
        "browInnerUp_R",
        "eyeBlink_L",
        "eyeBlink_R",
        "mouthFunnel",
    ];
    let mut eval_true = Vec::new();
    let mut eval_d = Vec::new();
    for s in eval {
        let mesh =
            mimic_assets::load_obj(&root().join(format!("configs/meshes/ict-facekit/{s}.obj")))
                .unwrap();
        eval_true.extend(mesh.positions.iter().zip(rest).map(|(a, b)| *a - *b));
        eval_d.extend(control_displacements(&rig, &mesh.positions));
    }
    write_f32(&out.join("eval_true.f32"), flat(&eval_true));
    write_f32(&out.join("eval_d.f32"), flat(&eval_d));

    let mut bases = Vec::new();
    let mut cols = 0;
    // Each spec: `key=value` pairs joined by `;` over the rig's solver settings: blend=T,M,B
    // (shell_blend), sat / sband (top split height / band), band (the regions' band), uk (the
    // brow kernel's Matern radius).
    for spec in args.iter().skip(2) {
        let mut r = rig.clone();
        let mut settings = rig.solver;
        for kv in spec.split(';') {
            let (k, v) = kv.split_once('=').expect("key=value");
            let f = |v: &str| v.parse::<f64>().unwrap();
            let split = settings.top_split.as_mut().unwrap();
            match k {
                "blend" => {
                    let s: Vec<f64> = v.split(',').map(f).collect();
                    settings.shell_blend = [s[0], s[1], s[2]];
                }
                "sat" => split.at = f(v) as f32,
                "sband" => split.band = f(v) as f32,
                "uk" => {
                    split.upper_kernel = Some(mimic_types::RbfKernel::Matern32 { radius: f(v) });
                }
                "band" => r.regions.band = f(v) as f32,
                "stiff" => settings.shell.stiffness = f(v),
                _ => panic!("unknown key {k}"),
            }
        }
        let b = build_basis(&r, &settings).unwrap();
        cols = b.control_count();
        let file = format!("basis_{}.f32", bases.len());
        write_f32(&out.join(&file), (0..n).flat_map(|i| b.row(i).to_vec()));
        bases.push(json!({"spec": spec, "file": file}));
        eprintln!("basis {spec}: {n} x {cols}");
    }
    let basis = build_basis(&rig, &rig.solver).unwrap();
    cols = cols.max(basis.control_count());
    let mut takes = Vec::new();
    for name in ["a_yn_question.kinect121.jsonl", "megamind_mediapipe.jsonl"] {
        let reader =
            mimic_capture::RecordingReader::open(&root().join("recordings").join(name), None)
                .unwrap();
        let path = root().join(format!("configs/layouts/{}.toml", reader.header().layout));
        let layout = mimic_assets::load_layout(&path).unwrap();
        let frames: Vec<_> = reader
            .read_all()
            .frames
            .into_iter()
            .map(|f| f.frame)
            .collect();
        let settings = RetargetSettings {
            positions: false,
            normals: false,
            ..RetargetSettings::default()
        };
        let mut rt = Retargeter::new(&rig, &layout, basis.clone(), settings).unwrap();
        let mut o = rt.new_output();
        let mut d = Vec::new();
        let mut tracked = Vec::new();
        for f in &frames {
            rt.step(f, &mut o);
            tracked.push(u8::from(o.status == FrameStatus::Tracked));
            d.extend_from_slice(&o.displacements);
        }
        let file = format!("d_{name}.f32");
        write_f32(&out.join(&file), flat(&d));
        std::fs::write(out.join(format!("tracked_{name}.u8")), &tracked).unwrap();
        takes.push(json!({"name": name, "frames": frames.len(), "file": file}));
        eprintln!("{name}: {} frames", frames.len());
    }
    let index = json!({
        "vertices": n, "columns": cols, "controls": controls, "shapes": names,
        "eval": eval, "bases": bases, "takes": takes,
    });
    std::fs::write(out.join("index.json"), index.to_string()).unwrap();
}
