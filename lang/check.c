/* check.c - semantic checks between parsing (lang/parse.y) and lowering (lang/lower.c).
 *
 * Per model: arrays are declared (x, a, s parameters and `array` declarations),
 * scalars exist from their first assignment in textual order, the model assigns its
 * own name, constant indices are in range, calls name a library function or an
 * earlier model with the right number and kinds of arguments, and comparisons and
 * logic appear only in if/while conditions.  Then the pragmas (`-- @free`, `-- @setops`,
 * `-- @box`).  Every problem is reported, each with did-you-mean suggestions.
 */
#include "check.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "frep.h"
#include "lib.h"

/* ---- string map ---------------------------------------------------------------- */

#define STRMAP_INITIAL_CAP 16u /* slots; doubled at half load */

static uint32_t strmap_hash(const char *s)
{
    uint32_t h = 2166136261u;
    while (*s) {
        h ^= (unsigned char)*s++;
        h *= 16777619u;
    }
    return h;
}

void strmap_init(strmap *m, arena *A)
{
    memset(m, 0, sizeof *m);
    m->A = A;
}

uint32_t *strmap_get(const strmap *m, const char *key)
{
    uint32_t i;
    if (!m->cap) return NULL;
    for (i = strmap_hash(key) & (m->cap - 1); m->keys[i]; i = (i + 1) & (m->cap - 1))
        if (strcmp(m->keys[i], key) == 0) return &m->vals[i];
    return NULL;
}

int strmap_put(strmap *m, const char *key, uint32_t val)
{
    uint32_t *v = strmap_get(m, key), i;
    if (v) {
        *v = val;
        return 0;
    }
    if (2 * (m->n + 1) > m->cap) {
        uint32_t ncap = m->cap ? 2 * m->cap : STRMAP_INITIAL_CAP, j;
        const char **k = arena_alloc(m->A, ncap * sizeof *k);
        uint32_t *vs = arena_alloc(m->A, ncap * sizeof *vs);
        if (!k || !vs) return -1;
        for (j = 0; j < m->cap; j++) {
            if (!m->keys[j]) continue;
            for (i = strmap_hash(m->keys[j]) & (ncap - 1); k[i]; i = (i + 1) & (ncap - 1)) {}
            k[i] = m->keys[j];
            vs[i] = m->vals[j];
        }
        m->keys = k;
        m->vals = vs;
        m->cap = ncap;
    }
    for (i = strmap_hash(key) & (m->cap - 1); m->keys[i]; i = (i + 1) & (m->cap - 1)) {}
    m->keys[i] = key;
    m->vals[i] = val;
    m->n++;
    return 0;
}

/* ---- helpers ------------------------------------------------------------------------ */

static int is_s(const ast_node *n) { return n->key && strcmp(n->key, "s") == 0; }

static const ast_node *s_use(const ast_node *n);

static const ast_node *s_use_list(const ast_list *l)
{
    const ast_node *u = NULL;
    for (uint32_t i = 0; i < l->n && !u; i++) u = s_use(l->v[i]);
    return u;
}

/* The first use of s as an array in n: s[i], s[i] = v, s = [...], a bare s. */
static const ast_node *s_use(const ast_node *n)
{
    const ast_node *u;
    if (!n) return NULL;
    if ((n->kind == AST_INDEX || n->kind == AST_ASSIGN_INDEX ||
         n->kind == AST_ASSIGN_ARRAY || n->kind == AST_VAR) && is_s(n))
        return n;
    if ((u = s_use(n->a)) || (u = s_use(n->b)) || (u = s_use_list(&n->list)) ||
        (u = s_use_list(&n->body)))
        return u;
    return s_use_list(&n->body2);
}

static int s_assigned(const ast_list *l)
{
    for (uint32_t i = 0; i < l->n; i++)
        if ((l->v[i]->kind == AST_ASSIGN && is_s(l->v[i])) || s_assigned(&l->v[i]->body) ||
            s_assigned(&l->v[i]->body2))
            return 1;
    return 0;
}

const ast_node *check_implicit_s(const ast_model *m)
{
    if (m->nparams != 2 || s_assigned(&m->body)) return NULL;
    for (uint32_t i = 0; i < m->narrays; i++)
        if (strcmp(m->arrays[i].key, "s") == 0) return NULL;
    return s_use_list(&m->body);
}

int check_find_model(const ast_file *f, const char *key, uint32_t before)
{
    uint32_t i;
    for (i = 0; i < before && i < f->nmodels; i++)
        if (strcmp(f->models[i].key, key) == 0) return (int)i;
    return -1;
}

char check_lib_kind(const char *args, uint32_t i, uint32_t *min, int *variadic)
{
    size_t n = strlen(args);
    int var = n > 0 && args[n - 1] == '*';
    if (var) n--;
    if (min) *min = (uint32_t)n;
    if (variadic) *variadic = var;
    if (i < n) return args[i];
    if (var && n > 0) return args[n - 1];
    return 0;
}

static uint32_t loc_len(ast_loc l)
{
    return l.end > l.off ? l.end - l.off : 1;
}

/* Case-insensitive edit distance, capped: larger distances are never suggested. */
#define CHECK_MAX_SUGGEST_LEN 64 /* longer names get no suggestion (bounded work) */
static unsigned edit_distance(const char *a, const char *b)
{
    unsigned row[CHECK_MAX_SUGGEST_LEN + 1];
    size_t la = strlen(a), lb = strlen(b), i, j;
    if (la > CHECK_MAX_SUGGEST_LEN || lb > CHECK_MAX_SUGGEST_LEN) return 1000;
    for (j = 0; j <= lb; j++) row[j] = (unsigned)j;
    for (i = 1; i <= la; i++) {
        unsigned diag = row[0];
        row[0] = (unsigned)i;
        for (j = 1; j <= lb; j++) {
            unsigned up = row[j];
            unsigned cost = tolower((unsigned char)a[i - 1]) == tolower((unsigned char)b[j - 1]) ? 0u : 1u;
            unsigned best = diag + cost;
            if (up + 1 < best) best = up + 1;
            if (row[j - 1] + 1 < best) best = row[j - 1] + 1;
            row[j] = best;
            diag = up;
        }
    }
    return row[lb];
}

typedef struct suggest {
    const char *name;
    const char *best;
    unsigned dist;
} suggest;

static void suggest_try(suggest *s, const char *cand)
{
    unsigned d = edit_distance(s->name, cand);
    size_t len = strlen(s->name);
    unsigned limit = (unsigned)(len / 3 + 1);
    if (d == 0 || d > limit || d >= len) return;
    if (!s->best || d < s->dist) {
        s->best = cand;
        s->dist = d;
    }
}

/* ---- per-model scope ----------------------------------------------------------- */

typedef struct ck_array {
    const char *name, *key;
    uint32_t size;
} ck_array;

