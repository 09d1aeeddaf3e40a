/* prim.c - evaluation and source form of fitted primitives (geom/prim.h).
 *
 * The same formulas as the language's frPlane/frSphere/frCylinder/frCone/frTorus, so a
 * model written by prim_write_call evaluates to what segment and evolve computed.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "prim.h"
#include "util.h"
#include "vec3.h"

/* Below this length a radial vector has no direction: the gradient there is chosen
 * perpendicular to the axis so it stays finite (the surface is not smooth there). */
#define PRIM_TINY 1e-300

/* Any unit vector perpendicular to unit a. */
static void any_perp(const double a[3], double u[3])
{
    double t[3] = {0, 0, 0};
    int k = fabs(a[0]) < fabs(a[1]) ? (fabs(a[0]) < fabs(a[2]) ? 0 : 2)
                                    : (fabs(a[1]) < fabs(a[2]) ? 1 : 2);
    t[k] = 1.0;
    double d = vec3_dot(t, a);
    for (int i = 0; i < 3; i++) u[i] = t[i] - d * a[i];
    double l = vec3_len(u);
    for (int i = 0; i < 3; i++) u[i] /= l;
}

/* prim_eval with a cone's sine and cosine of its angle given (s, c; unused by the
 * other types). */
static double eval_sc(const prim *q, const double x[3], double g[3], double s, double c)
{
    double v[3], f = 0.0;
    switch (q->type) {
    case PRIM_PLANE:
        f = q->r - vec3_dot(q->p, x);
        if (g) for (int i = 0; i < 3; i++) g[i] = -q->p[i];
        return f;
    case PRIM_SPHERE: {
        for (int i = 0; i < 3; i++) v[i] = x[i] - q->p[i];
        double l = vec3_len(v);
        f = q->r - l;
        if (g) {
            if (l > PRIM_TINY) for (int i = 0; i < 3; i++) g[i] = -v[i] / l;
            else g[0] = -1, g[1] = 0, g[2] = 0;
        }
        return f;
    }
    case PRIM_CYLINDER:
    case PRIM_CONE:
    case PRIM_TORUS: {
        for (int i = 0; i < 3; i++) v[i] = x[i] - q->p[i];
        double h = vec3_dot(v, q->a);
        double w[3];
        for (int i = 0; i < 3; i++) w[i] = v[i] - h * q->a[i];
        double rho = vec3_len(w);
        double e[3] = {0, 0, 0}; /* unit radial direction, for the gradient */
        if (g) {
            if (rho > PRIM_TINY) for (int i = 0; i < 3; i++) e[i] = w[i] / rho;
            else any_perp(q->a, e);
        }
        if (q->type == PRIM_CYLINDER) {
            f = q->r - rho;
            if (g) for (int i = 0; i < 3; i++) g[i] = -e[i];
        } else if (q->type == PRIM_CONE) {
            f = h * s - rho * c;
            if (g) for (int i = 0; i < 3; i++) g[i] = s * q->a[i] - c * e[i];
        } else {
            double dr = rho - q->R;
            double l = sqrt(dr * dr + h * h);
            f = q->r - l;
            if (g) {
                if (l > PRIM_TINY)
                    for (int i = 0; i < 3; i++) g[i] = -(dr * e[i] + h * q->a[i]) / l;
                else
                    for (int i = 0; i < 3; i++) g[i] = -e[i];
            }
        }
        return f;
    }
    case PRIM__COUNT:
        break;
    }
    if (g) g[0] = g[1] = g[2] = 0.0;
    return NAN;
}

void prim_trig(const prim *q, double sc[2])
{
    int cone = q->type == PRIM_CONE;
    sc[0] = cone ? sin(q->r) : 0;
    sc[1] = cone ? cos(q->r) : 0;
}

double prim_eval(const prim *q, const double x[3], double g[3])
{
    double sc[2];
    prim_trig(q, sc);
    return eval_sc(q, x, g, sc[0], sc[1]);
}

double prim_value(const prim *q, const double sc[2], const double x[3])
{
    return eval_sc(q, x, NULL, sc[0], sc[1]);
}

void prim_eval_many(const prim *q, size_t n, const double *x, const double *y,
                    const double *z, double *f, double *gx, double *gy, double *gz)
{
    for (size_t i = 0; i < n; i++) {
        double p[3] = {x[i], y[i], z[i]}, g[3];
        f[i] = prim_eval(q, p, gx ? g : NULL);
        if (gx) {
            gx[i] = g[0];
            gy[i] = g[1];
            gz[i] = g[2];
        }
    }
}

