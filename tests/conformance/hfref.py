#!/usr/bin/env python3
"""hfref.py - an independent HyperFun interpreter, the oracle of the conformance suite.

It shares no code with frep: its own scanner, parser and tree-walking evaluator, pure
Python and math, written from the reference interpreter's behaviour (HyperFun 1.x
int_scanner.c / int_parse_N.c / int_calc.c / int_global.c and the hflibrary_lib
primitives, as published with the R package 'hyperfun').  Where the reference is odd
it is followed, not corrected:

  * a file with no my_model evaluates its FIRST model;
  * the assignment to the model's name is the body's last statement (anything else
    is a syntax error there);
  * + - & | \\ @ share the lowest precedence, * / the next, ^ binds tightest of the
    binary operators and is left-associative; unary + - ~ apply to one operand only
    (-x^2 is (-x)^2);
  * comparisons chain left to right as values: a < b < c is (a < b) < c;
  * and, or, =, /=, not compare against EPS = 1e-6; a condition holds when |v| >= EPS;
  * x / y is an error when |y| < EPS; x ^ y follows the reference's integer loop
    (y within EPS above an integer) or exp(y log x) (x < 0: error);
  * mod(a, b) = fmod(round(a), round(b)) with round half up; sign() is always 1
    (SIGN_BUG; off, it is -1, 0 or 1 as in frep); array indices are rounded the same
    way (HF_round: 1.5 -> 2, 2.5 -> 3);
  * & | \\ are the R-functions with ALPHA = 0 (a + b -+ sqrt(a^2 + b^2));
  * numbers are scanned digit by digit as the reference does (a leading 0 followed by
    a digit, or an exponent starting with 0, is a syntax error), including its bug
    with negative exponents of two or more digits: it accumulates the sign into the
    first digit (-1, then -1*10 + 6), so 1e-16 reads as 1e-4 (EXPONENT_BUG; off, the
    exponent is read correctly); only space, tab and newline separate tokens; names
    are case-insensitive;
  * reading a variable that was never assigned on the path taken is a runtime error;
    a name never assigned before its use is a syntax error.

Usage: hfref.py FILE.hf < POINTS   prints one value per point (repr), 'nan' where the
       reference raises a runtime error.  Exit 2 with 'reject: MESSAGE' on stderr when
       the reference would reject the file, 3 with 'unsupported: MESSAGE' when this
       interpreter lacks a library function the file calls.
"""

import math
import sys

EPS = 1e-6
ALPHA = 0.0
SENTINEL = -1111111111111.0   # what library primitives return for bad arguments
MAX_LOOP = 1000000            # while iterations before giving up on a point
EXPONENT_BUG = True           # read 1e-16 as the reference does (as 1e-4)
SIGN_BUG = True               # sign() gives 1 for every argument, as the reference does


class Reject(Exception):
    """The reference would not parse this file."""


class Unsupported(Exception):
    """A construct or library function this interpreter does not implement."""


class RuntimeErr(Exception):
    """A runtime error of the reference: the point's value is NaN."""


# ---- scanner ------------------------------------------------------------------------

KEYWORDS = {"and", "or", "not", "xor", "array", "if", "then", "else", "endif",
            "while", "loop", "endloop"}
SINGLE = set("^+~*&|\\@,;=()[]{}")


def hf_round(d):
    c = math.ceil(d)
    return int(c - 1 if c - d > 0.5 else c)


