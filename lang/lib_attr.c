/* lib_attr.c - HyperFun's attribute library (hfA_*) and hfSawtooth, expanded into IR
 * like the rest of the library (lang/lib.c lists them; doc/library.md documents them).
 *
 * The attribute functions set the s[] array of a model (colours and other values a
 * point carries, frep_eval_attrs_par): their 'w' arguments are arrays written in
 * place, as the reference functions write through the array pointer they are given.
 * Each expander follows the reference source named above it (src/hflibrary_lib/ of
 * HyperFun); the reference passes arguments last first, so its f_a[0] is the last
 * argument of the call.  Reference constants: EPS = 1e-6 (int_global.c).
 */
#include <math.h>

#include "lib_impl.h"

#define HF_ATTR_EPS 1e-6
/* Terms of hfSawtooth's sum: each is a sine node of the expansion, so a bound keeps a
 * typo (n = 1e9) from exhausting the IR; far above any use of a sawtooth wave. */
#define FREP_SAWTOOTH_MAX_TERMS 4096
/* Terms of hfA_Turbulence's sum (one per octave, each 8 gradients of 3 sines):
 * freq must be below 2^32. */
#define FREP_TURBULENCE_MAX_TERMS 32

static ir_ref k_(lib_ctx *c, double v) { return ir_k(c->g, v); }
static ir_ref sel(lib_ctx *c, ir_ref cond, ir_ref a, ir_ref b) { return ir_select(c->g, cond, a, b); }
static ir_ref lt(lib_ctx *c, ir_ref a, ir_ref b) { return ir_op2(c->g, FREP_OP_LT, a, b); }
static ir_ref gt(lib_ctx *c, ir_ref a, ir_ref b) { return ir_op2(c->g, FREP_OP_GT, a, b); }
static ir_ref ge(lib_ctx *c, ir_ref a, ir_ref b) { return ir_op2(c->g, FREP_OP_GE, a, b); }

/* An array argument of at least `need` elements, else an error at the call. */
static int attr_size(lib_ctx *c, const lib_arg *a, uint32_t need, const char *fn,
                     const char *what)
{
    if (a->n >= need) return 1;
    c->error(c, "%s: array '%s' needs at least %u elements, it has %u", fn, what,
             (unsigned)need, (unsigned)a->n);
    return 0;
}

/* hfSawtooth(t, n, a, f) (myfunc.c): with N = int(n), 0 when N <= 1, else
 * (0.5 - sum_{k=1}^{N-1} sin(2 pi k f t) / k) * (2 / (a pi)); n must be a constant. */
LIB_EXPANDER(hf_sawtooth)
{
    ir *g = c->g;
    ir_ref t = a[0].s, amp = a[2].s, f = a[3].s, res;
    double nk;
    long terms, k;
    (void)n;
    if (!ir_is_const(g, a[1].s, &nk))
        return c->error(c, "hfSawtooth: the number of terms n must be a constant");
    if (!(fabs(nk) <= FREP_SAWTOOTH_MAX_TERMS))
        return c->error(c, "hfSawtooth: n = %g terms, at most %d", nk, FREP_SAWTOOTH_MAX_TERMS);
    terms = (long)nk;
    if (terms <= 1) return k_(c, 0.0);
    res = k_(c, 0.5);
    for (k = 1; k < terms; k++) {
        double dk = (double)k;
        ir_ref arg = ir_mul(g, ir_mul(g, k_(c, 2 * M_PI * dk), f), t);
        res = ir_sub(g, res, ir_div(g, ir_op1(g, FREP_OP_SIN, arg), k_(c, dk)));
    }
    return ir_mul(g, res, ir_div(g, k_(c, 2.0), ir_mul(g, amp, k_(c, M_PI))));
}

/* hfA_SetColor(f, s, r, g, b) (hfA_SetColor.c): s[1..3] = r, g, b where f >= 0;
 * value 1. */
LIB_EXPANDER(hfa_set_color)
{
    ir_ref on = ge(c, a[0].s, k_(c, 0.0));
    uint32_t i;
    (void)n;
    if (!attr_size(c, &a[1], 3, "hfA_SetColor", "s")) return IR_NONE;
    for (i = 0; i < 3; i++) a[1].elems[i] = sel(c, on, a[2 + i].s, a[1].elems[i]);
    return k_(c, 1.0);
}

/* hfA_SetAttributes(f, s, s1) (hfA_SetAttributes.c): s[i] = s1[i] for i up to the
 * smaller size where f >= 0; value 1. */
LIB_EXPANDER(hfa_set_attributes)
{
    ir_ref on = ge(c, a[0].s, k_(c, 0.0));
    uint32_t m = a[1].n < a[2].n ? a[1].n : a[2].n, i;
    (void)n;
    for (i = 0; i < m; i++) a[1].elems[i] = sel(c, on, a[2].elems[i], a[1].elems[i]);
    return k_(c, 1.0);
}

/* hfA_Union(f1, f2, s, s1, s2, op) (hfA_Union.c): the value u = f1 + f2 +
 * sqrt(f1^2 + f2^2); where u > -EPS, s takes s1 where only f1 >= 0, s2 where only
 * f2 >= 0, else by op = int(op): 0 s1, 1 s2, 2 s1 + s2, 3 min, 4 max (others: s
 * unchanged).  s1 and s2 need as many elements as s. */
