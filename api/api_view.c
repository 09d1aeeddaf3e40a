/* api_view.c - a cloud against a surface and the page of frep view in the public API:
 * view/distance.c's distances and colour scales, view/page.c's page and scene JSON,
 * view/serve.c's loopback server.  frep view and frep render (api/api_render.c)
 * measure through frep_cloud_distances().
 */
#include "config.h"

#include "api.h"
#include "distance.h"
#include "page.h"
#include "serve.h"

#include <string.h>

#include "alloc.h"

/* point distances (model or mesh) -> runtime errors -> vertex distances -> scales */
int frep_cloud_distances(const frep_cloud *c, const frep_mesh *m, const frep_program *p,
                         double iso, int nthreads, frep_distances *d, frep_diag_fn diag,
                         void *user)
{
    api_diag ad = { diag, user };
    frep_error e;
    frep_error_init(&e);
    memset(d, 0, sizeof *d);
    d->point = frep_malloc((c->n + 1) * sizeof *d->point);
    d->vertex = frep_malloc((m->nverts + 1) * sizeof *d->vertex);
    int rc = d->point && d->vertex ? 0 : frep_error_nomem(&e);
    if (rc == 0) {
        frep_runtime_error re;
        memset(&re, 0, sizeof re);
        rc = p ? view_point_distances(p, iso, c->n, c->x, c->y, c->z, nthreads, d->point, &re, &e)
               : view_mesh_distances(m, c->n, c->x, c->y, c->z, d->point, &e);
        if (rc == 0 && p) api_runtime_warning(&ad, p, &re);
    }
    if (rc == 0)
        rc = view_vertex_distances(m, c->n, c->x, c->y, c->z, d->vertex, &e);
    if (rc == 0)
        rc = view_auto_scale(d->point, c->n, VIEW_POINTS_QUANTILE, VIEW_POINTS_FACTOR, 0,
                             &d->point_scale, &e);
    if (rc == 0)
        rc = view_auto_scale(d->vertex, m->nverts, VIEW_SURFACE_QUANTILE, VIEW_SURFACE_FACTOR,
                             0, &d->vertex_scale, &e);
    if (rc == 0) return 0;
    frep_distances_free(d);
    return api_fail(&ad, &e);
}

void frep_distances_free(frep_distances *d)
{
    if (!d) return;
    frep_free(d->point);
    frep_free(d->vertex);
    memset(d, 0, sizeof *d);
}

/* ---- the page ---------------------------------------------------------------- */

void frep_view_scene_init(frep_view_scene *s)
{
    memset(s, 0, sizeof *s);
}

char *frep_view_page(const frep_view_scene *s, int watch, size_t *len, frep_diag_fn diag,
                     void *user)
{
    api_diag ad = { diag, user };
    frep_error e;
    frep_error_init(&e);
    size_t n = 0;
    char *page = view_page(s, watch, &n, &e);
    if (!page) api_fail(&ad, &e);
    if (len) *len = page ? n : 0;
    return page;
}

int frep_view_write_page(const frep_view_scene *s, FILE *f, frep_diag_fn diag, void *user)
{
    api_diag ad = { diag, user };
    frep_error e;
    frep_error_init(&e);
    return view_write_page(f, s, &e) == 0 ? 0 : api_fail(&ad, &e);
}

char *frep_view_scene_json(const frep_view_scene *s, size_t *len, frep_diag_fn diag,
                           void *user)
{
    api_diag ad = { diag, user };
    frep_buf b = FREP_BUF_INIT;
    view_scene_json(&b, s);
    size_t n = 0;
    char *json = buf_finish(&b, &n);
    if (!json) api_fail(&ad, NULL);
    if (len) *len = json ? n : 0;
    return json;
}

/* ---- the server -------------------------------------------------------------- */

frep_view_server *frep_view_server_open(int port, frep_diag_fn diag, void *user)
{
    api_diag ad = { diag, user };
    frep_error e;
    frep_error_init(&e);
    view_server *s = view_server_open(port, &e);
    if (!s) api_fail(&ad, &e);
    return s;
}

int frep_view_server_port(const frep_view_server *s) { return view_server_port(s); }

int frep_view_server_step(frep_view_server *s, int timeout_ms, frep_view_route_fn route,
                          void *user)
{
    return view_server_step(s, timeout_ms, route, user);
}

void frep_view_server_close(frep_view_server *s)
{
    if (s) view_server_close(s);
}
