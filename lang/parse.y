/* parse.y - Bison grammar of HyperFun 2.x models, building the tree of lang/ast.h.
 *
 * Pipeline: lang/lex.re (tokens) -> this parser (ast_file, arena-owned) ->
 * lang/check.c -> lang/lower.c.  Pure and reentrant: all state lives in lex_state.
 * Exactly one syntax error per file is reported (no recovery, no cascade), in words
 * a person can act on (see report_syntax_error below).  Precedence follows the
 * reference HyperFun interpreter (src/interpreter_lib/int_parse_N.c); where this
 * grammar accepts more (general conditions, expressions in array literals) the
 * checker decides.  doc/language.md documents every choice.
 */
%code requires {
#include "ast.h"
typedef struct lex_state lex_state;
}

%code top {
#include "config.h"
}

%code {
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "alloc.h"
#include "lex.h"

/* The parser's stack grows through frep's allocator like every other allocation. */
#define YYMALLOC frep_malloc
#define YYFREE frep_free

/* Enough for FREP_MAX_NESTING levels of every construct (about 16 states a level);
 * the lexer stops deeper nesting first, so "memory exhausted" cannot happen. */
#define YYMAXDEPTH 20000
_Static_assert(YYMAXDEPTH > 16 * FREP_MAX_NESTING + 1000, "parser stack covers nesting");

#define YYLLOC_DEFAULT(Cur, Rhs, N)                                  \
    do {                                                             \
        if (N) {                                                     \
            (Cur).line = YYRHSLOC(Rhs, 1).line;                      \
            (Cur).col = YYRHSLOC(Rhs, 1).col;                        \
            (Cur).off = YYRHSLOC(Rhs, 1).off;                        \
            (Cur).end = YYRHSLOC(Rhs, N).end;                        \
        } else {                                                     \
            (Cur).line = YYRHSLOC(Rhs, 0).line;                      \
            (Cur).col = YYRHSLOC(Rhs, 0).col;                        \
            (Cur).off = (Cur).end = YYRHSLOC(Rhs, 0).end;            \
        }                                                            \
    } while (0)

static void frep_yyerror(FREP_YYLTYPE *loc, lex_state *L, const char *msg);
static ast_node *binop(lex_state *L, ast_loc loc, ast_loc op_loc, int op, ast_node *a,
                       ast_node *b);
static ast_node *unop(lex_state *L, ast_loc loc, ast_loc op_loc, int op, ast_node *a);
static ast_node *leaf(lex_state *L, ast_kind kind, ast_loc loc, ast_loc name_loc,
                      const char *name, const char *key);
static int push(lex_state *L, ast_list *l, ast_node *n, ast_loc loc, uint32_t limit,
                const char *what);
static int start_model(lex_state *L, ast_loc loc, const char *name, const char *key,
                       ast_list *params);
static int array_size(lex_state *L, ast_loc loc, double v, uint32_t min, uint32_t *size);
static int add_array(lex_state *L, ast_loc loc, const char *name, const char *key,
                     double size, ast_loc size_loc);
static int model_statement(lex_state *L, ast_node *stmt);

#define CHECK(x) do { if (!(x)) YYABORT; } while (0)
}

%define api.pure full
%locations
%define api.location.type {ast_loc}
%define api.prefix {frep_yy}
%define parse.error custom
%define parse.lac full
%expect 0
%param {lex_state *L}

%union {
    double num;
    struct { const char *name, *key; } id;
    ast_node *node;
    ast_list list;
}

%token YYEOF 0 "end of file"
%token <id> T_IDENT "name"
%token <num> T_NUM "number"
%token T_ARRAY "array" T_IF "if" T_THEN "then" T_ELSE "else" T_ENDIF "endif"
%token T_WHILE "while" T_LOOP "loop" T_ENDLOOP "endloop"
%token T_AND "and" T_OR "or" T_NOT "not"
%token T_PLUS "+" T_MINUS "-" T_STAR "*" T_SLASH "/" T_CARET "^"
%token T_BAR "|" T_AMP "&" T_BSLASH "\\" T_AT "@" T_TILDE "~"
%token T_EQ "=" T_NE "/=" T_LT "<" T_LE "<=" T_GT ">" T_GE ">="
%token T_LPAREN "(" T_RPAREN ")" T_LBRACK "[" T_RBRACK "]" T_LBRACE "{" T_RBRACE "}"
%token T_COMMA "," T_SEMI ";"

