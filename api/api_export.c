/* api_export.c - OpenSCAD source in the public API: export/scad.c's translation of a
 * model's checked tree, with the failure reported through the caller's callback.
 */
#include "config.h"

#include "api.h"
#include "scad.h"

#include <string.h>

void frep_scad_options_init(frep_scad_options *o)
{
    memset(o, 0, sizeof *o);
    for (int i = 0; i < 3; i++) {
        o->box[i] = -API_DEFAULT_BOX;
        o->box[i + 3] = API_DEFAULT_BOX;
    }
    o->fn = FREP_SCAD_DEFAULT_FN;
}

char *frep_export_scad(const char *file, const char *src, size_t len,
                       const frep_scad_options *o, frep_diag_fn diag, void *user)
{
    api_diag ad = { diag, user };
    frep_error e;
    frep_error_init(&e);
    if (!o || !src || o->fn < 3 || o->fn > FREP_SCAD_MAX_FN) {
        frep_error_set(&e, FREP_EINPUT, "frep_export_scad: no source, or $fn outside 3..%d",
                       FREP_SCAD_MAX_FN);
        api_fail(&ad, &e);
        return NULL;
    }
    scad_options so;
    memset(&so, 0, sizeof so);
    so.model = o->model;
    so.a = o->a;
    so.na = o->na;
    memcpy(so.box, o->box, sizeof so.box);
    so.fn = o->fn;
    so.title = o->title;
    char *text = scad_export(file ? file : "(model)", src, len, &so, diag, user, &e);
    if (!text) api_fail(&ad, &e);
    return text;
}
