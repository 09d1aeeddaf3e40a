/* canon.c - the written form of an evolved model's primitives and tree (canon.h):
 * canonical parameters, numbers to the precision the inliers support, names by role.
 *
 * Uncertainties come from the segmentation's figures of each primitive: with n inliers
 * scattered by rms around it, a position is known to sigma = rms / sqrt(n) and a
 * direction to sigma / (patch half size).  A primitive without them (a .fit list the
 * user wrote) keeps the exact-looking precision of prim_write_call_scaled.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "canon.h"
#include "kdtree.h"
#include "tree.h"
#include "util.h"
#include "vec3.h"

/* ---- canonical parameters ----------------------------------------------------------- */

static double pow10_floor(double v) { return pow(10, floor(log10(v))); }

/* Snap the unit vector u: components within tol of 0 become 0 (not all), and in a
 * coordinate plane the angle to a multiple of 15 degrees.  Returns 1 when u changed. */
static int snap_dir(double u[3], double tol)
{
    double v[3];
    memcpy(v, u, sizeof v);
    int zero = 0, big = 0;
    for (int k = 0; k < 3; k++)
        if (fabs(v[k]) > fabs(v[big])) big = k;
    for (int k = 0; k < 3; k++)
        if (k != big && fabs(v[k]) <= tol) {
            v[k] = 0;
            zero++;
        }
    if (zero == 1) {
        int i = -1, j = -1;
        for (int k = 0; k < 3; k++)
            if (v[k] != 0) {
                if (i < 0) i = k;
                else j = k;
            }
        double step = FREP_PI / 12, phi = atan2(v[j], v[i]), s = round(phi / step) * step;
        if (fabs(phi - s) <= tol) {
            double l = hypot(v[i], v[j]);
            v[i] = l * cos(s);
            v[j] = l * sin(s);
            /* cos(pi/2) is 6e-17, not 0: an axis is an axis. */
            if (fabs(v[i]) < 1e-15) v[i] = 0;
            if (fabs(v[j]) < 1e-15) v[j] = 0;
        }
    }
    if (zero == 0) return 0;
    double l = vec3_len(v);
    for (int k = 0; k < 3; k++) v[k] /= l;
    for (int k = 0; k < 3; k++)
        if (v[k] == 1 || v[k] == -1) {
            v[(k + 1) % 3] = 0;
            v[(k + 2) % 3] = 0;
        }
    if (memcmp(v, u, sizeof v) == 0) return 0;
    memcpy(u, v, sizeof v);
    return 1;
}

/* Centre and half size of a primitive's inlier patch (the cloud's without one). */
static void patch(const evolve_result *r, const prim *q, double c[3], double *ext)
{
    if (q->has_obb) {
        memcpy(c, q->obb_c, 3 * sizeof *c);
        *ext = fmax(q->obb_half[0], fmax(q->obb_half[1], q->obb_half[2]));
    } else {
        memcpy(c, r->obb.c, 3 * sizeof *c);
        *ext = fmax(r->obb.h[0], fmax(r->obb.h[1], r->obb.h[2]));
    }
    if (!(*ext > 0)) *ext = r->diag / 2;
}

/* The canonical form of in: aggressive snaps within what the inliers cannot tell and
 * rounds to their standard error; otherwise both stay within CANON_MAX_SHIFT. */
static void canonical(const evolve_result *r, const prim *in, int aggressive, canon_prim *o)
{
    prim *q = &o->q;
    *q = *in;
    double c[3], ext, D = r->diag > 0 ? r->diag : 1;
    patch(r, in, c, &ext);
    int known = in->support > 1 && in->rms > 0;
    o->sigma = known ? in->rms / sqrt((double)in->support) : 0;
    double sdir = known ? o->sigma / ext : 0;
    /* Quanta: a power of ten at most the standard error, at most CANON_MAX_SHIFT of the
     * diagonal (over the patch for directions), at least the old fixed precision. */
    double cap_pos = pow10_floor(2 * CANON_MAX_SHIFT * D);
    double cap_dir = pow10_floor(2 * CANON_MAX_SHIFT * D / ext);
    if (aggressive) cap_pos = cap_dir = INFINITY;
    o->qpos = known ? fmin(pow10_floor(o->sigma), cap_pos) : PRIM_POS_QUANTUM * D;
    o->qdir = known ? fmin(pow10_floor(sdir), cap_dir) : PRIM_DIR_QUANTUM;
    o->qpos = fmax(o->qpos, PRIM_POS_QUANTUM * D);
    o->qdir = fmax(o->qdir, PRIM_DIR_QUANTUM);
    double tol = known ? fmin(CANON_MAX_SNAP, fmax(3 * sdir, in->rms / ext)) : 3 * PRIM_DIR_QUANTUM;
    if (!aggressive) tol = fmin(tol, 2 * CANON_MAX_SHIFT * D / ext);
    switch (q->type) {
    case PRIM_PLANE: {
        /* Keep the plane through the point of it nearest the patch centre. */
        double t = q->r - vec3_dot(q->p, c), c0[3];
        for (int k = 0; k < 3; k++) c0[k] = c[k] + t * q->p[k];
        o->snapped = snap_dir(q->p, tol);
        q->r = vec3_dot(q->p, c0);
        break;
    }
    case PRIM_CYLINDER: {
        double t = (c[0] - q->p[0]) * q->a[0] + (c[1] - q->p[1]) * q->a[1] + (c[2] - q->p[2]) * q->a[2];
        double f[3];
        for (int k = 0; k < 3; k++) f[k] = q->p[k] + t * q->a[k];
        o->snapped = snap_dir(q->a, tol);
        t = (c[0] - f[0]) * q->a[0] + (c[1] - f[1]) * q->a[1] + (c[2] - f[2]) * q->a[2];
        for (int k = 0; k < 3; k++) q->p[k] = f[k] + t * q->a[k];
        break;
    }
    case PRIM_CONE:
    case PRIM_TORUS:
        o->snapped = snap_dir(q->a, tol);
        break;
    case PRIM_SPHERE:
    case PRIM__COUNT:
        break;
    }
}

/* Bit 1 where leaf j is material, bit 2 where it is removed (under an odd number of
 * complements and subtrahends). */
static void polarity(const frep_insn *code, uint32_t end, int sign, canon_prim *o, size_t n)
{
    const frep_insn *in = &code[end];
    int k = tree_nin(in);
    if (k == 0) {
        if (in->arg < n) o[in->arg].polarity |= sign > 0 ? 1 : 2;
        return;
    }
    if (k == 1) {
        polarity(code, end - 1, -sign, o, n);
        return;
    }
    uint32_t l0, l1, r0;
    tree_operands(code, end, &l0, &l1, &r0);
    int sub = in->op == FREP_OP_MSUB || in->op == FREP_OP_RSUB;
    polarity(code, l1, sign, o, n);
    polarity(code, end - 1, sub ? -sign : sign, o, n);
}

static void set_name(canon_prim *o, size_t j, size_t n, const char *base)
{
    snprintf(o[j].name, sizeof o[j].name, "%s", base);
    for (unsigned k = 2;; k++) {
        size_t i = 0;
        while (i < n && (i == j || strcmp(o[i].name, o[j].name) != 0)) i++;
        if (i == n) return;
        snprintf(o[j].name, sizeof o[j].name, "%s_%u", base, k);
    }
}

/* A plane's role name: plane_x_left .. plane_z_top along an axis, else plane_k with
 * k one more than *count (which counts it). */
static void plane_base(const prim *q, unsigned *count, char *base, size_t size)
{
    static const char *const side[3][2] = { { "left", "right" }, { "front", "back" },
                                            { "bottom", "top" } };
    int ax = -1;
    for (int a = 0; a < 3; a++)
        if (q->p[a] == 1 || q->p[a] == -1) ax = a;
    if (ax >= 0) snprintf(base, size, "plane_%c_%s", "xyz"[ax], side[ax][q->p[ax] > 0]);
    else snprintf(base, size, "plane_%u", ++*count);
}

/* Role names, numbered in the order the tree first uses each primitive. */
static void names(const gp_tree *t, canon_prim *o, size_t n)
{
    unsigned count[PRIM__COUNT + 1] = { 0 }, bores = 0, cav = 0;
    for (uint32_t pc = 0; pc < t->len; pc++) {
        if (t->code[pc].op != FREP_OP_PRIM || t->code[pc].arg >= n) continue;
        size_t j = t->code[pc].arg;
        if (o[j].name[0]) continue;
        const prim *q = &o[j].q;
        char base[32];
        int removed = o[j].polarity == 2;
        switch (q->type) {
        case PRIM_PLANE: plane_base(q, &count[PRIM_PLANE], base, sizeof base); break;
        case PRIM_CYLINDER:
            if (removed) snprintf(base, sizeof base, "cyl_bore_%u", ++bores);
            else snprintf(base, sizeof base, "cyl_%u", ++count[PRIM_CYLINDER]);
            break;
        case PRIM_SPHERE:
            if (removed) snprintf(base, sizeof base, "sphere_cavity_%u", ++cav);
            else snprintf(base, sizeof base, "sphere_%u", ++count[PRIM_SPHERE]);
            break;
        case PRIM_CONE: snprintf(base, sizeof base, "cone_%u", ++count[PRIM_CONE]); break;
        case PRIM_TORUS: snprintf(base, sizeof base, "torus_%u", ++count[PRIM_TORUS]); break;
        case PRIM__COUNT: snprintf(base, sizeof base, "prim_%zu", j + 1); break;
        }
        set_name(o, j, n, base);
    }
}

static char op_char(uint8_t op)
{
    return op == FREP_OP_MAX || op == FREP_OP_RUNI ? '|'
         : op == FREP_OP_MIN || op == FREP_OP_RINT ? '&' : '\\';
}

/* ---- boundedness ------------------------------------------------------------------- */

/* The tree's value at x (min/max: R-functions have the same sign); leaves beyond the
 * list (the --residual model) count as everywhere inside, so such trees look unbounded.
 * Postfix on a stack: a valid tree's stack never holds more entries than its depth, at
 * most GP_MAX_TREE_DEPTH; a deeper tree is also taken as everywhere inside. */
static double tree_at(const frep_insn *code, uint32_t end, const prim *prims, size_t n,
                      const double *x)
{
    double st[GP_MAX_TREE_DEPTH + 1];
    uint32_t sp = 0;
    for (uint32_t pc = tree_subtree_start(code, end); pc <= end; pc++) {
        const frep_insn *in = &code[pc];
        int k = tree_nin(in);
        if (k == 0) {
            if (sp == GP_MAX_TREE_DEPTH + 1) return 1;
            st[sp++] = in->arg < n ? prim_eval(&prims[in->arg], x, NULL) : 1;
        } else if (k == 1) {
            st[sp - 1] = -st[sp - 1];
        } else {
            double b = st[--sp], a = st[sp - 1];
            char op = op_char(in->op);
            st[sp - 1] = op == '|' ? fmax(a, b) : op == '&' ? fmin(a, b) : fmin(a, -b);
        }
    }
    return st[0];
}

/* Probe k (0 .. 2 CANON_BOUND_DIRS - 1) of the boundedness test: Fibonacci points on
 * spheres of 2 and 8 diagonals around the cloud, the smaller sphere's first. */
static void bound_probe(const evolve_result *r, int k, double x[3])
{
    double R = (k < CANON_BOUND_DIRS ? 2 : 8) * r->diag;
    int i = k % CANON_BOUND_DIRS;
    double z = 1 - (2 * i + 1.0) / CANON_BOUND_DIRS, rho = sqrt(1 - z * z);
    double phi = i * FREP_PI * (3 - sqrt(5.0));
    x[0] = r->obb.c[0] + R * rho * cos(phi);
    x[1] = r->obb.c[1] + R * rho * sin(phi);
    x[2] = r->obb.c[2] + R * z;
}

int canon_tree_bounded(const evolve_result *r, const prim *prims, size_t nprims)
{
    const gp_tree *t = &r->tree;
    if (!t->len) return 0;
    for (int k = 0; k < 2 * CANON_BOUND_DIRS; k++) {
        double x[3];
        bound_probe(r, k, x);
        if (tree_at(t->code, t->len - 1, prims, nprims, x) >= 0) return 0;
    }
    return 1;
}

/* ---- the check of the written numbers ------------------------------------------------ */

/* The arguments canon_write_call prints, with their quanta, in its order. */
static void arguments(canon_prim *c, double **v, double *qu, int *n)
{
    prim *q = &c->q;
    int k = 0, dirs = q->type == PRIM_PLANE;
    for (int i = 0; i < 3; i++) {
        v[k] = &q->p[i];
        qu[k++] = dirs ? c->qdir : c->qpos;
    }
    if (q->type == PRIM_CYLINDER || q->type == PRIM_CONE || q->type == PRIM_TORUS)
        for (int i = 0; i < 3; i++) {
            v[k] = &q->a[i];
            qu[k++] = c->qdir;
        }
    if (q->type == PRIM_TORUS) {
        v[k] = &q->R;
        qu[k++] = c->qpos;
    }
    v[k] = &q->r;
    qu[k++] = q->type == PRIM_CONE ? c->qdir : c->qpos;
    *n = k;
}

/* The numbers as printed, read back: what the written model computes. */
static void round_prim(canon_prim *c)
{
    double *v[8], qu[8];
    int n;
    arguments(c, v, qu, &n);
    for (int k = 0; k < n; k++) {
        char buf[PRIM_NUM_BUF];
        prim_format_number(buf, *v[k], qu[k]);
        *v[k] = strtod(buf, NULL);
    }
}

/* The primitive the written call evaluates: directions made unit as frPlane and the
 * axial functions do (frPlane keeps d). */
static prim evaluated(const canon_prim *c)
{
    prim q = c->q;
    double *u = q.type == PRIM_PLANE ? q.p : q.a;
    if (q.type != PRIM_SPHERE) {
        double l = vec3_len(u);
        if (l > 0)
            for (int k = 0; k < 3; k++) u[k] /= l;
    }
    return q;
}

/* Mean |f| of the tree over the check points: the points' side of the Chamfer distance
 * (f of each primitive is a distance; min/max keep it one near the surface). */
static double mean_dist(const evolve_result *r, const prim *q, size_t n, const frep_cloud *cl,
                        size_t stride)
{
    const gp_tree *t = &r->tree;
    double s = 0;
    size_t m = 0;
    for (size_t i = 0; i < cl->n; i += stride, m++) {
        double x[3] = { cl->x[i], cl->y[i], cl->z[i] };
        s += fabs(tree_at(t->code, t->len - 1, q, n, x));
    }
    return m ? s / (double)m : 0;
}

/* Primitive p as fitted, its numbers printed to the quanta of a position and a
 * direction (its polarity kept). */
static void keep_fitted(const evolve_result *r, const prim *p, canon_prim *c)
{
    int pol = c->polarity;
    memset(c, 0, sizeof *c);
    c->q = *p;
    c->polarity = pol;
    c->qpos = PRIM_POS_QUANTUM * r->diag;
    c->qdir = PRIM_DIR_QUANTUM;
}

/* Per primitive in list order: the aggressive form when the model still explains the
 * points within CANON_MAX_CHANGE of the diagonal (mean distance), else the bounded one
 * when it does, else the exact primitive. */
static int check(const evolve_result *r, const prim *prims, size_t nprims,
                 const frep_cloud *cloud, const volatile sig_atomic_t *cancel, canon_prim *out)
{
    prim *q = frep_malloc(nprims * sizeof *q);
    if (!q) return -1;
    memcpy(q, prims, nprims * sizeof *q);
    size_t stride = cloud->n > CANON_CHECK_POINTS ? cloud->n / CANON_CHECK_POINTS : 1;
    double base = mean_dist(r, q, nprims, cloud, stride);
    double budget = CANON_MAX_CHANGE * r->diag;
    for (size_t j = 0; j < nprims; j++) {
        if (!out[j].polarity) continue;
        if (cancel && *cancel) {
            keep_fitted(r, &prims[j], &out[j]);
            continue;
        }
        canon_prim a;
        memset(&a, 0, sizeof a);
        a.polarity = out[j].polarity;
        canonical(r, &prims[j], 1, &a);
        round_prim(&a);
        q[j] = evaluated(&a);
        if (mean_dist(r, q, nprims, cloud, stride) <= base + budget) {
            out[j] = a;
            continue;
        }
        q[j] = evaluated(&out[j]);
        if (mean_dist(r, q, nprims, cloud, stride) <= base + budget) continue;
        q[j] = prims[j];
        keep_fitted(r, &prims[j], &out[j]);
    }
    frep_free(q);
    return 0;
}

int canon_prims(const evolve_result *r, const prim *prims, size_t nprims,
                const frep_cloud *cloud, int exact, const volatile sig_atomic_t *cancel,
                canon_prim *out)
{
    memset(out, 0, nprims * sizeof *out);
    const gp_tree *t = &r->tree;
    if (!t->len) return 0;
    polarity(t->code, t->len - 1, 1, out, nprims);
    for (size_t j = 0; j < nprims && exact; j++)
        out[j].q = prims[j];     /* quanta 0: every digit */
    for (size_t j = 0; j < nprims && !exact; j++)
        if (out[j].polarity) {
            canonical(r, &prims[j], 0, &out[j]);
            round_prim(&out[j]);
        }
    if (!exact && cloud && cloud->n && nprims && check(r, prims, nprims, cloud, cancel, out))
        return -1;
    names(t, out, nprims);
    return 0;
}

/* ---- writing ------------------------------------------------------------------------ */

void canon_write_call(FILE *f, const canon_prim *c)
{
    prim_write_call_quanta(f, &c->q, c->qpos, c->qdir);
}

/* A signed number as a term: " + 0.5", " - 0.5" (nothing for 0). */
static void term(FILE *f, double v, double quantum, const char *what, int *first)
{
    char buf[PRIM_NUM_BUF];
    prim_format_number(buf, fabs(v), quantum);
    if (strcmp(buf, "0") == 0) return;
    int one = strcmp(buf, "1") == 0 && what[0];
    if (*first) fprintf(f, "%s%s%s%s", v < 0 ? "-" : "", one ? "" : buf, one || !what[0] ? "" : "*", what);
    else fprintf(f, " %c %s%s%s", v < 0 ? '-' : '+', one ? "" : buf, one || !what[0] ? "" : "*", what);
    *first = 0;
}

/* (x[k] - p_k), or x[k] when p_k prints as 0. */
static void coord(FILE *f, int k, double p, double quantum)
{
    char buf[PRIM_NUM_BUF];
    prim_format_number(buf, fabs(p), quantum);
    if (strcmp(buf, "0") == 0) fprintf(f, "x[%d]", k + 1);
    else fprintf(f, "(x[%d] %c %s)", k + 1, p < 0 ? '+' : '-', buf);
}

/* |x - p|^2 and (x - p).u written out. */
static void len2(FILE *f, const prim *q, double qp)
{
    fputc('(', f);
    for (int k = 0; k < 3; k++) {
        if (k) fputs(" + ", f);
        coord(f, k, q->p[k], qp);
        fputs("^2", f);
    }
    fputc(')', f);
}

static void along(FILE *f, const prim *q, double qp, double qd)
{
    int first = 1;
    fputc('(', f);
    for (int k = 0; k < 3; k++) {
        char buf[PRIM_NUM_BUF];
        prim_format_number(buf, q->a[k], qd);
        if (strcmp(buf, "0") == 0) continue;
        if (!first) fputs(" + ", f);
        coord(f, k, q->p[k], qp);
        if (strcmp(buf, "1") != 0) fprintf(f, "*%s", buf);
        first = 0;
    }
    fputc(')', f);
}

void canon_write_hyperfun(FILE *f, const canon_prim *c)
{
    const prim *q = &c->q;
    double qp = c->qpos, qd = c->qdir;
    char r[PRIM_NUM_BUF], R[PRIM_NUM_BUF];
    prim_format_number(r, q->r, q->type == PRIM_CONE ? qd : qp);
    switch (q->type) {
    case PRIM_PLANE: {
        /* d - n.x (n made unit as frPlane does) */
        double l = vec3_len(q->p);
        int first = 1;
        term(f, q->r, qp, "", &first);
        for (int k = 0; k < 3; k++) {
            char x[8];
            snprintf(x, sizeof x, "x[%d]", k + 1);
            term(f, -q->p[k] / l, qd, x, &first);
        }
        if (first) fputs("0", f);
        return;
    }
    case PRIM_SPHERE:
        fprintf(f, "%s^2 - ", r);
        len2(f, q, qp);
        return;
    case PRIM_CYLINDER:
        fprintf(f, "%s^2 - (", r);
        len2(f, q, qp);
        fputs(" - ", f);
        along(f, q, qp, qd);
        fputs("^2)", f);
        return;
    case PRIM_CONE:
        fputs("(", f);
        along(f, q, qp, qd);
        fprintf(f, "*sin(%s) - sqrt(abs(", r);
        len2(f, q, qp);
        fputs(" - ", f);
        along(f, q, qp, qd);
        fprintf(f, "^2))*cos(%s))", r);
        return;
    case PRIM_TORUS:
        prim_format_number(R, q->R, qp);
        fprintf(f, "%s^2 - ((sqrt(abs(", r);
        len2(f, q, qp);
        fputs(" - ", f);
        along(f, q, qp, qd);
        fprintf(f, "^2)) - %s)^2 + ", R);
        along(f, q, qp, qd);
        fputs("^2)", f);
        return;
    case PRIM__COUNT:
        break;
    }
    fputs("0", f);
}

void canon_write_comment(FILE *f, const canon_prim *c)
{
    const prim *q = &c->q;
    char a[PRIM_NUM_BUF], b[PRIM_NUM_BUF];
    fprintf(f, "  -- %s", prim_type_name(q->type));
    switch (q->type) {
    case PRIM_CYLINDER:
    case PRIM_SPHERE:
        prim_format_number(a, q->r, c->qpos);
        fprintf(f, ", radius %s", a);
        break;
    case PRIM_TORUS:
        prim_format_number(a, q->R, c->qpos);
        prim_format_number(b, q->r, c->qpos);
        fprintf(f, ", radii %s and %s", a, b);
        break;
    case PRIM_CONE:
        prim_format_number(a, q->r * 180 / FREP_PI, c->qdir * 180 / FREP_PI);
        fprintf(f, ", half-angle %s degrees", a);
        break;
    case PRIM_PLANE:
    case PRIM__COUNT:
        break;
    }
    if (c->polarity == 2) fputs(", removed", f);
    if (q->constructed) fprintf(f, ", separating, constructed: %s", prim_constructed_why(q));
    else if (q->separating) fputs(", separating", f);
    else if (q->support) fprintf(f, ", %zu inliers", q->support);
    if (c->sigma > 0) {
        prim_format_number(a, c->sigma, c->sigma / 10);
        fprintf(f, ", +-%s", a);
    }
    if (c->snapped) fputs(", direction snapped", f);
}

/* ---- features: the tree as solids ---------------------------------------------------- */

/* The tree is read as n-ary intersections (with complemented operands: a \ b is
 * a & ~b) and unions; in each intersection, three pairs of opposite parallel planes on
 * orthogonal axes become a box, a cylinder and a pair of opposite planes across its
 * axis a capped cylinder.  min/max and R-functions have the same sign, so regrouping
 * the operands keeps the solid. */

typedef enum ft_kind { FT_LEAF, FT_BOX, FT_CAPPED, FT_AND, FT_OR } ft_kind;

typedef struct ft_term {
    uint32_t node;
    uint8_t neg;          /* complemented (a subtrahend of an intersection) */
} ft_term;

typedef struct ft_node {
    ft_kind kind;
    uint32_t leaf;        /* FT_LEAF: the primitive (nprims: the --residual base) */
    ft_term *t;           /* FT_AND, FT_OR: the operands */
    uint32_t n, cap;
    /* FT_BOX: frBox's numbers as printed (centre, half sizes, rotations about x, y, z),
     * its faces (leaf, complemented); FT_CAPPED: face[0] the cylinder, face[1..2]. */
    double c[3], h[3], rot[3];
    uint32_t face[6];     /* FT_BOX: FT_NONE for a free face (no fitted plane) */
    uint8_t fneg[6];
    uint8_t ends[6];      /* FT_BOX: a free face placed where the cut's points end (face_scan) */
    double fpl[6][4];     /* FT_BOX of the cover: each face's outward normal and offset */
    double qpos, qdir, sigma;   /* FT_BOX: printing quanta, the faces' standard error */
    char name[48];              /* FT_BOX, FT_CAPPED (a primitive's name + "_capped") */
} ft_node;

