/* lib_hf.c - the HyperFun FRep library expanded into IR (called through lib.c's
 * table by lang/lower.c).
 *
 * Each expander re-expresses the formula of the reference library
 * (hflibrary_lib/hf*.c of HyperFun 2.x) with the argument order of the reference
 * call; loops over data arrays are unrolled over their compile-time sizes and
 * conditionals become SELECT nodes.  doc/library.md gives every formula and lists
 * where frep deliberately differs (sentinels, globals, divisions by ~0).
 */
#include <math.h>
#include <stddef.h>

#include "lib_impl.h"
#include "util.h"

/* Newton steps of hfDEllipsoid, as the reference: each step is frozen once the
 * residual is below LIB_DELLIPSOID_TOL, so more steps never change a converged value. */
#define LIB_DELLIPSOID_STEPS 128
#define LIB_DELLIPSOID_TOL 1e-6
/* The quartic of the SARDF operations: samples that locate its root's cell, then
 * bisection steps that shrink the cell (width sqrt(min)/32) below double precision. */
#define LIB_SARDF_SAMPLES 32
#define LIB_SARDF_BISECT 50
/* |f| below this counts as "on the surface" in the SARDF operations (reference). */
#define LIB_SARDF_ZERO 1e-7

#define K(v) ir_k(g, (v))
#define OP1(o, a) ir_op1(g, FREP_OP_##o, (a))
#define OP2(o, a, b) ir_op2(g, FREP_OP_##o, (a), (b))

static ir_ref comp(lv3 v, int i) { return i == 0 ? v.x : (i == 1 ? v.y : v.z); }

/* x - center for the primitives called as f(x, center, ...). */
static lv3 rel(ir *g, const lib_arg *a)
{
    return lv3_sub(g, lv3_at(a[0].elems, 0), lv3_at(a[1].elems, 0));
}

/* The two axes other than `axis`, in the order the reference uses them. */
static void other_axes(int axis, int *i, int *j)
{
    *i = axis == 0 ? 1 : 0;
    *j = axis == 2 ? 1 : 2;
}

/* Array-size check of a 'v' argument: at least `need` elements. */
static int need_size(lib_ctx *c, const lib_arg *a, uint32_t need, const char *fn,
                     const char *what)
{
    if (a->n >= need) return 1;
    c->error(c, "%s: array '%s' needs at least %u elements, it has %u", fn, what,
             (unsigned)need, (unsigned)a->n);
    return 0;
}

/* Constant argument that must not be 0 (the reference's R_ checks reject it). */
static int nonzero_const(lib_ctx *c, ir_ref r, const char *fn, const char *what)
{
    double k;
    if (ir_is_const(c->g, r, &k) && k == 0) {
        c->error(c, "%s: %s must not be 0", fn, what);
        return 0;
    }
    return 1;
}

/* ---- quadrics ------------------------------------------------------------ */

/* hfSphere(x, center, R) = R^2 - |x - center|^2 */
LIB_EXPANDER(hf_sphere)
{
    ir *g = c->g;
    (void)n;
    return ir_sub(g, ir_sq(g, a[2].s), lv3_len2(g, rel(g, a)));
}

/* hfEllipsoid(x, center, a, b, c) = 1 - (dx/a)^2 - (dy/b)^2 - (dz/c)^2 */
LIB_EXPANDER(hf_ellipsoid)
{
    ir *g = c->g;
    (void)n;
    lv3 d = rel(g, a);
    ir_ref f = ir_sub(g, K(1.0), ir_sq(g, ir_div(g, d.x, a[2].s)));
    f = ir_sub(g, f, ir_sq(g, ir_div(g, d.y, a[3].s)));
    return ir_sub(g, f, ir_sq(g, ir_div(g, d.z, a[4].s)));
}

/* hfCylinderA(x, center, R) = R^2 - d_i^2 - d_j^2 for the axes i, j other than A */
static ir_ref cylinder(lib_ctx *c, lib_arg *a, int axis)
{
    ir *g = c->g;
    int i, j;
    other_axes(axis, &i, &j);
    lv3 d = rel(g, a);
    return ir_sub(g, ir_sub(g, ir_sq(g, a[2].s), ir_sq(g, comp(d, i))), ir_sq(g, comp(d, j)));
}
LIB_EXPANDER(hf_cylinder_x) { (void)n; return cylinder(c, a, 0); }
LIB_EXPANDER(hf_cylinder_y) { (void)n; return cylinder(c, a, 1); }
LIB_EXPANDER(hf_cylinder_z) { (void)n; return cylinder(c, a, 2); }

/* hfEllCylA(x, center, a, b) = 1 - (d_i/a)^2 - (d_j/b)^2 */
static ir_ref ellcyl(lib_ctx *c, lib_arg *a, int axis)
{
    ir *g = c->g;
    int i, j;
    other_axes(axis, &i, &j);
    lv3 d = rel(g, a);
    ir_ref f = ir_sub(g, K(1.0), ir_sq(g, ir_div(g, comp(d, i), a[2].s)));
    return ir_sub(g, f, ir_sq(g, ir_div(g, comp(d, j), a[3].s)));
}
LIB_EXPANDER(hf_ellcyl_x) { (void)n; return ellcyl(c, a, 0); }
LIB_EXPANDER(hf_ellcyl_y) { (void)n; return ellcyl(c, a, 1); }
LIB_EXPANDER(hf_ellcyl_z) { (void)n; return ellcyl(c, a, 2); }

/* hfEllConeA(x, center, a, b) = d_A^2 - (d_i/a)^2 - (d_j/b)^2; hfConeA uses a = b = R */
static ir_ref ellcone(lib_ctx *c, lib_arg *a, int axis, ir_ref ra, ir_ref rb)
{
    ir *g = c->g;
    int i, j;
    other_axes(axis, &i, &j);
    lv3 d = rel(g, a);
    ir_ref f = ir_sub(g, ir_sq(g, comp(d, axis)), ir_sq(g, ir_div(g, comp(d, i), ra)));
    return ir_sub(g, f, ir_sq(g, ir_div(g, comp(d, j), rb)));
}
LIB_EXPANDER(hf_cone_x) { (void)n; return ellcone(c, a, 0, a[2].s, a[2].s); }
LIB_EXPANDER(hf_cone_y) { (void)n; return ellcone(c, a, 1, a[2].s, a[2].s); }
LIB_EXPANDER(hf_cone_z) { (void)n; return ellcone(c, a, 2, a[2].s, a[2].s); }
LIB_EXPANDER(hf_ellcone_x) { (void)n; return ellcone(c, a, 0, a[2].s, a[3].s); }
LIB_EXPANDER(hf_ellcone_y) { (void)n; return ellcone(c, a, 1, a[2].s, a[3].s); }
LIB_EXPANDER(hf_ellcone_z) { (void)n; return ellcone(c, a, 2, a[2].s, a[3].s); }

/* hfTorusA(x, center, R, r0) = r0^2 - |d|^2 - R^2 + 2 R sqrt(d_i^2 + d_j^2) */
static ir_ref torus(lib_ctx *c, lib_arg *a, int axis)
{
    ir *g = c->g;
    int i, j;
    other_axes(axis, &i, &j);
    lv3 d = rel(g, a);
    ir_ref R = a[2].s, r0 = a[3].s;
    ir_ref rho = ir_sqrt(g, ir_add(g, ir_sq(g, comp(d, i)), ir_sq(g, comp(d, j))));
    ir_ref f = ir_sub(g, ir_sub(g, ir_sq(g, r0), lv3_len2(g, d)), ir_sq(g, R));
    return ir_add(g, f, ir_mul(g, ir_mul(g, K(2.0), R), rho));
}
LIB_EXPANDER(hf_torus_x) { (void)n; return torus(c, a, 0); }
LIB_EXPANDER(hf_torus_y) { (void)n; return torus(c, a, 1); }
LIB_EXPANDER(hf_torus_z) { (void)n; return torus(c, a, 2); }

/* Intersection used by hfBlock, following the set-operation semantics in force (the
 * reference reads its global ALPHA: 1 means min, else the R-alpha formula without
 * the 1/(1+alpha) factor, R0 for alpha = 0). */
static ir_ref block_int(lib_ctx *c, ir_ref p, ir_ref q)
{
    ir *g = c->g;
    switch ((frep_setops)c->setops) {
    case FREP_SETOPS_MINMAX: return OP2(MIN, p, q);
    case FREP_SETOPS_RALPHA:
        if (c->alpha == 1.0) return OP2(MIN, p, q);
        return ir_sub(g, ir_add(g, p, q),
                      lib_sqrt0(g, ir_sub(g, ir_add(g, ir_sq(g, p), ir_sq(g, q)),
                                          ir_mul(g, K(2.0 * c->alpha), ir_mul(g, p, q)))));
    case FREP_SETOPS_RFUNC: break;
    }
    return OP2(RINT, p, q);
}

/* hfBlock(x, vertex, dx, dy, dz): intersection of the slabs
 * (x - v)(v + dx - x) >= 0 along each axis. */
