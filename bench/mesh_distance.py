#!/usr/bin/python3
# mesh_distance.py - symmetric Chamfer and Hausdorff distances between two triangle
# meshes (.off, .obj or ASCII/binary .stl), relative to the bounding-box diagonal of the
# first; a benchmark helper of bench/bench_evolve.sh (frep evolve on real data), not
# part of make check.  Needs numpy and scipy (cKDTree).
#
# Both meshes are sampled area-weighted (fixed seed); the distance of a sample to the
# other mesh is approximated by the distance to the nearest of the other's samples, which
# overestimates it by about half the sample spacing (reported as "resolution").
#
# usage: mesh_distance.py REFERENCE OTHER [SAMPLES]   prints: chamfer hausdorff resolution
import struct
import sys

import numpy as np
from scipy.spatial import cKDTree


def read_off(path):
    with open(path) as f:
        words = []
        for line in f:
            line = line.split("#", 1)[0].strip()
            if line:
                words.extend(line.split())
    if not words[0].startswith("OFF"):
        raise ValueError("%s: not an OFF file" % path)
    i = 1
    nv, nf = int(words[i]), int(words[i + 1])
    i += 3
    v = np.array(words[i:i + 3 * nv], dtype=float).reshape(nv, 3)
    i += 3 * nv
    tris = []
    for _ in range(nf):
        k = int(words[i])
        idx = [int(w) for w in words[i + 1:i + 1 + k]]
        i += 1 + k
        for j in range(1, k - 1):
            tris.append((idx[0], idx[j], idx[j + 1]))
    return v, np.array(tris, dtype=int)


def read_obj(path):
    v, tris = [], []
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w:
                continue
            if w[0] == "v":
                v.append([float(t) for t in w[1:4]])
            elif w[0] == "f":
                idx = [int(t.split("/")[0]) - 1 for t in w[1:]]
                for j in range(1, len(idx) - 1):
                    tris.append((idx[0], idx[j], idx[j + 1]))
    return np.array(v), np.array(tris, dtype=int)


def read_stl(path):
    data = open(path, "rb").read()
    if data[:5] == b"solid" and b"facet" in data[:300]:
        pts = [float(t) for line in data.decode().splitlines()
               if line.strip().startswith("vertex") for t in line.split()[1:4]]
        v = np.array(pts).reshape(-1, 3)
    else:
        n = struct.unpack("<I", data[80:84])[0]
        rec = np.frombuffer(data[84:84 + 50 * n], dtype=np.dtype([("n", "<f4", 3),
                            ("v", "<f4", 9), ("a", "<u2")]))
        v = rec["v"].reshape(-1, 3).astype(float)
    return v, np.arange(len(v)).reshape(-1, 3)


def read_mesh(path):
    if path.endswith(".off"):
        return read_off(path)
    if path.endswith(".obj"):
        return read_obj(path)
    if path.endswith(".stl"):
        return read_stl(path)
    raise ValueError("%s: unknown mesh format" % path)


def sample(v, t, n, rng):
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    face = rng.choice(len(t), size=n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    return (1 - s)[:, None] * a[face] + (s * (1 - r2))[:, None] * b[face] + \
        (s * r2)[:, None] * c[face], area.sum()


def main():
    if len(sys.argv) < 3:
        sys.exit("usage: mesh_distance.py REFERENCE OTHER [SAMPLES]")
    n = int(sys.argv[3]) if len(sys.argv) > 3 else 200000
    rng = np.random.default_rng(1)
    va, ta = read_mesh(sys.argv[1])
    vb, tb = read_mesh(sys.argv[2])
    if len(ta) == 0 or len(tb) == 0:
        print("nan nan nan")
        return
    diag = np.linalg.norm(va.max(axis=0) - va.min(axis=0))
    pa, area = sample(va, ta, n, rng)
    pb, _ = sample(vb, tb, n, rng)
    da, _ = cKDTree(pb).query(pa)
    db, _ = cKDTree(pa).query(pb)
    chamfer = 0.5 * (da.mean() + db.mean())
    hausdorff = max(da.max(), db.max())
    resolution = 0.5 * np.sqrt(area / n)
    print("%.6g %.6g %.6g" % (chamfer / diag, hausdorff / diag, resolution / diag))


if __name__ == "__main__":
    main()
