#!/bin/sh
# evolve.sh - end-to-end tests of `frep evolve`: a cube and a block with a hole sampled
# from models by `frep sample`, primitives given as a .fit list or found by
# segmentation, the written model checked and evaluated by frep itself, the same seed
# at 1 and 2 threads, --dot, --no-support, bad input; --residual (a block model joined with the hole
# its cloud shows) and --refit (perturbed faces corrected). Prints TAP. Needs FREP.

: "${FREP:?FREP must name the frep binary}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-evolve.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM

. "$(dirname "$0")/tap.sh"
show() { sed 's/^/# /' "$1"; }

# The unit cube [-1,1]^3 as six half-spaces (inside >= 0).
cat >"$tmp/cube.hf" <<'EOF'
-- @setops minmax
-- @box -1.5 -1.5 -1.5 1.5 1.5 1.5
my_model(x[3], a[1])
{
    my_model = frPlane(x, 1, 0, 0, 1) & frPlane(x, -1, 0, 0, 1) &
               frPlane(x, 0, 1, 0, 1) & frPlane(x, 0, -1, 0, 1) &
               frPlane(x, 0, 0, 1, 1) & frPlane(x, 0, 0, -1, 1);
}
EOF
# The same planes, and two distractors, as a .fit list (f = d - n.x).
cat >"$tmp/cube.fit" <<'EOF'
plane 1 0 0 1
plane -1 0 0 1
plane 0 1 0 1
plane 0 -1 0 1
sphere 3 3 3 0.5
plane 0 0 1 1
plane 0 0 -1 1
plane 0.6 0.8 0 4
EOF

"$FREP" sample "$tmp/cube.hf" -n 3000 --seed 1 -o "$tmp/cube.xyz" -q 2>"$tmp/err"
report $? "sample the cube"

"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" -o "$tmp/m1.hf" --seed 5 -t 1 \
    --dot "$tmp/m1.dot" 2>"$tmp/err"
st=$?
report $st "evolve the cube from a .fit list"
[ $st = 0 ] || show "$tmp/err"
grep -q "tree size 11 nodes, 6 primitives" "$tmp/m1.hf"
st=$?
report $st "minimal tree: 11 nodes over the 6 faces"
[ $st = 0 ] || show "$tmp/m1.hf"
grep -q "100.00% both" "$tmp/m1.hf"
report $? "every point explained"
grep -q "seed 5" "$tmp/err"
report $? "seed printed"
grep -q '^-- @box ' "$tmp/m1.hf" && grep -q '^-- @setops minmax' "$tmp/m1.hf"
report $? "model has @box and @setops pragmas"
# The six faces of the .fit list are exact, so they are written as the one box.
! grep -q " = frSphere\|frPlane(x, 0\.6, 0\.8" "$tmp/m1.hf" && ! grep -q ' = frPlane' "$tmp/m1.hf" &&
    grep -q '^    box_1 = frBox(x, 0, 0, 0, 1, 1, 1, 0, 0, 0);' "$tmp/m1.hf" && grep -q '^    tree = box_1;$' "$tmp/m1.hf"
report $? "distractor primitives left out, the six faces written as one box"
"$FREP" check "$tmp/m1.hf" >/dev/null 2>"$tmp/err"
st=$?
report $st "written model compiles"
[ $st = 0 ] || show "$tmp/err"

# The model is the cube: inside at the centre, outside beyond each face, zero on faces.
printf '0 0 0\n0.9 0.5 -0.5\n1.2 0 0\n0 -1.2 0\n0 0 1.3\n1 0.3 0.2\n' >"$tmp/pts"
"$FREP" eval "$tmp/m1.hf" "$tmp/pts" >"$tmp/vals" 2>"$tmp/err"
awk 'NR==1 && $1 > 0.5 {a++} NR==2 && $1 > 0.05 {a++} NR>=3 && NR<=5 && $1 < -0.1 {a++}
     NR==6 && ($1 < 1e-9 && $1 > -1e-9) {a++} END {exit a == 6 ? 0 : 1}' "$tmp/vals"
