/* model.c - the model -> mesh steps that frep mesh, sample, render and view share: their
 * model options, compiling with the default box, polygonizing with progress and the
 * messages about the result, runtime errors reported once as warnings; mesh input; a
 * cloud's distances to the model and the model's to the cloud.
 */
#include "config.h"

#include "alloc.h"
#include "cli.h"
#include "cloud.h"
#include "distance.h"
#include "mesh.h"
#include "meshio.h"
#include "program.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* The box of a model without '-- @box' and without -b: HyperFun's default. */
#define MESH_CLI_DEFAULT_BOX 10.0

void mesh_cli_init(mesh_cli *c)
{
    memset(c, 0, sizeof *c);
    c->setops = -1;
}

void mesh_cli_free(mesh_cli *c)
{
    cli_list_free(&c->a);
    if (c->p) frep_program_free(c->p);
    free(c->src);
    c->p = NULL;
    c->src = NULL;
}

int mesh_cli_parse(const cli_opt_spec *spec, int argc, char **argv, void *ctx, size_t mc,
                   cli_args *args)
{
    int rc = cli_opt_parse(spec, argc, argv, ctx, args);
    ((mesh_cli *)((char *)ctx + mc))->has_box = cli_opt_given(spec, args, "box");
    return rc;
}

void mesh_cli_add_errors(mesh_cli *c, const frep_runtime_error *e)
{
    if (e->count == 0) return;
    uint64_t n = c->err.count;
    if (n == 0 || e->pc < c->err.pc) c->err = *e;
    c->err.count = n + e->count;
}

/* Runtime errors do not stop meshing (the points are NaN and count as outside), so
 * they are warnings here; frep eval's format otherwise. */
static void warning_diag(void *user, const frep_diag *d)
{
    frep_diag w = *d;
    w.severity = FREP_WARNING;
    cli_print_diag(user, &w);
}

void mesh_cli_report_errors(mesh_cli *c)
{
    if (c->err.count == 0 || !c->p) return;
    cli_diag_ctx dc = { c->src, c->srclen, 0, 0, NULL, 0, c->diag };
    frep_report_runtime_error(c->p, &c->err, warning_diag, &dc);
    cli_diag_done(&dc);
    memset(&c->err, 0, sizeof c->err);
}

/* A message about the model to standard error, and to c->diag when it is set (frep
 * view shows it in the page). */
static void model_note(mesh_cli *c, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    if (!c->diag) return;
    va_start(ap, fmt);
    char line[512];
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    buf_puts(c->diag, line);
}

static void progress_cb(void *user, double frac)
{
    int *last = user;
    int pct = (int)(100 * frac);
    if (pct == *last) return;
    *last = pct;
    fprintf(stderr, "\rfrep: meshing %3d%%", pct);
    fflush(stderr);
}

/* Does the model read its a[] array (parameters without a name span)? */
static int reads_a(const mesh_cli *c)
{
    const frep_program *p = c->p;
    for (uint32_t k = 0; k < p->ncode; k++)
        if (p->code[k].op == FREP_OP_PARAM && p->code[k].arg < p->nparams &&
            p->params[p->code[k].arg].end <= p->params[p->code[k].arg].off)
            return 1;
    return 0;
}

/* Are all the a[] elements the model has 0 (no -a, no '-- @params')? */
static int a_all_zero(const mesh_cli *c)
{
    for (size_t i = 0; i < c->p->nparams; i++)
        if (c->p->params[i].end <= c->p->params[i].off && c->p->params[i].value != 0) return 0;
    return 1;
}

