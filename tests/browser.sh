#!/bin/sh
# browser.sh - frep view's page in a real browser (headless Chromium, its software
# WebGL, driven by tests/cdp.py over the DevTools protocol): loaded from disk and from
# the --watch server, screenshots checked by tests/view_png.py (the model drawn where
# the mesh projects, the legend's colour bar), a save changing the open page's picture
# within seconds, a syntax error shown with its file:line:col.  Skipped, saying why,
# without chromium or python3 (TAP output).
: "${FREP:=./frep}" "${srcdir:=.}"
CHROMIUM=$(command -v chromium || command -v chromium-browser || command -v google-chrome || true)
if [ -z "$CHROMIUM" ]; then echo "1..0 # SKIP chromium is not installed (apt-get install chromium)"; exit 0; fi
if ! command -v python3 >/dev/null 2>&1; then echo "1..0 # SKIP python3 is not installed (the screenshot checks)"; exit 0; fi
T=${TMPDIR:-/tmp}/frep-browser-test.$$
mkdir -p "$T" || exit 1
pid=
trap '[ -n "$pid" ] && kill "$pid" 2>/dev/null; rm -rf "$T"' EXIT
n=0
fails=0
report() { # report STATUS DESCRIPTION
  n=$((n + 1))
  if [ "$1" = 0 ]; then echo "ok $n - $2"; else echo "not ok $n - $2"; fails=$((fails + 1)); fi
}
# The window and the page's side panel (view/viewer.html, #side).
SIZE=1000x700 SIDE=330
READY='until:document.body.getAttribute("data-ready"):30000'
FULL='until:document.body.getAttribute("data-full-at"):30000'
cdp() { timeout 180 python3 "$srcdir/tests/cdp.py" "$CHROMIUM" $SIZE "$@" 2>>"$T/cdp.log"; }
png() { python3 "$srcdir/tests/view_png.py" "$@"; }

printf 'my_model(x[3], a[1])\n{\n    my_model = frSphere(x, 0, 0, 0, 1.1);\n}\n' >"$T/big.hf"
printf 'my_model(x[3], a[1])\n{\n    my_model = frSphere(x, 0, 0, 0, 1);\n}\n' >"$T/unit.hf"
"$FREP" sample "$T/unit.hf" -b 2 -n 3000 --seed 1 -o "$T/unit.xyz" >/dev/null 2>&1
"$FREP" view "$T/big.hf" -b 2 -g 64 --points "$T/unit.xyz" -o "$T/big.html" -q

# from disk
cdp "file://$T/big.html" "$READY" shot:"$T/disk.png" 'eval:document.getElementById("legend").textContent' \
  'eval:(document.getElementById("source").textContent + document.getElementById("params").textContent).replace(/\n/g, " ")' \
  >"$T/disk.out"
png drawn "$T/disk.png" $SIDE >"$T/out"
report $? "from disk: the model is drawn and the legend's bar is there ($(cat "$T/out"))"
sed -n 1p "$T/disk.out" | grep -q '3000 of 3000 points inside the solid, 3000 deeper than'
report $? "from disk: the legend says every point is inside the too-large sphere"
sed -n 2p "$T/disk.out" | grep -q 'frSphere(x, 0, 0, 0, 1.1).*a\[1\]'
report $? "from disk: the source and the parameters are beside the picture"
cdp "file://$T/big.html?bench=30" 'until:document.body.getAttribute("data-frame-ms"):60000' \
  'eval:document.body.getAttribute("data-frame-ms")' >"$T/bench.out"
report $? "a frame time is measured: $(cat "$T/bench.out") ms a frame (software WebGL, $(wc -c <"$T/big.html") bytes)"

# level of detail: while the mouse drags, coarse copies are drawn (small thresholds make
# this small scene have them) into a drawing buffer of half the canvas's width and
# height (?lodres=2); full detail at full resolution again once the mouse is released,
# the same picture as a full frame drawn afresh at that camera
C=665,350
cdp "file://$T/big.html?lodtris=2000&lodpoints=500&lodres=2" "$READY" "$FULL" 'eval:document.body.getAttribute("data-first")' \
  'eval:document.body.getAttribute("data-drawn")' \
  'eval:document.body.getAttribute("data-buffer")' drag:$C,5,2,4 \
  'eval:document.body.getAttribute("data-drawn")' 'eval:document.body.getAttribute("data-buffer")' \
  release:685,358 'until:document.body.getAttribute("data-drawn") == document.body.getAttribute("data-full"):5000' \
  'eval:document.body.getAttribute("data-drawn")' 'eval:document.body.getAttribute("data-buffer")' \
  wait:300 shot:"$T/settled.png" 'eval:frepDebug.full()' wait:300 shot:"$T/full.png" >"$T/lod.out" 2>&1
