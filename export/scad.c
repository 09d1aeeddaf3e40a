/* scad.c - frep export: OpenSCAD source of a model, from export/csg.c's tree.
 *
 * parse (lang/parse.y) -> check (lang/check.c) -> csg_from_model (export/csg.c) -> the
 * text here.  Each sub-expression the model names (`body = ...;`) becomes a module of
 * that name, so the file reads like the model; min/max become intersection(),
 * union() and difference().  OpenSCAD has no infinite solids: a half-space is a cube,
 * an infinite cylinder or cone a long one, `big` units on a side around the mesh box
 * (4 box diagonals, so every part of them inside the box is exact), and a solid that
 * is unbounded as a whole is cut by the box, as frep mesh cuts it.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "buf.h"
#include "check.h"
#include "csg.h"
#include "scad.h"

/* Stand-ins of infinite solids span this many box diagonals. */
#define SCAD_BIG_DIAGONALS 4.0

typedef struct named {
    const csg_node *n;
    char name[80];
} named;

typedef struct writer {
    frep_buf *b;
    const scad_options *o;
    double big;          /* side of a half-space's cube, world units */
    double cb[3];        /* the box centre */
    named *mods;         /* sub-expressions written as modules, dependencies first */
    size_t nmods, cap;
    int universe;        /* a complement needs the universe() module */
    int nomem;
} writer;

/* ---- numbers and frames --------------------------------------------------------- */

/* A number as short as it can be while reading back within 1e-12 relative. */
static void num(writer *w, double v)
{
    char s[32];
    if (fabs(v) < 1e-300) v = 0;
    for (int p = 6; p <= 17; p++) {
        snprintf(s, sizeof s, "%.*g", p, v);
        double r = strtod(s, NULL);
        if (fabs(r - v) <= 1e-12 * fabs(v)) break;
    }
    if (strcmp(s, "-0") == 0) strcpy(s, "0");
    buf_puts(w->b, s);
}

/* A length rounded up to two significant digits: stand-ins only need to be long. */
static double round_up(double v)
{
    if (!(v > 0)) return v;
    double p = pow(10, floor(log10(v)) - 1);
    return ceil(v / p) * p;
}

static void vec(writer *w, const double *v)
{
    buf_putc(w->b, '[');
    for (int i = 0; i < 3; i++) {
        if (i) buf_puts(w->b, ", ");
        num(w, v[i]);
    }
    buf_putc(w->b, ']');
}

static void indent(writer *w, int d)
{
    for (int i = 0; i < d; i++) buf_puts(w->b, "    ");
}

static int is_zero3(const double *v) { return v[0] == 0 && v[1] == 0 && v[2] == 0; }

static void translate(writer *w, const double *t)
{
    if (is_zero3(t)) return;
    buf_puts(w->b, "translate(");
    vec(w, t);
    buf_puts(w->b, ") ");
}

/* A rotation taking +z to the unit vector u: the axis-aligned ones as rotate([..]). */
static void frame_z(writer *w, const double *u)
{
    static const struct { double u[3]; const char *s; } ax[] = {
        { { 0, 0, 1 }, "" },                        { { 0, 0, -1 }, "rotate([180, 0, 0]) " },
        { { 1, 0, 0 }, "rotate([0, 90, 0]) " },     { { -1, 0, 0 }, "rotate([0, -90, 0]) " },
        { { 0, 1, 0 }, "rotate([-90, 0, 0]) " },    { { 0, -1, 0 }, "rotate([90, 0, 0]) " },
    };
    for (size_t i = 0; i < sizeof ax / sizeof *ax; i++)
        if (fabs(u[0] - ax[i].u[0]) < 1e-15 && fabs(u[1] - ax[i].u[1]) < 1e-15 &&
            fabs(u[2] - ax[i].u[2]) < 1e-15) {
            buf_puts(w->b, ax[i].s);
            return;
        }
    /* About z x u by the angle between them. */
    double deg = acos(fmax(-1.0, fmin(1.0, u[2]))) * 180 / 3.14159265358979323846;
    double v[3] = { -u[1], u[0], 0 };
    buf_puts(w->b, "rotate(a = ");
    num(w, deg);
    buf_puts(w->b, ", v = ");
    vec(w, v);
    buf_puts(w->b, ") ");
}

