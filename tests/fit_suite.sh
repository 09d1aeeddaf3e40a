#!/bin/sh
# fit_suite.sh - reliability of `frep fit` on CAD-style templates (tests/fit/): a flanged
# bushing with a bolt circle (10 parameters) and an L bracket with slots (9), each in a
# min/max and an R-function version, and a blended part (8), each started far from the
# truth, fitted to 4,000 points that `frep sample` draws from the truth. A fit reaches
# the truth when every parameter is within 1% of its range. Prints TAP: one line per
# template (every seed must reach the truth), with the worst error and time.
# make check runs the cheap version: clean clouds, seed 1, and two hard clouds, also
# seed 1: a case written TEMPLATE+noise is fitted to a cloud with 0.2% noise (of the
# diagonal), TEMPLATE+outliers to one with 2% outliers; CASE@SEED runs seed SEED only
# (bracket_rfunc+outliers@2: every chain once ended with the slots switched off;
# TEMPLATE+outliers5 has 5% outliers: bracket_minmax+outliers5@9 ended with the wall
# too high while the annealing summed squares over the outliers). `make bench-fit` runs seeds
# 1-10 on noisy clouds (doc/benchmarks.md). Env: FREP, srcdir; FIT_SUITE_SEEDS ("1"),
# FIT_SUITE_CASES (all), FIT_SUITE_NOISE (relative noise of frep sample, 0),
# FIT_SUITE_OUTLIERS (e.g. "--outliers 0.02"), FIT_SUITE_OPTIONS (more frep fit options),
# FIT_SUITE_TABLE=1 (report, never fail).

: "${FREP:?FREP must name the frep binary}"
: "${srcdir:?srcdir must name the source tree}"
SEEDS=${FIT_SUITE_SEEDS:-"1"}
CASES=${FIT_SUITE_CASES:-"bushing_minmax bushing_rfunc bracket_minmax bracket_rfunc blend
bracket_minmax+noise bushing_minmax+outliers bracket_rfunc+outliers@2
bracket_minmax+outliers5@9"}
dir="$srcdir/tests/fit"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-fit-suite.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM

. "$(dirname "$0")/tap.sh"

# truth_of TEMPLATE -> the truth file (bushing_minmax -> bushing_truth)
truth_of() { echo "$dir/${1%%_*}_truth.hf"; }

# Largest |fitted - truth| / (hi - lo) over the parameters: the truth file's '@free'
# lines give the truth, the report's table the fitted values and bounds.
rel_error() { # rel_error TRUTH.hf REPORT
    awk '
    FNR == NR { if ($0 ~ /-- @free/) { v = $3; sub(";", "", v); t[$1] = v }; next }
    ($1 in t) && $NF ~ /\]$/ || ($1 in t) && /\[/ {
        line = $0; sub(/^[^[]*\[/, "", line); sub(/\].*$/, "", line)
        split(line, b, ","); lo = b[1] + 0; hi = b[2] + 0
        e = $3 - t[$1]; if (e < 0) e = -e; e /= (hi - lo); if (e > m) m = e; k++
    }
    END { if (k == 0) print 9; else printf "%.3g\n", m }' "$1" "$2"
}

lt() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a < b) }'; }

for spec in $CASES; do
    # CASE@SEED fits with that seed alone (a seed that once failed)
    seeds=$SEEDS
    case "$spec" in *@*) seeds=${spec##*@}; spec=${spec%@*} ;; esac
    case=${spec%%+*}
    truth=$(truth_of "$case")
    # the cloud's options: the environment's, or those a +noise / +outliers case names
    dirt="--noise ${FIT_SUITE_NOISE:-0} $FIT_SUITE_OUTLIERS"
    case "$spec" in
        *+noise) dirt="--noise 0.002" ;;
        *+outliers) dirt="--outliers 0.02" ;;
        *+outliers5) dirt="--outliers 0.05" ;;
    esac
    cloud="$tmp/${case%%_*}${spec#"$case"}.xyz"
    if [ ! -f "$cloud" ]; then
        "$FREP" sample "$truth" -n 4000 $dirt --seed 7 -o "$cloud" -q ||
            { report 1 "$spec: sampling $truth"; continue; }
    fi
    hits=0 runs=0 worst=0 tmax=0
    for seed in $seeds; do
        "$FREP" fit "$dir/$case.hf" "$cloud" --seed "$seed" $FIT_SUITE_OPTIONS -o "$tmp/out.hf" \
            > "$tmp/out.txt" 2> "$tmp/err.txt"
        e=$(rel_error "$truth" "$tmp/out.txt")
        t=$(awk '/^evaluations/ { print $4 }' "$tmp/out.txt")
        ev=$(awk '/^evaluations/ { sub(",", "", $2); print $2 }' "$tmp/out.txt")
        runs=$((runs + 1))
        lt "$e" 0.01 && hits=$((hits + 1))
        lt "$worst" "$e" && worst=$e
        lt "$tmax" "${t:-0}" && tmax=$t
        echo "# $spec seed $seed: error $e of the range, ${t:-?} s, ${ev:-?} evaluations"
    done
    report $([ $hits = $runs ] && echo 0 || echo 1) \
        "$spec: truth (1% of each range) on $hits of $runs seeds (worst $worst, slowest $tmax s)"
done
echo "1..$n"
[ -n "$FIT_SUITE_TABLE" ] && exit 0
exit $failed
