/* lib_ext.c - frep's extensions to the HyperFun library, expanded into IR (called
 * through lib.c's table by lang/lower.c): explicit set operations of each family,
 * and signed-distance primitives in general position with the exact names, argument
 * order and formulas of geom/prim.h, so that models written by `frep segment` and
 * `frep evolve` evaluate to the numbers prim_eval() gives.
 */
#include <stddef.h>

#include "lib_impl.h"

#define K(v) ir_k(g, (v))
#define OP1(o, a) ir_op1(g, FREP_OP_##o, (a))
#define OP2(o, a, b) ir_op2(g, FREP_OP_##o, (a), (b))

/* ---- set operations, whatever the file's semantics ----------------------------- */

LIB_EXPANDER(ext_r_union) { (void)n; return ir_op2(c->g, FREP_OP_RUNI, a[0].s, a[1].s); }
LIB_EXPANDER(ext_r_intersection) { (void)n; return ir_op2(c->g, FREP_OP_RINT, a[0].s, a[1].s); }
LIB_EXPANDER(ext_r_subtraction) { (void)n; return ir_op2(c->g, FREP_OP_RSUB, a[0].s, a[1].s); }
LIB_EXPANDER(ext_mm_union) { (void)n; return ir_op2(c->g, FREP_OP_MAX, a[0].s, a[1].s); }
LIB_EXPANDER(ext_mm_intersection) { (void)n; return ir_op2(c->g, FREP_OP_MIN, a[0].s, a[1].s); }
LIB_EXPANDER(ext_mm_subtraction) { (void)n; return ir_op2(c->g, FREP_OP_MSUB, a[0].s, a[1].s); }

/* raUnion(f, g, alpha) = (f + g + sqrt(f^2 + g^2 - 2 alpha f g)) / (1 + alpha) */
LIB_EXPANDER(ext_ra_union) { (void)n; return lib_ralpha(c, a[0].s, a[1].s, a[2].s, 1); }
/* raIntersection(f, g, alpha) = (f + g - sqrt(f^2 + g^2 - 2 alpha f g)) / (1 + alpha) */
LIB_EXPANDER(ext_ra_intersection) { (void)n; return lib_ralpha(c, a[0].s, a[1].s, a[2].s, 0); }
/* raSubtraction(f, g, alpha) = raIntersection(f, -g, alpha) */
LIB_EXPANDER(ext_ra_subtraction)
{
    (void)n;
    return lib_ralpha(c, a[0].s, ir_neg(c->g, a[1].s), a[2].s, 0);
}
/* frComplement(f) = -f */
LIB_EXPANDER(ext_complement) { (void)n; return ir_neg(c->g, a[0].s); }

/* ---- signed-distance primitives (inside >= 0) ------------------------------------ */

static lv3 point(const lib_arg *a) { return lv3_at(a[0].elems, 0); }
static lv3 scalars3(const lib_arg *a, uint32_t i)
{
    return lv3_make(a[i].s, a[i + 1].s, a[i + 2].s);
}

/* frPlane(x, nx, ny, nz, d) = d - n.x / |n| */
LIB_EXPANDER(ext_plane)
{
    ir *g = c->g;
    (void)n;
    lv3 nv = scalars3(a, 1);
    return ir_sub(g, a[4].s, ir_div(g, lv3_dot(g, nv, point(a)), lv3_len(g, nv)));
}

/* frSphere(x, cx, cy, cz, r) = r - |x - c| */
LIB_EXPANDER(ext_sphere)
{
    ir *g = c->g;
    (void)n;
    return ir_sub(g, a[4].s, lv3_len(g, lv3_sub(g, point(a), scalars3(a, 1))));
}

/* Axial frame of frCylinder/frCone/frTorus: v = x - p, unit axis u = a/|a|,
 * h = v.u (height along the axis), rho = |v - h u| (distance from the axis, a sum
 * of squares, so never NaN). */
static void axial(ir *g, const lib_arg *a, ir_ref *h, ir_ref *rho)
{
    lv3 v = lv3_sub(g, point(a), scalars3(a, 1));
    lv3 ax = scalars3(a, 4);
    lv3 u = lv3_div(g, ax, lv3_len(g, ax));
    *h = lv3_dot(g, v, u);
    *rho = lv3_len(g, lv3_sub(g, v, lv3_scale(g, u, *h)));
}

/* frCylinder(x, px, py, pz, ax, ay, az, r) = r - rho */
LIB_EXPANDER(ext_cylinder)
{
    ir *g = c->g;
    (void)n;
    ir_ref h, rho;
    axial(g, a, &h, &rho);
    return ir_sub(g, a[7].s, rho);
}

/* frCone(x, px, py, pz, ax, ay, az, angle) = h sin(angle) - rho cos(angle) */
LIB_EXPANDER(ext_cone)
{
    ir *g = c->g;
    (void)n;
    ir_ref h, rho;
    axial(g, a, &h, &rho);
    return ir_sub(g, ir_mul(g, h, OP1(SIN, a[7].s)), ir_mul(g, rho, OP1(COS, a[7].s)));
}

/* frTorus(x, px, py, pz, ax, ay, az, R, r) = r - sqrt((rho - R)^2 + h^2) */
LIB_EXPANDER(ext_torus)
{
    ir *g = c->g;
    (void)n;
    ir_ref h, rho;
    axial(g, a, &h, &rho);
    return ir_sub(g, a[8].s, ir_sqrt(g, ir_add(g, ir_sq(g, ir_sub(g, rho, a[7].s)), ir_sq(g, h))));
}

/* frBox(x, cx, cy, cz, hx, hy, hz, rx, ry, rz): the box of half sizes h centred at c,
 * rotated by rx about x, then ry about y, then rz about z (radians).  With
 * q = Rx(-rx) Ry(-ry) Rz(-rz) (x - c) and e_i = |q_i| - h_i:
 *   f = -|max(e, 0)|    outside (exact distance),
 *   f = -max(e_i)       inside  (distance to the nearest face). */
LIB_EXPANDER(ext_box)
{
    ir *g = c->g;
    (void)n;
    lv3 d = lv3_sub(g, point(a), scalars3(a, 1));
    ir_ref q[3] = { d.x, d.y, d.z };
    lib_rotate_pair(g, q, 0, 1, a[9].s);        /* undo the rotation about z */
    lib_rotate_pair(g, q, 2, 0, a[8].s);        /* then about y */
    lib_rotate_pair(g, q, 1, 2, a[7].s);        /* then about x */
    ir_ref e[3], o[3];
    for (int i = 0; i < 3; ++i) {
        e[i] = ir_sub(g, OP1(ABS, q[i]), a[4 + i].s);
        o[i] = OP2(MAX, e[i], K(0.0));
    }
    ir_ref out = lv3_len(g, lv3_make(o[0], o[1], o[2]));
    ir_ref in = OP2(MIN, OP2(MAX, OP2(MAX, e[0], e[1]), e[2]), K(0.0));
    return ir_neg(g, ir_add(g, out, in));
}
