/* csg.c - a checked model run symbolically into a tree of standard solids (csg.h).
 *
 * Every value is a csg_node: numbers and the coordinates x[1..3] are affine forms of
 * the world point (CSG_HALF), so the space mappings of the library (shift, rotate,
 * scale: arithmetic on x's elements) give each solid its local frame without special
 * cases.  Arithmetic stays exact on affine forms and on min/max of them (0.08 -
 * abs(x[1]) is a slab); set operations of any family become Boolean nodes, because
 * R-functions and R-alpha (|alpha| <= 1) have the sign of min/max, so the same solid.
 * Anything else (a product of two coordinates, a blend, a loop whose condition depends
 * on the point) has no Boolean meaning and stops the run at its source position.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "csg.h"

/* Statements run before giving up: constant loops are unrolled, so a model that loops
 * for ever must stop with an error, not hang the export. */
#define CSG_MAX_STEPS 1000000u

typedef struct slot {
    const char *name;     /* as first written */
    uint32_t size;        /* 0: a scalar */
    csg_node **e;         /* size elements (a scalar: one) */
} slot;

typedef struct scope {
    const ast_model *m;
    uint32_t index;       /* the model's number in the file */
    strmap names;         /* key -> slot index */
    slot *v;
    uint32_t n, cap;
} scope;

typedef struct cx {
    arena *A;
    const ast_file *f;
    int minmax;           /* the file's | & \ are min/max */
    const double *a;
    size_t na;
    csg_error *e;
    int failed;           /* an error is set: unwind */
    uint32_t steps;
} cx;

/* ---- errors and nodes ------------------------------------------------------------- */

static csg_node *fail(cx *c, ast_loc loc, uint32_t len, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;

static csg_node *fail(cx *c, ast_loc loc, uint32_t len, const char *fmt, ...)
{
    if (c->failed) return NULL;
    c->failed = 1;
    c->e->loc = loc;
    c->e->len = len ? len : 1;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->e->msg, sizeof c->e->msg, fmt, ap);
    va_end(ap);
    return NULL;
}

static uint32_t span(ast_loc l) { return l.end > l.off ? l.end - l.off : 1; }

static csg_node *oom(cx *c)
{
    return fail(c, (ast_loc){ 0, 0, 0, 0 }, 0, "out of memory");
}

static csg_node *node(cx *c, csg_kind k, ast_loc loc)
{
    csg_node *n = arena_alloc(c->A, sizeof *n);
    if (!n) return oom(c);
    n->kind = k;
    n->loc = loc;
    return n;
}

static csg_node *affine(cx *c, double k0, double kx, double ky, double kz, ast_loc loc)
{
    csg_node *n = node(c, CSG_HALF, loc);
    if (!n) return NULL;
    n->k[0] = k0;
    n->k[1] = kx;
    n->k[2] = ky;
    n->k[3] = kz;
    n->exact = 1;
    return n;
}

static csg_node *number(cx *c, double v, ast_loc loc) { return affine(c, v, 0, 0, 0, loc); }

static int is_const(const csg_node *n, double *v)
{
    if (n->kind != CSG_HALF || n->k[1] != 0 || n->k[2] != 0 || n->k[3] != 0) return 0;
    if (v) *v = n->k[0];
    return 1;
}

static csg_node *binop(cx *c, csg_kind k, csg_node *a, csg_node *b, int exact, ast_loc loc)
{
    csg_node *n = node(c, k, loc);
    if (!n) return NULL;
    n->a = a;
    n->c = b;
    n->exact = exact && a->exact && b->exact;
    return n;
}

/* -f: an affine form negated, min/max of exact fields by De Morgan, else a complement
 * node (the operand keeps its name: `body \ holes` stays readable). */
static csg_node *neg(cx *c, csg_node *a, ast_loc loc)
{
    if (a->kind == CSG_HALF) return affine(c, -a->k[0], -a->k[1], -a->k[2], -a->k[3], loc);
    if (a->kind == CSG_NOT) return a->a;
    if (a->exact && (a->kind == CSG_MIN || a->kind == CSG_MAX)) {
        csg_node *x = neg(c, a->a, loc), *y = x ? neg(c, a->c, loc) : NULL;
        return y ? binop(c, a->kind == CSG_MIN ? CSG_MAX : CSG_MIN, x, y, 1, loc) : NULL;
    }
    csg_node *n = node(c, CSG_NOT, loc);
    if (n) n->a = a;
    return n;
}

/* f + k for a constant k: exact only on affine forms and min/max of them. */
static csg_node *add_const(cx *c, csg_node *a, double k, ast_loc loc)
{
    if (a->kind == CSG_HALF) return affine(c, a->k[0] + k, a->k[1], a->k[2], a->k[3], loc);
    if (a->exact && (a->kind == CSG_MIN || a->kind == CSG_MAX)) {
        csg_node *x = add_const(c, a->a, k, loc), *y = x ? add_const(c, a->c, k, loc) : NULL;
        return y ? binop(c, a->kind, x, y, 1, loc) : NULL;
    }
    return fail(c, loc, 1, "adding a number to a solid's function changes its shape in a "
                           "way OpenSCAD cannot express");
}

