#!/bin/sh
# segment.sh - end-to-end tests of `frep segment` on clouds made by `frep sample` from
# tests/models/segment_*.hf (a box of six planes, a sphere, a capped cylinder, a cone
# frustum, a torus, all in general position): clean, and with Gaussian noise of 1% of
# the diagonal plus 5% outliers. Every surface must be found with the right type and
# parameters within the tolerances below, and nothing else. Prints TAP.
# Needs FREP (the frep binary) and srcdir (the source tree).

: "${FREP:?FREP must name the frep binary}"
: "${srcdir:?srcdir must name the source tree}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-segment.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM
M="$srcdir/tests/models"

# Points per cloud: enough for the smallest surface (the cone's near cap, 5% of the
# area) to clear the default minimum support of 1% of the points.
NPTS=20000
# Seed of the clouds (another one may be given to check that nothing hangs on luck).
SEED=${SEGMENT_TEST_SEED:-7}
# Tolerances (the models are about 1 unit across, diagonals 2.7 to 3.1):
# positions and radii in model units, directions and the cone angle in degrees.
TOL_POS_CLEAN=0.005
TOL_DEG_CLEAN=0.5
TOL_POS_NOISY=0.03
TOL_DEG_NOISY=2.5

. "$(dirname "$0")/tap.sh"

# The ground truth of each model in the .fit format of frep segment, derived from the
# model sources by hand: unit vectors are the models' vectors divided by their length,
# plane offsets are distances (frPlane normalizes), cylinder and cone points are on
# the axis, the torus line is "torus a c r R". Planes point outward.
truth() {
    case $1 in
    box)
        for v in "2 2 1 0.5" "-2 -2 -1 0.5" "-2 1 2 0.4" "2 -1 -2 0.4" "1 -2 2 0.3" \
                 "-1 2 -2 0.3"; do
            echo "$v" | awk '{ print "plane", $1 / 3, $2 / 3, $3 / 3, $4 }'
        done ;;
    sphere) echo "sphere 0.1 -0.2 0.05 0.7" ;;
    cylinder)
        echo "cylinder 0.333333333 0.666666667 0.666666667 0.3 0 0 0.4"
        echo "plane 0.333333333 0.666666667 0.666666667 0.7"
        echo "plane -0.333333333 -0.666666667 -0.666666667 0.5" ;;
    cone)
        # a = (1, 0, -3) / sqrt(10); the caps are 0.5 and 1.2 from the apex along a.
        echo "cone 0.316227766 0 -0.948683298 0.1 0.1 0.8 0.5"
        echo "plane 0.316227766 0 -0.948683298 0.472676"
        echo "plane -0.316227766 0 0.948683298 0.227324" ;;
    torus) echo "torus 0 0.707106781 0.707106781 0.1 0 -0.1 0.2 0.6" ;;
    esac
}

