//! What a send asks of the server and how it paces its frames ([`SendOptions`]), and the hello
//! of a weights (or audio) session built from them.

use crate::forward::ForwardTarget;
use serde_json::Value;

/// What a send asks of the server and how it paces its frames.
#[derive(Clone, Debug)]
pub struct SendOptions {
    /// Server address (host:port).
    pub to: String,
    /// Session name to open (the server's choice without one; a Live Link subject name).
    pub session: Option<String>,
    /// Token of a server started with one.
    pub token: Option<String>,
    /// Rig the session drives (the server's default without one).
    pub rig: Option<String>,
    /// The hello's `"forward"`: the server forwards this session's frames there too.
    pub forward: Option<ForwardTarget>,
    /// Frame rate of a weights CSV without a `t_us` column.
    pub rate: f64,
    /// Speed factor of the recorded pace (2 is twice as fast).
    pub speed: f64,
    /// As fast as the connection takes frames, ignoring the pace.
    pub fast: bool,
    /// Start again from the beginning after the last frame.
    pub looping: bool,
    /// Stop after this many frames.
    pub max_frames: Option<usize>,
    /// Told each reply line of the server that is neither its welcome nor its `bye` (errors,
    /// warnings), and why the replies stop being read if they do.
    pub on_reply: fn(&str),
}

/// A weights session's hello: mode, source and rate, with the options' session, rig, forward
/// and token.
pub(super) fn weights_hello(o: &SendOptions, source: String, rate_hz: f64) -> Value {
    let hello = serde_json::json!({"mode": "weights", "source": source, "rate_hz": rate_hz});
    with_request(o, hello)
}

/// `hello` with the options' session, rig, forward and token.
pub(super) fn with_request(o: &SendOptions, mut hello: Value) -> Value {
    let extra = [
        ("session", o.session.clone()),
        ("rig", o.rig.clone()),
        ("forward", o.forward.map(|f| f.to_string())),
        ("token", o.token.clone()),
    ];
    for (key, value) in extra {
        if let Some(v) = value {
            hello[key] = Value::from(v);
        }
    }
    hello
}
