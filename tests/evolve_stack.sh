#!/bin/sh
# evolve_stack.sh - a stack of three cubes each turned its own way beside a slab and a
# cube less a turned corner (the InverseCSG `six_cuboids`, its boxes as frep fitted
# them).  The top cube's bottom is buried in the cube below, but a corner of it shows:
# the box cover places that face past the end of the sides' points (cv_buried), which
# it now measures on the points themselves, not on their patches' turned boxes (0.5
# deeper), and the writer drops the cuts of the cube below's faces that trimmed it
# where the model explains the points as well without them (ft_drop_cuts): 6 boxes,
# one of them cut, as the program (before: the top cube less two boxes, 8 solids).
# Prints TAP. Needs FREP.

: "${FREP:?FREP must name the frep binary}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-evstack.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM

. "$(dirname "$0")/tap.sh"
show() { sed 's/^/# /' "$1"; }
vol() { "$FREP" mesh "$1" -o "$tmp/v.off" -g 128 --check 2>/dev/null | sed -n 's/.*volume \([0-9.e+-]*\).*/\1/p'; }

cat >"$tmp/stack.hf" <<'EOF2'
-- @setops minmax
-- @box -6 -5 -6 8 6 7
my_model(x[3], a[1])
{
    slab = frBox(x, -3.607259, -0.17308, -1.573128, 0.322443, 2.579555, 2.418358, 0.087267129, 0.174541249, 0.261800717);
    cube = frBox(x, -1.903964, 0.58755, -0.904698, 1.289783, 1.289784, 1.289784, -0.174531877, -0.174531983, -0.174532234);
    corner = frBox(x, 4.768952, 3.172661, 0.080491, 5.265875, 2.729614, 3.824537, 0.42953524, -0.71840266, -0.2508469);
    b1 = frBox(x, 2.99892, 1.073987, -0.85122, 1.612226, 1.612228, 1.612234, 7.3e-08, 0.17453252, 0.087266282);
    b2 = frBox(x, 2.823006, 0.789666, 1.683502, 1.289774, 1.289775, 1.289787, 0.220134363, 0.168535486, 0.352892495);
    b3 = frBox(x, 2.768254, 0.728393, 2.867075, 0.967346, 0.967337, 1.038428, 0.062994757, 0.338112892, 0.452360746);
    my_model = slab | (cube \ corner) | b1 | b2 | b3;
}
EOF2

"$FREP" sample "$tmp/stack.hf" -n 10000 --seed 1 -o "$tmp/stack.xyz" -q &&
    nice "$FREP" evolve "$tmp/stack.xyz" -o "$tmp/m.hf" --seed 1 -q 2>"$tmp/err"
st=$?
report $st "sample and evolve the stack"
[ $st = 0 ] || { show "$tmp/err"; echo "1..$n"; exit 1; }

grep -q '^    -- 6 solids: 6 boxes, .* 0 half-spaces$' "$tmp/m.hf" &&
    [ "$(grep -c '^    box_cut_[0-9]* = frBox' "$tmp/m.hf")" = 1 ]
st=$?
report $st "written as the program: 6 boxes, one cut ($(grep -o -- '-- [0-9]* solids.*' "$tmp/m.hf"))"
[ $st = 0 ] || show "$tmp/m.hf"

grep -Eq '^-- (99\.[5-9][0-9]|100\.00)% of 10000 points within epsilon' "$tmp/m.hf"
report $? "the model explains the points ($(grep -o '[0-9.]*% of 10000' "$tmp/m.hf"))"

vt=$(vol "$tmp/stack.hf")
vm=$(vol "$tmp/m.hf")
awk -v a="$vm" -v t="$vt" 'BEGIN { e = (a - t) / t; if (e < 0) e = -e; exit !(a != "" && e < 0.001) }'
report $? "mesh volume $vm within 0.1% of the truth's $vt"

