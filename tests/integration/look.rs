//! How rigs look: the textured ICT rig (`configs/rigs/ict-face-textured.toml`, the skin of
//! `configs/meshes/ict-facekit-textured/`) in `mimic render` against a golden image, in `mimic
//! view` headless, and in `mimic rig export` checked by the Khronos validator (tools/gltf-check);
//! and `mimic view`'s number keys blending the rig's morph targets in.
//!
//! Re-bless the golden with `MIMIC_BLESS=1 cargo test -p mimic --test integration look` and
//! look at the PNG. With no adapter the GPU tests fail with the renderer's message, unless
//! MIMIC_SKIP_GPU_TESTS is set.

use crate::{mimic, repo, text};
use mimic_render::Image;

/// The render goldens' bound (tests/integration/render.rs says why 0.25 per RGBA byte).
const MEAN_ABS_BOUND: f64 = 0.25;

fn skip() -> bool {
    let skip = std::env::var_os("MIMIC_SKIP_GPU_TESTS").is_some();
    if skip {
        eprintln!("MIMIC_SKIP_GPU_TESTS is set: skipping a GPU test");
    }
    skip
}

/// Pixels coloured like the texture's lips (red well above green, not dark): the untextured
/// head's skin is (231, 212, 200) in sRGB before light, its gums dark red inside the closed mouth.
fn lip_pixels(image: &Image) -> usize {
    image
        .rgba
        .chunks_exact(4)
        .filter(|p| u32::from(p[0]) > 90 && u32::from(p[0]) * 10 > u32::from(p[1]) * 16)
        .count()
}

/// Renders frame 0 (the rest shape) of `a_yn_question` on `rig` at 256 x 256.
fn render_neutral(rig: &str) -> Image {
    let dir = tempfile::tempdir().unwrap();
    let o = mimic(&[
        "render",
        "recordings/a_yn_question.jsonl",
        "--rig",
        rig,
        "--frames",
        "0",
        "--size",
        "256x256",
        "-o",
        dir.path().to_str().unwrap(),
    ]);
    assert!(o.status.success(), "mimic render failed:\n{}", text(&o).1);
    Image::load_png(&dir.path().join("frame_000000.png")).unwrap()
}

#[test]
fn the_textured_rig_renders_its_skin_and_matches_the_golden_image() {
    if skip() {
        return;
    }
    let textured = render_neutral("ict-face-textured");
    let path = repo().join("tests/golden_images/ict_textured_neutral_256.png");
    if std::env::var_os("MIMIC_BLESS").is_some() {
        textured.save_png(&path).unwrap();
    }
    let golden = Image::load_png(&path)
        .unwrap_or_else(|e| panic!("{e} (bless with MIMIC_BLESS=1 and review the PNG)"));
    let err = textured.mean_abs_error(&golden).unwrap();
    assert!(err <= MEAN_ABS_BOUND, "mean absolute error {err:.3}");
    // The texture shows: the image differs from the untextured head's by far more than the
    // bound, and the lips are coloured (the untextured head has none of their colour).
    let plain = render_neutral("ict-face");
    let change = textured.mean_abs_error(&plain).unwrap();
    assert!(
        change > 2.0 * MEAN_ABS_BOUND,
        "texture barely shows: {change}"
    );
    let (lips, none) = (lip_pixels(&textured), lip_pixels(&plain));
    assert!(
        lips > 100 && none < lips / 10,
        "lip pixels {lips} vs {none}"
    );
}

#[test]
fn headless_view_draws_the_texture() {
    if skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let shot = |rig: &str| {
        let png = dir.path().join(format!("{rig}.png"));
        let o = mimic(&[
            "view",
            "recordings/a_yn_question.jsonl",
            "--rig",
            rig,
            "--size",
            "128x128",
            "--headless-frames",
            "2",
            "--headless-out",
            png.to_str().unwrap(),
        ]);
        let (stdout, stderr) = text(&o);
        assert!(o.status.success(), "{stderr}");
        assert!(stdout.contains("mimic view: 2 images"), "{stdout}");
        Image::load_png(&png).unwrap()
    };
    let (textured, plain) = (shot("ict-face-textured"), shot("ict-face"));
    let (lips, none) = (lip_pixels(&textured), lip_pixels(&plain));
    assert!(lips > 20 && none < lips / 10, "lip pixels {lips} vs {none}");
}

#[test]
fn the_textured_rig_is_the_ict_rig_but_for_its_name_and_texture() {
    let read = |name: &str| -> toml::Table {
        let path = repo().join(format!("configs/rigs/{name}.toml"));
        toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    };
    let (mut a, mut b) = (read("ict-face"), read("ict-face-textured"));
    for t in [&mut a, &mut b] {
        t.remove("name");
        t.remove("description");
    }
    let look = b["look"].as_table().unwrap().clone();
    let textures = look["textures"].as_table().unwrap();
    assert_eq!(
        textures["M_Face"].as_str(),
        Some("../meshes/ict-facekit-textured/skin.png")
    );
    let mut look = look;
    look.remove("textures");
    b.insert("look".into(), toml::Value::Table(look));
    assert_eq!(
        a, b,
        "ict-face-textured.toml must stay a copy of ict-face.toml"
    );
    // The shipped texture is small.
    let png = repo().join("configs/meshes/ict-facekit-textured/skin.png");
    assert!(std::fs::metadata(png).unwrap().len() <= 256 * 1024);
}

