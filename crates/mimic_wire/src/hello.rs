//! The first line of a TCP connection (hellos) and the frame lines of a weights tracker.

use crate::audio::AudioFormat;
use crate::code::ErrorCode;
use mimic_types::RecordingHeader;
use serde_json::Value;

/// What the first line of a TCP connection asks for.
#[derive(Clone, Debug, PartialEq)]
pub enum Hello {
    /// A tracker: the recording header, with the optional `session` and `rig` fields.
    Tracker {
        /// The header (layout, rate, ...).
        header: Box<RecordingHeader>,
        /// Its `session` and `rig` fields.
        request: SessionRequest,
    },
    /// A tracker that sends named blendshape weights (`{"mode":"weights"}`), not landmarks.
    Weights(WeightsHello),
    /// A tracker that sends speech (`{"mode":"audio"}`): PCM chunks the server lip-syncs.
    Audio(AudioHello),
    /// A viewer joining a session.
    Viewer {
        /// Session name.
        session: String,
        /// Also send full vertex positions each frame.
        positions: bool,
    },
    /// A request for the counters, answered with one JSON line.
    Stats,
    /// An HTTP `GET` (only `/stats` is served).
    HttpGet {
        /// The request path.
        path: String,
    },
}

/// What every tracker hello asks for: a session name and a rig, both optional.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SessionRequest {
    /// Session name to open (default: one the server makes up).
    pub session: Option<String>,
    /// Rig to drive (default: the server's default rig).
    pub rig: Option<String>,
}

impl SessionRequest {
    /// The `session` and `rig` fields as `text` reads them; a bad session name is refused.
    fn read(text: impl Fn(&str) -> Option<String>) -> Result<Self, HelloError> {
        let session = text("session");
        if let Some(s) = &session
            && !valid_session_name(s)
        {
            return Err(HelloError::BadSessionName(s.clone()));
        }
        Ok(Self {
            session,
            rig: text("rig"),
        })
    }
}

/// The hello of a tracker that sends named blendshape weights (`{"mode":"weights"}`).
#[derive(Clone, Debug, PartialEq)]
pub struct WeightsHello {
    /// Session and rig; the rig must have morph targets.
    pub request: SessionRequest,
    /// Frame rate the tracker announces, if any.
    pub rate_hz: Option<f64>,
    /// Source the tracker announces (e.g. `arkit`), if any.
    pub source: Option<String>,
    /// Where the session's frames should also be forwarded (`"forward":"vmc:127.0.0.1:39539"`),
    /// as the tracker wrote it; the server checks it (`mimic_stream::forward`).
    pub forward: Option<String>,
}

/// The hello of a tracker that sends speech (`{"mode":"audio"}`, `crate::audio`).
#[derive(Clone, Debug, PartialEq)]
pub struct AudioHello {
    /// Session and rig; the rig must have morph targets.
    pub request: SessionRequest,
    /// The stream's sample rate and channels.
    pub format: AudioFormat,
    /// Where the session's frames should also be forwarded, as for a weights session.
    pub forward: Option<String>,
}

/// Why a first line is not a valid hello.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum HelloError {
    /// Not JSON, or not an object.
    #[error(
        "the first line must be a JSON object (a recording header or a viewer/stats hello): {0}"
    )]
    NotJson(String),
    /// A recording header that fails its checks.
    #[error("bad recording header: {0}")]
    BadHeader(String),
    /// A session name that is empty, too long or has odd characters.
    #[error("bad session name `{0}`: 1 to 64 characters of A-Z a-z 0-9 _ . -")]
    BadSessionName(String),
    /// An audio hello whose stream format is refused.
    #[error("bad audio hello: {0}")]
    BadAudio(String),
    /// A `token` that is not a string, or longer than [`MAX_TOKEN_BYTES`].
    #[error("`token` must be a string of at most {MAX_TOKEN_BYTES} bytes")]
    BadToken,
    /// An object that is none of the known hellos.
    #[error(
        "unknown hello: expected `format: mimic-recording`, `mode: weights`, `mode: audio`, `type: viewer` or `type: stats`"
    )]
    Unknown,
}

/// True for a session name of 1 to 64 characters from `A-Z a-z 0-9 _ . -`.
pub fn valid_session_name(s: &str) -> bool {
    (1..=64).contains(&s.len())
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'.' | b'-'))
}