/* Lowest first.  As in the reference: 'and' and 'or' share one level (left to
 * right); 'not' takes the next operand of a comparison, so `not a > b` is
 * `(not a) > b` (HF_For_Bool in int_parse_N.c); + - and the set operators | & \ @
 * share one level; ^ groups left to right; the prefix operators - + ~ bind tighter
 * than ^, so -a^2 is (-a)^2. */
%left T_OR T_AND
%left T_EQ T_NE T_LT T_LE T_GT T_GE
%precedence T_NOT
%left T_PLUS T_MINUS T_BAR T_AMP T_BSLASH T_AT
%left T_STAR T_SLASH
%left T_CARET
%precedence UNARY

%type <node> expr primary stmt
%type <list> stmts args arglist elems params

%%

/* file -> model { model } */
file: model
    | file model
    ;

/* model -> name '(' params ')' '{' { decl_stmt | stmt } '}' */
model: T_IDENT T_LPAREN params T_RPAREN
         { CHECK(start_model(L, @1, $1.name, $1.key, &$3) == 0); }
       T_LBRACE items T_RBRACE
         { ast_model *m = &L->models[L->nmodels - 1]; m->open_loc = @6; m->end_loc = @8; }
     ;

/* params -> name '[' number ']' { ',' name '[' number ']' }   (2 or 3 of them) */
params: T_IDENT T_LBRACK T_NUM T_RBRACK
          { $$ = (ast_list){ 0 };
            ast_node *n = leaf(L, AST_INDEX, @$, @1, $1.name, $1.key); CHECK(n);
            n->num = $3; n->op_loc = @3;
            CHECK(push(L, &$$, n, @$, 3, "") == 0); }
      | params T_COMMA T_IDENT T_LBRACK T_NUM T_RBRACK
          { $$ = $1;
            ast_loc at = @3; at.end = @6.end;
            ast_node *n = leaf(L, AST_INDEX, at, @3, $3.name, $3.key); CHECK(n);
            n->num = $5; n->op_loc = @5;
            CHECK(push(L, &$$, n, at, 3, "") == 0); }
      ;

items: %empty
     | items decl_stmt
     | items stmt        { CHECK(model_statement(L, $2) == 0); }
     ;

/* decl_stmt -> 'array' decl { ',' decl } ';' */
decl_stmt: T_ARRAY decls T_SEMI
             { ast_model *m = &L->models[L->nmodels - 1];
               if (m->body.n) {
                   lex_error(L, @1, 5, "array declarations must come before the first "
                             "statement of model '%s'", m->name);
                   YYABORT;
               } }
         ;

decls: decl
     | decls T_COMMA decl
     ;

/* decl -> name '[' number ']' */
decl: T_IDENT T_LBRACK T_NUM T_RBRACK
        { CHECK(add_array(L, @$, $1.name, $1.key, $3, @3) == 0); }
    ;

stmts: %empty            { $$ = (ast_list){ 0 }; }
     | stmts stmt        { $$ = $1; CHECK(push(L, &$$, $2, @2, UINT32_MAX, "") == 0); }
     ;

stmt: T_IDENT T_EQ expr T_SEMI
        { $$ = leaf(L, AST_ASSIGN, @$, @1, $1.name, $1.key); CHECK($$); $$->a = $3; }
    | T_IDENT T_LBRACK expr T_RBRACK T_EQ expr T_SEMI
        { $$ = leaf(L, AST_ASSIGN_INDEX, @$, @1, $1.name, $1.key); CHECK($$);
          $$->a = $3; $$->b = $6; }
    | T_IDENT T_EQ T_LBRACK elems T_RBRACK T_SEMI
        { $$ = leaf(L, AST_ASSIGN_ARRAY, @$, @1, $1.name, $1.key); CHECK($$);
          $$->list = $4; }
    | T_IF expr T_THEN stmts T_ENDIF T_SEMI
        { $$ = ast_new(L->A, AST_IF, @$); CHECK($$);
          $$->a = $2; $$->body = $4; $$->op_loc = @3; $$->close_loc = @5; }
    | T_IF expr T_THEN stmts T_ELSE stmts T_ENDIF T_SEMI
        { $$ = ast_new(L->A, AST_IF, @$); CHECK($$);
          $$->a = $2; $$->body = $4; $$->body2 = $6;
          $$->op_loc = @3; $$->else_loc = @5; $$->close_loc = @7; }
    | T_WHILE expr T_LOOP stmts T_ENDLOOP T_SEMI
        { $$ = ast_new(L->A, AST_WHILE, @$); CHECK($$);
          $$->a = $2; $$->body = $4; $$->op_loc = @3; $$->close_loc = @5; }
    ;

