#!/usr/bin/env python3
"""Leave-one-out choice of the top split's height and band (issue 45, item 1), on the data of
`cargo run -p mimic_retarget --example crease_dump -- DIR 'sat=AT;sband=BAND' ...` (a grid):
each basis' eval ratios (crease_explore.py's twin of `mimic eval`); for each of the eight shapes
the setting with the lowest mean ratio over the other seven, and that shape's ratio under it
(held out); then the crease counts of the settings named on the command line (or all).
Usage: python3 docs/crease_split_loo.py DIR [SPEC ...]
"""
import statistics
import sys

want = sys.argv[2:]
sys.argv = sys.argv[:2]
import crease_explore as X  # noqa: E402

rows = []
for i in range(len(X.IDX["bases"])):
    spec, B = X.load_basis(i)
    r = X.evaluate(B)
    rows.append((spec, r))
    print(f"{spec:<22} median {statistics.median(r):.3f} mean {r.mean():.3f} max {r.max():.3f}  "
          + " ".join(f"{x:.3f}" for x in r), flush=True)
held = []
for h, name in enumerate(X.IDX["eval"]):
    best = min(rows, key=lambda row: sum(x for i, x in enumerate(row[1]) if i != h))
    held.append(best[1][h])
    print(f"held out {name:<14} chosen on the other seven: {best[0]:<20} ratio {best[1][h]:.3f}")
print(f"leave-one-out: median {statistics.median(held):.3f}, mean {statistics.mean(held):.3f}, "
      f"max {max(held):.3f}", flush=True)
for i in range(len(X.IDX["bases"])):
    spec, B = X.load_basis(i)
    if want and spec not in want:
        continue
    X.report(spec, B)
