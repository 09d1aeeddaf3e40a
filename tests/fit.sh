#!/bin/sh
# fit.sh - end-to-end tests of `frep fit`: the paper's test part (examples/fit) sampled
# with `frep sample`, fitted from the paper's start "set2" (all parameters 1) by
# quasi-Newton alone (a wrong local minimum) and by annealing + quasi-Newton (the ground
# truth); write-back, determinism across thread counts, and bad input. Prints TAP.
# Needs FREP (the frep binary) and srcdir (the source tree).

: "${FREP:?FREP must name the frep binary}"
: "${srcdir:?srcdir must name the source tree}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-fit.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM
ex="$srcdir/examples/fit"

. "$(dirname "$0")/tap.sh"

# Largest parameter error of a report (stdout of frep fit) against the ground truth of
# examples/fit/part_truth.hf, relative to the box diagonal; the two holes may come out in
# either order.
part_error() {
    awk '
    BEGIN { split("-4 -2 -1 8 4 2 2.2 0.3 0.6 -2 0 1", t, " "); k = 0 }
    /^(x0|y0|z0|dx|dy|dz|h1x|h1y|r1|h2x|h2y|r2) / { v[++k] = $3 }
    END {
        if (k != 12) { print 1e9; exit }
        e1 = 0; e2 = 0
        for (i = 1; i <= 12; i++) {
            j = i; if (i > 6) j = (i <= 9) ? i + 3 : i - 3
            d = v[i] - t[i]; if (d < 0) d = -d; if (d > e1) e1 = d
            d = v[i] - t[j]; if (d < 0) d = -d; if (d > e2) e2 = d
        }
        e = (e1 < e2) ? e1 : e2
        print e / sqrt(84)
    }' "$1"
}

lt() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a < b) }'; }

# ---- the paper's experiment (section 6.1) -------------------------------------------
"$FREP" sample "$ex/part_truth.hf" -n 10714 -o "$tmp/part.xyz" --seed 1 -q
report $? "frep sample: 10714 points on the ground-truth part"
cp "$ex/part.hf" "$tmp/part.hf"

"$FREP" fit "$tmp/part.hf" "$tmp/part.xyz" --method qn -o "$tmp/qn.hf" > "$tmp/qn.out"
report $? "qn from set2 runs"
e=$(part_error "$tmp/qn.out")
lt "$e" 0.001
report $? "qn alone from set2 reaches the truth, as L-BFGS-B does (error $e of the diagonal)"
grep -q '^evaluations .*, converged$' "$tmp/qn.out"
report $? "qn from set2 says converged"

"$FREP" fit "$tmp/part.hf" "$tmp/part.xyz" --json "$tmp/r.json" > "$tmp/saqn.out"
report $? "sa+qn from set2 runs"
e=$(part_error "$tmp/saqn.out")
lt "$e" 0.001
report $? "sa+qn from set2 reaches the ground truth (error $e < 1e-3 of the diagonal)"
grep '^evaluations' "$tmp/saqn.out" | sed 's/^/# /'
cmp -s "$ex/part.hf" "$tmp/part.hf"
report $? "the template itself is untouched"
test -f "$tmp/part.fitted.hf"
report $? "output next to the template as part.fitted.hf"
# The holes are interchangeable: r1 may fit either radius.
grep -q '^-- @box ' "$tmp/part.fitted.hf" &&
    awk '/^    r1 = [-0-9.e]+;    -- @free \[0\.01, 10\]$/ {
             v = $3 + 0; if ((v - 0.6) ^ 2 < 1e-12 || (v - 1) ^ 2 < 1e-12) found = 1 }
         END { exit !found }' "$tmp/part.fitted.hf"
report $? "fitted values written in place, annotations kept, @box added"
"$FREP" check "$tmp/part.fitted.hf" > /dev/null 2>&1
report $? "the fitted template compiles"
grep -q '"rms_distance"' "$tmp/r.json" && grep -q '"seed": 1' "$tmp/r.json"
report $? "--json report"

# Starting from the answer, qn keeps it (the written values are the fitted ones).
"$FREP" fit "$tmp/part.fitted.hf" "$tmp/part.xyz" --method qn -o "$tmp/again.hf" > "$tmp/again.out"
e=$(part_error "$tmp/again.out")
lt "$e" 0.001
report $? "refitting the fitted template stays at the truth ($e)"
test "$(grep -c '^-- @box' "$tmp/again.hf")" = 1
report $? "refitting refreshes the @box line instead of adding one"

# Same seed, 1 and 2 threads: the same file, bit for bit.
"$FREP" fit "$tmp/part.hf" "$tmp/part.xyz" -t 1 --seed 5 -q -o "$tmp/t1.hf" &&
    "$FREP" fit "$tmp/part.hf" "$tmp/part.xyz" -t 2 --seed 5 -q -o "$tmp/t2.hf"
report $? "fits with 1 and 2 threads run"
cmp -s "$tmp/t1.hf" "$tmp/t2.hf"
report $? "same seed: identical result at 1 and 2 threads"

# The plain HyperFun form with a[].
"$FREP" fit "$ex/part_a.hf" "$tmp/part.xyz" -o "$tmp/a.hf" -a 1,1,1,1,1,1,1,1,1,1,1,1 \
    --bounds -10:10,-10:10,-10:10,0.01:20,0.01:20,0.01:20,-10:10,-10:10,0.01:10,-10:10,-10:10,0.01:10 \
    > "$tmp/a.out"
