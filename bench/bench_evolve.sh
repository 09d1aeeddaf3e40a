#!/bin/sh
# bench_evolve.sh - `make bench` figures of frep evolve (doc/benchmarks.md, "frep evolve").
#
# 1. Synthetic models written after the papers' (Fayolle & Pasko 2016; Friedrich et al.
#    2018), primitives given (-p) so that only the tree search is timed:
#      cube  the cube [-1,1]^3 (6 planes) at 65,000 points, no noise;
#      m0    a bracket: block, cylindrical boss, five holes, a groove, a spherical
#            pocket (17 primitives, after M0);
#      m1    a capped cylinder united with a sphere (4 primitives, after M1);
#      m2    a 4 x 3 grid of spheres cut by planes shared along columns and rows
#            (29 primitives, twelve 4-primitive cliques, after M2);
#    m0-m2 at 10^4 and 1.5*10^5 points with Gaussian noise sigma 0.01 (model units).
#    Unpartitioned and partitioned GA at 1 and 2 threads; RUNS seeds each; medians of the
#    run time (evolve's own clock), CPU seconds, tree size and explained share, and the
#    ratio of the 1- and 2-thread wall times.
#    Speed-up of partitioning (m0, m2 at 10^4 points, 1 thread, SPEEDUP_RUNS seeds): the
#    partitioned run's time T_p (whole run) and quality Q_p (the share of the scored
#    points its merged clique trees explain, the "merged" line of --trace); the
#    unpartitioned GA run long
#    (--generations SGENS --stagnation 0 --max-time BUDGET --stop-share Q_p-1 --trace);
#    its time to solution T_u = the first trace line whose share >= Q_p - 1 point;
#    speed-up T_u / T_p, or ">= T_end / T_p" when it never gets there, and T_u / T_m
#    with T_m the time of the merged tree (where the papers' pipeline ends)
#    (doc/evolve.md, "Speed-up of partitioning").
# 2. Real data, when ../shared/data/inversecsg exists next to the source tree:
#    frep sample MESH -> frep segment -> frep evolve -> frep mesh per model; time, tree
#    size, the ground truth's primitive counts, and the symmetric Chamfer and Hausdorff
#    distances of the result mesh to the input mesh relative to its diagonal
#    (bench/mesh_distance.py, needs /usr/bin/python3 with numpy and scipy).
#
# usage: FREP=path/to/frep sh bench_evolve.sh [SRCDIR]
# Environment: BENCH_EVOLVE_RUNS (3), BENCH_EVOLVE_MAX_TIME (60 s per run),
# BENCH_EVOLVE_SPEEDUP_RUNS (3), BENCH_EVOLVE_SPEEDUP_BUDGET (90 s per unpartitioned
# run; longer budgets give tighter lower bounds), BENCH_EVOLVE_SPEEDUP_GENERATIONS
# (100000: the budget decides), BENCH_EVOLVE_SKIP_SPEEDUP=1, BENCH_EVOLVE_SKIP_TABLE=1
# (the speed-up rows only), BENCH_EVOLVE_SKIP_SYNTH=1, BENCH_EVOLVE_SKIP_REAL=1,
# BENCH_EVOLVE_DATA (data folder).

: "${FREP:?FREP must name the frep binary}"
srcdir=${1:-$(dirname "$0")/..}
tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-bench-evolve.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM
RUNS=${BENCH_EVOLVE_RUNS:-3}
MAXT=${BENCH_EVOLVE_MAX_TIME:-60}
SRUNS=${BENCH_EVOLVE_SPEEDUP_RUNS:-3}
BUDGET=${BENCH_EVOLVE_SPEEDUP_BUDGET:-90}
SGENS=${BENCH_EVOLVE_SPEEDUP_GENERATIONS:-100000}
DATA=${BENCH_EVOLVE_DATA:-$srcdir/../shared/data/inversecsg}

echo "frep evolve benchmark: $(nproc 2>/dev/null || echo '?') cores, $RUNS runs per configuration (medians)"

median() { # median of the numbers on standard input
    sort -g | awk '{ v[NR] = $1 } END { if (NR == 0) print "-"; else if (NR % 2) print v[(NR + 1) / 2]; else printf "%.4g\n", (v[NR / 2] + v[NR / 2 + 1]) / 2 }'
}

