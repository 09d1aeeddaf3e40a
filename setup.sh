#!/bin/sh
# setup.sh - install missing build tools (Debian, as root), build frep, and then
#   ./setup.sh          run frep's main job on a bundled example
#   ./setup.sh check    run the whole test suite
#   ./setup.sh build    only build
# The build goes to build/ (the frep command is build/frep).
set -eu
cd "$(dirname "$0")"

need=""
for pair in gcc:gcc make:make autoreconf:autoconf automake:automake libtoolize:libtool \
            re2c:re2c bison:bison pkg-config:pkg-config; do
    cmd=${pair%%:*}; pkg=${pair#*:}
    command -v "$cmd" >/dev/null 2>&1 || need="$need $pkg"
done
# libraries: zlib for the PNG pictures of frep render
pkg-config --exists zlib 2>/dev/null || [ -f /usr/include/zlib.h ] || need="$need zlib1g-dev"
if [ -n "$need" ]; then
    echo "setup: installing$need"
    if [ "$(id -u)" -ne 0 ]; then echo "setup: run as root to install$need" >&2; exit 1; fi
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq $need >/dev/null
fi

if [ ! -x configure ] || [ configure.ac -nt configure ] || [ Makefile.am -nt Makefile.in ]; then
    autoreconf -fi
fi
mkdir -p build
cd build
[ -f Makefile ] || ../configure --quiet
jobs=$(nproc 2>/dev/null || echo 2)
make -s -j"$jobs"

case "${1:-run}" in
build) ;;
check) make -s -j"$jobs" check || { cat test-suite.log; exit 1; } ;;
run)
    # The journey frep is for: a scan (here sampled from a bundled model, with
    # noise) -> frep evolve -> a readable model.hf -> frep mesh -> a picture.
    mkdir -p quickstart
    set -x
    ./frep sample ../examples/reverse/part.hf -n 20000 --noise 0.001 --seed 1 -o quickstart/scan.xyz
    ./frep evolve quickstart/scan.xyz --seed 1 -o quickstart/model.hf
    cat quickstart/model.hf
    ./frep mesh quickstart/model.hf -g 96 -o quickstart/model.stl
    ./frep render quickstart/model.hf --points quickstart/scan.xyz -o quickstart/model.png
    { set +x; } 2>/dev/null
    echo "setup: the model is build/quickstart/model.hf, its mesh model.stl, its picture model.png"
    ;;
*) echo "usage: $0 [run|check|build]" >&2; exit 2 ;;
esac