st=$?
report $st "model evaluates as the cube"
[ $st = 0 ] || show "$tmp/vals"

grep -q "digraph" "$tmp/m1.dot" && [ "$(grep -c 'shape=box' "$tmp/m1.dot")" = 6 ]
report $? "--dot writes the tree with 6 leaves"

# Support trims (support.h) leave a solid whose surface the cloud covers as it is.
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" -o "$tmp/m1n.hf" --seed 5 -t 1 -q \
    --no-support 2>"$tmp/err"
grep '^    tree = ' "$tmp/m1n.hf" >"$tmp/t1n"
grep '^    tree = ' "$tmp/m1.hf" >"$tmp/t1"
cmp -s "$tmp/t1" "$tmp/t1n" && ! grep -q "no point supports" "$tmp/m1.hf"
report $? "no support trim on the cube: the same tree as with --no-support"

# A bar no face of the list stops: a cylinder along x sticks out of a box, its points
# end at x = 2 without a cap (an open scan), and a second box far off puts the
# clipping box's face at x = 3.5 + margin. Only the cylinder's separating plane
# x <= 2.02 (a face of its inliers' box) cuts it where its points end; without the
# trims it runs on to the clip through (2.8, 0, 0).
cat >"$tmp/bar.hf" <<'EOF2'
-- @setops minmax
-- @box -1.5 -3.5 -1.5 4 1.5 1.5
my_model(x[3], a[1])
{
    boxa = frPlane(x, 1, 0, 0, 1) & frPlane(x, -1, 0, 0, 1) & frPlane(x, 0, 1, 0, 1) &
           frPlane(x, 0, -1, 0, 1) & frPlane(x, 0, 0, 1, 1) & frPlane(x, 0, 0, -1, 1);
    boxb = frPlane(x, 1, 0, 0, 3.5) & frPlane(x, -1, 0, 0, -1.5) & frPlane(x, 0, 1, 0, -2) &
           frPlane(x, 0, -1, 0, 3) & frPlane(x, 0, 0, 1, 1) & frPlane(x, 0, 0, -1, 1);
    bar = frCylinder(x, 0, 0, 0, 1, 0, 0, 0.3) & frPlane(x, 1, 0, 0, 2);
    my_model = boxa | boxb | bar;
}
EOF2
cat >"$tmp/bar_prims.hf" <<'EOF2'
primitives(x[3], a[1])
{
  p1 = frPlane(x, 1, 0, 0, 1);  -- plane: 100 points
  p2 = frPlane(x, -1, 0, 0, 1);  -- plane: 100 points
  p3 = frPlane(x, 0, 1, 0, 1);  -- plane: 100 points
  p4 = frPlane(x, 0, -1, 0, 1);  -- plane: 100 points
  p5 = frPlane(x, 0, 0, 1, 1);  -- plane: 100 points
  p6 = frPlane(x, 0, 0, -1, 1);  -- plane: 100 points
  p7 = frPlane(x, 1, 0, 0, 3.5);  -- plane: 100 points
  p8 = frPlane(x, -1, 0, 0, -1.5);  -- plane: 100 points
  p9 = frPlane(x, 0, 1, 0, -2);  -- plane: 100 points
  p10 = frPlane(x, 0, -1, 0, 3);  -- plane: 100 points
  p11 = frCylinder(x, 0, 0, 0, 1, 0, 0, 0.3);  -- cylinder: 100 points
  p12 = frPlane(x, 1, 0, 0, 2.02);  -- separating plane
  p13 = frPlane(x, -1, 0, 0, -0.98);  -- separating plane
  primitives = p1 | p2;
}
EOF2
"$FREP" sample "$tmp/bar.hf" -n 6000 --seed 1 -o "$tmp/bar_raw.xyz" -q &&
    awk '!($1 > 1.999 && $2 * $2 + $3 * $3 < 0.09 + 1e-6)' "$tmp/bar_raw.xyz" >"$tmp/bar.xyz"
