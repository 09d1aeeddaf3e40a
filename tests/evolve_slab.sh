#!/bin/sh
# evolve_slab.sh - the slab of InverseCSG's six_cuboids (tests/models/evolve_slab.hf,
# exact), scanned: 50,000 points at 0.5% noise (0.071, as bench/bench_scan.py's n0.5),
# normals removed.  The slab's top face, 0.645 by 5.16, is not fitted at sampler seed
# 2, only constructed (a separating plane); the GA does not see constructed planes, and
# the final growth did not either, so the tree let the slab run 1.2 past its top (all
# ten probes below were inside; Hausdorff 10% on the bench's seed 1).  The final
# growth now joins every primitive (stage_grow_final in evolve/evolve.c).
# Prints TAP. Needs FREP and srcdir.

: "${FREP:?FREP must name the frep binary}"
srcdir=${srcdir:-.}

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-evslab.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM

. "$(dirname "$0")/tap.sh"
show() { sed 's/^/# /' "$1"; }
M="$srcdir/tests/models/evolve_slab.hf"

# Probes along the slab, halfway through its thickness, 0.5 above its top face (above)
# and 0.5 below it (below): slab coordinates (-0.32, v, 2.902 +- 0.5) for v = -1.5 ..
# 2.5, through the model's rotate([5, 10, 15]) and translate.
cat >"$tmp/above" <<'EOF2'
-2.530 -2.360 1.105
-2.773 -1.394 1.191
-3.016 -0.427 1.277
-3.259 0.539 1.363
-3.503 1.505 1.449
EOF2
cat >"$tmp/below" <<'EOF2'
-2.719 -2.320 0.124
-2.963 -1.354 0.210
-3.206 -0.388 0.296
-3.449 0.578 0.382
-3.692 1.544 0.468
EOF2
# inside MODEL FILE: how many of FILE's points MODEL puts inside (f >= 0).
inside() { "$FREP" eval "$1" "$2" | awk '$1 >= 0 { n++ } END { print n + 0 }'; }

a=$(inside "$M" "$tmp/above") b=$(inside "$M" "$tmp/below")
[ "$a" = 0 ] && [ "$b" = 5 ]
report $? "the model puts the probes above the slab outside, those below inside ($a, $b of 5)"

"$FREP" sample "$M" -n 50000 --noise 0.071abs --seed 2 -o "$tmp/c.xyz" -q &&
    awk '{ print $1, $2, $3 }' "$tmp/c.xyz" >"$tmp/scan.xyz" &&
    nice "$FREP" evolve "$tmp/scan.xyz" -o "$tmp/m.hf" --seed 1 -q 2>"$tmp/err"
st=$?
report $st "sample (seed 2, no normals) and evolve"
[ $st = 0 ] || show "$tmp/err"
a=$(inside "$tmp/m.hf" "$tmp/above") b=$(inside "$tmp/m.hf" "$tmp/below")
[ "$a" = 0 ]
report $? "no material above the slab's top face ($a of 5 probes inside)"
[ "$b" = 5 ]
report $? "the slab below it ($b of 5 probes inside)"
# The same part, clean (sampler seed 3): the cube less a turned cube has a pocket wall
# of a few tens of the 50,000 points, about 2 of the GA's 4,096.  The GA put another
# face of the part in its place, and material ran 5.9 from the truth's surface; the
# final growth now swaps such a leaf for the primitive that explains the points the
# tree misses (simplify_swap_leaves in evolve/simplify.c).  Measured: the truth's value
# at 20,000 points of the written model's surface (its faces' exact distances).
"$FREP" sample "$M" -n 50000 --seed 3 -o "$tmp/clean.xyz" -q &&
    nice "$FREP" evolve "$tmp/clean.xyz" -o "$tmp/mc.hf" --seed 1 -q 2>"$tmp/err" &&
    "$FREP" sample "$tmp/mc.hf" -n 20000 --seed 1 -o "$tmp/on.xyz" -q
st=$?
report $st "clean (seed 3): sample, evolve, sample the model's surface"
[ $st = 0 ] || show "$tmp/err"
far=$("$FREP" eval "$M" "$tmp/on.xyz" | awk '{ v = $1 < 0 ? -$1 : $1; if (v > m) m = v } END { print m + 0 }')
awk -v m="$far" 'BEGIN { exit !(m > 0 && m < 0.35) }'
report $? "clean: the model's surface within 0.35 of the truth's (farthest $far)"
tap_done