elems: expr              { $$ = (ast_list){ 0 };
                           CHECK(push(L, &$$, $1, @1, FREP_MAX_ARRAY, "elements in an array literal") == 0); }
     | elems T_COMMA expr { $$ = $1;
                           CHECK(push(L, &$$, $3, @3, FREP_MAX_ARRAY, "elements in an array literal") == 0); }
     ;

expr: expr T_OR expr     { CHECK($$ = binop(L, @$, @2, AST_OP_OR, $1, $3)); }
    | expr T_AND expr    { CHECK($$ = binop(L, @$, @2, AST_OP_AND, $1, $3)); }
    | T_NOT expr         { CHECK($$ = unop(L, @$, @1, AST_OP_NOT, $2)); }
    | expr T_EQ expr     { CHECK($$ = binop(L, @$, @2, AST_OP_EQ, $1, $3)); }
    | expr T_NE expr     { CHECK($$ = binop(L, @$, @2, AST_OP_NE, $1, $3)); }
    | expr T_LT expr     { CHECK($$ = binop(L, @$, @2, AST_OP_LT, $1, $3)); }
    | expr T_LE expr     { CHECK($$ = binop(L, @$, @2, AST_OP_LE, $1, $3)); }
    | expr T_GT expr     { CHECK($$ = binop(L, @$, @2, AST_OP_GT, $1, $3)); }
    | expr T_GE expr     { CHECK($$ = binop(L, @$, @2, AST_OP_GE, $1, $3)); }
    | expr T_PLUS expr   { CHECK($$ = binop(L, @$, @2, '+', $1, $3)); }
    | expr T_MINUS expr  { CHECK($$ = binop(L, @$, @2, '-', $1, $3)); }
    | expr T_BAR expr    { CHECK($$ = binop(L, @$, @2, '|', $1, $3)); }
    | expr T_AMP expr    { CHECK($$ = binop(L, @$, @2, '&', $1, $3)); }
    | expr T_BSLASH expr { CHECK($$ = binop(L, @$, @2, '\\', $1, $3)); }
    | expr T_AT expr     { CHECK($$ = binop(L, @$, @2, '@', $1, $3)); }
    | expr T_STAR expr   { CHECK($$ = binop(L, @$, @2, '*', $1, $3)); }
    | expr T_SLASH expr  { CHECK($$ = binop(L, @$, @2, '/', $1, $3)); }
    | expr T_CARET expr  { CHECK($$ = binop(L, @$, @2, '^', $1, $3)); }
    | T_MINUS expr %prec UNARY { CHECK($$ = unop(L, @$, @1, '-', $2)); }
    | T_TILDE expr %prec UNARY { CHECK($$ = unop(L, @$, @1, '~', $2)); }
    | T_PLUS expr %prec UNARY  { $$ = $2; /* the reference accepts a unary plus */ }
    | primary
    ;

primary: T_NUM
           { CHECK($$ = ast_num(L->A, @1, $1)); }
       | T_IDENT
           { CHECK($$ = leaf(L, AST_VAR, @1, @1, $1.name, $1.key)); }
       | T_IDENT T_LBRACK expr T_RBRACK
           { CHECK($$ = leaf(L, AST_INDEX, @$, @1, $1.name, $1.key));
             $$->a = $3; $$->depth = $3->depth + 1; }
       | T_IDENT T_LPAREN args T_RPAREN
           { CHECK($$ = leaf(L, AST_CALL, @$, @1, $1.name, $1.key));
             $$->list = $3;
             for (uint32_t i = 0; i < $3.n; i++)
                 if ($3.v[i]->depth + 1 > $$->depth) $$->depth = $3.v[i]->depth + 1;
             if ($$->depth > FREP_MAX_EXPR_DEPTH) {
                 lex_error(L, @$, @1.end - @1.off, "expression nested too deeply (more "
                           "than %u levels)", FREP_MAX_EXPR_DEPTH);
                 YYABORT;
             } }
       | T_LPAREN expr T_RPAREN
           { $$ = $2; $$->parens = 1; }
       ;

