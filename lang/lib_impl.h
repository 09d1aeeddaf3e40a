/* lib_impl.h - private helpers of the function library (lang/lib.c, lang/lib_hf.c,
 * lang/lib_ext.c, lang/lib_attr.c): 3-vectors of IR refs, guarded square roots, and the expanders
 * that lib.c lists in its table.  Not used outside those three files.
 */
#ifndef FREP_LIB_IMPL_H
#define FREP_LIB_IMPL_H

#include "frep.h"
#include "lib.h"

/* A point or direction as three IR refs. */
typedef struct lv3 {
    ir_ref x, y, z;
} lv3;

static inline lv3 lv3_make(ir_ref x, ir_ref y, ir_ref z)
{
    lv3 v = { x, y, z };
    return v;
}
/* Elements i, i+1, i+2 of an array argument (0-based). */
static inline lv3 lv3_at(const ir_ref *e, uint32_t i)
{
    return lv3_make(e[i], e[i + 1], e[i + 2]);
}
static inline lv3 lv3_sub(ir *g, lv3 a, lv3 b)
{
    return lv3_make(ir_sub(g, a.x, b.x), ir_sub(g, a.y, b.y), ir_sub(g, a.z, b.z));
}
static inline lv3 lv3_add(ir *g, lv3 a, lv3 b)
{
    return lv3_make(ir_add(g, a.x, b.x), ir_add(g, a.y, b.y), ir_add(g, a.z, b.z));
}
static inline lv3 lv3_scale(ir *g, lv3 a, ir_ref s)
{
    return lv3_make(ir_mul(g, a.x, s), ir_mul(g, a.y, s), ir_mul(g, a.z, s));
}
static inline lv3 lv3_div(ir *g, lv3 a, ir_ref s)
{
    return lv3_make(ir_div(g, a.x, s), ir_div(g, a.y, s), ir_div(g, a.z, s));
}
static inline ir_ref lv3_dot(ir *g, lv3 a, lv3 b)
{
    return ir_add(g, ir_add(g, ir_mul(g, a.x, b.x), ir_mul(g, a.y, b.y)),
                  ir_mul(g, a.z, b.z));
}
/* |a|^2 as a sum of squares: never negative, so its sqrt needs no guard. */
static inline ir_ref lv3_len2(ir *g, lv3 a)
{
    return ir_add(g, ir_add(g, ir_sq(g, a.x), ir_sq(g, a.y)), ir_sq(g, a.z));
}
static inline ir_ref lv3_len(ir *g, lv3 a) { return ir_sqrt(g, lv3_len2(g, a)); }
static inline lv3 lv3_cross(ir *g, lv3 a, lv3 b)
{
    return lv3_make(ir_sub(g, ir_mul(g, a.y, b.z), ir_mul(g, a.z, b.y)),
                    ir_sub(g, ir_mul(g, a.z, b.x), ir_mul(g, a.x, b.z)),
                    ir_sub(g, ir_mul(g, a.x, b.y), ir_mul(g, a.y, b.x)));
}
/* sqrt of a quantity that is >= 0 in exact arithmetic but may round below 0:
 * clamped at 0 so that rounding never turns into NaN and a domain error. */
static inline ir_ref lib_sqrt0(ir *g, ir_ref a)
{
    return ir_sqrt(g, ir_op2(g, FREP_OP_MAX, a, ir_k(g, 0.0)));
}

/* Inverse rotation by theta of the coordinates (i, j) of e (in place), the space
 * mapping that rotates an object by +theta: u' = u cos + v sin, v' = -u sin + v cos. */
static inline void lib_rotate_pair(ir *g, ir_ref *e, int i, int j, ir_ref theta)
{
    ir_ref ct = ir_op1(g, FREP_OP_COS, theta), st = ir_op1(g, FREP_OP_SIN, theta);
    ir_ref u = e[i], v = e[j];
    e[i] = ir_add(g, ir_mul(g, u, ct), ir_mul(g, v, st));
    e[j] = ir_add(g, ir_neg(g, ir_mul(g, u, st)), ir_mul(g, v, ct));
}

/* Shared set-operation expansion for R-alpha with an arbitrary (maybe non-constant)
 * alpha: (f + g +- sqrt(f^2 + g^2 - 2 alpha f g)) / (1 + alpha). */
ir_ref lib_ralpha(lib_ctx *c, ir_ref f, ir_ref g2, ir_ref alpha, int uni);

/* Expanders, listed in lib.c's table.  Each has the lib_expand_fn signature. */
#define LIB_EXPANDER(name) ir_ref name(lib_ctx *c, lib_arg *a, uint32_t n)