static void inverse3(const double *A, double *I)
{
    double d = A[0] * (A[4] * A[8] - A[5] * A[7]) - A[1] * (A[3] * A[8] - A[5] * A[6]) +
               A[2] * (A[3] * A[7] - A[4] * A[6]);
    I[0] = (A[4] * A[8] - A[5] * A[7]) / d;
    I[1] = (A[2] * A[7] - A[1] * A[8]) / d;
    I[2] = (A[1] * A[5] - A[2] * A[4]) / d;
    I[3] = (A[5] * A[6] - A[3] * A[8]) / d;
    I[4] = (A[0] * A[8] - A[2] * A[6]) / d;
    I[5] = (A[2] * A[3] - A[0] * A[5]) / d;
    I[6] = (A[3] * A[7] - A[4] * A[6]) / d;
    I[7] = (A[1] * A[6] - A[0] * A[7]) / d;
    I[8] = (A[0] * A[4] - A[1] * A[3]) / d;
}

/* The map from a solid's frame q = A w + b to the world: w = A^-1 (q - b). */
static void local_frame(writer *w, const csg_node *n)
{
    static const double I[9] = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
    if (memcmp(n->A, I, sizeof I) == 0) {
        double t[3] = { -n->b[0], -n->b[1], -n->b[2] };
        translate(w, t);
        return;
    }
    double Ai[9], t[3];
    inverse3(n->A, Ai);
    for (int i = 0; i < 3; i++)
        t[i] = -(Ai[3 * i] * n->b[0] + Ai[3 * i + 1] * n->b[1] + Ai[3 * i + 2] * n->b[2]);
    buf_puts(w->b, "multmatrix([");
    for (int i = 0; i < 3; i++) {
        buf_putc(w->b, '[');
        for (int j = 0; j < 3; j++) {
            num(w, Ai[3 * i + j]);
            buf_puts(w->b, ", ");
        }
        num(w, t[i]);
        buf_puts(w->b, "], ");
    }
    buf_puts(w->b, "[0, 0, 0, 1]]) ");
}

/* ---- solids ------------------------------------------------------------------- */

static const char *const axis_name[3] = { "x", "y", "z" };

/* rotate() taking +z to axis `a`, and the scale of a unit circle to the ellipse of
 * radii ea (along the first other axis, lang/lib_hf.c's order) and eb. */
static void axis_frame(writer *w, int a, double ea, double eb)
{
    static const char *const rot[3] = { "rotate([0, 90, 0]) ", "rotate([-90, 0, 0]) ", "" };
    buf_puts(w->b, rot[a]);
    if (ea == eb) return;
    /* rotate([0, 90, 0]) sends local x to -z, y to y: x's ellipse (y, z) is [eb, ea]. */
    double s[3] = { a == 0 ? eb : ea, a == 0 ? ea : eb, 1 };
    buf_puts(w->b, "scale(");
    vec(w, s);
    buf_puts(w->b, ") ");
}

