//! Live out (`mimic serve --forward vmc:ADDR | livelink:ADDR`, or a tracker hello's
//! `"forward"`): each accepted frame of a session, as the 52 ARKit blendshape curves and the head
//! rotation, sent on to a VMC receiver (OSC bundles, [`vmc`]) or a Live Link Face receiver (its
//! UDP packet, `mimic_trackers::livelink::encode_packet`). Weights and Live Link sessions
//! forward what drove the rig (Live Link: the curves as they came); landmark sessions the
//! blendshape fit of their controls.
//!
//! Bounded: every send is non-blocking; one the socket would block on (or that fails) is
//! dropped and counted (`forward_dropped` in `/stats`), never waited for.
//!
//! Never an open relay: the operator's `--forward` targets may be any address (warned about
//! beyond loopback), a tracker's own `"forward"` only one of those addresses (address and port)
//! or one the operator allowed (`--forward-allow ADDR:PORT`): not any loopback port, which would
//! let a tracker reach a local-only service (a DNS resolver on 127.0.0.2:53, say).

pub mod vmc;

use glam::Quat;
use mimic_retarget::WeightMap;
use mimic_retarget::gaze::{EYE_LOOK_NAMES, EyeGaze, eye_look_weights};
use mimic_trackers::livelink::{
    BLENDSHAPES, CURVE_NAMES, CURVES, HEAD_YAW, LEFT_EYE_YAW, LiveLinkPacket, curve_index,
    encode_packet, head_angles,
};
use mimic_trackers::namemap::{Inverse, Mapping, NameMap};
use std::net::{SocketAddr, UdpSocket};
use std::str::FromStr;
use std::sync::Arc;

/// What a forward target receives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ForwardKind {
    /// VMC (OSC over UDP).
    Vmc,
    /// Live Link Face UDP packets.
    LiveLink,
}

/// One place frames are forwarded to: `vmc:ADDR` or `livelink:ADDR`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ForwardTarget {
    /// The protocol.
    pub kind: ForwardKind,
    /// The receiver's UDP address.
    pub addr: SocketAddr,
}

/// A forward target that does not parse.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error("forward target `{0}`: expected vmc:HOST:PORT or livelink:HOST:PORT (an IP address)")]
pub struct ForwardTargetError(pub String);

impl FromStr for ForwardTarget {
    type Err = ForwardTargetError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || ForwardTargetError(s.to_string());
        let (kind, addr) = s.split_once(':').ok_or_else(bad)?;
        let kind = match kind.to_ascii_lowercase().as_str() {
            "vmc" => ForwardKind::Vmc,
            "livelink" => ForwardKind::LiveLink,
            _ => return Err(bad()),
        };
        let addr = addr.parse().map_err(|_| bad())?;
        Ok(Self { kind, addr })
    }
}

impl std::fmt::Display for ForwardTarget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kind = match self.kind {
            ForwardKind::Vmc => "vmc",
            ForwardKind::LiveLink => "livelink",
        };
        write!(f, "{kind}:{}", self.addr)
    }
}

/// Why a tracker's `"forward"` is refused.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum ForwardRefusal {
    /// It does not parse.
    #[error(transparent)]
    Parse(#[from] ForwardTargetError),
    /// Not an address (and port) the operator forwards to or allowed.
    #[error(
        "forward to {0}: a tracker may forward only to the addresses and ports `mimic serve --forward` or `--forward-allow` lists"
    )]
    NotAllowed(SocketAddr),
}

/// The server's forwarding settings.
#[derive(Clone, Debug, Default)]
pub struct ForwardSettings {
    /// Where every session's frames go (`--forward`).
    pub targets: Vec<ForwardTarget>,
    /// Addresses (and ports) besides the `targets`' a tracker's own `"forward"` may name
    /// (`--forward-allow`).
    pub allow: Vec<SocketAddr>,
    /// ARKit curves <-> the rig's morph targets (`configs/namemaps/arkit.toml`): its inverse
    /// reads a rig's weights back as curves.
    pub namemap: Arc<NameMap>,
    /// VMC blendshape names from ARKit names (`--forward-vmc-names`, e.g.
    /// `configs/namemaps/vrm.toml`); `None`: the ARKit names.
    pub vmc_names: Option<Arc<NameMap>>,
}

