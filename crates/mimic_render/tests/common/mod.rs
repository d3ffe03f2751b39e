//! Helpers shared by the GPU test files (each `mod common;`).

use mimic_render::Renderer;

/// A headless renderer of `w` x `h`, or `None` (with a note) when MIMIC_SKIP_GPU_TESTS is set;
/// with no adapter the test fails with the renderer's message.
pub fn renderer(w: u32, h: u32) -> Option<Renderer> {
    if std::env::var_os("MIMIC_SKIP_GPU_TESTS").is_some() {
        eprintln!("MIMIC_SKIP_GPU_TESTS is set: skipping a GPU test");
        return None;
    }
    match Renderer::new(w, h) {
        Ok(r) => Some(r),
        Err(e) => panic!("{e} (set MIMIC_SKIP_GPU_TESTS=1 to skip GPU tests)"),
    }
}