typedef struct checker {
    arena *A;
    const ast_file *f;
    diag_sink *d;
    uint32_t model;          /* index of the model being checked */
    strmap arrays;           /* key -> index into arr */
    ck_array *arr;
    uint32_t narr;
    strmap vars;             /* scalars assigned so far (textual order) */
    strmap later;            /* scalars assigned anywhere in the model -> their index */
    uint32_t nscalars;       /* entries of later */
    uint8_t *must, *may;     /* by scalar index: assigned on every / on some path to
                                the statement being checked (ck_flow_*) */
    int strict;              /* extensions are errors (ck_ext) */
    const char **varnames;   /* for suggestions */
    uint32_t nvarnames, capvarnames;
} checker;

static void ck_error(checker *c, ast_loc loc, const char *fmt, const char *a,
                     const char *b, const char *sugg)
{
    char msg[512];
    size_t n;
    (void)snprintf(msg, sizeof msg, fmt, a ? a : "", b ? b : "");
    n = strlen(msg);
    if (sugg) (void)snprintf(msg + n, sizeof msg - n, "; did you mean '%s'?", sugg);
    diag_report(c->d, FREP_ERROR, loc, loc_len(loc), "%s", msg);
}

static const ck_array *ck_array_find(const checker *c, const char *key)
{
    const uint32_t *i = strmap_get(&c->arrays, key);
    return i ? &c->arr[*i] : NULL;
}

static void ck_add_var(checker *c, const ast_node *n)
{
    if (strmap_get(&c->vars, n->key)) return;
    (void)strmap_put(&c->vars, n->key, 1);
    if (c->nvarnames == c->capvarnames) {
        uint32_t ncap = c->capvarnames ? 2 * c->capvarnames : 16;
        const char **v = arena_grow(c->A, c->varnames, c->nvarnames, ncap, sizeof *v);
        if (!v) return;
        c->varnames = v;
        c->capvarnames = ncap;
    }
    c->varnames[c->nvarnames++] = n->name;
}

/* A construct frep accepts and the reference interpreter rejects.  EXT_WARN: a
 * warning that names it (constructs that are likely slips: x assigned, a short
 * list, the model's value assigned early), an error with --strict.  EXT_STRICT:
 * frep's deliberate, documented extensions (its own functions, expressions in
 * lists, ...), which frep itself writes: reported only with --strict, as errors
 * (doc/language.md, section What HyperFun rejects). */
enum { EXT_WARN, EXT_STRICT };

static void ck_ext(checker *c, int tier, ast_loc loc, const char *what)
{
    if (tier == EXT_STRICT && !c->strict) return;
    diag_report(c->d, c->strict ? FREP_ERROR : FREP_WARNING, loc, loc_len(loc),
                "not HyperFun: %s; will not run in the reference interpreter", what);
}

/* A construct the reference accepts with a meaning that surprises (a rounded array
 * size, an array declared twice): frep gives it that meaning and warns; an error with
 * --strict.  fmt takes two %s. */
static void ck_surprise(checker *c, ast_loc loc, const char *fmt, const char *a,
                        const char *b)
{
    char what[640];
    (void)snprintf(what, sizeof what, fmt, a ? a : "", b ? b : "");
    diag_report(c->d, c->strict ? FREP_ERROR : FREP_WARNING, loc, loc_len(loc), "%s", what);
}

/* ck_ext with a name (or a number) in the description. */
static void ck_ext_fmt(checker *c, int tier, ast_loc loc, const char *fmt, const char *a,
                       const char *b)
{
    char what[640];
    (void)snprintf(what, sizeof what, fmt, a ? a : "", b ? b : "");
    ck_ext(c, tier, loc, what);
}

/* A name HyperFun's scanner cannot read as a new model, variable or array: one
 * starting with '_' (its names start with a letter), a reserved word of it (x, a, s
 * are the tokens of the three parameter arrays, xor a keyword no rule uses), or the
 * name of one of its functions (the scanner makes that a function token, which
 * neither a model header nor a statement may start with). */
static void ck_name(checker *c, ast_loc loc, const char *name, const char *key)
{
    const lib_fn *fn;
    if (name[0] == '_')
        ck_ext_fmt(c, EXT_STRICT, loc, "the name '%s' starts with '_'%s", name, "");
    else if (strcmp(key, "x") == 0 || strcmp(key, "a") == 0 || strcmp(key, "s") == 0 ||
             strcmp(key, "xor") == 0)
        ck_ext_fmt(c, EXT_STRICT, loc, "'%s' is a reserved word of HyperFun%s", name, "");
    else if ((fn = lib_lookup(name)) != NULL && !lib_frep_only(fn))
        ck_ext_fmt(c, EXT_STRICT, loc, "the name '%s' is the name of HyperFun's function "
                   "'%s'", name, fn->name);
}

/* Suggestions: which kinds of names are candidates. */
#define SUGG_FUNCS 1u
#define SUGG_VARS 2u
#define SUGG_ARRAYS 4u

static const char *ck_suggest(const checker *c, const char *name, unsigned what)
{
    suggest s = { name, NULL, 0 };
    uint32_t i, n;
    if (what & SUGG_FUNCS) {
        const lib_fn *fns = lib_all(&n);
        for (i = 0; i < n; i++) suggest_try(&s, fns[i].name);
        for (i = 0; i < c->model; i++) suggest_try(&s, c->f->models[i].name);
    }
    if (what & SUGG_VARS)
        for (i = 0; i < c->nvarnames; i++) suggest_try(&s, c->varnames[i]);
    if (what & SUGG_ARRAYS)
        for (i = 0; i < c->narr; i++) suggest_try(&s, c->arr[i].name);
    return s.best;
}

static int is_cmp(int op)
{
    return op == AST_OP_EQ || op == AST_OP_NE || op == AST_OP_LT || op == AST_OP_LE ||
           op == AST_OP_GT || op == AST_OP_GE;
}

static int is_logic(int op) { return op == AST_OP_AND || op == AST_OP_OR; }
static int is_not(int op) { return op == AST_OP_NOT; }

/* Does a condition operand start with a parenthesized part that an arithmetic
 * operator continues, as in `(x[1] - 1) * 2 > 0`?  HyperFun's HF_For_Bool reads a
 * '(' at the start of an operand as a parenthesized condition and then expects a
 * comparison, 'and', 'or' or 'then', so it rejects the operator after ')'. */
static int ck_paren_start(const ast_node *opnd)
{
    const ast_node *n = opnd;
    if (opnd->parens) return 0;
    while (n->kind == AST_BINARY && !n->parens && !is_cmp(n->op) && !is_logic(n->op))
        n = n->a;
    return n != opnd && n->parens;
}

/* A literal number, possibly negated: its value in *v. */
static int ck_literal(const ast_node *n, double *v)
{
    if (n->kind == AST_NUM) {
        *v = n->num;
        return 1;
    }
    if (n->kind == AST_UNARY && n->op == '-' && n->a && n->a->kind == AST_NUM) {
        *v = -n->a->num;
        return 1;
    }
    return 0;
}

static void ck_expr(checker *c, const ast_node *n, int where);

