#!/bin/sh
# mesh.sh - script tests of frep mesh, frep sample and frep render: formats, the
# --check invariants on the examples and test models, and bad input (TAP output).
: "${FREP:=./frep}" "${srcdir:=.}"
T=${TMPDIR:-/tmp}/frep-mesh-test.$$
mkdir -p "$T" || exit 1
trap 'rm -rf "$T"' EXIT
n=0
fails=0
t() { # t DESCRIPTION COMMAND...: ok when the command succeeds
  desc=$1; shift
  n=$((n + 1))
  if "$@" >"$T/out" 2>"$T/err"; then echo "ok $n - $desc"
  else echo "not ok $n - $desc"; sed 's/^/# /' "$T/err" "$T/out"; fails=$((fails + 1)); fi
}
f() { # f DESCRIPTION PATTERN COMMAND...: ok when the command fails saying PATTERN
  desc=$1; pat=$2; shift 2
  n=$((n + 1))
  if "$@" >"$T/out" 2>"$T/err"; then echo "not ok $n - $desc (succeeded)"; fails=$((fails + 1))
  elif grep -q -- "$pat" "$T/err"; then echo "ok $n - $desc"
  else echo "not ok $n - $desc"; sed 's/^/# /' "$T/err"; fails=$((fails + 1)); fi
}
w() { # w DESCRIPTION PATTERN COMMAND...: ok when the command succeeds saying PATTERN
  desc=$1; pat=$2; shift 2
  n=$((n + 1))
  if ! "$@" >"$T/out" 2>"$T/err"; then echo "not ok $n - $desc (failed)"; sed 's/^/# /' "$T/err"; fails=$((fails + 1))
  elif grep -q -- "$pat" "$T/err"; then echo "ok $n - $desc"
  else echo "not ok $n - $desc"; sed 's/^/# /' "$T/err"; fails=$((fails + 1)); fi
}
M="$srcdir/tests/models"
E="$srcdir/examples"
# every example: checks clean, meshes closed, manifold and oriented in its own box
for hf in "$E"/*.hf; do
  t "check $(basename "$hf")" "$FREP" check "$hf"
  t "mesh $(basename "$hf") is closed, manifold and oriented" \
    "$FREP" mesh "$hf" -g 41 -o "$T/m.stl" --check -q
  cp "$T/err" "$T/mesh.err"
  t "... and has no warnings" test ! -s "$T/mesh.err"
done
for hf in "$M"/*.hf; do
  for g in 13 40; do
    t "mesh $(basename "$hf") -g $g is closed, manifold and oriented" \
      "$FREP" mesh "$hf" -b 1.2 -g $g -o "$T/m.stl" --check -q
  done
done
# No self-intersecting triangle pairs (--check-intersections: the exact test, every pair, also
# those sharing a vertex or an edge) on the examples, the test models and the sharp CSG
# suite (bores meeting at an angle, a thin slot, near-touching blocks, a thin wall):
# before quad_diagonal's facing rule, csg.hf at -g 64 had 80 pairs.  And every vertex
# within 0.1 cell of the surface: before the settling step (mesh/settle.c) gear.hf
# -g 32 had 21 vertices farther, csg.hf -g 128 432, near.hf -g 64 540, up to 0.75 cell;
# before its second pass (targets beyond the cell, a look around the vertex, a wider
# turn) bracket.hf -g 32, near.hf -g 32, holes.hf -g 64 and 128, segment_box.hf -g 64
# and 128 and segment_cylinder.hf -g 128 kept 17, up to half a cell.
# mesh_suite GRID RUN...: each RUN is MODEL (the examples in their own box, `-- @box`,
# the other models in the suite's) or MODEL:own (its own box).
mesh_suite() {
  g=$1; shift
  for run in "$@"; do
    hf=${run%%:*}
    case $run in *:own*|"$E"/*) b= ;; *) b="-b 1.2" ;; esac
    n=$((n + 1))
    # shellcheck disable=SC2086
    "$FREP" mesh "$hf" $b -g "$g" -o "$T/m.stl" --check-intersections -q >"$T/out" 2>"$T/err"
    pairs=$(sed -n 's/^check: self-intersecting triangle pairs \([0-9]*\),.*/\1/p' "$T/out")
    far=$(sed -n 's/.*from the surface \([0-9]*\) (largest .*/\1/p' "$T/out")
    dist=$(sed -n 's/.*(largest \(.*\) cell)$/\1/p' "$T/out")
    name="$(basename "$hf")${b:+ $b} -g $g"
    ok=$([ "$pairs" = 0 ] && [ "$far" = 0 ] && echo 1)
    if [ "$ok" = 1 ]; then
      echo "ok $n - $name: $pairs self-intersecting triangle pairs, no vertex over 0.1 cell from the surface (largest $dist cell)"
    else
      echo "not ok $n - $name: $pairs self-intersecting triangle pairs, $far vertices over 0.1 cell from the surface (largest $dist cell)"
      fails=$((fails + 1))
    fi
  done
}
for g in 32 64 128; do
  # shellcheck disable=SC2046
  mesh_suite $g "$E"/*.hf "$M"/*.hf "$M"/sharp/*.hf
done
# At -g 256 the sharp models and the examples with the most settled vertices (holes.hf
# 16 far vertices and near.hf 29 before the second pass).  Before the settling step
# unfolded the fans of folded triangles (mesh/settle.c), holes.hf had 16 self-
# intersecting pairs here, twist.hf 32, and segment_cylinder.hf in its own box 12, 6
# and 20 at -g 32, 64, 128.  bracket.hf had 3 pairs here (a sliver folded along the
# rib's 45-degree edge) before the root finder kept a secant guess rounded one ulp past
# its bracket instead of bisecting (mesh/mesh.c, root_guess).  segment_cone.hf had 106
# pairs here along its cap's rim before ambiguous faces were decided by the field at
# their centre (mesh/mesh.c, face_decisions): a fixed rule gave cells holding the cap
# and the side two components each mixing both.  (About 1 s of CPU a model at -g 256.)
mesh_suite 256 "$M/sharp/near.hf" "$E/csg.hf" "$E/gear.hf" \
  "$M/sharp/holes.hf" "$E/bracket.hf" "$E/twist.hf" "$M/segment_cone.hf"
# The same rim on a coarse grid: 8 pairs at -g 36 before the faces were decided by the
# field (and 16, 18, 42 at -g 54, 102, 120).
mesh_suite 36 "$M/segment_cone.hf"
for g in 32 64 128; do mesh_suite $g "$M/segment_cylinder.hf:own"; done
# Quads with three feature vertices along a crease (mesh/quads.c, quad_diagonal): the
# diagonal joining the outer two cut across the crease and left a sliver that folded.
# segment_box.hf had 9, 6 and 6 self-intersecting pairs at -g 27, 50 and 122, csg.hf
# 6 vertices over 0.1 cell at -g 44 (the settling step could not move them past the
# slivers), blend.hf 3 pairs at -g 76, twist.hf 12 at -g 78.
mesh_suite 27 "$M/segment_box.hf"
mesh_suite 50 "$M/segment_box.hf"
mesh_suite 122 "$M/segment_box.hf"
mesh_suite 44 "$E/csg.hf"
mesh_suite 76 "$E/blend.hf"
mesh_suite 78 "$E/twist.hf"
# Edge and corner solutions of the QEF clamped into the cell when they still fit every
# crossing's tangent plane (mesh/mesh.c, MESH_QEF_FIT).  Sharp edges on grid planes
# (within rounding: x = 1 at -g 26 and 104 in the bracket's box) lie on the cells'
# faces, and their vertices fell back to the mass point, half a cell off the surface:
# bracket.hf had 2, 5, 19, 19, 11 and 2 vertices over 0.1 cell at -g 22, 26, 52, 104,
# 130 and 149, gear.hf 8 at -g 70, near.hf 1 at -g 40.  Creases just past a cell's
# face: the mass point's fan folded, segment_cylinder.hf had 6 self-intersecting pairs
# at -g 54, twist.hf 8 at -g 42, segment_box.hf 4 at -g 141.  near.hf at -g 20 is the
# tangent-plane test: clamped without it, a block's end on a grid plane beside a wall's
# edge left a vertex 0.31 cell off.
mesh_suite 22 "$E/bracket.hf"
mesh_suite 26 "$E/bracket.hf"
mesh_suite 52 "$E/bracket.hf"
mesh_suite 104 "$E/bracket.hf"
mesh_suite 130 "$E/bracket.hf"
mesh_suite 149 "$E/bracket.hf"
mesh_suite 70 "$E/gear.hf"
mesh_suite 40 "$M/sharp/near.hf"
mesh_suite 20 "$M/sharp/near.hf"
mesh_suite 54 "$M/segment_cylinder.hf"
mesh_suite 42 "$E/twist.hf"
mesh_suite 141 "$M/segment_box.hf"
# Mass points (rank 0) projected until 0.05 cell from the surface, not 0.1
# (mesh/mesh.c, MESH_PROJECT_TOL_MASS): segment_box.hf had 4 self-intersecting pairs at
# -g 42 and 90, a mass point beside a box corner stopped 0.065 cell outside a face.
# Projection across a crease for a flat patch (MESH_PROJECT_FACING): csg.hf had 16
# vertices 0.2 cell above the hole's rim at -g 117, near.hf 2 far vertices and 6
# self-intersecting pairs at -g 134.
mesh_suite 42 "$M/segment_box.hf"
mesh_suite 90 "$M/segment_box.hf"
mesh_suite 117 "$E/csg.hf"
mesh_suite 134 "$M/sharp/near.hf"
# Mass points nearer than the settling threshold settled when their fan meets another
# triangle (mesh/settle.c, MESH_SETTLE_TOL_MASS): segment_box.hf had 4 and 8 self-
# intersecting pairs at -g 54 and 102, a mass point beside a box corner 0.035 cell off
# a face.  Targets at the corners of a cell on the level (mesh/settle.c,
# level_corner_targets): near.hf had 4 vertices 0.32 cell off at -g 24, a phantom
# crease between a block's edge and the wall's.
mesh_suite 54 "$M/segment_box.hf"
mesh_suite 102 "$M/segment_box.hf"
mesh_suite 24 "$M/sharp/near.hf"
# Crossings the slope stop took where the field is flat past them are bisected further
# (mesh/mesh.c, MESH_ROOT_BISECT): near.hf had 2 vertices 1.05 cell off at -g 55, the
# crossing on the x-edge past the thin wall's end 0.12 cell short of it, its corner
# lost.  A mass point takes its clamped corner solution when the field puts that on the
# surface (mesh/mesh.c, clamped_on_surface): near.hf had 2 vertices 0.5 cell off at
# -g 120, the corner on the first block's face beside the gap missed the cylinder's
# tangent plane by 0.135 cell.
mesh_suite 55 "$M/sharp/near.hf"
mesh_suite 120 "$M/sharp/near.hf"
# ... but not the crossings already within 0.1 cell of the surface (MESH_ROOT_NEAR):
# bisected, the x-edges 0.02 cell above the wall's top face met the cylinder poking
# through it and near.hf had 8 self-intersecting pairs at -g 83.
mesh_suite 83 "$M/sharp/near.hf"
# A cube whose faces lie on grid planes (every corner of a face cell on the level, where
# the settling step moves vertices): its 8 corners stay sharp, a vertex within 1% of a
# cell of each, and no vertex far from the surface, at several grids.
cat > "$T/cube.hf" <<'EOF'
my_model(x[3], a[1])
{
  my_model = frPlane(x, 1, 0, 0, 0.5) & frPlane(x, -1, 0, 0, 0.5) & frPlane(x, 0, 1, 0, 0.5)
           & frPlane(x, 0, -1, 0, 0.5) & frPlane(x, 0, 0, 1, 0.5) & frPlane(x, 0, 0, -1, 0.5);
}
EOF
cat > "$T/corners.awk" <<'EOF'
# OFF vertices within tol of each corner of [-0.5, 0.5]^3: fails unless all 8 have one
NR == 2 { nv = $1 }
NR > 2 && NR <= 2 + nv {
  for (c = 0; c < 8; c++) {
    dx = $1 - (c % 2 ? 0.5 : -0.5); dy = $2 - (int(c / 2) % 2 ? 0.5 : -0.5)
    dz = $3 - (c >= 4 ? 0.5 : -0.5)
    if (dx * dx + dy * dy + dz * dz <= tol * tol) hit[c] = 1
  }
}
END { for (c = 0; c < 8; c++) if (!hit[c]) exit 1 }
EOF
for g in 16 32 64; do
  t "cube on grid planes -g $g: no vertex far from the surface" sh -c \
    "'$FREP' mesh '$T/cube.hf' -b 1 -g $g -o '$T/cube.off' --check -q | grep -q 'surface 0 ('"
  t "... and its 8 corners within 1% of a cell" \
    awk -v tol="$(awk "BEGIN { print 0.01 * 2 / $g }")" -f "$T/corners.awk" "$T/cube.off"
done
# One sheet crossing a cell face twice on both sides of the face (a tunnel thinner than
# a cell; near-touching parts): four quads used to share one mesh edge there.  These
# grids and boxes did so before the face vertices of mesh/mesh.c.
cat > "$T/near.hf" <<'EOF'
my_model(x[3], a[1])
{
  array c0[3], c1[3], c2[3], c3[3], c4[3], c5[3], c6[3];
  c0 = [-0.3573, -0.1604, -0.4463];
  c1 = [-0.1611, -0.2286, 0.1105];
  c2 = [-0.0462, -0.4973, 0.0887];
  c3 = [-0.209, -0.1902, -0.0898];
  c4 = [-0.1724, -0.2334, -0.0511];
  c5 = [0.0702, -0.2305, 0.1572];
  c6 = [-0.0723, -0.2984, -0.1167];
  my_model = ((((((hfSphere(x, c0, 0.1965) | hfSphere(x, c1, 0.0713)) & hfSphere(x, c2, 0.2958))
             | hfSphere(x, c3, 0.2327)) \ hfBlock(x, c4, 0.3063, 0.2086, 0.3077))
             | hfSphere(x, c5, 0.1569)) | hfBlock(x, c6, 0.2934, 0.3941, 0.1968));
}
EOF
t "near-touching CSG parts: closed, 2-manifold (edges and vertices), oriented" \
  "$FREP" mesh "$T/near.hf" -b -0.924,-0.874,-0.985,0.847,0.947,0.823 -g 17 --setops minmax \
  -o "$T/m.stl" --check -q
for gb in 24:-1.55,-1.63,-1.6,1.61,1.58,1.67 37:1.6 53:-1.3,-1.1,-1.7,1.2,1.7,1.3; do
  t "gyroid -g ${gb%%:*} -b ${gb#*:}: closed, 2-manifold (edges and vertices), oriented" \
    "$FREP" mesh "$srcdir/bench/bench_gyroid.hf" -g "${gb%%:*}" -b "${gb#*:}" -o "$T/m.stl" --check -q
done
t "block minus ball at 1 thread" "$FREP" mesh "$M/block_minus_ball.hf" -b 1 -g 50 -t 1 -o "$T/a.ply" -q
t "block minus ball at 2 threads" "$FREP" mesh "$M/block_minus_ball.hf" -b 1 -g 50 -t 2 -o "$T/b.ply" -q
t "the same mesh at 1 and 2 threads" cmp "$T/a.ply" "$T/b.ply"
# the bench gear at -g 64: stages big enough for 2 threads (mesh_threads_for)
t "gear -g 64 at 1 thread" "$FREP" mesh "$srcdir/bench/eval_gear.hf" -b 1.6 -g 64 -t 1 -o "$T/a.ply" -q
t "gear -g 64 at 2 threads" "$FREP" mesh "$srcdir/bench/eval_gear.hf" -b 1.6 -g 64 -t 2 -o "$T/b.ply" -q
t "gear -g 64 at the default threads" "$FREP" mesh "$srcdir/bench/eval_gear.hf" -b 1.6 -g 64 -o "$T/c.ply" -q
t "the same gear mesh at 1 and 2 threads" cmp "$T/a.ply" "$T/b.ply"
t "the same gear mesh at 1 thread and the default" cmp "$T/a.ply" "$T/c.ply"
# near.hf -g 64 settles hundreds of vertices (mesh/settle.c), decided in vertex order
t "near.hf -g 64 at 1 thread" "$FREP" mesh "$M/sharp/near.hf" -b 1.2 -g 64 -t 1 -o "$T/a.ply" -q
t "near.hf -g 64 at 3 threads" "$FREP" mesh "$M/sharp/near.hf" -b 1.2 -g 64 -t 3 -o "$T/b.ply" -q
t "the same settled mesh at 1 and 3 threads" cmp "$T/a.ply" "$T/b.ply"
# gyroid -g 72: 130000 triangles, enough for the parallel assembly (its arrays above
# POLY_PAR_MIN_BYTES, mesh/polygonize.c) and fold check (SETTLE_PAR_MIN_TRIS)
t "gyroid -g 72 at 1 thread" "$FREP" mesh "$srcdir/bench/bench_gyroid.hf" -b 1.6 -g 72 -t 1 -o "$T/a.stl" -q
t "gyroid -g 72 at 3 threads" "$FREP" mesh "$srcdir/bench/bench_gyroid.hf" -b 1.6 -g 72 -t 3 -o "$T/b.stl" -q
t "the same assembled mesh at 1 and 3 threads" cmp "$T/a.stl" "$T/b.stl"
for ext in stl obj ply off; do
  t "writes .$ext" "$FREP" mesh "$M/block_minus_ball.hf" -b 1 -g 16 -o "$T/m.$ext" -q
  t "samples .$ext" "$FREP" sample "$T/m.$ext" -n 50 -o "$T/s.xyz" --seed 3 -q
done
t "ASCII STL" sh -c "'$FREP' mesh '$M/block_minus_ball.hf' -b 1 -g 16 --ascii -o '$T/a.stl' -q && head -1 '$T/a.stl' | grep -q '^solid'"
t "sample a model" "$FREP" sample "$M/block_minus_ball.hf" -b 1 -n 1000 -o "$T/c.xyz" --seed 9 --noise 0.001 --outliers 0.05
t "sample prints the seed" sh -c "'$FREP' sample '$M/block_minus_ball.hf' -b 1 -n 10 -o '$T/d.xyz' --seed 9 | grep -q 'seed 9'"
t "sample writes 1000 lines of 6 numbers" sh -c "test \$(wc -l < '$T/c.xyz') -eq 1000 && awk 'NF != 6 { exit 1 }' '$T/c.xyz'"
t "render with points" "$FREP" render "$M/block_minus_ball.hf" -b 1 -g 32 --size 64x48 --view top --points "$T/c.xyz" -o "$T/v.png"
t "render writes a PNG" sh -c "head -c 8 '$T/v.png' | od -An -c | grep -q 'P   N   G'"
t "render a mesh file with points" sh -c "'$FREP' mesh '$M/block_minus_ball.hf' -b 1 -g 24 -o '$T/v.off' -q && '$FREP' render '$T/v.off' --size 64x48 --points '$T/c.xyz' -o '$T/vm.png' --scale 0.01 | grep -q '1000 points'"
t "render compresses: a 1000x1000 picture under 200 kB" sh -c "'$FREP' render '$M/block_minus_ball.hf' -b 1 -g 32 --size 1000x1000 -o '$T/big.png' -q && test \$(wc -c < '$T/big.png') -lt 200000"
f "empty model" "empty in the box" "$FREP" mesh "$M/block_minus_ball.hf" -b 5,6 -o "$T/e.stl"
f "full model" "fills all of" "$FREP" mesh "$M/block_minus_ball.hf" -b 0.1 -o "$T/e.stl"
f "huge -g" "1..2048" "$FREP" mesh "$M/block_minus_ball.hf" -g 99999 -o "$T/e.stl"
f "zero-size box" "box.*along x: \[1, 1\]" "$FREP" mesh "$M/block_minus_ball.hf" -b 1,1 -o "$T/e.stl"
f "unknown format" "cannot tell the format" "$FREP" mesh "$M/block_minus_ball.hf" -o "$T/e.xyz"
f "bad mesh input" "e.off:" sh -c "printf 'OFF\n1 1 0\n0 0 0\n3 0 0 7\n' > '$T/e.off' && '$FREP' sample '$T/e.off' -n 5 -o '$T/e.xyz'"
f "bad --view" "expected one of" "$FREP" render "$M/block_minus_ball.hf" --view upside -o "$T/e.png"
# runtime domain errors: one warning with the position of the failing operation
RE='thin_nan.hf:7:34: warning: sqrt of a negative number at [0-9]* points'
w "mesh reports sqrt of a negative with its position" "$RE" \
  "$FREP" mesh "$M/thin_nan.hf" -b 1.2 -g 20 -o "$T/n.stl" -q
cp "$T/err" "$T/warn"
t "... once" test "$(grep -c 'warning: sqrt' "$T/warn")" -eq 1
t "... with the source line and a caret" grep -q '^ *\^~~~$' "$T/warn"
w "sample reports it too" "$RE" \
  "$FREP" sample "$M/thin_nan.hf" -b 1.2 -n 100 --seed 1 -o "$T/n.xyz" -q
w "render reports it too" "$RE" \
  "$FREP" render "$M/thin_nan.hf" -b 1.2 -g 20 --size 32x32 -o "$T/n.png" -q
t "no warning without domain errors" sh -c "'$FREP' mesh '$M/block_minus_ball.hf' -b 1 -g 16 -o '$T/q.stl' -q 2>&1 | grep -c warning | grep -qx 0"
# -v: the work, then each step's wall time, which add up to at most the summary's
t "-v prints each step's wall time, within the summary's" sh -c "'$FREP' mesh '$E/gear.hf' -g 64 -o '$T/v.stl' -v > '$T/vt' && awk '
  / grid 64, / { total = \$NF == \"s\" ? \$(NF - 1) : 0 }
  /^time: octree [0-9.]* ms, contouring [0-9.]* ms, quads [0-9.]* ms, assembly [0-9.]* ms, settling [0-9.]* ms\$/ {
    seen = 1; sum = \$3 + \$6 + \$9 + \$12 + \$15 }
  END { exit !(seen && total > 0 && sum > 0 && sum <= 1000 * total + 1) }' '$T/vt'"
t "no output left behind by failures" sh -c "! ls '$T'/e.stl '$T'/e.png 2>/dev/null"
echo "1..$n"
test $fails -eq 0
