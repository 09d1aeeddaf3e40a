#!/bin/sh
# bench_fit.sh - `make bench` part of frep fit: the paper's test part (Fayolle, Pasko et
# al. 2004, section 6.1; examples/fit/part.hf), 10,714 points sampled from the ground
# truth, fitted from set1 (near the answer) and set2 (all parameters 1) with qn, sa and
# saqn; then scipy.optimize.dual_annealing (L-BFGS-B local search) on the very same
# objective (sum of f^2), points and bounds, CPU time against CPU time, with
# L-BFGS-B and dual_annealing also driven by frep's own objective and gradient through
# the C library (bench/bench_fit.py), when scipy is installed. Then the CAD-style
# templates of tests/fit_suite.sh over seeds 1-10 (clean, 0.2% and 1% noise, 5% outliers).
# Then a real CAD part: bench/mount.hf fitted to points sampled from the InverseCSG
# "mount" mesh (skipped when ../shared/data/inversecsg is absent; FREP_INVERSECSG=DIR
# points elsewhere).
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

cores=$(nproc 2>/dev/null || echo '?')
echo "frep fit, test part, 10714 points, $cores cores, OMP_NUM_THREADS=${OMP_NUM_THREADS:-default}"
printf '%-6s %-5s %5s %10s %9s %8s\n' start method seed error seconds evals
: > "$tmp/runs.txt"
for start in set1 set2; do
    for method in qn sa saqn; do
        for seed in $SEEDS; do
            "$FREP" fit "$tmp/$start.hf" "$tmp/part.xyz" --method $method --seed $seed \
                -o "$tmp/out.hf" > "$tmp/out.txt" 2>&1
            line=$(err "$tmp/out.txt")
            printf '%-6s %-5s %5s %s\n' $start $method $seed "$line"
            echo "$start $method $seed $line" >> "$tmp/runs.txt"
            [ $method = qn ] && break   # deterministic: one run is enough
        done
    done
done