static void torus_profile(writer *w, double R, double r)
{
    buf_puts(w->b, "rotate_extrude() ");
    if (r <= R) {
        buf_puts(w->b, "translate([");
        num(w, R);
        buf_puts(w->b, ", 0]) circle(r = ");
        num(w, r);
        buf_puts(w->b, ");");
        return;
    }
    /* A spindle torus: the profile circle crosses the axis; keep its outer half. */
    buf_puts(w->b, "intersection() { translate([");
    num(w, R);
    buf_puts(w->b, ", 0]) circle(r = ");
    num(w, r);
    buf_puts(w->b, "); translate([0, ");
    num(w, -r);
    buf_puts(w->b, "]) square([");
    num(w, R + r);
    buf_puts(w->b, ", ");
    num(w, 2 * r);
    buf_puts(w->b, "]); }");
}

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void prim(writer *w, const csg_node *n)
{
    const double *p = n->p;
    /* The box centre in the solid's frame, and the length of infinite stand-ins there. */
    double qc[3], na = 0;
    for (int i = 0; i < 3; i++) {
        qc[i] = n->b[i];
        for (int j = 0; j < 3; j++) {
            qc[i] += n->A[3 * i + j] * w->cb[j];
            na += n->A[3 * i + j] * n->A[3 * i + j];
        }
    }
    double L = round_up(w->big * sqrt(na));
    local_frame(w, n);
    switch (n->prim) {
    case CSG_SPHERE:
        translate(w, p);
        buf_puts(w->b, "sphere(r = ");
        num(w, p[3]);
        buf_puts(w->b, ");");
        break;
    case CSG_ELLIPSOID:
        translate(w, p);
        buf_puts(w->b, "scale(");
        vec(w, p + 3);
        buf_puts(w->b, ") sphere(r = 1);");
        break;
    case CSG_CYL_AXIS: {
        double c[3] = { p[0], p[1], p[2] };
        c[n->axis] = qc[n->axis];
        translate(w, c);
        axis_frame(w, n->axis, p[3], p[4]);
        buf_puts(w->b, "cylinder(h = ");
        num(w, L);
        buf_puts(w->b, ", r = ");
        num(w, p[3] == p[4] ? p[3] : 1);
        buf_printf(w->b, ", center = true);  // infinite along %s", axis_name[n->axis]);
        break;
    }
    case CSG_CONE_AXIS: {
        double H = round_up(L + fabs(qc[n->axis] - p[n->axis]));
        translate(w, p);
        axis_frame(w, n->axis, p[3], p[4]);
        double r2 = p[3] == p[4] ? p[3] * H : H;
        for (int k = 0; k < 2; k++) {
            buf_puts(w->b, k ? " mirror([0, 0, 1]) cylinder(h = " : "{ cylinder(h = ");
            num(w, H);
            buf_puts(w->b, ", r1 = 0, r2 = ");
            num(w, r2);
            buf_puts(w->b, ");");
        }
        buf_printf(w->b, " }  // double cone along %s", axis_name[n->axis]);
        break;
    }
    case CSG_TORUS_AXIS:
        translate(w, p);
        axis_frame(w, n->axis, 1, 1);
        torus_profile(w, p[3], p[4]);
        break;
    case CSG_BLOCK: {
        double v[3], d[3];
        for (int i = 0; i < 3; i++) {
            v[i] = p[i] + fmin(p[3 + i], 0);
            d[i] = fabs(p[3 + i]);
        }
        translate(w, v);
        buf_puts(w->b, "cube(");
        vec(w, d);
        buf_puts(w->b, ");");
        break;
    }
    case CSG_CYLINDER: {
        double t = (qc[0] - p[0]) * p[3] + (qc[1] - p[1]) * p[4] + (qc[2] - p[2]) * p[5];
        double f[3] = { p[0] + t * p[3], p[1] + t * p[4], p[2] + t * p[5] };
        translate(w, f);
        frame_z(w, p + 3);
        buf_puts(w->b, "cylinder(h = ");
        num(w, L);
        buf_puts(w->b, ", r = ");
        num(w, p[6]);
        buf_puts(w->b, ", center = true);  // infinite");
        break;
    }
    case CSG_CONE: {
        double d[3] = { qc[0] - p[0], qc[1] - p[1], qc[2] - p[2] };
        double H = round_up(L + fabs(dot3(d, p + 3)));
        translate(w, p);
        frame_z(w, p + 3);
        buf_puts(w->b, "cylinder(h = ");
        num(w, H);
        buf_puts(w->b, ", r1 = 0, r2 = ");
        num(w, H * tan(p[6]));
        buf_puts(w->b, ");  // infinite cone from its apex");
        break;
    }
    case CSG_TORUS:
        translate(w, p);
        frame_z(w, p + 3);
        torus_profile(w, p[6], p[7]);
        break;
    case CSG_BOX: {
        double deg[3], s[3];
        for (int i = 0; i < 3; i++) {
            deg[i] = p[6 + i] * 180 / 3.14159265358979323846;
            s[i] = 2 * fabs(p[3 + i]);
        }
        translate(w, p);
        if (!is_zero3(deg)) {
            buf_puts(w->b, "rotate(");
            vec(w, deg);
            buf_puts(w->b, ") ");
        }
        buf_puts(w->b, "cube(");
        vec(w, s);
        buf_puts(w->b, ", center = true);");
        break;
    }
    }
    buf_putc(w->b, '\n');
}

/* The half-space k0 + g.w >= 0 as a cube of side big on its inner side, centred on
 * the foot of the box centre; its equation in a comment. */
