#!/bin/sh
# tests/layers.sh - the include directions of the library's folders (TAP).
# Each folder is a layer; a file may include the headers of its own folder and of
# earlier layers only. Folders of one rank are independent of each other:
#   runtime (0) <- lang (1) <- geom (2) <- mesh, fit, segment, view, export (3) <- evolve (4)
#   <- api (5) <- cli (6)
# Headers are included by bare name (Makefile.am puts every folder on the include
# path), so a header name must also be unique across the folders.  The
# frep command (every file of cli/) includes frep.h (through cli.h) and no library header.
src=${srcdir:-$(cd "$(dirname "$0")/.." && pwd)}
cd "$src" || exit 1
layers="runtime:0 lang:1 geom:2 mesh:3 fit:3 segment:3 view:3 export:3 evolve:4 api:5 cli:6"

rank() {
    for l in $layers; do [ "${l%%:*}" = "$1" ] && { echo "${l#*:}"; return; }; done
    echo -1
}

# header -> folder, for every header of the layered folders
map=$(mktemp); trap 'rm -f "$map"' EXIT
for l in $layers; do
    d=${l%%:*}
    for h in "$d"/*.h; do [ -f "$h" ] && echo "$(basename "$h") $d"; done
done | sort >"$map"

n=0; bad=0
dups=$(awk '{print $1}' "$map" | uniq -d)
n=$((n + 1))
if [ -n "$dups" ]; then
    echo "not ok $n - header names unique across folders: $(echo $dups)"; bad=1
else
    echo "ok $n - header names unique across folders"
fi

for l in $layers; do
    d=${l%%:*}; r=${l#*:}
    problems=""
    for f in "$d"/*.c "$d"/*.h "$d"/*.re "$d"/*.y; do
        [ -f "$f" ] || continue
        case "$f" in lang/lex.c|lang/parse.c|lang/parse.h) continue ;; esac
        for inc in $(sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*"\([^"]*\)".*/\1/p' "$f"); do
            owner=$(awk -v h="$inc" '$1 == h {print $2}' "$map")
            [ -n "$owner" ] || continue          # config.h, generated or system headers
            [ "$owner" = "$d" ] && continue
            ro=$(rank "$owner")
            if [ "$ro" -ge "$r" ]; then problems="$problems $f:$inc($owner)"; fi
        done
    done
    n=$((n + 1))
    if [ -n "$problems" ]; then
        echo "not ok $n - $d (layer $r) includes only earlier layers:$problems"; bad=1
    else
        echo "ok $n - $d (layer $r) includes only earlier layers"
    fi
done

# The frep command is rebuilt on the public API (issue 20): every source and header
# of cli/ includes frep.h (through cli.h) and no library header of its own.
api_cmds=$(ls cli/*.c cli/*.h)
problems=""
for f in $api_cmds; do
    for inc in $(sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*"\([^"]*\)".*/\1/p' "$f"); do
        case "$inc" in config.h|cli.h|opt.h|frep.h) ;; *) problems="$problems $f:$inc" ;; esac
    done
done
n=$((n + 1))
if [ -n "$problems" ]; then
    echo "not ok $n - the commands on the public API include frep.h and cli/ only:$problems"; bad=1
else
    echo "ok $n - the commands on the public API include frep.h and cli/ only"
fi
echo "1..$n"
exit $bad
