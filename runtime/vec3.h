/* vec3.h - the 3-vector arithmetic of the library (meshing, primitives, RANSAC, GP
 * partitioning): dot and cross products, length, difference and unit vectors.  Inline
 * and exact as written, so every caller rounds the same way.
 */
#ifndef FREP_VEC3_H
#define FREP_VEC3_H

#include <math.h>

static inline double vec3_dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline void vec3_cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static inline double vec3_len(const double a[3]) { return sqrt(vec3_dot(a, a)); }

/* b - a */
static inline void vec3_sub(const double b[3], const double a[3], double d[3])
{
    for (int i = 0; i < 3; i++) d[i] = b[i] - a[i];
}

/* The one normalization of the library: v / |v| and 0 when |v| = sqrt(v . v) is
 * positive and finite; else -1 with v unchanged: |v| is 0 (v is zero, or so short that
 * v . v underflows: every component below about 1e-162), infinite (v . v overflows) or
 * NaN. Such a v has no usable direction; a caller that wants something else then (the
 * zero vector, a fallback direction, an error) does it where it calls. */
static inline int vec3_normalize(double v[3])
{
    double l = vec3_len(v);
    if (!(l > 0) || !isfinite(l)) return -1;
    for (int i = 0; i < 3; i++) v[i] /= l;
    return 0;
}

/* Unit u and v completing unit a to a right-handed frame (a, u, v): u is the x axis
 * (the y axis when a is within about 53 degrees of x) made orthogonal to a. */
static inline void vec3_basis(const double a[3], double u[3], double v[3])
{
    double t[3] = {1, 0, 0};
    if (fabs(a[0]) > 0.6) t[0] = 0, t[1] = 1;
    double d = vec3_dot(t, a);
    for (int k = 0; k < 3; k++) u[k] = t[k] - d * a[k];
    vec3_normalize(u);
    vec3_cross(a, u, v);
}

#endif
