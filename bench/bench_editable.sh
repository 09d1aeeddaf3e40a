#!/bin/sh
# bench_editable.sh - `make bench-editable`: the solids of the models frep evolve writes
# against the ground truth's (doc/benchmarks.md, "Editable models").
#
# For each model of ../shared/data/inversecsg with a ground-truth program (csg.scad):
# frep sample (POINTS points of the fine mesh, csg_high_res.off) -> frep evolve (segmenting first, so that the
# primitives carry their inlier figures and are rounded to them; seed 1, at most MAXT s) and the count of solids the written model states (`-- N solids: ...`:
# boxes, cylinders, spheres, cones, tori and the half-spaces left over each count 1)
# against the program's cube/cylinder/sphere calls; also the tree's primitives (what
# each surface as one solid gives) and the tree's size.
#
# usage: FREP=path/to/frep sh bench_editable.sh [SRCDIR]
# Environment: BENCH_EDITABLE_POINTS (10000), BENCH_EDITABLE_MAX_TIME (10 s per run),
# BENCH_EDITABLE_SEED (1), BENCH_EDITABLE_DATA (data folder), BENCH_EDITABLE_MODELS
# (names, default all with a csg.scad).

: "${FREP:?FREP must name the frep binary}"
srcdir=${1:-$(dirname "$0")/..}
tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-bench-editable.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM
PTS=${BENCH_EDITABLE_POINTS:-10000}
MAXT=${BENCH_EDITABLE_MAX_TIME:-10}
SEED=${BENCH_EDITABLE_SEED:-1}
DATA=${BENCH_EDITABLE_DATA:-$srcdir/../shared/data/inversecsg}
if [ ! -d "$DATA" ]; then
    echo "bench-editable: no data folder $DATA: skipped"
    exit 0
fi
models=${BENCH_EDITABLE_MODELS:-$(for d in "$DATA"/*/; do [ -f "$d/csg.scad" ] && basename "$d"; done)}

echo "Editable models: $PTS points per mesh, seed $SEED, evolve at most $MAXT s"
echo
echo "| model | GT solids | tree nodes | tree primitives (x GT) | solids written (x GT) | boxes | cylinders (capped) | spheres | half-spaces |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
: >"$tmp/ratios"
for name in $models; do
    d="$DATA/$name"
    # the fine mesh: the coarse one is a 12-sided prism for a cylinder and a 72-vertex
    # polyhedron for a sphere, whose facets the segmenter rightly finds as planes
    mesh="$d/csg_high_res.off"
    [ -f "$mesh" ] || mesh="$d/csg_low_res.off"
    gts=$(grep -o -E '\b(cube|cylinder|sphere)\s*\(' "$d/csg.scad" | wc -l)
    if ! { "$FREP" sample "$mesh" -n "$PTS" --seed "$SEED" -o "$tmp/r.xyz" -q &&
           "$FREP" evolve "$tmp/r.xyz" -o "$tmp/r.hf" --seed "$SEED" --max-time "$MAXT" -q; } \
           2>"$tmp/err"; then
        echo "| $name | $gts | failed: $(head -c 80 "$tmp/err" | tr '\n|' '  ') | | | | | | |"
        continue
    fi
    nodes=$(sed -n 's/.*tree size \([0-9]*\) nodes, \([0-9]*\) primitives.*/\1/p' "$tmp/r.hf")
    nprim=$(sed -n 's/.*tree size \([0-9]*\) nodes, \([0-9]*\) primitives.*/\2/p' "$tmp/r.hf")
    line=$(grep -m1 '^    -- [0-9]* solids:' "$tmp/r.hf")
    set -- $(echo "$line" | sed 's/[^0-9 ]/ /g')
    sol=$1 box=$2 cyl=$3 cap=$4 sph=$5 hs=$8
    echo "$sol $gts $nprim" >>"$tmp/ratios"
    echo "| $name | $gts | $nodes | $nprim ($(awk -v a="$nprim" -v b="$gts" 'BEGIN { printf "%.2f", a / b }')) | $sol ($(awk -v a="$sol" -v b="$gts" 'BEGIN { printf "%.2f", a / b }')) | $box | $cyl ($cap) | $sph | $hs |"
done
echo
awk '{ r = $1 / $2; p = $3 / $2; s += $1; g += $2; q += $3; if (r <= 1.2) ok++; n++
       if (r > mx) mx = r }
     END { if (n) printf "%d models; solids written / GT: total %.2f, largest %.2f, %d of %d at most 1.2x; tree primitives / GT: total %.2f\n", n, s / g, mx, ok, n, q / g }' "$tmp/ratios"