LIB_EXPANDER(hfa_union)
{
    ir *g = c->g;
    ir_ref f1 = a[0].s, f2 = a[1].s, op = ir_op1(g, FREP_OP_INT, a[5].s), zero = k_(c, 0.0);
    ir_ref u = ir_add(g, ir_add(g, f1, f2),
                      ir_sqrt(g, ir_add(g, ir_mul(g, f1, f1), ir_mul(g, f2, f2))));
    ir_ref inside = gt(c, u, k_(c, -HF_ATTR_EPS));
    ir_ref only1 = ir_op2(g, FREP_OP_AND, ge(c, f1, zero), lt(c, f2, zero));
    ir_ref only2 = ir_op2(g, FREP_OP_AND, ge(c, f2, zero), lt(c, f1, zero));
    uint32_t i, dim = a[2].n;
    (void)n;
    if (!attr_size(c, &a[3], dim, "hfA_Union", "s1") ||
        !attr_size(c, &a[4], dim, "hfA_Union", "s2"))
        return IR_NONE;
    for (i = 0; i < dim; i++) {
        ir_ref c1 = a[3].elems[i], c2 = a[4].elems[i], old = a[2].elems[i];
        ir_ref mn = sel(c, gt(c, c1, c2), c2, c1), mx = sel(c, gt(c, c1, c2), c1, c2);
        ir_ref by_op = sel(c, ir_op2(g, FREP_OP_EQ, op, k_(c, 0)), c1,
                       sel(c, ir_op2(g, FREP_OP_EQ, op, k_(c, 1)), c2,
                       sel(c, ir_op2(g, FREP_OP_EQ, op, k_(c, 2)), ir_add(g, c1, c2),
                       sel(c, ir_op2(g, FREP_OP_EQ, op, k_(c, 3)), mn,
                       sel(c, ir_op2(g, FREP_OP_EQ, op, k_(c, 4)), mx, old)))));
        a[2].elems[i] = sel(c, inside, sel(c, only1, c1, sel(c, only2, c2, by_op)), old);
    }
    return u;
}

/* hfA_Lerp / hfA_Cerp(s, s1, s2, f, fmin, fmax) (hfA_lerp.c): t = (f - fmin) /
 * (fmax - fmin) (Cerp: then t^2 (3 - 2t)); s = s1 where t < 0, s2 where t > 1, else
 * (1 - t) s1 + t s2; value t.  s1 and s2 need as many elements as s. */
static ir_ref lerp(lib_ctx *c, lib_arg *a, int cubic, const char *fn)
{
    ir *g = c->g;
    ir_ref t = ir_div(g, ir_sub(g, a[3].s, a[4].s), ir_sub(g, a[5].s, a[4].s));
    ir_ref below, above;
    uint32_t i, dim = a[0].n;
    if (!attr_size(c, &a[1], dim, fn, "s1") || !attr_size(c, &a[2], dim, fn, "s2"))
        return IR_NONE;
    if (cubic)
        t = ir_mul(g, ir_mul(g, t, t), ir_sub(g, k_(c, 3.0), ir_mul(g, k_(c, 2.0), t)));
    below = lt(c, t, k_(c, 0.0));
    above = gt(c, t, k_(c, 1.0));
    for (i = 0; i < dim; i++) {
        ir_ref s1 = a[1].elems[i], s2 = a[2].elems[i];
        ir_ref mix = ir_add(g, ir_mul(g, ir_sub(g, k_(c, 1.0), t), s1), ir_mul(g, t, s2));
        a[0].elems[i] = sel(c, below, s1, sel(c, above, s2, mix));
    }
    return t;
}
LIB_EXPANDER(hfa_lerp) { (void)n; return lerp(c, a, 0, "hfA_Lerp"); }
LIB_EXPANDER(hfa_cerp) { (void)n; return lerp(c, a, 1, "hfA_Cerp"); }

/* hfA_Clamp(f, lo, hi) (hfA_ToolBox.c): lo where f < lo, hi where f > hi, else f. */
LIB_EXPANDER(hfa_clamp)
{
    (void)n;
    return sel(c, lt(c, a[0].s, a[1].s), a[1].s, sel(c, gt(c, a[0].s, a[2].s), a[2].s, a[0].s));
}

/* hfA_Floor(v) (hfA_ToolBox.c): the C conversion (int)v, so truncation toward 0. */
LIB_EXPANDER(hfa_floor)
{
    (void)n;
    return ir_op1(c->g, FREP_OP_INT, a[0].s);
}

/* hfA_Pulse(f, p, q) (hfA_ToolBox.c): 0 where f < q or f > p, else 1 (the reference
 * compares f with its third argument first). */
LIB_EXPANDER(hfa_pulse)
{
    ir_ref out = ir_op2(c->g, FREP_OP_OR, lt(c, a[0].s, a[2].s), gt(c, a[0].s, a[1].s));
    (void)n;
    return sel(c, out, k_(c, 0.0), k_(c, 1.0));
}

/* hfA_Step(f, e) (hfA_ToolBox.c): 0 where f < e, else 1. */
LIB_EXPANDER(hfa_step)
{
    (void)n;
    return sel(c, lt(c, a[0].s, a[1].s), k_(c, 0.0), k_(c, 1.0));
}