/// Parses the first line of a connection (without its newline); a `token` it carries is
/// ignored (see [`parse_hello_with_token`]).
pub fn parse_hello(line: &[u8]) -> Result<Hello, HelloError> {
    parse_hello_with_token(line).map(|(h, _)| h)
}

/// Parses the first line of a connection (without its newline) and the token it presents:
/// the `token` field of any JSON hello (removed from a tracker's header, so it never reaches a
/// recording), or `token=` in the query of `GET /stats?token=...` (removed from the path).
/// Longest token kept: [`MAX_TOKEN_BYTES`]; a longer one is refused.
pub fn parse_hello_with_token(line: &[u8]) -> Result<(Hello, Option<String>), HelloError> {
    let line = trim_end(line);
    if let Some(rest) = line.strip_prefix(b"GET ") {
        let target = rest.split(|b| *b == b' ').next().unwrap_or_default();
        let target = String::from_utf8_lossy(target).into_owned();
        let (path, query) = match target.split_once('?') {
            Some((p, q)) => (p.to_string(), Some(q)),
            None => (target.clone(), None),
        };
        let token = query
            .into_iter()
            .flat_map(|q| q.split('&'))
            .find_map(|kv| kv.strip_prefix("token="))
            .map(str::to_string);
        check_token_len(token.as_deref())?;
        return Ok((Hello::HttpGet { path }, token));
    }
    let mut v: Value =
        serde_json::from_slice(line).map_err(|e| HelloError::NotJson(e.to_string()))?;
    let Value::Object(obj) = &mut v else {
        return Err(HelloError::NotJson("not an object".into()));
    };
    let token = match obj.remove("token") {
        None => None,
        Some(Value::String(t)) => Some(t),
        Some(_) => return Err(HelloError::BadToken),
    };
    check_token_len(token.as_deref())?;
    parse_hello_value(v).map(|h| (h, token))
}

/// Longest token a hello may present (bytes).
pub const MAX_TOKEN_BYTES: usize = 256;

fn check_token_len(token: Option<&str>) -> Result<(), HelloError> {
    match token {
        Some(t) if t.len() > MAX_TOKEN_BYTES => Err(HelloError::BadToken),
        _ => Ok(()),
    }
}

/// A JSON hello (its token already taken out).
fn parse_hello_value(v: Value) -> Result<Hello, HelloError> {
    let Value::Object(obj) = &v else {
        return Err(HelloError::NotJson("not an object".into()));
    };
    if obj.contains_key("format") {
        let header: RecordingHeader =
            serde_json::from_value(v.clone()).map_err(|e| HelloError::BadHeader(e.to_string()))?;
        header.check().map_err(HelloError::BadHeader)?;
        let text = |k: &str| {
            header
                .extra
                .get(k)
                .and_then(Value::as_str)
                .map(str::to_string)
        };
        let request = SessionRequest::read(text)?;
        return Ok(Hello::Tracker {
            header: Box::new(header),
            request,
        });
    }
    if obj.get("mode").and_then(Value::as_str) == Some("weights") {
        let text = |k: &str| obj.get(k).and_then(Value::as_str).map(str::to_string);
        return Ok(Hello::Weights(WeightsHello {
            request: SessionRequest::read(text)?,
            rate_hz: obj.get("rate_hz").and_then(Value::as_f64),
            source: text("source"),
            forward: text("forward"),
        }));
    }
    if obj.get("mode").and_then(Value::as_str) == Some("audio") {
        let text = |k: &str| obj.get(k).and_then(Value::as_str).map(str::to_string);
        return Ok(Hello::Audio(AudioHello {
            request: SessionRequest::read(text)?,
            format: AudioFormat::read(obj).map_err(HelloError::BadAudio)?,
            forward: text("forward"),
        }));
    }
    match obj.get("type").and_then(Value::as_str) {
        Some("viewer") => {
            let session = obj
                .get("session")
                .and_then(Value::as_str)
                .unwrap_or_default()
                .to_string();
            if !valid_session_name(&session) {
                return Err(HelloError::BadSessionName(session));
            }
            let positions = obj
                .get("positions")
                .and_then(Value::as_bool)
                .unwrap_or(false);
            Ok(Hello::Viewer { session, positions })
        }
        Some("stats") => Ok(Hello::Stats),
        _ => Err(HelloError::Unknown),
    }
}