report $? "sample the box with a bar, its end cap left out"
"$FREP" evolve "$tmp/bar.xyz" -p "$tmp/bar_prims.hf" -o "$tmp/bar1.hf" --seed 1 -t 1 -q \
    2>"$tmp/err" &&
    "$FREP" evolve "$tmp/bar.xyz" -p "$tmp/bar_prims.hf" -o "$tmp/bar0.hf" --seed 1 -t 1 -q \
        --no-support 2>>"$tmp/err"
report $? "evolve the bar with and without the support trims"
v1=$(echo "2.8 0 0" | "$FREP" eval "$tmp/bar1.hf")
v0=$(echo "2.8 0 0" | "$FREP" eval "$tmp/bar0.hf")
awk -v a="$v1" -v b="$v0" 'BEGIN { exit !(a < 0 && b > 0) }' &&
    grep -q "unsupported grid edges [0-9]* -> 0;" "$tmp/bar1.hf"
st=$?
report $st "the bar cut where its points end by its separating plane (f(2.8, 0, 0) $v1, $v0 untrimmed)"
[ $st = 0 ] || { grep -n "trim\|tree =" "$tmp/bar1.hf" "$tmp/bar0.hf" | sed 's/^/# /'; show "$tmp/err"; }

"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" -o "$tmp/m2.hf" --seed 5 -t 2 -q 2>"$tmp/err"
grep '^    tree = ' "$tmp/m1.hf" >"$tmp/t1"
grep '^    tree = ' "$tmp/m2.hf" >"$tmp/t2"
cmp -s "$tmp/t1" "$tmp/t2"
report $? "same seed, same tree at 1 and 2 threads (partitioned)"
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" -o "$tmp/m3.hf" --seed 6 -t 1 -q --no-partition
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" -o "$tmp/m4.hf" --seed 6 -t 2 -q --no-partition
grep '^    tree = ' "$tmp/m3.hf" >"$tmp/t3"
grep '^    tree = ' "$tmp/m4.hf" >"$tmp/t4"
cmp -s "$tmp/t3" "$tmp/t4" && grep -q "tree size 11 nodes" "$tmp/m3.hf"
report $? "unpartitioned GA: 11 nodes, same tree at 1 and 2 threads"

"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" -o "$tmp/m5.hf" --seed 2 -q --setops rfunc
grep -q "tree size 11 nodes" "$tmp/m5.hf" && grep -q '^-- @setops rfunc' "$tmp/m5.hf" &&
    "$FREP" check "$tmp/m5.hf" >/dev/null 2>&1
report $? "R-functions: 11 nodes, model compiles"

# A plate with two holes from a .fit list: the proxy of a subtracted primitive is the
# box of the points it explains as a complement (normals along +grad f), so each hole
# overlaps the top and bottom faces only and no clique holds both holes (before, such
# primitives had no proxy and overlapped everything: largest clique 5).
cat >"$tmp/plate.hf" <<'EOF'
-- @setops minmax
-- @box -2.5 -1.5 -0.5 2.5 1.5 1
my_model(x[3], a[1])
{
    my_model = frPlane(x, 1, 0, 0, 2) & frPlane(x, -1, 0, 0, 2) &
               frPlane(x, 0, 1, 0, 1) & frPlane(x, 0, -1, 0, 1) &
               frPlane(x, 0, 0, 1, 0.5) & frPlane(x, 0, 0, -1, 0) \
               frCylinder(x, -1.2, 0, 0, 0, 0, 1, 0.25) \ frCylinder(x, 1.2, 0, 0, 0, 0, 1, 0.25);
}
EOF
printf 'plane 1 0 0 2\nplane -1 0 0 2\nplane 0 1 0 1\nplane 0 -1 0 1\nplane 0 0 1 0.5\nplane 0 0 -1 0\ncylinder 0 0 1 -1.2 0 0 0.25\ncylinder 0 0 1 1.2 0 0 0.25\n' >"$tmp/plate.fit"
"$FREP" sample "$tmp/plate.hf" -n 4000 --seed 1 -o "$tmp/plate.xyz" -q &&
    "$FREP" evolve "$tmp/plate.xyz" -p "$tmp/plate.fit" -o "$tmp/plate_out.hf" --seed 1 -q 2>"$tmp/err"
