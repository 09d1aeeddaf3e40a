#!/bin/sh
# evolve_model.sh - the model frep evolve writes, as a CAD user reads and edits it
# (evolve/canon.c): a plate with two bores sampled with noise by frep sample,
# segmented and evolved.  Names by role, cylinder axis points near the part, no number
# printed finer than its standard error, editing a bore's radius changes the volume by
# the analytic amount, the bounded tree written without a clipping box, and the
# OpenSCAD export of the model agreeing with frep mesh (when OpenSCAD and numpy/scipy
# are installed).  Prints TAP. Needs FREP.

: "${FREP:?FREP must name the frep binary}"
src=${srcdir:-$(cd "$(dirname "$0")/.." && pwd)}

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-evmodel.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM

. "$(dirname "$0")/tap.sh"
skip() { n=$((n + 1)); echo "ok $n # SKIP $1"; }
show() { sed 's/^/# /' "$1"; }

# A 4 x 2 x 0.5 plate with bores of radius 0.25 at x = -1.2 and 1.2.
cat >"$tmp/plate.hf" <<'EOF'
-- @setops minmax
-- @box -2.5 -1.5 -0.5 2.5 1.5 1
my_model(x[3], a[1])
{
    array lo[3], c[3];
    lo = [-2, -1, 0];
    plate = hfBlock(x, lo, 4, 2, 0.5);
    c = [-1.2, 0, 0];
    b1 = hfCylinderZ(x, c, 0.25);
    c = [1.2, 0, 0];
    b2 = hfCylinderZ(x, c, 0.25);
    my_model = plate \ b1 \ b2;
}
EOF
"$FREP" sample "$tmp/plate.hf" -n 6000 --noise 0.002 --seed 1 -o "$tmp/plate.xyz" -q 2>"$tmp/err" &&
    nice "$FREP" evolve "$tmp/plate.xyz" -o "$tmp/m.hf" --seed 1 -q 2>"$tmp/err"
st=$?
report $st "sample the plate with noise, segment and evolve it"
[ $st = 0 ] || { show "$tmp/err"; echo "1..$n"; exit 1; }

# The six faces are one box: frBox(x, centre, half sizes, rotations), centre (0, 0, 0.25)
# and half sizes (2, 1, 0.25) within 0.005, no rotation (the faces snapped to the axes),
# its comment naming the faces by role; the bores numbered 1, 2 and removed together.
awk -F'[(),;]' '/^    box_1 = frBox\(x, / {
        for (i = 3; i <= 11; i++) v[i - 2] = $i + 0
        want = "0 0 0.25 2 1 0.25 0 0 0"; split(want, w, " ")
        for (i = 1; i <= 9; i++) if (v[i] - w[i] > 0.005 || w[i] - v[i] > 0.005) bad = 1
        for (i = 7; i <= 9; i++) if (v[i] != 0) bad = 1
        k++
    } END { exit !(k == 1 && !bad) }' "$tmp/m.hf" &&
    grep -q '^    box_1 = .*faces.*plane_z_top' "$tmp/m.hf" && grep -q '^    box_1 = .*faces.*plane_z_bottom' "$tmp/m.hf" &&
    grep -q '^    box_1 = .*faces.*plane_x_left' "$tmp/m.hf" && grep -q '^    box_1 = .*faces.*plane_y_back' "$tmp/m.hf" &&
    ! grep -q ' = frPlane' "$tmp/m.hf" &&
    grep -q '^    cyl_bore_1 = frCylinder(x, ' "$tmp/m.hf" && grep -q '^    cyl_bore_2 = frCylinder(x, ' "$tmp/m.hf" &&
    grep -q '^    bores = cyl_bore_[12] | cyl_bore_[12];$' "$tmp/m.hf" && grep -q '^    tree = box_1 \\ bores;$' "$tmp/m.hf" &&
    grep -q '^    -- 3 solids: 1 box, 2 cylinders (0 capped), 0 spheres, 0 cones, 0 tori, 0 half-spaces$' "$tmp/m.hf"
st=$?
report $st "the plate written as features: box_1 (centre 0 0 0.25, half sizes 2 1 0.25, faces by role) minus bores 1, 2: 3 solids"
[ $st = 0 ] || show "$tmp/m.hf"

# Each bore: the axis point within the part's box grown by its diagonal (the box
# [-2,2]x[-1,1]x[0,0.5], diagonal 4.5), axis within 0.02 of z, radius 0.25 +- 0.005.
awk -F'[(),;]' '/^    cyl_bore_[0-9] = frCylinder/ {
        px = $3 + 0; py = $4 + 0; pz = $5 + 0
        if (px < -6.5 || px > 6.5 || py < -5.5 || py > 5.5 || pz < -4.5 || pz > 5) bad = 1
        if ($6 * $6 + $7 * $7 > 0.02 * 0.02 || $8 * $8 < 0.999) bad = 1
        if ($9 - 0.25 > 0.005 || 0.25 - $9 > 0.005) bad = 1
        k++
    } END { exit !(k == 2 && !bad) }' "$tmp/m.hf"
