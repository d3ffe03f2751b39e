//! File limits of the importers and the recording reader: oversized files and devices are
//! refused before a byte is read, each error naming the file (and the cap).

use mimic_capture::RecordingReader;
use mimic_trackers::gfe::import_gfe;
use mimic_trackers::openface::{OpenFaceTiming, import_openface};
use mimic_types::limits::{GFE_FILE, OPENFACE_FILE};
use std::path::Path;

/// A sparse file one byte over `cap` (no disk used).
fn over(dir: &Path, name: &str, cap: u64) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::File::create(&p).unwrap().set_len(cap + 1).unwrap();
    p
}

#[test]
fn importers_refuse_files_over_their_caps() {
    let dir = tempfile::tempdir().unwrap();
    let gfe = over(dir.path(), "x_datapoints.txt", GFE_FILE.max_bytes);
    let e = import_gfe(&gfe, None, None).unwrap_err().to_string();
    assert!(
        e.ends_with(
            "x_datapoints.txt: cannot read: 67108865 bytes, over the 64 MiB cap for GFE files"
        ),
        "{e}"
    );
    let csv = over(dir.path(), "x.csv", OPENFACE_FILE.max_bytes);
    let e = import_openface(&csv, OpenFaceTiming::FileTimestamps, None)
        .unwrap_err()
        .to_string();
    assert!(
        e.ends_with(
            "x.csv: cannot read: 268435457 bytes, over the 256 MiB cap for OpenFace CSV files"
        ),
        "{e}"
    );
}

#[cfg(unix)]
#[test]
fn importers_and_reader_refuse_devices() {
    let zero = Path::new("/dev/zero");
    let e = import_gfe(zero, None, None).unwrap_err().to_string();
    assert_eq!(
        e,
        "/dev/zero: cannot read: not a regular file but a character device; GFE files are read only from regular files"
    );
    let e = import_openface(zero, OpenFaceTiming::Rate(30.0), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("not a regular file but a character device"),
        "{e}"
    );
    let e = RecordingReader::open(zero, None).err().unwrap().to_string();
    assert_eq!(
        e,
        "/dev/zero: cannot open: not a regular file but a character device; recordings are read only from regular files"
    );
}
