/* tritri.c - exact triangle-triangle intersection for the self-intersection count of
 * mesh_validate (geom/trimesh.c).  Predicates: orient2d and orient3d with a
 * floating-point filter, and Shewchuk's expansion arithmetic ("Adaptive Precision
 * Floating-Point Arithmetic and Fast Robust Geometric Predicates", 1997) when the
 * filter cannot decide, so every sign is exact for any double coordinates.
 * Two closed triangles meet iff an edge of one meets the other (the ends of their
 * common segment lie on edges); an edge meets a triangle by five orientations.
 */
#include "tritri.h"

#include <math.h>

/* ---- expansion arithmetic --------------------------------------------------------- */

/* Components of an expansion at most: orient3d's determinant of 2-component
 * differences needs 192. */
#define EXP_MAX 256
/* Relative error bounds of the filters, a safe multiple of Shewchuk's (7 + 56 eps) eps
 * for orient3d and (3 + 16 eps) eps for orient2d, so that contraction into fused
 * multiply-adds cannot break them. */
#define ORIENT3D_FILTER 1e-14
#define ORIENT2D_FILTER 1e-14

/* A nonoverlapping expansion: c[0..n-1] in increasing magnitude, sum exact. */
typedef struct expansion {
    int n;
    double c[EXP_MAX];
} expansion;

static void two_sum(double a, double b, double *x, double *y)
{
    double s = a + b, bv = s - a, av = s - bv;
    *x = s;
    *y = (a - av) + (b - bv);
}

static void two_diff(double a, double b, double *x, double *y)
{
    double s = a - b, bv = a - s, av = s + bv;
    *x = s;
    *y = (a - av) + (bv - b);
}

static void two_prod(double a, double b, double *x, double *y)
{
    *x = a * b;
    *y = fma(a, b, -*x);
}

/* e += f (e and f of at least one component each; Shewchuk's FAST-EXPANSION-SUM, zero components dropped): one merge of the
 * two component lists by magnitude, then a single pass of two_sum. */
static void exp_add(expansion *e, const expansion *f)
{
    double g[2 * EXP_MAX];
    int n = 0, i = 0, j = 0;
    if (e->n + f->n == 0) return;
    while (i < e->n && j < f->n)
        g[n++] = fabs(f->c[j]) < fabs(e->c[i]) ? f->c[j++] : e->c[i++];
    while (i < e->n) g[n++] = e->c[i++];
    while (j < f->n) g[n++] = f->c[j++];
    double q = g[0], hh;
    e->n = 0;
    for (int k = 1; k < n; k++) {
        two_sum(q, g[k], &q, &hh);
        if (hh != 0) e->c[e->n++] = hh;
    }
    if (q != 0 || e->n == 0) e->c[e->n++] = q;
}

/* h = e * b (SCALE-EXPANSION, zero components dropped). */
static void exp_scale(const expansion *e, double b, expansion *h)
{
    double q, hh, p1, p0, s;
    two_prod(e->c[0], b, &q, &hh);
    h->n = 0;
    if (hh != 0) h->c[h->n++] = hh;
    for (int i = 1; i < e->n; i++) {
        two_prod(e->c[i], b, &p1, &p0);
        two_sum(q, p0, &s, &hh);
        if (hh != 0) h->c[h->n++] = hh;
        q = p1 + s;
        hh = s - (q - p1);
        if (hh != 0) h->c[h->n++] = hh;
    }
    if (q != 0 || h->n == 0) h->c[h->n++] = q;
}

/* h = e * f, sign s (+1 or -1) applied. */
static void exp_mul(const expansion *e, const expansion *f, double s, expansion *h)
{
    expansion t;
    h->n = 1;
    h->c[0] = 0;
    for (int j = 0; j < f->n; j++) {
        exp_scale(e, s * f->c[j], &t);
        exp_add(h, &t);
    }
}

static int exp_sign(const expansion *e)
{
    double top = e->c[e->n - 1];
    return (top > 0) - (top < 0);
}

/* a - b exactly, as a two-component expansion. */
static void exp_diff(double a, double b, expansion *h)
{
    double x, y;
    two_diff(a, b, &x, &y);
    if (y == 0) {
        h->n = 1;
        h->c[0] = x;
        return;
    }
    h->n = 2;
    h->c[0] = y;
    h->c[1] = x;
}

/* u1 * v2 - u2 * v1 exactly. */
static void exp_minor(const expansion *u1, const expansion *v2, const expansion *u2,
                      const expansion *v1, expansion *h)
{
    expansion t;
    exp_mul(u1, v2, 1, h);
    exp_mul(u2, v1, -1, &t);
    exp_add(h, &t);
}

/* ---- predicates ------------------------------------------------------------------- */

