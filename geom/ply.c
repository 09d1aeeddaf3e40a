/* ply.c - PLY format names and binary values shared by the readers (geom/ply.h). */
#include "ply.h"

#include <string.h>

int ply_format_of(const char *word, ply_format *fmt)
{
    if (strcmp(word, "ascii") == 0) *fmt = PLY_ASCII;
    else if (strcmp(word, "binary_little_endian") == 0) *fmt = PLY_BIN_LE;
    else if (strcmp(word, "binary_big_endian") == 0) *fmt = PLY_BIN_BE;
    else return -1;
    return 0;
}

int ply_binary_value(const unsigned char **bp, const unsigned char *end, frep_ply_type t,
                     ply_format fmt, double *v)
{
    size_t sz = frep_ply_type_size(t);
    if ((size_t)(end - *bp) < sz) return -1;
    *v = frep_ply_decode(*bp, t, fmt == PLY_BIN_BE);
    *bp += sz;
    return 0;
}