static void ck_index(checker *c, const ast_node *n, const ck_array *arr, const ast_node *idx)
{
    double v;
    ck_expr(c, idx, 0);
    if (arr && ck_literal(idx, &v)) {
        /* Rounded to the nearest whole number, halves up, as the reference does. */
        double r = lib_hf_round_k(v);
        if (!(r >= 1 && r <= (double)arr->size)) {
            char a[64], b[160];
            (void)snprintf(a, sizeof a, "%g", v);
            (void)snprintf(b, sizeof b, "'%s' of size %u", arr->name, (unsigned)arr->size);
            ck_error(c, idx->loc, "index %s is out of range for array %s", a, b, NULL);
        }
    }
    (void)n;
}

/* call -> NAME '(' args ')' where NAME is an earlier model: every argument an array
 * at least as large as the model's parameter. */
static void ck_call_model(checker *c, const ast_node *n, const ast_model *m)
{
    uint32_t i;
    if (n->list.n != m->nparams) {
        char a[160], b[64];
        (void)snprintf(a, sizeof a, "model '%s' takes %u array arguments", m->name,
                       (unsigned)m->nparams);
        (void)snprintf(b, sizeof b, "%u", (unsigned)n->list.n);
        ck_error(c, n->op_loc, "%s, %s given", a, b, NULL);
    }
    for (i = 0; i < n->list.n; i++) {
        const ast_node *arg = n->list.v[i];
        const ck_array *arr = arg->kind == AST_VAR ? ck_array_find(c, arg->key) : NULL;
        if (!arr) {
            char a[200];
            (void)snprintf(a, sizeof a, "argument %u of model '%s'", (unsigned)i + 1,
                           m->name);
            ck_error(c, arg->loc, "%s must be an array", a, NULL, NULL);
            if (arg->kind != AST_VAR) ck_expr(c, arg, 0);
            continue;
        }
        if (i < m->nparams && arr->size < m->params[i].size) {
            char a[200], b[200];
            (void)snprintf(a, sizeof a, "array '%s' has %u elements", arr->name,
                           (unsigned)arr->size);
            (void)snprintf(b, sizeof b, "model '%s' needs %u for '%s'", m->name,
                           (unsigned)m->params[i].size, m->params[i].name);
            ck_error(c, arg->loc, "%s; %s", a, b, NULL);
        } else if (i < m->nparams && arr->size > m->params[i].size) {
            /* I_EXTERN_CALL's parser (int_parse_N.c) wants the sizes equal */
            char a[200], b[200];
            (void)snprintf(a, sizeof a, "'%s' of %u elements", arr->name, (unsigned)arr->size);
            (void)snprintf(b, sizeof b, "'%s[%u]' of model '%s'", m->params[i].name,
                           (unsigned)m->params[i].size, m->name);
            ck_ext_fmt(c, EXT_STRICT, arg->loc, "passing %s for %s, a smaller array", a, b);
        }
    }
}

/* call -> NAME '(' args ')' where NAME is neither a library function nor an earlier
 * model: the model itself, a later one, or unknown (with a suggestion). */
static void ck_call_unknown(checker *c, const ast_node *n)
{
    int later = check_find_model(c->f, n->key, c->f->nmodels);
    uint32_t i;
    if (later >= 0 && (uint32_t)later == c->model)
        ck_error(c, n->op_loc, "model '%s' cannot call itself", n->name, NULL, NULL);
    else if (later >= 0)
        ck_error(c, n->op_loc,
                 "model '%s' is defined later in the file; a model can only call "
                 "models defined before it%s", n->name, "", NULL);
    else
        ck_error(c, n->op_loc, "unknown function '%s'%s", n->name, "",
                 ck_suggest(c, n->name, SUGG_FUNCS));
    for (i = 0; i < n->list.n; i++)
        if (n->list.v[i]->kind != AST_VAR) ck_expr(c, n->list.v[i], 0);
}

/* Argument i of library function fn, of kind `kind` (lib.h letters): a number, or an
 * array of at least the size the function needs. */
static void ck_lib_arg(checker *c, const lib_fn *fn, uint32_t i, char kind,
                       const ast_node *arg)
{
    char what[200];
    (void)snprintf(what, sizeof what, "argument %u of '%s'", (unsigned)i + 1, fn->name);
    if (kind == 's') {
        if (arg->kind == AST_VAR && ck_array_find(c, arg->key) &&
            !strmap_get(&c->vars, arg->key))
            ck_error(c, arg->loc, "%s must be a number, but '%s' is an array", what,
                     arg->name, NULL);
        else
            ck_expr(c, arg, 0);
        return;
    }
    const ck_array *arr = arg->kind == AST_VAR ? ck_array_find(c, arg->key) : NULL;
    uint32_t need = kind == 'a' ? (i < 12 ? fn->sizes[i] : 0) : kind == 'v' || kind == 'w' ? 1 : 3;
    if (!arr) {
        if (arg->kind == AST_VAR && !strmap_get(&c->vars, arg->key))
            ck_error(c, arg->loc, "%s must be an array; unknown array '%s'", what,
                     arg->name, ck_suggest(c, arg->name, SUGG_ARRAYS));
        else
            ck_error(c, arg->loc, "%s must be an array%s", what, "", NULL);
        if (arg->kind != AST_VAR) ck_expr(c, arg, 0);
    } else if (arr->size < need) {
        char b[200];
        (void)snprintf(b, sizeof b, "at least %u elements, '%s' has %u",
                       (unsigned)need, arr->name, (unsigned)arr->size);
        ck_error(c, arg->loc, "%s must have %s", what, b, NULL);
    }
}

/* call -> NAME '(' args ')' where NAME is a library function: its arity, then each
 * argument's kind. */
static void ck_call_lib(checker *c, const ast_node *n, const lib_fn *fn)
{
    uint32_t min, i;
    int var;
    if (lib_frep_only(fn))
        ck_ext_fmt(c, EXT_STRICT, n->op_loc, "'%s' is a function of frep's own library%s",
                   fn->name, "");
    /* The reference's sign() gives 1 for every argument (FUNC_sign in int_calc.c sets
     * -1 for a negative one and then overwrites it); frep keeps the sign and says so. */
    if (strcmp(fn->name, "sign") == 0)
        diag_report(c->d, FREP_WARNING, n->op_loc, loc_len(n->op_loc),
                    "'sign' gives -1, 0 or 1; the HyperFun reference interpreter returns 1 "
                    "for every argument, so this file evaluates differently there");
    (void)check_lib_kind(fn->args, 0, &min, &var);
    if (n->list.n < min || (!var && n->list.n > min)) {
        char a[200], b[64];
        (void)snprintf(a, sizeof a, "'%s' takes %s%u argument%s", fn->name,
                       var ? "at least " : "", (unsigned)min, min == 1 ? "" : "s");
        (void)snprintf(b, sizeof b, "%u", (unsigned)n->list.n);
        ck_error(c, n->op_loc, "%s, %s given", a, b, NULL);
    }
    for (i = 0; i < n->list.n; i++) {
        char kind = check_lib_kind(fn->args, i, NULL, NULL);
        if (kind == 0) ck_expr(c, n->list.v[i], 0);
        else ck_lib_arg(c, fn, i, kind, n->list.v[i]);
    }
}