def scan(text):
    """The reference's tokens: (kind, value, line, col); kinds: num, id, op, str, eof."""
    toks = []
    i, line, col = 0, 1, 1
    n = len(text)
    while True:
        while i < n and text[i] in " \n\t":
            if text[i] == "\n":
                line, col = line + 1, 1
            else:
                col += 1
            i += 1
        if i >= n or text[i] == "\0":
            toks.append(("eof", None, line, col))
            return toks
        c = text[i]
        start = (line, col)
        if c == "-" and i + 1 < n and text[i + 1] == "-":
            while i < n and text[i] != "\n":
                i += 1
                col += 1
            continue
        if c in "<>/" and i + 1 < n and text[i + 1] == "=":
            toks.append(("op", c + "=", *start))
            i, col = i + 2, col + 2
            continue
        if c in SINGLE or c in "<>/-":
            toks.append(("op", c, *start))
            i, col = i + 1, col + 1
            continue
        if c == '"':
            j = i + 1
            while j < n and text[j] not in '"\n':
                j += 1
            if j >= n or text[j] != '"':
                raise Reject("%d:%d: second quotation mark expected" % start)
            toks.append(("str", text[i + 1:j], *start))
            col += j + 1 - i
            i = j + 1
            continue
        if c.isdigit() or c == ".":
            j = i
            val = 0.0
            err = False
            numeric = False
            if text[j] != ".":
                numeric = True
                val = float(ord(text[j]) - 48)
                j += 1
                if text[j - 1] == "0" and j < n and text[j].isdigit():
                    err = True
                while not err and j < n and text[j].isdigit():
                    val = val * 10.0 + (ord(text[j]) - 48)
                    j += 1
            if not err and j < n and text[j] == ".":
                j += 1
                if j < n and text[j].isdigit():
                    t = 10.0
                    while j < n and text[j].isdigit():
                        val = val + (ord(text[j]) - 48) / t
                        t *= 10.0
                        j += 1
                elif not numeric:
                    err = True
            if not err and j < n and text[j] in "eE":
                j += 1
                sign = 1.0
                if j < n and text[j] == "-":
                    sign = -1.0
                    j += 1
                elif j < n and text[j] == "+":
                    j += 1
                if j >= n or text[j] == "0" or not text[j].isdigit():
                    err = True
                else:
                    e = (sign if EXPONENT_BUG else 1.0) * (ord(text[j]) - 48)
                    j += 1
                    while j < n and text[j].isdigit():
                        e = e * 10.0 + (ord(text[j]) - 48)
                        j += 1
                    if not EXPONENT_BUG:
                        e *= sign
                    val = val * math.exp(e * math.log(10))
            if err:
                raise Reject("%d:%d: wrong format of number" % start)
            toks.append(("num", val, *start))
            col += j - i
            i = j
            continue
        if c.isalpha():
            j = i
            while j < n and (text[j].isalnum() or text[j] == "_"):
                j += 1
            word = text[i:j].lower()
            toks.append(("id", word, *start))
            col += j - i
            i = j
            continue
        raise Reject("%d:%d: unknown lexem %r" % (start[0], start[1], c))


# ---- library ------------------------------------------------------------------------
# Each entry: argument kinds ('r' number, 'a' array) and a function of the argument
# values in source order (arrays as Python lists, modified in place by the space
# mappings).  Formulas from the reference's hflibrary_lib sources.

def _dim3(x):
    return len(x) == 3


def hf_sphere(x, c, r):
    if not _dim3(x):
        return SENTINEL
    xt, yt, zt = x[0] - c[0], x[1] - c[1], x[2] - c[2]
    return r * r - xt * xt - yt * yt - zt * zt


def hf_ellipsoid(x, c, a, b, cc):
    if not _dim3(x) or abs(a) < EPS or abs(b) < EPS or abs(cc) < EPS:
        return SENTINEL
    xt, yt, zt = (x[0] - c[0]) / a, (x[1] - c[1]) / b, (x[2] - c[2]) / cc
    return 1.0 - xt * xt - yt * yt - zt * zt


def hf_block(x, v, dx, dy, dz):
    if not _dim3(x) or dx < 0 or dy < 0 or dz < 0:
        return SENTINEL
    xt = (x[0] - v[0]) * (v[0] + dx - x[0])
    yt = (x[1] - v[1]) * (v[1] + dy - x[1])
    zt = (x[2] - v[2]) * (v[2] + dz - x[2])
    if ALPHA == 1.0:
        return min(xt, yt, zt)
    f = xt + yt - math.sqrt(xt * xt + yt * yt - 2.0 * ALPHA * xt * yt)
    return f + zt - math.sqrt(f * f + zt * zt - 2.0 * ALPHA * f * zt)


def _axes(axis):
    """(axial index, the two radial indices) of an axis letter."""
    return {"x": (0, 1, 2), "y": (1, 0, 2), "z": (2, 0, 1)}[axis]


def hf_cylinder(axis):
    _, i, j = _axes(axis)

    def f(x, c, r):
        if not _dim3(x):
            return SENTINEL
        u, v = x[i] - c[i], x[j] - c[j]
        return r * r - u * u - v * v
    return f


def hf_ellcyl(axis):
    _, i, j = _axes(axis)

    def f(x, c, a, b):
        if not _dim3(x) or abs(a) < EPS or abs(b) < EPS:
            return SENTINEL
        u, v = (x[i] - c[i]) / a, (x[j] - c[j]) / b
        return 1.0 - u * u - v * v
    return f


def hf_cone(axis):
    k, i, j = _axes(axis)

    def f(x, c, r):
        if not _dim3(x):
            return SENTINEL
        w = x[k] - c[k]
        u, v = (x[i] - c[i]) / r, (x[j] - c[j]) / r
        return w * w - u * u - v * v
    return f


def hf_ellcone(axis):
    k, i, j = _axes(axis)

    def f(x, c, a, b):
        if not _dim3(x):
            return SENTINEL
        w = x[k] - c[k]
        u, v = (x[i] - c[i]) / a, (x[j] - c[j]) / b
        return w * w - u * u - v * v
    return f


def hf_torus(axis):
    k, i, j = _axes(axis)

    def f(x, c, big, r0):
        if not _dim3(x):
            return SENTINEL
        w, u, v = x[k] - c[k], x[i] - c[i], x[j] - c[j]
        u2, v2 = u * u, v * v
        return r0 * r0 - w * w - u2 - v2 - big * big + 2 * big * math.sqrt(u2 + v2)
    return f