st=$?
[ $st = 0 ] && grep -q "partitioned (12 cliques, largest 3;" "$tmp/plate_out.hf" &&
    grep -q "tree size 15 nodes, 8 primitives" "$tmp/plate_out.hf" &&
    grep -q "100.00% both" "$tmp/plate_out.hf"
st=$?
report $st "plate with two holes: holes' proxies local (12 cliques of 3), the 15-node tree"
[ $st = 0 ] || { show "$tmp/err"; show "$tmp/plate_out.hf"; }

# Without -p: segmentation first.
"$FREP" evolve "$tmp/cube.xyz" -o "$tmp/m6.hf" --seed 3 -q 2>"$tmp/err"
st=$?
[ $st = 0 ] && grep -q "100.00% both\|99\.[5-9][0-9]% both" "$tmp/m6.hf"
st=$?
report $st "segment then evolve explains the cube"
[ $st = 0 ] || { show "$tmp/err"; show "$tmp/m6.hf"; }

# Automatic alpha: 10 degrees on the clean cube, 35 on a noisy one (positions with
# Gaussian noise of 0.2% of the diagonal, a fifth of eps_d); --alpha overrides.
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" -o "$tmp/a1.hf" --seed 1 2>"$tmp/err"
grep -q 'frep evolve: alpha 10 degrees (automatic: clean' "$tmp/err" &&
    grep -q 'normals within 10 degrees' "$tmp/a1.hf"
report $? "automatic alpha: 10 degrees for a clean cloud"
"$FREP" sample "$tmp/cube.hf" -n 3000 --seed 2 --noise 0.002 -o "$tmp/noisy.xyz" -q
"$FREP" evolve "$tmp/noisy.xyz" -p "$tmp/cube.fit" -o "$tmp/a2.hf" --seed 1 2>"$tmp/err"
st=$?
[ $st = 0 ] && grep -q 'frep evolve: alpha 35 degrees (automatic: noisy' "$tmp/err" &&
    grep -q 'normals within 35 degrees' "$tmp/a2.hf" && grep -q 'tree size 11 nodes' "$tmp/a2.hf"
st=$?
report $st "automatic alpha: 35 degrees for a noisy cloud, still the 11-node cube"
[ $st = 0 ] || { show "$tmp/err"; show "$tmp/a2.hf"; }
"$FREP" evolve "$tmp/noisy.xyz" -p "$tmp/cube.fit" -o "$tmp/a3.hf" --seed 1 --alpha 20 2>"$tmp/err"
! grep -q 'automatic' "$tmp/err" && grep -q 'normals within 20 degrees' "$tmp/a3.hf"
report $? "--alpha overrides the automatic choice"

# --trace: a line per generation; the GA keeps its best (elitism), so the best fitness
# never falls within a phase; the last line gives the figures of the model.
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" -o "$tmp/tr.hf" --seed 1 --no-partition \
    --trace "$tmp/trace" -q 2>"$tmp/err"
st=$?
awk -v want="$(sed -n 's/.* \([0-9]*\) generations, .*/\1/p' "$tmp/tr.hf")" '
    /^#/ { if ($2 == "end:") end = $9; next }
    { n++; if ($1 != n || $6 < 0 || $6 > 100 || (n > 1 && $4 < f) || $7 != "ga") bad++; f = $4 }
    END { exit !bad && n == want && n > 0 && end == 11 && f > 0 ? 0 : 1 }' "$tmp/trace"
st=$?
report $st "--trace: one line per generation, best fitness never falls, end line"
[ $st = 0 ] || { show "$tmp/trace"; show "$tmp/err"; }
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" -o "$tmp/tr2.hf" --seed 1 --partition \
    --trace "$tmp/trace2" -q 2>"$tmp/err"
