//! Key bindings of `mimic view`: one table that both maps keys to actions and prints the help.

use winit::keyboard::{Key, NamedKey};

/// What a key does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Pause or resume.
    PlayPause,
    /// Move this many frames (a local replay; pauses nothing).
    Step(isize),
    /// Back to the first frame.
    Restart,
    /// Switch between the RBF and Laplacian bases (a local replay).
    ToggleSolver,
    /// Lit skin / displacement heat map.
    ToggleHeat,
    /// Turn the head with the performer's head rotation, or not.
    TogglePose,
    /// Back to the front view.
    ResetCamera,
    /// Blend the rig's morph target on this number key (0: key 1) in or out.
    Expression(usize),
    /// The key help on screen, or not.
    ToggleHelp,
    /// The morph-target weights as bars, or not.
    ToggleWeights,
    /// The heat map's colour legend, or not.
    ToggleLegend,
    /// Close the window.
    Quit,
}

/// The key bindings: key as typed, action, and what the help says.
pub const BINDINGS: &[(&str, Action, &str)] = &[
    ("space", Action::PlayPause, "play / pause"),
    ("left", Action::Step(-1), "one frame back (paused or not)"),
    ("right", Action::Step(1), "one frame on"),
    ("pageup", Action::Step(-30), "30 frames back"),
    ("pagedown", Action::Step(30), "30 frames on"),
    ("home", Action::Restart, "first frame"),
    (
        "s",
        Action::ToggleSolver,
        "solver: RBF <-> Laplacian (both bases kept)",
    ),
    ("h", Action::ToggleHeat, "heat map of |P - P0| on / off"),
    ("p", Action::TogglePose, "head rotation on / off"),
    ("r", Action::ResetCamera, "reset the camera"),
    (
        "w",
        Action::ToggleWeights,
        "morph-target weights as bars on / off",
    ),
    ("l", Action::ToggleLegend, "heat map colour legend on / off"),
    ("?", Action::ToggleHelp, "this key help on / off (also F1)"),
    ("f1", Action::ToggleHelp, ""),
    ("1", Action::Expression(0), "morph target 1 in / out"),
    ("2", Action::Expression(1), "morph target 2 in / out"),
    ("3", Action::Expression(2), "morph target 3 in / out"),
    ("4", Action::Expression(3), "morph target 4 in / out"),
    ("5", Action::Expression(4), "morph target 5 in / out"),
    ("6", Action::Expression(5), "morph target 6 in / out"),
    ("7", Action::Expression(6), "morph target 7 in / out"),
    ("8", Action::Expression(7), "morph target 8 in / out"),
    ("9", Action::Expression(8), "morph target 9 in / out"),
    ("q", Action::Quit, "quit (also Esc)"),
    ("escape", Action::Quit, ""),
];

/// Key and mouse help, as printed at start and by `mimic view --help`.
pub const HELP: &str = "\
Keys and mouse:
  left drag        orbit the camera        wheel        zoom
  right drag       scrub (drag across the window = the whole recording)
  space            play / pause            left/right   one frame back / on
  pageup/pagedown  30 frames back / on     home         first frame
  s                solver RBF <-> Laplacian (local replay; both bases kept)
  h                heat map of |P - P0|    p            head rotation on / off
  r                reset the camera        q, esc       quit
  1 - 9            blend the rig's morph targets 1-9 in / out (eased over 0.25 s; local replay)
  w                weights as bars         l            heat map legend on / off
  ?, F1            this help on screen
On screen and in the title bar: rig, solver, frame, fps, latency (local: step to present;
--connect: arrival to present), the last frame's state.";

/// Name of a key in [`BINDINGS`]: a named key in lower case, or the character typed.
fn key_name(key: &Key) -> Option<String> {
    match key {
        Key::Named(NamedKey::Space) => Some("space".into()),
        Key::Named(NamedKey::ArrowLeft) => Some("left".into()),
        Key::Named(NamedKey::ArrowRight) => Some("right".into()),
        Key::Named(NamedKey::PageUp) => Some("pageup".into()),
        Key::Named(NamedKey::PageDown) => Some("pagedown".into()),
        Key::Named(NamedKey::Home) => Some("home".into()),
        Key::Named(NamedKey::Escape) => Some("escape".into()),
        Key::Named(NamedKey::F1) => Some("f1".into()),
        Key::Character(c) => Some(c.to_lowercase()),
        _ => None,
    }
}

/// The action of a key press, if it has one.
pub fn action_for(key: &Key) -> Option<Action> {
    let name = key_name(key)?;
    action_named(&name)
}

/// The action bound to a key name of [`BINDINGS`] (also what `--headless-keys` takes).
pub fn action_named(name: &str) -> Option<Action> {
    BINDINGS
        .iter()
        .find(|(k, _, _)| k.eq_ignore_ascii_case(name))
        .map(|(_, a, _)| *a)
}

/// The actions of `--headless-keys` names, in order; a name bound to nothing is the error.
pub fn actions_named(names: &[String]) -> Result<Vec<Action>, crate::ViewError> {
    names
        .iter()
        .map(|k| {
            action_named(k.trim()).ok_or_else(|| {
                crate::ViewError::Option(format!(
                    "--headless-keys: no key `{k}` (see mimic view --help)"
                ))
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use winit::keyboard::SmolStr;

    #[test]
    fn keys_map_to_their_actions() {
        assert_eq!(
            action_for(&Key::Named(NamedKey::Space)),
            Some(Action::PlayPause)
        );
        assert_eq!(
            action_for(&Key::Named(NamedKey::ArrowLeft)),
            Some(Action::Step(-1))
        );
        assert_eq!(
            action_for(&Key::Character(SmolStr::new("S"))),
            Some(Action::ToggleSolver)
        );
        assert_eq!(
            action_for(&Key::Character(SmolStr::new("h"))),
            Some(Action::ToggleHeat)
        );
        assert_eq!(
            action_for(&Key::Named(NamedKey::Escape)),
            Some(Action::Quit)
        );
        assert_eq!(
            action_for(&Key::Character(SmolStr::new("3"))),
            Some(Action::Expression(2))
        );
        assert_eq!(
            action_for(&Key::Character(SmolStr::new("?"))),
            Some(Action::ToggleHelp)
        );
        assert_eq!(
            action_for(&Key::Named(NamedKey::F1)),
            Some(Action::ToggleHelp)
        );
        assert_eq!(
            action_for(&Key::Character(SmolStr::new("W"))),
            Some(Action::ToggleWeights)
        );
        assert_eq!(action_for(&Key::Character(SmolStr::new("0"))), None);
        assert_eq!(action_for(&Key::Character(SmolStr::new("z"))), None);
        assert_eq!(action_for(&Key::Named(NamedKey::Tab)), None);
    }

    #[test]
    fn every_binding_is_in_the_help() {
        for (key, _, what) in BINDINGS {
            let shown = match *key {
                "escape" => "esc",
                "f1" => "F1",
                // The number keys are listed as one range.
                k if k.len() == 1 && k.chars().all(|c| c.is_ascii_digit()) => "1 - 9",
                k => k,
            };
            assert!(HELP.contains(shown), "help lacks key {key}");
            assert!(what.is_empty() || !what.trim().is_empty());
        }
        // Each key is bound once.
        for (i, (a, _, _)) in BINDINGS.iter().enumerate() {
            assert!(
                BINDINGS[i + 1..].iter().all(|(b, _, _)| a != b),
                "{a} twice"
            );
        }
    }
}