def hf_superell(x, c, a, b, cc, s1, s2):
    if (not _dim3(x) or abs(a) < EPS or abs(b) < EPS or abs(cc) < EPS
            or abs(s1) < EPS or abs(s2) < EPS):
        return SENTINEL
    xt, yt, zt = (x[0] - c[0]) / a, (x[1] - c[1]) / b, (x[2] - c[2]) / cc
    p = 2.0 / s2
    xp, yp = abs(xt) ** p, abs(yt) ** p
    zp = abs(zt) ** (2.0 / s1)
    return 1.0 - (xp + yp) ** (s2 / s1) - zp


def hf_blobby(x, x0, y0, z0, a, b, t):
    num = len(b)
    if num <= 0:
        return SENTINEL
    s = 0.0
    for i in range(num):
        xt, yt, zt = x[0] - x0[i], x[1] - y0[i], x[2] - z0[i]
        s = s + b[i] * math.exp(-a[i] * (xt * xt + yt * yt + zt * zt))
    return s - t


def hf_noiseg(x, amp, freq, phase):
    if not _dim3(x):
        return SENTINEL
    a2x, a2y, a2z = freq * x[0], freq * x[1], freq * x[2]
    sx, sy, sz = math.sin(a2x), math.sin(a2y), math.sin(a2z)
    a1d = amp / 1.17
    sx2 = a1d * math.sin(a2x / 1.35 + phase * sz)
    sy2 = a1d * math.sin(a2y / 1.35 + phase * sx)
    sz2 = a1d * math.sin(a2z / 1.35 + phase * sy)
    return (amp * sx + sx2) * (amp * sy + sy2) * (amp * sz + sz2)


# The attribute library's deterministic functions (hfA_noiseg.c, hfA_Circles.c,
# hfA_Crackles.c, hfA_CheckerBoard.c, hfA_LookUpTable.c, hfA_SmoothLookUpTable.c,
# hfA_spline.c, pattern.h) and hfBezierVolume (hfBezierVolume.c, Bezier.c).  Arrays
# are written in place as the C code writes through its pointers; reads past an
# array's end (undefined in C) raise Unsupported.

def _gardner01(xt, yt, zt, phase, a2):
    """Noise() of pattern.h (a1 = 1), normalised to [0, 1]."""
    a2x, a2y, a2z = a2 * xt, a2 * yt, a2 * zt
    sx, sy, sz = math.sin(a2x), math.sin(a2y), math.sin(a2z)
    a1d = 1.0 / 1.17
    serx = sx + a1d * math.sin(a2x / 1.35 + phase * sz)
    sery = sy + a1d * math.sin(a2y / 1.35 + phase * sx)
    serz = sz + a1d * math.sin(a2z / 1.35 + phase * sy)
    c = 2.17 / 1.17
    cmin = (-c) ** 3
    return (serx * sery * serz - cmin) / (-cmin - cmin)


def _at(arr, k):
    if not 0 <= k < len(arr):
        raise Unsupported("a read past the end of an array (undefined in the reference)")
    return arr[k]


def hfa_noiseg(x, freq, phase):
    return _gardner01(x[0], x[1], x[2], phase, freq)


def _table(noise, rgb, color, prob, stop_at_first):
    n_prob = len(prob)
    if n_prob < len(color):
        color[n_prob] = 1.1
    for i in range(n_prob - 1):
        if prob[i] <= noise < prob[i + 1]:
            for j in range(len(rgb)):
                rgb[j] = _at(color, len(rgb) * i + j)
            if stop_at_first:
                break


def hfa_circles(x, rgb, color, prob):
    noise = math.fmod(math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]), 1.0)
    _table(noise, rgb, color, prob, True)
    return 1.0


def hfa_crackles(x, rgb, freq, color, prob):
    xt, yt, zt = x[0], x[1], x[2]
    phase = (abs(xt) + abs(yt) + abs(zt)) / 3.0
    total = (-1 + _gardner01(xt, xt, zt, phase, freq) * 2.0) + \
        (-1 + _gardner01(yt, yt, xt, phase, freq) * 2.0) + \
        (-1 + _gardner01(zt, zt, yt, phase, freq) * 2.0)
    i = int((total - math.floor(total)) * 1000.0)
    noise = (1.0 + math.sin(i * 2.0 * math.pi / 1000.0)) / 2.0
    _table(noise, rgb, color, prob, False)
    return 1.0


def hfa_checkerboard(x, cube, d, c, c_cube, c_space):
    lmin, lmax = [], []
    for i in range(3):
        delta = math.floor(x[i] / (d[i] + cube[i]))
        lmin.append((d[i] + cube[i]) * delta)
        lmax.append(lmin[i] + cube[i])
    if len(c_cube) == len(c_space):
        inside = all(lmin[i] < x[i] < lmax[i] for i in range(3))
        for i in range(len(c_cube)):
            if i >= len(c):
                raise Unsupported("a write past the end of an array")
            c[i] = c_cube[i] if inside else c_space[i]
    return 1.0


