/* test_faults.c - fault injection: every library entry point, on a small input, runs
 * once to count its allocations and then once more for every N from 1 to that count
 * with allocation N failing (tests/faults.h). Each run must not crash, must fail with
 * a status (or give the clean run's result when the failure was absorbed), must leave
 * no block alive, and where the API has an error message it must say "out of memory".
 *
 * Environment: FREP_FAULT_CASE=NAME runs only the cases whose name contains NAME,
 * FREP_FAULT_N=N only the run with allocation N failing, FREP_FAULT_VERBOSE=1 prints
 * each run (to find a crash), FREP_FAULT_TRACE=K (faults.h) the stack of allocation K.
 */
#include "config.h"

#include "buf.h"
#include "cloud.h"
#include "evolve.h"
#include "faults.h"
#include "fit.h"
#include "fitfile.h"
#include "frep.h"
#include "interval.h"
#include "kdtree.h"
#include "mesh.h"
#include "meshio.h"
#include "normals.h"
#include "distance.h"
#include "page.h"
#include "png.h"
#include "prune.h"
#include "refit.h"
#include "render.h"
#include "residual.h"
#include "sample.h"
#include "scad.h"
#include "segment.h"
#include "tap.h"
#include "util.h"
#include "writeback.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif

/* ---- what one run of a case gives --------------------------------------------------- */

#define OUT_MSG 600

typedef struct fault_out {
    uint64_t digest;        /* hash of the result, compared with the clean run's */
    char msg[OUT_MSG];      /* the error message of a failed run ("" when none) */
} fault_out;

static void digest_bytes(fault_out *o, const void *p, size_t n)
{
    const unsigned char *b = p;
    uint64_t h = o->digest ? o->digest : 1469598103934665603ull;
    for (size_t i = 0; i < n; i++) h = (h ^ b[i]) * 1099511628211ull;
    o->digest = h;
}

static void digest_doubles(fault_out *o, const double *v, size_t n)
{
    digest_bytes(o, v, n * sizeof *v);
}

static void digest_size(fault_out *o, size_t v) { digest_bytes(o, &v, sizeof v); }

static void set_msg(fault_out *o, const char *m)
{
    if (m && !o->msg[0]) snprintf(o->msg, sizeof o->msg, "%s", m);
}

/* Diagnostic callback: the first error's message. */
static void on_diag(void *user, const frep_diag *d)
{
    if (d->severity == FREP_ERROR) set_msg(user, d->message);
}

/* Bytes written to a memory stream, hashed into the digest; -1 when rc is. */
typedef struct mem_out {
    char *buf;
    size_t len;
    FILE *f;
} mem_out;

static FILE *mem_open(mem_out *m)
{
    m->buf = NULL;
    m->len = 0;
    m->f = open_memstream(&m->buf, &m->len);
    return m->f;
}

static int mem_close(mem_out *m, fault_out *o, int rc)
{
    if (fclose(m->f)) rc = -1;
    if (rc == 0) digest_bytes(o, m->buf, m->len);
    free(m->buf);
    return rc;
}

/* ---- fixtures: built once, without injected failures ------------------------------- */

/* A blend of two spheres with two free parameters and a box pragma. */
static const char model_src[] =
    "-- @box -2 -2 -2 2 2 2\n"
    "my_model(x[3], a[1])\n"
    "{\n"
    "    array c[3];\n"
    "    r = 1;     -- @free [0.5, 2]\n"
    "    d = 0.5;   -- @free [0, 1]\n"
    "    c = [d, 0, 0];\n"
    "    s1 = hfSphere(x, c, r);\n"
    "    c = [-d, 0, 0];\n"
    "    my_model = s1 | hfSphere(x, c, r) & (1 - x[3]) ;\n"
    "}\n"
    "other(x[3], a[1])\n"
    "{\n"
    "    other = 1 - sqrt(x[1]);\n"
    "}\n";

/* A model with an error, for the diagnostic paths. */
static const char bad_src[] =
    "my_model(x[3], a[1])\n"
    "{\n"
    "    my_model = hfSpher(x, 1);\n"
    "}\n";

/* The cube [-1,1]^3 as six half-spaces (min/max), the input of segment and evolve. */
static const char cube_src[] =
    "-- @setops minmax\n"
    "-- @box -1.5 -1.5 -1.5 1.5 1.5 1.5\n"
    "my_model(x[3], a[1])\n"
    "{\n"
    "    my_model = frPlane(x, 1, 0, 0, 1) & frPlane(x, -1, 0, 0, 1) &\n"
    "               frPlane(x, 0, 1, 0, 1) & frPlane(x, 0, -1, 0, 1) &\n"
    "               frPlane(x, 0, 0, 1, 1) & frPlane(x, 0, 0, -1, 1);\n"
    "}\n";

static const char cube_fit[] =
    "# the cube\n"
    "plane 1 0 0 1\nplane -1 0 0 1\nplane 0 1 0 1\nplane 0 -1 0 1\n"
    "sphere 3 3 3 0.5\nplane 0 0 1 1\nplane 0 0 -1 1\n";

typedef struct fixture {
    frep_program *prog;       /* model_src */
    frep_program *cube;       /* cube_src */
    frep_mesh mesh;           /* model_src polygonized on a coarse grid */
    frep_cloud *cloud;        /* CLOUD_POINTS points with normals on the cube */
    prim *prims;              /* cube_fit */
    size_t nprims;
    evolve_result evolved;    /* evolve_run on cloud and prims */
    char tmpdir[64];
} fixture;

/* Most primitives of a fixture list. */
#define MAX_PRIMS 16

/* Points of the fixture cloud: enough for segmentation to find the six faces. */
#define CLOUD_POINTS 120

#define NPTS 37
static double px[NPTS], py[NPTS], pz[NPTS];

/* ---- the cases: one function per entry point --------------------------------------- */

static int case_compile(const fixture *fx, fault_out *o)
{
    (void)fx;
    frep_compile_options opt;
    frep_compile_options_init(&opt);
    frep_program *p = frep_compile("m.hf", model_src, strlen(model_src), &opt, on_diag, o);
    if (!p) return -1;
    digest_size(o, frep_program_size(p));
    digest_size(o, frep_program_nparams(p));
    frep_program_free(p);
    return 0;
}

static int case_compile_error(const fixture *fx, fault_out *o)
{
    (void)fx;
    frep_compile_options opt;
    frep_compile_options_init(&opt);
    frep_program *p = frep_compile("bad.hf", bad_src, strlen(bad_src), &opt, on_diag, o);
    frep_program_free(p);
    return p ? 0 : -1;
}

