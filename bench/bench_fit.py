#!/usr/bin/env python3
"""bench_fit.py - frep fit against scipy, like for like, in one run: the paper's test part
(examples/fit/part.hf, 12 parameters) from set2 (all parameters 1), the same points, the
same bounds and the same objective, the sum of f^2 over the points (the paper's; scaling
by 1/N changes dual_annealing's acceptance, which is not scale-invariant). Every method
runs over the same seeds and is timed in CPU seconds of this process (scipy) or of the
frep child (resource.getrusage), so a loaded machine slows both alike.

Methods: frep saqn and qn (the command); scipy.optimize.dual_annealing with its default
L-BFGS-B local search on a numpy version of the part (finite-difference gradients, as a
scipy user would write it); dual_annealing and L-BFGS-B alone with frep's own objective
and analytic gradient through the C library (ctypes: frep_compile, fit_program_model,
fit_objective_new, fit_objective_value), so that only the search differs.

Usage: bench_fit.py FREP LIBFREP.so SRCDIR CLOUD.xyz [SEEDS...]"""
import ctypes as C
import os
import re
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.optimize import dual_annealing, minimize

TRUTH = np.array([-4, -2, -1, 8, 4, 2, -2, 0, 1, 2.2, 0.3, 0.6], dtype=float)
LO = [-10, -10, -10, 0.01, 0.01, 0.01, -10, -10, 0.01, -10, -10, 0.01]
HI = [10, 10, 10, 20, 20, 20, 10, 10, 10, 10, 10, 10]
NAMES = "x0 y0 z0 dx dy dz h1x h1y r1 h2x h2y r2".split()
DIAG = np.sqrt(84.0)
HIT = 1e-3          # "truth": largest parameter error below 1e-3 of the diagonal


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
    p = np.asarray(p, dtype=float)
    q = p.copy()
    q[6:9], q[9:12] = p[9:12], p[6:9]
    return min(np.abs(p - TRUTH).max(), np.abs(q - TRUTH).max()) / DIAG


class FrepObjective:
    """frep's algebraic objective (mean f^2) and its analytic gradient, through libfrep,
    times the point count: the sum of f^2."""

    def __init__(self, lib, template, pts):
        L = C.CDLL(lib)
        self.L = L
        DIAGCB = C.CFUNCTYPE(None, C.c_void_p, C.c_void_p)
        self._cb = DIAGCB(lambda u, d: None)
        opts = C.create_string_buffer(256)
        L.frep_compile_options_init(opts)
        text = open(template, "rb").read()
        L.frep_compile.restype = C.c_void_p
        L.frep_compile.argtypes = [C.c_char_p, C.c_char_p, C.c_size_t, C.c_void_p, DIAGCB,
                                   C.c_void_p]
        self.prog = L.frep_compile(template.encode(), text, len(text), opts, self._cb, None)
        if not self.prog:
            raise RuntimeError("cannot compile " + template)
        L.frep_program_nparams.restype = C.c_size_t
        L.frep_program_nparams.argtypes = [C.c_void_p]
        n = L.frep_program_nparams(self.prog)
        self.idx = (C.c_size_t * n)(*range(n))
        self.base = (C.c_double * n)(*([1.0] * n))
        self.model = C.create_string_buffer(64)        # fit_model: 5 words
        L.fit_program_model.argtypes = [C.c_void_p, C.c_void_p, C.c_size_t, C.c_void_p,
                                        C.c_void_p]
        if L.fit_program_model(self.prog, self.idx, n, self.base, self.model) != 0:
            raise RuntimeError("fit_program_model failed")
        self.n = n
        self.x = np.ascontiguousarray(pts[:, 0])
        self.y = np.ascontiguousarray(pts[:, 1])
        self.z = np.ascontiguousarray(pts[:, 2])
        dp = C.POINTER(C.c_double)
        self.points = (C.c_size_t * 1)(len(self.x))
        ptrs = [a.ctypes.data_as(C.c_void_p).value for a in (self.x, self.y, self.z)]
        self.pts = (C.c_void_p * 7)(len(self.x), *ptrs, None, None, None)
        cfg = C.create_string_buffer(64)
        L.fit_objective_config_init(cfg)
        L.fit_objective_new.restype = C.c_void_p
        L.fit_objective_new.argtypes = [C.c_void_p, C.c_void_p, C.c_void_p]
        self.obj = L.fit_objective_new(self.model, self.pts, cfg)
        if not self.obj:
            raise RuntimeError("fit_objective_new failed")
        L.fit_objective_value.restype = C.c_double
        L.fit_objective_value.argtypes = [C.c_void_p, dp, dp]
        self.N = float(len(self.x))
        self.evals = 0
        self._g = np.zeros(n)

    def __call__(self, p):
        self.evals += 1
        p = np.ascontiguousarray(p, dtype=float)
        v = self.L.fit_objective_value(self.obj, p.ctypes.data_as(C.POINTER(C.c_double)), None)
        return self.N * v

    def with_grad(self, p):
        self.evals += 1
        p = np.ascontiguousarray(p, dtype=float)
        g = self._g
        v = self.L.fit_objective_value(self.obj, p.ctypes.data_as(C.POINTER(C.c_double)),
                                       g.ctypes.data_as(C.POINTER(C.c_double)))
        return self.N * v, self.N * g.copy()