def _lookup(t, output, colormap, entry, smooth):
    dim1, n = len(output), len(entry)
    filled = False
    if t < entry[0]:
        for j in range(dim1):
            output[j] = _at(colormap, j)
    else:
        for i in range(n - 1):
            if entry[i] <= t < entry[i + 1]:
                filled = True
                lam = (t - entry[i]) / (entry[i + 1] - entry[i])
                for j in range(dim1):
                    if smooth:
                        output[j] = (1 - lam) * _at(colormap, dim1 * i + j) + \
                            lam * _at(colormap, dim1 * (i + 1) + j)
                    else:
                        output[j] = _at(colormap, dim1 * i + j)
                break
    if not filled:
        for j in range(dim1):
            output[j] = _at(colormap, dim1 * (n - 1) + j)
    return 1.0


def hfa_lookuptable(t, output, colormap, entry):
    return _lookup(t, output, colormap, entry, False)


def hfa_smoothlookuptable(t, output, colormap, entry):
    return _lookup(t, output, colormap, entry, True)


CATMULL_ROM = ((-0.5, 1.5, -1.5, 0.5), (1.0, -2.5, 2.0, -0.5),
               (-0.5, 0.0, 0.5, 0.0), (0.0, 1.0, 0.0, 0.0))


def hfa_spline(s, knot, x, xmin, xmax):
    n = len(s)
    size = len(knot) // n
    x = (x - xmin) / (xmax - xmin)
    if x < 0.0:
        for i in range(n):
            s[i] = knot[i]
    elif x > 1.0:
        for i in range(n):
            s[i] = _at(knot, (size - 1) * n + i)
    else:
        nspans = size - 3
        x = x * nspans
        span = int(x)
        if span >= nspans:
            span = nspans - 3
        x -= span
        for i in range(n):
            c3, c2, c1, c0 = (sum(row[k] * _at(knot, (span + k) * n + i) for k in range(4))
                              if span >= 0 else _at(knot, -1) for row in CATMULL_ROM)
            s[i] = ((c3 * x + c2) * x + c1) * x + c0
    return 1.0


def _r_int(p, q):
    return p + q - math.sqrt(p * p + q * q)


def hf_beziervolume(x, l, m, n, bbox, w):
    l, m, n = int(l), int(m), int(n)
    if max(l, m, n) > 21:
        raise Unsupported("hfBezierVolume of order above 21 (past the reference's table)")
    if len(x) != 3:
        return SENTINEL
    xt = (x[0] - bbox[0]) / (bbox[3] - bbox[0])
    yt = (x[1] - bbox[1]) / (bbox[4] - bbox[1])
    zt = (x[2] - bbox[2]) / (bbox[5] - bbox[2])

    def bern(i, d, t):
        return math.comb(d, i) * (1.0 - t) ** (d - i) * t ** i
    bu = [bern(i, l - 1, xt) for i in range(l)]
    bv = [bern(j, m - 1, zt) for j in range(m)]
    bw = [bern(k, n - 1, yt) for k in range(n)]
    b = 0.0
    for i in range(l):
        for j in range(m):
            for k in range(n):
                b = b + bu[i] * bv[j] * bw[k] * _at(w, i * m * n + j * n + k)
    xc = (bbox[3] - x[0]) * (x[0] - bbox[0])
    yc = (bbox[4] - x[1]) * (x[1] - bbox[1])
    zc = (bbox[5] - x[2]) * (x[2] - bbox[2])
    return _r_int(_r_int(_r_int(xc, yc), zc), b)


LIBRARY = {
    "hfa_noiseg": ("arr", hfa_noiseg),
    "hfa_circles": ("aaaa", hfa_circles),
    "hfa_crackles": ("aaraa", hfa_crackles),
    "hfa_checkerboard": ("aaaaaa", hfa_checkerboard),
    "hfa_lookuptable": ("raaa", hfa_lookuptable),
    "hfa_smoothlookuptable": ("raaa", hfa_smoothlookuptable),
    "hfa_spline": ("aarrr", hfa_spline),
    "hfbeziervolume": ("arrraa", hf_beziervolume),
    "hfsphere": ("aar", hf_sphere),
    "hfellipsoid": ("aarrr", hf_ellipsoid),
    "hfblock": ("aarrr", hf_block),
    "hfsuperell": ("aarrrrr", hf_superell),
    "hfblobby": ("aaaaaar", hf_blobby),
    "hfnoiseg": ("arrr", hf_noiseg),
}
for _ax in "xyz":
    LIBRARY["hfcylinder" + _ax] = ("aar", hf_cylinder(_ax))
    LIBRARY["hfellcyl" + _ax] = ("aarr", hf_ellcyl(_ax))
    LIBRARY["hfcone" + _ax] = ("aar", hf_cone(_ax))
    LIBRARY["hfellcone" + _ax] = ("aarr", hf_ellcone(_ax))
    LIBRARY["hftorus" + _ax] = ("aarr", hf_torus(_ax))