/* call -> NAME '(' args ')': an earlier model first, then the library. */
static void ck_call(checker *c, const ast_node *n)
{
    int mi = check_find_model(c->f, n->key, c->model);
    const lib_fn *fn;
    if (mi >= 0) {
        ck_call_model(c, n, &c->f->models[mi]);
        return;
    }
    fn = lib_lookup(n->name);
    if (fn) ck_call_lib(c, n, fn);
    else ck_call_unknown(c, n);
}

/* Where an expression stands: a value (arithmetic), an if/while condition, or the
 * operand of a construct already reported as misplaced, where nothing more is said
 * about conditions (one error per mistake, not a cascade). */
enum { CK_VALUE = 0, CK_COND = 1, CK_ANY = 2 };

/* A value where a condition belongs: HyperFun accepts it (HF_For_Bool reads an
 * expression) and takes it as true where |value| >= 1e-6, as frep does (lower.c,
 * lw_cond); a warning, because a comparison was usually meant. */
static void ck_paren_operand(checker *c, const ast_node *opnd)
{
    if (ck_paren_start(opnd))
        ck_ext(c, EXT_STRICT, opnd->loc, "a condition operand that starts with '(' and "
               "goes on after ')' (HyperFun reads the parentheses there as a whole "
               "condition)");
}

static void ck_not_condition(checker *c, const ast_node *n)
{
    ck_paren_operand(c, n);
    diag_report(c->d, FREP_WARNING, n->loc, loc_len(n->loc),
                "a number used as a condition: true where it is not 0 (|value| >= 1e-6, "
                "as in HyperFun); write a comparison such as '... /= 0' to say so");
}

/* expr -> VAR: a scalar assigned before this point, on every path to it.  The
 * reference interpreter stops with its Not_Initialized error where a variable is
 * read before a value reached it (int_calc.c); frep gives NaN there (lower.c,
 * cell_value), so a read that no assignment reaches is an error and one that only
 * some paths reach a warning. */
static void ck_var(checker *c, const ast_node *n)
{
    const uint32_t *vi;
    if (strmap_get(&c->vars, n->key)) {
        vi = strmap_get(&c->later, n->key);
        if (!vi || !c->may || !c->must) return;
        if (!c->may[*vi])
            ck_error(c, n->loc, "variable '%s' is not assigned on any path to this use "
                     "(it is assigned only in a branch that does not lead here)", n->name,
                     NULL, NULL);
        else if (!c->must[*vi])
            diag_report(c->d, FREP_WARNING, n->loc, loc_len(n->loc),
                        "variable '%s' may be used before it is assigned: some paths to "
                        "this use do not assign it (frep gives NaN there, where the "
                        "reference interpreter stops with an error)", n->name);
        return;
    }
    if (ck_array_find(c, n->key))
        ck_error(c, n->loc, "array '%s' used as a number; index it ('%s[1]') or pass "
                 "it to a function", n->name, n->name, NULL);
    else if (strmap_get(&c->later, n->key))
        ck_error(c, n->loc, "variable '%s' is used before it is assigned", n->name,
                 NULL, NULL);
    else
        ck_error(c, n->loc, "unknown variable '%s'%s", n->name, "",
                 ck_suggest(c, n->name, SUGG_VARS | SUGG_ARRAYS));
}

/* expr -> VAR '[' expr ']': a declared array, a constant index in range. */
static void ck_element(checker *c, const ast_node *n)
{
    const ck_array *arr = ck_array_find(c, n->key);
    if (!arr) {
        if (strmap_get(&c->vars, n->key))
            ck_error(c, n->op_loc, "'%s' is a number, not an array", n->name, NULL, NULL);
        else
            ck_error(c, n->op_loc, "unknown array '%s'%s", n->name, "",
                     ck_suggest(c, n->name, SUGG_ARRAYS));
    }
    ck_index(c, n, arr, n->a);
}

/* The operands' context: CK_ANY stays CK_ANY; otherwise `inner`. */
static int ck_inner(int where, int inner)
{
    return where == CK_ANY ? CK_ANY : inner;
}

/* unary -> '-' expr | NOT expr: 'not' only in a condition, and of a condition. */
static void ck_unary(checker *c, const ast_node *n, int where)
{
    if (is_not(n->op)) {
        if (where == CK_VALUE) {
            ck_error(c, n->op_loc, "'not' is only allowed in an if or while condition",
                     NULL, NULL, NULL);
            where = CK_ANY;
        }
        ck_expr(c, n->a, ck_inner(where, CK_COND));
        return;
    }
    if (where == CK_COND) {
        ck_not_condition(c, n);
        where = CK_VALUE;
    }
    ck_expr(c, n->a, ck_inner(where, CK_VALUE));
}

static int is_truth(const ast_node *n)
{
    return (n->kind == AST_BINARY && (is_cmp(n->op) || is_logic(n->op))) ||
           (n->kind == AST_UNARY && is_not(n->op));
}

/* cmp -> expr CMP expr in a condition, where an operand may itself be a comparison
 * (or and/or/not): `-1 <= x[1] < 0.5`.  The reference interpreter's HF_For_Compare
 * (int_parse_N.c) reads comparisons left to right, each giving 1 or 0, so this is
 * `(-1 <= x[1]) < 0.5`: the truth value compared with 0.5, not a range test.  frep
 * computes the same and says so. */
static void ck_compare_operand(checker *c, const ast_node *n, const ast_node *opnd)
{
    if (!is_truth(opnd)) {
        ck_paren_operand(c, opnd);
        ck_expr(c, opnd, CK_VALUE);
        return;
    }
    char hint[160] = "";
    if (opnd == n->a && is_cmp(opnd->op))
        (void)snprintf(hint, sizeof hint, "; for a range test write 'a %s b and b %s c'",
                       ast_op_name(opnd->op), ast_op_name(n->op));
    else if (opnd == n->a && opnd->kind == AST_UNARY && !opnd->parens)
        /* `not a > b`: 'not' takes the next operand, as in the reference's
         * HF_For_Bool, so this is `(not a) > b` */
        (void)snprintf(hint, sizeof hint, ": 'not' applies to the operand after it only, "
                       "so this is '(not a) %s b'; for the negation write 'not (a %s b)'",
                       ast_op_name(n->op), ast_op_name(n->op));
    diag_report(c->d, FREP_WARNING, n->op_loc, loc_len(n->op_loc),
                "'%s' compares the truth value (1 or 0) of '%s' with a number, as "
                "HyperFun does%s", ast_op_name(n->op), ast_op_name(opnd->op), hint);
    ck_expr(c, opnd, CK_COND);
}

/* binary -> expr OP expr: 'and'/'or' join conditions, comparisons compare values,
 * both only in a condition; anything else is a value. */
