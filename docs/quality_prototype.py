#!/usr/bin/env python3
"""numpy re-implementation of `build_basis` + `mimic eval` on ICT-FaceKit, for docs/quality.md.

Used to try ideas before building them in Rust ("Prototyped, not shipped"). It reproduces
`mimic eval --top-split off` and the shipped defaults to three decimals (checked in `main`).
Needs numpy only; about 10 s (one Dijkstra per control in pure Python).

    python3 docs/quality_prototype.py            # baseline, defaults, jaw term, socket/forehead metrics
"""
import heapq
import os
import re

import numpy as np

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
MESHES = os.path.join(ROOT, "configs/meshes/ict-facekit")
SHAPES = ["jawOpen", "mouthSmile_L", "mouthSmile_R", "browInnerUp_L", "browInnerUp_R",
          "eyeBlink_L", "eyeBlink_R", "mouthFunnel"]


def load_obj(path):
    v, f = [], []
    for line in open(path):
        if line.startswith("v "):
            v.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            idx = [int(t.split("/")[0]) - 1 for t in line.split()[1:]]
            f += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]
    return np.array(v), np.array(f)


V, F = load_obj(os.path.join(MESHES, "generic_neutral_mesh.obj"))
TRUE = {s: load_obj(os.path.join(MESHES, s + ".obj"))[0] for s in SHAPES}
N = len(V)
FROZEN = np.zeros(N, bool)
FROZEN[9409:11248] = True
FROZEN[14062:] = True
RIG = open(os.path.join(ROOT, "configs/rigs/ict-face.toml")).read()
CTRL = re.findall(r'fdp = "([\d.]+)"\nvertex = (\d+)\nregion = "(\w+)"', RIG)
FDP = [c[0] for c in CTRL]
CV = np.array([int(c[1]) for c in CTRL])
CR = [c[2] for c in CTRL]
IDX = {f: j for j, f in enumerate(FDP)}
EDGES = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), 1), axis=0)


def distances(scale=None):
    """Edge-path distance from every control; `scale(edge_a, edge_b)` multiplies edge lengths."""
    length = np.linalg.norm(V[EDGES[:, 0]] - V[EDGES[:, 1]], axis=1)
    if scale is not None:
        length = length * scale(EDGES[:, 0], EDGES[:, 1])
    adj = [[] for _ in range(N)]
    for (a, b), w in zip(EDGES, length):
        adj[a].append((b, w))
        adj[b].append((a, w))
    out = []
    for s in CV:
        d = np.full(N, np.inf)
        d[s] = 0.0
        heap = [(0.0, s)]
        while heap:
            dd, v = heapq.heappop(heap)
            if dd > d[v]:
                continue
            for w, le in adj[v]:
                if dd + le < d[w]:
                    d[w] = dd + le
                    heapq.heappush(heap, (dd + le, w))
        out.append(d)
    return np.array(out)


def exponential(s):
    return lambda r: np.exp(-r / s)


def matern32(s):
    # Unreachable vertices (infinite distance) get 0, as in mimic_solve::rbf.
    def k(r):
        with np.errstate(invalid="ignore"):
            v = (1 + np.sqrt(3) * r / s) * np.exp(-np.sqrt(3) * r / s)
        return np.where(np.isfinite(r), v, 0.0)
    return k


def ramp(y, border, band):
    return np.clip((y - border) / band + 0.5, 0, 1) if band > 0 else (y >= border).astype(float)


def rbf_columns(G, subset, kernel, prior=None):
    """Cardinal columns of `kernel` on the controls `subset`; `prior = (E, tau2)` adds the
    covariance `tau2 E E^T` of example fields (columns of E) to the kernel (a Gaussian-process
    posterior mean with the examples as a second, data-driven covariance)."""
    phi = np.array([[0.5 * (G[a][CV[b]] + G[b][CV[a]]) for b in subset] for a in subset])
    kcc, knc = kernel(phi), kernel(G[subset].T)
    if prior is not None:
        E, tau2 = prior
        ec = E[CV[subset]]
        kcc, knc = kcc + tau2 * ec @ ec.T, knc + tau2 * E @ ec.T
    return knc @ np.linalg.solve(kcc, np.eye(len(subset)))


def build(G, kernel=exponential(2.0), split=None, top_from=2.3, bottom_below=-1.8, band=1.4,
          prior=None):
    """Regions on; `split = (at, band, upper_kernel, lower_kernel)` as the rig's top_split."""
    y = V[:, 1]
    top, bottom = ramp(y, top_from, band), 1 - ramp(y, bottom_below, band)
    middle = np.clip(1 - top - bottom, 0, None)
    total = top + middle + bottom
    parts = [(middle / total, "middle", None, kernel), (bottom / total, "bottom", None, kernel)]
    if split is None:
        parts.append((top / total, "top", None, kernel))
    else:
        at, sband, ku, kl = split
        share = ramp(y, at, sband)
        parts.append((top / total * share, "top", True, ku))
        parts.append((top / total * (1 - share), "top", False, kl))
    B = np.zeros((N, len(CV)))
    for weight, region, upper, k in parts:
        sub = [j for j in range(len(CV)) if CR[j] == region
               and (upper is None or (V[CV[j], 1] >= split[0]) == upper)]
        B[:, sub] += weight[:, None] * rbf_columns(G, sub, k, prior)
    B[FROZEN] = 0
    return B


