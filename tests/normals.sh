#!/bin/sh
# normals.sh - `frep normals` on clouds whose true normals are known (frep sample of a
# box and a capped cylinder in general position, tests/models/segment_*.hf, and a thin
# plate and a 30-degree knife edge, tests/normals_{plate,wedge}.hf), clean and with
# Gaussian noise; then the bad input of frep normals, segment and evolve: too few
# points, all the same, on one line, on one plane, NaN coordinates, normals all zero.
# Prints TAP.
# Needs FREP (the frep binary) and srcdir (the source tree).

: "${FREP:?FREP must name the frep binary}"
: "${srcdir:?srcdir must name the source tree}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-normals.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM
M="$srcdir/tests/models"

# Points per cloud: the plate's wall (0.04) is then about 3 spacings thick, its rim
# faces hold 2% of the points each.
NPTS=20000
# Bounds on the median angle to the true normal (degrees, sign ignored).  The automatic
# neighbourhood aims at a predicted median error of 2 degrees on flat parts
# (geom/normals.c, NORMALS_TARGET_RAD); points within a neighbourhood radius of an edge
# and the cylinder's curvature add to it.  Clean: 3 degrees (PCA of exact samples of
# planes is exact; the cylinder's curvature over 12 neighbours is below a degree).
# Noise of 0.5% of the diagonal: 8 degrees, the target of issue 13 (plain PCA over
# 12 neighbours has 20 to 35 degrees there).
BOUND_CLEAN=3
BOUND_NOISY=8
# Share of normals pointing inward (> 90 degrees from the true outward normal): points
# at sharp edges may go either way (the plate's rim, 8% of its points, is 7 noise
# deviations wide); a flipped face puts a whole face inward (46% of the points for a
# side of the plate, 10% and more for the other models' faces), and no face may have
# half of its points inward (the rim faces, 1.8% each, are caught by this).
MAX_INWARD=0.02
# Noise as a fraction of the sampling box's diagonal (2.77 for these models): 0.5%
# (0.014, as issue 13 asks, about the point spacing) for the box and the cylinder; 0.2%
# for the plate (0.0055: its wall of 0.04 is then 7 deviations thick; at 0.5% the two
# sides' points overlap and no estimate can tell them apart).

. "$(dirname "$0")/tap.sh"

# measure TRUTH.xyz EST.xyz: "median_deg inward_share worst_face_inward_share"; faces
# are the groups of points with the same true normal (to 3 decimals; the cylinder's
# side points each have their own).
measure() {
    paste -d ' ' "$1" "$2" | awk '
    {
        l1 = sqrt($4 * $4 + $5 * $5 + $6 * $6); l2 = sqrt($10 * $10 + $11 * $11 + $12 * $12);
        c = ($4 * $10 + $5 * $11 + $6 * $12) / (l1 * l2);
        if (c > 1) c = 1; if (c < -1) c = -1;
        a = c < 0 ? -c : c;
        deg = atan2(sqrt(1 - a * a), a) * 180 / 3.141592653589793;
        print deg > "'"$tmp"'/deg";
        inward += (c < 0);
        key = sprintf("%.3f %.3f %.3f", $4 / l1, $5 / l1, $6 / l1);
        cnt[key]++; inw[key] += (c < 0);
    }
    END {
        worst = 0;
        for (k in cnt) if (cnt[k] >= 100 && inw[k] / cnt[k] > worst) worst = inw[k] / cnt[k];
        printf "%d %.6f %.4f\n", NR, inward / NR, worst;
    }' > "$tmp/m" || return 1
    nr=$(cut -d ' ' -f 1 "$tmp/m")
    med=$(sort -g "$tmp/deg" | awk -v n="$nr" 'NR == int((n + 1) / 2) { print; exit }')
    echo "$med $(cut -d ' ' -f 2,3 "$tmp/m")"
}

model_path() { # the plate and the wedge are kept apart from tests/models (tests/mesh.sh
    # meshes those)
    case $1 in normals_*) echo "$srcdir/tests/$1.hf" ;; *) echo "$M/$1.hf" ;; esac
}
# The wedge (tests/normals_wedge.hf): a knife edge of 30 degrees, whose faces' normals
# are 150 degrees apart; the plain sign of n1.n2 across it turned a face inside out
# (35% of the clean points inward); noise 0.2% as for the plate (the knife edge is
# thinner than the noise over its first 0.02).
for model in segment_box segment_cylinder normals_plate normals_wedge; do
    noisy=0.005
    case $model in normals_*) noisy=0.002 ;; esac
    for noise in 0 $noisy; do
        name="$model, noise $noise"
        if ! "$FREP" sample "$(model_path $model)" -n $NPTS --seed 3 --noise $noise -o "$tmp/t.xyz" -q; then
            report 1 "$name: frep sample"
            continue
        fi
        awk '{ print $1, $2, $3 }' "$tmp/t.xyz" > "$tmp/p.xyz"
        if ! "$FREP" normals "$tmp/p.xyz" -o "$tmp/e.xyz" -q 2>"$tmp/err"; then
            report 1 "$name: frep normals: $(cat "$tmp/err")"
            continue
        fi
        set -- $(measure "$tmp/t.xyz" "$tmp/e.xyz")
        bound=$BOUND_CLEAN
        [ "$noise" = 0 ] || bound=$BOUND_NOISY
        awk -v m="$1" -v b="$bound" 'BEGIN { exit !(m < b) }'
        report $? "$name: median angle $1 deg < $bound"
        awk -v s="$2" -v w="$3" -v b="$MAX_INWARD" 'BEGIN { exit !(s < b && w < 0.5) }'
        report $? "$name: inward share $2 < $MAX_INWARD, worst face $3 < 0.5 (no face flipped)"
    done