# compare TRUTH FOUND TOL_POS TOL_DEG: prints "matched spurious worst-detail" where each
# truth line is matched to one found line of its type within the tolerances.
compare() {
    awk -v tp="$3" -v td="$4" '
    function dot(a, b, i, j) { return a[i] * b[j] + a[i + 1] * b[j + 1] + a[i + 2] * b[j + 2] }
    function ang(x) { return atan2(sqrt(1 - (x > 1 ? 1 : x) ^ 2), x) * 57.29577951308232 }
    function absv(x) { return x < 0 ? -x : x }
    # Distance from point (b[j..j+2]) to the line through a[i..] along unit a[k..].
    function linedist(a, i, k, b, j,   d0, d1, d2, h) {
        d0 = b[j] - a[i]; d1 = b[j + 1] - a[i + 1]; d2 = b[j + 2] - a[i + 2]
        h = d0 * a[k] + d1 * a[k + 1] + d2 * a[k + 2]
        return sqrt((d0 - h * a[k]) ^ 2 + (d1 - h * a[k + 1]) ^ 2 + (d2 - h * a[k + 2]) ^ 2)
    }
    function pdist(a, i, b, j) {
        return sqrt((a[i] - b[j]) ^ 2 + (a[i + 1] - b[j + 1]) ^ 2 + (a[i + 2] - b[j + 2]) ^ 2)
    }
    # Worst error of found line f against truth line t, as a multiple of the tolerances
    # (<= 1: a match), or 1e9 for another type.
    function err(t, f,   T, F, e, x) {
        split(t, T, " "); split(f, F, " ")
        if (T[1] != F[1]) return 1e9
        if (T[1] == "plane") {
            e = ang(dot(T, F, 2, 2)) / td
            x = absv(T[5] - F[5]) / tp; if (x > e) e = x
        } else if (T[1] == "sphere") {
            e = pdist(T, 2, F, 2) / tp
            x = absv(T[5] - F[5]) / tp; if (x > e) e = x
        } else if (T[1] == "cylinder") {
            e = ang(absv(dot(T, F, 2, 2))) / td
            x = linedist(T, 5, 2, F, 5) / tp; if (x > e) e = x
            x = absv(T[8] - F[8]) / tp; if (x > e) e = x
        } else if (T[1] == "cone") {
            e = ang(dot(T, F, 2, 2)) / td
            x = pdist(T, 5, F, 5) / tp; if (x > e) e = x
            x = absv(T[8] - F[8]) * 57.29577951308232 / td; if (x > e) e = x
        } else {
            e = ang(absv(dot(T, F, 2, 2))) / td
            x = pdist(T, 5, F, 5) / tp; if (x > e) e = x
            x = absv(T[8] - F[8]) / tp; if (x > e) e = x
            x = absv(T[9] - F[9]) / tp; if (x > e) e = x
        }
        return e
    }
    FNR == NR { t[++nt] = $0; next }
    /^[a-z]/ { f[++nf] = $0 }
    END {
        matched = 0; worst = 0
        for (i = 1; i <= nt; i++) {
            best = 0; be = 1e18
            for (j = 1; j <= nf; j++)
                if (!used[j]) { e = err(t[i], f[j]); if (e < be) { be = e; best = j } }
            if (best && be <= 1) { used[best] = 1; matched++; if (be > worst) worst = be }
            else print "# missed:", t[i], "(best error", be, "x tolerance)" > "/dev/stderr"
        }
        for (j = 1; j <= nf; j++) if (!used[j]) print "# spurious:", f[j] > "/dev/stderr"
        printf "%d %d %.2f\n", matched, nf - matched, worst
    }' "$1" "$2"
}

for model in box sphere cylinder cone torus; do
    truth $model > "$tmp/$model.truth"
    want=$(wc -l < "$tmp/$model.truth")
    for kind in clean noisy; do
        if [ $kind = clean ]; then
            opts="--noise 0 --outliers 0"; tp=$TOL_POS_CLEAN; td=$TOL_DEG_CLEAN
        else
            opts="--noise 0.01 --outliers 0.05"; tp=$TOL_POS_NOISY; td=$TOL_DEG_NOISY
        fi
        c="$tmp/$model-$kind.xyz"
        # shellcheck disable=SC2086
        "$FREP" sample "$M/segment_$model.hf" -n $NPTS $opts --seed "$SEED" -o "$c" -q
        "$FREP" segment "$c" --seed 1 --no-separating -q -o "$tmp/$model-$kind.fit" \
            2> "$tmp/err"
        st=$?
        report $st "$model, $kind: frep segment runs"
        [ $st = 0 ] || { sed 's/^/# /' "$tmp/err"; continue; }
        set -- $(compare "$tmp/$model.truth" "$tmp/$model-$kind.fit" $tp $td 2> "$tmp/cmp")
        sed 's/^/# /' "$tmp/cmp"
        [ "$1" = "$want" ]
        report $? "$model, $kind: all $want surfaces found with the right type and parameters (worst error $3 x tolerance)"
        [ "$2" = 0 ]
        report $? "$model, $kind: no spurious primitive ($2)"
    done
done

# Small and close faces, clean: models written here (axis-aligned, planes only).
#  stairs: three treads 0.065 apart (2 epsilon of its diagonal, 3.17): the old
#          detector put one plane tilted by 3.3 degrees across all three (its band and
#          normal threshold hold them all); the risers (0.9% of the area) need the
#          second phase (--min-points-small).
#  boss:   a 2 x 2 x 0.2 plate with a 0.24 x 0.24 x 0.15 boss: the boss's five faces
#          hold 0.4-0.6% of the points each, under the 1% minimum support.
cat > "$tmp/stairs.hf" <<'EOF'
-- @setops minmax
-- @box -0.2 -0.2 -0.2 3.2 1.2 0.4
my_model(x[3], a[1])
{
  side = frPlane(x, 0, 1, 0, 1) & frPlane(x, 0, -1, 0, 0) & frPlane(x, 1, 0, 0, 3)
       & frPlane(x, 0, 0, -1, 0) & frPlane(x, -1, 0, 0, 0);
  my_model = side & (frPlane(x, 0, 0, 1, 0.065)
                     | (frPlane(x, -1, 0, 0, -1) & frPlane(x, 0, 0, 1, 0.13))
                     | (frPlane(x, -1, 0, 0, -2) & frPlane(x, 0, 0, 1, 0.195)));
}
EOF
printf '%s\n' "plane 0 1 0 1" "plane 0 -1 0 0" "plane 1 0 0 3" "plane 0 0 -1 0" "plane -1 0 0 0" \
    "plane 0 0 1 0.065" "plane 0 0 1 0.13" "plane 0 0 1 0.195" "plane -1 0 0 -1" \
    "plane -1 0 0 -2" > "$tmp/stairs.truth"
