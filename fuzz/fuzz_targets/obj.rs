//! Fuzzes the OBJ mesh parser.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(mesh) = mimic_assets::parse_obj(Path::new("fuzz.obj"), text) {
        let n = mesh.vertex_count();
        assert!(
            mesh.triangles.iter().flatten().all(|&i| (i as usize) < n),
            "triangle index out of range"
        );
    }
});
