/* prim.h - fitted primitives in general position: what `frep segment` detects, what
 * `frep evolve` combines, and how both are written as frep model source.
 *
 * Each primitive is a signed distance (inside >= 0) in frep's extension functions of
 * the language (frPlane, frSphere, frCylinder, frCone, frTorus; doc/language.md), so a
 * model written from a list of prim values evaluates to the same numbers.
 */
#ifndef FREP_PRIM_H
#define FREP_PRIM_H

#include <stddef.h>
#include <stdio.h>

typedef enum prim_type {
    PRIM_PLANE,     /* n (unit, outward), d: f = d - n.x          frPlane(x, nx,ny,nz, d) */
    PRIM_SPHERE,    /* c, r: f = r - |x - c|                       frSphere(x, cx,cy,cz, r) */
    PRIM_CYLINDER,  /* p (point on axis), a (unit axis), r: f = r - dist(x, axis)
                                                 frCylinder(x, px,py,pz, ax,ay,az, r) */
    PRIM_CONE,      /* p (apex), a (unit axis, opening direction), angle (half-angle, rad):
                       v = x - p, h = v.a, rho = |v - h a|, f = h sin(angle) - rho cos(angle)
                                                 frCone(x, px,py,pz, ax,ay,az, angle) */
    PRIM_TORUS,     /* p (centre), a (unit axis), R (major), r (minor):
                       f = r - sqrt((rho - R)^2 + h^2)
                                                 frTorus(x, px,py,pz, ax,ay,az, R, r) */
    PRIM__COUNT
} prim_type;

/* Constructed planes (prim.constructed): the cap of a cylinder whose axis meets another
 * cylinder's axis (segment_add_constructed), or the hidden face of a slab at its faces'
 * extent (segment_close_slabs). */
#define PRIM_CONSTRUCTED_MEET 1
#define PRIM_CONSTRUCTED_EXTENT 2

typedef struct prim {
    prim_type type;
    double p[3];      /* plane: n; sphere: c; cylinder/cone/torus: point/apex/centre */
    double a[3];      /* cylinder/cone/torus: unit axis; unused otherwise */
    double r;         /* plane: d; sphere/cylinder/torus minor radius r; cone: angle */
    double R;         /* torus: major radius */
    int separating;   /* added by Algorithm 2 of Fayolle & Pasko 2016, not fitted */
    int constructed;  /* a separating plane no point shows (0: not constructed):
                         PRIM_CONSTRUCTED_MEET or PRIM_CONSTRUCTED_EXTENT */
    size_t support;   /* inlier count (0 for separating primitives) */
    double rms;       /* RMS distance of the inliers */
    /* Bounded proxy: oriented box of the inliers (centre, axes, half sizes); valid when
     * has_obb. Used by the overlap graph of frep evolve. */
    double obb_c[3], obb_axes[3][3], obb_half[3];
    int has_obb;
} prim;

/* Value and (if g != NULL) gradient of a primitive at one point. */
double prim_eval(const prim *q, const double x[3], double g[3]);
/* prim_eval's value (no gradient) in loops over many points: prim_trig(q, sc) once,
 * then prim_value(q, sc, x) per point, the same bits without a cone's sine and cosine
 * per call (14% of the instructions of `frep segment` on a cylinder's noisy scan). */
void prim_trig(const prim *q, double sc[2]);
double prim_value(const prim *q, const double sc[2], const double x[3]);
/* Values (and gradients if gx != NULL) at n points, structure of arrays. */
void prim_eval_many(const prim *q, size_t n, const double *x, const double *y,
                    const double *z, double *f, double *gx, double *gy, double *gz);

/* Name of a type as in .fit files and summaries ("plane", "sphere", ...). */
const char *prim_type_name(prim_type t);
/* Half length of an axial primitive's inliers along its axis (q->a), from its box
 * (has_obb; one box axis is the primitive's axis). */
double prim_axial_half(const prim *q);
/* What a constructed plane q closes, for comments ("a cylinder's cap at another's
 * axis"); the readers of .hf lists take the kind back from it. */
const char *prim_constructed_why(const prim *q);
/* Why q is no surface, or NULL when it is one: a radius (sphere, cylinder, the torus's
 * two) not > 0, a cone's half-angle outside (0, pi/2) (0 is a line, pi/2 a plane,
 * beyond that the cone is empty or inverted), a non-finite parameter. The readers of
 * .fit and .hf lists refuse such primitives with the line. */
const char *prim_degenerate(const prim *q);
/* Printed precision of prim_write_call_scaled, relative to the model's size (scale,
 * e.g. the cloud's diagonal) for positions, radii and plane offsets, and absolute for
 * unit-vector components and cone angles (radians). Fitting noise is orders of
 * magnitude larger, so these digits only drop round-off like 2.9e-13 for 0. */
#define PRIM_POS_QUANTUM 1e-7
#define PRIM_DIR_QUANTUM 1e-9

/* The frep source call for q, e.g. "frSphere(x, 1, 2, 3, 0.5)", each number in the
 * shortest form that reads back exactly. */
void prim_write_call(FILE *f, const prim *q);
/* The same with numbers rounded for reading: each printed value is within half a
 * quantum of the fitted one (PRIM_POS_QUANTUM * scale for positions and lengths,
 * PRIM_DIR_QUANTUM for directions and angles), in the fewest significant digits.
 * scale <= 0 (or not finite) means exact output, as prim_write_call. */
void prim_write_call_scaled(FILE *f, const prim *q, double scale);
/* The same with the quanta given: qpos for positions and lengths, qdir for directions
 * and angles (0: exact). */
void prim_write_call_quanta(FILE *f, const prim *q, double qpos, double qdir);
/* Format v into buf (at least PRIM_NUM_BUF bytes) with the fewest significant digits
 * that stay within quantum / 2 of v ("0" when |v| is below that); quantum <= 0: the
 * shortest form that reads back exactly. */
#define PRIM_NUM_BUF 32
void prim_format_number(char *buf, double v, double quantum);

#endif
