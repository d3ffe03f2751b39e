//! The shipped ICT rigs are `mimic rig new` output (with their documented overrides,
//! `configs/rigs/overrides/`): the command in each rig's `# Regenerate:` header line, run into a
//! temporary folder (beside a link to `configs/meshes`), writes the shipped file again.
//!
//! One line may differ: `mesh = ...` is written relative to the rig's folder, which is the
//! temporary one here; the test checks that it names the same mesh file instead. The header's
//! `-o` path is the temporary file's and is compared as the shipped one.

use crate::{mimic, repo, text};

/// The rigs `rig new` makes, with the overrides each takes (docs/rigging.md, "The shipped rigs").
const SHIPPED: [&str; 5] = [
    "ict-face",
    "ict-face-textured",
    "ict-face.kinect121",
    "ict-face.ibug68",
    "ict-face.mediapipe478",
];

/// The words of the `# Regenerate:` line of a rig's text.
fn regenerate_command(rig: &str, shipped: &str) -> Vec<String> {
    let line = shipped
        .lines()
        .take(3)
        .find_map(|l| l.strip_prefix("# Regenerate: "))
        .unwrap_or_else(|| panic!("{rig}: no `# Regenerate:` line among its first three"));
    let words: Vec<String> = line.split_whitespace().map(str::to_string).collect();
    assert_eq!(words[..3], ["mimic", "rig", "new"], "{rig}: {line}");
    words
}

#[test]
fn shipped_rigs_are_rig_new_output_with_their_overrides() {
    // Paths in the overrides (morph target OBJs, textures) are relative to the rig, as in
    // configs/rigs/: the rigs are written to <tmp>/configs/rigs/ beside a link to the meshes.
    let tmp = tempfile::tempdir().unwrap();
    let dir_buf = tmp.path().join("configs/rigs");
    std::fs::create_dir_all(&dir_buf).unwrap();
    std::os::unix::fs::symlink(
        repo().join("configs/meshes"),
        tmp.path().join("configs/meshes"),
    )
    .unwrap();
    let dir = dir_buf.as_path();
    for rig in SHIPPED {
        let rel = format!("configs/rigs/{rig}.toml");
        let shipped = std::fs::read_to_string(repo().join(&rel)).unwrap();
        let words = regenerate_command(rig, &shipped);
        let o_at = words.iter().position(|w| w == "-o").unwrap();
        assert_eq!(
            words[o_at + 1],
            rel,
            "{rig}: the command writes another file"
        );
        let out = dir.join(format!("{rig}.toml"));
        let out_str = out.to_str().unwrap().to_string();
        let mut args: Vec<&str> = words[3..].iter().map(String::as_str).collect();
        args[o_at - 2] = &out_str;
        let mut full = vec!["rig", "new"];
        full.extend(args);
        let o = mimic(&full);
        let (stdout, stderr) = text(&o);
        assert!(o.status.success(), "{rig}: {stdout}\n{stderr}");
        let made = std::fs::read_to_string(&out).unwrap().replacen(
            &format!("-o {out_str} "),
            &format!("-o {rel} "),
            1,
        );
        let (mut n_mesh, mut n_lines) = (0, 0);
        for (k, (a, b)) in shipped.lines().zip(made.lines()).enumerate() {
            if let (Some(a), Some(b)) = (a.strip_prefix("mesh = "), b.strip_prefix("mesh = ")) {
                let unquote = |s: &str| s.trim_matches('"').to_string();
                let shipped_mesh = repo().join("configs/rigs").join(unquote(a));
                let made_mesh = dir.join(unquote(b));
                assert_eq!(
                    shipped_mesh.canonicalize().unwrap(),
                    made_mesh.canonicalize().unwrap(),
                    "{rig}: line {}: another mesh",
                    k + 1
                );
                n_mesh += 1;
                continue;
            }
            assert_eq!(a, b, "{rig}: line {} differs from rig new's", k + 1);
            n_lines += 1;
        }
        assert_eq!(n_mesh, 1, "{rig}: one mesh line");
        assert_eq!(
            shipped.lines().count(),
            made.lines().count(),
            "{rig}: line count ({n_lines} equal)"
        );
        assert_eq!(
            shipped.ends_with('\n'),
            made.ends_with('\n'),
            "{rig}: final newline"
        );
    }
}

/// `candide3.toml` stays a hand rig (docs/rigging.md, "The shipped rigs"): CANDIDE-3 has no
/// vertex for many iBUG points. Its header says so, not that `rig new` made it.
#[test]
fn candide3_is_the_one_hand_rig() {
    let text = std::fs::read_to_string(repo().join("configs/rigs/candide3.toml")).unwrap();
    assert!(
        !text.contains("# Regenerate: "),
        "candide3 has no rig new command"
    );
    for rig in SHIPPED {
        let t = std::fs::read_to_string(repo().join(format!("configs/rigs/{rig}.toml"))).unwrap();
        assert!(
            t.starts_with("# Made by `mimic rig new`"),
            "{rig}: not marked as rig new output"
        );
    }
}
