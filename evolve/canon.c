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
#include "tree.h"
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

/* Role names, numbered in the order the tree first uses each primitive. */
static void names(const gp_tree *t, canon_prim *o, size_t n)
{
    static const char *const side[3][2] = { { "left", "right" }, { "front", "back" },
                                            { "bottom", "top" } };
    unsigned count[PRIM__COUNT + 1] = { 0 }, bores = 0, cav = 0;
    for (uint32_t pc = 0; pc < t->len; pc++) {
        if (t->code[pc].op != FREP_OP_PRIM || t->code[pc].arg >= n) continue;
        size_t j = t->code[pc].arg;
        if (o[j].name[0]) continue;
        const prim *q = &o[j].q;
        char base[32];
        int removed = o[j].polarity == 2;
        switch (q->type) {
        case PRIM_PLANE: {
            int ax = -1;
            for (int k = 0; k < 3; k++)
                if (q->p[k] == 1 || q->p[k] == -1) ax = k;
            if (ax >= 0)
                snprintf(base, sizeof base, "plane_%c_%s", "xyz"[ax], side[ax][q->p[ax] > 0]);
            else
                snprintf(base, sizeof base, "plane_%u", ++count[PRIM_PLANE]);
            break;
        }
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

/* The tree's sign at x (min/max: R-functions have the same sign); leaves beyond the
 * list (the --residual model) count as everywhere inside, so such trees look unbounded. */
static double tree_at(const frep_insn *code, uint32_t end, const prim *prims, size_t n,
                      const double *x)
{
    const frep_insn *in = &code[end];
    int k = tree_nin(in);
    if (k == 0) return in->arg < n ? prim_eval(&prims[in->arg], x, NULL) : 1;
    if (k == 1) return -tree_at(code, end - 1, prims, n, x);
    uint32_t l0, l1, r0;
    tree_operands(code, end, &l0, &l1, &r0);
    double a = tree_at(code, l1, prims, n, x), b = tree_at(code, end - 1, prims, n, x);
    char op = op_char(in->op);
    return op == '|' ? fmax(a, b) : op == '&' ? fmin(a, b) : fmin(a, -b);
}

int canon_tree_bounded(const evolve_result *r, const prim *prims, size_t nprims)
{
    const gp_tree *t = &r->tree;
    if (!t->len) return 0;
    /* Fibonacci points on spheres of 2 and 8 diagonals around the cloud. */
    for (int s = 0; s < 2; s++) {
        double R = (s ? 8 : 2) * r->diag;
        for (int i = 0; i < CANON_BOUND_DIRS; i++) {
            double z = 1 - (2 * i + 1.0) / CANON_BOUND_DIRS, rho = sqrt(1 - z * z);
            double phi = i * FREP_PI * (3 - sqrt(5.0));
            double x[3] = { r->obb.c[0] + R * rho * cos(phi), r->obb.c[1] + R * rho * sin(phi),
                            r->obb.c[2] + R * z };
            if (tree_at(t->code, t->len - 1, prims, nprims, x) >= 0) return 0;
        }
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

/* Per primitive in list order: the aggressive form when the model still explains the
 * points within CANON_MAX_CHANGE of the diagonal (mean distance), else the bounded one
 * when it does, else the exact primitive. */
static int check(const evolve_result *r, const prim *prims, size_t nprims,
                 const frep_cloud *cloud, canon_prim *out)
{
    prim *q = frep_malloc(nprims * sizeof *q);
    if (!q) return -1;
    memcpy(q, prims, nprims * sizeof *q);
    size_t stride = cloud->n > CANON_CHECK_POINTS ? cloud->n / CANON_CHECK_POINTS : 1;
    double base = mean_dist(r, q, nprims, cloud, stride);
    double budget = CANON_MAX_CHANGE * r->diag;
    for (size_t j = 0; j < nprims; j++) {
        if (!out[j].polarity) continue;
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
        int pol = out[j].polarity;
        memset(&out[j], 0, sizeof out[j]);
        out[j].q = prims[j];
        out[j].polarity = pol;
        out[j].qpos = PRIM_POS_QUANTUM * r->diag;
        out[j].qdir = PRIM_DIR_QUANTUM;
    }
    frep_free(q);
    return 0;
}

int canon_prims(const evolve_result *r, const prim *prims, size_t nprims,
                const frep_cloud *cloud, int exact, canon_prim *out)
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
    if (!exact && cloud && cloud->n && nprims && check(r, prims, nprims, cloud, out)) return -1;
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
    if (q->separating) fputs(", separating", f);
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
    uint32_t face[6];
    uint8_t fneg[6];
    double qpos, qdir, sigma;   /* FT_BOX: printing quanta, the faces' standard error */
    char name[48];              /* FT_BOX, FT_CAPPED (a primitive's name + "_capped") */
} ft_node;

typedef struct ft {
    ft_node *v;
    uint32_t n, cap;
    int failed;
    const canon_prim *c;  /* per primitive: its canonical form */
    prim *q;              /* per primitive: what the written call evaluates */
    size_t nprims;
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

/* The box of the pairs p[k] = (plus, minus term index) of intersection node `and`:
 * an orthonormal frame from the pairs' normals, each face's offset along its axis,
 * the axes ordered and signed so that an axis-aligned box has no rotation; numbers
 * rounded as they print.  Returns the node, or FT_NONE. */
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
    double cw[3] = { 0, 0, 0 }, h[3];
    for (int k = 0; k < 3; k++) {
        double sp = d[k][0] / vec3_dot(n[k][0], u[k]);
        double sm = -d[k][1] / -vec3_dot(n[k][1], u[k]);
        h[k] = (sp - sm) / 2;
        if (!(h[k] > 0)) return FT_NONE;
        for (int w = 0; w < 3; w++) cw[w] += (sp + sm) / 2 * u[k][w];
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
    for (int k = 0; k < 3; k++)
        for (int s = 0; s < 2; s++) {
            ft_term tm = F->v[and].t[p[k][s]];
            uint32_t j = F->v[tm.node].leaf;
            v->face[2 * k + s] = j;
            v->fneg[2 * k + s] = tm.neg;
            v->qpos = fmin(v->qpos, F->c[j].qpos);
            v->qdir = fmin(v->qdir, F->c[j].qdir);
            if (F->c[j].sigma > 0 && (v->sigma == 0 || F->c[j].sigma < v->sigma))
                v->sigma = F->c[j].sigma;
        }
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
} ft_check;

/* Whether the tree still explains the cloud (mean distance within the limit) and keeps
 * the solid's sign at the grid points (without the cloud: always). */
static int ft_keeps(const ft *F, const ft_check *ck)
{
    if (!ck->cloud) return 1;
    for (size_t i = 0; i < ck->ng; i++) {
        if (fabs(ck->ref[i]) <= ck->gtol) continue;
        if ((ft_eval(F, ck->root, &ck->g[3 * i]) > 0) != (ck->ref[i] > 0)) return 0;
    }
    return ft_mean(F, ck->root, ck->cloud, ck->stride) <= ck->limit;
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

static void write_feature(FILE *f, const ft *F, const ft_node *v, const char *const *names, int hyperfun)
{
    char a[PRIM_NUM_BUF], b[PRIM_NUM_BUF], c[PRIM_NUM_BUF];
    fprintf(f, "    %s = ", v->name);
    size_t inl = 0;
    if (v->kind == FT_BOX) {
        for (int k = 0; k < 6; k++) inl += F->c[v->face[k]].q.support;
        if (hyperfun) {
            for (int k = 0; k < 6; k++) {
                canon_prim p = face_of(F, v->face[k], v->fneg[k]);
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
        for (int k = 0; k < 6; k++) fprintf(f, "%s %s", k ? "," : "", names[v->face[k]]);
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

static void apply_solids(ft *F, uint32_t i, const ft_check *ck)
{
    ft_node *v = &F->v[i];
    if (v->kind != FT_AND && v->kind != FT_OR) return;
    uint32_t n = v->n;
    for (uint32_t k = 0; k < n; k++) apply_solids(F, F->v[i].t[k].node, ck);
    if (F->v[i].kind == FT_AND) {
        ft_solids(F, i, ck);
        if (ck->cloud) ft_push(F, i, ck);
    }
}

int canon_write_body(FILE *f, const evolve_result *r, const prim *prims, const canon_prim *c,
                     size_t nprims, const frep_cloud *cloud, int exact, int hyperfun,
                     const char *base_call)
{
    const gp_tree *t = &r->tree;
    if (!t->len) return 0;
    ft F;
    memset(&F, 0, sizeof F);
    F.c = c;
    F.nprims = nprims;
    F.q = frep_calloc(nprims + 1, sizeof *F.q);
    const char **names = frep_calloc(nprims + 1, sizeof *names);
    unsigned *uses = NULL;
    uint32_t *order = NULL;
    uint8_t *seen = NULL, *pol = NULL;
    double *grid = NULL, *ref = NULL;
    fw w;
    memset(&w, 0, sizeof w);
    int rc = -1;
    if (!F.q || !names) goto done;
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
    if (F.failed) goto done;
    uses = frep_calloc(nprims + 1, sizeof *uses);
    order = frep_calloc(F.n, sizeof *order);
    seen = frep_calloc(F.n, 1);
    pol = frep_calloc(F.n, 1);
    w.stmt = frep_calloc(F.n, sizeof *w.stmt);
    if (!uses || !order || !seen || !pol || !w.stmt) goto done;
    uint32_t no = 0;
    fw_walk(&F, root, 0, uses, order, &no, seen, pol);
    /* Names and the count of solids. */
    unsigned nbox = 0, ncap = 0, kinds[PRIM__COUNT + 1] = { 0 };
    for (uint32_t k = 0; k < no; k++) {
        ft_node *v = &F.v[order[k]];
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
        if (!head++)
            fprintf(f, "    -- primitives, numbers rounded to what their inliers support (+- the "
                       "standard error of a position)\n");
        fprintf(f, "    %s = ", c[j].name);
        if (hyperfun) canon_write_hyperfun(f, &c[j]);
        else canon_write_call(f, &c[j]);
        fputc(';', f);
        canon_write_comment(f, &c[j]);
        fputc('\n', f);
    }
    if (base_call && uses[nprims])
        fprintf(f, "    base_part = %s;  -- the model given with --residual\n", base_call);
    if (no)
        fprintf(f, "    -- solids of the fitted faces (numbers rounded as their faces'; a face "
                   "moves with the box's centre and half size)\n");
    for (uint32_t k = 0; k < no; k++) write_feature(f, &F, &F.v[order[k]], names, hyperfun);
    fprintf(f, "    -- the construction tree: | union, & intersection, \\ subtraction, ~ complement\n");
    w.f = f;
    w.F = &F;
    w.names = names;
    w.large = t->len > 11;
    fw_root(&w, root);
    rc = ferror(f) ? -1 : 0;
done:
    ft_free(&F);
    frep_free(F.q);
    frep_free(names);
    frep_free(uses);
    frep_free(order);
    frep_free(seen);
    frep_free(pol);
    frep_free(w.stmt);
    frep_free(grid);
    frep_free(ref);
    return rc;
}