LIB_EXPANDER(hf_block)
{
    ir *g = c->g;
    (void)n;
    ir_ref s[3];
    for (int i = 0; i < 3; ++i) {
        ir_ref x = a[0].elems[i], v = a[1].elems[i];
        s[i] = ir_mul(g, ir_sub(g, x, v), ir_sub(g, ir_add(g, v, a[2 + i].s), x));
    }
    return block_int(c, block_int(c, s[0], s[1]), s[2]);
}

/* hfSuperell(x, center, a, b, c, s1, s2) =
 *   1 - (|dx/a|^(2/s2) + |dy/b|^(2/s2))^(s2/s1) - |dz/c|^(2/s1) */
LIB_EXPANDER(hf_superell)
{
    ir *g = c->g;
    (void)n;
    lv3 d = rel(g, a);
    ir_ref s1 = a[5].s, s2 = a[6].s;
    ir_ref p = ir_div(g, K(2.0), s2);
    ir_ref xp = OP2(POW, OP1(ABS, ir_div(g, d.x, a[2].s)), p);
    ir_ref yp = OP2(POW, OP1(ABS, ir_div(g, d.y, a[3].s)), p);
    ir_ref zp = OP2(POW, OP1(ABS, ir_div(g, d.z, a[4].s)), ir_div(g, K(2.0), s1));
    ir_ref xyp = OP2(POW, ir_add(g, xp, yp), ir_div(g, s2, s1));
    return ir_sub(g, ir_sub(g, K(1.0), xyp), zp);
}

/* ---- implicit surfaces from key points ------------------------------------ */

/* Squared distance from x to key point i of the arrays x0, y0, z0. */
static ir_ref key_r2(ir *g, const lib_arg *a, uint32_t i)
{
    lv3 k = lv3_make(a[1].elems[i], a[2].elems[i], a[3].elems[i]);
    return lv3_len2(g, lv3_sub(g, lv3_at(a[0].elems, 0), k));
}

/* Common size check of (x0, y0, z0, arrays...): every array as long as x0. */
static int key_sizes(lib_ctx *c, const lib_arg *a, uint32_t last, const char *fn,
                     const char *const *names)
{
    for (uint32_t k = 2; k <= last; ++k)
        if (!need_size(c, &a[k], a[1].n, fn, names[k])) return 0;
    return 1;
}

/* hfBlobby(x, x0, y0, z0, a, b, T) = sum_i b_i exp(-a_i r_i^2) - T */
LIB_EXPANDER(hf_blobby)
{
    static const char *const names[] = { "x", "x0", "y0", "z0", "a", "b" };
    ir *g = c->g;
    (void)n;
    if (!key_sizes(c, a, 5, "hfBlobby", names)) return IR_NONE;
    ir_ref f = K(0.0);
    for (uint32_t i = 0; i < a[1].n; ++i) {
        ir_ref e = OP1(EXP, ir_mul(g, ir_neg(g, a[4].elems[i]), key_r2(g, a, i)));
        f = ir_add(g, f, ir_mul(g, a[5].elems[i], e));
    }
    return ir_sub(g, f, a[6].s);
}

/* hfMetaball(x, x0, y0, z0, b, d, T) = sum_i m_i - T with, for d_i > 0 (else 0),
 *   m_i = b_i (1 - 3 r^2/d_i^2)      for r <= d_i/3
 *         1.5 b_i (1 - r/d_i)^2       for d_i/3 < r < d_i
 *         0                           for r >= d_i */
LIB_EXPANDER(hf_metaball)
{
    static const char *const names[] = { "x", "x0", "y0", "z0", "b", "d" };
    ir *g = c->g;
    (void)n;
    if (!key_sizes(c, a, 5, "hfMetaball", names)) return IR_NONE;
    ir_ref f = K(0.0);
    for (uint32_t i = 0; i < a[1].n; ++i) {
        ir_ref b = a[4].elems[i], d = a[5].elems[i];
        double dk;
        int dconst = ir_is_const(g, d, &dk);
        if (dconst && !(dk > 0)) continue;          /* the reference skips d <= 0 */
        int quiet = g->quiet;
        if (!dconst) g->quiet = 1;                  /* r/d is speculative when d <= 0 */
        ir_ref r = ir_sqrt(g, key_r2(g, a, i));
        ir_ref rd = ir_div(g, r, d);
        ir_ref near = ir_mul(g, b, ir_sub(g, K(1.0), ir_mul(g, K(3.0), ir_sq(g, rd))));
        ir_ref mid = ir_mul(g, ir_mul(g, K(1.5), b), ir_sq(g, ir_sub(g, K(1.0), rd)));
        ir_ref m = ir_select(g, OP2(LT, r, d), mid, K(0.0));
        m = ir_select(g, OP2(LE, r, ir_div(g, d, K(3.0))), near, m);
        g->quiet = quiet;
        if (!dconst) m = ir_select(g, OP2(GT, d, K(0.0)), m, K(0.0));
        f = ir_add(g, f, m);
    }
    return ir_sub(g, f, a[6].s);
}

/* hfSoft(x, x0, y0, z0, d, T) = sum_i s_i - T with
 *   s_i = 1 - 22 r^2/(9 d^2) + 17 r^4/(9 d^4) - 4 r^6/(9 d^6) for r <= d_i, else 0 */
LIB_EXPANDER(hf_soft)
{
    static const char *const names[] = { "x", "x0", "y0", "z0", "d" };
    ir *g = c->g;
    (void)n;
    if (!key_sizes(c, a, 4, "hfSoft", names)) return IR_NONE;
    ir_ref f = K(0.0);
    for (uint32_t i = 0; i < a[1].n; ++i) {
        ir_ref d = a[4].elems[i];
        ir_ref r2 = key_r2(g, a, i);
        ir_ref q = ir_div(g, r2, ir_sq(g, d));       /* r^2 / d^2 */
        ir_ref q2 = ir_sq(g, q);
        ir_ref s = ir_sub(g, K(1.0), ir_mul(g, K(22.0 / 9.0), q));
        s = ir_add(g, s, ir_mul(g, K(17.0 / 9.0), q2));
        s = ir_sub(g, s, ir_mul(g, K(4.0 / 9.0), ir_mul(g, q2, q)));
        f = ir_add(g, f, ir_select(g, OP2(LE, ir_sqrt(g, r2), d), s, K(0.0)));
    }
    return ir_sub(g, f, a[5].s);
}

/* ---- convolution surfaces with the Cauchy kernel 1/(1 + S^2 r^2)^2 ------------ */

/* hfConvPoint(x, vect, S, T) = sum_i 1/(1 + S_i^2 |x - p_i|^2)^2 - T */
LIB_EXPANDER(hf_conv_point)
{
    ir *g = c->g;
    (void)n;
    uint32_t N = a[2].n;
    if (!need_size(c, &a[1], 3 * N, "hfConvPoint", "vect")) return IR_NONE;
    lv3 x = lv3_at(a[0].elems, 0);
    ir_ref f = K(0.0);
    for (uint32_t i = 0; i < N; ++i) {
        ir_ref r2 = lv3_len2(g, lv3_sub(g, lv3_at(a[1].elems, 3 * i), x));
        ir_ref den = ir_add(g, K(1.0), ir_mul(g, ir_sq(g, a[2].elems[i]), r2));
        f = ir_add(g, f, ir_div(g, K(1.0), ir_sq(g, den)));
    }
    return ir_sub(g, f, a[3].s);
}

/* Closed-form convolution of the Cauchy kernel with S along the segment b -> e
 * (length l, unit direction u): with d = x - b, t = d.u,
 *   p^2 = 1 + S^2 (|d|^2 - t^2),  q^2 = 1 + S^2 |d - l u|^2,
 *   F = t/(2p^2(p^2 + S^2 t^2)) + (l - t)/(2 p^2 q^2)
 *       + (atan(S t/p) + atan(S (l - t)/p)) / (2 S p^3).
 * |d|^2 - t^2 >= 0 is clamped at 0 before use (rounding), and q^2 is computed as
 * 1 + S^2 (|d|^2 + l^2 - 2 l t) clamped the same way. */
static ir_ref cauchy_segment(ir *g, lv3 x, lv3 b, lv3 e, ir_ref S)
{
    lv3 be = lv3_sub(g, e, b);
    ir_ref l = lv3_len(g, be);
    lv3 u = lv3_div(g, be, l);
    lv3 d = lv3_sub(g, x, b);
    ir_ref d2 = lv3_len2(g, d);
    ir_ref t = lv3_dot(g, d, u);
    ir_ref S2 = ir_sq(g, S);
    ir_ref perp = OP2(MAX, ir_sub(g, d2, ir_sq(g, t)), K(0.0));
    ir_ref p2 = ir_add(g, K(1.0), ir_mul(g, S2, perp));
    ir_ref p = ir_sqrt(g, p2);
    ir_ref far = OP2(MAX, ir_sub(g, ir_add(g, d2, ir_sq(g, l)),
                                 ir_mul(g, ir_mul(g, K(2.0), l), t)), K(0.0));
    ir_ref q2 = ir_add(g, K(1.0), ir_mul(g, S2, far));
    ir_ref lt = ir_sub(g, l, t);
    ir_ref f1 = ir_div(g, t, ir_mul(g, ir_mul(g, K(2.0), p2),
                                    ir_add(g, p2, ir_mul(g, S2, ir_sq(g, t)))));
    ir_ref f2 = ir_div(g, lt, ir_mul(g, ir_mul(g, K(2.0), p2), q2));
    ir_ref at = ir_add(g, OP1(ATAN, ir_div(g, ir_mul(g, S, t), p)),
                       OP1(ATAN, ir_div(g, ir_mul(g, S, lt), p)));
    ir_ref f3 = ir_div(g, at, ir_mul(g, ir_mul(g, K(2.0), S), ir_mul(g, p2, p)));
    return ir_add(g, ir_add(g, f1, f2), f3);
}