args: %empty             { $$ = (ast_list){ 0 }; }
    | arglist
    ;

arglist: expr            { $$ = (ast_list){ 0 };
                           CHECK(push(L, &$$, $1, @1, FREP_MAX_ARGS, "arguments in a call") == 0); }
       | arglist T_COMMA expr
                         { $$ = $1;
                           CHECK(push(L, &$$, $3, @3, FREP_MAX_ARGS, "arguments in a call") == 0); }
       ;

%%

static void frep_yyerror(FREP_YYLTYPE *loc, lex_state *L, const char *msg)
{
    /* Only reached for Bison's own failures (syntax errors go through
     * yyreport_syntax_error; the nesting limit keeps the stack from running out). */
    lex_error(L, *loc, 1, "%s", msg);
}

static void out_of_memory(lex_state *L, ast_loc loc)
{
    lex_error(L, loc, 1, "out of memory");
}

static uint32_t span(ast_loc loc) { return loc.end > loc.off ? loc.end - loc.off : 1; }

/* Operator classes that share the additive precedence level. */
static int is_setop(int op) { return op == '|' || op == '&' || op == '\\' || op == '@'; }
static int is_addop(int op) { return op == '+' || op == '-'; }
static int is_logic(int op) { return op == AST_OP_AND || op == AST_OP_OR; }

static ast_node *binop(lex_state *L, ast_loc loc, ast_loc op_loc, int op, ast_node *a,
                       ast_node *b)
{
    ast_node *n = ast_binary(L->A, loc, op_loc, op, a, b);
    if (!n) { out_of_memory(L, loc); return NULL; }
    if (n->depth > FREP_MAX_EXPR_DEPTH) {
        lex_error(L, op_loc, span(op_loc), "expression nested too deeply (more than %u "
                  "levels); split it with intermediate variables", FREP_MAX_EXPR_DEPTH);
        return NULL;
    }
    /* Left operand at the same level without parentheses: a | b + c is (a | b) + c,
     * which surprises anyone who expects set operators to bind like logical ones. */
    if (a->kind == AST_BINARY && !a->parens) {
        if ((is_setop(op) && is_addop(a->op)) || (is_addop(op) && is_setop(a->op)))
            diag_report(L->d, FREP_WARNING, op_loc, span(op_loc),
                        "'%s' and '%s' share one precedence level and group left to "
                        "right: this is (... %s ...) %s ...; add parentheses to make "
                        "the order explicit", ast_op_name(a->op), ast_op_name(op),
                        ast_op_name(a->op), ast_op_name(op));
        else if (is_logic(op) && is_logic(a->op) && op != a->op)
            diag_report(L->d, FREP_WARNING, op_loc, span(op_loc),
                        "'and' and 'or' share one precedence level and group left to "
                        "right (as in HyperFun): this is (... %s ...) %s ...; add "
                        "parentheses to make the order explicit", ast_op_name(a->op),
                        ast_op_name(op));
    }
    return n;
}

static ast_node *unop(lex_state *L, ast_loc loc, ast_loc op_loc, int op, ast_node *a)
{
    ast_node *n = ast_unary(L->A, loc, op_loc, op, a);
    if (!n) { out_of_memory(L, loc); return NULL; }
    if (n->depth > FREP_MAX_EXPR_DEPTH) {
        lex_error(L, op_loc, span(op_loc), "expression nested too deeply (more than %u "
                  "levels)", FREP_MAX_EXPR_DEPTH);
        return NULL;
    }
    return n;
}

static ast_node *leaf(lex_state *L, ast_kind kind, ast_loc loc, ast_loc name_loc,
                      const char *name, const char *key)
{
    ast_node *n = ast_new(L->A, kind, loc);
    if (!n) { out_of_memory(L, loc); return NULL; }
    n->op_loc = name_loc;
    n->name = name;
    n->key = key;
    return n;
}

