#!/bin/sh
# fuzz.sh - build the libFuzzer targets with clang (ASan + UBSan) and run each for
# SECONDS (default 60) on its corpus.  Usage: tests/fuzz.sh [SECONDS [TARGET...]]
# (from the source tree, after a build from git so that lang/lex.c and lang/parse.c
# exist).  Targets (default: all):
#   compile    tests/fuzz_compile.c: the front end and compiler, seeded from the
#              examples, the golden tests and tests/fuzz/compile/ (inputs it found)
#   cloud      tests/fuzz_readers.c: point clouds (.xyz text and PLY)
#   mesh_off, mesh_stl, mesh_obj, mesh_ply: triangle mesh files
#   fit        the .fit primitive list;  prims_hf: the .hf primitive list
# The readers' seeds are tests/fuzz/TARGET/.  Not part of make check; .ci/run runs
# every target for 20 s.  Exits non-zero when a fuzzer finds a crash, a leak or a
# timeout (the input is left in ${TMPDIR:-/tmp}/frep-fuzz/TARGET as crash-*, leak-*
# or timeout-*); the last line of each run (executions, corpus) is printed.
set -eu
cd "$(dirname "$0")/.."
secs=${1:-60}
[ $# -gt 0 ] && shift
targets=${*:-compile cloud mesh_off mesh_stl mesh_obj mesh_ply fit prims_hf}
out=${TMPDIR:-/tmp}/frep-fuzz
cfg=${FREP_BUILD:-build}
[ -f "$cfg/config.h" ] || { echo "fuzz.sh: build first (./setup.sh build)" >&2; exit 2; }
src=$(pwd)
san="address,undefined -fno-sanitize-recover=undefined"
incs="-I$cfg -Iruntime -Ilang -Igeom -Isegment -DHAVE_CONFIG_H"

# The library's sources, compiled once for every target (an object is rebuilt when
# its source is newer).
objdir=$out/obj
mkdir -p "$objdir"
objs=
for f in lang/*.c runtime/*.c geom/*.c segment/*.c; do
    o=$objdir/$(echo "$f" | tr / _ | sed 's/\.c$/.o/')
    if [ ! -f "$o" ] || [ "$f" -nt "$o" ]; then
        clang -g -O1 -fsanitize=fuzzer-no-link,$san $incs -c "$f" -o "$o"
    fi
    case $f in geom/* | segment/*) objs="$objs $o" ;; *) base="${base:-} $o" ;; esac
done

reader_number() {
    case $1 in
        cloud) echo 1 ;; mesh_off) echo 2 ;; mesh_stl) echo 3 ;; mesh_obj) echo 4 ;;
        mesh_ply) echo 5 ;; fit) echo 6 ;; prims_hf) echo 7 ;;
        *) echo "fuzz.sh: unknown target '$1'" >&2; exit 2 ;;
    esac
}

for t in $targets; do
    dir=$out/$t
    mkdir -p "$dir/corpus"
    if [ "$t" = compile ]; then
        # the seeds: every model of the tree but the limit tests (slow on purpose)
        for f in examples/*.hf examples/*/*.hf tests/lang/*/*.hf tests/dis/*.hf \
            tests/fuzz/compile/*.hf; do
            [ -e "$f" ] || continue
            case $f in tests/lang/limits/*) continue ;; esac
            cp "$f" "$dir/corpus/$(echo "$f" | tr / _)"
        done
        clang -g -O1 -fsanitize=fuzzer,$san $incs tests/fuzz_compile.c $base -lm -o "$dir/fuzz"
        maxlen=4096
    else
        cp tests/fuzz/"$t"/* "$dir/corpus/"
        clang -g -O1 -fsanitize=fuzzer,$san $incs -DFUZZ_READER="$(reader_number "$t")" \
            tests/fuzz_readers.c $objs $base -lm -o "$dir/fuzz"
        maxlen=16384
    fi
    echo "== fuzz $t ($secs s)"
    (cd "$dir" && ./fuzz -max_total_time="$secs" -max_len=$maxlen -timeout=60 \
        -print_final_stats=1 corpus 2>"$dir/log") || {
        tail -n 40 "$dir/log" >&2
        echo "fuzz.sh: $t failed; the input is in $dir" >&2
        exit 1
    }
    grep -E '^stat::number_of_executed_units|^stat::peak_rss_mb|^#[0-9]+.*DONE' "$dir/log" |
        tr '\n' ' '
    echo
    cd "$src"
done
