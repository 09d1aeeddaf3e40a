#!/bin/sh
# fit_report.sh - what `frep fit` tells the user, checked against independent figures:
# the reported maximum distance against the exact distance of the points to the fitted
# box (closed form), the warnings (parameter on a bound, without effect, assigned again
# after its '@free' line, look-alike annotations), descriptions after '@free', the
# verdict line, and `frep mesh`'s hint at -a. Prints TAP. Needs FREP and srcdir.

: "${FREP:?FREP must name the frep binary}"
: "${srcdir:?srcdir must name the source tree}"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-fit-report.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM

. "$(dirname "$0")/tap.sh"

# A box with R-function slabs (HyperFun's hfBlock): |grad f| vanishes at its centre and
# is small near its edges, where |f|/|grad f| overstates distances by far.
cat > "$tmp/box_truth.hf" <<'HF'
-- @box -3 -2 -1.5 3 2 1.5
box_truth(x[3], a[1])
{
    array c[3];
    c = [-2, -1, -0.5];
    box_truth = hfBlock(x, c, 4, 2, 1);
}
HF
cat > "$tmp/box.hf" <<'HF'
-- a box template; the last parameter is free but unused
box(x[3], a[1])
{
    array c[3];
    x0 = -2.1;  -- @free [-3, 0] corner x
    y0 = -0.9;  -- @free [-3, 0] corner y
    z0 = -0.5;  -- @free [-3, 0]
    dx = 3.9;   -- @free [1, 6] length
    dy = 2.1;   -- @free [1, 6] width
    dz = 1.1;   -- @free [0.5, 3] height
    u = 1;      -- @free [0, 2] unused
    c = [x0, y0, z0];
    box = hfBlock(x, c, dx, dy, dz);
}
HF
"$FREP" sample "$tmp/box_truth.hf" -n 3000 --outliers 0.05 --seed 3 -o "$tmp/box.xyz" -q
report $? "sample a box with 5% outliers"
"$FREP" fit "$tmp/box.hf" "$tmp/box.xyz" --method qn -o "$tmp/boxfit.hf" > "$tmp/box.out" 2> "$tmp/box.err"
report $? "fit the box"
# The exact distance of each point to the fitted box, from the fitted values.
awk '
FNR == NR { if ($1 ~ /^(x0|y0|z0|dx|dy|dz)$/ && NF >= 4) v[$1] = $3; next }
{
    lo[1] = v["x0"]; lo[2] = v["y0"]; lo[3] = v["z0"]
    hi[1] = lo[1] + v["dx"]; hi[2] = lo[2] + v["dy"]; hi[3] = lo[3] + v["dz"]
    out = 0; inside = 1e300
    for (k = 1; k <= 3; k++) {
        p = $k; e = 0
        if (p < lo[k]) e = lo[k] - p; else if (p > hi[k]) e = p - hi[k]
        out += e * e
        m = p - lo[k]; if (hi[k] - p < m) m = hi[k] - p; if (m < inside) inside = m
    }
    d = out > 0 ? sqrt(out) : inside
    if (d > mx) mx = d
}
END { printf "%.9g\n", mx }' "$tmp/box.out" "$tmp/box.xyz" > "$tmp/true_max"
truemax=$(cat "$tmp/true_max")
repmax=$(awk '/^distance to the surface/ { v = $NF; sub(/.*max /, "", $0); split($0, a, " "); print a[1] + 0 }' "$tmp/box.out")
awk -v r="$repmax" -v t="$truemax" 'BEGIN { exit !(t > 0 && r >= t * (1 - 1e-6) && r <= 2 * t) }'
report $? "reported max distance $repmax within [1, 2] x the exact maximum $truemax"
firstorder=$("$FREP" eval "$tmp/boxfit.hf" --grad "$tmp/box.xyz" |
    awk '{ g = sqrt($2 * $2 + $3 * $3 + $4 * $4); d = g > 0 ? ($1 < 0 ? -$1 : $1) / g : 1e300; if (d > m) m = d } END { print m }')
awk -v f="$firstorder" -v t="$truemax" 'BEGIN { exit !(f > 2 * t) }'
report $? "(the first-order |f|/|grad f| would report $firstorder: the check above can fail)"