/* k f: a positive factor keeps every sign, so a solid is unchanged. */
static csg_node *scale(cx *c, csg_node *a, double k, ast_loc loc)
{
    if (k == 0) return number(c, 0, loc);
    if (k < 0) {
        csg_node *s = scale(c, a, -k, loc);
        return s ? neg(c, s, loc) : NULL;
    }
    if (a->kind == CSG_HALF) return affine(c, k * a->k[0], k * a->k[1], k * a->k[2], k * a->k[3], loc);
    if (a->exact && (a->kind == CSG_MIN || a->kind == CSG_MAX)) {
        csg_node *x = scale(c, a->a, k, loc), *y = x ? scale(c, a->c, k, loc) : NULL;
        return y ? binop(c, a->kind, x, y, 1, loc) : NULL;
    }
    return a;
}

/* ---- scopes ------------------------------------------------------------------------- */

static slot *scope_slot(scope *s, const char *key)
{
    uint32_t *i = strmap_get(&s->names, key);
    return i ? &s->v[*i] : NULL;
}

/* A new slot for key (size 0: a scalar), its elements unset (NULL). */
static slot *scope_add(cx *c, scope *s, const char *key, const char *name, uint32_t size)
{
    if (s->n == s->cap) {
        uint32_t cap = s->cap ? 2 * s->cap : 16;
        slot *nv = arena_grow(c->A, s->v, s->n, cap, sizeof *nv);
        if (!nv) return (slot *)oom(c);
        s->v = nv;
        s->cap = cap;
    }
    slot *y = &s->v[s->n];
    y->name = name;
    y->size = size;
    y->e = arena_alloc(c->A, (size ? size : 1) * sizeof *y->e);
    if (!y->e || strmap_put(&s->names, key, s->n) < 0) return (slot *)oom(c);
    s->n++;
    return y;
}

/* The scope of model m: x[1..3] the world coordinates (x[4..] 0), a[i] the given
 * values (0 for the missing ones), the other arrays unset. */
static int scope_init(cx *c, scope *s, uint32_t mi, int top)
{
    const ast_model *m = &c->f->models[mi];
    memset(s, 0, sizeof *s);
    s->m = m;
    s->index = mi;
    strmap_init(&s->names, c->A);
    for (uint32_t i = 0; i < m->nparams; i++) {
        slot *y = scope_add(c, s, m->params[i].key, m->params[i].name, m->params[i].size);
        if (!y) return -1;
        for (uint32_t j = 0; top && j < y->size; j++) {
            double v = i == 1 && j < c->na ? c->a[j] : 0;
            y->e[j] = i == 0 && j < 3 ? affine(c, 0, j == 0, j == 1, j == 2, m->params[i].loc)
                                      : number(c, v, m->params[i].loc);
            if (!y->e[j]) return -1;
        }
    }
    for (uint32_t i = 0; i < m->narrays; i++) {
        /* An array declared twice: the first declaration counts (lang/check.c). */
        if (strmap_get(&s->names, m->arrays[i].key)) continue;
        if (!scope_add(c, s, m->arrays[i].key, m->arrays[i].name, m->arrays[i].size)) return -1;
    }
    return 0;
}

/* ---- expressions -------------------------------------------------------------------- */

static csg_node *expr(cx *c, scope *s, const ast_node *n);
static int stmts(cx *c, scope *s, const ast_list *l);

static int const_arg(cx *c, scope *s, const ast_node *n, double *v, const char *what)
{
    csg_node *r = expr(c, s, n);
    if (!r) return -1;
    if (!is_const(r, v)) {
        fail(c, n->loc, span(n->loc), "%s depends on the point: OpenSCAD needs a number", what);
        return -1;
    }
    return 0;
}

/* The array a call argument names (a variable of an array), or NULL after an error. */
static slot *array_arg(cx *c, scope *s, const ast_node *n, uint32_t need)
{
    slot *y = n->kind == AST_VAR ? scope_slot(s, n->key) : NULL;
    if (!y || y->size == 0) {
        fail(c, n->loc, span(n->loc), "expected the name of an array");
        return NULL;
    }
    if (y->size < need) {
        fail(c, n->loc, span(n->loc), "array '%s' has %u elements, %u needed", n->name,
             y->size, need);
        return NULL;
    }
    for (uint32_t j = 0; j < need; j++)
        if (!y->e[j]) {
            fail(c, n->loc, span(n->loc), "element %u of '%s' is used before it is set", j + 1,
                 n->name);
            return NULL;
        }
    return y;
}

/* The numbers of an array argument (its first k elements). */
static int numbers_arg(cx *c, scope *s, const ast_node *n, uint32_t k, double *v)
{
    slot *y = array_arg(c, s, n, k);
    if (!y) return -1;
    for (uint32_t j = 0; j < k; j++)
        if (!is_const(y->e[j], &v[j])) {
            fail(c, n->loc, span(n->loc), "element %u of '%s' depends on the point: OpenSCAD "
                                          "needs a number", j + 1, n->name);
            return -1;
        }
    return 0;
}

static double det3(const double *A)
{
    return A[0] * (A[4] * A[8] - A[5] * A[7]) - A[1] * (A[3] * A[8] - A[5] * A[6]) +
           A[2] * (A[3] * A[7] - A[4] * A[6]);
}

