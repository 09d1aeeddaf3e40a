#!/usr/bin/env python3
"""run.py - the HyperFun conformance suite: frep against the independent hfref.py.

Every .hf file under tests/conformance/files (in the repository) and
tests/conformance/ext (git-ignored, filled from the sources MANIFEST lists) is
evaluated at 64 fixed points by hfref.py, which follows the reference interpreter,
and by `frep eval`.  A file conforms when every value agrees: both NaN (frep's NaN
where the reference raises a runtime error), or |frep - ref| <= 1e-9 max(1, |ref|).
Files the reference rejects, and files calling a library function hfref.py lacks,
are listed but not counted.  A file that differs only by a bug of the reference that
frep deliberately does not copy is counted apart as a documented deviation: its
scanner misreads negative exponents of two or more digits (1e-16 as 1e-4,
hfref.EXPONENT_BUG), and its sign() returns 1 for every argument (hfref.SIGN_BUG).

  run.py --frep PATH [--tap] [--dir DIR]...

--tap prints TAP for `make check` (one test per counted file; the files named in
XFAIL are expected to differ: 'not ok ... # TODO', and an unexpected pass fails the
suite so the mark is removed once frep is fixed).  Without --tap it prints one line
per file and the count "N of M files evaluate as the reference".
"""

import math
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import hfref  # noqa: E402

REL_TOL = 1e-9
NPOINTS = 64


def halton(i, base):
    f, r = 1.0, 0.0
    while i > 0:
        f /= base
        r += f * (i % base)
        i //= base
    return r


def points():
    """64 points: 32 in hfp's default box [-10,10]^3, 32 in [-2,2]^3, Halton (2,3,5)."""
    pts = []
    for k in range(NPOINTS):
        half = 10.0 if k < NPOINTS // 2 else 2.0
        pts.append([round(half * (2 * halton(k + 1, b) - 1), 6) for b in (2, 3, 5)])
    return pts


# hfref.py's own checks: what the reference's C code computes (int_calc.c,
# int_scanner.c, int_parse_N.c), worked out by hand, so the oracle is pinned too.
# (model body, point, expected value; NaN: a runtime error of the reference)
SELF = [
    ("m = mod(2.7, 2);", (0, 0, 0), 1.0),            # fmod(round 3, round 2)
    ("m = mod(-2.5, 2);", (0, 0, 0), 0.0),           # round half up: -2
    ("m = sign(-3);", (0, 0, 0), 1.0),               # its sign() always returns 1
    ("m = -2^2;", (0, 0, 0), 4.0),                   # unary minus takes one operand
    ("m = 2^3^2;", (0, 0, 0), 64.0),                 # ^ is left-associative
    ("m = 1 + 2 * 3 - 4 / 8;", (0, 0, 0), 6.5),
    ("m = 1 | 0 + 1;", (0, 0, 0), 3.0),  # | and + share a level: (1 | 0) + 1
    ("t = 0; if 3 < 2 < 1 then t = 1; endif; m = t;", (0, 0, 0), 1.0),  # (3<2)<1
    ("m = 1e-16 * 1e4;", (0, 0, 0), 1.0),            # 1e-16 reads as 1e-4
    ("m = 1e-10 * 1e10;", (0, 0, 0), 1.0),           # a 0 second digit is harmless
    ("m = x[1] / 1e-7;", (1, 0, 0), math.nan),       # |divisor| < EPS
    ("m = (0 - 8)^(1/3);", (0, 0, 0), math.nan),     # real power of a negative
    ("m = 0^0;", (0, 0, 0), math.nan),
    ("m = (x[1] - 2)^2.0000001;", (0, 0, 0), 4.0),   # within EPS above 2: the loop
    ("if x[1] > 0 then t = 1; endif; m = t;", (-1, 0, 0), math.nan),
    ("if x[1] > 0 then t = 1; endif; m = t;", (1, 0, 0), 1.0),
    ("m = x[1] & x[2];", (1, 2, 0), 3 - math.sqrt(5)),
    ("m = x[1] \\ x[2];", (1, 2, 0), -1 - math.sqrt(5)),
    ("m = sqrt(x[1]);", (-1, 0, 0), math.nan),
    ("array v[2]; v[1] = 3; m = v[2];", (0, 0, 0), math.nan),
    # indices are HF_round-ed: halves up (0.5 -> 1, 1.5 -> 2, 2.5 -> 3: out of range)
    ("array v[2]; v = [3, 4]; m = v[1.5];", (0, 0, 0), 4.0),
    ("array v[2]; v = [3, 4]; m = v[0.5];", (0, 0, 0), 3.0),
    ("array v[2]; v = [3, 4]; m = v[1.4999];", (0, 0, 0), 3.0),
    ("array v[2]; v = [3, 4]; m = v[2.5];", (0, 0, 0), math.nan),
    ("array v[2]; v = [3, 4]; m = v[0.4999];", (0, 0, 0), math.nan),
    ("array v[2]; v = [3, 4]; v[x[1]] = 7; m = v[2];", (1.5, 0, 0), 7.0),
    # library functions whose values are worked out by hand from their C sources:
    # Catmull-Rom through the squares reproduces (1 + 2u)^2; below the first entry
    # the look-up table ends with its last row; order-2 Bezier volume = trilinear
    # 4u + 2v + t with v from x[3], clipped: R_int(R_int(R_int(.25, .16), .09), 2.4)
    ("array k[5], o[1]; k = [0, 1, 4, 9, 16]; o = [0]; d = hfA_Spline(o, k, x[1], 0, 1);"
     " m = o[1];", (0.25, 0, 0), 2.25),
    ("array e[3], t[3], o[1]; e = [0, 1, 2]; t = [10, 20, 30]; o = [0];"
     " d = hfA_LookUpTable(x[1], o, t, e); m = o[1];", (-1, 0, 0), 30.0),
    ("array b[6], w[8]; b = [0, 0, 0, 1, 1, 1]; w = [0, 1, 2, 3, 4, 5, 6, 7];"
     " m = hfBezierVolume(x, 2, 2, 2, b, w);", (0.5, 0.2, 0.1), 0.057864077245282974),
]