/* hfA_SmoothStep(f, lo, hi) (hfA_ToolBox.c): 1 where f > hi, 0 where f < lo, else
 * t^2 (3 - 2t) with t = (f - lo) / (hi - lo). */
LIB_EXPANDER(hfa_smooth_step)
{
    ir *g = c->g;
    ir_ref t = ir_div(g, ir_sub(g, a[0].s, a[1].s), ir_sub(g, a[2].s, a[1].s));
    ir_ref s = ir_mul(g, ir_mul(g, t, t), ir_sub(g, k_(c, 3.0), ir_mul(g, k_(c, 2.0), t)));
    (void)n;
    return sel(c, gt(c, a[0].s, a[2].s), k_(c, 1.0),
               sel(c, lt(c, a[0].s, a[1].s), k_(c, 0.0), s));
}

/* hfA_Modulo(v, m) (hfA_ToolBox.c): r = v - int(v / m) m, then r + m where r < 0. */
LIB_EXPANDER(hfa_modulo)
{
    ir *g = c->g;
    ir_ref q = ir_op1(g, FREP_OP_INT, ir_div(g, a[0].s, a[1].s));
    ir_ref r = ir_sub(g, a[0].s, ir_mul(g, q, a[1].s));
    (void)n;
    return sel(c, lt(c, r, k_(c, 0.0)), ir_add(g, r, a[1].s), r);
}

/* hfA_Wave(v, c1, c2, freq) (hfA_Wave.c): w = (1 + sin(freq v)) / 2, then
 * w (c1 - c2) + c2 where c1 > c2, else w (c2 - c1) + c1. */
LIB_EXPANDER(hfa_wave)
{
    ir *g = c->g;
    ir_ref c1 = a[1].s, c2 = a[2].s;
    ir_ref w = ir_div(g, ir_add(g, k_(c, 1.0), ir_op1(g, FREP_OP_SIN, ir_mul(g, a[3].s, a[0].s))),
                      k_(c, 2.0));
    (void)n;
    return sel(c, gt(c, c1, c2), ir_add(g, ir_mul(g, w, ir_sub(g, c1, c2)), c2),
               ir_add(g, ir_mul(g, w, ir_sub(g, c2, c1)), c1));
}

/* hfA_RGBToHSV(rgb, hsv) (hfA_RGBToHSV.c): v = max, s = (max - min) / max (0 when
 * max <= 0), h in degrees from the largest component (0 when all are equal); value 1. */
LIB_EXPANDER(hfa_rgb_to_hsv)
{
    ir *g = c->g;
    ir_ref r, gr, b, mn, mx, d, h, zero = k_(c, 0.0);
    (void)n;
    if (!attr_size(c, &a[0], 3, "hfA_RGBToHSV", "rgb") ||
        !attr_size(c, &a[1], 3, "hfA_RGBToHSV", "hsv"))
        return IR_NONE;
    r = a[0].elems[0], gr = a[0].elems[1], b = a[0].elems[2];
    mn = sel(c, lt(c, gr, b), gr, b);
    mn = sel(c, lt(c, r, mn), r, mn);
    mx = sel(c, gt(c, gr, b), gr, b);
    mx = sel(c, gt(c, r, mx), r, mx);
    d = ir_sub(g, mx, mn);
    /* three independent terms, each added where its test holds, in this order */
    h = zero;
    h = sel(c, ir_op2(g, FREP_OP_AND, ir_op2(g, FREP_OP_EQ, mx, r), ir_op2(g, FREP_OP_NE, mx, gr)),
            ir_add(g, h, ir_div(g, ir_sub(g, gr, b), d)), h);
    h = sel(c, ir_op2(g, FREP_OP_AND, ir_op2(g, FREP_OP_EQ, mx, gr), ir_op2(g, FREP_OP_NE, mx, b)),
            ir_add(g, h, ir_add(g, k_(c, 2.0), ir_div(g, ir_sub(g, b, r), d))), h);
    h = sel(c, ir_op2(g, FREP_OP_AND, ir_op2(g, FREP_OP_EQ, mx, b), ir_op2(g, FREP_OP_NE, mx, r)),
            ir_add(g, h, ir_add(g, k_(c, 4.0), ir_div(g, ir_sub(g, r, gr), d))), h);
    a[1].elems[0] = sel(c, gt(c, d, zero), ir_mul(g, h, k_(c, 60.0)), zero);
    a[1].elems[1] = sel(c, gt(c, mx, zero), ir_div(g, d, mx), zero);
    a[1].elems[2] = mx;
    return k_(c, 1.0);
}

/* hfA_HSVToRGB(hsv, rgb) (hfA_HSVToRGB.c): h brought into [0, 360] (the reference adds
 * or subtracts 360 until it is; here in one step, the same for |h| < 720 and within
 * rounding beyond), then the piecewise-linear hue ramps clamped at 1, mixed with s
 * and scaled by v; value 1. */
