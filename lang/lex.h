/* lex.h - the lexer state of one parse (lang/lex.re), shared with the parser.
 *
 * Pipeline: source text -> lang/lex.re (tokens, annotations) -> lang/parse.y (tree).
 * The state is the whole context of one parse: no globals, so any number of parses
 * may run at once.  It also records what the parser's error messages need: the open
 * brackets and blocks (to say which one a missing closer belongs to) and the previous
 * token (to put a missing ';' right after it).
 */
#ifndef FREP_LEX_H
#define FREP_LEX_H

#include <stddef.h>
#include <stdint.h>

#include "arena.h"
#include "ast.h"
#include "parse.h"

/* An open bracket or block: kind is '(', '[', '{', 'i' (if) or 'w' (while). */
typedef struct lex_open {
    int kind;
    ast_loc loc;
} lex_open;

struct lex_state {
    /* input: a NUL-terminated copy of the source (a NUL inside it is an error) */
    const char *src;
    size_t len;
    const char *cur, *mrk, *tok;
    const char *line_start;   /* first byte of the current line */
    uint32_t line;

    arena *A;
    diag_sink *d;
    const char *filename;
    int error;                /* an error was reported: everyone stays quiet */

    /* annotations (-- @word text), in file order */
    ast_pragma *pragmas;
    uint32_t npragmas, cap_pragmas;

    /* open brackets and blocks, innermost last; bounded by FREP_MAX_NESTING */
    lex_open open[FREP_MAX_NESTING];
    uint32_t nopen;
    uint32_t unary_run;       /* prefix operators in a row (each one nests) */
    int last_ends_operand;    /* the last token can end an operand: a prefix op follows? */

    /* the last two tokens handed to the parser (the last one is the lookahead when
     * a syntax error is found) */
    int last_tok, prev_tok;
    ast_loc last_loc, prev_loc;
    int in_decl;              /* between 'array' and its ';' */

    /* the models built so far (the parser's output) */
    ast_model *models;
    uint32_t nmodels, cap_models;
};

/* Prepare L to read src[0..len) (copied, NUL-terminated, into the arena). Returns 0,
 * or -1 after reporting (too large, out of memory). */
int lex_init(lex_state *L, arena *A, diag_sink *d, const char *filename, const char *src,
             size_t len);

/* The next token for the Bison parser; FREP_YYEOF at the end, FREP_YYerror after
 * reporting a lexical error. */
int frep_yylex(FREP_YYSTYPE *val, FREP_YYLTYPE *loc, lex_state *L);

/* Report an error at loc (span len) unless one was reported already. */
void lex_error(lex_state *L, ast_loc loc, uint32_t len, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;

#endif