def self_checks():
    """[(description, None or what went wrong)] for SELF and the choice of model."""
    out = []
    for body, pt, want in SELF:
        model = hfref.load("m(x[3], a[1])\n{\n  %s\n}\n" % body)
        got = hfref.value_at(model, pt)
        ok = (math.isnan(want) and math.isnan(got)) or got == want or abs(got - want) < 1e-12
        out.append(("hfref: %s at %s is %r" % (body, pt, want),
                    None if ok else "got %r" % got))
    first = hfref.load("one(x[3], a[1]) { one = 1; }\ntwo(x[3], a[1]) { two = 2; }\n")
    got = hfref.value_at(first, (0, 0, 0))
    out.append(("hfref: with no my_model the first model is evaluated",
                None if got == 1.0 else "got %r" % got))
    for text, why in (("m(x[3], a[1]) { m = 05; }", "a number starting 0 then a digit"),
                      ("m(x[3], a[1]) { m = 1e05; }", "an exponent starting with 0"),
                      ("m(x[3], a[1]) { x[1] = 2; m = 1; }", "an assignment to x[]"),
                      ("m(x[3], a[1]) { array c[3]; c = [0, 0]; m = 1; }",
                       "an array literal shorter than its array"),
                      ("m(x[3], a[1]) { m = 1; m = 2; }", "the model's value assigned twice"),
                      ("m(x[3], a[1]) { m = 1; t = 2; }",
                       "a statement after the model's value")):
        try:
            hfref.load(text)
            out.append(("hfref: rejects %s" % why, "accepted"))
        except hfref.Reject:
            out.append(("hfref: rejects %s" % why, None))
    return out


def read_xfail(path):
    marks = {}
    if os.path.exists(path):
        with open(path) as fh:
            for line in fh:
                line = line.strip()
                if line and not line.startswith("#"):
                    name, _, reason = line.partition(" ")
                    marks[name] = reason.strip()
    return marks


def reference(path, pts, bugs=True):
    """('ok', values) | ('reject', why) | ('unsupported', why); bugs=False: without
    the reference's bugs frep does not copy (EXPONENT_BUG, SIGN_BUG)."""
    with open(path, "rb") as fh:
        text = fh.read().decode("latin-1").replace("\r\n", "\n")
    hfref.EXPONENT_BUG = hfref.SIGN_BUG = bugs
    try:
        model = hfref.load(text)
        return "ok", [hfref.value_at(model, p) for p in pts]
    except hfref.Reject as e:
        return "reject", str(e)
    except hfref.Unsupported as e:
        return "unsupported", str(e)
    finally:
        hfref.EXPONENT_BUG = hfref.SIGN_BUG = True


def frep_values(frep, path, ptsfile):
    r = subprocess.run([frep, "eval", path, ptsfile], capture_output=True, text=True)
    if r.returncode != 0:
        first = (r.stderr.strip().splitlines() or ["exit %d" % r.returncode])[0]
        return None, first
    vals = [float(t) for t in r.stdout.split()]
    return vals, None


