/* residual.h - `frep evolve --residual MODEL.hf`: an existing model becomes one more
 * leaf of the construction tree (the user-assisted loop of Fayolle & Pasko 2016, 6.6).
 *
 * The model's source is prepared for inclusion in the output (its pragmas disarmed, a
 * model named my_model renamed), its values and gradients are computed at the cloud's
 * points, and the points it explains poorly are marked; evolve.c then evolves a tree
 * for those points and joins it to the model.
 */
#ifndef FREP_EVOLVE_RESIDUAL_H
#define FREP_EVOLVE_RESIDUAL_H

#include <stddef.h>
#include <stdint.h>

#include "cloud.h"
#include "err.h"
#include "frep.h"
#include "tree.h"

/* Name the base model gets when it was called my_model, so that the joined model
 * (always my_model) is the file's default. A digit is appended while it is taken. */
#define RESIDUAL_BASE_NAME "base_model"

/* The model given with --residual, ready to be written before the joined model. */
typedef struct evolve_base {
    char *text;         /* its source: pragmas disarmed ("-- @box" -> "-- box"), the
                           chosen model renamed when it was my_model; NUL-terminated */
    char *name;         /* name of the chosen model in `text` */
    char *header;       /* parameter list for the joined model, e.g. "x[3], a[2]" */
    char *call;         /* the call of the base model from the joined one, "base(x, a)" */
    gp_setops setops;   /* the family its file uses (the evolved tree must match) */
    const frep_program *prog; /* compiled from the original source (not owned) */
} evolve_base;

/* Prepare the base model from its source (it must compile: prog is its program, with
 * `model` the chosen model's name or NULL for the default choice). Returns 0, or -1 with
 * err (may be NULL) set: parse failure, R-alpha set operations, a model not in 3D
 * ("file:line: what", FREP_EINPUT), out of memory (FREP_ENOMEM). Free with
 * residual_free(). */
int residual_prepare(const char *file, const char *src, size_t len, const char *model,
                     const frep_program *prog, evolve_base *b, frep_error *err);
void residual_free(evolve_base *b);

/* Values f[i] and gradients g[3i+c] of the base model at every cloud point, and ok[i]:
 * 1 where it could be evaluated, 0 where it cannot (runtime error, non-finite value;
 * f and g are then 0, and evolve treats the point as one the base leaves unexplained,
 * see evolve_options.base_ok). *nbad (may be NULL) counts the latter.
 * Returns 0, or -1 when out of memory. */
int residual_eval(const evolve_base *b, const frep_cloud *c, int threads, double *f,
                  double *g, uint8_t *ok, size_t *nbad);

#endif
