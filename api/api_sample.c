/* api_sample.c - surface sampling in the public API: mesh/sample.c over a program's
 * field (frep_sample) or a mesh's triangles (frep_sample_mesh).
 */
#include "config.h"

#include "api.h"
#include "sample.h"

_Static_assert(FREP_SAMPLE_MAX_POINTS == SAMPLE_MAX_POINTS, "the sampler's limit");

#include <string.h>

void frep_sample_options_init(frep_sample_options *o)
{
    sample_options so;
    sample_options_init(&so);
    memset(o, 0, sizeof *o);
    o->n = so.n;
    o->seed = so.seed;
    o->noise = so.noise;
    o->noise_absolute = so.noise_absolute;
    o->outliers = so.outliers;
    frep_mesh_options_init(&o->mesh);
    o->mesh.grid = so.mesh.grid;   /* 0: from the point count */
}

/* The sampler's options from the public ones (NULL: the defaults); the box resolved
 * for program p (NULL: a mesh, whose bounding box the sampler takes itself). */
static void to_sample_options(const frep_program *p, const frep_sample_options *o,
                              sample_options *so)
{
    frep_sample_options def;
    if (!o) {
        frep_sample_options_init(&def);
        o = &def;
    }
    sample_options_init(so);
    so->n = o->n;
    so->seed = o->seed;
    so->noise = o->noise;
    so->noise_absolute = o->noise_absolute;
    so->outliers = o->outliers;
    if (p) api_model_box(p, &o->mesh, so->mesh.box);
    so->mesh.grid = o->mesh.grid;
    so->mesh.iso = o->mesh.iso;
    so->mesh.nthreads = o->mesh.nthreads;
    so->mesh.progress = o->mesh.progress;
    so->mesh.progress_user = o->mesh.progress_user;
    so->mesh.interrupt = o->mesh.cancel_flag;
}

/* The sampler's failure: reported, unless it was stopped by the cancel flag. */
static frep_cloud *failed(const api_diag *d, const frep_error *e)
{
    if (e->code != FREP_ECANCEL) api_fail(d, e);
    return NULL;
}

frep_cloud *frep_sample(const frep_program *p, const frep_sample_options *o,
                        frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    sample_options so;
    to_sample_options(p, o, &so);
    mesh_field f;
    if (mesh_field_program(&f, p, o ? o->mesh.params : NULL) != 0) {
        api_fail(&d, &e);
        return NULL;
    }
    frep_cloud *c = NULL;
    int rc = sample_field(&f, &so, &c, &e);
    frep_runtime_error re;
    mesh_field_program_errors(&f, &re);
    mesh_field_program_free(&f);
    api_runtime_warning(&d, p, &re);
    return rc != 0 ? failed(&d, &e) : c;
}

frep_cloud *frep_sample_mesh(const frep_mesh *m, const frep_sample_options *o,
                             frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    sample_options so;
    to_sample_options(NULL, o, &so);
    frep_cloud *c = NULL;
    return sample_mesh(m, &so, &c, &e) != 0 ? failed(&d, &e) : c;
}
