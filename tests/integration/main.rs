//! End-to-end tests of the `mimic` binary on the shipped configs and recordings.

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

mod arkit;
mod audio;
mod avatar;
mod avatar_parts;
mod browser;
mod churn;
mod clock;
mod config_limits;
mod crash;
mod dense;
mod depth;
mod doors;
mod escape;
mod faults;
mod fit;
mod forward;
mod gltf;
mod gpu_bench;
mod hostile_avatar;
mod import;
mod info;
mod landmark_arkit;
mod live_audio;
mod livelink;
mod look;
mod loopback;
mod lost;
mod mediapipe;
mod morph;
mod nats;
mod open_mouth;
mod openseeface;
mod protected;
mod record_weights;
mod regression;
mod render;
mod replay;
mod replay_audio;
mod replay_take;
mod rig_new;
mod rig_orient;
mod seams;
mod serve;
mod serve_weights;
mod shell;
mod shipped_rigs;
mod slots;
mod view;
mod vrm;

use std::path::PathBuf;
use std::process::{Command, Output};

/// Repository root.
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("repo root")
}

/// Runs the built `mimic` binary in the repo root.
pub fn mimic(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mimic"))
        .args(args)
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .output()
        .expect("run mimic")
}

/// Stdout and stderr of an output, as text.
pub fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// `mimic eval --json` with `extra` flags on the shipped ICT expressions `shapes` (file stems of
/// configs/meshes/ict-facekit/); panics unless it succeeds.
pub fn eval_ict(extra: &[&str], shapes: &[&str]) -> serde_json::Value {
    let paths: Vec<String> = shapes
        .iter()
        .map(|s| format!("configs/meshes/ict-facekit/{s}.obj"))
        .collect();
    let mut args = vec!["eval", "--json"];
    args.extend_from_slice(extra);
    args.push("--shapes");
    args.extend(paths.iter().map(String::as_str));
    let o = mimic(&args);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    serde_json::from_str(&stdout).unwrap()
}
