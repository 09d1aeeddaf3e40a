/* test_mesh.c - unit tests of the interval evaluator (runtime/vm_interval.c) and the
 * dual-contouring mesher (mesh/mesh.c) on analytic fields given as C callbacks:
 * interval enclosures hold at sampled points; meshes are closed, 2-manifold,
 * outward, NaN-free, accurate (volume, distance, sharp corners) and thread-invariant.
 */
#include "config.h"

#include "alloc.h"
#include "interval.h"
#include "mesh.h"
#include "mesh_internal.h"
#include "meshio.h"
#include "opsem.h"
#include "program.h"
#include "tap.h"
#include "threads.h"

#include <math.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- a small deterministic RNG (xorshift64*) ------------------------------------- */

static double rnd(uint64_t *s)
{
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return (double)((*s * 2685821657736338717ULL) >> 11) / 9007199254740992.0;
}

/* ---- interval evaluator: every operation against point samples --------------------- */

static ival rand_ival(uint64_t *s)
{
    static const double scales[] = { 0.5, 2, 10, 1e3 };
    double sc = scales[(int)(rnd(s) * 4)];
    double a = (rnd(s) * 2 - 1) * sc, b = (rnd(s) * 2 - 1) * sc;
    if (rnd(s) < 0.2) b = a;                      /* degenerate (exact) operands */
    if (rnd(s) < 0.1) a = b = (double)(int)(a);   /* integer constants (for pow) */
    ival r = { a < b ? a : b, a < b ? b : a };
    return r;
}

static double in_ival(const ival *v, uint64_t *s)
{
    double u = rnd(s);
    if (u < 0.1) return v->lo;
    if (u < 0.2) return v->hi;
    return v->lo + (v->hi - v->lo) * rnd(s);
}

static void test_interval_ops(void)
{
    uint64_t seed = 12345;
    for (int op = 0; op < FREP_OP__COUNT; op++) {
        unsigned fl = op_flags((frep_opcode)op);
        if ((fl & (OPF_LEAF | OPF_CTRL)) || op == FREP_OP_LOADI) continue;
        int nin = op_nin((frep_opcode)op);
        long bad = 0, samples = 0;
        for (int trial = 0; trial < 400; trial++) {
            ival v[3] = { rand_ival(&seed), rand_ival(&seed), rand_ival(&seed) };
            if (op == FREP_OP_SELECT && rnd(&seed) < 0.5) v[0].lo = v[0].hi = rnd(&seed) < 0.5 ? 0 : 1;
            if ((op == FREP_OP_AND || op == FREP_OP_OR || op == FREP_OP_NOT) && rnd(&seed) < 0.5)
                v[0].lo = v[0].hi = 0;
            double k = (op == FREP_OP_AUNI || op == FREP_OP_AINT) ? rnd(&seed) * 2 - 1 : 0;
            ival r = ival_op((frep_opcode)op, v, k);
            if (!(r.lo <= r.hi)) { bad++; continue; }
            for (int t = 0; t < 30; t++) {
                double a = in_ival(&v[0], &seed), b = in_ival(&v[1], &seed), c = in_ival(&v[2], &seed);
                double y = op_scalar((frep_opcode)op, a, nin > 1 ? b : 0, c, k, NULL);
                if (isnan(y)) continue;
                samples++;
                if (!(y >= r.lo && y <= r.hi)) {
                    if (bad < 3)
                        diag("%s(%g, %g, %g) = %.17g outside [%.17g, %.17g] of [%g,%g] [%g,%g]",
                             op_name((frep_opcode)op), a, b, c, y, r.lo, r.hi, v[0].lo, v[0].hi,
                             v[1].lo, v[1].hi);
                    bad++;
                }
            }
        }
        ok(bad == 0 && samples > 0, "interval %s encloses %ld sampled values", op_name((frep_opcode)op),
           samples);
    }
}

/* Tightness: enclosures of simple operations are the exact ranges (up to an ulp). */
static void test_interval_tight(void)
{
    ival v[3] = { { 1, 2 }, { 3, 4 }, { 0, 0 } };
    ival r = ival_op(FREP_OP_ADD, v, 0);
    ok(r.lo >= 4 - 1e-15 && r.lo <= 4 && r.hi >= 6 && r.hi <= 6 + 1e-14, "[1,2]+[3,4] is [4,6]");
    v[0].lo = -1; v[0].hi = 2;
    r = ival_op(FREP_OP_SQUARE, v, 0);
    ok(r.lo == 0 && r.hi >= 4 && r.hi <= 4 + 1e-14, "[-1,2]^2 is [0,4]");
    v[0].lo = 0.1; v[0].hi = 0.2;
    r = ival_op(FREP_OP_SIN, v, 0);
    ok(r.lo <= sin(0.1) && r.lo > sin(0.1) - 1e-15 && r.hi >= sin(0.2) && r.hi < sin(0.2) + 1e-15,
       "sin is tight on a monotone piece");
    v[0].lo = 1; v[0].hi = 2; v[1].lo = -3; v[1].hi = 5;
    r = ival_op(FREP_OP_RUNI, v, 0);
    is_double(r.lo, opsem_runi(1, -3), 1e-14, "R-union lower bound is its value at (lo, lo)");
    is_double(r.hi, opsem_runi(2, 5), 1e-14, "R-union upper bound is its value at (hi, hi)");
    v[0].lo = -2; v[0].hi = 3; v[1].lo = v[1].hi = 3;
    r = ival_op(FREP_OP_POW, v, 0);
    ok(fabs(r.lo + 8) < 1e-13 && fabs(r.hi - 27) < 1e-13, "[-2,3]^3 is [-8,27]");
    v[1].lo = v[1].hi = 2;
    r = ival_op(FREP_OP_POW, v, 0);
    ok(r.lo == 0 && fabs(r.hi - 9) < 1e-13, "[-2,3]^2 is [0,9]");
    v[0].lo = 1; v[0].hi = 2; v[1].lo = 3; v[1].hi = 4;
    r = ival_op(FREP_OP_LT, v, 0);
    ok(r.lo == 1 && r.hi == 1, "[1,2] < [3,4] is decided");
}

/* A program assembled by hand: sphere of radius 1 united (R0) with a block, minus a
 * cylinder, then a branch on x (decided or not) for the conservative path. */
static frep_program *sphere_prog(int with_branch)
{
    frep_program *p = prog_new();
    frep_srcpos pos = { 0, 0, 0 };
    prog_emit(p, FREP_OP_CONST, 0, 1, 0, pos);
    prog_emit(p, FREP_OP_X, 0, 0, 0, pos);
    prog_emit(p, FREP_OP_SQUARE, 0, 0, 0, pos);
    prog_emit(p, FREP_OP_X, 1, 0, 0, pos);
    prog_emit(p, FREP_OP_SQUARE, 0, 0, 0, pos);
    prog_emit(p, FREP_OP_ADD, 0, 0, 0, pos);
    prog_emit(p, FREP_OP_X, 2, 0, 0, pos);
    prog_emit(p, FREP_OP_SQUARE, 0, 0, 0, pos);
    prog_emit(p, FREP_OP_ADD, 0, 0, 0, pos);
    prog_emit(p, FREP_OP_SUB, 0, 0, 0, pos);          /* 1 - r^2 */
    prog_emit(p, FREP_OP_CONST, 0, 0.5, 0, pos);
    prog_emit(p, FREP_OP_X, 0, 0, 0, pos);
    prog_emit(p, FREP_OP_ABS, 0, 0, 0, pos);
    prog_emit(p, FREP_OP_SUB, 0, 0, 0, pos);          /* 0.5 - |x| */
    prog_emit(p, FREP_OP_RSUB, 0, 0, 0, pos);
    prog_emit(p, FREP_OP_X, 1, 0, 0, pos);
    prog_emit(p, FREP_OP_SIN, 0, 0, 0, pos);
    prog_emit(p, FREP_OP_MUL, 0, 0.3, INSN_KB, pos);
    prog_emit(p, FREP_OP_ADD, 0, 0, 0, pos);
    if (with_branch) {
        /* t = f; if x > 0 then t = t * 2 */
        prog_emit(p, FREP_OP_STORE, 0, 0, 0, pos);
        prog_emit(p, FREP_OP_X, 0, 0, 0, pos);
        prog_emit(p, FREP_OP_GT, 0, 0, INSN_KB, pos);
        prog_emit(p, FREP_OP_JZ, 27, 0, 0, pos);
        prog_emit(p, FREP_OP_LOAD, 0, 0, 0, pos);
        prog_emit(p, FREP_OP_MUL, 0, 2, INSN_KB, pos);
        prog_emit(p, FREP_OP_STORE, 0, 0, 0, pos);
        prog_emit(p, FREP_OP_JMP, 27, 0, 0, pos);
        prog_emit(p, FREP_OP_LOAD, 0, 0, 0, pos);
        p->nslots = 1;
    }
    if (prog_finish(p) != 0) {
        frep_program_free(p);
        return NULL;
    }
    return p;
}