#[test]
fn the_textured_rig_exports_a_glb_with_its_texture_that_validates() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("textured.glb");
    let o = mimic(&[
        "rig",
        "export",
        "ict-face-textured",
        "-o",
        glb.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{:?}", text(&o));
    // The JSON chunk names the texture on M_Face, and the image is the shipped PNG byte for byte.
    let bytes = std::fs::read(&glb).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let bin = &bytes[20 + json_len + 8..];
    let face = json["materials"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["name"] == "M_Face")
        .unwrap();
    let tex = &face["pbrMetallicRoughness"]["baseColorTexture"];
    assert_eq!(tex["texCoord"], 0, "{face}");
    let image = &json["images"][json["textures"][tex["index"].as_u64().unwrap() as usize]["source"]
        .as_u64()
        .unwrap() as usize];
    assert_eq!(image["mimeType"], "image/png");
    let view = &json["bufferViews"][image["bufferView"].as_u64().unwrap() as usize];
    let (off, len) = (
        view["byteOffset"].as_u64().unwrap() as usize,
        view["byteLength"].as_u64().unwrap() as usize,
    );
    let png = std::fs::read(repo().join("configs/meshes/ict-facekit-textured/skin.png")).unwrap();
    assert!(
        bin[off..off + len] == png[..],
        "the embedded image is not skin.png"
    );
    // Untextured materials have no texture.
    let teeth = json["materials"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["name"] == "M_Teeth")
        .unwrap();
    assert!(teeth["pbrMetallicRoughness"]["baseColorTexture"].is_null());
    if crate::gltf::node_ready() {
        crate::gltf::check(&glb, None);
    }
}

#[test]
fn number_keys_blend_the_rigs_morph_targets_in() {
    if skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // Paused on frame 0 (space at image 2), then key 1 (image 3): ICT's first morph target,
    // jawOpen, eases in over 0.25 s, 15 images at 60 per simulated second; 40 images leave it on.
    let run = |keys: &str| {
        let png = dir.path().join(format!("{}.png", keys.replace(',', "_")));
        let o = mimic(&[
            "view",
            "recordings/a_yn_question.jsonl",
            "--rig",
            "ict-face",
            "--size",
            "96x96",
            "--headless-frames",
            "40",
            "--headless-keys",
            keys,
            "--headless-out",
            png.to_str().unwrap(),
        ]);
        let (stdout, stderr) = text(&o);
        assert!(o.status.success(), "{stderr}");
        (stdout, Image::load_png(&png).unwrap())
    };
    let (plain_out, plain) = run("space");
    let (open_out, open) = run("space,1");
    assert!(plain_out.contains("keys 1-8: expressions"), "{plain_out}");
    assert!(open_out.contains("1 jawOpen 1.00"), "{open_out}");
    // The open jaw changes the picture (the neutral and frame 300 differ by 0.72, render.rs).
    let change = open.mean_abs_error(&plain).unwrap();
    assert!(
        change > 2.0 * MEAN_ABS_BOUND,
        "jawOpen barely shows: {change}"
    );
    // Pressed again 20 images later (r, reset camera, changes nothing here), it eases back out
    // within the 16 images left: the picture is the plain one again.
    let again = format!("space,1,{}1", "r,".repeat(20));
    let (_, back) = run(&again);
    let diff = back.mean_abs_error(&plain).unwrap();
    assert!(
        diff <= MEAN_ABS_BOUND,
        "jawOpen did not go back out: {diff}"
    );
}

#[test]
fn a_waiting_viewer_says_what_it_waits_for_and_when_the_server_goes_away() {
    if skip() {
        return;
    }
    let server = crate::loopback::Serve::start(&["--rig", "candide3"]);
    let view = std::process::Command::new(env!("CARGO_BIN_EXE_mimic"))
        .args([
            "view",
            "--connect",
            &server.tcp,
            "--session",
            "nobody",
            "--size",
            "64x64",
            "--headless-frames",
            "1",
            "--headless-timeout",
            "120",
        ])
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    // No session comes; the server stops (Ctrl-C's path): the viewer ends, saying why.
    let _ = server.stop();
    let o = view.wait_with_output().unwrap();
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stdout.contains("mimic view: 0 images, 0 new frames"),
        "{stdout}"
    );
    assert!(
        stdout.contains("the server closed the connection") || stdout.contains("read error"),
        "{stdout}"
    );
}