done

# The crevice (tests/normals_crevice.hf): a block on a plate turned by 30 degrees, whose
# bottom face leaves the plate's top at 30 degrees; the outward normals of the two faces
# are 150 degrees apart.  Clean, the reflection rule keeps both outward.  At 0.5% noise
# (seed 3) the unoriented normals turn by only 30 degrees around the crevice's tip, the
# sign carried across it by the spanning tree is wrong and the whole block came out
# inward (a third of the points); the ray-parity check of each patch (geom/normals.c)
# must turn it back (the cuboid stacks of ../shared/data/inversecsg kept 19-38% inward
# for this reason).
for noise in 0 0.005; do
    name="normals_crevice, noise $noise"
    if ! "$FREP" sample "$(model_path normals_crevice)" -n $NPTS --seed 3 --noise $noise -o "$tmp/t.xyz" -q ||
        ! awk '{ print $1, $2, $3 }' "$tmp/t.xyz" > "$tmp/p.xyz" ||
        ! "$FREP" normals "$tmp/p.xyz" -o "$tmp/e.xyz" -q 2>"$tmp/err"; then
        report 1 "$name: frep sample or normals: $(cat "$tmp/err")"
        continue
    fi
    set -- $(measure "$tmp/t.xyz" "$tmp/e.xyz")
    awk -v s="$2" -v w="$3" -v b="$MAX_INWARD" 'BEGIN { exit !(s < b && w < 0.5) }'
    report $? "$name: inward share $2 < $MAX_INWARD, worst face $3 < 0.5 (no face flipped)"
done

# The slab (tests/normals_slab.hf): at 0.5% noise a neighbourhood of the narrow faces'
# points reaches across one of their edges almost everywhere, and the reweighted fits
# kept a tilt (median 8.7-9.8 degrees, seeds 1-3); each point now takes the plane of a
# flatter neighbourhood that passes through it (geom/normals.c, shift_point): 3.6-4.5.
SLAB_NARROW_DEG=6
for seed in 1 3; do
    name="normals_slab, noise 0.005, seed $seed"
    if ! "$FREP" sample "$(model_path normals_slab)" -n $NPTS --seed $seed --noise 0.005 -o "$tmp/t.xyz" -q ||
        ! awk '{ print $1, $2, $3 }' "$tmp/t.xyz" > "$tmp/p.xyz" ||
        ! "$FREP" normals "$tmp/p.xyz" -o "$tmp/e.xyz" -q 2>"$tmp/err"; then
        report 1 "$name: frep sample or normals: $(cat "$tmp/err")"
        continue
    fi
    # the narrow faces: true normal across z
    med=$(paste -d ' ' "$tmp/t.xyz" "$tmp/e.xyz" | awk '
        $6 < 0.5 && $6 > -0.5 {
            c = $4 * $10 + $5 * $11 + $6 * $12; if (c < 0) c = -c; if (c > 1) c = 1;
            print atan2(sqrt(1 - c * c), c) * 180 / 3.141592653589793 }' |
        sort -g | awk '{ v[NR] = $1 } END { print NR ? v[int((NR + 1) / 2)] : 90 }')
    awk -v m="$med" -v b="$SLAB_NARROW_DEG" 'BEGIN { exit !(m < b) }'
    report $? "$name: narrow faces' median angle $med deg < $SLAB_NARROW_DEG"
    set -- $(measure "$tmp/t.xyz" "$tmp/e.xyz")
    awk -v s="$2" -v w="$3" -v b="$MAX_INWARD" 'BEGIN { exit !(s < b && w < 0.5) }'
    report $? "$name: inward share $2 < $MAX_INWARD, worst face $3 < 0.5 (no face flipped)"
done

