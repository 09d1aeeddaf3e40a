/* test_lib.c - the function library (lang/lib*.c) against independent C code.
 *
 * For every built-in, HyperFun library function and frep extension, a tiny model
 * calling it is compiled with frep_compile() and evaluated at pseudo-random points;
 * the values must match a plain-double implementation of the formula documented in
 * doc/library.md, written here without the IR.  Space transformations are checked
 * through each coordinate of the transformed point.  Also: lib_all() covers every
 * name of doc/library.md and back, and bad arguments give compile errors.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "frep.h"
#include "lib.h"
#include "tap.h"

#define NPTS 50
#define PI 3.14159265358979323846

/* ---- helpers ----------------------------------------------------------------- */

static double sq(double v) { return v * v; }
static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static double len3(const double *a) { return sqrt(dot3(a, a)); }

static const double C0[3] = { 0.1, -0.2, 0.3 };   /* `c` in the models */
#define DECL_C "array c[3];\nc = [0.1, -0.2, 0.3];\n"

/* The two fields used by the set-operation tests: f1 a sphere, f2 a plane. */
static double F1(const double *p) { return 1 - p[0] * p[0] - p[1] * p[1] - p[2] * p[2]; }
static double F2(const double *p) { return p[0] + 0.2; }
#define DECL_F "f1 = 1 - x[1]*x[1] - x[2]*x[2] - x[3]*x[3];\nf2 = x[1] + 0.2;\n"

/* ---- references: built-ins --------------------------------------------------- */

#define REF(name, expr) \
    static double name(const double *p, int k) { (void)k; return (expr); }

REF(r_sqrt, sqrt(p[0] * p[0] + p[1] * p[1]))
REF(r_exp, exp(p[0]))
REF(r_log, log(p[0] * p[0] + 0.5))
REF(r_logd, log10(p[1] * p[1] + 0.5))
REF(r_sin, sin(p[0]))
REF(r_cos, cos(p[1]))
REF(r_tan, tan(p[2] * 0.5))
REF(r_asin, asin(p[0] / 2))
REF(r_acos, acos(p[1] / 2))
REF(r_atan, atan(p[2] * 3))
REF(r_abs, fabs(p[0]))
REF(r_sinh, sinh(p[0]))
REF(r_cosh, cosh(p[1]))
REF(r_tanh, tanh(p[2]))
REF(r_sign, (p[0] > 0 ? 1.0 : p[0] < 0 ? -1.0 : 0.0) + 10 * 0.0)
REF(r_ceil, ceil(p[0] * 3))
REF(r_floor, floor(p[1] * 3))
REF(r_int, trunc(p[2] * 3))
REF(r_frac, p[0] * 3 - trunc(p[0] * 3))
/* HF_round of the reference interpreter (int_parse_N.c of HyperFun). */
static double hf_round(double d)
{
    double c = ceil(d);
    return c - d > 0.5 ? c - 1 : c;
}
/* the reference's mod: fmod of the rounded arguments (int_calc.c, FUNC_mod) */
REF(r_mod, fmod(hf_round(p[0] * 20), hf_round(3.4)))
REF(r_max, p[0] > p[1] ? p[0] : p[1])
REF(r_min, p[0] < p[1] ? p[0] : p[1])
REF(r_atan2, atan2(p[0], p[1]))

/* ---- references: HyperFun primitives ------------------------------------------ */

static void rel3(const double *p, double *d)
{
    for (int i = 0; i < 3; ++i) d[i] = p[i] - C0[i];
}

static double r_sphere(const double *p, int k)
{
    double d[3];
    (void)k;
    rel3(p, d);
    return 0.64 - dot3(d, d);
}
static double r_ellipsoid(const double *p, int k)
{
    double d[3];
    (void)k;
    rel3(p, d);
    return 1 - sq(d[0] / 0.9) - sq(d[1] / 0.6) - sq(d[2] / 1.1);
}
/* axis k: 0, 1, 2 */
static double r_cylinder(const double *p, int k)
{
    double d[3];
    rel3(p, d);
    return 0.25 - (dot3(d, d) - d[k] * d[k]);
}
static double r_ellcyl(const double *p, int k)
{
    double d[3];
    rel3(p, d);
    /* a goes with the first remaining axis, b with the second */
    int i = k == 0 ? 1 : 0, j = k == 2 ? 1 : 2;
    return 1 - sq(d[i] / 0.7) - sq(d[j] / 0.4);
}
static double r_cone(const double *p, int k)
{
    double d[3];
    rel3(p, d);
    return d[k] * d[k] - (dot3(d, d) - d[k] * d[k]) / 0.36;
}
static double r_ellcone(const double *p, int k)
{
    double d[3];
    rel3(p, d);
    int i = k == 0 ? 1 : 0, j = k == 2 ? 1 : 2;
    return d[k] * d[k] - sq(d[i] / 0.5) - sq(d[j] / 0.8);
}
static double r_torus(const double *p, int k)
{
    double d[3];
    rel3(p, d);
    double rho = sqrt(dot3(d, d) - d[k] * d[k]);
    return 0.09 - dot3(d, d) - 0.64 + 2 * 0.8 * rho;
}
static double rint0(double a, double b) { return a + b - sqrt(a * a + b * b); }
/* hfBlock: k = 0 R-functions (default), k = 1 min/max */
static double r_block(const double *p, int k)
{
    const double e[3] = { 0.9, 0.7, 1.2 };
    double s[3];
    for (int i = 0; i < 3; ++i) s[i] = (p[i] - C0[i]) * (C0[i] + e[i] - p[i]);
    if (k == 1) return fmin(fmin(s[0], s[1]), s[2]);
    return rint0(rint0(s[0], s[1]), s[2]);
}
static double r_superell(const double *p, int k)
{
    double d[3];
    (void)k;
    rel3(p, d);
    double s1 = 0.5, s2 = 1.5;
    double xp = pow(fabs(d[0] / 0.9), 2 / s2), yp = pow(fabs(d[1] / 0.8), 2 / s2);
    double zp = pow(fabs(d[2] / 0.7), 2 / s1);
    return 1 - pow(xp + yp, s2 / s1) - zp;
}

static const double KX[3] = { 0, 0.5, -0.4 }, KY[3] = { 0.1, -0.3, 0.2 }, KZ[3] = { 0, 0.2, -0.1 };
#define DECL_KEYS "array x0[3], y0[3], z0[3], ka[3], kb[3], kd[3];\n" \
    "x0 = [0, 0.5, -0.4]; y0 = [0.1, -0.3, 0.2]; z0 = [0, 0.2, -0.1];\n" \
    "ka = [2, 3, 1.5]; kb = [1, 0.8, 1.2]; kd = [1.2, 0.9, 1.5];\n"
static const double KA[3] = { 2, 3, 1.5 }, KB[3] = { 1, 0.8, 1.2 }, KD[3] = { 1.2, 0.9, 1.5 };

static double key_r2(const double *p, int i)
{
    return sq(p[0] - KX[i]) + sq(p[1] - KY[i]) + sq(p[2] - KZ[i]);
}
static double r_blobby(const double *p, int k)
{
    double f = 0;
    (void)k;
    for (int i = 0; i < 3; ++i) f += KB[i] * exp(-KA[i] * key_r2(p, i));
    return f - 0.5;
}
static double r_metaball(const double *p, int k)
{
    double f = 0;
    (void)k;
    for (int i = 0; i < 3; ++i) {
        double r = sqrt(key_r2(p, i)), d = KD[i];
        if (r <= d / 3) f += KB[i] * (1 - 3 * r * r / (d * d));
        else if (r < d) f += 1.5 * KB[i] * sq(1 - r / d);
    }
    return f - 0.3;
}
static double r_soft(const double *p, int k)
{
    double f = 0;
    (void)k;
    for (int i = 0; i < 3; ++i) {
        double r2 = key_r2(p, i), d2 = KD[i] * KD[i];
        if (sqrt(r2) <= KD[i])
            f += 1 - 22 * r2 / (9 * d2) + 17 * r2 * r2 / (9 * d2 * d2) -
                 4 * r2 * r2 * r2 / (9 * d2 * d2 * d2);
    }
    return f - 0.2;
}