/* hfConvLine(x, begin, end, S, T) = sum_i F(segment begin_i -> end_i, S_i) - T */
LIB_EXPANDER(hf_conv_line)
{
    ir *g = c->g;
    (void)n;
    uint32_t N = a[3].n;
    if (!need_size(c, &a[1], 3 * N, "hfConvLine", "begin") ||
        !need_size(c, &a[2], 3 * N, "hfConvLine", "end"))
        return IR_NONE;
    lv3 x = lv3_at(a[0].elems, 0);
    ir_ref f = K(0.0);
    for (uint32_t i = 0; i < N; ++i)
        f = ir_add(g, f, cauchy_segment(g, x, lv3_at(a[1].elems, 3 * i),
                                         lv3_at(a[2].elems, 3 * i), a[3].elems[i]));
    return ir_sub(g, f, a[4].s);
}

/* hfConvLineR(x, begin, end, R): segments of "width" R.  S = 1/R when R < 1, else 1;
 * the sum is accumulated while below 1 and clamped at 1; the threshold is the
 * kernel integral at distance R from the last segment:
 *   T = l/(2 pT^2 qT^2) + atan(S l/pT)/(2 S pT^3), pT^2 = 1 + S^2 R^2,
 *   qT^2 = 1 + S^2 (R^2 + l^2). */
LIB_EXPANDER(hf_conv_line_r)
{
    ir *g = c->g;
    (void)n;
    uint32_t N = a[2].n / 3;
    if (N == 0) {
        c->error(c, "hfConvLineR: array 'end' needs at least 3 elements");
        return IR_NONE;
    }
    if (!need_size(c, &a[1], 3 * N, "hfConvLineR", "begin")) return IR_NONE;
    ir_ref R = a[3].s;
    int quiet = g->quiet;
    g->quiet = 1;                                   /* 1/R is speculative when R >= 1 */
    ir_ref S = ir_select(g, OP2(LT, R, K(1.0)), ir_div(g, K(1.0), R), K(1.0));
    g->quiet = quiet;
    ir_ref S2 = ir_sq(g, S);
    lv3 x = lv3_at(a[0].elems, 0);
    ir_ref f = K(0.0), T = K(0.0);
    for (uint32_t i = 0; i < N; ++i) {
        lv3 b = lv3_at(a[1].elems, 3 * i), e = lv3_at(a[2].elems, 3 * i);
        ir_ref l = lv3_len(g, lv3_sub(g, e, b));
        ir_ref pT2 = ir_add(g, K(1.0), ir_mul(g, S2, ir_sq(g, R)));
        ir_ref pT = ir_sqrt(g, pT2);
        ir_ref qT2 = ir_add(g, K(1.0), ir_mul(g, S2, ir_add(g, ir_sq(g, R), ir_sq(g, l))));
        T = ir_add(g, ir_div(g, l, ir_mul(g, ir_mul(g, K(2.0), pT2), qT2)),
                   ir_div(g, OP1(ATAN, ir_div(g, ir_mul(g, S, l), pT)),
                          ir_mul(g, ir_mul(g, K(2.0), S), ir_mul(g, pT2, pT))));
        ir_ref ft = cauchy_segment(g, x, b, e, S);
        f = ir_select(g, OP2(LT, f, K(1.0)), OP2(MIN, ir_add(g, f, ft), K(1.0)), f);
    }
    return ir_sub(g, f, T);
}

/* hfConvCurve(x, vect, S, T) = sum_i F(segment p_i -> p_{i+1}, S_i) - T */
LIB_EXPANDER(hf_conv_curve)
{
    ir *g = c->g;
    (void)n;
    uint32_t N = a[2].n;
    if (!need_size(c, &a[1], 3 * (N + 1), "hfConvCurve", "vect")) return IR_NONE;
    lv3 x = lv3_at(a[0].elems, 0);
    ir_ref f = K(0.0);
    for (uint32_t i = 0; i < N; ++i)
        f = ir_add(g, f, cauchy_segment(g, x, lv3_at(a[1].elems, 3 * i),
                                         lv3_at(a[1].elems, 3 * (i + 1)), a[2].elems[i]));
    return ir_sub(g, f, a[3].s);
}

/* Rotation of v about the unit axis k by angle with cosine co and sine si
 * (Rodrigues' matrix, as the reference writes it for hfConvArc). */
static lv3 rotate_axis(ir *g, lv3 v, lv3 k, ir_ref co, ir_ref si)
{
    ir_ref oc = ir_sub(g, K(1.0), co);
    ir_ref ii = ir_sq(g, k.x), jj = ir_sq(g, k.y), kk = ir_sq(g, k.z);
    ir_ref ij = ir_mul(g, k.x, k.y), jk = ir_mul(g, k.y, k.z), ki = ir_mul(g, k.z, k.x);
    ir_ref is = ir_mul(g, k.x, si), js = ir_mul(g, k.y, si), ks = ir_mul(g, k.z, si);
    lv3 r0 = lv3_make(ir_add(g, co, ir_mul(g, ii, oc)), ir_sub(g, ir_mul(g, ij, oc), ks),
                      ir_add(g, js, ir_mul(g, ki, oc)));
    lv3 r1 = lv3_make(ir_add(g, ks, ir_mul(g, ij, oc)), ir_add(g, co, ir_mul(g, jj, oc)),
                      ir_sub(g, ir_mul(g, jk, oc), is));
    lv3 r2 = lv3_make(ir_sub(g, ir_mul(g, ki, oc), js), ir_add(g, is, ir_mul(g, jk, oc)),
                      ir_add(g, co, ir_mul(g, kk, oc)));
    return lv3_make(lv3_dot(g, r0, v), lv3_dot(g, r1, v), lv3_dot(g, r2, v));
}

/* atanh(z) = (log(1 + z) - log(1 - z)) / 2 */
static ir_ref atanh_ir(ir *g, ir_ref z)
{
    return ir_mul(g, K(0.5), ir_sub(g, OP1(LOG, ir_add(g, K(1.0), z)),
                                    OP1(LOG, ir_sub(g, K(1.0), z))));
}

/* Kernel integral over an arc of radius r and angle th (radians, <= pi) in the
 * xy plane starting on the x axis, for a point p in the arc's frame (Yoshikawa):
 *   a = 2 r S^2, d2 = |p|^2, b = 1 + r^2 S^2 + S^2 d2,
 *   p2 = -r^4 S^4 + 2 r^2 S^2 (S^2 (d2 - 2 z^2) - 1) - (1 + S^2 d2)^2, p1 = sqrt|p2|,
 *   F1 = b y / (x p2 (a x - b)) + (a (x^2 + y^2) sin th - b y)
 *        / (x p2 (a (x cos th + y sin th) - b)),
 *   F2 = 2b (atan(-a y/p1) + atan((a y - (a x + b) tan(th/2))/p1)) / (p1 p2), p2 < 0
 *        2b (atanh(a y/p1) + atanh(((a x + b) tan(th/2) - a y)/p1)) / (p1 p2), else */
static ir_ref arc_kernel(ir *g, lv3 p, ir_ref r, ir_ref S, ir_ref th)
{
    ir_ref S2 = ir_sq(g, S), r2 = ir_sq(g, r);
    ir_ref A = ir_mul(g, ir_mul(g, K(2.0), r), S2);
    ir_ref d2 = lv3_len2(g, p);
    ir_ref B = ir_add(g, ir_add(g, K(1.0), ir_mul(g, r2, S2)), ir_mul(g, S2, d2));
    ir_ref p2 = ir_sub(g, ir_neg(g, ir_mul(g, ir_sq(g, r2), ir_sq(g, S2))),
                       ir_sq(g, ir_add(g, K(1.0), ir_mul(g, S2, d2))));
    p2 = ir_add(g, p2, ir_mul(g, ir_mul(g, K(2.0), ir_mul(g, r2, S2)),
                              ir_sub(g, ir_mul(g, S2, ir_sub(g, d2, ir_mul(g, K(2.0),
                                                                           ir_sq(g, p.z)))),
                                     K(1.0))));
    ir_ref p1 = ir_sqrt(g, OP1(ABS, p2));
    ir_ref p3 = ir_mul(g, p1, p2);
    ir_ref sn = OP1(SIN, th), cs = OP1(COS, th);
    ir_ref xp2 = ir_mul(g, p.x, p2);
    ir_ref by = ir_mul(g, B, p.y);
    ir_ref f1 = ir_div(g, by, ir_mul(g, xp2, ir_sub(g, ir_mul(g, A, p.x), B)));
    ir_ref num = ir_sub(g, ir_mul(g, ir_mul(g, A, ir_add(g, ir_sq(g, p.x), ir_sq(g, p.y))), sn),
                        by);
    ir_ref den = ir_mul(g, xp2, ir_sub(g, ir_mul(g, A, ir_add(g, ir_mul(g, p.x, cs),
                                                              ir_mul(g, p.y, sn))),
                                       B));
    f1 = ir_add(g, f1, ir_div(g, num, den));
    ir_ref ay = ir_mul(g, A, p.y);
    ir_ref w = ir_mul(g, ir_add(g, ir_mul(g, A, p.x), B), OP1(TAN, ir_mul(g, th, K(0.5))));
    ir_ref two_b = ir_mul(g, K(2.0), B);
    ir_ref neg = ir_add(g, OP1(ATAN, ir_div(g, ir_neg(g, ay), p1)),
                        OP1(ATAN, ir_div(g, ir_sub(g, ay, w), p1)));
    ir_ref pos = ir_add(g, atanh_ir(g, ir_div(g, ay, p1)),
                        atanh_ir(g, ir_div(g, ir_sub(g, w, ay), p1)));
    ir_ref f2 = ir_div(g, ir_mul(g, two_b, ir_select(g, OP2(LT, p2, K(0.0)), neg, pos)), p3);
    return ir_add(g, f1, f2);
}