# The cup (tests/normals_cup.hf): an open box with walls 0.11 thick, the thin walls of
# InverseCSG's nine_cuboids (its hollow cube keeps 8-10% of its normals inward at 0.5%
# noise).  At 0.5% noise (0.014) the walls are 8 noise deviations thick and both sides
# stay outward.  At 1% (0.028, 4 deviations, as nine_cuboids' walls at 0.5%) 2.2% of
# the points lie past their wall's midpoint, nearer the other sheet, where no estimate
# from positions can give them their own sheet's normal: the share inward is counted
# against the sheet nearest each point (cup_inward).  While the ray-parity check
# (geom/normals.c) counted every run of hits as a crossing, the stray feet inside the
# walls turned the votes of the inner faces and 5.5-18% came out inward (seeds 1-3), a
# whole inner wall on seeds 1 and 3; now 5.0-5.5%, every face under 8% inward (a
# flipped wall puts 35-40% of its face inward).
CUP_MAX_INWARD=0.08
CUP_MAX_FACE=0.2

# cup_inward TRUTH.xyz EST.xyz: the share of EST's normals pointing away from the
# outward normal of the cup's sheet nearest each point (the faces of tests/normals_cup.hf
# in its own frame: the outer cube of half size 0.5 without the top's opening, the
# cavity's four sides and floor at 0.39).
cup_inward() {
    paste -d ' ' "$1" "$2" | awk '
    function clamp(v, lo, hi) { return v < lo ? lo : v > hi ? hi : v }
    # face ax = val, outward along sg times axis ax, the other two axes in [l1, h1] x [l2, h2]
    function face(ax, val, sg, l1, h1, l2, h2,   o1, o2, d2) {
        o1 = ax == 0 ? 1 : 0; o2 = ax == 2 ? 1 : 2;
        d2 = (u[ax] - val) ^ 2 + (u[o1] - clamp(u[o1], l1, h1)) ^ 2 + (u[o2] - clamp(u[o2], l2, h2)) ^ 2;
        if (d2 < best) { best = d2; bax = ax; bsg = sg }
    }
    BEGIN { split("2 2 1 -2 1 2 1 -2 2", R, " "); a = 0.5; b = 0.39 }
    {
        for (k = 0; k < 3; k++) u[k] = (R[3 * k + 1] * $1 + R[3 * k + 2] * $2 + R[3 * k + 3] * $3) / 3;
        best = 1e300;
        for (k = 0; k < 3; k++) { face(k, -a, -1, -a, a, -a, a); if (k < 2) face(k, a, 1, -a, a, -a, a) }
        face(2, a, 1, -a, a, b, a); face(2, a, 1, -a, a, -a, -b);
        face(2, a, 1, b, a, -b, b); face(2, a, 1, -a, -b, -b, b);
        for (k = 0; k < 2; k++) { face(k, b, -1, -b, b, -b, a); face(k, -b, 1, -b, b, -b, a) }
        face(2, -b, 1, -b, b, -b, b);
        dot = bsg * (R[3 * bax + 1] * $10 + R[3 * bax + 2] * $11 + R[3 * bax + 3] * $12);
        inward += dot < 0;
    }
    END { printf "%.6f\n", inward / NR }'
}

for noise in 0.005 0.01; do
    seeds=3
    [ $noise = 0.01 ] && seeds="1 2 3"
    for seed in $seeds; do
        name="normals_cup, noise $noise, seed $seed"
        if ! "$FREP" sample "$(model_path normals_cup)" -n $NPTS --seed $seed --noise $noise -o "$tmp/t.xyz" -q ||
            ! awk '{ print $1, $2, $3 }' "$tmp/t.xyz" > "$tmp/p.xyz" ||
            ! "$FREP" normals "$tmp/p.xyz" -o "$tmp/e.xyz" -q 2>"$tmp/err"; then
            report 1 "$name: frep sample or normals: $(cat "$tmp/err")"
            continue
        fi
        set -- $(measure "$tmp/t.xyz" "$tmp/e.xyz")
        if [ $noise = 0.005 ]; then
            awk -v s="$2" -v w="$3" -v b="$MAX_INWARD" 'BEGIN { exit !(s < b && w < 0.5) }'
            report $? "$name: inward share $2 < $MAX_INWARD, worst face $3 < 0.5 (no wall flipped)"
        else
            near=$(cup_inward "$tmp/t.xyz" "$tmp/e.xyz")
            awk -v s="$near" -v w="$3" -v b="$CUP_MAX_INWARD" -v f="$CUP_MAX_FACE" \
                'BEGIN { exit !(s < b && w < f) }'
            report $? "$name: inward vs the nearest sheet $near < $CUP_MAX_INWARD, worst face $3 < $CUP_MAX_FACE (no wall flipped)"
        fi
    done
done

