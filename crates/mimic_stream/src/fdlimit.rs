//! The process's open-file limit (`RLIMIT_NOFILE`): raised toward the hard limit when a server
//! starts ([`raise`]), and read ([`soft`]) to keep the browser endpoint's connection budget below
//! it with descriptors to spare for trackers, viewers, stats and recordings.

/// The soft limit raised to the hard limit (capped at 1 048 576); returns the soft limit now in
/// force, or `None` where it cannot be read (not Unix).
pub fn raise() -> Option<u64> {
    imp::raise()
}

/// The soft open-file limit, or `None` where it cannot be read.
pub fn soft() -> Option<u64> {
    imp::soft()
}

#[cfg(unix)]
#[allow(
    clippy::unnecessary_cast,
    reason = "rlim_t is u64 on Linux but not on every Unix"
)]
mod imp {
    /// Highest soft limit asked for (a hard limit of "unlimited" is not taken literally).
    const CEILING: u64 = 1 << 20;

    fn get() -> Option<libc::rlimit> {
        let mut r = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: `r` is a valid, writable rlimit for the call's duration.
        let ok = unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut r) } == 0;
        ok.then_some(r)
    }

    pub(super) fn soft() -> Option<u64> {
        get().map(|r| r.rlim_cur as u64)
    }

    pub(super) fn raise() -> Option<u64> {
        let r = get()?;
        let want = (r.rlim_max as u64).min(CEILING);
        if (r.rlim_cur as u64) < want {
            let new = libc::rlimit {
                rlim_cur: want as libc::rlim_t,
                rlim_max: r.rlim_max,
            };
            // SAFETY: `new` is a valid rlimit, read by the call only.
            if unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &new) } != 0 {
                tracing::debug!("open-file limit not raised from {}", r.rlim_cur);
            }
        }
        soft()
    }
}

#[cfg(not(unix))]
mod imp {
    pub(super) fn soft() -> Option<u64> {
        None
    }

    pub(super) fn raise() -> Option<u64> {
        None
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn raising_never_lowers_the_soft_limit() {
        let before = super::soft();
        let after = super::raise();
        if let (Some(b), Some(a)) = (before, after) {
            assert!(a >= b, "{b} -> {a}");
        }
    }
}