cat > "$tmp/boss.hf" <<'EOF'
-- @setops minmax
-- @box -1.2 -1.2 -0.2 1.2 1.2 0.5
my_model(x[3], a[1])
{
  plate = frPlane(x, 1, 0, 0, 1) & frPlane(x, -1, 0, 0, 1) & frPlane(x, 0, 1, 0, 1)
        & frPlane(x, 0, -1, 0, 1) & frPlane(x, 0, 0, 1, 0.2) & frPlane(x, 0, 0, -1, 0);
  boss = frPlane(x, 1, 0, 0, 0.12) & frPlane(x, -1, 0, 0, 0.12) & frPlane(x, 0, 1, 0, 0.12)
       & frPlane(x, 0, -1, 0, 0.12) & frPlane(x, 0, 0, 1, 0.35) & frPlane(x, 0, 0, -1, 0);
  my_model = plate | boss;
}
EOF
printf '%s\n' "plane 1 0 0 1" "plane -1 0 0 1" "plane 0 1 0 1" "plane 0 -1 0 1" \
    "plane 0 0 1 0.2" "plane 0 0 -1 0" "plane 1 0 0 0.12" "plane -1 0 0 0.12" \
    "plane 0 1 0 0.12" "plane 0 -1 0 0.12" "plane 0 0 1 0.35" > "$tmp/boss.truth"
for model in stairs boss; do
    "$FREP" sample "$tmp/$model.hf" -n $NPTS --seed "$SEED" -o "$tmp/$model.xyz" -q
    "$FREP" segment "$tmp/$model.xyz" --seed 1 --no-separating -q -o "$tmp/$model.fit" \
        2> "$tmp/err"
    report $? "$model, clean: frep segment runs"
    want=$(wc -l < "$tmp/$model.truth")
    set -- $(compare "$tmp/$model.truth" "$tmp/$model.fit" $TOL_POS_CLEAN $TOL_DEG_CLEAN \
             2> "$tmp/cmp")
    sed 's/^/# /' "$tmp/cmp"
    [ "$1" = "$want" ] && [ "$2" = 0 ]
    report $? "$model, clean: all $want faces and nothing else ($1 found, $2 spurious)"
done
# Without the second phase the boss's faces are missed (what the option turns off).
"$FREP" segment "$tmp/boss.xyz" --seed 1 --no-separating -q --min-points-small 0 \
    -o "$tmp/boss1.fit" 2> "$tmp/err"
[ "$(grep -c . "$tmp/boss1.fit")" = 6 ]
report $? "boss, --min-points-small 0: only the plate's 6 faces ($(grep -c . "$tmp/boss1.fit"))"

