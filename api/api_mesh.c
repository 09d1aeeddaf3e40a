/* api_mesh.c - triangle meshes in the public API: polygonizing a program
 * (mesh/polygonize.c over the program's field, mesh/field.c), the mesh files
 * (geom/meshio.c) and the checks (geom/trimesh.c).  frep_mesh is geom/trimesh.h's
 * mesh, held in its own allocation.
 */
#include "config.h"

#include "api.h"
#include "mesh.h"
#include "meshio.h"
#include "trimesh.h"

#include <errno.h>
#include <math.h>
#include <string.h>

#include "alloc.h"

_Static_assert(FREP_MESH_AUTO == (int)MESHIO_UNKNOWN && FREP_MESH_STL == (int)MESHIO_STL &&
                   FREP_MESH_OBJ == (int)MESHIO_OBJ && FREP_MESH_PLY == (int)MESHIO_PLY &&
                   FREP_MESH_OFF == (int)MESHIO_OFF && FREP_MESH_WRL == (int)MESHIO_WRL,
               "the public formats are meshio's");
_Static_assert(FREP_MESH_MAX_GRID == MESH_MAX_GRID, "the polygonizer's limit");
_Static_assert(FREP_MESH_SURFACE_TOL == MESH_SURFACE_TOL, "frep mesh --check's bound");

void frep_mesh_options_init(frep_mesh_options *o)
{
    mesh_options mo;
    mesh_options_init(&mo);
    memset(o, 0, sizeof *o);
    memcpy(o->box, mo.box, sizeof o->box);
    o->grid = 64;     /* frep mesh's -g default */
    o->iso = mo.iso;
}

/* The polygonizer's options from the public ones, with the model box resolved. */
static void to_mesh_options(const frep_program *p, const frep_mesh_options *o, mesh_options *mo)
{
    mesh_options_init(mo);
    api_model_box(p, o, mo->box);
    mo->grid = o->grid;
    memcpy(mo->grid_axes, o->grid_axes, sizeof mo->grid_axes);
    mo->iso = o->iso;
    mo->nthreads = o->nthreads;
    mo->progress = o->progress;
    mo->progress_user = o->progress_user;
    mo->interrupt = o->cancel_flag;
}

/* One call of the polygonizer or of its distance check: the caller's diagnostics and
 * error, the options (the caller's, or the defaults when it gave none) and the model's
 * field. */
typedef struct mesh_call {
    api_diag d;
    frep_error e;
    frep_mesh_options def;
    mesh_options mo;
    mesh_field f;
} mesh_call;

/* Fill *c and open the model's field (freed with mesh_field_program_free).  Returns 0,
 * or -1 with nothing to free. */
static int mesh_call_open(mesh_call *c, const frep_program *p, const frep_mesh_options *o,
                          frep_diag_fn diag, void *user)
{
    c->d = (api_diag){ diag, user };
    frep_error_init(&c->e);
    if (!o) {
        frep_mesh_options_init(&c->def);
        o = &c->def;
    }
    to_mesh_options(p, o, &c->mo);
    return mesh_field_program(&c->f, p, o->params);
}

static void fill_info(frep_mesh_info *info, const mesh_options *mo, const mesh_stats *st)
{
    if (!info) return;
    memset(info, 0, sizeof *info);
    memcpy(info->box, mo->box, sizeof info->box);
    info->grid = mo->grid;
    info->points_nan = st->points_nan;
    info->touches_box = st->touches_box;
    info->full = st->full;
    info->seconds = st->seconds;
    info->octree_nodes = st->octree_nodes;
    info->blocks = st->blocks;
    info->blocks_total = st->blocks_total;
    info->eval_points = st->eval_points;
    info->grad_points = st->grad_points;
    info->cells_split = st->cells_split;
    info->face_vertices = st->face_vertices;
    info->settled = st->settled;
    info->octree_seconds = st->stage_seconds[MESH_STAGE_OCTREE];
    info->contour_seconds = st->stage_seconds[MESH_STAGE_CONTOUR];
    info->quads_seconds = st->stage_seconds[MESH_STAGE_QUADS];
    info->assembly_seconds = st->stage_seconds[MESH_STAGE_ASSEMBLY];
    info->settle_seconds = st->stage_seconds[MESH_STAGE_SETTLE];
}

