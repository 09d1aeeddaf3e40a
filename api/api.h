/* api.h - what the public job functions of api/ share (the layer above every library
 * folder and below the frep command): reporting an frep_error or a warning through
 * the caller's frep_diag_fn, writing a file atomically, the default model box.
 */
#ifndef FREP_API_H
#define FREP_API_H

#include <stdio.h>

#include "err.h"
#include "frep.h"
#include "segment.h"

/* The box of a program without `-- @box` when the options give none: HyperFun's
 * default, as the frep command's. */
#define API_DEFAULT_BOX 10.0

/* Where a job reports: the caller's callback (fn may be NULL: nothing is reported). */
typedef struct api_diag {
    frep_diag_fn fn;
    void *user;
} api_diag;

/* Hand message (with its position inside, no file/line fields) to the callback. */
void api_report(const api_diag *d, frep_severity sev, const char *message);
/* e's message as one FREP_ERROR ("out of memory" when e is empty); returns -1. */
int api_fail(const api_diag *d, const frep_error *e);
/* Runtime domain errors of p's evaluations, as one warning with the source position. */
void api_runtime_warning(const api_diag *d, const frep_program *p, const frep_runtime_error *re);

/* Write path ("-": standard output) with fn(f, ctx) returning 0 on success: into a
 * temporary next to it, renamed over path when everything was written.  Returns 0,
 * or -1 after reporting why. */
int api_write_atomic(const api_diag *d, const char *path, int (*fn)(FILE *f, void *ctx),
                     void *ctx);

/* The model box of options o for program p: o's when given, else the program's
 * `-- @box`, else [-API_DEFAULT_BOX, API_DEFAULT_BOX]^3. */
void api_model_box(const frep_program *p, const frep_mesh_options *o, double box[6]);

/* geom/normals.c's estimate over c with knn neighbours (0: from the data), polling
 * flag (may be NULL); info (may be NULL) filled.  Returns as normals_run: 0, 1 when
 * stopped by the flag, -1 out of memory; reports nothing (api/api_normals.c). */
int api_estimate_normals(frep_cloud *c, size_t knn, int nthreads, volatile sig_atomic_t *flag,
                         frep_normals_info *info);

/* A segmentation (api/api_segment.c), whose primitives frep_evolve() reads: segment/'s
 * result; npoints, the cloud's size (0 for primitives read from a file: no labels). */
struct frep_segmentation {
    segment_result r;
    size_t npoints;
};

#endif