# Right types where another type fits nearly as well, and small curved surfaces, clean,
# at the default settings (tests/models/segment_{dome,stacked,fillet}.hf; truths from
# the model sources: axes and centres as written there, planes outward):
#  dome:    a hemisphere on a cylinder of its radius: a sphere, not a cone or a torus
#           over the dome's rings, and one cylinder for the wall;
#  stacked: two coaxial disks of radii 0.8 and 0.45: two cylinders, not a sphere or a
#           torus through both rims, and the three planes;
#  fillet:  a block with a fillet of radius 0.08 (1.8% of the surface) and a
#           counterbore (hole r 0.12, recess r 0.22 with its floor, 1.2-4%);
#  steps:   a block with a ridge across its top (the top face in two apart patches:
#           one plane, not two) and a cube of side 0.1 standing on it whose four
#           sides hold 0.15% of the surface each (30-40 of the 20,000 points).
truth_more() {
    case $1 in
    dome) printf '%s\n' "cylinder 0 0 1 0 0 0 0.5" "sphere 0 0 0.2 0.5" "plane 0 0 -1 0.6" ;;
    stacked) printf '%s\n' "cylinder 0 0 1 0 0 0 0.8" "cylinder 0 0 1 0 0 0 0.45" \
                 "plane 0 0 -1 0" "plane 0 0 1 0.25" "plane 0 0 1 0.55" ;;
    fillet) printf '%s\n' "plane -1 0 0 1" "plane 0 1 0 0.6" "plane 0 -1 0 0.6" "plane 0 0 -1 0" \
                "plane 1 0 0 1" "plane 0 0 1 0.6" "cylinder 0 1 0 0.92 0 0.52 0.08" \
                "cylinder 0 0 1 -0.4 0 0 0.12" "cylinder 0 0 1 -0.4 0 0 0.22" "plane 0 0 1 0.45" ;;
    steps) printf '%s\n' "plane -1 0 0 1" "plane 1 0 0 1" "plane 0 1 0 0.6" "plane 0 -1 0 0.6" \
               "plane 0 0 -1 0" "plane 0 0 1 0.3" "plane -1 0 0 -0.4" "plane 1 0 0 0.5" \
               "plane 0 0 1 0.4" "plane -1 0 0 0.55" "plane 1 0 0 -0.45" "plane 0 1 0 0.05" \
               "plane 0 -1 0 0.05" ;;
    esac
}
for model in dome stacked fillet steps; do
    truth_more $model > "$tmp/$model.truth"
    want=$(wc -l < "$tmp/$model.truth")
    src="$M/segment_$model.hf"
    [ $model = steps ] && src="$srcdir/tests/segment_steps.hf"
    "$FREP" sample "$src" -n $NPTS --seed "$SEED" -o "$tmp/$model.xyz" -q
    "$FREP" segment "$tmp/$model.xyz" --seed 1 --no-separating -q -o "$tmp/$model.fit" \
        2> "$tmp/err"
    report $? "$model, clean: frep segment runs"
    set -- $(compare "$tmp/$model.truth" "$tmp/$model.fit" $TOL_POS_CLEAN $TOL_DEG_CLEAN \
             2> "$tmp/cmp")
    sed 's/^/# /' "$tmp/cmp"
    [ "$1" = "$want" ]
    report $? "$model, clean: all $want surfaces with their types ($1 found)"
    [ "$2" = 0 ]
    report $? "$model, clean: no other type or duplicate ($2 spurious: $(awk '{ print $1 }' \
        "$tmp/$model.fit" | sort | uniq -c | tr -s ' \n' ' '))"
done

# The default epsilon follows the measured noise: tight on the clean sphere (0.2% of
# the diagonal), 1% on the noisy one (where the band widens to the noise per shape).
eps_of() { "$FREP" segment "$1" --seed 1 --no-separating | awk '/^  epsilon/ { sub(/,/, "", $2); print $2 }'; }
e_clean=$(eps_of "$tmp/sphere-clean.xyz")
e_noisy=$(eps_of "$tmp/sphere-noisy.xyz")
awk -v a="$e_clean" -v b="$e_noisy" 'BEGIN { exit !(a > 0 && b >= 4 * a) }'
report $? "default epsilon from the noise: clean $e_clean, noisy $e_noisy"
# An epsilon far below the noise finds nothing: an error that says so and suggests
# an epsilon, no output file.
"$FREP" segment "$tmp/sphere-noisy.xyz" --seed 1 --epsilon 1e-5 -q -o "$tmp/none.fit" \
    2> "$tmp/err"
st=$?
[ $st = 1 ] && grep -q "below the noise" "$tmp/err" && grep -q -- "try --epsilon" "$tmp/err" &&
    [ ! -e "$tmp/none.fit" ]
report $? "epsilon below the noise: exit $st, explained ($(head -c 160 "$tmp/err"))"
# Errors of the segmentation itself read as every data error does: the command, the
# file, the message; here a cloud of 5 points (at least 8 are needed).
printf '0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 1 1\n' > "$tmp/five.xyz"
"$FREP" segment "$tmp/five.xyz" --seed 1 -q -o "$tmp/five.fit" 2> "$tmp/err"
st=$?
[ $st = 1 ] && grep -q "^frep segment: $tmp/five.xyz: too few points: 5" "$tmp/err" &&
    [ ! -e "$tmp/five.fit" ]
report $? "5 points: exit $st, 'frep segment: FILE: message' ($(head -c 160 "$tmp/err"))"

