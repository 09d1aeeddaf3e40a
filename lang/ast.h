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
    ast_loc op_loc;      /* operator (binary/unary) or name (var/call/assign) span */
    const char *name;    /* as written (VAR, INDEX, CALL, ASSIGN*) */
    const char *key;     /* lower-cased name: identifiers are case-insensitive */
    double num;          /* AST_NUM */
    int parens;          /* expression was written in parentheses */
    ast_node *a, *b;     /* operands, index, condition, assigned value (see kind) */
    ast_list list;       /* call arguments, array literal elements */
    ast_list body, body2;/* if: then/else statements; while: body */
};

typedef struct ast_array_decl {
    const char *name, *key;
    uint32_t size;
    ast_loc loc;
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

/* Diagnostics sink of a compile session: counts errors, forwards to the user. */
typedef struct diag_sink {
    frep_diag_fn fn;
    void *user;
    const char *file;
    unsigned errors, warnings;
} diag_sink;

void diag_report(diag_sink *d, frep_severity sev, ast_loc loc, uint32_t len,
                 const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;

/* Parse a whole file into `out` (arena-owned). Returns 0 on success, -1 after
 * reporting the first syntax error (one error, no cascade). Implemented in parse.y. */
int ast_parse(arena *A, const char *filename, const char *src, size_t len, diag_sink *d,
              ast_file *out);

/* Canonical source of a file (frep print). Parsing the result gives the same
 * program. Returns a malloc'ed string; free() it. Implemented in print.c. */
char *ast_print(const ast_file *f);

void ast_list_push(arena *A, ast_list *l, ast_node *n);

#endif