typedef struct ft {
    ft_node *v;
    uint32_t n, cap;
    int failed;
    canon_prim *c;        /* per primitive: its canonical form (a copy: ft_adopt_plane
                             names a plane the tree did not use) */
    prim *q;              /* per primitive: what the written call evaluates */
    size_t nprims;
    int spreading;        /* 1: apply_cover is inside ft_spread's trial (no spread there) */
} ft;

#define FT_NONE UINT32_MAX

static uint32_t ft_new(ft *F, ft_kind k)
{
    if (F->failed) return FT_NONE;
    if (F->n == F->cap) {
        uint32_t cap = F->cap ? 2 * F->cap : 32;
        ft_node *nv = frep_realloc(F->v, cap * sizeof *nv);
        if (!nv) {
            F->failed = 1;
            return FT_NONE;
        }
        F->v = nv;
        F->cap = cap;
    }
    memset(&F->v[F->n], 0, sizeof F->v[F->n]);
    F->v[F->n].kind = k;
    return F->n++;
}

static void ft_add(ft *F, uint32_t parent, uint32_t node, int neg)
{
    if (F->failed || node == FT_NONE) return;
    ft_node *p = &F->v[parent];
    if (p->n == p->cap) {
        uint32_t cap = p->cap ? 2 * p->cap : 4;
        ft_term *nt = frep_realloc(p->t, cap * sizeof *nt);
        if (!nt) {
            F->failed = 1;
            return;
        }
        p->t = nt;
        p->cap = cap;
    }
    p->t[p->n].node = node;
    p->t[p->n++].neg = (uint8_t)neg;
}

static uint32_t ft_build(ft *F, const frep_insn *code, uint32_t end);

/* The operands of the subtree at end (complemented when neg) into parent, an
 * intersection (pop '&') or union ('|'), flat where the operator allows:
 * a & (b \ c) = a & b & ~c, a & ~(b | c) = a & ~b & ~c, and their duals. */
static void ft_flat(ft *F, const frep_insn *code, uint32_t end, int neg, uint32_t parent, char pop)
{
    const frep_insn *in = &code[end];
    int k = tree_nin(in);
    if (k == 1) {
        ft_flat(F, code, end - 1, !neg, parent, pop);
        return;
    }
    if (k == 2) {
        uint32_t l0, l1, r0;
        tree_operands(code, end, &l0, &l1, &r0);
        char op = op_char(in->op);
        char same = pop, dual = pop == '&' ? '|' : '&';
        if (!neg && op == same) {
            ft_flat(F, code, l1, 0, parent, pop);
            ft_flat(F, code, end - 1, 0, parent, pop);
            return;
        }
        if (neg && op == dual) {
            ft_flat(F, code, l1, 1, parent, pop);
            ft_flat(F, code, end - 1, 1, parent, pop);
            return;
        }
        if (op == '\\' && neg == (pop == '|')) {
            /* & of a \ b: a, ~b; | of ~(a \ b): ~a, b */
            ft_flat(F, code, l1, neg, parent, pop);
            ft_flat(F, code, end - 1, !neg, parent, pop);
            return;
        }
    }
    ft_add(F, parent, ft_build(F, code, end), neg);
}

static uint32_t ft_build(ft *F, const frep_insn *code, uint32_t end)
{
    const frep_insn *in = &code[end];
    int k = tree_nin(in);
    if (k == 0) {
        uint32_t l = ft_new(F, FT_LEAF);
        if (l != FT_NONE) F->v[l].leaf = in->arg;
        return l;
    }
    char op = k == 1 ? '&' : op_char(in->op);
    uint32_t n = ft_new(F, op == '|' ? FT_OR : FT_AND);
    if (n != FT_NONE) ft_flat(F, code, end, 0, n, op == '|' ? '|' : '&');
    return n;
}

static void ft_free(ft *F)
{
    for (uint32_t i = 0; i < F->n; i++) frep_free(F->v[i].t);
    frep_free(F->v);
}

/* The plane of a term as a half-space n.x <= d (complemented: the other side), or 0
 * when the term is no plane leaf. */
static int ft_plane(const ft *F, ft_term t, double n[3], double *d)
{
    const ft_node *v = &F->v[t.node];
    if (v->kind != FT_LEAF || v->leaf >= F->nprims || F->q[v->leaf].type != PRIM_PLANE)
        return 0;
    const prim *q = &F->q[v->leaf];
    double s = t.neg ? -1 : 1;
    for (int k = 0; k < 3; k++) n[k] = s * q->p[k];
    *d = s * q->r;
    return 1;
}

/* frBox's value (lang/lib_ext.c) for centre c, half sizes h, frame columns R[.][k]. */
static double box_value(const double c[3], const double h[3], const double R[3][3], const double *x)
{
    double e[3], out = 0, in = -INFINITY;
    for (int k = 0; k < 3; k++) {
        double q = 0;
        for (int w = 0; w < 3; w++) q += R[w][k] * (x[w] - c[w]);
        e[k] = fabs(q) - h[k];
        out += e[k] > 0 ? e[k] * e[k] : 0;
        in = fmax(in, e[k]);
    }
    return -(sqrt(out) + fmin(in, 0));
}

/* Rz(rz) Ry(ry) Rx(rx), the frame of frBox's rotations. */
static void box_frame(const double rot[3], double R[3][3])
{
    double cx = cos(rot[0]), sx = sin(rot[0]), cy = cos(rot[1]), sy = sin(rot[1]);
    double cz = cos(rot[2]), sz = sin(rot[2]);
    R[0][0] = cz * cy;  R[0][1] = cz * sy * sx - sz * cx;  R[0][2] = cz * sy * cx + sz * sx;
    R[1][0] = sz * cy;  R[1][1] = sz * sy * sx + cz * cx;  R[1][2] = sz * sy * cx - cz * sx;
    R[2][0] = -sy;      R[2][1] = cy * sx;                 R[2][2] = cy * cx;
}

static double ft_eval(const ft *F, uint32_t i, const double *x)
{
    const ft_node *v = &F->v[i];
    switch (v->kind) {
    case FT_LEAF: return v->leaf < F->nprims ? prim_eval(&F->q[v->leaf], x, NULL) : 1;
    case FT_BOX: {
        double R[3][3];
        box_frame(v->rot, R);
        return box_value(v->c, v->h, R, x);
    }
    case FT_CAPPED: {
        double f = prim_eval(&F->q[v->face[0]], x, NULL);
        for (int k = 1; k < 3; k++) {
            double g = prim_eval(&F->q[v->face[k]], x, NULL);
            f = fmin(f, v->fneg[k] ? -g : g);
        }
        return f;
    }
    case FT_AND:
    case FT_OR: {
        double f = v->kind == FT_AND ? INFINITY : -INFINITY;
        for (uint32_t k = 0; k < v->n; k++) {
            double g = ft_eval(F, v->t[k].node, x);
            if (v->t[k].neg) g = -g;
            f = v->kind == FT_AND ? fmin(f, g) : fmax(f, g);
        }
        return f;
    }
    }
    return 1;
}

/* Two planes bound a slab across u: opposite normals within tol of each other. */
static int opposite(const double a[3], const double b[3], double tol)
{
    return vec3_dot(a, b) <= -cos(tol);
}

/* The box node of axes u (orthonormal rows), faces at u_k . x = lo[k] and hi[k]:
 * face[2k] the leaf of the hi face, face[2k + 1] the lo one (FT_NONE: a free face, no
 * fitted plane; fneg: the leaf complemented), the axes ordered and signed so that an
 * axis-aligned box has no rotation; numbers rounded as they print, to the finest
 * quantum of its fitted faces.  Returns the node, or FT_NONE. */
static uint32_t ft_box_node(ft *F, const double u[3][3], const double lo[3], const double hi[3],
                            const uint32_t face[6], const uint8_t fneg[6])
{
    double cw[3] = { 0, 0, 0 }, h[3];
    for (int k = 0; k < 3; k++) {
        h[k] = (hi[k] - lo[k]) / 2;
        if (!(h[k] > 0)) return FT_NONE;
        for (int w = 0; w < 3; w++) cw[w] += (hi[k] + lo[k]) / 2 * u[k][w];
    }
    /* Box axis k goes to the world axis it is nearest, pointing its way. */
    int used[3] = { 0, 0, 0 }, perm[3];
    double R[3][3], hh[3];
    for (int w = 0; w < 3; w++) {
        int best = -1;
        for (int k = 0; k < 3; k++)
            if (!used[k] && (best < 0 || fabs(u[k][w]) > fabs(u[best][w]))) best = k;
        used[best] = 1;
        perm[w] = best;
    }
    for (int w = 0; w < 3; w++) {
        int k = perm[w];
        double s = u[k][w] < 0 ? -1 : 1;
        for (int r = 0; r < 3; r++) R[r][w] = s * u[k][r];
        hh[w] = h[k];
    }
    double det = R[0][0] * (R[1][1] * R[2][2] - R[1][2] * R[2][1]) -
                 R[0][1] * (R[1][0] * R[2][2] - R[1][2] * R[2][0]) +
                 R[0][2] * (R[1][0] * R[2][1] - R[1][1] * R[2][0]);
    if (det < 0) {
        int m = 0;
        for (int w = 1; w < 3; w++)
            if (fabs(R[w][w]) < fabs(R[m][m])) m = w;
        for (int r = 0; r < 3; r++) R[r][m] = -R[r][m];
    }
    uint32_t b = ft_new(F, FT_BOX);
    if (b == FT_NONE) return FT_NONE;
    ft_node *v = &F->v[b];
    v->rot[1] = asin(fmax(-1, fmin(1, -R[2][0])));
    v->rot[0] = atan2(R[2][1], R[2][2]);
    v->rot[2] = atan2(R[1][0], R[0][0]);
    v->qpos = INFINITY;
    v->qdir = INFINITY;
    for (int k = 0; k < 6; k++) {
        uint32_t j = face[k];
        v->face[k] = j;
        v->fneg[k] = fneg[k];
        if (j == FT_NONE) continue;
        v->qpos = fmin(v->qpos, F->c[j].qpos);
        v->qdir = fmin(v->qdir, F->c[j].qdir);
        if (F->c[j].sigma > 0 && (v->sigma == 0 || F->c[j].sigma < v->sigma))
            v->sigma = F->c[j].sigma;
    }
    if (!isfinite(v->qpos)) v->qpos = PRIM_POS_QUANTUM;
    if (!isfinite(v->qdir)) v->qdir = PRIM_DIR_QUANTUM;
    for (int k = 0; k < 3; k++) {
        char buf[PRIM_NUM_BUF];
        prim_format_number(buf, cw[k], v->qpos);
        v->c[k] = strtod(buf, NULL);
        prim_format_number(buf, hh[k], v->qpos);
        v->h[k] = strtod(buf, NULL);
        prim_format_number(buf, v->rot[k], v->qdir);
        v->rot[k] = strtod(buf, NULL);
    }
    return b;
}

/* Box node b's face planes (fpl) from its axes u and extents lo, hi, in face order. */
static void box_set_planes(ft *F, uint32_t b, const double u[3][3], const double lo[3], const double hi[3])
{
    ft_node *v = &F->v[b];
    for (int a = 0; a < 3; a++) {
        memcpy(v->fpl[2 * a], u[a], 3 * sizeof(double));
        v->fpl[2 * a][3] = hi[a];
        for (int w = 0; w < 3; w++) v->fpl[2 * a + 1][w] = -u[a][w];
        v->fpl[2 * a + 1][3] = -lo[a];
    }
}

/* The box of the pairs p[k] = (plus, minus term index) of intersection node `and`:
 * an orthonormal frame from the pairs' normals, each face's offset along its axis.
 * Returns the node, or FT_NONE. */
static uint32_t ft_box(ft *F, uint32_t and, const uint32_t p[3][2])
{
    double n[3][2][3] = { { { 0 } } }, d[3][2] = { { 0 } }, u[3][3];
    for (int k = 0; k < 3; k++)
        for (int s = 0; s < 2; s++) ft_plane(F, F->v[and].t[p[k][s]], n[k][s], &d[k][s]);
    for (int k = 0; k < 3; k++)
        for (int w = 0; w < 3; w++) u[k][w] = n[k][0][w] - n[k][1][w];
    vec3_normalize(u[0]);
    double t = vec3_dot(u[1], u[0]);
    for (int w = 0; w < 3; w++) u[1][w] -= t * u[0][w];
    if (vec3_normalize(u[1])) return FT_NONE;
    double w2[3];
    vec3_cross(u[0], u[1], w2);
    if (vec3_dot(w2, u[2]) < 0)
        for (int w = 0; w < 3; w++) w2[w] = -w2[w];
    memcpy(u[2], w2, sizeof w2);
    /* Faces at u_k . x = s+ and s-: offset over the cosine to the axis. */
    double lo[3], hi[3];
    uint32_t face[6];
    uint8_t fneg[6];
    for (int k = 0; k < 3; k++) {
        hi[k] = d[k][0] / vec3_dot(n[k][0], u[k]);
        lo[k] = -d[k][1] / -vec3_dot(n[k][1], u[k]);
        for (int s = 0; s < 2; s++) {
            ft_term tm = F->v[and].t[p[k][s]];
            face[2 * k + s] = F->v[tm.node].leaf;
            fneg[2 * k + s] = tm.neg;
        }
    }
    return ft_box_node(F, u, lo, hi, face, fneg);
}

static double ft_mean(const ft *F, uint32_t root, const frep_cloud *cl, size_t stride)
{
    double s = 0;
    size_t m = 0;
    for (size_t i = 0; i < cl->n; i += stride, m++) {
        double x[3] = { cl->x[i], cl->y[i], cl->z[i] };
        s += fabs(ft_eval(F, root, x));
    }
    return m ? s / (double)m : 0;
}

/* Remove operands idx[0..k) of node `and` (in any order). */
static void ft_remove(ft *F, uint32_t and, uint32_t *idx, int k)
{
    ft_node *v = &F->v[and];
    uint8_t *gone = frep_calloc(v->n, 1);
    if (!gone) {
        F->failed = 1;
        return;
    }
    for (int i = 0; i < k; i++) gone[idx[i]] = 1;
    uint32_t o = 0;
    for (uint32_t i = 0; i < v->n; i++)
        if (!gone[i]) v->t[o++] = v->t[i];
    v->n = o;
    frep_free(gone);
}

typedef struct ft_check {
    const frep_cloud *cloud;   /* NULL: only exact boxes */
    size_t stride;
    double limit;              /* largest mean distance the model may reach */
    double tol;                /* angle within which planes pair, radians */
    uint32_t root;
    /* The solid before the rewrite: its values ref[i] at the points g[3i..3i+2] of a
     * grid over the cloud's box (NULL: no grid); a rewrite must keep every sign
     * where |ref| > gtol. */
    const double *g, *ref;
    size_t ng;
    double gtol;
    const volatile sig_atomic_t *cancel;   /* raised: every rewrite is refused */
} ft_check;

/* Whether the tree still explains the cloud (mean distance within the limit) and keeps
 * the solid's sign at the grid points (without the cloud: always). */
/* The grid points (away from the surface) where the tree has another sign than the
 * solid before the rewrite, counted up to more than `most`. */
static size_t ft_grid_diffs(const ft *F, const ft_check *ck, size_t most)
{
    size_t d = 0;
    for (size_t i = 0; i < ck->ng && d <= most; i++) {
        if (fabs(ck->ref[i]) <= ck->gtol) continue;
        d += (ft_eval(F, ck->root, &ck->g[3 * i]) > 0) != (ck->ref[i] > 0);
    }
    return d;
}

/* Whether the stop flag is raised (then no rewrite is tried or kept). */
static int ft_cancelled(const ft_check *ck)
{
    return ck->cancel && *ck->cancel;
}

static int ft_keeps(const ft *F, const ft_check *ck)
{
    if (!ck->cloud) return 1;
    if (ft_cancelled(ck)) return 0;
    return !ft_grid_diffs(F, ck, 0) && ft_mean(F, ck->root, ck->cloud, ck->stride) <= ck->limit;
}

/* Boxes and capped cylinders in intersection node `and`. */
static void ft_solids(ft *F, uint32_t and, const ft_check *ck)
{
    ft_node *v = &F->v[and];
    uint32_t n = v->n;
    if (n < 3) return;
    uint32_t (*pairs)[2] = frep_malloc(n * sizeof *pairs);
    uint8_t *paired = frep_calloc(n, 1);
    if (!pairs || !paired) {
        F->failed = 1;
        goto done;
    }
    double nn[2][3], dd[2];
    uint32_t np = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (paired[i] || !ft_plane(F, v->t[i], nn[0], &dd[0])) continue;
        for (uint32_t j = i + 1; j < n; j++) {
            if (paired[j] || !ft_plane(F, v->t[j], nn[1], &dd[1])) continue;
            if (opposite(nn[0], nn[1], ck->tol) && dd[0] + dd[1] > 0) {
                pairs[np][0] = i;
                pairs[np++][1] = j;
                paired[i] = paired[j] = 1;
                break;
            }
        }
    }
    uint32_t *rm = frep_malloc(n * sizeof *rm);
    int nrm = 0;
    if (!rm) {
        F->failed = 1;
        goto done;
    }
    /* A box: three pairs on orthogonal axes. */
    for (uint32_t a = 0; a < np && !nrm; a++)
        for (uint32_t b = a + 1; b < np && !nrm; b++)
            for (uint32_t c = b + 1; c < np && !nrm; c++) {
                uint32_t pr[3][2] = { { pairs[a][0], pairs[a][1] }, { pairs[b][0], pairs[b][1] },
                                      { pairs[c][0], pairs[c][1] } };
                double m[3][3] = { { 0 } }, dmy;
                for (int k = 0; k < 3; k++) ft_plane(F, F->v[and].t[pr[k][0]], m[k], &dmy);
                if (fabs(vec3_dot(m[0], m[1])) > sin(ck->tol) || fabs(vec3_dot(m[0], m[2])) > sin(ck->tol) ||
                    fabs(vec3_dot(m[1], m[2])) > sin(ck->tol))
                    continue;
                uint32_t box = ft_box(F, and, pr);
                if (box == FT_NONE) continue;
                /* Try it in place of the first face; keep it when the model still
                 * explains the points (without them: only a box its faces give
                 * exactly, the rounding of its numbers aside). */
                ft_term saved[6];
                for (int k = 0; k < 6; k++) saved[k] = F->v[and].t[pr[k / 2][k % 2]];
                F->v[and].t[pr[0][0]].node = box;
                F->v[and].t[pr[0][0]].neg = 0;
                for (int k = 1; k < 6; k++) {
                    F->v[and].t[pr[k / 2][k % 2]].node = box;
                    F->v[and].t[pr[k / 2][k % 2]].neg = 0;
                }
                int keep = ft_keeps(F, ck);
                if (!keep) {
                    for (int k = 0; k < 6; k++) F->v[and].t[pr[k / 2][k % 2]] = saved[k];
                    continue;
                }
                for (int k = 1; k < 6; k++) rm[nrm++] = pr[k / 2][k % 2];
                for (int k = 0; k < 3; k++) paired[pr[k][0]] = paired[pr[k][1]] = 2;
            }
    /* A capped cylinder: a cylinder and a pair of planes across its axis. */
    for (uint32_t i = 0; i < n; i++) {
        ft_term t = F->v[and].t[i];
        const ft_node *lv = &F->v[t.node];
        if (t.neg || lv->kind != FT_LEAF || lv->leaf >= F->nprims || F->q[lv->leaf].type != PRIM_CYLINDER)
            continue;
        const prim *cy = &F->q[lv->leaf];
        for (uint32_t a = 0; a < np; a++) {
            if (paired[pairs[a][0]] != 1) continue;
            double m[3] = { 0, 0, 0 }, dmy;
            ft_plane(F, F->v[and].t[pairs[a][0]], m, &dmy);
            if (fabs(vec3_dot(m, cy->a)) < cos(CANON_CAP_TILT)) continue;
            uint32_t cp = ft_new(F, FT_CAPPED);
            if (cp == FT_NONE) {
                frep_free(rm);
                goto done;
            }
            ft_node *cv = &F->v[cp];
            cv->face[0] = F->v[t.node].leaf;
            for (int s = 0; s < 2; s++) {
                ft_term ct = F->v[and].t[pairs[a][s]];
                cv->face[1 + s] = F->v[ct.node].leaf;
                cv->fneg[1 + s] = ct.neg;
                rm[nrm++] = pairs[a][s];
                paired[pairs[a][s]] = 2;
            }
            F->v[and].t[i].node = cp;
            break;
        }
    }
    if (nrm) ft_remove(F, and, rm, nrm);
    frep_free(rm);
done:
    frep_free(pairs);
    frep_free(paired);
}

/* ---- writing the features and the tree ----------------------------------------------- */

typedef struct fw {
    FILE *f;
    ft *F;
    const char *const *names;   /* per leaf, base_part last */
    int large;                  /* statements for sub-expressions */
    unsigned nparts, ncuts;
    char (*stmt)[16];           /* per node: its statement's name, "" inline */
} fw;

static void fw_expr(fw *w, uint32_t i, int top);

static void fw_term(fw *w, ft_term t, int first_neg)
{
    if (t.neg && first_neg) fputc('~', w->f);
    fw_expr(w, t.node, 0);
}

static void fw_expr(fw *w, uint32_t i, int top)
{
    const ft_node *v = &w->F->v[i];
    if (v->kind == FT_LEAF) {
        fputs(w->names[v->leaf], w->f);
        return;
    }
    if (v->kind == FT_BOX || v->kind == FT_CAPPED) {
        fputs(v->name, w->f);
        return;
    }
    if (!top && w->stmt[i][0]) {
        fputs(w->stmt[i], w->f);
        return;
    }
    int paren = !top && v->n > 1;
    if (paren) fputc('(', w->f);
    if (v->kind == FT_OR) {
        for (uint32_t k = 0; k < v->n; k++) {
            if (k) fputs(" | ", w->f);
            fw_term(w, v->t[k], 1);
        }
    } else {
        int first = 1;
        for (uint32_t k = 0; k < v->n; k++)
            if (!v->t[k].neg) {
                if (!first) fputs(" & ", w->f);
                fw_term(w, v->t[k], 0);
                first = 0;
            }
        for (uint32_t k = 0; k < v->n; k++)
            if (v->t[k].neg) {
                if (!first) fputs(" \\ ", w->f);
                fw_term(w, v->t[k], first);
                first = 0;
            }
    }
    if (paren) fputc(')', w->f);
}

static int fw_has_op(const ft *F, uint32_t i)
{
    const ft_node *v = &F->v[i];
    for (uint32_t k = 0; k < v->n; k++) {
        ft_kind kk = F->v[v->t[k].node].kind;
        if (kk == FT_AND || kk == FT_OR) return 1;
    }
    return 0;
}

/* Statements of the sub-expressions under node i, dependencies first: in a large tree
 * every operation of 3 operands or more, or over another operation. */
static void fw_stmts(fw *w, uint32_t i, int neg, int root)
{
    const ft_node *v = &w->F->v[i];
    if (v->kind != FT_AND && v->kind != FT_OR) return;
    for (uint32_t k = 0; k < v->n; k++) fw_stmts(w, v->t[k].node, v->t[k].neg, 0);
    if (root || !w->large || v->n < 2 || (v->n < 3 && !fw_has_op(w->F, i))) return;
    if (neg) snprintf(w->stmt[i], sizeof w->stmt[i], "cut_%u", ++w->ncuts);
    else snprintf(w->stmt[i], sizeof w->stmt[i], "part_%u", ++w->nparts);
    fprintf(w->f, "    %s = ", w->stmt[i]);
    fw_expr(w, i, 1);
    fputs(";\n", w->f);
}

/* Whether every operand of node i a subtraction removes is a cylinder (a bore). */
static int fw_bores(const fw *w, const ft_node *v)
{
    for (uint32_t k = 0; k < v->n; k++) {
        if (!v->t[k].neg) continue;
        const ft_node *c = &w->F->v[v->t[k].node];
        int cyl = c->kind == FT_CAPPED ||
                  (c->kind == FT_LEAF && c->leaf < w->F->nprims && w->F->q[c->leaf].type == PRIM_CYLINDER);
        if (!cyl) return 0;
    }
    return 1;
}

/* The root: `tree = body \ bores;` when it removes material from a body of several
 * operands or removes several; else one expression. */
