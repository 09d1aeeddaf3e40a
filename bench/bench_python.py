"""bench_python.py - evaluating N points from Python (the frep package) against the
C API (bench/bench_api_eval), one thread, CPU time, medians of RUNS runs
(doc/python.md, "Speed").
    python3 bench_python.py BENCH_API_EVAL MODEL.hf [N [RUNS]]
Needs FREP_LIBRARY (or an installed libfrep) and python/ on PYTHONPATH."""
import subprocess
import sys
import time

import numpy as np

import frep

exe, model = sys.argv[1], sys.argv[2]
n = int(sys.argv[3]) if len(sys.argv) > 3 else 1000000
runs = int(sys.argv[4]) if len(sys.argv) > 4 else 7
out = subprocess.run([exe, model, str(n), str(runs)], capture_output=True, text=True,
                     check=True).stdout.split()
c_secs, c_sum = float(out[1]), float(out[3])

p = frep.compile_file(model)
box = p.box() or (-1, -1, -1, 1, 1, 1)
t = np.linspace(0, 1, n)
x, y, z = (box[k] + t * (box[k + 3] - box[k]) for k in range(3))
f = np.empty(n)
secs = []
for _ in range(runs):
    t0 = time.process_time()
    p.eval(x, y, z, threads=1, out=f)
    secs.append(time.process_time() - t0)
py = sorted(secs)[runs // 2]
same = abs(f.sum() - c_sum) <= 1e-9 * max(1.0, abs(c_sum))
print("%s: %d points, %d instructions, one thread, CPU time medians of %d runs" %
      (model, n, p.size, runs))
print("C API %.4f s   Python %.4f s   ratio %.3f   same values: %s" %
      (c_secs, py, py / c_secs, same))