static int case_list_models(const fixture *fx, fault_out *o)
{
    (void)fx;
    size_t n = 0;
    char **v = frep_list_models("m.hf", model_src, strlen(model_src), &n, on_diag, o);
    if (!v) return -1;
    for (size_t i = 0; i < n; i++) digest_bytes(o, v[i], strlen(v[i]));
    frep_free_strings(v, n);
    return 0;
}

static int case_disassemble(const fixture *fx, fault_out *o)
{
    char *s = frep_disassemble(fx->prog);
    if (!s) return -1;
    digest_bytes(o, s, strlen(s));
    frep_free(s);
    return 0;
}

static int case_print_source(const fixture *fx, fault_out *o)
{
    (void)fx;
    size_t n = 0;
    char *s = frep_print_source("m.hf", model_src, strlen(model_src), 1, &n, on_diag, o);
    if (!s) return -1;
    digest_bytes(o, s, n);
    frep_free(s);
    return 0;
}

static int case_diag_format(const fixture *fx, fault_out *o)
{
    (void)fx;
    frep_diag d = { FREP_ERROR, "m.hf", 3, 16, 7, "unknown function 'hfSpher'" };
    char *s = frep_diag_format(&d, bad_src, strlen(bad_src));
    if (!s) return -1;
    digest_bytes(o, s, strlen(s));
    frep_free(s);
    return 0;
}

/* frep_eval, frep_eval_grad and frep_eval_dparams on one scratch. */
static int case_eval(const fixture *fx, fault_out *o)
{
    double f[NPTS], gx[NPTS], gy[NPTS], gz[NPTS];
    size_t np = frep_program_nparams(fx->prog);
    double *dp = malloc((np ? np : 1) * NPTS * sizeof *dp);
    frep_scratch *s = frep_scratch_new(fx->prog);
    if (!s || !dp) {
        free(dp);
        frep_scratch_free(s);
        return -1;
    }
    int rc = frep_eval(fx->prog, s, NPTS, px, py, pz, NULL, f);
    if (!rc) rc = frep_eval_grad(fx->prog, s, NPTS, px, py, pz, NULL, f, gx, gy, gz);
    if (!rc) rc = frep_eval_dparams(fx->prog, s, NPTS, px, py, pz, NULL, f, dp);
    frep_runtime_error e;
    frep_scratch_errors(s, &e);
    if (e.count) frep_report_runtime_error(fx->prog, &e, on_diag, o);
    frep_scratch_free(s);
    if (!rc) {
        digest_doubles(o, f, NPTS);
        digest_doubles(o, gx, NPTS);
        digest_doubles(o, dp, np * NPTS);
    }
    free(dp);
    return rc ? -1 : 0;
}

/* The OpenMP evaluators on two threads (the allocation order may then vary). */
static int case_eval_par(const fixture *fx, fault_out *o)
{
    double f[NPTS], gx[NPTS], gy[NPTS], gz[NPTS];
    frep_runtime_error e;
    if (frep_eval_par(fx->prog, NPTS, px, py, pz, NULL, f, 2, &e)) return -1;
    if (frep_eval_grad_par(fx->prog, NPTS, px, py, pz, NULL, f, gx, gy, gz, 2, &e)) return -1;
    digest_doubles(o, f, NPTS);
    digest_doubles(o, gx, NPTS);
    return 0;
}

/* Interval evaluation and tape pruning of one box. */
static int case_interval(const fixture *fx, fault_out *o)
{
    static const double box[6] = { -2, -2, -2, 0.1, 0.2, 0.3 };
    const frep_program *p = fx->prog;
    vm_iscratch *s = vm_iscratch_new(p);
    vm_pruner *r = vm_pruner_new(p);
    frep_insn *code = malloc(p->ncode * sizeof *code);
    frep_srcpos *pos = malloc(p->ncode * sizeof *pos);
    uint32_t *orig = malloc(p->ncode * sizeof *orig);
    int rc = -1;
    ival v;
    uint32_t n;
    double tol;
    if (s && r && code && pos && orig && !vm_eval_interval(p, s, box, NULL, &v) &&
        !vm_prune(r, s, box, NULL, code, pos, orig, &n, &v, &tol)) {
        digest_doubles(o, &v.lo, 1);
        digest_doubles(o, &v.hi, 1);
        digest_size(o, n);
        rc = 0;
    }
    free(code);
    free(pos);
    free(orig);
    vm_pruner_free(r);
    vm_iscratch_free(s);
    return rc;
}

/* prune_plan_new, prune_for_box and prune_for_subbox. */
static int case_prune(const fixture *fx, fault_out *o)
{
    static const double box[6] = { -2, -2, -2, 0.1, 0.2, 0.3 };
    static const double sub[6] = { -1, -1, -1, 0, 0, 0 };
    prune_plan *pl = prune_plan_new(fx->prog);
    prune_state *a = pl ? prune_state_new(pl) : NULL, *b = pl ? prune_state_new(pl) : NULL;
    int rc = -1;
    ival v, w;
    const frep_program *q;
    if (a && b && (q = prune_for_box(pl, a, box, NULL, &v)) &&
        (q = prune_for_subbox(pl, b, a, sub, NULL, &w))) {
        digest_size(o, q->ncode);
        digest_doubles(o, &w.lo, 1);
        rc = 0;
    }
    prune_state_free(a);
    prune_state_free(b);
    prune_plan_free(pl);
    return rc;
}

/* The tiled grid evaluator with pruning: values of two planes, then the summary. */
static int case_grid(const fixture *fx, fault_out *o)
{
    static const double box[6] = { -2, -2, -2, 2, 2, 2 };
    enum { N = 20 };
    double *f = malloc(2 * N * N * sizeof *f);
    frep_runtime_error e;
    memset(&e, 0, sizeof e);
    prune_grid_stats st;
    prune_grid_stats_init(&st);
    int rc = f ? prune_eval_grid_planes(fx->prog, N, box, 3, 2, 1, 1, f, &e, NULL) : -1;
    if (!rc) rc = prune_eval_grid_summary(fx->prog, N, box, 0, N, 1, 1, NULL, &st, &e, NULL);
    /* single precision: the float evaluator's scratch per thread */
    prune_grid_stats s32;
    prune_grid_stats_init(&s32);
    if (!rc)
        rc = prune_eval_grid_flags(fx->prog, N, box, 0, 1, PRUNE_GRID_SINGLE, &s32, &e, NULL,
                                   NULL);
    if (!rc) {
        digest_doubles(o, f, 2 * N * N);
        digest_doubles(o, &st.sum, 1);
        digest_size(o, (size_t)st.inside);
        digest_size(o, (size_t)s32.inside);
    }
    free(f);
    return rc;
}

