#!/bin/sh
# max_memory.sh - --max-memory, an option of every subcommand: a command whose data
# does not fit under the cap stops with "out of memory" and exit 1, its existing output
# untouched and no temporary left; the same command under a generous cap succeeds (so
# the cap, not the command, made it fail); malformed and too small sizes are usage
# errors. Prints TAP.
# Needs FREP (the frep binary) and srcdir (the source tree).

: "${FREP:?FREP must name the frep binary}"
: "${srcdir:?srcdir must name the source tree}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-maxmem.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM
EX="$srcdir/examples"

. "$(dirname "$0")/tap.sh"

# Usage errors first: they hold under every build.
for bad in 0 -5 1Q 12KX '' 1k; do
    "$FREP" mesh "$EX/csg.hf" --max-memory "$bad" -o "$tmp/u.stl" >/dev/null 2>"$tmp/err"
    st=$?
    [ $st = 2 ] && grep -q "^frep mesh: --max-memory: expected" "$tmp/err" && [ ! -e "$tmp/u.stl" ]
    report $? "--max-memory '$bad': exit $st, '$(head -n 1 "$tmp/err")'"
done

# AddressSanitizer reserves terabytes of shadow memory up front: under it no cap on the
# data segment can hold, so the caps themselves are tested only in plain builds.
if grep -q __asan_init "$FREP" 2>/dev/null; then
    echo "# skipped: the caps (an AddressSanitizer build)"
    tap_done
fi

# Every spelling of 64 MiB is accepted and a small mesh fits under it. Each worker
# thread costs about 1.5 MB (its stack, its share of the mesher's buffers), so the
# threads are fixed at 2 to make the figure independent of the machine's cores.
for good in 64M 64MiB 65536K 0.0625G 67108864; do
    "$FREP" mesh "$EX/csg.hf" -g 16 -t 2 --max-memory "$good" -o "$tmp/g.stl" -q 2>"$tmp/err"
    report $? "--max-memory $good is accepted (a mesh at -g 16 fits): '$(head -n 1 "$tmp/err")'"
done

# CMD OUT ARGS...: under 48M the command fails cleanly and OUT keeps its old contents;
# under 4G it writes OUT.
capped() {
    what=$1 out=$2
    shift 2
    echo "old contents" >"$out"
    "$FREP" "$@" --max-memory 48M >/dev/null 2>"$tmp/err"
    st=$?
    [ $st = 1 ] && grep -q "out of memory" "$tmp/err" &&
        [ "$(cat "$out")" = "old contents" ] && ! ls "$tmp"/*.tmp* >/dev/null 2>&1
    report $? "$what under 48M: exit $st, '$(head -n 1 "$tmp/err")', the old file kept"
    "$FREP" "$@" --max-memory 4G >/dev/null 2>"$tmp/err"
    st=$?
    [ $st = 0 ] && [ "$(cat "$out")" != "old contents" ]
    report $? "$what under 4G: exit $st, written"
}

# A cloud of 600,000 points: about 14 MB as read, several times that segmented.
"$FREP" sample "$EX/gear.hf" -n 600000 --seed 3 -o "$tmp/big.ply" -q || exit 1

capped "mesh -g 512 of the gear" "$tmp/m.stl" mesh "$EX/gear.hf" -g 512 -o "$tmp/m.stl" -q
capped "sample -n 2000000" "$tmp/s.xyz" sample "$EX/gear.hf" -n 2000000 --seed 1 \
    -o "$tmp/s.xyz" -q
capped "segment of 600,000 points" "$tmp/seg.fit" segment "$tmp/big.ply" --seed 1 \
    --max-time 5 -o "$tmp/seg.fit" -q

tap_done