int mesh_cli_compile(mesh_cli *c, const char *path)
{
    c->path = path;
    if (c->text) {
        c->p = cli_compile_text(path, c->text, strlen(c->text), c->model, c->a.v, c->a.n,
                                c->setops, c->strict, c->diag);
        c->src = c->p ? strdup(c->text) : NULL;
    } else
        c->p = cli_compile_file_diag(path, c->model, c->a.v, c->a.n, c->setops, c->strict, &c->src,
                                     c->diag);
    if (!c->p || cli_work_limit(c->p, c->max_work) != CLI_OK) return CLI_FAIL;
    c->srclen = c->src ? strlen(c->src) : 0;
    if (c->a.n == 0 && reads_a(c) && a_all_zero(c))
        model_note(c, "%s: note: the model reads a[], which neither -a nor a '-- @params' line "
                      "gives values: a[] is all 0\n", path);
    if (!c->has_box && !frep_program_box(c->p, c->box)) {
        for (int i = 0; i < 3; i++) {
            c->box[i] = -MESH_CLI_DEFAULT_BOX;
            c->box[i + 3] = MESH_CLI_DEFAULT_BOX;
        }
    }
    return CLI_OK;
}

/* What the polygonizer found: NaN points, no surface at all, a solid cut by the box. */
static int check_surface(mesh_cli *c, const char *sub, frep_mesh *m, const mesh_stats *st)
{
    if (st->points_nan)
        model_note(c, "%s: warning: the model is NaN (undefined) at %zu grid points; they count "
                      "as outside\n", c->path, st->points_nan);
    if (m->ntris == 0 || st->full) {
        model_note(c, "frep %s: %s: the model %s the box [%g,%g]x[%g,%g]x[%g,%g] at grid %d: "
                      "no surface (check -b and -g%s)\n", sub, c->path,
                st->full ? "fills all of" : "is empty in", c->box[0], c->box[3], c->box[1],
                c->box[4], c->box[2], c->box[5], c->grid, reads_a(c) ? ", and -a" : "");
        mesh_free(m);
        return CLI_FAIL;
    }
    if (st->touches_box)
        model_note(c, "%s: note: the solid reaches the box; the mesh is closed by caps on the "
                      "box faces (a larger -b shows all of it)\n", c->path);
    return CLI_OK;
}

int mesh_cli_polygonize(mesh_cli *c, const char *sub, frep_mesh *m, mesh_stats *st)
{
    /* Ctrl-C also stops the model's loops inside a block of points (the pruned copies
     * of mesh_field_program share the flag) */
    if (frep_program_set_cancel(c->p, cli_sigint_catch()) != 0) {
        fprintf(stderr, "frep %s: out of memory\n", sub);
        return CLI_FAIL;
    }
    mesh_field f;
    if (mesh_field_program(&f, c->p, NULL) != 0) {
        frep_program_set_cancel(c->p, NULL);
        fprintf(stderr, "frep %s: out of memory\n", sub);
        return CLI_FAIL;
    }
    mesh_options o;
    mesh_options_init(&o);
    memcpy(o.box, c->box, sizeof o.box);
    o.grid = c->grid;
    memcpy(o.grid_axes, c->grid_axes, sizeof o.grid_axes);
    o.iso = c->iso;
    o.nthreads = c->nthreads;
    o.interrupt = cli_sigint_catch();
    int last = -1;
    int tty = isatty(2);
    if (tty) {
        o.progress = progress_cb;
        o.progress_user = &last;
    }
    frep_error err;
    frep_error_init(&err);
    int rc = mesh_polygonize(&f, &o, m, st, &err);
    frep_runtime_error re;
    mesh_field_program_errors(&f, &re);
    mesh_cli_add_errors(c, &re);
    mesh_field_program_free(&f);
    frep_program_set_cancel(c->p, NULL);
    if (tty && last >= 0) fputs("\r                     \r", stderr);
    /* interrupted: the points a loop was stopped at are no errors of the model */
    if (rc != 0 && err.code == FREP_ECANCEL)
        return cli_interrupt_status(sub, "stopped while meshing, nothing written");
    mesh_cli_report_errors(c);
    if (frep_program_work_spent(c->p)) {
        if (rc == 0) mesh_free(m);
        return cli_work_check(sub, c->path, c->p);
    }
    if (rc != 0) {
        fprintf(stderr, "frep %s: %s\n", sub, err.msg);
        return CLI_FAIL;
    }
    return check_surface(c, sub, m, st);
}

