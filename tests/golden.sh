#!/bin/sh
# golden.sh - golden language tests: for every tests/lang/AREA/NAME.hf, run
# `frep check NAME.hf` from the file's directory and compare its standard error with
# NAME.err (whole diagnostics: message, source line, caret) or, without NAME.err,
# expect a clean check; where NAME.strict.err exists, compare `frep check --strict`
# with it (and expect failure); where NAME.print exists, compare `frep print NAME.hf` with it;
# for every tests/dis/NAME.hf compare `frep dis NAME.hf` with NAME.dis; and check
# that every message of lang/check.c appears in some NAME.err.  Areas: syntax
# (lexer, parser), names, calls, arrays, conditions, pragmas (lang/check.c),
# lowering and limits (lang/lower.c, library expansions).
# Prints TAP.  Needs FREP (the frep binary) and srcdir (the source tree).
# To refresh an expectation after a deliberate change: run the same command in the
# file's directory and review the difference before committing it.

: "${FREP:?FREP must name the frep binary}"
: "${srcdir:?srcdir must name the source tree}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-golden.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM

n=0
failed=0

report() { # report OK DESCRIPTION
    n=$((n + 1))
    if [ "$1" = 0 ]; then
        echo "ok $n - $2"
    else
        echo "not ok $n - $2"
        failed=1
    fi
}

show_diff() { # show_diff EXPECTED ACTUAL: as TAP comments
    diff -u "$1" "$2" | sed 's/^/# /'
}