def agree(f, r):
    if math.isnan(r) or math.isnan(f):
        return math.isnan(r) and math.isnan(f)
    return abs(f - r) <= REL_TOL * max(1.0, abs(r))


def compare(fv, rv, pts):
    """None when they agree, else a description of the first difference."""
    if len(fv) != len(rv):
        return "frep printed %d values for %d points" % (len(fv), len(rv))
    bad = [k for k in range(len(rv)) if not agree(fv[k], rv[k])]
    if not bad:
        return None
    k = bad[0]
    return "%d of %d points differ, e.g. at (%g, %g, %g): frep %r, reference %r" % (
        len(bad), len(rv), pts[k][0], pts[k][1], pts[k][2], fv[k], rv[k])


def collect(dirs):
    files = []
    for d in dirs:
        if not os.path.isdir(d):
            continue
        for root, _, names in os.walk(d):
            for n in names:
                if n.endswith(".hf"):
                    files.append(os.path.join(root, n))
    return sorted(files, key=lambda p: os.path.relpath(p, HERE))


def main(argv):
    frep, tap, dirs = None, False, []
    args = iter(argv[1:])
    for a in args:
        if a == "--frep":
            frep = next(args)
        elif a == "--tap":
            tap = True
        elif a == "--dir":
            dirs.append(next(args))
        else:
            sys.stderr.write(__doc__)
            return 64
    if not frep:
        sys.stderr.write("run.py: --frep PATH is required\n")
        return 64
    if not dirs:
        dirs = [os.path.join(HERE, "files"), os.path.join(HERE, "ext")]
    xfail = read_xfail(os.path.join(HERE, "XFAIL"))
    pts = points()
    fd, ptsfile = tempfile.mkstemp(suffix=".xyz")
    with os.fdopen(fd, "w") as fh:
        for p in pts:
            fh.write("%r %r %r\n" % tuple(p))
    n = counted = same = deviations = 0
    rejected, unsupported, failures = [], [], 0
    for desc, err in self_checks():
        if tap:
            n += 1
            print("%s %d - %s" % ("ok" if err is None else "not ok", n, desc))
            if err:
                print("# " + err)
        elif err:
            print("SELF-CHECK FAILED %s: %s" % (desc, err))
    try:
        for path in collect(dirs):
            name = os.path.relpath(path, HERE)
            kind, rv = reference(path, pts)
            if kind == "reject":
                rejected.append((name, rv))
                if tap:
                    n += 1
                    print("ok %d - %s # SKIP the reference rejects it: %s" % (n, name, rv))
                else:
                    print("reject   %s: %s" % (name, rv))
                continue
            if kind == "unsupported":
                unsupported.append((name, rv))
                if tap:
                    n += 1
                    print("ok %d - %s # SKIP hfref.py lacks %s" % (n, name, rv))
                else:
                    print("skip     %s: hfref.py lacks %s" % (name, rv))
                continue
            counted += 1
            fv, err = frep_values(frep, path, ptsfile)
            diff = ("frep rejects it: " + err) if fv is None else compare(fv, rv, pts)
            deviation = False
            if diff is not None and fv is not None:
                kind2, rv2 = reference(path, pts, bugs=False)
                deviation = kind2 == "ok" and compare(fv, rv2, pts) is None
            if deviation:
                deviations += 1
                diff = None
                name_note = (" (differs only by a bug of the reference: 1e-16 read as 1e-4, "
                             "or sign() always 1)")
            else:
                name_note = ""
            if diff is None and not deviation:
                same += 1
            if tap:
                n += 1
                mark = xfail.get(name)
                status = "ok" if diff is None else "not ok"
                todo = " # TODO %s" % mark if mark is not None else ""
                print("%s %d - %s%s%s" % (status, n, name, name_note, todo))
                if diff is not None:
                    print("# " + diff)
                if (diff is None) == (mark is not None):
                    failures += 1   # a difference not marked, or a mark that passes
            else:
                print("%s %s%s" % ("deviates" if deviation else "same    " if diff is None
                                   else "DIFFERS ", name, name_note if diff is None else ": " + diff))
    finally:
        os.unlink(ptsfile)
    summary = ("%d of %d files evaluate as the reference, %d more differ only by the "
               "reference's bugs (%d more rejected by the reference, %d calling "
               "functions hfref.py lacks)"
               % (same, counted, deviations, len(rejected), len(unsupported)))
    if tap:
        print("# " + summary)
        print("1..%d" % n)
        return 0
    print(summary)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