static void ck_binary(checker *c, const ast_node *n, int where)
{
    if (is_logic(n->op)) {
        if (where == CK_VALUE) {
            ck_error(c, n->op_loc, "'%s' is only allowed in an if or while condition",
                     n->op == AST_OP_AND ? "and" : "or", NULL, NULL);
            where = CK_ANY;
        }
        ck_expr(c, n->a, ck_inner(where, CK_COND));
        ck_expr(c, n->b, ck_inner(where, CK_COND));
        return;
    }
    if (is_cmp(n->op)) {
        if (where == CK_VALUE) {
            ck_error(c, n->op_loc, "comparison '%s' is only allowed in an if or while "
                     "condition", ast_op_name(n->op), NULL, NULL);
            where = CK_ANY;
        }
        if (where == CK_COND) {
            ck_compare_operand(c, n, n->a);
            ck_compare_operand(c, n, n->b);
            return;
        }
    } else if (where == CK_COND) {
        ck_not_condition(c, n);
        where = CK_VALUE;
    }
    ck_expr(c, n->a, ck_inner(where, CK_VALUE));
    ck_expr(c, n->b, ck_inner(where, CK_VALUE));
}

/* NUM as HyperFun's scanner reads it (int_scanner.c): no leading zero before
 * another digit (007), no exponent that starts with 0 (1e05). */
static void ck_number(checker *c, const ast_node *n)
{
    const char *t = c->f->src + n->loc.off, *end = c->f->src + n->loc.end, *e;
    char text[64];
    if (n->loc.end <= n->loc.off || n->loc.end > c->f->len) return;
    for (e = t; e < end && *e != 'e' && *e != 'E'; e++) {}
    if (e < end) {
        e++;
        if (e < end && (*e == '+' || *e == '-')) e++;
    }
    if (!((t + 1 < end && t[0] == '0' && t[1] >= '0' && t[1] <= '9') ||
          (e < end && *e == '0' && e > t && (e[-1] == 'e' || e[-1] == 'E' || e[-1] == '+' ||
                                              e[-1] == '-'))))
        return;
    (void)snprintf(text, sizeof text, "%.*s", (int)(end - t < 60 ? end - t : 60), t);
    ck_ext_fmt(c, EXT_STRICT, n->loc, "the number '%s' has a leading zero in its digits or its "
               "exponent%s", text, "");
}

/* expr -> NUM | VAR | VAR '[' expr ']' | CALL | unary | binary.  where: CK_VALUE,
 * CK_COND (part of an if/while condition, where comparisons and logic belong) or
 * CK_ANY (below a misplaced construct already reported). */
static void ck_expr(checker *c, const ast_node *n, int where)
{
    if (!n) return;
    if (where == CK_COND && (n->kind == AST_NUM || n->kind == AST_VAR ||
                             n->kind == AST_INDEX || n->kind == AST_CALL)) {
        ck_not_condition(c, n);
        where = CK_VALUE;
    }
    switch (n->kind) {
    case AST_NUM:
        ck_number(c, n);
        break;
    case AST_VAR:
        ck_var(c, n);
        break;
    case AST_INDEX:
        ck_element(c, n);
        break;
    case AST_CALL:
        ck_call(c, n);
        break;
    case AST_UNARY:
        ck_unary(c, n, where);
        break;
    case AST_BINARY:
        ck_binary(c, n, where);
        break;
    case AST_ASSIGN: case AST_ASSIGN_INDEX: case AST_ASSIGN_ARRAY: case AST_IF:
    case AST_WHILE:
        break;
    }
}

static void ck_stmts(checker *c, const ast_list *l);

/* ---- definite assignment: the must/may sets through if and while --------------- */

static void ck_flow_assign(checker *c, const char *key)
{
    const uint32_t *vi = strmap_get(&c->later, key);
    if (!vi || !c->must || !c->may) return;
    c->must[*vi] = c->may[*vi] = 1;
}

/* A copy of a set (NULL when out of memory: the flow checks then stop). */
static uint8_t *ck_flow_copy(checker *c, const uint8_t *v)
{
    uint8_t *r;
    if (!v) return NULL;
    r = arena_alloc(c->A, c->nscalars + 1);
    if (r) memcpy(r, v, c->nscalars);
    return r;
}

/* Every scalar some statement of l assigns, into set (may-assigned by a loop body). */
static void ck_flow_assigned(checker *c, const ast_list *l, uint8_t *set)
{
    uint32_t i;
    for (i = 0; i < l->n; i++) {
        const ast_node *n = l->v[i];
        const uint32_t *vi = n->kind == AST_ASSIGN ? strmap_get(&c->later, n->key) : NULL;
        if (vi) set[*vi] = 1;
        ck_flow_assigned(c, &n->body, set);
        ck_flow_assigned(c, &n->body2, set);
    }
}

/* if_stmt: each branch from the state before it; after it, assigned on every path
 * when both branches assign, on some path when either does. */
static void ck_if(checker *c, const ast_node *n)
{
    uint8_t *must0, *may0, *must1, *may1;
    uint32_t i;
    ck_expr(c, n->a, CK_COND);
    must0 = ck_flow_copy(c, c->must);
    may0 = ck_flow_copy(c, c->may);
    ck_stmts(c, &n->body);
    must1 = ck_flow_copy(c, c->must);
    may1 = ck_flow_copy(c, c->may);
    if (!must0 || !may0 || !must1 || !may1) {
        c->must = c->may = NULL;
        ck_stmts(c, &n->body2);
        return;
    }
    memcpy(c->must, must0, c->nscalars);
    memcpy(c->may, may0, c->nscalars);
    ck_stmts(c, &n->body2);
    for (i = 0; i < c->nscalars; i++) {
        c->must[i] = c->must[i] & must1[i];
        c->may[i] = c->may[i] | may1[i];
    }
}

/* while_stmt: the body may run any number of times, so what it assigns may reach
 * the condition and the body itself; after the loop only what held before is sure. */
static void ck_while(checker *c, const ast_node *n)
{
    uint8_t *must0 = ck_flow_copy(c, c->must);
    if (c->may) ck_flow_assigned(c, &n->body, c->may);
    ck_expr(c, n->a, CK_COND);
    ck_stmts(c, &n->body);
    if (must0 && c->must) memcpy(c->must, must0, c->nscalars);
}

/* ---- statements ------------------------------------------------------------------ */

/* The model's value assigned: HyperFun's grammar has it only as the last statement
 * of the body (HF_Get_Body_Def in int_parse_N.c: the operators stop at the model's
 * name, then 'name = expr ;' and '}' must follow). */
static void ck_result_assign(checker *c, const ast_node *n)
{
    const ast_model *m = &c->f->models[c->model];
    if (strcmp(n->key, m->key) != 0) return;
    if (m->body.n > 0 && m->body.v[m->body.n - 1] == n) return;
    ck_ext_fmt(c, EXT_WARN, n->op_loc, "the model's value '%s' is assigned by a statement other "
               "than the model's last%s", n->name, "");
}