static void fw_root(fw *w, uint32_t root)
{
    /* An operation of one operand is that operand. */
    while ((w->F->v[root].kind == FT_AND || w->F->v[root].kind == FT_OR) && w->F->v[root].n == 1 &&
           !w->F->v[root].t[0].neg && (w->F->v[w->F->v[root].t[0].node].kind == FT_AND ||
                                       w->F->v[w->F->v[root].t[0].node].kind == FT_OR))
        root = w->F->v[root].t[0].node;
    const ft_node *v = &w->F->v[root];
    fw_stmts(w, root, 0, 1);
    uint32_t pos = 0, negs = 0;
    for (uint32_t k = 0; v->kind == FT_AND && k < v->n; k++) {
        if (v->t[k].neg) negs++;
        else pos++;
    }
    if (!(v->kind == FT_AND && negs && pos && pos + negs >= 3)) {
        fputs("    tree = ", w->f);
        fw_expr(w, root, 1);
        fputs(";\n", w->f);
        return;
    }
    const char *cut = fw_bores(w, v) ? "bores" : "cuts";
    if (pos > 1) {
        fputs("    body =", w->f);
        for (uint32_t k = 0, first = 1; k < v->n; k++)
            if (!v->t[k].neg) {
                fputs(first ? " " : " & ", w->f);
                fw_expr(w, v->t[k].node, 0);
                first = 0;
            }
        fputs(";\n", w->f);
    }
    if (negs > 1) {
        fprintf(w->f, "    %s =", cut);
        for (uint32_t k = 0, first = 1; k < v->n; k++)
            if (v->t[k].neg) {
                fputs(first ? " " : " | ", w->f);
                fw_expr(w, v->t[k].node, 0);
                first = 0;
            }
        fputs(";\n", w->f);
    }
    fputs("    tree = ", w->f);
    if (pos > 1) fputs("body", w->f);
    else
        for (uint32_t k = 0; k < v->n; k++)
            if (!v->t[k].neg) fw_expr(w, v->t[k].node, 0);
    fputs(" \\ ", w->f);
    if (negs > 1) fputs(cut, w->f);
    else
        for (uint32_t k = 0; k < v->n; k++)
            if (v->t[k].neg) fw_expr(w, v->t[k].node, 0);
    fputs(";\n", w->f);
}

/* Leaves and features reachable from node i: leaf use counts, features in order of
 * appearance (order[*no]), their polarity. */
static void fw_walk(const ft *F, uint32_t i, int neg, unsigned *uses, uint32_t *order, uint32_t *no,
                    uint8_t *seen, uint8_t *pol)
{
    const ft_node *v = &F->v[i];
    if (v->kind == FT_LEAF) {
        uses[v->leaf]++;
        return;
    }
    if (v->kind == FT_BOX || v->kind == FT_CAPPED) {
        if (!seen[i]) order[(*no)++] = i;
        seen[i] = 1;
        pol[i] |= neg ? 2 : 1;
        return;
    }
    for (uint32_t k = 0; k < v->n; k++)
        fw_walk(F, v->t[k].node, neg ^ v->t[k].neg, uses, order, no, seen, pol);
}

/* A plane of a feature as written: complemented faces flipped (the same numbers). */
static canon_prim face_of(const ft *F, uint32_t j, int neg)
{
    canon_prim c = F->c[j];
    if (neg) {
        for (int k = 0; k < 3; k++) c.q.p[k] = -c.q.p[k] + 0.0;
        c.q.r = -c.q.r + 0.0;
    }
    return c;
}

/* A free face of a box of the cover as a plane, rounded as the box. */
static canon_prim free_face(const ft_node *v, int k)
{
    canon_prim c;
    memset(&c, 0, sizeof c);
    c.q.type = PRIM_PLANE;
    memcpy(c.q.p, v->fpl[k], 3 * sizeof(double));
    c.q.r = v->fpl[k][3];
    c.qpos = v->qpos;
    c.qdir = v->qdir;
    return c;
}

static void write_feature(FILE *f, const ft *F, const ft_node *v, const char *const *names, int hyperfun)
{
    char a[PRIM_NUM_BUF], b[PRIM_NUM_BUF], c[PRIM_NUM_BUF];
    fprintf(f, "    %s = ", v->name);
    size_t inl = 0;
    if (v->kind == FT_BOX) {
        for (int k = 0; k < 6; k++)
            if (v->face[k] != FT_NONE) inl += F->c[v->face[k]].q.support;
        if (hyperfun) {
            for (int k = 0; k < 6; k++) {
                canon_prim p = free_face(v, k);
                if (v->face[k] != FT_NONE) p = face_of(F, v->face[k], v->fneg[k]);
                fputs(k ? " & (" : "(", f);
                canon_write_hyperfun(f, &p);
                fputc(')', f);
            }
        } else {
            fputs("frBox(x", f);
            for (int k = 0; k < 9; k++) {
                double val = k < 3 ? v->c[k] : k < 6 ? v->h[k - 3] : v->rot[k - 6];
                prim_format_number(a, val, k < 6 ? v->qpos : v->qdir);
                fprintf(f, ", %s", a);
            }
            fputc(')', f);
        }
        prim_format_number(a, 2 * v->h[0], v->qpos);
        prim_format_number(b, 2 * v->h[1], v->qpos);
        prim_format_number(c, 2 * v->h[2], v->qpos);
        fprintf(f, ";  -- box %s x %s x %s (centre, half sizes, rotations about x, y, z in radians), "
                   "faces", a, b, c);
        int nfree = 0, nends = 0;
        for (int k = 0; k < 6; k++) {
            int none = v->face[k] == FT_NONE;
            fprintf(f, "%s %s", k ? "," : "", !none ? names[v->face[k]] : v->ends[k] ? "ends" : "free");
            nfree += none && !v->ends[k];
            nends += none && v->ends[k];
        }
        if (nfree)
            fputs(" (free: no point lies on that face; it is placed beyond the part, or inside "
                  "another solid where the face is hidden)", f);
        if (nends)
            fputs(" (ends: no plane was fitted to that face; it is placed where the points "
                  "around the cut fit best)", f);
        if (inl) fprintf(f, ", %zu inliers", inl);
        if (v->sigma > 0) {
            prim_format_number(a, v->sigma, v->sigma / 10);
            fprintf(f, ", +-%s", a);
        }
        fputc('\n', f);
        return;
    }
    const canon_prim *cy = &F->c[v->face[0]];
    if (hyperfun) canon_write_hyperfun(f, cy);
    else canon_write_call(f, cy);
    double len = 0;
    for (int k = 1; k < 3; k++) {
        canon_prim p = face_of(F, v->face[k], v->fneg[k]);
        fputs(" & ", f);
        if (hyperfun) {
            fputc('(', f);
            canon_write_hyperfun(f, &p);
            fputc(')', f);
        } else {
            canon_write_call(f, &p);
        }
        len += p.q.r;
        inl += p.q.support;
    }
    inl += cy->q.support;
    prim_format_number(a, cy->q.r, cy->qpos);
    prim_format_number(b, len, cy->qpos);
    fprintf(f, ";  -- capped cylinder, radius %s, length %s, caps %s and %s", a, b,
            names[v->face[1]], names[v->face[2]]);
    if (cy->polarity == 2) fputs(", removed", f);
    if (inl) fprintf(f, ", %zu inliers", inl);
    if (cy->sigma > 0) {
        prim_format_number(a, cy->sigma, cy->sigma / 10);
        fprintf(f, ", +-%s", a);
    }
    fputc('\n', f);
}

/* Whether node i (an intersection) has a box among its operands with leaf j a face. */
static int ft_box_uses(const ft *F, uint32_t i, uint32_t j)
{
    const ft_node *v = &F->v[i];
    for (uint32_t k = 0; k < v->n; k++) {
        const ft_node *b = &F->v[v->t[k].node];
        if (b->kind != FT_BOX) continue;
        for (int f = 0; f < 6; f++)
            if (b->face[f] == j) return 1;
    }
    return 0;
}

/* Planes of intersection `and` that complete a box in an intersection C under one of its
 * unions: A & (B | C) = A & (B | (A' & C)) for A' among A's operands, exactly; then
 * each plane the box took leaves A when the solid stays (ft_keeps). */
static void ft_push(ft *F, uint32_t and, const ft_check *ck)
{
    for (uint32_t k = 0; k < F->v[and].n && !F->failed; k++) {
        ft_term o = F->v[and].t[k];
        if (o.neg || F->v[o.node].kind != FT_OR) continue;
        for (uint32_t m = 0; m < F->v[o.node].n && !F->failed; m++) {
            ft_term ct = F->v[o.node].t[m];
            if (ct.neg || F->v[ct.node].kind != FT_AND) continue;
            uint32_t C = ct.node, n0 = F->v[C].n, added = 0;
            double nn[3], dd;
            for (uint32_t a = 0; a < F->v[and].n; a++)
                if (ft_plane(F, F->v[and].t[a], nn, &dd)) {
                    ft_add(F, C, F->v[and].t[a].node, F->v[and].t[a].neg);
                    added++;
                }
            if (!added || F->failed) {
                F->v[C].n = n0;
                continue;
            }
            ft_term *saved = frep_malloc(F->v[C].n * sizeof *saved);
            if (!saved) {
                F->failed = 1;
                return;
            }
            uint32_t ns = F->v[C].n;
            memcpy(saved, F->v[C].t, ns * sizeof *saved);
            ft_solids(F, C, ck);
            /* The planes the box did not take go again (they were copies). */
            int took = 0;
            uint32_t w = 0;
            for (uint32_t a = 0; a < F->v[C].n; a++) {
                ft_term t = F->v[C].t[a];
                int copy = 0;
                for (uint32_t b = n0; b < ns; b++)
                    if (saved[b].node == t.node && saved[b].neg == t.neg) copy = 1;
                int orig = 0;
                for (uint32_t b = 0; b < n0; b++)
                    if (saved[b].node == t.node && saved[b].neg == t.neg) orig = 1;
                if (copy && !orig) continue;
                F->v[C].t[w++] = t;
            }
            F->v[C].n = w;
            for (uint32_t a = 0; a < F->v[and].n; a++) {
                ft_term t = F->v[and].t[a];
                if (F->v[t.node].kind == FT_LEAF && ft_box_uses(F, C, F->v[t.node].leaf)) took = 1;
            }
            if (!took) {
                memcpy(F->v[C].t, saved, n0 * sizeof *saved);
                F->v[C].n = n0;
            } else {
                /* Planes the box took leave the outer intersection if the solid stays. */
                for (uint32_t a = 0; a < F->v[and].n;) {
                    ft_term t = F->v[and].t[a];
                    if (!ft_plane(F, t, nn, &dd) || !ft_box_uses(F, C, F->v[t.node].leaf)) {
                        a++;
                        continue;
                    }
                    uint32_t idx = a;
                    ft_node *v = &F->v[and];
                    memmove(&v->t[a], &v->t[a + 1], (v->n - a - 1) * sizeof *v->t);
                    v->n--;
                    if (!ft_keeps(F, ck)) {
                        memmove(&v->t[idx + 1], &v->t[idx], (v->n - idx) * sizeof *v->t);
                        v->t[idx] = t;
                        v->n++;
                        a++;
                    }
                }
            }
            frep_free(saved);
        }
    }
}

/* The solids the subtree at i writes: its boxes and capped cylinders, and its
 * primitives (each counted once). */
static unsigned ft_count(const ft *F, uint32_t i, uint8_t *prim_seen)
{
    const ft_node *v = &F->v[i];
    if (v->kind == FT_LEAF) {
        unsigned first = !prim_seen[v->leaf];
        prim_seen[v->leaf] = 1;
        return first;
    }
    if (v->kind == FT_BOX || v->kind == FT_CAPPED) return 1;
    unsigned c = 0;
    for (uint32_t k = 0; k < v->n; k++) c += ft_count(F, v->t[k].node, prim_seen);
    return c;
}

/* Whether every leaf under node i is a plane (boxes count as planes). */
static int ft_planar(const ft *F, uint32_t i)
{
    const ft_node *v = &F->v[i];
    switch (v->kind) {
    case FT_LEAF: return v->leaf < F->nprims && F->q[v->leaf].type == PRIM_PLANE;
    case FT_BOX: return 1;
    case FT_CAPPED: return 0;
    case FT_AND:
    case FT_OR:
        for (uint32_t k = 0; k < v->n; k++)
            if (!ft_planar(F, v->t[k].node)) return 0;
        return 1;
    }
    return 0;
}

/* How ft_spread_terms writes a term X & Uk where Uk is itself an intersection A & B:
 * nested, X & (A & B), or flat, X & A & B, where ft_solids finds X's caps beside a
 * cylinder of Uk (always, or where Uk holds a curved solid). */
enum { SPREAD_NESTED, SPREAD_FLAT_CURVED, SPREAD_FLAT };

/* Intersection i = X & U, U = U1 | ... | Un its operand o, written in place as the union
 * (X & U1) | ... | (X & Un) (min and max distribute exactly), the terms as `flat` says.
 * Returns the node that now holds the intersection (unreachable until put back),
 * FT_NONE when out of memory. */
static uint32_t ft_spread_terms(ft *F, uint32_t i, uint32_t o, int flat)
{
    ft_term ot = F->v[i].t[o];
    uint32_t u = ft_new(F, FT_OR), nu = F->v[ot.node].n;
    for (uint32_t k = 0; k < nu && u != FT_NONE; k++) {
        uint32_t a = ft_new(F, FT_AND);
        for (uint32_t m = 0; m < F->v[i].n && a != FT_NONE; m++)
            if (m != o) ft_add(F, a, F->v[i].t[m].node, F->v[i].t[m].neg);
        ft_term uk = F->v[ot.node].t[k];
        if (flat != SPREAD_NESTED && !uk.neg && F->v[uk.node].kind == FT_AND &&
            (flat == SPREAD_FLAT || !ft_planar(F, uk.node)))
            for (uint32_t m = 0; m < F->v[uk.node].n; m++)
                ft_add(F, a, F->v[uk.node].t[m].node, F->v[uk.node].t[m].neg);
        else
            ft_add(F, a, uk.node, uk.neg);
        ft_add(F, u, a, 0);
    }
    if (F->failed) return FT_NONE;
    ft_node saved = F->v[i];
    F->v[i] = F->v[u];
    F->v[u] = saved;
    return u;
}

/* Whether operand `o` of intersection `and` is a union holding a cylinder across a
 * pair of planes of the intersection (planes across its axis). */
static int ft_caps_union(const ft *F, uint32_t and, uint32_t o)
{
    const ft_node *v = &F->v[and];
    ft_term ot = v->t[o];
    if (ot.neg || F->v[ot.node].kind != FT_OR) return 0;
    const ft_node *u = &F->v[ot.node];
    for (uint32_t k = 0; k < u->n; k++) {
        const ft_node *lv = &F->v[u->t[k].node];
        if (u->t[k].neg || lv->kind != FT_LEAF || lv->leaf >= F->nprims ||
            F->q[lv->leaf].type != PRIM_CYLINDER)
            continue;
        int across = 0;
        for (uint32_t m = 0; m < v->n; m++) {
            double nn[3], d;
            if (m != o && ft_plane(F, v->t[m], nn, &d) &&
                fabs(vec3_dot(nn, F->q[lv->leaf].a)) >= cos(CANON_CAP_TILT))
                across++;
        }
        if (across >= 2) return 1;
    }
    return 0;
}

/* Whether the model loses its solid without any one operand of union u (never without
 * a cloud to tell). */
static int ft_needs_all(ft *F, uint32_t u, const ft_check *ck)
{
    uint32_t none = ft_new(F, FT_OR);   /* no operands: nothing (ft_eval) */
    if (!ck->cloud || none == FT_NONE) return 0;
    int all = 1;
    for (uint32_t k = 0; k < F->v[u].n && all; k++) {
        ft_term a = F->v[u].t[k];
        F->v[u].t[k] = (ft_term){ .node = none, .neg = 0 };
        all = !ft_keeps(F, ck);
        F->v[u].t[k] = a;
    }
    return all;
}

/* Intersection `and` of planes and a union holding a cylinder across two of them
 * (rails between caps, `x1 & x2 & (rail_1 | rail_2 | slab)`), distributed: the union of
 * each operand intersected with the rest, `(rail_1 & x1 & x2) | ...`, kept when every
 * term becomes one solid (a capped cylinder, a box), or when the terms write fewer
 * solids than the intersection did (a cylinder capped, another term left with a cut
 * of its own) and the model needs every term (a term it does not need is
 * ft_distribute's to drop).  An identity, so no check of the solid; 1 when the node
 * is now that union. */
static int ft_distribute_caps(ft *F, uint32_t and, const ft_check *ck)
{
    uint8_t *seen = NULL;
    int rc = 0;
    for (uint32_t o = 0; o < F->v[and].n && !F->failed && !rc; o++) {
        if (!ft_caps_union(F, and, o)) continue;
        if (!seen && !(seen = frep_calloc(F->nprims + 1, 1))) {
            F->failed = 1;
            break;
        }
        memset(seen, 0, F->nprims + 1);
        unsigned before = ft_count(F, and, seen);
        uint32_t u = ft_spread_terms(F, and, o, SPREAD_FLAT);
        if (u == FT_NONE) break;
        int whole = 1;
        for (uint32_t k = 0; k < F->v[and].n && !F->failed; k++) {
            uint32_t a = F->v[and].t[k].node;
            ft_solids(F, a, ck);
            whole &= F->v[a].n == 1;
        }
        memset(seen, 0, F->nprims + 1);
        if (F->failed) break;
        if (whole || (ft_count(F, and, seen) < before && ft_needs_all(F, and, ck))) {
            rc = 1;
            break;
        }
        ft_node saved = F->v[and];
        F->v[and] = F->v[u];
        F->v[u] = saved;
    }
    frep_free(seen);
    return rc;
}

static void apply_solids(ft *F, uint32_t i, const ft_check *ck)
{
    ft_node *v = &F->v[i];
    if (v->kind != FT_AND && v->kind != FT_OR) return;
    uint32_t n = v->n;
    for (uint32_t k = 0; k < n; k++) apply_solids(F, F->v[i].t[k].node, ck);
    if (F->v[i].kind == FT_AND && !ft_distribute_caps(F, i, ck)) {
        ft_solids(F, i, ck);
        if (ck->cloud) ft_push(F, i, ck);
    }
}

size_t canon_spread(size_t k, size_t n, size_t most)
{
    size_t m = n < most ? n : most;
    return m ? (size_t)((unsigned long long)k * n / m) : 0;
}

/* ---- the box cover: planar parts as unions of boxes ------------------------------------ */

/* A subtree whose leaves are all planes (a stack of cuboids the GA wrote as an
 * intersection of unions, a box with a corner cut away) is written again as a union of
 * terms P \ (N1 | N2): P a box whose six faces are planes of the subtree, each N a cut,
 * a box with faces among those planes or free (placed beyond the part).  The terms come
 * from a greedy cover of labelled points: the grid of ft_check, the cell centres of each
 * frame's planes and the cloud's points moved in and out along their normals, each
 * labelled by the subtree's sign.  The cover replaces the subtree only when it writes
 * fewer solids and the whole model passes ft_keeps (and stays bounded if it was). */

#define COVER_NO (COVER_MAX_OFFS + 2)
_Static_assert(COVER_MAX_NEG <= 65536, "cv_term.cut indices are uint16_t");
/* Outside points a box of the second pass may hold, per inside point (cv_run); of the
 * third: the GA's tree leaves out what few points show (a cube's corner poking out of
 * the one it sits in), and the box is kept where the model then explains the cloud
 * no worse. */
#define COVER_SLIVER 0.01
#define COVER_SLIVER_WIDE 0.1
/* Candidate boxes over all frames: at most COVER_MAX_FRAMES frames, each with at most
 * COVER_NO face positions per axis (free ends included), so at most C(COVER_NO, 2)
 * choices of the two faces on each of its three axes.  The other limits bound the
 * work so (729,000 boxes, the frames' point sets of nw words each), and cv_list needs
 * no check of its own. */
#define COVER_PAIRS (COVER_NO * (COVER_NO - 1) / 2)
#define COVER_MAX_BOXES ((size_t)COVER_MAX_FRAMES * COVER_PAIRS * COVER_PAIRS * COVER_PAIRS)
_Static_assert(COVER_MAX_BOXES <= 1000000, "the cover's work bound: fewer frames or offsets");
/* cv_box stores frames and face position indices in bytes. */
_Static_assert(COVER_MAX_FRAMES <= 256 && COVER_NO <= 256, "cv_box fields are uint8_t");
/* Cloud points moved in and out along their normals by this many grid tolerances
 * (ft_check.gtol), so that they are labelled: thin walls get points on both sides. */
#define COVER_CLOUD_SHIFT 3
/* Free faces lie at the cloud's oriented box grown by this factor (ft_check's grid
 * covers 1.1). */
#define COVER_FREE_GROWTH 1.25
/* A face hidden inside another solid (a cube stacked on another, its bottom buried):
 * on an axis with one fitted face, a buried position this many grid tolerances past
 * the far end of the inliers of the frame's other faces (cv_buried). */
#define COVER_BURIED_DEPTH 10

typedef struct cv_frame {
    double u[3][3];                      /* orthonormal axes */
    int n[3];                            /* face positions per axis, free ends included */
    double of[3][COVER_NO];              /* ascending; of[k][0] and of[k][n-1] free */
    uint32_t leaf[3][COVER_NO];          /* the plane there (FT_NONE: free) */
    uint8_t up[3][COVER_NO];             /* the leaf's outward normal is along +u */
} cv_frame;

typedef struct cv_box {
    uint8_t f, lo[3], hi[3];             /* frame, face position indices per axis */
} cv_box;

typedef struct cover {
    ft *F;
    const ft_check *ck;
    uint32_t node;
    size_t np, nw;                       /* labelled points, 64-bit words of a set */
    double *x;                           /* 3 np coordinates */
    uint64_t *in, *out;                  /* the subtree's sign there */
    cv_frame fr[COVER_MAX_FRAMES];
    int nf;
    uint64_t *iv;                        /* per frame, axis, lo, hi: points within */
    uint64_t *bits, *tmp, *pin;          /* scratch sets (pin: tmp's second half) */
    uint32_t planes[COVER_MAX_PLANES];
    int npl;
    int curved_ok;                       /* cv_planes passes over curved solids */
    double sliver;                       /* outside points a box may keep, per inside */
} cover;

static uint64_t *cv_iv(cover *C, int f, int k, int lo, int hi)
{
    return &C->iv[((((size_t)f * 3 + (size_t)k) * COVER_NO + (size_t)lo) * COVER_NO + (size_t)hi) * C->nw];
}

/* The points of box b into set s. */
static void cv_set(cover *C, cv_box b, uint64_t *s)
{
    const uint64_t *a = cv_iv(C, b.f, 0, b.lo[0], b.hi[0]), *c = cv_iv(C, b.f, 1, b.lo[1], b.hi[1]),
                   *e = cv_iv(C, b.f, 2, b.lo[2], b.hi[2]);
    for (size_t w = 0; w < C->nw; w++) s[w] = a[w] & c[w] & e[w];
}

static size_t cv_count(const cover *C, const uint64_t *a, const uint64_t *b)
{
    size_t n = 0;
    for (size_t w = 0; w < C->nw; w++) n += (size_t)__builtin_popcountll(a[w] & b[w]);
    return n;
}

/* Whether box a lies within box b (the same frame). */
static int cv_within(cv_box a, cv_box b)
{
    if (a.f != b.f) return 0;
    for (int k = 0; k < 3; k++)
        if (a.lo[k] < b.lo[k] || a.hi[k] > b.hi[k]) return 0;
    return 1;
}

/* The distinct plane leaves under node i (box faces included) into C->planes; 0 when
 * there are too many, or when a leaf is no plane unless C->curved_ok (then curved
 * solids are passed over). */
static int cv_planes(cover *C, uint32_t i)
{
    const ft *F = C->F;
    const ft_node *v = &F->v[i];
    uint32_t got[6];
    int ng = 0;
    switch (v->kind) {
    case FT_LEAF:
        if (v->leaf >= F->nprims || F->q[v->leaf].type != PRIM_PLANE) return C->curved_ok;
        got[ng++] = v->leaf;
        break;
    case FT_BOX:
        for (int k = 0; k < 6; k++)
            if (v->face[k] != FT_NONE) got[ng++] = v->face[k];
        break;
    case FT_CAPPED: return C->curved_ok;
    case FT_AND:
    case FT_OR:
        for (uint32_t k = 0; k < v->n; k++)
            if (!cv_planes(C, v->t[k].node)) return 0;
        return 1;
    }
    for (int g = 0; g < ng; g++) {
        int seen = 0;
        for (int k = 0; k < C->npl && !seen; k++) seen = C->planes[k] == got[g];
        if (seen) continue;
        if (C->npl == COVER_MAX_PLANES) return 0;
        C->planes[C->npl++] = got[g];
    }
    return 1;
}

/* The extent along u of plane q's inlier patch: of the cloud's points on the plane
 * (within the grid tolerance) and in its patch's box, the least and the greatest
 * u . x; the patch box's own extent when none is (a patch box turned against u is
 * wider along it than the points: a side face cut off by a turned solid below). */