/* frep_eval_grid: the public summary over the tiled evaluator, float path included. */
static int case_eval_grid(const fixture *fx, fault_out *o)
{
    frep_grid_options go;
    frep_grid_options_init(&go);
    go.n = 20;
    go.nthreads = 1;
    go.single = 1;
    frep_grid_summary g;
    if (frep_eval_grid(fx->prog, &go, &g, on_diag, o) != 0) return -1;
    digest_doubles(o, &g.sum, 1);
    digest_size(o, (size_t)g.inside);
    digest_size(o, (size_t)g.nans);
    return 0;
}

static int polygonize(const frep_program *p, int grid, frep_mesh *m, fault_out *o)
{
    mesh_field fld;
    if (mesh_field_program(&fld, p, NULL)) {
        set_msg(o, "out of memory");
        return -1;
    }
    mesh_options mo;
    mesh_options_init(&mo);
    frep_program_box(p, mo.box);
    mo.grid = grid;
    mo.nthreads = 1;
    mesh_stats st;
    frep_error err;
    frep_error_init(&err);
    int rc = mesh_polygonize(&fld, &mo, m, &st, &err);
    mesh_field_program_free(&fld);
    if (rc) set_msg(o, err.msg);
    return rc;
}

static int case_polygonize(const fixture *fx, fault_out *o)
{
    frep_mesh m;
    if (polygonize(fx->prog, 12, &m, o)) return -1;
    digest_doubles(o, m.v, 3 * m.nverts);
    digest_bytes(o, m.tri, 3 * m.ntris * sizeof *m.tri);
    mesh_free(&m);
    return 0;
}

static int case_mesh_validate(const fixture *fx, fault_out *o)
{
    mesh_check c;
    if (mesh_validate(&fx->mesh, &c)) return -1;
    digest_size(o, c.open_edges + c.nonmanifold_edges + c.nonmanifold_verts + c.unused_verts);
    digest_doubles(o, &c.volume, 1);
    return 0;
}

/* Every mesh format written to memory and parsed back. */
static int case_meshio(const fixture *fx, fault_out *o)
{
    static const struct { meshio_format fmt; int ascii; } fm[] = {
        { MESHIO_STL, 0 }, { MESHIO_STL, 1 }, { MESHIO_OBJ, 0 }, { MESHIO_PLY, 0 },
        { MESHIO_PLY, 1 }, { MESHIO_OFF, 0 }
    };
    for (size_t k = 0; k < sizeof fm / sizeof fm[0]; k++) {
        mem_out mo;
        if (!mem_open(&mo)) return -1;
        int rc = meshio_write(mo.f, &fx->mesh, fm[k].fmt, fm[k].ascii);
        if (fclose(mo.f)) rc = -1;
        frep_mesh m;
        frep_error err;
    frep_error_init(&err);
        meshio_format guess = k == 1 ? MESHIO_UNKNOWN : fm[k].fmt;   /* STL by content */
        if (!rc) rc = meshio_parse("m", mo.buf, mo.len, guess, &m, &err);
        free(mo.buf);
        if (rc) {
            set_msg(o, err.msg);
            return -1;
        }
        digest_size(o, m.ntris);
        digest_doubles(o, m.v, 3 * m.nverts);
        mesh_free(&m);
    }
    return 0;
}

/* A colour from the position (for case_colors). */
static void side_color(void *user, const double p[3], uint8_t rgb[3])
{
    (void)user;
    rgb[0] = p[0] > 0 ? 200 : 50;
    rgb[1] = 100;
    rgb[2] = p[2] > 0 ? 10 : 20;
}

/* Vertex colours (mesh_colors) into coloured PLY and VRML, the PLY read back. */
static int case_colors(const fixture *fx, fault_out *o)
{
    uint8_t *rgb = mesh_colors(&fx->mesh, side_color, NULL);
    if (!rgb) {
        set_msg(o, "out of memory");
        return -1;
    }
    int rc = 0;
    for (int k = 0; k < 2 && !rc; k++) {
        mem_out mo;
        if (!mem_open(&mo)) {
            frep_free(rgb);
            return -1;
        }
        rc = meshio_write_colored(mo.f, &fx->mesh, rgb, k ? MESHIO_WRL : MESHIO_PLY, 0);
        if (fclose(mo.f)) rc = -1;
        frep_mesh m;
        frep_error err;
        frep_error_init(&err);
        if (!rc && k == 0) {
            rc = meshio_parse("m", mo.buf, mo.len, MESHIO_PLY, &m, &err);
            if (rc) set_msg(o, err.msg);
            else {
                digest_size(o, m.ntris);
                mesh_free(&m);
            }
        }
        digest_size(o, mo.len);
        free(mo.buf);
    }
    digest_size(o, rgb[0]);
    frep_free(rgb);
    return rc;
}

/* meshio_read from a file. */
static int case_meshio_read(const fixture *fx, fault_out *o)
{
    char path[128];
    snprintf(path, sizeof path, "%s/m.off", fx->tmpdir);
    frep_mesh m;
    frep_error err;
    frep_error_init(&err);
    if (meshio_read(path, &m, &err)) {
        set_msg(o, err.msg);
        return -1;
    }
    digest_doubles(o, m.v, 3 * m.nverts);
    mesh_free(&m);
    return 0;
}

static const char cloud_xyz[] =
    "# a comment\n0 0 0\n1 0 0\n0 1 0\n\n0 0 1\n";

/* .xyz and PLY (written by cloud_write_ply) parsed; both writers. */
static int case_cloud(const fixture *fx, fault_out *o)
{
    frep_error err;
    frep_error_init(&err);
    frep_cloud *c = cloud_parse("c.xyz", cloud_xyz, strlen(cloud_xyz), &err);
    if (!c) {
        set_msg(o, err.msg);
        return -1;
    }
    digest_size(o, c->n);
    cloud_free(c);
    mem_out mo;
    if (!mem_open(&mo)) return -1;
    int rc = cloud_write_ply(mo.f, fx->cloud);
    if (fclose(mo.f)) rc = -1;
    c = rc ? NULL : cloud_parse("c.ply", mo.buf, mo.len, &err);
    free(mo.buf);
    if (!c) {
        set_msg(o, err.msg);
        return -1;
    }
    digest_doubles(o, c->x, c->n);
    if (!mem_open(&mo)) return -1;
    rc = cloud_write_for_path(mo.f, c, "c.xyz");
    cloud_free(c);
    return mem_close(&mo, o, rc);
}