# ---- models and their primitive lists (.fit: plane n d; sphere c r; cylinder axis point r)
write_models() {
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

cat >"$tmp/m0.hf" <<'EOF'
-- @setops minmax
-- @box -2.5 -2 -0.5 2.5 2 2
my_model(x[3], a[1]) {
    blk = frPlane(x, 1, 0, 0, 2) & frPlane(x, -1, 0, 0, 2) & frPlane(x, 0, 1, 0, 1.5) &
          frPlane(x, 0, -1, 0, 1.5) & frPlane(x, 0, 0, 1, 1) & frPlane(x, 0, 0, -1, 0);
    boss = frCylinder(x, 0, 0, 0, 0, 0, 1, 0.8) & frPlane(x, 0, 0, 1, 1.6) & frPlane(x, 0, 0, -1, 0);
    holes = frCylinder(x, 0, 0, 0, 0, 0, 1, 0.4) | frCylinder(x, 1.5, 1, 0, 0, 0, 1, 0.25) |
            frCylinder(x, 1.5, -1, 0, 0, 0, 1, 0.25) | frCylinder(x, -1.5, 1, 0, 0, 0, 1, 0.25) |
            frCylinder(x, -1.5, -1, 0, 0, 0, 1, 0.25);
    groove = frPlane(x, -1, 0, 0, -0.9) & frPlane(x, 1, 0, 0, 1.15) & frPlane(x, 0, 0, -1, -0.7);
    my_model = (blk | boss) \ holes \ groove \ frSphere(x, -1.2, 0, 1, 0.45);
}
EOF
cat >"$tmp/m0.fit" <<'EOF'
plane 1 0 0 2
plane -1 0 0 2
plane 0 1 0 1.5
plane 0 -1 0 1.5
plane 0 0 1 1
plane 0 0 -1 0
cylinder 0 0 1 0 0 0 0.8
plane 0 0 1 1.6
cylinder 0 0 1 0 0 0 0.4
cylinder 0 0 1 1.5 1 0 0.25
cylinder 0 0 1 1.5 -1 0 0.25
cylinder 0 0 1 -1.5 1 0 0.25
cylinder 0 0 1 -1.5 -1 0 0.25
plane -1 0 0 -0.9
plane 1 0 0 1.15
plane 0 0 -1 -0.7
sphere -1.2 0 1 0.45
EOF

cat >"$tmp/m1.hf" <<'EOF'
-- @setops minmax
-- @box -1.5 -1.5 -1.5 1.5 1.5 2.5
my_model(x[3], a[1]) {
    my_model = (frCylinder(x, 0, 0, 0, 0, 0, 1, 0.6) & frPlane(x, 0, 0, 1, 1) &
                frPlane(x, 0, 0, -1, 1)) | frSphere(x, 0, 0, 1, 0.9);
}
EOF
printf 'cylinder 0 0 1 0 0 0 0.6\nplane 0 0 1 1\nplane 0 0 -1 1\nsphere 0 0 1 0.9\n' >"$tmp/m1.fit"

# m2: part (i, j) of the 4 x 3 grid is a sphere r 1 at (3i, 3j, cz) cut by
# x <= 3i + 0.3 + 0.1i (one plane per column), y <= 3j + 0.35 + 0.1j (one per row) and
# z <= cz + 0.5 (the first two parts of rows 0 and 1 share theirs): 12 + 4 + 3 + 10 = 29.
(cd "$tmp" && awk 'BEGIN {
    expr = "";
    for (j = 0; j < 3; j++) for (i = 0; i < 4; i++) {
        cx = 3 * i; cy = 3 * j;
        cz = (i < 2 && j < 2) ? 0.4 * j : 0.3 * (4 * j + i) + 1;
        ox = 0.3 + 0.1 * i; oy = 0.35 + 0.1 * j;
        zk = (i < 2 && j < 2) ? "z" j : "z" i "_" j;
        printf "sphere %g %g %g 1\n", cx, cy, cz > "m2.fit";
        if (!(("x" i) in seen)) { seen["x" i] = 1; printf "plane 1 0 0 %g\n", cx + ox > "m2.fit" }
        if (!(("y" j) in seen)) { seen["y" j] = 1; printf "plane 0 1 0 %g\n", cy + oy > "m2.fit" }
        if (!(zk in seen)) { seen[zk] = 1; printf "plane 0 0 1 %g\n", cz + 0.5 > "m2.fit" }
        part = sprintf("(frSphere(x, %g, %g, %g, 1) & frPlane(x, 1, 0, 0, %g) & frPlane(x, 0, 1, 0, %g) & frPlane(x, 0, 0, 1, %g))", cx, cy, cz, cx + ox, cy + oy, cz + 0.5);
        expr = expr (expr == "" ? "" : " |\n        ") part;
    }
    printf "-- @setops minmax\n-- @box -1.5 -1.5 -1.5 10.5 7.5 5.5\nmy_model(x[3], a[1]) {\n    my_model = %s;\n}\n", expr > "m2.hf";
}')
}

