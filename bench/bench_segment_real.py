#!/usr/bin/env python3
"""bench_segment_real.py - `frep segment` quality on real data (part of make bench-segment).

For every model of ../shared/data/inversecsg with a mesh (csg_low_res.off) and ground-truth
surfaces (surface_primitives.prim): sample a cloud with `frep sample`, segment it, and
match the detected primitives to the ground truth. Prints per model how many ground-truth
surfaces were recovered, how many detected primitives are spurious, and the parameter
errors of the matches: position and radius relative to the mesh's bounding-box diagonal,
axis or normal angle in degrees.

usage: bench_segment_real.py FREP DATA_DIR [points] [extra segment options...]
"""
import math
import os
import subprocess
import sys
import tempfile

# A detected primitive recovers a ground-truth surface when it has the same type and
# its parameters are within these bounds (fractions of the diagonal, degrees).
MATCH_POS = 0.02
MATCH_DEG = 3.0


def unit(v):
    l = math.sqrt(sum(t * t for t in v))
    return [t / l for t in v], l


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def angle(a, b, oriented=False):
    c = dot(a, b)
    if not oriented:
        c = abs(c)
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def line_dist(p, a, q):
    """Distance of point q from the line through p along unit a."""
    v = [q[i] - p[i] for i in range(3)]
    h = dot(v, a)
    return math.sqrt(max(0.0, dot(v, v) - h * h))


def read_truth(path):
    """Ground truth in frep's conventions: plane (unit n, d) with n.x = d, sphere (c, r),
    cylinder (p, unit a, r)."""
    out = []
    for line in open(path):
        w = line.split()
        if not w:
            continue
        v = [float(t) for t in w[1:]]
        if w[0] == 'plane':  # n.x + d = 0, sign arbitrary
            n, l = unit(v[0:3])
            out.append(('plane', n, -v[3] / l))
        elif w[0] == 'sphere':
            out.append(('sphere', v[0:3], v[3]))
        elif w[0] == 'cylinder':
            a, _ = unit(v[3:6])
            out.append(('cylinder', v[0:3], a, v[6]))
    return out


def read_fit(path):
    """frep's .fit list (geom/fitfile.c)."""
    out = []
    for line in open(path):
        w = line.split()
        if not w or w[0].startswith('#'):
            continue
        v = [float(t) for t in w[1:]]
        if w[0] == 'plane':
            out.append(('plane', v[0:3], v[3]))
        elif w[0] == 'sphere':
            out.append(('sphere', v[0:3], v[3]))
        elif w[0] in ('cylinder', 'cone'):
            out.append((w[0], v[3:6], v[0:3], v[6]))
        elif w[0] == 'torus':
            out.append(('torus', v[3:6], v[0:3], v[6], v[7]))
    return out


def errors(t, f, diag):
    """(position/radius error / diag, angle in degrees) of detected f against truth t, or
    None for another type."""
    if t[0] != f[0]:
        return None
    if t[0] == 'plane':
        s = 1.0 if dot(t[1], f[1]) >= 0 else -1.0
        return abs(t[2] - s * f[2]) / diag, angle(t[1], f[1])
    if t[0] == 'sphere':
        d = math.sqrt(sum((t[1][i] - f[1][i]) ** 2 for i in range(3)))
        return max(d, abs(t[2] - f[2])) / diag, 0.0
    # cylinder: axis line distance (both ways, at the truth's point) and radius
    d = line_dist(f[1], f[2], t[1])
    return max(d, abs(t[3] - f[3])) / diag, angle(t[2], f[2])


def off_diagonal(path):
    with open(path) as fh:
        toks = fh.read().split()
    k = 1 if toks[0] == 'OFF' else 0
    nv = int(toks[k])
    k += 3
    lo = [1e300] * 3
    hi = [-1e300] * 3
    for i in range(nv):
        for j in range(3):
            x = float(toks[k + 3 * i + j])
            lo[j] = min(lo[j], x)
            hi[j] = max(hi[j], x)
    return math.sqrt(sum((hi[j] - lo[j]) ** 2 for j in range(3)))


def main():
    frep, data = sys.argv[1], sys.argv[2]
    npts = int(sys.argv[3]) if len(sys.argv) > 3 else 50000
    extra = sys.argv[4:]
    models = sorted(m for m in os.listdir(data)
                    if os.path.exists(os.path.join(data, m, 'csg_low_res.off'))
                    and os.path.exists(os.path.join(data, m, 'surface_primitives.prim')))
    print('%-28s %5s %9s %8s %10s %10s %8s %8s' % ('model', 'truth', 'recovered', 'spurious',
                                                   'pos med', 'pos max', 'deg med', 'deg max'))
    tot = [0, 0, 0]
    with tempfile.TemporaryDirectory() as tmp:
        for m in models:
            d = os.path.join(data, m)
            cloud = os.path.join(tmp, m + '.xyz')
            fit = os.path.join(tmp, m + '.fit')
            subprocess.run([frep, 'sample', os.path.join(d, 'csg_low_res.off'), '-n', str(npts),
                            '-o', cloud, '--seed', '1', '-q'], check=True)
            subprocess.run([frep, 'segment', cloud, '--seed', '1', '--no-separating', '-q',
                            '-o', fit] + extra, check=True)
            truth = read_truth(os.path.join(d, 'surface_primitives.prim'))
            found = read_fit(fit)
            diag = off_diagonal(os.path.join(d, 'csg_low_res.off'))
            # Greedy matching, best pairs first.
            pairs = []
            for i, t in enumerate(truth):
                for j, f in enumerate(found):
                    e = errors(t, f, diag)
                    if e and e[0] <= MATCH_POS and e[1] <= MATCH_DEG:
                        pairs.append((e[0] / MATCH_POS + e[1] / MATCH_DEG, i, j, e))
            pairs.sort()
            ti, fj, errs = set(), set(), []
            for _, i, j, e in pairs:
                if i in ti or j in fj:
                    continue
                ti.add(i)
                fj.add(j)
                errs.append(e)
            missed = [truth[i][0] for i in range(len(truth)) if i not in ti]
            spur = [found[j][0] for j in range(len(found)) if j not in fj]
            pe = sorted(e[0] for e in errs) or [float('nan')]
            ae = sorted(e[1] for e in errs) or [float('nan')]
            print('%-28s %5d %9d %8d %10.2e %10.2e %8.2f %8.2f' % (
                m, len(truth), len(errs), len(spur), pe[len(pe) // 2], pe[-1],
                ae[len(ae) // 2], ae[-1]))
            if missed or spur:
                print('    missed: %s; spurious: %s' % (
                    ', '.join(sorted(set('%d %s' % (missed.count(k), k) for k in missed))) or '-',
                    ', '.join(sorted(set('%d %s' % (spur.count(k), k) for k in spur))) or '-'))
            tot[0] += len(truth)
            tot[1] += len(errs)
            tot[2] += len(spur)
    print('%-28s %5d %9d %8d' % ('total', tot[0], tot[1], tot[2]))


if __name__ == '__main__':
    main()