grep -q "warning: the surface does not depend on u" "$tmp/box.err"
report $? "warning: a free parameter without effect"
grep -q '^u .* no effect$' "$tmp/box.out"
report $? "the table marks it"
grep -Eq '^fit: (poor|doubtful) - [0-9.]+% of points within 1% of the diagonal.*; [0-9]+ parameter warnings?$' "$tmp/box.out"
report $? "the verdict says poor or doubtful and why: $(grep '^fit:' "$tmp/box.out")"
grep -q '^dx .*+-' "$tmp/box.out" || grep -q '^parameter .* +- ' "$tmp/box.out"
report $? "standard errors in the table"

# A bound the truth lies beyond (dz <= 0.8, truth 1): on its bound.
sed -e 's/dz = 1.1;   -- @free \[0.5, 3\]/dz = 0.7;   -- @free [0.5, 0.8]/' -e '/u = 1;/d' \
    "$tmp/box.hf" > "$tmp/bound.hf"
"$FREP" sample "$tmp/box_truth.hf" -n 2000 --seed 4 -o "$tmp/clean.xyz" -q
"$FREP" fit "$tmp/bound.hf" "$tmp/clean.xyz" --method qn -o "$tmp/o.hf" > "$tmp/b.out" 2> "$tmp/b.err"
grep -q "warning: dz = 0.8 is on its bound \[0.5, 0.8\]" "$tmp/b.err" && grep -q '^dz .*on bound$' "$tmp/b.out"
report $? "warning and mark: a parameter on its bound"

# A clean fit: converged, good, no warning.
sed -e '/u = 1;/d' "$tmp/box.hf" > "$tmp/good.hf"
"$FREP" fit "$tmp/good.hf" "$tmp/clean.xyz" --method qn -o "$tmp/o.hf" > "$tmp/g.out" 2> "$tmp/g.err"
grep -q '^fit: good - 100.0% of points within 1% of the diagonal$' "$tmp/g.out" &&
    grep -q ', converged$' "$tmp/g.out" && ! grep -q warning "$tmp/g.err"
report $? "a clean fit: $(grep '^fit:' "$tmp/g.out")"

