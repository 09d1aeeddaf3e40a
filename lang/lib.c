/* lib.c - the function library's table: built-in functions, the HyperFun FRep
 * library (expanded in lib_hf.c) and frep's extensions (lib_ext.c).
 *
 * check.c finds calls here by name; lower.c calls `expand`, which turns the call
 * into scalar IR operations (no per-function opcodes), so gradients, parameter
 * derivatives, intervals, constant folding and CSE apply to library code too.
 * doc/library.md documents every entry with its defining formula.
 */
#include <math.h>
#include <stddef.h>

#include "lib_impl.h"

/* ---- built-in functions ----------------------------------------------------
 * Each maps to one opcode of runtime/ops.h; the opcode table states its meaning and
 * its domain errors (sqrt, log, logd, asin, acos, mod).  sign() is -1, 0 or 1 (the
 * reference interpreter returns 1 for every argument). */

#define LIB_UNARY(fname, OP) \
    static ir_ref fname(lib_ctx *c, lib_arg *a, uint32_t n) \
    { \
        (void)n; \
        return ir_op1(c->g, FREP_OP_##OP, a[0].s); \
    }
#define LIB_BINARY(fname, OP) \
    static ir_ref fname(lib_ctx *c, lib_arg *a, uint32_t n) \
    { \
        (void)n; \
        return ir_op2(c->g, FREP_OP_##OP, a[0].s, a[1].s); \
    }

LIB_UNARY(bi_sqrt, SQRT)
LIB_UNARY(bi_exp, EXP)
LIB_UNARY(bi_log, LOG)
LIB_UNARY(bi_logd, LOGD)
LIB_UNARY(bi_sin, SIN)
LIB_UNARY(bi_cos, COS)
/* tan(a) as the reference's FUNC_tan (int_calc.c): its runtime error "Tan argument
 * error" where |cos(a)| < EPS = 1e-6, so NaN there. */
static ir_ref bi_tan(lib_ctx *c, lib_arg *a, uint32_t n)
{
    ir *g = c->g;
    ir_ref near_pole = ir_op2(g, FREP_OP_LT, ir_op1(g, FREP_OP_ABS, ir_op1(g, FREP_OP_COS, a[0].s)),
                              ir_k(g, 1e-6));
    (void)n;
    return ir_select(g, near_pole, ir_k(g, NAN), ir_op1(g, FREP_OP_TAN, a[0].s));
}
LIB_UNARY(bi_asin, ASIN)
LIB_UNARY(bi_acos, ACOS)
LIB_UNARY(bi_atan, ATAN)
LIB_UNARY(bi_abs, ABS)
LIB_UNARY(bi_sinh, SINH)
LIB_UNARY(bi_cosh, COSH)
LIB_UNARY(bi_tanh, TANH)
LIB_UNARY(bi_sign, SIGN)
LIB_UNARY(bi_ceil, CEIL)
LIB_UNARY(bi_floor, FLOOR)
LIB_UNARY(bi_int, INT)
LIB_UNARY(bi_frac, FRAC)
LIB_BINARY(bi_max, MAX)
LIB_BINARY(bi_min, MIN)
LIB_BINARY(bi_atan2, ATAN2)

double lib_hf_round_k(double d)
{
    double c = ceil(d);
    return c - d > 0.5 ? c - 1 : c;
}

ir_ref lib_hf_round(ir *g, ir_ref d)
{
    ir_ref c = ir_op1(g, FREP_OP_CEIL, d);
    ir_ref down = ir_op2(g, FREP_OP_GT, ir_sub(g, c, d), ir_k(g, 0.5));
    return ir_select(g, down, ir_sub(g, c, ir_k(g, 1.0)), c);
}

/* mod(a, b) as the reference computes it (FUNC_mod in int_calc.c of HyperFun):
 * fmod(HF_round(a), HF_round(b)), so both arguments are first rounded to whole
 * numbers (mod(2.7, 2) = fmod(3, 2) = 1), the result has the sign of a, and a b that
 * rounds to 0 is the MOD opcode's domain error (the reference returns fmod's NaN). */
static ir_ref bi_mod(lib_ctx *c, lib_arg *a, uint32_t n)
{
    (void)n;
    return ir_op2(c->g, FREP_OP_MOD, lib_hf_round(c->g, a[0].s), lib_hf_round(c->g, a[1].s));
}

/* ---- set operations of the operators | & \ ---------------------------------- */

ir_ref lib_ralpha(lib_ctx *c, ir_ref f, ir_ref g2, ir_ref alpha, int uni)
{
    ir *g = c->g;
    double k;
    if (ir_is_const(g, alpha, &k))
        return ir_op2k(g, uni ? FREP_OP_AUNI : FREP_OP_AINT, f, g2, k);
    /* A non-constant alpha (a free parameter, say) has no immediate form: spell the
     * formula out.  The radicand is >= 0 for |alpha| <= 1 and is clamped like the
     * AUNI/AINT opcodes clamp it. */
    ir_ref rad = ir_sub(g, ir_add(g, ir_sq(g, f), ir_sq(g, g2)),
                        ir_mul(g, ir_mul(g, ir_k(g, 2.0), alpha), ir_mul(g, f, g2)));
    ir_ref root = lib_sqrt0(g, rad);
    ir_ref s = ir_add(g, f, g2);
    s = uni ? ir_add(g, s, root) : ir_sub(g, s, root);
    return ir_div(g, s, ir_add(g, ir_k(g, 1.0), alpha));
}

ir_ref lib_union(lib_ctx *c, ir_ref a, ir_ref b)
{
    switch ((frep_setops)c->setops) {
    case FREP_SETOPS_MINMAX: return ir_op2(c->g, FREP_OP_MAX, a, b);
    case FREP_SETOPS_RALPHA: return ir_op2k(c->g, FREP_OP_AUNI, a, b, c->alpha);
    case FREP_SETOPS_RFUNC: break;
    }
    return ir_op2(c->g, FREP_OP_RUNI, a, b);
}

ir_ref lib_intersection(lib_ctx *c, ir_ref a, ir_ref b)
{
    switch ((frep_setops)c->setops) {
    case FREP_SETOPS_MINMAX: return ir_op2(c->g, FREP_OP_MIN, a, b);
    case FREP_SETOPS_RALPHA: return ir_op2k(c->g, FREP_OP_AINT, a, b, c->alpha);
    case FREP_SETOPS_RFUNC: break;
    }
    return ir_op2(c->g, FREP_OP_RINT, a, b);
}

ir_ref lib_subtraction(lib_ctx *c, ir_ref a, ir_ref b)
{
    switch ((frep_setops)c->setops) {
    case FREP_SETOPS_MINMAX: return ir_op2(c->g, FREP_OP_MSUB, a, b);
    case FREP_SETOPS_RALPHA:
        return ir_op2k(c->g, FREP_OP_AINT, a, ir_neg(c->g, b), c->alpha);
    case FREP_SETOPS_RFUNC: break;
    }
    return ir_op2(c->g, FREP_OP_RSUB, a, b);
}

/* ---- the table ----------------------------------------------------------------
 * args: one letter per argument (lib.h); sizes: minimum sizes of 'a' arguments by
 * position.  Array sizes that depend on other arguments ('v') are checked by the
 * expanders themselves. */

#define S3 { 0, 3 }          /* second argument is a 3-element array */

static const lib_fn lib_table[] = {
    /* built-in functions */
    { "sqrt", "s", { 0 }, bi_sqrt, "square root (error for a negative argument)" },
    { "exp", "s", { 0 }, bi_exp, "e to the power of the argument" },
    { "log", "s", { 0 }, bi_log, "natural logarithm (error for an argument <= 0)" },
    { "logd", "s", { 0 }, bi_logd, "decimal logarithm (error for an argument <= 0)" },
    { "sin", "s", { 0 }, bi_sin, "sine (radians)" },
    { "cos", "s", { 0 }, bi_cos, "cosine (radians)" },
    { "tan", "s", { 0 }, bi_tan, "tangent (radians; NaN where |cos| < 1e-6)" },
    { "asin", "s", { 0 }, bi_asin, "arc sine (error outside [-1, 1])" },
    { "acos", "s", { 0 }, bi_acos, "arc cosine (error outside [-1, 1])" },
    { "atan", "s", { 0 }, bi_atan, "arc tangent" },
    { "abs", "s", { 0 }, bi_abs, "absolute value" },
    { "sinh", "s", { 0 }, bi_sinh, "hyperbolic sine" },
    { "cosh", "s", { 0 }, bi_cosh, "hyperbolic cosine" },
    { "tanh", "s", { 0 }, bi_tanh, "hyperbolic tangent" },
    { "sign", "s", { 0 }, bi_sign, "-1, 0 or 1" },
    { "ceil", "s", { 0 }, bi_ceil, "smallest integer >= the argument" },
    { "floor", "s", { 0 }, bi_floor, "largest integer <= the argument" },
    { "int", "s", { 0 }, bi_int, "the argument truncated toward zero" },
    { "frac", "s", { 0 }, bi_frac, "fractional part: a - int(a)" },
    { "mod", "ss", { 0 }, bi_mod,
      "remainder of round(a) / round(b) with the sign of a (error when round(b) = 0)" },
    { "max", "ss", { 0 }, bi_max, "larger of two values" },
    { "min", "ss", { 0 }, bi_min, "smaller of two values" },
    { "atan2", "ss", { 0 }, bi_atan2, "angle of the point (b, a): atan2(a, b)" },

    /* HyperFun FRep library: primitives */
    { "hfSphere", "xas", S3, hf_sphere, "sphere: R^2 - |x - center|^2" },
    { "hfEllipsoid", "xasss", S3, hf_ellipsoid, "ellipsoid with half-axes a, b, c" },
    { "hfCylinderX", "xas", S3, hf_cylinder_x, "infinite cylinder along x" },
    { "hfCylinderY", "xas", S3, hf_cylinder_y, "infinite cylinder along y" },
    { "hfCylinderZ", "xas", S3, hf_cylinder_z, "infinite cylinder along z" },
    { "hfEllCylX", "xass", S3, hf_ellcyl_x, "elliptic cylinder along x" },
    { "hfEllCylY", "xass", S3, hf_ellcyl_y, "elliptic cylinder along y" },
    { "hfEllCylZ", "xass", S3, hf_ellcyl_z, "elliptic cylinder along z" },
    { "hfConeX", "xas", S3, hf_cone_x, "double cone along x, radius R at distance 1" },
    { "hfConeY", "xas", S3, hf_cone_y, "double cone along y, radius R at distance 1" },
    { "hfConeZ", "xas", S3, hf_cone_z, "double cone along z, radius R at distance 1" },
    { "hfEllConeX", "xass", S3, hf_ellcone_x, "elliptic cone along x" },
    { "hfEllConeY", "xass", S3, hf_ellcone_y, "elliptic cone along y" },
    { "hfEllConeZ", "xass", S3, hf_ellcone_z, "elliptic cone along z" },
    { "hfTorusX", "xass", S3, hf_torus_x, "torus around the x axis" },
    { "hfTorusY", "xass", S3, hf_torus_y, "torus around the y axis" },
    { "hfTorusZ", "xass", S3, hf_torus_z, "torus around the z axis" },
    { "hfBlock", "xasss", S3, hf_block, "axis-aligned block from a vertex and edge lengths" },
    { "hfSuperell", "xasssss", S3, hf_superell, "superellipsoid" },
    { "hfBlobby", "xvvvvvs", { 0 }, hf_blobby, "blobby object (Blinn): sum b exp(-a r^2) - T" },
    { "hfMetaball", "xvvvvvs", { 0 }, hf_metaball, "metaballs (Nishimura)" },
    { "hfSoft", "xvvvvs", { 0 }, hf_soft, "soft objects (Wyvill)" },
    { "hfConvPoint", "xvvs", { 0 }, hf_conv_point, "Cauchy convolution of points" },
    { "hfConvLine", "xvvvs", { 0 }, hf_conv_line, "Cauchy convolution of line segments" },
    { "hfConvLineR", "xvvs", { 0 }, hf_conv_line_r, "Cauchy line segments of width R" },
    { "hfConvCurve", "xvvs", { 0 }, hf_conv_curve, "Cauchy convolution of a polyline" },
    { "hfConvArc", "xvvvvvvs", { 0 }, hf_conv_arc, "Cauchy convolution of circular arcs" },
    { "hfConvTriangle", "xvvs", { 0 }, hf_conv_triangle, "Cauchy convolution of triangles" },
    { "hfConvMesh", "xvvvs", { 0 }, hf_conv_mesh, "Cauchy convolution of an indexed mesh" },
    { "hfNoiseG", "xsss", { 0 }, hf_noise_g, "Gardner's solid noise" },
    /* HyperFun FRep library: space transformations (modify their first argument) */
    { "hfScale3D", "msss", { 0 }, hf_scale3d, "scale space: x /= sx ..." },
    { "hfShift3D", "msss", { 0 }, hf_shift3d, "shift space: x -= dx ..." },
    { "hfRotate3DX", "ms", { 0 }, hf_rotate3d_x, "rotate about the x axis" },
    { "hfRotate3DY", "ms", { 0 }, hf_rotate3d_y, "rotate about the y axis" },
    { "hfRotate3DZ", "ms", { 0 }, hf_rotate3d_z, "rotate about the z axis" },
    { "hfTwistX", "mssss", { 0 }, hf_twist_x, "twist about the x axis" },
    { "hfTwistY", "mssss", { 0 }, hf_twist_y, "twist about the y axis" },
    { "hfTwistZ", "mssss", { 0 }, hf_twist_z, "twist about the z axis" },
    { "hfStretch3D", "masss", S3, hf_stretch3d, "stretch space about a point" },
    { "hfTaperX", "mssss", { 0 }, hf_taper_x, "taper along x" },
    { "hfTaperY", "mssss", { 0 }, hf_taper_y, "taper along y" },
    { "hfTaperZ", "mssss", { 0 }, hf_taper_z, "taper along z" },
    { "hfSpaceMapCubic", "mvvv", { 0 }, hf_spacemap_cubic, "space mapping, cubic kernel" },
    { "hfSpaceMapExp", "mvvv", { 0 }, hf_spacemap_exp, "space mapping, Gaussian kernel" },
    /* HyperFun FRep library: blending */
    { "hfBlendUni", "sssss", { 0 }, hf_blend_uni, "blending union" },
    { "hfBlendInt", "sssss", { 0 }, hf_blend_int, "blending intersection" },
    /* HyperFun FRep library: distance-based */
    { "hfDConeX", "xas", S3, hf_dcone_x, "signed distance to a double cone along x" },
    { "hfDConeY", "xas", S3, hf_dcone_y, "signed distance to a double cone along y" },
    { "hfDConeZ", "xas", S3, hf_dcone_z, "signed distance to a double cone along z" },
    { "hfDCylinder", "xaas", { 0, 3, 3 }, hf_dcylinder, "signed distance to a cylinder" },
    { "hfDEllipsoid", "xasss", S3, hf_dellipsoid, "signed distance to an ellipsoid" },
    { "hfDTorusX", "xass", S3, hf_dtorus_x, "signed distance to a torus around x" },
    { "hfDTorusY", "xass", S3, hf_dtorus_y, "signed distance to a torus around y" },
    { "hfDTorusZ", "xass", S3, hf_dtorus_z, "signed distance to a torus around z" },
    { "hfDUni", "ssss", { 0 }, hf_duni, "distance-preserving union (SARDF)" },
    { "hfDInt", "ssss", { 0 }, hf_dint, "distance-preserving intersection (SARDF)" },
    { "hfDSub", "ssss", { 0 }, hf_dsub, "distance-preserving subtraction (SARDF)" },
    { "hfDBlendUni", "sss", { 0 }, hf_dblend_uni, "distance blending union of radius r" },
    { "hfDBlendInt", "sss", { 0 }, hf_dblend_int, "distance blending intersection of radius r" },
    { "hfSawtooth", "ssss", { 0 }, hf_sawtooth, "sawtooth wave: Fourier sum of n - 1 sines" },
    { "hfBezierVolume", "xsssvv", { 0 }, hf_bezier_volume, "Bezier volume clipped to a box" },
    /* HyperFun attribute library (lib_attr.c): 'w' arrays are written */
    { "hfA_SetColor", "swsss", { 0 }, hfa_set_color, "s[1..3] = r, g, b where f >= 0" },
    { "hfA_SetAttributes", "swv", { 0 }, hfa_set_attributes, "s = s1 where f >= 0" },
    { "hfA_Union", "sswvvs", { 0 }, hfa_union, "attributes of a union, by operator" },
    { "hfA_Lerp", "wvvsss", { 0 }, hfa_lerp, "s = linear mix of s1 and s2" },
    { "hfA_Cerp", "wvvsss", { 0 }, hfa_cerp, "s = cubic mix of s1 and s2" },
    { "hfA_Clamp", "sss", { 0 }, hfa_clamp, "f clamped to [lo, hi]" },
    { "hfA_Floor", "s", { 0 }, hfa_floor, "f truncated toward zero" },
    { "hfA_Pulse", "sss", { 0 }, hfa_pulse, "1 where q <= f <= p, else 0" },
    { "hfA_Step", "ss", { 0 }, hfa_step, "0 where f < e, else 1" },
    { "hfA_SmoothStep", "sss", { 0 }, hfa_smooth_step, "smooth step from lo to hi" },
    { "hfA_Modulo", "ss", { 0 }, hfa_modulo, "v modulo m, in [0, m)" },
    { "hfA_Wave", "ssss", { 0 }, hfa_wave, "sine wave between c1 and c2" },
    { "hfA_RGBToHSV", "vw", { 0 }, hfa_rgb_to_hsv, "hsv = the RGB colour rgb in HSV" },
    { "hfA_HSVToRGB", "vw", { 0 }, hfa_hsv_to_rgb, "rgb = the HSV colour hsv in RGB" },
    { "hfA_CheckerBoard", "xvvwvv", { 0 }, hfa_checkerboard, "out = in_block or in_gap by cell" },
    { "hfA_Crackles", "xwswv", { 0 }, hfa_crackles, "out = table row by a crackle pattern" },
    { "hfA_Circles", "xwwv", { 0 }, hfa_circles, "out = table row by concentric circles" },
    { "hfA_NoiseG", "xss", { 0 }, hfa_noise_g, "Gardner noise in [0, 1]" },
    { "hfA_NoiseP", "x", { 0 }, hfa_noise_p, "Perlin noise, about [-1, 1]" },
    { "hfA_Turbulence", "xs", { 0 }, hfa_turbulence, "sum of |2 noise - 1| / f octaves" },
    { "hfA_LookUpTable", "swvv", { 0 }, hfa_lookup_table, "out = table row by t" },
    { "hfA_SmoothLookUpTable", "swvv", { 0 }, hfa_smooth_lookup_table, "out = mixed table rows by t" },
    { "hfA_Spline", "wvsss", { 0 }, hfa_spline, "s = Catmull-Rom spline through knots" },

    /* frep extensions (from here to the end: lib_frep_only): explicit set operations */
    { "rUnion", "ss", { 0 }, ext_r_union, "R0 union f + g + sqrt(f^2 + g^2)" },
    { "rIntersection", "ss", { 0 }, ext_r_intersection, "R0 intersection" },
    { "rSubtraction", "ss", { 0 }, ext_r_subtraction, "R0 subtraction" },
    { "mmUnion", "ss", { 0 }, ext_mm_union, "min/max union: max(f, g)" },
    { "mmIntersection", "ss", { 0 }, ext_mm_intersection, "min/max intersection: min(f, g)" },
    { "mmSubtraction", "ss", { 0 }, ext_mm_subtraction, "min/max subtraction: min(f, -g)" },
    { "raUnion", "sss", { 0 }, ext_ra_union, "R-alpha union with parameter alpha" },
    { "raIntersection", "sss", { 0 }, ext_ra_intersection, "R-alpha intersection" },
    { "raSubtraction", "sss", { 0 }, ext_ra_subtraction, "R-alpha subtraction" },
    { "frComplement", "s", { 0 }, ext_complement, "complement: -f" },
    { "frBlendUnion", "sssss", { 0 }, hf_blend_uni, "blending union (same as hfBlendUni)" },
    { "frBlendIntersection", "sssss", { 0 }, hf_blend_int,
      "blending intersection (same as hfBlendInt)" },
    /* frep extensions: signed-distance primitives in general position (geom/prim.h) */
    { "frPlane", "xssss", { 0 }, ext_plane, "half-space d - n.x / |n|" },
    { "frSphere", "xssss", { 0 }, ext_sphere, "sphere r - |x - c|" },
    { "frCylinder", "xsssssss", { 0 }, ext_cylinder, "cylinder: point, axis, radius" },
    { "frCone", "xsssssss", { 0 }, ext_cone, "cone: apex, axis, half-angle" },
    { "frTorus", "xssssssss", { 0 }, ext_torus, "torus: centre, axis, R, r" },
    { "frBox", "xsssssssss", { 0 }, ext_box,
      "box: centre, half sizes, rotation angles about x, y, z" },
};

#define LIB_COUNT ((uint32_t)(sizeof lib_table / sizeof lib_table[0]))

static int lower_ascii(int ch)
{
    return ch >= 'A' && ch <= 'Z' ? ch - 'A' + 'a' : ch;
}

/* Identifiers are case-insensitive in HyperFun; compare ASCII letters folded. */
static int name_eq(const char *a, const char *b)
{
    for (; *a && *b; ++a, ++b)
        if (lower_ascii((unsigned char)*a) != lower_ascii((unsigned char)*b)) return 0;
    return *a == *b;
}

const lib_fn *lib_lookup(const char *name)
{
    if (!name) return NULL;
    for (uint32_t i = 0; i < LIB_COUNT; ++i)
        if (name_eq(lib_table[i].name, name)) return &lib_table[i];
    return NULL;
}

int lib_frep_only(const lib_fn *fn)
{
    static const char first_ext[] = "rUnion";
    uint32_t i;
    for (i = 0; i < LIB_COUNT; ++i)
        if (name_eq(lib_table[i].name, first_ext)) break;
    return fn >= lib_table + i && fn < lib_table + LIB_COUNT;
}

const lib_fn *lib_all(uint32_t *count)
{
    if (count) *count = LIB_COUNT;
    return lib_table;
}