/* hfConvArc(x, center, radius, theta, axis, angle, S, T): arcs of `radius` and
 * `theta` degrees (clamped to 360) around `center`, their plane rotated by `angle`
 * degrees about `axis`.  An arc over 180 degrees is split into a half circle and
 * the rest (the rest evaluated in the frame turned by 180 degrees about z). */
LIB_EXPANDER(hf_conv_arc)
{
    ir *g = c->g;
    (void)n;
    uint32_t N = a[6].n;
    if (!need_size(c, &a[1], 3 * N, "hfConvArc", "center") ||
        !need_size(c, &a[2], N, "hfConvArc", "radius") ||
        !need_size(c, &a[3], N, "hfConvArc", "theta") ||
        !need_size(c, &a[4], 3 * N, "hfConvArc", "axis") ||
        !need_size(c, &a[5], N, "hfConvArc", "angle"))
        return IR_NONE;
    const double rd = FREP_PI / 180.0;
    lv3 x = lv3_at(a[0].elems, 0);
    ir_ref f = K(0.0);
    int quiet = g->quiet;
    /* Both sides of the p2 sign test and of the over-180 test are evaluated; only the
     * chosen one matters, so the expansion is built quiet. */
    g->quiet = 1;
    for (uint32_t i = 0; i < N; ++i) {
        lv3 ax = lv3_at(a[4].elems, 3 * i);
        lv3 k = lv3_div(g, ax, lv3_len(g, ax));
        ir_ref ang = ir_mul(g, ir_neg(g, a[5].elems[i]), K(rd));
        lv3 p = rotate_axis(g, lv3_sub(g, x, lv3_at(a[1].elems, 3 * i)), k, OP1(COS, ang),
                            OP1(SIN, ang));
        ir_ref theta = OP2(MIN, a[3].elems[i], K(360.0));
        ir_ref r = a[2].elems[i], S = a[6].elems[i];
        ir_ref main = arc_kernel(g, p, r, S, ir_mul(g, OP2(MIN, theta, K(180.0)), K(rd)));
        lv3 turned = lv3_make(ir_neg(g, p.x), ir_neg(g, p.y), p.z);
        ir_ref over = arc_kernel(g, turned, r, S, ir_mul(g, ir_sub(g, theta, K(180.0)), K(rd)));
        ir_ref term = ir_add(g, main, ir_select(g, OP2(GT, theta, K(180.0)), over, K(0.0)));
        f = ir_add(g, f, term);
    }
    g->quiet = quiet;
    return ir_sub(g, f, a[7].s);
}

/* Kernel integral over the triangle a1 a2 a3 (Yoshikawa's closed form).  The
 * vertices are first relabelled so that a1 a2 is the longest edge; b is the foot of
 * the height from a3 onto a1 a2, u and v unit vectors from b towards a2 and a3. */
static ir_ref cauchy_triangle(ir *g, lv3 x, lv3 a1, lv3 a2, lv3 a3, ir_ref S)
{
    ir_ref l0 = lv3_len(g, lv3_sub(g, a2, a1));
    ir_ref l1 = lv3_len(g, lv3_sub(g, a3, a2));
    ir_ref l2 = lv3_len(g, lv3_sub(g, a1, a3));
    ir_ref c1 = OP2(AND, OP2(GE, l1, l2), OP2(GT, l1, l0));
    ir_ref c2 = OP2(AND, OP2(GE, l2, l1), OP2(GT, l2, l0));
    lv3 n1, n2, n3;
    /* case 1 rotates (a1, a2, a3) -> (a2, a3, a1); case 2 -> (a3, a1, a2) */
    n1 = lv3_make(ir_select(g, c1, a2.x, ir_select(g, c2, a3.x, a1.x)),
                  ir_select(g, c1, a2.y, ir_select(g, c2, a3.y, a1.y)),
                  ir_select(g, c1, a2.z, ir_select(g, c2, a3.z, a1.z)));
    n2 = lv3_make(ir_select(g, c1, a3.x, ir_select(g, c2, a1.x, a2.x)),
                  ir_select(g, c1, a3.y, ir_select(g, c2, a1.y, a2.y)),
                  ir_select(g, c1, a3.z, ir_select(g, c2, a1.z, a2.z)));
    n3 = lv3_make(ir_select(g, c1, a1.x, ir_select(g, c2, a2.x, a3.x)),
                  ir_select(g, c1, a1.y, ir_select(g, c2, a2.y, a3.y)),
                  ir_select(g, c1, a1.z, ir_select(g, c2, a2.z, a3.z)));
    lv3 a21 = lv3_sub(g, n2, n1), a13 = lv3_sub(g, n1, n3);
    ir_ref t = ir_neg(g, ir_div(g, lv3_dot(g, a21, a13), lv3_len2(g, a21)));
    lv3 b = lv3_add(g, n1, lv3_scale(g, a21, t));
    lv3 d = lv3_sub(g, x, b);
    lv3 uu = lv3_sub(g, n2, b), vv = lv3_sub(g, n3, b);
    ir_ref a2l = lv3_len(g, uu), h = lv3_len(g, vv);
    ir_ref a1l = lv3_len(g, lv3_sub(g, n1, b));
    lv3 u = lv3_div(g, uu, a2l), v = lv3_div(g, vv, h);
    ir_ref d2 = lv3_len2(g, d);
    ir_ref du = lv3_dot(g, d, u), dv = lv3_dot(g, d, v);
    ir_ref gg = ir_sub(g, dv, h);
    ir_ref m = ir_add(g, ir_mul(g, a2l, gg), ir_mul(g, du, h));
    ir_ref k = ir_sub(g, ir_mul(g, du, h), ir_mul(g, a1l, gg));
    ir_ref C2 = ir_add(g, ir_div(g, K(1.0), ir_sq(g, S)), ir_sub(g, d2, ir_sq(g, du)));
    ir_ref C = lib_sqrt0(g, C2);
    ir_ref q = ir_sub(g, C2, ir_sq(g, dv));
    ir_ref w = ir_add(g, ir_sub(g, C2, ir_mul(g, ir_mul(g, K(2.0), dv), h)), ir_sq(g, h));
    ir_ref hq = ir_mul(g, ir_sq(g, h), ir_add(g, q, ir_sq(g, du)));
    ir_ref huq = ir_mul(g, ir_mul(g, K(2.0), ir_mul(g, h, du)), gg);
    ir_ref A = lib_sqrt0(g, ir_sub(g, ir_add(g, ir_mul(g, ir_sq(g, a1l), w), hq),
                                   ir_mul(g, a1l, huq)));
    ir_ref B = lib_sqrt0(g, ir_add(g, ir_add(g, ir_mul(g, ir_sq(g, a2l), w), hq),
                                   ir_mul(g, a2l, huq)));
    ir_ref n1s = ir_add(g, a1l, du);
    ir_ref n2s = ir_sub(g, a2l, du);
    ir_ref n3s = ir_add(g, ir_mul(g, a1l, n1s), ir_mul(g, dv, h));
    ir_ref n4s = ir_sub(g, ir_neg(g, ir_mul(g, a1l, du)), ir_mul(g, gg, h));
    ir_ref n5s = ir_sub(g, ir_neg(g, ir_mul(g, a2l, n2s)), ir_mul(g, dv, h));
    ir_ref n6s = ir_add(g, ir_neg(g, ir_mul(g, a2l, du)), ir_mul(g, gg, h));
    ir_ref arc1 = ir_div(g, ir_mul(g, k, ir_add(g, OP1(ATAN, ir_div(g, n3s, A)),
                                                OP1(ATAN, ir_div(g, n4s, A)))), A);
    ir_ref arc2 = ir_div(g, ir_mul(g, m, ir_add(g, OP1(ATAN, ir_div(g, n5s, B)),
                                                OP1(ATAN, ir_div(g, n6s, B)))), B);
    ir_ref arc3 = ir_div(g, ir_mul(g, dv, ir_add(g, OP1(ATAN, ir_div(g, n1s, C)),
                                                 OP1(ATAN, ir_div(g, n2s, C)))), C);
    return ir_div(g, ir_add(g, ir_add(g, arc1, arc2), arc3),
                  ir_mul(g, ir_mul(g, K(2.0), q), S));
}