/* ---- references: convolution surfaces ----------------------------------------- */

static double r_convpoint(const double *p, int k)
{
    static const double v[6] = { 0, 0, 0, 0.5, 0.2, -0.3 }, S[2] = { 2, 1.5 };
    double f = 0;
    (void)k;
    for (int i = 0; i < 2; ++i) {
        double r2 = sq(v[3 * i] - p[0]) + sq(v[3 * i + 1] - p[1]) + sq(v[3 * i + 2] - p[2]);
        f += 1 / sq(1 + S[i] * S[i] * r2);
    }
    return f - 0.4;
}
/* Cauchy kernel integrated along the segment b -> e (Yoshikawa's closed form). */
static double seg(const double *p, const double *b, const double *e, double S)
{
    double ax[3], d[3];
    for (int i = 0; i < 3; ++i) ax[i] = e[i] - b[i];
    double l = len3(ax);
    for (int i = 0; i < 3; ++i) {
        ax[i] /= l;
        d[i] = p[i] - b[i];
    }
    double xx = dot3(d, ax), dd = dot3(d, d);
    double pp = sqrt(1 + S * S * (dd - xx * xx));
    double q = sqrt(1 + S * S * (dd + l * l - 2 * l * xx));
    return xx / (2 * pp * pp * (pp * pp + S * S * xx * xx)) + (l - xx) / (2 * pp * pp * q * q) +
           (atan(S * xx / pp) + atan(S * (l - xx) / pp)) / (2 * S * pp * pp * pp);
}
static const double LB[6] = { -0.5, 0, 0, 0, -0.4, 0.1 }, LE[6] = { 0.5, 0.1, 0, 0.2, 0.5, 0.3 };
#define DECL_LINES "array lb[6], le[6], ls[2];\nlb = [-0.5, 0, 0, 0, -0.4, 0.1];\n" \
    "le = [0.5, 0.1, 0, 0.2, 0.5, 0.3];\nls = [2, 1.5];\n"
static double r_convline(const double *p, int k)
{
    (void)k;
    return seg(p, LB, LE, 2) + seg(p, LB + 3, LE + 3, 1.5) - 0.3;
}
static double r_convliner(const double *p, int k)
{
    double R = 0.3, S = R < 1 ? 1 / R : 1, f = 0, T = 0;
    (void)k;
    for (int i = 0; i < 2; ++i) {
        double ax[3];
        for (int j = 0; j < 3; ++j) ax[j] = LE[3 * i + j] - LB[3 * i + j];
        double l = len3(ax);
        double pT = sqrt(1 + S * S * R * R), qT2 = 1 + S * S * (R * R + l * l);
        T = l / (2 * pT * pT * qT2) + atan(S * l / pT) / (2 * S * pT * pT * pT);
        double t = seg(p, LB + 3 * i, LE + 3 * i, S);
        if (f < 1) {
            f += t;
            if (f > 1) f = 1;
        }
    }
    return f - T;
}
static double r_convcurve(const double *p, int k)
{
    static const double v[9] = { -0.5, 0, 0, 0, 0.4, 0.1, 0.5, 0, 0.2 };
    (void)k;
    return seg(p, v, v + 3, 2) + seg(p, v + 3, v + 6, 1.5) - 0.3;
}

/* Arc kernel in the arc's frame (the formula of doc/library.md). */
static double arc_k(const double *q, double r, double S, double th)
{
    double x = q[0], y = q[1], z = q[2];
    double a = 2 * r * S * S, d2 = x * x + y * y + z * z;
    double b = 1 + r * r * S * S + S * S * d2;
    double p2 = -pow(r, 4) * pow(S, 4) + 2 * r * r * S * S * (S * S * (d2 - 2 * z * z) - 1) -
                sq(1 + S * S * d2);
    double p1 = sqrt(fabs(p2)), p3 = p1 * p2;
    double f1 = b * y / (x * p2 * (a * x - b)) +
                (a * (x * x + y * y) * sin(th) - b * y) /
                    (x * p2 * (a * (x * cos(th) + y * sin(th)) - b));
    double f2;
    if (p2 < 0)
        f2 = 2 * b * (atan(-a * y / p1) + atan((a * y - (a * x + b) * tan(th / 2)) / p1)) / p3;
    else
        f2 = 2 * b * (atanh(a * y / p1) + atanh(((a * x + b) * tan(th / 2) - a * y) / p1)) / p3;
    return f1 + f2;
}
static double r_convarc(const double *p, int k)
{
    const double rd = PI / 180, r = 0.6, S = 2, theta = 270, ang = -30 * rd;
    double ax[3] = { 0.3, 0.2, 1 }, v[3], q[3];
    (void)k;
    double l = len3(ax);
    for (int i = 0; i < 3; ++i) {
        ax[i] /= l;
        v[i] = p[i];                      /* centre at the origin */
    }
    /* rotate v by ang about ax (Rodrigues) */
    double c = cos(ang), s = sin(ang), kv = dot3(ax, v);
    double cr[3] = { ax[1] * v[2] - ax[2] * v[1], ax[2] * v[0] - ax[0] * v[2],
                     ax[0] * v[1] - ax[1] * v[0] };
    for (int i = 0; i < 3; ++i) q[i] = v[i] * c + cr[i] * s + ax[i] * kv * (1 - c);
    double f = arc_k(q, r, S, 180 * rd);
    double qt[3] = { -q[0], -q[1], q[2] };
    f += arc_k(qt, r, S, (theta - 180) * rd);
    return f - 0.2;
}

