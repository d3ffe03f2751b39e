//! Every file this crate reads goes through here: regular files only, each kind within its
//! size cap ([`mimic_types::limits`]); errors name the file (and the cap).

use crate::AssetError;
use mimic_types::FileKind;
use mimic_types::limits::{check_file, open_regular, read_capped};
use std::io::Read;
use std::path::Path;

/// The whole text of `path`, a file of `kind`.
pub(crate) fn read_text(path: &Path, kind: &FileKind) -> Result<String, AssetError> {
    read_capped(path, kind).map_err(|e| AssetError::read(path, e))
}

/// `path`, a file of `kind`, opened for a streaming reader that stops at the kind's cap.
pub(crate) fn open_capped(path: &Path, kind: &FileKind) -> Result<impl Read, AssetError> {
    check_file(path, kind).map_err(|e| AssetError::read(path, e))?;
    let file = open_regular(path, kind.what).map_err(|e| AssetError::read(path, e))?;
    Ok(file.take(kind.max_bytes))
}

#[cfg(test)]
mod tests {
    use mimic_types::limits::{LAYOUT_FILE, MORPH_FILE, MTL_FILE, OBJ_FILE, RIG_FILE};
    use std::path::Path;

    /// A sparse file one byte over `cap` (no disk used).
    fn over(dir: &Path, name: &str, cap: u64) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::File::create(&p).unwrap().set_len(cap + 1).unwrap();
        p
    }

    #[test]
    fn every_loader_refuses_a_file_over_its_cap() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let msg = |e: crate::AssetError| e.to_string();
        let layout = over(d, "l.toml", LAYOUT_FILE.max_bytes);
        assert!(
            msg(crate::load_layout(&layout).unwrap_err())
                .ends_with("l.toml: 1048577 bytes, over the 1 MiB cap for layout files")
        );
        let rig = over(d, "r.toml", RIG_FILE.max_bytes);
        assert!(
            msg(crate::load_rig(&rig).unwrap_err())
                .ends_with("r.toml: 1048577 bytes, over the 1 MiB cap for rig files")
        );
        assert!(
            msg(crate::load_rig_materials(&rig).unwrap_err())
                .ends_with("over the 1 MiB cap for rig files")
        );
        assert!(
            msg(crate::load_morph_targets(&rig, &tiny_rig()).unwrap_err())
                .ends_with("over the 1 MiB cap for rig files")
        );
        let obj = over(d, "m.obj", OBJ_FILE.max_bytes);
        assert!(
            msg(crate::load_obj(&obj).unwrap_err()).ends_with("over the 64 MiB cap for OBJ meshes")
        );
        over(d, "m.mtl", MTL_FILE.max_bytes);
        let e = crate::parse_obj_materials(&d.join("x.obj"), "mtllib m.mtl\n").unwrap_err();
        assert!(msg(e).ends_with("m.mtl: 1048577 bytes, over the 1 MiB cap for MTL files"));
        let morph = over(d, "m.txt", MORPH_FILE.max_bytes);
        assert!(
            msg(crate::load_morph_file(&morph).unwrap_err())
                .ends_with("over the 256 MiB cap for morph data files")
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_is_refused_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("l.toml");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("skipped: no mkfifo");
            return;
        }
        // Opening a FIFO for reading would block until a writer comes: the check comes first.
        let e = crate::load_layout(&fifo).unwrap_err().to_string();
        assert!(e.ends_with("l.toml: not a regular file but a FIFO (named pipe); layout files are read only from regular files"), "{e}");
        let e = crate::load_morph_file(&fifo).unwrap_err().to_string();
        assert!(e.contains("a FIFO (named pipe)"), "{e}");
    }

    /// A loaded 3-vertex rig (built through the loader, so new rig fields need no change here).
    fn tiny_rig() -> mimic_types::Rig {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("t.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        )
        .unwrap();
        let rig = dir.path().join("t.toml");
        std::fs::write(
            &rig,
            "name = \"t\"\nunits = \"cm\"\nmesh = \"t.obj\"\n[regions]\ntop_from = 1.0\nbottom_below = 0.0\nband = 0.5\n\n[[controls]]\nfdp = \"8.3\"\nvertex = 0\nregion = \"bottom\"\n",
        )
        .unwrap();
        crate::load_rig(&rig).unwrap()
    }
}
