/* model.c - the model -> mesh steps that frep mesh, sample, render and view share: their
 * model options, compiling with the default box, polygonizing (frep_polygonize) with
 * progress and the messages about the result, runtime errors reported once as
 * warnings; mesh input (frep_mesh_read); a cloud's distances to the model and the
 * model's to the cloud (frep_cloud_distances).  On the public API only.
 */
#include "config.h"

#include "cli.h"

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
    cli_text_puts(c->diag, line);
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

/* Does the model read its a[] array (parameters without a name)? */
static int reads_a(const mesh_cli *c)
{
    for (size_t i = 0; i < frep_program_na(c->p); i++)
        if (frep_program_param_used(c->p, i)) return 1;
    return 0;
}

/* Are all the a[] elements the model has 0 (no -a, no '-- @params')? */
static int a_all_zero(const mesh_cli *c)
{
    for (size_t i = 0; i < frep_program_na(c->p); i++)
        if (frep_program_param_value(c->p, i) != 0) return 0;
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

/* What the polygonizer found: no surface at all, a solid cut by the box. */
static int check_surface(mesh_cli *c, const char *sub, frep_mesh **m, const frep_mesh_info *info)
{
    if (frep_mesh_ntris(*m) == 0 || info->full) {
        model_note(c, "frep %s: %s: the model %s the box [%g,%g]x[%g,%g]x[%g,%g] at grid %d: "
                      "no surface (check -b and -g%s)\n", sub, c->path,
                info->full ? "fills all of" : "is empty in", c->box[0], c->box[3], c->box[1],
                c->box[4], c->box[2], c->box[5], c->grid, reads_a(c) ? ", and -a" : "");
        frep_mesh_free(*m);
        *m = NULL;
        return CLI_FAIL;
    }
    if (info->touches_box)
        model_note(c, "%s: note: the solid reaches the box; the mesh is closed by caps on the "
                      "box faces (a larger -b shows all of it)\n", c->path);
    return CLI_OK;
}

void mesh_cli_options(const mesh_cli *c, frep_mesh_options *o)
{
    frep_mesh_options_init(o);
    memcpy(o->box, c->box, sizeof o->box);
    o->has_box = 1;
    o->grid = c->grid;
    memcpy(o->grid_axes, c->grid_axes, sizeof o->grid_axes);
    o->iso = c->iso;
    o->nthreads = c->nthreads;
}

/* What a job of the public API reports during the model's steps: the model's runtime
 * errors (they carry its position) are printed at once, as warnings with the source
 * line; the first other warning (NaN grid points) and the error are kept, to be
 * printed once the work budget is checked (a spent budget explains both). */
typedef struct job_diag {
    mesh_cli *c;
    char warning[256], error[512];
} job_diag;

static void job_diag_cb(void *user, const frep_diag *d)
{
    job_diag *j = user;
    if (d->file) {
        mesh_cli *c = j->c;
        cli_diag_ctx dc = { c->src, c->srclen, 0, 0, NULL, 0, c->diag };
        cli_print_diag(&dc, d);
        cli_diag_done(&dc);
        return;
    }
    char *to = d->severity == FREP_ERROR ? j->error : j->warning;
    size_t size = d->severity == FREP_ERROR ? sizeof j->error : sizeof j->warning;
    if (!to[0]) snprintf(to, size, "%s", d->message);
}

int mesh_cli_mesh(mesh_cli *c, const char *sub, frep_mesh **m, frep_mesh_info *info)
{
    *m = NULL;
    /* Ctrl-C also stops the model's loops inside a block of points (the pruned copies
     * the mesher makes share the flag) */
    if (frep_program_set_cancel(c->p, cli_sigint_catch()) != 0) {
        fprintf(stderr, "frep %s: out of memory\n", sub);
        return CLI_FAIL;
    }
    frep_mesh_options o;
    mesh_cli_options(c, &o);
    o.cancel_flag = cli_sigint_catch();
    int last = -1;
    int tty = isatty(2);
    if (tty) {
        o.progress = progress_cb;
        o.progress_user = &last;
    }
    job_diag jd = { c, "", "" };
    *m = frep_polygonize(c->p, &o, info, job_diag_cb, &jd);
    frep_program_set_cancel(c->p, NULL);
    if (tty && last >= 0) fputs("\r                     \r", stderr);
    if (!*m && info->interrupted)
        return cli_interrupt_status(sub, "stopped while meshing, nothing written");
    if (frep_program_work_spent(c->p)) {
        frep_mesh_free(*m);
        *m = NULL;
        return cli_work_check(sub, c->path, c->p);
    }
    if (!*m) {
        fprintf(stderr, "frep %s: %s\n", sub, jd.error[0] ? jd.error : "out of memory");
        return CLI_FAIL;
    }
    if (jd.warning[0]) model_note(c, "%s: warning: %s\n", c->path, jd.warning);
    return check_surface(c, sub, m, info);
}

int cli_is_mesh_path(const char *path)
{
    return frep_mesh_format_for_path(path) != FREP_MESH_AUTO;
}

/* A mesh file's reader's message as it is (it names the file and line). */
static void read_diag(void *user, const frep_diag *d)
{
    (void)user;
    fprintf(stderr, "%s\n", d->message);
}

frep_mesh *cli_mesh_read(const char *path)
{
    return frep_mesh_read(path, read_diag, NULL);
}

int cli_cloud_measure(const char *sub, mesh_cli *mc, const frep_mesh *m, cli_cloud_dist *d)
{
    job_diag jd = { mc, "", "" };
    if (frep_cloud_distances(d->cl, m, mc->p, mc->iso, mc->nthreads, &d->d, job_diag_cb, &jd) == 0)
        return CLI_OK;
    model_note(mc, "frep %s: %s\n", sub, jd.error[0] ? jd.error : "out of memory");
    return CLI_FAIL;
}

int cli_cloud_distances(const char *sub, const char *path, mesh_cli *mc, const frep_mesh *m,
                        cli_cloud_dist *d)
{
    memset(d, 0, sizeof *d);
    job_diag jd = { mc, "", "" };
    d->cl = frep_cloud_read(path, job_diag_cb, &jd);
    if (!d->cl) {
        if (jd.error[0]) model_note(mc, "%s\n", jd.error);
        else model_note(mc, "frep %s: cannot read the cloud\n", sub);
        return CLI_FAIL;
    }
    return cli_cloud_measure(sub, mc, m, d);
}

void cli_cloud_dist_free(cli_cloud_dist *d)
{
    frep_cloud_free(d->cl);
    frep_distances_free(&d->d);
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