/* Triangle kernel (Yoshikawa's closed form) with the longest edge first. */
static double tri_k(const double *p, const double *t1, const double *t2, const double *t3,
                    double S)
{
    double A1[3], A2[3], A3[3];
    double l0 = sqrt(sq(t2[0] - t1[0]) + sq(t2[1] - t1[1]) + sq(t2[2] - t1[2]));
    double l1 = sqrt(sq(t3[0] - t2[0]) + sq(t3[1] - t2[1]) + sq(t3[2] - t2[2]));
    double l2 = sqrt(sq(t1[0] - t3[0]) + sq(t1[1] - t3[1]) + sq(t1[2] - t3[2]));
    const double *o1 = t1, *o2 = t2, *o3 = t3;
    if (l1 >= l2 && l1 > l0) { o1 = t2; o2 = t3; o3 = t1; }
    else if (l2 >= l1 && l2 > l0) { o1 = t3; o2 = t1; o3 = t2; }
    memcpy(A1, o1, sizeof A1);
    memcpy(A2, o2, sizeof A2);
    memcpy(A3, o3, sizeof A3);
    double a21[3], a13[3], b[3], d[3], u[3], v[3];
    for (int i = 0; i < 3; ++i) {
        a21[i] = A2[i] - A1[i];
        a13[i] = A1[i] - A3[i];
    }
    double t = -dot3(a21, a13) / dot3(a21, a21);
    for (int i = 0; i < 3; ++i) {
        b[i] = A1[i] + t * a21[i];
        d[i] = p[i] - b[i];
        u[i] = A2[i] - b[i];
        v[i] = A3[i] - b[i];
    }
    double a2 = len3(u), h = len3(v), tmp[3];
    for (int i = 0; i < 3; ++i) tmp[i] = A1[i] - b[i];
    double a1 = len3(tmp);
    for (int i = 0; i < 3; ++i) {
        u[i] /= a2;
        v[i] /= h;
    }
    double d2 = dot3(d, d), uu = dot3(d, u), vv = dot3(d, v);
    double g = vv - h, m = a2 * g + uu * h, kk = uu * h - a1 * g;
    double C2 = 1 / (S * S) + d2 - uu * uu, C = sqrt(C2);
    double q = C2 - vv * vv, w = C2 - 2 * vv * h + h * h;
    double A = sqrt(a1 * a1 * w + h * h * (q + uu * uu) - 2 * a1 * h * uu * g);
    double B = sqrt(a2 * a2 * w + h * h * (q + uu * uu) + 2 * a2 * h * uu * g);
    double n1 = a1 + uu, n2 = a2 - uu, n3 = a1 * n1 + vv * h, n4 = -a1 * uu - g * h;
    double n5 = -a2 * n2 - vv * h, n6 = -a2 * uu + g * h;
    double arc1 = kk * (atan(n3 / A) + atan(n4 / A)) / A;
    double arc2 = m * (atan(n5 / B) + atan(n6 / B)) / B;
    double arc3 = vv * (atan(n1 / C) + atan(n2 / C)) / C;
    return (arc1 + arc2 + arc3) / (2 * q * S);
}
static const double TV[18] = { 0, 0, 0, 1, 0, 0.1, 0.3, 0.8, 0,
                               -0.5, 0, 0, -0.4, 0.2, 0, -0.5, 1, 0.2 };
static double r_convtriangle(const double *p, int k)
{
    (void)k;
    return tri_k(p, TV, TV + 3, TV + 6, 2) + tri_k(p, TV + 9, TV + 12, TV + 15, 1.5) - 0.2;
}
static double r_convmesh(const double *p, int k)
{
    static const double mv[12] = { 0, 0, 0, 1, 0, 0.1, 0.3, 0.8, 0, -0.2, 0.5, 0.6 };
    (void)k;
    return tri_k(p, mv, mv + 3, mv + 6, 2) + tri_k(p, mv, mv + 6, mv + 9, 1.5) - 0.2;
}
static double r_noiseg(const double *p, int k)
{
    double amp = 2.5, fr = 0.7, ph = 1.4, s[3], w[3], f = 1;
    static const int o[3] = { 2, 0, 1 };
    (void)k;
    for (int i = 0; i < 3; ++i) {
        w[i] = fr * p[i];
        s[i] = sin(w[i]);
    }
    for (int i = 0; i < 3; ++i) f *= amp * s[i] + amp / 1.17 * sin(w[i] / 1.35 + ph * s[o[i]]);
    return f;
}

/* ---- references: space transformations (k = coordinate returned) ------------- */

static double r_scale(const double *p, int k)
{
    static const double s[3] = { 2, 0.5, 1.5 };
    return p[k] / s[k];
}
static double r_shift(const double *p, int k)
{
    static const double s[3] = { 0.1, -0.2, 0.3 };
    return p[k] - s[k];
}
/* inverse rotation of coordinates (i, j) by th */
static void rot(double *v, int i, int j, double th)
{
    double a = v[i] * cos(th) + v[j] * sin(th), b = -v[i] * sin(th) + v[j] * cos(th);
    v[i] = a;
    v[j] = b;
}
static double r_rotx(const double *p, int k) { double v[3] = { p[0], p[1], p[2] }; rot(v, 1, 2, 0.7); return v[k]; }
static double r_roty(const double *p, int k) { double v[3] = { p[0], p[1], p[2] }; rot(v, 2, 0, 0.7); return v[k]; }
static double r_rotz(const double *p, int k) { double v[3] = { p[0], p[1], p[2] }; rot(v, 0, 1, 0.7); return v[k]; }
static double twist(const double *p, int k, int ax)
{
    static const int ri[3] = { 1, 2, 0 }, rj[3] = { 2, 0, 1 };
    double v[3] = { p[0], p[1], p[2] };
    double t = (v[ax] + 1) / 2, th = (1 - t) * 0.2 + t * 1.3;
    rot(v, ri[ax], rj[ax], th);
    return v[k];
}
static double r_twistx(const double *p, int k) { return twist(p, k, 0); }
static double r_twisty(const double *p, int k) { return twist(p, k, 1); }
static double r_twistz(const double *p, int k) { return twist(p, k, 2); }
static double r_stretch(const double *p, int k)
{
    static const double s[3] = { 2, 0.5, 1.5 };
    return C0[k] + (p[k] - C0[k]) / s[k];
}
static double taper(const double *p, int k, int ax)
{
    double u = p[ax], sc;
    if (u < -0.5) sc = 0.6;
    else if (u > 0.8) sc = 1.4;
    else {
        double t = (u + 0.5) / 1.3;
        sc = (1 - t) * 0.6 + t * 1.4;
    }
    return k == ax ? p[k] : p[k] / sc;
}
static double r_taperx(const double *p, int k) { return taper(p, k, 0); }
static double r_tapery(const double *p, int k) { return taper(p, k, 1); }
static double r_taperz(const double *p, int k) { return taper(p, k, 2); }
static double spacemap(const double *p, int k, int cubic)
{
    static const double src[6] = { 0, 0, 0, 0.5, 0.5, 0 }, tgt[6] = { 0.3, 0.1, 0, 0.6, 0.4, 0.2 };
    static const double bb[6] = { 1, 1, 1, 0.8, 0.9, 1 };
    double v[3] = { p[0], p[1], p[2] };
    for (int i = 0; i < 6; i += 3) {
        double dt[3], q = 0;
        for (int j = 0; j < 3; ++j) {
            dt[j] = tgt[i + j] - src[i + j];
            q += sq((v[j] - tgt[i + j]) / (bb[i + j] * (1 + fabs(dt[j]))));
        }
        double w;
        if (cubic) {
            double s = sqrt(q);
            w = s <= 1 ? pow(1 - s, 3) / (1 + s) : 0;
        } else {
            w = exp(-q);
        }
        for (int j = 0; j < 3; ++j) v[j] -= w * dt[j];
    }
    return v[k];
}
static double r_smcubic(const double *p, int k) { return spacemap(p, k, 1); }
static double r_smexp(const double *p, int k) { return spacemap(p, k, 0); }

/* ---- references: blending and distances ---------------------------------------- */

static double blend(const double *p, int uni)
{
    double f1 = F1(p), f2 = F2(p);
    double d = 0.5 / (1 + sq(f1 / 0.8) + sq(f2 / 0.9));
    return f1 + f2 + (uni ? 1 : -1) * sqrt(f1 * f1 + f2 * f2) + d;
}
static double r_blenduni(const double *p, int k) { (void)k; return blend(p, 1); }
static double r_blendint(const double *p, int k) { (void)k; return blend(p, 0); }
static double r_dcone(const double *p, int k)
{
    double d[3];
    rel3(p, d);
    double t = atan(0.6), rho = sqrt(dot3(d, d) - d[k] * d[k]);
    return -(rho * cos(t) - fabs(d[k]) * sin(t));
}
static double r_dcylinder(const double *p, int k)
{
    static const double u[3] = { 0.3, 0.4, 1 };
    double w[3], cp[3];
    (void)k;
    for (int i = 0; i < 3; ++i) w[i] = C0[i] - p[i];
    cp[0] = u[1] * w[2] - u[2] * w[1];
    cp[1] = u[2] * w[0] - u[0] * w[2];
    cp[2] = u[0] * w[1] - u[1] * w[0];
    return 0.5 - sqrt(dot3(cp, cp) / dot3(u, u));
}
static double r_dtorus(const double *p, int k)
{
    double d[3];
    rel3(p, d);
    double rho = sqrt(dot3(d, d) - d[k] * d[k]);
    return -(sqrt(sq(rho - 0.8) + d[k] * d[k]) - 0.3);
}
/* Signed distance to the ellipsoid (half axes 0.9, 0.6, 1.1 at C0) computed by
 * bisection on the Lagrange parameter (not Newton, unlike the library). */