static void test_interval_program(void)
{
    for (int br = 0; br < 2; br++) {
        frep_program *p = sphere_prog(br);
        ok(p != NULL, "assembled test program %d", br);
        if (!p) continue;
        vm_iscratch *is = vm_iscratch_new(p);
        frep_scratch *s = frep_scratch_new(p);
        uint64_t seed = 99;
        long bad = 0, finite = 0, undecided = 0;
        for (int trial = 0; trial < 300; trial++) {
            double box[6];
            for (int c = 0; c < 3; c++) {
                double a = rnd(&seed) * 4 - 2, w = rnd(&seed) * (trial % 3 == 0 ? 2 : 0.2);
                box[c] = a;
                box[c + 3] = a + w;
            }
            ival r;
            vm_eval_interval(p, is, box, NULL, &r);
            if (isinf(r.lo) && isinf(r.hi)) undecided++;
            else finite++;
            double x[64], y[64], z[64], f[64];
            for (int i = 0; i < 64; i++) {
                x[i] = box[0] + (box[3] - box[0]) * (i < 8 ? (i & 1) : rnd(&seed));
                y[i] = box[1] + (box[4] - box[1]) * (i < 8 ? ((i >> 1) & 1) : rnd(&seed));
                z[i] = box[2] + (box[5] - box[2]) * (i < 8 ? ((i >> 2) & 1) : rnd(&seed));
            }
            frep_eval(p, s, 64, x, y, z, NULL, f);
            for (int i = 0; i < 64; i++)
                if (!isnan(f[i]) && !(f[i] >= r.lo && f[i] <= r.hi)) bad++;
        }
        ok(bad == 0, "program %d: every sampled value lies in its box's interval", br);
        ok(finite > (br ? 100 : 290), "program %d: %ld of 300 enclosures are finite (%ld unknown)",
           br, finite, undecided);
        vm_iscratch_free(is);
        frep_scratch_free(s);
        frep_program_free(p);
    }
}

/* ---- analytic fields for the mesher -------------------------------------------------- */

typedef enum field_kind {
    F_SPHERE, F_BLOCK, F_CYLINDER, F_CSG, F_THIN, F_BLEND, F_EMPTY, F_FULL, F_NANHALF, F_TORI,
    F_GYROID
} field_kind;

typedef struct tfield {
    field_kind kind;
    double r;            /* sphere / cylinder radius */
    double b[6];         /* block x0 y0 z0 x1 y1 z1 */
    int evals;
} tfield;

static double block_f(const double *b, double x, double y, double z, double g[3])
{
    double d[6] = { x - b[0], y - b[1], z - b[2], b[3] - x, b[4] - y, b[5] - z };
    int m = 0;
    for (int i = 1; i < 6; i++)
        if (d[i] < d[m]) m = i;
    if (g) {
        g[0] = g[1] = g[2] = 0;
        g[m % 3] = m < 3 ? 1 : -1;
    }
    return d[m];
}

static double tf_eval1(const tfield *t, double x, double y, double z, double g[3])
{
    double gg[3], f1, f2;
    switch (t->kind) {
    case F_SPHERE:
        if (g) { g[0] = -2 * x; g[1] = -2 * y; g[2] = -2 * z; }
        return t->r * t->r - x * x - y * y - z * z;
    case F_BLOCK: return block_f(t->b, x, y, z, g);
    case F_CYLINDER: {
        /* |z| <= 0.8 and x^2 + y^2 <= r^2, min/max intersection: sharp rims */
        double fc = t->r * t->r - x * x - y * y, fz = 0.8 - fabs(z);
        if (fc < fz) {
            if (g) { g[0] = -2 * x; g[1] = -2 * y; g[2] = 0; }
            return fc;
        }
        if (g) { g[0] = g[1] = 0; g[2] = z > 0 ? -1 : 1; }
        return fz;
    }
    case F_CSG: {
        /* block minus a sphere (min/max): sharp edges, corners and a spherical cavity */
        f1 = block_f(t->b, x, y, z, g);
        double rr = 0.7;
        f2 = x * x + (y - 0.6) * (y - 0.6) + z * z - rr * rr;
        if (f2 < f1) {
            if (g) { g[0] = 2 * x; g[1] = 2 * (y - 0.6); g[2] = 2 * z; }
            return f2;
        }
        return f1;
    }
    case F_THIN: {
        /* a wall 0.12 thick: thinner than a cell, one layer of grid points inside */
        double f = 0.06 - fabs(x - 0.013);
        f1 = 0.9 - y * y - z * z;
        if (f1 < f) {
            if (g) { g[0] = 0; g[1] = -2 * y; g[2] = -2 * z; }
            return f1;
        }
        if (g) { g[0] = x > 0.013 ? -1 : 1; g[1] = g[2] = 0; }
        return f;
    }
    case F_BLEND: {
        /* two spheres joined by an R0 union (smooth blend) */
        double a = 0.36 - (x - 0.4) * (x - 0.4) - y * y - z * z;
        double b = 0.36 - (x + 0.4) * (x + 0.4) - y * y - z * z;
        double s = sqrt(a * a + b * b);
        if (g) {
            double da = 1 + (s > 0 ? a / s : 0), db = 1 + (s > 0 ? b / s : 0);
            g[0] = da * -2 * (x - 0.4) + db * -2 * (x + 0.4);
            g[1] = (da + db) * -2 * y;
            g[2] = (da + db) * -2 * z;
        }
        return a + b + s;
    }
    case F_EMPTY: if (g) g[0] = g[1] = g[2] = 0; return -1;
    case F_FULL: if (g) g[0] = g[1] = g[2] = 0; return 1;
    case F_NANHALF:
        if (x > 0.3) { if (g) g[0] = g[1] = g[2] = NAN; return NAN; }
        if (g) { g[0] = -2 * x; g[1] = -2 * y; g[2] = -2 * z; }
        return 1 - x * x - y * y - z * z;
    case F_TORI: {
        /* two linked tori: genus, saddles, near-touching sheets */
        double q = sqrt(x * x + y * y) - 0.6;
        f1 = 0.04 - q * q - z * z;
        double q2 = sqrt((x - 0.6) * (x - 0.6) + z * z) - 0.6;
        f2 = 0.04 - q2 * q2 - y * y;
        if (g) {
            double rr = sqrt(x * x + y * y), r2 = sqrt((x - 0.6) * (x - 0.6) + z * z);
            if (f1 >= f2) {
                g[0] = rr > 0 ? -2 * q * x / rr : 0; g[1] = rr > 0 ? -2 * q * y / rr : 0;
                g[2] = -2 * z;
            } else {
                g[0] = r2 > 0 ? -2 * q2 * (x - 0.6) / r2 : 0; g[1] = -2 * y;
                g[2] = r2 > 0 ? -2 * q2 * z / r2 : 0;
            }
            (void)gg;
        }
        return f1 > f2 ? f1 : f2;
    }
    case F_GYROID: {
        /* bench/bench_gyroid.hf with min: the solid side of a gyroid of period 2 pi / 10
         * in a ball of radius 1.5; its tunnels get thinner than a cell at coarse grids */
        const double k = 10;
        double sx = sin(k * x), cx = cos(k * x), sy = sin(k * y), cy = cos(k * y);
        double sz = sin(k * z), cz = cos(k * z);
        f1 = 2.25 - x * x - y * y - z * z;
        f2 = -(sx * cy + sy * cz + sz * cx);
        if (g) {
            if (f1 < f2) {
                g[0] = -2 * x; g[1] = -2 * y; g[2] = -2 * z;
            } else {
                g[0] = -k * (cx * cy - sz * sx);
                g[1] = -k * (-sx * sy + cy * cz);
                g[2] = -k * (-sy * sz + cz * cx);
            }
        }
        return f1 < f2 ? f1 : f2;
    }
    }
    return NAN;
}

static int tf_eval(void *ctx, void *ts, size_t n, const double *x, const double *y,
                   const double *z, double *f)
{
    (void)ts;
    for (size_t i = 0; i < n; i++) f[i] = tf_eval1(ctx, x[i], y[i], z[i], NULL);
    return 0;
}

static int tf_grad(void *ctx, void *ts, size_t n, const double *x, const double *y,
                   const double *z, double *f, double *gx, double *gy, double *gz)
{
    (void)ts;
    for (size_t i = 0; i < n; i++) {
        double g[3] = { 0, 0, 0 };
        f[i] = tf_eval1(ctx, x[i], y[i], z[i], g);
        gx[i] = g[0];
        gy[i] = g[1];
        gz[i] = g[2];
    }
    return 0;
}

/* Sound intervals for the sphere (exact range of 1 - r^2 over a box). */
static int tf_interval(void *ctx, void *ts, const double box[6], double *lo, double *hi)
{
    const tfield *t = ctx;
    (void)ts;
    if (t->kind != F_SPHERE) {
        *lo = -INFINITY;
        *hi = INFINITY;
        return 0;
    }
    double mn = 0, mx = 0;
    for (int c = 0; c < 3; c++) {
        double a = box[c] * box[c], b = box[c + 3] * box[c + 3];
        mx += a > b ? a : b;
        mn += (box[c] <= 0 && box[c + 3] >= 0) ? 0 : (a < b ? a : b);
    }
    *lo = t->r * t->r - mx;
    *hi = t->r * t->r - mn;
    return 0;
}

