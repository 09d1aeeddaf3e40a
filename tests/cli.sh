#!/bin/sh
# cli.sh - the frep command's option layer (cli/opt.c) and its man page: every
# subcommand's --help, every listed option known to the parser, the shared messages of
# bad values (one thread-count and one seed parser for all), usage errors exit 2, and
# doc/frep.1 made from the help texts listing every subcommand and option. Prints TAP.
# Needs FREP and builddir.

: "${FREP:?FREP must name the frep binary}"
: "${builddir:?builddir must name the build tree}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-cli.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM

. "$(dirname "$0")/tap.sh"
# usage WANT-STDERR-LINE ARGS...: exit status 2, the message, then the hint to --help
usage() {
    want=$1; shift
    "$FREP" "$@" >"$tmp/out" 2>"$tmp/err"
    st=$?
    sub=$1
    printf '%s\nTry '\''frep %s --help'\''.\n' "$want" "$sub" >"$tmp/want"
    [ $st = 2 ] && cmp -s "$tmp/want" "$tmp/err" && [ ! -s "$tmp/out" ]
    r=$?
    [ $r = 0 ] || sed 's/^/# /' "$tmp/err"
    report $r "frep $*: exit 2, '$want'"
}

subs=$("$FREP" --help | awk '/^Subcommands:/ { on = 1; next } on && /^  [a-z]/ { print $1 }')
[ "$(echo $subs)" = "check eval print dis mesh sample fit render view normals segment evolve export" ]
report $? "frep --help lists the thirteen subcommands"

