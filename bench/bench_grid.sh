#!/bin/sh
# bench_grid.sh - grid evaluation throughput of frep eval --grid (make bench-eval-grid),
# the work of the libfive / HyperFun comparison in issue 2: a 193^3 grid over
# [-1.6,1.6]^3 on bench/eval_{sphere,csg,gear,gear_minmax}.hf, 1 and 2 threads, with
# and without interval tape pruning, one thread in single precision (--single), then a small grid (49^3) at 1 and 2 threads: two
# threads must not cost more than one on it (FREP_PAR_MIN_WORK).  Each line: medians of 5 runs of the whole
# command's CPU time (user + system, /usr/bin/time) and wall time, and of frep's own
# evaluation time; points/s from the CPU time, which a shared machine inflates least.
# Last, the R-function gear against the bound its square roots set: bench_eval
# --ceilings measures the R-functions one core evaluates per second, divided by the
# gear's count of them a point.
# Usage: bench_grid.sh FREP [SRCDIR [BENCH_EVAL]]
FREP=${1:-./frep}
SRCDIR=${2:-.}
BENCH_EVAL=${3:-}
RUNS=5
N=193
OUT=${TMPDIR:-/tmp}/frep-bench-grid.$$
trap 'rm -f "$OUT" "$OUT.t" "$OUT.s" "$OUT.rates"' EXIT
: > "$OUT.rates"
echo "# $(nproc 2>/dev/null || echo '?') cores, load average: $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null)"

# median of the numbers on standard input
median() { sort -n | awk '{ v[NR] = $1 } END { if (NR % 2) print v[(NR + 1) / 2]; else print (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }

# run MODEL THREADS [--no-prune]   (grid N points per axis, 193 unless set)
run() {
  model=$1; t=$2; shift 2
  n=${GRID_N:-$N}
  : > "$OUT"
  for i in $(seq $RUNS); do
    if [ -x /usr/bin/time ]; then
      /usr/bin/time -f "%e %U %S" -o "$OUT.t" "$FREP" eval "$model" --grid $n -b 1.6 -t "$t" "$@" > "$OUT.s" || return 1
    else
      s0=$(date +%s.%N)
      "$FREP" eval "$model" --grid $n -b 1.6 -t "$t" "$@" > "$OUT.s" || return 1
      echo "$s0 $(date +%s.%N)" | awk '{ print $2 - $1, "nan", 0 }' > "$OUT.t"
    fi
    echo "$(cat "$OUT.t") $(sed -n 's/^time *\([0-9.]*\) s evaluating.*/\1/p' "$OUT.s")" >> "$OUT"
  done
  wall=$(awk '{ print $1 }' "$OUT" | median)
  cpu=$(awk '{ print $2 + $3 }' "$OUT" | median)
  ev=$(awk '{ print $4 }' "$OUT" | median)
  per=$(sed -n 's/^program .*, \([0-9.]*\) evaluated per point.*/\1/p' "$OUT.s")
  rate=$(echo "$cpu" | awk -v n=$n '{ print n * n * n / $1 * 1e-6 }')
  printf '%-22s %4s^3 -t %s %-10s  cpu %6.3f s  wall %6.3f s  eval %6.3f s  %7.1f M points/s (cpu)  %6.1f insns/point\n' \
    "$(basename "$model")" "$n" "$t" "${1:-pruned}" "$cpu" "$wall" "$ev" "$rate" "$per"
  echo "$(basename "$model" .hf) $n $t ${1:-pruned} $rate" >> "$OUT.rates"
}

for m in eval_sphere eval_csg eval_gear eval_gear_minmax; do
  f="$SRCDIR/bench/$m.hf"
  "$FREP" dis "$f" 2>/dev/null | sed -n '2s/^; /# '"$m"': /p'
  for t in 1 2; do
    run "$f" "$t" --no-prune
    run "$f" "$t"
  done
  run "$f" 1 --single
done
for t in 1 2; do GRID_N=49 run "$SRCDIR/bench/eval_sphere.hf" "$t"; done

# libfive side by side: libfive is not packaged in Debian (nothing to apt-get install),
# so its rates are the figures doc/benchmarks.md records ("Grid evaluation": the
# ArrayEvaluator in float, -O3 -march=native, one core, the same 193^3 grid): 180-410 M
# points/s on the sphere and the small CSG model, 60 M on the min/max gear, which is
# also the gear libfive would evaluate for the R-function one (it has no R-functions).
echo "# libfive: not installable from Debian; its figures from doc/benchmarks.md (one core), frep's measured above"
echo "# $(nproc 2>/dev/null || echo '?') cores, load average: $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null)"
for row in "eval_sphere 180 410" "eval_csg 180 410" "eval_gear_minmax 60 60" "eval_gear 60 60"; do
  set -- $row
  for mode in pruned --single; do
    r=$(awk -v m="$1" -v mo="$mode" '$1 == m && $2 == 193 && $3 == 1 && $4 == mo { print $5 }' "$OUT.rates")
    [ -n "$r" ] || continue
    awk -v m="$1" -v mo="$mode" -v r="$r" -v lo="$2" -v hi="$3" 'BEGIN {
      printf "%-18s -t 1 %-9s frep %7.1f M points/s   libfive %s M   frep/libfive %.2f-%.2fx  (target 2x)\n",
        m, mo, r, (lo == hi ? lo : lo "-" hi), r / hi, r / lo }'
  done
done

# The R-function gear's square roots: whatever the rest costs, one core cannot evaluate
# it faster than its R-functions alone (a + b -+ sqrt(a^2 + b^2) on 256 lanes).
if [ -n "$BENCH_EVAL" ] && [ -x "$BENCH_EVAL" ]; then
  nr=$("$FREP" dis "$SRCDIR/bench/eval_gear.hf" | grep -cE '^ *[0-9]+ +(RUNI|RINT|RSUB|AUNI|AINT) ')
  rfun=$("$BENCH_EVAL" --ceilings 9 | awk '{ print $2 }')
  r=$(awk '$1 == "eval_gear" && $2 == 193 && $3 == 1 && $4 == "pruned" { print $5 }' "$OUT.rates")
  if [ -n "$r" ] && [ -n "$rfun" ]; then
    awk -v n="$nr" -v c="$rfun" -v r="$r" 'BEGIN {
      b = c / n * 1e-6
      printf "eval_gear          -t 1 pruned    frep %7.1f M points/s   %d R-functions a point, this core %.0f M R-functions/s: at most %.1f M points/s in double (%.0f%% of it; target 30 M)\n", r, n, c * 1e-6, b, 100 * r / b }'
  fi
fi
