#!/usr/bin/env python3
"""Makes skin.png, a procedural albedo for the ICT-FaceKit face (material M_Face, UV tile 0..1).

Run from the repository root:  python3 configs/meshes/ict-facekit-textured/make_skin.py
Needs numpy and Pillow. Deterministic (fixed seed): the same bytes each run with the same versions.

The features are placed in UV space from ICT's own iBUG-68 landmark vertices
(configs/rigs/ict-face.landmarks.json) and the neutral mesh's texture coordinates: lips filled
inside the outer lip contour (iBUG 48-59), brows drawn along iBUG 17-21 and 22-26, a blush on the
cheeks, a faint darker ring around the eyes, freckles over nose and cheeks and a low-amplitude
mottle over all. The border of the tile is the renderer's plain skin colour (mimic_render's
SKIN_ALBEDO, linear 0.80 0.66 0.58), which the untextured back of the head keeps, so the seam
between face and head does not show.
"""
import json
import os

import numpy as np
from PIL import Image, ImageDraw, ImageFilter

ROOT = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(ROOT, "..", "..", ".."))
OBJ = os.path.join(REPO, "configs/meshes/ict-facekit/generic_neutral_mesh.obj")
MARKS = os.path.join(REPO, "configs/rigs/ict-face.landmarks.json")
SIZE = 512


def srgb(linear):
    x = np.asarray(linear, dtype=np.float64)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055) * 255.0


def vertex_uvs():
    """Image-convention UV (u right, v down) of each vertex's first M_Face corner."""
    vt, uv_of, mat = [], {}, None
    with open(OBJ) as f:
        for line in f:
            t = line.split()
            if not t:
                continue
            if t[0] == "vt":
                vt.append((float(t[1]), float(t[2])))
            elif t[0] == "usemtl":
                mat = t[1]
            elif t[0] == "f" and mat == "M_Face":
                for c in t[1:]:
                    v, u = c.split("/")[:2]
                    uv_of.setdefault(int(v) - 1, vt[int(u) - 1])
    return {v: (u, 1.0 - w) for v, (u, w) in uv_of.items()}


def main():
    uvs = vertex_uvs()
    marks = json.load(open(MARKS))
    px = lambda i: (uvs[marks[i]][0] * SIZE, uvs[marks[i]][1] * SIZE)
    rng = np.random.default_rng(20)
    skin_lin = np.array([0.80, 0.66, 0.58])
    base = np.tile(skin_lin, (SIZE, SIZE, 1))
    yy, xx = np.mgrid[0:SIZE, 0:SIZE].astype(np.float64)

    def blob(cx, cy, r):
        return np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * r * r))

    # The face's extent in the tile: the jaw line (iBUG 0-16) and brows bound it.
    face = np.array([px(i) for i in range(27)])
    centre = face.mean(axis=0)
    span = np.ptp(face, axis=0).max()
    # Slightly warmer and darker towards the middle of the face, fading to plain skin.
    warm = blob(centre[0], centre[1], span * 0.45)
    base = base * (1 - 0.06 * warm[..., None]) + np.array([0.05, 0.0, -0.02]) * warm[..., None]
    # Cheek blush.
    for c in (px(2), px(14)):
        k = blob(0.65 * c[0] + 0.35 * px(30)[0], 0.65 * c[1] + 0.35 * px(30)[1], span * 0.08)
        base = base * (1 - 0.25 * k[..., None]) + np.array([0.78, 0.35, 0.35]) * 0.25 * k[..., None]
    # Mottle: smoothed noise, +-3%.
    noise = Image.fromarray((rng.random((SIZE // 8, SIZE // 8)) * 255).astype(np.uint8))
    noise = np.asarray(noise.resize((SIZE, SIZE), Image.BICUBIC), dtype=np.float64) / 255.0 - 0.5
    base = base * (1 + 0.06 * noise[..., None])
    # Freckles over nose and cheeks.
    for _ in range(90):
        a = rng.normal(size=2) * span * np.array([0.16, 0.07])
        cx, cy = px(30)[0] + a[0], px(30)[1] + a[1] + span * 0.02
        k = blob(cx, cy, rng.uniform(0.8, 1.8))
        base = base * (1 - 0.35 * k[..., None]) + np.array([0.45, 0.25, 0.15]) * 0.35 * k[..., None]
    # Darker rings around the eyes (iBUG 36-41, 42-47).
    for eye in (range(36, 42), range(42, 48)):
        e = np.array([px(i) for i in eye]).mean(axis=0)
        k = blob(e[0], e[1], span * 0.05)
        base = base * (1 - 0.12 * k[..., None])
    img = Image.fromarray(np.clip(srgb(np.clip(base, 0, 1)), 0, 255).round().astype(np.uint8))
    # Lips and brows, drawn on a layer and blurred a little at their edges.
    layer = Image.new("RGBA", (SIZE, SIZE), (0, 0, 0, 0))
    d = ImageDraw.Draw(layer)
    d.polygon([px(i) for i in range(48, 60)], fill=(196, 96, 100, 235))
    for brow in (range(17, 22), range(22, 27)):
        d.line([px(i) for i in brow], fill=(92, 62, 44, 230), width=max(3, SIZE // 80), joint="curve")
    layer = layer.filter(ImageFilter.GaussianBlur(1.2))
    img = Image.alpha_composite(img.convert("RGBA"), layer).convert("RGB")
    out = os.path.join(ROOT, "skin.png")
    img.save(out, optimize=True)
    print(out, os.path.getsize(out), "bytes")


if __name__ == "__main__":
    main()