/* x and a are the point and the parameters: HyperFun has no statement that assigns
 * them (a statement starting with x or a is a syntax error there); the space
 * transformations of the library change x through their argument instead. */
static void ck_param_assign(checker *c, const ast_node *n)
{
    const ast_model *m = &c->f->models[c->model];
    if (m->nparams >= 1 && strcmp(n->key, m->params[0].key) == 0)
        ck_ext_fmt(c, EXT_WARN, n->op_loc, "assigning to '%s', the point array of the model%s",
                   n->name, "");
    else if (m->nparams >= 2 && strcmp(n->key, m->params[1].key) == 0)
        ck_ext_fmt(c, EXT_WARN, n->op_loc, "assigning to '%s', the parameter array of the model%s",
                   n->name, "");
}

/* array_assign -> NAME '=' '[' list ']': HyperFun wants exactly one signed number
 * literal per element (HF_Get_Whole_Array_Assign_Operator). */
static void ck_list_literal(checker *c, const ast_node *n, const ck_array *arr)
{
    uint32_t i;
    double v;
    if (n->list.n < arr->size) {
        char a[64], b[200];
        (void)snprintf(a, sizeof a, "%u", (unsigned)n->list.n);
        (void)snprintf(b, sizeof b, "'%s' of %u elements", arr->name, (unsigned)arr->size);
        ck_ext_fmt(c, EXT_WARN, n->loc, "a list of %s values for %s (the rest would be 0)", a, b);
    }
    for (i = 0; i < n->list.n; i++)
        if (!ck_literal(n->list.v[i], &v)) {
            ck_ext(c, EXT_STRICT, n->list.v[i]->loc, "an element of a list [...] that is not a "
                   "signed number");
            break;
        }
}

static void ck_stmt(checker *c, const ast_node *n)
{
    switch (n->kind) {
    case AST_ASSIGN:
        ck_expr(c, n->a, CK_VALUE);
        if (ck_array_find(c, n->key)) {
            ck_error(c, n->op_loc, "cannot assign a number to array '%s'; assign its "
                     "elements or a list [...]", n->name, NULL, NULL);
        } else {
            /* (the model's own name was checked with its header) */
            if (!strmap_get(&c->vars, n->key) &&
                strcmp(n->key, c->f->models[c->model].key) != 0)
                ck_name(c, n->op_loc, n->name, n->key);
            ck_add_var(c, n);
            ck_flow_assign(c, n->key);
            ck_result_assign(c, n);
        }
        break;
    case AST_ASSIGN_INDEX: {
        const ck_array *arr = ck_array_find(c, n->key);
        if (!arr)
            ck_error(c, n->op_loc, "'%s' is not a declared array%s", n->name, "",
                     strmap_get(&c->vars, n->key) ? NULL : ck_suggest(c, n->name, SUGG_ARRAYS));
        else
            ck_param_assign(c, n);
        ck_index(c, n, arr, n->a);
        ck_expr(c, n->b, CK_VALUE);
        break;
    }
    case AST_ASSIGN_ARRAY: {
        const ck_array *arr = ck_array_find(c, n->key);
        uint32_t i;
        if (!arr) {
            ck_error(c, n->op_loc, "'%s' is not a declared array%s", n->name, "",
                     ck_suggest(c, n->name, SUGG_ARRAYS));
        } else if (n->list.n > arr->size) {
            char a[160], b[64];
            (void)snprintf(a, sizeof a, "array '%s' has %u elements", arr->name,
                           (unsigned)arr->size);
            (void)snprintf(b, sizeof b, "%u", (unsigned)n->list.n);
            ck_error(c, n->loc, "%s, but %s values are assigned", a, b, NULL);
        } else {
            ck_param_assign(c, n);
            ck_list_literal(c, n, arr);
        }
        for (i = 0; i < n->list.n; i++) ck_expr(c, n->list.v[i], CK_VALUE);
        break;
    }
    case AST_IF:
        ck_if(c, n);
        break;
    case AST_WHILE:
        ck_while(c, n);
        break;
    case AST_NUM: case AST_VAR: case AST_INDEX: case AST_CALL: case AST_UNARY:
    case AST_BINARY:
        ck_expr(c, n, CK_VALUE);
        break;
    }
}

static void ck_stmts(checker *c, const ast_list *l)
{
    uint32_t i;
    for (i = 0; i < l->n; i++) ck_stmt(c, l->v[i]);
}

/* Scalars assigned anywhere (for "used before it is assigned"), each numbered for
 * the must/may sets. */
static void ck_collect(checker *c, const ast_list *l)
{
    uint32_t i;
    for (i = 0; i < l->n; i++) {
        const ast_node *n = l->v[i];
        if (n->kind == AST_ASSIGN && !strmap_get(&c->later, n->key))
            (void)strmap_put(&c->later, n->key, c->nscalars++);
        ck_collect(c, &n->body);
        ck_collect(c, &n->body2);
    }
}

static void ck_declare(checker *c, const ast_array_decl *d, int local)
{
    const ck_array *old = ck_array_find(c, d->key);
    if (old && (!local || old < c->arr + c->f->models[c->model].nparams)) {
        ck_error(c, d->loc, "array '%s' is already declared", d->name, NULL, NULL);
        return;
    }
    if (old) {
        /* HF_Find_In_Name_Array (int_array.c) finds the first declaration of a name. */
        char sz[32];
        (void)snprintf(sz, sizeof sz, "%u", (unsigned)old->size);
        ck_surprise(c, d->loc, "array '%s' is declared again; HyperFun uses its first "
                    "declaration (size %s) and ignores this one", d->name, sz);
        return;
    }
    if (d->written != d->size) {
        char w[40], sz[32];
        (void)snprintf(w, sizeof w, "%.17g", d->written);
        (void)snprintf(sz, sizeof sz, "%u", (unsigned)d->size);
        ck_surprise(c, d->size_loc, "array size %s is rounded to %s, as HyperFun does "
                    "(halves up); write the whole number", w, sz);
    }
    if (d->size == 0) ck_error(c, d->loc, "array '%s' must have at least one element",
                               d->name, NULL, NULL);
    c->arr[c->narr].name = d->name;
    c->arr[c->narr].key = d->key;
    c->arr[c->narr].size = d->size;
    (void)strmap_put(&c->arrays, d->key, c->narr);
    c->narr++;
}

