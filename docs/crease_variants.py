#!/usr/bin/env python3
"""The basis variants tried against the creases (issue 45, item 1), on crease_explore.py's data:
the thin shell blended in by height (in the brow half only), Laplacian smoothing of B's rows.
DIR from `cargo run -p mimic_retarget --example crease_dump -- DIR blend=0,0.25,0.75 blend=0,0,0
blend=1,1,1` (the rig's basis, the RBF alone, the shell; in that order). Prints the rows of
docs/quality.md "Creases" for these variants; `--above Y` measures over y > Y instead of the
brows and forehead (with ICT's bound recomputed there).
Usage: python3 docs/crease_variants.py DIR [--above Y]
"""
import sys

import numpy as np
import scipy.sparse as sp

ABOVE = float(sys.argv[sys.argv.index("--above") + 1]) if "--above" in sys.argv else None
sys.argv = sys.argv[:2]
import crease_explore as X  # noqa: E402

y = X.rest[:, 1]
TOP = np.clip((y - 2.3) / 1.4 + 0.5, 0, 1)          # the rig's top weight (band 1.4)
BOT = 1 - np.clip((y + 1.8) / 1.4 + 0.5, 0, 1)
MID = np.maximum(1 - TOP - BOT, 0)


def upper(at=4.6, band=1.0):
    return np.clip((y - at) / band + 0.5, 0, 1)


def shell_share(top=0.0, mid=0.25, bot=0.75, brows=0.0, at=4.6, band=1.0):
    return top * TOP + mid * MID + bot * BOT + brows * TOP * upper(at, band)


def blend(b_rbf, b_sh, s):
    return (1 - s)[:, None] * b_rbf + s[:, None] * b_sh


# Uniform Laplacian smoothing over the free surface (the measure's edges).
A = X.adj.multiply(X.surface[:, None]).multiply(X.surface[None, :]).tocsr()
DEG = np.asarray(A.sum(1)).ravel()
AVG = (sp.diags(np.where(DEG > 0, 1 / np.maximum(DEG, 1), 0)) @ A).tocsr()


def smooth(B, w, steps, lam=0.5, keep_controls=True):
    """`steps` of B_i += lam w_i (avg_nbr B - B_i); w per vertex in [0, 1]."""
    w = w * X.surface
    if keep_controls:
        w = w.copy()
        w[X.ctrl_v] = 0
    for _ in range(steps):
        B = B + (lam * w)[:, None] * (AVG @ B - B)
    return B


if __name__ == "__main__":
    if ABOVE is not None:
        X.REG = np.flatnonzero(X.surface & (X.rest[:, 1] > ABOVE))
        X.BOUND = max(X.crease(X.rest + s) for s in X.shapes)
        print(f"measured over y > {ABOVE}: {len(X.REG)} vertices, ICT's bound {X.BOUND:.4f}")
    _, b_rig = X.load_basis(0)
    _, b_rbf = X.load_basis(1)
    _, b_shell = X.load_basis(2)
    brow = TOP * upper()
    X.report("today", b_rig)
    for t in [0.25, 0.5, 1.0]:
        X.report(f"shell in the brow half {t}", blend(b_rbf, b_shell, shell_share(brows=t)))
    for steps in [3, 5, 10, 40]:
        X.report(f"smooth {steps}, controls kept", smooth(b_rig, brow, steps))
    for steps in [10, 40]:
        X.report(f"smooth {steps}, controls too", smooth(b_rig, brow, steps, keep_controls=False))
    X.report("smooth 10 above y 5.2", smooth(b_rig, TOP * upper(5.7, 1.0), 10))
    tent = TOP * np.clip(1 - np.abs(y - 4.6) / 1.0, 0, 1)
    for steps in [5, 10]:
        X.report(f"smooth {steps} tent 3.6..5.6", smooth(b_rig, tent, steps))
