//! The avatar reader's error: one line naming the file and the JSON pointer of what is wrong.

use std::path::{Path, PathBuf};

/// Why an avatar file could not be read: the file, the JSON pointer (RFC 6901; empty for the
/// file as a whole) and what is wrong, shown on one line.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}: {}{}", path.display(), if pointer.is_empty() { String::new() } else { format!("{pointer}: ") }, message)]
pub struct AvatarError {
    /// The avatar file.
    pub path: PathBuf,
    /// JSON pointer of the offending value, e.g. `/meshes/0/primitives/1/indices`.
    pub pointer: String,
    /// What is wrong, in words (one line).
    pub message: String,
}

impl AvatarError {
    /// An error at `pointer` of `path`; line breaks in `message` become spaces.
    pub fn at(path: &Path, pointer: impl Into<String>, message: impl Into<String>) -> Self {
        let message: String = message.into();
        Self {
            path: path.to_path_buf(),
            pointer: pointer.into(),
            message: message.split_whitespace().collect::<Vec<_>>().join(" "),
        }
    }
}

/// The JSON pointer of a `gltf` crate validation path (`meshes[0].primitives[1].attributes["POSITION"]`
/// becomes `/meshes/0/primitives/1/attributes/POSITION`).
pub(crate) fn pointer_of_path(path: &str) -> String {
    let mut out = String::new();
    let mut token = String::new();
    let flush = |token: &mut String, out: &mut String| {
        if !token.is_empty() {
            out.push('/');
            out.push_str(&token.replace('~', "~0").replace('/', "~1"));
            token.clear();
        }
    };
    for c in path.chars() {
        match c {
            '.' | '[' | ']' => flush(&mut token, &mut out),
            '"' => {}
            c => token.push(c),
        }
    }
    flush(&mut token, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_paths_become_pointers_and_errors_stay_on_one_line() {
        assert_eq!(
            pointer_of_path(r#"meshes[0].primitives[1].attributes["POSITION"]"#),
            "/meshes/0/primitives/1/attributes/POSITION"
        );
        let e = AvatarError::at(Path::new("a.glb"), "/nodes/2", "bad\nnode");
        assert_eq!(e.to_string(), "a.glb: /nodes/2: bad node");
        let e = AvatarError::at(Path::new("a.glb"), "", "not a GLB");
        assert_eq!(e.to_string(), "a.glb: not a GLB");
    }
}
