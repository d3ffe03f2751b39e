//! The thin-shell solver's settings (`shell = { ... }` in a rig's `[solver]`, see
//! [`crate::SolverSettings::shell`]): its membrane weight, region switch and the mouth and eye
//! sockets with their handling.

use serde::{Deserialize, Serialize};

/// How the thin-shell solve treats the socket vertices ([`ShellSettings::sockets`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SocketMode {
    /// Part of the one shell solve, like any free vertex.
    Free,
    /// Held still (`u = 0`), a boundary of the face's solve.
    Frozen,
    /// Left out of the face's solve (the rims become free borders), then filled by their own
    /// screened membrane solve `(L + M / l^2) u = 0` from the rim, `l` = each socket's
    /// [`Socket::decay`]: the rim's motion fades over about `l` into the head.
    #[default]
    Decay,
}

/// Largest number of sockets [`Sockets`] holds.
pub const MAX_SOCKETS: usize = 8;

/// One socket of a rig: an inclusive vertex range inside the head, and its decay length.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Socket {
    /// First and last vertex (inclusive).
    pub vertices: [u32; 2],
    /// Decay length of [`SocketMode::Decay`], rig units.
    pub decay: f64,
}

/// Up to [`MAX_SOCKETS`] sockets (`[{ vertices = [11248, 13293], decay = 3.0 }, ...]`).
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(try_from = "Vec<Socket>", into = "Vec<Socket>")]
pub struct Sockets {
    /// Sockets in use.
    len: u8,
    /// Storage; entries past `len` are unused.
    items: [Socket; MAX_SOCKETS],
}

impl Sockets {
    /// The sockets in use.
    pub fn as_slice(&self) -> &[Socket] {
        &self.items[..usize::from(self.len)]
    }

    /// Mutable access to the sockets in use.
    pub fn as_mut_slice(&mut self) -> &mut [Socket] {
        &mut self.items[..usize::from(self.len)]
    }

    /// The decay length of the first socket holding vertex `i`, if any does.
    pub fn decay_of(&self, i: u32) -> Option<f64> {
        self.as_slice()
            .iter()
            .find(|s| (s.vertices[0]..=s.vertices[1]).contains(&i))
            .map(|s| s.decay)
    }

    /// Whether no socket is set.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl TryFrom<Vec<Socket>> for Sockets {
    type Error = String;

    fn try_from(v: Vec<Socket>) -> Result<Self, Self::Error> {
        if v.len() > MAX_SOCKETS {
            return Err(format!(
                "{} sockets, at most {MAX_SOCKETS} are allowed",
                v.len()
            ));
        }
        let mut out = Sockets::default();
        for (slot, s) in out.items.iter_mut().zip(&v) {
            if s.vertices[0] > s.vertices[1] {
                return Err(format!(
                    "socket vertices [{}, {}] run backwards",
                    s.vertices[0], s.vertices[1]
                ));
            }
            *slot = *s;
        }
        out.len = v.len() as u8;
        Ok(out)
    }
}

impl From<Sockets> for Vec<Socket> {
    fn from(s: Sockets) -> Self {
        s.as_slice().to_vec()
    }
}

/// Settings of the thin-shell solver (`shell = { ... }` in a rig's `[solver]`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShellSettings {
    /// `ks`, the weight of the membrane term `u'Lu` against the bending term `u'L M^-1 L u`, in
    /// rig units^-2 (0: pure bending, thin-plate-like; large: a membrane, the cotangent Laplacian).
    pub stiffness: f64,
    /// How the sockets move.
    pub socket_mode: SocketMode,
    /// The mouth and eye sockets, the inside of the head behind the lips and lids.
    pub sockets: Sockets,
    /// Cut the one solve's columns by region, as the Laplacian does (the shell's own switch: the
    /// solver-wide [`SolverSettings::regions`](crate::SolverSettings::regions) is for the RBF
    /// and the Laplacian). Off by default: each column is already 0 at every other control, and
    /// the cut measured worse on the median (docs/quality.md, "Thin shell").
    pub regions: bool,
}

impl Default for ShellSettings {
    fn default() -> Self {
        Self {
            stiffness: 0.0,
            socket_mode: SocketMode::Decay,
            sockets: Sockets::default(),
            regions: false,
        }
    }
}

impl ShellSettings {
    /// Largest membrane weight a rig may set.
    pub const MAX_STIFFNESS: f64 = 1e6;

    /// Range checks: stiffness in [0, 1e6], every decay length finite and > 0.
    pub fn validate(&self) -> Result<(), crate::SettingError> {
        let ks = self.stiffness;
        if !(ks.is_finite() && (0.0..=Self::MAX_STIFFNESS).contains(&ks)) {
            return Err(crate::SettingError::new(
                "solver.shell.stiffness",
                ks,
                format!("must be finite, >= 0 and <= {:e}", Self::MAX_STIFFNESS),
            ));
        }
        for s in self.sockets.as_slice() {
            if !(s.decay.is_finite() && s.decay > 0.0) {
                return Err(crate::SettingError::new(
                    "solver.shell.sockets.decay",
                    s.decay,
                    "must be finite and > 0",
                ));
            }
        }
        Ok(())
    }
}