st=$?
report $st "bore axis points near the part (not thousands of units along the axis), axes within 0.02 of z, radii 0.25 +- 0.005"
[ $st = 0 ] || show "$tmp/m.hf"

# No number finer than its standard error: on a line whose comment says "+-S", every
# number has at most as many decimals as the first significant digit of S.
awk '/^    [a-z_0-9]* = fr[A-Z][a-z]*\(x, .*\+-/ {
        s = $0; sub(/.*\+-/, "", s); sub(/[, ].*/, "", s); s += 0
        d = 0; while (s < 1 && d < 20) { s *= 10; d++ }
        call = $0; sub(/^[^(]*\(x, /, "", call); sub(/\).*/, "", call)
        m = split(call, v, ", ")
        for (i = 1; i <= m; i++) {
            dec = 0; if (index(v[i], ".")) { t = v[i]; sub(/.*\./, "", t); dec = length(t) }
            if (dec > d) { print "too fine: " v[i] " (+-" $0 ")"; bad = 1 }
        }
        k++
    } END { exit !(k >= 3 && !bad) }' "$tmp/m.hf" >"$tmp/fine"
st=$?
report $st "no printed number finer than the standard error its comment gives"
[ $st = 0 ] || { show "$tmp/fine"; show "$tmp/m.hf"; }

grep -q '^    evolved = tree;  -- bounded: no clipping box' "$tmp/m.hf" && ! grep -q 'clip_' "$tmp/m.hf"
st=$?
report $st "a bounded tree is written without a clipping box"
[ $st = 0 ] || show "$tmp/m.hf"

# Editing one dimension: bore 1's radius 0.25 -> 0.35 removes pi (0.35^2 - 0.25^2) 0.5
# = 0.0942 of volume; the other faces stay.
vol() { "$FREP" mesh "$1" -o "$tmp/v.off" -g 128 --check 2>/dev/null | sed -n 's/.*volume \([0-9.e+-]*\).*/\1/p'; }
awk '/^    cyl_bore_1 = frCylinder/ { sub(/, [0-9.]*\);/, ", 0.35);") } { print }' "$tmp/m.hf" >"$tmp/m2.hf"
v1=$(vol "$tmp/m.hf")
v2=$(vol "$tmp/m2.hf")
awk -v a="$v1" -v b="$v2" 'BEGIN { d = a - b; e = 3.14159265 * (0.35^2 - 0.25^2) * 0.5
    exit !(a > 0 && d > 0.95 * e && d < 1.05 * e) }'
st=$?
report $st "bore 1 widened to 0.35: volume $v1 -> $v2, the analytic 0.0942 less (5%)"
[ $st = 0 ] || diff "$tmp/m.hf" "$tmp/m2.hf" | sed 's/^/# /'

# The same solid as the tree of planes: the model written with --exact-numbers (every
# primitive as fitted, no box) has the volume within 0.5%, and at 20^3 points of the
# part's box grown by 10% the two agree on inside/outside except within 0.01 of the
# surface (the rounding of the numbers to their standard error, 0.001 here).
nice "$FREP" evolve "$tmp/plate.xyz" -o "$tmp/x.hf" --seed 1 -q --exact-numbers 2>"$tmp/err" &&
    grep -q ' = frPlane' "$tmp/x.hf" && ! grep -q 'frBox' "$tmp/x.hf"
st=$?
vx=$(vol "$tmp/x.hf")
awk 'BEGIN { for (i = 0; i < 20; i++) for (j = 0; j < 20; j++) for (k = 0; k < 20; k++)
        printf "%.4f %.4f %.4f\n", -2.2 + 4.4 * (i + 0.5) / 20, -1.1 + 2.2 * (j + 0.5) / 20, -0.05 + 0.6 * (k + 0.5) / 20 }' >"$tmp/pts"
[ $st = 0 ] && "$FREP" eval "$tmp/m.hf" "$tmp/pts" >"$tmp/va" 2>"$tmp/err" &&
    "$FREP" eval "$tmp/x.hf" "$tmp/pts" >"$tmp/vb" 2>>"$tmp/err" &&
    paste "$tmp/va" "$tmp/vb" | awk -v a="$v1" -v b="$vx" '
        { n++; if (($1 > 0) != ($2 > 0)) { d++; if ($2 > 0.01 || $2 < -0.01) far++ } }
        END { printf "# %d of %d points differ, %d beyond 0.01 of the surface\n", d, n, far
              exit !(n == 8000 && far == 0 && d < 80 && a > 0.995 * b && a < 1.005 * b) }'