LIB_EXPANDER(hfa_hsv_to_rgb)
{
    ir *g = c->g;
    ir_ref h, s, v, r, gr, b, one = k_(c, 1.0), k60 = k_(c, 60.0), k360 = k_(c, 360.0);
    ir_ref zero = k_(c, 0.0), lo, hi, rgb[3];
    uint32_t i;
    (void)n;
    if (!attr_size(c, &a[0], 3, "hfA_HSVToRGB", "hsv") ||
        !attr_size(c, &a[1], 3, "hfA_HSVToRGB", "rgb"))
        return IR_NONE;
    h = a[0].elems[0], s = a[0].elems[1], v = a[0].elems[2];
    h = sel(c, lt(c, h, zero),
            ir_add(g, h, ir_mul(g, k360, ir_op1(g, FREP_OP_CEIL, ir_div(g, ir_neg(g, h), k360)))),
            h);
    h = sel(c, gt(c, h, k360),
            ir_sub(g, h, ir_mul(g, k360, ir_op1(g, FREP_OP_CEIL,
                                                ir_div(g, ir_sub(g, h, k360), k360)))),
            h);
    lo = lt(c, h, k_(c, 120.0));
    hi = lt(c, h, k_(c, 240.0));
    r = sel(c, lo, ir_div(g, ir_sub(g, k_(c, 120.0), h), k60),
            sel(c, hi, zero, ir_div(g, ir_sub(g, h, k_(c, 240.0)), k60)));
    gr = sel(c, lo, ir_div(g, h, k60),
             sel(c, hi, ir_div(g, ir_sub(g, k_(c, 240.0), h), k60), zero));
    b = sel(c, lo, zero,
            sel(c, hi, ir_div(g, ir_sub(g, h, k_(c, 120.0)), k60),
                ir_div(g, ir_sub(g, k360, h), k60)));
    rgb[0] = r, rgb[1] = gr, rgb[2] = b;
    for (i = 0; i < 3; i++) {
        ir_ref ch = sel(c, lt(c, rgb[i], one), rgb[i], one);
        a[1].elems[i] = ir_mul(g, ir_add(g, ir_sub(g, one, s), ir_mul(g, s, ch)), v);
    }
    return k_(c, 1.0);
}

/* ---- patterns, look-up tables, splines (hfA_NoiseG.c, hfA_Crackles.c,
 * hfA_Circles.c, hfA_CheckerBoard.c, hfA_LookUpTable.c, hfA_SmoothLookUpTable.c,
 * hfA_spline.c and pattern.h of HyperFun) ------------------------------------- */

static ir_ref nan_(lib_ctx *c) { return k_(c, NAN); }
static ir_ref and_(lib_ctx *c, ir_ref a, ir_ref b) { return ir_op2(c->g, FREP_OP_AND, a, b); }

/* The Gardner series of pattern.h, normalised to [0, 1]: with a2 the frequency,
 * S = prod over (u, w) in ((x, z), (y, x), (z, y)) of
 *     sin(a2 u) + sin(a2 u / 1.35 + phase sin(a2 w)) / 1.17,
 * then (S - cmin) / (cmax - cmin) with cmax = -cmin = (2.17 / 1.17)^3. */
static ir_ref gardner(lib_ctx *c, const ir_ref x[3], ir_ref phase, ir_ref freq)
{
    ir *g = c->g;
    ir_ref ax[3], sn[3], prod = IR_NONE;
    double cc = 2.17 / 1.17, cmin = pow(-cc, 3), cmax = -cmin;
    int i;
    for (i = 0; i < 3; i++) {
        ax[i] = ir_mul(g, freq, x[i]);
        sn[i] = ir_op1(g, FREP_OP_SIN, ax[i]);
    }
    for (i = 0; i < 3; i++) {
        /* x pairs with sin(a2 z), y with sin(a2 x), z with sin(a2 y) */
        ir_ref other = sn[(i + 2) % 3];
        ir_ref inner = ir_add(g, ir_div(g, ax[i], k_(c, 1.35)), ir_mul(g, phase, other));
        ir_ref ser = ir_add(g, sn[i], ir_mul(g, k_(c, 1.0 / 1.17), ir_op1(g, FREP_OP_SIN, inner)));
        prod = prod == IR_NONE ? ser : ir_mul(g, prod, ser);
    }
    return ir_div(g, ir_sub(g, prod, k_(c, cmin)), k_(c, cmax - cmin));
}

/* hfA_NoiseG(x, freq, phase): the normalised Gardner series at x. */
LIB_EXPANDER(hfa_noise_g)
{
    ir_ref x[3] = { a[0].elems[0], a[0].elems[1], a[0].elems[2] };
    (void)n;
    return gardner(c, x, a[2].s, a[1].s);
}

/* The table step shared by hfA_Circles and hfA_Crackles: the attribute array `attr`
 * first gets attr[nmap + 1] = 1.1 (the reference writes that element, 0-based
 * color[n_prob], before reading; nothing when the array is shorter), then out takes
 * row i of attr (out's size dim elements from dim*i) where map[i] <= v < map[i + 1],
 * i < nmap - 1: the first such row when `first`, else the last; out is unchanged
 * where none holds. */
static int table_rows(lib_ctx *c, ir_ref v, lib_arg *out, lib_arg *attr, const lib_arg *map,
                      int first, const char *fn)
{
    uint32_t dim = out->n, nmap = map->n, rows = nmap > 1 ? nmap - 1 : 0, i, j;
    if (!attr_size(c, attr, dim * rows, fn, "attributes")) return 0;
    if (nmap < attr->n) attr->elems[nmap] = k_(c, 1.1);
    for (j = 0; j < dim; j++) {
        ir_ref r = out->elems[j];
        for (i = 0; i < rows; i++) {
            uint32_t row = first ? rows - 1 - i : i;
            ir_ref in = and_(c, ge(c, v, map->elems[row]), lt(c, v, map->elems[row + 1]));
            r = sel(c, in, attr->elems[dim * row + j], r);
        }
        out->elems[j] = r;
    }
    return 1;
}

