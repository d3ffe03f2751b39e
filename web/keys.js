// The browser viewer's keys and mouse (docs/browser.md): one table that both maps keys to what
// they do and fills the help box (`?`). Same keys as `mimic view` where they do the same.

/** [key as KeyboardEvent.key, action, what the help says]; number keys are listed once. */
export const BINDINGS = [
  [' ', 'pause', 'space: hold the frame on screen / follow the stream again'],
  ['h', 'heat', 'h: heat map of |P - P0| on / off (legend bottom right)'],
  ['p', 'pose', 'p: head rotation on / off'],
  ['r', 'reset', 'r: reset the view'],
  ['?', 'help', '?: this help on / off'],
];

/** The help box's lines. */
export const HELP = [
  'left drag: orbit · wheel: zoom · right drag: pan',
  ...BINDINGS.map(([, , what]) => what),
  "1-9: blend the rig's morph targets 1-9 in / out (0.25 s)",
];

/** What a key does: an action name, or `expression` with its index (key 1 is 0); null if none. */
export function actionFor(key) {
  if (key.length === 1 && key >= '1' && key <= '9') return { action: 'expression', index: Number(key) - 1 };
  const b = BINDINGS.find(([k]) => k === key.toLowerCase());
  return b ? { action: b[1] } : null;
}
