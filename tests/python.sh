#!/bin/sh
# tests/python.sh - the Python package (python/) under pytest against this build's
# libfrep.so (TAP: one line).  Needs /usr/bin/python3 with numpy and pytest (Debian:
# python3-numpy python3-pytest) and a shared build; skips with the reason otherwise.
s=${srcdir:-$(cd "$(dirname "$0")/.." && pwd)}
b=${builddir:-.}
py=${FREP_PYTHON:-/usr/bin/python3}
so=$(ls "$b"/.libs/libfrep.so.[0-9] 2>/dev/null | head -n 1)
if [ ! -x "$py" ]; then echo "1..0 # SKIP no $py"; exit 0; fi
if ! "$py" -c 'import numpy, pytest' 2>/dev/null; then
    echo "1..0 # SKIP $py lacks numpy or pytest (apt-get install python3-numpy python3-pytest)"
    exit 0
fi
if [ -z "$so" ]; then echo "1..0 # SKIP no shared libfrep.so in this build"; exit 0; fi
if [ -n "$(sed -n 's/^SAN_CFLAGS = *//p' "$b/Makefile" 2>/dev/null)" ]; then
    echo "1..0 # SKIP a sanitizer build's libfrep.so cannot be loaded into python3"; exit 0
fi
echo "1..1"
# From an empty directory: python -m puts the working directory first on sys.path, and
# a stray module in /tmp (a bisect.py) would shadow the standard library's.
work=$(mktemp -d "${TMPDIR:-/tmp}/frep-py.XXXXXX") || exit 1
trap 'rm -rf "$work"' EXIT INT TERM
out=$(cd "$work" && FREP_LIBRARY="$so" PYTHONPATH="$s/python" PYTHONDONTWRITEBYTECODE=1 \
      srcdir="$s" "$py" -m pytest -q -p no:cacheprovider "$s/python/tests" 2>&1)
rc=$?
echo "$out" | sed 's/^/# /'
if [ $rc -eq 0 ]; then echo "ok 1 - pytest python/tests: $(echo "$out" | tail -n 1)"
else echo "not ok 1 - pytest python/tests failed"; fi
