/* cloud.h - point clouds (positions, optional normals) and their file formats.
 *
 * The data that `frep sample` writes and that `frep fit`, `frep segment` and
 * `frep evolve` read: .xyz text (3 or 6 numbers a line) and PLY (ascii and binary).
 * Structure of arrays so the evaluators can take x, y, z directly.
 */
#ifndef FREP_CLOUD_H
#define FREP_CLOUD_H

#include <stddef.h>
#include <stdio.h>

#include "err.h"

/* A point cloud. x, y, z hold n values each; nx, ny, nz are NULL unless has_normals,
 * then they hold n values too (not necessarily unit length: readers keep what the file
 * says). cap is the allocated length of every array. Free with cloud_free(). */
typedef struct frep_cloud {
    size_t n, cap;
    double *x, *y, *z;
    double *nx, *ny, *nz;
    int has_normals;
} frep_cloud;

/* Longest cloud the readers accept: keeps n * sizeof(double) * 6 far from SIZE_MAX
 * and refuses absurd PLY vertex counts before allocating. */
#define CLOUD_MAX_POINTS ((size_t)1 << 31)

/* A new empty cloud (with normal arrays when with_normals). NULL when out of memory.
 * Free with cloud_free(). */
frep_cloud *cloud_new(int with_normals);
void cloud_free(frep_cloud *c);
/* Make room for at least cap points. Returns 0, or -1 when out of memory. */
int cloud_reserve(frep_cloud *c, size_t cap);
/* Append one point (normal ignored when the cloud has none; nrm may be NULL, giving a
 * zero normal). Returns 0, or -1 when out of memory or full. */
int cloud_push(frep_cloud *c, const double p[3], const double nrm[3]);
/* Give the cloud normal arrays (zero-filled) if it has none. Returns 0 or -1. */
int cloud_add_normals(frep_cloud *c);

/* Read a cloud from `path` ("-": standard input). The format is PLY when the data
 * start with "ply\n" (or "ply\r\n"), else .xyz text. Returns NULL on failure with err
 * (reset on entry; may be NULL) holding "path:line: what". */
frep_cloud *cloud_read(const char *path, frep_error *err);
/* Parse a cloud from memory; `name` is used in messages. Same conventions. */
frep_cloud *cloud_parse(const char *name, const char *data, size_t len, frep_error *err);

/* Writers: .xyz with 3 or 6 columns (%.17g; 6 when the cloud has normals), and PLY
 * binary little endian with double properties x y z [nx ny nz]. Return 0, or -1 on a
 * write error (check ferror). Use with cli_write_atomic for atomic output. */
int cloud_write_xyz(FILE *f, const frep_cloud *c);
int cloud_write_ply(FILE *f, const frep_cloud *c);
/* Write in the format named by the extension of `path` (.ply -> PLY, else .xyz). */
int cloud_write_for_path(FILE *f, const frep_cloud *c, const char *path);

/* Axis-aligned bounding box lo[3], hi[3]; zeros for an empty cloud. */
void cloud_bbox(const frep_cloud *c, double lo[3], double hi[3]);
/* Length of the bounding box diagonal (0 for an empty cloud or a single point),
 * without overflow or underflow of the squares (inf only when an extent is). */
double cloud_diagonal(const frep_cloud *c);
/* The scales the fitters and RANSAC work at (their squared and cubed distances stay
 * finite and normal): coordinates of magnitude at most CLOUD_MAX_COORD, and a
 * diagonal, if not 0, of at least CLOUD_MIN_DIAGONAL. */
#define CLOUD_MAX_COORD 1e50
#define CLOUD_MIN_DIAGONAL 1e-50
/* 0, or -1 with err (FREP_EINPUT, "name: ...: rescale the cloud") when c is outside
 * those scales; name (may be NULL) names the cloud in the message. */
int cloud_check_scale(const frep_cloud *c, const char *name, frep_error *err);
/* Normalize the normals to unit length; returns the number of zero-length (or
 * non-finite) normals, which are left as zero vectors. */
size_t cloud_normalize_normals(frep_cloud *c);

#endif