BUILTIN1 = {"sqrt", "exp", "log", "logd", "sin", "cos", "tan", "asin", "acos", "atan",
            "abs", "sinh", "cosh", "tanh", "sign", "ceil", "floor", "int", "frac"}
BUILTIN2 = {"mod", "max", "min", "atan2"}


# ---- parser -------------------------------------------------------------------------
# Expressions: ('num', v) ('var', name) ('elem', arr, expr) ('x'|'a'|'s', expr)
# ('un', op, e) ('bin', op, l, r) ('call', fname, [args]) ('model', name, [arrays])
# Statements: ('set', var, e) ('return', e) ('setel', arr, ie, e) ('fill', arr, [v])
# ('if', cond, then, else) ('while', cond, body)

class Model:
    def __init__(self, name):
        self.name = name
        self.xdim = self.adim = 0
        self.sdim = 1
        self.body = []
        self.scalars = set()
        self.arrays = {}


class Parser:
    def __init__(self, toks):
        self.t = toks
        self.i = 0
        self.models = {}
        self.order = []

    def peek(self):
        return self.t[self.i]

    def next(self):
        tok = self.t[self.i]
        self.i += 1
        return tok

    def fail(self, what):
        tok = self.peek()
        raise Reject("%d:%d: %s" % (tok[2], tok[3], what))

    def expect(self, kind, val=None):
        tok = self.peek()
        if tok[0] != kind or (val is not None and tok[1] != val):
            self.fail("%s expected" % (val or kind))
        return self.next()

    def at(self, kind, val=None):
        tok = self.peek()
        return tok[0] == kind and (val is None or tok[1] == val)

    def parse_file(self):
        while not self.at("eof"):
            self.parse_model()
        if not self.order:
            self.fail("body name expected")
        return self.models, self.order

    def parse_model(self):
        tok = self.expect("id")
        name = tok[1]
        if name in KEYWORDS or name in ("x", "a", "s") or name in LIBRARY:
            self.fail("body name expected")
        if name in self.models:
            self.fail("body name is not unique")
        m = Model(name)
        self.expect("op", "(")
        for want, attr in (("x", "xdim"), ("a", "adim")):
            if not self.at("id", want):
                self.fail('"%s" expected' % want)
            self.next()
            self.expect("op", "[")
            setattr(m, attr, self.array_size())
            self.expect("op", "]")
            if attr == "xdim":
                self.expect("op", ",")
        if self.at("op", ","):
            self.next()
            if not self.at("id", "s"):
                self.fail('"s" expected')
            self.next()
            self.expect("op", "[")
            m.sdim = self.array_size()
            self.expect("op", "]")
        self.expect("op", ")")
        self.expect("op", "{")
        self.m = m
        m.body = self.statements(("}",))
        self.expect("op", "}")
        # HF_Get_Body_Def: the statements stop at the model's name, and then
        # 'name = expr ;' '}' must follow: the assignment is the body's last statement.
        rets = [k for k, st in enumerate(m.body) if st[0] == "return"]
        if not rets:
            raise Reject("model %s never assigns its name" % name)
        if rets != [len(m.body) - 1]:
            raise Reject("the assignment to %s is not the model's last statement" % name)
        self.models[name] = m
        self.order.append(name)

    @staticmethod
    def returns(stmts):
        return any(s[0] == "return" for s in stmts)

    def array_size(self):
        # HF_Get_Array_Decl / HF_Get_X_A: the size is HF_round(number), at least 1
        tok = self.expect("num")
        size = hf_round(tok[1])
        if size < 1:
            self.fail("array size must be greater zero")
        return size

    def statements(self, enders):
        out = []
        while not (self.at("op") and self.peek()[1] in enders) and not (
                self.at("id") and self.peek()[1] in enders) and not self.at("eof"):
            out.append(self.statement())
        return out

    def statement(self):
        m = self.m
        tok = self.peek()
        if tok[0] != "id":
            self.fail('identifier, "if" or "while" expected')
        w = tok[1]
        if w == "array":
            self.next()
            while True:
                name = self.expect("id")[1]
                if name in KEYWORDS or name in ("x", "a", "s"):
                    self.fail("identifier expected")
                self.expect("op", "[")
                size = self.array_size()
                # declared twice: HF_Find_In_Name_Array finds the first declaration
                m.arrays.setdefault(name, size)
                self.expect("op", "]")
                if self.at("op", ","):
                    self.next()
                    continue
                break
            self.expect("op", ";")
            return ("nop",)
        if w == "if":
            self.next()
            cond = self.bool_expr()
            self.expect("id", "then")
            then = self.statements(("else", "endif"))
            other = []
            if self.at("id", "else"):
                self.next()
                other = self.statements(("endif",))
            self.expect("id", "endif")
            self.expect("op", ";")
            if self.returns(then) or self.returns(other):
                raise Reject("the model's name is assigned inside if")
            return ("if", cond, then, other)
        if w == "while":
            self.next()
            cond = self.bool_expr()
            self.expect("id", "loop")
            body = self.statements(("endloop",))
            self.expect("id", "endloop")
            self.expect("op", ";")
            if self.returns(body):
                raise Reject("the model's name is assigned inside while")
            return ("while", cond, body)
        if w in ("x", "a"):
            self.fail("assign to %s[] is not allowed" % w)
        if w in KEYWORDS or w in LIBRARY or w in BUILTIN1 or w in BUILTIN2:
            self.fail('identifier, "if" or "while" expected')
        self.next()
        if w == "s":
            if self.at("op", "["):
                self.next()
                ie = self.expr()
                self.expect("op", "]")
                self.expect("op", "=")
                e = self.expr()
                self.expect("op", ";")
                return ("setel", "s", ie, e)
            self.expect("op", "=")
            vals = self.literal(m.sdim)
            return ("fill", "s", vals)
        if w in m.arrays:
            if self.at("op", "["):
                self.next()
                ie = self.expr()
                self.expect("op", "]")
                self.expect("op", "=")
                e = self.expr()
                self.expect("op", ";")
                return ("setel", w, ie, e)
            self.expect("op", "=")
            return ("fill", w, self.literal(m.arrays[w]))
        self.expect("op", "=")
        if w == m.name:
            e = self.expr()
            self.expect("op", ";")
            return ("return", e)
        m.scalars.add(w)
        e = self.expr()
        self.expect("op", ";")
        return ("set", w, e)

    def literal(self, size):
        """'[' signed numbers ']' ';' with exactly size items."""
        self.expect("op", "[")
        vals = []
        for k in range(size):
            if k:
                self.expect("op", ",")
            sign = 1.0
            if self.at("op", "-"):
                self.next()
                sign = -1.0
            elif self.at("op", "+"):
                self.next()
            vals.append(sign * self.expect("num")[1])
        self.expect("op", "]")
        self.expect("op", ";")
        return vals

    # bool_expr -> compare {(and|or) compare}; compare -> bterm {cmp bterm};
    # bterm -> not bterm | '(' bool_expr ')' | expr
    def bool_expr(self):
        left = self.compare()
        while self.at("id", "and") or self.at("id", "or"):
            op = self.next()[1]
            left = ("bin", op, left, self.compare())
        return left

    def compare(self):
        left = self.bterm()
        while self.at("op") and self.peek()[1] in ("<", ">", "<=", ">=", "=", "/="):
            op = self.next()[1]
            left = ("bin", op, left, self.bterm())
        return left

    def bterm(self):
        if self.at("id", "not"):
            self.next()
            return ("un", "not", self.bterm())
        if self.at("op", "("):
            self.next()
            e = self.bool_expr()
            self.expect("op", ")")
            return e
        return self.expr()

    # expr -> term {(+|-|&|'|'|\|@) term}; term -> factor {(*|/) factor};
    # factor -> unary {^ unary}; unary -> (+|-|~) unary | primary
    def expr(self):
        left = self.term()
        while self.at("op") and self.peek()[1] in ("+", "-", "&", "|", "\\", "@"):
            op = self.next()[1]
            left = ("bin", op, left, self.term())
        return left

    def term(self):
        left = self.factor()
        while self.at("op") and self.peek()[1] in ("*", "/"):
            op = self.next()[1]
            left = ("bin", op, left, self.factor())
        return left

    def factor(self):
        left = self.unary()
        while self.at("op", "^"):
            self.next()
            left = ("bin", "^", left, self.unary())
        return left

    def unary(self):
        if self.at("op") and self.peek()[1] in ("+", "-", "~"):
            op = self.next()[1]
            return ("un", op, self.unary())
        return self.primary()

    def primary(self):
        m = self.m
        tok = self.next()
        kind, val = tok[0], tok[1]
        if kind == "num":
            return ("num", val)
        if kind == "op" and val == "(":
            e = self.expr()
            self.expect("op", ")")
            return e
        if kind != "id" or val in KEYWORDS:
            self.i -= 1
            self.fail("expression expected")
        if val in ("x", "a", "s"):
            self.expect("op", "[")
            e = self.expr()
            self.expect("op", "]")
            return (val, e)
        if val in m.arrays:
            self.expect("op", "[")
            e = self.expr()
            self.expect("op", "]")
            return ("elem", val, e)
        if val in m.scalars:
            return ("var", val)
        if val in BUILTIN1 or val in BUILTIN2:
            self.expect("op", "(")
            args = [self.expr()]
            if val in BUILTIN2:
                self.expect("op", ",")
                args.append(self.expr())
            self.expect("op", ")")
            return ("call", val, args)
        if val in LIBRARY:
            kinds = LIBRARY[val][0]
            self.expect("op", "(")
            args = []
            for k, kd in enumerate(kinds):
                if k:
                    self.expect("op", ",")
                args.append(self.array_arg() if kd == "a" else self.expr())
            self.expect("op", ")")
            return ("call", val, args)
        if val in self.models:
            callee = self.models[val]
            self.expect("op", "(")
            arrs = [self.array_arg()]
            self.expect("op", ",")
            arrs.append(self.array_arg())
            if self.at("op", ","):
                self.next()
                arrs.append(self.array_arg())
            self.expect("op", ")")
            dims = [self.array_len(a) for a in arrs]
            want = [callee.xdim, callee.adim, callee.sdim]
            if dims[:2] != want[:2] or (len(arrs) == 3 and dims[2] != want[2]) or (
                    len(arrs) == 2 and callee.sdim != 1):
                raise Reject("%d:%d: wrong number of items in array" % (tok[2], tok[3]))
            return ("model", val, arrs)
        if val.startswith("hf"):
            raise Unsupported("library function %s" % val)
        raise Reject("%d:%d: unassigned identificator %s" % (tok[2], tok[3], val))

    def array_arg(self):
        tok = self.next()
        if tok[0] == "id" and (tok[1] in ("x", "a", "s") or tok[1] in self.m.arrays):
            return tok[1]
        raise Reject("%d:%d: only array name expected" % (tok[2], tok[3]))

    def array_len(self, name):
        m = self.m
        return {"x": m.xdim, "a": m.adim, "s": m.sdim}.get(name) or m.arrays[name]