tail -n 2 "$tmp/trace2" | head -n 1 | awk '$6 == 100 && $7 == "polish" { ok = 1 } END { exit !ok }'
report $? "--trace of a partitioned run: the polish phase explains every scored point"
# Phases in order: merge lines, one merged and one grown line (with shares), then the
# polish, which stops after EVOLVE_POLISH_STAGNATION = 15 generations without
# improvement (the cube's merged tree is already perfect: 16 generations).
awk '!/^#/ { ph[++n] = $7; sh[n] = $6 }
     END { i = 1; while (ph[i] == "merge") i++
           if (i == 1 || ph[i] != "merged" || ph[i + 1] != "grown" || sh[i] != 100) exit 1
           for (j = i + 2; j <= n; j++) if (ph[j] != "polish") exit 1
           exit n - i - 1 == 16 ? 0 : 1 }' "$tmp/trace2" &&
    grep -q "16 generations polishing" "$tmp/tr2.hf"
st=$?
report $st "--trace phases: merge, merged, grown, 16 polish generations"
[ $st = 0 ] || show "$tmp/trace2"
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" -o "$tmp/tr4.hf" --seed 1 --partition \
    --polish-stagnation 5 -q 2>"$tmp/err" && grep -q "6 generations polishing" "$tmp/tr4.hf"
report $? "--polish-stagnation 5: 6 polish generations"
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" --polish-stagnation 0 -q 2>"$tmp/err" >/dev/null
[ $? = 2 ] && grep -q "polish-stagnation" "$tmp/err"
report $? "--polish-stagnation 0 refused"

"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" -o "$tmp/tr3.hf" --seed 1 --no-partition \
    --stop-share 50 --trace "$tmp/trace3" -q 2>"$tmp/err"
awk '!/^#/ { n++; s = $6; if (s >= 50) hit++ } END { exit hit == 1 && s >= 50 && n > 0 ? 0 : 1 }' \
    "$tmp/trace3" && [ "$(grep -vc '^#' "$tmp/trace3")" -lt "$(grep -vc '^#' "$tmp/trace")" ]
report $? "--stop-share: the GA ends at the first generation explaining 50% of the points"

# Bad input: clear messages, non-zero exit, no crash.
: >"$tmp/empty.fit"
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/empty.fit" -o "$tmp/x.hf" -q 2>"$tmp/err"
st=$?
[ $st = 1 ] && grep -q "no primitives" "$tmp/err" && [ ! -e "$tmp/x.hf" ]
report $? "no primitives: error, no output"
printf 'plane 1 0 0\n' >"$tmp/bad.fit"
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/bad.fit" -q 2>"$tmp/err" >/dev/null
[ $? = 1 ] && grep -q "bad.fit:1" "$tmp/err"
report $? "malformed .fit: file:line message"
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/cube.fit" --population 1 --seed 1 -q -o "$tmp/p1.hf" 2>"$tmp/err"
[ $? = 0 ] && "$FREP" check "$tmp/p1.hf" >/dev/null 2>&1
report $? "population of 1 gives a model"
printf 'plane 0 0 1 50\n' >"$tmp/far.fit"
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/far.fit" --seed 1 -q -o "$tmp/far.hf" 2>"$tmp/err"
[ $? = 0 ] && grep -q "0.00% both" "$tmp/far.hf"
report $? "a primitive that explains nothing: a model saying so"
"$FREP" evolve "$tmp/cube.xyz" --population -3 2>"$tmp/err"
[ $? = 2 ] && grep -q "population" "$tmp/err"
report $? "bad option value: usage error"
"$FREP" evolve "$tmp/nonexistent.xyz" -p "$tmp/cube.fit" 2>"$tmp/err"
[ $? = 1 ] && grep -q "nonexistent.xyz" "$tmp/err"
report $? "missing cloud: message"