static void cv_patch_range(const cover *C, const prim *q, const double u[3], double *lo, double *hi)
{
    const frep_cloud *cl = C->ck->cloud;
    double gtol = C->ck->gtol, a = INFINITY, b = -INFINITY;
    for (size_t i = 0; cl && i < cl->n; i++) {
        double x[3] = { cl->x[i], cl->y[i], cl->z[i] }, d[3];
        if (fabs(vec3_dot(q->p, x) - q->r) > gtol) continue;
        for (int w = 0; w < 3; w++) d[w] = x[w] - q->obb_c[w];
        int in = 1;
        for (int e = 0; e < 3 && in; e++) in = fabs(vec3_dot(d, q->obb_axes[e])) <= q->obb_half[e] + gtol;
        if (!in) continue;
        double t = vec3_dot(x, u);
        a = fmin(a, t);
        b = fmax(b, t);
    }
    if (a <= b) {
        *lo = a;
        *hi = b;
        return;
    }
    double c = vec3_dot(q->obb_c, u), e = 0;
    for (int w = 0; w < 3; w++) e += fabs(vec3_dot(q->obb_axes[w], u)) * q->obb_half[w];
    *lo = c - e;
    *hi = c + e;
}

/* On axis k of frame fr with one fitted face (at index 1, outward along +u when up):
 * the buried position on the other side, COVER_BURIED_DEPTH grid tolerances past the
 * inlier patches of the frame's faces across k, where the box's side faces stop being
 * seen.  Returns 0 when no such face has a patch or the position is not past the face. */
static int cv_buried(const cover *C, const cv_frame *fr, int k, double *at)
{
    const ft *F = C->F;
    double ct = cos(C->ck->tol), lo = INFINITY, hi = -INFINITY;
    for (int p = 0; p < C->npl; p++) {
        const prim *q = &F->q[C->planes[p]];
        int across = 0;
        for (int j = 0; j < 3; j++)
            if (j != k && fabs(vec3_dot(q->p, fr->u[j])) >= ct) across = 1;
        if (!across || !q->has_obb) continue;
        double plo, phi;
        cv_patch_range(C, q, fr->u[k], &plo, &phi);
        lo = fmin(lo, plo);
        hi = fmax(hi, phi);
    }
    if (!(lo <= hi)) return 0;
    double depth = COVER_BURIED_DEPTH * C->ck->gtol, o = fr->of[k][1];
    *at = fr->up[k][1] ? lo - depth : hi + depth;
    return fr->up[k][1] ? *at < o - C->ck->gtol : *at > o + C->ck->gtol;
}

/* Frames: orthogonal triples of the planes' directions; on each axis the planes'
 * positions, merged within the grid tolerance, a buried position where one face is
 * hidden (cv_buried), and the two free ends. */
static int cv_frames(cover *C, const evolve_result *r)
{
    const ft *F = C->F;
    double dir[COVER_MAX_PLANES][3];
    int nd = 0;
    double ct = cos(C->ck->tol), st = sin(C->ck->tol);
    for (int k = 0; k < C->npl; k++) {
        const double *n = F->q[C->planes[k]].p;
        int seen = 0;
        for (int e = 0; e < nd && !seen; e++) seen = fabs(vec3_dot(n, dir[e])) >= ct;
        if (!seen) memcpy(dir[nd++], n, sizeof dir[0]);
    }
    C->nf = 0;
    for (int a = 0; a < nd; a++)
        for (int b = a + 1; b < nd; b++)
            for (int c = b + 1; c < nd; c++) {
                if (fabs(vec3_dot(dir[a], dir[b])) > st || fabs(vec3_dot(dir[a], dir[c])) > st ||
                    fabs(vec3_dot(dir[b], dir[c])) > st)
                    continue;
                if (C->nf == COVER_MAX_FRAMES) return 0;
                cv_frame *fr = &C->fr[C->nf++];
                memcpy(fr->u[0], dir[a], sizeof fr->u[0]);
                memcpy(fr->u[1], dir[b], sizeof fr->u[1]);
                double t = vec3_dot(fr->u[1], fr->u[0]);
                for (int w = 0; w < 3; w++) fr->u[1][w] -= t * fr->u[0][w];
                vec3_normalize(fr->u[1]);
                vec3_cross(fr->u[0], fr->u[1], fr->u[2]);
                if (vec3_dot(fr->u[2], dir[c]) < 0)
                    for (int w = 0; w < 3; w++) fr->u[2][w] = -fr->u[2][w];
            }
    double gtol = C->ck->gtol;
    for (int f = 0; f < C->nf; f++) {
        cv_frame *fr = &C->fr[f];
        for (int k = 0; k < 3; k++) {
            int n = 1;
            for (int p = 0; p < C->npl; p++) {
                const prim *q = &F->q[C->planes[p]];
                double nu = vec3_dot(q->p, fr->u[k]);
                if (fabs(nu) < ct) continue;
                double o = q->r / nu;
                int at = 1;
                while (at < n && fr->of[k][at] < o) at++;
                if ((at < n && fr->of[k][at] - o <= gtol) || (at > 1 && o - fr->of[k][at - 1] <= gtol))
                    continue;
                if (n - 1 == COVER_MAX_OFFS) return 0;
                memmove(&fr->of[k][at + 1], &fr->of[k][at], (size_t)(n - at) * sizeof fr->of[k][0]);
                memmove(&fr->leaf[k][at + 1], &fr->leaf[k][at], (size_t)(n - at) * sizeof fr->leaf[k][0]);
                memmove(&fr->up[k][at + 1], &fr->up[k][at], (size_t)(n - at) * sizeof fr->up[k][0]);
                fr->of[k][at] = o;
                fr->leaf[k][at] = C->planes[p];
                fr->up[k][at] = nu > 0;
                n++;
            }
            double b;
            if (n == 2 && cv_buried(C, fr, k, &b)) {
                int at = fr->up[k][1] ? 1 : 2;
                if (at == 1) {
                    fr->of[k][2] = fr->of[k][1];
                    fr->leaf[k][2] = fr->leaf[k][1];
                    fr->up[k][2] = fr->up[k][1];
                }
                fr->of[k][at] = b;
                fr->leaf[k][at] = FT_NONE;
                fr->up[k][at] = 0;
                n++;
            }
            /* The free ends: beyond the grown oriented box of the cloud. */
            double c = vec3_dot(r->obb.c, fr->u[k]), e = 0;
            for (int a = 0; a < 3; a++) e += fabs(vec3_dot(r->obb.ax[a], fr->u[k])) * r->obb.h[a];
            e = COVER_FREE_GROWTH * e + gtol;
            fr->of[k][0] = fmin(c - e, n > 1 ? fr->of[k][1] - e : c - e);
            fr->leaf[k][0] = FT_NONE;
            fr->of[k][n] = fmax(c + e, n > 1 ? fr->of[k][n - 1] + e : c + e);
            fr->leaf[k][n] = FT_NONE;
            fr->n[k] = n + 1;
        }
    }
    return C->nf > 0;
}

/* The value of the model (root) at x with node i's solid replaced by all of space (full) or by
 * nothing: an empty intersection is +inf, an empty union -inf (ft_eval). */
static double ft_eval_as(ft *F, uint32_t root, uint32_t i, int full, const double *x)
{
    ft_node saved = F->v[i];
    F->v[i].kind = full ? FT_AND : FT_OR;
    F->v[i].n = 0;
    double v = ft_eval(F, root, x);
    F->v[i] = saved;
    return v;
}

/* Point x labelled by the subtree's sign there (1 inside, 2 outside) and kept, or 0 and
 * skipped: on the subtree's surface, or where the subtree does not matter, the model's
 * sign being the same whether the subtree is everything or nothing (inside a solid it
 * is joined to, outside one it is intersected with: a cube's bottom buried in the cube
 * below).  The cover then needs not reproduce the subtree where nothing shows it;
 * cv_run checks the model as a whole. */
static int cv_push(cover *C, size_t *cap, const double *x)
{
    double v = ft_eval(C->F, C->node, x), gtol = C->ck->gtol;
    if (fabs(v) <= gtol) return 0;
    uint32_t root = C->ck->root;
    if (C->node != root) {
        double full = ft_eval_as(C->F, root, C->node, 1, x);
        double none = ft_eval_as(C->F, root, C->node, 0, x);
        if ((full > gtol && none > gtol) || (full < -gtol && none < -gtol)) return 0;
    }
    if (C->np == *cap) {
        size_t nc = *cap ? 2 * *cap : 4096;
        double *nx = frep_realloc(C->x, 3 * nc * sizeof *nx);
        if (!nx) return -1;
        C->x = nx;
        *cap = nc;
    }
    memcpy(&C->x[3 * C->np], x, 3 * sizeof *x);
    C->np++;
    return v > 0 ? 1 : 2;
}

/* The labelled points and, per frame, axis and pair of face positions, the set of
 * points between them. */
static int cv_points(cover *C)
{
    const ft_check *ck = C->ck;
    size_t cap = 0;
    uint8_t *lab = NULL;
    size_t labcap = 0;
    int rc = -1;
#define CV_ADD(P)                                                                    \
    do {                                                                             \
        int l_ = cv_push(C, &cap, (P));                                              \
        if (l_ < 0) goto done;                                                       \
        if (l_) {                                                                    \
            if (C->np > labcap) {                                                    \
                size_t nc_ = labcap ? 2 * labcap : 4096;                             \
                uint8_t *nl_ = frep_realloc(lab, nc_);                               \
                if (!nl_) goto done;                                                 \
                lab = nl_;                                                           \
                labcap = nc_;                                                        \
            }                                                                        \
            lab[C->np - 1] = (uint8_t)l_;                                            \
        }                                                                            \
    } while (0)
    for (size_t i = 0; i < ck->ng; i++) CV_ADD(&ck->g[3 * i]);
    const frep_cloud *cl = ck->cloud;
    if (cl->has_normals) {
        size_t m = cl->n < COVER_CLOUD_POINTS ? cl->n : COVER_CLOUD_POINTS;
        double h = COVER_CLOUD_SHIFT * ck->gtol;
        for (size_t k = 0; k < m; k++)
            for (int s = -1; s <= 1; s += 2) {
                size_t i = canon_spread(k, cl->n, COVER_CLOUD_POINTS);
                double p[3] = { cl->x[i] + s * h * cl->nx[i], cl->y[i] + s * h * cl->ny[i],
                                cl->z[i] + s * h * cl->nz[i] };
                CV_ADD(p);
            }
    }
    for (int f = 0; f < C->nf; f++) {
        const cv_frame *fr = &C->fr[f];
        int a[3];
        for (a[0] = 0; a[0] + 1 < fr->n[0]; a[0]++)
            for (a[1] = 0; a[1] + 1 < fr->n[1]; a[1]++)
                for (a[2] = 0; a[2] + 1 < fr->n[2]; a[2]++) {
                    double p[3] = { 0, 0, 0 };
                    for (int k = 0; k < 3; k++) {
                        double m = (fr->of[k][a[k]] + fr->of[k][a[k] + 1]) / 2;
                        for (int w = 0; w < 3; w++) p[w] += m * fr->u[k][w];
                    }
                    CV_ADD(p);
                }
    }
#undef CV_ADD
    C->nw = (C->np + 63) / 64;
    size_t nsets = (size_t)C->nf * 3 * COVER_NO * COVER_NO;
    C->in = frep_calloc(C->nw, sizeof *C->in);
    C->out = frep_calloc(C->nw, sizeof *C->out);
    C->bits = frep_calloc(C->nw, sizeof *C->bits);
    C->tmp = frep_calloc(2 * C->nw, sizeof *C->tmp);
    C->pin = C->tmp ? C->tmp + C->nw : NULL;
    C->iv = frep_calloc(nsets * C->nw, sizeof *C->iv);
    if (!C->np || !C->in || !C->out || !C->bits || !C->tmp || !C->iv) goto done;
    for (size_t i = 0; i < C->np; i++) {
        uint64_t m = (uint64_t)1 << (i % 64);
        if (lab[i] == 1) C->in[i / 64] |= m;
        else C->out[i / 64] |= m;
    }
    for (int f = 0; f < C->nf; f++)
        for (int k = 0; k < 3; k++) {
            const cv_frame *fr = &C->fr[f];
            for (size_t i = 0; i < C->np; i++) {
                double t = vec3_dot(&C->x[3 * i], fr->u[k]);
                int lo = 0;
                while (lo < fr->n[k] && fr->of[k][lo] < t) lo++;
                /* between positions lo-1 and lo: within every [a, b] with a < lo <= b */
                for (int s = 0; s < lo; s++)
                    for (int e = lo; e < fr->n[k]; e++)
                        cv_iv(C, f, k, s, e)[i / 64] |= (uint64_t)1 << (i % 64);
            }
        }
    rc = 0;
done:
    frep_free(lab);
    return rc;
}

/* A candidate term: box P, its cuts (indices into the negatives), the inside points it
 * has; ncut COVER_MAX_CUTS + 1 when no cuts remove P's outside points. */
typedef struct cv_term {
    cv_box p;
    uint8_t ncut;
    uint16_t cut[COVER_MAX_CUTS];
    size_t nin;
} cv_term;

typedef struct cv_neg {
    cv_box b;
    size_t nin, nout, span;              /* inside and outside points it holds */
} cv_neg;

static int cv_neg_cmp(const void *pa, const void *pb)
{
    const cv_neg *a = pa, *b = pb;
    double sa = (double)a->nout - (double)a->nin, sb = (double)b->nout - (double)b->nin;
    if (sa != sb) return sa < sb ? 1 : -1;
    if (a->nin != b->nin) return a->nin > b->nin ? 1 : -1;
    if (a->span != b->span) return a->span < b->span ? 1 : -1;
    return memcmp(&a->b, &b->b, sizeof a->b);
}

static int cv_term_cmp(const void *pa, const void *pb)
{
    const cv_term *a = pa, *b = pb;
    double ra = (double)a->nin / (1 + a->ncut), rb = (double)b->nin / (1 + b->ncut);
    if (ra != rb) return ra < rb ? 1 : -1;
    return memcmp(&a->p, &b->p, sizeof a->p);
}

/* The boxes of every frame, faces at fitted planes only or (free) at the free ends
 * too, into out (NULL: counted only); returns their number (at most COVER_MAX_BOXES). */
static size_t cv_list(const cover *C, int free, cv_box *out)
{
    size_t m = 0;
    for (int f = 0; f < C->nf; f++) {
        const cv_frame *fr = &C->fr[f];
        int a = free ? 0 : 1, z[3];
        for (int k = 0; k < 3; k++) z[k] = free ? fr->n[k] - 1 : fr->n[k] - 2;
        cv_box b;
        b.f = (uint8_t)f;
        for (int l0 = a; l0 < z[0]; l0++)
            for (int h0 = l0 + 1; h0 <= z[0]; h0++)
                for (int l1 = a; l1 < z[1]; l1++)
                    for (int h1 = l1 + 1; h1 <= z[1]; h1++)
                        for (int l2 = a; l2 < z[2]; l2++)
                            for (int h2 = l2 + 1; h2 <= z[2]; h2++) {
                                b.lo[0] = (uint8_t)l0, b.hi[0] = (uint8_t)h0;
                                b.lo[1] = (uint8_t)l1, b.hi[1] = (uint8_t)h1;
                                b.lo[2] = (uint8_t)l2, b.hi[2] = (uint8_t)h2;
                                if (out) out[m] = b;
                                m++;
                            }
    }
    return m;
}

/* The chosen terms: a greedy weighted cover of the inside points (most new points per
 * box first), then terms whose points the others cover dropped.  The second pass
 * (C->sliver > 0) lets that sliver of the inside points go uncovered, as it lets each
 * box keep a sliver of outside points: the GA's thin slabs of extra material that no
 * box of fitted faces holds; cv_run's check of the whole model decides.  Returns the
 * number of terms (0: the inside points are not covered, -1: out of memory). */
static int cv_choose(cover *C, cv_term *t, size_t nt, const cv_neg *neg, cv_term *chosen)
{
    uint64_t *cov = frep_calloc(C->nw, sizeof *cov);
    uint64_t *own = frep_calloc((size_t)COVER_MAX_TERMS * C->nw, sizeof *own);
    int n = 0, rc = -1;
    if (!cov || !own) goto done;
    size_t total = cv_count(C, C->in, C->in), got = 0;
    size_t need = total - (size_t)(C->sliver * (double)total);
    while (got < total && n < COVER_MAX_TERMS) {
        double best = 0;
        size_t bi = 0;
        for (size_t i = 0; i < nt; i++) {
            double cost = 1 + t[i].ncut;
            if ((double)t[i].nin / cost <= best) break;   /* sorted by this bound */
            cv_set(C, t[i].p, C->bits);
            for (int k = 0; k < t[i].ncut; k++) {
                cv_set(C, neg[t[i].cut[k]].b, C->tmp);
                for (size_t w = 0; w < C->nw; w++) C->bits[w] &= ~C->tmp[w];
            }
            size_t g = 0;
            for (size_t w = 0; w < C->nw; w++)
                g += (size_t)__builtin_popcountll(C->bits[w] & C->in[w] & ~cov[w]);
            if ((double)g / cost > best) {
                best = (double)g / cost;
                bi = i;
            }
        }
        if (best <= 0) break;
        uint64_t *o = &own[(size_t)n * C->nw];
        cv_set(C, t[bi].p, o);
        for (int k = 0; k < t[bi].ncut; k++) {
            cv_set(C, neg[t[bi].cut[k]].b, C->tmp);
            for (size_t w = 0; w < C->nw; w++) o[w] &= ~C->tmp[w];
        }
        for (size_t w = 0; w < C->nw; w++) {
            o[w] &= C->in[w];
            cov[w] |= o[w];
        }
        got = cv_count(C, cov, C->in);
        chosen[n++] = t[bi];
    }
    rc = 0;
    if (got < need) goto done;
    /* Drop, last first, a term whose points the others cover. */
    for (int i = n - 1; i >= 0; i--) {
        memset(cov, 0, C->nw * sizeof *cov);
        for (int j = 0; j < n; j++)
            if (j != i)
                for (size_t w = 0; w < C->nw; w++) cov[w] |= own[(size_t)j * C->nw + w];
        if (cv_count(C, cov, C->in) < got) continue;
        memmove(&chosen[i], &chosen[i + 1], (size_t)(n - i - 1) * sizeof *chosen);
        memmove(&own[(size_t)i * C->nw], &own[(size_t)(i + 1) * C->nw],
                (size_t)(n - i - 1) * C->nw * sizeof *own);
        n--;
    }
    rc = n;
done:
    frep_free(cov);
    frep_free(own);
    return rc;
}

/* The node of box b (a positive or a cut): fitted faces as leaves, free ones as the
 * planes of the free ends. */
static uint32_t cv_node(cover *C, cv_box b)
{
    const cv_frame *fr = &C->fr[b.f];
    double lo[3], hi[3];
    uint32_t face[6];
    uint8_t fneg[6];
    for (int k = 0; k < 3; k++) {
        lo[k] = fr->of[k][b.lo[k]];
        hi[k] = fr->of[k][b.hi[k]];
        face[2 * k] = fr->leaf[k][b.hi[k]];
        fneg[2 * k] = !fr->up[k][b.hi[k]];
        face[2 * k + 1] = fr->leaf[k][b.lo[k]];
        fneg[2 * k + 1] = fr->up[k][b.lo[k]];
    }
    uint32_t n = ft_box_node(C->F, fr->u, lo, hi, face, fneg);
    if (n != FT_NONE) box_set_planes(C->F, n, fr->u, lo, hi);
    return n;
}

/* Solids written for the subtree at i: its distinct leaves and feature nodes. */
static size_t cv_solids(const ft *F, uint32_t i, uint32_t *seen, size_t *ns)
{
    const ft_node *v = &F->v[i];
    if (v->kind == FT_AND || v->kind == FT_OR) {
        size_t s = 0;
        for (uint32_t k = 0; k < v->n; k++) s += cv_solids(F, v->t[k].node, seen, ns);
        return s;
    }
    uint32_t key = v->kind == FT_LEAF ? v->leaf : (uint32_t)F->nprims + 1 + i;
    for (size_t k = 0; k < *ns; k++)
        if (seen[k] == key) return 0;
    seen[(*ns)++] = key;
    return 1;
}

/* Whether node i is outside at every probe of canon_tree_bounded (bound_probe). */
static int ft_bounded(const ft *F, uint32_t i, const evolve_result *r)
{
    for (int k = 0; k < 2 * CANON_BOUND_DIRS; k++) {
        double x[3];
        bound_probe(r, k, x);
        if (ft_eval(F, i, x) >= 0) return 0;
    }
    return 1;
}

static void cv_free(cover *C)
{
    frep_free(C->x);
    frep_free(C->in);
    frep_free(C->out);
    frep_free(C->iv);
    frep_free(C->bits);
    frep_free(C->tmp);
}

/* The terms of the cover of node i: positives with their cuts, sorted by inside points
 * per solid.  Returns their number (0: none), -1 when out of memory. */
static long cv_terms(cover *C, cv_term **pt, cv_neg **pn)
{
    /* the boxes with free faces include those of fitted faces only */
    cv_box *bx = frep_malloc((cv_list(C, 1, NULL) + 1) * sizeof *bx);
    /* coverable: inside points of pure positives; wanted: outside points of impure ones */
    uint64_t *coverable = frep_calloc(2 * C->nw, sizeof *coverable), *wanted = coverable + C->nw;
    cv_term *t = NULL;
    cv_neg *neg = NULL;
    long rc = -1;
    if (!bx || !coverable) goto done;
    /* Positives: boxes of fitted faces with inside points. */
    size_t nb = cv_list(C, 0, bx), nt = 0;
    t = frep_malloc((nb + 1) * sizeof *t);
    if (!t) goto done;
    for (size_t i = 0; i < nb; i++) {
        cv_set(C, bx[i], C->bits);
        size_t nin = cv_count(C, C->bits, C->in);
        if (!nin) continue;
        t[nt].p = bx[i];
        t[nt].nin = nin;
        size_t nout = cv_count(C, C->bits, C->out);
        t[nt].ncut = (double)nout > C->sliver * (double)nin ? COVER_MAX_CUTS + 1 : 0;
        if (!t[nt].ncut)
            for (size_t w = 0; w < C->nw; w++) coverable[w] |= C->bits[w] & C->in[w];
        else
            for (size_t w = 0; w < C->nw; w++) wanted[w] |= C->bits[w] & C->out[w];
        nt++;
    }
    /* Cuts: boxes (free faces allowed) holding outside points of impure positives
     * (wanted) whose inside points some positive without outside points can give back;
     * those that hold the most wanted points less inside points first, none within
     * another that holds no more inside points (which removes all it removes, at no
     * further cost), at most COVER_MAX_NEG. */
    nb = cv_list(C, 1, bx);
    neg = frep_malloc((nb + 1) * sizeof *neg);
    if (!neg) goto done;
    size_t nn = 0;
    for (size_t i = 0; i < nb; i++) {
        cv_set(C, bx[i], C->bits);
        int bad = 0;
        for (size_t w = 0; w < C->nw && !bad; w++) bad = (C->bits[w] & C->in[w] & ~coverable[w]) != 0;
        size_t no = bad ? 0 : cv_count(C, C->bits, wanted);
        if (!no) continue;
        neg[nn].b = bx[i];
        neg[nn].nin = cv_count(C, C->bits, C->in);
        neg[nn].nout = no;
        neg[nn].span = 0;
        for (int k = 0; k < 3; k++) neg[nn].span += (size_t)(bx[i].hi[k] - bx[i].lo[k]);
        nn++;
    }
    qsort(neg, nn, sizeof *neg, cv_neg_cmp);
    size_t kept = 0;
    for (size_t i = 0; i < nn && kept < COVER_MAX_NEG; i++) {
        int in = 0;
        for (size_t k = 0; k < kept && !in; k++)
            in = neg[k].nin == neg[i].nin && cv_within(neg[i].b, neg[k].b);
        if (!in) neg[kept++] = neg[i];
    }
    /* Each impure positive: the cuts that remove the most of its outside points (ties:
     * the fewest of its inside points, which other terms must then give back), until
     * no more of them are left than the pass lets a box keep (C->sliver per inside
     * point: the GA's slivers a cut of fitted faces cannot take). */
    size_t ok = 0;
    for (size_t i = 0; i < nt; i++) {
        if (t[i].ncut) {
            cv_set(C, t[i].p, C->bits);
            for (size_t w = 0; w < C->nw; w++) C->bits[w] &= C->out[w];
            int nc = 0;
            size_t keep = (size_t)(C->sliver * (double)t[i].nin);
            cv_set(C, t[i].p, C->tmp);
            for (size_t w = 0; w < C->nw; w++) C->pin[w] = C->tmp[w] & C->in[w];
            while (nc < COVER_MAX_CUTS && cv_count(C, C->bits, C->bits) > keep) {
                size_t best = 0, bi = 0, lost = 0;
                for (size_t k = 0; k < kept; k++) {
                    cv_set(C, neg[k].b, C->tmp);
                    size_t g = cv_count(C, C->tmp, C->bits);
                    if (g < best || !g) continue;
                    size_t l = cv_count(C, C->tmp, C->pin);
                    if (g > best || l < lost) best = g, bi = k, lost = l;
                }
                if (!best) break;
                t[i].cut[nc++] = (uint16_t)bi;
                cv_set(C, neg[bi].b, C->tmp);
                for (size_t w = 0; w < C->nw; w++) C->bits[w] &= ~C->tmp[w];
            }
            if (cv_count(C, C->bits, C->bits) > keep) continue;
            t[i].ncut = (uint8_t)nc;

        }
        t[ok++] = t[i];
    }
    qsort(t, ok, sizeof *t, cv_term_cmp);
    *pt = t;
    *pn = neg;
    t = NULL;
    neg = NULL;
    rc = (long)ok;
done:
    frep_free(bx);
    frep_free(coverable);
    frep_free(t);
    frep_free(neg);
    return rc;
}

