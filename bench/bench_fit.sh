#!/bin/sh
# bench_fit.sh - `make bench` part of frep fit: the paper's test part (Fayolle, Pasko et
# al. 2004, section 6.1; examples/fit/part.hf), 10,714 points sampled from the ground
# truth, fitted from set1 (near the answer) and set2 (all parameters 1) with qn, sa and
# saqn; then scipy.optimize.dual_annealing (L-BFGS-B local search) on the very same
# algebraic objective, points and bounds (bench/bench_fit.py), when scipy is installed.
# Usage: bench_fit.sh FREP SRCDIR [SEEDS]   (FIT_BENCH_NO_SCIPY=1: frep only)

FREP=${1:?usage: bench_fit.sh FREP SRCDIR}
SRCDIR=${2:?usage: bench_fit.sh FREP SRCDIR}
SEEDS=${3:-"1 2 3 4 5"}
ex="$SRCDIR/examples/fit"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-bench-fit.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM

"$FREP" sample "$ex/part_truth.hf" -n 10714 -o "$tmp/part.xyz" --seed 1 -q || exit 1
# set1: every parameter a quarter unit or so off the truth.
sed -e 's/x0 = 1;/x0 = -4.25;/' -e 's/y0 = 1;/y0 = -1.7;/' -e 's/z0 = 1;/z0 = -1.25;/' \
    -e 's/dx = 1;/dx = 8.3;/' -e 's/dy = 1;/dy = 3.75;/' -e 's/dz = 1;/dz = 2.3;/' \
    -e 's/h1x = 1;/h1x = -2.25;/' -e 's/h1y = 1;/h1y = 0.3;/' -e 's/r1 = 1;/r1 = 0.75;/' \
    -e 's/h2x = 1;/h2x = 2.5;/' -e 's/h2y = 1;/h2y = 0.05;/' -e 's/r2 = 1;/r2 = 0.9;/' \
    "$ex/part.hf" > "$tmp/set1.hf"
cp "$ex/part.hf" "$tmp/set2.hf"

# Error: largest parameter error over the box diagonal (holes in either order).
err() {
    awk '
    BEGIN { split("-4 -2 -1 8 4 2 2.2 0.3 0.6 -2 0 1", t, " "); k = 0 }
    /^(x0|y0|z0|dx|dy|dz|h1x|h1y|r1|h2x|h2y|r2) / { v[++k] = $3 }
    /^evaluations/ { ev = $2; tm = $4 }
    END {
        e1 = 0; e2 = 0
        for (i = 1; i <= 12; i++) {
            j = i; if (i > 6) j = (i <= 9) ? i + 3 : i - 3
            d = v[i] - t[i]; if (d < 0) d = -d; if (d > e1) e1 = d
            d = v[i] - t[j]; if (d < 0) d = -d; if (d > e2) e2 = d
        }
        e = (e1 < e2) ? e1 : e2
        sub(",", "", ev)
        printf "%10.3g %9s %8s", e / sqrt(84), tm, ev
    }' "$1"
}

echo "frep fit, test part, 10714 points, OMP_NUM_THREADS=${OMP_NUM_THREADS:-default}"
printf '%-6s %-5s %5s %10s %9s %8s\n' start method seed error seconds evals
for start in set1 set2; do
    for method in qn sa saqn; do
        for seed in $SEEDS; do
            "$FREP" fit "$tmp/$start.hf" "$tmp/part.xyz" --method $method --seed $seed \
                -o "$tmp/out.hf" > "$tmp/out.txt" 2>&1
            printf '%-6s %-5s %5s %s\n' $start $method $seed "$(err "$tmp/out.txt")"
            [ $method = qn ] && break   # deterministic: one run is enough
        done
    done
done

py=
[ -n "$FIT_BENCH_NO_SCIPY" ] || for cand in python3 /usr/bin/python3; do
    if "$cand" -c 'import scipy.optimize' 2>/dev/null; then py=$cand; break; fi
done
if [ -n "$py" ]; then
    echo
    echo "scipy.optimize.dual_annealing on the same objective (algebraic, mean f^2), set2:"
    "$py" "$SRCDIR/bench/bench_fit.py" "$tmp/part.xyz" $SEEDS
else
    echo
    echo "scipy not installed (python3-scipy): dual_annealing comparison skipped"
fi