# --residual: a block model, a cloud of the block with a hole; the tree evolved for the
# hole's wall is joined by subtraction. With the cylinder given (-p) and segmented.
cat >"$tmp/block.hf" <<'EOF'
-- @setops minmax
-- @box -1.5 -1.5 -1 1.5 1.5 1
my_model(x[3], a[1])
{
    my_model = frPlane(x, 1, 0, 0, 1) & frPlane(x, -1, 0, 0, 1) & frPlane(x, 0, 1, 0, 1) &
               frPlane(x, 0, -1, 0, 1) & frPlane(x, 0, 0, 1, 0.5) & frPlane(x, 0, 0, -1, 0.5);
}
EOF
cat >"$tmp/hole.hf" <<'EOF'
-- @setops minmax
-- @box -1.5 -1.5 -1 1.5 1.5 1
my_model(x[3], a[1])
{
    blk = frPlane(x, 1, 0, 0, 1) & frPlane(x, -1, 0, 0, 1) & frPlane(x, 0, 1, 0, 1) &
          frPlane(x, 0, -1, 0, 1) & frPlane(x, 0, 0, 1, 0.5) & frPlane(x, 0, 0, -1, 0.5);
    my_model = blk \ frCylinder(x, 0.2, 0.1, 0, 0, 0, 1, 0.4);
}
EOF
"$FREP" sample "$tmp/hole.hf" -n 4000 --seed 1 -o "$tmp/hole.xyz" -q
# .fit cylinders are: axis, point on the axis, radius.
printf 'sphere 3 3 3 1\ncylinder 0 0 1 0.2 0.1 0 0.4\n' >"$tmp/hole.fit"
"$FREP" evolve "$tmp/hole.xyz" --residual "$tmp/block.hf" -p "$tmp/hole.fit" -o "$tmp/r1.hf" \
    --seed 1 2>"$tmp/err"
st=$?
[ $st = 0 ] && grep -q '^    tree = base_part \\ cyl_bore_1;$' "$tmp/r1.hf" && grep -q '100.00% both' "$tmp/r1.hf" &&
    grep -q 'base_part = base_model(x, a);' "$tmp/r1.hf" && grep -q 'explains 3[0-9]* of 4000 points' "$tmp/err"
st=$?
report $st "--residual -p: the block joined with minus the cylinder, every point explained"
[ $st = 0 ] || { show "$tmp/err"; show "$tmp/r1.hf"; }
# Values: 0.4 (the faces), 0.2 (faces), -0.4 (on the hole's axis).
printf -- '-0.6 -0.6 0\n0.8 0.8 0\n0.2 0.1 0.3\n' >"$tmp/rpts"
"$FREP" eval "$tmp/r1.hf" "$tmp/rpts" >"$tmp/rvals" 2>"$tmp/err"
awk 'NR==1 && $1 > 0.39 && $1 < 0.41 {a++} NR==2 && $1 > 0.19 && $1 < 0.21 {a++} NR==3 && $1 < -0.39 {a++}
     END {exit a == 3 ? 0 : 1}' "$tmp/rvals"
st=$?
report $st "--residual model is my_model (the default) and evaluates as the block with a hole"
[ $st = 0 ] || { show "$tmp/rvals"; show "$tmp/err"; }
"$FREP" evolve "$tmp/hole.xyz" --residual "$tmp/block.hf" -o "$tmp/r2.hf" --seed 1 -q 2>"$tmp/err" &&
    grep -q '100.00% both' "$tmp/r2.hf" && grep -q 'frCylinder' "$tmp/r2.hf" &&
    "$FREP" check "$tmp/r2.hf" >/dev/null 2>&1
st=$?
report $st "--residual without -p: the residual points are segmented, the hole recovered"
[ $st = 0 ] || { show "$tmp/err"; show "$tmp/r2.hf"; }
# Residual of a residual: the base's my_model is renamed again, the file still compiles.
"$FREP" evolve "$tmp/hole.xyz" --residual "$tmp/r1.hf" -o "$tmp/r3.hf" --seed 1 -q 2>"$tmp/err" &&
    grep -q '^base_model2(x\[3\], a\[1\])' "$tmp/r3.hf" && grep -q '100.00% both' "$tmp/r3.hf" &&
    "$FREP" check "$tmp/r3.hf" >/dev/null 2>&1
