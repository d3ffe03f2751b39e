#![allow(clippy::unwrap_used, reason = "tmp")]
use mimic_assets::Orientation;
use mimic_rig::{FindSettings, TemplateHead, register_template};
use std::path::PathBuf;
fn configs() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs")
}
#[test]
fn probe_all() {
    let template = TemplateHead::ict(&configs()).unwrap();
    let mp = mimic_assets::load_obj(&configs().join("models/mediapipe/face_model_with_iris.obj"))
        .unwrap();
    for (name, mesh) in [("mediapipe", mp), ("ict", template.mesh.clone())] {
        for o in Orientation::all() {
            let mut t = mesh.clone();
            for p in &mut t.positions {
                *p = o.to_file(*p) * 10.0;
            }
            let t0 = std::time::Instant::now();
            let r = register_template(&t, &template, &FindSettings::default()).unwrap();
            let ok = r.orientation == o;
            println!(
                "{name} {:>22} -> {:>22} {} best {:.3}/{:.4} second {:.3}/{:.4} sim cov {:.2} {:.2}s",
                o.describe(),
                r.orientation.describe(),
                if ok { "OK" } else { "WRONG" },
                r.probes[0].coverage,
                r.probes[0].rms,
                r.probes[1].coverage,
                r.probes[1].rms,
                r.rigid.coverage,
                t0.elapsed().as_secs_f32()
            );
        }
    }
}