/* The union of the chosen terms as a new node; each cut one node however many terms
 * it cuts.  *solids: the boxes written.  Returns the node, FT_NONE (memory). */
static uint32_t cv_union(cover *C, const cv_term *chosen, int n, const cv_neg *neg, size_t *solids)
{
    ft *F = C->F;
    uint16_t used[COVER_MAX_TERMS * COVER_MAX_CUTS];
    uint32_t cutnode[COVER_MAX_TERMS * COVER_MAX_CUTS];
    int nu = 0;
    for (int k = 0; k < n; k++)
        for (int c = 0; c < chosen[k].ncut; c++) {
            int dup = 0;
            for (int e = 0; e < nu && !dup; e++) dup = used[e] == chosen[k].cut[c];
            if (!dup) used[nu++] = chosen[k].cut[c];
        }
    *solids = (size_t)(n + nu);
    for (int e = 0; e < nu; e++)
        if ((cutnode[e] = cv_node(C, neg[used[e]].b)) == FT_NONE) return FT_NONE;
    uint32_t u = ft_new(F, FT_OR);
    for (int k = 0; k < n && u != FT_NONE; k++) {
        uint32_t p = cv_node(C, chosen[k].p), term = p;
        if (p == FT_NONE) return FT_NONE;
        if (chosen[k].ncut) {
            term = ft_new(F, FT_AND);
            ft_add(F, term, p, 0);
            for (int c = 0; c < chosen[k].ncut; c++)
                for (int e = 0; e < nu; e++)
                    if (used[e] == chosen[k].cut[c]) ft_add(F, term, cutnode[e], 1);
        }
        ft_add(F, u, term, 0);
    }
    return F->failed ? FT_NONE : u;
}

/* The cover of node i, in its place when it writes fewer solids and the model keeps
 * its solid (ft_keeps, and bounded if it was).  A second pass lets a box, after its
 * cuts, keep slivers of the subtree's outside (at most COVER_SLIVER of its inside
 * points): a face the GA left cutting a corner off another part, which the cloud does
 * not show; that cover is kept only when it differs from the tree at no more than
 * COVER_SLIVER of the inside grid points and explains the cloud at least as well
 * (mean distance).  Returns 1 when it replaced node i, 0 when
 * not, -1 when out of memory. */
static int cv_run(ft *F, uint32_t i, const ft_check *ck, const evolve_result *r)
{
    cover C;
    memset(&C, 0, sizeof C);
    C.F = F;
    C.ck = ck;
    C.node = i;
    cv_term *t = NULL, chosen[COVER_MAX_TERMS];
    cv_neg *neg = NULL;
    uint32_t *seen = NULL;
    int rc = 0;
    if (ft_cancelled(ck) || !cv_planes(&C, i) || C.npl < 6 || !cv_frames(&C, r)) goto done;
    rc = -1;
    seen = frep_malloc((F->n + F->nprims + 2) * sizeof *seen);
    if (!seen || cv_points(&C)) goto done;
    size_t ns = 0, before = cv_solids(F, i, seen, &ns), nin = 0;
    for (size_t g = 0; g < ck->ng; g++) nin += ck->ref[g] > ck->gtol;
    double mean = ft_mean(F, ck->root, ck->cloud, ck->stride);
    int bounded = ft_bounded(F, ck->root, r);
    for (int pass = 0; pass < 3 && !ft_cancelled(ck); pass++) {
        C.sliver = pass == 2 ? COVER_SLIVER_WIDE : pass ? COVER_SLIVER : 0;
        frep_free(t);
        frep_free(neg);
        t = NULL;
        neg = NULL;
        long nt = cv_terms(&C, &t, &neg);
        if (nt < 0) goto done;
        int n = nt ? cv_choose(&C, t, (size_t)nt, neg, chosen) : 0;
        if (n < 0) goto done;
        if (!n) continue;
        size_t after;
        uint32_t u = cv_union(&C, chosen, n, neg, &after);
        if (u == FT_NONE && F->failed) goto done;
        if (u == FT_NONE) continue;
        if (after >= before) continue;
        ft_node saved = F->v[i];
        F->v[i] = F->v[u];
        size_t most = (size_t)(COVER_SLIVER * (double)nin);
        int keeps = pass ? !ft_cancelled(ck) && ft_grid_diffs(F, ck, most) <= most &&
                               ft_mean(F, ck->root, ck->cloud, ck->stride) <= mean
                         : ft_keeps(F, ck);
        if (keeps && (!bounded || ft_bounded(F, ck->root, r))) {
            F->v[u] = saved;   /* the old operands stay allocated, unreachable */
            rc = 1;
            goto done;
        }
        F->v[u] = F->v[i];
        F->v[i] = saved;
    }
    rc = 0;
done:
    cv_free(&C);
    frep_free(t);
    frep_free(neg);
    frep_free(seen);
    return rc;
}

/* Operands of node i with sel[k] set grouped into a new node of its kind, and that
 * node covered (cv_run); the operands go back when the cover does not replace it.
 * Regrouping the operands of an intersection or a union keeps the solid.  Returns 1
 * when covered, 0 when not, -1 when out of memory. */
static int cover_group(ft *F, uint32_t i, const uint8_t *sel, const ft_check *ck,
                       const evolve_result *r)
{
    uint32_t g = ft_new(F, F->v[i].kind);
    if (g == FT_NONE) return -1;
    uint32_t ns = F->v[i].n, w = 0;
    ft_term *saved = frep_malloc(ns * sizeof *saved);
    if (!saved) return -1;
    memcpy(saved, F->v[i].t, ns * sizeof *saved);
    for (uint32_t k = 0; k < ns; k++) {
        if (sel[k]) ft_add(F, g, saved[k].node, saved[k].neg);
        else F->v[i].t[w++] = saved[k];
    }
    F->v[i].t[w].node = g;
    F->v[i].t[w++].neg = 0;
    F->v[i].n = w;
    int rc = F->failed ? -1 : cv_run(F, g, ck, r);
    if (rc <= 0) {
        memcpy(F->v[i].t, saved, ns * sizeof *saved);
        F->v[i].n = ns;
    }
    frep_free(saved);
    return rc;
}

/* Intersection i = X & (U1 | ... | Un), X its other operands, written again as
 * (X & U1) | ... | (X & Un) (min and max distribute exactly), X then dropped from each
 * term where the model keeps its solid (ft_keeps), or else the whole term dropped
 * where the model keeps its solid without it: an operand the GA put at the root for
 * one part (a face of one cube of a stack, a no-op elsewhere) goes to that part, where
 * the cover can read it, and a term that only repeats another part of the model (a
 * box's faces joined to a sphere the model already holds) goes.  The union taken is
 * the first whose rewrite keeps X in exactly one term (X written once), or in none
 * once a term is dropped; where X is needed by no term and no term goes, it is kept
 * as it is.  A term Uk that is an intersection holding a curved solid is written flat
 * beside X (SPREAD_FLAT_CURVED), so that apply_solids, run by apply_cover on the
 * rewritten node, caps a cylinder between X's face and its own (a post standing on a
 * plate whose bottom the GA put at the root).  Returns 1 when node i was rewritten, 0
 * when not. */
static int ft_distribute(ft *F, uint32_t i, const ft_check *ck)
{
    if (F->v[i].kind != FT_AND || F->v[i].n < 2) return 0;
    for (uint32_t o = 0; o < F->v[i].n && !F->failed && !ft_cancelled(ck); o++) {
        ft_term ot = F->v[i].t[o];
        if (ot.neg || F->v[ot.node].kind != FT_OR || F->v[ot.node].n < 2) continue;
        uint32_t none = ft_new(F, FT_OR);   /* no operands: nothing (ft_eval) */
        uint32_t u = ft_spread_terms(F, i, o, SPREAD_FLAT_CURVED), nu = F->v[ot.node].n;
        if (u == FT_NONE) return 0;
        uint32_t kept = 0, dropped = 0, w = 0;
        for (uint32_t k = 0; k < nu && kept <= 1; k++) {
            ft_term a = F->v[i].t[k];
            F->v[i].t[k] = F->v[ot.node].t[k];
            if (ft_keeps(F, ck)) continue;
            F->v[i].t[k].node = none;
            F->v[i].t[k].neg = 0;
            if (ft_keeps(F, ck)) {
                dropped++;
            } else {
                F->v[i].t[k] = a;
                kept++;
            }
        }
        if (kept == 1 || (kept == 0 && dropped)) {
            for (uint32_t k = 0; k < F->v[i].n; k++)
                if (F->v[i].t[k].node != none) F->v[i].t[w++] = F->v[i].t[k];
            F->v[i].n = w;
            return 1;
        }
        ft_node saved = F->v[i];
        F->v[i] = F->v[u];
        F->v[u] = saved;
    }
    return 0;
}

/* ---- factoring: a common operand of union terms taken out ------------------------------ */

/* Whether terms a and b write the same expression: a leaf by its primitive, a box or
 * capped cylinder by its numbers and faces, an operation operand by operand in order. */
static int ft_same(const ft *F, ft_term a, ft_term b)
{
    if (a.neg != b.neg) return 0;
    if (a.node == b.node) return 1;
    const ft_node *x = &F->v[a.node], *y = &F->v[b.node];
    if (x->kind != y->kind) return 0;
    if (x->kind == FT_LEAF) return x->leaf == y->leaf;
    if (x->kind == FT_BOX || x->kind == FT_CAPPED)
        return !memcmp(x->c, y->c, sizeof x->c) && !memcmp(x->h, y->h, sizeof x->h) &&
               !memcmp(x->rot, y->rot, sizeof x->rot) && !memcmp(x->face, y->face, sizeof x->face) &&
               !memcmp(x->fneg, y->fneg, sizeof x->fneg);
    if ((x->kind != FT_AND && x->kind != FT_OR) || x->n != y->n) return 0;
    for (uint32_t k = 0; k < x->n; k++)
        if (!ft_same(F, x->t[k], y->t[k])) return 0;
    return 1;
}

/* The operand of node `and` (an intersection or a union) the same as x (-1: none). */
static int ft_find(const ft *F, uint32_t and, ft_term x)
{
    for (uint32_t m = 0; m < F->v[and].n; m++)
        if (ft_same(F, F->v[and].t[m], x)) return (int)m;
    return -1;
}

/* Whether node u is a union of two or more leaves. */
static int ft_leaves(const ft *F, uint32_t u)
{
    if (F->v[u].kind != FT_OR || F->v[u].n < 2) return 0;
    for (uint32_t k = 0; k < F->v[u].n; k++)
        if (F->v[F->v[u].t[k].node].kind != FT_LEAF) return 0;
    return 1;
}

/* Where term t is X & P, P a primitive or a union of primitives, and X the same as
 * x: the index of X in t (-1: no such term). */
static int ft_factor_term(const ft *F, ft_term t, ft_term x)
{
    if (t.neg || F->v[t.node].kind != FT_AND || F->v[t.node].n != 2) return -1;
    for (int m = 0; m < 2; m++) {
        ft_term p = F->v[t.node].t[1 - m];
        if (ft_same(F, F->v[t.node].t[m], x) &&
            (F->v[p.node].kind == FT_LEAF || (!p.neg && ft_leaves(F, p.node))))
            return m;
    }
    return -1;
}

/* Union i = (X & P) | (X & Q) | R written X & (P | Q) | R (exact for min and max), P
 * and Q primitives or unions of primitives: the operand X common to the most such
 * terms, taken out once.  The GA builds a part cut by a pocket as one term per face
 * group, (S \ A) | (S \ B); factored, the faces meet in one union, S & ~(A & B), that
 * apply_pockets writes as one box.  X is a solid other than a plane (a box, a capped
 * cylinder), or a union of leaves: a plane taken out of the terms would leave a box of
 * the cover without its face (the cover reads a subtree alone).  Larger terms are
 * left alone (InverseCSG's 133: a cylinder taken out of two subtrees of planes left
 * its pocket in no intersection with a curved solid, three half-spaces instead of a
 * box).  Returns 1 when node i was rewritten. */
static int ft_factor(ft *F, uint32_t i)
{
    if (F->v[i].kind != FT_OR || F->v[i].n < 2) return 0;
    uint32_t best = 0, bk = 0, bm = 0;
    for (uint32_t k = 0; k < F->v[i].n; k++) {
        ft_term tk = F->v[i].t[k];
        if (tk.neg || F->v[tk.node].kind != FT_AND || F->v[tk.node].n != 2) continue;
        for (uint32_t m = 0; m < 2; m++) {
            ft_term x = F->v[tk.node].t[m];
            double pn[3], pd;
            ft_kind xk = F->v[x.node].kind;
            if (ft_plane(F, x, pn, &pd) || ((xk == FT_AND || xk == FT_OR) && !ft_leaves(F, x.node)) ||
                ft_factor_term(F, tk, x) < 0)
                continue;
            uint32_t c = 0;
            for (uint32_t j = k + 1; j < F->v[i].n; j++) c += ft_factor_term(F, F->v[i].t[j], x) >= 0;
            if (c > best) best = c, bk = k, bm = m;
        }
    }
    if (!best) return 0;
    ft_term x = F->v[F->v[i].t[bk].node].t[bm];
    uint32_t a = ft_new(F, FT_AND), u = ft_new(F, FT_OR);
    if (F->failed) return 0;
    ft_add(F, a, x.node, x.neg);
    ft_add(F, a, u, 0);
    uint32_t w = 0, n = F->v[i].n;
    for (uint32_t k = 0; k < n && !F->failed; k++) {
        ft_term tk = F->v[i].t[k];
        int m = k < bk ? -1 : ft_factor_term(F, tk, x);
        if (m < 0) {
            F->v[i].t[w++] = tk;
            continue;
        }
        ft_term o = F->v[tk.node].t[1 - m];
        if (F->v[o.node].kind == FT_OR && !o.neg) {
            for (uint32_t q = 0; q < F->v[o.node].n; q++)
                ft_add(F, u, F->v[o.node].t[q].node, F->v[o.node].t[q].neg);
        } else {
            ft_add(F, u, o.node, o.neg);
        }
        if (k == bk) F->v[i].t[w++] = (ft_term){ a, 0 };
    }
    if (F->failed) return 0;
    F->v[i].n = w;
    return 1;
}

/* A half-space h of one union term X & h that is an operand of a union U of another
 * term, Y & U (X, Y primitives, U a union of primitives), is replaced by a copy of U
 * where the model keeps its solid (ft_keeps): X & h grows by X & (U \ h), held by the
 * model already (the notch of two joined spheres, which the GA cuts from one sphere
 * by the notch's face alone).  Then ft_factor takes U out of both terms (both are of
 * its form), and the notch is cut once.  Returns 1 when node i was rewritten. */
static int ft_widen(ft *F, uint32_t i, const ft_check *ck)
{
    if (F->v[i].kind != FT_OR || !ck->cloud) return 0;
    for (uint32_t k = 0; k < F->v[i].n; k++) {
        ft_term tk = F->v[i].t[k];
        if (tk.neg || F->v[tk.node].kind != FT_AND || F->v[tk.node].n != 2) continue;
        for (uint32_t m = 0; m < 2; m++) {
            ft_term h = F->v[tk.node].t[m];
            if (F->v[h.node].kind != FT_LEAF || F->v[F->v[tk.node].t[1 - m].node].kind != FT_LEAF)
                continue;
            for (uint32_t j = 0; j < F->v[i].n; j++) {
                ft_term tj = F->v[i].t[j];
                if (j == k || tj.neg || F->v[tj.node].kind != FT_AND || F->v[tj.node].n != 2) continue;
                for (uint32_t l = 0; l < 2; l++) {
                    ft_term ut = F->v[tj.node].t[l];
                    if (ut.neg || !ft_leaves(F, ut.node) || ft_find(F, ut.node, h) < 0 ||
                        F->v[F->v[tj.node].t[1 - l].node].kind != FT_LEAF || ft_cancelled(ck))
                        continue;
                    F->v[tk.node].t[m] = ut;   /* shared until kept: then copied */
                    if (ft_keeps(F, ck)) {
                        uint32_t c = ft_new(F, FT_OR);
                        for (uint32_t q = 0; q < F->v[ut.node].n && c != FT_NONE; q++) {
                            uint32_t lf = ft_new(F, FT_LEAF);
                            if (lf == FT_NONE) break;
                            F->v[lf].leaf = F->v[F->v[ut.node].t[q].node].leaf;
                            ft_add(F, c, lf, F->v[ut.node].t[q].neg);
                        }
                        if (!F->failed) {
                            F->v[tk.node].t[m] = (ft_term){ c, 0 };
                            return 1;
                        }
                    }
                    F->v[tk.node].t[m] = h;
                }
            }
        }
    }
    return 0;
}

/* A union term Y & h (Y and h primitives) absorbed by another term S & U, S a primitive
 * or a union of primitives holding Y, U a union of primitives: U grows by h, (S & (U |
 * h)) holds Y & h, and Y & h goes, where the model keeps its solid (what S & h adds
 * outside Y lies outside the part).  The GA leaves a face out of a union of cut faces
 * and adds the part of one solid beyond that face back: `(sphere_1 & x_left) |
 * ((sphere_2 | sphere_1) & (4 faces))` is `(sphere_2 | sphere_1) & (5 faces)`, one
 * box cut away (two_spheres_one_cuboid, 20,000 points, seed 1).  Returns 1 when a term
 * went. */
static int ft_absorb(ft *F, uint32_t i, const ft_check *ck)
{
    if (F->v[i].kind != FT_OR || F->v[i].n < 2 || !ck->cloud) return 0;
    for (uint32_t k = 0; k < F->v[i].n; k++) {
        ft_term tk = F->v[i].t[k];
        if (tk.neg || F->v[tk.node].kind != FT_AND || F->v[tk.node].n != 2) continue;
        for (uint32_t m = 0; m < 2; m++) {
            ft_term y = F->v[tk.node].t[1 - m], h = F->v[tk.node].t[m];
            if (y.neg || F->v[y.node].kind != FT_LEAF || F->v[h.node].kind != FT_LEAF) continue;
            for (uint32_t j = 0; j < F->v[i].n; j++) {
                ft_term tj = F->v[i].t[j];
                if (j == k || tj.neg || F->v[tj.node].kind != FT_AND || F->v[tj.node].n != 2) continue;
                for (uint32_t l = 0; l < 2; l++) {
                    ft_term st = F->v[tj.node].t[l], ut = F->v[tj.node].t[1 - l];
                    int holds = ft_same(F, st, y) ||
                                (!st.neg && ft_leaves(F, st.node) && ft_find(F, st.node, y) >= 0);
                    if (!holds || ut.neg || !ft_leaves(F, ut.node) || ft_find(F, ut.node, h) >= 0 ||
                        ft_cancelled(ck))
                        continue;
                    uint32_t c = ft_new(F, FT_OR);
                    for (uint32_t q = 0; q < F->v[ut.node].n && c != FT_NONE; q++)
                        ft_add(F, c, F->v[ut.node].t[q].node, F->v[ut.node].t[q].neg);
                    uint32_t lf = ft_new(F, FT_LEAF);
                    if (F->failed || c == FT_NONE || lf == FT_NONE) return 0;
                    F->v[lf].leaf = F->v[h.node].leaf;
                    ft_add(F, c, lf, h.neg);
                    if (F->failed) return 0;
                    F->v[tj.node].t[1 - l] = (ft_term){ c, 0 };
                    F->v[i].t[k] = F->v[i].t[F->v[i].n - 1];
                    F->v[i].n--;
                    if (ft_keeps(F, ck)) return 1;
                    F->v[i].n++;
                    F->v[i].t[F->v[i].n - 1] = F->v[i].t[k];
                    F->v[i].t[k] = tk;
                    F->v[tj.node].t[1 - l] = ut;
                }
            }
        }
    }
    return 0;
}

static void apply_factor(ft *F, uint32_t i, const ft_check *ck)
{
    if (F->v[i].kind != FT_AND && F->v[i].kind != FT_OR) return;
    for (uint32_t k = 0; k < F->v[i].n; k++) apply_factor(F, F->v[i].t[k].node, ck);
    while (!F->failed && ft_factor(F, i)) {}
    while (!F->failed && ft_widen(F, i, ck) && ft_factor(F, i)) {}
    while (!F->failed && ft_absorb(F, i, ck)) {}
}

/* A copy of the nodes of F (their operand arrays too): a rewrite tried and taken back. */
typedef struct ft_saved {
    ft_node *v;
    uint32_t n;
} ft_saved;

static int ft_save(const ft *F, ft_saved *s)
{
    s->n = F->n;
    s->v = frep_malloc((F->n + 1) * sizeof *s->v);
    if (!s->v) return -1;
    memcpy(s->v, F->v, F->n * sizeof *s->v);
    for (uint32_t k = 0; k < F->n; k++) {
        s->v[k].t = NULL;
        s->v[k].cap = 0;
        if (!F->v[k].n) continue;
        s->v[k].t = frep_malloc(F->v[k].n * sizeof *s->v[k].t);
        if (!s->v[k].t) {
            for (uint32_t m = 0; m < k; m++) frep_free(s->v[m].t);
            frep_free(s->v);
            s->v = NULL;
            return -1;
        }
        memcpy(s->v[k].t, F->v[k].t, F->v[k].n * sizeof *s->v[k].t);
        s->v[k].cap = F->v[k].n;
    }
    return 0;
}

static void ft_saved_free(ft_saved *s)
{
    if (!s->v) return;
    for (uint32_t k = 0; k < s->n; k++) frep_free(s->v[k].t);
    frep_free(s->v);
    s->v = NULL;
}

/* F's nodes replaced by the saved ones (s is consumed). */
static void ft_restore(ft *F, ft_saved *s)
{
    for (uint32_t k = 0; k < F->n; k++) frep_free(F->v[k].t);
    frep_free(F->v);
    F->v = s->v;
    F->n = F->cap = s->n;
    s->v = NULL;
}

static int apply_cover(ft *F, uint32_t i, const ft_check *ck, const evolve_result *r);

/* The rest of apply_cover: its operands, then its operands of planes grouped. */
static int cover_operands(ft *F, uint32_t i, const ft_check *ck, const evolve_result *r)
{
    uint32_t n = F->v[i].n;
    for (uint32_t k = 0; k < n; k++)
        if (apply_cover(F, F->v[i].t[k].node, ck, r)) return -1;
    n = F->v[i].n;
    uint8_t *sel = frep_calloc(n, 1);
    if (!sel) return -1;
    cover C;
    uint32_t ng = 0;
    for (uint32_t k = 0; k < n; k++) {
        memset(&C, 0, sizeof C);
        C.F = F;
        sel[k] = (uint8_t)cv_planes(&C, F->v[i].t[k].node);
        ng += sel[k];
    }
    int rc = 0;
    if (ng >= 2 && ng < n) {
        /* Group the operands that are planes alone. */
        rc = cover_group(F, i, sel, ck, r);
    } else if (ng == n && n >= 3 && n <= COVER_MAX_LEAVE_OUT) {
        for (uint32_t k = 0; k < n && rc == 0; k++) {
            memset(sel, 1, n);
            sel[k] = 0;
            rc = cover_group(F, i, sel, ck, r);
        }
    }
    frep_free(sel);
    return rc < 0 ? -1 : 0;
}

/* The operands of union u added to union `to`, those that are unions themselves by
 * their own operands. */
