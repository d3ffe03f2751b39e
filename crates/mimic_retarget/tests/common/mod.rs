//! What mimic_retarget's tests share: the repository's files, shipped recordings and the shipped
//! ICT rig with its basis (`mod common;` in each test; a test uses what it needs).
#![allow(dead_code, reason = "each test uses its part")]
#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use mimic_solve::{Basis, build_basis};
use mimic_types::{LandmarkFrame, Layout, Rig};
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

/// The repository's root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A shipped layout by name.
pub fn layout(name: &str) -> Layout {
    mimic_assets::load_layout(&root().join(format!("configs/layouts/{name}.toml"))).unwrap()
}

/// A shipped recording's layout and frames.
pub fn recording(name: &str) -> (Layout, Vec<LandmarkFrame>) {
    let reader =
        mimic_capture::RecordingReader::open(&root().join("recordings").join(name), None).unwrap();
    let layout = layout(&reader.header().layout);
    let frames = reader
        .read_all()
        .frames
        .into_iter()
        .map(|f| f.frame)
        .collect();
    (layout, frames)
}

/// The shipped ICT rig and its basis, built once.
pub fn ict() -> &'static (Rig, Arc<Basis>) {
    static ICT: OnceLock<(Rig, Arc<Basis>)> = OnceLock::new();
    ICT.get_or_init(|| {
        let rig = mimic_assets::load_rig(&root().join("configs/rigs/ict-face.toml")).unwrap();
        let basis = Arc::new(build_basis(&rig, &rig.solver).unwrap());
        (rig, basis)
    })
}