/// One weight frame line: `{"t_us": .., "weights": {"name": value, ..}}`.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightFrame {
    /// Capture time (µs, the tracker's clock).
    pub timestamp_us: i64,
    /// `(name, value)` pairs in line order; values as sent (finite, not yet clamped).
    pub weights: Vec<(String, f64)>,
}

/// Why a weight frame line is rejected.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum WeightFrameError {
    /// Not JSON (JSON has no NaN: a `NaN` literal lands here), not an object, or no integer `t_us`.
    #[error("{0}")]
    Json(String),
    /// `weights` missing or not an object, or a value that is not a number.
    #[error("{0}")]
    Weight(String),
}

impl WeightFrameError {
    /// The error code the session answers with.
    pub fn code(&self) -> ErrorCode {
        match self {
            WeightFrameError::Json(_) => ErrorCode::BadJson,
            WeightFrameError::Weight(_) => ErrorCode::BadWeight,
        }
    }
}

/// Parses a weight frame line (without its newline).
pub fn parse_weight_frame(line: &[u8]) -> Result<WeightFrame, WeightFrameError> {
    let v: Value = serde_json::from_slice(trim_end(line))
        .map_err(|e| WeightFrameError::Json(format!("invalid JSON: {e}")))?;
    let Value::Object(obj) = v else {
        return Err(WeightFrameError::Json(
            "a weight frame is a JSON object".into(),
        ));
    };
    let timestamp_us = obj
        .get("t_us")
        .and_then(Value::as_i64)
        .ok_or_else(|| WeightFrameError::Json("`t_us` must be an integer (µs)".into()))?;
    let Some(Value::Object(map)) = obj.get("weights") else {
        return Err(WeightFrameError::Weight(
            "`weights` must be an object of name: number".into(),
        ));
    };
    let mut weights = Vec::with_capacity(map.len());
    for (name, value) in map {
        match value.as_f64() {
            Some(x) if x.is_finite() => weights.push((name.clone(), x)),
            _ => {
                return Err(WeightFrameError::Weight(format!(
                    "weight `{name}` is {value}, not a number"
                )));
            }
        }
    }
    Ok(WeightFrame {
        timestamp_us,
        weights,
    })
}