static void ck_model(checker *c, uint32_t mi)
{
    const ast_model *m = &c->f->models[mi];
    uint32_t i;
    c->model = mi;
    strmap_init(&c->arrays, c->A);
    strmap_init(&c->vars, c->A);
    strmap_init(&c->later, c->A);
    c->narr = 0;
    c->nvarnames = c->capvarnames = 0;
    c->varnames = NULL;
    c->arr = arena_alloc(c->A, (m->nparams + m->narrays + 1) * sizeof *c->arr);
    if (!c->arr) return;
    if (check_find_model(c->f, m->key, mi) >= 0)
        ck_error(c, m->loc, "model '%s' is already defined", m->name, NULL, NULL);
    ck_name(c, m->loc, m->name, m->key);
    for (i = 0; i < m->nparams; i++) {
        static const char *const hf_param[3] = { "x", "a", "s" };
        ck_declare(c, &m->params[i], 0);
        if (strcmp(m->params[i].key, hf_param[i]) != 0)
            ck_ext_fmt(c, EXT_STRICT, m->params[i].loc, "the parameter array '%s' where HyperFun "
                       "requires the name '%s'", m->params[i].name, hf_param[i]);
    }
    for (i = 0; i < m->narrays; i++) {
        ck_declare(c, &m->arrays[i], 1);
        ck_name(c, m->arrays[i].loc, m->arrays[i].name, m->arrays[i].key);
    }
    const ast_node *su = check_implicit_s(m);
    if (su && !ck_array_find(c, "s")) {
        ck_surprise(c, su->loc, "model '%s' uses 's' without declaring it; HyperFun "
                    "acts as if it declared s[1] (starting at 0 here, no attribute "
                    "output): declare it, %s(x[...], a[...], s[1])", m->name, m->name);
        c->arr[c->narr].name = "s";
        c->arr[c->narr].key = "s";
        c->arr[c->narr].size = 1;
        (void)strmap_put(&c->arrays, "s", c->narr);
        c->narr++;
    }
    if (ck_array_find(c, m->key))
        ck_error(c, m->loc, "the result '%s' of a model cannot be an array", m->name, NULL,
                 NULL);
    c->nscalars = 0;
    ck_collect(c, &m->body);
    c->must = arena_alloc(c->A, c->nscalars + 1);
    c->may = arena_alloc(c->A, c->nscalars + 1);
    if (c->must) memset(c->must, 0, c->nscalars + 1);
    if (c->may) memset(c->may, 0, c->nscalars + 1);
    if (!c->must || !c->may) c->must = c->may = NULL;
    ck_stmts(c, &m->body);
    if (!strmap_get(&c->later, m->key))
        ck_error(c, m->loc, "model '%s' never assigns its result; add '%s = ...;'", m->name,
                 m->name, NULL);
}

/* ---- pragmas ------------------------------------------------------------------------ */

static const char *skip_ws(const char *s)
{
    while (*s == ' ' || *s == '\t' || *s == '\r') s++;
    return s;
}

/* The statement that ends on the line of the comment at byte offset off: the one
 * with the largest end <= off and no newline in between. */
static const ast_node *stmt_before(const ast_file *f, const ast_list *l, uint32_t off,
                                   const ast_node *best)
{
    uint32_t i;
    for (i = 0; i < l->n; i++) {
        const ast_node *n = l->v[i];
        if (n->loc.end <= off && (!best || n->loc.end > best->loc.end)) best = n;
        best = stmt_before(f, &n->body, off, best);
        best = stmt_before(f, &n->body2, off, best);
    }
    return best;
}

static int is_top_stmt(const ast_list *l, const ast_node *n, uint32_t *index)
{
    uint32_t i;
    for (i = 0; i < l->n; i++)
        if (l->v[i] == n) {
            *index = i;
            return 1;
        }
    return 0;
}

/* The statement a pragma at byte offset off annotates: the last one ending before it
 * on the same line, in any model (*m receives the model), or NULL. */
static const ast_node *pragma_stmt(const ast_file *f, uint32_t off, const ast_model **m)
{
    const ast_node *st = NULL;
    uint32_t mi, o;
    for (mi = 0; mi < f->nmodels; mi++) {
        const ast_node *s = stmt_before(f, &f->models[mi].body, off, NULL);
        if (s && (!st || s->loc.end > st->loc.end)) {
            st = s;
            *m = &f->models[mi];
        }
    }
    if (!st) return NULL;
    for (o = st->loc.end; o < off && o < f->len; o++)
        if (f->src[o] == '\n') return NULL;
    return st;
}

/* Why statement st of model m cannot carry '@free' (NULL: it can; *v receives the
 * literal's value). */
static const char *free_refusal(const ast_node *st, const ast_model *m, double *v)
{
    uint32_t idx = 0, j;
    if (!st || st->kind != AST_ASSIGN || !ck_literal(st->a, v))
        return "'@free' must follow a statement 'name = NUMBER;' on the same line";
    if (!is_top_stmt(&m->body, st, &idx))
        return "'@free' parameters must be assigned outside if and while";
    for (j = 0; j < idx; j++)
        if (m->body.v[j]->kind == AST_ASSIGN && strcmp(m->body.v[j]->key, st->key) == 0)
            return "'@free' must mark the first assignment of its variable";
    if (strcmp(st->key, m->key) == 0) return "the model's result cannot be a '@free' parameter";
    return NULL;
}

/* free_text -> description? | '[' NUMBER ',' NUMBER ']' description?, a description
 * being free text that starts with a letter (`-- @free [1, 5] flange radius`): the
 * bounds into fr. Returns 0, -1 after reporting empty bounds, or 1 when the text is
 * malformed. */
static int free_bounds(checker *c, const ast_pragma *p, check_free *fr)
{
    const char *t = skip_ws(p->text ? p->text : "");
    char *e;
    double lo, hi;
    if (*t == '\0' || isalpha((unsigned char)*t)) return 0;
    if (*t != '[') return 1;
    t = skip_ws(t + 1);
    lo = strtod(t, &e);
    if (e == t) return 1;
    t = skip_ws(e);
    if (*t != ',') return 1;
    t = skip_ws(t + 1);
    hi = strtod(t, &e);
    if (e == t) return 1;
    t = skip_ws(e);
    if (*t != ']') return 1;
    t = skip_ws(t + 1);
    if (*t != '\0' && !isalpha((unsigned char)*t)) return 1;
    if (!(lo <= hi)) {
        diag_report(c->d, FREP_ERROR, p->loc, 5, "'@free' bounds [%g, %g] are empty (lo > hi)",
                    lo, hi);
        return -1;
    }
    if (!(fr->value >= lo && fr->value <= hi))
        diag_report(c->d, FREP_WARNING, p->loc, 5,
                    "initial value %g of '%s' is outside its bounds [%g, %g]", fr->value,
                    fr->name, lo, hi);
    fr->lo = lo;
    fr->hi = hi;
    fr->has_bounds = 1;
    return 0;
}

/* A later assignment (at any depth) of the variable of '@free' statement st in list l,
 * or NULL. */
static const ast_node *later_assign(const ast_list *l, const ast_node *st)
{
    uint32_t i;
    for (i = 0; i < l->n; i++) {
        const ast_node *n = l->v[i], *r;
        if (n != st && n->loc.off > st->loc.off &&
            (n->kind == AST_ASSIGN || n->kind == AST_ASSIGN_ARRAY) && strcmp(n->key, st->key) == 0)
            return n;
        if ((r = later_assign(&n->body, st)) || (r = later_assign(&n->body2, st))) return r;
    }
    return NULL;
}

/* Warn when a '@free' variable is assigned again after its line: the fit then changes a
 * value the model no longer reads there. */