# Normals estimated by frep (PCA and propagation) instead of the sampler's: the clean
# box and cylinder without their normal columns.
for model in box cylinder; do
    cut -d' ' -f1-3 "$tmp/$model-clean.xyz" > "$tmp/$model-nonormals.xyz"
    "$FREP" segment "$tmp/$model-nonormals.xyz" --seed 1 --no-separating -q \
        -o "$tmp/$model-nonormals.fit" 2> "$tmp/err"
    set -- $(compare "$tmp/$model.truth" "$tmp/$model-nonormals.fit" \
                     $TOL_POS_CLEAN $TOL_DEG_CLEAN 2> "$tmp/cmp")
    sed 's/^/# /' "$tmp/cmp"
    [ "$1" = "$(wc -l < "$tmp/$model.truth")" ] && [ "$2" = 0 ]
    report $? "$model, clean, estimated normals: every surface and nothing else ($1 found, $2 spurious)"
done

# A frame of rails with a sphere at each corner (tests/models/segment_frame.hf) at 0.5%
# and 1% noise, without normals: the rails, infinite cylinders to the detector, take
# most of each corner sphere's points, leaving caps of about 50 points that only the
# second phase sees (at 1% noise epsilon, capped at 1% of the diagonal, is about one
# noise deviation, and only the caps' own bands tell them from leftovers).  Every
# sphere must be found with its centre and radius (0.714) within the tolerance (1.5
# noise deviations), and nothing but the 2 faces, 4 rails and 4 spheres.
for frame in "0.5% 0.005 0.1" "1% 0.01 0.2"; do
    set -- $frame
    "$FREP" sample "$M/segment_frame.hf" -n $NPTS --noise $2 --seed "$SEED" -o "$tmp/frame.xyz" -q
    cut -d' ' -f1-3 "$tmp/frame.xyz" > "$tmp/frame-nonormals.xyz"
    "$FREP" segment "$tmp/frame-nonormals.xyz" --seed 1 --no-separating -q -o "$tmp/frame.fit" \
        2> "$tmp/err"
    report $? "frame, $1 noise, no normals: frep segment runs"
    awk -v tol=$3 '$1 == "sphere" {
             for (sx = -1; sx <= 1; sx += 2) for (sy = -1; sy <= 1; sy += 2)
                 if ((($2 - sx * 2.857) ^ 2 + ($3 - sy * 4.286) ^ 2 + $4 ^ 2) ^ 0.5 <= tol &&
                     ($5 - 0.714) ^ 2 <= tol ^ 2) hit[sx, sy] = 1 }
         END { n = 0; for (k in hit) n++; print n; exit n != 4 }' "$tmp/frame.fit" > "$tmp/n"
    report $? "frame, $1 noise: the 4 corner spheres within $3 ($(cat "$tmp/n") found: $(grep \
        sphere "$tmp/frame.fit" | awk '{ printf "%.3f %.3f %.3f r %.3f; ", $2, $3, $4, $5 }'))"
    [ "$(awk '{ print $1 }' "$tmp/frame.fit" | sort | uniq -c | tr -s ' \n' ' ')" = \
      " 4 cylinder 2 plane 4 sphere " ]
    report $? "frame, $1 noise: 2 planes, 4 cylinders, 4 spheres and nothing else ($(awk \
        '{ print $1 }' "$tmp/frame.fit" | sort | uniq -c | tr -s ' \n' ' '))"
done

# A corner cut off a cube (tests/models/segment_corner.hf): a face of 19 of 50,000
# points.  On the clean sample with its normals the second phase goes down to 0.02% of
# the points (10) and finds it; without normals (estimated ones blend across edges) it
# stays at 0.04% (20) and finds the cube's 6 faces only.
"$FREP" sample "$M/segment_corner.hf" -n 50000 --seed 1 -o "$tmp/corner.xyz" -q
"$FREP" segment "$tmp/corner.xyz" --seed 1 --no-separating -o "$tmp/corner.fit" > "$tmp/out" 2>&1
report $? "corner, clean with normals: frep segment runs"
grep -q '(small 10)' "$tmp/out"
report $? "corner, clean with normals: second phase down to 10 points ($(grep -o '(small [0-9]*)' "$tmp/out"))"
awk '$1 == "plane" && ($2 + $3 + $4) / 3 ^ 0.5 > 0.9994 && ($5 - 1.682976) ^ 2 < 0.005 ^ 2 { n++ }
     END { exit n != 1 }' "$tmp/corner.fit"
