#!/bin/sh
# conformance.sh - the HyperFun conformance suite (TAP): third-party HyperFun files
# evaluated by frep and by the independent interpreter tests/conformance/hfref.py, which
# follows the reference interpreter; tests/conformance/run.py says more.  Needs python3
# (plain, no modules); skipped without it.
: "${FREP:=./frep}" "${srcdir:=.}"
PY=$(command -v python3 || true)
if [ -z "$PY" ]; then
  echo "1..0 # SKIP python3 not found (the reference interpreter hfref.py is Python)"
  exit 0
fi
exec "$PY" "$srcdir/tests/conformance/run.py" --frep "$FREP" --tap