static int push(lex_state *L, ast_list *l, ast_node *n, ast_loc loc, uint32_t limit,
                const char *what)
{
    if (l->n >= limit) {
        if (*what)
            lex_error(L, loc, span(loc), "too many %s (at most %u)", what, limit);
        else
            lex_error(L, loc, span(loc), "a model takes 2 or 3 arrays: "
                      "name(x[3], a[1]) or name(x[3], a[1], s[1])");
        return -1;
    }
    if (ast_list_push(L->A, l, n)) { out_of_memory(L, loc); return -1; }
    return 0;
}

/* Array sizes are number literals, rounded to the nearest whole number, halves up, as
 * the reference does (HF_round in int_parse_N.c; lang/check.c warns when that
 * changed the number), then in [min, FREP_MAX_ARRAY]. */
static int array_size(lex_state *L, ast_loc loc, double v, uint32_t min, uint32_t *size)
{
    if (v <= FREP_MAX_ARRAY) v = ceil(v) - v > 0.5 ? ceil(v) - 1 : ceil(v);
    if (v < min) {
        lex_error(L, loc, span(loc), "array size must be at least %u", min);
        return -1;
    }
    if (v > FREP_MAX_ARRAY) {
        lex_error(L, loc, span(loc), "array too large (at most %u elements)",
                  FREP_MAX_ARRAY);
        return -1;
    }
    *size = (uint32_t)v;
    return 0;
}

/* The header `name(x[N], a[M] [, s[K]])` has been read: open a new model. */
static int start_model(lex_state *L, ast_loc loc, const char *name, const char *key,
                       ast_list *params)
{
    if (params->n < 2) {
        lex_error(L, params->v[0]->loc, span(params->v[0]->loc),
                  "a model takes 2 or 3 arrays: name(x[3], a[1]) or "
                  "name(x[3], a[1], s[1])");
        return -1;
    }
    if (L->nmodels >= FREP_MAX_MODELS) {
        lex_error(L, loc, span(loc), "too many models in one file (at most %u)",
                  FREP_MAX_MODELS);
        return -1;
    }
    if (L->nmodels == L->cap_models) {
        uint32_t cap = L->cap_models ? 2 * L->cap_models : 4;
        ast_model *m = arena_grow(L->A, L->models, L->nmodels, cap, sizeof *m);
        if (!m) { out_of_memory(L, loc); return -1; }
        L->models = m;
        L->cap_models = cap;
    }
    ast_model *m = &L->models[L->nmodels++];
    memset(m, 0, sizeof *m);
    m->name = name;
    m->key = key;
    m->loc = loc;
    m->nparams = params->n;
    for (uint32_t i = 0; i < params->n; i++) {
        ast_node *p = params->v[i];
        ast_array_decl *d = &m->params[i];
        d->name = p->name;
        d->key = p->key;
        d->loc = p->loc;
        d->written = p->num;
        d->size_loc = p->op_loc;
        /* x[0] or a[0] is accepted as in the reference: a model may use no parameter */
        if (array_size(L, p->op_loc, p->num, 0, &d->size)) return -1;
    }
    return 0;
}

static int add_array(lex_state *L, ast_loc loc, const char *name, const char *key,
                     double size, ast_loc size_loc)
{
    ast_model *m = &L->models[L->nmodels - 1];
    uint32_t n;
    if (array_size(L, size_loc, size, 1, &n)) return -1;
    if (m->narrays % 8 == 0) {
        ast_array_decl *a = arena_grow(L->A, m->arrays, m->narrays, m->narrays + 8,
                                       sizeof *a);
        if (!a) { out_of_memory(L, loc); return -1; }
        m->arrays = a;
    }
    ast_array_decl *d = &m->arrays[m->narrays++];
    d->name = name;
    d->key = key;
    d->size = n;
    d->written = size;
    d->loc = loc;
    d->size_loc = size_loc;
    return 0;
}

static int model_statement(lex_state *L, ast_node *stmt)
{
    ast_model *m = &L->models[L->nmodels - 1];
    return push(L, &m->body, stmt, stmt->loc, UINT32_MAX, "");
}

/* ---- syntax error messages ---------------------------------------------- */

/* How an expected token is named in "expected X". */
static const char *expected_name(yysymbol_kind_t k)
{
    if (k == YYSYMBOL_YYEOF) return "end of file";
    if (k == YYSYMBOL_T_IDENT) return "a name";
    if (k == YYSYMBOL_T_NUM) return "a number";
    return NULL;
}