pub(crate) fn trim_end(b: &[u8]) -> &[u8] {
    let mut end = b.len();
    while end > 0 && matches!(b[end - 1], b'\n' | b'\r') {
        end -= 1;
    }
    &b[..end]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn audio_hello_names_its_format_and_refuses_a_bad_one() {
        let h = parse_hello(br#"{"mode":"audio","session":"a","sample_rate":22050,"channels":2,"forward":"vmc:127.0.0.1:1"}"#)
            .unwrap();
        let Hello::Audio(a) = h else { panic!("{h:?}") };
        assert_eq!(a.request.session.as_deref(), Some("a"));
        assert_eq!((a.format.sample_rate, a.format.channels), (22050, 2));
        assert_eq!(a.forward.as_deref(), Some("vmc:127.0.0.1:1"));
        let e = parse_hello(br#"{"mode":"audio","sample_rate":4000}"#).unwrap_err();
        assert!(matches!(e, HelloError::BadAudio(_)) && e.to_string().contains("sample_rate"));
        let e = parse_hello(br#"{"mode":"audio","session":"a b","sample_rate":16000}"#);
        assert!(matches!(e, Err(HelloError::BadSessionName(_))));
    }

    #[test]
    fn tokens_are_taken_out_of_every_hello() {
        let (h, t) =
            parse_hello_with_token(br#"{"type":"viewer","session":"a","token":"s3cret"}"#).unwrap();
        assert!(matches!(h, Hello::Viewer { .. }));
        assert_eq!(t.as_deref(), Some("s3cret"));
        let header = br#"{"format":"mimic-recording","version":1,"layout":"ibug68","units":"m","source":"x","rate_hz":30.0,"point_count":68,"token":"k"}"#;
        let (h, t) = parse_hello_with_token(header).unwrap();
        assert_eq!(t.as_deref(), Some("k"));
        let Hello::Tracker { header, .. } = h else {
            panic!("{h:?}")
        };
        // The token never reaches the header (nor a recording written from it).
        assert!(!header.extra.contains_key("token"));
        let (h, t) = parse_hello_with_token(br#"{"mode":"weights","token":"w"}"#).unwrap();
        assert!(matches!(h, Hello::Weights(_)));
        assert_eq!(t.as_deref(), Some("w"));
        let (h, t) = parse_hello_with_token(b"GET /stats?x=1&token=q HTTP/1.0\r").unwrap();
        assert_eq!(
            h,
            Hello::HttpGet {
                path: "/stats".into()
            }
        );
        assert_eq!(t.as_deref(), Some("q"));
        let (_, t) = parse_hello_with_token(br#"{"type":"stats"}"#).unwrap();
        assert_eq!(t, None);
        assert_eq!(
            parse_hello_with_token(br#"{"type":"stats","token":7}"#),
            Err(HelloError::BadToken)
        );
        let long = format!(
            r#"{{"type":"stats","token":"{}"}}"#,
            "x".repeat(MAX_TOKEN_BYTES + 1)
        );
        assert_eq!(
            parse_hello_with_token(long.as_bytes()),
            Err(HelloError::BadToken)
        );
    }

    #[test]
    fn hello_kinds() {
        let h = br#"{"format":"mimic-recording","version":1,"layout":"ibug68","units":"m","source":"x","rate_hz":30,"session":"a","rig":"candide3"}"#;
        match parse_hello(h).unwrap() {
            Hello::Tracker { header, request } => {
                assert_eq!(header.layout, "ibug68");
                assert_eq!(request.session.as_deref(), Some("a"));
                assert_eq!(request.rig.as_deref(), Some("candide3"));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(
            parse_hello(br#"{"type":"viewer","session":"a","positions":true}"#).unwrap(),
            Hello::Viewer {
                session: "a".into(),
                positions: true
            }
        );
        assert_eq!(
            parse_hello(b"{\"type\":\"stats\"}\r\n").unwrap(),
            Hello::Stats
        );
        assert_eq!(
            parse_hello(b"GET /stats HTTP/1.1\r\n").unwrap(),
            Hello::HttpGet {
                path: "/stats".into()
            }
        );
        assert!(matches!(parse_hello(b"hello"), Err(HelloError::NotJson(_))));
        assert!(matches!(
            parse_hello(br#"{"type":"viewer","session":"a b"}"#),
            Err(HelloError::BadSessionName(_))
        ));
        assert!(matches!(
            parse_hello(br#"{"format":"mimic-recording","version":2,"layout":"x","units":"m","source":"x","rate_hz":30}"#),
            Err(HelloError::BadHeader(_))
        ));
    }

    #[test]
    fn weights_hello_and_frames() {
        assert_eq!(
            parse_hello(br#"{"mode":"weights","session":"w","rig":"ict-face","rate_hz":60}"#)
                .unwrap(),
            Hello::Weights(WeightsHello {
                request: SessionRequest {
                    session: Some("w".into()),
                    rig: Some("ict-face".into()),
                },
                rate_hz: Some(60.0),
                source: None,
                forward: None,
            })
        );
        assert!(matches!(
            parse_hello(br#"{"mode":"weights","session":"a b"}"#),
            Err(HelloError::BadSessionName(_))
        ));
        let f = parse_weight_frame(br#"{"t_us":7,"weights":{"jawOpen":0.5,"x":2}}"#).unwrap();
        assert_eq!(f.timestamp_us, 7);
        assert_eq!(
            f.weights,
            vec![("jawOpen".to_string(), 0.5), ("x".to_string(), 2.0)]
        );
        let code = |l: &[u8]| parse_weight_frame(l).unwrap_err().code();
        // JSON has no NaN: the literal is a JSON error.
        assert_eq!(
            code(br#"{"t_us":7,"weights":{"jawOpen":NaN}}"#),
            ErrorCode::BadJson
        );
        assert_eq!(code(br#"{"weights":{}}"#), ErrorCode::BadJson);
        assert_eq!(code(br#"[1]"#), ErrorCode::BadJson);
        assert_eq!(
            code(br#"{"t_us":7,"weights":{"jawOpen":"a"}}"#),
            ErrorCode::BadWeight
        );
        assert_eq!(
            code(br#"{"t_us":7,"weights":{"jawOpen":null}}"#),
            ErrorCode::BadWeight
        );
        assert_eq!(code(br#"{"t_us":7,"weights":[0.5]}"#), ErrorCode::BadWeight);
        assert_eq!(code(br#"{"t_us":7}"#), ErrorCode::BadWeight);
    }
}
