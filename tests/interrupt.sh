#!/bin/sh
# interrupt.sh - nothing lost, nothing hangs: Ctrl-C (SIGINT), SIGTERM and SIGHUP in
# each phase of the long commands (segment, evolve's segmentation, GAs, simplification,
# merge, refit and writing, normals, mesh, render, sample, fit) with the latency
# measured from the signal to the exit; a second signal
# aborts at once; the temporary file of a write is removed; write errors (a full
# disk: /dev/full, a file size limit, a full tmpfs when one can be mounted) are
# reported with their reason; loops that used to hang end; the evaluation work budget
# (--max-work) stops long model loops with a clear error. Prints TAP.
# Needs FREP (the frep binary) and srcdir (the source tree).

: "${FREP:?FREP must name the frep binary}"
: "${srcdir:?srcdir must name the source tree}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-interrupt.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM
EX="$srcdir/examples"

# The promise of doc/architecture.md ("Interrupts"): every phase polls the flag at
# least every 0.1 s of work, so a signal is answered within a second of an idle
# machine; on a loaded one the limit grows with the load per processor.
ncpu=$(getconf _NPROCESSORS_ONLN 2>/dev/null || echo 1)
MAX_LATENCY=$(awk -v l="$(cut -d' ' -f1 /proc/loadavg 2>/dev/null || echo 0)" -v c="$ncpu" \
    -v m="${INTERRUPT_MAX_LATENCY:-1.0}" 'BEGIN { f = l / c; printf "%.2f", m * (f > 1 ? f : 1) }')
# The 1 s of processor time is the promise for a plain build; AddressSanitizer runs the
# same work about three times slower, so under it the limits are three times larger.
MAX_CPU=1.0
if grep -q __asan_init "$FREP" 2>/dev/null; then
    MAX_CPU=3.0
    MAX_LATENCY=$(awk -v m="$MAX_LATENCY" 'BEGIN { printf "%.2f", 3 * m }')
fi
echo "# latency limit $MAX_LATENCY s, $MAX_CPU s of processor time (1 s x the load per processor, $ncpu processors)"
tck=$(getconf CLK_TCK 2>/dev/null || echo 100)
# A command that does not end this long after its signal is killed (the test fails
# instead of blocking).
WATCHDOG_S=120

. "$(dirname "$0")/tap.sh"
now() { date +%s.%N; }
# explain STATUS DESCRIPTION: report, and when the case failed, the state of the last
# signalled command and the end of its output (a rare failure on a loaded machine
# then says which of its conditions did not hold).
explain() {
    report "$@"
    [ "$1" = 0 ] && return
    echo "#   running when signalled: $alive, exit $st, limits $MAX_LATENCY s and $MAX_CPU s," \
        "temporaries: $(ls "$tmp"/*.tmp* 2>/dev/null | tr '\n' ' ')"
    echo "#   the end of its output:"
    tail -c 600 "$tmp/err" 2>/dev/null | tr '\r' '\n' | grep . | tail -n 5 | sed 's/^/#     /'
}

# start CMD...: run in the background (pid in $pid; stdout in $tmp/out, stderr in
# $tmp/err) under a watchdog that kills it after WATCHDOG_S seconds.
# Under nohup (or a runner that ignores SIGHUP) frep keeps an ignored SIGHUP ignored, on
# purpose; the commands started here get the default back so that the SIGHUP cases test
# frep's handler and not the caller's environment.
if env --default-signal=HUP true 2>/dev/null; then
    hup_default="env --default-signal=HUP"
else
    hup_default=""
fi

watchdog() {
    (
        i=0
        while [ $i -lt $((WATCHDOG_S * 10)) ] && kill -0 "$pid" 2>/dev/null; do
            sleep 0.1
            i=$((i + 1))
        done
        kill -9 "$pid" 2>/dev/null
    ) >/dev/null 2>&1 &
    dog=$!
}
start() {
    : >"$tmp/err"
    $hup_default "$@" >"$tmp/out" 2>"$tmp/err" &
    pid=$!
    spid=
    watchdog
}
# start_tty CMD...: as start, under a pseudo-terminal (script(1)), where the commands
# show on stderr the phase they are in (their progress line), so that a signal can be
# sent in a given phase; stdout and stderr both go to $tmp/err. pid is the command's,
# spid script's (whose status is the command's). 1 (nothing started) without script
# or /proc.
have_tty=0
if script -qefc true /dev/null </dev/null >/dev/null 2>&1 && [ -r /proc/$$/stat ]; then
    have_tty=1