for s in $subs; do
    "$FREP" "$s" --help >"$tmp/help" 2>"$tmp/err"
    st=$?
    [ $st = 0 ] && [ ! -s "$tmp/err" ] && head -n 1 "$tmp/help" | grep -q "^usage: frep $s "
    report $? "frep $s --help: usage on stdout, exit 0"
    "$FREP" "$s" -h >"$tmp/h" 2>&1
    cmp -s "$tmp/help" "$tmp/h"
    report $? "frep $s -h is --help"
    # Every option the help lists is one the parser knows (both come from one table).
    opts=$(awk '/^Options:$/ { on = 1; next }
                on && /^  (-[a-zA-Z0-9], )?--[a-z]/ || on && /^      --[a-z]/ {
                    for (i = 1; i <= NF; i++) if ($i ~ /^-/) { o = $i; sub(/,$/, "", o); print o } }' \
           "$tmp/help")
    bad=0
    for o in $opts; do
        "$FREP" "$s" "$o" >/dev/null 2>"$tmp/err"
        st=$?
        if [ $st != 2 ] || grep -q "unknown option" "$tmp/err"; then
            echo "# frep $s $o: exit $st: $(head -n 1 "$tmp/err")"
            bad=1
        fi
    done
    report $bad "frep $s: the $(echo $opts | wc -w) listed options are known"
done

M="${srcdir:-.}/tests/models/block_minus_ball.hf"
usage "frep mesh: unknown option '--bogus'" mesh "$M" --bogus -o "$tmp/x.stl"
usage "frep mesh: unknown option '-Z'" mesh "$M" -Z -o "$tmp/x.stl"
usage "frep mesh: option '--output' needs a value" mesh "$M" --output
usage "frep eval: option '-m' needs a value" eval "$M" -m
usage "frep mesh: -g: expected grid cells per axis in 1..2048, got '0'" mesh "$M" -g 0 -o "$tmp/x.stl"
usage "frep mesh: --grid: expected grid cells per axis in 1..2048, got '4096' (the mesh would not fit in memory)" \
    mesh "$M" --grid 4096 -o "$tmp/x.stl"
for s in mesh sample render view eval fit segment evolve; do
    usage "frep $s: -t: expected an integer in 1..1024, got '0'" $s "$M" -t 0
    usage "frep $s: --threads: expected an integer in 1..1024, got '2.5'" $s "$M" --threads 2.5
done
for s in sample fit segment evolve; do
    usage "frep $s: --seed: expected a non-negative integer, got '-1'" $s "$M" --seed -1
    usage "frep $s: --seed: expected a non-negative integer, got ''" $s "$M" --seed ''
done
usage "frep fit: --loss-scale: expected a number > 0, got '0'" fit "$M" "$M" --loss-scale 0
usage "frep fit: --method: expected saqn, qn, sa or lm, got 'x'" fit "$M" "$M" --method x
usage "frep fit: -a: expected comma-separated numbers, got '1,,2'" fit "$M" "$M" -a 1,,2
usage "frep mesh: -b: the box has no extent along x: [1, 1]" mesh "$M" -b 1,1 -o "$tmp/x.stl"
usage "frep eval: -b is only for --grid" eval "$M" -b 1
usage "frep segment: --types: unknown primitive type 'cube' (expected plane, sphere, cylinder, cone, torus)" \
    segment "$M" --types plane,cube
usage "frep evolve: --crossover: expected a number in [0, 1], got '2'" evolve "$M" --crossover 2
usage "frep evolve: --generations: expected an integer in 1..1000000000, got '1e10'" evolve "$M" --generations 1e10
usage "frep render: --size: expected WxH with sides 1..16384, got '0x3'" render "$M" --size 0x3 -o "$tmp/x.png"
usage "frep check: unknown option '-m'" check -m x "$M"

# hfp's options (HyperFun's polygonizer): translated, or refused naming what to use.
B="-b 1 -g 8 -q"
usage "frep mesh: -o my_model: frep's -o is the output file; my_model is a model in $M: did you mean -m my_model?" \
    mesh "$M" -o my_model
usage "frep mesh: hfp's -cl is the wireframe colour of its viewer; frep mesh draws nothing (see the mesh with frep view)" \
    mesh "$M" -cl 255,0,0 -stl "$tmp/x.stl"
usage "frep mesh: hfp's -pov output (POV-Ray mesh) is not a format frep writes: use -o FILE.stl, .obj, .ply, .off or .wrl" \
    mesh "$M" -pov "$tmp/x.pov"
usage "frep mesh: hfp's -stl needs a file name" mesh "$M" -stl
usage "frep mesh: -x X,Z,Y: frep meshes x[1], x[2], x[3] as x, y, z and reads x[4..] as 0; other mappings are not supported" \
    mesh "$M" -x X,Z,Y -o "$tmp/x.stl"
usage "frep mesh: hfp's -d sets its viewer's display mode; frep mesh has no viewer (frep view shows a mesh)" \
    mesh "$M" -d 5 -o "$tmp/x.stl"
usage "frep mesh: -o $tmp/y.stl: the output is already '$tmp/x.stl'" mesh "$M" -stl "$tmp/x.stl" -o "$tmp/y.stl"
usage "frep mesh: --color: expected model, none, V or R,G,B with each in 0..255, got '255,0'" mesh "$M" -cf 255,0 -o "$tmp/x.ply"
usage "frep mesh: --color: expected model, none, V or R,G,B with each in 0..255, got '256'" mesh "$M" --color 256 -o "$tmp/x.ply"
usage "frep mesh: --color: STL files carry no colours (use .ply or .wrl)" mesh "$M" -ct -o "$tmp/x.stl"
usage "frep mesh: --color: STL files carry no colours (use .ply or .wrl)" mesh "$M" --color 9 -o "$tmp/x.stl"
"$FREP" mesh "$M" $B -stl "$tmp/a.stl" && head -c 5 "$tmp/a.stl" | grep -q '^solid'
report $? "frep mesh -stl FILE writes text STL to FILE"
"$FREP" mesh "$M" $B -stlb "$tmp/b.stl" && ! head -c 5 "$tmp/b.stl" | grep -q '^solid' &&
    [ "$(wc -c < "$tmp/b.stl")" -gt 84 ]
report $? "frep mesh -stlb FILE writes binary STL to FILE"
"$FREP" mesh "$M" $B -wrl "$tmp/c.wrl" && head -n 1 "$tmp/c.wrl" | grep -q '^#VRML V2.0 utf8$' &&
    grep -q 'IndexedFaceSet' "$tmp/c.wrl" && grep -q 'diffuseColor 0.196078 0.784314 0.313725' "$tmp/c.wrl"
report $? "frep mesh -wrl FILE writes VRML 2.0 with hfp's default face colour"
"$FREP" mesh "$M" $B -o "$tmp/c2.wrl" && cmp -s "$tmp/c.wrl" "$tmp/c2.wrl"
report $? "frep mesh -o FILE.wrl is -wrl FILE"
# the VRML faces are the OFF faces, the points the OFF points (same mesh, same order)
"$FREP" mesh "$M" $B -o "$tmp/c.off" &&
    awk 'NR > 2 && NF == 4 { print $2 ", " $3 ", " $4 ", -1," }' "$tmp/c.off" > "$tmp/off.f" &&
    awk '/coordIndex/ { on = 1; next } on && /\]/ { on = 0 } on { $1 = $1; print }' "$tmp/c.wrl" > "$tmp/wrl.f" &&
    [ -s "$tmp/off.f" ] && cmp -s "$tmp/off.f" "$tmp/wrl.f"
report $? "frep mesh -wrl: coordIndex lists the mesh's triangles"
"$FREP" mesh "$M" $B -cf 255,16,0 --ascii -o "$tmp/d.ply" &&
    grep -q '^property uchar red$' "$tmp/d.ply" &&
    awk '/^end_header/ { on = 1; next } on && NF == 9 { n++; if ($7 != 255 || $8 != 16 || $9 != 0) bad = 1 }
         END { exit !(n > 0 && !bad) }' "$tmp/d.ply"
report $? "frep mesh -cf 255,16,0 colours every PLY vertex"
"$FREP" mesh "$M" $B --color 51 -o "$tmp/e.wrl" && grep -q 'colorPerVertex TRUE' "$tmp/e.wrl" &&
    ! grep -q diffuseColor "$tmp/e.wrl" && grep -q '^        0.2 0.2 0.2,$' "$tmp/e.wrl"
report $? "frep mesh --color 51 gives the VRML vertices grey 0.2"
# The model's own colours (s[1..3] of color_sphere.hf, hfA_SetColor where f >= 0):
# every vertex's against the formulas at the sphere point nearest it, within one
# count (the colours are taken a thousandth of a cell inside the surface); the
# clamping below 0 and above 1 must show.
C="${srcdir:-.}/tests/models/color_sphere.hf"
colors_ok() { # colors_ok FILE.ply: every vertex coloured as color_sphere.hf says
    awk -v R=0.8 '
        function cl(v) { return v < 0 ? 0 : v > 1 ? 255 : int(v * 255 + 0.5) }
        function ad(a, b) { return a > b ? a - b : b - a }
        /^element vertex/ { nv = $3 }
        body && nv > 0 {
            nv--; n++
            k = R / sqrt($1 * $1 + $2 * $2 + $3 * $3); x = $1 * k; y = $2 * k; z = $3 * k
            if (ad($7, cl((x + 1) / 2)) > 1 || ad($8, cl(y * y)) > 1 || ad($9, cl(1.5 * z)) > 1) bad++
            if ($9 == 0) lo++
            if ($9 == 255) hi++
        }
        /^end_header/ { body = 1 }
        END { if (bad) print "# " bad " of " n " vertices coloured wrong"
              exit !(n > 100 && !bad && lo > 0 && hi > 0) }' "$1"
}
"$FREP" mesh "$C" -b 1 -g 16 -q --ascii -o "$tmp/s.ply" && colors_ok "$tmp/s.ply"
report $? "frep mesh: PLY vertex colours from the model's s[1..3] (hfA_SetColor), clamped"
"$FREP" mesh "$C" -b 1 -g 23 -q --ascii -ct -o "$tmp/s2.ply" && colors_ok "$tmp/s2.ply"
report $? "frep mesh -ct (--color model): the same at another grid"
"$FREP" mesh "$C" -b 1 -g 16 -q --ascii --color 255,16,0 -o "$tmp/s3.ply" &&
    awk '/^end_header/ { on = 1; next } on && NF == 9 { n++; if ($7 != 255 || $8 != 16 || $9 != 0) bad = 1 }
         END { exit !(n > 0 && !bad) }' "$tmp/s3.ply"
report $? "frep mesh --color R,G,B overrides the model's colours"
"$FREP" mesh "$C" -b 1 -g 16 -q --ascii --color none -o "$tmp/s4.ply" &&
    ! grep -q 'property uchar red' "$tmp/s4.ply"
report $? "frep mesh --color none: no colours"
"$FREP" mesh "$C" -b 1 -g 16 -q -o "$tmp/s.wrl" && grep -q 'colorPerVertex TRUE' "$tmp/s.wrl" &&
    ! grep -q diffuseColor "$tmp/s.wrl"
report $? "frep mesh: VRML Color from the model's s[1..3]"
"$FREP" mesh "$C" -b 1 -g 16 -q -o "$tmp/s.stl"
report $? "frep mesh: a model with colours still writes STL (no colours)"
"$FREP" mesh "$M" $B --ascii -o "$tmp/s5.ply" && ! grep -q 'property uchar red' "$tmp/s5.ply"
report $? "frep mesh: a model without s[] gets no colours"
"$FREP" mesh "$M" $B --color model -o "$tmp/s6.ply" 2>"$tmp/err"
[ $? = 1 ] && grep -q 'has 0 attributes; colours need s\[1..3\]' "$tmp/err" && [ ! -e "$tmp/s6.ply" ]
report $? "frep mesh --color model without s[1..3]: an error, no file"

# --strict on every command that compiles a model: frep's own rUnion is accepted
# without it (the command works) and an error "not HyperFun" with it (exit 1, no output).
cat > "$tmp/ext.hf" <<'EOF2'
my_model(x[3], a[1]) {
  r = 0.8;  -- @free [0.1, 1.5]
  my_model = rUnion(r*r - x[1]*x[1] - x[2]*x[2] - x[3]*x[3], -1);
}
EOF2
"$FREP" sample "$tmp/ext.hf" -b 1 -n 200 --seed 1 -q -o "$tmp/ext.xyz" 2>/dev/null
report $? "frep sample of a model with frep's rUnion works without --strict"
strict() { # strict NAME OUT ARGS...: works without --strict, fails with it, OUT not written
    name=$1 out=$2; shift 2
    rm -f "$out"
    "$FREP" "$@" >/dev/null 2>"$tmp/err" && rm -f "$out" && ! "$FREP" "$@" --strict >"$tmp/out" 2>"$tmp/err"
    st=$?
    [ $st = 0 ] && grep -q "error: not HyperFun: 'rUnion'" "$tmp/err" && [ ! -e "$out" ] &&
        { [ "$out" = "$tmp/out" ] || [ ! -s "$tmp/out" ]; }
    r=$?
    [ $r = 0 ] || sed 's/^/# /' "$tmp/err"
    report $r "frep $name --strict: HyperFun's rejections are errors"
}
echo "0 0 0" > "$tmp/pt"
strict eval "$tmp/none" eval "$tmp/ext.hf" "$tmp/pt"
strict mesh "$tmp/st.stl" mesh "$tmp/ext.hf" -b 1 -g 8 -q -o "$tmp/st.stl"
strict sample "$tmp/st.xyz" sample "$tmp/ext.hf" -b 1 -n 50 --seed 1 -q -o "$tmp/st.xyz"
strict render "$tmp/st.png" render "$tmp/ext.hf" -b 1 -g 16 --size 16x16 -q -o "$tmp/st.png"
strict view "$tmp/st.html" view "$tmp/ext.hf" -b 1 -g 8 -q -o "$tmp/st.html"
strict fit "$tmp/st.hf" fit "$tmp/ext.hf" "$tmp/ext.xyz" --seed 1 -q -o "$tmp/st.hf"
strict dis "$tmp/none" dis "$tmp/ext.hf"
strict check "$tmp/none" check "$tmp/ext.hf"
"$FREP" print "$tmp/ext.hf" > "$tmp/out" 2>"$tmp/err" && grep -q rUnion "$tmp/out" &&
    ! "$FREP" print --strict "$tmp/ext.hf" > "$tmp/out" 2>"$tmp/err" && [ ! -s "$tmp/out" ] &&
    grep -q "error: not HyperFun: 'rUnion'" "$tmp/err"
report $? "frep print --strict: checks first, prints nothing on errors"
"$FREP" mesh "$M" -b 1 -g 8 -t -x X,Y,Z -i 0.01 -o "$tmp/f.stl" > "$tmp/out" &&
    "$FREP" mesh "$M" -b 1 -g 8 --iso 0.01 -o "$tmp/g.stl" > /dev/null && cmp -s "$tmp/f.stl" "$tmp/g.stl" &&
    grep -q 's$' "$tmp/out"
report $? "hfp's -t (time report), -x X,Y,Z and -i V are accepted; -i is --iso"
# hfp's per-axis grid: a unit cube in -b 1 -g 4,4,8 (cells 0.5 x 0.5 x 0.25) is meshed
# closed, and its face vertices sit at the cells' centres (to 1e-3; edges a 1e-4 cell
# outside): x and y in {+-0.25, +-0.5},
# z in {+-0.125, +-0.375, +-0.5}.
printf 'my_model(x[3], a[1])\n{\n  my_model = min(min(0.5 - abs(x[1]), 0.5 - abs(x[2])), 0.5 - abs(x[3]));\n}\n' \
    > "$tmp/cube.hf"
"$FREP" mesh "$tmp/cube.hf" -b 1 -g 4,4,8 --check -o "$tmp/h.off" > "$tmp/out" &&
    grep -q ', grid 4,4,8, ' "$tmp/out" &&
    [ "$(awk 'NR > 2 && NF == 3 { printf "%.3f\n", $1 }' "$tmp/h.off" | sort -u | tr '\n' ' ')" = \
      "-0.250 -0.500 0.250 0.500 " ] &&
    [ "$(awk 'NR > 2 && NF == 3 { printf "%.3f\n", $3 }' "$tmp/h.off" | sort -u | tr '\n' ' ')" = \
      "-0.125 -0.375 -0.500 0.125 0.375 0.500 " ]
report $? "frep mesh -g 4,4,8: a closed cube, cells of 0.5 along x and y and 0.25 along z"
"$FREP" mesh "$tmp/cube.hf" -b 1 -g 4,4,4 -q -o "$tmp/i.off" && "$FREP" mesh "$tmp/cube.hf" -b 1 -g 4 -q -o "$tmp/j.off" &&
    cmp -s "$tmp/i.off" "$tmp/j.off" && ! cmp -s "$tmp/h.off" "$tmp/i.off"
report $? "frep mesh -g 4,4,4 is -g 4; -g 4,4,8 differs"
usage "frep mesh: -g 4,4: expected N or NX,NY,NZ with each in 1..2048" mesh "$M" -g 4,4 -o "$tmp/x.stl"

# A data file that cannot be read: "frep SUB: cannot read FILE: reason", exit 1, the
# same style whether the command reads it itself or through the library (fit, render).
for c in "fit $M $tmp/none.xyz -o $tmp/none.hf" "render $M --points $tmp/none.xyz -o $tmp/none.png" \
         "segment $tmp/none.xyz" "normals $tmp/none.xyz -o $tmp/none.ply"; do
    sub=${c%% *}
    # shellcheck disable=SC2086
    "$FREP" $c >/dev/null 2>"$tmp/err"
    st=$?
    [ $st = 1 ] && [ "$(head -n 1 "$tmp/err")" = "frep $sub: cannot read $tmp/none.xyz: No such file or directory" ]
    report $? "frep $sub with a missing cloud: exit $st, '$(head -n 1 "$tmp/err")'"
done

# The man page: made by make from the help texts, every subcommand and option in it.
man="$builddir/doc/frep.1"
[ -s "$man" ] && head -n 1 "$man" | grep -q '^\.TH FREP 1 '
report $? "doc/frep.1 is made"
bad=0
for s in $subs; do
    grep -q "^\.SS \"frep $s\"$" "$man" || { echo "# no section for frep $s"; bad=1; }
    for o in $("$FREP" "$s" --help | grep -o -- '--[a-z][a-z-]*' | sort -u); do
        grep -q -- "$(echo "$o" | sed 's/-/\\\\-/g')" "$man" || { echo "# frep $s: no $o"; bad=1; }
    done
done
report $bad "doc/frep.1 has every subcommand and every option"
if command -v groff >/dev/null 2>&1; then
    groff -man -Tutf8 -ww "$man" 2>"$tmp/err" >/dev/null && [ ! -s "$tmp/err" ]
    report $? "doc/frep.1 formats without warnings"
fi

tap_done
