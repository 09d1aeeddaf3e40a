#!/bin/sh
# tests/install.sh - installing frep the usual ways (TAP): `make install prefix=DIR`
# puts the command, the library, frep.h, a frep.pc naming DIR, the man page, the
# documents and the examples under DIR; a C program (examples/api/eval.c) built with
# pkg-config against DIR runs and writes the mesh `frep mesh` writes; the Python
# example runs against DIR (when /usr/bin/python3 has numpy); DESTDIR stages an
# install whose frep.pc names the final prefix; make uninstall removes every file.
s=${srcdir:-$(cd "$(dirname "$0")/.." && pwd)}
b=${builddir:-.}
if ! command -v pkg-config >/dev/null 2>&1 || ! command -v "${CC:-cc}" >/dev/null 2>&1; then
    echo "1..0 # SKIP needs pkg-config and a C compiler"; exit 0
fi
tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-install.XXXXXX")
trap 'rm -rf "$tmp"' EXIT INT TERM
p=$tmp/prefix
n=0
t() { n=$((n + 1)); if [ "$1" -eq 0 ]; then echo "ok $n - $2"; else echo "not ok $n - $2"; fi; }
echo "1..12"
# MAKEFLAGS of the make check that runs us would bring its -j and targets along
env -u MAKEFLAGS -u MFLAGS make -s -C "$b" install prefix="$p" >"$tmp/log" 2>&1
rc=$?; [ $rc -eq 0 ] || sed 's/^/# /' "$tmp/log"
t $rc "make install prefix=$p"
"$p/bin/frep" --version >"$tmp/v" 2>&1
t $? "the installed frep runs ($(head -n 1 "$tmp/v"))"
[ -f "$p/include/frep.h" ] && ls "$p"/lib/libfrep.* >/dev/null 2>&1
t $? "frep.h and libfrep installed"
grep -qx "prefix=$p" "$p/lib/pkgconfig/frep.pc" && grep -qx "libdir=$p/lib" "$p/lib/pkgconfig/frep.pc"
t $? "frep.pc names the prefix of make install"
[ -f "$p/share/man/man1/frep.1" ]
t $? "man page frep.1 installed"
[ -f "$p/share/doc/frep/api.md" ] && [ -f "$p/share/doc/frep/examples/csg.hf" ] &&
    [ -f "$p/share/doc/frep/examples/reverse/part.hf" ] && [ -f "$p/share/doc/frep/examples/api/eval.c" ]
t $? "documents and examples installed under share/doc/frep"

# a C program against the installed library, through pkg-config
export PKG_CONFIG_PATH="$p/lib/pkgconfig"
static=; ls "$p"/lib/libfrep.so >/dev/null 2>&1 || static=--static
# compiled with the build's flags: a sanitizer or coverage build's library needs them
mk() { sed -n "s/^$1 = //p" "$b/Makefile" | head -n 1; }
san=$(mk SAN_CFLAGS); flags="$(mk CFLAGS) $(mk LDFLAGS) $san"
${CC:-cc} $flags -o "$tmp/eval" "$s/examples/api/eval.c" $(pkg-config --cflags frep) \
    $(pkg-config --libs $static frep) >"$tmp/log" 2>&1
rc=$?; [ $rc -eq 0 ] || sed 's/^/# /' "$tmp/log"
t $rc "examples/api/eval.c builds with pkg-config --cflags --libs frep"
LD_LIBRARY_PATH="$p/lib" "$tmp/eval" "$s/examples/csg.hf" "$tmp/api.stl" 24 >"$tmp/out" 2>&1 &&
    "$p/bin/frep" mesh "$s/examples/csg.hf" -g 24 -o "$tmp/cli.stl" >/dev/null 2>&1 &&
    cmp -s "$tmp/api.stl" "$tmp/cli.stl"
rc=$?; sed 's/^/# /' "$tmp/out"
t $rc "it runs against the installed libfrep and writes frep mesh's bytes"
LD_LIBRARY_PATH="$p/lib" ldd "$tmp/eval" 2>/dev/null | grep -q "libfrep.so.0 => $p/lib/" || [ -n "$static" ]
t $? "it loads the installed libfrep.so.0"

# the Python package installed by pip (offline, from a copy: the source tree may be
# read-only), then the Python example, finding the library through pkg-config
if /usr/bin/python3 -c 'import numpy' 2>/dev/null && [ -z "$static" ] && [ -z "$san" ]; then
    pypath="$s/python" how="from python/"
    cp -R "$s/python" "$tmp/pysrc" && chmod -R u+w "$tmp/pysrc"
    if /usr/bin/python3 -m pip --version >/dev/null 2>&1 &&
       /usr/bin/python3 -m pip install -q --no-deps --no-build-isolation --no-index \
           --target "$tmp/py" "$tmp/pysrc" >"$tmp/log" 2>&1; then
        pypath="$tmp/py" how="installed by pip"
    else
        sed 's/^/# /' "$tmp/log" 2>/dev/null
    fi
    (cd "$tmp" && LD_LIBRARY_PATH="$p/lib" PYTHONPATH="$pypath" PYTHONDONTWRITEBYTECODE=1 \
        /usr/bin/python3 "$s/examples/api/mesh.py" "$s/examples/csg.hf" "$tmp/py.stl" 24) \
        >"$tmp/out" 2>&1 && cmp -s "$tmp/py.stl" "$tmp/cli.stl"
    rc=$?; sed 's/^/# /' "$tmp/out"
    t $rc "examples/api/mesh.py ($how) runs against the installed libfrep, same mesh"
else
    n=$((n + 1)); echo "ok $n # SKIP no /usr/bin/python3 with numpy, or a static or sanitizer build"
fi

env -u MAKEFLAGS -u MFLAGS make -s -C "$b" install prefix=/opt/frep-test DESTDIR="$tmp/stage" >"$tmp/log" 2>&1 &&
    [ -x "$tmp/stage/opt/frep-test/bin/frep" ] &&
    grep -qx "prefix=/opt/frep-test" "$tmp/stage/opt/frep-test/lib/pkgconfig/frep.pc"
rc=$?; [ $rc -eq 0 ] || sed 's/^/# /' "$tmp/log"
t $rc "make install DESTDIR=STAGE prefix=/opt/frep-test stages the tree, frep.pc names /opt/frep-test"

env -u MAKEFLAGS -u MFLAGS make -s -C "$b" uninstall prefix="$p" >"$tmp/log" 2>&1
left=$(find "$p" -type f | sed "s|^$p/||" | tr '\n' ' ')
[ -z "$left" ]
t $? "make uninstall removes every file${left:+ (left: $left)}"
# leave the build's frep.pc naming the configured prefix again
env -u MAKEFLAGS -u MFLAGS make -s -C "$b" frep.pc >/dev/null 2>&1
