/* scad.h - frep export: a model as OpenSCAD source (export/scad.c), from the tree of
 * standard solids export/csg.c builds out of the checked syntax tree.
 */
#ifndef FREP_SCAD_H
#define FREP_SCAD_H

#include <stddef.h>

#include "err.h"
#include "frep.h"

/* $fn by default and at most: frep.h's (the reasons are there). */
#define SCAD_DEFAULT_FN FREP_SCAD_DEFAULT_FN
#define SCAD_MAX_FN FREP_SCAD_MAX_FN

typedef struct scad_options {
    const char *model;      /* the model to export; NULL: my_model, else the last */
    const double *a;        /* values of a[] (missing: 0) */
    size_t na;
    double box[6];          /* the box frep mesh uses (lo, hi): unbounded solids are cut
                               by it, and it sizes the stand-ins of infinite solids */
    int fn;                 /* $fn, 3..SCAD_MAX_FN */
    const char *title;      /* first header line (NULL: none), e.g. the command */
} scad_options;

/* OpenSCAD source of a model (file names it in messages; src of len bytes).  Problems
 * of the source, and the construct that has no OpenSCAD equivalent, go to diag as
 * errors with their position (file:line:col); *err then says the export failed.
 * Returns the text (frep_free it) or NULL. */
char *scad_export(const char *file, const char *src, size_t len, const scad_options *o,
                  frep_diag_fn diag, void *user, frep_error *err);

#endif
