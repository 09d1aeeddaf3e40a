#!/usr/bin/python3
"""bench_scan.py - frep on realistic scans of InverseCSG's CAD parts (make bench-scan).

A scanner gives neither exact positions nor normals.  For every model of
../shared/data/inversecsg with a mesh: sample points with `frep sample` (which knows
the true normals), make scan-like clouds from them, and measure

- normals: `frep normals` on the cloud without normals; median angle to the true
  normal (unoriented, degrees) and the share of normals pointing inward (> 90 degrees
  from the true outward normal: a flipped face shows here);
- evolve (unless --normals-only): `frep evolve` with a work budget (generations), the
  result meshed with `frep mesh`; Chamfer and Hausdorff distances to the true mesh and
  both one-sided means (true surface -> model: missing surfaces; model -> true surface:
  extra material), relative to the mesh diagonal (bench/mesh_distance.py's sampling);
  the surfaces `frep segment` finds with the same seed and defaults (what evolve
  combines) matched to surface_primitives.prim (bench/bench_segment_real.py's rules);
  wall time of segment + evolve.

Conditions: clean (with the true normals), Gaussian noise of 0.5% and 1% of the diagonal
on every coordinate with the normals removed, a one-sided scan (the points a depth
buffer sees from three viewing directions of one hemisphere, 0.5% noise) and uneven
density (kept with probability falling 20-fold along x, 0.5% noise).

usage: bench_scan.py FREP DATA_DIR [--points N] [--seeds 1,2,3] [--generations G]
                     [--models a,b,...] [--conditions clean,n0.5,n1,onesided,uneven]
                     [--normals-only] [--threads T] [--max-time S]
Needs /usr/bin/python3 with numpy and scipy; prints a clear message and exits 0 when the
data are absent.
"""
import argparse
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_segment_real as segreal  # noqa: E402
import mesh_distance as md  # noqa: E402

CONDITIONS = ['clean', 'n0.5', 'n1', 'onesided', 'uneven']
# The targets: Chamfer and Hausdorff bounds (fractions of the diagonal) and the
# share of models that must meet both, per condition (clean: all).
TARGET_CHAMFER = 0.005
TARGET_HAUSDORFF = 0.02
TARGET_SHARE = {'clean': 1.0, 'n0.5': 0.9, 'n1': 0.75}
TARGET_NORMAL_DEG = 8.0
# Depth-buffer cell of the one-sided scan, in median point spacings, and the depth
# tolerance (fraction of the diagonal) within which a point counts as the visible one.
SCAN_CELL_SPACINGS = 2.0
SCAN_DEPTH_TOL = 0.01


def read_xyz(path):
    a = np.loadtxt(path, ndmin=2)
    return a[:, :3], (a[:, 3:6] if a.shape[1] >= 6 else None)


def write_xyz(path, p, n=None):
    a = p if n is None else np.hstack([p, n])
    np.savetxt(path, a, fmt='%.9g')