fi
start_tty() {
    : >"$tmp/err"
    [ $have_tty = 1 ] || return 1
    $hup_default script -qefc "exec $*" /dev/null </dev/null >"$tmp/err" 2>&1 &
    spid=$!
    pid=
    i=0
    while [ -z "$pid" ] && [ $i -lt 1000 ] && kill -0 "$spid" 2>/dev/null; do
        pid=$(cut -d' ' -f1 "/proc/$spid/task/$spid/children" 2>/dev/null)
        [ -n "$pid" ] || pid=$(pgrep -P "$spid" 2>/dev/null | head -n 1)
        [ -n "$pid" ] || sleep 0.01
        i=$((i + 1))
    done
    [ -n "$pid" ] || pid=$spid
    watchdog
}
# skip_tty DESCRIPTION...: the SKIP lines of tests that need start_tty.
skip_tty() {
    for d in "$@"; do
        echo "ok $((n = n + 1)) # SKIP $d: no script(1) or /proc for a pseudo-terminal"
    done
}
# wait_for TEXT [SECONDS]: until TEXT appears on the command's stderr (1: it ended or
# the time ran out first).
wait_for() {
    i=0
    while [ $i -lt $((${2:-60} * 20)) ]; do
        grep -q "$1" "$tmp/err" 2>/dev/null && return 0
        kill -0 "$pid" 2>/dev/null || return 1
        sleep 0.05
        i=$((i + 1))
    done
    return 1
}
# wait_cpu SECONDS: until the command has used SECONDS of processor time (so that it
# is past its input whatever the load; without /proc, a plain sleep).
wait_cpu() {
    if [ ! -r "/proc/$pid/stat" ]; then
        sleep "$1"
        return 0
    fi
    while kill -0 "$pid" 2>/dev/null; do
        t=$(awk -v k="$tck" '{ sub(/.*\) /, ""); print ($12 + $13) / k }' "/proc/$pid/stat" 2>/dev/null)
        awk -v t="${t:-0}" -v s="$1" 'BEGIN { exit !(t >= s) }' && return 0
        sleep 0.05
    done
    return 1
}
# wait_file GLOB: until a file matching GLOB exists (1: the command ended first).
wait_file() {
    i=0
    while [ $i -lt 1200 ]; do
        for f in $1; do [ -e "$f" ] && return 0; done
        kill -0 "$pid" 2>/dev/null || return 1
        sleep 0.01
        i=$((i + 1))
    done
    return 1
}
# stop SIG...: send each signal in turn and wait; st is the exit status, lat the
# seconds from the first signal to the exit, cpu the processor seconds the command
# used in that time (its last reading before it ended, every 10 ms: on a loaded
# machine the wall time measures the load), alive 1 when the command was still
# running when signalled (else the test proves nothing). A signal after the first is
# sent as soon as the one before it has been delivered (its pending bit cleared:
# two pending signals of one kind would merge into one); late is 1 when the command
# had already ended by then (it handled the first one that fast: the test of the
# second proves nothing, run it again).
stat_of() { # stat_of PID: "STATE CPU-SECONDS" of a process
    awk -v k="$tck" '{ sub(/.*\) /, ""); printf "%s %.3f", $1, ($12 + $13) / k }' \
        "/proc/$1/stat" 2>/dev/null
}
stop() {
    alive=0
    kill -0 "$pid" 2>/dev/null && alive=1
    c0=$(stat_of "$pid")
    c0=${c0#* }
    c1=$c0
    t0=$(now)
    first=1
    late=0
    for s in "$@"; do
        if [ $first = 0 ]; then
            delivered "$prev"
            case $(stat_of "$pid") in "" | Z*) late=1 ;; esac
        fi
        first=0
        prev=$s
        kill -"$s" "$pid" 2>/dev/null
    done
    while :; do
        r=$(stat_of "$pid")
        case $r in "" | Z*) break ;; esac
        c1=${r#* }
        sleep 0.01
    done
    t1=$(now)
    wait "${spid:-$pid}"
    st=$?
    wait "$dog" 2>/dev/null
    lat=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }')
    cpu=$(awk -v a="${c0:-0}" -v b="${c1:-0}" 'BEGIN { printf "%.2f", b - a }')
    lat="$lat s ($cpu s of processor time)"
}
# The latency is within the limit: the processor time under 1 s, the wall time
# under MAX_LATENCY (1 s x the load per processor).
# delivered SIG: until SIG is no longer pending for the command (at most 1 s; without
# /proc, 0.05 s).
delivered() {
    if [ ! -r "/proc/$pid/status" ]; then
        sleep 0.05
        return 0
    fi
    case $1 in HUP) bit=1 ;; INT) bit=2 ;; TERM) bit=16384 ;; *) bit=0 ;; esac
    i=0
    while [ $i -lt 1000 ]; do
        p=0
        while read -r k v; do
            case $k in SigPnd: | ShdPnd:) p=$((p | 0x$v)) ;; esac
        done <"/proc/$pid/status" 2>/dev/null
        [ $((p & bit)) = 0 ] && return 0
        i=$((i + 1))
    done
}
fast() {
    awk -v l="${lat%% *}" -v c="$cpu" -v m="$MAX_LATENCY" -v mc="$MAX_CPU" \
        'BEGIN { exit !(l < m && c < mc) }'
}
no_tmp() { ! ls "$tmp"/*.tmp* >/dev/null 2>&1; }

# ---- inputs ---------------------------------------------------------------------------
# A cloud whose segmentation takes seconds (200,000 points of the gear; binary PLY,
# read at once), and a small one with its primitives for the GA phases.
"$FREP" sample "$EX/gear.hf" -n 200000 --seed 3 -o "$tmp/big.ply" -q || exit 1
"$FREP" sample "$EX/csg.hf" -n 20000 --seed 3 -o "$tmp/small.xyz" -q || exit 1
"$FREP" segment "$tmp/small.xyz" --seed 3 -o "$tmp/small.fit" -q >/dev/null || exit 1
"$FREP" segment "$tmp/small.xyz" --seed 3 -o "$tmp/small.hf" -q >/dev/null || exit 1

# ---- segment ---------------------------------------------------------------------------
start "$FREP" segment "$tmp/big.ply" --seed 1 -o "$tmp/seg.fit" -q
wait_cpu 1.5
stop INT
[ $alive = 1 ] && [ $st = 130 ] && fast && [ -f "$tmp/seg.fit" ] && no_tmp &&
    grep -q 'frep segment: interrupted (Ctrl-C): wrote the primitives found so far' "$tmp/err"
explain $? "segment: Ctrl-C during RANSAC: exit $st after $lat, the primitives so far written"

# the merge of redundant primitives that follows the detection (its progress stage
# "merge"): it polls per pair of primitives tried
if start_tty "$FREP" segment "$tmp/big.ply" --seed 1 -o "$tmp/segm.fit"; then
    wait_for 'segment: merge:'
    stop INT
    [ $alive = 1 ] && [ $st = 130 ] && fast && [ -s "$tmp/segm.fit" ] && no_tmp &&
        grep -q 'frep segment: interrupted (Ctrl-C): wrote the primitives found so far' "$tmp/err"
    explain $? "segment: Ctrl-C during the merge of redundant primitives: exit $st after $lat, the primitives written"
else
    skip_tty "segment: Ctrl-C during the merge"
fi


# ---- evolve ----------------------------------------------------------------------------
# its own segmentation (after the cloud is read: "N points, seed S")
start "$FREP" evolve "$tmp/big.ply" --seed 1 -o "$tmp/ev1.hf"
wait_for 'points, seed' && wait_cpu 1.5
stop INT
[ $alive = 1 ] && [ $st = 130 ] && fast &&
    grep -q 'frep evolve: interrupted (Ctrl-C)' "$tmp/err" && no_tmp
explain $? "evolve: Ctrl-C during its segmentation: exit $st after $lat"
if [ -f "$tmp/ev1.hf" ]; then
    "$FREP" check "$tmp/ev1.hf" 2>/dev/null
    explain $? "... the model written from the primitives found so far compiles"
else
    grep -q 'nothing written' "$tmp/err"
    explain $? "... no primitive yet: nothing written, and it says so"
fi

# the clique GAs of a partitioned run: they would never stop by themselves
start "$FREP" evolve "$tmp/small.xyz" -p "$tmp/small.fit" --seed 1 --stagnation 1000000 \
    --generations 1000000000 -o "$tmp/ev2.hf" --trace "$tmp/ev2.trace"
wait_cpu 2
stop INT
[ $alive = 1 ] && [ $st = 130 ] && fast && "$FREP" check "$tmp/ev2.hf" 2>/dev/null &&
    grep -q ', partitioned (' "$tmp/ev2.hf" && grep -q 'wrote the best tree so far' "$tmp/err"
explain $? "evolve: Ctrl-C during the clique GAs: exit $st after $lat, the union of the clique trees written"
[ -s "$tmp/ev2.trace" ] && no_tmp
explain $? "... with its --trace, no temporary left"

# one GA over all primitives
start "$FREP" evolve "$tmp/small.xyz" -p "$tmp/small.fit" --seed 1 --no-partition \
    --stagnation 1000000 --generations 1000000000 -o "$tmp/ev3.hf" --refit
wait_cpu 2
stop INT
[ $alive = 1 ] && [ $st = 130 ] && fast && "$FREP" check "$tmp/ev3.hf" 2>/dev/null
explain $? "evolve: Ctrl-C during the GA: exit $st after $lat, the best tree written (no refit)"

# the simplification of the final tree: a GA of 5 generations over the gear's 50-odd
# primitives (segmented from 5,000 points), every point of 20,000 scored (--sample 0),
# leaves seconds of simplification and growth (about 7 s of processor time against
# 0.5 s for the GA); it used to poll nothing and ran to its end
"$FREP" sample "$EX/gear.hf" -n 5000 --seed 3 -o "$tmp/g5.xyz" -q &&
    "$FREP" segment "$tmp/g5.xyz" --seed 3 -o "$tmp/g5.fit" -q >/dev/null &&
    "$FREP" sample "$EX/gear.hf" -n 20000 --seed 3 -o "$tmp/g20.xyz" -q || exit 1
start "$FREP" evolve "$tmp/g20.xyz" -p "$tmp/g5.fit" --seed 1 --no-partition --sample 0 \
    --generations 5 -o "$tmp/ev5.hf"
wait_cpu 2.5
stop INT
[ $alive = 1 ] && [ $st = 130 ] && fast && "$FREP" check "$tmp/ev5.hf" 2>/dev/null &&
    "$FREP" eval "$tmp/ev5.hf" "$tmp/g20.xyz" >/dev/null 2>&1 &&
    grep -q 'wrote the best tree so far' "$tmp/err" && no_tmp
explain $? "evolve: Ctrl-C during the simplification: exit $st after $lat, the tree so far written and evaluated"

# the merge of the clique trees of a partitioned run, and the refit of the primitives
# after the search (each seen by its progress line)
if start_tty "$FREP" evolve "$tmp/g20.xyz" -p "$tmp/g5.fit" --seed 1 --generations 5 \
    -o "$tmp/ev6.hf"; then
    wait_for 'merging clique trees'
    stop INT
    [ $alive = 1 ] && [ $st = 130 ] && fast && "$FREP" check "$tmp/ev6.hf" 2>/dev/null &&
        grep -q 'wrote the best tree so far' "$tmp/err" && no_tmp
    explain $? "evolve: Ctrl-C during the merge of the clique trees: exit $st after $lat, the tree so far written"
else
    skip_tty "evolve: Ctrl-C during the merge of the clique trees"
fi
# (a GA of 150 generations, unsimplified, on one thread: the refit of its 55
# parameters takes 0.8 s on an idle machine; with 20 generations it took 0.06 s, and
# the signal, sent within 0.05 s of the progress line, came after the write)
if start_tty "$FREP" evolve "$tmp/g20.xyz" -p "$tmp/g5.fit" --seed 1 --generations 150 \
    -t 1 --no-partition --no-simplify --refit -o "$tmp/ev7.hf"; then
    wait_for 'refitting the primitives'
    stop INT
    [ $alive = 1 ] && [ $st = 130 ] && fast && "$FREP" check "$tmp/ev7.hf" 2>/dev/null &&
        grep -q 'wrote the best tree so far' "$tmp/err" && no_tmp
    explain $? "evolve: Ctrl-C during the refit: exit $st after $lat, the tree written"
else
    skip_tty "evolve: Ctrl-C during the refit"
fi
# the writing of the model ("rounding the numbers and forming solids"): its checks
# evaluate the tree at the check points (0.1-0.6 s on these 200,000 points) and poll
# the flag, so the model is written at once with the numbers not yet checked as
# fitted.  A signal that came after the write (exit 0: the checks ended first) proves
# nothing: the run is tried again, at most 5 times, and the case is skipped when every
# attempt missed the writing (the model then written whole, by a normal exit).
if [ $have_tty = 1 ]; then
    try=0
    while :; do
        start_tty "$FREP" evolve "$tmp/big.ply" -p "$tmp/g5.fit" --seed 1 --generations 150 \
            -t 1 --no-partition -o "$tmp/ev8.hf"
        wait_for 'rounding the numbers'
        stop INT
        try=$((try + 1))
        [ $st = 0 ] && [ $try -lt 5 ] || break
    done
    if [ $st = 0 ] && "$FREP" check "$tmp/ev8.hf" 2>/dev/null; then
        # Every signal came after the write (a loaded machine: the progress line reaches
        # the test later than the writing's 0.1-0.6 s): nothing was tested.
        echo "ok $((n = n + 1)) # SKIP evolve: Ctrl-C while writing the model: the signal came after the write in $try attempts"
    else
        [ $alive = 1 ] && [ $st = 130 ] && fast && "$FREP" check "$tmp/ev8.hf" 2>/dev/null &&
            grep -q 'wrote the best tree so far' "$tmp/err" && no_tmp
        r=$?
        explain $r "evolve: Ctrl-C while writing the model: exit $st after $lat, the model written (attempt $try)"
        [ $r = 0 ] || "$FREP" check "$tmp/ev8.hf" 2>&1 | sed 's/^/#   frep check: /'
    fi
else
    skip_tty "evolve: Ctrl-C while writing the model"
fi

# a second Ctrl-C aborts at once: the existing output is untouched, no temporary left
try=0
while :; do
    echo 'kept' >"$tmp/ev4.hf"
    start "$FREP" evolve "$tmp/big.ply" --seed 1 -o "$tmp/ev4.hf"
    wait_for 'points, seed' && wait_cpu 1.5
    stop INT INT
    try=$((try + 1))
    [ $late = 1 ] && [ $try -lt 5 ] || break
done
[ $alive = 1 ] && [ $st = 130 ] && fast && [ "$(cat "$tmp/ev4.hf")" = kept ] && no_tmp
explain $? "evolve: a second Ctrl-C aborts at once: exit $st after $lat, output untouched (attempt $try)"

# ---- normals ------------------------------------------------------------------------------
# frep normals of the 200,000 gear points (their normals are replaced; about 2 s): a
# partial estimate is no result, so nothing is written and the old file stays.
echo 'kept' >"$tmp/n.xyz"
start "$FREP" normals "$tmp/big.ply" -o "$tmp/n.xyz"
wait_cpu 0.7
stop INT
[ $alive = 1 ] && [ $st = 130 ] && fast && [ "$(cat "$tmp/n.xyz")" = kept ] && no_tmp &&
    grep -q 'frep normals: interrupted (Ctrl-C): nothing written' "$tmp/err"
explain $? "normals: Ctrl-C while estimating: exit $st after $lat, the old file kept"

# ---- mesh, sample ------------------------------------------------------------------------
echo 'kept' >"$tmp/m.stl"
start "$FREP" mesh "$EX/gear.hf" -g 1024 -o "$tmp/m.stl"
wait_cpu 1
stop INT
[ $alive = 1 ] && [ $st = 130 ] && fast && [ "$(cat "$tmp/m.stl")" = kept ] && no_tmp &&
    grep -q 'frep mesh: interrupted (Ctrl-C): stopped while meshing, nothing written' "$tmp/err"
explain $? "mesh: Ctrl-C while meshing: exit $st after $lat, the old file kept"

start "$FREP" sample "$EX/gear.hf" -n 1000000 -g 768 --seed 1 -o "$tmp/s.xyz"
wait_cpu 1
stop TERM
[ $alive = 1 ] && [ $st = 143 ] && fast && [ ! -e "$tmp/s.xyz" ] && no_tmp &&
    grep -q 'frep sample: interrupted (SIGTERM)' "$tmp/err"
explain $? "sample: SIGTERM while sampling: exit $st after $lat, nothing written"

# frep render: the drawing (the distances of 200,000 points to the surface) polls
# nothing, so a signal ends it at once; the meshing before it polls.  The picture is
# large enough to draw for 4.5 s of processor time on an AVX-512 Xeon (at 4000x3000 it
# ended there before the 1.5 s at which it is signalled).
echo 'kept' >"$tmp/r.png"
start "$FREP" render "$EX/gear.hf" -g 64 --points "$tmp/big.ply" --size 8000x6000 -o "$tmp/r.png"
wait_cpu 1.5
stop INT
[ $alive = 1 ] && [ $st = 130 ] && fast && [ "$(cat "$tmp/r.png")" = kept ] && no_tmp
explain $? "render: Ctrl-C while drawing: exit $st after $lat, the old picture kept"

# frep fit: the annealing, then the quasi-Newton phase (their progress lines), on the
# test part of doc/fit.md; the best parameters so far are written. 1% of the points are
# outliers: no chain explains them, so the annealing does not stop after one chain
# (FIT_ONE_CHAIN_SHARE in fit/fit.c) before the signal comes.
"$FREP" sample "$EX/fit/part_truth.hf" -n 100000 --outliers 0.01 --seed 1 \
    -o "$tmp/part.xyz" -q || exit 1
for ph in annealing quasi-Newton; do
    # the annealing with chains that do not end by themselves; quasi-Newton alone
    case $ph in annealing) m="--sa-chains 1000 --sa-stall 1000000" ;; *) m="--method qn" ;; esac
    if start_tty "$FREP" fit "$EX/fit/part.hf" "$tmp/part.xyz" $m -o "$tmp/fit_$ph.hf"; then
        wait_for "$ph  *.*iteration"
        stop INT
        [ $alive = 1 ] && [ $st = 130 ] && fast && "$FREP" check "$tmp/fit_$ph.hf" 2>/dev/null &&
            grep -q 'interrupted: best so far' "$tmp/err" && no_tmp
        explain $? "fit: Ctrl-C during the $ph: exit $st after $lat, the best parameters written"
    else
        skip_tty "fit: Ctrl-C during the $ph"
    fi
done

# signals during a write: a first one lets the write finish (the result is complete)
# and the status says it came; a second one removes the temporary and stops at once
start "$FREP" sample "$EX/sphere.hf" -n 3000000 --seed 1 -o "$tmp/w1.xyz"
wait_file "$tmp/w1.xyz.tmp*"
stop HUP
[ $alive = 1 ] && [ $st = 129 ] && no_tmp && [ "$(wc -l <"$tmp/w1.xyz")" = 3000000 ]
explain $? "sample: SIGHUP during the write: the file is complete, exit $st"

try=0
while :; do
    start "$FREP" sample "$EX/sphere.hf" -n 3000000 --seed 1 -o "$tmp/w2.xyz"
    wait_file "$tmp/w2.xyz.tmp*"
    stop TERM TERM
    try=$((try + 1))
    [ $late = 1 ] && [ $try -lt 5 ] && rm -f "$tmp/w2.xyz" || break
done
[ $alive = 1 ] && [ $st = 143 ] && fast && no_tmp && [ ! -e "$tmp/w2.xyz" ]
explain $? "sample: two SIGTERMs during the write: temporary removed, exit $st after $lat (attempt $try)"

# a command that does not poll (eval) stops at once, with the signal's status
start "$FREP" eval "$EX/gear.hf" --grid 2000
wait_cpu 0.5
stop HUP
[ $alive = 1 ] && [ $st = 129 ] && fast && grep -q 'frep: interrupted' "$tmp/err"
explain $? "eval --grid: SIGHUP stops it at once: exit $st after $lat: $(head -c 300 "$tmp/err")"

# ---- write errors ---------------------------------------------------------------------
full() { # full DESCRIPTION CMD...: stdout to /dev/full must fail with the reason
    d=$1
    shift
    "$@" >/dev/full 2>"$tmp/ferr"
    fs=$?
    [ $fs != 0 ] && grep -q 'No space left on device' "$tmp/ferr"
    explain $? "$d to a full disk: exit $fs, '$(head -n 1 "$tmp/ferr")'"
}
if [ -w /dev/full ]; then
    full "frep print" "$FREP" print "$EX/gear.hf"
    full "frep dis" "$FREP" dis "$EX/sphere.hf"
    echo '0 0 0' >"$tmp/p.txt"
    full "frep eval POINTS" "$FREP" eval "$EX/sphere.hf" "$tmp/p.txt"
    full "frep eval --grid" "$FREP" eval "$EX/sphere.hf" --grid 8
    full "frep sample -o -" "$FREP" sample "$EX/sphere.hf" -n 100 -o - -q
    full "frep mesh -o -" "$FREP" mesh "$EX/sphere.hf" -o - -q
    full "frep segment's table" "$FREP" segment "$tmp/small.xyz" --seed 1
else
    for d in print dis eval eval-grid sample mesh segment; do
        echo "ok $((n = n + 1)) # SKIP $d: no writable /dev/full"
    done
fi
# An output that is no regular file is written in place: a temporary renamed over it
# replaced /dev/full (as root) or a FIFO with a plain file.  -o /dev/full fails with the
# reason and leaves the device a device; -o FIFO sends the data through the pipe.
dev_full() { # dev_full SUB ARGS...: frep SUB ARGS... -o /dev/full
    "$FREP" "$@" -o /dev/full 2>"$tmp/ferr"
    fs=$?
    [ $fs != 0 ] && grep -q 'No space left on device' "$tmp/ferr" && [ -c /dev/full ]
    explain $? "frep $1 -o /dev/full: exit $fs, the reason, /dev/full still a device"
}
if [ -c /dev/full ] && [ -w /dev/full ]; then
    dev_full sample "$EX/sphere.hf" -n 100 -q
    dev_full render "$EX/sphere.hf" -g 16 --size 64x48 -q
    dev_full normals "$tmp/small.xyz" -q
else
    for d in sample render normals; do
        echo "ok $((n = n + 1)) # SKIP $d -o /dev/full: no writable /dev/full"
    done
fi
if mkfifo "$tmp/pipe" 2>/dev/null; then
    timeout 60 cat "$tmp/pipe" >"$tmp/piped" &
    rd=$!
    "$FREP" sample "$EX/sphere.hf" -n 100 --seed 1 -q -o "$tmp/pipe"
    fs=$?
    wait $rd
    "$FREP" sample "$EX/sphere.hf" -n 100 --seed 1 -q -o "$tmp/direct.xyz" &&
        [ $fs = 0 ] && [ -p "$tmp/pipe" ] && cmp -s "$tmp/piped" "$tmp/direct.xyz"
    explain $? "frep sample -o FIFO: the points through the pipe, the FIFO kept"
    rm -f "$tmp/pipe"
else
    echo "ok $((n = n + 1)) # SKIP sample -o FIFO: no mkfifo"
fi
echo 'kept' >"$tmp/big.stl"
(
    trap '' XFSZ
    ulimit -f 16 && exec "$FREP" mesh "$EX/gear.hf" -o "$tmp/big.stl" -q
) 2>"$tmp/ferr"
fs=$?
[ $fs = 1 ] && grep -q "cannot write $tmp/big.stl: File too large" "$tmp/ferr" &&
    [ "$(cat "$tmp/big.stl")" = kept ] && no_tmp
explain $? "a file over the size limit: exit $fs, the reason, the old file kept, no temporary"
mkdir "$tmp/small_fs"
if mount -t tmpfs -o size=64k tmpfs "$tmp/small_fs" 2>/dev/null; then
    "$FREP" mesh "$EX/gear.hf" -o "$tmp/small_fs/g.stl" -q 2>"$tmp/ferr"
    fs=$?
    [ $fs = 1 ] && grep -q 'No space left on device' "$tmp/ferr" &&
        [ -z "$(ls "$tmp/small_fs")" ]
    explain $? "a full file system (64 KiB tmpfs): exit $fs, 'No space left on device', nothing left"
    umount "$tmp/small_fs"
else
    echo "ok $((n = n + 1)) # SKIP full tmpfs: cannot mount one (not root)"
fi

# ---- bounded loops and parameter ranges ---------------------------------------------------
"$FREP" sample "$EX/csg.hf" -n 3000 --seed 1 -o "$tmp/c3k.xyz" -q
start "$FREP" segment "$tmp/c3k.xyz" --cluster 1e-12 --seed 1 -q
wait "$pid"
st=$?
wait "$dog" 2>/dev/null
[ $st = 0 ]
explain $? "segment --cluster 1e-12 ends (RANSAC_MAX_DRAWS bounds the rejected extractions): exit $st"
for d in 64 1024; do
    start "$FREP" evolve "$tmp/small.xyz" -p "$tmp/small.fit" --seed 1 --max-depth $d \
        --generations 5 --population 20 -o "$tmp/deep.hf" -q
    wait "$pid"
    st=$?
    wait "$dog" 2>/dev/null
    [ $st = 0 ] && ! grep -q 'out of memory' "$tmp/err" && "$FREP" check "$tmp/deep.hf" 2>/dev/null
    explain $? "evolve --max-depth $d (the ends of the range): exit $st, a model"
done

# ---- the work budget of evaluation (--max-work) ---------------------------------------------
# A loop of 10^6 iterations at every point (too long to unroll: it runs at evaluation
# time): at the default mesh grid that was minutes of work; the budget (10^9 loop
# iterations summed over the points, CLI_DEFAULT_MAX_WORK) stops it with a clear error.
printf '%s\n' 'my_model(x[3], a[1])' '{' '  i = 0;' '  while i < 1000000 loop' \
    '    i = i + 1;' '  endloop;' \
    '  my_model = a[1] - sqrt(x[1]*x[1] + x[2]*x[2] + x[3]*x[3]) + 0 * i;' '}' >"$tmp/loop.hf"
budget() { # budget SUB CMD...: exit 1 with the budget's message (and but for fit, the
    # runtime error at the loop), no temporary
    b_sub=$1
    shift
    start "$@"
    wait "$pid"
    fs=$?
    wait "$dog" 2>/dev/null
    [ $fs = 1 ] &&
        grep -q "frep $b_sub: .*the model's loops ran over the work budget of [0-9]* iterations" "$tmp/err" &&
        { [ "$b_sub" = fit ] || grep -q 'loop.hf:4:9: .*loop iterations over the work budget' "$tmp/err"; } &&
        no_tmp
}
echo '0 0 0' >"$tmp/p0.txt"
budget eval "$FREP" eval "$tmp/loop.hf" "$tmp/p0.txt" --max-work 100000 && [ ! -s "$tmp/out" ]
explain $? "eval POINTS --max-work 1e5 on a 10^6-iteration loop: exit $fs, no value printed"
budget eval "$FREP" eval "$tmp/loop.hf" --grid 8 --max-work 100000 && ! grep -q '^inside' "$tmp/out"
explain $? "eval --grid --max-work 1e5: exit $fs, no summary"
echo 'kept' >"$tmp/budget.stl"
t0=$(now)
budget mesh "$FREP" mesh "$tmp/loop.hf" -a 1 -o "$tmp/budget.stl" && [ "$(cat "$tmp/budget.stl")" = kept ]
explain $? "mesh at the default grid and budget: exit $fs after $(awk -v a="$t0" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }') s, the old file kept: $(tail -n 1 "$tmp/err")"
budget sample "$FREP" sample "$tmp/loop.hf" -a 1 -n 100 --seed 1 -o "$tmp/budget.xyz" --max-work 1000000 &&
    [ ! -e "$tmp/budget.xyz" ]
explain $? "sample --max-work 1e6: exit $fs, nothing written"
"$FREP" sample "$EX/sphere.hf" -n 300 --seed 1 -o "$tmp/sph.xyz" -q
budget fit "$FREP" fit "$tmp/loop.hf" "$tmp/sph.xyz" -a 0.5 -o "$tmp/budget_fit.hf" --max-work 1000000 -q &&
    [ ! -e "$tmp/budget_fit.hf" ]
explain $? "fit --max-work 1e6: exit $fs, nothing written"
"$FREP" eval "$tmp/loop.hf" "$tmp/p0.txt" -a 1 --max-work 1000000 >"$tmp/out" 2>"$tmp/err"
fs=$?
[ $fs = 0 ] && [ "$(cat "$tmp/out")" = 1 ]
explain $? "eval within --max-work 1e6 (10^6 iterations): exit $fs, the value $(cat "$tmp/out")"
"$FREP" eval "$tmp/loop.hf" "$tmp/p0.txt" --max-work 0 >/dev/null 2>"$tmp/err"
fs=$?
[ $fs = 2 ] && grep -q 'max-work' "$tmp/err"
explain $? "--max-work 0 is refused as a usage error (exit $fs)"

# Ctrl-C inside the model's loops: a block of 256 points of this loop (its bound a
# parameter, so it is never unrolled) is seconds of work; the loop itself sees the flag
# (frep_program_set_cancel), not only the blocks (it took 1.5 s before).
printf '%s\n' 'my_model(x[3], a[1])' '{' '  i = 0;' '  s = 0;' '  while i < 1000000 * a[1] loop' \
    '    s = s + sin(i * x[1]) * cos(i * x[2]) + sin(i * x[3]) * cos(s) + exp(-i) * sin(s);' \
    '    i = i + 1;' '  endloop;' '  my_model = a[1] - sqrt(x[1]*x[1] + x[2]*x[2] + x[3]*x[3]) + 0 * s;' \
    '}' >"$tmp/loopc.hf"
echo 'kept' >"$tmp/loopc.stl"
start "$FREP" mesh "$tmp/loopc.hf" -a 1 --max-work 1e15 -o "$tmp/loopc.stl"
wait_cpu 1
stop INT
[ $alive = 1 ] && [ $st = 130 ] && fast && [ "$(cat "$tmp/loopc.stl")" = kept ] && no_tmp &&
    grep -q 'stopped while meshing, nothing written' "$tmp/err" && ! grep -q 'loop' "$tmp/err"
explain $? "mesh: Ctrl-C inside a model's loop: exit $st after $lat, the old file kept, no loop error reported"

# ---- scale -------------------------------------------------------------------------------
awk 'BEGIN { for (i = 0; i < 2000; i++) printf "%.17g %.17g %.17g 0 0 1\n", (i % 45) * 1e300, int(i / 45) * 1e300, 0 }' >"$tmp/huge.xyz"
"$FREP" segment "$tmp/huge.xyz" --seed 1 -q 2>"$tmp/ferr"
fs=$?
[ $fs = 1 ] && grep -q 'coordinates reach .*: rescale the cloud' "$tmp/ferr"
explain $? "segment of a cloud at 1e300: refused clearly (exit $fs): $(cat "$tmp/ferr")"
awk 'BEGIN { for (i = 0; i < 2000; i++) printf "%.17g %.17g %.17g 0 0 1\n", (i % 45) * 1e-300, int(i / 45) * 1e-300, 0 }' >"$tmp/tiny.xyz"
"$FREP" segment "$tmp/tiny.xyz" --seed 1 -q 2>"$tmp/ferr"
fs=$?
[ $fs = 1 ] && grep -q 'spans .*: rescale the cloud' "$tmp/ferr" && ! grep -q 'same point' "$tmp/ferr"
explain $? "segment of 2,000 distinct points at 1e-300: not 'the same point' (exit $fs): $(cat "$tmp/ferr")"
cat >"$tmp/huge.off" <<'EOF'
OFF
4 4 0
0 0 0
1e300 0 0
0 1e300 0
0 0 1e300
3 0 2 1
3 0 1 3
3 0 3 2
3 1 2 3
EOF
"$FREP" sample "$tmp/huge.off" -n 1000 --seed 1 -o "$tmp/huge_s.xyz" -q
fs=$?
[ $fs = 0 ] && ! grep -qi 'nan\|inf' "$tmp/huge_s.xyz" && [ "$(wc -l <"$tmp/huge_s.xyz")" = 1000 ]
explain $? "sample of a mesh at 1e300: finite points and normals (exit $fs)"
"$FREP" sample "$EX/sphere.hf" -n 100 --noise 1e308 --seed 1 -o "$tmp/noise.xyz" -q 2>"$tmp/ferr"
fs=$?
[ $fs = 1 ] && [ ! -e "$tmp/noise.xyz" ] && grep -q 'would not be finite' "$tmp/ferr"
explain $? "sample --noise 1e308: refused, nothing written (exit $fs)"

# ---- primitive lists -------------------------------------------------------------------
bad_list() { # bad_list FILE EXPECTED DESCRIPTION
    "$FREP" evolve "$tmp/small.xyz" -p "$1" --seed 1 -o "$tmp/bad.hf" -q 2>"$tmp/ferr"
    fs=$?
    [ $fs = 1 ] && [ ! -e "$tmp/bad.hf" ] && grep -q "$2" "$tmp/ferr"
    explain $? "$3: exit $fs, '$(head -n 1 "$tmp/ferr")'"
}
printf 'plane 0 0 1 0\nsphere 0 0 0 -1\n' >"$tmp/neg.fit"
bad_list "$tmp/neg.fit" 'neg.fit:2: degenerate sphere: the radius must be > 0' "a negative radius in a .fit list"
printf 'cylinder 0 0 1 0 0 0 0\n' >"$tmp/zero.fit"
bad_list "$tmp/zero.fit" 'zero.fit:1: degenerate cylinder: the radius must be > 0' "a zero radius in a .fit list"
for a in 0 1.5707963267948966 3.141592653589793; do
    printf 'p(x[3], a[1])\n{\n  p1 = frPlane(x, 0, 0, 1, 0);\n  p2 = frCone(x, 0, 0, 0, 0, 0, 1, %s);\n}\n' $a >"$tmp/cone.hf"
    bad_list "$tmp/cone.hf" 'cone.hf:4:8: degenerate frCone(): the half-angle must be in (0, pi/2)' \
        "a cone of half-angle $a in a .hf list"
done
head -c 700 "$tmp/small.hf" >"$tmp/cut.hf"
bad_list "$tmp/cut.hf" "cut.hf:[0-9]*:[0-9]*: expected '}' to close '{'" "a .hf list cut off mid-file"
printf 'sph\033[2Jere 0 0 0 1\n' >"$tmp/ctl.fit"
bad_list "$tmp/ctl.fit" "unknown primitive type 'sph\\\\x1b\\[2Jere'" "a control byte in a message is escaped"

echo "1..$n"
[ $failed = 0 ]
