/* ast.h - abstract syntax tree of a HyperFun source file.
 *
 * Pipeline: lang/lex.re (tokens) -> lang/parse.y (this tree) -> lang/check.c
 * (names, arities) -> lang/lower.c (IR DAG, lang/ir.h) -> lang/emit.c (bytecode).
 * Every node lives in the compile session's arena (lang/arena.h): nothing here is
 * freed individually, and parser error recovery cannot leak.
 */
#ifndef FREP_AST_H
#define FREP_AST_H

#include <stdint.h>
#include <stddef.h>

#include "arena.h"
#include "frep.h"

/* A source span: 1-based line/col of its first character, byte offsets [off, end). */
typedef struct ast_loc {
    uint32_t line, col;
    uint32_t off, end;
} ast_loc;

/* Limits of the front end. Each is checked by lang/parse.y or lang/lex.re, reported
 * as an ordinary error, and hit by a test in tests/test_parse.c. */
#define FREP_MAX_SOURCE (64u << 20)  /* bytes of one file: offsets are 32-bit and the
                                        tree of a file takes ~10x its size */
#define FREP_MAX_NESTING 256         /* open brackets + if/while + prefix operators in a
                                        row: bounds the parser stack (never "memory
                                        exhausted") and the recursion of later passes */
#define FREP_MAX_EXPR_DEPTH 10000    /* height of one expression tree (long chains such
                                        as a|b|c|...): passes over the tree recurse, and
                                        10000 frames stay well inside an 8 MiB stack */
#define FREP_MAX_IDENT 255           /* characters of a name: the reference interpreter's
                                        limit, so every file it reads is read here too */
#define FREP_MAX_MODELS 4096         /* models in one file: calls between them are looked
                                        up by name; far above any real file */
#define FREP_MAX_ARRAY (1u << 16)    /* elements of a declared array or array literal:
                                        every element becomes its own value slot */
#define FREP_MAX_ARGS 1024           /* arguments of one call: no library function takes
                                        more than a handful; bounds the call checks */

typedef enum ast_kind {
    /* expressions */
    AST_NUM,       /* num */
    AST_VAR,       /* name: scalar variable or whole array (decided by check.c) */
    AST_INDEX,     /* name[a] */
    AST_CALL,      /* name(list...) - library function or earlier model */
    AST_UNARY,     /* op a: '-' negation, '~' set complement, 'n' logical not */
    AST_BINARY,    /* a op b: + - * / ^ | & \ @, comparisons, 'a' and, 'o' or */
    /* statements */
    AST_ASSIGN,        /* name = a; */
    AST_ASSIGN_INDEX,  /* name[a] = b; */
    AST_ASSIGN_ARRAY,  /* name = [list...]; */
    AST_IF,            /* if a then body else body2 endif; (body2 may be empty) */
    AST_WHILE          /* while a loop body endloop; */
} ast_kind;

/* Binary/unary operator codes (ast_node.op). Comparisons use these codes: */
enum {
    AST_OP_EQ = 'e',   /* = */
    AST_OP_NE = 'n',   /* /= */
    AST_OP_LT = '<',
    AST_OP_LE = 'l',   /* <= */
    AST_OP_GT = '>',
    AST_OP_GE = 'g',   /* >= */
    AST_OP_AND = 'a',
    AST_OP_OR = 'o',
    AST_OP_NOT = '!'
    /* the rest are the character itself: + - * / ^ | & \ @ ~ */
};

typedef struct ast_node ast_node;

typedef struct ast_list {
    ast_node **v;
    uint32_t n, cap;
} ast_list;

struct ast_node {
    ast_kind kind;
    int op;              /* AST_UNARY / AST_BINARY operator code */
    ast_loc loc;         /* whole node; for AST_BINARY the operator token is op_loc */
    ast_loc op_loc;      /* operator (binary/unary) or name (var/call/assign) span;
                            AST_IF: the 'then' keyword, AST_WHILE: the 'loop' keyword */
    ast_loc else_loc;    /* AST_IF: the 'else' keyword (line 0 when there is none) */
    ast_loc close_loc;   /* AST_IF/AST_WHILE: the 'endif'/'endloop' keyword */
    uint32_t depth;      /* expressions: height of the tree below (a leaf is 1) */
    const char *name;    /* as written (VAR, INDEX, CALL, ASSIGN*) */
    const char *key;     /* lower-cased name: identifiers are case-insensitive */
    double num;          /* AST_NUM */
    int parens;          /* expression was written in parentheses (not part of the tree:
                            ast_node_equal ignores it) */
    ast_node *a, *b;     /* operands, index, condition, assigned value (see kind) */
    ast_list list;       /* call arguments, array literal elements */
    ast_list body, body2;/* if: then/else statements; while: body */
};