static void ft_add_flat(ft *F, uint32_t to, uint32_t u)
{
    for (uint32_t k = 0; k < F->v[u].n && !F->failed; k++) {
        ft_term t = F->v[u].t[k];
        if (!t.neg && F->v[t.node].kind == FT_OR) ft_add_flat(F, to, t.node);
        else ft_add(F, to, t.node, t.neg);
    }
}

/* The root intersection i = X & (U1 | ... | Un) spread whole, (X & U1) | ... | (X & Un),
 * X left in every term that needs it (ft_distribute wants X in one term at most): the
 * GA puts faces of the parts below at the root of a stack, where no cover of the whole
 * is found and no Uk is bounded alone; each X & Uk is.  The union taken is the one of
 * most terms, its nested unions flattened into it (the GA nests them pairwise); a
 * term that is an intersection holding a curved solid is flattened too, and the
 * solids are read again (apply_solids), so that a cylinder between X's bottom and its
 * own top face is capped.  Tried against the covers of the tree as it is
 * (cover_operands), and kept when the whole tree then writes fewer solids.  Only
 * where X is planes alone and the root's planes are within the cover's limits
 * (COVER_MAX_PLANES distinct planes, COVER_MAX_TERMS terms): the trial covers the tree
 * twice, and each term holds all of X.  Returns 1 when node i is covered (spread or
 * not), 0 when the spread does not apply, -1 when out of memory. */
static int ft_spread(ft *F, uint32_t i, const ft_check *ck, const evolve_result *r)
{
    if (i != ck->root || F->spreading || !ck->cloud || F->v[i].kind != FT_AND || F->v[i].n < 2) return 0;
    uint32_t o = F->v[i].n, most = 1;
    for (uint32_t k = 0; k < F->v[i].n; k++) {
        ft_term t = F->v[i].t[k];
        if (!t.neg && F->v[t.node].kind == FT_OR && F->v[t.node].n > most) o = k, most = F->v[t.node].n;
    }
    if (o == F->v[i].n || most > COVER_MAX_TERMS) return 0;
    for (uint32_t k = 0; k < F->v[i].n; k++)
        if (k != o && !ft_planar(F, F->v[i].t[k].node)) return 0;
    cover C;
    memset(&C, 0, sizeof C);
    C.F = F;
    C.curved_ok = 1;
    if (!cv_planes(&C, i)) return 0;
    uint8_t *seen = frep_calloc(F->nprims + 1, 1);
    ft_saved plain = { 0 }, before = { 0 };
    int rc = -1;
    F->spreading = 1;
    if (!seen || ft_save(F, &before) || cover_operands(F, i, ck, r) || ft_save(F, &plain)) goto done;
    unsigned c0 = ft_count(F, ck->root, seen);
    ft_restore(F, &before);
    uint32_t flat = ft_new(F, FT_OR);
    if (flat == FT_NONE) goto done;
    ft_add_flat(F, flat, F->v[i].t[o].node);
    if (F->failed) goto done;
    rc = 1;
    if (F->v[flat].n > COVER_MAX_TERMS) {
        ft_restore(F, &plain);
        goto done;
    }
    rc = -1;
    F->v[i].t[o].node = flat;
    ft_term ot = F->v[i].t[o];
    uint32_t nu = F->v[ot.node].n;
    if (ft_spread_terms(F, i, o, SPREAD_FLAT_CURVED) == FT_NONE) goto done;
    /* X dropped from each term where the model keeps its solid without it */
    uint32_t need = 0;
    for (uint32_t k = 0; k < nu; k++) {
        ft_term a = F->v[i].t[k];
        F->v[i].t[k] = F->v[ot.node].t[k];
        if (!ft_keeps(F, ck)) F->v[i].t[k] = a, need++;
    }
    /* X needed by no term is a no-op at the root: that is no spread */
    unsigned c1 = c0;
    if (need) {
        if (apply_cover(F, i, ck, r)) goto done;
        apply_solids(F, i, ck);
        if (F->failed) goto done;
        memset(seen, 0, F->nprims + 1);
        c1 = ft_count(F, ck->root, seen);
    }
    if (c1 >= c0 || !ft_keeps(F, ck)) ft_restore(F, &plain);
    rc = 1;
done:
    F->spreading = 0;
    ft_saved_free(&before);
    ft_saved_free(&plain);
    frep_free(seen);
    if (rc < 0) F->failed = 1;
    return rc;
}

/* The cover of every subtree of planes, largest first; in an operation of planes and
 * other solids (a box stack minus a bore), of its operands of planes grouped; in an
 * operation of planes alone that no cover writes whole (one of its solids has a face
 * direction no fitted plane gives, so that no frame holds it), of all its operands but
 * one, each left out in turn (up to COVER_MAX_LEAVE_OUT operands); and at the root,
 * spread whole (ft_spread). */
static int apply_cover(ft *F, uint32_t i, const ft_check *ck, const evolve_result *r)
{
    if (F->v[i].kind != FT_AND && F->v[i].kind != FT_OR) return 0;
    int rc = cv_run(F, i, ck, r);
    if (rc) return rc < 0 ? -1 : 0;
    if (ft_distribute(F, i, ck)) {
        apply_solids(F, i, ck);
        return F->failed ? -1 : apply_cover(F, i, ck, r);
    }
    if (F->failed) return -1;
    rc = ft_spread(F, i, ck, r);
    if (rc) return rc < 0 ? -1 : 0;
    return cover_operands(F, i, ck, r);
}

/* ---- parts: a model of parts apart, each covered alone ---------------------------------- */

/* Nearest neighbours each cloud point is linked to, when nearer than the gap (ft_parts). */
#define PARTS_KNN 12
/* Clusters of linked points ft_parts merges by their boxes: more, and the cloud is too
 * sparse for its gap (work bound: the merge compares every pair of boxes). */
#define PARTS_MAX_PIECES 256

/* The parts of the cloud: its points linked to those of their PARTS_KNN nearest within
 * CANON_PARTS_GAP of the diagonal, and clusters whose boxes meet merged (a hollow
 * part's inner faces lie in its outer box).  Writes the parts' boxes, grown by the gap
 * (a face's edge lies up to a point spacing beyond its points), into lo[], hi[] and
 * returns their number: 0 when fewer than 2 or more than CANON_PARTS_MAX, -1 when out
 * of memory. */
static int ft_parts(const ft_check *ck, const evolve_result *r, double lo[][3], double hi[][3])
{
    const frep_cloud *cl = ck->cloud;
    size_t n = cl->n;
    double gap = CANON_PARTS_GAP * r->diag;
    if (n < 2 || n > UINT32_MAX) return 0;
    kd_tree *t = kd_build(n, cl->x, cl->y, cl->z);
    uint32_t *up = frep_malloc(n * sizeof *up);
    double (*box)[6] = frep_malloc(PARTS_MAX_PIECES * sizeof *box);
    int np = -1;
    if (!t || !up || !box) goto done;
    for (size_t i = 0; i < n; i++) up[i] = (uint32_t)i;
    for (size_t i = 0; i < n; i++) {
        uint32_t idx[PARTS_KNN];
        double d2[PARTS_KNN], q[3] = { cl->x[i], cl->y[i], cl->z[i] };
        size_t m = kd_knn(t, q, PARTS_KNN, idx, d2);
        for (size_t j = 0; j < m && d2[j] <= gap * gap; j++) frep_uf_join(up, (uint32_t)i, idx[j]);
    }
    /* each point's cluster number, tagged, in up[]: a point's parent comes before it
     * (frep_uf_join) and is numbered already */
    np = 0;
    for (size_t i = 0; i < n; i++) {
        if (up[i] != i) {
            up[i] = up[up[i]];
            continue;
        }
        if (np == PARTS_MAX_PIECES) {
            np = 0;
            goto done;
        }
        up[i] = (uint32_t)np++ | 0x80000000u;
    }
    for (int p = 0; p < np; p++)
        for (int k = 0; k < 3; k++) box[p][k] = INFINITY, box[p][3 + k] = -INFINITY;
    for (size_t i = 0; i < n; i++) {
        double *b = box[up[i] & 0x7fffffffu], q[3] = { cl->x[i], cl->y[i], cl->z[i] };
        for (int k = 0; k < 3; k++) b[k] = fmin(b[k], q[k]), b[3 + k] = fmax(b[3 + k], q[k]);
    }
    for (int merged = 1; merged;) {
        merged = 0;
        for (int a = 0; a < np; a++)
            for (int b = a + 1; b < np; b++) {
                int meet = 1;
                for (int k = 0; k < 3 && meet; k++)
                    meet = box[a][k] <= box[b][3 + k] && box[b][k] <= box[a][3 + k];
                if (!meet) continue;
                for (int k = 0; k < 3; k++)
                    box[a][k] = fmin(box[a][k], box[b][k]), box[a][3 + k] = fmax(box[a][3 + k], box[b][3 + k]);
                if (b != --np) memcpy(box[b], box[np], sizeof box[b]);   /* the last takes b's place */
                merged = 1;
                b = a;
            }
    }
    if (np < 2 || np > CANON_PARTS_MAX) np = 0;
    for (int a = 0; a < np; a++)
        for (int k = 0; k < 3; k++) lo[a][k] = box[a][k] - gap, hi[a][k] = box[a][3 + k] + gap;
done:
    kd_free(t);
    frep_free(up);
    frep_free(box);
    return np;
}

/* The sign over the box c +- h of the linear function of value f at c and gradient g:
 * 1 where it is positive all over, -1 negative all over, else 0. */
static int linear_sign(double f, const double g[3], const double h[3])
{
    double e = fabs(g[0]) * h[0] + fabs(g[1]) * h[1] + fabs(g[2]) * h[2];
    return f - e > 0 ? 1 : f + e < 0 ? -1 : 0;
}

/* Term t restricted to the box c +- h (world axes): 1 when its solid holds all of the
 * box, -1 when none of it, else 0 and *out the term with the operands that hold all or
 * none of the box left out (new operations; leaves and solids shared).  A half-space is
 * bounded over the box exactly (it is linear), a box by its faces' half-spaces and its
 * extent along the world axes, a capped cylinder by its caps; other solids are kept. */
static int ft_restrict(ft *F, ft_term t, const double c[3], const double h[3], ft_term *out)
{
    int s = t.neg ? -1 : 1;
    *out = t;
    const ft_node *v = &F->v[t.node];
    double g[3];
    switch (v->kind) {
    case FT_LEAF:
        if (v->leaf >= F->nprims || F->q[v->leaf].type != PRIM_PLANE) return 0;
        return s * linear_sign(prim_eval(&F->q[v->leaf], c, g), g, h);
    case FT_BOX: {
        /* the intersection of its faces' half-spaces h_k -+ R_k . (x - c_box) */
        double R[3][3];
        box_frame(v->rot, R);
        for (int w = 0; w < 3; w++) {   /* apart along a world axis */
            double reach = 0;
            for (int k = 0; k < 3; k++) reach += fabs(R[w][k]) * v->h[k];
            if (fabs(v->c[w] - c[w]) > reach + h[w]) return -s;
        }
        int all = 1;
        for (int k = 0; k < 6; k++) {
            double fk = v->h[k / 2];
            for (int w = 0; w < 3; w++) {
                g[w] = (k & 1 ? 1 : -1) * R[w][k / 2];
                fk += g[w] * (c[w] - v->c[w]);
            }
            int sg = linear_sign(fk, g, h);
            if (sg < 0) return -s;
            all &= sg > 0;
        }
        return all ? s : 0;
    }
    case FT_CAPPED:
        for (int k = 1; k < 3; k++) {
            double fk = prim_eval(&F->q[v->face[k]], c, g);
            if (linear_sign(v->fneg[k] ? -fk : fk, g, h) < 0) return -s;
        }
        return 0;
    case FT_AND:
    case FT_OR: {
        int all = v->kind == FT_AND ? 1 : -1;   /* an operand that changes nothing */
        uint32_t m = ft_new(F, v->kind);
        if (m == FT_NONE) return 0;
        for (uint32_t k = 0; k < F->v[t.node].n; k++) {
            ft_term o;
            int w = ft_restrict(F, F->v[t.node].t[k], c, h, &o);
            if (F->failed) return 0;
            if (w == -all) return -all * s;
            if (w == 0) ft_add(F, m, o.node, o.neg);
        }
        if (F->failed) return 0;
        if (F->v[m].n == 0) return all * s;
        *out = F->v[m].n == 1 ? F->v[m].t[0] : (ft_term){ m, 0 };
        out->neg ^= t.neg;
        return 0;
    }
    }
    return 0;
}

/* The operand `clip` of an intersection under node i left out where the model keeps its
 * solid (and bounded if it was) without it.  Returns whether it is gone everywhere. */
static int ft_unclip(ft *F, uint32_t i, uint32_t clip, const ft_check *ck, const evolve_result *r, int bounded)
{
    ft_node *v = &F->v[i];
    if (v->kind != FT_AND && v->kind != FT_OR) return 1;
    int gone = 1;
    for (uint32_t k = 0; k < F->v[i].n; k++) {
        ft_term a = F->v[i].t[k];
        if (a.node != clip) {
            gone &= ft_unclip(F, a.node, clip, ck, r, bounded);
            continue;
        }
        if (F->v[i].kind != FT_AND || F->v[i].n < 2) return 0;
        F->v[i].t[k] = F->v[i].t[--F->v[i].n];   /* the last operand takes its place */
        if (ft_keeps(F, ck) && (!bounded || ft_bounded(F, ck->root, r))) {
            k--;   /* look at slot k again (unsigned: wraps to the loop's k++) */
            continue;
        }
        F->v[i].t[F->v[i].n++] = F->v[i].t[k];
        F->v[i].t[k] = a;
        gone = 0;
    }
    return gone;
}

/* The root of a model of parts apart (ft_parts: a stack here, a plate there) written
 * as the union of the root restricted to each part's box (ft_restrict), the box kept
 * as a clip, and each such term covered alone (apply_cover): a cover of the whole has
 * more planes and frames than its limits allow, or the GA's tree mixes the parts at
 * the root.  The clips are then left out where the model keeps its solid without
 * them.  Kept when no clip stays, the model keeps its solid and the whole tree writes
 * fewer solids; not tried where the tree holds no half-space (the covers write
 * half-spaces as boxes).  Returns -1 when out of memory, else 0. */
static int apply_parts(ft *F, uint32_t root, const ft_check *ck, const evolve_result *r)
{
    if (!ck->cloud || (F->v[root].kind != FT_AND && F->v[root].kind != FT_OR) || ft_cancelled(ck)) return 0;
    uint8_t *seen = frep_calloc(F->nprims + 1, 1);
    if (!seen) return -1;
    unsigned c0 = ft_count(F, root, seen);
    /* the covers write half-spaces as boxes: a tree without one gains nothing */
    int planes = 0;
    for (size_t j = 0; j < F->nprims && !planes; j++) planes = seen[j] && F->q[j].type == PRIM_PLANE;
    double lo[CANON_PARTS_MAX][3], hi[CANON_PARTS_MAX][3];
    int np = planes ? ft_parts(ck, r, lo, hi) : 0;
    ft_saved before = { 0 };
    if (np <= 0 || ft_save(F, &before)) {
        frep_free(seen);
        return np <= 0 ? np : -1;
    }
    int bounded = ft_bounded(F, root, r), keep = 0;
    uint32_t u = ft_new(F, FT_OR), clip[CANON_PARTS_MAX];
    static const double axes[3][3] = { { 1, 0, 0 }, { 0, 1, 0 }, { 0, 0, 1 } };
    static const uint32_t free6[6] = { FT_NONE, FT_NONE, FT_NONE, FT_NONE, FT_NONE, FT_NONE };
    static const uint8_t neg6[6] = { 0 };
    for (int p = 0; p < np && !F->failed; p++) {
        double c[3], h[3];
        for (int k = 0; k < 3; k++) c[k] = (lo[p][k] + hi[p][k]) / 2, h[k] = (hi[p][k] - lo[p][k]) / 2;
        ft_term o;
        int w = ft_restrict(F, (ft_term){ root, 0 }, c, h, &o);
        clip[p] = ft_box_node(F, axes, lo[p], hi[p], free6, neg6);
        if (F->failed || w != 0 || clip[p] == FT_NONE) goto done;
        box_set_planes(F, clip[p], axes, lo[p], hi[p]);
        uint32_t a = ft_new(F, FT_AND);
        if (a == FT_NONE) goto done;
        if (!o.neg && F->v[o.node].kind == FT_AND)
            for (uint32_t k = 0; k < F->v[o.node].n; k++) ft_add(F, a, F->v[o.node].t[k].node, F->v[o.node].t[k].neg);
        else
            ft_add(F, a, o.node, o.neg);
        ft_add(F, a, clip[p], 0);
        ft_add(F, u, a, 0);
    }
    if (F->failed) goto done;
    ft_node saved = F->v[root];
    F->v[root] = F->v[u];
    F->v[u] = saved;
    if (!ft_keeps(F, ck)) goto done;
    for (int p = 0; p < np && !F->failed; p++) {
        uint32_t a = F->v[root].t[p].node;
        apply_solids(F, a, ck);
        if (F->failed || apply_cover(F, a, ck, r)) goto done;
    }
    int gone = 1;
    for (int p = 0; p < np; p++) gone &= ft_unclip(F, root, clip[p], ck, r, bounded);
    memset(seen, 0, F->nprims + 1);
    keep = gone && !F->failed && ft_count(F, root, seen) < c0 && ft_keeps(F, ck);
done:
    if (!keep && !F->failed) ft_restore(F, &before);
    ft_saved_free(&before);
    frep_free(seen);
    return F->failed ? -1 : 0;
}

/* ---- pockets: unions of planes as boxes cut away -------------------------------------- */

/* An operand of an intersection that is a union of planes, X & (h1 | ... | hn), is X less
 * the intersection of their complements, X \ (~h1 & ... & ~hn): a pocket or a slot cut
 * into X.  When the complements bound a box on one frame (at most two of them on each of
 * three orthogonal directions, opposite ones on the same direction), the pocket is
 * written as that box, its faces without a plane free (beyond the part, where the cover
 * puts them, cv_frames); a subtraction of an intersection of planes the same way.  n
 * half-spaces become one solid; kept when the model keeps its solid (ft_keeps, and
 * bounded if it was). */

/* Whether every box operand of intersection `and` (one at least) lies in the half-space
 * n.x <= d, to within tol. */
static int boxes_within(const ft *F, uint32_t and, const double n[3], double d, double tol)
{
    int boxes = 0;
    for (uint32_t k = 0; k < F->v[and].n; k++) {
        ft_term t = F->v[and].t[k];
        /* through operations of one operand (a union the cover left of one box) */
        while ((F->v[t.node].kind == FT_AND || F->v[t.node].kind == FT_OR) && F->v[t.node].n == 1) {
            uint8_t neg = t.neg;
            t = F->v[t.node].t[0];
            t.neg ^= neg;
        }
        const ft_node *b = &F->v[t.node];
        if (b->kind != FT_BOX || t.neg) continue;
        double R[3][3], m = vec3_dot(n, b->c);
        box_frame(b->rot, R);
        for (int e = 0; e < 3; e++)
            m += fabs(n[0] * R[0][e] + n[1] * R[1][e] + n[2] * R[2][e]) * b->h[e];
        if (m > d + tol) return 0;
        boxes++;
    }
    return boxes > 0;
}

/* Term *t of an operand of intersection `and` read as one plane there: a plane, or an
 * intersection of planes all but one of which hold the intersection's boxes (the GA's
 * `h1 | (face & h2)` beside a box of that face is `h1 | h2` inside it).  0 when not. */
static int ft_context_plane(const ft *F, uint32_t and, double tol, ft_term *t)
{
    const ft_node *v = &F->v[t->node];
    if (v->kind == FT_LEAF) return 1;
    if (v->kind != FT_AND || t->neg) return 0;
    ft_term one = { FT_NONE, 0 };
    for (uint32_t k = 0; k < v->n; k++) {
        double n[3], d;
        if (!ft_plane(F, v->t[k], n, &d)) return 0;
        if (boxes_within(F, and, n, d, tol)) continue;
        if (one.node != FT_NONE) return 0;
        one = v->t[k];
    }
    if (one.node == FT_NONE) return 0;
    *t = one;
    return 1;
}

/* The half-spaces of the pocket that operand `o` of intersection `and` cuts away into
 * n[], d[] (n.x <= d each) and their terms into pt[] (neg: the face complemented);
 * returns their number, 0 when the operand is no union of planes (or a subtraction of
 * an intersection of planes) of POCKET_MIN_FACES to 6 operands. */
static int pocket_faces(const ft *F, uint32_t and, double tol, ft_term o, double n[6][3], double d[6],
                        ft_term pt[6])
{
    const ft_node *v = &F->v[o.node];
    if (!((v->kind == FT_OR && !o.neg) || (v->kind == FT_AND && o.neg))) return 0;
    if (v->n < POCKET_MIN_FACES || v->n > 6) return 0;
    for (uint32_t k = 0; k < v->n; k++) {
        pt[k] = v->t[k];
        if (and != FT_NONE && !ft_context_plane(F, and, tol, &pt[k])) return 0;
        if (v->kind == FT_OR) pt[k].neg = !pt[k].neg;
        if (!ft_plane(F, pt[k], n[k], &d[k])) return 0;
    }
    return (int)v->n;
}

/* The box node of the m half-spaces n[], d[] (terms pt[]), their normals within tol of
 * one square frame's axes, each fitted face where its plane crosses the axis through
 * the point `at` (NULL: the origin), free faces beyond the cloud's box grown by
 * COVER_FREE_GROWTH; FT_NONE when they bound no box on one frame. */
static uint32_t pocket_box(ft *F, int m, const double n[6][3], const double d[6], const ft_term pt[6],
                           double tol, const double *at, const ft_check *ck, const evolve_result *r)
{
    double u[3][3];
    int nd = 0, axis[6], side[6];
    double ct = cos(tol), st = sin(tol);
    for (int k = 0; k < m; k++) {
        int a = -1;
        for (int e = 0; e < nd && a < 0; e++)
            if (fabs(vec3_dot(n[k], u[e])) >= ct) a = e;
        if (a < 0) {
            if (nd == 3) return FT_NONE;
            for (int e = 0; e < nd; e++)
                if (fabs(vec3_dot(n[k], u[e])) > st) return FT_NONE;
            memcpy(u[nd], n[k], sizeof u[nd]);
            a = nd++;
        }
        axis[k] = a;
        side[k] = vec3_dot(n[k], u[a]) > 0;
        for (int e = 0; e < k; e++)
            if (axis[e] == a && side[e] == side[k]) return FT_NONE;
    }
    if (nd < 2) return FT_NONE;
    /* Orthonormal axes: the first direction, the second made orthogonal to it, their
     * cross product turned to the third where there is one. */
    double t = vec3_dot(u[1], u[0]), w3[3];
    for (int w = 0; w < 3; w++) u[1][w] -= t * u[0][w];
    if (vec3_normalize(u[1])) return FT_NONE;
    vec3_cross(u[0], u[1], w3);
    if (nd == 3 && vec3_dot(w3, u[2]) < 0)
        for (int w = 0; w < 3; w++) w3[w] = -w3[w];
    memcpy(u[2], w3, sizeof w3);
    double lo[3], hi[3];
    uint32_t face[6];
    uint8_t fneg[6], fit[6] = { 0 };
    for (int k = 0; k < 6; k++) face[k] = FT_NONE, fneg[k] = 0;
    for (int k = 0; k < m; k++) {
        int a = axis[k];
        double c = vec3_dot(n[k], u[a]), dk = d[k];
        int f = side[k] ? 2 * a : 2 * a + 1;
        if (at) {
            /* the plane's place on the axis through `at`, not through the origin: its
             * normal may be off the square frame's axis by up to tol */
            double along = vec3_dot(at, u[a]), p[3];
            for (int w = 0; w < 3; w++) p[w] = at[w] - along * u[a][w];
            dk -= vec3_dot(n[k], p);
        }
        if (side[k]) hi[a] = dk / c;
        else lo[a] = -dk / -c;
        face[f] = F->v[pt[k].node].leaf;
        fneg[f] = pt[k].neg;
        fit[f] = 1;
    }
    for (int a = 0; a < 3; a++) {
        double c = vec3_dot(r->obb.c, u[a]), e = 0;
        for (int k = 0; k < 3; k++) e += fabs(vec3_dot(r->obb.ax[k], u[a])) * r->obb.h[k];
        e = COVER_FREE_GROWTH * e + ck->gtol;
        if (!fit[2 * a + 1]) lo[a] = fmin(c - e, fit[2 * a] ? hi[a] - e : c - e);
        if (!fit[2 * a]) hi[a] = fmax(c + e, fit[2 * a + 1] ? lo[a] + e : c + e);
        if (!(hi[a] > lo[a])) return FT_NONE;
    }
    uint32_t b = ft_box_node(F, u, lo, hi, face, fneg);
    if (b != FT_NONE) box_set_planes(F, b, u, lo, hi);
    return b;
}