impl ForwardSettings {
    /// A tracker's `"forward"` value checked: the address and port of one of the operator's
    /// [`Self::targets`] or one in [`Self::allow`].
    pub fn check_session_target(&self, text: &str) -> Result<ForwardTarget, ForwardRefusal> {
        let t: ForwardTarget = text.parse()?;
        let same = |a: &SocketAddr| {
            a.ip().to_canonical() == t.addr.ip().to_canonical() && a.port() == t.addr.port()
        };
        if self.allow.iter().any(same) || self.targets.iter().any(|x| same(&x.addr)) {
            Ok(t)
        } else {
            Err(ForwardRefusal::NotAllowed(t.addr))
        }
    }
}

/// What one forward of a frame did: datagrams sent and dropped.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sent {
    /// Datagrams handed to the socket.
    pub sent: u64,
    /// Datagrams dropped (the socket would block, or the send failed).
    pub dropped: u64,
}

/// A session's forwarding: one non-blocking socket per target, the rig's weights read back as
/// ARKit curves, the VMC names.
#[derive(Debug)]
pub struct Forwarder {
    targets: Vec<(ForwardTarget, UdpSocket)>,
    namemap: Arc<NameMap>,
    /// Rig weights -> the 52 curves (built for the session's rig).
    inverse: Option<Inverse>,
    /// VMC names of the 52 curves and the mapping onto them.
    vmc: Option<(Arc<NameMap>, Mapping)>,
    vmc_names: Vec<String>,
    vmc_values: Vec<f32>,
    curves: [f32; CURVES],
    subject: String,
    buf: Vec<u8>,
    /// The first forwarded frame's time: Live Link frame times count from it.
    first_us: Option<i64>,
    /// The gaze of the next [`Forwarder::weights`] frame (left, right), if the tracker gives one.
    gaze: Option<[EyeGaze; 2]>,
}

/// Writes gaze `g` into Live Link `curves`: ARKit's eight `eyeLook*` weights by name, and each
/// eye's yaw and pitch (radians, as the head's angles) into `LeftEyeYaw` .. `RightEyePitch`.
fn put_gaze(g: [EyeGaze; 2], curves: &mut [f32; CURVES]) {
    // Where the eight eyeLook curves are, found once (not per forwarded frame).
    static LOOK_CURVES: std::sync::OnceLock<[Option<usize>; 8]> = std::sync::OnceLock::new();
    let at = LOOK_CURVES.get_or_init(|| EYE_LOOK_NAMES.map(curve_index));
    let mut look = [0.0; 8];
    eye_look_weights(g, &mut look);
    for (k, w) in at.iter().zip(look) {
        if let Some(k) = k {
            curves[*k] = w;
        }
    }
    for (eye, e) in g.iter().enumerate() {
        curves[LEFT_EYE_YAW + 3 * eye] = e.yaw;
        curves[LEFT_EYE_YAW + 3 * eye + 1] = e.pitch;
    }
}

/// A non-blocking UDP socket to send to `addr` from (loopback for a loopback receiver).
fn socket_for(addr: SocketAddr) -> std::io::Result<UdpSocket> {
    let bind: SocketAddr = match (addr.is_ipv4(), addr.ip().is_loopback()) {
        (true, true) => "127.0.0.1:0",
        (true, false) => "0.0.0.0:0",
        (false, true) => "[::1]:0",
        (false, false) => "[::]:0",
    }
    .parse()
    .map_err(std::io::Error::other)?;
    let s = UdpSocket::bind(bind)?;
    s.set_nonblocking(true)?;
    Ok(s)
}

