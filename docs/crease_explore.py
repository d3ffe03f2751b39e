#!/usr/bin/env python3
"""Tries bases against the crease measure and the eval without replaying (issue 45, item 1).

Reads what `cargo run -p mimic_retarget --example crease_dump -- DIR SPEC...` writes: the ICT
rig's rest mesh, ICT's expression shapes, the eight eval shapes, every frame's displacements of
the two shipped takes (controls and rigid parts: positions = rest + B d, so a basis needs no
replay) and the bases of the specs. A numpy twin of `mimic_retarget::quality::crease` (checked
against the Rust figures of the crease test) and of `mimic eval`'s ratio.
Usage: python3 docs/crease_explore.py DIR
"""
import json
import sys

import numpy as np
import scipy.sparse as sp

D = sys.argv[1] if len(sys.argv) > 1 else "/tmp/crease"
IDX = json.load(open(f"{D}/index.json"))
N, C = IDX["vertices"], IDX["columns"]
rest = np.fromfile(f"{D}/rest.f32", np.float32).reshape(N, 3).astype(np.float64)
tris = np.fromfile(f"{D}/tris.u32", np.uint32).reshape(-1, 3).astype(np.int64)
frozen = np.fromfile(f"{D}/frozen.u8", np.uint8).astype(bool)
surface = ~frozen
ctrl_v = np.array([c["vertex"] for c in IDX["controls"]])
brow_y = min(rest[c["vertex"], 1] for c in IDX["controls"] if c["fdp"].startswith("4."))
forehead = surface & (rest[:, 1] > brow_y)

# The measure's surface: triangles with every corner free; its edges; ring averaging.
T = tris[surface[tris].all(1)]
e = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), 1)
e = np.unique(e, axis=0)
deg = np.bincount(e.ravel(), minlength=N)
adj = sp.coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                    shape=(N, N)).tocsr()
inv = np.where(surface, 1.0 / (1.0 + deg), 0.0)
RING = (sp.diags(inv) @ (sp.identity(N) + adj)).tocsr()
tri_idx = T.ravel()
SCAT = sp.coo_matrix((np.ones(len(tri_idx)), (tri_idx, np.repeat(np.arange(len(T)), 3))),
                     shape=(N, len(T))).tocsr()
REG = np.flatnonzero(forehead)


def smoothed_normals(p):
    a, b, c = p[T[:, 0]], p[T[:, 1]], p[T[:, 2]]
    n = SCAT @ np.cross(b - a, c - a)
    for _ in range(2):
        n = RING @ n
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(ln > 0, n / np.where(ln > 0, ln, 1), 0)


N0 = smoothed_normals(rest)


def crease(p, per_vertex=False):
    r = np.cross(N0, smoothed_normals(p))
    avg = r
    for _ in range(4):
        avg = RING @ avg
    dev = np.linalg.norm(r - avg, axis=1)
    if per_vertex:
        return dev
    d = np.sort(dev[REG])
    return d[min(int(round((len(d) - 1) * 0.995)), len(d) - 1)]


shapes = np.fromfile(f"{D}/ict_shapes.f32", np.float32).reshape(-1, N, 3)
BOUND = max(crease(rest + s) for s in shapes)
ev_true = np.fromfile(f"{D}/eval_true.f32", np.float32).reshape(8, N, 3).astype(np.float64)
ev_d = np.fromfile(f"{D}/eval_d.f32", np.float32).reshape(8, -1, 3).astype(np.float64)
takes = []
for t in IDX["takes"]:
    d = np.fromfile(f"{D}/{t['file']}", np.float32).reshape(t["frames"], C, 3).astype(np.float64)
    tr = np.fromfile(f"{D}/tracked_{t['name']}.u8", np.uint8).astype(bool)
    step = 5 if t["name"].startswith("a_yn") else 1
    keep = [k for k in range(t["frames"]) if k % step == 0 and tr[k]]
    takes.append((t["name"], keep, d))


def load_basis(i):
    b = IDX["bases"][i]
    return b["spec"], np.fromfile(f"{D}/{b['file']}", np.float32).reshape(N, C).astype(np.float64)


def evaluate(B):
    """The eval's ratios of the eight shapes (non-frozen vertices), as `mimic eval`."""
    out = []
    for k in range(8):
        d = np.zeros((C, 3))
        d[: ev_d.shape[1]] = ev_d[k]
        u = B @ d
        err = np.linalg.norm(u - ev_true[k], axis=1)[surface].mean()
        out.append(err / np.linalg.norm(ev_true[k], axis=1)[surface].mean())
    return np.array(out)


def creases(B, frames=None):
    """Per take: (frames over the bound, frames measured, largest, its frame)."""
    res = []
    for name, keep, d in takes:
        ks = keep if frames is None else [k for k in keep if k in frames]
        v = np.array([crease(rest + B @ d[k]) for k in ks])
        res.append((int((v > BOUND).sum()), len(ks), float(v.max()), ks[int(v.argmax())]))
    return res


def report(label, B):
    r = evaluate(B)
    c = creases(B)
    print(f"{label:<44} eval median {np.median(r):.3f} worst {r.max():.3f} "
          f"[{' '.join(f'{x:.3f}' for x in r)}]  "
          + "  ".join(f"{n.split('.')[0][:8]} {o}/{m} top {t:.4f}@{k}" for n, (o, m, t, k)
                      in zip([t[0] for t in takes], c)), flush=True)
    return r, c


if __name__ == "__main__":
    print(f"bound {BOUND:.4f}, brow line {brow_y:.2f}, region {len(REG)}")
    for i in range(len(IDX["bases"])):
        spec, B = load_basis(i)
        report(spec, B)