/* Every operand of intersection i that is a pocket, as its box cut away, when i holds
 * a curved solid (a sphere, a cylinder): a part of planes alone is the cover's, which
 * reads its cuts with the part's own faces, and whose limits leave half-spaces. */
static void ft_pockets(ft *F, uint32_t i, const ft_check *ck, const evolve_result *r, int bounded)
{
    if (ft_planar(F, i)) return;
    for (uint32_t k = 0; k < F->v[i].n && !F->failed && !ft_cancelled(ck); k++) {
        double n[6][3], d[6];
        ft_term pt[6], o = F->v[i].t[k];
        int m = pocket_faces(F, FT_NONE, 0, o, n, d, pt);
        if (!m) continue;
        uint32_t b = pocket_box(F, m, n, d, pt, ck->tol, NULL, ck, r);
        if (b == FT_NONE) continue;
        F->v[i].t[k].node = b;
        F->v[i].t[k].neg = 1;
        if (!ft_keeps(F, ck) || (bounded && !ft_bounded(F, ck->root, r))) F->v[i].t[k] = o;
    }
}

/* Over the check points (every ck->stride-th of the cloud): the mean |f| of the model
 * (returned, as ft_mean), the number within eps of its surface (*near), marked in in[]
 * when in is not NULL, and of those marked in was[] (when not NULL) the number no
 * longer within eps (*lost).  One pass: each point is evaluated once. */
static double ft_fit(const ft *F, const ft_check *ck, double eps, uint8_t *in, const uint8_t *was,
                     size_t *near, size_t *lost)
{
    double s = 0;
    size_t m = 0, k = 0, gone = 0;
    for (size_t i = 0; i < ck->cloud->n; i += ck->stride, m++) {
        double x[3] = { ck->cloud->x[i], ck->cloud->y[i], ck->cloud->z[i] }, f = ft_eval(F, ck->root, x);
        int e = fabs(f) <= eps;
        s += fabs(f);
        if (in) in[m] = (uint8_t)e;
        if (was) gone += (size_t)(was[m] && !e);
        k += (size_t)e;
    }
    *near = k;
    if (lost) *lost = gone;
    return m ? s / (double)m : 0;
}

/* Cuts of intersection i (its complemented operands: boxes cut away, and any other
 * solid) dropped where the model explains the cloud no worse without them (the mean
 * distance, or every check point within eps_d still is) and differs from the tree
 * before the rewrites at no more than COVER_SLIVER of the inside grid points: a cut of
 * the faces of the solid below that trims a box's buried face, placed too deep, where
 * a corner of that face shows (six_cuboids' top cube); a sliver a spurious primitive
 * cut from a face (six_cuboids at 20,000 points, seed 3: a torus of radius 16 on a top
 * face, less that face's plane).  Also, whatever the grid says, where without them the
 * model explains (within eps_d) every check point it did and CANON_DROP_GAIN of them
 * more: the GA's tree cut away scanned material (three_cuboids_one_cylinder at seed 5:
 * a cut on a face of the other box's frame took a corner of the lower box whose faces
 * hold 2% of the points).  With `net` (apply_net_drops), only where without them the
 * model explains more of the cloud net of the points it loses: a smaller mean distance
 * and CANON_DROP_GAIN of the check points more within eps_d, whatever the grid says (a
 * cut of the cube below that took most of a turned cube's sides, and hid its buried
 * face's sliver below the cube: nine_cuboids at 20,000 points, seed 3). */
static void ft_drop_cuts(ft *F, uint32_t i, const ft_check *ck, const evolve_result *r, int bounded, int net)
{
    size_t nin = 0;
    for (size_t g = 0; g < ck->ng; g++) nin += ck->ref[g] > ck->gtol;
    size_t most = (size_t)(COVER_SLIVER * (double)nin), total = (ck->cloud->n + ck->stride - 1) / ck->stride;
    uint8_t *was = frep_malloc(total + 1);
    if (!was) {
        F->failed = 1;
        return;
    }
    for (uint32_t k = 0; k < F->v[i].n && !F->failed && !ft_cancelled(ck);) {
        ft_term t = F->v[i].t[k];
        if (!t.neg || F->v[i].n < 2) {
            k++;
            continue;
        }
        size_t nwas, nnow, lost;
        double mean = ft_fit(F, ck, r->eps_d, was, NULL, &nwas, NULL);
        ft_node *v = &F->v[i];
        memmove(&v->t[k], &v->t[k + 1], (v->n - k - 1) * sizeof *v->t);
        v->n--;
        double now = ft_fit(F, ck, r->eps_d, NULL, was, &nnow, &lost);
        /* CANON_DROP_GAIN of the check points more within eps_d, net of those lost */
        int gain = nnow > nwas && (double)(nnow - nwas) >= CANON_DROP_GAIN * (double)total;
        /* no worse: the mean distance, or no check point leaves the surface */
        int worse = now > mean && lost;
        int drop = net ? gain && now < mean
                       : !worse && ((gain && !lost) || ft_grid_diffs(F, ck, most) <= most);
        if (drop && (!bounded || ft_bounded(F, ck->root, r)))
            continue;
        v = &F->v[i];
        memmove(&v->t[k + 1], &v->t[k], (v->n - k) * sizeof *v->t);
        v->t[k] = t;
        v->n++;
        k++;
    }
    frep_free(was);
}

static void apply_pockets(ft *F, uint32_t i, const ft_check *ck, const evolve_result *r, int bounded)
{
    ft_node *v = &F->v[i];
    if (v->kind != FT_AND && v->kind != FT_OR) return;
    uint32_t n = v->n;
    for (uint32_t k = 0; k < n; k++) apply_pockets(F, F->v[i].t[k].node, ck, r, bounded);
    if (F->v[i].kind == FT_AND) {
        ft_pockets(F, i, ck, r, bounded);
        ft_drop_cuts(F, i, ck, r, bounded, 0);
    }
}

/* Plane j, which the tree does not use, as a face of the model: printed to the
 * quanta of a fitted plane (keep_fitted) and named plane_N after the planes named. */
static void ft_adopt_plane(ft *F, uint32_t j, const evolve_result *r)
{
    canon_prim *c = &F->c[j];
    keep_fitted(r, &F->q[j], c);
    c->polarity = 2;
    char base[32];
    unsigned taken = 0;   /* plane_1 .. plane_taken are names already */
    for (size_t i = 0; i < F->nprims; i++) {
        snprintf(base, sizeof base, "plane_%u", taken + 1);
        if (strcmp(F->c[i].name, base) == 0) taken++, i = (size_t)-1;
    }
    plane_base(&c->q, &taken, base, sizeof base);
    set_name(F->c, j, F->nprims, base);
}

/* Term k of intersection i set to the box cut (axes u, extents lo, hi, faces face,
 * fneg) with free face f at `at`; returns the node it held before (trial_end puts it
 * back), or FT_NONE when that is no box (the term unchanged). */
static uint32_t trial_begin(ft *F, uint32_t i, uint32_t k, int f, double at, const double u[3][3],
                            const double lo[3], const double hi[3], const uint32_t face[6],
                            const uint8_t fneg[6])
{
    double nlo[3], nhi[3];
    memcpy(nlo, lo, sizeof nlo);
    memcpy(nhi, hi, sizeof nhi);
    if (f % 2 == 0) nhi[f / 2] = at;
    else nlo[f / 2] = at;
    uint32_t b = F->v[i].t[k].node, nb = ft_box_node(F, u, nlo, nhi, face, fneg);
    if (nb == FT_NONE) return FT_NONE;
    F->v[i].t[k].node = nb;
    return b;
}

/* The term back to node b, the trial box's node given back when it was the last made
 * (nothing refers to it). */
static void trial_end(ft *F, uint32_t i, uint32_t k, uint32_t b)
{
    uint32_t nb = F->v[i].t[k].node;
    F->v[i].t[k].node = b;
    if (nb == F->n - 1) F->n--;
}

/* The sum of min(f^2, eps^2) of the model over the cloud points idx[0..n) with free
 * face f of the box cut that is term k of intersection i (axes u, extents lo, hi, faces
 * face, fneg) at `at` (trial_begin); NAN when that is no box. */
static double scan_sum(ft *F, uint32_t i, uint32_t k, int f, double at, const double u[3][3],
                       const double lo[3], const double hi[3], const uint32_t face[6],
                       const uint8_t fneg[6], const size_t *idx, size_t n, const ft_check *ck, double e)
{
    const frep_cloud *cl = ck->cloud;
    uint32_t b = trial_begin(F, i, k, f, at, u, lo, hi, face, fneg);
    if (b == FT_NONE) return NAN;
    double sum = 0;
    for (size_t m = 0; m < n; m++) {
        double x[3] = { cl->x[idx[m]], cl->y[idx[m]], cl->z[idx[m]] }, v = ft_eval(F, ck->root, x);
        sum += fmin(v * v, e * e);
    }
    trial_end(F, i, k, b);
    return sum;
}

/* The share of the part of free face f at `at` that the model shows (its value within
 * eps / 2 of 0 at the point) over which a cloud point of idx[0..n) lies near:
 * the face's rectangle (the box's extents lo, hi across it) sampled on a
 * CANON_SCAN_GRID square grid.  1 when the model shows none of it. */
static double face_covered(ft *F, uint32_t i, uint32_t k, int f, double at, const double u[3][3],
                           const double lo[3], const double hi[3], const uint32_t face[6],
                           const uint8_t fneg[6], const size_t *idx, size_t n, const ft_check *ck,
                           double e)
{
    const frep_cloud *cl = ck->cloud;
    int a = f / 2, b1 = (a + 1) % 3, b2 = (a + 2) % 3;
    /* near: within 2 eps, or twice the points' spacing where they are sparser (the
     * median distance to the nearest of CANON_SCAN_GRID of them, evenly spread) */
    double nn[CANON_SCAN_GRID], reach = 2 * e;
    size_t ns = n < CANON_SCAN_GRID ? n : CANON_SCAN_GRID;
    for (size_t q = 0; q < ns; q++) {
        size_t p = idx[canon_spread(q, n, CANON_SCAN_GRID)];
        nn[q] = HUGE_VAL;
        for (size_t m = 0; m < n; m++) {
            double d[3] = { cl->x[idx[m]] - cl->x[p], cl->y[idx[m]] - cl->y[p], cl->z[idx[m]] - cl->z[p] };
            double l = vec3_dot(d, d);
            if (idx[m] != p && l < nn[q]) nn[q] = l;
        }
    }
    if (ns) {
        for (size_t q = 1; q < ns; q++)   /* in order (a few: insertion) */
            for (size_t t = q; t > 0 && nn[t] < nn[t - 1]; t--) {
                double sw = nn[t];
                nn[t] = nn[t - 1];
                nn[t - 1] = sw;
            }
        reach = fmax(reach, 2 * sqrt(nn[ns / 2]));
    }
    /* and at least half a grid cell's diagonal: each grid point stands for its cell */
    reach = fmax(reach, 0.5 * hypot(hi[b1] - lo[b1], hi[b2] - lo[b2]) / CANON_SCAN_GRID);
    uint32_t b = trial_begin(F, i, k, f, at, u, lo, hi, face, fneg);
    if (b == FT_NONE) return 0;
    size_t shown = 0, near = 0;
    for (int gi = 0; gi < CANON_SCAN_GRID; gi++)
        for (int gj = 0; gj < CANON_SCAN_GRID; gj++) {
            double s1 = lo[b1] + (hi[b1] - lo[b1]) * (gi + 0.5) / CANON_SCAN_GRID;
            double s2 = lo[b2] + (hi[b2] - lo[b2]) * (gj + 0.5) / CANON_SCAN_GRID, g[3];
            for (int w = 0; w < 3; w++) g[w] = at * u[a][w] + s1 * u[b1][w] + s2 * u[b2][w];
            if (!(fabs(ft_eval(F, ck->root, g)) <= e / 2)) continue;
            shown++;
            for (size_t m = 0; m < n; m++) {
                double d[3] = { cl->x[idx[m]] - g[0], cl->y[idx[m]] - g[1], cl->z[idx[m]] - g[2] };
                if (vec3_dot(d, d) <= reach * reach) {
                    near++;
                    break;
                }
            }
        }
    trial_end(F, i, k, b);
    return shown ? (double)near / (double)shown : 1;
}

/* Is x within grow of the box of axes u (rows) and extents lo, hi along them? */
static int in_box(const double u[3][3], const double lo[3], const double hi[3], double grow,
                  const double x[3])
{
    for (int w = 0; w < 3; w++) {
        double t = vec3_dot(u[w], x);
        if (!(t >= lo[w] - grow && t <= hi[w] + grow)) return 0;
    }
    return 1;
}

/* The place along u[a] for free face f of the box cut (axes u, extents lo, hi, faces
 * face, fneg) that is term k of intersection i where the model fits the cloud's points
 * around the cut best: the least sum of min(f^2, eps_d^2) over the points in the box
 * grown by 2 eps_d (scan_sum), the face tried every eps_d from the opposite face to the
 * points' end, then every eps_d / CANON_SCAN_STEPS about the best.  NAN when no place
 * fits CANON_SCAN_GAIN points' worth (eps_d^2 each) better than the face where it is,
 * when the best is within 2 eps_d of the points' end (a pocket open to the outside: no
 * point says where a lid is not), when fewer than CANON_SCAN_SUPPORT points lie on the
 * face there or points are near less than CANON_SCAN_COVERED of the part of it the
 * model shows (face_covered: material the cut would leave where no point is; the sum
 * counts the points only where they are, not where they are not), or out of memory. */
static double face_scan(ft *F, uint32_t i, uint32_t k, int f, const double u[3][3], const double lo[3],
                        const double hi[3], const uint32_t face[6], const uint8_t fneg[6],
                        const ft_check *ck, const evolve_result *r)
{
    const frep_cloud *cl = ck->cloud;
    int a = f / 2;
    double dir = f % 2 == 0 ? 1 : -1;   /* outward along u[a] */
    double e = r->eps_d, grow = 2 * e, end = -HUGE_VAL;   /* end: the points' reach, times dir */
    size_t n = 0, cap = 0, *idx = NULL;
    for (size_t p = 0; p < cl->n; p++) {
        double x[3] = { cl->x[p], cl->y[p], cl->z[p] };
        if (!in_box(u, lo, hi, grow, x)) continue;
        if (n == cap) {
            size_t nc = cap ? 2 * cap : 1024;
            size_t *ni = frep_realloc(idx, nc * sizeof *ni);
            if (!ni) {
                frep_free(idx);
                return NAN;
            }
            idx = ni, cap = nc;
        }
        idx[n++] = p;
        end = fmax(end, dir * vec3_dot(u[a], x));
    }
    /* in outward coordinates s = dir * (u[a] . x): from the opposite face to the end */
    double from = dir > 0 ? lo[a] : -hi[a], to = fmin(dir > 0 ? hi[a] : -lo[a], end + e);
    double here = 0, best = NAN, best_s;
    for (size_t m = 0; m < n; m++) {
        double x[3] = { cl->x[idx[m]], cl->y[idx[m]], cl->z[idx[m]] }, v = ft_eval(F, ck->root, x);
        here += fmin(v * v, e * e);
    }
    best_s = here - CANON_SCAN_GAIN * e * e;
    for (int pass = 0; pass < 2 && n; pass++) {
        double step = pass ? e / CANON_SCAN_STEPS : e, s0 = pass ? best - e : from + e;
        double s1 = pass ? fmin(best + e, to) : to;
        if (pass && isnan(best)) break;
        for (double sc = s0; sc < s1 && !F->failed; sc += step) {
            double sum = scan_sum(F, i, k, f, dir * sc, u, lo, hi, face, fneg, idx, n, ck, e);
            if (sum < best_s) best_s = sum, best = sc;
        }
    }
    /* the face's own points: on its plane, inside its rectangle, normals within
     * CANON_SCAN_NORMAL_DEG of it */
    size_t on = 0;
    double ca = cos(CANON_SCAN_NORMAL_DEG * FREP_PI / 180);
    for (size_t m = 0; m < n && !isnan(best); m++) {
        size_t p = idx[m];
        double x[3] = { cl->x[p], cl->y[p], cl->z[p] };
        if (fabs(dir * vec3_dot(u[a], x) - best) > e) continue;
        int in = 1;
        for (int w = 0; w < 3 && in; w++) {
            double t = vec3_dot(u[w], x);
            in = w == a || (t >= lo[w] && t <= hi[w]);
        }
        if (in && cl->has_normals) {
            double nx[3] = { cl->nx[p], cl->ny[p], cl->nz[p] };
            in = fabs(vec3_dot(nx, u[a])) >= ca;
        }
        on += (size_t)in;
    }

    double covered = isnan(best) ? 0 : face_covered(F, i, k, f, dir * best, u, lo, hi, face, fneg, idx, n, ck, e);
    frep_free(idx);
    /* at the points' end the face is as good as free: beyond the part */
    if (isnan(best) || best > end - 2 * e || on < CANON_SCAN_SUPPORT || covered < CANON_SCAN_COVERED)
        return NAN;
    return dir * best;
}

/* Free face f of the box cut that is term k of intersection i moved to each fitted
 * plane along its direction within the cut's extent, the tree's or one it left out;
 * the one where the model explains most check points within eps_d is kept where it
 * explains no fewer than before and the mean distance is smaller: a cut the cover ran
 * through a wall (its face free, beyond the part) stops at the wall's fitted face, a
 * pocket's cut at its smallest faces (ft_adopt_plane).  1 when the cut changed. */
static int ft_tighten_face(ft *F, uint32_t i, uint32_t k, int f, const ft_check *ck, const evolve_result *r)
{
    uint32_t b = F->v[i].t[k].node;
    double u[3][3], lo[3], hi[3];
    for (int a = 0; a < 3; a++) {
        memcpy(u[a], F->v[b].fpl[2 * a], sizeof u[a]);
        hi[a] = F->v[b].fpl[2 * a][3];
        lo[a] = -F->v[b].fpl[2 * a + 1][3];
    }
    uint32_t face[6];
    uint8_t fneg[6];
    memcpy(face, F->v[b].face, sizeof face);
    memcpy(fneg, F->v[b].fneg, sizeof fneg);
    int a = f / 2, up = f % 2 == 0;
    size_t nwas, best_near = 0;
    double mean = ft_fit(F, ck, r->eps_d, NULL, NULL, &nwas, NULL), best_mean = mean;
    uint32_t best = FT_NONE, best_j = FT_NONE;
    double best_lo[3], best_hi[3];
    uint8_t best_neg = 0;
    for (size_t j = 0; j < F->nprims && !F->failed; j++) {
        /* a plane of the list: one the tree uses (canonical, named), or a fitted face
         * it left out (a pocket's smallest faces, 10-30 points) that explains more */
        if (F->q[j].type != PRIM_PLANE) continue;
        double c = vec3_dot(F->q[j].p, u[a]);
        if (fabs(c) < cos(ck->tol)) continue;
        /* the half-space u . x <= at (an upper face) or >= at (a lower one) */
        double at = F->q[j].r / c;
        if (!(at > lo[a] + ck->gtol && at < hi[a] - ck->gtol)) continue;
        double nlo[3], nhi[3];
        memcpy(nlo, lo, sizeof nlo);
        memcpy(nhi, hi, sizeof nhi);
        uint32_t nface[6];
        uint8_t nneg[6];
        memcpy(nface, face, sizeof nface);
        memcpy(nneg, fneg, sizeof nneg);
        if (up) nhi[a] = at;
        else nlo[a] = at;
        nface[f] = (uint32_t)j;
        nneg[f] = (uint8_t)(up ? c < 0 : c > 0);
        uint32_t nb = ft_box_node(F, u, nlo, nhi, nface, nneg);
        if (nb == FT_NONE) continue;
        box_set_planes(F, nb, u, nlo, nhi);
        F->v[i].t[k].node = nb;
        size_t nnow;
        double now = ft_fit(F, ck, r->eps_d, NULL, NULL, &nnow, NULL);
        F->v[i].t[k].node = b;
        if (nnow > best_near || (nnow == best_near && now < best_mean)) {
            best = nb, best_j = (uint32_t)j, best_near = nnow, best_mean = now;
            best_neg = nneg[f];
            memcpy(best_lo, nlo, sizeof best_lo);
            memcpy(best_hi, nhi, sizeof best_hi);
        }
    }
    if (best == FT_NONE || best_near < nwas || !(best_mean < mean)) return 0;
    if (!F->c[best_j].name[0]) {
        /* the box again, with the face's quanta */
        ft_adopt_plane(F, best_j, r);
        face[f] = best_j;
        fneg[f] = best_neg;
        best = ft_box_node(F, u, best_lo, best_hi, face, fneg);
        if (best == FT_NONE) return 0;
        box_set_planes(F, best, u, best_lo, best_hi);
    }
    memcpy(F->v[best].ends, F->v[b].ends, sizeof F->v[best].ends);
    F->v[best].ends[f] = 0;
    F->v[i].t[k].node = best;
    return 1;
}

/* How far along u[a] (the largest u[a].x, or the smallest when !up) the cloud's points
 * on fitted face g of the box of axes u and extents lo, hi reach: within eps_d of its
 * plane, their normals (when the cloud has them) within alpha of its, inside the box
 * across the third axis.  NAN when no point is. */
static double face_reach(const ft *F, uint32_t g, const double u[3][3], const double lo[3],
                         const double hi[3], int a, int up, const ft_check *ck, const evolve_result *r)
{
    const frep_cloud *cl = ck->cloud;
    const prim *q = &F->q[g];
    double ca = cos(r->alpha), best = NAN;
    for (size_t i = 0; i < cl->n; i++) {
        double x[3] = { cl->x[i], cl->y[i], cl->z[i] };
        if (fabs(vec3_dot(q->p, x) - q->r) > r->eps_d) continue;
        if (cl->has_normals) {
            double nx[3] = { cl->nx[i], cl->ny[i], cl->nz[i] };
            if (fabs(vec3_dot(q->p, nx)) < ca) continue;
        }
        int in = 1;
        for (int e = 0; e < 3 && in; e++) {
            double t = vec3_dot(u[e], x);
            /* g's own axis: the plane test above; axis a: the box's extent */
            if (fabs(vec3_dot(u[e], q->p)) <= 0.5) in = t >= lo[e] - ck->gtol && t <= hi[e] + ck->gtol;
        }
        if (!in) continue;
        double t = vec3_dot(u[a], x);
        if (isnan(best) || (up ? t > best : t < best)) best = t;
    }
    return best;
}

/* Operand k of intersection i, a union of planes its boxes read as a pocket (pocket_faces
 * with ft_context_plane), written as that pocket's box cut away, each free face first
 * where the points of the box's fitted faces end (face_reach), then WEDGE_ROUNDS times
 * in turn where the points around the cut fit best (face_scan, from the fitted face
 * opposite out to the free place); put back unless the model then explains more check
 * points, the mean distance no larger: the GA's cut of a pocket whose far faces hold
 * too few points to be fitted runs on through the part (three_cuboids at 0.5% noise:
 * 12-23 points a face).  1 when the operand changed. */