int cli_is_mesh_path(const char *path)
{
    return meshio_format_for_path(path) != MESHIO_UNKNOWN;
}

int cli_read_mesh(const char *sub, const char *path, frep_mesh *m)
{
    frep_error msg;
    frep_error_init(&msg);
    if (meshio_read(path, m, &msg) == 0) return CLI_OK;
    if (msg.msg[0]) fprintf(stderr, "%s\n", msg.msg);
    else fprintf(stderr, "frep %s: cannot read the mesh\n", sub);
    return CLI_FAIL;
}

/* The signed distances of the points and the vertices', and both scales. */
static int measure(mesh_cli *mc, const frep_mesh *m, cli_cloud_dist *d, frep_error *e)
{
    const frep_cloud *cl = d->cl;
    frep_runtime_error re;
    memset(&re, 0, sizeof re);
    int rc = mc->p ? view_point_distances(mc->p, mc->iso, cl->n, cl->x, cl->y, cl->z,
                                          mc->nthreads, d->pdist, &re, e)
                   : view_mesh_distances(m, cl->n, cl->x, cl->y, cl->z, d->pdist, e);
    if (rc != 0) return -1;
    mesh_cli_add_errors(mc, &re);
    mesh_cli_report_errors(mc);
    if (view_vertex_distances(m, cl->n, cl->x, cl->y, cl->z, d->vdist, e) != 0 ||
        view_auto_scale(d->pdist, cl->n, VIEW_POINTS_QUANTILE, VIEW_POINTS_FACTOR, 0,
                        &d->pscale, e) != 0)
        return -1;
    return view_auto_scale(d->vdist, m->nverts, VIEW_SURFACE_QUANTILE, VIEW_SURFACE_FACTOR, 0,
                           &d->vscale, e);
}

int cli_cloud_measure(const char *sub, mesh_cli *mc, const frep_mesh *m, cli_cloud_dist *d)
{
    d->pdist = malloc((d->cl->n + 1) * sizeof *d->pdist);
    d->vdist = malloc((m->nverts + 1) * sizeof *d->vdist);
    frep_error e;
    frep_error_init(&e);
    if (!d->pdist || !d->vdist) frep_error_nomem(&e);
    else if (measure(mc, m, d, &e) == 0) return CLI_OK;
    model_note(mc, "frep %s: %s\n", sub, e.msg);
    return CLI_FAIL;
}

int cli_cloud_distances(const char *sub, const char *path, mesh_cli *mc, const frep_mesh *m,
                        cli_cloud_dist *d)
{
    frep_error msg;
    frep_error_init(&msg);
    memset(d, 0, sizeof *d);
    d->cl = cloud_read(path, &msg);
    if (!d->cl) {
        if (msg.msg[0]) model_note(mc, "%s\n", msg.msg);
        else model_note(mc, "frep %s: cannot read the cloud\n", sub);
        return CLI_FAIL;
    }
    return cli_cloud_measure(sub, mc, m, d);
}

void cli_cloud_dist_free(cli_cloud_dist *d)
{
    cloud_free(d->cl);
    free(d->pdist);
    free(d->vdist);
    memset(d, 0, sizeof *d);
}

int mesh_cli_vertex_colors(mesh_cli *mc, const char *sub, const frep_mesh *m, uint8_t **rgb)
{
    double cell = HUGE_VAL;
    for (int q = 0; q < 3; q++) {
        int gr = mc->grid_axes[q] ? mc->grid_axes[q] : mc->grid;
        double h = (mc->box[q + 3] - mc->box[q]) / gr;
        cell = h < cell ? h : cell;
    }
    frep_runtime_error re;
    memset(&re, 0, sizeof re);
    int rc = frep_mesh_colors(mc->p, m, cell, mc->iso, NULL, mc->nthreads, rgb, &re);
    mesh_cli_add_errors(mc, &re);
    mesh_cli_report_errors(mc);
    if (rc == 0) return CLI_OK;
    fprintf(stderr, "frep %s: out of memory colouring the mesh\n", sub);
    return CLI_FAIL;
}
