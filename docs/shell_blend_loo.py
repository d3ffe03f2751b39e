#!/usr/bin/env python3
"""Leave-one-out choice of the RBF rig's thin-shell blend on the eight shipped ICT expressions.

The 38-FDP RBF with a share of the thin-shell basis blended into its regions
(`solver.shell_blend`, docs/quality.md "RBF and thin shell by region"). Runs `mimic eval --json`
once per setting of a grid of shares (top, middle, bottom; the shell keeps the rig's own settings,
those of `--solver shell`; `0,0,0` is the plain RBF), then for each shape picks the setting with the
lowest mean ratio over the other seven and reports that shape's ratio under it (held out).
Usage, from the repository root after `cargo build --release -p mimic`:
    python3 docs/shell_blend_loo.py [path/to/mimic] [rig] [extra eval args...]
(rig: ict-face by default; `top` runs the top share 0.5 as well, as measured for ict-face.)
"""
import itertools
import json
import statistics
import subprocess
import sys

MIMIC = sys.argv[1] if len(sys.argv) > 1 else "target/release/mimic"
RIG = sys.argv[2] if len(sys.argv) > 2 else "ict-face"
EXTRA = [a for a in sys.argv[3:] if a != "top"]
S = "configs/meshes/ict-facekit"
SHAPES = ["jawOpen", "mouthSmile_L", "mouthSmile_R", "browInnerUp_L", "browInnerUp_R",
          "eyeBlink_L", "eyeBlink_R", "mouthFunnel"]
GRID = {
    "top": ["0", "0.5"] if "top" in sys.argv[3:] else ["0"],
    "middle": ["0", "0.25", "0.5", "0.75", "1"],
    "bottom": ["0", "0.25", "0.5", "0.75", "1"],
}


def run(args):
    cmd = [MIMIC, "eval", "--rig", RIG, "--json", *args, *EXTRA,
           "--shapes", *[f"{S}/{s}.obj" for s in SHAPES]]
    out = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    return [s["all"]["ratio"] for s in out["shapes"]], out["noise_gain"]


def show(label, ratios, gain):
    print(f"{label:<20} median {statistics.median(ratios):.3f} mean {statistics.mean(ratios):.3f} "
          f"max {max(ratios):.3f} gain {gain:.2f}  " + " ".join(f"{r:.3f}" for r in ratios),
          flush=True)


def main():
    rows = []
    for top, mid, bot in itertools.product(*GRID.values()):
        ratios, gain = run(["--shell-blend", f"{top},{mid},{bot}"])
        label = f"blend {top},{mid},{bot}"
        rows.append((label, ratios, gain))
        show(label, ratios, gain)
    held = []
    for h, name in enumerate(SHAPES):
        best = min(rows, key=lambda r: statistics.mean(x for i, x in enumerate(r[1]) if i != h))
        held.append(best[1][h])
        print(f"held out {name:<14} chosen on the other seven: {best[0]:<20} ratio {best[1][h]:.3f}")
    print(f"leave-one-out: median {statistics.median(held):.3f}, mean {statistics.mean(held):.3f}, "
          f"max {max(held):.3f}")


if __name__ == "__main__":
    main()