static int is_expr_start(yysymbol_kind_t k)
{
    return k == YYSYMBOL_T_NUM || k == YYSYMBOL_T_IDENT || k == YYSYMBOL_T_LPAREN ||
           k == YYSYMBOL_T_MINUS || k == YYSYMBOL_T_PLUS || k == YYSYMBOL_T_TILDE ||
           k == YYSYMBOL_T_NOT;
}

static int is_binary(yysymbol_kind_t k)
{
    return k == YYSYMBOL_T_PLUS || k == YYSYMBOL_T_MINUS || k == YYSYMBOL_T_STAR ||
           k == YYSYMBOL_T_SLASH || k == YYSYMBOL_T_CARET || k == YYSYMBOL_T_BAR ||
           k == YYSYMBOL_T_AMP || k == YYSYMBOL_T_BSLASH || k == YYSYMBOL_T_AT ||
           k == YYSYMBOL_T_EQ || k == YYSYMBOL_T_NE || k == YYSYMBOL_T_LT ||
           k == YYSYMBOL_T_LE || k == YYSYMBOL_T_GT || k == YYSYMBOL_T_GE ||
           k == YYSYMBOL_T_AND || k == YYSYMBOL_T_OR;
}

/* The found token, described: "end of file", "name 'foo'", "number '1e5'", "'endif'". */
static void describe_found(lex_state *L, yysymbol_kind_t k, ast_loc at, char *buf,
                           size_t size)
{
    int n = (int)(at.end - at.off);
    if (n > 40) n = 40;
    if (k == YYSYMBOL_YYEOF)
        snprintf(buf, size, "end of file");
    else if (k == YYSYMBOL_T_IDENT)
        snprintf(buf, size, "name '%.*s'", n, L->src + at.off);
    else if (k == YYSYMBOL_T_NUM)
        snprintf(buf, size, "number '%.*s'", n, L->src + at.off);
    else
        snprintf(buf, size, "'%s'", yysymbol_name(k));
}

static int closer_of(int open_kind, yysymbol_kind_t *k, const char **open_name,
                     const char **close_name)
{
    switch (open_kind) {
    case '(': *k = YYSYMBOL_T_RPAREN; *open_name = "("; *close_name = ")"; return 1;
    case '[': *k = YYSYMBOL_T_RBRACK; *open_name = "["; *close_name = "]"; return 1;
    case '{': *k = YYSYMBOL_T_RBRACE; *open_name = "{"; *close_name = "}"; return 1;
    case 'i': *k = YYSYMBOL_T_ENDIF; *open_name = "if"; *close_name = "endif"; return 1;
    case 'w': *k = YYSYMBOL_T_ENDLOOP; *open_name = "while"; *close_name = "endloop";
              return 1;
    default: return 0;
    }
}

/* The position right after the token before the lookahead: where a missing ';' or
 * the end of an unfinished construct belongs. */
static ast_loc after_prev(const lex_state *L)
{
    ast_loc p = L->prev_loc;
    p.col += p.end - p.off;
    p.off = p.end;
    return p;
}

/* What a syntax error is reported from: the lookahead, the tokens that would fit,
 * and where the message goes. */
typedef struct syntax_ctx {
    lex_state *L;
    yysymbol_kind_t tok;       /* the lookahead */
    ast_loc at;                /* its position */
    yysymbol_kind_t exp[YYNTOKENS];
    int nexp;
    int has[YYNTOKENS];        /* has[k]: token k would fit */
    int eof;
    const char *eof_note;
    ast_loc where;             /* where the message points: after the previous token at
                                  end of file, else the lookahead */
    uint32_t len;
    char found[96];            /* the lookahead, described */
    const lex_open *open;      /* innermost open bracket or block, not the lookahead */
    int want_open;             /* the lookahead closes this kind ('(' '[' '{' 'w' 'i'), or 0 */
} syntax_ctx;

/* 0. a closer with nothing to close (unless it is a typo for the closer of the
 * innermost bracket). */