cat >"$tmp/nine.hf" <<'EOF2'
-- @setops minmax
-- @box -6 -6 -4 7 6 7
my_model(x[3], a[1])
{
    top = frBox(x, 2.76477, 2.877911, 2.85701, 0.967344, 0.967346, 1.049136, 0.063000839, 0.33811053, 0.452361111);
    middle = frBox(x, 2.822946, 2.940207, 1.683533, 1.2898, 1.289793, 1.289787, 0.220138061, 0.168527601, 0.35291716);
    base = frBox(x, 2.998915, 3.224473, -0.85122, 1.612226, 1.612226, 1.612234, 3.37e-07, 0.174532532, 0.087267674);
    slab = frBox(x, -3.60728, 1.977391, -1.573127, 0.322443, 2.579578, 2.418356, 0.087267989, 0.174540754, 0.261807938);
    cube = frBox(x, -1.903965, 2.738022, -0.904703, 1.289784, 1.289786, 1.289785, -0.174535967, -0.174530887, -0.174532685);
    corner = frBox(x, 5.834095, 6.537493, 0.283692, 5.949455, 3.902991, 4.722539, 0.42954132, -0.7184037, -0.25085012);
    inner = frBox(x, -1.806777, -2.68067, -0.913139, 0.967337, 0.96734, 0.967339, 0.34906672, 0.523598782, 0.698131497);
    cup = frBox(x, -1.993725, -2.693572, -1.175543, 1.61223, 1.61223, 1.612232, 0.349066372, 0.523598707, 0.698132734);
    hollow = frBox(x, 0.638396, -2.511937, 2.519048, 1.289784, 1.289787, 5.829726, 0.349066372, 0.523598707, 0.698132734);
    my_model = top | middle | base | slab | (cube \ corner) | inner | (cup \ hollow);
}
EOF2
"$FREP" sample "$tmp/nine.hf" -n 10000 --seed 1 -o "$tmp/nine.xyz" -q
report $? "sample the nine cubes"
"$FREP" segment "$tmp/nine.xyz" --seed 1 -o "$tmp/nine.seg" >"$tmp/seg.out" 2>&1
eps=$(sed -n 's/^-- seed 1, epsilon \([0-9.e+-]*\),.*/\1/p' "$tmp/nine.seg")
diag=$(awk 'NR == 1 { for (k = 1; k <= 3; k++) lo[k] = hi[k] = $k }
            { for (k = 1; k <= 3; k++) { if ($k < lo[k]) lo[k] = $k; if ($k > hi[k]) hi[k] = $k } }
            END { print sqrt((hi[1]-lo[1])^2 + (hi[2]-lo[2])^2 + (hi[3]-lo[3])^2) }' "$tmp/nine.xyz")
awk -v e="$eps" -v d="$diag" 'BEGIN { exit !(e != "" && e <= 0.0021 * d) }'
report $? "clean sample, edges in most neighbourhoods: epsilon $eps, the floor of 0.2% of the diagonal $diag"
[ -n "$eps" ] || show "$tmp/seg.out"

vt=$(vol "$tmp/nine.hf")
for s in 1 2; do
    nice "$FREP" evolve "$tmp/nine.xyz" -o "$tmp/n$s.hf" --seed $s -q 2>"$tmp/err"
    report $? "evolve the nine cubes, seed $s"
    sol=$(sed -n 's/^    -- \([0-9]*\) solids: \([0-9]*\) boxes, .* \([0-9]*\) half-spaces$/\1 \2 \3/p' "$tmp/n$s.hf")
    echo "$sol" | awk '{ exit !($1 <= 10 && $1 == $2 && $3 == 0) }'
    st=$?
    report $st "seed $s: at most 10 solids, all boxes ($(grep -o -- '-- [0-9]* solids.*' "$tmp/n$s.hf"))"
    [ $st = 0 ] || show "$tmp/n$s.hf"
    vm=$(vol "$tmp/n$s.hf")
    awk -v a="$vm" -v t="$vt" 'BEGIN { e = (a - t) / t; if (e < 0) e = -e; exit !(a != "" && e < 0.025) }'
    report $? "seed $s: mesh volume $vm within 2.5% of the truth's $vt"
done

tap_done