static void half(writer *w, const csg_node *n)
{
    const double *g = n->k + 1;
    double gg = dot3(g, g), gl = sqrt(gg), u[3];
    double t = (n->k[0] + dot3(g, w->cb)) / gg;
    double f[3];
    for (int i = 0; i < 3; i++) {
        u[i] = g[i] / gl;
        f[i] = w->cb[i] - t * g[i];
    }
    int axis = -1;
    for (int i = 0; i < 3; i++)
        if (g[(i + 1) % 3] == 0 && g[(i + 2) % 3] == 0) axis = i;
    double B = w->big;
    if (axis >= 0) {
        /* Axis-aligned: the cube's lowest corner directly. */
        double lo[3];
        for (int i = 0; i < 3; i++) lo[i] = f[i] - B / 2;
        lo[axis] = g[axis] > 0 ? f[axis] : f[axis] - B;
        translate(w, lo);
        buf_puts(w->b, "cube(big);  // ");
        buf_printf(w->b, "%s %s ", axis_name[axis], g[axis] > 0 ? ">=" : "<=");
        num(w, -n->k[0] / g[axis]);
        buf_putc(w->b, '\n');
        return;
    }
    translate(w, f);
    frame_z(w, u);
    buf_puts(w->b, "translate([-big / 2, -big / 2, 0]) cube(big);  // ");
    for (int i = 0, first = 1; i < 3; i++) {
        if (g[i] == 0) continue;
        buf_puts(w->b, !first && g[i] >= 0 ? " + " : !first ? " - " : g[i] < 0 ? "-" : "");
        first = 0;
        num(w, fabs(g[i]) / gl);
        buf_printf(w->b, " %s", axis_name[i]);
    }
    buf_puts(w->b, " >= ");
    num(w, -n->k[0] / gl);
    buf_putc(w->b, '\n');
}

/* ---- set operations ------------------------------------------------------------- */

static const char *mod_name(const writer *w, const csg_node *n)
{
    for (size_t i = 0; i < w->nmods; i++)
        if (w->mods[i].n == n) return w->mods[i].name;
    return NULL;
}

static void node(writer *w, const csg_node *n, int d, int top);

/* The operands of a chain of one operation (a | b | c is one union()), a named
 * sub-expression being one operand. */
static void gather(writer *w, const csg_node *n, csg_kind k, const csg_node ***v, size_t *len,
                   size_t *cap)
{
    /* A constant that changes no sign: max(-1, f) and min(1, f) are f's solid. */
    double c = n->k[0];
    if (n->kind == CSG_HALF && n->k[1] == 0 && n->k[2] == 0 && n->k[3] == 0 &&
        (k == CSG_MAX ? c < 0 : c >= 0))
        return;
    if (n->kind == k && !mod_name(w, n)) {
        gather(w, n->a, k, v, len, cap);
        gather(w, n->c, k, v, len, cap);
        return;
    }
    if (*len == *cap) {
        size_t nc = *cap ? 2 * *cap : 8;
        const csg_node **nv = frep_realloc(*v, nc * sizeof *nv);
        if (!nv) {
            w->nomem = 1;
            return;
        }
        *v = nv;
        *cap = nc;
    }
    (*v)[(*len)++] = n;
}

static void block(writer *w, const char *op, const csg_node *const *v, size_t len, int d)
{
    indent(w, d);
    buf_printf(w->b, "%s() {\n", op);
    for (size_t i = 0; i < len; i++) node(w, v[i], d + 1, 0);
    indent(w, d);
    buf_puts(w->b, "}\n");
}

/* An intersection: its complemented operands subtracted from the others. */
static void intersection(writer *w, const csg_node *n, int d)
{
    const csg_node **v = NULL, **pos = NULL, **negs = NULL;
    size_t len = 0, cap = 0, np = 0, nn = 0, cn = 0;
    gather(w, n->a, CSG_MIN, &v, &len, &cap);
    gather(w, n->c, CSG_MIN, &v, &len, &cap);
    pos = frep_malloc((len + 1) * sizeof *pos);
    if (!pos) w->nomem = 1;
    for (size_t i = 0; pos && i < len; i++) {
        if (v[i]->kind == CSG_NOT) gather(w, v[i]->a, CSG_MAX, &negs, &nn, &cn);
        else pos[np++] = v[i];
    }
    if (w->nomem) {
        frep_free(v);
        frep_free(pos);
        frep_free(negs);
        return;
    }
    if (nn == 0) {
        block(w, "intersection", pos, np, d);
    } else {
        indent(w, d);
        buf_puts(w->b, "difference() {\n");
        if (np == 0) {
            indent(w, d + 1);
            buf_puts(w->b, "universe();\n");
            w->universe = 1;
        } else if (np == 1) {
            node(w, pos[0], d + 1, 0);
        } else {
            block(w, "intersection", pos, np, d + 1);
        }
        for (size_t i = 0; i < nn; i++) node(w, negs[i], d + 1, 0);
        indent(w, d);
        buf_puts(w->b, "}\n");
    }
    frep_free(v);
    frep_free(pos);
    frep_free(negs);
}