/* A solid of kind k in the frame its point argument gives: q = A w + b, each of the
 * first three elements an affine form of the world point. */
static csg_node *prim(cx *c, scope *s, const ast_node *call, csg_prim k, int axis,
                      const double *p, int np)
{
    slot *y = array_arg(c, s, call->list.v[0], 3);
    if (!y) return NULL;
    csg_node *n = node(c, CSG_PRIM, call->loc);
    if (!n) return NULL;
    n->prim = k;
    n->axis = axis;
    memcpy(n->p, p, (size_t)np * sizeof *p);
    for (int i = 0; i < 3; i++) {
        const csg_node *e = y->e[i];
        if (e->kind != CSG_HALF)
            return fail(c, call->list.v[0]->loc, span(call->list.v[0]->loc),
                        "coordinate %d of the point is not an affine map of x: OpenSCAD can "
                        "only move, turn and scale solids", i + 1);
        n->b[i] = e->k[0];
        for (int j = 0; j < 3; j++) n->A[3 * i + j] = e->k[1 + j];
    }
    if (!(fabs(det3(n->A)) > 1e-300))
        return fail(c, call->list.v[0]->loc, span(call->list.v[0]->loc),
                    "the space mapping of the point is singular");
    return n;
}

/* Scalars args[from .. from+k-1] of a call as numbers. */
static int scalars(cx *c, scope *s, const ast_node *call, uint32_t from, uint32_t k, double *v)
{
    for (uint32_t i = 0; i < k; i++)
        if (const_arg(c, s, call->list.v[from + i], &v[i], "this argument")) return -1;
    return 0;
}

/* The library's solids: hfX(x, centre[3], numbers...), frX(x, numbers...). */
typedef struct lib_solid {
    const char *key;
    csg_prim prim;
    int axis;             /* *_AXIS kinds */
    int hf;               /* centre or vertex array second, then nhf numbers */
    int nnum;             /* numbers (after the array for hf solids) */
} lib_solid;

static const lib_solid solids[] = {
    { "hfsphere", CSG_SPHERE, 0, 1, 1 },       { "hfellipsoid", CSG_ELLIPSOID, 0, 1, 3 },
    { "hfcylinderx", CSG_CYL_AXIS, 0, 1, 1 },  { "hfcylindery", CSG_CYL_AXIS, 1, 1, 1 },
    { "hfcylinderz", CSG_CYL_AXIS, 2, 1, 1 },  { "hfellcylx", CSG_CYL_AXIS, 0, 1, 2 },
    { "hfellcyly", CSG_CYL_AXIS, 1, 1, 2 },    { "hfellcylz", CSG_CYL_AXIS, 2, 1, 2 },
    { "hfconex", CSG_CONE_AXIS, 0, 1, 1 },     { "hfconey", CSG_CONE_AXIS, 1, 1, 1 },
    { "hfconez", CSG_CONE_AXIS, 2, 1, 1 },     { "hfellconex", CSG_CONE_AXIS, 0, 1, 2 },
    { "hfellconey", CSG_CONE_AXIS, 1, 1, 2 },  { "hfellconez", CSG_CONE_AXIS, 2, 1, 2 },
    { "hftorusx", CSG_TORUS_AXIS, 0, 1, 2 },   { "hftorusy", CSG_TORUS_AXIS, 1, 1, 2 },
    { "hftorusz", CSG_TORUS_AXIS, 2, 1, 2 },   { "hfblock", CSG_BLOCK, 0, 1, 3 },
    { "frsphere", CSG_SPHERE, 0, 0, 4 },       { "frcylinder", CSG_CYLINDER, 0, 0, 7 },
    { "frcone", CSG_CONE, 0, 0, 7 },           { "frtorus", CSG_TORUS, 0, 0, 8 },
    { "frbox", CSG_BOX, 0, 0, 9 },
};

static csg_node *solid_call(cx *c, scope *s, const ast_node *n, const lib_solid *L)
{
    double p[9] = { 0 };
    int np = 0;
    if (L->hf) {
        if (numbers_arg(c, s, n->list.v[1], 3, p)) return NULL;
        np = 3;
    }
    if (scalars(c, s, n, L->hf ? 2 : 1, (uint32_t)L->nnum, p + np)) return NULL;
    np += L->nnum;
    if (L->prim == CSG_CYL_AXIS || L->prim == CSG_CONE_AXIS) {
        if (L->nnum == 1) p[np++] = p[3];       /* circular: b = a */
        if (!(p[3] != 0 && p[4] != 0))
            return fail(c, n->loc, span(n->loc), "%s: a radius is 0", n->name);
        p[3] = fabs(p[3]);
        p[4] = fabs(p[4]);
    }
    if (L->prim == CSG_ELLIPSOID && !(p[3] != 0 && p[4] != 0 && p[5] != 0))
        return fail(c, n->loc, span(n->loc), "%s: a half-axis is 0", n->name);
    if ((L->prim == CSG_TORUS_AXIS && p[3] < 0) || (L->prim == CSG_TORUS && p[6] < 0))
        return fail(c, n->loc, span(n->loc), "%s: a negative major radius has no OpenSCAD "
                                             "equivalent", n->name);
    if (L->prim == CSG_CYLINDER || L->prim == CSG_CONE || L->prim == CSG_TORUS) {
        double l = sqrt(p[3] * p[3] + p[4] * p[4] + p[5] * p[5]);
        if (!(l > 0)) return fail(c, n->loc, span(n->loc), "%s: zero-length axis", n->name);
        for (int i = 3; i < 6; i++) p[i] /= l;
    }
    if (L->prim == CSG_CONE && !(p[6] > 0 && p[6] < 1.5707963267948966))
        return fail(c, n->loc, span(n->loc), "%s: a half-angle outside (0, pi/2) has no "
                                             "OpenSCAD equivalent", n->name);
    return prim(c, s, n, L->prim, L->axis, p, np);
}