static double r_dellipsoid(const double *p, int k)
{
    const double e[3] = { 0.9, 0.6, 1.1 };
    double d[3];
    (void)k;
    rel3(p, d);
    double in = sq(d[0] / e[0]) + sq(d[1] / e[1]) + sq(d[2] / e[2]);
    /* closest point: y_i = e_i^2 d_i / (t + e_i^2) with sum (y_i/e_i)^2 = 1;
     * t in (-min e^2, 0] inside, [0, inf) outside; g(t) is decreasing there */
    double emin2 = fmin(fmin(e[0] * e[0], e[1] * e[1]), e[2] * e[2]);
    double lo = in < 1 ? -emin2 : 0, hi = in < 1 ? 0 : 1e3;
    for (int it = 0; it < 200; ++it) {
        double t = 0.5 * (lo + hi), g = 0;
        for (int i = 0; i < 3; ++i) g += sq(e[i] * d[i] / (t + e[i] * e[i]));
        if (g > 1) lo = t;
        else hi = t;
    }
    double t = 0.5 * (lo + hi), dist2 = 0;
    for (int i = 0; i < 3; ++i) {
        double y = e[i] * e[i] * d[i] / (t + e[i] * e[i]);
        dist2 += sq(y - d[i]);
    }
    return in < 1 ? sqrt(dist2) : -sqrt(dist2);
}

/* SARDF (doc/library.md): the quartic root by a fine scan for the last + to -
 * sign change in [0, sqrt(min(x, y))], then bisection. */
static double quart(double m, double x, double y, double R)
{
    return pow(m, 4) - 4 * sqrt(R) * pow(m, 3) - 4 * R * m * m + 4 * sqrt(R) * (x + y) * m -
           (x * x + y * y);
}
static double quart_root(double x, double y, double R)
{
    double top = sqrt(fmin(x, y)), lo = 0, hi = top;
    const int steps = 4000;
    for (int i = steps - 1; i >= 0; --i) {
        double m = top * i / steps;
        if (quart(m, x, y, R) > 0) {
            lo = m;
            hi = top * (i + 1) / steps;
            break;
        }
    }
    for (int it = 0; it < 100; ++it) {
        double m = 0.5 * (lo + hi);
        if (quart(m, x, y, R) > 0) lo = m;
        else hi = m;
    }
    return 0.5 * (lo + hi);
}
static double sardf_int(double x, double y, double R, double al)
{
    const double z = 1e-7;
    if (fabs(x) < z && fabs(y) < z) return 0;
    if (fabs(y) < z && x > 0) return 0;
    if (fabs(y) < z && x < 0) return x;
    if (fabs(x) < z && y > 0) return 0;
    if (fabs(x) < z && y < 0) return y;
    if (fabs(x) > z && fabs(y) > z) {
        if (x < 0 && y > 0) return x;
        if (y < 0 && x > 0) return y;
        if (x > 0 && y > 0) {
            double lim = sq(x - 2 * R) + sq(y - 2 * R);
            if (x <= R || y <= R || (x <= 2 * R && y <= 2 * R && lim >= R * R)) {
                double xx = x * x / (4 * R), yy = y * y / (4 * R);
                if (xx <= y && yy <= x) return sq(quart_root(x, y, R));
                if (xx > y) return y;
                if (yy > x) return x;
            } else {
                if (y <= x + R && y >= x - R) {
                    double b = -2 * x + 4 * R - 2 * y, c = x * x + y * y + R * R - 2 * x * R - 2 * y * R;
                    double Ds = b * b - 8 * c;
                    if (Ds >= 0) return (-b + sqrt(Ds)) / 4;
                } else {
                    if (y < x - R) return y;
                    if (y > x + R) return x;
                }
            }
        }
        if (x < 0 && y < 0) {
            double g = 1 / tan(al), g2 = tan(al), gt = x / y;
            if (gt < g && gt > g2) {
                double t = tan(al), aa = 1 - t * t - 2 * t, b = 2 * t * (x + y), c = -x * x - y * y;
                return (-b - sqrt(b * b - 4 * aa * c)) / (2 * aa);
            } else if (gt >= g) {
                return x;
            } else if (gt <= g2) {
                return y;
            }
        }
    }
    return 0;
}
static double sardf_uni(double x, double y, double R, double al)
{
    const double z = 1e-7;
    if (fabs(x) < z && fabs(y) < z) return 0;
    if (fabs(x) < z && y > 0) return y;
    if (fabs(x) < z && y < 0) return 0;
    if (fabs(y) < z && x > 0) return x;
    if (fabs(y) < z && x < 0) return 0;
    if (fabs(x) > z && fabs(y) > z) {
        if (y > 0 && x < 0) return y;
        if (x > 0 && y < 0) return x;
        if (x > 0 && y > 0) {
            double g = 1 / tan(al), g2 = tan(al), gt = x / y;
            if (gt < g && gt > g2) {
                double t = tan(al), aa = t * t + 2 * t - 1, b = -2 * t * (x + y), c = x * x + y * y;
                return (-b - sqrt(b * b - 4 * aa * c)) / (2 * aa);
            } else if (gt >= g) {
                return x;
            } else if (gt <= g2) {
                return y;
            }
        }
        if (x < 0 && y < 0) {
            double lim2 = sq(x + 2 * R) + sq(y + 2 * R);
            if (x >= -R || y >= -R || (x >= -2 * R && y >= -2 * R && lim2 >= R * R)) {
                double xx = -x * x / (4 * R), yy = -y * y / (4 * R);
                if (x <= yy && y <= xx) return -sq(quart_root(-x, -y, R));
                if (y > xx) return y;
                if (yy < x) return x;
            } else {
                if (y <= x + R && y >= x - R) {
                    double b = -2 * x - 4 * R - 2 * y, c = x * x + y * y + R * R + 2 * x * R + 2 * y * R;
                    double Ds = b * b - 8 * c;
                    if (Ds >= 0) return (-b - sqrt(Ds)) / 4;
                } else {
                    if (y < x - R) return x;
                    if (y > x + R) return y;
                }
            }
        }
    }
    return 0;
}
/* the SARDF tests scale the fields down so that all cases occur in [-1.5, 1.5]^3 */
static double SF1(const double *p) { return 0.3 * F1(p); }
static double SF2(const double *p) { return 0.3 * (p[1] - 0.1); }
#define DECL_SF "f1 = 0.3*(1 - x[1]*x[1] - x[2]*x[2] - x[3]*x[3]);\nf2 = 0.3*(x[2] - 0.1);\n"
static double r_duni(const double *p, int k) { (void)k; return sardf_uni(SF1(p), SF2(p), 0.3, 0.5); }
static double r_dint(const double *p, int k) { (void)k; return sardf_int(SF1(p), SF2(p), 0.3, 0.5); }
static double r_dsub(const double *p, int k) { (void)k; return sardf_int(SF1(p), -SF2(p), 0.3, 0.5); }
static double dblend(const double *p, int uni)
{
    double x = F1(p), y = F2(p), r = 0.3;
    if (y <= x + r && y >= x - r) {
        double b = uni ? -2 * x - 4 * r - 2 * y : -2 * x + 4 * r - 2 * y;
        double c = uni ? x * x + y * y + r * r + 2 * x * r + 2 * y * r
                       : x * x + y * y + r * r - 2 * x * r - 2 * y * r;
        double Ds = b * b - 8 * c;
        if (Ds >= 0) return uni ? (-b - sqrt(Ds)) / 4 : (-b + sqrt(Ds)) / 4;
        return 0;
    }
    if (y < x - r) return uni ? x : y;
    return uni ? y : x;
}
static double r_dblenduni(const double *p, int k) { (void)k; return dblend(p, 1); }
static double r_dblendint(const double *p, int k) { (void)k; return dblend(p, 0); }