/* hfA_Circles(x, out, attr, map) (hfA_Circles.c, ConcentriqueCircle of pattern.h):
 * v = fmod(|x|, 1), then the table step (first matching row); value 1. */
LIB_EXPANDER(hfa_circles)
{
    ir *g = c->g;
    ir_ref r2 = ir_add(g, ir_add(g, ir_sq(g, a[0].elems[0]), ir_sq(g, a[0].elems[1])),
                       ir_sq(g, a[0].elems[2]));
    ir_ref v = ir_op2(g, FREP_OP_MOD, ir_sqrt(g, r2), k_(c, 1.0));
    (void)n;
    if (!table_rows(c, v, &a[1], &a[2], &a[3], 1, "hfA_Circles")) return IR_NONE;
    return k_(c, 1.0);
}

/* hfA_Crackles(x, out, freq, attr, map) (hfA_Crackles.c, Crackles and cycle of
 * pattern.h): phase = (|x1| + |x2| + |x3|) / 3; three Gardner values mapped to
 * [-1, 1], of (x1, x1, x3), (x2, x2, x1), (x3, x3, x2); their sum s; then
 * v = (1 + sin(2 pi i / 1000)) / 2 with i = int(frac_floor(s) * 1000); then the table
 * step (the last matching row: the reference does not stop at the first); value 1. */
LIB_EXPANDER(hfa_crackles)
{
    ir *g = c->g;
    ir_ref *x = a[0].elems, freq = a[2].s, sum = IR_NONE, v, i1000;
    ir_ref phase = ir_div(g, ir_add(g, ir_add(g, ir_op1(g, FREP_OP_ABS, x[0]),
                                              ir_op1(g, FREP_OP_ABS, x[1])),
                                    ir_op1(g, FREP_OP_ABS, x[2])), k_(c, 3.0));
    int k;
    (void)n;
    for (k = 0; k < 3; k++) {
        ir_ref p[3] = { x[k], x[k], x[(k + 2) % 3] };
        ir_ref nz = ir_add(g, k_(c, -1.0), ir_mul(g, gardner(c, p, phase, freq), k_(c, 2.0)));
        sum = sum == IR_NONE ? nz : ir_add(g, sum, nz);
    }
    i1000 = ir_op1(g, FREP_OP_INT, ir_mul(g, ir_sub(g, sum, ir_op1(g, FREP_OP_FLOOR, sum)),
                                          k_(c, 1000.0)));
    v = ir_div(g, ir_add(g, k_(c, 1.0),
                         ir_op1(g, FREP_OP_SIN, ir_div(g, ir_mul(g, ir_mul(g, i1000, k_(c, 2.0)),
                                                                 k_(c, M_PI)),
                                                       k_(c, 1000.0)))),
               k_(c, 2.0));
    if (!table_rows(c, v, &a[1], &a[3], &a[4], 0, "hfA_Crackles")) return IR_NONE;
    return k_(c, 1.0);
}

/* hfA_CheckerBoard(x, block, gap, out, in_block, in_gap) (hfA_CheckerBoard.c): per
 * axis p = block + gap, lo = p floor(x / p), hi = lo + block; where lo < x < hi on all
 * three axes out = in_block, else in_gap (their sizes must agree, else out is left
 * alone; out is written up to that size); value 1. */
LIB_EXPANDER(hfa_checkerboard)
{
    ir *g = c->g;
    ir_ref inside = IR_NONE;
    uint32_t i, dim = a[4].n;
    (void)n;
    if (!attr_size(c, &a[1], 3, "hfA_CheckerBoard", "block") ||
        !attr_size(c, &a[2], 3, "hfA_CheckerBoard", "gap"))
        return IR_NONE;
    if (a[4].n != a[5].n) return k_(c, 1.0);
    if (!attr_size(c, &a[3], dim, "hfA_CheckerBoard", "out")) return IR_NONE;
    for (i = 0; i < 3; i++) {
        ir_ref x = a[0].elems[i], period = ir_add(g, a[2].elems[i], a[1].elems[i]);
        ir_ref lo = ir_mul(g, period, ir_op1(g, FREP_OP_FLOOR, ir_div(g, x, period)));
        ir_ref hi = ir_add(g, lo, a[1].elems[i]);
        ir_ref in = and_(c, gt(c, x, lo), lt(c, x, hi));
        inside = inside == IR_NONE ? in : and_(c, inside, in);
    }
    for (i = 0; i < dim; i++) a[3].elems[i] = sel(c, inside, a[4].elems[i], a[5].elems[i]);
    return k_(c, 1.0);
}

/* hfA_LookUpTable / hfA_SmoothLookUpTable(t, out, table, entries)
 * (hfA_LookUpTable.c, hfA_SmoothLookUpTable.c): with m entries e and rows of out's
 * size in table: the first i < m - 1 with e[i] <= t < e[i + 1] gives row i (smooth:
 * row i mixed with row i + 1 by l = (t - e[i]) / (e[i + 1] - e[i])); otherwise, and
 * also where t is below the first entry (the reference's first-row case there is
 * overwritten by its "none found" case), the last row; value 1. */
