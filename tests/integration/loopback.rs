//! A `mimic serve` child on loopback and the raw-socket helpers the serve and fault tests
//! share (docs/protocol.md): viewers, JSON reply lines, recordings' lines, stats polling.
//!
//! Every socket has a read timeout and every server is stopped with SIGINT (then killed if it
//! has not exited), so the tests stop by themselves. Waiting is always for a stats condition
//! with a generous deadline, never a fixed sleep.

use crate::repo;
use mimic_stream::wire::{FrameMessage, RigMessage, ViewerMessage, decode_viewer_message};
use serde_json::Value;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// How long a test socket waits for the server before failing.
pub const READ_TIMEOUT: Duration = Duration::from_secs(60);

/// A `mimic serve` child process on 127.0.0.1 with OS-chosen ports.
pub struct Serve {
    child: Child,
    stdout: BufReader<std::process::ChildStdout>,
    /// TCP address.
    pub tcp: String,
    /// UDP address.
    pub udp: String,
    /// The `--token` it was started with (its stats requests present it).
    pub token: Option<String>,
    /// The browser endpoint's address, when started with `--http`.
    pub http: Option<String>,
    /// The loopback address stats requests come from (`None`: the default, 127.0.0.1); a test
    /// that fills one address's share polls from another, so its polls never take (nor are
    /// refused for) the slots kept for stats.
    pub stats_from: Option<String>,
}

impl Serve {
    /// Starts `mimic serve --listen 127.0.0.1:0 ARGS` and reads where it listens.
    pub fn start(args: &[&str]) -> Serve {
        Self::start_with_file_limit(args, None)
    }

    /// [`Serve::start`] with the child's open-file limit (soft and hard) set to `nofile`.
    pub fn start_with_file_limit(args: &[&str], nofile: Option<u64>) -> Serve {
        let mut command = Command::new(env!("CARGO_BIN_EXE_mimic"));
        command
            .args(["serve", "--listen", "127.0.0.1:0"])
            .args(args)
            .current_dir(repo())
            .env_remove("RUST_LOG")
            .env_remove("MIMIC_TOKEN")
            .stdout(Stdio::piped())
            .stderr(Stdio::null());
        if let Some(n) = nofile {
            use std::os::unix::process::CommandExt;
            let limit = libc::rlimit {
                rlim_cur: n as libc::rlim_t,
                rlim_max: n as libc::rlim_t,
            };
            // SAFETY: setrlimit is async-signal-safe and reads only `limit`, a copy owned by
            // the closure.
            unsafe {
                command.pre_exec(move || {
                    if libc::setrlimit(libc::RLIMIT_NOFILE, &limit) == 0 {
                        Ok(())
                    } else {
                        Err(std::io::Error::last_os_error())
                    }
                });
            }
        }
        let mut child = command.spawn().expect("spawn mimic serve");
        let token = args
            .iter()
            .position(|a| *a == "--token")
            .map(|k| args[k + 1].to_string());
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let mut first = String::new();
        stdout.read_line(&mut first).unwrap();
        // "mimic serve: tcp ADDR udp ADDR rigs [...]"
        let words: Vec<&str> = first.split_whitespace().collect();
        assert!(
            words.len() >= 6 && words[2] == "tcp",
            "serve said: {first:?}"
        );
        let http = words
            .iter()
            .position(|w| *w == "http")
            .and_then(|k| words.get(k + 1))
            .map(|s| s.to_string());
        Serve {
            child,
            stdout,
            tcp: words[3].to_string(),
            udp: words[5].to_string(),
            token,
            http,
            stats_from: None,
        }
    }

    /// Sends SIGINT (Ctrl-C), waits for a clean exit and returns the rest of stdout.
    pub fn stop(mut self) -> String {
        let pid = self.child.id().to_string();
        let ok = Command::new("kill").args(["-INT", &pid]).status().unwrap();
        assert!(ok.success());
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                assert!(status.success(), "mimic serve exited with {status}");
                break;
            }
            assert!(
                Instant::now() < deadline,
                "mimic serve did not stop on SIGINT"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        let mut rest = String::new();
        self.stdout.read_to_string(&mut rest).unwrap();
        rest
    }

    /// The server's process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// The server's counters (a stats request).
    pub fn stats(&self) -> Value {
        let mut s = match &self.stats_from {
            Some(from) => connect_from(from, &self.tcp),
            None => connect(&self.tcp),
        };
        let mut hello = serde_json::json!({"type": "stats"});
        if let Some(t) = &self.token {
            hello["token"] = Value::from(t.as_str());
        }
        s.write_all(format!("{hello}\n").as_bytes()).unwrap();
        let mut line = String::new();
        BufReader::new(s).read_line(&mut line).unwrap();
        serde_json::from_str(&line).unwrap()
    }

