#!/bin/sh
# tests/fault_coverage.sh - which allocation sites of the library no test reaches.
#   sh tests/fault_coverage.sh [SRCDIR [BUILDDIR]]     (make fault-coverage runs it)
# Builds frep with gcov instrumentation in BUILDDIR (default build-coverage), runs the
# whole suite there (tests/test_faults makes every allocation fail once), then lists
# each line of the library (runtime lang geom mesh fit segment export evolve, without the
# allocator runtime/alloc.c itself) that calls frep_malloc, frep_calloc, frep_realloc,
# frep_reallocarray, frep_strdup, frep_strndup or frep_aligned_alloc and never ran.
# Prints "reached/total" and fails when any site is left.
set -eu
src=$(cd "${1:-$(dirname "$0")/..}" && pwd)
build=${2:-$src/build-coverage}
jobs=$(nproc 2>/dev/null || echo 2)

mkdir -p "$build"
cd "$build"
# -O2 with plain counters: the atomic ones gcc uses with OpenMP keep the evaluator's
# loops from vectorizing (the suite ran 10-100 times slower); a count lost to a race
# between threads never leaves a line that ran at zero.
if [ ! -f Makefile ]; then
    "$src/configure" --quiet --disable-shared CFLAGS="-O2 -g --coverage -fprofile-update=single" LDFLAGS="--coverage"
fi
make -s -j"$jobs"
find . -name '*.gcda' -exec rm -f {} +
make -s -j"$jobs" check >/dev/null 2>&1 || echo "fault_coverage: make check failed (see $build/test-suite.log); counting anyway" >&2

# gcov of every library object: lines "count:line:text" under a "Source:" header.
list=$(mktemp "${TMPDIR:-/tmp}/frep-cov.XXXXXX")
trap 'rm -f "$list"' EXIT INT TERM
for dir in runtime lang geom mesh fit segment export evolve; do
    [ -d "$dir" ] || continue
    for gcno in "$dir"/*.gcno; do
        [ -f "$gcno" ] || continue
        (cd "$dir" && gcov -t -o "$(basename "$gcno")" "$(basename "$gcno" .gcno).c" 2>/dev/null) || true
    done
done | awk -v src="$src/" '
    /^ *-: *0:Source:/ { f = $0; sub(/^ *-: *0:Source:/, "", f); sub(/^(\.\.\/)+/, "", f);
                         sub("^" src, "", f); next }
    {
        if (f !~ /^(runtime|lang|geom|mesh|fit|segment|export|evolve)\// || f == "runtime/alloc.c") next
        n = split($0, part, ":")
        if (n < 3) next
        count = part[1]; gsub(/ /, "", count); line = part[2] + 0
        text = substr($0, length(part[1]) + length(part[2]) + 3)
        if (text !~ /frep_(malloc|calloc|realloc|reallocarray|strdup|strndup|aligned_alloc)\(/) next
        if (count == "-") next
        key = f ":" line
        ran = (count ~ /^[0-9]+\*?$/ && count + 0 > 0) ? 1 : 0
        if (!(key in seen)) { seen[key] = ran; where[key] = text } else if (ran) seen[key] = 1
    }
    END { for (k in seen) printf "%s\t%d\t%s\n", k, seen[k], where[k] }' | sort -t: -k1,1 -k2,2n >"$list"

total=$(wc -l <"$list")
reached=$(awk -F'\t' '$2 == 1' "$list" | wc -l)
awk -F'\t' '$2 == 0 { sub(/^[ \t]+/, "", $3); printf "%s: never reached: %s\n", $1, $3 }' "$list"
echo "fault_coverage: allocation sites reached: $reached/$total"
[ "$reached" -eq "$total" ]