impl Forwarder {
    /// The forwarding of session `subject` on a rig whose morph targets are `rig_names` (none:
    /// only curves given as they came can be forwarded) to `targets`; `None` without targets.
    pub fn new(
        settings: &ForwardSettings,
        targets: &[ForwardTarget],
        rig_names: &[String],
        subject: &str,
    ) -> std::io::Result<Option<Self>> {
        if targets.is_empty() {
            return Ok(None);
        }
        let mut socks = Vec::with_capacity(targets.len());
        for t in targets {
            socks.push((*t, socket_for(t.addr)?));
        }
        let inverse = (!rig_names.is_empty()).then(|| {
            let rig = WeightMap::new(rig_names);
            let mut probe = vec![0.0f32; rig_names.len()];
            settings
                .namemap
                .inverse(&CURVE_NAMES[..BLENDSHAPES], |t: &str| {
                    rig.apply([(t, 1.0)], &mut probe);
                    probe.iter().position(|w| *w > 0.0)
                })
        });
        // ARKit's own spelling (`jawOpen`): the stream's name with its first letter lower case.
        let arkit: Vec<String> = CURVE_NAMES[..BLENDSHAPES]
            .iter()
            .map(|n| {
                let mut c = n.chars();
                c.next()
                    .map(|f| f.to_ascii_lowercase().to_string() + c.as_str())
                    .unwrap_or_default()
            })
            .collect();
        let (vmc, vmc_names) = match &settings.vmc_names {
            Some(map) => {
                let refs: Vec<&str> = arkit.iter().map(String::as_str).collect();
                let m = map.resolve(&refs);
                let names = m.targets.clone();
                (Some((map.clone(), m)), names)
            }
            None => (None, arkit),
        };
        Ok(Some(Self {
            targets: socks,
            namemap: settings.namemap.clone(),
            inverse,
            vmc_values: vec![0.0; vmc_names.len()],
            vmc,
            vmc_names,
            curves: [0.0; CURVES],
            subject: subject.to_string(),
            buf: Vec::new(),
            first_us: None,
            gaze: None,
        }))
    }

    /// The targets, for logs.
    pub fn targets(&self) -> impl Iterator<Item = &ForwardTarget> {
        self.targets.iter().map(|(t, _)| t)
    }

    /// Forwards a frame given as the rig's weights (read back as ARKit curves) and the head
    /// rotation.
    pub fn weights(&mut self, t_us: i64, rig_weights: &[f32], head: Quat) -> Sent {
        match &self.inverse {
            Some(inv) => inv.apply(&self.namemap, rig_weights, &mut self.curves[..BLENDSHAPES]),
            None => self.curves[..BLENDSHAPES].fill(0.0),
        }
        self.curves[BLENDSHAPES..].fill(0.0);
        self.curves[HEAD_YAW..HEAD_YAW + 3].copy_from_slice(&head_angles(head));
        if let Some(g) = self.gaze {
            put_gaze(g, &mut self.curves);
        }
        self.send(t_us, head)
    }

    /// The gaze (left, right eye) the next [`Forwarder::weights`] frames carry: the eight
    /// `eyeLook*` curves (in place of the rig's) and the eyes' yaw and pitch; `None`: none.
    pub fn set_gaze(&mut self, gaze: Option<[EyeGaze; 2]>) {
        self.gaze = gaze;
    }

    /// Forwards a frame given as the 61 Live Link curves (as they came) and the head rotation.
    pub fn curves(&mut self, t_us: i64, curves: &[f32; CURVES], head: Quat) -> Sent {
        self.curves = *curves;
        self.send(t_us, head)
    }