static void *tf_thread_new(void *ctx) { return ctx; }
static void tf_thread_free(void *ctx, void *ts) { (void)ctx; (void)ts; }

static mesh_field make_field(tfield *t, int with_interval)
{
    mesh_field f = { t, tf_thread_new, tf_thread_free, tf_eval, tf_grad,
                     with_interval ? tf_interval : NULL, NULL, 0 };
    return f;
}

/* mesh_polygonize with a fresh error (the first error set wins). */
/* Options for the cube [-half, half]^3 at `grid` cells per axis on `threads` threads. */
static void cube_options(mesh_options *o, double half, int grid, int threads)
{
    mesh_options_init(o);
    for (int c = 0; c < 3; c++) {
        o->box[c] = -half;
        o->box[c + 3] = half;
    }
    o->grid = grid;
    o->nthreads = threads;
}

static int polygonize(const mesh_field *f, const mesh_options *o, frep_mesh *m, mesh_stats *st,
                      frep_error *err)
{
    frep_error_init(err);
    return mesh_polygonize(f, o, m, st, err);
}

static int run_mesh(tfield *t, const double box[6], int grid, int threads, frep_mesh *m,
                    mesh_stats *st)
{
    mesh_field f = make_field(t, 1);
    mesh_options o;
    mesh_options_init(&o);
    memcpy(o.box, box, sizeof o.box);
    o.grid = grid;
    o.nthreads = threads;
    frep_error err;
    int rc = polygonize(&f, &o, m, st, &err);
    if (rc != 0) diag("mesh_polygonize: %s", err.msg);
    return rc;
}

static void check_closed(const char *name, const frep_mesh *m, mesh_check *c)
{
    mesh_validate(m, c);
    ok(m->ntris > 0 && c->open_edges == 0 && c->nonmanifold_edges == 0 && c->flipped_edges == 0,
       "%s: %zu triangles, every edge shared by two triangles in opposite directions "
       "(open %zu, non-manifold %zu, flipped %zu)", name, m->ntris, c->open_edges,
       c->nonmanifold_edges, c->flipped_edges);
    ok(c->nonmanifold_verts == 0 && c->unused_verts == 0,
       "%s: every vertex's triangles form one closed fan (%zu do not, %zu unused)", name,
       c->nonmanifold_verts, c->unused_verts);
    ok(c->degenerate == 0 && c->nonfinite == 0, "%s: no zero-area triangle (%zu), no NaN (%zu)",
       name, c->degenerate, c->nonfinite);
}

/* Largest |distance| of vertices and triangle centroids to the true surface, given
 * a distance function. */
static double max_dist(const frep_mesh *m, double (*dist)(const double *p))
{
    double worst = 0;
    for (size_t t = 0; t < m->ntris; t++) {
        double c[3] = { 0, 0, 0 };
        for (int k = 0; k < 3; k++) {
            const double *p = &m->v[3 * m->tri[3 * t + k]];
            double d = fabs(dist(p));
            if (d > worst) worst = d;
            for (int j = 0; j < 3; j++) c[j] += p[j] / 3;
        }
        double d = fabs(dist(c));
        if (d > worst) worst = d;
    }
    return worst;
}

static double sphere_dist(const double *p) { return sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) - 1; }

static const double test_block[6] = { -0.71, -0.53, -0.47, 0.63, 0.58, 0.66 };

static double block_dist(const double *p)
{
    /* distance to the boundary of the block (inside: distance to the nearest face) */
    double out2 = 0, inner = INFINITY;
    for (int c = 0; c < 3; c++) {
        double lo = test_block[c], hi = test_block[c + 3];
        double d = p[c] < lo ? lo - p[c] : (p[c] > hi ? p[c] - hi : 0);
        out2 += d * d;
        double e = fmin(p[c] - lo, hi - p[c]);
        if (e < inner) inner = e;
    }
    return out2 > 0 ? sqrt(out2) : inner;
}

static void test_mesh_shapes(void)
{
    const double box[6] = { -1.5, -1.5, -1.5, 1.5, 1.5, 1.5 };
    frep_mesh m;
    mesh_stats st;
    mesh_check c;
    tfield t;
    const double PI = 3.14159265358979323846;

    /* sphere */
    memset(&t, 0, sizeof t);
    t.kind = F_SPHERE;
    t.r = 1;
    if (run_mesh(&t, box, 48, 2, &m, &st) == 0) {
        check_closed("sphere", &m, &c);
        double cell = 3.0 / 48, v = 4 * PI / 3;
        ok(c.volume > 0 && fabs(c.volume - v) < 0.01 * v, "sphere: volume %.5f within 1%% of %.5f",
           c.volume, v);
        double d = max_dist(&m, sphere_dist);
        ok(d < 0.1 * cell, "sphere: Hausdorff distance %.2e below a tenth of a cell", d);
        ok(st.blocks < st.blocks_total, "sphere: octree skipped blocks (%zu of %zu evaluated)",
           st.blocks, st.blocks_total);
        /* outward vertex normals */
        size_t badn = 0;
        for (size_t i = 0; i < m.nverts; i++) {
            const double *p = &m.v[3 * i], *n = &m.n[3 * i];
            double r = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            if ((p[0] * n[0] + p[1] * n[1] + p[2] * n[2]) / r < 0.99) badn++;
        }
        ok(badn == 0, "sphere: vertex normals are the outward analytic normals (%zu off)", badn);
        /* the distance check: the mesh's vertices within 0.1 cell; a vertex pushed 0.3
         * cell out along its radius is found, at a distance between 0.25 and 0.35 cell
         * (the first-order estimate of this field, |r^2 - 1| / 2r, and the search ladder) */
        mesh_field f = make_field(&t, 1);
        mesh_options o;
        mesh_options_init(&o);
        memcpy(o.box, box, sizeof o.box);
        o.grid = 48;
        mesh_distance md;
        frep_error err;
        frep_error_init(&err);
        int rc = mesh_surface_distance(&f, &o, &m, MESH_SURFACE_TOL, &md, &err);
        ok(rc == 0 && md.far == 0 && md.max_dist < MESH_SURFACE_TOL,
           "sphere: no vertex farther than %g cell (largest %.3g)", MESH_SURFACE_TOL, md.max_dist);
        double *p = &m.v[0], r = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        for (int k = 0; k < 3; k++) p[k] *= (1 + 0.3 * cell) / r;
        rc = mesh_surface_distance(&f, &o, &m, MESH_SURFACE_TOL, &md, &err);
        ok(rc == 0 && md.far == 1 && md.worst == 0 && md.max_dist > 0.25 && md.max_dist < 0.35,
           "sphere: the vertex moved 0.3 cell out is the one far vertex (%zu, at %.3g cell)",
           md.far, md.max_dist);
        mesh_free(&m);
    } else {
        ok(0, "sphere meshed");
    }

    /* block with corners off the grid */
    memset(&t, 0, sizeof t);
    t.kind = F_BLOCK;
    memcpy(t.b, test_block, sizeof t.b);
    if (run_mesh(&t, box, 40, 2, &m, &st) == 0) {
        double cell = 3.0 / 40;
        check_closed("block", &m, &c);
        double v = (t.b[3] - t.b[0]) * (t.b[4] - t.b[1]) * (t.b[5] - t.b[2]);
        ok(fabs(c.volume - v) < 0.01 * v, "block: volume %.5f within 1%% of %.5f", c.volume, v);
        double d = max_dist(&m, block_dist);
        ok(d < 0.01 * cell, "block: faces reproduced (distance %.2e, cell %.3f)", d, cell);
        double worst = 0;
        for (int k = 0; k < 8; k++) {
            double q[3] = { t.b[(k & 1) ? 3 : 0], t.b[(k & 2) ? 4 : 1], t.b[(k & 4) ? 5 : 2] };
            double best = INFINITY;
            for (size_t i = 0; i < m.nverts; i++) {
                double dx = m.v[3 * i] - q[0], dy = m.v[3 * i + 1] - q[1], dz = m.v[3 * i + 2] - q[2];
                double dd = sqrt(dx * dx + dy * dy + dz * dz);
                if (dd < best) best = dd;
            }
            if (best > worst) worst = best;
        }
        ok(worst < 0.01 * cell, "block: the 8 corners are mesh vertices within 1%% of a cell (%.2e)",
           worst);
        mesh_free(&m);
    } else {
        ok(0, "block meshed");
    }

    /* cylinder with sharp rims */
    memset(&t, 0, sizeof t);
    t.kind = F_CYLINDER;
    t.r = 0.6;
    if (run_mesh(&t, box, 48, 2, &m, &st) == 0) {
        check_closed("cylinder", &m, &c);
        double v = PI * 0.36 * 1.6;
        ok(fabs(c.volume - v) < 0.01 * v, "cylinder: volume %.5f within 1%% of %.5f", c.volume, v);
        mesh_free(&m);
    } else {
        ok(0, "cylinder meshed");
    }

    /* other shapes: closed and valid */
    static const struct { field_kind k; const char *name; int grid; } more[] = {
        { F_CSG, "block minus sphere", 37 }, { F_THIN, "thin wall", 23 },
        { F_BLEND, "blended spheres", 31 }, { F_TORI, "linked tori", 29 },
        { F_TORI, "linked tori (coarse)", 11 }, { F_THIN, "thin wall (coarse)", 10 },
    };
    for (size_t i = 0; i < sizeof more / sizeof more[0]; i++) {
        memset(&t, 0, sizeof t);
        t.kind = more[i].k;
        memcpy(t.b, test_block, sizeof t.b);
        if (run_mesh(&t, box, more[i].grid, 2, &m, &st) == 0) {
            check_closed(more[i].name, &m, &c);
            ok(c.volume > 0, "%s: positive volume %.4f", more[i].name, c.volume);
            mesh_free(&m);
        } else {
            ok(0, "%s meshed", more[i].name);
        }
    }
}