/* cloud_read from a file. */
static int case_cloud_read(const fixture *fx, fault_out *o)
{
    char path[128];
    snprintf(path, sizeof path, "%s/c.xyz", fx->tmpdir);
    frep_error err;
    frep_error_init(&err);
    frep_cloud *c = cloud_read(path, &err);
    if (!c) {
        set_msg(o, err.msg);
        return -1;
    }
    digest_doubles(o, c->x, c->n);
    cloud_free(c);
    return 0;
}

static int case_sample_model(const fixture *fx, fault_out *o)
{
    mesh_field fld;
    if (mesh_field_program(&fld, fx->prog, NULL)) {
        set_msg(o, "out of memory");
        return -1;
    }
    sample_options so;
    sample_options_init(&so);
    so.n = 50;
    so.noise = 0.01;
    so.outliers = 0.1;
    frep_program_box(fx->prog, so.mesh.box);
    so.mesh.grid = 12;
    so.mesh.nthreads = 1;
    frep_cloud *c = NULL;
    frep_error err;
    frep_error_init(&err);
    int rc = sample_field(&fld, &so, &c, &err);
    mesh_field_program_free(&fld);
    if (rc) {
        set_msg(o, err.msg);
        return -1;
    }
    digest_doubles(o, c->x, c->n);
    cloud_free(c);
    return 0;
}

static int case_sample_mesh(const fixture *fx, fault_out *o)
{
    sample_options so;
    sample_options_init(&so);
    so.n = 50;
    so.noise = 0.01;
    so.outliers = 0.1;
    frep_cloud *c = NULL;
    frep_error err;
    frep_error_init(&err);
    if (sample_mesh(&fx->mesh, &so, &c, &err)) {
        set_msg(o, err.msg);
        return -1;
    }
    digest_doubles(o, c->x, c->n);
    cloud_free(c);
    return 0;
}

/* A copy of the fixture's cloud, without normals when bare (the copy allocates too). */
static frep_cloud *cloud_copy(const frep_cloud *src, int bare)
{
    frep_cloud *c = cloud_new(!bare && src->has_normals);
    if (!c || cloud_reserve(c, src->n)) {
        cloud_free(c);
        return NULL;
    }
    for (size_t i = 0; i < src->n; i++) {
        double p[3] = { src->x[i], src->y[i], src->z[i] };
        double q[3] = { src->nx[i], src->ny[i], src->nz[i] };
        if (cloud_push(c, p, q)) {
            cloud_free(c);
            return NULL;
        }
    }
    return c;
}

static int case_normals(const fixture *fx, fault_out *o)
{
    frep_cloud *c = cloud_copy(fx->cloud, 1);
    if (!c) return -1;
    int rc = normals_estimate(c, 0, 1);
    if (!rc) digest_doubles(o, c->nx, c->n);
    cloud_free(c);
    return rc;
}

/* The same cloud with noise of about a third of its spacing: normals_run keeps the
 * neighbours of the fit for the shift of noisy clouds (NORMALS_KEEP_MAX_BYTES); when
 * that allocation fails they are searched again, and the normals must be the same. */
static int case_normals_noisy(const fixture *fx, fault_out *o)
{
    frep_cloud *c = cloud_copy(fx->cloud, 1);
    if (!c) return -1;
    uint64_t h = 88172645463325252ull;
    double *v[3] = {c->x, c->y, c->z};
    for (size_t i = 0; i < c->n; i++)
        for (int d = 0; d < 3; d++) {
            h ^= h << 13, h ^= h >> 7, h ^= h << 17;
            v[d][i] += 0.12 * ((double)(h >> 11) / 9007199254740992.0 - 0.5);
        }
    normals_config cfg;
    normals_config_init(&cfg);
    cfg.nthreads = 1;
    normals_info info;
    int rc = normals_run(c, &cfg, &info);
    if (!rc) {
        digest_doubles(o, c->nx, c->n);
        /* noisy enough for the shift (NORMALS_REFLECT_MAX_NOISE is 0.1) */
        digest_size(o, info.noise >= 0.1 * info.spacing ? 1 : 0);
    }
    cloud_free(c);
    return rc;
}

/* The public entry point (api/api_normals.c): every failure reported as "out of
 * memory" through the callback. */
static int case_api_normals(const fixture *fx, fault_out *o)
{
    frep_cloud *c = cloud_copy(fx->cloud, 1);
    if (!c) {
        set_msg(o, "out of memory");
        return -1;
    }
    frep_normals_options no;
    frep_normals_options_init(&no);
    no.nthreads = 1;
    frep_normals_info info;
    int rc = frep_normals(c, &no, &info, on_diag, o);
    if (!rc) {
        digest_doubles(o, c->nx, c->n);
        digest_size(o, info.knn);
    }
    cloud_free(c);
    return rc;
}

static int case_kdtree(const fixture *fx, fault_out *o)
{
    const frep_cloud *c = fx->cloud;
    kd_tree *t = kd_build(c->n, c->x, c->y, c->z);
    if (!t) return -1;
    uint32_t idx[8];
    double d2[8];
    double q[3] = { 0.3, 0.2, 0.1 };
    size_t k = kd_knn(t, q, 8, idx, d2);
    digest_bytes(o, idx, k * sizeof *idx);
    kd_free(t);
    return 0;
}

/* Acceptance probability of the segmentation: lower than the default, so RANSAC stops
 * drawing soon once the faces are found (the run is repeated hundreds of times). */
#define SEGMENT_PROBABILITY 0.9

static int case_segment(const fixture *fx, fault_out *o)
{
    frep_cloud *c = cloud_copy(fx->cloud, 1);
    if (!c) {
        set_msg(o, "out of memory");
        return -1;
    }
    segment_config cfg;
    segment_config_init(&cfg);
    cfg.seed = 3;
    cfg.nthreads = 1;
    cfg.probability = SEGMENT_PROBABILITY;
    segment_result res;
    frep_error err;
    frep_error_init(&err);
    int rc = segment_run(c, &cfg, &res, &err);
    cloud_free(c);
    if (rc) {
        set_msg(o, err.msg);
        return -1;
    }
    digest_size(o, res.nprims);
    digest_bytes(o, res.label, fx->cloud->n * sizeof *res.label);
    mem_out mo;
    if (!mem_open(&mo)) {
        segment_result_free(&res);
        return -1;
    }
    rc = segment_write_hf(mo.f, res.prims, res.nprims, "segmented", res.diagonal);
    if (!rc) rc = fitfile_write(mo.f, res.prims, res.nprims);
    segment_result_free(&res);
    return mem_close(&mo, o, rc);
}