# ---- evaluator ----------------------------------------------------------------------

class Frame:
    def __init__(self, model, x, a, s):
        self.m = model
        self.arr = {"x": x, "a": a, "s": s}
        for name, size in model.arrays.items():
            self.arr[name] = [None] * size
        self.var = {}


def index(frame, name, e):
    arr = frame.arr[name]
    k = hf_round(ev(frame, e))
    if not 1 <= k <= len(arr):
        raise RuntimeErr("index out of range")
    return arr, k - 1


def whole(frame, name):
    arr = frame.arr[name]
    if any(v is None for v in arr):
        raise RuntimeErr("some items of array are unassigned")
    return arr


def ipow(base, e):
    if abs(base) < EPS:
        if e <= EPS:
            raise RuntimeErr("zero value in negative or zero power")
        return 0.0
    if e - math.floor(e) < EPS:
        p = hf_round(abs(e))
        v = 1.0
        for _ in range(p):
            v *= base
        if e < 0.0:
            if v == 0.0:
                return math.copysign(math.inf, v)
            v = 1 / v
        return v
    if base < 0.0:
        raise RuntimeErr("negative value for power")
    try:
        return math.exp(e * math.log(base))
    except OverflowError:
        return math.inf


def rfun(a, b, sign):
    return (1 / (1 + ALPHA)) * (a + b + sign * math.sqrt(abs(a * a + b * b - 2 * ALPHA * a * b)))