/* frPlane(x, nx, ny, nz, d) = d - n.q / |n|: a half-space, affine in the world point. */
static csg_node *plane_call(cx *c, scope *s, const ast_node *n)
{
    double p[4];
    slot *y = array_arg(c, s, n->list.v[0], 3);
    if (!y || scalars(c, s, n, 1, 4, p)) return NULL;
    double l = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    if (!(l > 0)) return fail(c, n->loc, span(n->loc), "frPlane: zero-length normal");
    double k[4] = { p[3], 0, 0, 0 };
    for (int i = 0; i < 3; i++) {
        const csg_node *e = y->e[i];
        if (e->kind != CSG_HALF)
            return fail(c, n->list.v[0]->loc, span(n->list.v[0]->loc),
                        "coordinate %d of the point is not an affine map of x", i + 1);
        for (int j = 0; j < 4; j++) k[j] -= p[i] / l * e->k[j];
    }
    return affine(c, k[0], k[1], k[2], k[3], n->loc);
}

/* Space mappings: the array's first three elements rewritten in place (lib_hf.c). */
static csg_node *mapping_call(cx *c, scope *s, const ast_node *n, int which)
{
    slot *y = array_arg(c, s, n->list.v[0], 3);
    double p[3];
    if (!y || scalars(c, s, n, 1, which == 'r' + 'x' || which == 'r' + 'y' || which == 'r' + 'z'
                      ? 1 : 3, p))
        return NULL;
    csg_node **e = y->e;
    ast_loc loc = n->loc;
    if (which == 's') {                 /* hfScale3D: x_i / s_i */
        for (int i = 0; i < 3; i++) {
            if (p[i] == 0) return fail(c, loc, span(loc), "hfScale3D: a scale factor is 0");
            if (!(e[i] = scale(c, e[i], 1 / p[i], loc))) return NULL;
        }
    } else if (which == 't') {          /* hfShift3D: x_i - d_i */
        for (int i = 0; i < 3; i++)
            if (!(e[i] = e[i]->kind == CSG_HALF ? add_const(c, e[i], -p[i], loc)
                                                : fail(c, loc, span(loc), "hfShift3D of a "
                                                       "coordinate that is not affine")))
                return NULL;
    } else {                            /* hfRotate3D: u' = u cos + v sin, v' = -u sin + v cos */
        int ax = which - 'r' - 'x', i = ax == 0 ? 1 : ax == 1 ? 2 : 0, j = ax == 0 ? 2 : ax == 1 ? 0 : 1;
        const csg_node *u = e[i], *v = e[j];
        if (u->kind != CSG_HALF || v->kind != CSG_HALF)
            return fail(c, loc, span(loc), "rotation of a coordinate that is not affine");
        double ct = cos(p[0]), st = sin(p[0]), ku[4], kv[4];
        for (int k = 0; k < 4; k++) {
            ku[k] = u->k[k] * ct + v->k[k] * st;
            kv[k] = -u->k[k] * st + v->k[k] * ct;
        }
        e[i] = affine(c, ku[0], ku[1], ku[2], ku[3], loc);
        e[j] = e[i] ? affine(c, kv[0], kv[1], kv[2], kv[3], loc) : NULL;
        if (!e[j]) return NULL;
    }
    return number(c, 1, loc);
}

/* Built-in functions of numbers; min, max and abs also of exact fields. */
typedef struct builtin {
    const char *key;
    int nargs;
    double (*f1)(double);
    double (*f2)(double, double);
} builtin;

static double sign_(double v) { return v > 0 ? 1 : v < 0 ? -1 : 0; }
static double frac_(double v) { return v - trunc(v); }
static double logd_(double v) { return log10(v); }

static const builtin builtins[] = {
    { "sqrt", 1, sqrt, NULL },   { "exp", 1, exp, NULL },    { "log", 1, log, NULL },
    { "logd", 1, logd_, NULL },  { "sin", 1, sin, NULL },    { "cos", 1, cos, NULL },
    { "tan", 1, tan, NULL },     { "asin", 1, asin, NULL },  { "acos", 1, acos, NULL },
    { "atan", 1, atan, NULL },   { "abs", 1, fabs, NULL },   { "sinh", 1, sinh, NULL },
    { "cosh", 1, cosh, NULL },   { "tanh", 1, tanh, NULL },  { "sign", 1, sign_, NULL },
    { "ceil", 1, ceil, NULL },   { "floor", 1, floor, NULL }, { "int", 1, trunc, NULL },
    { "frac", 1, frac_, NULL },  { "mod", 2, NULL, fmod },   { "max", 2, NULL, fmax },
    { "min", 2, NULL, fmin },    { "atan2", 2, NULL, atan2 },
};