static int orient3d_exact(const double *a, const double *b, const double *c, const double *d)
{
    static const int rot[3][3] = { { 0, 1, 2 }, { 1, 2, 0 }, { 2, 0, 1 } };
    const double *p[3] = { a, b, c };
    expansion D[3][3], m, t, det;
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) exp_diff(p[i][k], d[k], &D[i][k]);
    det.n = 1;
    det.c[0] = 0;
    for (int r = 0; r < 3; r++) {
        const expansion *x = D[rot[r][0]], *y = D[rot[r][1]], *z = D[rot[r][2]];
        exp_minor(&y[1], &z[2], &y[2], &z[1], &m);   /* y.y z.z - y.z z.y */
        exp_mul(&m, &x[0], 1, &t);
        exp_add(&det, &t);
    }
    return exp_sign(&det);
}

int tri_orient3d(const double *a, const double *b, const double *c, const double *d)
{
    double adx = a[0] - d[0], ady = a[1] - d[1], adz = a[2] - d[2];
    double bdx = b[0] - d[0], bdy = b[1] - d[1], bdz = b[2] - d[2];
    double cdx = c[0] - d[0], cdy = c[1] - d[1], cdz = c[2] - d[2];
    double m1 = bdy * cdz - bdz * cdy, m2 = cdy * adz - cdz * ady, m3 = ady * bdz - adz * bdy;
    double det = adx * m1 + bdx * m2 + cdx * m3;
    double perm = fabs(adx) * (fabs(bdy * cdz) + fabs(bdz * cdy)) +
                  fabs(bdx) * (fabs(cdy * adz) + fabs(cdz * ady)) +
                  fabs(cdx) * (fabs(ady * bdz) + fabs(adz * bdy));
    if (fabs(det) > ORIENT3D_FILTER * perm) return (det > 0) - (det < 0);
    /* four points with one coordinate equal lie in a plane normal to that axis (the
     * flat faces of CSG solids, where most undecided cases come from) */
    for (int k = 0; k < 3; k++)
        if (a[k] == d[k] && b[k] == d[k] && c[k] == d[k]) return 0;
    /* ... or in two lines parallel to an axis (the walls of extrusions, whose vertices
     * stand in columns), or three of them on one such line */
    const double *p[4] = { a, b, c, d };
    for (int k = 0; k < 3; k++) {
        int i = (k + 1) % 3, j = (k + 2) % 3;
        int same[4][4];
        for (int u = 0; u < 4; u++)
            for (int w = u + 1; w < 4; w++) same[u][w] = p[u][i] == p[w][i] && p[u][j] == p[w][j];
        if ((same[0][1] && same[2][3]) || (same[0][2] && same[1][3]) || (same[0][3] && same[1][2]) ||
            (same[0][1] && same[0][2]) || (same[0][1] && same[0][3]) || (same[0][2] && same[0][3]) ||
            (same[1][2] && same[1][3]))
            return 0;
    }
    return orient3d_exact(a, b, c, d);
}

/* The sign of det [a - c; b - c] in the coordinates i, j. */
static int orient2d(const double *a, const double *b, const double *c, int i, int j)
{
    double acx = a[i] - c[i], acy = a[j] - c[j], bcx = b[i] - c[i], bcy = b[j] - c[j];
    double det = acx * bcy - acy * bcx, perm = fabs(acx * bcy) + fabs(acy * bcx);
    if (fabs(det) > ORIENT2D_FILTER * perm) return (det > 0) - (det < 0);
    /* on a line parallel to an axis, or two of the points the same */
    if ((a[i] == c[i] && b[i] == c[i]) || (a[j] == c[j] && b[j] == c[j]) ||
        (a[i] == c[i] && a[j] == c[j]) || (b[i] == c[i] && b[j] == c[j]) ||
        (a[i] == b[i] && a[j] == b[j]))
        return 0;
    expansion ax, ay, bx, by, h;
    exp_diff(a[i], c[i], &ax);
    exp_diff(a[j], c[j], &ay);
    exp_diff(b[i], c[i], &bx);
    exp_diff(b[j], c[j], &by);
    exp_minor(&ax, &by, &ay, &bx, &h);
    return exp_sign(&h);
}

/* ---- segments and triangles ------------------------------------------------------- */

/* The two coordinates kept when projecting triangle a, b, c along the axis of its
 * normal's largest component (its projected area is then far from 0). */
static void tri_plane_axes(const double *a, const double *b, const double *c, int *i, int *j)
{
    double u[3], w[3], n[3];
    for (int k = 0; k < 3; k++) {
        u[k] = b[k] - a[k];
        w[k] = c[k] - a[k];
    }
    n[0] = fabs(u[1] * w[2] - u[2] * w[1]);
    n[1] = fabs(u[2] * w[0] - u[0] * w[2]);
    n[2] = fabs(u[0] * w[1] - u[1] * w[0]);
    int drop = n[0] >= n[1] && n[0] >= n[2] ? 0 : (n[1] >= n[2] ? 1 : 2);
    *i = drop == 0 ? 1 : 0;
    *j = drop == 2 ? 1 : 2;
}