def ev(f, e):
    k = e[0]
    if k == "num":
        return e[1]
    if k == "var":
        if e[1] not in f.var:
            raise RuntimeErr("not initialized variable")
        return f.var[e[1]]
    if k in ("x", "a", "s", "elem"):
        name = e[1] if k == "elem" else k
        arr, i = index(f, name, e[2] if k == "elem" else e[1])
        if arr[i] is None:
            raise RuntimeErr("unassigned identificator")
        return arr[i]
    if k == "un":
        v = ev(f, e[2])
        if e[1] == "not":
            return 1.0 if abs(v) < EPS else 0.0
        return v if e[1] == "+" else -v
    if k == "bin":
        op = e[1]
        a = ev(f, e[2])
        b = ev(f, e[3])
        if op == "+":
            return a + b
        if op == "-":
            return a - b
        if op == "*":
            return a * b
        if op == "/":
            if abs(b) < EPS:
                raise RuntimeErr("division by zero")
            return a / b
        if op == "^":
            return ipow(a, b)
        if op in ("&", "@"):
            return rfun(a, b, -1.0)
        if op == "|":
            return rfun(a, b, 1.0)
        if op == "\\":
            return rfun(a, -b, -1.0)
        if op == "and":
            return 1.0 if abs(a) >= EPS and abs(b) >= EPS else 0.0
        if op == "or":
            return 0.0 if abs(a) < EPS and abs(b) < EPS else 1.0
        if op == "<":
            return 1.0 if a < b else 0.0
        if op == ">":
            return 1.0 if a > b else 0.0
        if op == "<=":
            return 1.0 if a <= b else 0.0
        if op == ">=":
            return 1.0 if a >= b else 0.0
        if op == "=":
            return 1.0 if abs(a - b) < EPS else 0.0
        if op == "/=":
            return 1.0 if abs(a - b) >= EPS else 0.0
        raise Unsupported("operator " + op)
    if k == "call":
        name = e[1]
        if name in LIBRARY:
            kinds, fn = LIBRARY[name]
            args = [whole(f, a) if kd == "a" else ev(f, a) for kd, a in zip(kinds, e[2])]
            try:
                return fn(*args)
            except ZeroDivisionError:
                return math.inf
        return builtin(name, [ev(f, a) for a in e[2]])
    if k == "model":
        callee = f.m.file_models[e[1]]
        copies = [list(whole(f, a)) for a in e[2]]
        if len(copies) == 2:
            copies.append([0.0] * callee.sdim)
        v, s = run(callee, *copies)
        if len(e[2]) == 3:
            f.arr[e[2][2]][:] = s
        return v
    raise Unsupported(k)


