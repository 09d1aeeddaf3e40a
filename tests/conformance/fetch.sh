#!/bin/sh
# fetch.sh - fill the git-ignored tests/conformance/ext/ with the third-party HyperFun
# files that MANIFEST lists (their terms keep them out of the repository), from their
# public URLs.  Needs internet access and curl; `make check` never runs it.
#   tests/conformance/fetch.sh [--force]
# A file already present is kept unless --force.  Sources given as
# owner/repo@commit:path are fetched from raw.githubusercontent.com at that commit;
# the others (web pages the model is printed in) are listed to be copied by hand.
set -u
here=$(cd "$(dirname "$0")" && pwd)
force=0
[ "${1:-}" = "--force" ] && force=1
command -v curl >/dev/null 2>&1 || { echo "fetch.sh: curl not found" >&2; exit 1; }
got=0 kept=0 failed=0 manual=0
while IFS='|' read -r dest src terms; do
    dest=$(echo "$dest" | tr -d ' ')
    src=$(echo "$src" | sed 's/^ *//; s/ *$//')
    case "$dest" in ''|'#'*) continue ;; esac
    out="$here/ext/$dest"
    if [ -f "$out" ] && [ "$force" -eq 0 ]; then kept=$((kept + 1)); continue; fi
    case "$src" in
    *@*:*)
        repo=${src%%@*}; rest=${src#*@}; commit=${rest%%:*}; path=${rest#*:}
        url="https://raw.githubusercontent.com/$repo/$commit/$path"
        mkdir -p "$(dirname "$out")"
        if curl -fsSL --max-time 60 -o "$out.tmp" "$url"; then
            mv "$out.tmp" "$out"; got=$((got + 1))
        else
            rm -f "$out.tmp"; failed=$((failed + 1))
            echo "fetch.sh: could not fetch $url" >&2
        fi ;;
    *)
        manual=$((manual + 1))
        echo "fetch.sh: copy by hand: $dest from $src" ;;
    esac
done < "$here/MANIFEST"
echo "fetch.sh: $got fetched, $kept already present, $failed failed, $manual to copy by hand"
[ "$failed" -eq 0 ]