# 100 outliers of our own inside the box, at least 0.4 from every face (the clean points
# are on the surface): the robust refinement recovers the box (least squares is pulled
# 0.02 off) and the verdict counts exactly those 100 as outliers, leaving them out of
# the standard errors.
{ awk '{ print $1, $2, $3 }' "$tmp/clean.xyz"
  awk 'BEGIN { for (i = 0; i < 100; i++) printf "%.6f %.6f %.6f\n", -1.5 + 3 * ((i * 7) % 100) / 100,
               -0.5 + ((i * 13) % 100) / 100, -0.1 + 0.2 * ((i * 37) % 100) / 100 }'
} > "$tmp/mixed.xyz"
"$FREP" fit "$tmp/good.hf" "$tmp/mixed.xyz" --method qn -o "$tmp/o.hf" > "$tmp/r.out" 2> "$tmp/r.err"
grep -q '^fit: good - [0-9.]*% of points within 1% of the diagonal; 100 points (4.8%) taken for outliers$' "$tmp/r.out"
report $? "outliers counted in the verdict: $(grep '^fit:' "$tmp/r.out")"
rerr() { awk 'BEGIN { split("-2 -1 -0.5 4 2 1", t, " "); split("x0 y0 z0 dx dy dz", k, " ") }
    { for (i = 1; i <= 6; i++) if ($1 == k[i]) { e = $3 - t[i]; if (e < 0) e = -e; if (e > m) m = e } }
    END { print m + 0 }' "$1"; }
e=$(rerr "$tmp/r.out")
awk -v e="$e" 'BEGIN { exit !(e < 1e-3) }' && ! grep -q 'loose' "$tmp/r.out"
report $? "robust fit through outliers: error $e < 1e-3, no parameter loose"
"$FREP" fit "$tmp/good.hf" "$tmp/mixed.xyz" --method qn --no-robust -o "$tmp/o.hf" > "$tmp/n.out" 2>&1
e=$(rerr "$tmp/n.out")
awk -v e="$e" 'BEGIN { exit !(e > 1e-2) }'
report $? "(least squares, --no-robust: error $e > 1e-2, so the test above can fail)"
# The annealing on a bounded loss (--sa-loss cauchy, its scale from the cloud's size)
# before the robust local phase: through the same outliers it ends at the box too.
"$FREP" fit "$tmp/good.hf" "$tmp/mixed.xyz" --sa-loss cauchy --seed 2 -o "$tmp/o.hf" > "$tmp/s.out" 2>&1
e=$(rerr "$tmp/s.out")
awk -v e="$e" 'BEGIN { exit !(e < 1e-3) }' && grep -q ', seed 2$' "$tmp/s.out"
report $? "annealing on a Cauchy loss, then the robust refinement: error $e < 1e-3"

# Assigned again after its '@free' line: a compile warning, and no effect.
sed -e 's/^    c = \[x0, y0, z0\];/    z0 = -0.5;\n    c = [x0, y0, z0];/' -e '/u = 1;/d' "$tmp/box.hf" > "$tmp/again.hf"
"$FREP" fit "$tmp/again.hf" "$tmp/clean.xyz" --method qn -o "$tmp/o.hf" > "$tmp/a.out" 2> "$tmp/a.err"
grep -q "warning: 'z0' is assigned again on line [0-9]* after its '@free' line" "$tmp/a.err" &&
    grep -q "warning: the surface does not depend on z0" "$tmp/a.err"
[ "$(grep -c "is assigned again" "$tmp/a.err")" = 1 ]
report $? "warnings: '@free' variable assigned again (once)"

# A comment that looks like an annotation but is not one.
sed -e 's/    z0 = -0.5;  -- @free \[-3, 0\]/    z0 = -0.5;  -- corner z @free [-3, 0]/' -e '/u = 1;/d' \
    "$tmp/box.hf" > "$tmp/look.hf"
grep -q "corner z @free" "$tmp/look.hf" || echo "# look.hf was not made"
"$FREP" fit "$tmp/look.hf" "$tmp/clean.xyz" --method qn -o "$tmp/o.hf" > "$tmp/l.out" 2> "$tmp/l.err"
grep -q "look.hf:7: warning: '@free' is not at the start of the comment" "$tmp/l.err" &&
    ! grep -q '^z0 ' "$tmp/l.out"
report $? "warning: '-- corner z @free [...]' is no annotation (and frees nothing)"
grep -q "warning" "$tmp/g.err"
[ $? != 0 ]
report $? "descriptions after '@free [lo, hi]' are accepted without a word"

# frep mesh of an a[] template without -a: empty, with a hint at -a.
"$FREP" mesh "$srcdir/examples/fit/part_a.hf" -o "$tmp/m.stl" 2> "$tmp/m.err"
grep -q "part_a.hf: note: the model reads a\[\], which neither -a nor a '-- @params' line gives values" "$tmp/m.err"
report $? "frep mesh: an a[] model without values says so"
"$FREP" mesh "$tmp/box_truth.hf" -b 0.1 -o "$tmp/m.stl" 2> "$tmp/m.err"
[ $? != 0 ] && grep -q "fills all of the box" "$tmp/m.err"
report $? "frep mesh: a model that fills the box says so" 

# The CAD suite's clean bracket (tests/fit/bracket_truth.hf), fitted from the truth: the
# sampler leaves a few points 0.03-0.04 inside its corners, where the first-order
# estimate and the Newton landing point of the R-function blocks both overstate the
# distance 3-5x (the report once said max 0.104). Exact distances, closed form: the L
# prism's faces, the slots (stadiums along z) and the wall hole (cylinder along y).
"$FREP" sample "$srcdir/tests/fit/bracket_truth.hf" -n 4000 --seed 7 -o "$tmp/br.xyz" -q
"$FREP" fit "$srcdir/tests/fit/bracket_truth.hf" "$tmp/br.xyz" --method qn -o "$tmp/brfit.hf" \
    > "$tmp/br.out" 2> /dev/null
report $? "fit the clean bracket from its truth"
awk '
function rect(a, b, a0, a1, b0, b1,   da, db) {
    da = a < a0 ? a0 - a : (a > a1 ? a - a1 : 0); db = b < b0 ? b0 - b : (b > b1 ? b - b1 : 0)
    return sqrt(da * da + db * db) }
function min(a, b) { return a < b ? a : b }
function seg(px, py, ax, bx, y,   u) { u = px < ax ? ax : (px > bx ? bx : px); return sqrt((px - u) ^ 2 + (py - y) ^ 2) }
FNR == NR { if (NF >= 4 && $1 ~ /^(w|d|t|hw|sx|sl|sr|sy|hr)$/) v[$1] = $3; next }
{
    w = v["w"]; d = v["d"]; t = v["t"]; hw = v["hw"]; sx = v["sx"]; sl = v["sl"]
    sr = v["sr"]; sy = v["sy"]; hr = v["hr"]
    x = $1; y = $2; z = $3; h = w / 2
    inL = x >= -h && x <= h && ((y >= 0 && y <= d && z >= 0 && z <= t) || (y >= d - t && y <= d && z >= 0 && z <= hw))
    e = min(rect(y, z, 0, d, 0, t), rect(y, z, d - t, d, 0, hw))
    dend = min(sqrt((x + h) ^ 2 + e * e), sqrt((x - h) ^ 2 + e * e))
    ex = x < -h ? -h - x : (x > h ? x - h : 0)
    s = min(rect(y, z, 0, d, 0, 0), rect(y, z, 0, 0, 0, t))
    s = min(s, min(rect(y, z, 0, d - t, t, t), rect(y, z, d - t, d - t, t, hw)))
    s = min(s, min(rect(y, z, d - t, d, hw, hw), rect(y, z, d, d, 0, hw)))
    dL = min(dend, sqrt(s * s + ex * ex))
    q = min(seg(x, y, -sx - sl, -sx + sl, sy) - sr, seg(x, y, sx - sl, sx + sl, sy) - sr)
    q = min(q, sqrt(x * x + (z - t - (hw - t) / 2) ^ 2) - hr)
    dd = !inL ? dL : (q >= 0 ? min(dL, q) : min(-q, dL))
    if (dd > mx) mx = dd; ss += dd * dd; n++
}
END { printf "%.9g %.9g\n", sqrt(ss / n), mx }' "$tmp/br.out" "$tmp/br.xyz" > "$tmp/br.exact"
read -r trms tmax < "$tmp/br.exact"
rrms=$(awk '/^distance to the surface/ { sub(/.*rms /, ""); print $1 + 0 }' "$tmp/br.out")
rmax=$(awk '/^distance to the surface/ { sub(/.*max /, ""); print $1 + 0 }' "$tmp/br.out")
awk -v r="$rrms" -v t="$trms" 'BEGIN { exit !(t > 0 && r >= t * (1 - 1e-6) && r <= 2 * t) }'
report $? "bracket: reported rms $rrms within [1, 2] x the exact $trms"
awk -v r="$rmax" -v t="$tmax" 'BEGIN { exit !(t > 0 && r >= t * (1 - 1e-6) && r <= 2 * t) }'
report $? "bracket: reported max $rmax within [1, 2] x the exact $tmax"


# One annealing chain when it explains the points (FIT_ONE_CHAIN_SHARE, fit/fit.c): from
# the truth, the first chain's result puts every point of the clean bracket within 1% of
# the diagonal, though the first-order distances of 3% of them say otherwise (hfBlock's
# slabs at the middle of the thin plate); the second chain is skipped, which costs one
# evaluation (the check) where running it cost 4,654 (10,649 against 5,995).
evals_of() { awk '/^evaluations/ { sub(",", "", $2); print $2 }' "$1"; }
"$FREP" fit "$srcdir/tests/fit/bracket_truth.hf" "$tmp/br.xyz" -o "$tmp/brfit.hf" \
    > "$tmp/br2.out" 2> /dev/null &&
"$FREP" fit "$srcdir/tests/fit/bracket_truth.hf" "$tmp/br.xyz" --sa-chains 1 -o "$tmp/brfit.hf" \
    > "$tmp/br1.out" 2> /dev/null
e2=$(evals_of "$tmp/br2.out") e1=$(evals_of "$tmp/br1.out")
[ -n "$e1" ] && [ -n "$e2" ] && [ "$e2" -le $((e1 + 1)) ]
report $? "bracket: no second chain once the first explains the points ($e2 against $e1 evaluations)"
tap_done
