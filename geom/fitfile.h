/* fitfile.h - the ".fit" primitive list of the reference GP implementation of Fayolle
 * and Pasko (written by its RANSAC segmenter, read by its GP): one primitive a line,
 *   plane nx ny nz d | sphere cx cy cz r | cylinder ax ay az px py pz r |
 *   cone ax ay az cx cy cz angle | torus ax ay az cx cy cz rminor rmajor
 * Interchange format of `frep segment -o X.fit` and `frep evolve -p X.fit`.
 */
#ifndef FREP_FITFILE_H
#define FREP_FITFILE_H

#include <stddef.h>
#include <stdio.h>

#include "err.h"

#include "prim.h"

/* Parse a .fit list from memory (`name` for messages). Blank lines and lines starting
 * with '#' are skipped. Axes and plane normals are normalized. On success returns 0 and
 * a malloc'ed array in *out (frep_free()); else -1 with err (reset on entry; may be
 * NULL) holding "name:line: what". */
int fitfile_parse(const char *name, const char *text, size_t len, prim **out, size_t *n,
                  frep_error *err);
/* Write the list (%.17g). Returns 0 or -1 on a write error. */
int fitfile_write(FILE *f, const prim *p, size_t n);

#endif
