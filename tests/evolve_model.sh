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

n=0
failed=0
report() { # report STATUS DESCRIPTION
    n=$((n + 1))
    if [ "$1" = 0 ]; then echo "ok $n - $2"; else echo "not ok $n - $2"; failed=1; fi
}
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

grep -q '^    plane_z_top = frPlane(x, 0, 0, 1, 0\.49[0-9]*);\|^    plane_z_top = frPlane(x, 0, 0, 1, 0\.50*[0-4]*);' "$tmp/m.hf" &&
    grep -q '^    plane_z_bottom = frPlane(x, 0, 0, -1, 0\.00[0-4]*);\|^    plane_z_bottom = frPlane(x, 0, 0, -1, -0\.00[0-4]*);' "$tmp/m.hf" &&
    grep -q '^    plane_x_left = frPlane(x, -1, 0, 0, ' "$tmp/m.hf" && grep -q '^    plane_y_back = frPlane(x, 0, 1, 0, ' "$tmp/m.hf" &&
    grep -q '^    cyl_bore_1 = frCylinder(x, ' "$tmp/m.hf" && grep -q '^    cyl_bore_2 = frCylinder(x, ' "$tmp/m.hf"
st=$?
report $st "faces named by role and snapped to the axes (plane_z_top at z = 0.5 +- 0.005), bores numbered 1, 2"
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
    } END { exit !(k >= 4 && !bad) }' "$tmp/m.hf" >"$tmp/fine"
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

# --hyperfun: the same tree in pure HyperFun (no frep extension), the same solid.
nice "$FREP" evolve "$tmp/plate.xyz" -o "$tmp/h.hf" --seed 1 -q --hyperfun 2>"$tmp/err" &&
    ! grep -q '= fr[A-Z]' "$tmp/h.hf" && grep -q '^    plane_z_top = 0\.[45][0-9]* - x\[3\];' "$tmp/h.hf" &&
    grep -q '^    cyl_bore_2 = 0\.25[0-9]*^2 - (' "$tmp/h.hf"
st=$?
vh=$(vol "$tmp/h.hf")
[ $st = 0 ] && awk -v a="$v1" -v b="$vh" 'BEGIN { exit !(b > 0.995 * a && b < 1.005 * a) }'
st=$?
report $st "--hyperfun: arithmetic of x only (plane_z_top = 0.5 - x[3]), volume $vh as $v1 (0.5%)"
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

echo "1..$n"
exit $failed
