#!/bin/sh
# bench_segment.sh - `make bench-segment`: frep segment time on 10^5 and 10^6 points
# sampled from bench_segment.hf (with normals from the sampler, and 10^5 without), and
# on clouds sampled from the InverseCSG meshes in ../shared/data/inversecsg when that
# directory exists (primitive counts against surface_primitives.prim).
# usage: bench_segment.sh FREP SRCDIR
set -eu
FREP=$1
SRC=$2
T=${TMPDIR:-/tmp}/frep-bench-segment.$$
mkdir -p "$T"
trap 'rm -rf "$T"' EXIT

echo "== frep segment: synthetic (8 surfaces), 2 threads"
for n in 100000 1000000; do
    "$FREP" sample "$SRC/bench/bench_segment.hf" -n $n -o "$T/c$n.ply" --seed 1 -q
    /usr/bin/time -f "   %e s wall, %U s user, %M KB peak" \
        "$FREP" segment "$T/c$n.ply" --seed 1 -t 2 | tail -1
done
# Without normals: PCA + MST orientation included.
awk '{print $1, $2, $3}' "$T/c100000.ply" >/dev/null 2>&1 || true
"$FREP" sample "$SRC/bench/bench_segment.hf" -n 100000 -o "$T/n.xyz" --seed 1 -q
cut -d' ' -f1-3 "$T/n.xyz" > "$T/p.xyz"
echo "-- 100000 points without normals"
/usr/bin/time -f "   %e s wall, %U s user, %M KB peak" \
    "$FREP" segment "$T/p.xyz" --seed 1 -t 2 | tail -1

DATA=$SRC/../shared/data/inversecsg
if [ -d "$DATA" ]; then
    echo "== InverseCSG meshes (50000 points each): detected vs ground-truth surfaces"
    for d in "$DATA"/*/; do
        m=$(basename "$d")
        [ -f "$d/csg_low_res.off" ] || continue
        "$FREP" sample "$d/csg_low_res.off" -n 50000 -o "$T/$m.xyz" --seed 1 -q || continue
        "$FREP" segment "$T/$m.xyz" --seed 1 -t 2 --no-separating -o "$T/$m.fit" -q || continue
        got=$(awk '{c[$1]++} END {for (k in c) printf "%s:%d ", k, c[k]}' "$T/$m.fit")
        if [ -f "$d/surface_primitives.prim" ]; then
            want=$(awk '{c[$1]++} END {for (k in c) printf "%s:%d ", k, c[k]}' "$d/surface_primitives.prim")
        else
            want="(no ground truth)"
        fi
        printf '  %-6s found %s| truth %s\n' "$m" "$got" "$want"
    done
else
    echo "== $DATA not found: real-data benchmark skipped"
fi