report $? "--residual of an evolved model: nested, compiles, explains every point"
grep -v '@setops' "$tmp/block.hf" >"$tmp/block_rf.hf"
"$FREP" evolve "$tmp/hole.xyz" --residual "$tmp/block_rf.hf" --setops minmax -q -o "$tmp/x2.hf" 2>"$tmp/err"
[ $? = 1 ] && grep -q 'disagrees' "$tmp/err" && [ ! -e "$tmp/x2.hf" ]
report $? "--residual with other set operations than the model's: error"
printf 'my_model(x[3], a[1]) {\n  my_model = 1 +;\n}\n' >"$tmp/broken.hf"
"$FREP" evolve "$tmp/hole.xyz" --residual "$tmp/broken.hf" -q -o "$tmp/x3.hf" 2>"$tmp/err"
[ $? = 1 ] && grep -q 'broken.hf:2:' "$tmp/err" && [ ! -e "$tmp/x3.hf" ]
report $? "--residual with a broken model: its diagnostic, no output"

# --refit: two faces perturbed (one tilted by 0.02 and shifted by 0.02, one shifted by
# 0.015) are moved back onto the points.
printf 'plane 1 0.02 0 0.98\nplane -1 0 0 1\nplane 0 1 0 1\nplane 0 -1 0 1.015\nplane 0 0 1 1\nplane 0 0 -1 1\n' \
    >"$tmp/pert.fit"
"$FREP" evolve "$tmp/cube.xyz" -p "$tmp/pert.fit" --refit -o "$tmp/rf.hf" --seed 1 2>"$tmp/err"
st=$?
[ $st = 0 ] && grep -q '^-- refit: 24 parameters, RMS distance' "$tmp/rf.hf" &&
    grep -q 'frep evolve: refit:' "$tmp/err"
report $? "--refit reports the RMS distance before and after"
# On the faces x = 1 and y = -1 the value is 0; at (0.2, 0.9, 0) it is 0.1.
printf '1 0.3 0.2\n-0.5 -1 0.7\n0.2 0.9 0\n' >"$tmp/fpts"
"$FREP" eval "$tmp/rf.hf" "$tmp/fpts" >"$tmp/fvals" 2>"$tmp/err"
awk 'NR<=2 && ($1 > 1e-6 || $1 < -1e-6) {bad++} NR==3 && ($1 < 0.0999 || $1 > 0.1001) {bad++}
     END {exit NR == 3 && !bad ? 0 : 1}' "$tmp/fvals"
st=$?
report $st "--refit moves the perturbed faces back onto the points"
[ $st = 0 ] || { show "$tmp/fvals"; grep 'refit\|p[14] =' "$tmp/rf.hf" | sed 's/^/# /'; }
sed -n 's/^-- refit: .*RMS distance \([0-9.e+-]*\) -> \([0-9.e+-]*\),.*/\1 \2/p' "$tmp/rf.hf" >"$tmp/rms"
awk 'NF == 2 && $1 > 0.005 && $2 < $1 / 100 {ok = 1} END {exit ok ? 0 : 1}' "$tmp/rms"
report $? "--refit: the RMS distance falls a hundredfold or more"
# A cloud of more points than refit fits at once: it fits a seeded subset of them.
"$FREP" sample "$tmp/cube.hf" -n 5000 --seed 2 -o "$tmp/cube5k.xyz" -q 2>"$tmp/err" &&
    "$FREP" evolve "$tmp/cube5k.xyz" -p "$tmp/pert.fit" --refit -o "$tmp/rf5k.hf" --seed 1 -q \
        2>"$tmp/err" &&
    sed -n 's/^-- refit: .*RMS distance \([0-9.e+-]*\) -> \([0-9.e+-]*\),.*/\1 \2/p' \
        "$tmp/rf5k.hf" >"$tmp/rms" &&
    awk 'NF == 2 && $1 > 0.005 && $2 < $1 / 100 {ok = 1} END {exit ok ? 0 : 1}' "$tmp/rms"
report $? "--refit of a large cloud (a subset fitted): the RMS distance falls"

tap_done
