#!/bin/sh
# bench_evolve.sh - `make bench` figures of frep evolve: time to solution and tree size
# of the unpartitioned GA against the partitioned one, at 1 and 2 threads, on
#   cube  the unit cube (6 planes) at 65,000 points,
#   m1    a block with a cylindrical hole and a spherical cap (4+ primitives, after the
#         paper's M1) at 10^4 points with noise,
#   m2    twelve separate parts of 4 primitives each (a sphere cut by three planes:
#         twelve 4-primitive cliques, after the paper's M2) at 10^4 points with noise.
# Primitives are given (-p) so that only the tree search is timed. Needs FREP; prints a
# table (Markdown) for doc/benchmarks.md. CPU seconds are reported as well as wall
# seconds because a loaded machine inflates the latter.

: "${FREP:?FREP must name the frep binary}"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-bench-evolve.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM
MAXT=${BENCH_EVOLVE_MAX_TIME:-60}

# ---- models and their primitive lists ------------------------------------------
cat >"$tmp/cube.hf" <<'EOF'
-- @setops minmax
-- @box -1.5 -1.5 -1.5 1.5 1.5 1.5
my_model(x[3], a[1]) {
    my_model = frPlane(x, 1, 0, 0, 1) & frPlane(x, -1, 0, 0, 1) & frPlane(x, 0, 1, 0, 1) &
               frPlane(x, 0, -1, 0, 1) & frPlane(x, 0, 0, 1, 1) & frPlane(x, 0, 0, -1, 1);
}
EOF
printf 'plane 1 0 0 1\nplane -1 0 0 1\nplane 0 1 0 1\nplane 0 -1 0 1\nplane 0 0 1 1\nplane 0 0 -1 1\n' \
    >"$tmp/cube.fit"

# m1: block [-1,1]x[-1,1]x[-0.5,0.5] minus a z-cylinder r 0.4, plus a sphere cap on top.
cat >"$tmp/m1.hf" <<'EOF'
-- @setops minmax
-- @box -1.5 -1.5 -1 1.5 1.5 1.5
my_model(x[3], a[1]) {
    blk = frPlane(x, 1, 0, 0, 1) & frPlane(x, -1, 0, 0, 1) & frPlane(x, 0, 1, 0, 1) &
          frPlane(x, 0, -1, 0, 1) & frPlane(x, 0, 0, 1, 0.5) & frPlane(x, 0, 0, -1, 0.5);
    my_model = (blk | frSphere(x, 0.5, 0.5, 0.5, 0.45)) \ frCylinder(x, -0.4, -0.4, 0, 0, 0, 1, 0.3);
}
EOF
cat >"$tmp/m1.fit" <<'EOF'
plane 1 0 0 1
plane -1 0 0 1
plane 0 1 0 1
plane 0 -1 0 1
plane 0 0 1 0.5
plane 0 0 -1 0.5
sphere 0.5 0.5 0.5 0.45
cylinder 0 0 1 -0.4 -0.4 0 0.3
EOF

# m2: twelve parts on a 4x3 grid, 3 apart, at heights 0.3 k: a sphere r 1 cut by
# x <= cx + ox, y <= cy + oy, z <= cz + 0.5, the offsets chosen so that no plane of one
# part passes within epsilon of another part's cut face (twelve separate cliques).
: >"$tmp/m2.fit"
expr=""
for i in 0 1 2 3; do
    for j in 0 1 2; do
        k=$((3 * i + j)); cx=$((3 * i)); cy=$((3 * j))
        cz=$(awk "BEGIN{print 0.3 * $k}")
        ox=$(awk "BEGIN{print $cx + 0.1 + 0.3 * $j}")
        oy=$(awk "BEGIN{print $cy + 0.1 + 0.25 * $i}")
        oz=$(awk "BEGIN{print $cz + 0.5}")
        part="(frSphere(x, $cx, $cy, $cz, 1) & frPlane(x, 1, 0, 0, $ox) & frPlane(x, 0, 1, 0, $oy) & frPlane(x, 0, 0, 1, $oz))"
        if [ -z "$expr" ]; then expr="$part"; else expr="$expr | $part"; fi
        printf 'sphere %s %s %s 1\nplane 1 0 0 %s\nplane 0 1 0 %s\nplane 0 0 1 %s\n' \
            "$cx" "$cy" "$cz" "$ox" "$oy" "$oz" >>"$tmp/m2.fit"
    done
done
printf -- '-- @setops minmax\n-- @box -1.5 -1.5 -1.5 10.5 7.5 5\nmy_model(x[3], a[1]) {\n    my_model = %s;\n}\n' \
    "$expr" >"$tmp/m2.hf"

"$FREP" sample "$tmp/cube.hf" -n 65000 --seed 1 -o "$tmp/cube.xyz" -q || exit 1
"$FREP" sample "$tmp/m1.hf" -n 10000 --seed 1 --noise 0.001 -o "$tmp/m1.xyz" -q || exit 1
"$FREP" sample "$tmp/m2.hf" -n 10000 --seed 1 --noise 0.001 -o "$tmp/m2.xyz" -q || exit 1

echo "| model | points | primitives | GA | threads | wall s | CPU s | nodes | explained |"
echo "|---|---:|---:|---|---:|---:|---:|---:|---:|"
for m in cube m1 m2; do
    np=$(grep -c . "$tmp/$m.fit")
    pts=$(grep -c . "$tmp/$m.xyz")
    for mode in --no-partition --partition; do
        for t in 1 2; do
            /usr/bin/time -f "%e %U %S" -o "$tmp/time" "$FREP" evolve "$tmp/$m.xyz" -p "$tmp/$m.fit" \
                -o "$tmp/out.hf" --seed 1 -t "$t" $mode --max-time "$MAXT" -q 2>/dev/null
            wall=$(cut -d' ' -f1 "$tmp/time")
            cpu=$(awk '{printf "%.2f", $2 + $3}' "$tmp/time")
            nodes=$(sed -n 's/.*tree size \([0-9]*\) nodes.*/\1/p' "$tmp/out.hf")
            expl=$(sed -n 's/.* \([0-9.]*%\) both/\1/p' "$tmp/out.hf")
            echo "| $m | $pts | $np | ${mode#--} | $t | $wall | $cpu | $nodes | $expl |"
        done
    done
done