first=$(sed -n 1p "$T/lod.out") full=$(sed -n 2p "$T/lod.out") fbuf=$(sed -n 3p "$T/lod.out")
dragms=$(sed -n 4p "$T/lod.out") moving=$(sed -n 5p "$T/lod.out") mbuf=$(sed -n 6p "$T/lod.out")
after=$(sed -n 7p "$T/lod.out") abuf=$(sed -n 8p "$T/lod.out")
[ -n "$full" ] && [ "$full" = "$after" ] && [ "${moving%% *}" -lt "${full%% *}" ] 2>/dev/null &&
  [ "${moving##* }" -lt "${full##* }" ] 2>/dev/null && [ "${moving##* }" -le 500 ]
report $? "while dragging a coarse copy is drawn ($moving triangles and points, of $full), then all of it ($after)"
fw=${fbuf%% *} fh=${fbuf##* } mw=${mbuf%% *} mh=${mbuf##* }
[ -n "$fbuf" ] && [ "$fbuf" = "$abuf" ] && [ $((2 * mw - fw)) -ge -1 ] 2>/dev/null && [ $((2 * mw - fw)) -le 1 ] &&
  [ $((2 * mh - fh)) -ge -1 ] && [ $((2 * mh - fh)) -le 1 ]
report $? "while dragging the drawing buffer is halved ($mbuf pixels, of $fbuf), then full again ($abuf); a move drawn in ${dragms%% *} ms"
png same "$T/settled.png" "$T/full.png" >"$T/out"
report $? "the picture after the drag is the full-detail one ($(cat "$T/out"))"
[ -n "$first" ] && [ "${first%% *}" -lt "${full%% *}" ] 2>/dev/null
report $? "the first picture is the coarse copy ($first triangles and points), then the full one ($full)"
# ?lodms=1: every moving frame takes longer than 1 ms, so the reduction doubles to its
# largest, a quarter of the width and height, and then the copies of ?lodlow=1000
# triangles and ?lodlowpoints=300 points are drawn
cdp "file://$T/big.html?lodms=1&lodlow=1000&lodlowpoints=300" "$READY" 'eval:document.body.getAttribute("data-buffer")' \
  'eval:document.body.getAttribute("data-full")' drag:$C,5,2,8 'eval:document.body.getAttribute("data-buffer")' \
  'eval:document.body.getAttribute("data-drawn")' release:705,366 >"$T/adapt.out" 2>&1
fbuf=$(sed -n 1p "$T/adapt.out") full=$(sed -n 2p "$T/adapt.out") mbuf=$(sed -n 4p "$T/adapt.out")
moving=$(sed -n 5p "$T/adapt.out")
fw=${fbuf%% *} mw=${mbuf%% *}
[ -n "$mbuf" ] && [ $((4 * mw - fw)) -ge -2 ] 2>/dev/null && [ $((4 * mw - fw)) -le 2 ]
report $? "slow moving frames shrink the drawing buffer to a quarter ($mbuf pixels, of $fbuf)"
[ -n "$moving" ] && [ "${moving%% *}" -le 1500 ] 2>/dev/null && [ "${moving##* }" -eq 300 ] 2>/dev/null &&
  [ "$full" = "11676 3000" ]
report $? "... and then draw the coarser copies ($moving triangles and points, of $full)"

# the model's colours (s[1..3]): a red and a green sphere
printf 'my_model(x[3], a[1], s[3])\n{\n    f1 = frSphere(x, -0.6, 0, 0, 0.5);\n    f2 = frSphere(x, 0.6, 0, 0, 0.5);\n    c1 = hfA_SetColor(f1, s, 1, 0, 0);\n    c2 = hfA_SetColor(f2, s, 0, 1, 0);\n    my_model = f1 | f2;\n}\n' >"$T/rg.hf"
"$FREP" view "$T/rg.hf" -b 1.2 -g 48 -o "$T/rg.html" -q
cdp "file://$T/rg.html" "$READY" shot:"$T/rg.png" 'eval:document.getElementById("surface").value' >"$T/rg.out"
png colours "$T/rg.png" $SIDE red green >"$T/out" && [ "$(cat "$T/rg.out")" = 3 ]
report $? "a model's colours are drawn: $(cat "$T/out")"

# a warning of the compiler shown in the page (the build did not fail)
printf 'my_model(x[3], a[1])\n{\n    x[1] = x[1];\n    my_model = frSphere(x, 0, 0, 0, 0.5);\n}\n' >"$T/warn.hf"
"$FREP" view "$T/warn.hf" -b 1 -g 32 -o "$T/warn.html" -q 2>/dev/null
cdp "file://$T/warn.html" "$READY" shot:"$T/warn.png" 'eval:document.getElementById("diag").hidden' \
  'eval:document.getElementById("diag").textContent.replace(/\n/g, " ")' >"$T/warn.out"
[ "$(sed -n 1p "$T/warn.out")" = False ] && sed -n 2p "$T/warn.out" | grep -q "^Messages about the model:.*warn.hf:3:[0-9]*: warning: "
report $? "a compiler warning is shown in the page: $(sed -n 2p "$T/warn.out")"
[ -s "$T/warn.out" ] || tail -n 5 "$T/cdp.log" | sed 's/^/#   cdp: /'
png colours "$T/warn.png" $SIDE red >"$T/out"
[ $? = 1 ]
report $? "a model without colours has no red surface ($(cat "$T/out"))"

# from the --watch server: load, save a new model, then a syntax error
cp "$T/big.hf" "$T/w.hf"
"$FREP" view --watch "$T/w.hf" -b 2 -g 64 --points "$T/unit.xyz" --port 0 --timeout 170 -q \
  >"$T/wout" 2>"$T/werr" &
pid=$!
# Up to 60 s for the server to mesh the model and print its address: under `make check
# -j2` beside the evolve tests 10 s was once too short (an empty URL, tests 14-19 failed).
i=0
while [ $i -lt 600 ] && kill -0 "$pid" 2>/dev/null && ! grep -q serving "$T/wout" 2>/dev/null; do
  sleep 0.1
  i=$((i + 1))
done
url=$(sed -n 's|.*\(http://127.0.0.1:[0-9]*/\).*|\1|p' "$T/wout")
two='my_model = frSphere(x, 0.6, 0, 0, 0.5) | frSphere(x, -0.6, 0, 0, 0.5);'
bad='my_model = frSphere(x 0, 0, 0, 0.8);'
cdp "$url" "$READY" shot:"$T/served.png" \
  "run:printf 'my_model(x[3], a[1])\\n{\\n    $two\\n}\\n' > '$T/w.hf'" mark \
  'until:document.body.getAttribute("data-version") >= 2:10000' \
  'since:document.body.getAttribute("data-updated")' shot:"$T/edited.png" \
  'eval:document.getElementById("diag").hidden' \
  "run:printf 'my_model(x[3], a[1])\\n{\\n    $bad\\n}\\n' > '$T/w.hf'" \
  'until:!document.getElementById("diag").hidden:10000' \
  'eval:document.getElementById("diagtext").textContent' >"$T/watch.out"
st=$?
png drawn "$T/served.png" $SIDE >"$T/out"
report $? "from the server: the model is drawn ($(cat "$T/out"))"
png diff "$T/served.png" "$T/edited.png" >"$T/out"
report $? "a save changes the open page's picture ($(cat "$T/out"))"
ms=$(sed -n 1p "$T/watch.out")
[ "$ms" -lt 3000 ] 2>/dev/null
report $? "the new picture is drawn ${ms:-?} ms after the save"
[ "$(sed -n 2p "$T/watch.out")" = True ]
report $? "... and the new model compiled (no messages shown)"
[ $st = 0 ] && sed -n 3p "$T/watch.out" | grep -q "w.hf:3:[0-9]*: error: "
report $? "a syntax error is shown in the page with its file:line:col: $(sed -n 3p "$T/watch.out")"

kill -INT "$pid"
wait "$pid"
report $? "the server stops at Ctrl-C"
pid=
[ -s "$T/cdp.log" ] && sed 's/^/# /' "$T/cdp.log"
echo "1..$n"
[ $fails = 0 ]