/* Exactly zero area: collinear in every projection. */
static int tri_degenerate(const double *a, const double *b, const double *c)
{
    return orient2d(a, b, c, 0, 1) == 0 && orient2d(a, b, c, 1, 2) == 0 &&
           orient2d(a, b, c, 2, 0) == 0;
}

/* Closed segments pq and rs of one plane (coordinates i, j) meet. */
static int seg_seg_2d(const double *p, const double *q, const double *r, const double *s,
                      int i, int j)
{
    int o1 = orient2d(p, q, r, i, j), o2 = orient2d(p, q, s, i, j);
    if (o1 == 0 && o2 == 0) {
        /* collinear: overlap of the projections on one axis where they are not points */
        int k = p[i] != q[i] || r[i] != s[i] ? i : j;
        double lo1 = fmin(p[k], q[k]), hi1 = fmax(p[k], q[k]);
        double lo2 = fmin(r[k], s[k]), hi2 = fmax(r[k], s[k]);
        return lo1 <= hi2 && lo2 <= hi1;
    }
    int o3 = orient2d(r, s, p, i, j), o4 = orient2d(r, s, q, i, j);
    return o1 * o2 <= 0 && o3 * o4 <= 0;
}

/* Closed point p lies in triangle a, b, c of its plane (coordinates i, j). */
static int point_in_tri_2d(const double *p, const double *a, const double *b, const double *c,
                           int i, int j)
{
    int s = orient2d(a, b, c, i, j);
    int s1 = orient2d(a, b, p, i, j), s2 = orient2d(b, c, p, i, j), s3 = orient2d(c, a, p, i, j);
    return s != 0 && s1 != -s && s2 != -s && s3 != -s;
}

/* Closed segment pq meets closed triangle a, b, c (not degenerate). */
static int seg_tri(const double *p, const double *q, const double *a, const double *b,
                   const double *c)
{
    int op = tri_orient3d(a, b, c, p), oq = tri_orient3d(a, b, c, q);
    if (op == oq && op != 0) return 0;
    if (op == 0 && oq == 0) {
        int i, j;
        tri_plane_axes(a, b, c, &i, &j);
        return point_in_tri_2d(p, a, b, c, i, j) || point_in_tri_2d(q, a, b, c, i, j) ||
               seg_seg_2d(p, q, a, b, i, j) || seg_seg_2d(p, q, b, c, i, j) ||
               seg_seg_2d(p, q, c, a, i, j);
    }
    /* pq crosses the plane: the line pq passes through the triangle when it turns the
     * same way (or not at all) around the three edges */
    int s1 = tri_orient3d(p, q, a, b), s2 = tri_orient3d(p, q, b, c), s3 = tri_orient3d(p, q, c, a);
    return !((s1 > 0 || s2 > 0 || s3 > 0) && (s1 < 0 || s2 < 0 || s3 < 0));
}

/* Vertices first..2 of q lie strictly on one side of the plane of p. */
static int plane_side(const double *const p[3], const double *const q[3], int first)
{
    int s = tri_orient3d(p[0], p[1], p[2], q[first]);
    if (s == 0) return 0;
    for (int i = first + 1; i < 3; i++)
        if (tri_orient3d(p[0], p[1], p[2], q[i]) != s) return 0;
    return 1;
}

int tri_tri_intersect(const double *const p[3], const double *const q[3], int nshared)
{
    if (nshared >= 3) return 1;
    if (tri_degenerate(p[0], p[1], p[2]) || tri_degenerate(q[0], q[1], q[2])) return 0;
    if (nshared == 2) {
        /* sharing edge p0 p1: only a coplanar fold, p2 and q2 on one side of it */
        if (tri_orient3d(p[0], p[1], p[2], q[2]) != 0) return 0;
        int i, j;
        tri_plane_axes(p[0], p[1], p[2], &i, &j);
        int s = orient2d(p[0], p[1], p[2], i, j);
        return s != 0 && orient2d(p[0], p[1], q[2], i, j) == s;
    }
    /* the cheap rejection first (filtered orientations, exact only near a plane):
     * one triangle strictly on one side of the other's plane, apart from the shared
     * vertex, meets it at most there */
    if (nshared == 0 && (plane_side(p, q, 0) || plane_side(q, p, 0))) return 0;
    if (nshared == 1 && (plane_side(p, q, 1) || plane_side(q, p, 1))) return 0;
    if (nshared == 1)
        return seg_tri(p[1], p[2], q[0], q[1], q[2]) || seg_tri(q[1], q[2], p[0], p[1], p[2]);
    for (int e = 0; e < 3; e++) {
        if (seg_tri(p[e], p[(e + 1) % 3], q[0], q[1], q[2])) return 1;
        if (seg_tri(q[e], q[(e + 1) % 3], p[0], p[1], p[2])) return 1;
    }
    return 0;
}