static csg_node *builtin_call(cx *c, scope *s, const ast_node *n, const builtin *b)
{
    csg_node *v[2];
    double k[2];
    int all = 1;
    for (int i = 0; i < b->nargs; i++) {
        if (!(v[i] = expr(c, s, n->list.v[i]))) return NULL;
        all = all && is_const(v[i], &k[i]);
    }
    if (all) return number(c, b->nargs == 1 ? b->f1(k[0]) : b->f2(k[0], k[1]), n->loc);
    if (strcmp(b->key, "min") == 0) return binop(c, CSG_MIN, v[0], v[1], 1, n->loc);
    if (strcmp(b->key, "max") == 0) return binop(c, CSG_MAX, v[0], v[1], 1, n->loc);
    if (strcmp(b->key, "abs") == 0 && v[0]->exact) {
        csg_node *m = neg(c, v[0], n->loc);
        return m ? binop(c, CSG_MAX, v[0], m, 1, n->loc) : NULL;
    }
    return fail(c, n->op_loc, span(n->op_loc), "%s() of a function of the point has no "
                                               "OpenSCAD equivalent", n->name);
}

/* Explicit set operations: their sign is min/max's, whatever the family. */
static csg_node *setop_call(cx *c, scope *s, const ast_node *n, int op, int exact, int alpha)
{
    csg_node *a = expr(c, s, n->list.v[0]);
    if (a && op == 'c') return neg(c, a, n->loc);
    csg_node *b = a ? expr(c, s, n->list.v[1]) : NULL;
    if (!b) return NULL;
    if (alpha) {
        double al;
        if (const_arg(c, s, n->list.v[2], &al, "alpha")) return NULL;
        if (!(al > -1 && al <= 1))
            return fail(c, n->list.v[2]->loc, span(n->list.v[2]->loc),
                        "alpha outside (-1, 1] is not a set operation");
    }
    if (op == '\\' && !(b = neg(c, b, n->loc))) return NULL;
    return binop(c, op == '|' ? CSG_MAX : CSG_MIN, a, b, exact, n->loc);
}

/* The final value of each scalar of a scope takes the variable's name (values a loop
 * or a later assignment replaced stay anonymous, inside the named ones). */
static void name_values(scope *s)
{
    for (uint32_t i = 0; i < s->n; i++) {
        csg_node *v = s->v[i].size ? NULL : s->v[i].e[0];
        if (v && !v->name && !is_const(v, NULL)) v->name = s->v[i].name;
    }
}

static csg_node *model_call(cx *c, scope *s, const ast_node *n, uint32_t mi)
{
    scope callee;
    if (scope_init(c, &callee, mi, 0)) return NULL;
    const ast_model *m = callee.m;
    /* Arrays are passed by value (lang/lower.c): the callee works on copies. */
    for (uint32_t i = 0; i < m->nparams && i < n->list.n; i++) {
        slot *y = array_arg(c, s, n->list.v[i], 0);
        if (!y) return NULL;
        slot *p = &callee.v[i];
        for (uint32_t j = 0; j < p->size; j++)
            if (!(p->e[j] = j < y->size && y->e[j] ? y->e[j] : number(c, 0, n->loc)))
                return NULL;
    }
    if (stmts(c, &callee, &m->body)) return NULL;
    name_values(&callee);
    slot *r = scope_slot(&callee, m->key);
    if (!r || !r->e[0])
        return fail(c, m->loc, span(m->loc), "model '%s' never assigns its result", m->name);
    return r->e[0];
}

static csg_node *call(cx *c, scope *s, const ast_node *n)
{
    int mi = check_find_model(c->f, n->key, s->index);
    if (mi >= 0) return model_call(c, s, n, (uint32_t)mi);
    for (size_t i = 0; i < sizeof solids / sizeof *solids; i++)
        if (strcmp(n->key, solids[i].key) == 0) return solid_call(c, s, n, &solids[i]);
    for (size_t i = 0; i < sizeof builtins / sizeof *builtins; i++)
        if (strcmp(n->key, builtins[i].key) == 0) return builtin_call(c, s, n, &builtins[i]);
    static const struct { const char *key; int op, exact, alpha; } sets[] = {
        { "runion", '|', 0, 0 },     { "rintersection", '&', 0, 0 }, { "rsubtraction", '\\', 0, 0 },
        { "mmunion", '|', 1, 0 },    { "mmintersection", '&', 1, 0 }, { "mmsubtraction", '\\', 1, 0 },
        { "raunion", '|', 0, 1 },    { "raintersection", '&', 0, 1 }, { "rasubtraction", '\\', 0, 1 },
        { "frcomplement", 'c', 1, 0 },
    };
    for (size_t i = 0; i < sizeof sets / sizeof *sets; i++)
        if (strcmp(n->key, sets[i].key) == 0)
            return setop_call(c, s, n, sets[i].op, sets[i].exact, sets[i].alpha);
    if (strcmp(n->key, "frplane") == 0) return plane_call(c, s, n);
    static const struct { const char *key; int which; } maps[] = {
        { "hfscale3d", 's' }, { "hfshift3d", 't' }, { "hfrotate3dx", 'r' + 'x' },
        { "hfrotate3dy", 'r' + 'y' }, { "hfrotate3dz", 'r' + 'z' },
    };
    for (size_t i = 0; i < sizeof maps / sizeof *maps; i++)
        if (strcmp(n->key, maps[i].key) == 0) return mapping_call(c, s, n, maps[i].which);
    return fail(c, n->op_loc, span(n->op_loc), "%s() has no OpenSCAD equivalent (OpenSCAD "
                "has Boolean operations of standard solids, moved, turned and scaled)",
                n->name);
}

