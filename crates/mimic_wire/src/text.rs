//! Untrusted text (a tracker's or a recording's header strings) made safe to print on a
//! terminal: control characters and escape codes shown escaped, never interpreted; a JSON
//! summary of such text as indented `key: value` lines ([`plain_lines`], `mimic info`).

use std::borrow::Cow;
use std::fmt::Write as _;

/// True for a character a terminal may act on rather than show: C0 and C1 controls, DEL, and
/// the bidirectional overrides and isolates (which reorder what is shown).
fn needs_escape(c: char) -> bool {
    c.is_control() || matches!(c, '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
}

/// `s` with every control character (ESC of an escape code included), DEL, C1 control and
/// bidirectional override written as a Rust-style escape (`\n`, `\t`, `\r`, `\u{1b}`), and `\`
/// itself as `\\` when anything was escaped, so the printed text is unambiguous. Text without
/// such characters comes back borrowed, unchanged.
pub fn escape_untrusted(s: &str) -> Cow<'_, str> {
    if !s.chars().any(needs_escape) {
        return Cow::Borrowed(s);
    }
    let mut out = String::with_capacity(s.len() + 8);
    for c in s.chars() {
        match c {
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            '\\' => out.push_str("\\\\"),
            c if needs_escape(c) => {
                let _ = write!(out, "\\u{{{:x}}}", c as u32);
            }
            c => out.push(c),
        }
    }
    Cow::Owned(out)
}

/// A JSON object as indented `key: value` lines (a nested object as `key:` and its lines two
/// spaces in), every key and value escaped ([`escape_untrusted`]); anything but an object gives
/// no lines.
pub fn plain_lines(v: &serde_json::Value) -> String {
    let mut out = String::new();
    plain(v, 0, &mut out);
    out
}

/// [`plain_lines`] of `v` at `indent` levels, appended to `out`.
fn plain(v: &serde_json::Value, indent: usize, out: &mut String) {
    use serde_json::Value;
    let pad = "  ".repeat(indent);
    if let Value::Object(map) = v {
        for (k, val) in map {
            let _ = match val {
                Value::Object(_) => {
                    let _ = writeln!(out, "{pad}{}:", escape_untrusted(k));
                    plain(val, indent + 1, out);
                    Ok(())
                }
                Value::String(s) => {
                    writeln!(out, "{pad}{}: {}", escape_untrusted(k), escape_untrusted(s))
                }
                other => writeln!(
                    out,
                    "{pad}{}: {}",
                    escape_untrusted(k),
                    escape_untrusted(&other.to_string())
                ),
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escape_codes_and_controls_are_shown_not_interpreted() {
        assert!(matches!(
            escape_untrusted("Kinect v2, 30 Hz \\ ok"),
            Cow::Borrowed(_)
        ));
        assert_eq!(
            escape_untrusted("\u{1b}[2J\u{1b}]0;pwned\u{7}x"),
            "\\u{1b}[2J\\u{1b}]0;pwned\\u{7}x"
        );
        assert_eq!(escape_untrusted("a\nb\\c"), "a\\nb\\\\c");
        assert_eq!(escape_untrusted("\u{9b}31m\u{7f}"), "\\u{9b}31m\\u{7f}");
        assert_eq!(escape_untrusted("abc\u{202e}fed"), "abc\\u{202e}fed");
        // Nothing a terminal acts on is left.
        let out = escape_untrusted("\u{0}\u{1f}\u{80}\u{9f}\u{2066}");
        assert!(!out.chars().any(needs_escape), "{out}");
    }
}