static ir_ref lookup(lib_ctx *c, lib_arg *a, int smooth, const char *fn)
{
    ir *g = c->g;
    ir_ref t = a[0].s, *e = a[3].elems;
    uint32_t dim = a[1].n, m = a[3].n, i, j;
    if (!attr_size(c, &a[2], dim * m, fn, "table")) return IR_NONE;
    for (j = 0; j < dim; j++) {
        ir_ref r = a[2].elems[dim * (m - 1) + j];
        for (i = m - 1; i-- > 0;) {
            ir_ref in = and_(c, ge(c, t, e[i]), lt(c, t, e[i + 1]));
            ir_ref row = a[2].elems[dim * i + j];
            if (smooth) {
                ir_ref l = ir_div(g, ir_sub(g, t, e[i]), ir_sub(g, e[i + 1], e[i]));
                row = ir_add(g, ir_mul(g, ir_sub(g, k_(c, 1.0), l), row),
                             ir_mul(g, l, a[2].elems[dim * (i + 1) + j]));
            }
            r = sel(c, in, row, r);
        }
        a[1].elems[j] = sel(c, lt(c, t, e[0]), a[2].elems[dim * (m - 1) + j], r);
    }
    return k_(c, 1.0);
}
LIB_EXPANDER(hfa_lookup_table) { (void)n; return lookup(c, a, 0, "hfA_LookUpTable"); }
LIB_EXPANDER(hfa_smooth_lookup_table)
{
    (void)n;
    return lookup(c, a, 1, "hfA_SmoothLookUpTable");
}

/* hfA_Spline(s, knots, x, xmin, xmax) (hfA_spline.c): a Catmull-Rom spline through
 * K = size(knots) / size(s) control rows of size(s) values.  u = (x - xmin) /
 * (xmax - xmin); s = row 1 where u < 0, row K where u > 1; else with spans = K - 3,
 * v = u spans, span = int(v) (spans - 3 where that is >= spans, as the reference
 * does at u = 1), w = v - span, and rows P0..P3 from row span + 1:
 * s = ((c3 w + c2) w + c1) w + c0 with c3 = -P0/2 + 3P1/2 - 3P2/2 + P3/2,
 * c2 = P0 - 5P1/2 + 2P2 - P3/2, c1 = -P0/2 + P2/2, c0 = P1.  A span outside the rows
 * (fewer than 4 rows, or fewer than 6 at u = 1) reads outside the reference's array:
 * NaN here.  Value 1. */
static ir_ref catmull_rom(lib_ctx *c, const lib_arg *knots, uint32_t dim, uint32_t i,
                          long span, ir_ref w)
{
    ir *g = c->g;
    static const double cr[4][4] = { { -0.5, 1.5, -1.5, 0.5 }, { 1.0, -2.5, 2.0, -0.5 },
                                     { -0.5, 0.0, 0.5, 0.0 }, { 0.0, 1.0, 0.0, 0.0 } };
    ir_ref coef[4], r;
    int row, k;
    for (row = 0; row < 4; row++) {
        ir_ref sum = IR_NONE;
        for (k = 0; k < 4; k++) {
            ir_ref term = ir_mul(g, k_(c, cr[row][k]), knots->elems[(uint32_t)(span + k) * dim + i]);
            sum = sum == IR_NONE ? term : ir_add(g, sum, term);
        }
        coef[row] = sum;
    }
    r = ir_add(g, ir_mul(g, ir_add(g, ir_mul(g, ir_add(g, ir_mul(g, coef[0], w), coef[1]), w),
                                   coef[2]), w), coef[3]);
    return r;
}

LIB_EXPANDER(hfa_spline)
{
    ir *g = c->g;
    uint32_t dim = a[0].n, rows = dim ? a[1].n / dim : 0, i;
    long spans = (long)rows - 3, sp;
    ir_ref u, v, span, below, above;
    (void)n;
    if (rows == 0)
        return c->error(c, "hfA_Spline: array 'knots' needs at least %u elements, it has %u",
                        (unsigned)dim, (unsigned)a[1].n);
    u = ir_div(g, ir_sub(g, a[2].s, a[3].s), ir_sub(g, a[4].s, a[3].s));
    below = lt(c, u, k_(c, 0.0));
    above = gt(c, u, k_(c, 1.0));
    v = ir_mul(g, u, k_(c, (double)spans));
    span = ir_op1(g, FREP_OP_INT, v);
    for (i = 0; i < dim; i++) {
        ir_ref r = nan_(c);
        if (spans >= 3) {
            long last = spans - 3;
            r = sel(c, ge(c, span, k_(c, (double)spans)),
                    catmull_rom(c, &a[1], dim, i, last, ir_sub(g, v, k_(c, (double)last))), r);
        }
        for (sp = 0; sp < spans; sp++)
            r = sel(c, ir_op2(g, FREP_OP_EQ, span, k_(c, (double)sp)),
                    catmull_rom(c, &a[1], dim, i, sp, ir_sub(g, v, k_(c, (double)sp))), r);
        a[0].elems[i] = sel(c, below, a[1].elems[i],
                            sel(c, above, a[1].elems[(rows - 1) * dim + i], r));
    }
    return k_(c, 1.0);
}