/* Primitive lists: .fit and .hf text. */
/* Named sub-expressions, a slab of min/max arithmetic, a complement: every branch of
 * the export's writer that allocates. */
static const char export_src[] =
    "-- @box -2 -2 -2 2 2 2\n"
    "my_model(x[3], a[1])\n"
    "{\n"
    "    array c[3];\n"
    "    c = [0, 0, 0];\n"
    "    ball = hfSphere(x, c, 1);\n"
    "    slab = 0.5 - abs(x[3]);\n"
    "    holes = hfCylinderZ(x, c, 0.2) | frCylinder(x, 0, 0, 0, 1, 0, 0, 0.2);\n"
    "    my_model = (ball & slab) \\ holes | ~frSphere(x, 3, 3, 3, 5.5);\n"
    "}\n";

static int case_export(const fixture *fx, fault_out *o)
{
    (void)fx;
    scad_options so;
    memset(&so, 0, sizeof so);
    for (int i = 0; i < 3; i++) {
        so.box[i] = -2;
        so.box[i + 3] = 2;
    }
    so.fn = SCAD_DEFAULT_FN;
    frep_error err;
    char *t = scad_export("e.hf", export_src, strlen(export_src), &so, on_diag, o, &err);
    if (!t) {
        set_msg(o, err.msg);
        return -1;
    }
    digest_bytes(o, t, strlen(t));
    frep_free(t);
    return 0;
}

static int case_prims(const fixture *fx, fault_out *o)
{
    prim *p = NULL;
    size_t n = 0;
    frep_error err;
    frep_error_init(&err);
    if (fitfile_parse("c.fit", cube_fit, strlen(cube_fit), &p, &n, &err)) {
        set_msg(o, err.msg);
        return -1;
    }
    frep_free(p);
    mem_out mo;
    if (!mem_open(&mo)) return -1;
    int rc = segment_write_hf(mo.f, fx->prims, fx->nprims, "cube", 0);
    if (fclose(mo.f)) rc = -1;
    if (!rc) rc = segment_parse_prims("c.hf", mo.buf, mo.len, 0, &p, &n, &err);
    free(mo.buf);
    if (rc) {
        set_msg(o, err.msg);
        return -1;
    }
    digest_bytes(o, p, n * sizeof *p);
    frep_free(p);
    return 0;
}

static int case_fit(const fixture *fx, fault_out *o)
{
    const frep_program *p = fx->prog;
    enum { NP = 8 };
    size_t idx[2], nfree = 0, np = frep_program_nparams(p);
    double base[NP], lo[2], hi[2], q[2];
    if (np > NP) return -1;
    for (size_t j = 0; j < np; j++) {
        base[j] = frep_program_param_value(p, j);
        if (nfree < 2 && frep_program_param_bounds(p, j, &lo[nfree], &hi[nfree])) {
            q[nfree] = base[j] * 1.1 + 0.05;
            idx[nfree++] = j;
        }
    }
    if (nfree != 2) return -1;
    fit_model m;
    if (fit_program_model(p, idx, nfree, base, &m)) {
        set_msg(o, "out of memory");
        return -1;
    }
    const frep_cloud *c = fx->cloud;
    fit_points pts = { c->n, c->x, c->y, c->z, NULL, NULL, NULL };
    fit_config cfg;
    fit_config_init(&cfg);
    cfg.max_evals = 60;
    cfg.sa_points = 50;
    cfg.obj.nthreads = 1;
    cfg.surrogate = &m;         /* the annealing's model: its robust objective too */
    fit_result res;
    frep_error err;
    frep_error_init(&err);
    int rc = fit_run(&m, &pts, lo, hi, q, &cfg, &res, &err);
    fit_program_model_free(&m);
    if (rc) {
        set_msg(o, err.msg);
        return -1;
    }
    digest_doubles(o, q, 2);
    return 0;
}

/* The template write-back of frep fit. */
static int case_writeback(const fixture *fx, fault_out *o)
{
    (void)fx;
    const char *r = strstr(model_src, "r = 1;") + 4;
    fit_edit e = { (uint32_t)(r - model_src), (uint32_t)(r - model_src + 1), 1.25, 0.5, 2 };
    double box[6] = { -1, -1, -1, 1, 1, 1 };
    size_t len;
    char *s = fit_writeback(model_src, strlen(model_src), &e, 1, box, "-- fitted: test", &len);
    if (!s) return -1;
    digest_bytes(o, s, len);
    frep_free(s);
    return 0;
}

static void evolve_opts(evolve_options *eo, int partition)
{
    evolve_options_init(eo);
    eo->gp.population = 12;
    eo->gp.generations = 4;
    eo->gp.stagnation = 3;
    eo->gp.threads = 1;
    eo->gp.seed = 5;
    eo->gp.setops = GP_SETOPS_MINMAX;
    eo->partition = partition;
    eo->sample = 200;
}

/* The model and the Graphviz drawing of an evolve result, without the run's time (it
 * differs from run to run; the result must not). The writers give a status only; on a
 * memory stream a failure is out of memory. */
static int write_evolved(const fixture *fx, fault_out *o, const evolve_result *r,
                         const prim *pr, const evolve_options *eo)
{
    mem_out mo;
    if (!mem_open(&mo)) return -1;
    evolve_meta meta = { .command = "test", .cloud = "cube.xyz", .seed = 5,
                         .setops = eo->gp.setops };
    evolve_result timeless = *r;
    timeless.seconds = 0;
    int rc = evolve_write_model(mo.f, &timeless, pr, fx->nprims, &meta);
    if (!rc) rc = evolve_write_dot(mo.f, &timeless, pr, fx->nprims);
    rc = mem_close(&mo, o, rc);
    if (rc) set_msg(o, "out of memory");
    return rc;
}

static int run_evolve(const fixture *fx, fault_out *o, int partition)
{
    evolve_options eo;
    evolve_opts(&eo, partition);
    evolve_result res;
    frep_error err;
    frep_error_init(&err);
    if (evolve_run(&eo, fx->cloud, fx->prims, fx->nprims, NULL, NULL, &res, &err)) {
        set_msg(o, err.msg);
        return -1;
    }
    int rc = write_evolved(fx, o, &res, fx->prims, &eo);
    evolve_result_free(&res);
    return rc;
}

