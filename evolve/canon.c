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
    const prim *q = &c->q;
    double v[8], qu[8];
    int n = 0;
    const char *name = "frPlane";
    double qp = c->qpos, qd = c->qdir;
    switch (q->type) {
    case PRIM_PLANE:
    case PRIM_SPHERE:
        name = q->type == PRIM_PLANE ? "frPlane" : "frSphere";
        for (int k = 0; k < 3; k++) {
            v[n] = q->p[k];
            qu[n++] = q->type == PRIM_PLANE ? qd : qp;
        }
        v[n] = q->r;
        qu[n++] = qp;
        break;
    case PRIM_CYLINDER:
    case PRIM_CONE:
    case PRIM_TORUS:
        name = q->type == PRIM_CYLINDER ? "frCylinder" : q->type == PRIM_CONE ? "frCone" : "frTorus";
        for (int k = 0; k < 3; k++) {
            v[n] = q->p[k];
            qu[n++] = qp;
        }
        for (int k = 0; k < 3; k++) {
            v[n] = q->a[k];
            qu[n++] = qd;
        }
        if (q->type == PRIM_TORUS) {
            v[n] = q->R;
            qu[n++] = qp;
        }
        v[n] = q->r;
        qu[n++] = q->type == PRIM_CONE ? qd : qp;
        break;
    case PRIM__COUNT:
        fputs("0", f);
        return;
    }
    fprintf(f, "%s(x", name);
    for (int k = 0; k < n; k++) {
        char buf[PRIM_NUM_BUF];
        prim_format_number(buf, v[k], qu[k]);
        fprintf(f, ", %s", buf);
    }
    fputc(')', f);
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

/* ---- the tree ------------------------------------------------------------------------ */

typedef struct tw {
    frep_buf *b;
    const frep_insn *code;
    const char *const *names;
    const prim *prims;
    size_t nprims;
    char (*part)[16];     /* per pc: the sub-expression's name, "" when inline */
} tw;


static void expr(tw *w, uint32_t end, int top, int paren);

/* The operands of a chain of one associative operator, flat: a & b & c. */
static void chain(tw *w, uint32_t end, char op, int first)
{
    const frep_insn *in = &w->code[end];
    if (tree_nin(in) == 2 && op_char(in->op) == op && (first || !w->part[end][0])) {
        uint32_t l0, l1, r0;
        tree_operands(w->code, end, &l0, &l1, &r0);
        chain(w, l1, op, 0);
        buf_printf(w->b, " %c ", op);
        chain(w, end - 1, op, 0);
        return;
    }
    expr(w, end, 0, 1);
}

static void expr(tw *w, uint32_t end, int top, int paren)
{
    const frep_insn *in = &w->code[end];
    if (!top && w->part[end][0]) {
        buf_puts(w->b, w->part[end]);
        return;
    }
    int k = tree_nin(in);
    if (k == 0) {
        buf_puts(w->b, w->names[in->arg]);
        return;
    }
    if (k == 1) {
        buf_putc(w->b, '~');
        expr(w, end - 1, 0, 1);
        return;
    }
    char op = op_char(in->op);
    if (paren && !top) buf_putc(w->b, '(');
    if (op == '\\') {
        uint32_t l0, l1, r0;
        tree_operands(w->code, end, &l0, &l1, &r0);
        /* Left to right, as the language groups: a \ b \ c needs no parentheses. */
        const frep_insn *li = &w->code[l1];
        int lsub = tree_nin(li) == 2 && op_char(li->op) == '\\' && !w->part[l1][0];
        expr(w, l1, lsub, !lsub);
        buf_puts(w->b, " \\ ");
        expr(w, end - 1, 0, 1);
    } else {
        chain(w, end, op, 1);
    }
    if (paren && !top) buf_putc(w->b, ')');
}

static uint32_t nodes(const frep_insn *code, uint32_t end)
{
    return end - tree_subtree_start(code, end) + 1;
}

/* An intersection of planes only, with at least 4 of them. */
static int plane_block(const tw *w, uint32_t end)
{
    uint32_t s = tree_subtree_start(w->code, end), planes = 0;
    for (uint32_t pc = s; pc <= end; pc++) {
        const frep_insn *in = &w->code[pc];
        if (in->op == FREP_OP_PRIM) {
            if (in->arg >= w->nprims || w->prims[in->arg].type != PRIM_PLANE) return 0;
            planes++;
        } else if (!(tree_nin(in) == 2 && op_char(in->op) == '&')) {
            return 0;
        }
    }
    return planes >= 4;
}

/* parent[pc] of every node (the root: len), right[pc] when it is a right operand. */
static void parents(const frep_insn *code, uint32_t end, uint32_t *parent, uint8_t *right)
{
    int k = tree_nin(&code[end]);
    if (k == 1) {
        parent[end - 1] = end;
        right[end - 1] = 1;
        parents(code, end - 1, parent, right);
    } else if (k == 2) {
        uint32_t l0, l1, r0;
        tree_operands(code, end, &l0, &l1, &r0);
        parent[l1] = end;
        parent[end - 1] = end;
        right[end - 1] = 1;
        parents(code, l1, parent, right);
        parents(code, end - 1, parent, right);
    }
}

/* Name the sub-expressions, bottom-up (post-order is pc order), and write them. */
static void parts(tw *w, uint32_t len)
{
    uint32_t *parent = frep_calloc(len, sizeof *parent);
    uint8_t *right = frep_calloc(len, 1);
    if (!parent || !right) {
        w->b->failed = 1;
        frep_free(parent);
        frep_free(right);
        return;
    }
    parent[len - 1] = len;
    parents(w->code, len - 1, parent, right);
    unsigned nb = 0, nc = 0, np = 0;
    for (uint32_t pc = 0; pc + 1 < len; pc++) {
        const frep_insn *in = &w->code[pc];
        if (tree_nin(in) != 2 || nodes(w->code, pc) < 5) continue;
        const frep_insn *pi = &w->code[parent[pc]];
        char op = op_char(in->op), pop = tree_nin(pi) == 2 ? op_char(pi->op) : '~';
        int cut = pop == '~' || (pop == '\\' && right[pc]);
        /* Inside a chain of its own operator it stays flat, unless a block. */
        int flat = pop == op && op != '\\';
        int block = plane_block(w, pc);
        if (flat && (!block || plane_block(w, parent[pc]))) continue;
        if (block) snprintf(w->part[pc], sizeof w->part[pc], "block_%u", ++nb);
        else if (cut) snprintf(w->part[pc], sizeof w->part[pc], "cut_%u", ++nc);
        else snprintf(w->part[pc], sizeof w->part[pc], "part_%u", ++np);
        buf_printf(w->b, "    %s = ", w->part[pc]);
        expr(w, pc, 1, 0);
        buf_puts(w->b, ";\n");
    }
    frep_free(parent);
    frep_free(right);
}

void canon_write_tree(frep_buf *b, const gp_tree *t, const char *const *names, const prim *prims,
                      size_t nprims)
{
    if (!t->len) return;
    tw w = { b, t->code, names, prims, nprims, NULL };
    w.part = frep_calloc(t->len, sizeof *w.part);
    if (!w.part) {
        b->failed = 1;
        return;
    }
    if (t->len > 11) parts(&w, t->len);
    buf_puts(b, "    tree = ");
    expr(&w, t->len - 1, 1, 0);
    buf_puts(b, ";\n");
    frep_free(w.part);
}