const char *prim_degenerate(const prim *q)
{
    for (int k = 0; k < 3; k++)
        if (!isfinite(q->p[k]) || !isfinite(q->a[k])) return "a parameter is not finite";
    if (!isfinite(q->r) || !isfinite(q->R)) return "a parameter is not finite";
    switch (q->type) {
    case PRIM_PLANE: return NULL;
    case PRIM_SPHERE:
    case PRIM_CYLINDER: return q->r > 0 ? NULL : "the radius must be > 0";
    case PRIM_CONE:
        return q->r > 0 && q->r < FREP_PI / 2 ? NULL
                                              : "the half-angle must be in (0, pi/2) radians";
    case PRIM_TORUS:
        return q->r > 0 && q->R > 0 ? NULL : "both radii must be > 0";
    case PRIM__COUNT: break;
    }
    return "unknown type";
}

const char *prim_type_name(prim_type t)
{
    switch (t) {
    case PRIM_PLANE: return "plane";
    case PRIM_SPHERE: return "sphere";
    case PRIM_CYLINDER: return "cylinder";
    case PRIM_CONE: return "cone";
    case PRIM_TORUS: return "torus";
    case PRIM__COUNT: break;
    }
    return "?";
}

double prim_axial_half(const prim *q)
{
    double h = 0;
    for (int k = 0; k < 3; k++)
        h = fmax(h, fabs(vec3_dot(q->obb_axes[k], q->a)) * q->obb_half[k]);
    return h;
}

const char *prim_constructed_why(const prim *q)
{
    return q->constructed == PRIM_CONSTRUCTED_EXTENT ? "a slab's hidden face at its faces' extent"
                                                     : "a cylinder's cap at another's axis";
}

void prim_format_number(char *buf, double v, double quantum)
{
    if (!isfinite(v)) {
        snprintf(buf, PRIM_NUM_BUF, "%.17g", v);
        return;
    }
    if (quantum > 0 && fabs(v) < 0.5 * quantum) {
        strcpy(buf, "0");
        return;
    }
    /* At 17 significant digits every double reads back exactly, so the loop ends. */
    for (int digits = 1; digits <= 17; digits++) {
        snprintf(buf, PRIM_NUM_BUF, "%.*g", digits, v);
        double t = strtod(buf, NULL);
        if (quantum > 0 ? fabs(t - v) <= 0.5 * quantum : t == v) break;
    }
    if (strcmp(buf, "-0") == 0) strcpy(buf, "0");
}

void prim_write_call_quanta(FILE *f, const prim *q, double qp, double qd)
{
    /* Each argument after x with its quantum, in the call's order. */
    double v[8], qu[8];
    int n = 0;
    const char *name = "frPlane";
    switch (q->type) {
    case PRIM_PLANE:
    case PRIM_SPHERE:
        name = q->type == PRIM_PLANE ? "frPlane" : "frSphere";
        for (int k = 0; k < 3; k++) {
            v[n] = q->p[k];
            qu[n++] = q->type == PRIM_PLANE ? qd : qp;
        }
        v[n] = q->r;
        qu[n++] = qp;
        break;
    case PRIM_CYLINDER:
    case PRIM_CONE:
    case PRIM_TORUS:
        name = q->type == PRIM_CYLINDER ? "frCylinder" : q->type == PRIM_CONE ? "frCone"
                                                                            : "frTorus";
        for (int k = 0; k < 3; k++) {
            v[n] = q->p[k];
            qu[n++] = qp;
        }
        for (int k = 0; k < 3; k++) {
            v[n] = q->a[k];
            qu[n++] = qd;
        }
        if (q->type == PRIM_TORUS) {
            v[n] = q->R;
            qu[n++] = qp;
        }
        v[n] = q->r;
        qu[n++] = q->type == PRIM_CONE ? qd : qp;
        break;
    case PRIM__COUNT:
        fputs("0", f);
        return;
    }
    fprintf(f, "%s(x", name);
    for (int k = 0; k < n; k++) {
        char buf[PRIM_NUM_BUF];
        prim_format_number(buf, v[k], qu[k]);
        fprintf(f, ", %s", buf);
    }
    fputc(')', f);
}

void prim_write_call_scaled(FILE *f, const prim *q, double scale)
{
    int exact = !(scale > 0) || !isfinite(scale);
    prim_write_call_quanta(f, q, exact ? 0 : PRIM_POS_QUANTUM * scale,
                           exact ? 0 : PRIM_DIR_QUANTUM);
}

void prim_write_call(FILE *f, const prim *q)
{
    prim_write_call_scaled(f, q, 0.0);
}