/* One node at depth d; a named sub-expression is a call of its module unless top. */
static void node(writer *w, const csg_node *n, int d, int top)
{
    const char *name = mod_name(w, n);
    if (name && !top) {
        indent(w, d);
        buf_printf(w->b, "%s();\n", name);
        return;
    }
    switch (n->kind) {
    case CSG_HALF: {
        indent(w, d);
        if (n->k[1] == 0 && n->k[2] == 0 && n->k[3] == 0) {
            w->universe |= n->k[0] >= 0;
            buf_puts(w->b, n->k[0] >= 0 ? "universe();  // all of space\n"
                                        : "union();  // nothing\n");
            return;
        }
        half(w, n);
        return;
    }
    case CSG_PRIM:
        indent(w, d);
        prim(w, n);
        return;
    case CSG_NOT:
        indent(w, d);
        buf_puts(w->b, "difference() {\n");
        indent(w, d + 1);
        buf_puts(w->b, "universe();\n");
        w->universe = 1;
        node(w, n->a, d + 1, 0);
        indent(w, d);
        buf_puts(w->b, "}\n");
        return;
    case CSG_MIN:
        intersection(w, n, d);
        return;
    case CSG_MAX: {
        const csg_node **v = NULL;
        size_t len = 0, cap = 0;
        gather(w, n->a, CSG_MAX, &v, &len, &cap);
        gather(w, n->c, CSG_MAX, &v, &len, &cap);
        if (!w->nomem) block(w, "union", v, len, d);
        frep_free(v);
        return;
    }
    }
}

/* ---- modules ------------------------------------------------------------------- */

static int reserved(const char *s)
{
    static const char *const words[] = {
        "module", "function", "if", "else", "for", "let", "each", "assert", "echo", "include",
        "use", "true", "false", "undef", "cube", "sphere", "cylinder", "polyhedron", "union",
        "difference", "intersection", "translate", "rotate", "scale", "mirror", "multmatrix",
        "color", "hull", "minkowski", "circle", "square", "polygon", "text", "offset", "resize",
        "linear_extrude", "rotate_extrude", "import", "render", "children", "projection",
        "surface", "universe", "big", "box", "intersection_for",
    };
    for (size_t i = 0; i < sizeof words / sizeof *words; i++)
        if (strcmp(s, words[i]) == 0) return 1;
    return 0;
}

/* Every named node reachable from n, dependencies first, each once, under a unique
 * name that OpenSCAD does not reserve. */
static void collect(writer *w, const csg_node *n)
{
    if (w->nomem || mod_name(w, n)) return;
    if (n->a) collect(w, n->a);
    if (n->c) collect(w, n->c);
    if (!n->name || n->kind == CSG_NOT) return;
    if (w->nmods == w->cap) {
        size_t nc = w->cap ? 2 * w->cap : 16;
        named *nv = frep_realloc(w->mods, nc * sizeof *nv);
        if (!nv) {
            w->nomem = 1;
            return;
        }
        w->mods = nv;
        w->cap = nc;
    }
    named *m = &w->mods[w->nmods];
    m->n = n;
    snprintf(m->name, sizeof m->name, "%s%s", n->name, reserved(n->name) ? "_" : "");
    char base[80];
    memcpy(base, m->name, sizeof base);
    for (unsigned k = 2;; k++) {
        size_t i = 0;
        while (i < w->nmods && strcmp(w->mods[i].name, m->name) != 0) i++;
        if (i == w->nmods) break;
        snprintf(m->name, sizeof m->name, "%.60s_%u", base, k);
    }
    w->nmods++;
}

