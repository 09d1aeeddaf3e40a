#!/bin/sh
# doc/man.sh FREP - write the frep(1) manual page on standard output, made from the
# --help texts of the built frep (`frep --help` and `frep SUBCOMMAND --help`), so the
# page says what the program says. POSIX sh and awk; run by make (doc/frep.1).
set -eu
frep=$1

version=$("$frep" --version | sed 's/^frep //')
subs=$("$frep" --help | awk '/^Subcommands:/ { on = 1; next } on && /^  [a-z]/ { print $1 }')

# help2roff: one --help text -> man markup. Paragraphs are filled; "usage:" lines are
# kept as they are; each option of the "Options:" list becomes a tagged paragraph.
help2roff() {
    awk '
    function esc(s) { gsub(/\\/, "\\e", s); return s }
    function line(s) { s = esc(s); if (s ~ /^[.\047]/) s = "\\&" s; print s }
    function flush() { if (tag != "") { print ".TP"; t = esc(tag); gsub(/-/, "\\-", t);
                       print "\\fB" t "\\fR"; line(text) } tag = ""; text = "" }
    /^usage: / || (usage && /^       frep /) {
        if (!usage) print ".nf"; usage = 1; line($0); next }
    usage { print ".fi"; usage = 0 }
    /^Options:$/ { print ".PP"; print ".B Options"; opts = 1; next }
    opts && /^  (-[a-zA-Z0-9], )?--[a-z]/ || opts && /^      --[a-z]/ {
        flush(); s = $0; sub(/^ +/, "", s)
        if (match(s, /   */)) { tag = substr(s, 1, RSTART - 1); text = substr(s, RSTART + RLENGTH) }
        else { tag = s; text = "" }
        next }
    opts && /^   / { s = $0; sub(/^ +/, "", s); text = text " " s; next }
    /^$/ { flush(); print ".PP"; next }
    { flush(); line($0) }
    END { flush(); if (usage) print ".fi" }'
}

cat <<EOF
.TH FREP 1 "" "frep $version" "User Commands"
.SH NAME
frep \\- function-representation (FRep) modeling with HyperFun models
.SH SYNOPSIS
.B frep
.I SUBCOMMAND
[\\fIoptions\\fR] [\\fIargs\\fR]
.br
.B frep
.I SUBCOMMAND
.B \\-\\-help
.br
.B frep \\-\\-version
.SH DESCRIPTION
EOF
"$frep" --help | awk '
    function esc(s) { gsub(/\\/, "\\e", s); if (s ~ /^[.\047]/) s = "\\&" s; return s }
    /^Subcommands:/ { print ".SS Subcommands"; on = 1; next }
    on && /^  [a-z]/ { name = $1; s = $0; sub(/^  [a-z]+ +/, "", s)
                       print ".TP"; print "\\fB" name "\\fR"; print esc(s); next }
    on && /^$/ { on = 0; print ".PP"; next }
    /^usage: / || /^$/ { next }
    { print esc($0) }'
echo ".SH SUBCOMMANDS"
for s in $subs; do
    echo ".SS \"frep $s\""
    "$frep" "$s" --help | help2roff
done
cat <<EOF
.SH EXIT STATUS
0 on success, 1 when the job failed (errors in the model, bad data), 2 for a bad
command line; frep fit exits with 130 when interrupted by Ctrl-C.
.SH SEE ALSO
The documents in doc/ of the frep sources: architecture.md, fit.md, segment.md.
EOF