/* A grid with NaN points: they counted as outside. */
static void nan_warning(const api_diag *d, size_t points_nan)
{
    if (!points_nan) return;
    char msg[160];
    snprintf(msg, sizeof msg, "the model is NaN (undefined) at %zu grid points; they count as "
                              "outside", points_nan);
    api_report(d, FREP_WARNING, msg);
}

frep_mesh *frep_polygonize(const frep_program *p, const frep_mesh_options *o,
                           frep_mesh_info *info, frep_diag_fn diag, void *user)
{
    mesh_call c;
    if (mesh_call_open(&c, p, o, diag, user) != 0) {
        api_fail(&c.d, &c.e);
        return NULL;
    }
    frep_mesh *m = frep_calloc(1, sizeof *m);
    if (!m) {
        mesh_field_program_free(&c.f);
        api_fail(&c.d, &c.e);
        return NULL;
    }
    mesh_stats st;
    memset(&st, 0, sizeof st);
    int rc = mesh_polygonize(&c.f, &c.mo, m, &st, &c.e);
    frep_runtime_error re;
    mesh_field_program_errors(&c.f, &re);
    mesh_field_program_free(&c.f);
    if (rc != 0 && c.e.code == FREP_ECANCEL) {
        /* stopped: the points a loop was stopped at are no errors of the model */
        frep_mesh_free(m);
        if (info) {
            memset(info, 0, sizeof *info);
            info->interrupted = 1;
        }
        return NULL;
    }
    api_runtime_warning(&c.d, p, &re);
    if (rc != 0) {
        frep_mesh_free(m);
        api_fail(&c.d, &c.e);
        return NULL;
    }
    nan_warning(&c.d, st.points_nan);
    fill_info(info, &c.mo, &st);
    return m;
}

frep_mesh *frep_mesh_new(size_t nverts, const double *v, const double *n, size_t ntris,
                         const uint32_t *tri, frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    if ((nverts && !v) || (ntris && !tri) || nverts > MESHIO_MAX_ELEMENTS ||
        ntris > MESHIO_MAX_ELEMENTS) {
        frep_error_set(&e, FREP_EINPUT, "frep_mesh_new: missing arrays or more than %zu "
                                        "vertices or triangles", (size_t)MESHIO_MAX_ELEMENTS);
        api_fail(&d, &e);
        return NULL;
    }
    for (size_t i = 0; i < 3 * ntris; i++)
        if (tri[i] >= nverts) {
            frep_error_set(&e, FREP_EINPUT, "frep_mesh_new: triangle %zu uses vertex %lu of %zu",
                           i / 3, (unsigned long)tri[i], nverts);
            api_fail(&d, &e);
            return NULL;
        }
    frep_mesh *m = frep_calloc(1, sizeof *m);
    if (m) {
        m->v = frep_malloc(3 * nverts * sizeof *m->v + 1);
        m->n = n ? frep_malloc(3 * nverts * sizeof *m->n + 1) : NULL;
        m->tri = frep_malloc(3 * ntris * sizeof *m->tri + 1);
    }
    if (!m || !m->v || (n && !m->n) || !m->tri) {
        frep_mesh_free(m);
        api_fail(&d, &e);
        return NULL;
    }
    m->nverts = nverts;
    m->ntris = ntris;
    if (nverts) memcpy(m->v, v, 3 * nverts * sizeof *v);
    if (n && nverts) memcpy(m->n, n, 3 * nverts * sizeof *n);
    if (ntris) memcpy(m->tri, tri, 3 * ntris * sizeof *tri);
    return m;
}

frep_mesh *frep_mesh_read(const char *path, frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    frep_mesh *m = frep_calloc(1, sizeof *m);
    if (!m) {
        api_fail(&d, &e);
        return NULL;
    }
    if (meshio_read(path, m, &e) != 0) {
        frep_mesh_free(m);
        api_fail(&d, &e);
        return NULL;
    }
    return m;
}

