/* ply.h - what the two PLY readers of geom/ share: the cloud reader (cloud.c, strict
 * header, values as one token stream) and the mesh reader (meshio.c, lenient header,
 * one record a line) each parse their own header grammar with their own messages, and
 * both name formats and decode binary values through these.
 */
#ifndef FREP_PLY_H
#define FREP_PLY_H

#include "util.h"

typedef enum ply_format { PLY_ASCII, PLY_BIN_LE, PLY_BIN_BE } ply_format;

/* The format a header's 'format' line names ("ascii", "binary_little_endian",
 * "binary_big_endian") into *fmt; -1 for any other word. */
int ply_format_of(const char *word, ply_format *fmt);

/* One binary value of type t at *bp (byte order of fmt), *bp advanced past it; -1 when
 * fewer than its bytes remain before end. */
int ply_binary_value(const unsigned char **bp, const unsigned char *end, frep_ply_type t,
                     ply_format fmt, double *v);

#endif