def child_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_frep(frep, template, cloud, method, seed, out, extra=()):
    t0 = child_cpu()
    res = subprocess.run([frep, "fit", template, cloud, "--method", method, "--seed",
                          str(seed), "-o", out, *extra], capture_output=True, text=True,
                         env=dict(os.environ, OMP_NUM_THREADS="1"))
    cpu = child_cpu() - t0
    vals = {}
    evals = 0
    for line in res.stdout.splitlines():
        w = line.split()
        if w and w[0] in NAMES and len(w) >= 3:
            vals[w[0]] = float(w[2])
        m = re.match(r"evaluations (\d+)", line)
        if m:
            evals = int(m.group(1))
    p = [vals.get(k, np.nan) for k in NAMES]
    return error(p), cpu, evals


def summary(name, rows):
    errs = np.array([r[0] for r in rows])
    cpu = np.array([r[1] for r in rows])
    ev = np.array([r[2] for r in rows])
    hits = int(np.sum(errs < HIT))
    print("%-44s %5s %10.3g %9.3f %9.3f %9d" % (name, "%d/%d" % (hits, len(rows)),
                                                 np.median(errs), np.median(cpu),
                                                 np.mean(cpu), int(np.median(ev))))
    sys.stdout.flush()
    return hits, np.median(cpu)


def main():
    if len(sys.argv) < 5:
        sys.exit(__doc__)
    frep, lib, srcdir, cloud = sys.argv[1:5]
    seeds = [int(s) for s in sys.argv[5:]] or [1, 2, 3]
    pts = np.loadtxt(cloud, usecols=(0, 1, 2))
    x, y, z = pts[:, 0].copy(), pts[:, 1].copy(), pts[:, 2].copy()
    template = os.path.join(srcdir, "examples", "fit", "part_a.hf")
    fo = FrepObjective(lib, template, pts)
    bounds = list(zip(LO, HI))
    tmp = tempfile.mkdtemp()
    out = os.path.join(tmp, "out.hf")
    set2 = os.path.join(srcdir, "examples", "fit", "part.hf")

    print("test part, %d points, set2 (all 1), objective sum of f^2, seeds %s; CPU seconds"
          % (len(x), " ".join(map(str, seeds))))
    print("%-44s %5s %10s %9s %9s %9s" % ("method", "truth", "med.error", "med.cpu",
                                          "mean.cpu", "med.evals"))

    rows = [run_frep(frep, set2, cloud, "saqn", s, out) for s in seeds]
    summary("frep saqn (1 thread)", rows)
    # The objective alone, as dual_annealing's: no robust refinement (geometric
    # distances, Cauchy loss) after the local phase.
    rows = [run_frep(frep, set2, cloud, "saqn", s, out, ("--no-robust",)) for s in seeds]
    summary("frep saqn --no-robust (1 thread)", rows)
    rows = [run_frep(frep, set2, cloud, "qn", 1, out)]
    summary("frep qn (1 thread, deterministic)", rows)

    fo.evals = 0
    t0 = time.process_time()
    r = minimize(fo.with_grad, np.ones(12), jac=True, method="L-BFGS-B", bounds=bounds,
                 options=dict(maxiter=15000, maxfun=15000))
    summary("scipy L-BFGS-B, frep's gradient (C API)", [(error(r.x), time.process_time() - t0,
                                                        fo.evals)])

    rows = []
    for s in seeds:
        fo.evals = 0
        t0 = time.process_time()
        r = dual_annealing(fo, bounds, x0=np.ones(12), seed=s,
                           minimizer_kwargs=dict(jac=lambda p: fo.with_grad(p)[1],
                                                 method="L-BFGS-B"))
        rows.append((error(r.x), time.process_time() - t0, fo.evals))
    summary("scipy dual_annealing, frep's f and gradient", rows)

    count = [0]

    def objective(p):
        count[0] += 1
        return float(np.sum(model(p, x, y, z) ** 2))

    rows = []
    for s in seeds:
        count[0] = 0
        t0 = time.process_time()
        r = dual_annealing(objective, bounds, x0=np.ones(12), seed=s)
        rows.append((error(r.x), time.process_time() - t0, count[0]))
    summary("scipy dual_annealing, numpy f (FD gradient)", rows)


if __name__ == "__main__":
    main()
