#!/usr/bin/env python3
"""Writes the Surrey Face Model's shape mean and its six expressions as OBJ files.

Usage: python3 tools/sfm_to_obj.py EOS_CHECKOUT OUT_DIR

EOS_CHECKOUT is a clone of github.com/patrikhuber/eos; its `share/sfm_shape_3448.bin` (the
shape-only SFM, free for non-commercial use, hence not in this repository) and
`share/expression_blendshapes_3448.bin` are cereal binary archives (eos's
`morphablemodel/PcaModel.hpp`, `Blendshape.hpp`, `io/eigen_cerealisation.hpp`). Writes
OUT_DIR/neutral.obj (the mean, mm) and OUT_DIR/<name>.obj = mean + blendshape for anger,
disgust, fear, happiness, sadness and surprise, on the same 6 736 triangles
(docs/rigging.md, "Which solver"). Standard library only.
"""

import os
import struct
import sys


class Reader:
    """Little-endian reads from a cereal binary archive."""

    def __init__(self, data):
        self.data, self.at = data, 0

    def take(self, fmt):
        values = struct.unpack_from("<" + fmt, self.data, self.at)
        self.at += struct.calcsize("<" + fmt)
        return values

    def matrix(self):
        """An Eigen matrix: int32 rows, int32 cols, then rows * cols float32 (column-major)."""
        rows, cols = self.take("ii")
        return list(self.take("%df" % (rows * cols))), rows, cols


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    share = os.path.join(sys.argv[1], "share")
    out = sys.argv[2]
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(share, "sfm_shape_3448.bin"), "rb") as f:
        r = Reader(f.read())
    (version,) = r.take("I")  # MorphableModel's cereal class version
    mean, rows, _ = r.matrix()
    r.matrix()  # orthonormal PCA basis
    r.matrix()  # eigenvalues
    (count,) = r.take("Q")
    flat = r.take("%di" % (3 * count))
    triangles = [flat[k : k + 3] for k in range(0, len(flat), 3)]
    n = rows // 3
    print("SFM archive version %d: %d vertices, %d triangles" % (version, n, count))

    def write(name, offsets):
        with open(os.path.join(out, name + ".obj"), "w") as f:
            f.write("# Surrey Face Model (eos share/, non-commercial use only): %s\n" % name)
            for i in range(n):
                f.write("v %.6f %.6f %.6f\n" % tuple(mean[3 * i + k] + offsets[3 * i + k] for k in range(3)))
            for a, b, c in triangles:
                f.write("f %d %d %d\n" % (a + 1, b + 1, c + 1))

    write("neutral", [0.0] * rows)
    with open(os.path.join(share, "expression_blendshapes_3448.bin"), "rb") as f:
        r = Reader(f.read())
    (shapes,) = r.take("Q")
    for _ in range(shapes):
        (length,) = r.take("Q")
        name = r.data[r.at : r.at + length].decode()
        r.at += length
        deformation, drows, _ = r.matrix()
        if drows != rows:
            sys.exit("%s: %d values, the mean has %d" % (name, drows, rows))
        write(name, deformation)
        print("wrote %s" % os.path.join(out, name + ".obj"))


if __name__ == "__main__":
    main()