/* lib_hf.c: the HyperFun FRep library */
LIB_EXPANDER(hf_sphere);
LIB_EXPANDER(hf_ellipsoid);
LIB_EXPANDER(hf_cylinder_x);
LIB_EXPANDER(hf_cylinder_y);
LIB_EXPANDER(hf_cylinder_z);
LIB_EXPANDER(hf_ellcyl_x);
LIB_EXPANDER(hf_ellcyl_y);
LIB_EXPANDER(hf_ellcyl_z);
LIB_EXPANDER(hf_cone_x);
LIB_EXPANDER(hf_cone_y);
LIB_EXPANDER(hf_cone_z);
LIB_EXPANDER(hf_ellcone_x);
LIB_EXPANDER(hf_ellcone_y);
LIB_EXPANDER(hf_ellcone_z);
LIB_EXPANDER(hf_torus_x);
LIB_EXPANDER(hf_torus_y);
LIB_EXPANDER(hf_torus_z);
LIB_EXPANDER(hf_block);
LIB_EXPANDER(hf_superell);
LIB_EXPANDER(hf_blobby);
LIB_EXPANDER(hf_metaball);
LIB_EXPANDER(hf_soft);
LIB_EXPANDER(hf_conv_point);
LIB_EXPANDER(hf_conv_line);
LIB_EXPANDER(hf_conv_line_r);
LIB_EXPANDER(hf_conv_curve);
LIB_EXPANDER(hf_conv_arc);
LIB_EXPANDER(hf_conv_triangle);
LIB_EXPANDER(hf_conv_mesh);
LIB_EXPANDER(hf_noise_g);
LIB_EXPANDER(hf_scale3d);
LIB_EXPANDER(hf_shift3d);
LIB_EXPANDER(hf_rotate3d_x);
LIB_EXPANDER(hf_rotate3d_y);
LIB_EXPANDER(hf_rotate3d_z);
LIB_EXPANDER(hf_twist_x);
LIB_EXPANDER(hf_twist_y);
LIB_EXPANDER(hf_twist_z);
LIB_EXPANDER(hf_stretch3d);
LIB_EXPANDER(hf_taper_x);
LIB_EXPANDER(hf_taper_y);
LIB_EXPANDER(hf_taper_z);
LIB_EXPANDER(hf_spacemap_cubic);
LIB_EXPANDER(hf_spacemap_exp);
LIB_EXPANDER(hf_blend_uni);
LIB_EXPANDER(hf_blend_int);
LIB_EXPANDER(hf_dcone_x);
LIB_EXPANDER(hf_dcone_y);
LIB_EXPANDER(hf_dcone_z);
LIB_EXPANDER(hf_dcylinder);
LIB_EXPANDER(hf_dellipsoid);
LIB_EXPANDER(hf_dtorus_x);
LIB_EXPANDER(hf_dtorus_y);
LIB_EXPANDER(hf_dtorus_z);
LIB_EXPANDER(hf_duni);
LIB_EXPANDER(hf_dint);
LIB_EXPANDER(hf_dsub);
LIB_EXPANDER(hf_dblend_uni);
LIB_EXPANDER(hf_dblend_int);

/* lib_attr.c: the attribute library (hfA_*) and hfSawtooth */
LIB_EXPANDER(hf_sawtooth);
LIB_EXPANDER(hfa_set_color);
LIB_EXPANDER(hfa_set_attributes);
LIB_EXPANDER(hfa_union);
LIB_EXPANDER(hfa_lerp);
LIB_EXPANDER(hfa_cerp);
LIB_EXPANDER(hfa_clamp);
LIB_EXPANDER(hfa_floor);
LIB_EXPANDER(hfa_pulse);
LIB_EXPANDER(hfa_step);
LIB_EXPANDER(hfa_smooth_step);
LIB_EXPANDER(hfa_modulo);
LIB_EXPANDER(hfa_wave);
LIB_EXPANDER(hfa_rgb_to_hsv);
LIB_EXPANDER(hfa_hsv_to_rgb);
LIB_EXPANDER(hfa_noise_g);
LIB_EXPANDER(hfa_circles);
LIB_EXPANDER(hfa_crackles);
LIB_EXPANDER(hfa_checkerboard);
LIB_EXPANDER(hfa_lookup_table);
LIB_EXPANDER(hfa_smooth_lookup_table);
LIB_EXPANDER(hfa_spline);
LIB_EXPANDER(hf_bezier_volume);
LIB_EXPANDER(hfa_noise_p);
LIB_EXPANDER(hfa_turbulence);

/* lib_ext.c: frep's extensions */
LIB_EXPANDER(ext_r_union);
LIB_EXPANDER(ext_r_intersection);
LIB_EXPANDER(ext_r_subtraction);
LIB_EXPANDER(ext_mm_union);
LIB_EXPANDER(ext_mm_intersection);
LIB_EXPANDER(ext_mm_subtraction);
LIB_EXPANDER(ext_ra_union);
LIB_EXPANDER(ext_ra_intersection);
LIB_EXPANDER(ext_ra_subtraction);
LIB_EXPANDER(ext_complement);
LIB_EXPANDER(ext_plane);
LIB_EXPANDER(ext_sphere);
LIB_EXPANDER(ext_cylinder);
LIB_EXPANDER(ext_cone);
LIB_EXPANDER(ext_torus);
LIB_EXPANDER(ext_box);

#endif