typedef struct ast_array_decl {
    const char *name, *key;
    uint32_t size;      /* the size written, rounded as the reference does (HF_round) */
    double written;     /* the size as written (2.6 in `c[2.6]`) */
    ast_loc loc;
    ast_loc size_loc;   /* the size's number */
} ast_array_decl;

/* A model: name(x[N], a[M] [, s[K]]) { array decls; statements } */
typedef struct ast_model {
    const char *name, *key;
    ast_loc loc;                     /* name token */
    ast_array_decl params[3];        /* x, a, optional s (names as written) */
    uint32_t nparams;                /* 2 or 3 */
    ast_array_decl *arrays;          /* local array declarations */
    uint32_t narrays;
    ast_list body;                   /* statements */
    ast_loc open_loc;                /* opening brace */
    ast_loc end_loc;                 /* closing brace */
} ast_model;

/* A `-- @word rest` comment (annotation). The lexer collects them in file order. */
typedef struct ast_pragma {
    const char *word;   /* "free", "setops", "box", ... (lower-case) */
    const char *text;   /* rest of the comment after the word, trimmed */
    ast_loc loc;        /* position of '@' */
} ast_pragma;

typedef struct ast_file {
    const char *filename;
    const char *src;       /* source text (not NUL-terminated in general) */
    size_t len;
    ast_model *models;
    uint32_t nmodels;
    ast_pragma *pragmas;
    uint32_t npragmas;
} ast_file;

/* Diagnostics sink of a compile session: counts errors, forwards to the user.
 * Once memory has run out (diag_nomem, or the session arena A has failed), one
 * "out of memory" error is reported and every later diagnostic is only counted: it
 * may be a consequence of the lost allocation, not of the source. */
typedef struct diag_sink {
    frep_diag_fn fn;
    void *user;
    const char *file;
    unsigned errors, warnings;
    const arena *A;        /* the session arena, or NULL */
    int nomem;             /* "out of memory" was reported */
} diag_sink;

void diag_report(diag_sink *d, frep_severity sev, ast_loc loc, uint32_t len,
                 const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;

/* Report "out of memory" (an error without position), once per session. */
void diag_nomem(diag_sink *d);

/* Parse a whole file into `out` (arena-owned). Returns 0 on success, -1 after
 * reporting the first syntax error (one error, no cascade). Implemented in parse.y. */
int ast_parse(arena *A, const char *filename, const char *src, size_t len, diag_sink *d,
              ast_file *out);

/* Canonical source of a file (frep print). Parsing the result gives the same
 * program. Returns a malloc'ed string; frep_free() it. Implemented in print.c. */
char *ast_print(const ast_file *f);

/* Append n to l (storage grows in the arena). Returns 0, or -1 when out of memory. */
int ast_list_push(arena *A, ast_list *l, ast_node *n);

/* Node constructors (lang/ast.c): zeroed arena nodes with kind, loc and depth set;
 * NULL when out of memory. */
ast_node *ast_new(arena *A, ast_kind kind, ast_loc loc);
ast_node *ast_num(arena *A, ast_loc loc, double v);
ast_node *ast_unary(arena *A, ast_loc loc, ast_loc op_loc, int op, ast_node *a);
ast_node *ast_binary(arena *A, ast_loc loc, ast_loc op_loc, int op, ast_node *a,
                     ast_node *b);

/* Structural equality: kinds, operators, numbers, names as written, children and
 * pragmas; source positions and the parens flag are ignored. 1 when equal. */
int ast_node_equal(const ast_node *a, const ast_node *b);
int ast_file_equal(const ast_file *a, const ast_file *b);

/* Spelling of an operator code for messages and printing ("+", "<=", "and"...). */
const char *ast_op_name(int op);

#endif
