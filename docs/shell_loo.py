#!/usr/bin/env python3
"""Leave-one-out choice of the thin-shell settings on the eight shipped ICT expressions.

Runs `mimic eval --json` once per setting of a small grid (membrane weight ks, socket handling,
regions), then for each shape picks the setting with the lowest mean ratio over the other seven
and reports that shape's ratio under it (held out). Prints the grid and the held-out figures.
Usage, from the repository root after `cargo build --release -p mimic`:
    python3 docs/shell_loo.py [path/to/mimic] [extra eval args...]
"""
import itertools
import json
import statistics
import subprocess
import sys

MIMIC = sys.argv[1] if len(sys.argv) > 1 else "target/release/mimic"
EXTRA = sys.argv[2:]
S = "configs/meshes/ict-facekit"
SHAPES = ["jawOpen", "mouthSmile_L", "mouthSmile_R", "browInnerUp_L", "browInnerUp_R",
          "eyeBlink_L", "eyeBlink_R", "mouthFunnel"]
GRID = {
    "--shell-stiffness": ["0", "1", "2", "5", "10"],
    # (mode, mouth socket decay, eye socket decay), cm; the rig's sockets are the mouth
    # (11248-13293) and the eyes (13294-14061).
    "sockets": [("free",), ("frozen",), ("decay", "1,0.3"), ("decay", "2,0.3"), ("decay", "3,0.3"),
                ("decay", "2,0.1"), ("decay", "2,1")],
    "--shell-regions": ["on", "off"],
}


def run(args):
    cmd = [MIMIC, "eval", "--rig", "ict-face", "--solver", "shell", "--json", *args, *EXTRA,
           "--shapes", *[f"{S}/{s}.obj" for s in SHAPES]]
    out = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    return [s["all"]["ratio"] for s in out["shapes"]], out["noise_gain"], out["setup_ms"]


def main():
    rows = []
    for ks, sock, reg in itertools.product(*GRID.values()):
        args = ["--shell-stiffness", ks, "--sockets", sock[0], "--shell-regions", reg]
        if len(sock) > 1:
            args += ["--socket-decay", sock[1]]
        ratios, gain, setup = run(args)
        label = f"ks {ks}, sockets {' '.join(sock)}, regions {reg}"
        rows.append((label, ratios, gain))
        print(f"{label:<44} median {statistics.median(ratios):.3f} max {max(ratios):.3f} "
              f"gain {gain:.2f} setup {setup:.0f} ms  " + " ".join(f"{r:.2f}" for r in ratios),
              flush=True)
    held = []
    for h, name in enumerate(SHAPES):
        best = min(rows, key=lambda r: statistics.mean(x for i, x in enumerate(r[1]) if i != h))
        held.append(best[1][h])
        print(f"held out {name:<14} chosen on the other seven: {best[0]:<44} ratio {best[1][h]:.3f}")
    print(f"leave-one-out: median {statistics.median(held):.3f}, max {max(held):.3f}")


if __name__ == "__main__":
    main()
