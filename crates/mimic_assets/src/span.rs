//! Byte offsets to line numbers, for errors that point into a config file.

/// 1-based line number of byte `offset` in `text`.
pub(crate) fn line_of(text: &str, offset: usize) -> usize {
    let end = offset.min(text.len());
    text.as_bytes()[..end]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// 1-based line of the `nth` spanned entry (0-based) for which `matches` holds; 1 if there is none.
pub(crate) fn line_of_nth<T>(
    text: &str,
    entries: &[toml::Spanned<T>],
    matches: impl Fn(&T) -> bool,
    nth: usize,
) -> usize {
    entries
        .iter()
        .filter(|e| matches(e.get_ref()))
        .nth(nth)
        .map(|e| line_of(text, e.span().start))
        .unwrap_or(1)
}

/// Converts a TOML parse error into its line and message.
pub(crate) fn toml_error(
    path: &std::path::Path,
    text: &str,
    e: toml::de::Error,
) -> crate::AssetError {
    let line = e.span().map(|s| line_of(text, s.start)).unwrap_or(1);
    crate::AssetError::Toml {
        path: path.to_path_buf(),
        line,
        message: e.message().trim().to_string(),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn counts_lines() {
        let t = "a\nbb\nccc";
        assert_eq!(super::line_of(t, 0), 1);
        assert_eq!(super::line_of(t, 2), 2);
        assert_eq!(super::line_of(t, 5), 3);
        assert_eq!(super::line_of(t, 100), 3);
    }
}