/* hfConvTriangle(x, vect, S, T) = sum_i F(triangle vect[9i..9i+8], S_i) - T */
LIB_EXPANDER(hf_conv_triangle)
{
    ir *g = c->g;
    (void)n;
    uint32_t N = a[2].n;
    if (!need_size(c, &a[1], 9 * N, "hfConvTriangle", "vect")) return IR_NONE;
    lv3 x = lv3_at(a[0].elems, 0);
    ir_ref f = K(0.0);
    for (uint32_t i = 0; i < N; ++i)
        f = ir_add(g, f, cauchy_triangle(g, x, lv3_at(a[1].elems, 9 * i),
                                         lv3_at(a[1].elems, 9 * i + 3),
                                         lv3_at(a[1].elems, 9 * i + 6), a[2].elems[i]));
    return ir_sub(g, f, a[3].s);
}

/* hfConvMesh(x, vect, tri, S, T): triangles given by 1-based vertex indices
 * tri[3i..3i+2] into the vertex array vect; the indices must be constants. */
LIB_EXPANDER(hf_conv_mesh)
{
    ir *g = c->g;
    (void)n;
    uint32_t N = a[3].n, nv = a[1].n / 3;
    if (!need_size(c, &a[2], 3 * N, "hfConvMesh", "tri")) return IR_NONE;
    lv3 x = lv3_at(a[0].elems, 0);
    ir_ref f = K(0.0);
    for (uint32_t i = 0; i < N; ++i) {
        lv3 v[3];
        for (uint32_t j = 0; j < 3; ++j) {
            double k;
            if (!ir_is_const(g, a[2].elems[3 * i + j], &k)) {
                c->error(c, "hfConvMesh: triangle index tri[%u] must be a constant",
                         (unsigned)(3 * i + j + 1));
                return IR_NONE;
            }
            if (!(k >= 1 && k <= (double)nv)) {
                c->error(c, "hfConvMesh: triangle index tri[%u] = %g is not a vertex "
                         "(1..%u)", (unsigned)(3 * i + j + 1), k, (unsigned)nv);
                return IR_NONE;
            }
            v[j] = lv3_at(a[1].elems, 3 * ((uint32_t)k - 1));
        }
        f = ir_add(g, f, cauchy_triangle(g, x, v[0], v[1], v[2], a[3].elems[i]));
    }
    return ir_sub(g, f, a[4].s);
}

/* hfNoiseG(x, amp, freq, phase): Gardner's series, product of
 *   Ser(u) = amp sin(freq u) + amp/1.17 sin(freq u/1.35 + phase sin(freq v))
 * over (u, v) = (x, z), (y, x), (z, y). */
LIB_EXPANDER(hf_noise_g)
{
    ir *g = c->g;
    (void)n;
    ir_ref amp = a[1].s, freq = a[2].s, phase = a[3].s;
    ir_ref w[3], s[3];
    for (int i = 0; i < 3; ++i) {
        w[i] = ir_mul(g, freq, a[0].elems[i]);
        s[i] = OP1(SIN, w[i]);
    }
    ir_ref a1d = ir_div(g, amp, K(1.17));
    ir_ref f = K(1.0);
    static const int other[3] = { 2, 0, 1 };
    for (int i = 0; i < 3; ++i) {
        ir_ref s2 = ir_mul(g, a1d, OP1(SIN, ir_add(g, ir_div(g, w[i], K(1.35)),
                                                 ir_mul(g, phase, s[other[i]]))));
        f = ir_mul(g, f, ir_add(g, ir_mul(g, amp, s[i]), s2));
    }
    return f;
}

/* ---- space transformations: rewrite a[0] in place, return 1 --------------------- */

/* hfScale3D(xt, sx, sy, sz): xt_i = xt_i / s_i */
LIB_EXPANDER(hf_scale3d)
{
    ir *g = c->g;
    (void)n;
    for (int i = 0; i < 3; ++i)
        if (!nonzero_const(c, a[1 + i].s, "hfScale3D", "a scale factor")) return IR_NONE;
    for (int i = 0; i < 3; ++i) a[0].elems[i] = ir_div(g, a[0].elems[i], a[1 + i].s);
    return K(1.0);
}

/* hfShift3D(xt, dx, dy, dz): xt_i = xt_i - d_i */
LIB_EXPANDER(hf_shift3d)
{
    ir *g = c->g;
    (void)n;
    for (int i = 0; i < 3; ++i) a[0].elems[i] = ir_sub(g, a[0].elems[i], a[1 + i].s);
    return K(1.0);
}

/* Axis -> rotated pair, as the reference: x: (y, z), y: (z, x), z: (x, y). */
static const int rot_i[3] = { 1, 2, 0 }, rot_j[3] = { 2, 0, 1 };

LIB_EXPANDER(hf_rotate3d_x) { (void)n; lib_rotate_pair(c->g, a[0].elems, 1, 2, a[1].s); return ir_k(c->g, 1.0); }
LIB_EXPANDER(hf_rotate3d_y) { (void)n; lib_rotate_pair(c->g, a[0].elems, 2, 0, a[1].s); return ir_k(c->g, 1.0); }
LIB_EXPANDER(hf_rotate3d_z) { (void)n; lib_rotate_pair(c->g, a[0].elems, 0, 1, a[1].s); return ir_k(c->g, 1.0); }

/* hfTwistA(xt, u1, u2, theta1, theta2): t = (xt_A - u1)/(u2 - u1),
 * rotate about A by (1 - t) theta1 + t theta2 */
static ir_ref twist(lib_ctx *c, lib_arg *a, int axis)
{
    ir *g = c->g;
    ir_ref t = ir_div(g, ir_sub(g, a[0].elems[axis], a[1].s), ir_sub(g, a[2].s, a[1].s));
    ir_ref th = ir_add(g, ir_mul(g, ir_sub(g, K(1.0), t), a[3].s), ir_mul(g, t, a[4].s));
    lib_rotate_pair(g, a[0].elems, rot_i[axis], rot_j[axis], th);
    return K(1.0);
}
LIB_EXPANDER(hf_twist_x) { (void)n; return twist(c, a, 0); }
LIB_EXPANDER(hf_twist_y) { (void)n; return twist(c, a, 1); }
LIB_EXPANDER(hf_twist_z) { (void)n; return twist(c, a, 2); }

/* hfStretch3D(xt, x0, sx, sy, sz): xt_i = x0_i + (xt_i - x0_i) / s_i */
LIB_EXPANDER(hf_stretch3d)
{
    ir *g = c->g;
    (void)n;
    for (int i = 0; i < 3; ++i)
        if (!nonzero_const(c, a[2 + i].s, "hfStretch3D", "a scale factor")) return IR_NONE;
    for (int i = 0; i < 3; ++i) {
        ir_ref x0 = a[1].elems[i];
        a[0].elems[i] = ir_add(g, x0, ir_div(g, ir_sub(g, a[0].elems[i], x0), a[2 + i].s));
    }
    return K(1.0);
}

/* hfTaperA(xt, u1, u2, s1, s2): scale = s1 below u1, s2 above u2, linear between;
 * the two other coordinates are divided by scale. */
static ir_ref taper(lib_ctx *c, lib_arg *a, int axis, const char *fn)
{
    ir *g = c->g;
    double k;
    for (int i = 3; i <= 4; ++i)
        if (ir_is_const(g, a[i].s, &k) && !(k > 0)) {
            c->error(c, "%s: scale factors must be > 0", fn);
            return IR_NONE;
        }
    ir_ref u = a[0].elems[axis], u1 = a[1].s, u2 = a[2].s, s1 = a[3].s, s2 = a[4].s;
    int quiet = g->quiet;
    g->quiet = 1;           /* the interpolation is speculative outside [u1, u2] */
    ir_ref t = ir_div(g, ir_sub(g, u, u1), ir_sub(g, u2, u1));
    ir_ref lerp = ir_add(g, ir_mul(g, ir_sub(g, K(1.0), t), s1), ir_mul(g, t, s2));
    g->quiet = quiet;
    ir_ref scale = ir_select(g, OP2(LT, u, u1), s1, ir_select(g, OP2(GT, u, u2), s2, lerp));
    int i, j;
    other_axes(axis, &i, &j);
    a[0].elems[i] = ir_div(g, a[0].elems[i], scale);
    a[0].elems[j] = ir_div(g, a[0].elems[j], scale);
    return K(1.0);
}
LIB_EXPANDER(hf_taper_x) { (void)n; return taper(c, a, 0, "hfTaperX"); }
LIB_EXPANDER(hf_taper_y) { (void)n; return taper(c, a, 1, "hfTaperY"); }
LIB_EXPANDER(hf_taper_z) { (void)n; return taper(c, a, 2, "hfTaperZ"); }

