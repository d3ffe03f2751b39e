//! Config files that used to take the server down (issue 15): `mimic info` refuses each with one
//! line naming the file and the line of the offending setting, within a 4 GB address space.

use crate::repo;
use std::path::Path;
use std::process::{Command, Output};

/// Runs the built `mimic` with `args` under `ulimit -v 4000000` (KiB: about 4 GB).
fn mimic_4gb(args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 4000000 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_mimic"))
        .args(args)
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .output()
        .expect("run mimic under sh")
}

/// Asserts `mimic info file` fails with exactly one stderr line ending in `want`.
fn refused(file: &Path, want: &str) {
    let out = mimic_4gb(&["info", file.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "accepted: {stderr}");
    assert_eq!(out.status.code(), Some(1), "not a clean failure: {stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    let line = stderr.trim_end();
    assert!(line.starts_with("error: "), "{line}");
    assert!(line.ends_with(want), "{line}\nwant ...{want}");
}

/// A rig over `t.obj` (three vertices) with `mesh` and `band` as given.
fn rig(dir: &Path, mesh: &str, band: &str) -> std::path::PathBuf {
    std::fs::write(dir.join("t.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let path = dir.join("r.toml");
    std::fs::write(
        &path,
        format!(
            "name = \"r\"\nunits = \"cm\"\nmesh = \"{mesh}\"\n[regions]\ntop_from = 1.0\nbottom_below = 0.0\nband = {band}\n\n[[controls]]\nfdp = \"8.3\"\nvertex = 1\nregion = \"bottom\"\n"
        ),
    )
    .unwrap();
    path
}

#[test]
fn the_sane_rig_passes_under_the_same_limit() {
    let dir = tempfile::tempdir().unwrap();
    let out = mimic_4gb(&["info", rig(dir.path(), "t.obj", "0.5").to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn layout_with_a_trillion_points_is_refused_at_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("l.toml");
    std::fs::write(
        &path,
        "name = \"huge\"\nstable = [0, 1, 2]\npoint_count = 1000000000000\n\n[[controls]]\nfdp = \"8.3\"\npoints = [1]\nregion = \"bottom\"\n",
    )
    .unwrap();
    refused(
        &path,
        "l.toml:3: layout `huge` has point_count 1000000000000, over the maximum of 4096 points",
    );
}

#[test]
fn rig_with_a_nan_band_is_refused_at_its_line() {
    let dir = tempfile::tempdir().unwrap();
    refused(
        &rig(dir.path(), "t.obj", "nan"),
        "r.toml:7: regions.band = NaN: must be finite and >= 0",
    );
}

#[cfg(unix)]
#[test]
fn rig_whose_mesh_is_dev_zero_is_refused_at_its_line() {
    let dir = tempfile::tempdir().unwrap();
    refused(
        &rig(dir.path(), "/dev/zero", "0.5"),
        "r.toml:3: /dev/zero: not a regular file but a character device; OBJ meshes are read only from regular files",
    );
}

#[test]
fn rig_whose_mesh_is_over_the_obj_cap_is_refused_at_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = rig(dir.path(), "big.obj", "0.5");
    // Sparse: 64 MiB + 1 byte of nothing on disk.
    let big = std::fs::File::create(dir.path().join("big.obj")).unwrap();
    big.set_len(64 * 1024 * 1024 + 1).unwrap();
    refused(
        &path,
        "big.obj: 67108865 bytes, over the 64 MiB cap for OBJ meshes",
    );
    let line =
        String::from_utf8_lossy(&mimic_4gb(&["info", path.to_str().unwrap()]).stderr).into_owned();
    assert!(line.contains("r.toml:3: "), "{line}");
}

#[cfg(unix)]
#[test]
fn gfe_import_of_a_device_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("x.jsonl");
    let out = mimic_4gb(&[
        "import",
        "gfe",
        "/dev/zero",
        "-o",
        out_path.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("/dev/zero: cannot read: not a regular file but a character device"),
        "{stderr}"
    );
    assert!(!out_path.exists());
}