report $? "corner, clean with normals: the cut face x + y + z = 2.915 found ($(grep -c plane \
    "$tmp/corner.fit") planes)"
cut -d' ' -f1-3 "$tmp/corner.xyz" > "$tmp/corner-nonormals.xyz"
"$FREP" segment "$tmp/corner-nonormals.xyz" --seed 1 --no-separating -o "$tmp/corner.fit" \
    > "$tmp/out" 2>&1 && grep -q '(small 20)' "$tmp/out"
report $? "corner, estimated normals: second phase stays at 20 points ($(grep -o '(small [0-9]*)' \
    "$tmp/out"))"

# scan NAME MODEL N SEED: N points of tests/models/MODEL.hf at 0.5% noise (sampler's
# seed SEED), normals removed, segmented with seed 1 and no separating primitives into
# $tmp/NAME.fit.
scan() {
    "$FREP" sample "$M/$2.hf" -n "$3" --noise 0.005 --seed "$4" -o "$tmp/$1.xyz" -q &&
    cut -d' ' -f1-3 "$tmp/$1.xyz" > "$tmp/$1-nonormals.xyz" &&
    "$FREP" segment "$tmp/$1-nonormals.xyz" --seed 1 --no-separating -q \
        -o "$tmp/$1.fit" 2> "$tmp/err"
}
# kinds_of FIT: how many primitives of each type, on one line.
kinds_of() { awk '{ print $1 }' "$1" | sort | uniq -c | tr -s ' \n' ' '; }

# Two boxes, one turned (tests/models/segment_two_boxes.hf), at 0.5% noise without
# normals: twelve planes.  A cylinder of the boxes' size lies within the noise band
# across two faces meeting at an edge, and a cone across a face and its neighbours;
# before face_modes (segment/ransac.c) weighed such shapes against the faces of their
# two dominant normals, seeds 1-6 gave 1-5 curved shapes each and no run the 12 planes.
for s in 1 2 3; do
    scan boxes segment_two_boxes 20000 $s
    report $? "two boxes, 0.5% noise (seed $s), no normals: frep segment runs"
    kinds=$(kinds_of "$tmp/boxes.fit")
    [ "$kinds" = " 12 plane " ]
    report $? "two boxes, seed $s: the 12 faces as planes and nothing else ($kinds)"
done