/* hfSpaceMapCubic / hfSpaceMapExp(xt, source, target, b): for each point pair,
 * dt = target - source, q = sum_i ((xt_i - target_i) / (b_i (1 + |dt_i|)))^2,
 * xt -= w dt with w = max(1 - sqrt q, 0)^3 / (1 + sqrt q) (cubic) or exp(-q). */
static ir_ref spacemap(lib_ctx *c, lib_arg *a, int cubic, const char *fn)
{
    ir *g = c->g;
    uint32_t N = a[1].n;
    if (N % 3 != 0) {
        c->error(c, "%s: array 'source' must hold whole points (a multiple of 3 "
                 "elements), it has %u", fn, (unsigned)N);
        return IR_NONE;
    }
    if (!need_size(c, &a[2], N, fn, "target") || !need_size(c, &a[3], N, fn, "b"))
        return IR_NONE;
    for (uint32_t p = 0; p < N; p += 3) {
        ir_ref dt[3], q = K(0.0);
        for (int i = 0; i < 3; ++i) {
            ir_ref to = a[2].elems[p + (uint32_t)i];
            dt[i] = ir_sub(g, to, a[1].elems[p + (uint32_t)i]);
            ir_ref den = ir_mul(g, a[3].elems[p + (uint32_t)i],
                                ir_add(g, K(1.0), OP1(ABS, dt[i])));
            q = ir_add(g, q, ir_sq(g, ir_div(g, ir_sub(g, a[0].elems[i], to), den)));
        }
        ir_ref w;
        if (cubic) {
            ir_ref s = ir_sqrt(g, q);
            ir_ref o = OP2(MAX, ir_sub(g, K(1.0), s), K(0.0));
            w = ir_div(g, ir_mul(g, ir_sq(g, o), o), ir_add(g, K(1.0), s));
        } else {
            w = OP1(EXP, ir_neg(g, q));
        }
        for (int i = 0; i < 3; ++i) a[0].elems[i] = ir_sub(g, a[0].elems[i], ir_mul(g, w, dt[i]));
    }
    return K(1.0);
}
LIB_EXPANDER(hf_spacemap_cubic) { (void)n; return spacemap(c, a, 1, "hfSpaceMapCubic"); }
LIB_EXPANDER(hf_spacemap_exp) { (void)n; return spacemap(c, a, 0, "hfSpaceMapExp"); }

/* ---- blending -------------------------------------------------------------------- */

/* hfBlendUni/Int(f1, f2, a0, a1, a2) = f1 + f2 +- sqrt(f1^2 + f2^2)
 *                                       + a0 / (1 + (f1/a1)^2 + (f2/a2)^2) */
static ir_ref blend(lib_ctx *c, lib_arg *a, int uni)
{
    ir *g = c->g;
    ir_ref f1 = a[0].s, f2 = a[1].s;
    ir_ref den = ir_add(g, ir_add(g, K(1.0), ir_sq(g, ir_div(g, f1, a[3].s))),
                        ir_sq(g, ir_div(g, f2, a[4].s)));
    ir_ref disp = ir_div(g, a[2].s, den);
    return ir_add(g, uni ? OP2(RUNI, f1, f2) : OP2(RINT, f1, f2), disp);
}
LIB_EXPANDER(hf_blend_uni) { (void)n; return blend(c, a, 1); }
LIB_EXPANDER(hf_blend_int) { (void)n; return blend(c, a, 0); }

/* ---- distance-based primitives ----------------------------------------------------- */

/* hfDConeA(x, center, R) = |d_A| sin t - sqrt(d_i^2 + d_j^2) cos t, t = atan R */
static ir_ref dcone(lib_ctx *c, lib_arg *a, int axis)
{
    ir *g = c->g;
    int i, j;
    other_axes(axis, &i, &j);
    lv3 d = rel(g, a);
    ir_ref t = OP1(ATAN, a[2].s);
    ir_ref rho = ir_sqrt(g, ir_add(g, ir_sq(g, comp(d, i)), ir_sq(g, comp(d, j))));
    return ir_sub(g, ir_mul(g, OP1(ABS, comp(d, axis)), OP1(SIN, t)),
                  ir_mul(g, rho, OP1(COS, t)));
}
LIB_EXPANDER(hf_dcone_x) { (void)n; return dcone(c, a, 0); }
LIB_EXPANDER(hf_dcone_y) { (void)n; return dcone(c, a, 1); }
LIB_EXPANDER(hf_dcone_z) { (void)n; return dcone(c, a, 2); }

/* hfDCylinder(x, center, u, R) = R - |u x (center - x)| / |u| */
LIB_EXPANDER(hf_dcylinder)
{
    ir *g = c->g;
    (void)n;
    lv3 u = lv3_at(a[2].elems, 0);
    lv3 cp = lv3_cross(g, u, lv3_sub(g, lv3_at(a[1].elems, 0), lv3_at(a[0].elems, 0)));
    return ir_sub(g, a[3].s, ir_sqrt(g, ir_div(g, lv3_len2(g, cp), lv3_len2(g, u))));
}

/* hfDTorusA(x, center, R, r0) = r0 - sqrt((sqrt(d_i^2 + d_j^2) - R)^2 + d_A^2) */
static ir_ref dtorus(lib_ctx *c, lib_arg *a, int axis)
{
    ir *g = c->g;
    int i, j;
    other_axes(axis, &i, &j);
    lv3 d = rel(g, a);
    ir_ref rho = ir_sqrt(g, ir_add(g, ir_sq(g, comp(d, i)), ir_sq(g, comp(d, j))));
    ir_ref e = ir_sqrt(g, ir_add(g, ir_sq(g, ir_sub(g, rho, a[2].s)), ir_sq(g, comp(d, axis))));
    return ir_sub(g, a[3].s, e);
}
LIB_EXPANDER(hf_dtorus_x) { (void)n; return dtorus(c, a, 0); }
LIB_EXPANDER(hf_dtorus_y) { (void)n; return dtorus(c, a, 1); }
LIB_EXPANDER(hf_dtorus_z) { (void)n; return dtorus(c, a, 2); }

/* hfDEllipsoid(x, center, a, b, c): distance to the closest point of the ellipsoid
 * surface, positive inside.  The closest point is (a^2 x + t c)/(t + a^2), ... where
 * t is the root of s(t) = p^2 q^2 r^2 - a^2u^2 q^2 r^2 - b^2v^2 p^2 r^2 - c^2w^2 p^2 q^2
 * (p = t + a^2, q = t + b^2, r = t + c^2; u, v, w = x - center) found by Newton steps
 * from t = 0 (inside) or max(a, b, c) |x - center| (outside). */
LIB_EXPANDER(hf_dellipsoid)
{
    ir *g = c->g;
    (void)n;
    lv3 d = rel(g, a);
    ir_ref ea = a[2].s, eb = a[3].s, ec = a[4].s;
    ir_ref a2 = ir_sq(g, ea), b2 = ir_sq(g, eb), c2 = ir_sq(g, ec);
    ir_ref a2u2 = ir_mul(g, a2, ir_sq(g, d.x)), b2v2 = ir_mul(g, b2, ir_sq(g, d.y));
    ir_ref c2w2 = ir_mul(g, c2, ir_sq(g, d.z));
    ir_ref in = ir_add(g, ir_add(g, ir_sq(g, ir_div(g, d.x, ea)), ir_sq(g, ir_div(g, d.y, eb))),
                       ir_sq(g, ir_div(g, d.z, ec)));
    ir_ref inside = OP2(LT, in, K(1.0));
    ir_ref t = ir_select(g, inside, K(0.0),
                         ir_mul(g, OP2(MAX, OP2(MAX, ea, eb), ec), lv3_len(g, d)));
    int quiet = g->quiet;
    for (int it = 0; it < LIB_DELLIPSOID_STEPS; ++it) {
        ir_ref p = ir_add(g, t, a2), q = ir_add(g, t, b2), r = ir_add(g, t, c2);
        ir_ref p2 = ir_sq(g, p), q2 = ir_sq(g, q), r2 = ir_sq(g, r);
        ir_ref s = ir_mul(g, ir_mul(g, p2, q2), r2);
        s = ir_sub(g, s, ir_mul(g, a2u2, ir_mul(g, q2, r2)));
        s = ir_sub(g, s, ir_mul(g, b2v2, ir_mul(g, p2, r2)));
        s = ir_sub(g, s, ir_mul(g, c2w2, ir_mul(g, p2, q2)));
        ir_ref pq = ir_mul(g, p, q), pr = ir_mul(g, p, r), qr = ir_mul(g, q, r);
        ir_ref pqr = ir_mul(g, pq, r);
        ir_ref ds = ir_mul(g, pqr, ir_add(g, ir_add(g, qr, pr), pq));
        ds = ir_sub(g, ds, ir_mul(g, ir_mul(g, a2u2, qr), ir_add(g, q, r)));
        ds = ir_sub(g, ds, ir_mul(g, ir_mul(g, b2v2, pr), ir_add(g, p, r)));
        ds = ir_sub(g, ds, ir_mul(g, ir_mul(g, c2w2, pq), ir_add(g, p, q)));
        ds = ir_mul(g, K(2.0), ds);
        g->quiet = 1;       /* the step is unused once converged (ds may then be 0) */
        ir_ref step = ir_sub(g, t, ir_div(g, s, ds));
        g->quiet = quiet;
        t = ir_select(g, OP2(LT, OP1(ABS, s), K(LIB_DELLIPSOID_TOL)), t, step);
    }
    lv3 x = lv3_at(a[0].elems, 0), ce = lv3_at(a[1].elems, 0);
    lv3 cl = lv3_make(ir_div(g, ir_add(g, ir_mul(g, a2, x.x), ir_mul(g, t, ce.x)), ir_add(g, t, a2)),
                      ir_div(g, ir_add(g, ir_mul(g, b2, x.y), ir_mul(g, t, ce.y)), ir_add(g, t, b2)),
                      ir_div(g, ir_add(g, ir_mul(g, c2, x.z), ir_mul(g, t, ce.z)), ir_add(g, t, c2)));
    ir_ref dist = lv3_len(g, lv3_sub(g, cl, x));
    return ir_select(g, inside, dist, ir_neg(g, dist));
}