static void test_mesh_threads(void)
{
    const double box[6] = { -1.2, -1.1, -1.3, 1.3, 1.2, 1.1 };
    tfield t;
    memset(&t, 0, sizeof t);
    t.kind = F_CSG;
    memcpy(t.b, test_block, sizeof t.b);
    frep_mesh a, b;
    mesh_stats st;
    int ra = run_mesh(&t, box, 45, 1, &a, &st), rb = run_mesh(&t, box, 45, 3, &b, &st);
    ok(ra == 0 && rb == 0 && a.nverts == b.nverts && a.ntris == b.ntris &&
       memcmp(a.v, b.v, 3 * a.nverts * sizeof *a.v) == 0 &&
       memcmp(a.tri, b.tri, 3 * a.ntris * sizeof *a.tri) == 0,
       "the same mesh at 1 and 3 threads (%zu triangles)", a.ntris);
    mesh_free(&a);
    mesh_free(&b);
}

/* A field that counts, per thread state, the points it evaluated, to tell which of a
 * run's thread states (one per thread) did any work.  With `wait`, thread state 0 (the
 * calling thread's) evaluates nothing until another state has (or 10 s have passed):
 * the run then has to use a second thread, however the machine schedules them. */
#define CF_STATES 8
typedef struct cstate {
    struct cfield *cf;
    int k;
    _Atomic long points;
} cstate;
typedef struct cfield {
    tfield t;
    cstate st[CF_STATES];
    int nst, busy, wait;
    _Atomic long others;      /* points evaluated by the states k > 0 */
} cfield;

static void *cf_thread_new(void *ctx)
{
    cfield *c = ctx;
    if (c->nst == CF_STATES) return NULL;
    cstate *s = &c->st[c->nst];
    s->cf = c;
    s->k = c->nst++;
    atomic_store(&s->points, 0);
    return s;
}

static void cf_thread_free(void *ctx, void *ts)
{
    cfield *c = ctx;
    cstate *s = ts;
    c->busy += atomic_load(&s->points) > 0;
}

static void cf_count(cstate *s, size_t n)
{
    if (s->k > 0) atomic_fetch_add(&s->cf->others, (long)n);
    else
        for (int i = 0; i < 10000 && s->cf->wait && atomic_load(&s->cf->others) == 0; i++) {
            struct timespec ms = { 0, 1000000 };
            nanosleep(&ms, NULL);
        }
    atomic_fetch_add(&s->points, (long)n);
}

static int cf_eval(void *ctx, void *ts, size_t n, const double *x, const double *y,
                   const double *z, double *f)
{
    cf_count(ts, n);
    return tf_eval(&((cfield *)ctx)->t, NULL, n, x, y, z, f);
}

static int cf_grad(void *ctx, void *ts, size_t n, const double *x, const double *y,
                   const double *z, double *f, double *gx, double *gy, double *gz)
{
    cf_count(ts, n);
    return tf_grad(&((cfield *)ctx)->t, NULL, n, x, y, z, f, gx, gy, gz);
}

static int cf_interval(void *ctx, void *ts, const double box[6], double *lo, double *hi)
{
    (void)ts;
    return tf_interval(&((cfield *)ctx)->t, NULL, box, lo, hi);
}

/* Mesh the CSG test shape with the counting field of cost `cost` on `threads` threads
 * (0: the default); *busy receives the thread states that evaluated points. */
static int run_counted(double cost, int threads, int wait, int grid, frep_mesh *m, int *busy)
{
    const double box[6] = { -1.2, -1.1, -1.3, 1.3, 1.2, 1.1 };
    cfield c;
    memset(&c, 0, sizeof c);
    c.t.kind = F_CSG;
    memcpy(c.t.b, test_block, sizeof c.t.b);
    c.wait = wait;
    mesh_field f = { &c, cf_thread_new, cf_thread_free, cf_eval, cf_grad, cf_interval, NULL, cost };
    mesh_options o;
    mesh_options_init(&o);
    memcpy(o.box, box, sizeof o.box);
    o.grid = grid;
    o.nthreads = threads;
    mesh_stats st;
    frep_error err;
    int rc = polygonize(&f, &o, m, &st, &err);
    *busy = c.busy;
    return rc;
}

/* The stages' thread counts follow the work (mesh_threads_for): a costly field runs on
 * the threads asked for, a cheap small job on one; the mesh is the same either way, at
 * 1, 2, 3 threads and the default. */
static void test_mesh_thread_sizing(void)
{
    frep_mesh m1, m;
    int busy = 0;
    int r1 = run_counted(1e9, 1, 0, 45, &m1, &busy);
    ok(r1 == 0 && busy == 1, "a costly field at 1 thread: one thread state works (%d)", busy);
    int threads[3] = { 2, 3, 0 };
    for (int i = 0; i < 3; i++) {
        int par = frep_threads(threads[i]) > 1;
        int r = run_counted(1e9, threads[i], par, 45, &m, &busy);
        ok(r == 0 && (par ? busy >= 2 : busy == 1),
           "a costly field at %d threads (0: default): %d thread states work", threads[i], busy);
        ok(r == 0 && r1 == 0 && m.nverts == m1.nverts && m.ntris == m1.ntris &&
               memcmp(m.v, m1.v, 3 * m.nverts * sizeof *m.v) == 0 &&
               memcmp(m.n, m1.n, 3 * m.nverts * sizeof *m.n) == 0 &&
               memcmp(m.tri, m1.tri, 3 * m.ntris * sizeof *m.tri) == 0,
           "the same mesh at 1 and %d threads (0: default), byte for byte", threads[i]);
        if (r == 0) mesh_free(&m);
    }
    /* a 12^3 grid of a cheap field: ~30 blocks of 729 corners x 32: under FREP_PAR_MIN_WORK */
    int r = run_counted(0, 2, 0, 12, &m, &busy);
    ok(r == 0 && busy == 1, "a small cheap job at 2 threads stays on one (%d states work)", busy);
    if (r == 0) mesh_free(&m);
    if (r1 == 0) mesh_free(&m1);
}

/* The checker itself: two tetrahedra sharing one vertex are closed and every edge has
 * two triangles, but the shared vertex is two cones touching at a point. */
static void test_validate_pinch(void)
{
    double v[21] = { 0, 0, 0,  1, 0, 0,  0, 1, 0,  0, 0, 1,  -1, 0, 0,  0, -1, 0,  0, 0, -1 };
    /* outward triangles of tetrahedra (0,1,2,3) and (0,4,5,6) */
    uint32_t tri[24] = { 0, 2, 1,  0, 1, 3,  0, 3, 2,  1, 2, 3,
                         0, 4, 5,  0, 6, 4,  0, 5, 6,  4, 6, 5 };
    frep_mesh m = { 7, 8, v, NULL, tri };
    mesh_check c;
    mesh_validate(&m, &c);
    ok(c.open_edges == 0 && c.nonmanifold_edges == 0 && c.flipped_edges == 0,
       "two tetrahedra touching at a vertex: edges closed and oriented");
    is_int((long)c.nonmanifold_verts, 1, "... and the shared vertex is non-manifold");
    m.ntris = 4;
    mesh_validate(&m, &c);
    ok(c.nonmanifold_verts == 0 && c.unused_verts == 3, "one tetrahedron: manifold, 3 unused vertices");
}

/* Intersecting pairs of m by testing every pair of triangles whose boxes overlap. */
static size_t brute_pairs(const frep_mesh *m)
{
    size_t n = 0;
    for (size_t s = 0; s < m->ntris; s++)
        for (size_t t = s + 1; t < m->ntris; t++) {
            uint32_t tri[6];
            memcpy(tri, &m->tri[3 * s], 3 * sizeof *tri);
            memcpy(tri + 3, &m->tri[3 * t], 3 * sizeof *tri);
            frep_mesh two = { m->nverts, 2, m->v, NULL, tri };
            size_t k;
            mesh_self_intersections(&two, &k, NULL);
            n += k;
        }
    return n;
}

/* The self-intersection test: pairs sharing nothing, a vertex or an edge, coplanar or
 * not, touching or crossing; and the grid against all pairs on a mesh. */
