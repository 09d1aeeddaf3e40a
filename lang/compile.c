/* compile.c - frep_compile(): the whole compiler pipeline behind the public API.
 *
 * source -> lang/parse.y (AST) -> lang/check.c (names, kinds, pragmas) ->
 * lang/lower.c (IR DAG + statements) -> lang/emit.c (bytecode, runtime/program.h).
 * Everything but the program lives in one arena, freed when compiling ends.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "ast.h"
#include "check.h"
#include "emit.h"
#include "frep.h"
#include "ir.h"
#include "lower.h"
#include "program.h"

void frep_compile_options_init(frep_compile_options *o)
{
    memset(o, 0, sizeof *o);
    o->model = NULL;
    o->a = NULL;
    o->na = 0;
    o->setops_override = -1;
    o->alpha = 0;
    o->optimize = 1;
    o->strict = 0;
}

static int lower_key_eq(const char *key, const char *name)
{
    /* Model names are case-insensitive, like every identifier. */
    while (*key && *name) {
        char a = *key++, b = *name++;
        if (b >= 'A' && b <= 'Z') b = (char)(b - 'A' + 'a');
        if (a != b) return 0;
    }
    return *key == *name;
}

/* Which model to compile: options->model, else "my_model", else the first, as the
 * reference interpreter and hfp do (they evaluate the first body of the file). */
static int pick_model(const ast_file *f, const char *want)
{
    uint32_t i;
    if (want) {
        for (i = 0; i < f->nmodels; i++)
            if (lower_key_eq(f->models[i].key, want)) return (int)i;
        return -1;
    }
    for (i = 0; i < f->nmodels; i++)
        if (strcmp(f->models[i].key, "my_model") == 0) return (int)i;
    return f->nmodels ? 0 : -1;
}

/* frep_program_param_info of every parameter: a[1..na], then the named ones. */
static int fill_params(frep_program *p, const lowered *lo, const frep_compile_options *o)
{
    uint32_t n = lo->na + lo->nnamed, i;
    p->nparams = n;
    p->na = lo->na;
    if (n == 0) return 0;
    p->params = frep_calloc(n, sizeof *p->params);
    if (!p->params) return -1;
    for (i = 0; i < lo->na; i++) {
        frep_param_info *pi = &p->params[i];
        char buf[32];
        (void)snprintf(buf, sizeof buf, "a[%u]", (unsigned)i + 1);
        pi->name = frep_strdup(buf);
        if (!pi->name) return -1;
        pi->value = o->a && i < o->na ? o->a[i] : 0.0;
        pi->lo = -INFINITY;
        pi->hi = INFINITY;
    }
    for (i = 0; i < lo->nnamed; i++) {
        const check_free *fr = lo->named[i].fr;
        frep_param_info *pi = &p->params[lo->na + i];
        pi->name = frep_strdup(fr->name);
        if (!pi->name) return -1;
        pi->value = fr->value;
        pi->lo = fr->lo;
        pi->hi = fr->hi;
        pi->has_bounds = fr->has_bounds;
        pi->pos.line = fr->lit.line;
        pi->pos.col = fr->lit.col;
        pi->pos.len = fr->lit.end - fr->lit.off;
        pi->off = fr->lit.off;
        pi->end = fr->lit.end;
    }
    return 0;
}

/* One compile session: the stages below run in order over it. */
typedef struct session {
    const frep_compile_options *opt;
    arena A;
    diag_sink d;
    ast_file f;
    check_info ci;
    uint32_t model;         /* index of the model compiled (stage_pick) */
    ir g;
    lowered lo;
    frep_program *p;
} session;

static const ast_loc no_loc = { 0, 0, 0, 0 };

/* Parse the source into the session's tree; a file without models is an error. */
static int stage_parse(session *s, const char *file, const char *text, size_t len)
{
    if (ast_parse(&s->A, file, text, len, &s->d, &s->f) != 0 || s->d.errors) return -1;
    if (s->f.nmodels == 0) {
        diag_report(&s->d, FREP_ERROR, no_loc, 0, "no model in the file");
        return -1;
    }
    return 0;
}

/* Semantic checks of every model and pragma (lang/check.c). */
static int stage_check(session *s)
{
    return check_file(&s->A, &s->f, s->opt->strict, &s->d, &s->ci) != 0 || s->d.errors ? -1 : 0;
}

/* Which model to compile: options->model, else "my_model", else the first. */
static int stage_pick(session *s)
{
    int mi = pick_model(&s->f, s->opt->model);
    if (mi < 0) {
        diag_report(&s->d, FREP_ERROR, no_loc, 0, "no model named '%s' in the file",
                    s->opt->model);
        return -1;
    }
    s->model = (uint32_t)mi;
    return 0;
}

/* Lower the model to IR with the set operations in force: the file's @setops unless
 * the options override it (lang/lower.c). */
static int stage_lower(session *s)
{
    const frep_compile_options *opt = s->opt;
    const ast_model *m = &s->f.models[s->model];
    lower_options lopt;
    memset(&lopt, 0, sizeof lopt);
    lopt.a = opt->a;
    lopt.na = opt->na;
    lopt.setops = s->ci.has_setops ? s->ci.setops : FREP_SETOPS_RFUNC;
    lopt.alpha = s->ci.has_setops ? s->ci.alpha : 0;
    if (opt->setops_override >= 0) {
        lopt.setops = opt->setops_override;
        lopt.alpha = opt->alpha;
    }
    ir_init(&s->g, &s->A, opt->optimize);
    if (lower_model(&s->A, &s->f, s->model, &s->ci, &lopt, &s->g, &s->d, &s->lo) != 0)
        return -1;
    if (opt->a && opt->na > s->lo.na)
        diag_report(&s->d, FREP_WARNING, m->loc, 1,
                    "%zu values given for a[], but model '%s' declares a[%u]; the rest are "
                    "ignored", opt->na, m->name, (unsigned)s->lo.na);
    return 0;
}