static int ft_wedge(ft *F, uint32_t i, uint32_t k, const ft_check *ck, const evolve_result *r)
{
    double n[6][3], d[6];
    ft_term pt[6], o = F->v[i].t[k];
    int m = pocket_faces(F, i, ck->gtol, o, n, d, pt);
    if (!m) return 0;
    /* the pocket's middle: of its faces' inlier patches */
    double mid[3] = { 0, 0, 0 };
    int np = 0;
    for (int j = 0; j < m; j++) {
        const prim *q = &F->q[F->v[pt[j].node].leaf];
        if (!q->has_obb) continue;
        for (int w = 0; w < 3; w++) mid[w] += q->obb_c[w];
        np++;
    }
    for (int w = 0; w < 3; w++) mid[w] /= np ? np : 1;
    uint32_t b = pocket_box(F, m, n, d, pt, CANON_WEDGE_DEG * FREP_PI / 180, np ? mid : NULL, ck, r);
    if (b == FT_NONE) return 0;
    const ft_node *v = &F->v[b];
    double u[3][3], lo[3], hi[3], lo0[3], hi0[3];
    for (int a = 0; a < 3; a++) {
        memcpy(u[a], v->fpl[2 * a], sizeof u[a]);
        hi0[a] = hi[a] = v->fpl[2 * a][3];
        lo0[a] = lo[a] = -v->fpl[2 * a + 1][3];
    }
    uint32_t face[6];
    uint8_t fneg[6], ends[6] = { 0 };
    memcpy(face, v->face, sizeof face);
    memcpy(fneg, v->fneg, sizeof fneg);
    for (int f = 0; f < 6; f++) {
        if (face[f] != FT_NONE) continue;
        int a = f / 2, up = f % 2 == 0;
        for (int g = 0; g < 6; g++) {
            if (g / 2 == a || face[g] == FT_NONE) continue;
            double t = face_reach(F, face[g], u, lo0, hi0, a, up, ck, r);
            if (isnan(t) || !(t > lo0[a] && t < hi0[a])) continue;
            if (!ends[f] || (up ? t > hi[a] : t < lo[a])) {
                if (up) hi[a] = t;
                else lo[a] = t;
            }
            ends[f] = 1;
        }
    }
    size_t nwas, nnow = 0;
    double mean = ft_fit(F, ck, r->eps_d, NULL, NULL, &nwas, NULL), now = mean;
    int placed = 0;
    for (int round = 0; round < WEDGE_ROUNDS && !F->failed; round++)
        for (int f = 0; f < 6 && !F->failed; f++) {
            if (face[f] != FT_NONE) continue;
            int a = f / 2, up = f % 2 == 0;
            /* from the opposite face out to the free place, the others where they are */
            double slo[3], shi[3];
            memcpy(slo, lo, sizeof slo);
            memcpy(shi, hi, sizeof shi);
            if (up) shi[a] = hi0[a];
            else slo[a] = lo0[a];
            uint32_t sb = ft_box_node(F, u, slo, shi, face, fneg);
            if (sb == FT_NONE) break;
            box_set_planes(F, sb, u, slo, shi);
            F->v[i].t[k] = (ft_term){ sb, 1 };
            double t = face_scan(F, i, k, f, u, slo, shi, face, fneg, ck, r);
            if (up) hi[a] = isnan(t) ? hi0[a] : t;
            else lo[a] = isnan(t) ? lo0[a] : t;
            ends[f] = (uint8_t)!isnan(t);
            placed |= ends[f];
        }
    uint32_t nb = placed ? ft_box_node(F, u, lo, hi, face, fneg) : FT_NONE;
    if (nb != FT_NONE) {
        box_set_planes(F, nb, u, lo, hi);
        memcpy(F->v[nb].ends, ends, sizeof ends);
        F->v[i].t[k] = (ft_term){ nb, 1 };
        now = ft_fit(F, ck, r->eps_d, NULL, NULL, &nnow, NULL);
    }
    /* The box's frame is square where the faces were not quite: kept where it explains
     * more check points and the mean distance is no larger. */
    int keep = nb != FT_NONE && nnow > nwas && now <= mean;
    if (!keep) F->v[i].t[k] = o;
    return keep;
}

/* Whether the model is the same without term k of union u at every check grid point
 * away from the surface (at[] the model's values now) and explains the cloud no worse
 * (no fewer check points within eps_d, the mean distance within CANON_MAX_CHANGE of
 * the diagonal, the writer's measure of no change): a term that another's rewrite made
 * redundant. */
static int ft_redundant(ft *F, uint32_t u, uint32_t k, const ft_check *ck, const evolve_result *r,
                        const double *at)
{
    size_t nwas, nnow;
    double mean = ft_fit(F, ck, r->eps_d, NULL, NULL, &nwas, NULL);
    ft_term t = F->v[u].t[k];
    uint32_t none = ft_new(F, FT_OR);
    if (none == FT_NONE) return 0;
    F->v[u].t[k] = (ft_term){ .node = none, .neg = 0 };
    int same = 1;
    for (size_t g = 0; g < ck->ng && same; g++)
        if (fabs(at[g]) > ck->gtol) same = (ft_eval(F, ck->root, &ck->g[3 * g]) > 0) == (at[g] > 0);
    double now = same ? ft_fit(F, ck, r->eps_d, NULL, NULL, &nnow, NULL) : 0;
    F->v[u].t[k] = t;
    return same && nnow >= nwas && now <= mean + CANON_MAX_CHANGE * r->diag;
}

/* Every box cut of the tree with free faces tightened (ft_tighten_face), then the union
 * terms the model no longer needs dropped (ft_redundant). */
static void apply_tighten(ft *F, uint32_t i, const ft_check *ck, const evolve_result *r, int *changed)
{
    ft_node *v = &F->v[i];
    if (v->kind != FT_AND && v->kind != FT_OR) return;
    uint32_t n = v->n;
    for (uint32_t k = 0; k < n; k++) apply_tighten(F, F->v[i].t[k].node, ck, r, changed);
    if (F->v[i].kind != FT_AND) return;
    for (uint32_t k = 0; k < F->v[i].n && !F->failed; k++) {
        ft_term t = F->v[i].t[k];
        if (!t.neg || F->v[t.node].kind != FT_BOX) {
            *changed |= ft_wedge(F, i, k, ck, r);
            continue;
        }
        for (int f = 0; f < 6; f++)
            if (F->v[F->v[i].t[k].node].face[f] == FT_NONE) *changed |= ft_tighten_face(F, i, k, f, ck, r);
    }
}

/* Every union term of the tree that ft_redundant finds redundant dropped (at: scratch
 * for the model's values at the check grid, ck->ng of them). */
static void apply_redundant(ft *F, uint32_t i, const ft_check *ck, const evolve_result *r, double *at)
{
    ft_node *v = &F->v[i];
    if (v->kind != FT_AND && v->kind != FT_OR) return;
    uint32_t n = v->n;
    for (uint32_t k = 0; k < n; k++) apply_redundant(F, F->v[i].t[k].node, ck, r, at);
    if (F->v[i].kind != FT_OR) return;
    int stale = 1;   /* at[] is the model's only until a term goes */
    for (uint32_t k = 0; k < F->v[i].n && F->v[i].n > 1 && !F->failed;) {
        for (size_t g = 0; stale && g < ck->ng; g++) at[g] = ft_eval(F, ck->root, &ck->g[3 * g]);
        stale = ft_redundant(F, i, k, ck, r, at);
        if (!stale) {
            k++;
            continue;
        }
        memmove(&F->v[i].t[k], &F->v[i].t[k + 1], (F->v[i].n - k - 1) * sizeof *F->v[i].t);
        F->v[i].n--;
    }
}

/* The cuts' free faces tightened, then the terms that made redundant dropped. */
static void apply_cut_faces(ft *F, uint32_t root, const ft_check *ck, const evolve_result *r)
{
    int changed = 0;
    apply_tighten(F, root, ck, r, &changed);
    if (!changed || F->failed) return;
    double *at = frep_malloc(ck->ng * sizeof *at);
    if (!at) {
        F->failed = 1;
        return;
    }
    apply_redundant(F, root, ck, r, at);
    frep_free(at);
}

/* ft_drop_cuts' net drops over the tree, after every other rewrite: they pass over the
 * grid, and run last so that the grid's budget for slivers (COVER_SLIVER, counted
 * against the tree before the rewrites) goes to the other drops first. */
static void apply_net_drops(ft *F, uint32_t i, const ft_check *ck, const evolve_result *r, int bounded)
{
    ft_node *v = &F->v[i];
    if (v->kind != FT_AND && v->kind != FT_OR) return;
    uint32_t n = v->n;
    for (uint32_t k = 0; k < n; k++) apply_net_drops(F, F->v[i].t[k].node, ck, r, bounded);
    if (F->v[i].kind == FT_AND) ft_drop_cuts(F, i, ck, r, bounded, 1);
}

/* ---- joints: a sphere that closes cylinders ------------------------------------------
 * A frame's rails are infinite cylinders to the GA, and where two meet at a corner they
 * cross: the corner is square where the part has a sphere of the rails' radius (mount:
 * 0.32 beyond it, 2.5% of the diagonal, at all four corners).  Segmentation finds the
 * sphere, but its points are few (mount's four hold 1.5% of them) and the tree that
 * leaves it out scores nearly as well.  Beyond the rails' ends the part is the sphere
 * alone, so the corner is cut there: tree \ (box \ sphere), the box reaching from the
 * centre outward along each rail's axis (away from the rail's points) and across the
 * others, kept where the model then explains more of the cloud's points in and around
 * the box, at a mean distance there no larger (the whole cloud's check points hold a
 * few of a corner's: mount's gain 1-4 of 4,096, where 37-60 of the 500-650 points
 * about the corner are).  The same closes a single rail's rounded end. */

/* Sphere j, in canonical form cs, as a solid of the model named sphere_N after the
 * spheres named. */
static void ft_adopt_sphere(ft *F, uint32_t j, const canon_prim *cs)
{
    canon_prim *c = &F->c[j];
    *c = *cs;
    c->polarity = 1;
    char base[32];
    unsigned taken = 0;
    for (size_t i = 0; i < F->nprims; i++) {
        snprintf(base, sizeof base, "sphere_%u", taken + 1);
        if (strcmp(F->c[i].name, base) == 0) taken++, i = (size_t)-1;
    }
    snprintf(base, sizeof base, "sphere_%u", taken + 1);
    set_name(F->c, j, F->nprims, base);
}

/* The outward axes (away from each rail's points) of the cylinders of the tree that
 * sphere q closes, into e (at most 2, at right angles); their number, 0 for none. */
static int joint_axes(const ft *F, const prim *q, double e[2][3])
{
    int n = 0;
    for (size_t g = 0; g < F->nprims; g++) {
        const prim *cy = &F->q[g];
        if (cy->type != PRIM_CYLINDER || F->c[g].polarity != 1 || !cy->has_obb ||
            fabs(cy->r - q->r) > JOINT_RADIUS * q->r)
            continue;
        double v[3], a[3];
        vec3_sub(q->p, cy->p, v);
        memcpy(a, cy->a, sizeof a);
        if (vec3_normalize(a)) continue;
        double h = vec3_dot(v, a), w[3];
        for (int k = 0; k < 3; k++) w[k] = v[k] - h * a[k];
        if (vec3_len(w) > JOINT_AXIS * q->r) continue;
        /* the rail's points lie on one side of the centre */
        double s = (cy->obb_c[0] - q->p[0]) * a[0] + (cy->obb_c[1] - q->p[1]) * a[1] +
                   (cy->obb_c[2] - q->p[2]) * a[2];
        if (fabs(s) < q->r) continue;
        for (int k = 0; k < 3; k++) a[k] = s > 0 ? -a[k] : a[k];
        if (n == 1 && fabs(vec3_dot(a, e[0])) > sin(JOINT_ORTHO_DEG * FREP_PI / 180)) {
            if (vec3_dot(a, e[0]) > 0) continue;   /* the same rail's other piece */
            return 0;                               /* a rail through the centre: no end */
        }
        if (n == 2) return 0;
        memcpy(e[n++], a, sizeof a);
    }
    return n;
}

/* The mean |f| of the model over every cloud point within eps of the box of axes u and
 * extents lo, hi (where a cut of that box can change the model; returned) and the
 * number of them within eps of its surface (*near). */
static double box_fit(const ft *F, const ft_check *ck, const double u[3][3], const double lo[3],
                      const double hi[3], double eps, size_t *near)
{
    const frep_cloud *cl = ck->cloud;
    double s = 0;
    size_t m = 0, k = 0;
    for (size_t i = 0; i < cl->n; i++) {
        double x[3] = { cl->x[i], cl->y[i], cl->z[i] };
        if (!in_box(u, lo, hi, eps, x)) continue;
        double f = ft_eval(F, ck->root, x);
        s += fabs(f);
        k += (size_t)(fabs(f) <= eps);
        m++;
    }
    *near = k;
    return m ? s / (double)m : 0;
}

/* Sphere j cut into the model at the end of the rails it closes (see above) and named;
 * 1 when it was.  The root is an intersection (apply_joints). */
static int ft_joint(ft *F, uint32_t root, uint32_t j, const ft_check *ck, const evolve_result *r)
{
    prim q0 = F->q[j];
    const prim *q = &F->q[j];
    double e[2][3], u[3][3], lo[3], hi[3], reach = JOINT_REACH * q->r;
    int n = joint_axes(F, q, e);
    if (!n) return 0;
    /* the sphere rounded as the tree's primitives are (canon_prims), the box to its
     * quantum */
    canon_prim cs;
    memset(&cs, 0, sizeof cs);
    canonical(r, q, 0, &cs);
    round_prim(&cs);
    memcpy(u[0], e[0], sizeof u[0]);
    if (n == 2) {
        double t = vec3_dot(e[1], u[0]);
        for (int k = 0; k < 3; k++) u[1][k] = e[1][k] - t * u[0][k];
        if (vec3_normalize(u[1])) return 0;
    } else {
        vec3_basis(u[0], u[1], u[2]);
    }
    vec3_cross(u[0], u[1], u[2]);
    for (int a = 0; a < 3; a++) {
        double c = vec3_dot(u[a], q->p);
        lo[a] = a < n ? c : c - reach;
        hi[a] = c + reach;
    }
    uint32_t face[6] = { FT_NONE, FT_NONE, FT_NONE, FT_NONE, FT_NONE, FT_NONE };
    uint8_t fneg[6] = { 0 };
    size_t nwas, nnow;
    double mean = box_fit(F, ck, u, lo, hi, r->eps_d, &nwas);
    uint32_t n0 = F->n, b = ft_box_node(F, u, lo, hi, face, fneg);
    uint32_t leaf = ft_new(F, FT_LEAF), cut = ft_new(F, FT_AND);
    if (b == FT_NONE || leaf == FT_NONE || cut == FT_NONE) return 0;
    box_set_planes(F, b, u, lo, hi);
    ft_node *v = &F->v[b];
    v->qpos = cs.qpos;
    for (int k = 0; k < 3; k++) {
        char buf[PRIM_NUM_BUF];
        prim_format_number(buf, v->c[k], v->qpos);
        v->c[k] = strtod(buf, NULL);
        prim_format_number(buf, v->h[k], v->qpos);
        v->h[k] = strtod(buf, NULL);
    }
    F->v[leaf].leaf = j;
    F->q[j] = evaluated(&cs);
    ft_add(F, cut, b, 0);
    ft_add(F, cut, leaf, 1);
    ft_add(F, root, cut, 1);
    if (F->failed) return 0;
    double now = box_fit(F, ck, u, lo, hi, r->eps_d, &nnow);
    if (nnow > nwas && now <= mean) {
        ft_adopt_sphere(F, j, &cs);
        return 1;
    }
    F->q[j] = q0;
    F->v[root].n--;
    frep_free(F->v[cut].t);
    F->n = n0;
    return 0;
}

/* Every sphere the tree leaves out tried as a joint (ft_joint), in list order.  A root
 * that is no intersection becomes one of a single operand first (written the same). */
static void apply_joints(ft *F, uint32_t root, const ft_check *ck, const evolve_result *r)
{
    uint32_t body = FT_NONE;   /* the root's operand when it was made an intersection */
    for (uint32_t j = 0; j < F->nprims && !F->failed && !ft_cancelled(ck); j++) {
        if (F->q[j].type != PRIM_SPHERE || F->c[j].polarity || !F->q[j].support) continue;
        if (F->v[root].kind != FT_AND) {
            body = ft_new(F, FT_AND);
            if (body == FT_NONE) return;
            F->v[body] = F->v[root];
            memset(&F->v[root], 0, sizeof F->v[root]);
            F->v[root].kind = FT_AND;
            ft_add(F, root, body, 0);
            if (F->failed) return;
        }
        ft_joint(F, root, j, ck, r);
    }
    /* no joint: the root as it was */
    ft_node *v = &F->v[root];
    if (!F->failed && body != FT_NONE && v->n == 1 && body == F->n - 1) {
        ft_term *t = v->t;
        *v = F->v[body];
        frep_free(t);
        F->n--;
    }
}

/* Primitive c's statement, `name = call;  -- comment`, the list's heading first (head
 * counts the statements written). */
static void write_prim(FILE *f, const canon_prim *c, int hyperfun, int *head)
{
    if (!(*head)++)
        fprintf(f, "    -- primitives, numbers rounded to what their inliers support (+- the "
                   "standard error of a position)\n");
    fprintf(f, "    %s = ", c->name);
    if (hyperfun) canon_write_hyperfun(f, c);
    else canon_write_call(f, c);
    fputc(';', f);
    canon_write_comment(f, c);
    fputc('\n', f);
}

int canon_write_body(FILE *f, const evolve_result *r, const prim *prims, const canon_prim *c,
                     size_t nprims, const frep_cloud *cloud, int exact, int hyperfun,
                     const char *base_call, const volatile sig_atomic_t *cancel)
{
    const gp_tree *t = &r->tree;
    if (!t->len) return 0;
    ft F;
    memset(&F, 0, sizeof F);
    F.c = frep_malloc((nprims + 1) * sizeof *F.c);
    F.nprims = nprims;
    F.q = frep_calloc(nprims + 1, sizeof *F.q);
    const char **names = frep_calloc(nprims + 1, sizeof *names);
    unsigned *uses = NULL;
    uint32_t *order = NULL;
    uint8_t *seen = NULL, *pol = NULL, *dup = NULL;
    double *grid = NULL, *ref = NULL;
    fw w;
    memset(&w, 0, sizeof w);
    int rc = -1;
    if (!F.c || !F.q || !names) goto done;
    memcpy(F.c, c, nprims * sizeof *F.c);
    c = F.c;
    for (size_t j = 0; j < nprims; j++) {
        F.q[j] = c[j].name[0] ? evaluated(&c[j]) : prims[j];
        names[j] = c[j].name;
    }
    names[nprims] = "base_part";
    uint32_t root = ft_build(&F, t->code, t->len - 1);
    if (F.failed) goto done;
    ft_check ck;
    memset(&ck, 0, sizeof ck);
    ck.root = root;
    ck.tol = 1e-9;
    ck.cancel = cancel;
    if (cloud && cloud->n && !exact) {
        ck.cloud = cloud;
        ck.stride = cloud->n > CANON_CHECK_POINTS ? cloud->n / CANON_CHECK_POINTS : 1;
        ck.limit = mean_dist(r, prims, nprims, cloud, ck.stride) + CANON_MAX_CHANGE * r->diag;
        ck.tol = 2 * CANON_MAX_SNAP;
        grid = frep_malloc(3 * CANON_GRID * CANON_GRID * CANON_GRID * sizeof *grid);
        ref = frep_malloc(CANON_GRID * CANON_GRID * CANON_GRID * sizeof *ref);
        if (!grid || !ref) goto done;
        /* Cell centres of the cloud's oriented box grown by 10%. */
        size_t ng = 0;
        for (int a = 0; a < CANON_GRID; a++)
            for (int b = 0; b < CANON_GRID; b++)
                for (int e = 0; e < CANON_GRID; e++, ng++) {
                    double s3[3] = { a, b, e };
                    for (int d = 0; d < 3; d++) {
                        double x = r->obb.c[d];
                        for (int k = 0; k < 3; k++)
                            x += r->obb.ax[k][d] * 1.1 * r->obb.h[k] * (2 * (s3[k] + 0.5) / CANON_GRID - 1);
                        grid[3 * ng + d] = x;
                    }
                    ref[ng] = ft_eval(&F, root, &grid[3 * ng]);
                }
        ck.g = grid;
        ck.ref = ref;
        ck.ng = ng;
        ck.gtol = CANON_GRID_TOL * r->diag;
    }
    if (!exact) apply_solids(&F, root, &ck);
    if (!F.failed && !exact) apply_factor(&F, root, &ck);
    if (!F.failed && ck.cloud && apply_cover(&F, root, &ck, r)) F.failed = 1;
    if (!F.failed && ck.cloud && apply_parts(&F, root, &ck, r)) F.failed = 1;
    if (!F.failed && ck.cloud) apply_pockets(&F, root, &ck, r, ft_bounded(&F, root, r));
    if (!F.failed && ck.cloud) apply_net_drops(&F, root, &ck, r, ft_bounded(&F, root, r));
    if (!F.failed && ck.cloud) apply_cut_faces(&F, root, &ck, r);
    if (!F.failed && ck.cloud) apply_joints(&F, root, &ck, r);
    if (F.failed) goto done;
    uses = frep_calloc(nprims + 1, sizeof *uses);
    order = frep_calloc(F.n, sizeof *order);
    seen = frep_calloc(F.n, 1);
    pol = frep_calloc(F.n, 1);
    w.stmt = frep_calloc(F.n, sizeof *w.stmt);
    if (!uses || !order || !seen || !pol || !w.stmt) goto done;
    uint32_t no = 0;
    fw_walk(&F, root, 0, uses, order, &no, seen, pol);
    /* Names and the count of solids; a solid the tree holds twice (one capped cylinder
     * in two terms that are not factored) is named, counted and written once. */
    unsigned nbox = 0, ncap = 0, kinds[PRIM__COUNT + 1] = { 0 };
    dup = frep_calloc(no + 1, 1);
    if (!dup) goto done;
    for (uint32_t k = 0; k < no; k++) {
        ft_node *v = &F.v[order[k]];
        for (uint32_t e = 0; e < k && !dup[k]; e++)
            if (ft_same(&F, (ft_term){ order[e], 0 }, (ft_term){ order[k], 0 })) {
                memcpy(v->name, F.v[order[e]].name, sizeof v->name);
                dup[k] = 1;
            }
        if (dup[k]) continue;
        if (v->kind == FT_BOX) {
            snprintf(v->name, sizeof v->name, pol[order[k]] == 2 ? "box_cut_%u" : "box_%u", ++nbox);
        } else {
            ncap++;
            snprintf(v->name, sizeof v->name, "%s%s", c[v->face[0]].name, uses[v->face[0]] ? "_capped" : "");
        }
    }
    for (size_t j = 0; j < nprims; j++)
        if (uses[j]) kinds[prims[j].type]++;
    unsigned solids = nbox + ncap;
    for (int k = 0; k < PRIM__COUNT; k++) solids += kinds[k];
    fprintf(f, "    -- %u solids: %u box%s, %u cylinder%s (%u capped), %u sphere%s, %u cone%s, "
               "%u tor%s, %u half-space%s\n",
            solids, nbox, nbox == 1 ? "" : "es", ncap + kinds[PRIM_CYLINDER],
            ncap + kinds[PRIM_CYLINDER] == 1 ? "" : "s", ncap, kinds[PRIM_SPHERE],
            kinds[PRIM_SPHERE] == 1 ? "" : "s", kinds[PRIM_CONE], kinds[PRIM_CONE] == 1 ? "" : "s",
            kinds[PRIM_TORUS], kinds[PRIM_TORUS] == 1 ? "us" : "i", kinds[PRIM_PLANE],
            kinds[PRIM_PLANE] == 1 ? "" : "s");
    /* The primitives the tree still names, in the order it first uses them. */
    int head = 0;
    for (uint32_t pc = 0; pc < t->len; pc++) {
        size_t j = t->code[pc].arg;
        if (t->code[pc].op != FREP_OP_PRIM || j >= nprims || !uses[j] || !c[j].name[0]) continue;
        int first = 1;
        for (uint32_t e = 0; e < pc && first; e++)
            first = !(t->code[e].op == FREP_OP_PRIM && t->code[e].arg == j);
        if (!first) continue;
        write_prim(f, &c[j], hyperfun, &head);
    }
    /* ... then those a rewrite took in (a joint's sphere), in list order. */
    for (size_t j = 0; j < nprims; j++) {
        int in_code = 0;
        for (uint32_t pc = 0; pc < t->len && !in_code; pc++)
            in_code = t->code[pc].op == FREP_OP_PRIM && t->code[pc].arg == j;
        if (in_code || !uses[j] || !c[j].name[0]) continue;
        write_prim(f, &c[j], hyperfun, &head);
    }
    if (base_call && uses[nprims])
        fprintf(f, "    base_part = %s;  -- the model given with --residual\n", base_call);
    if (no)
        fprintf(f, "    -- solids of the fitted faces (numbers rounded as their faces'; a face "
                   "moves with the box's centre and half size)\n");
    for (uint32_t k = 0; k < no; k++)
        if (!dup[k]) write_feature(f, &F, &F.v[order[k]], names, hyperfun);
    fprintf(f, "    -- the construction tree: | union, & intersection, \\ subtraction, ~ complement\n");
    w.f = f;
    w.F = &F;
    w.names = names;
    w.large = t->len > 11;
    fw_root(&w, root);
    rc = ferror(f) ? -1 : 0;
done:
    ft_free(&F);
    frep_free(F.c);
    frep_free(F.q);
    frep_free(names);
    frep_free(uses);
    frep_free(order);
    frep_free(seen);
    frep_free(pol);
    frep_free(dup);
    frep_free(w.stmt);
    frep_free(grid);
    frep_free(ref);
    return rc;
}