static int case_evolve(const fixture *fx, fault_out *o) { return run_evolve(fx, o, 0); }
static int case_evolve_part(const fixture *fx, fault_out *o) { return run_evolve(fx, o, 1); }

/* The --residual base: the cube's my_model renamed (longer: the text grows) and its
 * values at the cloud. */
static int case_residual(const fixture *fx, fault_out *o)
{
    evolve_base b;
    frep_error err;
    frep_error_init(&err);
    if (residual_prepare("cube.hf", cube_src, strlen(cube_src), NULL, fx->cube, &b, &err)) {
        set_msg(o, err.msg);
        return -1;
    }
    digest_bytes(o, b.text, strlen(b.text));
    digest_bytes(o, b.call, strlen(b.call));
    const frep_cloud *c = fx->cloud;
    double f[CLOUD_POINTS], g[3 * CLOUD_POINTS];
    uint8_t okp[CLOUD_POINTS];
    size_t nbad = 0;
    int rc = c->n <= CLOUD_POINTS ? residual_eval(&b, c, 1, f, g, okp, &nbad) : -1;
    if (rc) set_msg(o, "out of memory");
    else digest_doubles(o, f, c->n);
    residual_free(&b);
    return rc ? -1 : 0;
}

/* evolve_refit on a copy of the fixture's evolve result. */
static int case_refit(const fixture *fx, fault_out *o)
{
    evolve_options eo;
    evolve_opts(&eo, 0);
    evolve_result res = fx->evolved;
    memset(&res.tree, 0, sizeof res.tree);
    prim pr[MAX_PRIMS];
    memcpy(pr, fx->prims, fx->nprims * sizeof *pr);
    evolve_refit_info ri;
    frep_error err;
    frep_error_init(&err);
    int rc = tree_copy(&res.tree, &fx->evolved.tree);
    if (rc) set_msg(o, "out of memory");
    if (!rc && (rc = evolve_refit(&eo, fx->cloud, pr, fx->nprims, NULL, &res, &ri, &err)))
        set_msg(o, err.msg);
    if (!rc) rc = write_evolved(fx, o, &res, pr, &eo);
    evolve_result_free(&res);
    return rc;
}

static int case_render(const fixture *fx, fault_out *o)
{
    enum { W = 24, H = 16 };
    uint8_t rgb[3 * W * H];
    render_options ro = { W, H, "iso", { -2, -2, -2, 2, 2, 2 }, NULL, 0, 0, { { 0 } }, NULL };
    const frep_cloud *c = fx->cloud;
    render_points rp = { c->n, c->x, c->y, c->z, NULL, 1, 0 };
    frep_error err;
    frep_error_init(&err);
    if (render_mesh(&fx->mesh, &rp, &ro, rgb, &err)) {
        set_msg(o, err.msg);
        return -1;
    }
    mem_out mo;
    if (!mem_open(&mo)) return -1;
    return mem_close(&mo, o, png_write_rgb(mo.f, rgb, W, H));
}

/* A formatted copy (runtime/util.h). */
static int case_strdupf(const fixture *fx, fault_out *o)
{
    (void)fx;
    char *s = frep_strdupf("%s:%d: %g", "m.hf", 3, 0.25);
    if (!s) return -1;
    digest_bytes(o, s, strlen(s));
    frep_free(s);
    return 0;
}

/* The shared growable buffer, grown past its first block. */
static int case_buf(const fixture *fx, fault_out *o)
{
    (void)fx;
    frep_buf b = FREP_BUF_INIT;
    for (int i = 0; i < 40; i++) buf_printf(&b, "line %d of the buffer test\n", i);
    buf_putc(&b, '.');
    size_t len;
    char *str = buf_finish(&b, &len);
    if (!str) return -1;
    digest_bytes(o, str, len);
    frep_free(str);
    return 0;
}

/* frep view's distances: the model's to the cloud's points, the mesh's, the vertices'
 * to the cloud, and the scale chosen from them. */
static int case_view_distances(const fixture *fx, fault_out *o)
{
    const frep_cloud *c = fx->cloud;
    const frep_mesh *m = &fx->mesh;
    double *d = malloc((c->n + m->nverts) * sizeof *d), s = 0;
    if (!d) return -1;
    frep_error e;
    frep_error_init(&e);
    int rc = view_point_distances(fx->prog, 0, c->n, c->x, c->y, c->z, 1, d, NULL, &e);
    if (!rc) rc = view_auto_scale(d, c->n, VIEW_POINTS_QUANTILE, 1, 0, &s, &e);
    if (!rc) digest_doubles(o, d, c->n), digest_doubles(o, &s, 1);
    if (!rc) rc = view_mesh_distances(m, c->n, c->x, c->y, c->z, d, &e);
    if (!rc) rc = view_vertex_distances(m, c->n, c->x, c->y, c->z, d + c->n, &e);
    if (!rc) digest_doubles(o, d, c->n + m->nverts);
    if (rc) set_msg(o, e.msg);
    free(d);
    return rc;
}

/* frep view's page of the fixture mesh and cloud. */
static int case_view_page(const fixture *fx, fault_out *o)
{
    const frep_cloud *c = fx->cloud;
    view_scene sc;
    memset(&sc, 0, sizeof sc);
    sc.name = "fixture.hf";
    sc.mesh = &fx->mesh;
    sc.npoints = c->n;
    sc.px = c->x;
    sc.py = c->y;
    sc.pz = c->z;
    sc.pdist = c->x;
    sc.pscale = 1;
    sc.source = "my_model(x[3], a[1]) { my_model = 1; }";
    frep_error e;
    frep_error_init(&e);
    size_t len;
    char *page = view_page(&sc, 0, &len, &e);
    if (!page) {
        set_msg(o, e.msg);
        return -1;
    }
    digest_bytes(o, page, len);
    frep_free(page);
    return 0;
}

/* The public API of frep view and frep render's distances (api/api_view.c): the
 * model's and the mesh's distances with their scales. */
static int case_api_distances(const fixture *fx, fault_out *o)
{
    frep_distances d;
    for (int k = 0; k < 2; k++) {
        if (frep_cloud_distances(fx->cloud, &fx->mesh, k ? NULL : fx->prog, 0, 1, &d, on_diag,
                                 o) != 0)
            return -1;
        digest_doubles(o, d.point, fx->cloud->n);
        digest_doubles(o, d.vertex, fx->mesh.nverts);
        digest_doubles(o, &d.point_scale, 1);
        frep_distances_free(&d);
    }
    return 0;
}