# One configuration: RUNS seeds; a table row of medians.
bench_row() { # bench_row MODEL CLOUD MODE THREADS
    m=$1 cloud=$2 mode=$3 t=$4
    : >"$tmp/runs"
    s=1
    while [ "$s" -le "$RUNS" ]; do
        /usr/bin/time -f "%U %S" -o "$tmp/time" "$FREP" evolve "$tmp/$cloud.xyz" -p "$tmp/$m.fit" \
            -o "$tmp/out.hf" --seed "$s" -t "$t" "$mode" --max-time "$MAXT" -q 2>/dev/null
        secs=$(sed -n 's/^-- seed .*generations, \([0-9.]*\) s$/\1/p' "$tmp/out.hf")
        cpu=$(awk '{ printf "%.2f", $1 + $2 }' "$tmp/time")
        nodes=$(sed -n 's/.*tree size \([0-9]*\) nodes.*/\1/p' "$tmp/out.hf")
        expl=$(sed -n 's/.* \([0-9.]*\)% both$/\1/p' "$tmp/out.hf")
        echo "$secs $cpu $nodes $expl" >>"$tmp/runs"
        s=$((s + 1))
    done
    np=$(grep -c . "$tmp/$m.fit")
    pts=$(grep -c . "$tmp/$cloud.xyz")
    wall=$(cut -d' ' -f1 "$tmp/runs" | median)
    echo "$cloud ${mode#--} $t $wall" >>"$tmp/walls"
    echo "| $m | $pts | $np | ${mode#--} | $t | $wall | $(cut -d' ' -f2 "$tmp/runs" | median) | $(cut -d' ' -f3 "$tmp/runs" | median) | $(cut -d' ' -f4 "$tmp/runs" | median)% |"
}

# Median of "value flag" lines (flag 1: the value is a lower bound); ">=" when the
# median is, or averages, a lower bound.
median_bound() {
    sort -g | awk '{ v[NR] = $1; b[NR] = $2 }
        END { if (NR == 0) { print "-"; exit }
              if (NR % 2) { k = (NR + 1) / 2; m = v[k]; lb = b[k] }
              else { k = NR / 2; m = (v[k] + v[k + 1]) / 2; lb = b[k] || b[k + 1] }
              printf "%s%.1f\n", lb ? ">= " : "", m }'
}

