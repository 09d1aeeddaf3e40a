#!/bin/sh
# bench_mesh.sh - meshing time and peak memory of frep mesh (make bench-mesh):
#  1. bench/bench_mesh.hf (~150-instruction CSG part) at -g 128, 256 and 512;
#  2. the comparison with libfive and HyperFun's polygonizer: bench/bench_gear.hf
#     (~440 instructions) and bench/bench_gyroid.hf at -g 128 over [-1.6,1.6]^3 with
#     1 and 2 threads;
#  3. the gyroid written as OFF text (formatted on the threads) at 1 and 2 threads.
# Each line: the median of 5 runs of the mesher's own time (the summary line: octree,
# evaluation, vertices, triangles), and of the whole command's wall time, CPU time
# (user + system: compiling, meshing, writing the binary STL) and peak resident
# memory (/usr/bin/time).  For the gear and the gyroid at 1 thread it also prints the
# ratio of the whole command's CPU time to libfive's meshing time on the same work
# (doc/benchmarks.md: 0.08 s and 0.36 s, measured on this kind of machine).
# Usage: bench_mesh.sh FREP [SRCDIR]
FREP=${1:-./frep}
SRCDIR=${2:-.}
# An uninstalled build's ./frep is libtool's wrapper script, whose shell start-up
# costs ~15 ms per run: time the real program next to it.
if [ -x "$(dirname "$FREP")/.libs/frep" ] && head -c 2 "$FREP" | grep -q '#!'; then
  LD_LIBRARY_PATH="$(cd "$(dirname "$FREP")/.libs" && pwd)${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
  export LD_LIBRARY_PATH
  FREP="$(dirname "$FREP")/.libs/frep"
fi
OUT=${TMPDIR:-/tmp}/frep-bench-mesh.$$.stl
RUNS=5
trap 'rm -f "$OUT" "$OUT.t" "$OUT.s" "${OUT%.stl}.off"' EXIT
echo "# $(nproc 2>/dev/null || echo '?') cores, load average: $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null)"

# median of the numbers on standard input
median() { sort -n | awk '{ v[NR] = $1 } END { if (NR % 2) print v[(NR + 1) / 2]; else print (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }

# run MODEL GRID THREADS [OUTPUT]: RUNS runs, prints medians
run() {
  model=$1; g=$2; t=$3; out=${4:-$OUT}
  : > "$OUT.t"
  for i in $(seq $RUNS); do
    if [ -x /usr/bin/time ]; then
      /usr/bin/time -f "%e %U %S %M" -o "$OUT.t.1" "$FREP" mesh "$model" -b 1.6 -g "$g" -t "$t" -o "$out" > "$OUT.s" || return 1
      echo "$(cat "$OUT.t.1") $(sed -n 's/.*, \([0-9.]*\) s$/\1/p' "$OUT.s")" >> "$OUT.t"
    else
      "$FREP" mesh "$model" -b 1.6 -g "$g" -t "$t" -o "$out" -q || return 1
    fi
  done
  rm -f "$OUT.t.1"
  tris=$("$FREP" mesh "$model" -b 1.6 -g "$g" -t "$t" -o "$OUT" | sed -n 's/.* \([0-9]*\) triangles.*/\1/p')
  if [ -s "$OUT.t" ]; then
    wall=$(awk '{ print $1 }' "$OUT.t" | median)
    cpu=$(awk '{ print $2 + $3 }' "$OUT.t" | median)
    mem=$(awk '{ print $4 }' "$OUT.t" | median)
    mesh=$(awk '{ print $5 }' "$OUT.t" | median)
    ref=
    case "$(basename "$model") $g $t${4:+ text}" in
      "bench_gear.hf 128 1") ref=0.08 ;;
      "bench_gyroid.hf 128 1") ref=0.36 ;;
    esac
    printf '%-22s -g %-4s -t %s  %9s triangles  meshing %6.3f s  wall %6.3f s  cpu %6.3f s  peak %6.1f MB%s\n' \
      "$(basename "$model")${4:+ ${out##*.}}" "$g" "$t" "$tris" "$mesh" "$wall" "$cpu" "$(echo "$mem" | awk '{ print $1 / 1024 }')" \
      "$(if [ -n "$ref" ]; then echo "$cpu $ref" | awk '{ printf "  cpu / libfive %.2f", $1 / $2 }'; fi)"
  else
    printf '%-22s -g %-4s -t %s  %9s triangles (no /usr/bin/time)\n' "$(basename "$model")" "$g" "$t" "$tris"
  fi
}

for m in "$SRCDIR/bench/bench_gear.hf" "$SRCDIR/bench/bench_gyroid.hf"; do
  "$FREP" dis "$m" 2>/dev/null | sed -n '2s/^; /# '"$(basename "$m")"': /p'
  for t in 1 2; do run "$m" 128 "$t"; done
done
"$FREP" dis "$SRCDIR/bench/bench_mesh.hf" 2>/dev/null | sed -n '2s/^; /# bench_mesh.hf: /p'
for g in 128 256 512; do run "$SRCDIR/bench/bench_mesh.hf" "$g" 2; done
for t in 1 2; do run "$SRCDIR/bench/bench_gyroid.hf" 128 "$t" "${OUT%.stl}.off"; done
