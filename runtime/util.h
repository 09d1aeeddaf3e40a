/* util.h - small internal helpers shared by the library modules (not public API).
 *
 * A malloc'ed printf for the "file:line: what" messages the readers hand back, the
 * PLY scalar types that both the cloud reader (cloud.c) and the mesh reader
 * (meshio.c) decode, a monotonic clock for timings, a union-find forest, and pi.
 */
#ifndef FREP_UTIL_H
#define FREP_UTIL_H

#include <stddef.h>
#include <stdint.h>

/* printf into a new string; returns it (free with frep_free()) or NULL when out of memory
 * or on an encoding error. */
char *frep_strdupf(const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 1, 2)))
#endif
    ;

/* The scalar types of a PLY property; FREP_PLY_NONE for a name PLY does not define. */
typedef enum frep_ply_type {
    FREP_PLY_NONE, FREP_PLY_I8, FREP_PLY_U8, FREP_PLY_I16, FREP_PLY_U16,
    FREP_PLY_I32, FREP_PLY_U32, FREP_PLY_F32, FREP_PLY_F64
} frep_ply_type;

/* The type named s in a PLY header ("uchar", "float32", ...), or FREP_PLY_NONE. */
frep_ply_type frep_ply_type_of(const char *s);
/* Bytes one binary value of type t takes (0 for FREP_PLY_NONE). */
size_t frep_ply_type_size(frep_ply_type t);
/* Decode one binary value of type t at p (frep_ply_type_size(t) bytes), big-endian
 * when big_endian is non-zero, little-endian otherwise. */
double frep_ply_decode(const unsigned char *p, frep_ply_type t, int big_endian);

/* Seconds on a monotonic clock (differences are wall time, immune to clock changes). */
double frep_now_seconds(void);

/* Coordinate i of the grid of n cells from lo to hi (points i = 0..n; eval --grid,
 * the polygonizer and so sampling lay their grids with it): lo + (hi - lo) i / n, the
 * formula HyperFun's and libfive's grids use, with both end points exact (i = n gives
 * hi itself, which lo + (hi - lo) need not round to).  i outside 0..n extrapolates (the
 * polygonizer's padding cells). */
static inline double frep_grid_coord(double lo, double hi, long i, long n)
{
    if (i == n) return hi;
    return lo + (hi - lo) * (double)i / (double)n;
}

/* The root of element i in the union-find forest up[] (up[r] == r at a root), the path
 * halved on the way. */
static inline uint32_t frep_uf_root(uint32_t *up, uint32_t i)
{
    while (up[i] != i) {
        up[i] = up[up[i]];
        i = up[i];
    }
    return i;
}

/* The sets of a and b joined: the larger root goes below the smaller, so that every
 * element's parent has a smaller index than it (a pass in index order meets a root
 * before the elements below it). */
static inline void frep_uf_join(uint32_t *up, uint32_t a, uint32_t b)
{
    uint32_t ra = frep_uf_root(up, a), rb = frep_uf_root(up, b);
    if (ra != rb) up[ra > rb ? ra : rb] = ra < rb ? ra : rb;
}

/* pi to more digits than a double holds (C11 has no M_PI). */
#define FREP_PI 3.14159265358979323846

#endif
