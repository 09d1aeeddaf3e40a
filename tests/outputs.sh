#!/bin/sh
# tests/outputs.sh - write what every subcommand outputs on the examples (and on a few
# shared CAD models when ../shared/data is there) into a folder, with a SHA-256 list.
# A refactoring that must not change behaviour runs it before and after and compares:
#   sh tests/outputs.sh build/frep /tmp/before; ...; sh tests/outputs.sh build/frep /tmp/after
#   diff /tmp/before/SHA256SUMS /tmp/after/SHA256SUMS
# Not part of make check: it pins no result, it only compares two builds.
set -u
frep=$(cd "$(dirname "$1")" && pwd)/$(basename "$1"); out=$2
src=$(cd "$(dirname "$0")/.." && pwd)
data=${FREP_DATA:-$src/../shared/data}
rm -rf "$out"; mkdir -p "$out"; cd "$out" || exit 1

# run NAME CMD...: stdout, stderr (timing lines dropped) and exit status of one command
run() {
    name=$1; shift
    "$@" >"$name.out" 2>"$name.err"; echo "$?" >"$name.rc"
}

for m in "$src"/examples/*.hf "$src"/examples/reverse/*.hf "$src"/tests/models/*.hf; do
    b=$(basename "$m" .hf)
    run "$b.check" "$frep" check "$m"
    run "$b.print" "$frep" print "$m"
    run "$b.dis" "$frep" dis "$m"
    run "$b.grid" "$frep" eval "$m" --grid 41 -b 2 -t 1
    run "$b.mesh" "$frep" mesh "$m" -g 40 -b 2 -t 1 -o "$b.stl"
    run "$b.meshobj" "$frep" mesh "$m" -g 24 -b 2 -t 1 -o "$b.obj"
    run "$b.meshply" "$frep" mesh "$m" -g 24 -b 2 -t 1 -o "$b.ply"
    run "$b.meshoff" "$frep" mesh "$m" -g 24 -b 2 -t 1 --check -o "$b.off"
    run "$b.sample" "$frep" sample "$m" -n 3000 -b 2 --seed 3 --noise 0.002 -t 1 -o "$b.xyz"
    run "$b.render" "$frep" render "$m" -b 2 -g 32 -t 1 -o "$b.png"
    run "$b.evalpts" "$frep" eval "$m" "$b.xyz" --grad
done
run sample_mesh "$frep" sample csg.off -n 2000 --seed 2 -o csg_from_mesh.xyz
run render_pts "$frep" render "$src/examples/csg.hf" -b 2 -g 32 --points csg.xyz -o csg_pts.png

for t in part part_a sakepot; do
    truth="$src/examples/fit/${t%_a}_truth.hf"
    [ -f "$truth" ] || truth="$src/examples/fit/part_truth.hf"
    run "fit_$t.sample" "$frep" sample "$truth" -n 4000 --seed 5 --noise 0.001 -o "fit_$t.xyz"
    run "fit_$t" "$frep" fit "$src/examples/fit/$t.hf" "fit_$t.xyz" --seed 2 -t 2 \
        -o "fit_$t.fitted.hf" --json "fit_$t.json"
done

for m in segment_box segment_cylinder segment_torus; do
    run "seg_$m" "$frep" segment "$m.xyz" --seed 4 -t 2 -o "seg_$m.hf"
    run "segfit_$m" "$frep" segment "$m.xyz" --seed 4 -t 1 -o "seg_$m.fit"
done
run rev.sample "$frep" sample "$src/examples/reverse/part.hf" -n 20000 --noise 0.001 --seed 1 -o rev.xyz
run rev.evolve "$frep" evolve rev.xyz --seed 1 -t 2 -o rev_model.hf
run rev.evolve_t1 "$frep" evolve rev.xyz --seed 1 -t 1 -o rev_model_t1.hf
run rev.evolve_rf "$frep" evolve rev.xyz --seed 2 --setops rfunc -t 2 -o rev_model_rf.hf
run rev.mesh "$frep" mesh rev_model.hf -g 48 -o rev_model.stl

if [ -d "$data/inversecsg" ]; then
    for m in one_cylinder two_cuboids_one_cylinder mount 096; do
        d="$data/inversecsg/$m"
        [ -f "$d/csg_low_res.off" ] || continue
        run "real_$m.sample" "$frep" sample "$d/csg_low_res.off" -n 10000 --seed 1 -o "real_$m.xyz"
        run "real_$m.seg" "$frep" segment "real_$m.xyz" --seed 1 -t 2 -o "real_$m.fit"
        run "real_$m.evolve" "$frep" evolve "real_$m.xyz" --seed 1 -t 2 -o "real_$m.hf"
    done
fi
if [ -f "$data/fayolle_fit_example/example.fit" ]; then
    run fayolle "$frep" segment --help
fi
rm -f ./*.tmp*
# wall/CPU times and rates vary between runs; everything else must not
for f in *.out *.err *.hf *.json; do
    sed -i -E -e 's/[0-9][0-9.e+-]* ?(s|ms|million points\/s|M points\/s|points\/s|evals\/s)\b/T/g' \
        -e 's/"(seconds|cpu_seconds|wall_seconds)": [0-9.e+-]+/"\1": T/g' "$f"
done
sha256sum -- * | grep -v ' SHA256SUMS$' >SHA256SUMS
echo "outputs: $(wc -l <SHA256SUMS) files in $out"
