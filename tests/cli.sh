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

n=0
failed=0
report() { # report STATUS DESCRIPTION
    n=$((n + 1))
    if [ "$1" = 0 ]; then echo "ok $n - $2"; else echo "not ok $n - $2"; failed=1; fi
}
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
[ "$(echo $subs)" = "check eval print dis mesh sample fit render view segment evolve export" ]
report $? "frep --help lists the twelve subcommands"

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

echo "1..$n"
exit $failed
