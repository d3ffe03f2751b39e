#!/usr/bin/env python3
"""The basis variants tried against the creases (issue 45, item 1), on crease_explore.py's data.
Usage: python3 docs/crease_variants.py DIR [variant ...]
"""
import sys

import numpy as np
import scipy.sparse as sp

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
