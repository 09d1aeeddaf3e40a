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

/* The reference's noise and pattern attributes (Perlin noise tables, look-up tables,
 * splines) are known by name but not reproduced: a call is an error saying so. */
LIB_EXPANDER(hfa_unsupported)
{
    (void)a;
    (void)n;
    return c->error(c, "this HyperFun attribute function is not implemented in frep "
                       "(frep implements hfA_SetColor, hfA_SetAttributes, hfA_Union, "
                       "hfA_Lerp, hfA_Cerp, hfA_Wave, hfA_RGBToHSV, hfA_HSVToRGB and the "
                       "toolbox functions)");
}
