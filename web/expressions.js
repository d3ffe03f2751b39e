// Quick expression switching on the number keys 1-9 (docs/browser.md), as `mimic view` does it
// (crates/mimic_view/src/expressions.rs): each key blends one of the rig's first nine morph
// targets in or out, linearly over EASE_SECONDS and drawn through a smoothstep, on top of the
// live frame.

/** Seconds a number key takes to blend an expression fully in or out (mimic view's). */
export const EASE_SECONDS = 0.25;
/** Most expressions on keys (1-9). */
export const MAX_KEYS = 9;

/** The weights of the expressions on the number keys, each easing towards 0 or 1. */
export class Expressions {
  /** @param {string[]} names the rig's morph targets (the first MAX_KEYS are kept), all off */
  constructor(names) {
    this.names = names.slice(0, MAX_KEYS);
    this.target = this.names.map(() => 0);
    this.weight = this.names.map(() => 0);
  }

  /** Key k (0-based: key 1 is 0) pressed: in if it was off or going out, else out. */
  toggle(k) {
    if (k < 0 || k >= this.target.length) return false;
    this.target[k] = this.target[k] > 0.5 ? 0 : 1;
    return true;
  }

  /** Moves each weight towards its target by dt / EASE_SECONDS; whether any changed. */
  advance(dt) {
    const step = Math.max(dt / EASE_SECONDS, 0);
    let changed = false;
    for (let k = 0; k < this.weight.length; k++) {
      const w = this.weight[k];
      const t = this.target[k];
      const next = w < t ? Math.min(w + step, t) : Math.max(w - step, t);
      changed ||= next !== w;
      this.weight[k] = next;
    }
    return changed;
  }

  /** The drawn weight of expression k: smoothstep of its linear progress (0 and 1 exact). */
  eased(k) {
    const x = Math.min(Math.max(this.weight[k] ?? 0, 0), 1);
    return x * x * (3 - 2 * x);
  }

  /** Whether every expression has reached its key's state. */
  settled() {
    return this.weight.every((w, k) => w === this.target[k]);
  }

  /** The readout's part: the expressions blended in, with their weights, or the keys' hint. */
  label() {
    const on = this.names
      .map((name, k) => [name, k, this.eased(k)])
      .filter(([, , w]) => w > 0)
      .map(([name, k, w]) => `${k + 1} ${name} ${w.toFixed(2)}`);
    if (on.length) return on.join(', ');
    return this.names.length ? `keys 1-${this.names.length}: expressions` : 'no expressions on keys';
  }
}