    /// Polls the stats until `ok` holds (at most 20 s).
    pub fn wait_for(&self, what: &str, ok: impl Fn(&Value) -> bool) -> Value {
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            let s = self.stats();
            if ok(&s) {
                return s;
            }
            assert!(
                Instant::now() < deadline,
                "timed out waiting for {what}: {s}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A TCP connection with a read timeout.
pub fn connect(addr: &str) -> TcpStream {
    let s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(READ_TIMEOUT)).unwrap();
    s
}

/// A TCP connection from source address `from` (any of 127.0.0.0/8 on Linux) with a read
/// timeout.
pub fn connect_from(from: &str, addr: &str) -> TcpStream {
    use socket2::{Domain, Socket, Type};
    let to: std::net::SocketAddr = addr.parse().unwrap();
    let src: std::net::SocketAddr = format!("{from}:0").parse().unwrap();
    let s = Socket::new(Domain::IPV4, Type::STREAM, None).unwrap();
    s.bind(&src.into()).unwrap();
    s.connect(&to.into()).unwrap();
    let s: TcpStream = s.into();
    s.set_read_timeout(Some(READ_TIMEOUT)).unwrap();
    s
}

/// Opens a viewer on `session`.
pub fn viewer(addr: &str, session: &str, positions: bool) -> TcpStream {
    let mut s = connect(addr);
    let hello =
        format!("{{\"type\":\"viewer\",\"session\":\"{session}\",\"positions\":{positions}}}\n");
    s.write_all(hello.as_bytes()).unwrap();
    s
}

/// One viewer message: u32 LE length, then kind and payload.
pub fn read_message(s: &mut impl Read) -> Option<ViewerMessage> {
    let mut len = [0u8; 4];
    s.read_exact(&mut len).ok()?;
    let mut body = vec![0u8; u32::from_le_bytes(len) as usize];
    s.read_exact(&mut body).unwrap();
    Some(decode_viewer_message(body[0], &body[1..]).unwrap())
}

/// What a viewer saw of one session.
#[derive(Default)]
pub struct Seen {
    pub session: Option<Value>,
    pub rig: Option<RigMessage>,
    pub frames: Vec<FrameMessage>,
    pub end: Option<Value>,
}

/// Reads one session (session, rig, frames) up to its end message.
pub fn read_session(s: &mut TcpStream) -> Seen {
    let mut seen = Seen::default();
    while let Some(m) = read_message(s) {
        match m {
            ViewerMessage::Session(v) => seen.session = Some(v),
            ViewerMessage::Rig(r) => seen.rig = Some(r),
            ViewerMessage::Frame(f) => seen.frames.push(f),
            ViewerMessage::End(v) => {
                seen.end = Some(v);
                break;
            }
            ViewerMessage::Error(e) => panic!("viewer error {e}"),
        }
    }
    seen
}

/// One JSON line.
pub fn read_json_line(r: &mut impl BufRead) -> Value {
    let mut line = String::new();
    r.read_line(&mut line).unwrap();
    serde_json::from_str(&line).unwrap_or_else(|e| panic!("{e}: {line:?}"))
}

/// The server closed the connection: end of stream, or a reset if it left our bytes unread.
pub fn assert_closed(r: &mut impl BufRead) {
    match r.read_line(&mut String::new()) {
        Ok(0) => {}
        Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => {}
        other => panic!("connection not closed: {other:?}"),
    }
}

/// The recording's header line with a session name added.
pub fn header_with_session(recording: &str, session: &str) -> String {
    let text = std::fs::read_to_string(repo().join(recording)).unwrap();
    let mut h: Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
    h["session"] = Value::from(session);
    format!("{h}\n")
}

/// The recording's frame lines, each with its newline.
pub fn frame_lines(recording: &str) -> Vec<String> {
    let text = std::fs::read_to_string(repo().join(recording)).unwrap();
    text.lines().skip(1).map(|l| format!("{l}\n")).collect()
}

impl Serve {
    /// The stats entry of the session named `name` with id `id` (0: the newest of that name).
    pub fn session(stats: &Value, name: &str, id: u64) -> Value {
        stats["sessions"]
            .as_array()
            .into_iter()
            .flatten()
            .filter(|s| s["name"] == name && (id == 0 || s["id"] == id))
            .max_by_key(|s| s["id"].as_u64())
            .cloned()
            .unwrap_or(Value::Null)
    }

    /// Polls until session `name` (newest of that name) satisfies `ok`; returns its entry.
    pub fn wait_for_session(&self, name: &str, what: &str, ok: impl Fn(&Value) -> bool) -> Value {
        let s = self.wait_for(what, |s| {
            let x = Serve::session(s, name, 0);
            !x.is_null() && ok(&x)
        });
        Serve::session(&s, name, 0)
    }
}