/* hfBezierVolume(x, l, m, n, bbox, w) (hfBezierVolume.c, Bezier.c): with the box
 * bbox = (xmin, ymin, zmin, xmax, ymax, zmax) and u, v, t the point's coordinates
 * mapped to [0, 1] by it (u from x1, v from x3, t from x2: the reference's order),
 * B = sum_{i<l, j<m, k<n} b(i, l-1, u) b(j, m-1, v) b(k, n-1, t) w[i m n + j n + k]
 * with the Bernstein polynomial b(i, d, s) = C(d, i) (1 - s)^(d - i) s^i, clipped by
 * the box: R_int(R_int(R_int(X, Y), Z), B), X = (xmax - x1)(x1 - xmin) and so on,
 * R_int(p, q) = p + q - sqrt(p^2 + q^2).  l, m, n are truncated and must be
 * constants (each term is a node); the reference's binomial table stops at degree
 * 20, so each is at most 21.  An x of other than 3 elements gives the reference's
 * -1111111111111. */
#define FREP_BEZIER_MAX_ORDER 21

static ir_ref r_int(ir *g, ir_ref p, ir_ref q)
{
    return ir_sub(g, ir_add(g, p, q), ir_sqrt(g, ir_add(g, ir_sq(g, p), ir_sq(g, q))));
}

/* (b(0, d, s), ..., b(d, d, s)) into out[0..d]. */
static void bernstein(lib_ctx *c, long d, ir_ref s, ir_ref *out)
{
    ir *g = c->g;
    ir_ref one_s = ir_sub(g, k_(c, 1.0), s);
    long i, k;
    for (i = 0; i <= d; i++) {
        double binom = 1;
        ir_ref r;
        for (k = 1; k <= i; k++) binom = binom * (double)(d - i + k) / (double)k;
        r = k_(c, binom);
        for (k = 0; k < d - i; k++) r = ir_mul(g, r, one_s);
        for (k = 0; k < i; k++) r = ir_mul(g, r, s);
        out[i] = r;
    }
}

LIB_EXPANDER(hf_bezier_volume)
{
    ir *g = c->g;
    static const char *const names[3] = { "l", "m", "n" };
    long ord[3];
    ir_ref *x = a[0].elems, *box = a[4].elems, *w = a[5].elems, par[3], cube, sum;
    ir_ref bas[3][FREP_BEZIER_MAX_ORDER];
    int k;
    long i, j, q;
    (void)n;
    for (k = 0; k < 3; k++) {
        double d;
        if (!ir_is_const(g, a[1 + k].s, &d))
            return c->error(c, "hfBezierVolume: the order %s must be a constant", names[k]);
        if (!(fabs(d) < FREP_BEZIER_MAX_ORDER + 1))
            return c->error(c, "hfBezierVolume: order %s = %g, at most %d (the reference's "
                               "binomial table ends at degree 20)", names[k], d,
                            FREP_BEZIER_MAX_ORDER);
        ord[k] = (long)d;
        if (ord[k] < 0) ord[k] = 0;
    }
    if (!attr_size(c, &a[4], 6, "hfBezierVolume", "bbox") ||
        !attr_size(c, &a[5], (uint32_t)(ord[0] * ord[1] * ord[2]), "hfBezierVolume", "w"))
        return IR_NONE;
    if (a[0].n != 3) return k_(c, -1111111111111.0);
    /* u from x1, v from x3 (order m), t from x2 (order n) */
    for (k = 0; k < 3; k++)
        par[k] = ir_div(g, ir_sub(g, x[k], box[k]), ir_sub(g, box[3 + k], box[k]));
    if (ord[0] > 0) bernstein(c, ord[0] - 1, par[0], bas[0]);
    if (ord[1] > 0) bernstein(c, ord[1] - 1, par[2], bas[1]);
    if (ord[2] > 0) bernstein(c, ord[2] - 1, par[1], bas[2]);
    sum = k_(c, 0.0);
    for (i = 0; i < ord[0]; i++)
        for (j = 0; j < ord[1]; j++)
            for (q = 0; q < ord[2]; q++)
                sum = ir_add(g, sum,
                             ir_mul(g, ir_mul(g, ir_mul(g, bas[0][i], bas[1][j]), bas[2][q]),
                                    w[i * ord[1] * ord[2] + j * ord[2] + q]));
    cube = IR_NONE;
    for (k = 0; k < 3; k++) {
        ir_ref side = ir_mul(g, ir_sub(g, box[3 + k], x[k]), ir_sub(g, x[k], box[k]));
        cube = cube == IR_NONE ? side : r_int(g, cube, side);
    }
    return r_int(g, cube, sum);
}

/* hfA_NoiseP(x) and hfA_Turbulence(x, freq) (hfA_noisep.c, hfA_turbulence.c, perlin.h):
 * Perlin's gradient noise noise3 as the reference computes it - a unit gradient at
 * each integer lattice point, the offsets to the cell's 8 corners dotted with their
 * gradients, blended with the s-curve 3t^2 - 2t^3 along x, then y, then z; 0 at every
 * lattice point, values within about [-1, 1] - except where its gradients come from.
 * The reference draws them and a permutation from rand() after srand(time(NULL)), so
 * its noise differs on every run (and with every C library's rand); frep takes the
 * gradient at lattice point (i, j, k) from a fixed hash, the fractional part of
 * 43758.5453 sin(a i + b j + c k) for three (a, b, c), mapped to [-1, 1) and
 * normalised: the same noise on every run, with no period (the reference's repeats
 * every 256 cells).  Both are attribute functions: a model's solid does not depend on
 * them unless the model uses their values. */