/* ---- references: set operations and extensions --------------------------------- */

static double ralpha(double f, double g, double al, int uni)
{
    double r = sqrt(f * f + g * g - 2 * al * f * g);
    return (f + g + (uni ? r : -r)) / (1 + al);
}
REF(r_runion, F1(p) + F2(p) + sqrt(F1(p) * F1(p) + F2(p) * F2(p)))
REF(r_rint, F1(p) + F2(p) - sqrt(F1(p) * F1(p) + F2(p) * F2(p)))
REF(r_rsub, F1(p) - F2(p) - sqrt(F1(p) * F1(p) + F2(p) * F2(p)))
REF(r_mmunion, fmax(F1(p), F2(p)))
REF(r_mmint, fmin(F1(p), F2(p)))
REF(r_mmsub, fmin(F1(p), -F2(p)))
REF(r_raunion, ralpha(F1(p), F2(p), 0.4, 1))
REF(r_raint, ralpha(F1(p), F2(p), 0.4, 0))
REF(r_rasub, ralpha(F1(p), -F2(p), 0.4, 0))
REF(r_complement, -F1(p))
REF(r_ralpha_op_sub, ralpha(F1(p), -F2(p), 0.5, 0))

static double r_plane(const double *p, int k)
{
    (void)k;
    return 0.3 - (p[0] + 2 * p[1] + 2 * p[2]) / 3;
}
static double r_frsphere(const double *p, int k)
{
    double d[3];
    (void)k;
    rel3(p, d);
    return 0.8 - len3(d);
}
/* axial frame: point pt, axis ax -> h, rho */
static void axial(const double *p, const double *pt, const double *ax, double *h, double *rho)
{
    double u[3], v[3], l = len3(ax);
    for (int i = 0; i < 3; ++i) {
        u[i] = ax[i] / l;
        v[i] = p[i] - pt[i];
    }
    *h = dot3(v, u);
    *rho = sqrt(fmax(dot3(v, v) - *h * *h, 0));
}
static double r_frcylinder(const double *p, int k)
{
    static const double pt[3] = { 0.1, 0, 0 }, ax[3] = { 1, 1, 0 };
    double h, rho;
    (void)k;
    axial(p, pt, ax, &h, &rho);
    return 0.5 - rho;
}
static double r_frcone(const double *p, int k)
{
    static const double pt[3] = { 0, 0, -0.5 }, ax[3] = { 0, 0.3, 1 };
    double h, rho;
    (void)k;
    axial(p, pt, ax, &h, &rho);
    return h * sin(0.5) - rho * cos(0.5);
}
static double r_frtorus(const double *p, int k)
{
    static const double pt[3] = { 0.1, 0, 0 }, ax[3] = { 0, 1, 1 };
    double h, rho;
    (void)k;
    axial(p, pt, ax, &h, &rho);
    return 0.3 - sqrt(sq(rho - 0.8) + h * h);
}
/* frBox: world = Rz Ry Rx local + c, so local = Rx^T Ry^T Rz^T (world - c); the
 * matrices are built explicitly here. */
static void matvec_t(double m[3][3], const double *v, double *out)
{
    for (int i = 0; i < 3; ++i) out[i] = m[0][i] * v[0] + m[1][i] * v[1] + m[2][i] * v[2];
}
static double r_frbox(const double *p, int k)
{
    const double hs[3] = { 0.5, 0.7, 0.4 }, rx = 0.3, ry = -0.5, rz = 0.8;
    double Rx[3][3] = { { 1, 0, 0 }, { 0, cos(rx), -sin(rx) }, { 0, sin(rx), cos(rx) } };
    double Ry[3][3] = { { cos(ry), 0, sin(ry) }, { 0, 1, 0 }, { -sin(ry), 0, cos(ry) } };
    double Rz[3][3] = { { cos(rz), -sin(rz), 0 }, { sin(rz), cos(rz), 0 }, { 0, 0, 1 } };
    double d[3], t1[3], t2[3], q[3];
    (void)k;
    rel3(p, d);
    matvec_t(Rz, d, t1);
    matvec_t(Ry, t1, t2);
    matvec_t(Rx, t2, q);
    double e[3], o = 0;
    for (int i = 0; i < 3; ++i) {
        e[i] = fabs(q[i]) - hs[i];
        o += sq(fmax(e[i], 0));
    }
    double mx = fmax(fmax(e[0], e[1]), e[2]);
    return mx > 0 ? -sqrt(o) : -mx;
}

/* ---- the cases ------------------------------------------------------------------- */

typedef struct tcase {
    const char *name;       /* shown in the TAP line */
    const char *body;       /* model statements; the model is named m */
    double (*ref)(const double *p, int k);
    int k;                  /* passed to ref (axis or coordinate) */
    double tol;             /* relative tolerance: |got - want| <= tol (1 + |want|) */
    int setops;             /* -1 or a frep_setops override */
    double alpha;
} tcase;

#define T1 1e-12
#define C1(fn, body, ref) { fn, body, ref, 0, T1, -1, 0 }
#define CK(fn, body, ref, k) { fn, body, ref, k, T1, -1, 0 }
#define XT "array xt[3];\nxt = [x[1], x[2], x[3]];\n"
#define XTC "array xt[3], c[3];\nxt = [x[1], x[2], x[3]];\nc = [0.1, -0.2, 0.3];\n"
/* transformations: the model returns coordinate K of xt; (d - 1) * 1000 checks that
 * the call itself returned 1 */
#define TR(fn, call, ref) \
    CK(fn, XTC "d = " call ";\nm = xt[1] + (d - 1)*1000;\n", ref, 0), \
    CK(fn, XTC "d = " call ";\nm = xt[2] + (d - 1)*1000;\n", ref, 1), \
    CK(fn, XTC "d = " call ";\nm = xt[3] + (d - 1)*1000;\n", ref, 2)

