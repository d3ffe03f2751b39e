//! Fuzzes the rig TOML loader; the rig's mesh resolves in a scratch folder holding `tri.obj`.
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;

/// Scratch folder with a 4-vertex mesh `tri.obj` (the corpus rigs name it), made once per process.
fn rig_path() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("mimic-fuzz-rig-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(
            dir.join("tri.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n",
        )
        .unwrap();
        dir.join("rig.toml")
    })
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    // Only meshes inside the scratch folder: a fuzzed `mesh = "/dev/zero"` would read forever.
    if text.contains('/') || text.contains('\\') || text.contains("..") {
        return;
    }
    let _ = mimic_assets::parse_rig(rig_path(), text);
});