void frep_mesh_free(frep_mesh *m)
{
    if (!m) return;
    mesh_free(m);
    frep_free(m);
}

size_t frep_mesh_nverts(const frep_mesh *m) { return m->nverts; }
size_t frep_mesh_ntris(const frep_mesh *m) { return m->ntris; }
const double *frep_mesh_vertices(const frep_mesh *m) { return m->v; }
const double *frep_mesh_normals(const frep_mesh *m) { return m->n; }
const uint32_t *frep_mesh_triangles(const frep_mesh *m) { return m->tri; }

typedef struct mesh_out {
    const frep_mesh *m;
    meshio_format fmt;
    int ascii;
} mesh_out;

static int write_mesh(FILE *f, void *ctx)
{
    const mesh_out *o = ctx;
    return meshio_write(f, o->m, o->fmt, o->ascii);
}

int frep_mesh_write(const frep_mesh *m, const char *path, frep_mesh_format fmt, int ascii,
                    frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    mesh_out o = { m, (meshio_format)fmt, ascii };
    if (fmt == FREP_MESH_AUTO)
        o.fmt = path && strcmp(path, "-") == 0 ? MESHIO_STL : meshio_format_for_path(path);
    if (o.fmt == MESHIO_UNKNOWN || o.fmt > MESHIO_WRL) {
        frep_error e;
        frep_error_init(&e);
        frep_error_set(&e, FREP_EINPUT, "cannot tell the format of '%s': use .stl, .obj, .ply, "
                                        ".off or .wrl", path ? path : "(null)");
        return api_fail(&d, &e);
    }
    return api_write_atomic(&d, path, write_mesh, &o);
}

frep_mesh_format frep_mesh_format_for_path(const char *path)
{
    return path ? (frep_mesh_format)meshio_format_for_path(path) : FREP_MESH_AUTO;
}

const char *frep_mesh_format_name(frep_mesh_format fmt)
{
    return meshio_format_name(fmt <= FREP_MESH_WRL ? (meshio_format)fmt : MESHIO_UNKNOWN);
}

int frep_mesh_write_stream(const frep_mesh *m, const uint8_t *rgb, FILE *f,
                           frep_mesh_format fmt, int ascii)
{
    if (fmt <= FREP_MESH_AUTO || fmt > FREP_MESH_WRL) {
        errno = EINVAL;
        return -1;
    }
    return meshio_write_colored(f, m, rgb, (meshio_format)fmt, ascii);
}

int frep_mesh_surface_distance(const frep_program *p, const frep_mesh_options *o,
                               const frep_mesh *m, double tol, frep_mesh_distance *r,
                               frep_diag_fn diag, void *user)
{
    mesh_call c;
    if (mesh_call_open(&c, p, o, diag, user) != 0) return api_fail(&c.d, &c.e);
    mesh_distance md;
    memset(&md, 0, sizeof md);
    int rc = mesh_surface_distance(&c.f, &c.mo, m, tol, &md, &c.e);
    mesh_field_program_free(&c.f);
    if (rc != 0) return api_fail(&c.d, &c.e);
    r->max_dist = md.max_dist;
    r->worst = md.worst;
    r->far = md.far;
    r->capped = md.capped;
    r->skipped = md.skipped;
    return 0;
}

int frep_mesh_check(const frep_mesh *m, int self_intersections, frep_mesh_check_result *r,
                    frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    mesh_check c;
    memset(r, 0, sizeof *r);
    if (mesh_validate(m, &c) != 0 ||
        (self_intersections && mesh_self_intersections(m, &r->self_intersections, NULL) != 0))
        return api_fail(&d, NULL);
    r->open_edges = c.open_edges;
    r->nonmanifold_edges = c.nonmanifold_edges;
    r->flipped_edges = c.flipped_edges;
    r->nonmanifold_verts = c.nonmanifold_verts;
    r->unused_verts = c.unused_verts;
    r->degenerate = c.degenerate;
    r->nonfinite = c.nonfinite;
    r->volume = c.volume;
    r->area = c.area;
    return 0;
}

/* ---- the model's colours at the vertices ---- */

/* A colour channel from an attribute: [0,1] -> 0..255, clamped; NaN (a domain error)
 * is 0. */
