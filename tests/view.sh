#!/bin/sh
# view.sh - script tests of frep view: the page from a model, a mesh file and with a
# cloud; --watch serving on loopback, rebuilding after a save, stopping by itself
# (--timeout) and at Ctrl-C; frep fit --view (TAP output).  The HTTP checks use curl
# and are skipped without it; tests/browser.sh loads the page in Chromium.
: "${FREP:=./frep}" "${srcdir:=.}"
T=${TMPDIR:-/tmp}/frep-view-test.$$
mkdir -p "$T" || exit 1
pid=
trap '[ -n "$pid" ] && kill "$pid" 2>/dev/null; rm -rf "$T"' EXIT
n=0
fails=0
report() { # report STATUS DESCRIPTION
  n=$((n + 1))
  if [ "$1" = 0 ]; then echo "ok $n - $2"; else echo "not ok $n - $2"; fails=$((fails + 1)); fi
}
skip() { n=$((n + 1)); echo "ok $n - $1 # SKIP $2"; }
M="$srcdir/tests/models"

"$FREP" sample "$M/block_minus_ball.hf" -b 1 -n 2000 --seed 3 -o "$T/c.xyz" >/dev/null 2>&1
"$FREP" view "$M/block_minus_ball.hf" -b 1 -g 32 --points "$T/c.xyz" -o "$T/p.html" >"$T/out" 2>"$T/err"
report $? "frep view writes a page"
grep -q "^$T/p.html: [0-9.]* MB, [0-9]* triangles, 2000 points (colour scale " "$T/out"
report $? "the summary line: size, triangles, points, scale"
head -c 15 "$T/p.html" | grep -q '<!DOCTYPE html>' && grep -q 'var FREP_SCENE = {"version":0' "$T/p.html"
report $? "the page holds the viewer and the scene"
! grep -q 'src="http\|href="http\|/\*@FREP_SCENE@\*/' "$T/p.html"
report $? "no network resource, no placeholder left"
"$FREP" mesh "$M/block_minus_ball.hf" -b 1 -g 24 -o "$T/m.off" -q &&
  "$FREP" view "$T/m.off" --points "$T/c.xyz" -o "$T/m.html" -q && grep -q '"source":null' "$T/m.html"
report $? "a mesh file as the model, with points"
"$FREP" view "$M/block_minus_ball.hf" -b 1 -g 32 --points "$T/nope.xyz" -o "$T/x.html" 2>"$T/err"
[ $? = 1 ] && [ ! -f "$T/x.html" ]
report $? "a missing cloud fails and writes nothing"

# messages of the polygonizer and the compiler in the page, not only in the terminal
printf 'my_model(x[3], a[1])\n{\n    my_model = frSphere(x, 0, 0, 0, 1.2);\n}\n' >"$T/big.hf"
"$FREP" view "$T/big.hf" -b 1 -g 16 -o "$T/big.html" -q 2>"$T/err"
grep -q '"diag":"[^"]*big.hf: note: the solid reaches the box' "$T/big.html" &&
  grep -q '"failed":false' "$T/big.html" && grep -q 'the solid reaches the box' "$T/err"
report $? "the polygonizer's note is in the page (and on standard error), the build not failed"
printf 'my_model(x[3], a[1])\n{\n    x[1] = x[1];\n    my_model = frSphere(x, 0, 0, 0, 0.5);\n}\n' >"$T/warn.hf"
"$FREP" view "$T/warn.hf" -b 1 -g 16 -o "$T/warn.html" -q 2>"$T/err"
grep -q '"diag":"[^"]*warn.hf:3:[0-9]*: warning: ' "$T/warn.html" && grep -q 'warn.hf:3:[0-9]*: warning: ' "$T/err"
report $? "the compiler's warning is in the page with its file:line:col: $(sed -n 1p "$T/err")"

# the model's colours (s[1..3]) as vertex colours; none without attributes
"$FREP" view "$M/color_sphere.hf" -b 1 -g 16 -o "$T/col.html" -q &&
  grep -q '"rgb":"[A-Za-z0-9+/=]\{8,\}"' "$T/col.html" && grep -q '"rgb":null' "$T/p.html"
report $? "a model with s[1..3] gets vertex colours in the page, one without gets none"

# frep render draws the model's colours: a red and a green sphere give red and green
# pixels (tests/view_png.py), the plain sphere none
printf 'my_model(x[3], a[1], s[3])\n{\n    f1 = frSphere(x, -0.6, 0, 0, 0.5);\n    f2 = frSphere(x, 0.6, 0, 0, 0.5);\n    c1 = hfA_SetColor(f1, s, 1, 0, 0);\n    c2 = hfA_SetColor(f2, s, 0, 1, 0);\n    my_model = f1 | f2;\n}\n' >"$T/rg.hf"
if command -v python3 >/dev/null 2>&1; then
  "$FREP" render "$T/rg.hf" -b 1.2 -g 32 --size 400x300 -o "$T/rg.png" -q &&
    python3 "$srcdir/tests/view_png.py" colours "$T/rg.png" 0 red green >"$T/out"
  report $? "frep render draws a model's colours: $(cat "$T/out")"
  "$FREP" render "$T/big.hf" -b 1.5 -g 32 --size 400x300 -o "$T/plain.png" -q
  python3 "$srcdir/tests/view_png.py" colours "$T/plain.png" 0 red >"$T/out"
  [ $? = 1 ]
  report $? "... and a model without colours has no red pixels ($(cat "$T/out"))"
else
  skip "frep render draws a model's colours" "python3 is not installed"
  skip "a model without colours has no red pixels" "python3 is not installed"
fi

