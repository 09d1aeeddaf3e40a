# tests/tap.sh - the TAP reporting every shell test shares; sourced with
#   . "$(dirname "$0")/tap.sh"
# report STATUS DESCRIPTION prints "ok N - DESCRIPTION" when STATUS is 0, else
# "not ok N - ..." and marks the run failed; tap_done prints the plan and exits with
# the run's status.  report_todo STATUS DESCRIPTION REASON reports a known failure:
# "not ok ... # TODO REASON" (XFAIL) does not fail the run, and once it passes the
# "ok ... # TODO" (XPASS) fails `make check` until the TODO is removed.
n=0
failed=0
report() { # report STATUS DESCRIPTION
    n=$((n + 1))
    if [ "$1" = 0 ]; then echo "ok $n - $2"; else echo "not ok $n - $2"; failed=1; fi
}
report_todo() { # report_todo STATUS DESCRIPTION REASON
    n=$((n + 1))
    if [ "$1" = 0 ]; then echo "ok $n - $2 # TODO $3"; else echo "not ok $n - $2 # TODO $3"; fi
}
tap_done() {
    echo "1..$n"
    exit $failed
}
