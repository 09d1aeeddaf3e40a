/* api_normals.c - normal estimation in the public API: the checks a cloud must pass
 * (geom/cloud.c's scale, geom/normals.c's shape) and geom/normals.c's robust,
 * consistently oriented normals over a frep_cloud, in place.  frep_segment() runs the
 * same estimate on a cloud without normals (api_estimate_normals).
 */
#include "config.h"

#include "api.h"
#include "cloud.h"
#include "kdtree.h"
#include "normals.h"

#include <string.h>

_Static_assert(FREP_NORMALS_MAX_KNN == KD_MAX_K, "the k-d tree's largest query");
_Static_assert(FREP_NORMALS_MIN_KNN == NORMALS_MIN_POINTS, "three points span a plane");

int frep_cloud_check(const frep_cloud *c, const char *name, int *planar, frep_diag_fn diag,
                     void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    if (planar) *planar = 0;
    if (!name) name = "the cloud";
    if (cloud_check_scale(c, name, &e) || normals_check_cloud(c, name, planar, &e))
        return api_fail(&d, &e);
    return 0;
}

void frep_normals_options_init(frep_normals_options *o)
{
    normals_config c;
    normals_config_init(&c);
    memset(o, 0, sizeof *o);
    o->knn = c.knn;
    o->nthreads = c.nthreads;
}

int api_estimate_normals(frep_cloud *c, size_t knn, int nthreads, volatile sig_atomic_t *flag,
                         frep_normals_info *info)
{
    normals_config cfg;
    normals_config_init(&cfg);
    cfg.knn = knn;
    cfg.nthreads = nthreads;
    cfg.interrupt = flag;
    normals_info ni;
    int rc = normals_run(c, &cfg, &ni);
    if (info) {
        info->knn = ni.knn;
        info->spacing = ni.spacing;
        info->noise = ni.noise;
        info->components = ni.components;
        info->flipped = ni.flipped;
        info->interrupted = ni.interrupted;
    }
    return rc;
}

int frep_normals(frep_cloud *c, const frep_normals_options *o, frep_normals_info *info,
                 frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    frep_normals_options def;
    if (!o) {
        frep_normals_options_init(&def);
        o = &def;
    }
    if (info) memset(info, 0, sizeof *info);
    if (o->knn && (o->knn < FREP_NORMALS_MIN_KNN || o->knn > FREP_NORMALS_MAX_KNN)) {
        frep_error_set(&e, FREP_EINPUT, "knn %zu: expected %d..%d neighbours, or 0 (from the "
                       "data)", o->knn, FREP_NORMALS_MIN_KNN, FREP_NORMALS_MAX_KNN);
        return api_fail(&d, &e);
    }
    if (frep_cloud_check(c, NULL, NULL, diag, user)) return -1;
    int rc = api_estimate_normals(c, o->knn, o->nthreads, o->cancel_flag, info);
    if (rc < 0) return api_fail(&d, NULL);
    return rc;
}