# Medians per start and method; "truth" counts runs with error < 1e-3 of the diagonal.
median() { sort -g | awk '{ v[NR] = $1 } END { if (NR == 0) print "-"; else if (NR % 2) print v[(NR + 1) / 2]; else print (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
echo
echo "summary (medians over seeds; $cores cores):"
printf '%-6s %-5s %7s %12s %10s %8s\n' start method truth error seconds evals
for start in set1 set2; do
    for method in qn sa saqn; do
        awk -v s=$start -v m=$method '$1 == s && $2 == m' "$tmp/runs.txt" > "$tmp/sel.txt"
        n=$(wc -l < "$tmp/sel.txt")
        hits=$(awk '$4 < 1e-3' "$tmp/sel.txt" | wc -l)
        printf '%-6s %-5s %7s %12s %10s %8s\n' $start $method "$hits/$n" \
            "$(awk '{ print $4 }' "$tmp/sel.txt" | median)" \
            "$(awk '{ print $5 }' "$tmp/sel.txt" | median)" \
            "$(awk '{ print $6 }' "$tmp/sel.txt" | median)"
    done
done

py=
[ -n "$FIT_BENCH_NO_SCIPY" ] || for cand in python3 /usr/bin/python3; do
    if "$cand" -c 'import scipy.optimize' 2>/dev/null; then py=$cand; break; fi
done
lib=${FREP_LIB:-$(dirname "$FREP")/.libs/libfrep.so}
# bench_fit.py reaches the fit module (fit_objective_*), which the installed libfrep.so
# does not export (libfrep.sym): link an unversioned copy of its convenience archive.
core="$(dirname "$FREP")/.libs/libfrepcore.a"
if [ -z "$FREP_LIB" ] && [ -f "$core" ] &&
    ${CC:-cc} -shared -o "$tmp/libfrep_all.so" -Wl,--whole-archive "$core" \
        -Wl,--no-whole-archive -lm -fopenmp 2>/dev/null; then
    lib=$tmp/libfrep_all.so
fi
if [ -n "$py" ] && [ -f "$lib" ]; then
    echo
    echo "frep against scipy, like for like (sum of f^2, CPU seconds, one process), set2:"
    OMP_NUM_THREADS=1 "$py" "$SRCDIR/bench/bench_fit.py" "$FREP" "$lib" "$SRCDIR" "$tmp/part.xyz" $SEEDS
else
    echo
    echo "scipy (python3-scipy) or $lib missing: the scipy comparison is skipped"
fi

# ---- CAD-style templates (tests/fit_suite.sh): seeds 1-10, clean and noisy clouds ---------
echo
echo "CAD-style templates (tests/fit/), seeds 1-10, clean clouds, defaults:"
FREP="$FREP" srcdir="$SRCDIR" FIT_SUITE_TABLE=1 FIT_SUITE_SEEDS="1 2 3 4 5 6 7 8 9 10" \
    sh "$SRCDIR/tests/fit_suite.sh" | grep -v '^#'
echo "the same, noise 0.2% of the diagonal, --objective geometric:"
FREP="$FREP" srcdir="$SRCDIR" FIT_SUITE_TABLE=1 FIT_SUITE_SEEDS="1 2 3 4 5 6 7 8 9 10" \
    FIT_SUITE_NOISE=0.002 FIT_SUITE_OPTIONS="--objective geometric" \
    sh "$SRCDIR/tests/fit_suite.sh" | grep -v '^#'
echo "the same, noise 1% of the diagonal, defaults (robust refinement):"
FREP="$FREP" srcdir="$SRCDIR" FIT_SUITE_TABLE=1 FIT_SUITE_SEEDS="1 2 3 4 5 6 7 8 9 10" \
    FIT_SUITE_NOISE=0.01 sh "$SRCDIR/tests/fit_suite.sh" | grep -v '^#'
echo "the same, 5% outliers, defaults, and with --sa-loss geman:"
FREP="$FREP" srcdir="$SRCDIR" FIT_SUITE_TABLE=1 FIT_SUITE_SEEDS="1 2 3 4 5 6 7 8 9 10" \
    FIT_SUITE_OUTLIERS="--outliers 0.05" sh "$SRCDIR/tests/fit_suite.sh" | grep -v '^#'
FREP="$FREP" srcdir="$SRCDIR" FIT_SUITE_TABLE=1 FIT_SUITE_SEEDS="1 2 3 4 5 6 7 8 9 10" \
    FIT_SUITE_OUTLIERS="--outliers 0.05" FIT_SUITE_OPTIONS="--sa-loss geman" \
    sh "$SRCDIR/tests/fit_suite.sh" | grep -v '^#'

# ---- a real CAD part: the InverseCSG "mount" ------------------------------------------
data=${FREP_INVERSECSG:-$SRCDIR/../shared/data/inversecsg}
mesh="$data/mount/csg_high_res.off"
echo
if [ ! -f "$mesh" ]; then
    echo "InverseCSG data not found ($mesh): mount benchmark skipped"
    exit 0
fi
"$FREP" sample "$mesh" -n 10000 -o "$tmp/mount.xyz" --seed 1 -q || exit 1
# Ground truth from mount/csg.scad, in the template's terms (see bench/mount.hf).
truth="hx 2.857143 hy 4.285714 rad 0.714286 tz -0.928574 uw 1.642857 ud 3.285714 uh 2.571429 zc 2.5 rcut 1.071429 rboss 1.642857 hboss 1.428571"
cp "$SRCDIR/bench/mount.hf" "$tmp/mount_near.hf"
sed -E 's/^(    [a-z]+ = )-?[0-9.]+;( +-- @free)/\11;\2/' "$SRCDIR/bench/mount.hf" > "$tmp/mount_ones.hf"
mount_err() { # largest absolute parameter error and its parameter
    awk -v t="$truth" '
    BEGIN { n = split(t, a, " "); for (i = 1; i < n; i += 2) want[a[i]] = a[i + 1] }
    ($1 in want) && NF >= 3 { d = $3 - want[$1]; if (d < 0) d = -d; if (d > e) { e = d; w = $1 } }
    /^evaluations/ { ev = $2; tm = $4 }
    END { sub(",", "", ev); printf "%10.3g %-6s %9s %8s", e, w, tm, ev }' "$1"
}
echo "frep fit, InverseCSG mount (bench/mount.hf, 11 parameters), 10000 points from"
echo "csg_high_res.off; error = largest |fitted - csg.scad value| (part size ~12.7)"
printf '%-6s %-5s %5s %10s %-6s %9s %8s\n' start method seed error param seconds evals
for start in near ones; do
    for method in qn saqn; do
        for seed in $SEEDS; do
            "$FREP" fit "$tmp/mount_$start.hf" "$tmp/mount.xyz" --method $method --seed $seed \
                -o "$tmp/mfit.hf" > "$tmp/mout.txt" 2>&1
            printf '%-6s %-5s %5s %s\n' $start $method $seed "$(mount_err "$tmp/mout.txt")"
            [ $method = qn ] && break
        done
    done
done
echo "(the mesh's cylinders are 60-gons: radii fit about 0.1% small)"