# Speed-up of partitioning on one model: SRUNS seeds, 1 thread.
speedup_rows() { # speedup_rows MODEL CLOUD
    m=$1 cloud=$2
    : >"$tmp/sp"
    s=1
    while [ "$s" -le "$SRUNS" ]; do
        "$FREP" evolve "$tmp/$cloud.xyz" -p "$tmp/$m.fit" -o "$tmp/p.hf" --seed "$s" -t 1 \
            --partition --max-time "$MAXT" --trace "$tmp/tp" -q 2>/dev/null
        # T_p, Q_p: the partitioned run's end (wall, CPU) and the share of the tree its
        # GA phases give (the merged clique trees, before growth and polish); T_m: the
        # time of that tree (the papers' pipeline ends there).
        set -- $(awk '/^# end:/ { w = $3; c = $6; n = $9; f = $11 }
                      !/^#/ && $7 == "merged" { q = $6; mw = $2; mc = $3 }
                      END { print w, c, q + 0, n, f, mw + 0, mc + 0 }' "$tmp/tp")
        tpw=$1 tpc=$2 qp=$3 np_=$4 fp=$5 tmw=$6 tmc=$7
        # The unpartitioned GA stops at the target (--stop-share), else at the budget.
        target=$(awk -v q="$qp" 'BEGIN { printf "%.3f", (q > 1 ? q - 1 : 0.001) }')
        "$FREP" evolve "$tmp/$cloud.xyz" -p "$tmp/$m.fit" -o "$tmp/u.hf" --seed "$s" -t 1 \
            --no-partition --generations "$SGENS" --stagnation 0 --max-time "$BUDGET" \
            --stop-share "$target" --trace "$tmp/tu" -q 2>/dev/null
        # T_u: the first unpartitioned line with share >= Q_p - 1; else the run's end.
        set -- $(awk -v q="$qp" '/^# end:/ { w = $3; c = $6; n = $9; f = $11 }
                      !/^#/ && !hit && $6 >= q - 1 { hit = 1; hw = $2; hc = $3; g = $1 }
                      !/^#/ { last = $1; best = $6 }
                      END { if (hit) print hw, hc, 0, g, n, f, best
                            else print w, c, 1, last, n, f, best }' "$tmp/tu")
        tuw=$1 tuc=$2 lb=$3 gen=$4 nu=$5 fu=$6 bu=$7
        rw=$(awk -v a="$tuw" -v b="$tpw" 'BEGIN { printf "%.2f", a / b }')
        rc=$(awk -v a="$tuc" -v b="$tpc" 'BEGIN { printf "%.2f", a / b }')
        rm=$(awk -v a="$tuw" -v b="$tmw" 'BEGIN { printf "%.2f", (b > 0 ? a / b : 0) }')
        ge=""
        [ "$lb" = 1 ] && ge=">= "
        echo "$rw $lb $rc $np_ $nu $rm" >>"$tmp/sp"
        echo "| $m | $s | $tpw | $tpc | $tmw | $qp% | $np_ | $fp | $ge$tuw | $ge$tuc | $gen | $bu% | $nu | $fu | $ge$rw | $ge$rc | $ge$rm |"
        s=$((s + 1))
    done
    echo "| $m | median | | | | | $(cut -d' ' -f4 "$tmp/sp" | median) | | | | | | $(cut -d' ' -f5 "$tmp/sp" | median) | | $(cut -d' ' -f1,2 "$tmp/sp" | median_bound) | $(awk '{ print $3, $2 }' "$tmp/sp" | median_bound) | $(awk '{ print $6, $2 }' "$tmp/sp" | median_bound) |"
}

if [ -z "$BENCH_EVOLVE_SKIP_SYNTH" ]; then
    write_models
    "$FREP" sample "$tmp/cube.hf" -n 65000 --seed 1 -o "$tmp/cube.xyz" -q || exit 1
    for m in m0 m1 m2; do
        "$FREP" sample "$tmp/$m.hf" -n 10000 --seed 1 --noise 0.01abs -o "$tmp/${m}_10k.xyz" -q || exit 1
        "$FREP" sample "$tmp/$m.hf" -n 150000 --seed 1 --noise 0.01abs -o "$tmp/${m}_150k.xyz" -q || exit 1
    done
    if [ -z "$BENCH_EVOLVE_SKIP_TABLE" ]; then
    echo
    echo "| model | points | primitives | GA | threads | time s | CPU s | nodes | explained |"
    echo "|---|---:|---:|---|---:|---:|---:|---:|---:|"
    : >"$tmp/walls"
    for mc in cube:cube m0:m0_10k m0:m0_150k m1:m1_10k m1:m1_150k m2:m2_10k m2:m2_150k; do
        for mode in --no-partition --partition; do
            for t in 1 2; do
                bench_row "${mc%%:*}" "${mc#*:}" "$mode" "$t"
            done
        done
    done
    echo
    echo "Wall time, 1 thread / 2 threads (medians above; > 1: the second thread helps):"
    echo
    echo "| cloud | GA | 1 thread s | 2 threads s | ratio |"
    echo "|---|---|---:|---:|---:|"
    awk '$3 == 1 { one[$1 " " $2] = $4 } $3 == 2 { two[$1 " " $2] = $4; k[++n] = $1 " " $2 }
         END { for (i = 1; i <= n; i++) { split(k[i], a, " ")
                   printf "| %s | %s | %s | %s | %.2f |\n", a[1], a[2], one[k[i]], two[k[i]],
                          (two[k[i]] > 0 ? one[k[i]] / two[k[i]] : 0) } }' "$tmp/walls"
    fi

    if [ -z "$BENCH_EVOLVE_SKIP_SPEEDUP" ]; then
        echo
        echo "Speed-up of partitioning: 1 thread, seeds 1-$SRUNS; unpartitioned GA run with"
        echo "--generations $SGENS --stagnation 0 --max-time $BUDGET; target = share of the merged clique trees - 1 point;"
        echo "shares of the scored sample (GA phases, before growth and simplification); final = every point."
        echo
        echo "| model | seed | part. s | part. CPU s | part. to merged s | part. GA share | part. nodes | part. final | unpart. to target s | CPU s | generations | unpart. best share | unpart. nodes | unpart. final | speed-up | speed-up CPU | speed-up to merged |"
        echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
        for mc in m0:m0_10k m2:m2_10k; do
            speedup_rows "${mc%%:*}" "${mc#*:}"
        done
    fi
fi

# ---- real data: InverseCSG's meshes ---------------------------------------------
if [ -z "$BENCH_EVOLVE_SKIP_REAL" ] && [ -d "$DATA" ]; then
    if ! /usr/bin/python3 -c 'import numpy, scipy' 2>/dev/null; then
        echo "real data: skipped (needs /usr/bin/python3 with numpy and scipy)"
        exit 0
    fi
    echo
    echo "Real data ($DATA): 20,000 points sampled from each mesh, segmented, evolved"
    echo "(seed 1, at most $MAXT s), meshed at -g 128; distances relative to the mesh diagonal;"
    echo "time: wall seconds of sample + segment + evolve, CPU: their user + system seconds."
    echo
    echo "| model | GT solids | GT surfaces | segmented | tree nodes | tree primitives | explained | time s | CPU s | Chamfer | Hausdorff |"
    echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    for d in "$DATA"/*/; do
        name=$(basename "$d")
        mesh="$d/csg_low_res.off"
        [ -f "$mesh" ] || mesh="$d/csg_high_res.off"
        [ -f "$mesh" ] || continue
        gts=-; gtp=-
        [ -f "$d/csg.scad" ] && gts=$(grep -o -E '\b(cube|cylinder|sphere)\s*\(' "$d/csg.scad" | wc -l)
        [ -f "$d/surface_primitives.prim" ] && gtp=$(grep -c -E '^(plane|sphere|cylinder|cone|torus)' "$d/surface_primitives.prim")
        t0=$(date +%s.%N)
        : >"$tmp/cpu"
        ok=1
        /usr/bin/time -a -o "$tmp/cpu" -f "%U %S" \
            "$FREP" sample "$mesh" -n 20000 --seed 1 -o "$tmp/r.xyz" -q 2>"$tmp/err" || ok=0
        [ $ok = 1 ] && { /usr/bin/time -a -o "$tmp/cpu" -f "%U %S" \
            "$FREP" segment "$tmp/r.xyz" -o "$tmp/r.fit" --seed 1 -q 2>"$tmp/err" || ok=0; }
        [ $ok = 1 ] && { /usr/bin/time -a -o "$tmp/cpu" -f "%U %S" "$FREP" evolve "$tmp/r.xyz" -p "$tmp/r.fit" -o "$tmp/r.hf" --seed 1 \
            --max-time "$MAXT" -q 2>"$tmp/err" || ok=0; }
        t1=$(date +%s.%N)
        [ $ok = 1 ] && { "$FREP" mesh "$tmp/r.hf" -o "$tmp/r.off" -g 128 -q 2>"$tmp/err" || ok=0; }
        if [ $ok = 0 ]; then
            echo "| $name | $gts | $gtp | - | - | - | - | - | - | failed: $(head -c 80 "$tmp/err" | tr '\n|' '  ') | |"
            continue
        fi
        nseg=$(grep -c . "$tmp/r.fit")
        nodes=$(sed -n 's/.*tree size \([0-9]*\) nodes, \([0-9]*\) primitives.*/\1/p' "$tmp/r.hf")
        nprim=$(sed -n 's/.*tree size \([0-9]*\) nodes, \([0-9]*\) primitives.*/\2/p' "$tmp/r.hf")
        expl=$(sed -n 's/.* \([0-9.]*\)% both$/\1/p' "$tmp/r.hf")
        secs=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }')
        cpu=$(awk '{ s += $1 + $2 } END { printf "%.1f", s }' "$tmp/cpu")
        dist=$(/usr/bin/python3 "$srcdir/bench/mesh_distance.py" "$mesh" "$tmp/r.off" 200000 2>/dev/null)
        ch=$(echo "$dist" | awk '{ printf "%.3f%%", 100 * $1 }')
        ha=$(echo "$dist" | awk '{ printf "%.2f%%", 100 * $2 }')
        echo "| $name | $gts | $gtp | $nseg | $nodes | $nprim | $expl% | $secs | $cpu | $ch | $ha |"
    done
fi