static int se_unmatched_closer(syntax_ctx *e)
{
    lex_state *L = e->L;
    int found_open = 0;
    if (!e->want_open) return 0;
    for (uint32_t i = 0; i < L->nopen; i++) found_open |= L->open[i].kind == e->want_open;
    const lex_open *in = L->nopen ? &L->open[L->nopen - 1] : NULL;
    if (in && ((in->kind == '(' && e->has[YYSYMBOL_T_RPAREN]) ||
               (in->kind == '[' && e->has[YYSYMBOL_T_RBRACK])))
        found_open = 1;
    if (found_open) return 0;
    static const char *const opener_name[] = { "(", "[", "{", "while", "if" };
    int w = e->want_open;
    const char *o = opener_name[w == '(' ? 0 : w == '[' ? 1 : w == '{' ? 2 : w == 'w' ? 3 : 4];
    lex_error(L, e->at, e->len, "unexpected %s without a matching '%s'", e->found, o);
    return 1;
}

/* 1. a closer is possible here: name what it would close (for a block, only when what
 * came instead could be a wrong closer); 4. also at the end of the file. */
static int se_unclosed(syntax_ctx *e, int at_eof_only)
{
    yysymbol_kind_t ck;
    const char *on, *cn;
    int closer_like = e->eof || e->want_open || e->tok == YYSYMBOL_T_SEMI ||
                      e->tok == YYSYMBOL_T_COMMA;
    if (!e->open || !closer_of(e->open->kind, &ck, &on, &cn)) return 0;
    if (at_eof_only ? !e->eof
                    : !(e->has[ck] && (closer_like || e->open->kind == '(' ||
                                       e->open->kind == '[')))
        return 0;
    lex_error(e->L, e->where, e->len, "expected '%s' to close '%s' at %u:%u%s", cn, on,
              (unsigned)e->open->loc.line, (unsigned)e->open->loc.col, e->eof_note);
    return 1;
}

/* 2. then/loop after a condition. */
static int se_then_loop(syntax_ctx *e)
{
    if (!e->has[YYSYMBOL_T_THEN] && !e->has[YYSYMBOL_T_LOOP]) return 0;
    const char *kw = e->has[YYSYMBOL_T_THEN] ? "then" : "loop";
    const char *st = e->has[YYSYMBOL_T_THEN] ? "if" : "while";
    lex_error(e->L, e->where, e->len, "expected '%s' after the condition of '%s', found %s",
              kw, st, e->found);
    return 1;
}

/* 3. a missing ';' belongs right after the previous token. */
static int se_semicolon(syntax_ctx *e)
{
    lex_state *L = e->L;
    if (!e->has[YYSYMBOL_T_SEMI] || !L->prev_tok) return 0;
    ast_loc p = after_prev(L);
    if (L->prev_tok == T_ENDIF || L->prev_tok == T_ENDLOOP)
        lex_error(L, p, 1, "expected ';' after '%s'",
                  L->prev_tok == T_ENDIF ? "endif" : "endloop");
    else if (L->in_decl)
        lex_error(L, p, 1, "expected ',' or ';' in array declaration, found %s", e->found);
    else
        lex_error(L, p, 1, "expected ';' after assignment, found %s", e->found);
    return 1;
}

/* 5. between models. */
static int se_between_models(syntax_ctx *e)
{
    lex_state *L = e->L;
    if (!e->has[YYSYMBOL_T_IDENT] || e->open || e->nexp > 2) return 0;
    if (e->eof && L->nmodels == 0 && !L->prev_tok)
        lex_error(L, (ast_loc){ 0, 0, 0, 0 }, 0, "no model in the file: expected a "
                  "model such as 'my_model(x[3], a[1]) { ... }'");
    else
        lex_error(L, e->where, e->len, "expected a model such as "
                  "'my_model(x[3], a[1]) { ... }', found %s", e->found);
    return 1;
}

