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
}

static char *dup_str(const char *s)
{
    size_t n = strlen(s);
    char *p = frep_malloc(n + 1);
    if (p) memcpy(p, s, n + 1);
    return p;
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

/* Which model to compile: options->model, else "my_model", else the last. */
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
    return f->nmodels ? (int)f->nmodels - 1 : -1;
}

/* frep_program_param_info of every parameter: a[1..na], then the named ones. */
static int fill_params(frep_program *p, const lowered *lo, const frep_compile_options *o)
{
    uint32_t n = lo->na + lo->nnamed, i;
    p->nparams = n;
    if (n == 0) return 0;
    p->params = frep_calloc(n, sizeof *p->params);
    if (!p->params) return -1;
    for (i = 0; i < lo->na; i++) {
        frep_param_info *pi = &p->params[i];
        char buf[32];
        (void)snprintf(buf, sizeof buf, "a[%u]", (unsigned)i + 1);
        pi->name = dup_str(buf);
        if (!pi->name) return -1;
        pi->value = o->a && i < o->na ? o->a[i] : 0.0;
        pi->lo = -INFINITY;
        pi->hi = INFINITY;
    }
    for (i = 0; i < lo->nnamed; i++) {
        const check_free *fr = lo->named[i].fr;
        frep_param_info *pi = &p->params[lo->na + i];
        pi->name = dup_str(fr->name);
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

frep_program *frep_compile(const char *file, const char *text, size_t len,
                           const frep_compile_options *opt, frep_diag_fn diag, void *user)
{
    frep_compile_options defaults;
    arena A;
    diag_sink d;
    ast_file f;
    check_info ci;
    lowered lo;
    lower_options lopt;
    ir g;
    frep_program *p = NULL;
    int mi;
    ast_loc none;

    if (!opt) {
        frep_compile_options_init(&defaults);
        opt = &defaults;
    }
    memset(&d, 0, sizeof d);
    memset(&none, 0, sizeof none);
    d.fn = diag;
    d.user = user;
    d.file = file;
    arena_init(&A);
    if (ast_parse(&A, file, text, len, &d, &f) != 0 || d.errors) goto done;
    if (f.nmodels == 0) {
        diag_report(&d, FREP_ERROR, none, 0, "no model in the file");
        goto done;
    }
    if (check_file(&A, &f, &d, &ci) != 0 || d.errors) goto done;
    mi = pick_model(&f, opt->model);
    if (mi < 0) {
        diag_report(&d, FREP_ERROR, none, 0, "no model named '%s' in the file", opt->model);
        goto done;
    }
    memset(&lopt, 0, sizeof lopt);
    lopt.a = opt->a;
    lopt.na = opt->na;
    lopt.setops = ci.has_setops ? ci.setops : FREP_SETOPS_RFUNC;
    lopt.alpha = ci.has_setops ? ci.alpha : 0;
    if (opt->setops_override >= 0) {
        lopt.setops = opt->setops_override;
        lopt.alpha = opt->alpha;
    }
    ir_init(&g, &A, opt->optimize);
    if (lower_model(&A, &f, (uint32_t)mi, &ci, &lopt, &g, &d, &lo) != 0) goto done;
    if (opt->a && opt->na > lo.na)
        diag_report(&d, FREP_WARNING, f.models[mi].loc, 1,
                    "%zu values given for a[], but model '%s' declares a[%u]; the rest are "
                    "ignored", opt->na, f.models[mi].name, (unsigned)lo.na);
    p = prog_new();
    if (!p) goto oom;
    if (fill_params(p, &lo, opt) < 0) goto oom;
    p->model = dup_str(f.models[mi].name);
    if (file) p->file = dup_str(file);
    if (!p->model || (file && !p->file)) goto oom;
    if (ci.has_box) {
        memcpy(p->box, ci.box, sizeof p->box);
        p->has_box = 1;
    }
    if (emit_program(&g, &lo, p) != 0) {
        diag_report(&d, FREP_ERROR, f.models[mi].loc, 1,
                    "model '%s' is too large to compile (out of memory, or more than %u "
                    "slots or a stack deeper than %u)", f.models[mi].name,
                    (unsigned)FREP_MAX_SLOTS, (unsigned)FREP_MAX_STACK);
        frep_program_free(p);
        p = NULL;
    }
    goto done;
oom:
    diag_report(&d, FREP_ERROR, none, 0, "out of memory");
    frep_program_free(p);
    p = NULL;
done:
    arena_free(&A);
    return p;
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
    *count = 0;
    arena_init(&A);
    if (ast_parse(&A, file, text, len, &d, &f) == 0 && !d.errors) {
        v = frep_calloc(f.nmodels + 1, sizeof *v);
        if (v) {
            for (i = 0; i < f.nmodels; i++) {
                v[i] = dup_str(f.models[i].name);
                if (!v[i]) {
                    frep_free_strings(v, i);
                    v = NULL;
                    break;
                }
            }
            if (v) *count = f.nmodels;
        }
        if (!v) diag_report(&d, FREP_ERROR, (ast_loc){ 0, 0, 0, 0 }, 0, "out of memory");
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
