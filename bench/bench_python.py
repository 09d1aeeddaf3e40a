"""bench_python.py - evaluating N points from Python (the frep package) against the
C API (bench/bench_api_eval, a C program), one thread, CPU time (doc/python.md,
"Speed").  ROUNDS rounds alternate the sides, each the median of 5 runs, so a
loaded machine slows them alike; the ratios printed are medians of the rounds'
ratios.  A third side calls frep_eval_par through ctypes directly on the package's
arrays: the package's own cost is its difference from that.  The fixed cost of one call from Python is measured on a 1-point array.
    python3 bench_python.py BENCH_API_EVAL MODEL.hf [N [ROUNDS]]
Needs FREP_LIBRARY (or an installed libfrep) and python/ on PYTHONPATH."""
import subprocess
import sys
import time

import numpy as np

import frep

exe, model = sys.argv[1], sys.argv[2]
n = int(sys.argv[3]) if len(sys.argv) > 3 else 1000000
rounds = int(sys.argv[4]) if len(sys.argv) > 4 else 7
RUNS = 5

p = frep.compile_file(model)
box = p.box() or (-1, -1, -1, 1, 1, 1)
t = np.linspace(0, 1, n)
x, y, z = (box[k] + t * (box[k + 3] - box[k]) for k in range(3))
f = np.empty(n)


def c_side():
    out = subprocess.run([exe, model, str(n), str(RUNS)], capture_output=True, text=True,
                         check=True).stdout.split()
    return float(out[1]), float(out[3])


def timed(fn):
    secs = []
    for _ in range(RUNS):
        t0 = time.process_time()
        fn()
        secs.append(time.process_time() - t0)
    return sorted(secs)[RUNS // 2]


def package():
    p.eval(x, y, z, threads=1, out=f)


lib = frep._L()


def raw():
    """frep_eval_par through ctypes on the same arrays: the package's own cost is the
    difference."""
    lib.frep_eval_par(p._h, n, x.ctypes.data, y.ctypes.data, z.ctypes.data, None,
                      f.ctypes.data, 1, None)


cs, ps, rs, ratios, own = [], [], [], [], []
for _ in range(rounds):
    c, c_sum = c_side()
    py = timed(package)
    r = timed(raw)
    cs.append(c)
    ps.append(py)
    rs.append(r)
    ratios.append(py / c)
    own.append(py / r)
same = abs(f.sum() - c_sum) <= 1e-9 * max(1.0, abs(c_sum))

one = np.zeros(1)
calls = []
for _ in range(2000):
    t0 = time.perf_counter()
    p.eval(one, one, one, threads=1)
    calls.append(time.perf_counter() - t0)

med = lambda v: sorted(v)[len(v) // 2]
print("%s: %d points, %d instructions, one thread, CPU time, %d rounds of %d runs" %
      (model, n, p.size, rounds, RUNS))
print("C API %.4f s   Python %.4f s   (medians)   ratio Python/C: median %.3f, rounds %s"
      % (med(cs), med(ps), med(ratios), " ".join("%.2f" % r for r in ratios)))
print("package against frep_eval_par called through ctypes in the same process: "
      "median ratio %.3f" % med(own))
print("same values: %s   one call from Python on 1 point: %.1f us (median of 2000)" %
      (same, med(calls) * 1e6))
