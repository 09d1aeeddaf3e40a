#!/bin/sh
# max_time.sh - --max-time bounds the whole of frep segment and frep evolve (reading,
# normal estimation, segmentation, GA, writing) on a cloud large and noisy enough that
# each step alone takes longer than the bound; the command says what it cut short and
# still writes its result. Prints TAP.
# Needs FREP (the frep binary) and srcdir (the source tree).

: "${FREP:?FREP must name the frep binary}"
: "${srcdir:?srcdir must name the source tree}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-maxtime.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM
M="$srcdir/tests/models"

# The bound asked for, and the allowance: 10% (issue 13's target) plus 1.5 s for
# starting the process, reading the cloud (about 0.5 s of processor time for these
# 150,000 points) and the unpolled steps after the stop, on an idle machine; on a
# loaded one the allowance grows with the load per processor, as the latency limit of
# tests/interrupt.sh does (the command then gets a fraction of a processor).
T=2
ncpu=$(getconf _NPROCESSORS_ONLN 2>/dev/null || echo 1)
SLACK=$(awk -v l="$(cut -d' ' -f1 /proc/loadavg 2>/dev/null || echo 0)" -v c="$ncpu" \
    'BEGIN { f = l / c; printf "%.2f", 1.5 * (f > 1 ? f : 1) }')
echo "# allowance $SLACK s (1.5 s x the load per processor, $ncpu processors)"
NPTS=150000

. "$(dirname "$0")/tap.sh"

now() { date +%s.%N; }

"$FREP" sample "$M/segment_box.hf" -n $NPTS --seed 1 --noise 0.01 -o "$tmp/t.xyz" -q || exit 1
awk '{ print $1, $2, $3 }' "$tmp/t.xyz" > "$tmp/p.xyz"

for cmd in segment evolve; do
    out="$tmp/out.$cmd"
    [ $cmd = segment ] && out="$tmp/out.fit"
    [ $cmd = evolve ] && out="$tmp/out.hf"
    t0=$(now)
    "$FREP" $cmd "$tmp/p.xyz" --seed 1 -o "$out" --max-time $T >/dev/null 2>"$tmp/err"
    st=$?
    t1=$(now)
    wall=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", b - a }')
    awk -v w="$wall" -v t=$T -v s=$SLACK 'BEGIN { exit !(w <= 1.1 * t + s) }'
    report $? "$cmd --max-time $T: $wall s wall <= 1.1 T + $SLACK s"
    [ $st -lt 128 ] && grep -q -- "--max-time $T s reached" "$tmp/err"
    report $? "$cmd: says what it cut short (exit $st): $(grep -- '--max-time' "$tmp/err" | head -n 1)"
done
# segment keeps what it found (maybe nothing) and exits 0; evolve writes a model when
# the time left a primitive to combine, else fails with its reason.
[ -f "$tmp/out.fit" ]
report $? "segment: the primitives found so far are written"

# A deadline inside the GA (10,000 points with their normals: segmentation takes a
# fraction of T; one GA without partitioning or stagnation stop never ends by itself):
# the best tree so far is written as a model, within the same allowance.
"$FREP" sample "$M/segment_box.hf" -n 10000 --seed 1 --noise 0.005 -o "$tmp/n.xyz" -q || exit 1
t0=$(now)
"$FREP" evolve "$tmp/n.xyz" --seed 1 -o "$tmp/ga.hf" --max-time $T --generations 1000000 \
    --stagnation 0 --no-partition >/dev/null 2>"$tmp/err"
st=$?
t1=$(now)
wall=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", b - a }')
awk -v w="$wall" -v t=$T -v s=$SLACK 'BEGIN { exit !(w <= 1.1 * t + s) }'
report $? "evolve, deadline in the GA, --max-time $T: $wall s wall <= 1.1 T + $SLACK s"
[ $st = 0 ] && grep -q -- "--max-time $T s reached during" "$tmp/err" && grep -q "^evolved(x\[3\]" "$tmp/ga.hf"
report $? "evolve: the best tree so far written (exit $st): $(grep -- '--max-time' "$tmp/err" | head -n 1)"

tap_done