static uint8_t channel(double v)
{
    if (!(v > 0)) return 0;
    if (v >= 1) return 255;
    return (uint8_t)(v * 255 + 0.5);
}

/* Where the colours are evaluated: the surface point near the vertex (one Newton step
 * along the gradient: a vertex may be a tenth of a cell off a curved surface), then
 * this fraction of the cell inside it.  hfA_SetColor's "where f >= 0" fails at about
 * half of the points exactly on the surface (f = 0 to rounding); a thousandth of a cell
 * moves a colour by far less than 1/255 for any colour that changes by less than its
 * full range over a cell. */
#define MESH_COLOR_INSET 1e-3
/* A Newton step longer than this many cells (a flat spot of f) is not taken. */
#define MESH_COLOR_MAX_STEP 1.0

/* Keep the first error (lowest pc) of two evaluations, counting both. */
static void add_errors(frep_runtime_error *into, const frep_runtime_error *e)
{
    if (e->count == 0) return;
    uint64_t n = into->count;
    if (n == 0 || e->pc < into->pc) *into = *e;
    into->count = n + e->count;
}

/* The points the colours are evaluated at, into xyz (3 n: all x, all y, all z), from
 * f and its gradient at the vertices of m (g: 4 n scratch). */
static int color_points(const frep_program *p, const frep_mesh *m, double cell, double iso,
                        const double *params, int nthreads, double *xyz, double *g,
                        frep_runtime_error *re)
{
    size_t n = m->nverts;
    for (size_t i = 0; i < n; i++)
        for (int q = 0; q < 3; q++) xyz[q * n + i] = m->v[3 * i + q];
    frep_runtime_error e;
    memset(&e, 0, sizeof e);
    if (frep_eval_grad_par(p, n, xyz, xyz + n, xyz + 2 * n, params, g, g + n, g + 2 * n,
                           g + 3 * n, nthreads, &e) != 0)
        return -1;
    add_errors(re, &e);
    for (size_t i = 0; i < n; i++) {
        double d[3] = { g[n + i], g[2 * n + i], g[3 * n + i] };
        double len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2], len = sqrt(len2);
        if (!(len > 0) || !isfinite(len2) || !isfinite(g[i])) continue;
        double t = (iso - g[i]) / len; /* signed distance to f = iso, along d/len */
        if (!(fabs(t) <= MESH_COLOR_MAX_STEP * cell)) t = 0;
        t += MESH_COLOR_INSET * cell;  /* inside: f grows along the gradient */
        for (int q = 0; q < 3; q++) xyz[q * n + i] += t * d[q] / len;
    }
    return 0;
}

int frep_mesh_colors(const frep_program *p, const frep_mesh *m, double cell, double iso,
                     const double *params, int nthreads, uint8_t **rgb, frep_runtime_error *re)
{
    frep_runtime_error all;
    size_t k = frep_program_nattrs(p), n = m->nverts;
    memset(&all, 0, sizeof all);
    *rgb = NULL;
    if (re) *re = all;
    if (k < 3 || n == 0) return 0;
    double *xyz = frep_calloc(n, 3 * sizeof *xyz), *s = frep_calloc(n, k * sizeof *s);
    double *g = frep_calloc(n, 4 * sizeof *g);
    uint8_t *out = frep_calloc(n, 3);
    int rc = xyz && s && g && out &&
                     color_points(p, m, cell, iso, params, nthreads, xyz, g, &all) == 0
                 ? 0
                 : -1;
    if (rc == 0) {
        frep_runtime_error e;
        memset(&e, 0, sizeof e);
        if (frep_eval_attrs_par(p, n, xyz, xyz + n, xyz + 2 * n, params, s, nthreads, &e) != 0)
            rc = -1;
        add_errors(&all, &e);
    }
    if (rc == 0) {
        for (size_t i = 0; i < n; i++)
            for (int q = 0; q < 3; q++) out[3 * i + q] = channel(s[i * k + q]);
        *rgb = out;
    } else
        frep_free(out);
    frep_free(xyz);
    frep_free(g);
    frep_free(s);
    if (re) *re = all;
    return rc;
}