static void warn_reassigned(checker *c, const ast_pragma *p, const ast_list *body,
                            const ast_node *st)
{
    const ast_node *n = later_assign(body, st);
    if (n)
        diag_report(c->d, FREP_WARNING, p->loc, 5,
                    "'%s' is assigned again on line %u after its '@free' line; the model "
                    "reads the later value there", st->name, (unsigned)n->loc.line);
}

/* pragma -> '@params' NUMBER (','? NUMBER)*: default values of a[] for when no -a is
 * given (what `frep fit` writes into an a[] template), into out. */
static void ck_params_pragma(checker *c, const ast_pragma *p, check_info *out)
{
    const char *t = skip_ws(p->text ? p->text : "");
    uint32_t n = 0, cap = 1;
    const char *q;
    double *v;
    for (q = t; *q; q++) cap += *q == ',' || *q == ' ';
    v = arena_alloc(c->A, cap * sizeof *v);
    if (!v) return;
    while (*t != '\0' && n < cap) {
        char *e;
        v[n] = strtod(t, &e);
        if (e == t || !isfinite(v[n])) {
            diag_report(c->d, FREP_ERROR, p->loc, (uint32_t)strlen(p->word) + 1,
                        "'@params' expects numbers v1, v2, ... (the values of a[1], a[2], ...)");
            return;
        }
        n++;
        t = skip_ws(e);
        if (*t == ',') t = skip_ws(t + 1);
    }
    out->avals = v;
    out->navals = n;
}

/* pragma -> '@free' free_text after `name = NUMBER;`: a named free parameter. */
static void ck_free_pragma(checker *c, const ast_pragma *p, check_info *out)
{
    const ast_model *m = NULL;
    const ast_node *st = pragma_stmt(c->f, p->loc.off, &m);
    double v = 0;
    const char *why = free_refusal(st, m, &v);
    check_free *fr;
    uint32_t j;
    int rc;
    if (why) {
        diag_report(c->d, FREP_ERROR, p->loc, 5, "%s", why);
        return;
    }
    fr = &out->frees[out->nfree];
    memset(fr, 0, sizeof *fr);
    fr->stmt = st;
    fr->name = st->name;
    fr->value = v;
    fr->lo = -INFINITY;
    fr->hi = INFINITY;
    fr->lit = st->a->loc;
    rc = free_bounds(c, p, fr);
    if (rc > 0)
        diag_report(c->d, FREP_ERROR, p->loc, 5,
                    "malformed '@free': expected '[lo, hi]', a description or nothing after it");
    if (rc != 0) return;
    warn_reassigned(c, p, &m->body, st);
    for (j = 0; j < out->nfree; j++)
        if (out->frees[j].stmt == st) return; /* two pragmas on one line: one parameter */
    out->nfree++;
}

/* pragma -> '@setops' ('rfunc' | 'minmax' | 'ralpha' ALPHA), before the first model. */
static void ck_setops_pragma(checker *c, const ast_pragma *p, check_info *out)
{
    const ast_file *f = c->f;
    const char *t = skip_ws(p->text ? p->text : "");
    uint32_t wlen = (uint32_t)strlen(p->word) + 1;
    uint32_t first_model = f->nmodels ? f->models[0].loc.off : UINT32_MAX;
    char *e;
    if (p->loc.off > first_model) {
        diag_report(c->d, FREP_ERROR, p->loc, wlen,
                    "'@setops' must come before the first model");
        return;
    }
    if (strncmp(t, "rfunc", 5) == 0 && *skip_ws(t + 5) == '\0') {
        out->setops = FREP_SETOPS_RFUNC;
    } else if (strncmp(t, "minmax", 6) == 0 && *skip_ws(t + 6) == '\0') {
        out->setops = FREP_SETOPS_MINMAX;
    } else if (strncmp(t, "ralpha", 6) == 0 && (t[6] == ' ' || t[6] == '\t')) {
        double a = strtod(t + 6, &e);
        if (e == t + 6 || *skip_ws(e) != '\0' || !(a >= -1 && a <= 1)) {
            diag_report(c->d, FREP_ERROR, p->loc, wlen,
                        "'@setops ralpha' needs one ALPHA in [-1, 1]");
            return;
        }
        out->setops = FREP_SETOPS_RALPHA;
        out->alpha = a;
    } else {
        diag_report(c->d, FREP_ERROR, p->loc, wlen,
                    "'@setops' expects 'rfunc', 'minmax' or 'ralpha ALPHA'");
        return;
    }
    out->has_setops = 1;
}

/* pragma -> '@box' X0 Y0 Z0 X1 Y1 Z1 (commas optional), a non-empty box. */
static void ck_box_pragma(checker *c, const ast_pragma *p, check_info *out)
{
    const char *s = skip_ws(p->text ? p->text : "");
    double b[6];
    int k;
    for (k = 0; k < 6; k++) {
        char *e;
        b[k] = strtod(s, &e);
        if (e == s) break;
        s = skip_ws(e);
        if (*s == ',') s = skip_ws(s + 1);
    }
    if (k < 6 || *s != '\0' || !(b[0] < b[3] && b[1] < b[4] && b[2] < b[5])) {
        diag_report(c->d, FREP_ERROR, p->loc, (uint32_t)strlen(p->word) + 1,
                    "'@box' expects six numbers x0 y0 z0 x1 y1 z1 with x0 < x1, "
                    "y0 < y1, z0 < z1");
        return;
    }
    memcpy(out->box, b, sizeof b);
    out->has_box = 1;
}

static void ck_pragmas(checker *c, check_info *out)
{
    const ast_file *f = c->f;
    uint32_t i;
    out->frees = arena_alloc(c->A, (f->npragmas + 1) * sizeof *out->frees);
    if (!out->frees) return;
    for (i = 0; i < f->npragmas; i++) {
        const ast_pragma *p = &f->pragmas[i];
        if (strcmp(p->word, "free") == 0)
            ck_free_pragma(c, p, out);
        else if (strcmp(p->word, "setops") == 0)
            ck_setops_pragma(c, p, out);
        else if (strcmp(p->word, "box") == 0)
            ck_box_pragma(c, p, out);
        else if (strcmp(p->word, "params") == 0)
            ck_params_pragma(c, p, out);
        else
            diag_report(c->d, FREP_WARNING, p->loc, (uint32_t)strlen(p->word) + 1,
                        "unknown pragma '@%s' ignored (known: @free, @setops, @box, @params)",
                        p->word);
    }
}

unsigned check_file(arena *A, const ast_file *f, int strict, diag_sink *d, check_info *out)
{
    checker c;
    unsigned before = d->errors;
    uint32_t i;
    memset(out, 0, sizeof *out);
    memset(&c, 0, sizeof c);
    c.A = A;
    c.f = f;
    c.d = d;
    c.strict = strict;
    for (i = 0; i < f->nmodels; i++) ck_model(&c, i);
    ck_pragmas(&c, out);
    if (A->failed) diag_nomem(d); /* the checks above may have been cut short */
    return d->errors - before;
}
