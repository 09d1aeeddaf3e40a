#!/bin/sh
# bench_segment.sh - `make bench-segment`: frep segment time on 10^5 and 10^6 points
# sampled from bench_segment.hf (with normals from the sampler, and 10^5 without; the
# median of 3 runs each), and quality on clouds sampled from the InverseCSG meshes in
# ../shared/data/inversecsg when that directory exists (bench_segment_real.py: recovered
# and spurious surfaces against surface_primitives.prim, parameter errors).
# usage: bench_segment.sh FREP SRCDIR
set -eu
FREP=$1
SRC=$2
T=${TMPDIR:-/tmp}/frep-bench-segment.$$
mkdir -p "$T"
trap 'rm -rf "$T"' EXIT

# median3 LABEL COMMAND...: run three times, print the median wall and user times.
median3() {
    label=$1; shift
    for k in 1 2 3; do
        /usr/bin/time -f "%e %U %M" -o "$T/time$k" "$@" > "$T/out$k"
    done
    tail -1 "$T/out1"
    cat "$T/time1" "$T/time2" "$T/time3" | sort -n | sed -n 2p |
        awk -v l="$label" '{ printf "   %s: median of 3: %s s wall (%s s user), %d MB peak\n", l, $1, $2, $3 / 1024 }'
}
echo "== frep segment: synthetic (8 surfaces), 2 threads, $(nproc 2>/dev/null || echo '?') cores, load $(cut -d' ' -f1 /proc/loadavg 2>/dev/null)"
for n in 100000 1000000; do
    "$FREP" sample "$SRC/bench/bench_segment.hf" -n $n -o "$T/c$n.ply" --seed 1 -q
    median3 "$n points" "$FREP" segment "$T/c$n.ply" --seed 1 -t 2
done
# Without normals: PCA + MST orientation included.
"$FREP" sample "$SRC/bench/bench_segment.hf" -n 100000 -o "$T/n.xyz" --seed 1 -q
cut -d' ' -f1-3 "$T/n.xyz" > "$T/p.xyz"
median3 "100000 points without normals" "$FREP" segment "$T/p.xyz" --seed 1 -t 2

DATA=$SRC/../shared/data/inversecsg
if [ -d "$DATA" ] && command -v python3 >/dev/null 2>&1; then
    echo "== InverseCSG meshes (50000 points each) against surface_primitives.prim"
    python3 "$SRC/bench/bench_segment_real.py" "$FREP" "$DATA" 50000 -t 2
else
    echo "== $DATA or python3 not found: real-data benchmark skipped"
fi

# The anchor: CGAL's Efficient RANSAC (libcgal-dev, header-only; bench/cgal_ransac.cpp,
# compiled here and never linked into frep) at its defaults and with InverseCSG's tuned
# settings, against frep's defaults on the same clean clouds, seeds 1-3, with one
# scoring (bench_segment_anchor.py). Skipped without CGAL, a C++ compiler, Debian's
# python3 or the data.
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
if [ -d "$DATA" ] && command -v "$PY" >/dev/null 2>&1; then
    CGAL=-
    CXX=${CXX:-c++}
    if [ -f /usr/include/CGAL/Shape_detection/Efficient_RANSAC.h ] && command -v "$CXX" >/dev/null 2>&1 &&
       "$CXX" -O2 -DNDEBUG -std=c++17 "$SRC/bench/cgal_ransac.cpp" -o "$T/cgal_ransac" -lgmp -lmpfr 2> "$T/cgal.err"; then
        CGAL=$T/cgal_ransac
    else
        echo "== CGAL (libcgal-dev) or a C++ compiler not found: frep's column only"
    fi
    echo "== frep segment vs CGAL Efficient RANSAC, clean 50000-point clouds, seeds 1-3"
    "$PY" "$SRC/bench/bench_segment_anchor.py" "$FREP" "$DATA" "$CGAL" 50000 1,2,3
fi
