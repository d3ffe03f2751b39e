#!/usr/bin/env python3
"""Writes ICT-FaceKit's expression set and identity shapes as shape packs (docs: the `//!` of
crates/mimic_assets/src/shape_pack.rs) from ../shared/data/ict-facekit.

- configs/meshes/ict-facekit/expressions.shapes: every expression OBJ (the 8 shipped beside it
  and expressions/*.obj.gz: 57 shapes, ICT's names) minus generic_neutral_mesh.obj, quantum
  1e-4 cm (every component within 5e-5 cm of ICT's delta).
- configs/meshes/ict-facekit/identities.shapes: identities/identity000-009, quantum 1e-3 cm,
  on the skin only (vertices 0-11247: face, head and neck; the rest left out as zero). Tests
  make new heads from them (neutral + sum w_i identity_i).
Usage, from the repository root: python3 tools/ict_shapes.py [--data ../shared/data/ict-facekit]
"""
import argparse
import gzip
import pathlib
import struct

MAGIC = b"mimic shapes 1\n"
SKIN = 11248


def vertices(path):
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt") as f:
        return [tuple(float(x) for x in line.split()[1:4]) for line in f if line.startswith("v ")]


def varint(out, v):
    while v >= 0x80:
        out.append((v & 0x7F) | 0x80)
        v >>= 7
    out.append(v)


def pack(neutral, shapes, quantum, keep=None):
    q32 = struct.unpack("<f", struct.pack("<f", quantum))[0]
    out = bytearray(MAGIC)
    varint(out, len(neutral))
    varint(out, len(shapes))
    out += struct.pack("<f", quantum)
    for name, verts in shapes:
        if len(verts) != len(neutral):
            raise SystemExit(f"{name}: {len(verts)} vertices, the neutral has {len(neutral)}")
        rows = []
        for i, (a, b) in enumerate(zip(verts, neutral)):
            r = [round((a[k] - b[k]) / q32) for k in range(3)]
            if any(r) and (keep is None or i < keep):
                rows.append((i, r))
        varint(out, len(name.encode()))
        out += name.encode()
        varint(out, len(rows))
        nxt = 0
        for i, r in rows:
            varint(out, i - nxt)
            nxt = i + 1
            for x in r:
                varint(out, (x << 1) ^ (x >> 63))
    return bytes(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=pathlib.Path, default=pathlib.Path("../shared/data/ict-facekit"))
    ap.add_argument("--out", type=pathlib.Path, default=pathlib.Path("configs/meshes/ict-facekit"))
    a = ap.parse_args()
    neutral = vertices(a.data / "generic_neutral_mesh.obj")
    files = [p for p in a.data.glob("*.obj") if p.stem != "generic_neutral_mesh"]
    files += list((a.data / "expressions").glob("*.obj.gz"))
    named = sorted((p.name.split(".")[0], p) for p in files)
    expressions = [(n, vertices(p)) for n, p in named]
    identities = [(p.name.split(".")[0], vertices(p))
                  for p in sorted((a.data / "identities").glob("identity*.obj.gz"))]
    for file, shapes, q, keep in [("expressions.shapes", expressions, 1e-4, None),
                                  ("identities.shapes", identities, 1e-3, SKIN)]:
        data = pack(neutral, shapes, q, keep)
        (a.out / file).write_bytes(data)
        print(f"{a.out / file}: {len(shapes)} shapes, {len(data)} bytes")


if __name__ == "__main__":
    main()