static void test_self_intersections(void)
{
    static const struct {
        double v[18];
        uint32_t t[6];
        int want;
        const char *what;
    } cases[] = {
        { { 0, 0, 0, 1, 0, 0, 0, 1, 0, .2, .2, -1, .2, .2, 1, 3, 3, 0 }, { 0, 1, 2, 3, 4, 5 }, 1,
          "a triangle piercing another" },
        { { 0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 2, -1, 2, 2, 1, 3, 3, 0 }, { 0, 1, 2, 3, 4, 5 }, 0,
          "two triangles apart" },
        { { 0, 0, 0, 1, 0, 0, 0, 1, 0, .5, .5, 0, 5, 0, 1, 0, 5, 1 }, { 0, 1, 2, 3, 4, 5 }, 1,
          "a vertex touching another triangle's edge" },
        { { 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0 }, { 0, 1, 2, 1, 0, 3 }, 0,
          "sharing an edge, at a right angle" },
        { { 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 0, 0, 0, 0, 0 }, { 0, 1, 2, 1, 0, 3 }, 1,
          "sharing an edge, folded flat onto each other" },
        { { 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 0, 0 }, { 0, 1, 2, 1, 0, 3 }, 0,
          "sharing an edge, flat, side by side" },
        { { 0, 0, 0, 1, 0, 0, 0, 1, 0, -1, 0, 0, 0, -1, 0, 0, 0, 0 }, { 0, 1, 2, 0, 3, 4 }, 0,
          "sharing a vertex, flat, apart" },
        { { 0, 0, 0, 1, 0, 0, 0, 1, 0, .3, .3, -1, .3, .3, 1, 0, 0, 0 }, { 0, 1, 2, 0, 3, 4 }, 1,
          "sharing a vertex, the opposite edge through the other" },
        { { 0, 0, 0, 1, 0, 0, 0, 1, 0, .5, .2, 0, .2, .5, 0, 0, 0, 0 }, { 0, 1, 2, 0, 3, 4 }, 1,
          "sharing a vertex, flat, one inside the other" },
        { { 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 1, -1, -1, 1, 0, 0, 0 }, { 0, 1, 2, 0, 3, 4 }, 0,
          "sharing a vertex, the other above" },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        double cv[18];
        uint32_t ct[6];
        memcpy(cv, cases[i].v, sizeof cv);
        memcpy(ct, cases[i].t, sizeof ct);
        frep_mesh m = { 6, 2, cv, NULL, ct };
        size_t n;
        mesh_self_intersections(&m, &n, NULL);
        is_int((long)n, cases[i].want, "self-intersection: %s", cases[i].what);
    }
    /* near-coplanar: a vertex 1e-17 below a far-off plane (the filter cannot decide) */
    double v[18] = { 1e6, 1e6, 0, 1e6 + 1, 1e6, 0, 1e6, 1e6 + 1, 0,
                     1e6 + .2, 1e6 + .2, -1e-17, 1e6 + .2, 1e6 + .3, -1, 1e6 + 3, 1e6 + 3, -1 };
    uint32_t t[6] = { 0, 1, 2, 3, 4, 5 };
    frep_mesh m = { 6, 2, v, NULL, t };
    size_t n;
    mesh_self_intersections(&m, &n, NULL);
    is_int((long)n, 0, "self-intersection: exact for a vertex just below a plane far out");
    v[11] = 0;
    mesh_self_intersections(&m, &n, NULL);
    is_int((long)n, 1, "... and touching when on it");

    tfield tf;
    memset(&tf, 0, sizeof tf);
    tf.kind = F_CSG;
    memcpy(tf.b, test_block, sizeof tf.b);
    const double box[6] = { -1.5, -1.5, -1.5, 1.5, 1.5, 1.5 };
    frep_mesh cm;
    mesh_stats st;
    if (run_mesh(&tf, box, 23, 1, &cm, &st) == 0) {
        size_t g;
        mesh_self_intersections(&cm, &g, NULL);
        size_t b = brute_pairs(&cm);
        ok(g == b, "self-intersections: the grid finds the %zu pairs of the all-pairs test (%zu)", b, g);
        mesh_free(&cm);
    }
}

/* One sheet crossing a cell face twice on both sides (tunnels of the gyroid thinner
 * than a cell): before face vertices, four quads shared a mesh edge on these grids. */
static void test_mesh_tunnels(void)
{
    static const struct { int grid; double box[6]; } cases[] = {
        { 24, { -1.55, -1.63, -1.6, 1.61, 1.58, 1.67 } },
        { 37, { -1.6, -1.6, -1.6, 1.6, 1.6, 1.6 } },
        { 45, { -1.55, -1.63, -1.6, 1.61, 1.58, 1.67 } },
    };
    size_t extra = 0;
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        tfield t;
        frep_mesh m;
        mesh_stats st;
        mesh_check c;
        char name[64];
        memset(&t, 0, sizeof t);
        t.kind = F_GYROID;
        snprintf(name, sizeof name, "gyroid -g %d", cases[i].grid);
        if (run_mesh(&t, cases[i].box, cases[i].grid, 2, &m, &st) == 0) {
            check_closed(name, &m, &c);
            extra += st.face_vertices;
            mesh_free(&m);
        } else {
            ok(0, "%s meshed", name);
        }
    }
    ok(extra > 0, "the gyroid needed %zu face vertices", extra);
    /* the face vertices do not depend on the thread count either */
    tfield t;
    memset(&t, 0, sizeof t);
    t.kind = F_GYROID;
    frep_mesh a, b;
    mesh_stats st;
    int ra = run_mesh(&t, cases[1].box, cases[1].grid, 1, &a, &st);
    int rb = run_mesh(&t, cases[1].box, cases[1].grid, 3, &b, &st);
    ok(ra == 0 && rb == 0 && st.face_vertices > 0 && a.nverts == b.nverts && a.ntris == b.ntris &&
       memcmp(a.v, b.v, 3 * a.nverts * sizeof *a.v) == 0 &&
       memcmp(a.tri, b.tri, 3 * a.ntris * sizeof *a.tri) == 0,
       "gyroid: the same mesh at 1 and 3 threads (%zu triangles)", a.ntris);
    mesh_free(&a);
    mesh_free(&b);
}

static void test_mesh_bad(void)
{
    const double box[6] = { -1.5, -1.5, -1.5, 1.5, 1.5, 1.5 };
    tfield t;
    frep_mesh m;
    mesh_stats st;
    mesh_check c;
    memset(&t, 0, sizeof t);
    t.kind = F_EMPTY;
    ok(run_mesh(&t, box, 20, 2, &m, &st) == 0 && m.ntris == 0 && !st.full,
       "empty model: no triangles");
    mesh_free(&m);
    t.kind = F_FULL;
    if (run_mesh(&t, box, 20, 2, &m, &st) == 0) {
        ok(st.full && st.touches_box, "full model: reported as filling the box");
        check_closed("full model (box caps)", &m, &c);
        ok(fabs(c.volume - 27) < 0.01 * 27, "full model: the mesh is the box (volume %.3f)", c.volume);
        mesh_free(&m);
    } else {
        ok(0, "full model meshed");
    }
    t.kind = F_NANHALF;
    if (run_mesh(&t, box, 24, 2, &m, &st) == 0) {
        ok(st.points_nan > 0, "NaN region: %zu NaN grid points counted", st.points_nan);
        check_closed("sphere cut by a NaN region", &m, &c);
        mesh_free(&m);
    } else {
        ok(0, "NaN region meshed");
    }
    t.kind = F_SPHERE;
    t.r = 1;
    /* a sphere cut by the box: capped, closed */
    const double half[6] = { -1.5, -1.5, -1.5, 1.5, 1.5, 0.25 };
    if (run_mesh(&t, half, 24, 2, &m, &st) == 0) {
        ok(st.touches_box, "sphere cut by the box touches it");
        check_closed("sphere cut by the box", &m, &c);
        mesh_free(&m);
    } else {
        ok(0, "cut sphere meshed");
    }
    mesh_field f = make_field(&t, 1);
    mesh_options o;
    frep_error err;
    mesh_options_init(&o);
    o.grid = 0;
    ok(polygonize(&f, &o, &m, &st, &err) != 0 && err.code == FREP_EINPUT, "grid 0 refused: %s", err.msg);
    o.grid = MESH_MAX_GRID + 1;
    ok(polygonize(&f, &o, &m, &st, &err) != 0 && err.code == FREP_EINPUT, "huge grid refused: %s", err.msg);
    o.grid = 10;
    o.box[3] = o.box[0];
    ok(polygonize(&f, &o, &m, &st, &err) != 0 && err.code == FREP_EINPUT, "zero-size box refused: %s", err.msg);
    mesh_options_init(&o);
    o.box[4] = NAN;
    ok(polygonize(&f, &o, &m, &st, &err) != 0 && err.code == FREP_EINPUT, "NaN box refused: %s", err.msg);
}