report $? "a[] template with -a and --bounds"
grep -q '^-- @params -4\.0000[0-9]*, -2\.0000[0-9]*, ' "$tmp/a.hf"
report $? "a[] template: the fitted a[] recorded in a '-- @params' line"
# Self-contained: with no -a the fitted file is the fitted shape. Grid occupancy of the
# box around the part: the fitted a[] file and the ground truth agree; the template
# itself (a[] all 0 without -a) is empty.
inside() { "$FREP" eval "$1" --grid 30 -b -6,-4,-3,6,4,3 | awk '/^inside/ { print $2 }'; }
ia=$(inside "$tmp/a.hf") it=$(inside "$ex/part_truth.hf") i0=$(inside "$ex/part_a.hf")
[ -n "$ia" ] && [ "$ia" -gt 0 ] && awk -v a="$ia" -v t="$it" 'BEGIN { d = a - t; exit !(d * d <= 25) }'
report $? "a[] fitted file evaluates to the fitted shape with no -a ($ia of 27000 grid points inside, truth $it)"
[ "$i0" = 0 ]
report $? "the a[] template itself without -a is empty (a[] = 0): the check above can fail"
sed -e 's/^a\[\([0-9]*\)\]/p\1/' "$tmp/a.out" | awk '
    /^p[0-9]+ / { i = substr($1, 2) + 0; split("x0 y0 z0 dx dy dz h1x h1y r1 h2x h2y r2", nm, " "); $1 = nm[i] }
    { print }' > "$tmp/a2.out"
e=$(part_error "$tmp/a2.out")
lt "$e" 0.001
report $? "a[] template reaches the truth ($e)"

# ---- noise and outliers ----------------------------------------------------------------
# Gaussian noise of 1% of the part's diagonal (9.17) and 5% outliers; from a start near
# the answer (set1) the robust geometric fit recovers every parameter within the noise.
"$FREP" sample "$ex/part_truth.hf" -n 10714 --noise 0.0917abs --outliers 0.05 --seed 4 \
    -o "$tmp/noisy.xyz" -q
sed -e 's/x0 = 1;/x0 = -4.25;/' -e 's/y0 = 1;/y0 = -1.7;/' -e 's/z0 = 1;/z0 = -1.25;/' \
    -e 's/dx = 1;/dx = 8.3;/' -e 's/dy = 1;/dy = 3.75;/' -e 's/dz = 1;/dz = 2.3;/' \
    -e 's/h1x = 1;/h1x = -2.25;/' -e 's/h1y = 1;/h1y = 0.3;/' -e 's/r1 = 1;/r1 = 0.75;/' \
    -e 's/h2x = 1;/h2x = 2.5;/' -e 's/h2y = 1;/h2y = 0.05;/' -e 's/r2 = 1;/r2 = 0.9;/' \
    "$ex/part.hf" > "$tmp/set1.hf"
"$FREP" fit "$tmp/set1.hf" "$tmp/noisy.xyz" --method qn --objective geometric --loss cauchy \
    -o "$tmp/noisy.hf" > "$tmp/noisy.out"
report $? "robust fit of a noisy cloud with outliers runs"
e=$(part_error "$tmp/noisy.out")
lt "$e" 0.01
report $? "noise 1% + 5% outliers, set1, geometric cauchy: error $e < 0.01 of the diagonal"

# ---- bad input: clear message, non-zero exit, files untouched ------------------------
printf 'm(x[3], a[1]) { m = 1 - x[1]*x[1]; }\n' > "$tmp/nofree.hf"
"$FREP" fit "$tmp/nofree.hf" "$tmp/part.xyz" -o "$tmp/bad.hf" 2> "$tmp/err"
test $? -ne 0 && grep -q 'no free parameters' "$tmp/err"
report $? "a template without free parameters is refused"

printf 'm(x[3], a[1]) {\n  r = 20;  -- @free [1, 4]\n  m = r - x[1];\n}\n' > "$tmp/outside.hf"
"$FREP" fit "$tmp/outside.hf" "$tmp/part.xyz" -o "$tmp/bad.hf" 2> "$tmp/err"
test $? -ne 0 && grep -q 'outside its bounds' "$tmp/err"
report $? "a start value outside its bounds is refused"

printf '1 2 3\nnan 1 2\n' > "$tmp/nan.xyz"
for i in 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15; do echo "$i 0 0" >> "$tmp/nan.xyz"; done
cp "$tmp/part.hf" "$tmp/inplace.hf"
"$FREP" fit "$tmp/inplace.hf" "$tmp/nan.xyz" --in-place 2> "$tmp/err"
test $? -ne 0 && grep -q 'not finite' "$tmp/err"
report $? "a cloud with NaN is refused"
cmp -s "$tmp/part.hf" "$tmp/inplace.hf"
report $? "--in-place leaves the template alone on failure"

printf '1 2 3\n4 5 6\n' > "$tmp/few.xyz"
"$FREP" fit "$tmp/part.hf" "$tmp/few.xyz" -o "$tmp/bad.hf" 2> "$tmp/err"
test $? -ne 0 && grep -q 'too few' "$tmp/err"
report $? "too few points are refused"

printf '1 2 3\n4 5\n' > "$tmp/cols.xyz"
"$FREP" fit "$tmp/part.hf" "$tmp/cols.xyz" -o "$tmp/bad.hf" 2> "$tmp/err"
test $? -ne 0 && grep -q 'cols.xyz:2' "$tmp/err"
report $? "missing columns: file:line message"

: > "$tmp/empty.xyz"
"$FREP" fit "$tmp/part.hf" "$tmp/empty.xyz" -o "$tmp/bad.hf" 2> "$tmp/err"
test $? -ne 0 && test -s "$tmp/err"
report $? "an empty cloud is refused"
test ! -e "$tmp/bad.hf"
report $? "no output file after failures"

"$FREP" fit "$tmp/part.hf" "$tmp/part.xyz" --method nope 2> "$tmp/err"
test $? -eq 2
report $? "a bad option is a usage error (exit 2)"

tap_done
