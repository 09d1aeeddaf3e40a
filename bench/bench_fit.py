#!/usr/bin/env python3
"""bench_fit.py - the baseline of bench_fit.sh: scipy.optimize.dual_annealing (with its
default L-BFGS-B local search) on the same objective as `frep fit --global-objective
algebraic`: the mean of f^2 over the points, f the test part of examples/fit/part.hf
(hfBlock slabs and z-cylinders combined by Rvachev intersection, as HyperFun does),
within the same bounds, from the same start (set2: all parameters 1).
Usage: bench_fit.py CLOUD.xyz [SEEDS...]"""
import sys
import time

import numpy as np
from scipy.optimize import dual_annealing

TRUTH = np.array([-4, -2, -1, 8, 4, 2, 2.2, 0.3, 0.6, -2, 0, 1], dtype=float)
LO = [-10, -10, -10, 0.01, 0.01, 0.01, -10, -10, 0.01, -10, -10, 0.01]
HI = [10, 10, 10, 20, 20, 20, 10, 10, 10, 10, 10, 10]


def rand(a, b):
    return a + b - np.sqrt(a * a + b * b)


def model(p, x, y, z):
    s = [(c - p[k]) * (p[k] + p[3 + k] - c) for k, c in enumerate((x, y, z))]
    f = rand(rand(s[0], s[1]), s[2])
    for k in (6, 9):
        cyl = p[k + 2] ** 2 - (x - p[k]) ** 2 - (y - p[k + 1]) ** 2
        f = rand(f, -cyl)
    return f


def error(p):
    q = p.copy()
    q[6:9], q[9:12] = p[9:12], p[6:9]
    diag = np.sqrt(84.0)
    return min(np.abs(p - TRUTH).max(), np.abs(q - TRUTH).max()) / diag


def main():
    pts = np.loadtxt(sys.argv[1], usecols=(0, 1, 2))
    x, y, z = pts[:, 0].copy(), pts[:, 1].copy(), pts[:, 2].copy()
    seeds = [int(s) for s in sys.argv[2:]] or [1]
    count = [0]

    def objective(p):
        count[0] += 1
        return float(np.mean(model(p, x, y, z) ** 2))

    print("%-5s %10s %9s %8s" % ("seed", "error", "seconds", "evals"))
    rows = []
    for seed in seeds:
        count[0] = 0
        t0 = time.perf_counter()
        r = dual_annealing(objective, list(zip(LO, HI)), x0=np.ones(12), seed=seed)
        dt = time.perf_counter() - t0
        rows.append((error(r.x), dt, count[0]))
        print("%-5d %10.3g %9.3f %8d" % (seed, rows[-1][0], dt, count[0]))
    med = np.median(np.array(rows), axis=0)
    hits = sum(1 for e, _, _ in rows if e < 1e-3)
    print("median: error %.3g, %.3f s, %d evals; truth (error < 1e-3) for %d of %d seeds"
          % (med[0], med[1], int(med[2]), hits, len(rows)))


if __name__ == "__main__":
    main()