    /// Sends the current curves to every target.
    fn send(&mut self, t_us: i64, head: Quat) -> Sent {
        let mut out = Sent::default();
        for (t, sock) in &self.targets {
            match t.kind {
                ForwardKind::Vmc => {
                    match &self.vmc {
                        Some((map, m)) => {
                            m.apply(map, &self.curves[..BLENDSHAPES], &mut self.vmc_values)
                        }
                        None => self.vmc_values.copy_from_slice(&self.curves[..BLENDSHAPES]),
                    }
                    vmc::encode_frame(&self.vmc_names, &self.vmc_values, head, &mut self.buf);
                }
                ForwardKind::LiveLink => {
                    // 60 fps frame times from the first forwarded frame (a recording's clock
                    // may be Unix time, past an i32 of frames).
                    let t0 = *self.first_us.get_or_insert(t_us);
                    let frames = t_us.saturating_sub(t0).max(0) as f64 * 60.0 / 1e6;
                    self.buf = encode_packet(&LiveLinkPacket {
                        device_id: "00000000-0000-4000-8000-6d696d696373".into(),
                        subject: self.subject.clone(),
                        frame: frames.floor().min(f64::from(i32::MAX)) as i32,
                        subframe: frames.fract() as f32,
                        rate_numerator: 60,
                        rate_denominator: 1,
                        curves: self.curves,
                    });
                }
            }
            match sock.send_to(&self.buf, t.addr) {
                Ok(_) => out.sent += 1,
                Err(_) => out.dropped += 1,
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gaze_goes_out_as_eye_look_curves_and_eye_angles() {
        let mut curves = [0.0; CURVES];
        // The left eye looks toward the subject's left (out) and up, the right one down.
        let g = [
            EyeGaze {
                yaw: 0.2,
                pitch: 0.1,
            },
            EyeGaze {
                yaw: 0.0,
                pitch: -0.2,
            },
        ];
        put_gaze(g, &mut curves);
        let at = |name: &str| curves[CURVE_NAMES.iter().position(|c| *c == name).unwrap()];
        assert!(at("EyeLookOutLeft") > 0.3 && at("EyeLookUpLeft") > 0.1);
        assert_eq!((at("EyeLookInLeft"), at("EyeLookDownLeft")), (0.0, 0.0));
        assert!(at("EyeLookDownRight") > 0.3 && at("EyeLookOutRight") == 0.0);
        assert_eq!((at("LeftEyeYaw"), at("LeftEyePitch")), (0.2, 0.1));
        assert_eq!((at("RightEyeYaw"), at("RightEyePitch")), (0.0, -0.2));
    }

    #[test]
    fn targets_parse_and_sessions_may_forward_only_to_loopback_or_allowed() {
        let t: ForwardTarget = "vmc:127.0.0.1:39539".parse().unwrap();
        assert_eq!(t.kind, ForwardKind::Vmc);
        assert_eq!(t.to_string(), "vmc:127.0.0.1:39539");
        let t: ForwardTarget = "livelink:[::1]:11111".parse().unwrap();
        assert_eq!(t.kind, ForwardKind::LiveLink);
        for bad in [
            "vmc",
            "osc:127.0.0.1:1",
            "vmc:localhost:1",
            "livelink:1.2.3.4",
        ] {
            assert!(bad.parse::<ForwardTarget>().is_err(), "{bad}");
        }
        let mut s = ForwardSettings::default();
        // Not even loopback without the operator's word: any local port is a local service.
        for refused in [
            "vmc:127.0.0.1:39539",
            "vmc:127.0.0.2:53",
            "vmc:192.168.1.5:39539",
        ] {
            assert_eq!(
                s.check_session_target(refused),
                Err(ForwardRefusal::NotAllowed(refused[4..].parse().unwrap()))
            );
        }
        s.allow.push("192.168.1.5:39539".parse().unwrap());
        assert!(s.check_session_target("vmc:192.168.1.5:39539").is_ok());
        assert!(s.check_session_target("livelink:192.168.1.5:39539").is_ok());
        assert!(s.check_session_target("vmc:192.168.1.5:39540").is_err());
        // The operator's own targets are allowed to trackers too.
        s.targets.push("livelink:127.0.0.1:11111".parse().unwrap());
        assert!(s.check_session_target("vmc:127.0.0.1:11111").is_ok());
        assert!(s.check_session_target("vmc:127.0.0.2:11111").is_err());
    }
}