for hf in "$srcdir"/tests/lang/*/*.hf; do
    [ -e "$hf" ] || continue
    dir=$(dirname "$hf")
    name=$(basename "$hf" .hf)
    area=$(basename "$dir")

    # frep check: diagnostics and exit status
    (cd "$dir" && "$FREP" check "$name.hf" >/dev/null 2>"$tmp/err")
    status=$?
    if [ -f "$dir/$name.err" ]; then
        expected="$dir/$name.err"
        # a file with an error must fail; one with warnings only must pass
        if grep -q ': error: ' "$expected"; then want_fail=1; else want_fail=0; fi
    else
        : >"$tmp/empty"
        expected="$tmp/empty"
        want_fail=0
    fi
    if cmp -s "$expected" "$tmp/err"; then same=0; else same=1; fi
    if [ "$want_fail" = 1 ]; then
        [ "$status" -ne 0 ] && [ "$status" -lt 128 ]; st=$?
    else
        [ "$status" -eq 0 ]; st=$?
    fi
    if [ "$same" = 0 ] && [ "$st" = 0 ]; then
        report 0 "$area/$name: check"
    else
        report 1 "$area/$name: check (exit status $status)"
        show_diff "$expected" "$tmp/err"
    fi

    # frep check --strict: what HyperFun rejects is an error
    if [ -f "$dir/$name.strict.err" ]; then
        (cd "$dir" && "$FREP" check --strict "$name.hf" >/dev/null 2>"$tmp/err")
        status=$?
        if cmp -s "$dir/$name.strict.err" "$tmp/err" && [ "$status" -eq 1 ]; then
            report 0 "$area/$name: check --strict"
        else
            report 1 "$area/$name: check --strict (exit status $status)"
            show_diff "$dir/$name.strict.err" "$tmp/err"
        fi
    fi

    # frep print: the canonical source
    if [ -f "$dir/$name.print" ]; then
        (cd "$dir" && "$FREP" print "$name.hf" >"$tmp/out" 2>/dev/null)
        status=$?
        if [ "$status" = 0 ] && cmp -s "$dir/$name.print" "$tmp/out"; then
            report 0 "$area/$name: print"
        else
            report 1 "$area/$name: print (exit status $status)"
            show_diff "$dir/$name.print" "$tmp/out"
        fi
        # printing the printed source again changes nothing
        cp "$tmp/out" "$tmp/again.hf"
        (cd "$tmp" && "$FREP" print again.hf >"$tmp/out2" 2>/dev/null)
        if cmp -s "$tmp/out" "$tmp/out2"; then
            report 0 "$area/$name: print is a fixed point"
        else
            report 1 "$area/$name: print is a fixed point"
            show_diff "$tmp/out" "$tmp/out2"
        fi
    fi
done

# frep dis: disassembly goldens pin what the compiler emits
for hf in "$srcdir"/tests/dis/*.hf; do
    [ -e "$hf" ] || continue
    dir=$(dirname "$hf")
    name=$(basename "$hf" .hf)
    (cd "$dir" && "$FREP" dis "$name.hf" >"$tmp/dis" 2>"$tmp/err")
    status=$?
    if [ "$status" = 0 ] && cmp -s "$dir/$name.dis" "$tmp/dis"; then
        report 0 "dis/$name: disassembly"
    else
        report 1 "dis/$name: disassembly (exit status $status)"
        show_diff "$dir/$name.dis" "$tmp/dis"
        sed 's/^/# /' "$tmp/err"
    fi
done

# frep print writes what reads back unchanged: for every model that compiles (the
# goldens above, the disassembly goldens and the examples), compile the printed source
# and compare its disassembly with the original's, position comments and the file
# name aside.  The disassembly writes every constant with %.17g, so equal listings
# mean equal doubles; and no printed number has an exponent starting with 0, which
# the reference interpreter's scanner rejects (int_scanner.c of HyperFun).
strip_dis() { sed 's/;.*$//; s/[[:space:]]*$//' "$1"; }
for hf in "$srcdir"/tests/lang/*/*.hf "$srcdir"/tests/dis/*.hf "$srcdir"/examples/*.hf \
          "$srcdir"/examples/*/*.hf; do
    [ -e "$hf" ] || continue
    dir=$(dirname "$hf")
    name=$(basename "$hf" .hf)
    (cd "$dir" && "$FREP" dis "$name.hf" >"$tmp/dis1" 2>/dev/null) || continue
    (cd "$dir" && "$FREP" print "$name.hf" >"$tmp/printed.hf" 2>/dev/null)
    (cd "$tmp" && "$FREP" dis printed.hf >"$tmp/dis2" 2>/dev/null)
    strip_dis "$tmp/dis1" >"$tmp/dis1s"
    strip_dis "$tmp/dis2" >"$tmp/dis2s"
    rel=${hf#"$srcdir"/}
    if cmp -s "$tmp/dis1s" "$tmp/dis2s" &&
       ! grep -v -e '^[[:space:]]*--' "$tmp/printed.hf" | grep -Eq '[0-9.][eE][-+]?0[0-9]'; then
        report 0 "$rel: printed source compiles to the same program"
    else
        report 1 "$rel: printed source compiles to the same program"
        diff -u "$tmp/dis1s" "$tmp/dis2s" | sed 's/^/# /'
        grep -En '[0-9.][eE][-+]?0[0-9]' "$tmp/printed.hf" | sed 's/^/# exponent: /'
    fi
done

# Every message of the checker is pinned by a golden: each string literal of
# lang/check.c that holds a space (the messages and the parts they are built from)
# must have its longest piece between printf directives in some tests/lang .err.
grep -o '"[^"]*"' "$srcdir/lang/check.c" | grep ' ' | sed 's/^"//; s/"$//' |
while IFS= read -r lit; do
    piece=$(printf '%s\n' "$lit" | sed 's/%[a-z]*/\
/g' | awk '{ if (length($0) > length(best)) best = $0 } END { print best }')
    if ! cat "$srcdir"/tests/lang/*/*.err | grep -qF -e "$piece"; then
        echo "$lit"
    fi
done >"$tmp/unpinned"
if [ -s "$tmp/unpinned" ]; then
    report 1 "every message of lang/check.c has a golden"
    sed 's/^/# no golden shows: /' "$tmp/unpinned"
else
    report 0 "every message of lang/check.c has a golden"
fi

echo "1..$n"
exit $failed