/* The program's header: parameters, model and file names, the @box. */
static int stage_program(session *s, const char *file)
{
    const ast_model *m = &s->f.models[s->model];
    frep_program *p = prog_new();
    s->p = p;
    if (!p || fill_params(p, &s->lo, s->opt) < 0) goto nomem;
    p->model = frep_strdup(m->name);
    if (file) p->file = frep_strdup(file);
    if (!p->model || (file && !p->file)) goto nomem;
    if (s->ci.has_box) {
        memcpy(p->box, s->ci.box, sizeof p->box);
        p->has_box = 1;
    }
    return 0;
nomem:
    diag_nomem(&s->d);
    return -1;
}

/* Schedule the IR with root `lo->root` into p (lang/emit.c); each failure has its
 * own message. */
static int emit_root(session *s, const lowered *lo, frep_program *p)
{
    const ast_model *m = &s->f.models[s->model];
    switch (emit_program(&s->g, lo, p)) {
    case EMIT_OK:
        return 0;
    case EMIT_NOMEM:
        diag_nomem(&s->d);
        break;
    case EMIT_SLOTS:
        diag_report(&s->d, FREP_ERROR, m->loc, 1, "model '%s' is too large to compile "
                    "(more than %u slots)", m->name, (unsigned)FREP_MAX_SLOTS);
        break;
    case EMIT_STACK:
        diag_report(&s->d, FREP_ERROR, m->loc, 1, "model '%s' is too large to compile "
                    "(a stack deeper than %u)", m->name, (unsigned)FREP_MAX_STACK);
        break;
    case EMIT_BUG:
        diag_report(&s->d, FREP_ERROR, m->loc, 1, "internal error: the bytecode of model "
                    "'%s' could not be scheduled", m->name);
        break;
    }
    return -1;
}

/* The model's value: the program itself. */
static int stage_emit(session *s)
{
    return emit_root(s, &s->lo, s->p);
}

/* Its attributes: one program per element of s[], from the same IR and statements
 * with that element's final value as the root (frep_eval_attrs_par). */
static int stage_attrs(session *s)
{
    frep_program *p = s->p;
    uint32_t k;
    if (!s->lo.has_s || s->lo.nattrs == 0) return 0;
    p->attrs = frep_calloc(s->lo.nattrs, sizeof *p->attrs);
    if (!p->attrs || !s->lo.attrs) goto nomem;
    p->nattrs = s->lo.nattrs;
    for (k = 0; k < s->lo.nattrs; k++) {
        lowered lo = s->lo;
        frep_program *a = prog_new();
        p->attrs[k] = a;
        if (!a || fill_params(a, &s->lo, s->opt) < 0) goto nomem;
        a->model = frep_strdup(p->model);
        if (p->file) a->file = frep_strdup(p->file);
        if (!a->model || (p->file && !a->file)) goto nomem;
        lo.root = s->lo.attrs[k];
        if (emit_root(s, &lo, a) < 0) return -1;
    }
    return 0;
nomem:
    diag_nomem(&s->d);
    return -1;
}

frep_program *frep_compile(const char *file, const char *text, size_t len,
                           const frep_compile_options *opt, frep_diag_fn diag, void *user)
{
    frep_compile_options defaults;
    session s;
    if (!opt) {
        frep_compile_options_init(&defaults);
        opt = &defaults;
    }
    memset(&s, 0, sizeof s);
    s.opt = opt;
    arena_init(&s.A);
    s.d.fn = diag;
    s.d.user = user;
    s.d.file = file;
    s.d.A = &s.A;
    if (stage_parse(&s, file, text, len) < 0 || stage_check(&s) < 0 || stage_pick(&s) < 0 ||
        stage_lower(&s) < 0 || stage_program(&s, file) < 0 || stage_emit(&s) < 0 ||
        stage_attrs(&s) < 0) {
        frep_program_free(s.p);
        s.p = NULL;
    }
    arena_free(&s.A);
    return s.p;
}

char **frep_list_models(const char *file, const char *text, size_t len, size_t *count,
                        frep_diag_fn diag, void *user)
{
    arena A;
    diag_sink d;
    ast_file f;
    char **v = NULL;
    uint32_t i;
    memset(&d, 0, sizeof d);
    d.fn = diag;
    d.user = user;
    d.file = file;
    d.A = &A;
    *count = 0;
    arena_init(&A);
    if (ast_parse(&A, file, text, len, &d, &f) == 0 && !d.errors) {
        v = frep_calloc(f.nmodels + 1, sizeof *v);
        if (v) {
            for (i = 0; i < f.nmodels; i++) {
                v[i] = frep_strdup(f.models[i].name);
                if (!v[i]) {
                    frep_free_strings(v, i);
                    v = NULL;
                    break;
                }
            }
            if (v) *count = f.nmodels;
        }
        if (!v) diag_nomem(&d);
    }
    arena_free(&A);
    return v;
}

void frep_free_strings(char **v, size_t n)
{
    size_t i;
    if (!v) return;
    for (i = 0; i < n; i++) frep_free(v[i]);
    frep_free(v);
}