# The same result at any thread count, and an explicit --knn.
"$FREP" sample "$M/segment_box.hf" -n 5000 --seed 1 --noise 0.005 -o "$tmp/t.xyz" -q
awk '{ print $1, $2, $3 }' "$tmp/t.xyz" > "$tmp/p.xyz"
"$FREP" normals "$tmp/p.xyz" -o "$tmp/e1.xyz" -t 1 -q && "$FREP" normals "$tmp/p.xyz" -o "$tmp/e2.xyz" -t 2 -q &&
    cmp -s "$tmp/e1.xyz" "$tmp/e2.xyz"
report $? "the same normals with 1 and 2 threads"
"$FREP" normals "$tmp/p.xyz" -o "$tmp/e3.xyz" --knn 40 2>"$tmp/err" && grep -q " 40 neighbours," "$tmp/err"
report $? "--knn 40 is used: $(cat "$tmp/err")"
"$FREP" normals "$tmp/p.xyz" -o "$tmp/e3.xyz" --knn 2 2>"$tmp/err"
[ $? = 2 ] && grep -q "knn" "$tmp/err"
report $? "--knn 2 is a usage error"

# ---- bad input: a clear message, a non-zero exit below 128 (no crash) ----------------
# expect_fail CMD FILE PATTERN DESCRIPTION [extra args]
expect_fail() {
    cmd=$1 file=$2 pat=$3 what=$4
    shift 4
    case $cmd in
        normals) "$FREP" normals "$file" -o "$tmp/out.xyz" "$@" >/dev/null 2>"$tmp/err" ;;
        segment) "$FREP" segment "$file" --seed 1 -o "$tmp/out.fit" "$@" >/dev/null 2>"$tmp/err" ;;
        evolve) "$FREP" evolve "$file" --seed 1 -o "$tmp/out.hf" --generations 5 "$@" >/dev/null 2>"$tmp/err" ;;
    esac
    st=$?
    [ $st -ne 0 ] && [ $st -lt 128 ] && grep -q -- "$pat" "$tmp/err"
    report $? "$cmd: $what: exit $st, $(head -n 1 "$tmp/err")"
}

printf '0 0 0\n1 0 0\n' > "$tmp/two.xyz"
awk 'BEGIN { for (i = 0; i < 50; i++) print "0.5 0.25 -1" }' > "$tmp/same.xyz"
awk 'BEGIN { for (i = 0; i < 200; i++) print i / 100, 2 * i / 100, -i / 100 }' > "$tmp/line.xyz"
awk 'BEGIN { srand(5); for (i = 0; i < 2000; i++) print rand(), rand(), 0.25 }' > "$tmp/plane.xyz"
awk 'BEGIN { srand(5); for (i = 0; i < 2000; i++) { u = rand(); v = rand();
    print u, v, 0.5 * u - 0.25 * v } }' > "$tmp/tilted.xyz"
printf '0 0 0\nnan 1 0\n1 1 1\n' > "$tmp/nan.xyz"
awk '{ print $1, $2, $3, 0, 0, 0 }' "$tmp/p.xyz" > "$tmp/zero.xyz"
for cmd in normals segment evolve; do
    expect_fail $cmd "$tmp/two.xyz" "too few points" "two points"
    expect_fail $cmd "$tmp/same.xyz" "all 50 points are the same" "one point 50 times"
    expect_fail $cmd "$tmp/line.xyz" "all 200 points lie on one line" "points on a line"
    expect_fail $cmd "$tmp/nan.xyz" "nan.xyz:2:" "NaN coordinates"
done
expect_fail evolve "$tmp/plane.xyz" "lie on one plane" "coplanar points"
expect_fail segment "$tmp/zero.xyz" "all 5000 normals are zero" "normals all zero"
expect_fail evolve "$tmp/zero.xyz" "all 5000 normals are zero" "normals all zero"

# What is no error: frep normals replaces zero normals, and the normals of a tilted
# plane are its normal (0.5, -0.25, -1)/|..| up to the sign, all with one sign; frep
# segment finds the one plane of a coplanar cloud.
"$FREP" normals "$tmp/zero.xyz" -o "$tmp/out.xyz" -q
report $? "normals: a cloud with zero normals gets new ones"
"$FREP" normals "$tmp/tilted.xyz" -o "$tmp/out.xyz" -q &&
    awk 'BEGIN { l = sqrt(0.25 + 0.0625 + 1) }
         { c = (0.5 * $4 - 0.25 * $5 - $6) / l; if (c < 0.9999 && c > -0.9999) bad++;
           if (c > 0) pos++; else neg++ }
         END { exit !(bad == 0 && (pos == 0 || neg == 0)) }' "$tmp/out.xyz"
report $? "normals: a tilted plane's normals are its normal, consistently oriented"
"$FREP" segment "$tmp/plane.xyz" --seed 1 -o "$tmp/out.fit" -q --no-separating &&
    [ "$(grep -c '^plane' "$tmp/out.fit")" = 1 ]
report $? "segment: one plane in a coplanar cloud"

tap_done