def jaw_term(G, hinge=(0.0, 1.0), chin=("2.1", "2.10", "2.11", "2.12"),
             lower=("8.2", "8.7", "8.8", "2.3"), neutral=("8.3", "8.4", "2.4", "2.5"),
             p=4.0, falloff=None):
    """Affine field vanishing on the hinge axis (x through y, z = hinge), fitted to the chin."""
    q = np.stack([V[:, 1] - hinge[0], V[:, 2] - hinge[1]], 1)
    J = [IDX[f] for f in chin]
    Q = q[CV[J]]
    beta = q @ np.linalg.solve(Q.T @ Q, Q.T)
    member = [IDX[f] for f in chin + lower]
    upper = [j for j in range(len(CV)) if FDP[j] not in chin + lower + neutral]
    with np.errstate(all="ignore"):
        gj, gu = G[member].min(0), G[upper].min(0)
        w = gu ** p / (gu ** p + gj ** p)
        if falloff:
            w = w * np.exp(-G[J].min(0) / falloff)
    w[~np.isfinite(w)] = 0
    out = np.zeros((N, len(CV)))
    out[:, J] = w[:, None] * beta
    out[FROZEN] = 0
    return out


def with_jaw(J, R):
    return J + R @ (np.eye(len(CV)) - J[CV])


def shape_ratio(B, s):
    D = TRUE[s] - V
    e = np.linalg.norm(B @ D[CV] - D, axis=1)[~FROZEN]
    return e.mean() / np.linalg.norm(D, axis=1)[~FROZEN].mean()


def evaluate(B, label, per_shape=None):
    """`per_shape(s)`: a basis per held-out shape (leave-one-out); else `B` for all."""
    ratios, gain = [], 0.0
    for s in SHAPES:
        Bs = B if per_shape is None else per_shape(s)
        ratios.append(shape_ratio(Bs, s))
        gain = max(gain, np.abs(Bs).sum(1).max())
    r = sorted(ratios)
    print(f"{label:<44} median {(r[3] + r[4]) / 2:.3f} max {r[-1]:.3f} gain {gain:.2f} | "
          + " ".join(f"{x:.3f}" for x in ratios))


def main():
    G = distances()
    R = build(G)
    evaluate(R, "previous defaults (--top-split off)")
    split = (4.6, 1.0, matern32(2.0), matern32(1.0))
    evaluate(build(G, split=split), "defaults (top split, Matern 2 / 1)")
    evaluate(build(G, kernel=matern32(2.0)), "Matern 2 everywhere, no split")
    for falloff in (None, 4.0, 10.0):
        evaluate(with_jaw(jaw_term(G, falloff=falloff), R), f"jaw term, membership p=4, falloff {falloff}")
    mouth = np.zeros(N, bool)
    mouth[11248:14062] = True
    mouth &= V[:, 1] < 1
    for s in (0.7, 0.5):
        Gs = distances(lambda a, b, s=s: np.where(mouth[a] & mouth[b], s, 1.0))
        evaluate(build(Gs), f"mouth socket edges x {s}")
    # Two levels: a wide exponential field interpolating the controls, the defaults interpolating
    # what it leaves at them (B = a Bc + Bf (I - a Bc[controls])).
    Bf = build(G, split=split)
    for radius, a in ((4.0, 0.5), (4.0, 1.0), (6.0, 0.5)):
        Bc = build(G, kernel=exponential(radius), split=(4.6, 1.0, exponential(radius), exponential(radius)))
        evaluate(a * Bc + Bf @ (np.eye(len(CV)) - a * Bc[CV]), f"two levels, exp {radius} cm, a {a}")
    # The other shipped shapes as a covariance prior (each held-out shape left out of it, and
    # its left/right twin too with `pairs`): x, y, z of each shape's displacement as 3 fields.
    twin = {"mouthSmile_L": "mouthSmile_R", "browInnerUp_L": "browInnerUp_R", "eyeBlink_L": "eyeBlink_R"}
    twin.update({b: a for a, b in list(twin.items())})

    def examples(held, pairs):
        E = np.stack([(TRUE[t] - V)[:, a] for t in SHAPES
                      if t != held and not (pairs and twin.get(held) == t) for a in range(3)], 1)
        E[FROZEN] = 0
        return E
    for tau2 in (0.3, 3.0, 10.0):
        for pairs in (False, True):
            evaluate(None, f"example prior tau2 {tau2}, leave-{'pair' if pairs else 'one'}-out",
                     lambda s: build(G, split=split, prior=(examples(s, pairs), tau2)))


if __name__ == "__main__":
    main()
