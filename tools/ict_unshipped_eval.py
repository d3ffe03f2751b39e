#!/usr/bin/env python3
"""Scores rigs on the ICT-FaceKit expressions the project does not ship (docs/quality.md, "On the
ICT expressions the project does not ship").

The project ships 8 of ICT-FaceKit's 53 expressions (configs/meshes/ict-facekit/SOURCE.md); the
others are held out: no setting was chosen on them. Point this at a checkout of
github.com/ICT-VGL/ICT-FaceKit (its FaceXModel/ folder, the same topology) and it runs
`mimic eval --json` on every expression there except the shipped eight, the identity shapes and
the neutral, and prints each rig's median, mean and max ratio, then the ratio per shape.
Shapes that move no skin (PupilDilate_*: mean displacement below 1e-4 cm, ratio meaningless) are
listed but left out of the summary.
Usage, from the repository root after `cargo build --release -p mimic`:
    python3 tools/ict_unshipped_eval.py FACEXMODEL_DIR [--mimic target/release/mimic]
        [--rig ict-face[:extra eval args]]...
e.g. --rig ict-face --rig "ict-face:--shell-blend 0,0,0" --rig ict-face.mediapipe478
"""
import argparse
import json
import pathlib
import shlex
import statistics
import subprocess

SHIPPED = {"jawOpen", "mouthSmile_L", "mouthSmile_R", "browInnerUp_L", "browInnerUp_R",
           "eyeBlink_L", "eyeBlink_R", "mouthFunnel"}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("facexmodel", type=pathlib.Path)
    ap.add_argument("--mimic", default="target/release/mimic")
    ap.add_argument("--rig", action="append", default=[])
    a = ap.parse_args()
    shapes = sorted(p for p in a.facexmodel.glob("*.obj")
                    if p.stem not in SHIPPED and not p.stem.startswith("identity")
                    and p.stem != "generic_neutral_mesh")
    if not shapes:
        raise SystemExit(f"{a.facexmodel}: no expression OBJs")
    table = {}
    for spec in a.rig or ["ict-face"]:
        rig, _, extra = spec.partition(":")
        cmd = [a.mimic, "eval", "--rig", rig, "--json", *shlex.split(extra),
               "--shapes", *map(str, shapes)]
        out = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
        rows = {pathlib.Path(s["shape"]).stem: (s["all"]["ratio"], s["all"]["mean_displacement"])
                for s in out["shapes"]}
        table[spec] = rows
        kept = [r for r, disp in rows.values() if disp >= 1e-4]
        skipped = sorted(k for k, (_, disp) in rows.items() if disp < 1e-4)
        print(f"{spec:<40} {len(kept)} shapes: median {statistics.median(kept):.3f} "
              f"mean {statistics.mean(kept):.3f} max {max(kept):.3f} "
              f"gain {out['noise_gain']:.2f} (left out, no skin motion: {', '.join(skipped)})")
    names = sorted(next(iter(table.values())))
    print("shape".ljust(20) + "".join(s[:24].rjust(26) for s in table))
    for n in names:
        print(n.ljust(20) + "".join(f"{table[s][n][0]:26.3f}" for s in table))


if __name__ == "__main__":
    main()