/* Write a mesh in every format, read it back: same triangles, same volume. */
static void test_meshio(void)
{
    const double box[6] = { -1.5, -1.5, -1.5, 1.5, 1.5, 1.5 };
    tfield t;
    memset(&t, 0, sizeof t);
    t.kind = F_CSG;
    memcpy(t.b, test_block, sizeof t.b);
    frep_mesh m;
    mesh_stats st;
    mesh_check c0;
    if (run_mesh(&t, box, 20, 2, &m, &st) != 0) {
        ok(0, "mesh for I/O");
        return;
    }
    mesh_validate(&m, &c0);
    static const struct { meshio_format f; int ascii; const char *name; } fm[] = {
        { MESHIO_STL, 0, "binary STL" }, { MESHIO_STL, 1, "ASCII STL" }, { MESHIO_OBJ, 0, "OBJ" },
        { MESHIO_PLY, 0, "binary PLY" }, { MESHIO_PLY, 1, "ASCII PLY" }, { MESHIO_OFF, 0, "OFF" },
    };
    for (size_t i = 0; i < sizeof fm / sizeof fm[0]; i++) {
        FILE *f = tmpfile();
        if (!f) { ok(0, "tmpfile"); continue; }
        int wr = meshio_write(f, &m, fm[i].f, fm[i].ascii);
        long len = ftell(f);
        rewind(f);
        char *buf = malloc((size_t)len + 1);
        size_t got = fread(buf, 1, (size_t)len, f);
        fclose(f);
        frep_mesh r;
        frep_error err;
        int rd = meshio_parse("mem", buf, got, fm[i].f, &r, &err);
        mesh_check c1;
        memset(&c1, 0, sizeof c1);
        if (rd == 0) mesh_validate(&r, &c1);
        ok(wr == 0 && rd == 0 && r.ntris == m.ntris && fabs(c1.volume - c0.volume) < 1e-5 * fabs(c0.volume),
           "%s: written and read back (%zu triangles, volume %.6f vs %.6f)%s%s", fm[i].name,
           rd == 0 ? r.ntris : 0, c1.volume, c0.volume, err.msg[0] ? ": " : "", err.msg[0] ? err.msg : "");
        free(buf);
        if (rd == 0) mesh_free(&r);
    }
    mesh_free(&m);
    static const struct { meshio_format f; const char *text; const char *want; } bad[] = {
        { MESHIO_OFF, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n", "mem:6: vertex index 3" },
        { MESHIO_OFF, "OFF\n3 1 0\n0 0 0\n1 0\n", "mem:4: expected 3 coordinates" },
        { MESHIO_OBJ, "v 0 0 0\nv 1 0 0\nf 1 2 3\n", "mem:3: vertex index 3 out of range" },
        { MESHIO_PLY, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
          "mem: the vertex element lacks" },
        { MESHIO_STL, "hello", "mem: neither binary STL" },
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        frep_mesh r;
        frep_error err;
        int rd = meshio_parse("mem", bad[i].text, strlen(bad[i].text), bad[i].f, &r, &err);
        ok(rd != 0 && err.msg[0] && strncmp(err.msg, bad[i].want, strlen(bad[i].want)) == 0,
           "bad mesh file: '%s'", err.msg[0] ? err.msg : "(no message)");
    }
    /* an element without properties holds no data, however many records it declares
     * (up to MESHIO_MAX_ELEMENTS) */
    static const char empty[] = "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
                                "property uchar x\nproperty uchar y\nproperty uchar z\n"
                                "element junk 268435456\nelement face 1\n"
                                "property list uchar uchar vertex_indices\nend_header\n"
                                "\0\0\0\1\0\0\0\1\0\3\0\1\2";
    frep_mesh r;
    frep_error err;
    int rd = meshio_parse("mem", empty, sizeof empty - 1, MESHIO_PLY, &r, &err);
    ok(rd == 0 && r.ntris == 1, "binary PLY with a property-less element of 2^28 records: %s",
       rd == 0 ? "read" : err.msg);
    if (rd == 0) mesh_free(&r);
}

/* ---- tape pruning (vm_prune) and the program field ---------------------------------- */

/* A gear: a loop of teeth unioned by R-functions (unrolled by the compiler), a body,
 * a hub and a bore; the pruner has plenty to drop away from each tooth. */
static const char prune_src[] =
    "my_model(x[3], a[1])\n"
    "{\n"
    "  array c[3];\n"
    "  c = [0, 0, 0];\n"
    "  body = hfCylinderZ(x, c, 1.2) & (0.25 - x[3]) & (x[3] + 0.25);\n"
    "  teeth = -1;\n"
    "  i = 0;\n"
    "  while i < 9 loop\n"
    "    t = 2 * 3.14159265358979 * i / 9;\n"
    "    u = cos(t) * x[1] + sin(t) * x[2];\n"
    "    v = cos(t) * x[2] - sin(t) * x[1];\n"
    "    teeth = teeth | ((u - 1.1) & (1.45 - u) & (0.12 - v) & (v + 0.12));\n"
    "    i = i + 1;\n"
    "  endloop;\n"
    "  my_model = ((body | (teeth & (0.25 - x[3]) & (x[3] + 0.25))) \\ hfCylinderZ(x, c, 0.3))"
    " | hfSphere(x, c, 0.5);\n"
    "}\n";

static frep_program *compile_text(const char *src, int setops)
{
    frep_compile_options o;
    frep_compile_options_init(&o);
    o.setops_override = setops;
    return frep_compile("prune.hf", src, strlen(src), &o, NULL, NULL);
}

static void test_prune_program(int setops)
{
    const char *name = setops == FREP_SETOPS_MINMAX ? "min/max" : "R-functions";
    frep_program *p = compile_text(prune_src, setops);
    ok(p != NULL, "%s: the gear compiles", name);
    if (!p) return;
    vm_pruner *pr = vm_pruner_new(p);
    ok(pr != NULL, "%s: straight-line code can be pruned", name);
    vm_iscratch *is = vm_iscratch_new(p);
    frep_scratch *s = frep_scratch_new(p);
    frep_program sub = *p;
    sub.code = malloc(p->ncode * sizeof *sub.code);
    sub.pos = malloc(p->ncode * sizeof *sub.pos);
    uint32_t *orig = malloc(p->ncode * sizeof *orig);
    uint64_t seed = 7;
    long shorter = 0, sign_bad = 0, value_bad = 0, checked = 0, orig_bad = 0;
    uint32_t shortest = p->ncode;
    for (int trial = 0; pr && trial < 200; trial++) {
        double box[6];
        for (int c = 0; c < 3; c++) {
            double a = rnd(&seed) * 3.2 - 1.6, w = 0.05 + rnd(&seed) * (trial % 4 ? 0.2 : 1);
            box[c] = a;
            box[c + 3] = a + w;
        }
        ival r;
        uint32_t n = 0;
        double tol = -1;
        if (vm_prune(pr, is, box, NULL, sub.code, sub.pos, orig, &n, &r, &tol) != 0) continue;
        sub.ncode = n;
        if (n < p->ncode) shorter++;
        if (n < shortest) shortest = n;
        for (uint32_t i = 0; i < n; i++)
            if (orig[i] >= p->ncode || (orig[i] > 0 && i > 0 && orig[i] <= orig[i - 1])) orig_bad++;
        double x[64], y[64], z[64], f[64], g[64];
        for (int i = 0; i < 64; i++) {
            x[i] = box[0] + (box[3] - box[0]) * rnd(&seed);
            y[i] = box[1] + (box[4] - box[1]) * rnd(&seed);
            z[i] = box[2] + (box[5] - box[2]) * rnd(&seed);
        }
        frep_eval(p, s, 64, x, y, z, NULL, f);
        frep_eval(&sub, s, 64, x, y, z, NULL, g);
        for (int i = 0; i < 64; i++) {
            checked++;
            if (fabs(g[i]) >= tol && (g[i] >= 0) != (f[i] >= 0)) sign_bad++;
            if (setops == FREP_SETOPS_MINMAX && g[i] != f[i]) value_bad++;
        }
    }
    ok(shorter > 50, "%s: %ld of 200 boxes give a shorter program (shortest %u of %u)", name,
       shorter, shortest, p->ncode);
    ok(sign_bad == 0, "%s: pruned values have the original's sign at %ld points", name, checked);
    if (setops == FREP_SETOPS_MINMAX)
        ok(value_bad == 0, "min/max: pruned values equal the original's exactly");
    ok(orig_bad == 0, "%s: the pc map points into the original program, in order", name);

    /* meshing with and without pruning: the same topology, vertices within 1e-3 cell */
    mesh_options o;
    cube_options(&o, 1.6, 61, 1); /* no plane of the model on the grid: no ties at zero */
    frep_mesh a, b, c3;
    mesh_stats st;
    frep_error err;
    mesh_field f;
    mesh_field_program(&f, p, NULL);
    o.nthreads = 1;
    int ra = polygonize(&f, &o, &a, &st, &err);
    o.nthreads = 3;
    int rc = polygonize(&f, &o, &c3, &st, &err);
    f.focus = NULL;
    o.nthreads = 1;
    int rb = polygonize(&f, &o, &b, &st, &err);
    mesh_field_program_free(&f);
    ok(ra == 0 && rb == 0 && rc == 0, "%s: meshed with and without pruning", name);
    if (ra == 0 && rb == 0 && rc == 0) {
        /* The same cells hold the same vertices.  The R-function blends near creases
         * see other values, which may tip the QEF's rank decision of a cell (a vertex
         * snaps to an edge or stays at the mass point) or a quad's diagonal: rare,
         * and bounded by the cell. */
        ok(a.nverts == b.nverts && a.ntris == b.ntris,
           "%s: pruning keeps the vertices and triangles (%zu, %zu)", name, a.nverts, a.ntris);
        double dmax = 0, dsum = 0;
        for (size_t i = 0; a.nverts == b.nverts && i < a.nverts; i++) {
            double d = 0;
            for (int k = 0; k < 3; k++) d = fmax(d, fabs(a.v[3 * i + k] - b.v[3 * i + k]));
            dmax = fmax(dmax, d);
            dsum += d;
        }
        double cell = 3.2 / 61;
        ok(dmax < cell && dsum / (double)a.nverts < 0.01 * cell,
           "%s: vertices move by %.2g cell at most, %.2g on average", name, dmax / cell,
           dsum / (double)a.nverts / cell);
        ok(a.nverts == c3.nverts && memcmp(a.v, c3.v, 3 * a.nverts * sizeof *a.v) == 0,
           "%s: pruned meshes are the same at 1 and 3 threads", name);
        mesh_check ck;
        mesh_validate(&a, &ck);
        ok(ck.open_edges == 0 && ck.nonmanifold_edges == 0 && ck.flipped_edges == 0 &&
           ck.degenerate == 0, "%s: the pruned mesh is closed and manifold", name);
    }
    if (ra == 0) mesh_free(&a);
    if (rb == 0) mesh_free(&b);
    if (rc == 0) mesh_free(&c3);
    free(sub.code);
    free(sub.pos);
    free(orig);
    vm_pruner_free(pr);
    vm_iscratch_free(is);
    frep_scratch_free(s);
    frep_program_free(p);
}

/* Domain errors raised while meshing reach mesh_field_program_errors with the
 * original program's pc, pruned or not. */
/* Settling evaluates a block's short runs of points on the whole program
 * (SETTLE_FOCUS_MIN): pruning the program for the block would cost more than the run.
 * The field's callbacks, counted: the points evaluated after each focus on a box. */
#define FOCUS_RUNS 4096
typedef struct focus_count {
    mesh_field inner;
    long boxes;                       /* focus calls with a box */
    size_t run[FOCUS_RUNS];           /* points evaluated after each, until the next */
    int focused;
} focus_count;

static int counting_focus(void *ctx, void *ts, const double box[6], double *sign_tol)
{
    focus_count *c = ctx;
    c->focused = box != NULL;
    if (box && c->boxes < FOCUS_RUNS) c->run[c->boxes] = 0;
    if (box) c->boxes++;
    return c->inner.focus(c->inner.ctx, ts, box, sign_tol);
}
static void count_points(focus_count *c, size_t n)
{
    if (c->focused && c->boxes <= FOCUS_RUNS) c->run[c->boxes - 1] += n;
}
static void *counting_thread_new(void *ctx)
{
    focus_count *c = ctx;
    return c->inner.thread_new(c->inner.ctx);
}
static void counting_thread_free(void *ctx, void *ts)
{
    focus_count *c = ctx;
    c->inner.thread_free(c->inner.ctx, ts);
}
static int counting_eval(void *ctx, void *ts, size_t n, const double *x, const double *y,
                         const double *z, double *f)
{
    focus_count *c = ctx;
    count_points(c, n);
    return c->inner.eval(c->inner.ctx, ts, n, x, y, z, f);
}
static int counting_grad(void *ctx, void *ts, size_t n, const double *x, const double *y,
                         const double *z, double *f, double *gx, double *gy, double *gz)
{
    focus_count *c = ctx;
    count_points(c, n);
    return c->inner.grad(c->inner.ctx, ts, n, x, y, z, f, gx, gy, gz);
}
static int counting_interval(void *ctx, void *ts, const double box[6], double *lo, double *hi)
{
    focus_count *c = ctx;
    return c->inner.interval(c->inner.ctx, ts, box, lo, hi);
}

static void test_settle_focus(void)
{
    frep_program *p = compile_text(prune_src, FREP_SETOPS_MINMAX);
    if (!p) return;
    static focus_count c;
    memset(&c, 0, sizeof c);
    mesh_field_program(&c.inner, p, NULL);
    mesh_field f = c.inner;
    f.ctx = &c;
    f.thread_new = counting_thread_new;
    f.thread_free = counting_thread_free;
    f.eval = counting_eval;
    f.grad = counting_grad;
    f.interval = counting_interval;
    f.focus = counting_focus;
    mesh_options o;
    cube_options(&o, 1.6, 61, 1);   /* one thread: the callbacks' counts are not atomic */
    frep_mesh m;
    mesh_stats st;
    frep_error err;
    /* the focus calls without settling, then with it: settling's come after those */
    o.no_projection = 1;
    int rc = polygonize(&f, &o, &m, &st, &err);
    if (rc == 0) mesh_free(&m);
    long contour = c.boxes;
    c.boxes = 0;
    o.no_projection = 0;
    rc |= polygonize(&f, &o, &m, &st, &err);
    ok(rc == 0 && st.settled > 0 && c.boxes <= FOCUS_RUNS,
       "settling's focus: the gear meshed, %zu vertices settled", st.settled);
    long shortest = -1;
    for (long i = contour; i < c.boxes && i < FOCUS_RUNS; i++)
        if (shortest < 0 || (long)c.run[i] < shortest) shortest = (long)c.run[i];
    ok(rc == 0 && c.boxes >= contour && (shortest < 0 || shortest >= SETTLE_FOCUS_MIN),
       "settling's focus: %ld focused runs while contouring; while settling %ld, each of "
       "at least %d points (shortest %ld)", contour, c.boxes - contour, SETTLE_FOCUS_MIN,
       shortest);
    if (rc == 0) mesh_free(&m);
    mesh_field_program_free(&c.inner);
    frep_program_free(p);
}

static void test_mesh_errors(void)
{
    const char *src = "my_model(x[3], a[1])\n{\n  b = 0.5 - x[1] * x[1] - x[2] * x[2] - x[3] * x[3];\n"
                      "  my_model = (b | (x[1] - 5)) + 0 * sqrt(x[1]);\n}\n";
    frep_program *p = compile_text(src, -1);
    ok(p != NULL, "error model compiles");
    if (!p) return;
    uint32_t sqrt_pc = UINT32_MAX;
    for (uint32_t pc = 0; pc < p->ncode; pc++)
        if (p->code[pc].op == FREP_OP_SQRT) sqrt_pc = pc;
    mesh_options o;
    cube_options(&o, 1, 20, 2);
    mesh_field f;
    mesh_field_program(&f, p, NULL);
    frep_mesh m;
    mesh_stats st;
    frep_error err;
    int rc = polygonize(&f, &o, &m, &st, &err);
    frep_runtime_error e;
    mesh_field_program_errors(&f, &e);
    mesh_field_program_free(&f);
    ok(rc == 0 && e.count > 0 && e.pc == sqrt_pc && e.x < 0,
       "sqrt of a negative is reported at pc %u (expected %u), %llu times, at x = %g", e.pc,
       sqrt_pc, (unsigned long long)e.count, e.x);
    if (rc == 0) mesh_free(&m);
    frep_program_free(p);
}

/* An allocator failing allocation number fail_at (counting from 1; 0: none). */
typedef struct failing_alloc {
    long count, fail_at;
} failing_alloc;

static void *failing_alloc_fn(void *user, void *p, size_t n)
{
    failing_alloc *a = user;
    if (n == 0) {
        free(p);
        return NULL;
    }
    if (++a->count == a->fail_at) return NULL;
    return realloc(p, n);
}

/* Every allocation of a run failing in turn: the run fails with FREP_ENOMEM and
 * "out of memory" (possibly with what it was doing), never with another report. */
static void test_mesh_nomem(void)
{
    tfield t;
    memset(&t, 0, sizeof t);
    t.kind = F_SPHERE;
    t.r = 1;
    mesh_field f = make_field(&t, 1);
    mesh_options o;
    cube_options(&o, 1.5, 20, 1);
    failing_alloc fa = { 0, 0 };
    frep_set_allocator(failing_alloc_fn, &fa);
    frep_mesh m;
    mesh_stats st;
    frep_error err;
    int rc0 = polygonize(&f, &o, &m, &st, &err);
    mesh_free(&m);
    long total = fa.count, failed = 0, wrong = 0;
    for (long k = 1; k <= total; k++) {
        fa.count = 0;
        fa.fail_at = k;
        if (polygonize(&f, &o, &m, &st, &err) == 0) {
            mesh_free(&m);
            continue;
        }
        failed++;
        if (err.code != FREP_ENOMEM || strncmp(err.msg, "out of memory", 13) != 0) {
            if (wrong++ == 0) diag("allocation %ld: '%s'", k, err.msg);
        }
    }
    frep_set_allocator(NULL, NULL);
    ok(rc0 == 0 && total > 0 && failed == total && wrong == 0,
       "each of %ld allocations failing: %ld runs fail, %ld not as out of memory", total, failed,
       wrong);
}

/* frep_prefault on n bytes at an unaligned address of a zeroed buffer, then on the
 * same bytes written: the contents and the bytes beside them stay as they were. */
static void prefault_keeps(size_t n)
{
    unsigned char *z = frep_calloc(1, n + 8);
    int kept = z != NULL;
    if (z) {
        frep_prefault(z + 3, n);
        for (size_t k = 0; k < n + 8; k++) kept &= z[k] == 0;
        for (size_t k = 0; k < n + 8; k++) z[k] = (unsigned char)(k * 31);
        frep_prefault(z + 3, n);
        for (size_t k = 0; k < n + 8; k++) kept &= z[k] == (unsigned char)(k * 31);
    }
    ok(kept, "frep_prefault keeps the contents of %zu bytes", n);
    frep_free(z);
}

/* The blocks' pools: every allocation aligned, none overlapping another across slab
 * boundaries, one larger than a slab in a slab of its own; frep_prefault keeps a
 * buffer's contents, at unaligned ends too. */
static void test_mesh_pools(void)
{
    mmem mem = { 0 };
    mesher M = { .nthreads = 1, .mems = &mem };
    enum { N = 3000 };
    unsigned char *a[N];
    size_t len[N];
    int aligned = 1, got = 1;
    for (int i = 0; i < N; i++) {
        len[i] = 1 + (size_t)(i * 7919) % 2000;   /* ~3 MB in all: several slabs */
        a[i] = mesh_pool_alloc(&mem.pool[MESH_POOL_POS], len[i]);
        got &= a[i] != NULL;
        if (!a[i]) break;
        aligned &= (uintptr_t)a[i] % _Alignof(max_align_t) == 0;
        memset(a[i], i & 0xFF, len[i]);
    }
    ok(got && aligned, "pool: %d allocations, aligned for any type", N);
    int kept = got;
    for (int i = 0; i < N && kept; i++)
        for (size_t k = 0; k < len[i]; k++) kept &= a[i][k] == (unsigned char)(i & 0xFF);
    ok(kept, "pool: no allocation overwrites another");
    size_t big = MESH_SLAB_BYTES + 12345;
    unsigned char *b = mesh_pool_alloc(&mem.pool[MESH_POOL_POS], big);
    unsigned char *c = mesh_pool_alloc(&mem.pool[MESH_POOL_POS], 64);
    if (b) memset(b, 0xA5, big);
    if (c) memset(c, 0x5A, 64);
    ok(b && c && b[0] == 0xA5 && b[big - 1] == 0xA5 && (c + 64 <= b || c >= b + big),
       "pool: an allocation larger than a slab (%zu bytes)", big);
    mesh_pools_free(&M, MESH_POOL_POS);
    ok(mem.pool[MESH_POOL_POS].slabs == NULL, "pool: freed whole");

    prefault_keeps(5 * FREP_PREFAULT_MIN_BYTES + 333);
    prefault_keeps(3 * FREP_HUGE_PAGE_BYTES + 333);   /* huge pages offered inside */
}

/* The whole of a meshio_write into memory (malloc'd, *len bytes); NULL on failure. */
static char *written(const frep_mesh *m, const uint8_t *rgb, meshio_format fmt, int ascii, size_t *len)
{
    FILE *f = tmpfile();
    if (!f) return NULL;
    char *buf = NULL;
    if (meshio_write_colored(f, m, rgb, fmt, ascii) == 0) {
        long n = ftell(f);
        rewind(f);
        buf = n >= 0 ? malloc((size_t)n + 1) : NULL;
        if (buf) *len = fread(buf, 1, (size_t)n, f);
    }
    fclose(f);
    return buf;
}

/* The text formats are formatted in chunks on several threads (geom/meshio.c,
 * write_text): the bytes are those of one line at a time, at any thread count.  A
 * mesh of 70,001 vertices and triangles (over two rounds of chunks on 3 threads) with
 * values of every magnitude; the reference OFF is printed here line by line. */
static void test_meshio_text_threads(void)
{
    const size_t n = 70001;
    frep_mesh m;
    memset(&m, 0, sizeof m);
    m.nverts = m.ntris = n;
    m.v = malloc(3 * n * sizeof *m.v);
    m.n = malloc(3 * n * sizeof *m.n);
    m.tri = malloc(3 * n * sizeof *m.tri);
    uint8_t *rgb = malloc(3 * n);
    char *ref = malloc(160 * n + 64);
    if (!m.v || !m.n || !m.tri || !rgb || !ref) {
        ok(0, "text formats on threads: out of memory");
        return;
    }
    uint64_t st = 12345;
    for (size_t i = 0; i < 3 * n; i++) {
        st = st * 6364136223846793005ULL + 1442695040888963407ULL;
        double u = (double)(st >> 11) / 9007199254740992.0;
        m.v[i] = (u - 0.5) * pow(10, (double)(i % 37) - 18);
        m.n[i] = u - 0.5;
        m.tri[i] = (uint32_t)((st >> 20) % n);
        rgb[i] = (uint8_t)(st >> 40);
    }
    m.tri[0] = 0;            /* the smallest and largest indices */
    m.tri[1] = (uint32_t)n - 1;
    size_t rl = (size_t)sprintf(ref, "OFF\n%zu %zu 0\n", n, n);
    for (size_t i = 0; i < n; i++)
        rl += (size_t)sprintf(ref + rl, "%.10g %.10g %.10g\n", m.v[3 * i], m.v[3 * i + 1], m.v[3 * i + 2]);
    for (size_t t = 0; t < n; t++)
        rl += (size_t)sprintf(ref + rl, "3 %u %u %u\n", m.tri[3 * t], m.tri[3 * t + 1], m.tri[3 * t + 2]);
    size_t len = 0;
    char *off = written(&m, NULL, MESHIO_OFF, 0, &len);
    ok(off && len == rl && memcmp(off, ref, rl) == 0, "OFF of %zu vertices: the bytes of one line at a time", n);
    free(off);
    rl = (size_t)sprintf(ref, "# written by frep: %zu vertices, %zu triangles\n", n, n);
    for (size_t i = 0; i < n; i++)
        rl += (size_t)sprintf(ref + rl, "v %.10g %.10g %.10g\n", m.v[3 * i], m.v[3 * i + 1], m.v[3 * i + 2]);
    for (size_t i = 0; i < n; i++)
        rl += (size_t)sprintf(ref + rl, "vn %.6g %.6g %.6g\n", m.n[3 * i], m.n[3 * i + 1], m.n[3 * i + 2]);
    for (size_t t = 0; t < n; t++) {
        uint32_t a = m.tri[3 * t] + 1, b = m.tri[3 * t + 1] + 1, c = m.tri[3 * t + 2] + 1;
        rl += (size_t)sprintf(ref + rl, "f %u//%u %u//%u %u//%u\n", a, a, b, b, c, c);
    }
    char *obj = written(&m, NULL, MESHIO_OBJ, 0, &len);
    ok(obj && len == rl && memcmp(obj, ref, rl) == 0, "OBJ with normals: the bytes of one line at a time");
    free(obj);
    static const struct { meshio_format f; int ascii, rgb; const char *name; } fm[] = {
        { MESHIO_OFF, 0, 0, "OFF" }, { MESHIO_OBJ, 0, 0, "OBJ" }, { MESHIO_STL, 1, 0, "ASCII STL" },
        { MESHIO_PLY, 1, 1, "ASCII PLY" }, { MESHIO_WRL, 0, 1, "VRML" },
    };
    for (size_t k = 0; k < sizeof fm / sizeof fm[0]; k++) {
        size_t l1 = 0, l3 = 0;
#ifdef _OPENMP
        int was = omp_get_max_threads();
        omp_set_num_threads(1);
#endif
        char *a = written(&m, fm[k].rgb ? rgb : NULL, fm[k].f, fm[k].ascii, &l1);
#ifdef _OPENMP
        omp_set_num_threads(3);
#endif
        char *b = written(&m, fm[k].rgb ? rgb : NULL, fm[k].f, fm[k].ascii, &l3);
#ifdef _OPENMP
        omp_set_num_threads(was);
#endif
        ok(a && b && l1 == l3 && l1 > 0 && memcmp(a, b, l1) == 0,
           "%s: the same %zu bytes on 1 and 3 threads", fm[k].name, l1);
        free(a);
        free(b);
    }
    free(m.v);
    free(m.n);
    free(m.tri);
    free(rgb);
    free(ref);
}

int main(void)
{
    test_interval_ops();
    test_interval_tight();
    test_interval_program();
    test_mesh_shapes();
    test_mesh_threads();
    test_mesh_thread_sizing();
    test_validate_pinch();
    test_self_intersections();
    test_mesh_tunnels();
    test_mesh_bad();
    test_mesh_nomem();
    test_mesh_pools();
    test_meshio();
    test_meshio_text_threads();
    test_prune_program(-1);
    test_prune_program(FREP_SETOPS_MINMAX);
    test_settle_focus();
    test_mesh_errors();
    return done_testing();
}