/* The page, its scene JSON and the page written to a stream, through the public API. */
static int case_api_view_page(const fixture *fx, fault_out *o)
{
    const frep_cloud *c = fx->cloud;
    frep_view_scene sc;
    frep_view_scene_init(&sc);
    sc.name = "fixture.hf";
    sc.mesh = &fx->mesh;
    sc.npoints = c->n;
    sc.px = c->x;
    sc.py = c->y;
    sc.pz = c->z;
    size_t len;
    char *page = frep_view_page(&sc, 1, &len, on_diag, o);
    if (!page) return -1;
    digest_bytes(o, page, len);
    frep_free(page);
    char *json = frep_view_scene_json(&sc, &len, on_diag, o);
    if (!json) return -1;
    digest_bytes(o, json, len);
    frep_free(json);
    mem_out mo;
    if (!mem_open(&mo)) return -1;
    return mem_close(&mo, o, frep_view_write_page(&sc, mo.f, on_diag, o));
}

/* The loopback server of frep view --watch, opened and closed. */
static int case_api_view_server(const fixture *fx, fault_out *o)
{
    (void)fx;
    frep_view_server *s = frep_view_server_open(0, on_diag, o);
    if (!s) return -1;
    frep_view_server_close(s);
    return 0;
}

/* frep export through the public API. */
static int case_api_export(const fixture *fx, fault_out *o)
{
    (void)fx;
    frep_scad_options so;
    frep_scad_options_init(&so);
    for (int i = 0; i < 3; i++) {
        so.box[i] = -2;
        so.box[i + 3] = 2;
    }
    char *t = frep_export_scad("e.hf", export_src, strlen(export_src), &so, on_diag, o);
    if (!t) return -1;
    digest_bytes(o, t, strlen(t));
    frep_free(t);
    return 0;
}

/* ---- the driver --------------------------------------------------------------------- */

typedef int (*case_fn)(const fixture *fx, fault_out *o);

typedef struct fault_case {
    const char *name;
    case_fn fn;
    int has_msg;     /* MSG_*: how the API reports a failure */
    const char *todo;   /* known wrong reports (not leaks), for the owners of the code */
} fault_case;

enum {
    MSG_NONE,        /* a status only */
    MSG_GIVEN        /* a message in a frep_error or through a callback */
};

static const fault_case cases[] = {
    { "compile", case_compile, MSG_GIVEN, NULL },
    { "compile_error", case_compile_error, MSG_GIVEN, NULL },
    { "list_models", case_list_models, MSG_GIVEN, NULL },
    { "disassemble", case_disassemble, MSG_NONE, NULL },
    { "print_source", case_print_source, MSG_GIVEN, NULL },
    { "diag_format", case_diag_format, MSG_NONE, NULL },
    { "eval", case_eval, MSG_NONE, NULL },
    { "eval_par", case_eval_par, MSG_NONE, NULL },
    { "interval", case_interval, MSG_NONE, NULL },
    { "prune", case_prune, MSG_NONE, NULL },
    { "grid", case_grid, MSG_NONE, NULL },
    { "eval_grid", case_eval_grid, MSG_GIVEN, NULL },
    { "polygonize", case_polygonize, MSG_GIVEN, NULL },
    { "mesh_validate", case_mesh_validate, MSG_NONE, NULL },
    { "meshio", case_meshio, MSG_GIVEN, NULL },
    { "colors", case_colors, MSG_GIVEN, NULL },
    { "meshio_read", case_meshio_read, MSG_GIVEN, NULL },
    { "cloud", case_cloud, MSG_GIVEN, NULL },
    { "cloud_read", case_cloud_read, MSG_GIVEN, NULL },
    { "sample_model", case_sample_model, MSG_GIVEN, NULL },
    { "sample_mesh", case_sample_mesh, MSG_GIVEN, NULL },
    { "normals", case_normals, MSG_NONE, NULL },
    { "normals_noisy", case_normals_noisy, MSG_NONE, NULL },
    { "api_normals", case_api_normals, MSG_GIVEN, NULL },
    { "kdtree", case_kdtree, MSG_NONE, NULL },
    { "segment", case_segment, MSG_GIVEN, NULL },
    { "prims", case_prims, MSG_GIVEN, NULL },
    { "export", case_export, MSG_GIVEN, NULL },
    { "fit", case_fit, MSG_GIVEN, NULL },
    { "writeback", case_writeback, MSG_NONE, NULL },
    { "evolve", case_evolve, MSG_GIVEN, NULL },
    { "evolve_partition", case_evolve_part, MSG_GIVEN, NULL },
    { "residual", case_residual, MSG_GIVEN, NULL },
    { "refit", case_refit, MSG_GIVEN, NULL },
    { "render", case_render, MSG_NONE, NULL },
    { "view_distances", case_view_distances, MSG_GIVEN, NULL },
    { "view_page", case_view_page, MSG_GIVEN, NULL },
    { "api_distances", case_api_distances, MSG_GIVEN, NULL },
    { "api_view_page", case_api_view_page, MSG_GIVEN, NULL },
    { "api_view_server", case_api_view_server, MSG_GIVEN, NULL },
    { "api_export", case_api_export, MSG_GIVEN, NULL },
    { "buf", case_buf, MSG_NONE, NULL },
    { "strdupf", case_strdupf, MSG_NONE, NULL },
};

/* Injected failures reported in detail per case; the others are only counted. */
#define MAX_REPORTS 3

typedef struct run_opts {
    const char *only;       /* FREP_FAULT_CASE */
    unsigned long only_n;   /* FREP_FAULT_N; 0: all */
    int verbose;
} run_opts;

static int run_once(const fault_case *c, const fixture *fx, unsigned long n, fault_out *o)
{
    memset(o, 0, sizeof *o);
    fault_arm(n);
    return c->fn(fx, o);
}

/* What is wrong with the run failing allocation n (NULL: nothing); *hard is set for a
 * leak, the other faults are about what the run reports. */
static const char *judge(const fault_case *c, int rc0, const fault_out *o0, int rc,
                         const fault_out *o, size_t live, int hit, int *hard)
{
    *hard = live != 0;
    if (live) return "leak";
    if (rc == rc0 && o->digest == o0->digest && strcmp(o->msg, o0->msg) == 0) return NULL;
    if (rc == 0) return "success with another result";
    if (!hit) return "failure without an injected failure";
    if (c->has_msg && !strstr(o->msg, "out of memory")) return "message is not \"out of memory\"";
    return NULL;
}