# A tower of three turned cubes (tests/models/segment_tower.hf, the tower of
# InverseCSG's six_cuboids) at 0.5% noise without normals: planes only.  A cone around
# a corner lies within the noise band across strips of the corner's three faces, and a
# cylinder of radius 9 across two nearly parallel faces of a step; their points'
# normals keep their faces' directions (segment/ransac.c, across_faces).  Before
# that test, seeds 1-4 each gave one cone or 1-3 cylinders.
for s in 1 2 3; do
    scan tower segment_tower 25000 $s
    report $? "tower, 0.5% noise (seed $s), no normals: frep segment runs"
    kinds=$(kinds_of "$tmp/tower.fit")
    nplanes=$(grep -c '^plane' "$tmp/tower.fit")
    [ "$(awk '$1 != "plane"' "$tmp/tower.fit" | wc -l)" -eq 0 ]
    report $? "tower, seed $s: nothing curved ($kinds)"
    # And at least 10 of them are the model's faces: within 3 degrees, offsets within 0.1
    # (1% of the diagonal).  The others (10-12 of 13-15 match at seeds 1-3) are tilted
    # by 3-4 degrees between two faces that meet at a shallow angle, where the top of
    # one cube carries the next: issue 13's recall, not yet met here.
    good=$(grep -o 'frPlane([^)]*)' "$M/segment_tower.hf" | sed 's/frPlane(x,//; s/[,)]//g' |
        awk -v fit="$tmp/tower.fit" '
            { n++; a[n] = $1; b[n] = $2; c[n] = $3; d[n] = $4 }
            END { while ((getline l < fit) > 0) { split(l, w, " "); if (w[1] != "plane") continue
                      ok = 0
                      for (i = 1; i <= n; i++) { dot = a[i] * w[2] + b[i] * w[3] + c[i] * w[4]
                          s = dot < 0 ? -1 : 1
                          if (s * dot > cos(3 * 3.14159265 / 180) && (d[i] - s * w[5])^2 < 0.01) ok = 1 }
                      good += ok }
                  print good + 0 }')
    [ "$good" -ge 10 ]
    report $? "tower, seed $s: at least 10 planes are the model's faces ($good of $nplanes)"
done

# Two balls less a notch that leaves a thin cap (tests/models/segment_cap.hf) at 0.5%
# noise without normals: the notch's face x = 3 is narrow, and its normals are blended
# with the cap's other side, 10-12 degrees off, which small_normal_limit refuses
# (segment/ransac.c).  A second-phase plane off the found shapes and parallel to a
# found plane is kept as such a narrow face (narrow_face); before it, seeds 1-3 gave
# planes at x = 2.911, none and 2.874.  The tower above holds the rule's other side: a
# plane across a shallow step is no parallel to snap to (at seed 3 it gave a plane
# between the step's faces and a cylinder).
for s in 1 2 3; do
    scan cap segment_cap 50000 $s
    report $? "cap, 0.5% noise (seed $s), no normals: frep segment runs"
    x3=$(awk '$1 == "plane" && ($2 > 0.999 || $2 < -0.999) { x = $5 * ($2 > 0 ? 1 : -1)
                                                               if ((x - 3)^2 < 0.0025) print x }' "$tmp/cap.fit")
    [ -n "$x3" ]
    report $? "cap, seed $s: the notch's face x = 3 found within 0.05 (${x3:-none}; $(kinds_of "$tmp/cap.fit"))"
done

# Mount's middle less a groove (tests/models/segment_groove.hf) at 0.5% noise without
# normals: the groove, 86 degrees of a cylinder of radius 1.071 along y at x = 0, z =
# 1.571, holds about 1,700 of the 50,000 points.  Before plane_on_arc
# (segment/ransac.c) tried a plane whose inliers' normals disagree with it as the
# cylinder they describe, seeds 2-4 gave one or two planes across the arc and no
# cylinder of that radius.
for s in 2 3 4; do
    scan groove segment_groove 50000 $s
    report $? "groove, 0.5% noise (seed $s), no normals: frep segment runs"
    g=$(awk '$1 == "cylinder" { ay = $3 < 0 ? -$3 : $3; dx = $5; dz = $7 - 1.571
                                if (ay > cos(3 * 3.14159265 / 180) && ($8 - 1.071)^2 < 0.0225 &&
                                    dx * dx + dz * dz < 0.0225) printf "r %.3f at x %.3f z %.3f", $8, $5, $7 }' \
        "$tmp/groove.fit")
    [ -n "$g" ]
    report $? "groove, seed $s: the cylinder within 3 degrees and 0.15 (${g:-none}; $(kinds_of "$tmp/groove.fit"))"
done

# Mount's middle with its bore (tests/models/segment_pocket.hf) at 0.5% noise without
# normals.  The bore's floor, z = -0.071, lies 0.143 (2.2 sigma) above the plate's top
# around it.  Found on its own, the floor's plane lies within the slack band of the
# plate's and their patches touch at cells that wide; before mergeable
# (segment/ransac.c) required a part beside the larger one's patch to be at its level,
# seeds 1-4 folded the floor into the plate (checked here on 1-3).  And no torus across
# the disc's top and the two coaxial walls below it (the disc's side and the bore's):
# such a torus' inliers' normals keep their faces' directions, 90, 0 and 180 degrees
# around its tube, but the walls' normals turn around the axis, so they are not face
# modes; before tube_share counted the modes around the tube, seeds 2, 8 and 9 gave
# one (seed 1's, across the block's side with 0.47 of its normals in three tube
# angles, went when across_faces' share went from 0.5 to 0.45).
for s in 1 2 3 8 9; do
    scan pocket segment_pocket 50000 $s
    report $? "pocket, 0.5% noise (seed $s), no normals: frep segment runs"
    case $s in 1 | 2 | 3)
        z=$(awk '$1 == "plane" { az = $4 < 0 ? -$4 : $4; z = $5 / $4
                                 if (az > 0.999 && (z + 0.071)^2 < 0.0009) printf "z %.3f", z }' \
            "$tmp/pocket.fit")
        [ -n "$z" ]
        report $? "pocket, seed $s: the floor's plane within 0.03 (${z:-none}; $(kinds_of "$tmp/pocket.fit"))" ;;
    esac
    case $s in 2 | 8 | 9)
        [ "$(awk '$1 == "torus"' "$tmp/pocket.fit" | wc -l)" -eq 0 ]
        report $? "pocket, seed $s: no torus ($(kinds_of "$tmp/pocket.fit"))" ;;
    esac
done

