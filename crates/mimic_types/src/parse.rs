//! Parsers of the option values several commands share: durations in seconds, inclusive index
//! ranges, `WIDTHxHEIGHT` sizes, factors, listening addresses. Each error names the text it
//! could not read.

/// The longest duration an option takes: 10^6 s (about 11.6 days). Longer ones would overflow
/// instants advanced by them (`Instant + Duration` panics) and mean nothing anyway.
pub const MAX_OPTION_SECONDS: f64 = 1e6;

/// Inclusive vertex index ranges (`mimic eval --vertices`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VertexRanges(pub Vec<(u32, u32)>);

impl VertexRanges {
    /// Whether vertex `i` lies in one of the ranges.
    pub fn contains(&self, i: usize) -> bool {
        self.0
            .iter()
            .any(|&(a, b)| (a as usize..=b as usize).contains(&i))
    }
}

/// Parses `0-9408,11248-14061` as [`VertexRanges`] (a single index is a range of one;
/// backwards is an error).
pub fn parse_vertex_ranges(text: &str) -> Result<VertexRanges, String> {
    parse_ranges(text, false).map(VertexRanges)
}

/// Parses a rate or speed factor: a number in [0.001, 1000000] (`mimic send --rate`, `--speed`).
pub fn parse_factor(text: &str) -> Result<f64, String> {
    let v: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a number"))?;
    if !(1e-3..=1e6).contains(&v) {
        return Err(format!("{text} is out of range: 0.001 to 1000000"));
    }
    Ok(v)
}

/// Parses a listening address, or a port alone for loopback (`mimic serve --http`: `8080` is
/// `127.0.0.1:8080`).
pub fn parse_listen_addr(s: &str) -> Result<std::net::SocketAddr, String> {
    if let Ok(port) = s.parse::<u16>() {
        return Ok(std::net::SocketAddr::from(([127, 0, 0, 1], port)));
    }
    s.parse()
        .map_err(|_| format!("`{s}` is neither a port nor an address like 127.0.0.1:8080"))
}

/// Parses `WIDTHxHEIGHT` (`--size`), e.g. `512x512`.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("--size `{s}`: expected WIDTHxHEIGHT, e.g. 512x512"))?;
    let side = |v: &str, what: &str| {
        v.trim()
            .parse()
            .map_err(|e| format!("--size {what} `{v}`: {e}"))
    };
    Ok((side(w, "width")?, side(h, "height")?))
}

/// Parses a duration in seconds: a finite number in [0, [`MAX_OPTION_SECONDS`]].
pub fn parse_seconds(text: &str) -> Result<f64, String> {
    let s: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a number of seconds"))?;
    if !(0.0..=MAX_OPTION_SECONDS).contains(&s) {
        return Err(format!(
            "{text} s is out of range: 0 to {MAX_OPTION_SECONDS} s (about 11.6 days)"
        ));
    }
    Ok(s)
}

/// [`parse_seconds`] for an `f32` value.
pub fn parse_seconds_f32(text: &str) -> Result<f32, String> {
    // In range, so the narrowing only rounds.
    parse_seconds(text).map(|s| s as f32)
}

/// Parses inclusive index ranges `0-9408,11248-14061` (a single index is a range of one); a
/// range written backwards is an error, or with `swap_backwards` read the other way round.
pub fn parse_ranges(text: &str, swap_backwards: bool) -> Result<Vec<(u32, u32)>, String> {
    text.split(',')
        .map(|part| {
            let (a, b) = part.split_once('-').unwrap_or((part, part));
            let parse = |s: &str| {
                s.trim()
                    .parse::<u32>()
                    .map_err(|e| format!("`{part}`: {e}"))
            };
            let (a, b) = (parse(a)?, parse(b)?);
            if a > b && !swap_backwards {
                return Err(format!("`{part}`: range runs backwards"));
            }
            Ok((a.min(b), a.max(b)))
        })
        .collect()
}

/// Hidden vertex ranges: as `text` gives them (backwards ranges swapped), none for `none`, or
/// the rig look's when not given.
pub fn parse_hidden(text: Option<&str>, look: &crate::RigLook) -> Result<Vec<(u32, u32)>, String> {
    match text {
        None => Ok(look.hidden.iter().map(|[a, b]| (*a, *b)).collect()),
        Some(s) if s.trim() == "none" => Ok(Vec::new()),
        Some(s) => parse_ranges(s, true),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse_and_backwards_is_an_error_or_swapped() {
        let r = parse_ranges("0-9408,11248-14061,20000", false).unwrap();
        assert_eq!(r, vec![(0, 9408), (11248, 14061), (20000, 20000)]);
        assert!(parse_ranges("5-1", false).is_err() && parse_ranges("a-3", false).is_err());
        assert_eq!(parse_ranges("5-3,7", true).unwrap(), vec![(3, 5), (7, 7)]);
    }

    #[test]
    fn hidden_ranges_default_to_the_look() {
        let look = crate::RigLook {
            hidden: vec![[1, 4]],
            ..Default::default()
        };
        assert_eq!(parse_hidden(None, &look).unwrap(), vec![(1, 4)]);
        assert!(parse_hidden(Some("none"), &look).unwrap().is_empty());
        assert_eq!(parse_hidden(Some("9"), &look).unwrap(), vec![(9, 9)]);
        assert!(parse_hidden(Some("1-x"), &look).is_err());
    }

    #[test]
    fn duration_options_are_range_checked() {
        assert_eq!(parse_seconds("0"), Ok(0.0));
        assert_eq!(parse_seconds("2.5"), Ok(2.5));
        assert_eq!(parse_seconds("1e6"), Ok(1e6));
        for bad in ["1e19", "1000001", "-1", "nan", "inf", "soon", ""] {
            assert!(parse_seconds(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_seconds_f32("0.25"), Ok(0.25));
        assert!(parse_seconds_f32("1e39").is_err());
    }
}