static const tcase cases[] = {
    C1("sqrt", "m = sqrt(x[1]*x[1] + x[2]*x[2]);", r_sqrt),
    C1("exp", "m = exp(x[1]);", r_exp),
    C1("log", "m = log(x[1]*x[1] + 0.5);", r_log),
    C1("logd", "m = logd(x[2]*x[2] + 0.5);", r_logd),
    C1("sin", "m = sin(x[1]);", r_sin),
    C1("cos", "m = cos(x[2]);", r_cos),
    C1("tan", "m = tan(x[3]*0.5);", r_tan),
    C1("asin", "m = asin(x[1]/2);", r_asin),
    C1("acos", "m = acos(x[2]/2);", r_acos),
    C1("atan", "m = atan(x[3]*3);", r_atan),
    C1("abs", "m = abs(x[1]);", r_abs),
    C1("sinh", "m = sinh(x[1]);", r_sinh),
    C1("cosh", "m = cosh(x[2]);", r_cosh),
    C1("tanh", "m = tanh(x[3]);", r_tanh),
    C1("sign", "m = sign(x[1]) + 10*sign(x[1] - x[1]);", r_sign),
    C1("ceil", "m = ceil(x[1]*3);", r_ceil),
    C1("floor", "m = floor(x[2]*3);", r_floor),
    C1("int", "m = int(x[3]*3);", r_int),
    C1("frac", "m = frac(x[1]*3);", r_frac),
    C1("mod", "m = mod(x[1]*20, 3.4);", r_mod),
    C1("max", "m = max(x[1], x[2]);", r_max),
    C1("min", "m = min(x[1], x[2]);", r_min),
    C1("atan2", "m = atan2(x[1], x[2]);", r_atan2),

    C1("hfSphere", DECL_C "m = hfSphere(x, c, 0.8);", r_sphere),
    C1("hfEllipsoid", DECL_C "m = hfEllipsoid(x, c, 0.9, 0.6, 1.1);", r_ellipsoid),
    CK("hfCylinderX", DECL_C "m = hfCylinderX(x, c, 0.5);", r_cylinder, 0),
    CK("hfCylinderY", DECL_C "m = hfCylinderY(x, c, 0.5);", r_cylinder, 1),
    CK("hfCylinderZ", DECL_C "m = hfCylinderZ(x, c, 0.5);", r_cylinder, 2),
    CK("hfEllCylX", DECL_C "m = hfEllCylX(x, c, 0.7, 0.4);", r_ellcyl, 0),
    CK("hfEllCylY", DECL_C "m = hfEllCylY(x, c, 0.7, 0.4);", r_ellcyl, 1),
    CK("hfEllCylZ", DECL_C "m = hfEllCylZ(x, c, 0.7, 0.4);", r_ellcyl, 2),
    CK("hfConeX", DECL_C "m = hfConeX(x, c, 0.6);", r_cone, 0),
    CK("hfConeY", DECL_C "m = hfConeY(x, c, 0.6);", r_cone, 1),
    CK("hfConeZ", DECL_C "m = hfConeZ(x, c, 0.6);", r_cone, 2),
    CK("hfEllConeX", DECL_C "m = hfEllConeX(x, c, 0.5, 0.8);", r_ellcone, 0),
    CK("hfEllConeY", DECL_C "m = hfEllConeY(x, c, 0.5, 0.8);", r_ellcone, 1),
    CK("hfEllConeZ", DECL_C "m = hfEllConeZ(x, c, 0.5, 0.8);", r_ellcone, 2),
    CK("hfTorusX", DECL_C "m = hfTorusX(x, c, 0.8, 0.3);", r_torus, 0),
    CK("hfTorusY", DECL_C "m = hfTorusY(x, c, 0.8, 0.3);", r_torus, 1),
    CK("hfTorusZ", DECL_C "m = hfTorusZ(x, c, 0.8, 0.3);", r_torus, 2),
    C1("hfBlock", DECL_C "m = hfBlock(x, c, 0.9, 0.7, 1.2);", r_block),
    { "hfBlock (min/max)", DECL_C "m = hfBlock(x, c, 0.9, 0.7, 1.2);", r_block, 1, T1,
      FREP_SETOPS_MINMAX, 0 },
    { "hfSuperell", DECL_C "m = hfSuperell(x, c, 0.9, 0.8, 0.7, 0.5, 1.5);", r_superell, 0,
      1e-10, -1, 0 },
    C1("hfBlobby", DECL_KEYS "m = hfBlobby(x, x0, y0, z0, ka, kb, 0.5);", r_blobby),
    C1("hfMetaball", DECL_KEYS "m = hfMetaball(x, x0, y0, z0, kb, kd, 0.3);", r_metaball),
    C1("hfSoft", DECL_KEYS "m = hfSoft(x, x0, y0, z0, kd, 0.2);", r_soft),
    C1("hfConvPoint", "array v[6], s[2];\nv = [0, 0, 0, 0.5, 0.2, -0.3];\ns = [2, 1.5];\n"
                      "m = hfConvPoint(x, v, s, 0.4);", r_convpoint),
    { "hfConvLine", DECL_LINES "m = hfConvLine(x, lb, le, ls, 0.3);", r_convline, 0, 1e-10, -1, 0 },
    { "hfConvLineR", DECL_LINES "m = hfConvLineR(x, lb, le, 0.3);", r_convliner, 0, 1e-10, -1, 0 },
    { "hfConvCurve", "array v[9], s[2];\nv = [-0.5, 0, 0, 0, 0.4, 0.1, 0.5, 0, 0.2];\n"
                     "s = [2, 1.5];\nm = hfConvCurve(x, v, s, 0.3);", r_convcurve, 0, 1e-10, -1, 0 },
    { "hfConvArc", "array ce[3], ra[1], th[1], ax[3], an[1], s[1];\nce = [0, 0, 0];\n"
                   "ra = [0.6];\nth = [270];\nax = [0.3, 0.2, 1];\nan = [30];\ns = [2];\n"
                   "m = hfConvArc(x, ce, ra, th, ax, an, s, 0.2);", r_convarc, 0, 1e-8, -1, 0 },
    { "hfConvTriangle", "array v[18], s[2];\nv = [0, 0, 0, 1, 0, 0.1, 0.3, 0.8, 0, "
                        "-0.5, 0, 0, -0.4, 0.2, 0, -0.5, 1, 0.2];\ns = [2, 1.5];\n"
                        "m = hfConvTriangle(x, v, s, 0.2);", r_convtriangle, 0, 1e-9, -1, 0 },
    { "hfConvMesh", "array v[12], t[6], s[2];\nv = [0, 0, 0, 1, 0, 0.1, 0.3, 0.8, 0, -0.2, 0.5, 0.6];\n"
                    "t = [1, 2, 3, 1, 3, 4];\ns = [2, 1.5];\n"
                    "m = hfConvMesh(x, v, t, s, 0.2);", r_convmesh, 0, 1e-9, -1, 0 },
    C1("hfNoiseG", "m = hfNoiseG(x, 2.5, 0.7, 1.4);", r_noiseg),

    TR("hfScale3D", "hfScale3D(xt, 2, 0.5, 1.5)", r_scale),
    TR("hfShift3D", "hfShift3D(xt, 0.1, -0.2, 0.3)", r_shift),
    TR("hfRotate3DX", "hfRotate3DX(xt, 0.7)", r_rotx),
    TR("hfRotate3DY", "hfRotate3DY(xt, 0.7)", r_roty),
    TR("hfRotate3DZ", "hfRotate3DZ(xt, 0.7)", r_rotz),
    TR("hfTwistX", "hfTwistX(xt, -1, 1, 0.2, 1.3)", r_twistx),
    TR("hfTwistY", "hfTwistY(xt, -1, 1, 0.2, 1.3)", r_twisty),
    TR("hfTwistZ", "hfTwistZ(xt, -1, 1, 0.2, 1.3)", r_twistz),
    TR("hfStretch3D", "hfStretch3D(xt, c, 2, 0.5, 1.5)", r_stretch),
    TR("hfTaperX", "hfTaperX(xt, -0.5, 0.8, 0.6, 1.4)", r_taperx),
    TR("hfTaperY", "hfTaperY(xt, -0.5, 0.8, 0.6, 1.4)", r_tapery),
    TR("hfTaperZ", "hfTaperZ(xt, -0.5, 0.8, 0.6, 1.4)", r_taperz),
#define SM "array xt[3], src[6], tgt[6], bb[6];\nxt = [x[1], x[2], x[3]];\nsrc = [0, 0, 0, 0.5, 0.5, 0];\n" \
    "tgt = [0.3, 0.1, 0, 0.6, 0.4, 0.2];\nbb = [1, 1, 1, 0.8, 0.9, 1];\n"
    CK("hfSpaceMapCubic", SM "d = hfSpaceMapCubic(xt, src, tgt, bb);\nm = xt[1] + (d-1)*1000;", r_smcubic, 0),
    CK("hfSpaceMapCubic", SM "d = hfSpaceMapCubic(xt, src, tgt, bb);\nm = xt[2] + (d-1)*1000;", r_smcubic, 1),
    CK("hfSpaceMapCubic", SM "d = hfSpaceMapCubic(xt, src, tgt, bb);\nm = xt[3] + (d-1)*1000;", r_smcubic, 2),
    CK("hfSpaceMapExp", SM "d = hfSpaceMapExp(xt, src, tgt, bb);\nm = xt[1] + (d-1)*1000;", r_smexp, 0),
    CK("hfSpaceMapExp", SM "d = hfSpaceMapExp(xt, src, tgt, bb);\nm = xt[2] + (d-1)*1000;", r_smexp, 1),
    CK("hfSpaceMapExp", SM "d = hfSpaceMapExp(xt, src, tgt, bb);\nm = xt[3] + (d-1)*1000;", r_smexp, 2),

    C1("hfBlendUni", DECL_F "m = hfBlendUni(f1, f2, 0.5, 0.8, 0.9);", r_blenduni),
    C1("hfBlendInt", DECL_F "m = hfBlendInt(f1, f2, 0.5, 0.8, 0.9);", r_blendint),
    CK("hfDConeX", DECL_C "m = hfDConeX(x, c, 0.6);", r_dcone, 0),
    CK("hfDConeY", DECL_C "m = hfDConeY(x, c, 0.6);", r_dcone, 1),
    CK("hfDConeZ", DECL_C "m = hfDConeZ(x, c, 0.6);", r_dcone, 2),
    C1("hfDCylinder", "array c[3], u[3];\nc = [0.1, -0.2, 0.3];\nu = [0.3, 0.4, 1];\nm = hfDCylinder(x, c, u, 0.5);",
       r_dcylinder),
    /* the reference stops its Newton iteration at a residual of 1e-6 (documented), so
     * the distance is only accurate to about 1e-5 */
    { "hfDEllipsoid", DECL_C "m = hfDEllipsoid(x, c, 0.9, 0.6, 1.1);", r_dellipsoid, 0, 1e-4,
      -1, 0 },
    CK("hfDTorusX", DECL_C "m = hfDTorusX(x, c, 0.8, 0.3);", r_dtorus, 0),
    CK("hfDTorusY", DECL_C "m = hfDTorusY(x, c, 0.8, 0.3);", r_dtorus, 1),
    CK("hfDTorusZ", DECL_C "m = hfDTorusZ(x, c, 0.8, 0.3);", r_dtorus, 2),
    { "hfDUni", DECL_SF "m = hfDUni(f1, f2, 0.3, 0.5);", r_duni, 0, 1e-9, -1, 0 },
    { "hfDInt", DECL_SF "m = hfDInt(f1, f2, 0.3, 0.5);", r_dint, 0, 1e-9, -1, 0 },
    { "hfDSub", DECL_SF "m = hfDSub(f1, f2, 0.3, 0.5);", r_dsub, 0, 1e-9, -1, 0 },
    C1("hfDBlendUni", DECL_F "m = hfDBlendUni(f1, f2, 0.3);", r_dblenduni),
    C1("hfDBlendInt", DECL_F "m = hfDBlendInt(f1, f2, 0.3);", r_dblendint),

    C1("rUnion", DECL_F "m = rUnion(f1, f2);", r_runion),
    C1("rIntersection", DECL_F "m = rIntersection(f1, f2);", r_rint),
    C1("rSubtraction", DECL_F "m = rSubtraction(f1, f2);", r_rsub),
    C1("mmUnion", DECL_F "m = mmUnion(f1, f2);", r_mmunion),
    C1("mmIntersection", DECL_F "m = mmIntersection(f1, f2);", r_mmint),
    C1("mmSubtraction", DECL_F "m = mmSubtraction(f1, f2);", r_mmsub),
    C1("raUnion", DECL_F "m = raUnion(f1, f2, 0.4);", r_raunion),
    C1("raIntersection", DECL_F "m = raIntersection(f1, f2, 0.4);", r_raint),
    C1("raSubtraction", DECL_F "m = raSubtraction(f1, f2, 0.4);", r_rasub),
    /* alpha from the a[] array: not a compile-time constant */
    C1("raUnion (alpha = a[1])", DECL_F "m = raUnion(f1, f2, a[1]);", r_raunion),
    C1("raSubtraction (alpha = a[1])", DECL_F "m = raSubtraction(f1, f2, a[1]);", r_rasub),
    C1("frComplement", DECL_F "m = frComplement(f1);", r_complement),
    C1("frBlendUnion", DECL_F "m = frBlendUnion(f1, f2, 0.5, 0.8, 0.9);", r_blenduni),
    C1("frBlendIntersection", DECL_F "m = frBlendIntersection(f1, f2, 0.5, 0.8, 0.9);", r_blendint),
    C1("frPlane", "m = frPlane(x, 1, 2, 2, 0.3);", r_plane),
    C1("frSphere", "m = frSphere(x, 0.1, -0.2, 0.3, 0.8);", r_frsphere),
    { "frCylinder", "m = frCylinder(x, 0.1, 0, 0, 1, 1, 0, 0.5);", r_frcylinder, 0, 1e-10, -1, 0 },
    { "frCone", "m = frCone(x, 0, 0, -0.5, 0, 0.3, 1, 0.5);", r_frcone, 0, 1e-10, -1, 0 },
    { "frTorus", "m = frTorus(x, 0.1, 0, 0, 0, 1, 1, 0.8, 0.3);", r_frtorus, 0, 1e-10, -1, 0 },
    C1("frBox", "m = frBox(x, 0.1, -0.2, 0.3, 0.5, 0.7, 0.4, 0.3, -0.5, 0.8);", r_frbox),

    /* the operators under each semantics (lib_union & co.) */
    C1("| under R-functions", DECL_F "m = f1 | f2;", r_runion),
    { "& under min/max", DECL_F "m = f1 & f2;", r_mmint, 0, T1, FREP_SETOPS_MINMAX, 0 },
    { "\\ under min/max", DECL_F "m = f1 \\ f2;", r_mmsub, 0, T1, FREP_SETOPS_MINMAX, 0 },
    { "\\ under R-alpha 0.5", DECL_F "m = f1 \\ f2;", r_ralpha_op_sub, 0, T1,
      FREP_SETOPS_RALPHA, 0.5 },
};