# InverseCSG's mount, exact (tests/models/segment_mount.hf), at 0.5% noise without
# normals: no cylinder tilted across the disc.  On seeds 3 and 8 the disc's side was
# fitted as a cylinder of radius 1.71-1.78 tilted 28-32 degrees, whose flanks lie on
# the block's two sides: its normals disagree with it, 0.47-0.49 of them in three
# directions, and across_faces (segment/ransac.c) kept such shapes under 0.5.  (Seed 5
# then gives another, of radius 2.5 tilted 57 degrees.)
for s in 3 8; do
    scan mount segment_mount 50000 $s
    report $? "mount (seed $s): frep segment runs"
    tilted=$(awk '$1 == "cylinder" { az = $4 < 0 ? -$4 : $4
                                     if (az > 0.2 && az < 0.95) printf "r %.2f, a_z %.2f; ", $8, az }' \
        "$tmp/mount.fit")
    [ -z "$tilted" ]
    report $? "mount, seed $s: no tilted cylinder (${tilted:-none}; $(kinds_of "$tmp/mount.fit"))"
done

# InverseCSG's mount_with_hole, exact (tests/models/segment_mount_hole.hf), at 0.5%
# noise without normals: the disc's side and the bore are short walls whose points'
# normals blend with their neighbours'.  On seeds 6-8 the disc's side was a cylinder of
# radius 1.71-1.78 tilted 26-34 degrees through the bore and the block, its band
# widened to its residuals' spread (band_too_wide in segment/ransac.c now rejects such
# a shape), and seed 8 also gave a torus of tube 1.04 between the bore and the groove;
# the disc's side came out upright on none of them.
for s in 6 7 8; do
    scan hole segment_mount_hole 50000 $s
    report $? "mount_with_hole (seed $s): frep segment runs"
    tilted=$(awk '$1 == "cylinder" && $8 > 1 { az = $4 < 0 ? -$4 : $4
                                              if (az > 0.17 && az < 0.985) printf "r %.2f, a_z %.2f; ", $8, az }' \
        "$tmp/hole.fit")
    [ -z "$tilted" ]
    report $? "mount_with_hole, seed $s: no wide cylinder tilted 10-80 degrees (${tilted:-none}; $(kinds_of "$tmp/hole.fit"))"
    case $s in 6 | 8)
        side=$(awk '$1 == "cylinder" { az = $4 < 0 ? -$4 : $4
                                       if (az > 0.995 && $8 > 1.6 && $8 < 1.75) printf "r %.3f", $8 }' "$tmp/hole.fit")
        [ -n "$side" ]
        report $? "mount_with_hole, seed $s: the disc's side upright, radius 1.6-1.75 (${side:-none})" ;;
    esac
done

# Readable .hf output: the clean box written with separating primitives off. The
# fitted values carry round-off (e.g. 1e-13 for 0); the file must show none of it,
# every number at most 10 significant digits, and still evaluate (frep check).
"$FREP" segment "$tmp/box-clean.xyz" --seed 1 --no-separating -q -o "$tmp/box.hf"
report $? "box: .hf written"
! sed 's/--.*//' "$tmp/box.hf" | grep -Eq '[0-9]e-(0[89]|[1-9][0-9])'
report $? "box .hf: no round-off noise like 2.9e-13"
awk '!/^ *--/ { s = $0; gsub(/[^0-9.eE+-]+/, " ", s); k = split(s, w, " ")
     for (i = 1; i <= k; i++) { d = w[i]; sub(/[eE].*/, "", d); gsub(/[^0-9]/, "", d)
         sub(/^0+/, "", d); if (length(d) > 10) bad = 1 } }
     END { exit bad }' "$tmp/box.hf"
report $? "box .hf: at most 10 significant digits per number"
"$FREP" check "$tmp/box.hf" > /dev/null 2>&1
report $? "box .hf: a valid model (frep check)"
# The rounded file against the exact fit: the planes read back from the .hf and the
# .fit differ by far less than the tolerance (1e-7 of the diagonal for offsets; the
# angle test is limited by the arccosine near 1).
awk '/frPlane/ { s = $0; sub(/.*frPlane\(x, /, "", s); sub(/\).*/, "", s); gsub(/,/, "", s)
     print "plane", s }' "$tmp/box.hf" > "$tmp/box-hf.fit"
set -- $(compare "$tmp/box-clean.fit" "$tmp/box-hf.fit" 1e-6 0.01 2> "$tmp/cmp")
[ "$1" = 6 ] && [ "$2" = 0 ]
report $? "box .hf: rounded planes within 1e-6 of the exact fit ($1 of 6)"

tap_done
