#!/usr/bin/env python3
"""The outside reference of `mimic bench --numpy`: numpy's `B @ D` in float32 over the same rows.

Usage: bench_numpy.py MATRIX.f32 ROWS COLS [REPS]

MATRIX.f32 holds ROWS x COLS little-endian float32, row-major (the moving rows of the rig's basis,
written by `mimic bench`); D is a COLS x 3 float32 matrix of control displacements. Times only the
product `B @ D` on one BLAS thread (a fresh output each call, as a numpy user writes it; and `np.matmul(..., out=)`
into a kept buffer), REPS times after a warm-up, and prints the medians in microseconds as JSON.
"""

import json
import os
import sys
import time

# One thread, like the step it is compared with (a multi-threaded BLAS spins on a busy machine).
for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import numpy as np  # noqa: E402  (after the thread settings)


def main() -> None:
    path, rows, cols = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    reps = int(sys.argv[4]) if len(sys.argv) > 4 else 2000
    b = np.fromfile(path, dtype="<f4").reshape(rows, cols)
    d = np.random.default_rng(1).standard_normal((cols, 3)).astype(np.float32)
    out = np.empty((rows, 3), dtype=np.float32)
    for _ in range(50):
        b @ d
    fresh, kept = [], []
    for _ in range(reps):
        t = time.perf_counter_ns()
        b @ d
        fresh.append(time.perf_counter_ns() - t)
        t = time.perf_counter_ns()
        np.matmul(b, d, out=out)
        kept.append(time.perf_counter_ns() - t)
    print(
        json.dumps(
            {
                "rows": rows,
                "cols": cols,
                "reps": reps,
                "numpy": np.__version__,
                "matmul_median_us": float(np.median(fresh)) / 1e3,
                "matmul_out_median_us": float(np.median(kept)) / 1e3,
            }
        )
    )


if __name__ == "__main__":
    main()