#define NCASES (sizeof cases / sizeof cases[0])

/* ---- running ------------------------------------------------------------------- */

typedef struct diag_buf {
    char text[2048];
    int errors;
} diag_buf;

static void collect(void *user, const frep_diag *d)
{
    diag_buf *b = user;
    size_t n = strlen(b->text);
    if (d->severity == FREP_ERROR) ++b->errors;
    (void)snprintf(b->text + n, sizeof b->text - n, "%u:%u: %s\n", (unsigned)d->line,
                   (unsigned)d->col, d->message);
}

static frep_program *compile_body(const char *body, int setops, double alpha, diag_buf *db)
{
    static const double avals[1] = { 0.4 };
    char src[4096];
    frep_compile_options o;
    (void)snprintf(src, sizeof src, "m(x[3], a[1]) {\n%s\n}\n", body);
    frep_compile_options_init(&o);
    o.a = avals;
    o.na = 1;
    if (setops >= 0) {
        o.setops_override = setops;
        o.alpha = alpha;
    }
    memset(db, 0, sizeof *db);
    return frep_compile("test.hf", src, strlen(src), &o, collect, db);
}

static void points(double *x, double *y, double *z)
{
    unsigned long s = 12345;
    for (int i = 0; i < NPTS; ++i) {
        double v[3];
        for (int j = 0; j < 3; ++j) {
            s = s * 6364136223846793005UL + 1442695040888963407UL;
            v[j] = -1.5 + 3.0 * (double)((s >> 11) & 0xFFFFFFFFFFFFFUL) / 4503599627370496.0;
        }
        x[i] = v[0];
        y[i] = v[1];
        z[i] = v[2];
    }
}