def visible(p, n, view, diag, spacing):
    """Points a depth buffer along -view sees (facing the viewer, nearest in their cell)."""
    v = view / np.linalg.norm(view)
    u = np.cross(v, [1.0, 0.0, 0.0] if abs(v[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(v, u)
    depth = p @ v
    cell = SCAN_CELL_SPACINGS * spacing
    key = np.floor(p @ u / cell).astype(np.int64) * 1000003 + np.floor(p @ w / cell).astype(np.int64)
    order = np.lexsort((-depth, key))
    ks, ds = key[order], depth[order]
    first = np.ones(len(ks), bool)
    first[1:] = ks[1:] != ks[:-1]
    top = np.maximum.accumulate(np.where(first, np.arange(len(ks)), 0))
    ok = ds >= ds[top] - SCAN_DEPTH_TOL * diag
    vis = np.zeros(len(p), bool)
    vis[order[ok]] = True
    return vis & (n @ v > 0)


def make_cloud(frep, mesh, cond, npts, seed, tmp):
    """The cloud of one condition: (points, true normals, normals given to frep or None)."""
    over = 4 if cond in ('onesided', 'uneven') else 1
    raw = os.path.join(tmp, 'raw.xyz')
    subprocess.run([frep, 'sample', mesh, '-n', str(npts * over), '-o', raw, '--seed', str(seed),
                    '-q'], check=True)
    p, n = read_xyz(raw)
    n = n / np.linalg.norm(n, axis=1)[:, None]
    rng = np.random.default_rng(seed * 1000 + CONDITIONS.index(cond))
    diag = float(np.linalg.norm(p.max(0) - p.min(0)))
    if cond == 'onesided':
        spacing = float(np.median(cKDTree(p).query(p[:2000], 2)[0][:, 1]))
        keep = np.zeros(len(p), bool)
        for view in ([1.0, 0.3, 0.8], [-0.8, 0.6, 0.7], [0.1, -1.0, 0.6]):
            keep |= visible(p, n, np.array(view), diag, spacing)
        p, n = p[keep], n[keep]
    elif cond == 'uneven':
        x = (p[:, 0] - p[:, 0].min()) / max(np.ptp(p[:, 0]), 1e-300)
        keep = rng.random(len(p)) < np.exp(-math.log(20.0) * x)
        p, n = p[keep], n[keep]
    if len(p) > npts:
        pick = rng.choice(len(p), npts, replace=False)
        p, n = p[pick], n[pick]
    sigma = {'clean': 0.0, 'n0.5': 0.005, 'n1': 0.01, 'onesided': 0.005, 'uneven': 0.005}[cond]
    p = p + rng.normal(0.0, sigma * diag, p.shape)
    return p, n, (n if cond == 'clean' else None), diag


def normals_error(frep, cloud, truth, tmp, threads):
    out = os.path.join(tmp, 'normals.xyz')
    t0 = time.time()
    r = subprocess.run([frep, 'normals', cloud, '-o', out, '-t', str(threads)],
                       capture_output=True, text=True)
    dt = time.time() - t0
    if r.returncode != 0:
        return None, None, dt, r.stderr.strip()
    _, est = read_xyz(out)
    c = np.sum(est * truth, axis=1)
    deg = np.degrees(np.arccos(np.clip(np.abs(c), 0, 1)))
    return float(np.median(deg)), float(np.mean(c < 0)), dt, r.stderr.strip().splitlines()[-1]


def one_sided(ref_mesh, model_off):
    va, ta = md.read_mesh(ref_mesh)
    vb, tb = md.read_mesh(model_off)
    if len(tb) == 0:
        return [float('nan')] * 4
    rng = np.random.default_rng(1)
    diag = np.linalg.norm(va.max(0) - va.min(0))
    pa, _ = md.sample(va, ta, 100000, rng)
    pb, _ = md.sample(vb, tb, 100000, rng)
    da, _ = cKDTree(pb).query(pa)
    db, _ = cKDTree(pa).query(pb)
    return [0.5 * (da.mean() + db.mean()) / diag, max(da.max(), db.max()) / diag,
            da.mean() / diag, db.mean() / diag]


def surfaces(frep, cloud, prim_path, mesh, seed, tmp, threads):
    if not os.path.exists(prim_path):
        return '-'
    fit = os.path.join(tmp, 'seg.fit')
    r = subprocess.run([frep, 'segment', cloud, '--seed', str(seed), '--no-separating', '-q',
                        '-o', fit, '-t', str(threads)], capture_output=True)
    if r.returncode != 0:
        return 'fail'
    truth = segreal.read_truth(prim_path)
    found = segreal.read_fit(fit)
    diag = segreal.off_diagonal(mesh)
    pairs = []
    for i, t in enumerate(truth):
        for j, f in enumerate(found):
            e = segreal.errors(t, f, diag)
            if e and e[0] <= segreal.MATCH_POS and e[1] <= segreal.MATCH_DEG:
                pairs.append((e[0] / segreal.MATCH_POS + e[1] / segreal.MATCH_DEG, i, j))
    pairs.sort()
    ti, fj = set(), set()
    for _, i, j in pairs:
        if i not in ti and j not in fj:
            ti.add(i)
            fj.add(j)
    return '%d/%d+%d' % (len(ti), len(truth), len(found) - len(fj))


def evolve_run(frep, cloud, mesh, seed, gens, tmp, threads, max_time):
    hf, off = os.path.join(tmp, 'm.hf'), os.path.join(tmp, 'm.off')
    t0 = time.time()
    r = subprocess.run([frep, 'evolve', cloud, '-o', hf, '--seed', str(seed), '--generations',
                        str(gens), '-q', '-t', str(threads)] +
                       (['--max-time', str(max_time)] if max_time > 0 else []),
                       capture_output=True, text=True)
    dt = time.time() - t0
    if r.returncode != 0:
        return None, dt, r.stderr.strip().splitlines()[-1:] or ['failed']
    r = subprocess.run([frep, 'mesh', hf, '-o', off, '-g', '128', '-q'], capture_output=True,
                       text=True)
    if r.returncode != 0:
        return None, dt, ['mesh failed']
    return one_sided(mesh, off), dt, None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('frep')
    ap.add_argument('data')
    ap.add_argument('--points', type=int, default=50000)
    ap.add_argument('--seeds', default='1')
    ap.add_argument('--generations', type=int, default=200)
    ap.add_argument('--models', default='')
    ap.add_argument('--conditions', default=','.join(CONDITIONS))
    ap.add_argument('--normals-only', action='store_true')
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--max-time', type=float, default=0,
                    help='also bound each frep evolve run (seconds; 0: only the generations)')
    a = ap.parse_args()
    if not os.path.isdir(a.data):
        print('bench_scan: %s not found: skipped (it holds the InverseCSG meshes)' % a.data)
        return 0
    models = sorted(m for m in os.listdir(a.data)
                    if os.path.exists(os.path.join(a.data, m, 'csg_low_res.off')))
    if a.models:
        models = [m for m in models if m in a.models.split(',')]
    conds = a.conditions.split(',')
    seeds = [int(s) for s in a.seeds.split(',')]
    print('frep on scan-like clouds: %d points, seeds %s, %s; distances relative to the '
          'diagonal' % (a.points, a.seeds, 'normals only' if a.normals_only
                        else '%d generations' % a.generations))
    if a.normals_only:
        print('%-28s %-9s %4s %9s %8s %7s  %s' % ('model', 'condition', 'seed', 'med deg',
                                                 'inward', 'time', 'frep normals says'))
    else:
        print('%-28s %-9s %4s %8s %8s %8s %8s %7s %10s %7s' % (
            'model', 'condition', 'seed', 'med deg', 'chamfer', 'hausdf', 'missing', 'extra',
            'surfaces', 'time'))
    summary = {c: [0, 0, []] for c in conds}
    for m in models:
        d = os.path.join(a.data, m)
        # the fine mesh, the design: the coarse one is a 12-sided prism for a cylinder and
        # a 72-vertex polyhedron for a sphere, facets a scan of the part would not show
        mesh = os.path.join(d, 'csg_high_res.off')
        if not os.path.exists(mesh):
            mesh = os.path.join(d, 'csg_low_res.off')
        for cond in conds:
            for seed in seeds:
                with tempfile.TemporaryDirectory() as tmp:
                    p, truth, given, _ = make_cloud(a.frep, mesh, cond, a.points, seed, tmp)
                    cloud = os.path.join(tmp, 'c.xyz')
                    write_xyz(cloud, p)
                    med, inward, dt, said = normals_error(a.frep, cloud, truth, tmp, a.threads)
                    if given is not None:
                        write_xyz(cloud, p, given)
                    summary[cond][2].append(med if med is not None else float('nan'))
                    if a.normals_only:
                        print('%-28s %-9s %4d %9.2f %7.2f%% %6.1fs  %s' % (
                            m, cond, seed, med if med is not None else float('nan'),
                            100 * (inward or 0), dt, said))
                        sys.stdout.flush()
                        continue
                    res, dt, why = evolve_run(a.frep, cloud, mesh, seed, a.generations, tmp,
                                              a.threads, a.max_time)
                    surf = surfaces(a.frep, cloud, os.path.join(d, 'surface_primitives.prim'),
                                    mesh, seed, tmp, a.threads)
                    if res is None:
                        print('%-28s %-9s %4d %8.2f  failed: %s' % (m, cond, seed, med or 0,
                                                                    why[0]))
                        summary[cond][1] += 1
                        continue
                    ch, hd, miss, extra = res
                    print('%-28s %-9s %4d %8.2f %7.3f%% %7.2f%% %7.3f%% %6.3f%% %10s %6.1fs' % (
                        m, cond, seed, med, 100 * ch, 100 * hd, 100 * miss, 100 * extra, surf, dt))
                    sys.stdout.flush()
                    summary[cond][1] += 1
                    if ch < TARGET_CHAMFER and hd < TARGET_HAUSDORFF:
                        summary[cond][0] += 1
    print('summary:')
    for c in conds:
        good, runs, degs = summary[c]
        degs = [x for x in degs if x == x]
        line = '  %-9s normals median of medians %.2f deg (target < %g at 0.5%% noise)' % (
            c, float(np.median(degs)) if degs else float('nan'), TARGET_NORMAL_DEG)
        if not a.normals_only:
            line += '; %d of %d runs under %.1f%% Chamfer and %g%% Hausdorff' % (
                good, runs, 100 * TARGET_CHAMFER, 100 * TARGET_HAUSDORFF)
            if c in TARGET_SHARE:
                line += ' (target: %d%%)' % round(100 * TARGET_SHARE[c])
        print(line)
    return 0


if __name__ == '__main__':
    sys.exit(main())