/* ---- SARDF set operations (Fayolle, Pasko, Schmitt, Mirenkov 2006) ---------------- */

/* Builds "the first true condition wins" chains from the last case backwards. */
typedef struct sel_chain {
    ir *g;
    ir_ref r;
} sel_chain;
static void sel_case(sel_chain *s, ir_ref cond, ir_ref val)
{
    s->r = ir_select(s->g, cond, val, s->r);
}

/* Value of the quartic of the bounded SARDF blend at m (Horner's scheme):
 *   P(m) = m^4 - 4 sqrt(R) m^3 - 4 R m^2 + 4 sqrt(R) (x + y) m - (x^2 + y^2). */
static ir_ref sardf_poly(ir *g, ir_ref m, ir_ref c3, ir_ref c2, ir_ref c1, ir_ref c0)
{
    ir_ref p = ir_add(g, ir_mul(g, ir_add(g, m, c3), m), c2);
    return ir_add(g, ir_mul(g, ir_add(g, ir_mul(g, p, m), c1), m), c0);
}

/* The blend value is d = m^2 for the root m of P that joins the neighbouring cases
 * continuously: on the edge of the angle region (y = x^2/(4R)) it is m = sqrt(y),
 * and inside it is the largest root in [0, sqrt(min(x, y))] (P(0) < 0 and
 * P(sqrt(min(x, y))) <= 0 there, with a positive hump between).  Found by sampling
 * P on LIB_SARDF_SAMPLES points for the last positive sample, then bisection. */
static ir_ref sardf_quartic(ir *g, ir_ref x, ir_ref y, ir_ref R)
{
    ir_ref sr = lib_sqrt0(g, R);
    ir_ref c3 = ir_mul(g, K(-4.0), sr), c2 = ir_mul(g, K(-4.0), R);
    ir_ref c1 = ir_mul(g, ir_mul(g, K(4.0), sr), ir_add(g, x, y));
    ir_ref c0 = ir_neg(g, ir_add(g, ir_sq(g, x), ir_sq(g, y)));
    ir_ref top = lib_sqrt0(g, OP2(MIN, x, y));
    ir_ref h = ir_mul(g, top, K(1.0 / LIB_SARDF_SAMPLES));
    ir_ref lo = K(0.0);
    for (int k = 1; k < LIB_SARDF_SAMPLES; ++k) {
        ir_ref m = ir_mul(g, h, K((double)k));
        lo = ir_select(g, OP2(GT, sardf_poly(g, m, c3, c2, c1, c0), K(0.0)), m, lo);
    }
    ir_ref hi = ir_add(g, lo, h);
    for (int i = 0; i < LIB_SARDF_BISECT; ++i) {
        ir_ref m = ir_mul(g, ir_add(g, lo, hi), K(0.5));
        ir_ref pos = OP2(GT, sardf_poly(g, m, c3, c2, c1, c0), K(0.0));
        lo = ir_select(g, pos, m, lo);
        hi = ir_select(g, pos, hi, m);
    }
    return ir_mul(g, ir_add(g, lo, hi), K(0.5));
}

/* Bounded blend of the intersection for x, y > 0 (int_sardef_1, quadrant I). */
static ir_ref sardf_int_q1(ir *g, ir_ref x, ir_ref y, ir_ref R)
{
    ir_ref twoR = ir_mul(g, K(2.0), R), R2 = ir_sq(g, R);
    ir_ref lim = ir_add(g, ir_sq(g, ir_sub(g, x, twoR)), ir_sq(g, ir_sub(g, y, twoR)));
    ir_ref angle = OP2(OR, OP2(OR, OP2(LE, x, R), OP2(LE, y, R)),
                       OP2(AND, OP2(AND, OP2(LE, x, twoR), OP2(LE, y, twoR)), OP2(GE, lim, R2)));
    ir_ref fourR = ir_mul(g, K(4.0), R);
    ir_ref xx = ir_div(g, ir_sq(g, x), fourR), yy = ir_div(g, ir_sq(g, y), fourR);
    ir_ref m = sardf_quartic(g, x, y, R);
    sel_chain a = { g, K(0.0) };
    sel_case(&a, OP2(GT, yy, x), x);
    sel_case(&a, OP2(GT, xx, y), y);
    sel_case(&a, OP2(AND, OP2(LE, xx, y), OP2(LE, yy, x)), ir_sq(g, m));
    /* strip: (-b + sqrt(b^2 - 8c))/4 with b = -2x + 4R - 2y, c = x^2 + y^2 + R^2 - 2xR - 2yR */
    ir_ref b = ir_add(g, ir_mul(g, K(-2.0), ir_add(g, x, y)), fourR);
    ir_ref cc = ir_sub(g, ir_add(g, ir_add(g, ir_sq(g, x), ir_sq(g, y)), R2),
                       ir_mul(g, twoR, ir_add(g, x, y)));
    ir_ref Ds = ir_sub(g, ir_sq(g, b), ir_mul(g, K(8.0), cc));
    ir_ref band = ir_div(g, ir_add(g, ir_neg(g, b), lib_sqrt0(g, Ds)), K(4.0));
    sel_chain s = { g, K(0.0) };
    sel_case(&s, OP2(GT, y, ir_add(g, x, R)), x);
    sel_case(&s, OP2(LT, y, ir_sub(g, x, R)), y);
    sel_case(&s, OP2(AND, OP2(AND, OP2(LE, y, ir_add(g, x, R)), OP2(GE, y, ir_sub(g, x, R))),
                     OP2(GE, Ds, K(0.0))), band);
    return ir_select(g, angle, a.r, s.r);
}

/* Unbounded (angle alpha) blend for x, y of equal sign:
 *   t = tan(alpha), inside the angle tan(alpha) < x/y < 1/tan(alpha):
 *   (-b - sqrt(b^2 - 4 aa c)) / (2 aa) with, for the union in quadrant I,
 *   aa = t^2 + 2t - 1, b = -2t(x + y), c = x^2 + y^2, and for the intersection in
 *   quadrant III aa = 1 - t^2 - 2t, b = 2t(x + y), c = -(x^2 + y^2);
 *   x when x/y >= 1/tan(alpha), y when x/y <= tan(alpha). */
static ir_ref sardf_alpha(ir *g, ir_ref x, ir_ref y, ir_ref alpha, int uni)
{
    ir_ref t = OP1(TAN, alpha);
    ir_ref gk = ir_div(g, K(1.0), t), gt = ir_div(g, x, y);
    ir_ref t2 = ir_sq(g, t), tw = ir_mul(g, K(2.0), t);
    ir_ref aa, b, cc;
    ir_ref s2 = ir_add(g, ir_sq(g, x), ir_sq(g, y));
    if (uni) {
        aa = ir_sub(g, ir_add(g, t2, tw), K(1.0));
        b = ir_neg(g, ir_mul(g, tw, ir_add(g, x, y)));
        cc = s2;
    } else {
        aa = ir_sub(g, ir_sub(g, K(1.0), t2), tw);
        b = ir_mul(g, tw, ir_add(g, x, y));
        cc = ir_neg(g, s2);
    }
    ir_ref disc = ir_sub(g, ir_sq(g, b), ir_mul(g, ir_mul(g, K(4.0), aa), cc));
    ir_ref v = ir_div(g, ir_sub(g, ir_neg(g, b), lib_sqrt0(g, disc)), ir_mul(g, K(2.0), aa));
    sel_chain s = { g, K(0.0) };
    sel_case(&s, OP2(LE, gt, t), y);
    sel_case(&s, OP2(GE, gt, gk), x);
    sel_case(&s, OP2(AND, OP2(LT, gt, gk), OP2(GT, gt, t)), v);
    return s.r;
}