static void run_case(const tcase *t, const double *x, const double *y, const double *z)
{
    diag_buf db;
    frep_program *p = compile_body(t->body, t->setops, t->alpha, &db);
    if (!p) {
        ok(0, "%s (k=%d) compiles", t->name, t->k);
        diag("%s", db.text);
        return;
    }
    frep_scratch *s = frep_scratch_new(p);
    double f[NPTS];
    int rc = s ? frep_eval(p, s, NPTS, x, y, z, NULL, f) : -1;
    int bad = 0;
    double worst = 0, wgot = 0, wwant = 0;
    for (int i = 0; rc == 0 && i < NPTS; ++i) {
        const double pt[3] = { x[i], y[i], z[i] };
        double want = t->ref(pt, t->k);
        double err = fabs(f[i] - want);
        if (!(err <= t->tol * (1 + fabs(want)))) {
            if (!bad || err > worst || isnan(err)) {
                worst = err;
                wgot = f[i];
                wwant = want;
            }
            ++bad;
        }
    }
    ok(rc == 0 && bad == 0, "%s (k=%d) matches its formula at %d points", t->name, t->k, NPTS);
    if (bad) diag("  %d points differ; worst got %.17g want %.17g", bad, wgot, wwant);
    frep_scratch_free(s);
    frep_program_free(p);
}

/* A model that must not compile, with a message mentioning `what`. */
static void must_fail(const char *body, const char *what)
{
    diag_buf db;
    frep_program *p = compile_body(body, -1, 0, &db);
    ok(!p && strstr(db.text, what) != NULL, "rejected: %s", what);
    if (p) frep_program_free(p);
    else if (!strstr(db.text, what)) diag("%s", db.text);
}

/* Every `### name(` heading of doc/library.md names a library function, and every
 * library function has a heading. */
static void check_doc(void)
{
    const char *srcdir = getenv("srcdir");
    char path[4096];
    (void)snprintf(path, sizeof path, "%s/doc/library.md", srcdir ? srcdir : ".");
    FILE *fp = fopen(path, "r");
    if (!fp) {
        ok(0, "doc/library.md readable (%s)", path);
        return;
    }
    uint32_t nfn;
    const lib_fn *fns = lib_all(&nfn);
    char *seen = calloc(nfn, 1);
    char line[1024];
    int unknown = 0, headings = 0;
    while (fgets(line, sizeof line, fp)) {
        if (strncmp(line, "### `", 5) != 0) continue;
        char name[128];
        size_t k = 0;
        for (const char *q = line + 5; *q && *q != '(' && *q != '`' && k + 1 < sizeof name; ++q)
            name[k++] = *q;
        name[k] = 0;
        ++headings;
        const lib_fn *fn = lib_lookup(name);
        if (!fn) {
            ++unknown;
            diag("  doc names '%s', which the library lacks", name);
        } else {
            seen[fn - fns] = 1;
        }
    }
    fclose(fp);
    int missing = 0;
    for (uint32_t i = 0; i < nfn; ++i)
        if (!seen[i]) {
            ++missing;
            diag("  '%s' is not documented", fns[i].name);
        }
    free(seen);
    ok(headings > 0 && unknown == 0, "every documented name is in lib_all() (%d headings)", headings);
    ok(missing == 0, "every lib_all() entry is documented (%u functions)", (unsigned)nfn);
}

int main(void)
{
    double x[NPTS], y[NPTS], z[NPTS];
    points(x, y, z);
    for (size_t i = 0; i < NCASES; ++i) run_case(&cases[i], x, y, z);

    /* lookup is case-insensitive, unknown names give NULL */
    ok(lib_lookup("HFSPHERE") == lib_lookup("hfSphere") && lib_lookup("hfSphere") != NULL,
       "lookup ignores case");
    ok(lib_lookup("hfNoSuchThing") == NULL, "unknown name: NULL");

    must_fail("array x0[2], y0[1], z0[2], ka[2], kb[2];\nx0 = [0, 1]; y0 = [0]; z0 = [0, 1];\n"
              "ka = [1, 1]; kb = [1, 1];\nm = hfBlobby(x, x0, y0, z0, ka, kb, 0.5);",
              "hfBlobby");
    must_fail("array v[9], t[3], s[1];\nv = [0,0,0, 1,0,0, 0,1,0];\nt = [1, 2, 4];\ns = [1];\n"
              "m = hfConvMesh(x, v, t, s, 0.1);", "hfConvMesh");
    must_fail("array v[9], t[3], s[1];\nv = [0,0,0, 1,0,0, 0,1,0];\nt = [1, 2, x[1]];\ns = [1];\n"
              "m = hfConvMesh(x, v, t, s, 0.1);", "constant");
    must_fail("array xt[3];\nxt = [x[1], x[2], x[3]];\nd = hfScale3D(xt, 1, 0, 1);\nm = xt[1];",
              "hfScale3D");
    must_fail("array xt[3];\nxt = [x[1], x[2], x[3]];\nd = hfTaperZ(xt, 0, 1, -1, 1);\nm = xt[1];",
              "hfTaperZ");
    must_fail("array xt[3], s[4], t[4], b[4];\nxt = [x[1], x[2], x[3]];\ns = [0,0,0,0];\n"
              "t = [0,0,0,0];\nb = [1,1,1,1];\nd = hfSpaceMapExp(xt, s, t, b);\nm = xt[1];",
              "multiple of 3");

    /* hfDEllipsoid at known distances: 0.5 beyond the x half-axis is 0.5 outside,
     * 0.2 inside from the end of the y half-axis is 0.2 inside */
    {
        diag_buf db;
        frep_program *p = compile_body(DECL_C "m = hfDEllipsoid(x, c, 0.9, 0.6, 1.1);", -1, 0, &db);
        frep_scratch *s = p ? frep_scratch_new(p) : NULL;
        double px[2] = { 0.1 + 0.9 + 0.5, 0.1 }, py[2] = { -0.2, -0.2 + 0.6 - 0.2 };
        double pz[2] = { 0.3, 0.3 };
        double f[2] = { NAN, NAN };
        if (s) (void)frep_eval(p, s, 2, px, py, pz, NULL, f);
        is_double(f[0], -0.5, 1e-5, "hfDEllipsoid 0.5 beyond the surface is -0.5");
        is_double(f[1], 0.2, 1e-5, "hfDEllipsoid 0.2 inside the surface is 0.2");
        frep_scratch_free(s);
        frep_program_free(p);
    }

    check_doc();
    return done_testing();
}
