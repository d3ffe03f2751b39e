//! `mimic view` without a display: `--headless-frames` runs the window's loop into an offscreen
//! target (lavapipe on CI), for a local replay and for a live `mimic serve` session.

use crate::loopback::Serve;
use crate::{mimic, repo, text};
use mimic_render::Image;
use std::process::{Command, Stdio};

fn skip() -> bool {
    let skip = std::env::var_os("MIMIC_SKIP_GPU_TESTS").is_some();
    if skip {
        eprintln!("MIMIC_SKIP_GPU_TESTS is set: skipping a GPU test");
    }
    skip
}

#[test]
fn help_lists_the_key_bindings() {
    let o = mimic(&["view", "--help"]);
    let (stdout, _) = text(&o);
    assert!(o.status.success());
    for key in [
        "space",
        "left/right",
        "wheel",
        "right drag",
        "heat map",
        "Laplacian",
    ] {
        assert!(stdout.contains(key), "help lacks `{key}`:\n{stdout}");
    }
}

#[test]
fn headless_local_replay_plays_pauses_scrubs_and_switches_solver() {
    if skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("last.png");
    // 30 images at 60 per simulated second over a 30 fps recording: frames 0..=14 play; then
    // space (image 2) pauses at frame 0, right (3) steps to 1, s (4) switches to the Laplacian
    // basis, h (5) turns the heat map on, space (6) resumes: 24 more images are 12 frames.
    let o = mimic(&[
        "view",
        "recordings/a_yn_question.jsonl",
        "--rig",
        "ict-face",
        "--size",
        "96x96",
        "--headless-frames",
        "30",
        "--headless-keys",
        "space,right,s,h,space",
        "--headless-out",
        png.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    assert!(stdout.contains("mimic view: 30 images"), "{stdout}");
    assert!(stdout.contains("solver laplacian"), "{stdout}");
    assert!(stdout.contains("| heat |"), "{stdout}");
    // Key help is printed only when a window opens.
    assert!(!stdout.contains("Keys and mouse"), "{stdout}");
    let last: u64 = stdout
        .split("last frame ")
        .nth(1)
        .and_then(|s| s.split(',').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no last frame in {stdout}"));
    assert!((1..=14).contains(&last), "{stdout}");
    let image = Image::load_png(&png).unwrap();
    assert_eq!((image.width, image.height), (96, 96));
    // The heat map colours the head: blue-dominant pixels exist.
    let blue = image
        .rgba
        .chunks(4)
        .filter(|p| p[2] > 120 && p[2] > p[0] + 40)
        .count();
    assert!(blue > 200, "{blue} heat-map pixels");
}

#[test]
fn headless_viewer_follows_a_live_session() {
    if skip() {
        return;
    }
    let server = Serve::start(&["--rig", "candide3"]);
    let view = Command::new(env!("CARGO_BIN_EXE_mimic"))
        .args([
            "view",
            "--connect",
            &server.tcp,
            "--session",
            "live",
            "--size",
            "64x64",
            "--headless-frames",
            "5",
            "--headless-timeout",
            "60",
        ])
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    server.wait_for("the viewer", |s| s["viewers_active"] == 1);
    let sent = mimic(&[
        "send",
        "recordings/openface_test.jsonl",
        "--to",
        &server.tcp,
        "--session",
        "live",
        // At the recording's own pace (about 3 s): a software renderer on a busy machine then
        // still draws five frames before the session ends.
        "--speed",
        "1",
    ]);
    assert!(sent.status.success(), "{}", text(&sent).1);
    let o = view.wait_with_output().unwrap();
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    // Five frames with new data were drawn (newer ones may have replaced older ones unseen).
    assert!(stdout.contains("5 new frames"), "{stdout}");
    assert!(stdout.contains("solver live"), "{stdout}");
    assert!(stdout.contains("mimic view: candide3 (live)"), "{stdout}");
}