static csg_node *index_expr(cx *c, scope *s, const ast_node *n)
{
    slot *y = scope_slot(s, n->key);
    double iv;
    if (!y || y->size == 0) return fail(c, n->loc, span(n->loc), "'%s' is not an array", n->name);
    if (const_arg(c, s, n->a, &iv, "the index")) return NULL;
    if (!(iv >= 1 && iv <= y->size) || iv != floor(iv))
        return fail(c, n->a->loc, span(n->a->loc), "index %g out of range 1..%u", iv, y->size);
    csg_node *v = y->e[(uint32_t)iv - 1];
    if (!v) return fail(c, n->loc, span(n->loc), "'%s[%g]' is used before it is set", n->name, iv);
    return v;
}

static int truth(cx *c, scope *s, const ast_node *n, int *t);

/* a op b of two values (arithmetic, comparison, set operation). */
static csg_node *binary(cx *c, scope *s, const ast_node *n)
{
    int op = n->op;
    if (op == AST_OP_AND || op == AST_OP_OR) {
        int ta, tb;
        if (truth(c, s, n->a, &ta) || truth(c, s, n->b, &tb)) return NULL;
        return number(c, op == AST_OP_AND ? (ta && tb) : (ta || tb), n->loc);
    }
    csg_node *a = expr(c, s, n->a), *b = a ? expr(c, s, n->b) : NULL;
    if (!b) return NULL;
    double ka = 0, kb = 0;
    int ca = is_const(a, &ka), cb = is_const(b, &kb);
    ast_loc at = n->op_loc;
    switch (op) {
    case '|': return binop(c, CSG_MAX, a, b, c->minmax, n->loc);
    case '&': case '@': return binop(c, CSG_MIN, a, b, c->minmax, n->loc);
    case '\\': {
        csg_node *nb = neg(c, b, n->loc);
        return nb ? binop(c, CSG_MIN, a, nb, c->minmax, n->loc) : NULL;
    }
    default: break;
    }
    if (ca && cb) {
        double v;
        switch (op) {
        case '+': v = ka + kb; break;
        case '-': v = ka - kb; break;
        case '*': v = ka * kb; break;
        case '/': v = ka / kb; break;
        case '^': v = pow(ka, kb); break;
        case AST_OP_EQ: v = ka == kb; break;
        case AST_OP_NE: v = ka != kb; break;
        case AST_OP_LT: v = ka < kb; break;
        case AST_OP_LE: v = ka <= kb; break;
        case AST_OP_GT: v = ka > kb; break;
        case AST_OP_GE: v = ka >= kb; break;
        default: return fail(c, at, span(at), "operator '%s' unknown", ast_op_name(op));
        }
        return number(c, v, n->loc);
    }
    switch (op) {
    case AST_OP_EQ: case AST_OP_NE: case AST_OP_LT: case AST_OP_LE: case AST_OP_GT:
    case AST_OP_GE:
        return fail(c, n->loc, span(n->loc), "a condition that depends on the point has no "
                                             "OpenSCAD equivalent");
    case '+': case '-':
        if (op == '-' && !(b = neg(c, b, n->loc))) return NULL;
        if (a->kind == CSG_HALF && b->kind == CSG_HALF)
            return affine(c, a->k[0] + b->k[0], a->k[1] + b->k[1], a->k[2] + b->k[2],
                          a->k[3] + b->k[3], n->loc);
        if (ca || cb) return add_const(c, ca ? b : a, ca ? ka : (op == '-' ? -kb : kb), at);
        break;
    case '*':
        if (ca || cb) return scale(c, ca ? b : a, ca ? ka : kb, n->loc);
        break;
    case '/':
        if (cb && kb != 0) return scale(c, a, 1 / kb, n->loc);
        break;
    default: break;
    }
    return fail(c, at, span(at), "'%s' of functions of the point has no OpenSCAD equivalent "
                "(only sums of coordinates, numbers times functions, and set operations do)",
                ast_op_name(op));
}