static const double perlin_hash[3][3] = {
    { 12.9898, 78.233, 37.719 }, { 39.3467, 11.1351, 83.1554 }, { 73.156, 52.235, 9.151 }
};
#define PERLIN_HASH_SCALE 43758.5453

static ir_ref fract_(lib_ctx *c, ir_ref v)
{
    return ir_sub(c->g, v, ir_op1(c->g, FREP_OP_FLOOR, v));
}

/* The gradient at the lattice point (i, j, k), a unit vector. */
static lv3 perlin_gradient(lib_ctx *c, const ir_ref ijk[3])
{
    ir *g = c->g;
    ir_ref e[3];
    lv3 v;
    int m, d;
    for (m = 0; m < 3; m++) {
        ir_ref lin = IR_NONE;
        for (d = 0; d < 3; d++) {
            ir_ref t = ir_mul(g, ijk[d], k_(c, perlin_hash[m][d]));
            lin = lin == IR_NONE ? t : ir_add(g, lin, t);
        }
        e[m] = ir_sub(g, ir_mul(g, k_(c, 2.0),
                                fract_(c, ir_mul(g, ir_op1(g, FREP_OP_SIN, lin),
                                                 k_(c, PERLIN_HASH_SCALE)))),
                      k_(c, 1.0));
    }
    v = lv3_make(e[0], e[1], e[2]);
    /* |v| >= 1 unless all three hashes are 1/2 at once: the bound only keeps the
     * division defined */
    return lv3_div(g, v, ir_sqrt(g, ir_op2(g, FREP_OP_MAX, lv3_len2(g, v), k_(c, 1e-300))));
}

static ir_ref lerp_(lib_ctx *c, ir_ref t, ir_ref a, ir_ref b)
{
    return ir_add(c->g, a, ir_mul(c->g, t, ir_sub(c->g, b, a)));
}

/* noise3 at the point p (three refs). */
static ir_ref perlin3(lib_ctx *c, const ir_ref p[3])
{
    ir *g = c->g;
    ir_ref cell[3], r[3], s[3], val[8];
    int d, corner;
    for (d = 0; d < 3; d++) {
        cell[d] = ir_op1(g, FREP_OP_FLOOR, p[d]);
        r[d] = ir_sub(g, p[d], cell[d]);
        s[d] = ir_mul(g, ir_sq(g, r[d]), ir_sub(g, k_(c, 3.0), ir_mul(g, k_(c, 2.0), r[d])));
    }
    for (corner = 0; corner < 8; corner++) { /* bit 0: x + 1, bit 1: y + 1, bit 2: z + 1 */
        ir_ref ijk[3], off[3];
        for (d = 0; d < 3; d++) {
            int up = (corner >> d) & 1;
            ijk[d] = up ? ir_add(g, cell[d], k_(c, 1.0)) : cell[d];
            off[d] = up ? ir_sub(g, r[d], k_(c, 1.0)) : r[d];
        }
        val[corner] = lv3_dot(g, perlin_gradient(c, ijk), lv3_make(off[0], off[1], off[2]));
    }
    for (d = 0; d < 3; d++) { /* blend along x, then y, then z */
        int half = 8 >> (d + 1), i;
        for (i = 0; i < half; i++) val[i] = lerp_(c, s[d], val[2 * i], val[2 * i + 1]);
    }
    return val[0];
}

/* hfA_NoiseP(x): noise3 at (x[1], x[2], x[3]). */
LIB_EXPANDER(hfa_noise_p)
{
    (void)n;
    return perlin3(c, a[0].elems);
}

/* hfA_Turbulence(x, freq): the sum of |2 noise3(f x) - 1| / f over f = freq, freq/2,
 * ... while f >= 1 (none when freq < 1: 0).  freq must be a constant, the number of
 * terms at most FREP_TURBULENCE_MAX_TERMS. */
LIB_EXPANDER(hfa_turbulence)
{
    ir *g = c->g;
    ir_ref sum = IR_NONE;
    double f;
    int terms = 0;
    (void)n;
    if (!ir_is_const(g, a[1].s, &f))
        return c->error(c, "hfA_Turbulence: the frequency freq must be a constant");
    if (!(f < ldexp(1.0, FREP_TURBULENCE_MAX_TERMS)))
        return c->error(c, "hfA_Turbulence: freq = %g gives more than %d terms (freq < 2^%d)",
                        f, FREP_TURBULENCE_MAX_TERMS, FREP_TURBULENCE_MAX_TERMS);
    for (; f >= 1.0; f /= 2, terms++) {
        ir_ref p[3], term;
        int d;
        for (d = 0; d < 3; d++) p[d] = ir_mul(g, a[0].elems[d], k_(c, f));
        term = ir_op1(g, FREP_OP_ABS,
                      ir_sub(g, ir_mul(g, k_(c, 2.0), perlin3(c, p)), k_(c, 1.0)));
        term = ir_div(g, term, k_(c, f));
        sum = sum == IR_NONE ? term : ir_add(g, sum, term);
    }
    return terms ? sum : k_(c, 0.0);
}