def builtin(name, v):
    a = v[0]
    if name == "sqrt":
        if a < 0.0:
            raise RuntimeErr("negative value for square root")
        return math.sqrt(a)
    if name in ("log", "logd"):
        if not a > 0.0:
            raise RuntimeErr("negative for log function")
        return math.log(a) if name == "log" else math.log10(a)
    if name == "tan":
        if abs(math.cos(a)) < EPS:
            raise RuntimeErr("cannot compute tan")
        return math.tan(a)
    if name in ("asin", "acos"):
        if abs(a) > 1.0:
            raise RuntimeErr("argument must be in range -1.0 .. +1.0")
        return math.asin(a) if name == "asin" else math.acos(a)
    if name == "sign":
        # FUNC_sign in int_calc.c sets -1.0 for a negative argument, then 1.0 anyway.
        if SIGN_BUG:
            return 1.0
        return -1.0 if a < 0.0 else (1.0 if a > 0.0 else 0.0)
    if name == "int":
        return float(math.trunc(a)) if math.isfinite(a) else a
    if name == "frac":
        return math.modf(a)[0]
    if name == "mod":
        d = hf_round(v[1])
        if d == 0:
            raise RuntimeErr("mod by zero")
        return math.fmod(hf_round(a), d)
    if name == "max":
        return a if a > v[1] else v[1]
    if name == "min":
        return a if a < v[1] else v[1]
    if name == "atan2":
        return math.atan2(a, v[1])
    if name in ("exp", "sinh", "cosh"):
        try:
            return getattr(math, name)(a)
        except OverflowError:
            return math.inf if name != "sinh" or a > 0 else -math.inf
    return getattr(math, {"abs": "fabs"}.get(name, name))(a)


class Return(Exception):
    def __init__(self, value):
        self.value = value


def execute(f, stmts, budget):
    for s in stmts:
        k = s[0]
        if k == "nop":
            continue
        if k == "set":
            f.var[s[1]] = ev(f, s[2])
        elif k == "return":
            raise Return(ev(f, s[1]))
        elif k == "setel":
            arr, i = index(f, s[1], s[2])
            arr[i] = ev(f, s[3])
        elif k == "fill":
            f.arr[s[1]][:len(s[2])] = s[2]
        elif k == "if":
            execute(f, s[2] if abs(ev(f, s[1])) >= EPS else s[3], budget)
        elif k == "while":
            while abs(ev(f, s[1])) >= EPS:
                budget[0] -= 1
                if budget[0] < 0:
                    raise Unsupported("a while loop ran %d iterations" % MAX_LOOP)
                execute(f, s[2], budget)


def run(model, x, a, s):
    f = Frame(model, x, a, s)
    try:
        execute(f, model.body, [MAX_LOOP])
    except Return as r:
        return r.value, f.arr["s"]
    raise RuntimeErr("bad code: no value")


def load(text):
    """The models of a file and the one the reference evaluates."""
    p = Parser(scan(text))
    models, order = p.parse_file()
    for m in models.values():
        m.file_models = models
    return models["my_model"] if "my_model" in models else models[order[0]]


def value_at(model, pt):
    if model.xdim < 3:
        raise Unsupported("x has %d items" % model.xdim)
    x = list(pt) + [0.0] * (model.xdim - 3)
    try:
        v, _ = run(model, x, [0.0] * model.adim, [0.0] * model.sdim)
    except RuntimeErr:
        return math.nan
    except (OverflowError, ValueError):
        return math.nan
    return v


def main(argv):
    if len(argv) != 2:
        sys.stderr.write("usage: hfref.py FILE.hf < POINTS\n")
        return 64
    try:
        with open(argv[1], "rb") as fh:
            text = fh.read().decode("latin-1").replace("\r\n", "\n")
        model = load(text)
        out = []
        for line in sys.stdin:
            if not line.strip() or line.startswith("#"):
                continue
            pt = [float(t) for t in line.split()[:3]]
            out.append(value_at(model, pt))
    except Reject as e:
        sys.stderr.write("reject: %s\n" % e)
        return 2
    except Unsupported as e:
        sys.stderr.write("unsupported: %s\n" % e)
        return 3
    for v in out:
        sys.stdout.write("nan\n" if math.isnan(v) else repr(v) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