static csg_node *expr(cx *c, scope *s, const ast_node *n)
{
    if (c->failed) return NULL;
    switch (n->kind) {
    case AST_NUM: return number(c, n->num, n->loc);
    case AST_VAR: {
        slot *y = scope_slot(s, n->key);
        if (!y || y->size)
            return fail(c, n->loc, span(n->loc), "'%s' is an array, not a value", n->name);
        if (!y->e[0]) return fail(c, n->loc, span(n->loc), "'%s' is used before it is set", n->name);
        return y->e[0];
    }
    case AST_INDEX: return index_expr(c, s, n);
    case AST_CALL: return call(c, s, n);
    case AST_UNARY: {
        if (n->op == AST_OP_NOT || n->op == 'n') {
            int t;
            return truth(c, s, n->a, &t) ? NULL : number(c, !t, n->loc);
        }
        csg_node *a = expr(c, s, n->a);
        return a ? neg(c, a, n->loc) : NULL;
    }
    case AST_BINARY: return binary(c, s, n);
    case AST_ASSIGN: case AST_ASSIGN_INDEX: case AST_ASSIGN_ARRAY: case AST_IF: case AST_WHILE:
        break;
    }
    return fail(c, n->loc, span(n->loc), "not an expression");
}

/* A condition: a number (nonzero is true); a point-dependent one stops the run. */
static int truth(cx *c, scope *s, const ast_node *n, int *t)
{
    csg_node *v = expr(c, s, n);
    double k;
    if (!v) return -1;
    if (!is_const(v, &k)) {
        fail(c, n->loc, span(n->loc), "a condition that depends on the point has no OpenSCAD "
                                      "equivalent");
        return -1;
    }
    *t = k != 0;
    return 0;
}

/* ---- statements ---------------------------------------------------------------------- */

static int set_scalar(cx *c, scope *s, const ast_node *st, csg_node *v)
{
    slot *y = scope_slot(s, st->key);
    if (!y && !(y = scope_add(c, s, st->key, st->name, 0))) return -1;
    if (y->size) {
        fail(c, st->op_loc, span(st->op_loc), "'%s' is an array", st->name);
        return -1;
    }
    y->e[0] = v;
    return 0;
}

static int stmt(cx *c, scope *s, const ast_node *st)
{
    if (++c->steps > CSG_MAX_STEPS) {
        fail(c, st->loc, span(st->loc), "more than %u statements run: a loop that does not "
                                        "end?", CSG_MAX_STEPS);
        return -1;
    }
    switch (st->kind) {
    case AST_ASSIGN: {
        csg_node *v = expr(c, s, st->a);
        return v ? set_scalar(c, s, st, v) : -1;
    }
    case AST_ASSIGN_INDEX: {
        slot *y = scope_slot(s, st->key);
        double iv;
        if (!y || !y->size) {
            fail(c, st->op_loc, span(st->op_loc), "'%s' is not an array", st->name);
            return -1;
        }
        if (const_arg(c, s, st->a, &iv, "the index")) return -1;
        if (!(iv >= 1 && iv <= y->size) || iv != floor(iv)) {
            fail(c, st->a->loc, span(st->a->loc), "index %g out of range 1..%u", iv, y->size);
            return -1;
        }
        csg_node *v = expr(c, s, st->b);
        if (!v) return -1;
        y->e[(uint32_t)iv - 1] = v;
        return 0;
    }
    case AST_ASSIGN_ARRAY: {
        slot *y = scope_slot(s, st->key);
        if (!y || !y->size) {
            fail(c, st->op_loc, span(st->op_loc), "'%s' is not an array", st->name);
            return -1;
        }
        /* A parallel assignment: every value first, then the elements. */
        csg_node **v = arena_alloc(c->A, (st->list.n + 1) * sizeof *v);
        if (!v) return oom(c), -1;
        for (uint32_t i = 0; i < st->list.n; i++)
            if (!(v[i] = expr(c, s, st->list.v[i]))) return -1;
        for (uint32_t i = 0; i < st->list.n && i < y->size; i++) y->e[i] = v[i];
        return 0;
    }
    case AST_IF: {
        int t;
        if (truth(c, s, st->a, &t)) return -1;
        return stmts(c, s, t ? &st->body : &st->body2);
    }
    case AST_WHILE:
        for (;;) {
            int t;
            if (truth(c, s, st->a, &t)) return -1;
            if (!t) return 0;
            if (stmts(c, s, &st->body)) return -1;
        }
    case AST_NUM: case AST_VAR: case AST_INDEX: case AST_CALL: case AST_UNARY: case AST_BINARY:
        return expr(c, s, st) ? 0 : -1;   /* a call for its effect on an array */
    }
    return 0;
}

static int stmts(cx *c, scope *s, const ast_list *l)
{
    for (uint32_t i = 0; i < l->n; i++)
        if (stmt(c, s, l->v[i])) return -1;
    return 0;
}

csg_node *csg_from_model(arena *A, const ast_file *f, uint32_t model, int setops,
                         const double *a, size_t na, csg_error *e)
{
    cx c = { A, f, setops == FREP_SETOPS_MINMAX, a, na, e, 0, 0 };
    memset(e, 0, sizeof *e);
    scope s;
    if (scope_init(&c, &s, model, 1) || stmts(&c, &s, &s.m->body)) return NULL;
    name_values(&s);
    slot *r = scope_slot(&s, s.m->key);
    if (!r || !r->e[0])
        return fail(&c, s.m->loc, span(s.m->loc), "model '%s' never assigns its result",
                    s.m->name);
    if (is_const(r->e[0], NULL))
        return fail(&c, s.m->loc, span(s.m->loc), "model '%s' is a constant: no solid",
                    s.m->name);
    return r->e[0];
}

