#!/bin/sh
# eval_grid.sh - script tests of frep eval --grid (TAP output): interval tape pruning
# changes nothing but the time (summaries and runtime errors identical with and without
# it, at 1 and 2 threads), it does shorten min/max CSG, and the volume estimate of a
# sphere is right; --single keeps double's counts and errors.
: "${FREP:=./frep}" "${srcdir:=.}"
T=${TMPDIR:-/tmp}/frep-grid-test.$$
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
# grid FILE OUT ARGS...: the summary without the time and program lines, and stderr
grid() {
  f=$1; o=$2; shift 2
  "$FREP" eval "$f" --grid 49 -b 1.6 "$@" > "$o.full" 2> "$o.err" || return 1
  grep -v '^time\|^program' "$o.full" > "$o"
}
B="$srcdir/bench"
for m in eval_gear_minmax eval_gear eval_csg; do
  t "$m: summary computed" grid "$B/$m.hf" "$T/$m.0" --no-prune -t 1
  t "$m: pruned, 1 thread: computed" grid "$B/$m.hf" "$T/$m.1" -t 1
  t "$m: pruned, 2 threads: computed" grid "$B/$m.hf" "$T/$m.2" -t 2
  t "$m: pruned, 1 thread: same summary" cmp "$T/$m.0" "$T/$m.1"
  t "$m: pruned, 2 threads: same summary" cmp "$T/$m.0" "$T/$m.2"
done
per=$(sed -n 's/^program *\([0-9]*\) instructions, \([0-9.]*\) evaluated.*/\1 \2/p' "$T/eval_gear_minmax.1.full")
t "min/max gear: pruning evaluates under 60% of the instructions ($per)" \
  awk -v s="$per" 'BEGIN { split(s, v, " "); exit !(v[1] > 400 && v[2] < v[1] * 0.6) }'
per=$(sed -n 's/^program *\([0-9]*\) instructions, \([0-9.]*\) evaluated.*/\1 \2/p' "$T/eval_gear.1.full")
t "R-function gear: nothing is pruned ($per)" \
  awk -v s="$per" 'BEGIN { split(s, v, " "); exit !(v[1] == v[2]) }'

# Sphere of radius 1.2: volume V = 4/3 pi 1.2^3 = 7.2382.  About V / h^3 of the grid
# points (spacing h = 3.2/48) are inside, so the estimate (inside fraction x box
# volume) is V (48/49)^3 = 6.8066; within 1.5%.
grid "$B/eval_sphere.hf" "$T/sphere" -t 2
vol=$(sed -n 's/^volume *\([0-9.e+-]*\) .*/\1/p' "$T/sphere")
t "sphere volume estimate $vol is 6.807 within 1.5%" \
  awk -v v="$vol" 'BEGIN { exit !(v > 6.8066 * 0.985 && v < 6.8066 * 1.015) }'

# The grid's coordinates are lo + (hi - lo) i/(N - 1), end points exact: planes at grid
# coordinates.  At --grid 193 -b 1.6, x_i = -1.6 + 3.2 i/192 is -0.9 at i = 42 and 0.9 at
# i = 150 (exact rationals), so x + 0.9 >= 0 holds for i = 42..192 (151 of the 193
# values) and 0.9 - y >= 0 for i = 0..150 (151): 151 x 193^2 = 5624599 points inside
# each.  (lo + step i puts x_42 at -0.9000000000000001: 150 x 193^2.)
printf 'my_model(x[3], a[1])\n{\n  my_model = x[1] + 0.9;\n}\n' > "$T/px.hf"
printf 'my_model(x[3], a[1])\n{\n  my_model = 0.9 - x[2];\n}\n' > "$T/py.hf"
printf 'my_model(x[3], a[1])\n{\n  my_model = x[3] - 1.6;\n}\n' > "$T/pz.hf"
for p in px py; do
  "$FREP" eval "$T/$p.hf" --grid 193 -b 1.6 > "$T/$p.out"
  t "plane $p at a grid coordinate: 151 x 193^2 = 5624599 inside" grep -q '^inside    5624599 ' "$T/$p.out"
done
"$FREP" eval "$T/pz.hf" --grid 193 -b 1.6 > "$T/pz.out"
t "plane z = 1.6 at the upper end point: one layer, 193^2 = 37249 inside" grep -q '^inside    37249 ' "$T/pz.out"

# Threads sized by the job (FREP_PAR_MIN_WORK = 4e6 node-evaluations): the sphere's
# 9 instructions at 9^3 points are ~6600, so -t 2 runs on one thread.
"$FREP" eval "$B/eval_sphere.hf" --grid 9 -b 1.6 -t 2 > "$T/tiny.out"
t "a tiny grid runs on one thread even with -t 2" grep -q ' on 1 thread$' "$T/tiny.out"

# Domain errors: the same count and position with and without pruning.
cat > "$T/err.hf" <<'HF'
my_model(x[3], a[1])
{
  my_model = max(sqrt(x[1] - 0.5), 0.3 - x[2]^2 - x[3]^2);
}
HF
grid "$T/err.hf" "$T/e0" --no-prune
grid "$T/err.hf" "$T/e1"
t "runtime error reported" grep -q "sqrt of a negative number" "$T/e0.err"
t "runtime error count and position identical with pruning" \
  sh -c "sed 's/e\\.g\\..*//' '$T/e0.err' > '$T/e0.m' && sed 's/e\\.g\\..*//' '$T/e1.err' > '$T/e1.m' && cmp '$T/e0.m' '$T/e1.m' && cmp '$T/e0' '$T/e1'"

# --single: the float path (where the CPU has AVX2) gives double's inside and NaN counts
# and the same error report; min, max and sum agree to about 6 digits.
inside() { sed -n 's/^inside *\([0-9]*\) .*/\1/p' "$1"; }
for m in eval_gear eval_gear_minmax eval_csg; do
  grid "$B/$m.hf" "$T/$m.s" --single -t 2
  t "$m --single: the inside count is double's ($(inside "$T/$m.s"))" \
    test "$(inside "$T/$m.s")" = "$(inside "$T/$m.0")"
  t "$m --single: says which precision ran" grep -q '^precision \(single: [0-9]* blocks\|double (--single needs\)' "$T/$m.s"
  t "$m --single: min, max and sum within 1e-5 relative" awk '
    /^values/ { k++; mn[k] = $3; mx[k] = $5; sm[k] = $7 }
    function off(a, b) { d = a - b; if (d < 0) d = -d; return d > 1e-5 * (1 + (b < 0 ? -b : b)) }
    END { exit !(k == 2 && !off(mn[1], mn[2]) && !off(mx[1], mx[2]) && !off(sm[1], sm[2])) }' "$T/$m.0" "$T/$m.s"
done
grid "$T/err.hf" "$T/e2" --single
t "--single: the same runtime errors" \
  sh -c "sed 's/e\\.g\\..*//' '$T/e2.err' > '$T/e2.m' && cmp '$T/e0.m' '$T/e2.m'"
printf 'my_model(x[3], a[1])\n{\n  my_model = sin(x[1]) - 0.5;\n}\n' > "$T/sin.hf"
grid "$T/sin.hf" "$T/sin" --single
t "--single: a program the float path lacks (sin) runs in double and says so" grep -q '^precision double' "$T/sin"
t "--single needs --grid" sh -c "! '$FREP' eval '$B/eval_sphere.hf' --single < /dev/null 2> '$T/u.err' && grep -q 'only for --grid' '$T/u.err'"
echo "1..$n"
[ "$fails" -eq 0 ]
