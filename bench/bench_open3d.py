#!/usr/bin/python3
"""bench_open3d.py - cross-check of frep's meshes with Open3D (make bench-open3d).

Meshes each model with `frep mesh --check-intersections` (OFF, full precision) and loads the file in
Open3D (Debian's python3-open3d): is_watertight(), is_self_intersecting() and
get_volume() against frep's own volume.  Open3D tests every pair of triangles that
share no vertex (quadratic in the triangles), so grids stay small.
Usage: bench_open3d.py FREP SRCDIR [GRID...]
"""
import os
import re
import subprocess
import sys
import tempfile

try:
    import open3d as o3d
except ImportError:
    print("# open3d is not installed (apt-get install python3-open3d): skipped")
    sys.exit(0)

frep, srcdir = sys.argv[1], sys.argv[2]
grids = [int(g) for g in sys.argv[3:]] or [32, 64]
models = sorted(os.path.join(srcdir, "examples", f) for f in os.listdir(os.path.join(srcdir, "examples"))
                if f.endswith(".hf"))
bad = 0
with tempfile.TemporaryDirectory() as tmp:
    out = os.path.join(tmp, "m.off")
    for g in grids:
        for m in models:
            r = subprocess.run([frep, "mesh", m, "-g", str(g), "-o", out, "--check-intersections", "-q", "-t", "1"],
                               capture_output=True, text=True)
            vol = re.search(r"volume ([-0-9.e+]+)", r.stdout)
            pairs = re.search(r"self-intersecting triangle pairs (\d+)", r.stdout)
            mesh = o3d.io.read_triangle_mesh(out)
            wt, si = mesh.is_watertight(), mesh.is_self_intersecting()
            ov = mesh.get_volume() if wt and not si else float("nan")
            fv = float(vol.group(1)) if vol else float("nan")
            agree = abs(ov - fv) <= 1e-6 * abs(fv)
            ok = wt and not si and agree
            bad += not ok
            print("%-16s -g %-4d %7d triangles  watertight %-5s self-intersecting %-5s "
                  "volume open3d %.6g frep %.6g  frep pairs %s  %s"
                  % (os.path.basename(m), g, len(mesh.triangles), wt, si, ov, fv,
                     pairs.group(1) if pairs else "?", "ok" if ok else "DIFFERS"))
print("# %d disagreement(s)" % bad)
sys.exit(1 if bad else 0)