# --watch
cp "$M/block_minus_ball.hf" "$T/w.hf"
"$FREP" view --watch "$T/w.hf" -b 1 -g 24 --port 0 --timeout 1 >"$T/out" 2>"$T/err"
st=$?
[ $st = 0 ] && grep -q '^frep view: serving .* on http://127.0.0.1:[0-9]*/' "$T/out" && grep -q 'stopped' "$T/err"
report $? "--watch --timeout 1 serves on 127.0.0.1 and stops by itself (exit $st)"

"$FREP" view --watch "$T/w.hf" -b 1 -g 24 --port 0 --timeout 20 >"$T/wout" 2>"$T/werr" &
pid=$!
i=0
while [ $i -lt 100 ] && ! grep -q serving "$T/wout" 2>/dev/null; do sleep 0.1; i=$((i + 1)); done
port=$(sed -n 's|.*http://127.0.0.1:\([0-9]*\)/.*|\1|p' "$T/wout")
[ -n "$port" ]
report $? "the watch server tells its port"
if command -v curl >/dev/null 2>&1 && [ -n "$port" ]; then
  v1=$(curl -s "http://127.0.0.1:$port/version")
  curl -s "http://127.0.0.1:$port/" | head -c 15 | grep -q '<!DOCTYPE html>'
  report $? "GET / is the page"
  sleep 0.05
  printf 'my_model(x[3], a[1])\n{\n    my_model = frSphere(x, 0, 0, 0, 0.5);\n}\n' >"$T/w.hf"
  i=0; v2=$v1
  while [ $i -lt 50 ] && [ "$v2" = "$v1" ]; do sleep 0.1; v2=$(curl -s "http://127.0.0.1:$port/version"); i=$((i + 1)); done
  [ "$v2" -gt "$v1" ] 2>/dev/null
  report $? "a save makes a new version ($v1 -> $v2 in about $((i * 100)) ms)"
  printf 'my_model(x[3], a[1])\n{\n    my_model = frSphere(x 0, 0, 0, 0.5);\n}\n' >"$T/w.hf"
  i=0; d=
  while [ $i -lt 50 ] && ! echo "$d" | grep -q '"diag":"'; do sleep 0.1; d=$(curl -s "http://127.0.0.1:$port/scene.json"); i=$((i + 1)); done
  echo "$d" | grep -q '"diag":"[^"]*w.hf:3:[0-9]*: error: ' && echo "$d" | grep -q '"mesh":{"nv"'
  report $? "a syntax error: its file:line:col in the scene, the last good mesh kept"
  curl -s -o /dev/null -w '%{http_code}' "http://127.0.0.1:$port/nothing" | grep -q 404
  report $? "unknown paths are 404"
else
  for d in "GET / is the page" "a save makes a new version" "a syntax error is shown" "404"; do
    skip "$d" "curl is not installed"
  done
fi
kill -INT "$pid"
wait "$pid"
st=$?
pid=
[ $st = 0 ] && grep -q 'stopped' "$T/werr"
report $? "Ctrl-C stops the server cleanly (exit $st)"

# --watch with a cloud: a save of the cloud does not mesh again, a save of the model
# does not read the cloud again (the log line of each version says what was done)
cp "$M/block_minus_ball.hf" "$T/w.hf"
cp "$T/c.xyz" "$T/wc.xyz"
"$FREP" view --watch "$T/w.hf" -b 1 -g 24 --points "$T/wc.xyz" --port 0 --timeout 20 \
  >"$T/wout" 2>"$T/werr" &
pid=$!
wait_log() { # wait_log N: until the log has version N
  i=0
  while [ $i -lt 100 ] && ! grep -q "version $1 of" "$T/werr"; do sleep 0.1; i=$((i + 1)); done
}
wait_log 1
sleep 0.05
# saved in two pieces 50 ms apart, as a slow writer does: read once, when complete
{ head -n 500 "$T/c.xyz"; sleep 0.05; sed -n '501,1000p' "$T/c.xyz"; } >"$T/wc.xyz"
wait_log 2
grep -q 'version 2 of .*: cloud read again, mesh kept' "$T/werr"
report $? "a save of the cloud measures it against the mesh as it is: $(grep 'version 2' "$T/werr")"
# The model saved once the watcher is quiet (on a loaded machine the cloud's second
# piece may come after the settle time and make a version of its own), and checked on
# the version that meshes it.
sleep 0.5
n0=$(wc -l <"$T/werr")
printf 'my_model(x[3], a[1])\n{\n    my_model = frSphere(x, 0, 0, 0, 0.5);\n}\n' >"$T/w.hf"
since_save() { tail -n +$((n0 + 1)) "$T/werr" | grep 'version [0-9]* of .*: model meshed'; }
i=0
while [ $i -lt 100 ] && ! since_save >/dev/null; do sleep 0.1; i=$((i + 1)); done
since_save | grep -q 'model meshed again, cloud kept'
report $? "a save of the model meshes it again, the cloud kept: $(since_save)"
kill -INT "$pid"
wait "$pid"
pid=

"$FREP" view --watch "$T/w.hf" --port 99999 -o "$T/x.html" 2>"$T/err"
[ $? = 2 ] && grep -q 'port' "$T/err"
report $? "a port beyond 65535 is a usage error"

# frep fit --view
E="$srcdir/examples/fit"
"$FREP" sample "$E/part_truth.hf" -n 1500 --seed 5 -o "$T/f.xyz" >/dev/null 2>&1
"$FREP" fit "$E/part.hf" "$T/f.xyz" --seed 2 --max-evals 200 -o "$T/f.hf" --view "$T/f.html" -q 2>"$T/err"
grep -q '"name":"'"$T"'/f.hf"' "$T/f.html" 2>/dev/null && grep -q '"points":{"n":1500' "$T/f.html"
report $? "frep fit --view writes the page of the fitted template with the cloud"

echo "1..$n"
[ $fails = 0 ]