/* 6. a list of what would fit, grouped so that it stays short. */
static void se_expected_list(syntax_ctx *e)
{
    const char *names[8];
    int nn = 0, expr_done = 0, nbin = 0;
    int stmt = e->has[YYSYMBOL_T_IF] && e->has[YYSYMBOL_T_WHILE];
    for (int i = 0; i < e->nexp; i++) nbin += is_binary(e->exp[i]);
    for (int i = 0; i < e->nexp && nn < 8; i++) {
        yysymbol_kind_t k = e->exp[i];
        if (e->has[YYSYMBOL_T_NUM] && is_expr_start(k)) {
            if (!expr_done) names[nn++] = "an expression";
            expr_done = 1;
        } else if (nbin > 3 && is_binary(k)) {
            if (nbin > 0) names[nn++] = "an operator";
            nbin = -1000;
        } else if (stmt && (k == YYSYMBOL_T_IDENT || k == YYSYMBOL_T_IF ||
                            k == YYSYMBOL_T_WHILE)) {
            if (stmt == 1) names[nn++] = "a statement";
            stmt = 2;
        } else {
            names[nn++] = expected_name(k) ? expected_name(k) : NULL;
            if (!names[nn - 1]) names[nn - 1] = yysymbol_name(k);
        }
    }
    if (nn == 0 || nn > 4) {
        lex_error(e->L, e->where, e->len, "unexpected %s", e->found);
        return;
    }
    char list[256];
    size_t used = 0;
    list[0] = '\0';
    for (int i = 0; i < nn; i++) {
        int quote = names[i][0] != 'a' || strchr(names[i], ' ') == NULL;
        if (strcmp(names[i], "end of file") == 0) quote = 0;
        int w = snprintf(list + used, sizeof list - used, "%s%s%s%s%s",
                         i == 0 ? "" : i == nn - 1 ? " or " : ", ", quote ? "'" : "",
                         names[i], quote ? "'" : "", "");
        if (w < 0 || (size_t)w >= sizeof list - used) break;
        used += (size_t)w;
    }
    lex_error(e->L, e->where, e->len, "expected %s, found %s", list, e->found);
}

/* The one message of a syntax error: the first of the steps below that applies. */
static int yyreport_syntax_error(const yypcontext_t *ctx, lex_state *L)
{
    if (L->error) return 0;
    syntax_ctx e;
    memset(&e, 0, sizeof e);
    e.L = L;
    e.tok = yypcontext_token(ctx);
    e.at = *yypcontext_location(ctx);
    e.nexp = yypcontext_expected_tokens(ctx, e.exp, YYNTOKENS);
    if (e.nexp < 0) e.nexp = 0;
    for (int i = 0; i < e.nexp; i++) e.has[e.exp[i]] = 1;
    e.eof = e.tok == YYSYMBOL_YYEOF;
    e.eof_note = e.eof ? " (reached end of file)" : "";
    e.where = e.eof && L->prev_tok ? after_prev(L) : e.at;
    e.len = e.eof ? 1 : span(e.at);
    describe_found(L, e.tok, e.at, e.found, sizeof e.found);
    for (uint32_t i = L->nopen; i-- > 0;)
        if (L->open[i].loc.off != e.at.off || e.eof) { e.open = &L->open[i]; break; }
    yysymbol_kind_t t = e.tok;
    e.want_open = t == YYSYMBOL_T_RPAREN ? '(' : t == YYSYMBOL_T_RBRACK ? '['
                : t == YYSYMBOL_T_RBRACE ? '{' : t == YYSYMBOL_T_ENDLOOP ? 'w'
                : t == YYSYMBOL_T_ENDIF || t == YYSYMBOL_T_ELSE ? 'i' : 0;
    if (se_unmatched_closer(&e) || se_unclosed(&e, 0) || se_then_loop(&e) ||
        se_semicolon(&e) || se_unclosed(&e, 1) || se_between_models(&e))
        return 0;
    se_expected_list(&e);
    return 0;
}

/* ---- entry point ---------------------------------------------------------- */

int ast_parse(arena *A, const char *filename, const char *src, size_t len, diag_sink *d,
              ast_file *out)
{
    memset(out, 0, sizeof *out);
    out->filename = filename;
    out->src = src;
    out->len = len;
    if (d && !d->file) d->file = filename;
    if (d && !d->A) d->A = A;
    lex_state *L = arena_alloc(A, sizeof *L);
    if (!L) {
        diag_report(d, FREP_ERROR, (ast_loc){ 0, 0, 0, 0 }, 0, "out of memory");
        return -1;
    }
    if (lex_init(L, A, d, filename, src, len)) return -1;
    int r = frep_yyparse(L);
    if (r != 0 || L->error || A->failed) {
        if (!L->error) lex_error(L, (ast_loc){ 0, 0, 0, 0 }, 0, "out of memory");
        return -1;
    }
    out->models = L->models;
    out->nmodels = L->nmodels;
    out->pragmas = L->pragmas;
    out->npragmas = L->npragmas;
    return 0;
}