/* A TAP line that is a known failure ("# TODO why") when todo is not NULL. */
static void ok_todo(int cond, const char *todo, const char *what)
{
    ++tap_n;
    if (!cond && !todo) ++tap_failed;
    printf("%s %d - %s", cond ? "ok" : "not ok", tap_n, what);
    if (todo) printf(" # TODO %s", todo);
    putchar('\n');
    fflush(stdout);
}

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void run_case(const fault_case *c, const fixture *fx, const run_opts *ro)
{
    double t0 = now();
    fault_out o0, o;
    int rc0 = run_once(c, fx, 0, &o0);
    unsigned long count = fault_count();
    size_t live0 = fault_live();
    if (!ok(live0 == 0, "%s: clean run (%lu allocations, status %d%s%s)", c->name, count, rc0,
            o0.msg[0] ? ": " : "", o0.msg))
        fault_report(stdout, 10);
    unsigned long failed = 0, absorbed = 0, leaks = 0, wrong = 0;
    for (unsigned long n = 1; n <= count; n++) {
        if (ro->only_n && n != ro->only_n) continue;
        if (ro->verbose) printf("# %s: allocation %lu fails\n", c->name, n), fflush(stdout);
        int rc = run_once(c, fx, n, &o);
        size_t live = fault_live();
        int hit = fault_hit(), hard;
        const char *why = judge(c, rc0, &o0, rc, &o, live, hit, &hard);
        if (!why) {
            if (rc == rc0 && o.digest == o0.digest) absorbed++;
            else failed++;
            continue;
        }
        if (hard ? leaks++ < MAX_REPORTS : wrong++ < MAX_REPORTS) {
            diag("%s: allocation %lu of %lu fails: %s (status %d, %zu blocks alive, "
                 "message '%s')", c->name, n, count, why, rc, live, o.msg);
            fault_report(stdout, 5);
        }
    }
    ok(leaks == 0, "%s: allocation N failing for N = 1..%lu: no leak (%lu failed, %lu absorbed)",
       c->name, count, failed, absorbed);
    char what[200];
    snprintf(what, sizeof what, "%s: every failure says out of memory, every absorbed one "
             "gives the same result (%lu do not)", c->name, wrong);
    ok_todo(wrong == 0, c->todo, what);
    diag("%s: %.2f s", c->name, now() - t0);
}

/* ---- fixtures ----------------------------------------------------------------------- */

static frep_program *compile_fixture(const char *src)
{
    frep_compile_options opt;
    frep_compile_options_init(&opt);
    return frep_compile("fixture.hf", src, strlen(src), &opt, NULL, NULL);
}

static int write_file(const char *dir, const char *name, int (*fn)(FILE *, const void *),
                      const void *arg)
{
    char path[128];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    int rc = fn(f, arg);
    return fclose(f) || rc ? -1 : 0;
}

static int write_off(FILE *f, const void *m) { return meshio_write(f, m, MESHIO_OFF, 0); }
static int write_xyz(FILE *f, const void *c) { return cloud_write_xyz(f, c); }

static int fixture_init(fixture *fx)
{
    memset(fx, 0, sizeof *fx);
    for (int i = 0; i < NPTS; i++) {
        px[i] = -1.5 + 3.0 * i / (NPTS - 1);
        py[i] = 0.3 * (i % 5) - 0.6;
        pz[i] = 0.1 * (i % 7) - 0.3;
    }
    fault_out o;
    memset(&o, 0, sizeof o);
    fx->prog = compile_fixture(model_src);
    fx->cube = compile_fixture(cube_src);
    if (!fx->prog || !fx->cube) return -1;
    if (polygonize(fx->prog, 10, &fx->mesh, &o)) return diag("fixture mesh: %s", o.msg), -1;
    mesh_field fld;
    if (mesh_field_program(&fld, fx->cube, NULL)) return -1;
    sample_options so;
    sample_options_init(&so);
    so.n = CLOUD_POINTS;
    so.seed = 2;
    frep_program_box(fx->cube, so.mesh.box);
    so.mesh.grid = 8;
    frep_error err;
    frep_error_init(&err);
    int rc = sample_field(&fld, &so, &fx->cloud, &err);
    mesh_field_program_free(&fld);
    if (rc) return diag("fixture cloud: %s", err.msg), -1;
    frep_error fe;
    if (fitfile_parse("cube.fit", cube_fit, strlen(cube_fit), &fx->prims, &fx->nprims, &fe))
        return diag("fixture primitives: %s", fe.msg), -1;
    evolve_options eo;
    evolve_opts(&eo, 0);
    frep_error_init(&fe);
    if (fx->nprims > MAX_PRIMS ||
        evolve_run(&eo, fx->cloud, fx->prims, fx->nprims, NULL, NULL, &fx->evolved, &fe))
        return -1;
    snprintf(fx->tmpdir, sizeof fx->tmpdir, "%s/frep-faults.XXXXXX",
             getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    if (strlen(fx->tmpdir) > 60 || !mkdtemp(fx->tmpdir)) return -1;
    if (write_file(fx->tmpdir, "m.off", write_off, &fx->mesh) ||
        write_file(fx->tmpdir, "c.xyz", write_xyz, fx->cloud))
        return -1;
    return 0;
}

static void fixture_free(fixture *fx)
{
    char path[128];
    snprintf(path, sizeof path, "%s/m.off", fx->tmpdir);
    remove(path);
    snprintf(path, sizeof path, "%s/c.xyz", fx->tmpdir);
    remove(path);
    remove(fx->tmpdir);
    frep_program_free(fx->prog);
    frep_program_free(fx->cube);
    mesh_free(&fx->mesh);
    cloud_free(fx->cloud);
    frep_free(fx->prims);
    evolve_result_free(&fx->evolved);
}

int main(void)
{
    fault_install();
#ifdef _OPENMP
    /* One thread wherever the library takes OpenMP's default: the allocations then come
     * in the same order in every run (eval_par asks for two threads itself). */
    omp_set_num_threads(1);
#endif
    run_opts ro = { getenv("FREP_FAULT_CASE"), 0, getenv("FREP_FAULT_VERBOSE") != NULL };
    if (getenv("FREP_FAULT_N")) ro.only_n = strtoul(getenv("FREP_FAULT_N"), NULL, 10);
    (void)tap_close;
    fixture fx;
    fault_arm(0);
    if (!ok(fixture_init(&fx) == 0, "fixtures built")) return done_testing();
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        if (!ro.only || strstr(cases[i].name, ro.only)) run_case(&cases[i], &fx, &ro);
    fault_arm(0);
    fixture_free(&fx);
    return done_testing();
}
