#!/bin/sh
# bench_view.sh - frep view's page in headless Chromium (software WebGL, no GPU; make
# bench-view): for the typical part (examples/reverse/part.hf, grid 128, 20000 points)
# and for a million triangles with a million points (the part at grid 512, 10^6
# points), the page's size, the time from opening it to the first picture, and the
# median frame time of an orbit in full detail, and the median time from a mouse move
# to its picture over a scripted drag of 20 moves (coarse copies and a reduced drawing
# buffer, view/viewer.html).  The load average is printed beside each figure.
# Window 1200x800.  Needs chromium and python3.
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

load() { cut -d' ' -f1 /proc/loadavg 2>/dev/null; }
# measure NAME PAGE: size, time to the first picture, frame times full and while dragging
measure() {
  size=$(wc -c <"$2")
  l1=$(load)
  ready=$(cdp "file://$2" "$READY" 'since:document.body.getAttribute("data-ready-at")' \
    'eval:document.body.getAttribute("data-load-ms")' 'eval:document.body.getAttribute("data-full")' \
    'until:document.body.getAttribute("data-full-at"):600000' 'since:document.body.getAttribute("data-full-at")' \
    'eval:document.body.getAttribute("data-start-ms")' 'eval:document.body.getAttribute("data-first")')
  l2=$(load)
  full=$(cdp "file://$2?bench=5" "$FRAMES" 'eval:document.body.getAttribute("data-frame-ms")')
  l3=$(load)
  # a scripted drag of 20 moves, each waiting for its picture: at a fixed half
  # resolution (?lodres=2), at full resolution (?lodres=1), and adapting (the default)
  drag() {
    cdp "file://$2$1" "$READY" drag:700,400,4,1,20 'eval:document.body.getAttribute("data-drawn")' \
      'eval:document.body.getAttribute("data-buffer")' | tr '\n' ' ' | awk '{ printf "%s ms (max %s; %s triangles, %s points, %sx%s pixels)", $1, $2, $4, $5, $6, $7 }'
  }
  d2=$(drag "?lodres=2" "$2"); l4=$(load)
  d1=$(drag "?lodres=1" "$2"); l5=$(load)
  da=$(drag "" "$2"); l6=$(load)
  set -- "$1" $ready
  printf '%s: %d triangles, %d points; page %.2f MB\n' "$1" "$4" "$5" "$(echo "$size" | awk '{ print $1 / 1e6 }')"
  printf '  first picture %d ms after opening (%s triangles, %s points; script started at %s ms, decode and upload %s ms), full detail at %s ms [load %s]\n' \
    "$2" "$8" "$9" "$7" "$3" "$6" "$l2"
  printf '  frame in full detail %s ms (median of 5 orbit frames) [load %s]\n' "$full" "$l3"
  printf '  frame while dragging, median of 20 moves: buffer fixed at 1/2 (?lodres=2) %s [load %s]\n' "$d2" "$l4"
  printf '    buffer fixed at 1/1 (?lodres=1) %s [load %s]\n' "$d1" "$l5"
  printf '    adaptive (default) %s [load %s]\n' "$da" "$l6"
}

P="$SRCDIR/examples/reverse/part.hf"
"$FREP" sample "$P" -n 20000 --seed 1 -o "$T/part.xyz" >/dev/null 2>&1 || exit 1
"$FREP" view "$P" -g 128 --points "$T/part.xyz" -o "$T/part.html" -q || exit 1
measure "typical part (grid 128)" "$T/part.html"

"$FREP" sample "$P" -n 1000000 --seed 1 -o "$T/big.xyz" >/dev/null 2>&1 || exit 1
"$FREP" view "$P" -g "$BIGGRID" --points "$T/big.xyz" -o "$T/big.html" -q || exit 1
measure "part at grid $BIGGRID, 10^6 points" "$T/big.html"
