#!/bin/sh
# tests/exports.sh - the dynamic symbols libfrep.so exports (TAP): every one starts
# with frep_, every one is a function frep.h declares, and every function frep.h
# declares is exported (libfrep.sym, made from the header, is the list; nm -D the
# truth).  And the frep command (cli/*.o) uses the library only through those
# functions: it is built on the public API (issue 20).  Skipped in a build without the
# shared library (--disable-shared).
b=${builddir:-.}
so=$(ls "$b"/.libs/libfrep.so.[0-9]* 2>/dev/null | head -n 1)
if [ -z "$so" ] || ! command -v nm >/dev/null 2>&1; then
    echo "1..0 # SKIP no shared libfrep.so in this build (or no nm)"
    exit 0
fi
tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-exports.XXXXXX")
trap 'rm -rf "$tmp"' EXIT INT TERM
# defined dynamic symbols of any kind (functions T, data D/B/R, weak W/V, ...)
nm -D --defined-only "$so" | awk 'NF >= 3 { print $3 }' | sed 's/@.*//' | LC_ALL=C sort -u >"$tmp/exported"
LC_ALL=C sort -u "$b/libfrep.sym" >"$tmp/declared"
n=$(wc -l <"$tmp/exported" | tr -d ' ')
d=$(wc -l <"$tmp/declared" | tr -d ' ')
echo "1..5"
echo "# $so exports $n symbols; frep.h declares $d functions"
bad=$(grep -v '^frep_' "$tmp/exported" | tr '\n' ' ')
if [ -z "$bad" ]; then echo "ok 1 - every exported symbol starts with frep_"
else echo "not ok 1 - exported without the frep_ prefix: $bad"; fi
extra=$(LC_ALL=C comm -23 "$tmp/exported" "$tmp/declared" | tr '\n' ' ')
if [ -z "$extra" ]; then echo "ok 2 - every exported symbol is declared in frep.h"
else echo "not ok 2 - exported but not in frep.h (internal): $extra"; fi
missing=$(LC_ALL=C comm -13 "$tmp/exported" "$tmp/declared" | tr '\n' ' ')
if [ -z "$missing" ]; then echo "ok 3 - every function of frep.h is exported"
else echo "not ok 3 - declared in frep.h but not exported: $missing"; fi
# the list itself: a sanity floor against an empty or truncated extraction
if [ "$d" -ge 40 ] && grep -qx frep_compile "$tmp/declared" && grep -qx frep_version "$tmp/declared"
then echo "ok 4 - libfrep.sym lists frep.h's functions ($d)"
else echo "not ok 4 - libfrep.sym looks wrong ($d names)"; fi
# the command's objects: what they take from the library is frep.h's functions only
core=$(ls "$b"/.libs/libfrepcore.a 2>/dev/null | head -n 1)
objs=$(ls "$b"/cli/*.o 2>/dev/null)
if [ -z "$core" ] || [ -z "$objs" ]; then
    echo "ok 5 # SKIP no libfrepcore.a or cli/*.o in this build"
else
    nm --defined-only "$core" 2>/dev/null | awk 'NF >= 3 && $2 ~ /[TDBRVW]/ { print $3 }' |
        LC_ALL=C sort -u >"$tmp/core"
    nm -u $objs | awk 'NF >= 2 { print $2 }' | LC_ALL=C sort -u >"$tmp/used"
    LC_ALL=C comm -12 "$tmp/used" "$tmp/core" >"$tmp/taken"
    internal=$(LC_ALL=C comm -23 "$tmp/taken" "$tmp/declared" | tr '\n' ' ')
    k=$(wc -l <"$tmp/taken" | tr -d ' ')
    if [ -z "$internal" ] && [ "$k" -ge 40 ]; then
        echo "ok 5 - the frep command uses $k functions of the library, all in frep.h"
    else
        echo "not ok 5 - the frep command uses the library's internals: $internal ($k in all)"
    fi
fi