static void write_all(writer *w, const csg_node *root, const char *file, const char *model)
{
    const scad_options *o = w->o;
    int bounded = csg_bounded(root);
    frep_buf body = FREP_BUF_INIT, *out = w->b;
    w->b = &body;
    for (size_t i = 0; i < w->nmods; i++) {
        buf_printf(w->b, "module %s()\n", w->mods[i].name);
        node(w, w->mods[i].n, 0, 1);
        buf_putc(w->b, '\n');
    }
    const char *rn = mod_name(w, root);
    if (!bounded) {
        buf_puts(w->b, "// The solid is unbounded: it is cut by the box frep mesh uses; grow box_lo\n"
                       "// and box_hi to see more of it.\n"
                       "intersection() {\n");
        if (rn) buf_printf(w->b, "    %s();\n", rn);
        else node(w, root, 1, 1);
        buf_puts(w->b, "    translate(box_lo) cube(box_hi - box_lo);\n}\n");
    } else if (rn) {
        buf_printf(w->b, "%s();\n", rn);
    } else {
        node(w, root, 0, 1);
    }
    w->b = out;
    if (o->title) buf_printf(w->b, "// %s\n", o->title);
    buf_printf(w->b, "// OpenSCAD translation of model '%s' of %s by frep export: the same solid,\n"
                     "// its named sub-expressions as modules.\n", model, file);
    buf_printf(w->b, "$fn = %d;  // facets of a full circle of the round solids\n", o->fn);
    buf_puts(w->b, "big = ");
    num(w, w->big);
    buf_puts(w->b, ";  // the side of the cubes that stand for half-spaces and the length\n"
                   "            // of infinite cylinders: 4 diagonals of the model's box\n");
    if (!bounded || w->universe) {
        buf_puts(w->b, "box_lo = ");
        vec(w, o->box);
        buf_puts(w->b, ";\nbox_hi = ");
        vec(w, o->box + 3);
        buf_puts(w->b, ";\n");
    }
    if (w->universe)
        buf_puts(w->b, "// All of space as far as the model goes: complements are cut from it.\n"
                       "module universe() translate((box_lo + box_hi) / 2 - [big, big, big] / 2) "
                       "cube(big);\n");
    buf_putc(w->b, '\n');
    if (body.failed) w->b->failed = 1;
    else if (body.len) buf_put(w->b, body.s, body.len);
    buf_free(&body);
}

/* ---- the export ---------------------------------------------------------------- */

static int pick(const ast_file *f, const char *want)
{
    for (uint32_t i = 0; want && i < f->nmodels; i++) {
        const char *k = f->models[i].key, *s = want;
        while (*k && *s && *k == (*s >= 'A' && *s <= 'Z' ? *s - 'A' + 'a' : *s)) k++, s++;
        if (!*k && !*s) return (int)i;
    }
    if (want) return -1;
    for (uint32_t i = 0; i < f->nmodels; i++)
        if (strcmp(f->models[i].key, "my_model") == 0) return (int)i;
    return f->nmodels ? (int)f->nmodels - 1 : -1;
}

char *scad_export(const char *file, const char *src, size_t len, const scad_options *o,
                  frep_diag_fn diag, void *user, frep_error *err)
{
    frep_error_init(err);
    arena A;
    arena_init(&A);
    diag_sink ds = { diag, user, file, 0, 0, &A, 0 };
    ast_file f;
    check_info ci;
    memset(&f, 0, sizeof f);
    char *text = NULL;
    int mi = -1;
    csg_node *root = NULL;
    csg_error ce;
    if (ast_parse(&A, file, src, len, &ds, &f) != 0 || ds.errors ||
        check_file(&A, &f, 0, &ds, &ci) != 0 || ds.errors) {
        if (A.failed) frep_error_nomem(err);
        else frep_error_set(err, FREP_EINPUT, "%s: errors in the model", file);
        goto done;
    }
    if ((mi = pick(&f, o->model)) < 0) {
        frep_error_set(err, FREP_EINPUT, "%s: no model named '%s'", file,
                       o->model ? o->model : "");
        goto done;
    }
    root = csg_from_model(&A, &f, (uint32_t)mi, ci.has_setops ? ci.setops : FREP_SETOPS_RFUNC,
                          o->a, o->na, &ce);
    if (!root) {
        if (A.failed) {
            frep_error_nomem(err);
        } else {
            diag_report(&ds, FREP_ERROR, ce.loc, ce.len, "%s", ce.msg);
            frep_error_set(err, FREP_EINPUT, "%s: model '%s' has no OpenSCAD equivalent", file,
                           f.models[mi].name);
        }
        goto done;
    }
    {
        frep_buf b = FREP_BUF_INIT;
        writer w;
        memset(&w, 0, sizeof w);
        w.b = &b;
        w.o = o;
        double dg = 0;
        for (int i = 0; i < 3; i++) {
            w.cb[i] = (o->box[i] + o->box[i + 3]) / 2;
            dg += (o->box[i + 3] - o->box[i]) * (o->box[i + 3] - o->box[i]);
        }
        w.big = round_up(SCAD_BIG_DIAGONALS * sqrt(dg));
        collect(&w, root);
        if (!w.nomem) write_all(&w, root, file, f.models[mi].name);
        frep_free(w.mods);
        if (w.nomem) buf_free(&b);
        else text = buf_finish(&b, NULL);
        if (!text) frep_error_nomem(err);
    }
done:
    arena_free(&A);
    return text;
}
