/* util.c - small internal helpers shared by the library modules (runtime/util.h):
 * the malloc'ed printf behind the readers' error messages, the PLY scalar types
 * decoded by both the point-cloud reader and the mesh reader, the monotonic clock.
 */
#include "config.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "alloc.h"
#include "util.h"

char *frep_strdupf(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n < 0) return NULL;
    char *s = frep_malloc((size_t)n + 1);
    if (!s) return NULL;
    va_start(ap, fmt);
    vsnprintf(s, (size_t)n + 1, fmt, ap);
    va_end(ap);
    return s;
}

frep_ply_type frep_ply_type_of(const char *s)
{
    static const struct { const char *name; frep_ply_type t; } names[] = {
        {"char", FREP_PLY_I8}, {"int8", FREP_PLY_I8},
        {"uchar", FREP_PLY_U8}, {"uint8", FREP_PLY_U8},
        {"short", FREP_PLY_I16}, {"int16", FREP_PLY_I16},
        {"ushort", FREP_PLY_U16}, {"uint16", FREP_PLY_U16},
        {"int", FREP_PLY_I32}, {"int32", FREP_PLY_I32},
        {"uint", FREP_PLY_U32}, {"uint32", FREP_PLY_U32},
        {"float", FREP_PLY_F32}, {"float32", FREP_PLY_F32},
        {"double", FREP_PLY_F64}, {"float64", FREP_PLY_F64},
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (strcmp(s, names[i].name) == 0) return names[i].t;
    return FREP_PLY_NONE;
}

size_t frep_ply_type_size(frep_ply_type t)
{
    switch (t) {
    case FREP_PLY_I8: case FREP_PLY_U8: return 1;
    case FREP_PLY_I16: case FREP_PLY_U16: return 2;
    case FREP_PLY_I32: case FREP_PLY_U32: case FREP_PLY_F32: return 4;
    case FREP_PLY_F64: return 8;
    case FREP_PLY_NONE: break;
    }
    return 0;
}

double frep_ply_decode(const unsigned char *p, frep_ply_type t, int big_endian)
{
    /* Gather the bytes least significant first, then reinterpret: this works the
     * same on hosts of either byte order. */
    unsigned char b[8];
    size_t n = frep_ply_type_size(t);
    if (n > sizeof b) n = sizeof b; /* never: the largest PLY type has 8 bytes */
    for (size_t i = 0; i < n; i++) b[i] = big_endian ? p[n - 1 - i] : p[i];
    uint64_t u = 0;
    for (size_t i = 0; i < n; i++) u |= (uint64_t)b[i] << (8 * i);
    switch (t) {
    case FREP_PLY_I8: return (double)(int8_t)(uint8_t)u;
    case FREP_PLY_U8: return (double)(uint8_t)u;
    case FREP_PLY_I16: return (double)(int16_t)(uint16_t)u;
    case FREP_PLY_U16: return (double)(uint16_t)u;
    case FREP_PLY_I32: return (double)(int32_t)(uint32_t)u;
    case FREP_PLY_U32: return (double)(uint32_t)u;
    case FREP_PLY_F32: {
        uint32_t w = (uint32_t)u;
        float f;
        memcpy(&f, &w, sizeof f);
        return (double)f;
    }
    case FREP_PLY_F64: {
        double d;
        memcpy(&d, &u, sizeof d);
        return d;
    }
    case FREP_PLY_NONE: break;
    }
    return 0.0;
}

double frep_now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