st=$?
report $st "the box is the same solid as its six planes (--exact-numbers): volume $v1 vs $vx, inside/outside agree"
[ $st = 0 ] || { show "$tmp/err"; show "$tmp/x.hf"; }

# Enlarging a face: box_1's top face moved up by 0.2 (centre z and half size z +0.1
# each) grows the volume by the top face's area (4 x 2 less the two bores) x 0.2 =
# 1.5215 (within 3%) and the mesh's z extent by 0.2; x and y extents stay (0.01).
awk -F', ' '/^    box_1 = frBox\(x, / { $4 = $4 + 0.1; $7 = $7 + 0.1 } { print }' OFS=', ' "$tmp/m.hf" >"$tmp/m3.hf"
ext() { "$FREP" mesh "$1" -o "$tmp/e.off" -g 128 -q 2>/dev/null &&
    awk 'NR == 2 { nv = $1 } NR > 2 && NR <= 2 + nv {
            for (i = 1; i <= 3; i++) { if (!(NR > 3) || $i < lo[i]) lo[i] = $i; if (!(NR > 3) || $i > hi[i]) hi[i] = $i } }
         END { printf "%.4f %.4f %.4f %.4f %.4f %.4f\n", lo[1], hi[1], lo[2], hi[2], lo[3], hi[3] }' "$tmp/e.off"; }
v3=$(vol "$tmp/m3.hf")
e1=$(ext "$tmp/m.hf")
e3=$(ext "$tmp/m3.hf")
echo "# extents before: $e1; after: $e3"
awk -v a="$v1" -v b="$v3" -v e1="$e1" -v e3="$e3" 'BEGIN {
        d = b - a; e = (8 - 2 * 3.14159265 * 0.25^2) * 0.2
        split(e1, p, " "); split(e3, q, " ")
        ok = a > 0 && d > 0.97 * e && d < 1.03 * e
        for (i = 1; i <= 5; i++) if (p[i] - q[i] > 0.01 || q[i] - p[i] > 0.01) ok = 0
        if (q[6] - p[6] < 0.19 || q[6] - p[6] > 0.21) ok = 0
        exit !ok }'
st=$?
report $st "top face of box_1 moved up 0.2: volume $v1 -> $v3 (analytic +1.5215, 3%), only the z extent grows"
[ $st = 0 ] || diff "$tmp/m.hf" "$tmp/m3.hf" | sed 's/^/# /'

# --hyperfun: the same tree in pure HyperFun (no frep extension), the same solid.
nice "$FREP" evolve "$tmp/plate.xyz" -o "$tmp/h.hf" --seed 1 -q --hyperfun 2>"$tmp/err" &&
    ! grep -q '= fr[A-Z]' "$tmp/h.hf" && grep -q '^    box_1 = .*(0\.[45][0-9]* - x\[3\])' "$tmp/h.hf" &&
    grep -q '^    cyl_bore_2 = 0\.25[0-9]*^2 - (' "$tmp/h.hf"
st=$?
vh=$(vol "$tmp/h.hf")
[ $st = 0 ] && awk -v a="$v1" -v b="$vh" 'BEGIN { exit !(b > 0.995 * a && b < 1.005 * a) }'
st=$?
report $st "--hyperfun: arithmetic of x only (box_1 = ... & (0.5 - x[3])), volume $vh as $v1 (0.5%)"
[ $st = 0 ] || { show "$tmp/err"; show "$tmp/h.hf"; }

# The export agrees.
if command -v openscad >/dev/null 2>&1 && /usr/bin/python3 -c 'import numpy, scipy.spatial' 2>/dev/null; then
    "$FREP" export "$tmp/m.hf" -o "$tmp/m.scad" -q --fn 64 &&
        "$FREP" mesh "$tmp/m.hf" -o "$tmp/ref.off" -g 96 -q 2>/dev/null &&
        openscad -o "$tmp/m.off" "$tmp/m.scad" >"$tmp/err" 2>&1
    st=$?
    d=$(/usr/bin/python3 "$src/bench/mesh_distance.py" "$tmp/ref.off" "$tmp/m.off" 60000)
    [ $st = 0 ] && awk -v c="${d%% *}" 'BEGIN { exit !(c < 0.005) }'
    report $? "OpenSCAD's mesh of the exported model within 0.5% Chamfer of frep mesh (${d%% *})"
else
    skip "OpenSCAD or /usr/bin/python3 with numpy and scipy not installed"
fi

tap_done
