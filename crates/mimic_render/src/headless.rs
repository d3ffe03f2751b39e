//! Headless rendering's environment.

use std::path::Path;

/// Keeps Mesa's Vulkan device-select layer from looking for a Wayland display where there can be
/// none (no absolute `XDG_RUNTIME_DIR`): its look asks libwayland, which prints
/// `error: XDG_RUNTIME_DIR is invalid or not set in the environment.` once per device listing.
/// The layer only orders the devices (a display's GPU first); without a display the renderer
/// picks its adapter alone.
///
/// # Safety
/// Writes the process environment: call it before any other thread exists (first thing in a
/// command), so that nothing reads the environment while it is written.
pub unsafe fn quiet_headless_vulkan() {
    let runtime_dir = std::env::var_os("XDG_RUNTIME_DIR");
    let no_display = runtime_dir.is_none_or(|d| !Path::new(&d).is_absolute());
    if no_display && std::env::var_os("NODEVICE_SELECT").is_none() {
        // SAFETY: the caller has started no thread yet (this function's contract).
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
}
