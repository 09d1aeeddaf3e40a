#!/bin/sh
# bench_view.sh - frep view's page in headless Chromium (software WebGL, no GPU; make
# bench-view): for the typical part (examples/reverse/part.hf, grid 128, 20000 points)
# and for a million triangles with a million points (the part at grid 512, 10^6
# points), the page's size, the time from opening it to the first picture, and the
# mean frame time of an orbit in full detail and as while the mouse drags (the coarse
# copies of view/viewer.html).  Window 1200x800.  Needs chromium and python3.
# Usage: bench_view.sh FREP [SRCDIR] [BIGGRID]
FREP=${1:-./frep}
SRCDIR=${2:-.}
BIGGRID=${3:-512}
CHROMIUM=$(command -v chromium || command -v chromium-browser || command -v google-chrome || true)
if [ -z "$CHROMIUM" ]; then echo "bench-view: chromium is not installed (apt-get install chromium)"; exit 0; fi
T=${TMPDIR:-/tmp}/frep-bench-view.$$
mkdir -p "$T" || exit 1
trap 'rm -rf "$T"' EXIT
echo "# $(nproc 2>/dev/null || echo '?') cores, load average: $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null)"
cdp() { timeout 900 python3 "$SRCDIR/tests/cdp.py" "$CHROMIUM" 1200x800 "$@"; }
READY='until:document.body.getAttribute("data-ready"):600000'
FRAMES='until:document.body.getAttribute("data-frame-ms"):900000'

# measure NAME PAGE: size, time to the first picture, frame times full and coarse
measure() {
  size=$(wc -c <"$2")
  ready=$(cdp "file://$2" "$READY" 'since:document.body.getAttribute("data-ready-at")' \
    'eval:document.body.getAttribute("data-load-ms")' 'eval:document.body.getAttribute("data-full")')
  full=$(cdp "file://$2?bench=5" "$FRAMES" 'eval:document.body.getAttribute("data-frame-ms")')
  lod=$(cdp "file://$2?bench=20&lod=1" "$FRAMES" 'eval:document.body.getAttribute("data-frame-ms")')
  set -- "$1" $ready
  printf '%s: %d triangles, %d points; page %.2f MB; first picture %d ms after opening (decode and upload %s ms); frame %s ms in full detail, %s ms while dragging\n' \
    "$1" "$4" "$5" "$(echo "$size" | awk '{ print $1 / 1e6 }')" "$2" "$3" "$full" "$lod"
}

P="$SRCDIR/examples/reverse/part.hf"
"$FREP" sample "$P" -n 20000 --seed 1 -o "$T/part.xyz" >/dev/null 2>&1 || exit 1
"$FREP" view "$P" -g 128 --points "$T/part.xyz" -o "$T/part.html" -q || exit 1
measure "typical part (grid 128)" "$T/part.html"

"$FREP" sample "$P" -n 1000000 --seed 1 -o "$T/big.xyz" >/dev/null 2>&1 || exit 1
"$FREP" view "$P" -g "$BIGGRID" --points "$T/big.xyz" -o "$T/big.html" -q || exit 1
measure "part at grid $BIGGRID, 10^6 points" "$T/big.html"
