#!/bin/sh
# fuzz.sh - build the libFuzzer target tests/fuzz_compile.c with clang (ASan + UBSan)
# and run it for SECONDS (default 60) on a corpus seeded from the examples and the
# golden tests.  Usage: tests/fuzz.sh [SECONDS]   (from the source tree, after a build
# from git so that lang/lex.c and lang/parse.c exist).  Not part of make check; .ci/run
# runs it for 30 s.  Exits non-zero when the fuzzer finds a crash, a leak or a timeout
# (the input is left in ${TMPDIR:-/tmp}/frep-fuzz as crash-*, leak-* or timeout-*).
set -eu
cd "$(dirname "$0")/.."
secs=${1:-60}
out=${TMPDIR:-/tmp}/frep-fuzz
mkdir -p "$out/corpus"
# the seeds: every model of the tree but the limit tests (slow on purpose)
for f in examples/*.hf examples/*/*.hf tests/lang/*/*.hf tests/dis/*.hf; do
    [ -e "$f" ] || continue
    case $f in tests/lang/limits/*) continue ;; esac
    cp "$f" "$out/corpus/$(echo "$f" | tr / _)"
done
cfg=${FREP_BUILD:-build}
[ -f "$cfg/config.h" ] || { echo "fuzz.sh: build first (./setup.sh build)" >&2; exit 2; }
clang -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
    -I"$cfg" -Iruntime -Ilang -DHAVE_CONFIG_H \
    tests/fuzz_compile.c lang/*.c runtime/*.c -lm -o "$out/fuzz_compile"
cd "$out" && ./fuzz_compile -max_total_time="$secs" -max_len=4096 -timeout=60 corpus
