#!/usr/bin/env python3
"""bench_segment_anchor.py - frep segment against CGAL's Efficient RANSAC (make bench-segment).

For every model of ../shared/data/inversecsg with a mesh and ground-truth surfaces
(surface_primitives.prim), for seeds 1-3: sample a clean cloud of POINTS points from
csg_high_res.off (the CAD parts facetted at $fn 30-60; csg_low_res.off has spheres of a
dozen facets around) with its true normals (`frep sample --seed S`), then detect primitives with
  - frep segment at its defaults,
  - CGAL's Efficient RANSAC at its defaults (when the CGAL program is given),
  - CGAL with InverseCSG's tuned settings (the model's ransac.conf; models without one
    get the settings most of the others share: epsilon 0.002, cluster_epsilon 0.1,
    min_points 200, normal_threshold 0.9, probability 0.05),
and score each against the ground truth with bench_segment_real.py's matching (same type,
position and radius within 2% of the diagonal, axis within 3 degrees; one detection per
true surface, duplicates count as spurious): recall = matched / true surfaces, precision =
matched / detections. Prints per model the medians over the seeds and the CPU time
(user + system of the detector alone), then the means, minima and CPU totals.

usage: bench_segment_anchor.py FREP DATA_DIR [CGAL_PROGRAM|-] [points] [seeds]
"""
import os
import resource
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_segment_real as R  # noqa: E402

TUNED_FALLBACK = {'epsilon': 0.002, 'cluster_epsilon': 0.1, 'min_points': 200,
                  'normal_threshold': 0.9, 'probability': 0.05}


def tuned(path):
    conf = dict(TUNED_FALLBACK)
    if os.path.exists(path):
        for line in open(path):
            w = line.replace(':', ' ').split()
            if len(w) == 2 and w[0] in conf:
                conf[w[0]] = float(w[1])
    return [str(conf[k]) for k in ('epsilon', 'cluster_epsilon')] + \
        [str(int(conf['min_points']))] + \
        [str(conf[k]) for k in ('normal_threshold', 'probability')]


def timed(cmd, out=None):
    """Run cmd; its CPU seconds (children's user + system)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out is None:
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    else:
        with open(out, 'w') as fh:
            subprocess.run(cmd, check=True, stdout=fh)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def score(truth, found, diag):
    pairs = []
    for i, t in enumerate(truth):
        for j, f in enumerate(found):
            e = R.errors(t, f, diag)
            if e and e[0] <= R.MATCH_POS and e[1] <= R.MATCH_DEG:
                pairs.append((e[0] / R.MATCH_POS + e[1] / R.MATCH_DEG, i, j))
    pairs.sort()
    ti, fj = set(), set()
    for _, i, j in pairs:
        if i in ti or j in fj:
            continue
        ti.add(i)
        fj.add(j)
    rec = len(ti) / len(truth) if truth else 1.0
    prec = len(fj) / len(found) if found else 0.0
    missed = [truth[i][0] for i in range(len(truth)) if i not in ti]
    spur = [found[j][0] for j in range(len(found)) if j not in fj]
    return rec, prec, missed, spur


def main():
    frep, data = sys.argv[1], sys.argv[2]
    cgal = sys.argv[3] if len(sys.argv) > 3 and sys.argv[3] != '-' else None
    npts = int(sys.argv[4]) if len(sys.argv) > 4 else 50000
    seeds = [int(s) for s in sys.argv[5].split(',')] if len(sys.argv) > 5 else [1, 2, 3]
    only = os.environ.get('BENCH_MODELS', '').split()
    models = sorted(m for m in os.listdir(data) if not only or m in only
                    if os.path.exists(os.path.join(data, m, 'csg_high_res.off'))
                    and os.path.exists(os.path.join(data, m, 'surface_primitives.prim')))
    methods = ['frep'] + (['cgal-default', 'cgal-tuned'] if cgal else [])
    head = '%-27s %5s' % ('model', 'truth')
    for me in methods:
        head += ' | %-12s %5s %5s %6s' % (me, 'rec', 'prec', 'CPU s')
    print('medians over seeds %s, %d points, clean with true normals' %
          (','.join(map(str, seeds)), npts))
    print(head)
    agg = {me: ([], [], []) for me in methods}
    with tempfile.TemporaryDirectory() as tmp:
        for m in models:
            d = os.path.join(data, m)
            truth = R.read_truth(os.path.join(d, 'surface_primitives.prim'))
            diag = R.off_diagonal(os.path.join(d, 'csg_low_res.off'))
            per = {me: ([], [], []) for me in methods}
            notes = []
            for s in seeds:
                cloud = os.path.join(tmp, '%s.%d.xyz' % (m, s))
                subprocess.run([frep, 'sample', os.path.join(d, 'csg_high_res.off'), '-n',
                                str(npts), '-o', cloud, '--seed', str(s), '-q'], check=True)
                for me in methods:
                    fit = os.path.join(tmp, '%s.%d.%s.fit' % (m, s, me))
                    if me == 'frep':
                        cpu = timed([frep, 'segment', cloud, '--seed', str(s),
                                     '--no-separating', '-q', '-t', '1', '-o', fit] +
                                    os.environ.get('FREP_SEGMENT_OPTS', '').split())
                    elif me == 'cgal-default':
                        cpu = timed([cgal, cloud, str(s)], fit)
                    else:
                        cpu = timed([cgal, cloud, str(s)] + tuned(os.path.join(d, 'ransac.conf')),
                                    fit)
                    rec, prec, missed, spur = score(truth, R.read_fit(fit), diag)
                    per[me][0].append(rec)
                    per[me][1].append(prec)
                    per[me][2].append(cpu)
                    if me == 'frep' and (missed or spur):
                        notes.append('seed %d: missed %s; spurious %s' % (
                            s, ' '.join(missed) or '-', ' '.join(spur) or '-'))
            row = '%-27s %5d' % (m, len(truth))
            for me in methods:
                r, p, c = (statistics.median(v) for v in per[me])
                agg[me][0].append(r)
                agg[me][1].append(p)
                agg[me][2].append(c)
                row += ' | %-12s %5.2f %5.2f %6.2f' % ('', r, p, c)
            print(row)
            for n in notes:
                print('    frep %s' % n)
    row = '%-27s %5s' % ('mean (min)', '')
    for me in methods:
        r, p, c = agg[me]
        row += ' | %-12s %5.2f %5.2f %6.1f' % ('', statistics.mean(r), statistics.mean(p), sum(c))
    print(row)
    row = '%-27s %5s' % ('minimum', '')
    for me in methods:
        r, p, c = agg[me]
        row += ' | %-12s %5.2f %5.2f %6s' % ('', min(r), min(p), '')
    print(row)


if __name__ == '__main__':
    main()