/* SARDF intersection (int_sardef_1 of the reference). */
static ir_ref sardf_int(ir *g, ir_ref x, ir_ref y, ir_ref R, ir_ref alpha)
{
    ir_ref z = K(LIB_SARDF_ZERO), zero = K(0.0);
    ir_ref ax = OP1(ABS, x), ay = OP1(ABS, y);
    ir_ref x0 = OP2(LT, ax, z), y0 = OP2(LT, ay, z);
    ir_ref xn = OP2(GT, ax, z), yn = OP2(GT, ay, z);
    ir_ref both = OP2(AND, xn, yn);
    sel_chain s = { g, zero };
    sel_case(&s, OP2(AND, both, OP2(AND, OP2(LT, x, zero), OP2(LT, y, zero))),
             sardf_alpha(g, x, y, alpha, 0));
    sel_case(&s, OP2(AND, both, OP2(AND, OP2(GT, x, zero), OP2(GT, y, zero))),
             sardf_int_q1(g, x, y, R));
    sel_case(&s, OP2(AND, both, OP2(AND, OP2(LT, y, zero), OP2(GT, x, zero))), y);
    sel_case(&s, OP2(AND, both, OP2(AND, OP2(LT, x, zero), OP2(GT, y, zero))), x);
    sel_case(&s, OP2(AND, x0, OP2(LT, y, zero)), y);
    sel_case(&s, OP2(AND, x0, OP2(GT, y, zero)), zero);
    sel_case(&s, OP2(AND, y0, OP2(LT, x, zero)), x);
    sel_case(&s, OP2(AND, y0, OP2(GT, x, zero)), zero);
    sel_case(&s, OP2(AND, x0, y0), zero);
    return s.r;
}

/* SARDF union (uni_sardef_1): the bounded blend in quadrant III is the intersection
 * blend of quadrant I mirrored, -int_q1-shape(-x, -y), written out as the reference
 * does; the unbounded (alpha) blend is in quadrant I. */
static ir_ref sardf_uni_q3(ir *g, ir_ref x, ir_ref y, ir_ref R)
{
    ir_ref twoR = ir_mul(g, K(2.0), R), R2 = ir_sq(g, R);
    ir_ref lim2 = ir_add(g, ir_sq(g, ir_add(g, x, twoR)), ir_sq(g, ir_add(g, y, twoR)));
    ir_ref nR = ir_neg(g, R), n2R = ir_neg(g, twoR);
    ir_ref angle = OP2(OR, OP2(OR, OP2(GE, x, nR), OP2(GE, y, nR)),
                       OP2(AND, OP2(AND, OP2(GE, x, n2R), OP2(GE, y, n2R)), OP2(GE, lim2, R2)));
    ir_ref fourR = ir_mul(g, K(4.0), R);
    ir_ref xx = ir_neg(g, ir_div(g, ir_sq(g, x), fourR));
    ir_ref yy = ir_neg(g, ir_div(g, ir_sq(g, y), fourR));
    /* the quartic of quadrant III is that of quadrant I at (-x, -y) */
    ir_ref m = sardf_quartic(g, ir_neg(g, x), ir_neg(g, y), R);
    sel_chain a = { g, K(0.0) };
    sel_case(&a, OP2(LT, yy, x), x);
    sel_case(&a, OP2(GT, y, xx), y);
    sel_case(&a, OP2(AND, OP2(LE, x, yy), OP2(LE, y, xx)), ir_neg(g, ir_sq(g, m)));
    /* strip: (-b - sqrt(b^2 - 8c))/4 with b = -2x - 4R - 2y, c = x^2 + y^2 + R^2 + 2xR + 2yR */
    ir_ref b = ir_sub(g, ir_mul(g, K(-2.0), ir_add(g, x, y)), fourR);
    ir_ref cc = ir_add(g, ir_add(g, ir_add(g, ir_sq(g, x), ir_sq(g, y)), R2),
                       ir_mul(g, twoR, ir_add(g, x, y)));
    ir_ref Ds = ir_sub(g, ir_sq(g, b), ir_mul(g, K(8.0), cc));
    ir_ref band = ir_div(g, ir_sub(g, ir_neg(g, b), lib_sqrt0(g, Ds)), K(4.0));
    sel_chain s = { g, K(0.0) };
    sel_case(&s, OP2(GT, y, ir_add(g, x, R)), y);
    sel_case(&s, OP2(LT, y, ir_sub(g, x, R)), x);
    sel_case(&s, OP2(AND, OP2(AND, OP2(LE, y, ir_add(g, x, R)), OP2(GE, y, ir_sub(g, x, R))),
                     OP2(GE, Ds, K(0.0))), band);
    return ir_select(g, angle, a.r, s.r);
}

static ir_ref sardf_uni(ir *g, ir_ref x, ir_ref y, ir_ref R, ir_ref alpha)
{
    ir_ref z = K(LIB_SARDF_ZERO), zero = K(0.0);
    ir_ref ax = OP1(ABS, x), ay = OP1(ABS, y);
    ir_ref x0 = OP2(LT, ax, z), y0 = OP2(LT, ay, z);
    ir_ref both = OP2(AND, OP2(GT, ax, z), OP2(GT, ay, z));
    sel_chain s = { g, zero };
    sel_case(&s, OP2(AND, both, OP2(AND, OP2(LT, x, zero), OP2(LT, y, zero))),
             sardf_uni_q3(g, x, y, R));
    sel_case(&s, OP2(AND, both, OP2(AND, OP2(GT, x, zero), OP2(GT, y, zero))),
             sardf_alpha(g, x, y, alpha, 1));
    sel_case(&s, OP2(AND, both, OP2(AND, OP2(GT, x, zero), OP2(LT, y, zero))), x);
    sel_case(&s, OP2(AND, both, OP2(AND, OP2(GT, y, zero), OP2(LT, x, zero))), y);
    sel_case(&s, OP2(AND, y0, OP2(LT, x, zero)), zero);
    sel_case(&s, OP2(AND, y0, OP2(GT, x, zero)), x);
    sel_case(&s, OP2(AND, x0, OP2(LT, y, zero)), zero);
    sel_case(&s, OP2(AND, x0, OP2(GT, y, zero)), y);
    sel_case(&s, OP2(AND, x0, y0), zero);
    return s.r;
}

/* All cases of the SARDF operations are evaluated (SELECT), so they are built quiet. */
LIB_EXPANDER(hf_duni)
{
    ir *g = c->g;
    (void)n;
    int quiet = g->quiet;
    g->quiet = 1;
    ir_ref r = sardf_uni(g, a[0].s, a[1].s, a[2].s, a[3].s);
    g->quiet = quiet;
    return r;
}
LIB_EXPANDER(hf_dint)
{
    ir *g = c->g;
    (void)n;
    int quiet = g->quiet;
    g->quiet = 1;
    ir_ref r = sardf_int(g, a[0].s, a[1].s, a[2].s, a[3].s);
    g->quiet = quiet;
    return r;
}
LIB_EXPANDER(hf_dsub)
{
    ir *g = c->g;
    (void)n;
    int quiet = g->quiet;
    g->quiet = 1;
    ir_ref r = sardf_int(g, a[0].s, ir_neg(g, a[1].s), a[2].s, a[3].s);
    g->quiet = quiet;
    return r;
}

/* hfDBlendUni/Int(f1, f2, r): within the band |f2 - f1| <= r the circular blend
 *   union:        (-b - sqrt(b^2 - 8c))/4, b = -2f1 - 4r - 2f2, c = f1^2 + f2^2 + r^2 + 2f1 r + 2f2 r
 *   intersection: (-b + sqrt(b^2 - 8c))/4, b = -2f1 + 4r - 2f2, c = f1^2 + f2^2 + r^2 - 2f1 r - 2f2 r
 * (0 where b^2 - 8c < 0); outside it max(f1, f2) resp. min(f1, f2). */
static ir_ref dblend(lib_ctx *c, lib_arg *a, int uni)
{
    ir *g = c->g;
    ir_ref x = a[0].s, y = a[1].s, r = a[2].s;
    ir_ref s = ir_add(g, x, y);
    ir_ref b = ir_mul(g, K(-2.0), s), cc = ir_add(g, ir_add(g, ir_sq(g, x), ir_sq(g, y)), ir_sq(g, r));
    ir_ref rs = ir_mul(g, ir_mul(g, K(2.0), r), s);
    if (uni) {
        b = ir_sub(g, b, ir_mul(g, K(4.0), r));
        cc = ir_add(g, cc, rs);
    } else {
        b = ir_add(g, b, ir_mul(g, K(4.0), r));
        cc = ir_sub(g, cc, rs);
    }
    ir_ref Ds = ir_sub(g, ir_sq(g, b), ir_mul(g, K(8.0), cc));
    ir_ref root = lib_sqrt0(g, Ds);
    ir_ref band = ir_div(g, uni ? ir_sub(g, ir_neg(g, b), root) : ir_add(g, ir_neg(g, b), root),
                         K(4.0));
    sel_chain sc = { g, K(0.0) };
    sel_case(&sc, OP2(GT, y, ir_add(g, x, r)), uni ? y : x);
    sel_case(&sc, OP2(LT, y, ir_sub(g, x, r)), uni ? x : y);
    sel_case(&sc, OP2(AND, OP2(AND, OP2(LE, y, ir_add(g, x, r)), OP2(GE, y, ir_sub(g, x, r))),
                      OP2(GE, Ds, K(0.0))), band);
    return sc.r;
}
LIB_EXPANDER(hf_dblend_uni) { (void)n; return dblend(c, a, 1); }
LIB_EXPANDER(hf_dblend_int) { (void)n; return dblend(c, a, 0); }