/* The directions a world-space frame row maps its solid's axis to: w = A^-1 q. */
static void world_axis(const csg_node *n, int axis, double *u)
{
    const double *A = n->A;
    /* Column `axis` of A^-1 is the cross product of the other two rows of A, scaled. */
    int i = (axis + 1) % 3, j = (axis + 2) % 3;
    const double *ri = A + 3 * i, *rj = A + 3 * j;
    u[0] = ri[1] * rj[2] - ri[2] * rj[1];
    u[1] = ri[2] * rj[0] - ri[0] * rj[2];
    u[2] = ri[0] * rj[1] - ri[1] * rj[0];
}

/* What the operands of an intersection chain say about its directions of recession:
 * half-space normals g (the chain recedes along u only if g.u >= 0 for each) and
 * infinite cylinders' axes (only along them). */
typedef struct recession {
    double g[64][3];
    int ng;
    double axis[3];
    int has_axis, bounded, unknown;
} recession;

static void recede(const csg_node *n, recession *r)
{
    if (n->kind == CSG_MIN) {
        recede(n->a, r);
        recede(n->c, r);
        return;
    }
    if (csg_bounded(n)) {
        r->bounded = 1;
        return;
    }
    double u[3];
    if (n->kind == CSG_HALF && r->ng < 64) {
        memcpy(r->g[r->ng++], n->k + 1, sizeof u);
        return;
    }
    if (n->kind == CSG_PRIM && (n->prim == CSG_CYL_AXIS || n->prim == CSG_CYLINDER)) {
        if (n->prim == CSG_CYL_AXIS) {
            world_axis(n, n->axis, u);
        } else {
            double Ai[3][3];
            for (int k = 0; k < 3; k++) world_axis(n, k, Ai[k]);
            for (int k = 0; k < 3; k++)
                u[k] = Ai[0][k] * n->p[3] + Ai[1][k] * n->p[4] + Ai[2][k] * n->p[5];
        }
        if (!r->has_axis) {
            memcpy(r->axis, u, sizeof u);
            r->has_axis = 1;
            return;
        }
        double w[3] = { r->axis[1] * u[2] - r->axis[2] * u[1], r->axis[2] * u[0] - r->axis[0] * u[2],
                        r->axis[0] * u[1] - r->axis[1] * u[0] };
        double l = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
        double la = sqrt(r->axis[0] * r->axis[0] + r->axis[1] * r->axis[1] + r->axis[2] * r->axis[2]);
        double lu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        if (l > 1e-12 * la * lu) r->bounded = 1;   /* two crossing cylinders */
        return;
    }
    r->unknown = 1;   /* a cone, a complement, a union: no direction excluded */
}

/* Whether u is a direction of recession of the half-spaces (within round-off). */
static int recedes(const recession *r, const double *u)
{
    double lu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    if (!(lu > 0)) return 0;
    for (int i = 0; i < r->ng; i++) {
        const double *g = r->g[i];
        double lg = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
        if (g[0] * u[0] + g[1] * u[1] + g[2] * u[2] < -1e-12 * lg * lu) return 0;
    }
    return 1;
}

/* An intersection of half-spaces (and cylinders) is bounded when no direction recedes:
 * with a cylinder only its axis could; else the cone {u : g.u >= 0} is {0} when the
 * normals have rank 3 and no edge of it, +-(g_i x g_j), satisfies every g. */
static int chain_bounded(const csg_node *n)
{
    recession r;
    memset(&r, 0, sizeof r);
    recede(n, &r);
    if (r.bounded) return 1;
    if (r.unknown && !r.has_axis && r.ng == 0) return 0;
    if (r.has_axis) {
        double m[3] = { -r.axis[0], -r.axis[1], -r.axis[2] };
        return !recedes(&r, r.axis) && !recedes(&r, m);
    }
    double G[9] = { 0 };
    int rank3 = 0;
    for (int i = 0; i < r.ng && !rank3; i++)
        for (int j = i + 1; j < r.ng && !rank3; j++)
            for (int k = j + 1; k < r.ng && !rank3; k++) {
                memcpy(G, r.g[i], 3 * sizeof *G);
                memcpy(G + 3, r.g[j], 3 * sizeof *G);
                memcpy(G + 6, r.g[k], 3 * sizeof *G);
                rank3 = fabs(det3(G)) > 1e-12;
            }
    if (!rank3) return 0;
    for (int i = 0; i < r.ng; i++)
        for (int j = i + 1; j < r.ng; j++) {
            const double *a = r.g[i], *b = r.g[j];
            double u[3] = { a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                            a[0] * b[1] - a[1] * b[0] };
            double m[3] = { -u[0], -u[1], -u[2] };
            if (recedes(&r, u) || recedes(&r, m)) return 0;
        }
    return 1;
}

int csg_bounded(const csg_node *n)
{
    switch (n->kind) {
    case CSG_HALF: return 0;
    case CSG_NOT: return 0;
    case CSG_MIN: return chain_bounded(n);
    case CSG_MAX: return csg_bounded(n->a) && csg_bounded(n->c);
    case CSG_PRIM:
        return n->prim != CSG_CYL_AXIS && n->prim != CSG_CONE_AXIS && n->prim != CSG_CYLINDER &&
               n->prim != CSG_CONE;
    }
    return 0;
}
