#!/bin/sh
# bench_mesh.sh - meshing time and peak memory of frep mesh on bench/bench_mesh.hf at
# -g 128, 256 and 512 (make bench). Usage: bench_mesh.sh FREP [SRCDIR]
FREP=${1:-./frep}
SRCDIR=${2:-.}
MODEL="$SRCDIR/bench/bench_mesh.hf"
OUT=${TMPDIR:-/tmp}/frep-bench-mesh.$$.stl
echo "# frep mesh on $MODEL, box 1.6 (the model spans [-1.4,1.4]x[-1,1]x[-0.2,1])"
"$FREP" dis "$MODEL" 2>/dev/null | grep -c . | sed 's/^/# bytecode lines: /'
for g in 128 256 512; do
  if [ -x /usr/bin/time ]; then
    /usr/bin/time -f "%e s wall, %U s user, %M KiB peak" "$FREP" mesh "$MODEL" -b 1.6 -g $g -o "$OUT" 2>&1
  else
    "$FREP" mesh "$MODEL" -b 1.6 -g $g -o "$OUT"
  fi
done
rm -f "$OUT"
